"""Faults and hostile input on the surfaces beside the storage: worker processes whose parent dies, the
feature cache against changed files and changed code, the web app's extraction under concurrent requests."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import warnings
from pathlib import Path

import pytest

from scanner.runtime.processes import PARENT_POLL_S

ROOT = Path(__file__).resolve().parents[2]

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet collected by init, does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _env() -> dict[str, str]:
    """This process's environment with this tree first on the path."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


def _python(code: str, **kwargs) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], env=_env(), text=True, **kwargs)


# -- 1. no orphaned workers --------------------------------------------------------------------------------

EXTRACT_AND_WAIT = """
import multiprocessing, sys, time

if __name__ == "__main__":
    import features
    from scanner.runtime import local
    from scanner.simulation import synthetic_scan

    if sys.argv[1:] == ["server"]:
        local.start_workers_from_a_server()
    scans = [synthetic_scan(m, seed=1, image_size=(96, 96), sample_id=f"{m}-1") for m in ("oak-planed", "float-glass")]
    space = features.extract_many(scans, workers=2, progress=False)
    assert not space.failed, space.failed
    print(" ".join(str(p.pid) for p in multiprocessing.active_children()), flush=True)
    time.sleep(600)
"""


@linux_only
@pytest.mark.parametrize("started", ["forked", "server"])
def test_workers_end_within_a_bound_when_their_parent_is_killed(tmp_path, started):
    script = tmp_path / "extract_and_wait.py"  # a file: the fork server imports the main module by path
    script.write_text(EXTRACT_AND_WAIT)
    parent = subprocess.Popen([sys.executable, str(script), started], env=_env(), stdout=subprocess.PIPE, text=True)
    try:
        workers = [int(pid) for pid in parent.stdout.readline().split()]
    finally:
        parent.send_signal(signal.SIGKILL)  # as the out-of-memory killer does: no clean-up in the parent
        parent.wait()
    assert len(workers) == 2
    deadline = time.monotonic() + 10 * PARENT_POLL_S + 5  # the poll, and a worker's exit under load
    while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    survivors = [pid for pid in workers if _alive(pid)]
    for pid in survivors:  # leave nothing behind even when the test fails
        os.kill(pid, signal.SIGKILL)
    assert not survivors, f"workers {survivors} outlived their killed parent"


# -- 2. the feature cache never serves values for other bytes ---------------------------------------------

def _database_with_one_scan(tmp_path: Path, scan):
    from scanner.storage.database import Database

    db = Database(tmp_path / "db")
    db.add(scan)
    record = db.records()[0]
    photo = next(db.root / e.path for e in db.files(record.scan_id) if e.path.endswith(".png"))
    return db, record, photo


def _other_photo(path: Path) -> bytes:
    """A valid PNG of the same size as ``path`` with other pixels."""
    import cv2
    import numpy as np

    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    ok, encoded = cv2.imencode(".png", np.ascontiguousarray(255 - image))
    assert ok
    return encoded.tobytes()


def test_a_file_changed_after_its_features_were_cached_is_named_not_served(tmp_path):
    from conftest import make_scan

    from scanner.workflows.database import extract_database

    db, record, photo = _database_with_one_scan(tmp_path, make_scan(1))
    first = extract_database(db, workers=1, progress=False)
    assert not first.failed
    photo.write_bytes(_other_photo(photo))
    again = extract_database(db, workers=1, progress=False)
    assert len(again) == 0 and len(again.failed) == 1
    scan_id, reason = again.failed[0]
    assert scan_id == record.scan_id and photo.name in reason and "db check" in reason and "\n" not in reason


def test_a_changed_file_without_a_cached_row_is_not_extracted_under_the_catalogued_hash(tmp_path):
    import numpy as np
    from conftest import make_scan

    from scanner.workflows.database import extract_database

    db, record, photo = _database_with_one_scan(tmp_path, make_scan(2))
    original = photo.read_bytes()
    photo.write_bytes(_other_photo(photo))
    changed = extract_database(db, workers=1, progress=False)
    assert len(changed) == 0 and photo.name in changed.failed[0][1]
    assert db._conn.execute("SELECT COUNT(*) FROM feature_cache").fetchone()[0] == 0  # nothing poisoned
    photo.write_bytes(original)  # restored: db check is clean, and the values are the original bytes'
    assert db.check().ok
    restored = extract_database(db, workers=1, progress=False)
    from features import extract

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the hand-built scan lacks the raw channels
        expected = extract(db.get(record.scan_id))
    np.testing.assert_array_equal(restored.X[0], np.array(list(expected.values())))


def test_a_changed_file_is_named_by_the_workers_too(tmp_path):
    from conftest import make_scan

    from scanner.workflows.database import extract_database

    db, record, photo = _database_with_one_scan(tmp_path, make_scan(3))
    db.add(make_scan(4, sample_id="granite-02"))
    photo.write_bytes(_other_photo(photo))
    space = extract_database(db, workers=2, progress=False)
    assert len(space) == 1 and [s for s, _ in space.failed] == [record.scan_id]
    assert photo.name in space.failed[0][1]


def test_the_code_version_is_that_of_the_code_the_process_imported(tmp_path, monkeypatch):
    from features import REGISTRY, code_version

    module = tmp_path / "late_family.py"
    module.write_text("from features.registry import Family\n"
                      "def compute(prepared):\n    return {'late.one': 1.0}\n"
                      "FAMILY = Family('late', 'Late', ('late.one',), compute)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import late_family

    version_in_a_fresh_process = (f"import sys; sys.path.insert(0, {str(tmp_path)!r}); import late_family, "
                                  "features; features.REGISTRY.register(late_family.FAMILY); "
                                  "print(features.code_version())")
    REGISTRY.register(late_family.FAMILY)
    try:
        imported = _python(version_in_a_fresh_process, stdout=subprocess.PIPE).communicate(timeout=120)[0].strip()
        module.write_text(module.read_text().replace("1.0", "2.0"))  # updated on disk, not in this process
        updated = _python(version_in_a_fresh_process, stdout=subprocess.PIPE).communicate(timeout=120)[0].strip()
        assert updated != imported and code_version() == imported  # asked for the first time after the update
    finally:
        REGISTRY.unregister("late")
        sys.modules.pop("late_family", None)


CONCURRENT_FIRST_CALLS = """
import sys, threading
sys.setswitchinterval(1e-6)  # threads interleave as often as they can
from features import registry
barrier = threading.Barrier(16)
answers, errors = [], []

def ask():
    barrier.wait()
    try:
        answers.append(registry.REGISTRY.code_version("features.extraction", "scanner.workflows", "gui.app"))
    except Exception as exc:
        errors.append(repr(exc))

threads = [threading.Thread(target=ask) for _ in range(16)]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
print(len(set(answers)), len(answers), errors)
"""


def test_the_code_version_is_computed_once_when_threads_ask_at_once():
    # Modules no registration read yet (the web app's): every thread parses them at once without the lock.
    for _ in range(3):
        process = _python(CONCURRENT_FIRST_CALLS, stdout=subprocess.PIPE)
        assert process.communicate(timeout=120)[0].strip() == "1 16 []"


# -- 7, 8. the web app under concurrent feature requests ---------------------------------------------------

def _serve(db: Path) -> tuple[subprocess.Popen, str]:
    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "serve", "--db", str(db), "--port", "0"],
                               env=_env(), stderr=subprocess.PIPE, text=True)
    for line in process.stderr:
        if " at http://" in line:
            return process, line.split(" at ", 1)[1].split("/ ", 1)[0]
    process.kill()
    raise AssertionError("the server printed no address")


def _get(url: str) -> int:
    import urllib.error
    import urllib.request

    try:
        with urllib.request.urlopen(url, timeout=300) as answer:
            answer.read()
            return answer.status
    except urllib.error.HTTPError as exc:
        return exc.code


@linux_only
def test_concurrent_feature_requests_at_a_fresh_server_all_answer(tmp_path):
    import concurrent.futures
    import sqlite3

    from scanner.simulation.database import synthetic_database

    db = synthetic_database(tmp_path / "db", materials=["oak-planed", "float-glass"], scans_per_material=3,
                            image_size=(96, 96), progress=False, workers=1)
    ids = [record.scan_id for record in db.records()]
    db.close()
    for _ in range(4):  # each round a fresh server (first calls) and an empty feature cache (workers fork)
        with sqlite3.connect(tmp_path / "db" / "catalog.sqlite") as conn:
            conn.execute("DELETE FROM feature_cache")
        process, url = _serve(tmp_path / "db")
        try:
            paths = ["/db/export/features.csv"] * 3 + [f"/db/scan/{scan_id}" for scan_id in ids[:3]]
            with concurrent.futures.ThreadPoolExecutor(len(paths)) as requests:
                answers = list(requests.map(_get, [url + path for path in paths]))
            assert answers == [200] * len(paths)
            process.send_signal(signal.SIGTERM)
            assert process.wait(60) == 0 and "texplorer: stopped" in process.stderr.read()
        finally:
            process.kill()
            process.wait()


def _descendants(pid: int) -> set[int]:
    """Every running process below ``pid`` (children, their children, ...), from /proc."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
        except (OSError, IndexError, ValueError):
            continue
    found, frontier = set(), {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return {child for child in found if _alive(child)}


@linux_only
def test_sigterm_during_an_export_leaves_no_worker_and_no_bundle(tmp_path):
    """``texplorer serve`` stopped by SIGTERM while an export job extracts features: the server stops as on
    Ctrl-C, every process it started (the fork server and its extraction workers) ends, and the job's folder
    in $TMPDIR is deleted."""
    import http.cookiejar
    import json
    import re
    import urllib.parse
    import urllib.request

    from scanner.simulation.database import synthetic_database

    synthetic_database(tmp_path / "db", materials=["oak-planed", "float-glass", "mild-steel-brushed"],
                       scans_per_material=4, image_size=(320, 320), progress=False, workers=1).close()
    # A short $TMPDIR: the fork server's socket lives in it, and a Unix socket's path holds at most 107 bytes
    # (pytest's tmp_path under xdist is already 70 long).
    scratch = Path(tempfile.mkdtemp(prefix="tx-", dir="/tmp"))
    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "serve", "--db", str(tmp_path / "db"),
                                "--port", "0"], env={**_env(), "TMPDIR": str(scratch)}, stderr=subprocess.PIPE,
                               text=True)
    try:
        printed = []
        for line in process.stderr:
            printed.append(line)
            if " at http://" in line:
                url = line.split(" at ", 1)[1].split("/ ", 1)[0]
                break
        else:
            raise AssertionError(f"the server printed no address: {''.join(printed)}")
        browser = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))
        with browser.open(f"{url}/db/", timeout=120) as page:
            token = re.search(r'name="csrf_token" value="([^"]+)"', page.read().decode()).group(1)
        form = urllib.parse.urlencode({"csrf_token": token, "label": "", "session": "", "license": "CC0-1.0"}).encode()
        with browser.open(f"{url}/db/export", data=form, timeout=120) as page:  # redirected to the job's page
            job = page.url.rstrip("/").rsplit("/", 1)[1]
        deadline = time.monotonic() + 120
        while True:
            with browser.open(f"{url}/db/export/{job}/status", timeout=120) as answer:
                status = json.loads(answer.read())
            workers = _descendants(process.pid)
            if status["phase"] == "features" and len(workers) >= 2 and list(scratch.glob("texplorer-export-*")):
                break
            assert status["running"] and time.monotonic() < deadline, (status, workers)
            time.sleep(0.05)
        process.send_signal(signal.SIGTERM)
        assert process.wait(60) == 0 and "texplorer: stopped" in process.stderr.read()
        deadline = time.monotonic() + 5  # workers watch their parent and end within 0.5 s of it
        while {pid for pid in workers if _alive(pid)} and time.monotonic() < deadline:
            time.sleep(0.05)
        assert {pid for pid in workers if _alive(pid)} == set()
        assert list(scratch.iterdir()) == []
    finally:
        process.kill()
        process.wait()
        shutil.rmtree(scratch, ignore_errors=True)


@linux_only
def test_serve_under_a_tmpdir_too_long_for_a_socket_says_so_in_one_line(tmp_path):
    long = tmp_path / ("t" * max(1, 100 - len(str(tmp_path))))
    long.mkdir()
    done = subprocess.run([sys.executable, "-m", "scanner.cli", "serve", "--db", str(tmp_path / "db"), "--port",
                           "0"], env={**_env(), "TMPDIR": str(long)}, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and len(done.stderr.strip().splitlines()) == 1
    assert "set TMPDIR to a shorter folder" in done.stderr and str(long) in done.stderr


# -- 3, 9. one pixel limit that cannot be dodged, and decoding bounded in time ------------------------------

def progressive_jpeg(width: int, height: int, repeats: int = 0, seed: int = 0) -> bytes:
    """A progressive JPEG of noise whose last scan is repeated ``repeats`` more times before the end."""
    import cv2
    import numpy as np

    image = np.random.default_rng(seed).integers(0, 256, (height, width, 3), dtype=np.uint8)
    ok, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_PROGRESSIVE, 1, cv2.IMWRITE_JPEG_QUALITY, 50])
    assert ok
    data = encoded.tobytes()
    last = data.rindex(b"\xff\xda")
    return data[:-2] + data[last:-2] * repeats + b"\xff\xd9"


def tiff(*pages: list[tuple[int, int, int]], loop: bool = False) -> bytes:
    """A little-endian TIFF whose pages are directories of ``(tag, type, value)`` entries (1 value each),
    each with a strip of 16 zero bytes; ``loop``: the last directory points back to the first."""
    import struct

    out = bytearray(b"II*\x00" + struct.pack("<I", 8))
    strip = 0
    for number, entries in enumerate(pages):
        entries = [*entries, (259, 3, 1), (262, 3, 1), (273, 4, 0), (277, 3, 1), (278, 4, 1 << 30), (279, 4, 16)]
        start = len(out)
        size = 2 + 12 * len(entries) + 4
        strip = start + size
        out += struct.pack("<H", len(entries))
        for tag, kind, value in entries:
            value = strip if tag == 273 else value
            out += struct.pack("<HHI", tag, kind, 1) + struct.pack("<I" if kind == 4 else "<HH", *(
                (value,) if kind == 4 else (value, 0)))
        last = number == len(pages) - 1
        out += struct.pack("<I", 8 if last and loop else 0 if last else strip + 16)
        out += bytes(16)
    return bytes(out)


def hostile_images() -> dict[str, tuple[bytes, str]]:
    """Seeded hostile images per format, each with a word its refusal names."""
    from conftest import png_bomb

    sides = [(256, 4, 10), (257, 4, 10)]
    return {
        "png-bomb": (png_bomb(20000, 20000), "pixels"),
        "jpeg-scans": (progressive_jpeg(640, 480, repeats=40), "scans"),
        "tiff-width-twice": (tiff([(256, 4, 20000), (256, 4, 10), (257, 4, 20000), (257, 4, 10)]), "twice"),
        "tiff-large-second-page": (tiff(sides, [(256, 4, 20000), (257, 4, 20000)]), "pixels"),
        "tiff-side-as-two-values": (tiff([(256, 4, 10), (257, 12, 10)]), "whole number"),
        "tiff-loop": (tiff(sides, sides, loop=True), "loop"),
        "tiff-many-pages": (tiff(*[sides] * 17), "pages"),
    }


def test_every_hostile_image_is_refused_from_its_header_in_one_line():
    from scanner.photo import PhotoError, check_pixels

    for case, (data, word) in hostile_images().items():
        with pytest.raises(PhotoError) as refused:
            check_pixels(data, name=case)
        message = str(refused.value)
        assert message.startswith(f"{case}: ") and word in message and "\n" not in message, case


def test_a_jpeg_within_the_scan_limit_decodes():
    from scanner.photo import MAX_JPEG_SCANS, decode, jpeg_scans

    plain = progressive_jpeg(64, 48)
    assert 1 < jpeg_scans(plain) <= MAX_JPEG_SCANS
    assert decode(plain).shape == (48, 64, 3)
    assert jpeg_scans(progressive_jpeg(64, 48, repeats=MAX_JPEG_SCANS - jpeg_scans(plain))) == MAX_JPEG_SCANS


def test_the_pages_of_a_plain_tiff_are_read_as_its_decoder_reads_them(tmp_path):
    import cv2
    import numpy as np
    import tifffile

    from scanner.photo import image_size, tiff_pages

    path = tmp_path / "two.tif"
    with tifffile.TiffWriter(path) as writer:
        writer.write(np.zeros((30, 40), np.uint8))
        writer.write(np.zeros((50, 20), np.uint8))
    data = path.read_bytes()
    assert tiff_pages(data) == [(40, 30), (20, 50)] and image_size(data) == ("TIFF", 40, 50)
    assert cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED).shape == (30, 40)



# -- 4, 5. ingest: bounded bridging, one bad file of each kind skipped by name ------------------------------

INGEST_MAPPING = """
[[files]]
glob = "**/*.csv"
time_column = "t"
[[files.channels]]
name = "pdc"
role = "pressure_dc"
columns = "p"
[[files]]
glob = "**/*.wav"
[[files.channels]]
name = "audio"
role = "audio"
[[files]]
glob = "**/*.np[yz]"
rate = 100.0
[[files.channels]]
name = "v"
role = "vibration"
"""


def _good_csv(path: Path, n: int = 50) -> None:
    path.write_text("t,p\n" + "".join(f"{i / 100},{i}\n" for i in range(n)))


def hostile_recordings(folder: Path) -> dict[str, str]:
    """One hostile file of each kind written into ``folder``, with a word its skipped line names."""
    import zipfile

    import numpy as np

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "jump.csv").write_text("t,p\n0,1\n0.01,2\n0.02,3\n4000000000,4\n4000000000.01,5\n")
    (folder / "nudge.csv").write_text("t,p\n0,1\n0.01,2\n0.02,3\n50000000,4\n50000000.01,5\n")  # 5e9 samples
    (folder / "empty_rate.wav").write_bytes(
        b"RIFF\x24\x00\x00\x00WAVEfmt \x10\x00\x00\x00\x01\x00\x00\x00\x44\xac\x00\x00\x88\x58\x01\x00"
        b"\x02\x00\x10\x00data\x00\x00\x00\x00")  # no channels: the standard library divides by zero
    np.save(folder / "objects.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    (folder / "cut.npz").write_bytes(b"PK\x03\x04" + bytes(30))
    with zipfile.ZipFile(folder / "short_header.npz", "w") as archive:
        archive.writestr("v.npy", b"\x93NUMPY\x01\x00\xff\xff{'descr': '<f8', 'fortran_order': False, }")
    return {"jump": "bridge", "nudge": "bridge", "empty_rate": "empty_rate.wav", "objects": "objects.npy",
            "cut": "cut.npz", "short_header": "short_header.npz"}


def test_one_hostile_file_of_each_kind_is_named_and_skipped_and_the_good_one_stored(tmp_path, capsys):
    from scanner.cli import main
    from scanner.storage import ingest

    lab = tmp_path / "lab" / "cork"
    expected = hostile_recordings(lab)
    _good_csv(lab / "good.csv")
    (tmp_path / "map.toml").write_text(INGEST_MAPPING)
    code = main(["ingest", str(tmp_path / "lab"), "--mapping", str(tmp_path / "map.toml"), "--db",
                 str(tmp_path / "db"), "--name", "lab"])
    out = capsys.readouterr().out.splitlines()
    assert code == 3
    stored = ingest.load_recordings(ingest.set_folder(tmp_path / "db", "lab"))
    assert [r.name for r in stored] == ["good"] and stored[0].channels["pdc"].data.size == 50
    for name, word in expected.items():
        lines = [line for line in out if f"cork/{name}" in line]
        assert lines and any(word in line for line in lines), (name, out)


def _gapped_stream(path: Path, rate: float, seconds: float, gaps: int, gap_s: tuple[float, float], seed: int) -> int:
    """A timestamped CSV shaped like a USB force sensor's log: ``rate`` Hz over ``seconds`` with ``gaps``
    pauses of ``gap_s`` seconds each (uniform); returns its number of rows."""
    import numpy as np

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, seconds, 1.0 / rate)
    for start in np.sort(rng.choice(t.size - 1, size=gaps, replace=False))[::-1]:
        t[start + 1:] += rng.uniform(*gap_s)  # every later sample moves back by the pause
    path.write_text("t,p\n" + "".join(f"{a:.6f},{np.sin(a):.6f}\n" for a in t))
    return int(t.size)


def test_a_stream_bridged_many_times_over_is_kept_and_a_clock_jump_refused(tmp_path):
    from scanner.storage import ingest
    from scanner.storage.ingest.alignment import MAX_BRIDGED_BYTES

    lab = tmp_path / "lab" / "cork"
    lab.mkdir(parents=True)
    # 150 Hz for 6 s of samples with 70 pauses of 0.6-0.9 s: ~7,900 grid samples from 900 real ones, bridged
    # nine times over (the old rule refused more than once), but a few kB: kept, with a note.
    real = _gapped_stream(lab / "usb.csv", 150.0, 6.0, 70, (0.6, 0.9), seed=1)
    # A jump of the clock: 40 real samples at 100 Hz, then one step of 5e7 s (5e9 samples, 40 GB).
    t = [i / 100 for i in range(20)] + [5e7 + i / 100 for i in range(20)]
    (lab / "jump.csv").write_text("t,p\n" + "".join(f"{a!r},1.0\n" for a in t))
    report = ingest.ingest(lab.parent, ingest.parse_mapping(INGEST_MAPPING, "lab"))
    assert [r.name for r in report.recordings] == ["usb"]
    kept = report.recordings[0]
    info = kept.meta["time_base"]["channels"]["pdc"]
    assert info["gaps"] == 70 and kept.channels["pdc"].data.size > 8 * real
    assert any(note.kind == "gap" and "usb.csv" in note.text for note in report.notes)
    assert len(report.skipped) == 1 and report.skipped[0].startswith("cork/jump: recording skipped: jump.csv")
    assert "5e+07 s" in report.skipped[0] and f"{MAX_BRIDGED_BYTES >> 20} MiB" in report.skipped[0]


def test_the_bridging_bound_is_in_bytes_per_channel_not_relative_to_the_stream(tmp_path, monkeypatch):
    from scanner.storage import ingest
    from scanner.storage.ingest import alignment

    lab = tmp_path / "lab" / "cork"
    lab.mkdir(parents=True)
    monkeypatch.setattr(alignment, "MAX_BRIDGED_BYTES", 8 * 5000)  # the rule, at a size a test can hold
    limit = alignment.MAX_BRIDGED_BYTES // 8  # samples of one column the gaps may add: 125x the 40 real ones
    for name, missing in (("within", limit - 10), ("beyond", limit + 10)):
        t = [i / 100 for i in range(20)] + [(i + missing) / 100 for i in range(20, 40)]
        (lab / f"{name}.csv").write_text("t,p\n" + "".join(f"{a!r},1.0\n" for a in t))
    report = ingest.ingest(lab.parent, ingest.parse_mapping(INGEST_MAPPING, "lab"))
    assert [r.name for r in report.recordings] == ["within"]
    assert report.recordings[0].channels["pdc"].data.size == 40 + limit - 10
    assert len(report.skipped) == 1 and report.skipped[0].startswith("cork/beyond: recording skipped: beyond.csv")


# -- 6. a set replaced crash-safe ----------------------------------------------------------------------------

KILLED_STORE = """
import os, signal, sys
from pathlib import Path
import numpy as np
from scanner.scan import Recording, Trace
from scanner.storage import ingest

db, kill_at = sys.argv[1], int(sys.argv[2])
renames = {"count": 0}
replace = os.replace

def replace_then_maybe_die(source, target):
    replace(source, target)
    renames["count"] += 1
    if renames["count"] == kill_at:
        os.kill(os.getpid(), signal.SIGKILL)

os.replace = replace_then_maybe_die
new = [Recording(f"new{i}", {"v": Trace(np.full(8, 2.0), 100.0, "V")}, {"vibration": "v"}, "cork") for i in range(3)]
ingest.store_recordings(db, "lab", new, replace=True)
"""


@linux_only
def test_a_replacement_killed_after_any_rename_is_rolled_forward_or_back_never_lost(tmp_path):
    import numpy as np

    from scanner.scan import Recording, Trace
    from scanner.storage import ingest
    from scanner.storage.database import Database

    old = [Recording("old", {"v": Trace(np.full(8, 1.0), 100.0, "V")}, {"vibration": "v"}, "cork")]
    # Renames 1-3 put each new recording file in place in the staging folder, 4-6 swap (staged -> new, set
    # -> old, new -> set); 7 never comes.
    for kill_at in range(1, 8):
        db = tmp_path / f"db{kill_at}"
        Database(db).close()
        ingest.store_recordings(db, "lab", old)
        process = subprocess.run(
            [sys.executable, "-c", KILLED_STORE, str(db), str(kill_at)], capture_output=True, text=True,
            env=_env(), timeout=120)
        killed = process.returncode == -signal.SIGKILL
        assert killed == (kill_at < 7), process.stderr
        with Database(db) as database:
            leftovers = database.check().leftovers
            assert bool(leftovers) == killed and all(p.startswith("recordings/.lab.") for p in leftovers)
            repaired = database.repair()
            assert database.check().leftovers == [] and bool(repaired) == killed
        # Killed before the new set was complete: the old one stays; after: the replacement is finished.
        expected = ["old"] if kill_at <= 3 else ["new0", "new1", "new2"]
        assert [r.name for r in ingest.load_recordings(ingest.set_folder(db, "lab"))] == expected
        assert sorted(p.name for p in (db / "recordings").iterdir() if p.name != ".swap.lock") == ["lab"]


# -- 10. ingest memory bounded: limits count the values as held, per format --------------------------------

def test_size_limits_count_the_values_as_held_after_conversion_for_every_format(tmp_path, monkeypatch):
    import numpy as np
    from scipy.io import wavfile

    from scanner.storage import ingest

    monkeypatch.setattr(ingest.readers, "MAX_ARRAY_BYTES", 8 * 1000)  # 1000 values as float64
    spec = ingest.FileMap(glob="*", suffix=None, format=None, channels=(ingest.ChannelMap("v", "vibration"),),
                          rate=100.0)
    np.save(tmp_path / "int8.npy", np.ones(1001, np.int8))  # 1001 bytes in the file, 8008 as held
    np.savez_compressed(tmp_path / "zeros.npz", v=np.zeros(1001, np.int8))
    wavfile.write(tmp_path / "sound.wav", 8000, np.zeros(1001, np.int16))
    (tmp_path / "table.csv").write_text("t,p\n" + "".join(f"{i},{i}\n" for i in range(501)))  # 1002 values
    for name in ("int8.npy", "zeros.npz", "sound.wav", "table.csv"):
        with pytest.raises(ingest.IngestError, match=rf"{name}: .*more than the 0 MB one file may hold"):
            ingest.read_file(tmp_path / name, spec)
    np.save(tmp_path / "fits.npy", np.ones(1000, np.int8))
    assert ingest.read_file(tmp_path / "fits.npy", spec)[0]["v"].data.size == 1000


def test_a_truncated_wav_is_named_not_imported_short(tmp_path):
    import numpy as np
    from scipy.io import wavfile

    from scanner.storage import ingest

    wavfile.write(tmp_path / "full.wav", 8000, np.arange(800, dtype=np.int16))
    data = (tmp_path / "full.wav").read_bytes()
    (tmp_path / "cut.wav").write_bytes(data[:len(data) // 2])
    spec = ingest.FileMap(glob="*", suffix=None, format=None, channels=(ingest.ChannelMap("a", "audio"),))
    assert ingest.read_file(tmp_path / "full.wav", spec)[0]["a"].data.size == 800
    with pytest.raises(ingest.IngestError, match="cut.wav: the WAV file is truncated"):
        ingest.read_file(tmp_path / "cut.wav", spec)


def test_a_table_is_read_as_before_line_by_line(tmp_path):
    from scanner.storage import ingest

    path = tmp_path / "t.csv"
    path.write_text("# comment\r\nx,y,\r\n1,2,\r\n\r\n3,nan,\r\n")
    names, values = ingest.read_table(path, ",", True)
    assert names == ["x", "y"] and values.shape == (2, 2) and values[1, 0] == 3.0 and values[1, 1] != values[1, 1]
    names, values = ingest.read_table(path, ",", False, skip_rows=1)
    assert names == ["0", "1"] and values.tolist()[0] == [1.0, 2.0]


HOSTILE_IMAGES_UNDER_A_LIMIT = """
import json, resource, sys, time
from pathlib import Path
sys.path.insert(0, sys.argv[1])
sys.path.insert(1, str(Path(sys.argv[1]).parent))  # conftest, which the corpus takes its PNG bomb from
from test_reliability import hostile_images
from scanner.photo import PhotoError, decode
from scanner.storage.ingest import IngestError, read_image

folder = Path(sys.argv[2])
corpus = hostile_images()  # made before the limit: making the cases is not what is measured
with open("/proc/self/status") as status:
    used = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
resource.setrlimit(resource.RLIMIT_AS, (used + (512 << 20), resource.RLIM_INFINITY))
for case, (data, _) in corpus.items():
    path = folder / (case + (".tif" if case.startswith("tiff") else ".img"))
    path.write_bytes(data)
    outcomes = []
    for read in (read_image, lambda p: decode(p.read_bytes(), p.name)):
        try:
            read(path)
            outcomes.append("decoded")
        except (IngestError, PhotoError):
            outcomes.append("refused")
        except BaseException as exc:
            outcomes.append(type(exc).__name__)
    print(json.dumps({"case": case, "outcomes": outcomes}), flush=True)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the address-space limit needs /proc and setrlimit")
def test_hostile_images_are_refused_by_ingest_and_load_within_a_memory_limit(tmp_path):
    import json

    here = str(ROOT / "tests" / "system")
    result = subprocess.run([sys.executable, "-c", HOSTILE_IMAGES_UNDER_A_LIMIT, here, str(tmp_path)],
                            capture_output=True, text=True, timeout=300, env=_env())
    lines = [json.loads(line) for line in result.stdout.splitlines()]
    assert [line["case"] for line in lines] == list(hostile_images()), result.stderr
    assert all(line["outcomes"] == ["refused", "refused"] for line in lines), lines
