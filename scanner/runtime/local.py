"""Worker processes on this machine: pools forked from this process (or started by a fork server), kept
between the calls of a command, of a job or of every request of a server.

- :class:`WorkerPool`: processes kept across the batches of one job;
- :class:`SharedWorkers`: the one bounded set of a server (:func:`share_workers`), for all its threads;
- the workers kept between two calls of a command (:func:`kept_workers`, ended :data:`KEEP_WORKERS_S`
  after the last call or by :func:`release_workers`);
- :func:`worker_map` and :func:`run_tasks`: tasks in those workers, results in completion order;
- :func:`run_aside`: one call in a process forked now, while this one goes on.

Every worker ends with the process that started it (:mod:`scanner.runtime.processes`), runs BLAS and
OpenCV on one thread (:mod:`scanner.runtime.threads`) and keeps the memory it frees
(:mod:`scanner.runtime.memory`).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import multiprocessing
import multiprocessing.util
import os
import tempfile
import threading
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence

from scanner.lazy import library, preload
from scanner.runtime.memory import give_back_free_memory, keep_freed_memory
from scanner.runtime.processes import end_with_parent
from scanner.runtime.threads import one_thread_each, one_thread_for_good
from taxonomy.errors import TexplorerError

forkserver = library("multiprocessing.forkserver", workers=False)  # where it exists (POSIX): when a server starts


def _drop_tasks_not_started(futures: Iterable[concurrent.futures.Future]) -> None:
    """Cancel every task a pool has not handed to a worker yet (the caller left early: Ctrl-C).

    Done here, not by ``shutdown(cancel_futures=True)``: the pool's own thread does that cancelling, and
    only if the executor object still exists when it wakes. A generator that is closed drops its pool at
    once, so under load the thread found it gone and ran every queued task (and at interpreter exit, the
    process waited for them all). A future already handed over (running or in the call queue) refuses.
    """
    for future in futures:
        future.cancel()


SHARED_WORKER_NICENESS = 10
"""How much lower the scheduling priority of :class:`SharedWorkers` is than the server's (``nice``): with every
core extracting, a page request is answered at once rather than after a worker's time slice."""


class WorkerPool:
    """Worker processes kept across several :func:`features.extract_many` calls: a job that extracts in batches
    (the web app's export warms the feature cache 16 scans at a time, checking for cancellation between)
    pays the workers' start-up once, not once per batch. :func:`features.extract_many` keeps its own workers for
    its next call as well (:class:`_KeptWorkers`), for :data:`KEEP_WORKERS_S`; a job's pool is its own
    until the job closes it, whatever the job's pauses and whatever other threads extract meanwhile.

    That start-up is forking the workers and, in each one's first scan, the page faults of a new heap and
    of every page it shares with this process, copied when written; docs/performance.md gives the measured
    speed-ups on a process's first call and on calls that find the workers kept (``bench_features.py``).

    The processes are forked by the first batch that needs them, so a job whose scans are all cached forks
    none, and they end when the pool is closed (``with WorkerPool(2) as pool: ...``). They run the code
    of the moment they were forked: keep a pool for one job, not for the life of a process;
    :func:`features.extract_many` ends them and forks new ones when the feature code, its columns or the working
    directory (a scan's relative paths) changed (:meth:`serving`). A worker that dies (killed, out of
    memory) fails the batch it was in, as a pool of that batch's own would; the next batch starts new
    workers, also after one died between batches. One batch at a time: a pool is not shared between
    threads.
    """

    shared = False
    """True for a process's :class:`SharedWorkers`: many threads' batches at once, never closed by one."""
    niceness = 0
    """How much lower the workers' scheduling priority is than this process's."""

    def __init__(self, workers: int | None = None) -> None:
        self.size = max(1, workers or os.cpu_count() or 1)
        self._executor: concurrent.futures.ProcessPoolExecutor | None = None
        self._key: Hashable = None
        self._lock = threading.RLock()  # a SharedWorkers holds it across its own bookkeeping and the submission

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        """Let the workers end. Tasks not started were dropped by their batch; the workers end by
        themselves once a task already handed to them is done, and the executor's thread collects them
        (waiting here for each to tear down its address space would only delay the caller)."""
        with self._lock:
            if self._executor is not None:
                self._executor.shutdown(wait=False)
                self._executor = None

    def serving(self, key: Hashable) -> WorkerPool:
        """The pool for work of ``key`` (:func:`features.extract_many`'s: the feature code's version, the column
        names and the working directory). Workers forked for another key are ended first: they would run
        the code of before (a family registered since), and their rows would be stored under the new key."""
        if key is not ANY_WORK and key != self._key:
            self.close()
            self._key = key
        return self

    def _submit(self, fn: Callable, item: object, key: Hashable = None) -> concurrent.futures.Future:
        """``fn(item)`` on a worker; ``key`` names the work for :class:`SharedWorkers` (unused here)."""
        with self._lock:
            if self._executor is None:  # the first submission forks every worker
                self._executor = _forked_pool(self.size, self.niceness)
            try:
                return self._executor.submit(fn, item)
            except concurrent.futures.BrokenExecutor:  # a worker died between batches (killed while idle)
                self._executor.shutdown(wait=False)
                self._executor = _forked_pool(self.size, self.niceness)
                return self._executor.submit(fn, item)

    def submit(self, fn: Callable[..., object], *args: object) -> concurrent.futures.Future:
        """``fn(*args)`` on one of these workers, as ``concurrent.futures.Executor.submit``: a job's work
        other than extraction (the web app trains a model version there, at the workers' lower priority,
        while the server answers the operator). ``fn`` must be importable by name; it, ``args`` and the
        result are pickled."""
        return self._submit(_call, (fn, args))

    def _done_with(self, futures: Iterable[concurrent.futures.Future]) -> None:
        """A batch leaves early (Ctrl-C, an error): its tasks not started are dropped."""
        _drop_tasks_not_started(futures)


class SharedWorkers(WorkerPool):
    """The one set of workers of a process that extracts for many threads at once (the web app: every
    request and export job of a server): ``size`` processes, started when first needed, whatever the number of
    concurrent calls; their tasks queue in the order they were submitted. Work already queued or running for
    the same ``key`` (a scan's content and the feature code) is not submitted again: a second request for the
    same uncached scans waits for the first one's results. A batch that leaves early drops only the tasks
    no other batch waits for. A worker that dies fails the batches that were waiting on it; the next
    submission starts new workers. Set up by :func:`share_workers`; :func:`features.extract_many` uses them for every
    call of the process from then on."""

    shared = True
    niceness = SHARED_WORKER_NICENESS

    def __init__(self, workers: int | None = None) -> None:
        super().__init__(workers)
        self._waiting: dict[Hashable, tuple[concurrent.futures.Future, int]] = {}

    def _submit(self, fn: Callable, item: object, key: Hashable = None) -> concurrent.futures.Future:
        if key is None:
            return super()._submit(fn, item)
        with self._lock:  # one thread at a time looks for the work and submits it
            queued = self._waiting.get(key)
            if queued is not None and not queued[0].cancelled():
                self._waiting[key] = (queued[0], queued[1] + 1)
                return queued[0]
            future = super()._submit(fn, item)
            self._waiting[key] = (future, 1)
        future.add_done_callback(functools.partial(self._finished, key))
        return future

    def _finished(self, key: Hashable, future: concurrent.futures.Future) -> None:
        with self._lock:
            if key in self._waiting and self._waiting[key][0] is future:
                del self._waiting[key]

    def _done_with(self, futures: Iterable[concurrent.futures.Future]) -> None:
        with self._lock:
            waiters = {id(future): (key, n) for key, (future, n) in self._waiting.items()}
            alone = []
            for future in futures:
                key, n = waiters.get(id(future), (None, 1))
                if n > 1:
                    self._waiting[key] = (future, n - 1)
                else:
                    alone.append(future)
        _drop_tasks_not_started(alone)

    def serving(self, key: Hashable) -> WorkerPool:
        """These workers, whatever the work: they are started by the worker server, and each checks that it
        runs the caller's feature code (``features.extraction``)."""
        return self


KEEP_WORKERS_S = 10.0
"""How long :func:`features.extract_many`'s own workers wait for its next call before they end: long enough for a
program that extracts call after call, short enough that workers holding the memory of large scans (some
700 MB each after 12 MP photos) give it back soon after the last."""


class _KeptWorkers:
    """:func:`features.extract_many`'s own workers, kept between its calls as a :class:`WorkerPool` is kept between a
    job's batches: forking two workers and their first scans (page faults, cold caches) cost a few percent
    of a short batch, which every call without a pool paid again (docs/performance.md).

    They end :data:`KEEP_WORKERS_S` after the call that last used them (a timer thread), when
    :func:`release_workers` is called, and at exit; they are forked anew for a call that asks for another
    number, or whose feature code, columns or working directory (a scan's relative paths) are not those they
    were forked with. What else a process changes after forking them (a function replaced at run time, an
    environment variable) they do not see: :func:`release_workers` then. One call uses them at a time: a
    call made while another thread's has them forks its own, as does a call in a process forked from this
    one (whose lock and pool are the parent's)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pid = os.getpid()
        self._pool: WorkerPool | None = None
        self._timer: threading.Timer | None = None

    @contextlib.contextmanager
    def lent(self, size: int, key: Hashable) -> Iterator[WorkerPool | None]:
        """The kept workers, ``size`` of them serving ``key``, for one call; None when they are taken."""
        if os.getpid() != self._pid or not self._lock.acquire(blocking=False):
            yield None
            return
        try:
            self._stop_timer()
            if self._pool is None or self._pool.size != size:
                self._close()
                self._pool = WorkerPool(size)
            yield self._pool.serving(key)
        finally:
            self._timer = threading.Timer(KEEP_WORKERS_S, self._expire)
            self._timer.daemon = True  # the process exits without waiting for it
            self._timer.start()
            self._lock.release()

    def release(self) -> None:
        """End the workers now (after the call that has them, if one does)."""
        if os.getpid() != self._pid:
            return
        with self._lock:
            self._stop_timer()
            self._close()

    def _stop_timer(self) -> None:
        """Cancel the timer and wait for its thread to end: a thread alive while workers are forked is
        copied into them as a lock it might hold."""
        if self._timer is not None:
            self._timer.cancel()
            self._timer.join()
            self._timer = None

    def _expire(self) -> None:
        if self._lock.acquire(blocking=False):  # else a call has them, and starts a new timer when it ends
            try:
                self._timer = None
                self._close()
            finally:
                self._lock.release()

    def _close(self) -> None:
        if self._pool is not None:
            self._pool.close()
            self._pool = None


_KEPT = _KeptWorkers()


def kept_workers(size: int, key: Hashable) -> contextlib.AbstractContextManager[WorkerPool | None]:
    """The workers kept between calls, ``size`` of them serving ``key``, for one call; None when another
    thread's call has them (:class:`_KeptWorkers`)."""
    return _KEPT.lent(size, key)


ANY_WORK = None
"""The key of :meth:`_KeptWorkers.lent` that serves the kept workers as they are: work that runs no feature
code of its own version (the evaluation's folds, :func:`worker_map`)."""


def worker_map(fn: Callable, items: Sequence, workers: int | None = None,
               tick: Callable[[int], object] = lambda n: None) -> Iterator[tuple[int, object]]:
    """``(index, fn(item))`` for every item, in completion order, in the worker processes
    :func:`features.extract_many` keeps (forked from this process, with everything it imported: no start-up of their
    own), or in this process for ``workers`` 1. ``fn`` and the items are pickled to the workers.

    The evaluation's folds run here after the features of the same job: a pool of fresh interpreters
    (joblib's) would import the whole stack again in each worker first (docs/performance.md).
    Leaving early (closing the iterator, Ctrl-C) drops the tasks not started.
    """
    size = workers or os.cpu_count() or 1
    indices = range(len(items))
    if size == 1 or len(items) <= 1:
        yield from run_tasks(fn, items, indices, 1, tick)
        return
    with _KEPT.lent(size, ANY_WORK) as pool:
        yield from run_tasks(fn, items, indices, size, tick, pool)


def run_aside(fn: Callable[..., object], *args: object) -> concurrent.futures.Future:
    """``fn(*args)`` in one process forked from this one now, while this process goes on (with the workers
    of :func:`worker_map`, say): the future holds its result or its exception. The process ends with this
    one and runs BLAS and OpenCV on one thread, as the workers do. Where this process cannot fork (no
    ``fork``, or :func:`start_workers_from_a_server` was called: other threads hold locks), ``fn`` runs
    here, at once, and the future is already done. ``fn`` and its result are pickled, ``args`` too.
    """
    if _FORK is None or _SERVER["context"] is not None:
        done: concurrent.futures.Future = concurrent.futures.Future()
        try:
            done.set_result(fn(*args))
        except Exception as exc:  # noqa: BLE001 - handed to the caller through the future, as a process would
            done.set_exception(exc)
        return done
    give_back_free_memory()
    with one_thread_each():  # a forked child must not reconfigure the pools it inherits: limit them here
        aside = concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=_FORK, initializer=_start_worker,
                                                      initargs=(os.getpid(), True))
        future = aside.submit(fn, *args)  # forks the process now (a forking pool starts its workers at once)
    aside.shutdown(wait=False)  # the process ends once fn returns
    return future


_SHARED: dict[str, SharedWorkers | None] = {"pool": None}


def share_workers(workers: int | None = None) -> SharedWorkers:
    """Make every later extraction of this process, from any thread, run on one :class:`SharedWorkers` of
    ``workers`` processes (default: the number of cores), started by the worker server: call
    :func:`start_workers_from_a_server` first. A server that extracts for concurrent requests then holds
    at most ``workers`` worker processes, not a pool per request. :func:`end_shared_workers` ends them."""
    if _SERVER["context"] is None:
        raise TexplorerError("share_workers() needs the worker server: call start_workers_from_a_server() first")
    if _SHARED["pool"] is None or _SHARED["pool"].size != max(1, workers or os.cpu_count() or 1):
        end_shared_workers()
        _SHARED["pool"] = SharedWorkers(workers)
    return _SHARED["pool"]


def shared_workers() -> SharedWorkers | None:
    """The workers of :func:`share_workers`, if this process shares a set."""
    return _SHARED["pool"]


def end_shared_workers() -> None:
    """End the workers of :func:`share_workers`; later extractions start their own again."""
    pool, _SHARED["pool"] = _SHARED["pool"], None
    if pool is not None:
        pool.close()


@contextlib.contextmanager
def job_workers(workers: int | None = None) -> Iterator[WorkerPool]:
    """Workers for a job that extracts in batches: the process's :class:`SharedWorkers` where it has them
    (a server's job shares them with its requests), else a :class:`WorkerPool` of ``workers``, ended after."""
    if _SHARED["pool"] is not None:
        yield _SHARED["pool"]
        return
    with WorkerPool(workers) as pool:
        yield pool

def release_workers() -> None:
    """End the workers :func:`features.extract_many` keeps for its next call now, rather than :data:`KEEP_WORKERS_S`
    after its last call.

    Call it when a program is done extracting (they hold the memory of the largest scan they extracted), or
    before it changes what the features depend on at run time (they run the code of the moment they were
    forked).
    """
    _KEPT.release()


_FORK = multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods() else None
"""Workers are forked where the system can (Linux: Python 3.14 makes forkserver the default): they inherit
the one-thread limits set while forking (:func:`scanner.runtime.threads.one_thread_each`) and the loaded code."""

_SERVER: dict[str, multiprocessing.context.BaseContext | None] = {"context": None}
"""The worker server's context once :func:`start_workers_from_a_server` was called."""

def start_workers_from_a_server(preload: Sequence[str] = ()) -> None:
    """Start the workers of every later pool from a server process started now (multiprocessing's
    forkserver, started with this process's ``sys.path`` and the modules named in ``preload`` imported, so
    that each worker it forks starts with them loaded), not by forking this process.

    For a process that extracts while other threads run (the web app: request threads reading SQLite, an
    export job): a worker forked from it inherits every lock another thread held at that moment, held for
    good (SQLite's memory mutex: the worker hangs in ``sqlite3_free``). The server has one thread; call
    this before starting any other, and the server is started before them too. Its workers import nothing
    more and check that they run the caller's feature code (``features.code_version``). Where the system has no
    forkserver, the pools use the default start method (spawn).
    """
    if _SERVER["context"] is not None:
        return
    if "forkserver" not in multiprocessing.get_all_start_methods():
        _SERVER["context"] = multiprocessing.get_context()
        return
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(preload))
    try:
        forkserver.ensure_running()
    except OSError as exc:
        if "AF_UNIX path too long" not in str(exc):
            raise
        raise TexplorerError(f"the worker server's socket does not fit in $TMPDIR ({tempfile.gettempdir()}): a "
                             "Unix socket's path holds at most 107 bytes; set TMPDIR to a shorter folder") from None
    _SERVER["context"] = context


def revive_worker_server() -> bool:
    """Start the worker server again if its socket was deleted (a ``/tmp`` cleaner removes a file it has not
    seen used for days): the server still runs but no worker can be started from it, and every pool would
    fail. Stops the orphaned server and starts a new one at a new socket; True if it did (a killed server
    is restarted by multiprocessing itself)."""
    if _SERVER["context"] is None or _SERVER["context"].get_start_method() != "forkserver":
        return False
    server = forkserver._forkserver  # multiprocessing's one instance; its state is what pools connect to
    with server._lock:
        address = server._forkserver_address
        if server._forkserver_pid is None or address is None \
                or multiprocessing.util.is_abstract_socket_namespace(address) or os.path.exists(address):
            return False
        os.close(server._forkserver_alive_fd)  # the server ends when its "alive" pipe closes
        with contextlib.suppress(ChildProcessError):
            os.waitpid(server._forkserver_pid, 0)
        server._forkserver_pid = server._forkserver_alive_fd = server._forkserver_address = None
    server.ensure_running()
    return True


def _call(task: tuple[Callable[..., object], tuple[object, ...]]) -> object:
    """A :meth:`WorkerPool.submit` task in a worker: ``fn(*args)``."""
    fn, args = task
    return fn(*args)


def _start_worker(parent: int | None, forked: bool, niceness: int = 0) -> None:
    """A worker's first step: end with ``parent`` (None: the server that forked it, which ends with this
    process; :func:`scanner.runtime.processes.end_with_parent`), then keep the memory it frees. A worker not
    ``forked`` from this process limits its own thread pools (a forked one inherited the limits); one
    with a ``niceness`` lowers its scheduling priority by it."""
    end_with_parent(parent)
    if not forked:
        one_thread_for_good()
    if niceness:
        os.nice(niceness)
    keep_freed_memory()


def _forked_pool(workers: int, niceness: int = 0) -> concurrent.futures.ProcessPoolExecutor:
    """``workers`` processes that end with this process and keep the memory they free
    (:func:`_start_worker`): forked where possible, after this process gave its free memory back
    (:func:`give_back_free_memory`: a lighter fork), or started by the worker server once
    :func:`start_workers_from_a_server` was called."""
    server = _SERVER["context"]
    if server is not None:
        revive_worker_server()
        return concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=server,
                                                      initializer=_start_worker, initargs=(None, False, niceness))
    give_back_free_memory()
    preload()  # the workers share the libraries the features compute with instead of each importing its own
    return concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=_FORK, initializer=_start_worker,
                                                  initargs=(os.getpid(), _FORK is not None, niceness))


def run_tasks(fn: Callable, items: Sequence, indices: Sequence[int], workers: int,
         tick: Callable[[int], object], pool: WorkerPool | None = None,
         keys: Sequence[Hashable] | None = None) -> Iterable[tuple[int, tuple]]:
    """``(index, fn(item))`` for every item, in this process (``workers`` 1) or worker processes
    (completion order): those of ``pool``, else a pool of ``workers`` for this call only. ``keys`` name the
    items' work for a :class:`SharedWorkers` pool, which runs the same work once for every batch waiting on it."""
    if workers == 1:
        for index, item in zip(indices, items, strict=True):
            result = fn(item)
            tick(1)
            yield index, result
        return
    own = pool is None
    workers_here = WorkerPool(workers) if pool is None else pool
    keys = [None] * len(items) if keys is None else keys
    # OpenCV's threads are restored only once every result is in: restarted at once, they would spin-wait
    # on the cores the workers need. The workers forked in here inherit the one-thread setting.
    with one_thread_each():
        futures: dict[concurrent.futures.Future, list[int]] = {}
        try:
            for index, item, key in zip(indices, items, keys, strict=True):
                futures.setdefault(workers_here._submit(fn, item, key), []).append(index)
            for future in concurrent.futures.as_completed(futures):
                result = future.result()
                for index in futures[future]:
                    tick(1)
                    yield index, result
        except concurrent.futures.BrokenExecutor:
            if not workers_here.shared:  # a worker died: this batch fails, the pool's next batch forks new ones
                workers_here.close()
            raise
        finally:
            workers_here._done_with(futures)
            if own:
                workers_here.close()
