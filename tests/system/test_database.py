"""The scan database (docs/database.md): catalog + files, check, rebuild, concurrency and crash safety: the
system tests (writers killed with kill -9)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from conftest import make_scan
from unit.test_database import _corrupt, _fill

from scanner.cli import EXIT_PROBLEMS, main
from scanner.storage.database import Database
from scanner.storage.files import owned_folder
from scanner.storage.matfile import save_scan

CRASHING_WRITER = textwrap.dedent("""
    import os, signal, sys
    sys.path.insert(0, {tests!r})
    from conftest import make_scan
    import scanner.storage.database as database

    def crash(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGKILL)

    database.Database._insert = crash  # the files are written, the catalog rows never will be
    database.Database(sys.argv[1]).add(make_scan(int(sys.argv[2]), sample_id=sys.argv[3]))
""")


def _crash_during_add(tmp_path: Path, root: Path, seed: int, sample_id: str) -> None:
    script = tmp_path / "crashing_writer.py"
    script.write_text(CRASHING_WRITER.format(tests=str(Path(__file__).parents[1])))
    run = subprocess.run([sys.executable, str(script), str(root), str(seed), sample_id], timeout=120)
    assert run.returncode == -signal.SIGKILL


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL of a subprocess is POSIX-only")
def test_crash_leftovers_are_listed_apart_and_removed_but_files_of_nobody_are_kept(tmp_path, capsys):
    root = tmp_path / "db"
    db = Database(root)
    _fill(db)
    _crash_during_add(tmp_path, root, 4, "granite-04")
    uncommitted = [f"scans/C6S1M1P2X1/granite-04/granite-04-001{end}" for end in
                   ("_disp.png", "_illu.png", "_macro.png", ".mat")]
    folder = root / "scans/C6S1M1P2X1/granite-03"
    folder.mkdir()
    (folder / ".granite-03-001.mat.tmp-0123456789ab").write_bytes(b"MATLAB 5.0 half of a fi")
    for photo in ("disp", "macro"):  # an interrupted write of an older version: photos, no .mat
        (folder / f"granite-03-001_{photo}.png").write_bytes(b"\x89PNG...")
    abandoned = root / ".import.tmp-00112233aabb"
    abandoned.mkdir()
    (abandoned / "owner.lock").write_bytes(b"")
    (abandoned / "bundle").mkdir()
    with owned_folder(root / ".import.tmp-ffeeddccbbaa") as running:
        report = db.check()
        leftovers = sorted([*uncommitted, "scans/C6S1M1P2X1/granite-03/.granite-03-001.mat.tmp-0123456789ab",
                            "scans/C6S1M1P2X1/granite-03/granite-03-001_disp.png",
                            "scans/C6S1M1P2X1/granite-03/granite-03-001_macro.png"]) + [".import.tmp-00112233aabb/"]
        assert report.ok and report.unknown == [] and report.leftovers == leftovers
        assert main(["db", "check", "--db", str(root)]) == 0
        out = capsys.readouterr().out
        assert all(f"leftover {path}" in out for path in leftovers)
        assert "8 crash leftover(s), which 'texplorer db check --repair' removes" in out
        assert main(["db", "check", "--repair", "--db", str(root)]) == 0
        out = capsys.readouterr().out
        assert sorted(line.removeprefix("removed  ") for line in out.splitlines()
                      if line.startswith("removed  ")) == sorted(leftovers)
        assert running.is_dir()  # the staging folder of a live import is left alone
    assert db.check().leftovers == [] and not any((root / ".pending").iterdir())
    assert not (root / "scans/C6S1M1P2X1/granite-04").exists() and not folder.exists()

    # A complete scan nobody catalogued (copied in by hand) and a stray file are not leftovers: kept.
    save_scan(make_scan(5, sample_id="granite-05"), root / "scans/C6S1M1P2X1/granite-05/granite-05-001.mat")
    (root / "scans/readme.txt").write_text("notes")
    assert main(["db", "check", "--repair", "--db", str(root)]) == EXIT_PROBLEMS
    report = db.check()
    assert report.leftovers == [] and report.unknown == sorted(
        ["scans/readme.txt", *(f"scans/C6S1M1P2X1/granite-05/granite-05-001{end}"
                               for end in ("_disp.png", "_illu.png", "_macro.png", ".mat"))])
    assert db.rebuild().scans == 5 and db.check().unknown == ["scans/readme.txt"]  # rebuild adopts the scan


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL of a subprocess is POSIX-only")
def test_the_next_add_removes_the_files_of_an_add_that_never_committed(tmp_path):
    root = tmp_path / "db"
    db = Database(root)
    _fill(db)
    _crash_during_add(tmp_path, root, 4, "granite-04")
    assert len(db.check().leftovers) == 4 and len(list((root / ".pending").iterdir())) == 1
    db.add(make_scan(5, sample_id="granite-05"))
    report = db.check()
    assert report.ok and report.leftovers == [] and not any((root / ".pending").iterdir())
    assert db.add(make_scan(4, sample_id="granite-04")) == "granite-04-001"  # the crashed scan, added again
    assert db.check().ok and len(db) == 6


KILLER = textwrap.dedent("""
    import json, os, random, signal, sqlite3, sys, time
    sys.path.insert(0, {tests!r})
    from conftest import make_scan
    from scanner.lazy import preload
    from scanner.storage.database import Database
    from scanner.storage.files import sha256_file

    root, kills, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    # One add in a scratch database first: what storage imports or sets up on first use (OpenCV, scipy.io)
    # is then in every forked writer, which starts adding at once, as before those imports were deferred.
    preload()
    Database(root + "-warm-up").add(make_scan(0, sample_id="warm-up", image_shape=(96, 96), seconds=0.3))
    rng = random.Random(seed)
    Database(root).close()
    committed, leftovers = set(), set()
    for round_ in range(kills):
        first = 1000 * round_  # a killed scan may have committed: the next writer starts at new ids
        read, write = os.pipe()
        pid = os.fork()  # a copy of this process with everything imported: a kill every few hundred ms
        if pid == 0:
            os.close(read)
            db = Database(root)
            for i in range(first, first + 1000):
                db.add(make_scan(i, sample_id=f"s-{{i:05d}}", image_shape=(96, 96), seconds=0.3))
                os.write(write, f"s-{{i:05d}}-001\\n".encode())
            os._exit(0)
        os.close(write)
        time.sleep(rng.uniform(0.0, 0.3))
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        with os.fdopen(read) as acks:
            acknowledged = set(acks.read().split())
        with sqlite3.connect(os.path.join(root, "catalog.sqlite")) as conn:
            integrity = conn.execute("PRAGMA integrity_check").fetchone()[0]
        db = Database(root)
        ids = {{r.scan_id for r in db.records()}}
        dangling = [e.path for r in db.records() for e in db.files(r.scan_id)
                    if not os.path.isfile(os.path.join(root, e.path))
                    or sha256_file(os.path.join(root, e.path)) != e.sha256]
        report = db.check()
        print(json.dumps({{"integrity": integrity, "lost": sorted(committed - ids),
                          "unacknowledged_lost": sorted(acknowledged - ids), "dangling": dangling,
                          "missing": report.missing, "changed": report.changed, "unknown": report.unknown,
                          "stale": sorted(leftovers & set(report.leftovers)) if acknowledged else [],
                          "acknowledged": len(acknowledged)}}), flush=True)
        committed, leftovers = committed | ids, set(report.leftovers)
        db.close()
    db = Database(root)
    removed = db.repair()
    report = db.check()
    print(json.dumps({{"final": True, "removed": len(removed), "ok": report.ok, "leftovers": report.leftovers,
                      "scans": len(db)}}), flush=True)
""")


def _run_killer(script: str, tmp_path: Path, *args: str) -> list[dict]:
    path = tmp_path / "killer.py"
    path.write_text(script.format(tests=str(Path(__file__).parents[1])))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}  # a single-threaded parent forks
    run = subprocess.run([sys.executable, str(path), *args], capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr[-2000:]
    return [json.loads(line) for line in run.stdout.splitlines()]


@pytest.mark.skipif(os.name != "posix", reason="fork and SIGKILL are POSIX-only")
def test_writers_killed_at_60_random_moments_lose_nothing_and_leave_only_leftovers_the_next_add_removes(tmp_path):
    rounds = _run_killer(KILLER, tmp_path, str(tmp_path / "db"), "60", "1234")
    *kills, final = rounds
    assert len(kills) == 60
    for n, kill in enumerate(kills):
        assert kill["integrity"] == "ok", n
        assert kill["lost"] == [] and kill["unacknowledged_lost"] == [], f"kill {n} lost committed scans: {kill}"
        assert kill["dangling"] == [] and kill["missing"] == [] and kill["changed"] == [], f"kill {n}: {kill}"
        assert kill["unknown"] == [], f"kill {n} left files that are not recognised as leftovers: {kill}"
        assert kill["stale"] == [], f"the add after kill {n - 1} did not remove its leftovers: {kill}"
    assert sum(kill["acknowledged"] for kill in kills) >= 30, "the writers never got far enough to test anything"
    assert final["ok"] and final["leftovers"] == [] and final["scans"] >= 30


REBUILD_KILLER = textwrap.dedent("""
    import json, os, random, shutil, signal, sys, time
    sys.path.insert(0, {tests!r})
    from scanner.storage.database import Database, DatabaseError

    template, work, kills, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    rng = random.Random(seed)
    shutil.copytree(template, work + "-timing")
    started = time.perf_counter()
    Database(work + "-timing").rebuild()
    duration = time.perf_counter() - started
    # Kills at the k-th file rename (the catalog swap, the quarantine moves), then at random moments.
    plan = [("replace", k, 0.0) for k in (1, 2, 3)] + [("time", 0, rng.uniform(0, 2 * duration))
                                                          for _ in range(kills)]
    for round_, (mode, kill_at, delay) in enumerate(plan):
        root = f"{{work}}-{{round_}}"
        shutil.copytree(template, root)
        pid = os.fork()
        if pid == 0:
            if mode == "replace":
                real, calls = os.replace, []
                def replace(*args, **kwargs):
                    calls.append(args)
                    if len(calls) == kill_at:
                        os.kill(os.getpid(), signal.SIGKILL)
                    return real(*args, **kwargs)
                os.replace = replace
            Database(root).rebuild()
            os._exit(0)
        if mode == "time":
            time.sleep(delay)
            os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        db = Database(root)
        try:
            ids = sorted(r.scan_id for r in db.records())
            report = db.check()
            state = {{"ids": ids, "missing": report.missing, "changed": report.changed}}
        except DatabaseError as exc:
            state = {{"unreadable": str(exc)}}
        db.close()
        finished = Database(root).rebuild()
        db = Database(root)
        report = db.check()
        state.update(mode=mode, after=sorted(r.scan_id for r in db.records()), skipped=len(finished.skipped),
                     ok=report.ok, unknown=report.unknown, leftovers=report.leftovers,
                     quarantined=sorted(p.name for p in (db.root / "quarantine").rglob("*.mat")))
        print(json.dumps(state), flush=True)
        db.close()
""")


@pytest.mark.skipif(os.name != "posix", reason="fork and SIGKILL are POSIX-only")
@pytest.mark.parametrize("catalog", ["readable", "corrupt"])
def test_a_rebuild_killed_at_any_moment_never_leaves_a_smaller_catalog(tmp_path, catalog):
    template = tmp_path / "template"
    db = Database(template)
    for i in range(8):
        db.add(make_scan(i, sample_id=f"s-{i:02d}", image_shape=(64, 64)))
    for i in (8, 9):  # complete scans the catalog does not know yet: rebuild adopts them
        save_scan(make_scan(i, sample_id=f"s-{i:02d}", image_shape=(64, 64)),
                  template / f"scans/C6S1M1P2X1/s-{i:02d}/s-{i:02d}-001.mat")
    (template / "scans/C6S1M1P2X1/s-03/s-03-002.mat").write_bytes(b"MATLAB 5.0 cut short")
    catalogued = sorted(r.scan_id for r in db.records())
    db.close()
    if catalog == "corrupt":
        _corrupt(template, "random bytes")
    everything = sorted([*catalogued, "s-08-001", "s-09-001"])
    states = _run_killer(REBUILD_KILLER, tmp_path, str(template), str(tmp_path / "work"), "12", "7")
    for n, state in enumerate(states):
        if catalog == "readable":  # one transaction: the old catalog or the new one, never anything less
            assert state["ids"] in (catalogued, everything), (n, state)
            assert state["missing"] == [] and state["changed"] == [], (n, state)
        elif "unreadable" in state:  # killed before the new catalog was swapped in: the broken one is kept
            assert "texplorer db rebuild" in state["unreadable"], (n, state)
        else:  # swapped in: complete
            assert state["ids"] == everything and state["missing"] == [] and state["changed"] == [], (n, state)
        # Rebuilding again finishes the job: every good scan catalogued, the bad file in quarantine.
        assert state["after"] == everything and state["ok"] and state["unknown"] == [], (n, state)
        assert state["leftovers"] == [] and state["quarantined"] == ["s-03-002.mat"], (n, state)
    if catalog == "corrupt":  # the deterministic kills: just before the swap, and just after it
        assert "unreadable" in states[0] and states[1]["ids"] == everything
