"""The features of a scan (docs/features.md) and their parallel, cached extraction into a feature space.

The features are those of the registered families (:mod:`features.registry`), in their order; the paper's
193 (:mod:`features.families`) are registered when this package is imported.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import functools
import multiprocessing
import os
import sys
import threading
import warnings
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from tqdm import tqdm

from features import cluster, tactum
from features.memory import give_back_free_memory, keep_freed_memory, reusing_freed_memory
from features.prepared import PreparedScan
from features.registry import REGISTRY, fix_code_version
from features.space import FeatureSpace
from features.threads import one_blas_thread, one_thread_each, one_thread_for_good
from scanner.lazy import preload
from scanner.processes import end_with_parent
from scanner.scan import Scan
from scanner.storage.stored import NotOnThisMachine
from taxonomy.errors import ParameterError, TexplorerError

if TYPE_CHECKING:  # Dask is an optional dependency (texplorer[cluster])
    from distributed import Client


def code_version(families: Sequence[str] | None = None) -> str:
    """Hash of the feature code (every registered family's module, this module and what they import): a
    cached feature vector is reused only with the code that computed it. ``families`` (default: the
    default families) adds the chosen families' names and parameters (:meth:`Registry.code_version`)."""
    return REGISTRY.code_version(__name__, families=families)


fix_code_version(__name__)  # this module's source and its imports, as imported now


def without_short_channels(scan: Scan) -> Scan:
    """``scan`` without the channels too short for their features (``Scan.short_channels``), with a warning.

    Their features are then NaN like those of a missing channel: a single sample has no spread, no
    relaxation and no cooling curve, and computing them anyway gives silent zeros (docs/features.md).
    """
    short = scan.short_channels()
    if not short:
        return scan
    described = ", ".join(f"{name} ({scan[name].n} of the {need} samples its features need)"
                          for name, need in short.items())
    warnings.warn(f"scan {scan.scan_id}: too short: {described}; treated as missing", tactum.MissingDataWarning,
                  stacklevel=3)  # the caller of features.extract
    return dataclasses.replace(scan, traces={k: v for k, v in scan.traces.items() if k not in short})


REUSE_FROM_PIXELS = 1 << 22
"""Photos from 4 megapixels on: their float64 gray image (32 MiB) and larger temporaries are above glibc's
largest mapping threshold, so without :func:`reusing_freed_memory` each is faulted in anew."""


def extract(scan: Scan, families: Sequence[str] | None = None) -> dict[str, float]:
    """The named features of a scan (docs/features.md): every default family's (or those named in
    ``families``, opt-in ones too: :mod:`features.modern`), in order.

    The scan is prepared once (:class:`~features.prepared.PreparedScan`) for all families; channels too short
    for their features count as missing (:func:`without_short_channels`). BLAS runs on one thread, since a
    product's summation order depends on its thread count: the last bits of a few features (Tamura
    contrast, MaCo, MaRG) would otherwise differ between machines. A scan with a photo of
    :data:`REUSE_FROM_PIXELS` or more is extracted :func:`reusing_freed_memory` (docs/performance.md).

    Parameters
    ----------
    scan : Scan
        A stored or simulated scan.
    families : sequence of str, optional
        The families to compute (default: the default ones, the paper's 193 features), opt-in ones too.

    Returns
    -------
    dict of str to float
        The 193 features of :data:`features.NAMES` (and those of any family registered since), a finite
        float or NaN where a value is undefined.

    Warns
    -----
    MissingDataWarning
        Naming the channel and the features it made NaN.

    Examples
    --------
    >>> import features
    >>> from scanner.simulation import synthetic_scan
    >>> values = features.extract(synthetic_scan("mild-steel-brushed", seed=0, image_size=(320, 320)))
    >>> len(values), values["other.metal"]
    (193, 1.0)
    """
    values: dict[str, float] = {}
    large = any(photo.shape[0] * photo.shape[1] >= REUSE_FROM_PIXELS for photo in scan.images.values())
    with reusing_freed_memory() if large else contextlib.nullcontext(), one_blas_thread():
        prepared = PreparedScan(without_short_channels(scan))
        for family in REGISTRY.chosen(families):
            computed = family.compute(prepared)
            if tuple(computed) != family.columns:
                # A programming error, not bad input.
                raise RuntimeError(f"the {family.name} family returned names out of its fixed column order")
            values.update(computed)
    return values


# -- many scans ----------------------------------------------------------------------------------------

class _Bar(tqdm):
    """The progress bar without tqdm's monitor thread: workers are forked only from a process whose one
    thread is the forking one (another thread could hold a lock the workers inherit held)."""

    monitor_interval = 0


class FeatureCache(Protocol):
    """Where feature vectors are kept between runs (``scanner.Database`` implements it)."""

    def cached_features(self, content_hash: str, code_version: str) -> dict[str, float] | None:
        """The values stored for this content and feature code, or None."""

    def store_features(self, content_hash: str, code_version: str, values: dict[str, float]) -> None:
        """Keep ``values`` for this content and feature code."""


@dataclass(frozen=True)
class ScanSource:
    """A scan to extract, loaded where it is processed (in a worker process), with its row identity.

    Parameters
    ----------
    scan_id : str
        The row's id in the feature space.
    label : str
        The row's label.
    group : str
        The row's group (sample id).
    load : callable returning Scan
        Loads the scan; pickled to the worker that extracts it.
    cache_key : str, optional
        The scan's content hash: with one, :func:`extract_many` reads and writes the feature cache.
    """

    scan_id: str
    label: str
    group: str
    load: Callable[[], Scan]
    cache_key: str | None = None


def _return(scan: Scan) -> Scan:
    return scan


def source_of(scan: Scan) -> ScanSource:
    """Wrap an in-memory scan (no cache key: it has no stored content hash)."""
    return ScanSource(scan.scan_id, scan.meta.label, scan.meta.sample_id, functools.partial(_return, scan))


def _extract_source(source: ScanSource,
                    families: tuple[str, ...] | None = None) -> tuple[list[float] | None, str | None]:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # missing-channel warnings are expected on partial scans
            values = extract(source.load(), families)
    except NotOnThisMachine:
        raise  # a cluster worker without the scan's files: the client sends them (features.cluster)
    except Exception as exc:  # one broken scan must not stop the others; reported with its id
        return None, f"{type(exc).__name__}: {exc}"
    return list(values.values()), None


def _unverified(source: ScanSource) -> str | None:
    """Why ``source``'s cached features must not be served (its files are not the bytes they were computed
    from: ``load.verify()`` of a :class:`~scanner.storage.stored.StoredScan`), or None."""
    verify = getattr(source.load, "verify", None)
    if verify is None:
        return None
    try:
        verify()
    except (TexplorerError, OSError) as exc:
        return f"{type(exc).__name__}: {exc}"
    return None


def _extract_with_code(version: str, families: tuple[str, ...] | None,
                       source: ScanSource) -> tuple[list[float] | None, str | None]:
    """:func:`_extract_source` in a worker process, refused where the worker's feature code is not ``version``
    (the caller's): a worker started by a server (:func:`start_workers_from_a_server`) imported the code
    when that server started, which may be after the caller imported it and the files changed."""
    if code_version(families) != version:
        return None, (f"this worker runs feature code {code_version(families)}, the calling process {version}: "
                      "the code changed on disk since the process started; restart it")
    return _extract_source(source, families)


def extract_many(scans: Iterable[Scan | ScanSource], workers: int | None = None, *,
                 cache: FeatureCache | None = None, progress: bool = True, client: Client | None = None,
                 ship_data: bool = False, pool: WorkerPool | None = None,
                 families: Sequence[str] | None = None) -> FeatureSpace:
    """Features of many scans as a :class:`FeatureSpace`, rows in input order.

    A scan that fails is reported in ``FeatureSpace.failed`` with its id and the reason, the others are kept.
    With a ``cache``, sources with a ``cache_key`` (the scan's content hash) are looked up first and stored
    after, keyed by :func:`code_version` too, so a second run over unchanged scans only reads the cache. A
    cached row is served only once the source's files are verified to be the bytes it was computed from (a
    stored scan's ``load.verify()``: their SHA-256), and a stored scan is extracted only from its catalogued
    bytes: a file changed since it was stored fails its row, naming the file, and nothing is cached.

    Parameters
    ----------
    scans : iterable of Scan or ScanSource
        Scans, or sources that load them where they are extracted (with label, group and cache key).
    workers : int, optional
        Processes (default: the number of cores; 1 = in this process), kept for the next call
        (:data:`KEEP_WORKERS_S`; :func:`release_workers` ends them at once).
    cache : FeatureCache, optional
        Where cached rows are read and new ones written (a ``scanner.Database``); only this process uses it.
    progress : bool
        Show a progress bar.
    client : distributed.Client, optional
        Extract the uncached scans on this Dask cluster instead, with the same results
        (:func:`features.cluster.extract`).
    ship_data : bool
        Send each scan's files from here instead of letting the cluster's workers read them.
    pool : WorkerPool, optional
        Workers kept across the calls of a job that extracts in batches.
    families : sequence of str, optional
        The families to compute (default: the default ones, the paper's 193 features), opt-in ones too;
        their cache entries are keyed by their names and parameters as well.

    Returns
    -------
    FeatureSpace

    Examples
    --------
    >>> import features
    >>> from scanner.simulation import synthetic_scan
    >>> scans = [synthetic_scan(m, seed=s, image_size=(320, 320)) for m in ("oak-planed", "cork-board") for s in (1, 2)]
    >>> space = features.extract_many(scans, workers=1, progress=False)
    >>> space.X.shape, space.y("coarse").tolist()
    ((4, 193), ['C1', 'C1', 'C2', 'C2'])
    """
    pool = pool or _SHARED["pool"]  # a job's own pool, else the process's shared workers (job_workers gives both)
    if pool is not None and not pool.shared and workers not in (None, pool.size):
        raise ParameterError(f"workers={workers} with a pool of {pool.size} workers")
    sources = [s if isinstance(s, ScanSource) else source_of(s) for s in scans]
    families = None if families is None else tuple(f.name for f in REGISTRY.chosen(families))
    names = REGISTRY.columns_of(families)
    version = code_version(families)
    work = _extract_source if families is None else functools.partial(_extract_source, families=families)
    rows: list[list[float] | None] = [None] * len(sources)
    errors: dict[int, str] = {}
    todo = []
    for i, source in enumerate(sources):
        cached = cache.cached_features(source.cache_key, version) if cache and source.cache_key else None
        if cached is None or tuple(cached) != names:
            todo.append(i)
        elif (problem := _unverified(source)) is not None:
            errors[i] = problem
        else:
            rows[i] = list(cached.values())
    bar = _Bar(total=len(todo), desc="features", unit="scan", file=sys.stderr, disable=None if progress else True,
               leave=False)
    size = (pool.size if pool else workers) or os.cpu_count() or 1
    workers = size if pool is not None and pool.shared else max(1, min(size, len(todo) or 1))
    with contextlib.ExitStack() as stack:
        if client is not None:
            results = cluster.extract(client, work, [sources[i] for i in todo], todo, bar.update,
                                      version=functools.partial(code_version, families), ship_data=ship_data)
        else:
            key = (version, names, _working_directory())
            if pool is not None:
                pool = pool.serving(key)
            elif workers > 1:  # this function's own, kept between calls (None: another thread's call has them)
                pool = stack.enter_context(_KEPT.lent(size, key))
            fn = work if workers == 1 else functools.partial(_extract_with_code, version, families)
            keys = [(version, sources[i].cache_key) if sources[i].cache_key else None for i in todo]
            results = _run(fn, [sources[i] for i in todo], todo, workers, bar.update, pool, keys)
        # leaving early (Ctrl-C) ends the workers' tasks now, not at exit
        for i, (row, error) in stack.enter_context(contextlib.closing(results)):
            if error is not None:
                errors[i] = error
                continue
            rows[i] = row
            if cache is not None and sources[i].cache_key:
                cache.store_features(sources[i].cache_key, version, dict(zip(names, row, strict=True)))
    bar.close()
    kept = [i for i in range(len(sources)) if rows[i] is not None]
    return FeatureSpace(
        X=np.array([rows[i] for i in kept], dtype=np.float64).reshape(len(kept), len(names)),
        columns=names,
        scan_ids=[sources[i].scan_id for i in kept],
        label_text=[sources[i].label for i in kept],
        groups=[sources[i].group for i in kept],
        failed=[(sources[i].scan_id, errors[i]) for i in sorted(errors)],
    )


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
    """Worker processes kept across several :func:`extract_many` calls: a job that extracts in batches
    (the web app's export warms the feature cache 16 scans at a time, checking for cancellation between)
    pays the workers' start-up once, not once per batch. :func:`extract_many` keeps its own workers for
    its next call as well (:class:`_KeptWorkers`), for :data:`KEEP_WORKERS_S`; a job's pool is its own
    until the job closes it, whatever the job's pauses and whatever other threads extract meanwhile.

    That start-up is forking the workers and, in each one's first scan, the page faults of a new heap and
    of every page it shares with this process, copied when written; docs/performance.md gives the measured
    speed-ups on a process's first call and on calls that find the workers kept (``bench_features.py``).

    The processes are forked by the first batch that needs them, so a job whose scans are all cached forks
    none, and they end when the pool is closed (``with WorkerPool(2) as pool: ...``). They run the code
    of the moment they were forked: keep a pool for one job, not for the life of a process;
    :func:`extract_many` ends them and forks new ones when the feature code, its columns or the working
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
        """The pool for work of ``key`` (:func:`extract_many`'s: the feature code's version, the column
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
    submission starts new workers. Set up by :func:`share_workers`; :func:`extract_many` uses them for every
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
        runs the caller's feature code (:func:`_extract_with_code`)."""
        return self


KEEP_WORKERS_S = 10.0
"""How long :func:`extract_many`'s own workers wait for its next call before they end: long enough for a
program that extracts call after call, short enough that workers holding the memory of large scans (some
700 MB each after 12 MP photos) give it back soon after the last."""


class _KeptWorkers:
    """:func:`extract_many`'s own workers, kept between its calls as a :class:`WorkerPool` is kept between a
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


ANY_WORK = None
"""The key of :meth:`_KeptWorkers.lent` that serves the kept workers as they are: work that runs no feature
code of its own version (the evaluation's folds, :func:`worker_map`)."""


def worker_map(fn: Callable, items: Sequence, workers: int | None = None,
               tick: Callable[[int], object] = lambda n: None) -> Iterator[tuple[int, object]]:
    """``(index, fn(item))`` for every item, in completion order, in the worker processes
    :func:`extract_many` keeps (forked from this process, with everything it imported: no start-up of their
    own), or in this process for ``workers`` 1. ``fn`` and the items are pickled to the workers.

    The evaluation's folds run here after the features of the same job: a pool of fresh interpreters
    (joblib's) would import the whole stack again in each worker first (docs/performance.md).
    Leaving early (closing the iterator, Ctrl-C) drops the tasks not started.
    """
    size = workers or os.cpu_count() or 1
    indices = range(len(items))
    if size == 1 or len(items) <= 1:
        yield from _run(fn, items, indices, 1, tick)
        return
    with _KEPT.lent(size, ANY_WORK) as pool:
        yield from _run(fn, items, indices, size, tick, pool)


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


def _working_directory() -> str | None:
    """The working directory of this process, None where it was removed (its scans' relative paths are then
    found nowhere, by kept workers or new ones)."""
    try:
        return os.getcwd()
    except OSError:
        return None


def release_workers() -> None:
    """End the workers :func:`extract_many` keeps for its next call now, rather than :data:`KEEP_WORKERS_S`
    after its last call.

    Call it when a program is done extracting (they hold the memory of the largest scan they extracted), or
    before it changes what the features depend on at run time (they run the code of the moment they were
    forked).
    """
    _KEPT.release()


_FORK = multiprocessing.get_context("fork") if "fork" in multiprocessing.get_all_start_methods() else None
"""Workers are forked where the system can (Linux: Python 3.14 makes forkserver the default): they inherit
the one-thread limits set while forking (:func:`features.threads.one_thread_each`) and the loaded code."""

_SERVER: dict[str, multiprocessing.context.BaseContext | None] = {"context": None}
"""The worker server's context once :func:`start_workers_from_a_server` was called."""

WORKER_SERVER_PRELOAD = ("features", "scanner.storage.stored")
"""Modules the worker server imports once, so that each worker it forks starts with them loaded."""


def start_workers_from_a_server() -> None:
    """Start the workers of every later pool from a server process started now (multiprocessing's
    forkserver, started with this process's ``sys.path`` and :data:`WORKER_SERVER_PRELOAD` imported), not
    by forking this process.

    For a process that extracts while other threads run (the web app: request threads reading SQLite, an
    export job): a worker forked from it inherits every lock another thread held at that moment, held for
    good (SQLite's memory mutex: the worker hangs in ``sqlite3_free``). The server has one thread; call
    this before starting any other, and the server is started before them too. Its workers import nothing
    more and check that they run the caller's feature code (:func:`code_version`). Where the system has no
    forkserver, the pools use the default start method (spawn).
    """
    if _SERVER["context"] is not None:
        return
    if "forkserver" not in multiprocessing.get_all_start_methods():
        _SERVER["context"] = multiprocessing.get_context()
        return
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(list(WORKER_SERVER_PRELOAD))
    from multiprocessing import forkserver  # noqa: PLC0415 (only where it exists)

    try:
        forkserver.ensure_running()
    except OSError as exc:
        if "AF_UNIX path too long" not in str(exc):
            raise
        import tempfile  # noqa: PLC0415 (only to name the folder)

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
    from multiprocessing import forkserver, util  # noqa: PLC0415 (only where it exists)

    server = forkserver._forkserver  # multiprocessing's one instance; its state is what pools connect to
    with server._lock:
        address = server._forkserver_address
        if server._forkserver_pid is None or address is None or util.is_abstract_socket_namespace(address) \
                or os.path.exists(address):
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
    process; :func:`scanner.processes.end_with_parent`), then keep the memory it frees. A worker not
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


def _run(fn: Callable, items: Sequence, indices: Sequence[int], workers: int,
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
