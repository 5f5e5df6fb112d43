"""Faults and hostile input on the surfaces beside the storage: worker processes whose parent dies, the
feature cache against changed files and changed code, the web app's extraction under concurrent requests."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings
from pathlib import Path

import pytest

from scanner.processes import PARENT_POLL_S

ROOT = Path(__file__).resolve().parents[1]

linux_only = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet collected by init, does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _python(code: str, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-c", textwrap.dedent(code)], env=env, text=True, **kwargs)


# -- 1. no orphaned workers --------------------------------------------------------------------------------

EXTRACT_AND_WAIT = """
import multiprocessing, sys, time

if __name__ == "__main__":
    import features
    from scanner.simulation import synthetic_scan

    if sys.argv[1:] == ["server"]:
        features.start_workers_from_a_server()
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
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    parent = subprocess.Popen([sys.executable, str(script), started], env=env, stdout=subprocess.PIPE, text=True)
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

    from scanner.workflows import extract_database

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

    from scanner.workflows import extract_database

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

    from scanner.workflows import extract_database

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
