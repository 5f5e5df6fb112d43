"""The thread limits of extraction (scanner.runtime.threads): counted across the threads that extract at once, and safe
to fork from while other threads take them (also scanner.runtime.memory's settings): the system tests (forked
processes)."""

from __future__ import annotations

import os
import time

import pytest
from unit.test_threads import (
    a_thread_holding_openblas,  # noqa: F401 (a fixture)
)

from scanner.runtime import memory, threads
from scanner.runtime.threads import one_blas_thread, one_thread_each


def _take_a_limit() -> None:
    with one_blas_thread():
        pass


@pytest.mark.skipif(not hasattr(os, "fork"), reason="forks")
@pytest.mark.parametrize(("module", "what_a_worker_does"), [(threads, _take_a_limit),
                                                            (memory, memory.keep_freed_memory)])
def test_a_child_forked_while_another_thread_holds_the_lock_does_not_wait_for_it(module, what_a_worker_does):
    # extract_many forks from the thread that runs it while another thread may hold one of these locks
    # (taking a thread limit; giving memory back after a 12 MP prediction, which takes milliseconds). The
    # child has only the forking thread, so a lock held at the fork would never be released there.
    with module._lock:
        pid = os.fork()
        if pid == 0:
            try:
                what_a_worker_does()
            finally:
                os._exit(0)
    deadline = time.monotonic() + 20
    while (done := os.waitpid(pid, os.WNOHANG)) == (0, 0) and time.monotonic() < deadline:
        time.sleep(0.01)
    if done == (0, 0):
        os.kill(pid, 9)
        os.waitpid(pid, 0)
    assert done != (0, 0) and os.waitstatus_to_exitcode(done[1]) == 0, "the child waited for the lock"


def _threads_after_extracting(scan) -> list[str]:
    from features import extract

    extract(scan)
    names = []
    for task in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{task}/comm") as comm:
            names.append(comm.read().strip())
    return names


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads in /proc")
@pytest.mark.parametrize("beside", [None, "a_thread_holding_openblas"])
def test_a_forked_worker_extracts_on_its_one_thread(request, beside):
    # extract_many forks its workers with BLAS at one thread. A worker that found BLAS on more and set the
    # limit itself started OpenBLAS's pool there, threads that spun on the cores the workers need. Seen in
    # the test suite when another thread controlled OpenBLAS (threadpoolctl >= 3.8), so the parent's limit
    # was silently ignored.
    import concurrent.futures

    from scanner.simulation import synthetic_scan

    if beside:
        request.getfixturevalue(beside)
    scan = synthetic_scan("oak-planed", seed=2)
    with one_thread_each(), concurrent.futures.ProcessPoolExecutor(max_workers=1) as pool:
        assert len(pool.submit(_threads_after_extracting, scan).result()) == 1
