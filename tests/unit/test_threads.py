"""The thread limits of extraction (scanner.runtime.threads): counted across the threads that extract at once, and
safe to fork from while other threads take them (also scanner.runtime.memory's settings)."""

from __future__ import annotations

import sys
import threading

import cv2
import pytest

from scanner.runtime import threads
from scanner.runtime.threads import one_blas_thread, one_thread_each, thread_pools


def _blas_threads() -> set[int]:
    """The threads of every process-wide pool: OpenBLAS's. OpenMP's limit (and OpenBLAS's on the OpenMP
    layer) is per thread, so another thread's limit does not show in this one; no feature calls OpenMP."""
    return {controller.num_threads for controller in thread_pools().lib_controllers
            if controller.internal_api == "openblas" and controller.threading_layer != "openmp"}


@pytest.fixture
def two_threads_each():
    """BLAS, OpenMP and OpenCV on two threads (also on a one-core machine), as found before the test after."""
    if not _blas_threads():
        pytest.skip("no OpenBLAS with a process-wide thread pool is loaded")
    opencv = cv2.getNumThreads()
    cv2.setNumThreads(2)
    with thread_pools().limit(limits=2):
        yield
    cv2.setNumThreads(opencv)


def _inside_until(block, entered: threading.Event, leave: threading.Event) -> threading.Thread:
    def run() -> None:
        with block():
            entered.set()
            leave.wait(20)

    thread = threading.Thread(target=run)
    thread.start()
    assert entered.wait(20)
    return thread


@pytest.mark.parametrize("block", [one_blas_thread, one_thread_each])
def test_a_thread_that_ends_its_block_leaves_the_limit_to_a_thread_still_inside(two_threads_each, block):
    # The web app extracts an export's batches in one thread and the operator's end-of-scan prediction in
    # another. With a limit per caller, the first to end restored two threads under the other one: its
    # remaining BLAS products ran on two threads (other last bits), or it forked workers with full pools.
    entered, leave = threading.Event(), threading.Event()
    other = _inside_until(block, entered, leave)
    try:
        with block():
            assert _blas_threads() == {1}
            leave.set()
            other.join(20)
            assert not other.is_alive()
            assert _blas_threads() == {1}
            if block is one_thread_each:
                assert cv2.getNumThreads() == 1
    finally:
        leave.set()
        other.join(20)
    assert _blas_threads() == {2} and cv2.getNumThreads() == 2


def test_blocks_nest_and_restore_what_they_found(two_threads_each):
    with one_thread_each():
        with one_blas_thread():
            assert _blas_threads() == {1} and cv2.getNumThreads() == 1
        assert _blas_threads() == {1} and cv2.getNumThreads() == 1
    assert _blas_threads() == {2} and cv2.getNumThreads() == 2
    assert threads._blas["users"] == 0 and threads._cv2["users"] == 0


@pytest.fixture
def a_thread_holding_openblas():
    """A live thread that set BLAS and OpenMP to two threads outside a ``with`` block (as a server's thread
    may have): with threadpoolctl >= 3.8 it keeps control of OpenBLAS's pool while it lives, and other
    threads' limits were silently ignored."""
    if not _blas_threads():
        pytest.skip("no OpenBLAS with a process-wide thread pool is loaded")
    holding, leave = threading.Event(), threading.Event()

    def hold() -> None:
        limiter = thread_pools().limit(limits=2)
        holding.set()
        leave.wait(60)
        limiter.restore_original_limits()
        threads._release_openblas_control()

    opencv = cv2.getNumThreads()
    cv2.setNumThreads(2)
    thread = threading.Thread(target=hold, daemon=True)
    thread.start()
    assert holding.wait(20)
    yield
    leave.set()
    thread.join(20)
    cv2.setNumThreads(opencv)


def test_the_limit_holds_while_another_thread_controls_openblas(a_thread_holding_openblas):
    with one_blas_thread():
        assert _blas_threads() == {1}
    assert _blas_threads() == {2}


def test_the_pools_are_found_again_after_an_import(monkeypatch):
    # taxonomy.learning.evaluation imports scikit-learn, whose OpenMP pool was missed by a controller found once
    # when features was imported, so the fits' limit did not cover it.
    import types

    assert thread_pools() is thread_pools()
    before = thread_pools()
    monkeypatch.setitem(sys.modules, "a_module_imported_since", types.ModuleType("a_module_imported_since"))
    assert thread_pools() is not before
