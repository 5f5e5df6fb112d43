"""The scan database (SPEC 3): catalog + files, check, rebuild, concurrency and crash safety."""

from __future__ import annotations

import dataclasses
import os
import random
import signal
import sqlite3
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest
from conftest import make_scan

from scanner.database import Database, DatabaseError
from scanner.files import sha256_file
from taxonomy.labels import LabelError


def _fill(db: Database) -> None:
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, session_id="s-1", operator="ab"))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2", operator="cd"))
    db.add(make_scan(2, label="C6S1M1P3X1", sample_id="granite-02", scan_index=1, session_id="s-2", operator="cd"))
    db.add(make_scan(3, label="C7S1M1P8X1", sample_id="steel-01", scan_index=1, session_id="s-3", operator="ab",
                     rigid=True, drop=("f_fold", "alpha_f")))


def test_add_get_and_list_with_filters(tmp_path):
    db = Database(tmp_path / "db")
    _fill(db)
    assert len(db) == 4
    assert db.summary() == {"materials": 3, "samples": 3, "sessions": 3, "scans": 4, "files": 16}
    assert [r.scan_id for r in db.records(label="C6")] == ["granite-01-001", "granite-01-002", "granite-02-001"]
    assert [r.scan_id for r in db.records(label="C6S1M1P3X1")] == ["granite-02-001"]
    assert [r.scan_id for r in db.records(sample="granite-01")] == ["granite-01-001", "granite-01-002"]
    assert [r.scan_id for r in db.records(session="s-2")] == ["granite-01-002", "granite-02-001"]
    assert [r.scan_id for r in db.records(operator="ab")] == ["granite-01-001", "steel-01-001"]
    with pytest.raises(LabelError, match="not a label or class prefix"):  # LIKE wildcards are no codes
        db.records(label="C6_")
    assert db.record("steel-01-001").rigid
    assert db.get("granite-01-002") == make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2",
                                                  operator="cd")
    assert (tmp_path / "db/scans/C6S1M1P2X1/granite-01/granite-01-002.mat").is_file()
    assert db.next_scan_index("granite-01") == 3 and db.next_scan_index("new-sample") == 1
    with pytest.raises(DatabaseError, match="no scan 'nope'"):
        db.record("nope")


def test_add_refuses_duplicates_and_relabelled_samples_without_touching_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    path = tmp_path / "scans/C6S1M1P2X1/granite-01/granite-01-001.mat"
    before = path.read_bytes()
    with pytest.raises(DatabaseError, match="granite-01-001 is already in the database"):
        db.add(make_scan(9, sample_id="granite-01", scan_index=1))
    assert path.read_bytes() == before
    with pytest.raises(DatabaseError, match="sample granite-01 is C6S1M1P2X1 in the database, not C5S1M1P2X1"):
        db.add(make_scan(9, label="C5S1M1P2X1", sample_id="granite-01", scan_index=3))
    assert db.check().ok


def test_check_reports_missing_changed_and_unknown_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    report = db.check()
    assert report.ok and report.checked == 16
    scans = tmp_path / "scans"
    (scans / "C6S1M1P2X1/granite-01/granite-01-001_macro.png").unlink()
    mat = scans / "C6S1M1P3X1/granite-02/granite-02-001.mat"
    data = bytearray(mat.read_bytes())
    data[-1] ^= 0xFF
    mat.write_bytes(bytes(data))
    (scans / "stray.txt").write_text("?")
    report = db.check()
    assert report.missing == ["scans/C6S1M1P2X1/granite-01/granite-01-001_macro.png"]
    assert report.changed == ["scans/C6S1M1P3X1/granite-02/granite-02-001.mat"]
    assert report.unknown == ["scans/stray.txt"] and not report.ok


def test_rebuild_recreates_the_catalog_from_files_alone(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    db.store_features("abc", "1", {"x": 1.0})
    before = [dataclasses.replace(r, added="") for r in db.records()]
    db.close()
    for name in ("catalog.sqlite", "catalog.sqlite-wal", "catalog.sqlite-shm"):
        (tmp_path / name).unlink(missing_ok=True)
    fresh = Database(tmp_path)
    assert len(fresh) == 0
    report = fresh.rebuild()
    assert report.scans == 4 and report.skipped == []
    assert [dataclasses.replace(r, added="") for r in fresh.records()] == before
    assert fresh.check().ok


def test_rebuild_replaces_a_corrupt_catalog_and_skips_bad_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    db.close()
    (tmp_path / "catalog.sqlite").write_bytes(b"not sqlite at all " * 500)
    for name in ("catalog.sqlite-wal", "catalog.sqlite-shm"):
        (tmp_path / name).unlink(missing_ok=True)
    (tmp_path / "scans/C9S1M1P1X1/x/x-001.mat").parent.mkdir(parents=True)
    (tmp_path / "scans/C9S1M1P1X1/x/x-001.mat").write_bytes(b"MATLAB 5.0 truncated")
    broken = Database(tmp_path)
    with pytest.raises(DatabaseError, match="catalog is unreadable.*texplorer db rebuild"):
        broken.records()
    report = broken.rebuild()
    assert report.scans == 4
    assert len(report.skipped) == 1 and report.skipped[0].startswith("scans/C9S1M1P1X1/x/x-001.mat: not a readable")
    assert any(p.name.startswith("catalog.sqlite.broken-") for p in tmp_path.iterdir())
    assert len(broken) == 4


def test_feature_cache_round_trips_nan(tmp_path):
    db = Database(tmp_path)
    assert db.cached_features("h", "1") is None
    db.store_features("h", "1", {"a": 1.5, "b": float("nan")})
    values = db.cached_features("h", "1")
    assert values["a"] == 1.5 and values["b"] != values["b"]
    assert db.cached_features("h", "2") is None


def test_opening_a_missing_database_without_create_is_a_clear_error(tmp_path):
    with pytest.raises(DatabaseError, match="nothing: no texplorer database here"):
        Database(tmp_path / "nothing", create=False)
    # A folder that is not a database is refused and left as it was; one with scans/ is a database
    # whose catalog can be rebuilt.
    (tmp_path / "other").mkdir()
    with pytest.raises(DatabaseError, match="other: no texplorer database here"):
        Database(tmp_path / "other", create=False)
    assert list((tmp_path / "other").iterdir()) == []
    (tmp_path / "other" / "scans").mkdir()
    assert len(Database(tmp_path / "other", create=False)) == 0


def test_readers_work_while_a_writer_adds(tmp_path):
    db = Database(tmp_path)
    db.add(make_scan(0, sample_id="s-00", images=False))
    errors: list[BaseException] = []
    counts: list[list[int]] = [[], []]
    stop = threading.Event()

    def read(seen: list[int]) -> None:
        reader = Database(tmp_path)
        try:
            while not stop.is_set():
                records = reader.records()
                seen.append(len(records))
                for record in records[-2:]:
                    reader.get(record.scan_id, images=False)
        except BaseException as exc:  # reported to the main thread
            errors.append(exc)
        finally:
            reader.close()

    threads = [threading.Thread(target=read, args=(seen,)) for seen in counts]
    for thread in threads:
        thread.start()
    for i in range(1, 15):
        db.add(make_scan(i, sample_id=f"s-{i:02d}", images=False))
        # Each reader reads at least once between two adds, so reads and writes really interleave,
        # however loaded the machine is.
        before = [len(seen) for seen in counts]
        deadline = time.monotonic() + 30
        while any(len(seen) <= n for seen, n in zip(counts, before, strict=True)) and not errors:
            assert time.monotonic() < deadline, "a reader made no progress while the writer was adding"
            time.sleep(0.001)
    stop.set()
    for thread in threads:
        thread.join()
    assert not errors, errors
    for seen in counts:  # each reader saw the catalog grow, never shrink or break
        assert len(seen) >= 14 and seen == sorted(seen) and seen[0] >= 1 and seen[-1] == 15
    assert len(db) == 15


WRITER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {tests!r})
    from conftest import make_scan
    from scanner.database import Database
    db = Database({root!r})
    start = int(sys.argv[1])
    for i in range(start, start + 1000):
        db.add(make_scan(i, sample_id=f"s-{{i:04d}}", image_shape=(200, 200), seconds=0.5))
        print(f"s-{{i:04d}}-001", flush=True)
""")


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL of a subprocess is POSIX-only")
def test_a_writer_killed_at_random_moments_never_corrupts_the_catalog(tmp_path):
    root = tmp_path / "db"
    Database(root).close()
    script = tmp_path / "writer.py"
    script.write_text(WRITER.format(tests=str(Path(__file__).parent), root=str(root)))
    rng = random.Random(1234)
    committed: set[str] = set()
    next_index = 0
    for _ in range(12):
        writer = subprocess.Popen([sys.executable, str(script), str(next_index)], stdout=subprocess.PIPE, text=True)
        time.sleep(rng.uniform(0.6, 2.0))  # interpreter start-up is ~0.5 s; kills land inside add()
        os.kill(writer.pid, signal.SIGKILL)
        out, _ = writer.communicate()
        acknowledged = set(out.split())
        committed |= acknowledged
        next_index += 1000

        db = Database(root)
        with sqlite3.connect(root / "catalog.sqlite") as conn:
            assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        ids = {r.scan_id for r in db.records()}
        assert committed <= ids, "an acknowledged scan was lost"
        for record in db.records():
            for entry in db.files(record.scan_id):
                path = root / entry.path
                assert path.is_file(), f"catalog row points to missing {entry.path}"
                assert sha256_file(path) == entry.sha256, f"catalog row points to partial {entry.path}"
        committed = ids
        report = db.check()
        assert not report.missing and not report.changed
        db.close()
    assert len(committed) >= 5, "the writer never got far enough to test anything"
    # An interrupted scan can simply be added again: its leftover files are overwritten.
    db = Database(root)
    for i in range(0, next_index, 1000):
        for k in range(i, i + 1000):
            if f"s-{k:04d}-001" not in committed:
                db.add(make_scan(k, sample_id=f"s-{k:04d}", image_shape=(200, 200), seconds=0.5))
                break
    assert not db.check().missing


def test_label_prefix_stops_at_the_class_boundary(tmp_path):
    db = Database(tmp_path)
    db.add(make_scan(0, label="C6S1M1P2X1", sample_id="a", images=False))
    db.add(make_scan(1, label="C60S1M1P2X1", sample_id="b", images=False))
    db.add(make_scan(2, label="C6S12M1P2X1", sample_id="c", images=False))
    assert sorted(r.sample_id for r in db.records(label="C6")) == ["a", "c"]
    assert [r.sample_id for r in db.records(label="C6S1")] == ["a"]
    assert [r.sample_id for r in db.records(label="C6S1M1P2X1")] == ["a"]
    assert [r.sample_id for r in db.records(label="C60")] == ["b"]
