"""The thread pools of BLAS, OpenMP and OpenCV while scans are extracted: one thread, counted across threads.

Extraction limits them in two scopes:

- :func:`one_blas_thread` while one scan is extracted in this process (also a recording's windows, and
  an evaluation's fits, whose folds run side by side): a BLAS product's summation order depends on its
  thread count, so the last bits of a few features (Tamura contrast, MaCo, MaRG) would otherwise differ
  between machines with other core counts, and from a Dask worker's;
- :func:`one_thread_each` while worker processes are forked and run (OpenCV too): each worker inherits
  one thread per pool, as the workers already keep every core busy.

The limits are process-wide, and the web app extracts in several threads at once (an export job's batches
beside the operator's end-of-scan prediction). A limit taken and given back per caller would let the
first one to finish restore the pools while another is still extracting or forking: its remaining
products then ran on several threads (other last bits), or a worker was forked with a full BLAS pool,
which it started and spun on the cores the workers need. So the limits are counted: the first user sets
them, the last one restores what it found.

The first and the last user may be different threads. threadpoolctl lets only one thread at a time
set OpenBLAS's process-wide pool (the first that sets it, until it leaves a ``with`` block or ends) and
silently ignores the others, so a long-lived thread that once limited BLAS (a web server's) made every
other thread's limit a no-op. Each change here therefore releases that control before and after itself.

OpenMP's limit (and that of an OpenBLAS built on OpenMP) is per thread, so it holds in the first user's
thread only and is restored in the last user's (where the first user's thread keeps one OpenMP thread);
no feature calls into OpenMP (scikit-learn's fits do, in an evaluation's worker processes, each on its
own), and the wheels' OpenBLAS uses pthreads.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
from collections.abc import Callable, Iterator

import threadpoolctl
from threadpoolctl import ThreadpoolController

from scanner.lazy import library

cv2 = library("cv2")

_lock = threading.Lock()
_blas = {"users": 0, "limiter": None}
_cv2 = {"users": 0, "threads": None}


def _start_afresh_in_child() -> None:
    """A forked child has only the forking thread: a lock another thread held at the fork would stay held,
    and the parent's users are not the child's. Its own first extraction then finds one BLAS thread where
    the parent's limit took effect (extract_many's workers), and limits BLAS itself where it did not. Its
    OpenCV setting is left alone: a forked child must not reconfigure OpenCV's inherited thread pool."""
    global _lock
    _lock = threading.Lock()
    _blas.update(users=0, limiter=None)
    _cv2.update(users=0, threads=None)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_start_afresh_in_child)


def thread_pools() -> ThreadpoolController:
    """The thread pools (BLAS, OpenMP) loaded in this process, found again only when modules were imported
    since: looking them up walks every loaded library, which took longer than the rest of extracting a
    small scan, and a new pool comes with an import (scikit-learn's OpenMP with ``taxonomy.learning.evaluation``,
    after :mod:`features` had found numpy's, scipy's and OpenCV's)."""
    return _thread_pools(len(sys.modules))


@functools.lru_cache(maxsize=1)
def _thread_pools(modules: int) -> ThreadpoolController:
    return ThreadpoolController()


def _release_openblas_control() -> None:
    """Let any thread set OpenBLAS's pool again (threadpoolctl >= 3.8; earlier versions have no control)."""
    release = getattr(getattr(threadpoolctl, "OpenBLASController", None), "clear_controlling_thread", None)
    if release is not None:
        release(force=True)


def _take_blas() -> None:
    if _blas["users"] == 0:
        pools = thread_pools()
        # Where every pool already has one thread (a worker forked by extract_many), setting the limit
        # again is not free: OpenBLAS rebuilds its pool on the first call that sets it, and the new threads
        # spun for about 0.1 s on the cores the workers need (a scan's first extraction took 5 times as long).
        if not all(controller.num_threads == 1 for controller in pools.lib_controllers):
            _release_openblas_control()
            try:
                _blas["limiter"] = pools.limit(limits=1)
            finally:
                _release_openblas_control()
    _blas["users"] += 1


def _give_blas() -> None:
    _blas["users"] -= 1
    if _blas["users"] == 0 and _blas["limiter"] is not None:
        _release_openblas_control()
        try:
            _blas["limiter"].restore_original_limits()
        finally:
            _blas["limiter"] = None
            _release_openblas_control()


def _take_cv2() -> None:
    if _cv2["users"] == 0:
        _cv2["threads"] = cv2.getNumThreads()
        cv2.setNumThreads(1)
    _cv2["users"] += 1


def _give_cv2() -> None:
    _cv2["users"] -= 1
    if _cv2["users"] == 0:
        cv2.setNumThreads(_cv2["threads"])


@contextlib.contextmanager
def _counted(*steps: tuple[Callable[[], None], Callable[[], None]]) -> Iterator[None]:
    """``take`` of every ``(take, give)`` step on entering, ``give`` in reverse on leaving, under the lock."""
    with _lock:
        for take, _ in steps:
            take()
    try:
        yield
    finally:
        with _lock:
            for _, give in reversed(steps):
                give()


def one_blas_thread() -> contextlib.AbstractContextManager[None]:
    """BLAS and OpenMP on one thread while the block runs here and while any other thread is inside one."""
    return _counted((_take_blas, _give_blas))


def one_thread_for_good() -> None:
    """OpenCV, BLAS and OpenMP on one thread for the rest of this process: a worker that was not forked by
    :func:`one_thread_each` (started by a server, or spawned) limits its own pools, which it has not
    started yet (so OpenCV's may be set)."""
    with _lock:
        _take_cv2()
        _take_blas()


def one_thread_each() -> contextlib.AbstractContextManager[None]:
    """OpenCV, BLAS and OpenMP on one thread while worker processes are forked and run, so that each worker
    inherits that: each one's own pools (OpenCV's as many threads as cores, BLAS's for long dot products)
    would put several threads on a core. Set in the parent because a forked child must not reconfigure
    OpenCV's inherited thread pool (it can hang). OpenCV's threads are restored only when the last such
    block ends: restarted while workers run, they would spin-wait on the cores the workers need."""
    return _counted((_take_cv2, _give_cv2), (_take_blas, _give_blas))
