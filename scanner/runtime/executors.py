"""One interface to where the work runs, chosen once: worker processes on this machine or a Dask cluster.

A command or the web app chooses the runtime once (:func:`chosen`: ``--workers`` for processes here, else
:func:`connect` from ``--scheduler``, Dask's own configuration ``DASK_SCHEDULER_ADDRESS`` or nothing:
processes here) and makes it current while it runs (:func:`using`).
The feature, learning and related-method code asks :func:`current` where to run and never branches on
it: both runtimes answer the same methods, shaped as :class:`concurrent.futures.Executor`'s.

==========================  =============================================================================
:meth:`Runtime.submit`      ``fn(*args)`` while the caller goes on (a model trained beside the folds)
:meth:`Runtime.map_unordered`  ``fn(*call)`` for every call, results in completion order with their index
:meth:`Runtime.share`       data many calls use, sent to the workers once (Dask's ``scatter``)
:meth:`Runtime.extract`     feature extraction of stored or in-memory scans, checked against the code here
==========================  =============================================================================

:class:`LocalRuntime` runs on this machine's worker processes (:mod:`scanner.runtime.local`: kept between
calls, a job's :class:`~scanner.runtime.local.WorkerPool` or a server's shared set); :class:`DaskRuntime`
on a Dask cluster's workers (:mod:`scanner.runtime.cluster`). Results are the same bit for bit.
"""

from __future__ import annotations

import abc
import concurrent.futures
import contextlib
import functools
import os
import threading
from collections.abc import Callable, Hashable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from scanner.runtime import cluster
from scanner.runtime.local import WorkerPool, kept_workers, run_aside, run_tasks, shared_workers, worker_map

if TYPE_CHECKING:
    from distributed import Client

Tick = Callable[[int], object]


class Runtime(abc.ABC):
    """Where the work of a command runs; every method is safe to call from any thread."""

    @abc.abstractmethod
    def submit(self, fn: Callable[..., Any], /, *args: Any) -> concurrent.futures.Future:
        """``fn(*args)`` while the caller goes on: a future with ``result()``, as ``Executor.submit``.
        ``fn`` must be importable by name; it, ``args`` and the result are pickled."""

    @abc.abstractmethod
    def map_unordered(self, fn: Callable[..., Any], calls: Sequence[tuple], *, workers: int | None = None,
                      name: str = "texplorer", tick: Tick | None = None) -> Iterator[tuple[int, Any]]:
        """``(i, fn(*calls[i]))`` for every call, in completion order; an exception of a call is raised here;
        leaving the iteration early (closing it, Ctrl-C) drops the calls not started.

        ``workers``: processes on this machine (default one per core, 1: in this process, in order); a
        cluster has its own. ``name`` prefixes the tasks' keys on a cluster's dashboard; ``tick(1)`` is
        called for every result."""

    @abc.abstractmethod
    def share(self, items: Sequence[Any]) -> list[Any]:
        """``items`` as arguments for :meth:`map_unordered`'s calls that travel once, whatever the number of
        calls that use them: the items themselves here, handles to a copy on a cluster's workers there."""

    @abc.abstractmethod
    def extract(self, fn: Callable[[Any], Any], items: Sequence[Any], indices: Sequence[int], tick: Tick, *,
                version: Callable[[], str], key: Hashable, keys: Sequence[Hashable | None],
                workers: int | None = None, pool: WorkerPool | None = None) -> Iterator[tuple[int, Any]]:
        """``(indices[i], fn(items[i]))`` for every item, in completion order: the features of scans.

        ``items`` are ``features.ScanSource``-like (a ``load`` attribute: a stored scan a cluster's worker
        may read from shared storage or get from here, see :func:`scanner.runtime.cluster.extract`).
        ``version()`` is the feature code version the results must come from (a worker running other code
        stops the run on a cluster; ``fn`` itself refuses it in a process of this machine started by a
        server). ``key`` names the work as a whole (workers kept for other work are not used) and ``keys``
        each item's (a server's shared workers run work queued twice once). ``workers`` and ``pool`` choose
        the processes of this machine (see :func:`features.extract_many`); a cluster has its own.
        """

    def describe(self) -> str:
        """One line saying where the work runs."""
        return "processes on this machine"


class LocalRuntime(Runtime):
    """Worker processes of this machine (:mod:`scanner.runtime.local`): forked from this process with
    everything it imported, kept for the next call, or those of a job's pool or a server's shared set."""

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> concurrent.futures.Future:
        """``fn(*args)`` in one process forked now (:func:`~scanner.runtime.local.run_aside`)."""
        return run_aside(fn, *args)

    def map_unordered(self, fn: Callable[..., Any], calls: Sequence[tuple], *, workers: int | None = None,
                      name: str = "texplorer", tick: Tick | None = None) -> Iterator[tuple[int, Any]]:
        """In the kept workers (:func:`~scanner.runtime.local.worker_map`), or here for ``workers`` 1."""
        return worker_map(functools.partial(_called, fn), calls, workers, tick or _no_tick)

    def share(self, items: Sequence[Any]) -> list[Any]:
        """The items: the workers get what a call needs with the call."""
        return list(items)

    def extract(self, fn: Callable[[Any], Any], items: Sequence[Any], indices: Sequence[int], tick: Tick, *,
                version: Callable[[], str], key: Hashable, keys: Sequence[Hashable | None],
                workers: int | None = None, pool: WorkerPool | None = None) -> Iterator[tuple[int, Any]]:
        """In this process (one worker, or one item), in ``pool`` (a job's, else the server's shared
        workers), or in the workers kept between calls (``key``: forked anew for other work)."""
        pool = pool or shared_workers()
        size = (pool.size if pool else workers) or os.cpu_count() or 1
        count = size if pool is not None and pool.shared else max(1, min(size, len(items) or 1))
        with contextlib.ExitStack() as stack:
            if pool is not None:
                pool = pool.serving(key)
            elif count > 1:  # the kept workers (None: another thread's call has them; this call forks its own)
                pool = stack.enter_context(kept_workers(size, key))
            yield from run_tasks(fn, items, indices, count, tick, pool, keys)


class DaskRuntime(Runtime):
    """The workers of a Dask cluster (:mod:`scanner.runtime.cluster`), through ``client``. With
    ``ship_data`` this machine sends each stored scan's files to the workers instead of letting them read
    the files from shared storage."""

    def __init__(self, client: Client, *, ship_data: bool = False) -> None:
        self.client = client
        self.ship_data = ship_data

    def submit(self, fn: Callable[..., Any], /, *args: Any) -> concurrent.futures.Future:
        """``fn(*args)`` as one task on the cluster (BLAS on one thread, as here), through the client's
        ``concurrent.futures`` executor."""
        return self.client.get_executor(pure=False).submit(cluster.pinned, fn, *args)

    def map_unordered(self, fn: Callable[..., Any], calls: Sequence[tuple], *, workers: int | None = None,
                      name: str = "texplorer", tick: Tick | None = None) -> Iterator[tuple[int, Any]]:
        """One task per call (:func:`scanner.runtime.cluster.run`)."""
        return cluster.run(self.client, fn, calls, name=name, tick=tick)

    def share(self, items: Sequence[Any]) -> list[Any]:
        """Scattered to the workers once (:func:`scanner.runtime.cluster.scatter`)."""
        return cluster.scatter(self.client, list(items))

    def extract(self, fn: Callable[[Any], Any], items: Sequence[Any], indices: Sequence[int], tick: Tick, *,
                version: Callable[[], str], key: Hashable, keys: Sequence[Hashable | None],
                workers: int | None = None, pool: WorkerPool | None = None) -> Iterator[tuple[int, Any]]:
        """On the cluster (:func:`scanner.runtime.cluster.extract`)."""
        return cluster.extract(self.client, fn, items, indices, tick, version=version, ship_data=self.ship_data)

    def describe(self) -> str:
        """``dask: 2 worker(s) (2 threads) at tcp://..., dashboard ...``."""
        return f"dask: {cluster.describe(self.client)}"


def _called(fn: Callable[..., Any], call: tuple) -> Any:
    return fn(*call)


def _no_tick(n: int) -> None:
    """No progress to show."""


LOCAL = LocalRuntime()
"""Processes on this machine: the runtime when none was chosen."""

_current: list[Runtime] = [LOCAL]
_lock = threading.Lock()


def current() -> Runtime:
    """The runtime chosen for this process (:func:`using`), else :data:`LOCAL`."""
    return _current[-1]


@contextlib.contextmanager
def using(runtime: Runtime) -> Iterator[Runtime]:
    """Make ``runtime`` current for every thread of this process until the block ends."""
    with _lock:
        _current.append(runtime)
    try:
        yield runtime
    finally:
        with _lock:  # the innermost choice of this runtime (it may be current at several depths)
            del _current[max(i for i, chosen in enumerate(_current) if chosen is runtime)]


@contextlib.contextmanager
def connect(scheduler: str | None = None, *, ship_data: bool = False) -> Iterator[Runtime]:
    """The runtime ``scheduler`` names, made current until the block ends: a Dask cluster for an address
    or ``local:N``, or the one Dask's configuration names (``DASK_SCHEDULER_ADDRESS``, a Dask YAML file);
    else processes on this machine (:func:`scanner.runtime.cluster.connect`). The cluster's client is
    closed on exit (with the LocalCluster of ``local:N``)."""
    with cluster.connect(scheduler) as client:
        runtime = LOCAL if client is None else DaskRuntime(client, ship_data=ship_data)
        with using(runtime):
            yield runtime


@contextlib.contextmanager
def chosen(scheduler: str | None = None, *, workers: int | None = None, ship_data: bool = False) -> Iterator[Runtime]:
    """The runtime a command's or a server's settings choose, current until the block ends: processes on
    this machine for ``workers`` (however Dask is configured), else :func:`connect`'s choice for
    ``scheduler``.

    Raises
    ------
    ClusterError
        Both ``workers`` and ``scheduler`` are given, or the scheduler cannot be reached.
    """
    if workers and scheduler:
        raise cluster.ClusterError("--workers sets processes on this machine, --scheduler a Dask cluster: give one")
    if workers:
        with using(LOCAL):
            yield LOCAL
        return
    with connect(scheduler, ship_data=ship_data) as runtime:
        yield runtime
