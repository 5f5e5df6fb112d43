"""Where extraction's large temporaries come from: glibc's allocator told to reuse freed memory.

Extracting a 12-megapixel scan allocates and frees several hundred MB of temporaries, each photo anew:
TacTUM's Harris planes are 130 MB, the gray images and spectra 43-86 MB each. glibc serves blocks that
large (above its largest mapping threshold, 32 MiB) with fresh mappings and unmaps them when they are
freed, so the next photo faults the same amount in again (numpy asks for huge pages for its large
arrays, but OpenCV's own buffers fault a page at a time; the counts are in docs/performance.md). Two
settings let freed memory serve the next allocation instead:

- :func:`keep_freed_memory`, for good: a process that extracts scan after scan (:func:`~features.extract_many`'s
  workers, kept for its next call or a job's batches) then holds its peak resident memory until it ends;
- :func:`reusing_freed_memory`, for one block: the photos and TacTUM of one scan reuse each other's
  temporaries, and at the end the free memory goes back to the system (``malloc_trim``), for a process that
  goes on doing other things (the CLI, the web app's end-of-scan prediction).

Values are unaffected: only where memory comes from changes. Elsewhere than glibc (macOS, Windows, musl)
both do nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import sys
import threading
from collections.abc import Iterator

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_MMAP_MAX = -4
"""glibc's ``mallopt`` parameters (malloc.h)."""

_KEEP = {_M_MMAP_MAX: 0, _M_TRIM_THRESHOLD: 2**31 - 1}
"""No block from a mapping of its own; free memory at the top of the heap never given back."""

_AFTERWARDS = {_M_MMAP_MAX: 65536, _M_MMAP_THRESHOLD: 32 << 20, _M_TRIM_THRESHOLD: 64 << 20}
"""Settings once :func:`reusing_freed_memory` ends: glibc's default number of mappings, and the thresholds
its adaptive rule reaches by itself after freeing large blocks (mapping threshold at most 32 MiB on 64-bit
systems, trim threshold twice that). Setting any threshold fixes both, so they are fixed at those values
rather than at the 128 KiB start, where every array above 128 KiB would be faulted in anew each time."""

_lock = threading.Lock()
_state = {"for_good": False, "blocks": 0}


def _start_afresh_in_child() -> None:
    """A forked child has only the forking thread: the lock, held at the fork by another thread that was
    giving memory back (``malloc_trim`` can take milliseconds), would stay held, and the worker's
    :func:`keep_freed_memory` wait for ever. The parent's blocks are not the child's."""
    global _lock
    _lock = threading.Lock()
    _state["blocks"] = 0


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_start_afresh_in_child)


@functools.cache
def _glibc() -> ctypes.CDLL | None:
    """The C library, if it is glibc with ``mallopt`` and ``malloc_trim`` (Linux), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        libc.mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
        libc.malloc_trim.argtypes = (ctypes.c_size_t,)
    except (OSError, AttributeError):
        return None
    return libc


def _set(libc: ctypes.CDLL, settings: dict[int, int]) -> bool:
    """Apply every setting (a list, not a generator: one refused does not skip the others); whether all took."""
    return all([bool(libc.mallopt(parameter, value)) for parameter, value in settings.items()])


def keep_freed_memory() -> bool:
    """Let this process reuse the memory it frees instead of returning it to the system, until it ends.

    For :func:`~features.extract_many`'s workers: a scan's temporaries serve the next scan instead of being
    faulted in again; the worker holds its peak resident memory until it ends.
    :func:`reusing_freed_memory` does nothing in such a process.

    The free memory the process has at the call is given back first (``malloc_trim``): in a forked worker
    that is the parent's free heap, whose pages it shares with the parent, so that reusing them would copy
    each one.

    Returns
    -------
    bool
        Whether the setting took (False where the C library is not glibc).
    """
    libc = _glibc()
    if libc is None:
        return False
    with _lock:
        libc.malloc_trim(0)
        _state["for_good"] = _set(libc, _KEEP)
        return _state["for_good"]


def give_back_free_memory() -> bool:
    """Give the free memory of this process's heap back to the system now (``malloc_trim``).

    :func:`~features.extract_many` calls it before forking its workers: a fork copies the page table of
    every resident page, free ones included, and each worker would then give the same pages back itself
    (:func:`keep_freed_memory`), or copy them on first use (docs/performance.md). Blocks of
    :func:`reusing_freed_memory` running in other threads lose nothing: the memory they hold is in use.

    Returns
    -------
    bool
        Whether anything was given back (False where the C library is not glibc).
    """
    libc = _glibc()
    if libc is None:
        return False
    with _lock:
        return bool(libc.malloc_trim(0))


@contextlib.contextmanager
def reusing_freed_memory() -> Iterator[None]:
    """Inside the block, freed memory is kept for the block's next allocations; at its end the free memory
    is given back to the system (``malloc_trim``) and glibc's settings become :data:`_AFTERWARDS`.

    Thread-safe: blocks may overlap in several threads; the memory is given back when the last one ends.
    Memory: the block holds its peak until it ends, about 120 MB more than without it for a 12-megapixel
    scan (freed blocks are not returned in the middle of the scan, and a free block too small for the next
    allocation grows the heap); the time it saves is in docs/performance.md.
    """
    libc = _glibc()
    with _lock:
        first = libc is not None and not _state["for_good"] and _state["blocks"] == 0
        if first:
            _set(libc, _KEEP)
        _state["blocks"] += 1
    try:
        yield
    finally:
        with _lock:
            _state["blocks"] -= 1
            if libc is not None and not _state["for_good"] and _state["blocks"] == 0:
                _set(libc, _AFTERWARDS)
                libc.malloc_trim(0)
