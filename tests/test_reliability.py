"""Faults and hostile input on the surfaces beside the storage: worker processes whose parent dies, the
feature cache against changed files and changed code, the web app's extraction under concurrent requests."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
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
