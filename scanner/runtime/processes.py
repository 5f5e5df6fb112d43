"""Worker processes that end with the process that started them.

A worker forked by a pool blocks on the pool's pipe for its next task. When its parent dies without
closing that pipe (SIGKILL, the kernel's out-of-memory killer), the worker never sees the end of it: it
inherited the pipe's write end itself, so it waits for ever, re-parented to init, holding every byte it
had (after a 12-megapixel scan some 700 MB). :func:`end_with_parent` gives each worker a thread that
watches the process that started it and ends the worker within :data:`PARENT_POLL_S` of that process's
death, whatever signal ended it.

Two signs are watched: the worker's parent process id changing (the kernel re-parents an orphan), and,
for a worker started by multiprocessing's fork server, the pipe multiprocessing keeps between it and the
process that asked for it (:func:`multiprocessing.parent_process`): such a worker's parent is the server,
which itself stays alive as long as any of its workers does.

Linux's parent-death signal (``prctl(PR_SET_PDEATHSIG)``) is not used: it is sent when the *thread* that
forked the child ends, not the process, and a pool forks its workers from whichever thread submits first
(a web request's thread, which ends when its request is answered), so it would kill healthy workers.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import threading

PARENT_POLL_S = 0.5
"""How often a worker checks that its parent is alive: a worker outlives its parent by at most this."""


def end_with_parent(parent: int | None = None) -> None:
    """End this process as soon as the process that started it is gone.

    For a worker's initializer. ``parent`` is the process id the worker was forked by (a worker whose
    parent died before this call, already re-parented, ends at once); None for a worker started by a fork
    server, watched through its multiprocessing parent. The watching thread is a daemon that only waits on
    a pipe or sleeps; it holds no lock the worker's tasks use.
    """
    parent = os.getppid() if parent is None else parent
    if os.getppid() != parent:
        os._exit(1)
    origin = multiprocessing.parent_process()
    sentinel = origin.sentinel if origin is not None and origin.pid != parent else None
    threading.Thread(target=_watch, args=(parent, sentinel), name="end-with-parent", daemon=True).start()


def _watch(parent: int, sentinel: int | None) -> None:
    """Return never; end the process when ``parent`` is no longer its parent or ``sentinel`` (the far end of
    the pipe to the process that asked the fork server for this worker) is closed."""
    while os.getppid() == parent:
        if sentinel is None:
            threading.Event().wait(PARENT_POLL_S)
        elif multiprocessing.connection.wait([sentinel], timeout=PARENT_POLL_S):
            break
    os._exit(1)  # the parent is gone: nobody collects this worker's results, and its memory is wanted
