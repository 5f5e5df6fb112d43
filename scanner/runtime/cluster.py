"""Feature extraction and evaluation on a Dask cluster (``dask.distributed``) when one machine is not enough.

Where the work runs is decided once per command by :func:`connect`:

- nothing given: processes on this machine (the worker processes ``extract_many`` keeps, which also run
  the evaluation grid's folds: ``worker_map``), as without Dask;
- a running Dask scheduler, named by ``--scheduler tcp://HOST:PORT`` or by Dask's own configuration
  (``scheduler-address``: the ``DASK_SCHEDULER_ADDRESS`` environment variable or a Dask YAML file), so a
  lab that already runs Dask changes nothing;
- ``local:N``: a ``LocalCluster`` of N single-threaded worker processes on this machine, with Dask's
  dashboard.

The process that connects (the client) alone reads the catalog and writes the feature cache: workers only
compute and return numbers, so SQLite is never written from two machines. Cached features are looked up
before anything is submitted. Every task runs the same functions as a local process does, so results
equal the local run bit for bit; they are yielded in completion order and placed by their index.

Where the data lives (:func:`extract`): a worker reads a stored scan from the path the client names when
it sees the catalogued bytes there (shared storage); otherwise the client reads the files and sends them
(``ship_data``, chosen automatically when a worker cannot see the path, and per scan for a worker that
joins later). A worker that dies costs its tasks a rerun elsewhere (Dask's scheduler reruns a task up to
``distributed.scheduler.allowed-failures`` times, then the scan is reported as failed). When the scheduler
has had no worker at all for :func:`no_workers_timeout` seconds while tasks wait (every worker died or
left), the run stops with a :class:`ClusterError` naming the scheduler instead of waiting for good. Leaving
a run early (Ctrl-C, an error) cancels every task still submitted.
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import logging
import math
import os
import signal
import site
import sys
import threading
import time
import uuid
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

from threadpoolctl import threadpool_limits

from scanner.lazy import optional
from taxonomy.errors import NotOnThisMachine, TexplorerError

if TYPE_CHECKING:
    from distributed import Client, Future

LOCAL = "local"
"""``local`` or ``local:N``: a LocalCluster of N worker processes here (default: one per core)."""

NO_WORKERS_TIMEOUT = 30.0
"""Seconds a run waits for a worker while its scheduler has none (all died or left) before it stops:
long enough for Dask's nanny to restart a killed worker (a second or two) or an adaptive cluster to start
one; ``$TEXPLORER_DASK_NO_WORKERS_TIMEOUT`` sets another bound."""
NO_WORKERS_ENV = "TEXPLORER_DASK_NO_WORKERS_TIMEOUT"
WORKER_CHECK_INTERVAL = 1.0
"""Seconds between two questions to the scheduler, while waiting for results, whether it has a worker."""

SHIP_WINDOW_PER_THREAD = 2
"""Scans whose files are in flight per worker thread when the client sends them: enough to keep every
worker busy while the next files travel, few enough to bound the memory of the client and the workers."""

Item = TypeVar("Item")


class ClusterError(TexplorerError, ValueError):
    """The cluster cannot run the work as asked (no Dask, unreachable scheduler, mismatched workers)."""


class DataShipped(UserWarning):
    """Workers do not see the database's files, so the client sends each scan's bytes."""


# -- connecting --------------------------------------------------------------------------------------

def _distributed():
    return optional("distributed", "cluster", "running on a Dask cluster", error=ClusterError)


def scheduler_address(scheduler: str | None = None) -> str | None:
    """The scheduler to use: ``scheduler`` if given, else Dask's configured ``scheduler-address``
    (``DASK_SCHEDULER_ADDRESS``, a Dask YAML file, or ``dask.config.set`` in this process), else None for
    processes on this machine. Dask is imported for the question only where it could answer something
    (:func:`dask_configuration_exists`, or Dask already imported)."""
    if scheduler:
        return scheduler.strip()
    if "dask.config" not in sys.modules and not dask_configuration_exists():
        return None  # nothing could name one: no need to import Dask (some 0.2-0.4 s of every command's start)
    try:
        dask_config = optional("dask.config", "cluster", "a Dask scheduler address")
    except ImportError:  # not installed, or broken: no scheduler named by it
        if os.environ.get("DASK_SCHEDULER_ADDRESS"):
            _distributed()  # the user asked for Dask: say what is missing
        return None
    return dask_config.get("scheduler-address", None) or None


CONFIGURATION_SUFFIXES = (".json", ".yaml", ".yml")


def dask_configuration_exists(environ: Mapping[str, str] | None = None) -> bool:
    """Whether Dask could find any configuration of its own: a ``DASK_*`` environment variable, or a
    YAML or JSON file in one of the places Dask reads (``$DASK_ROOT_CONFIG`` or ``/etc/dask``,
    ``<prefix>/etc/dask`` of this Python and of its site prefixes, ``~/.config/dask``, ``$DASK_CONFIG``).
    False only where none exists: then no scheduler address is configured, and Dask need not be imported
    to say so."""
    environ = os.environ if environ is None else environ
    if any(key.startswith("DASK_") for key in environ):
        return True
    places = [environ.get("DASK_ROOT_CONFIG", "/etc/dask"), os.path.join(sys.prefix, "etc", "dask"),
              *(os.path.join(prefix, "etc", "dask") for prefix in site.PREFIXES),
              os.path.join(os.path.expanduser("~"), ".config", "dask")]
    for place in places:
        if os.path.isfile(place):
            return True
        with contextlib.suppress(OSError):
            if any(os.path.splitext(name)[1].lower() in CONFIGURATION_SUFFIXES for name in os.listdir(place)):
                return True
    return False


def local_workers(address: str) -> int | None:
    """N of ``local:N`` (None for ``local``: one worker per core); ClusterError for anything else."""
    _, _, count = address.partition(":")
    if not count:
        return None
    if not count.isdigit() or int(count) < 1:
        raise ClusterError(f"--scheduler {address}: expected local:N with N >= 1 worker processes")
    return int(count)


@contextlib.contextmanager
def connect(scheduler: str | None = None) -> Iterator[Client | None]:
    """A ``distributed.Client`` for the scheduler :func:`scheduler_address` names, closed on exit (with
    the LocalCluster of ``local:N``); None when no scheduler is named or configured."""
    address = scheduler_address(scheduler)
    if address is None:
        yield None
        return
    distributed = _distributed()
    if address == LOCAL or address.startswith(LOCAL + ":"):
        n = local_workers(address)
        # Errors only: a cancelled task's warnings (Ctrl-C) are not news; the dashboard shows the rest.
        with distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, preload=[__name__],
                                      silence_logs=logging.ERROR) as cluster, distributed.Client(cluster) as client:
            yield client
        return
    try:  # waits as long as Dask's distributed.comm.timeouts.connect (30 s unless configured)
        client = distributed.Client(address)
    except (OSError, ValueError, TypeError) as exc:
        raise ClusterError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    with client:
        yield client


def dask_setup(worker: Any) -> None:
    """Run by each worker of ``local:N`` as it starts (a Dask preload): ignore Ctrl-C.

    The workers share the terminal, whose Ctrl-C is meant for texplorer; texplorer then cancels the work
    and closes the cluster with its workers. Left alone, every worker would also print a traceback.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def no_workers_timeout() -> float:
    """``$TEXPLORER_DASK_NO_WORKERS_TIMEOUT`` (seconds, > 0) or :data:`NO_WORKERS_TIMEOUT`."""
    text = os.environ.get(NO_WORKERS_ENV, "").strip()
    if not text:
        return NO_WORKERS_TIMEOUT
    try:
        seconds = float(text)
    except ValueError:
        seconds = math.nan
    if not (math.isfinite(seconds) and seconds > 0):
        raise ClusterError(f"${NO_WORKERS_ENV} must be a positive number of seconds, got {text!r}")
    return seconds


def worker_count(client: Client) -> int:
    """How many workers the client's scheduler has now; a ClusterError naming it if it does not answer."""
    try:
        return len(client.nthreads(callback_timeout=max(10.0, WORKER_CHECK_INTERVAL)))
    except (OSError, TimeoutError) as exc:
        raise ClusterError(f"the Dask scheduler at {_address(client)} does not answer ({type(exc).__name__}: "
                           f"{exc})") from None


def _address(client: Client) -> str:
    scheduler = getattr(client, "scheduler", None)
    return getattr(scheduler, "address", None) or "?"


def completions(client: Client, completed: Any, patience: float | None = None) -> Iterator[Future]:
    """The futures of ``completed`` (a ``distributed.as_completed``, which may grow meanwhile) as they finish.

    While none is ready the scheduler is asked every :data:`WORKER_CHECK_INTERVAL` s whether it has a
    worker: a task waits for one as long as it takes, so a cluster whose workers all died would wait for
    good. When it has had none for ``patience`` seconds (:func:`no_workers_timeout`), a ClusterError
    names the scheduler and how many tasks were waiting.
    """
    patience = no_workers_timeout() if patience is None else patience
    alone_since: float | None = None
    next_check = time.monotonic() + WORKER_CHECK_INTERVAL
    while not completed.is_empty():
        if completed.has_ready():
            yield next(completed)
            continue
        now = time.monotonic()
        if now >= next_check:
            next_check = now + WORKER_CHECK_INTERVAL
            if worker_count(client):
                alone_since = None
            else:
                alone_since = now if alone_since is None else alone_since
                if now - alone_since >= patience:
                    raise ClusterError(f"the Dask scheduler at {_address(client)} has had no worker for "
                                       f"{now - alone_since:.0f} s (they died or left) and {completed.count()} "
                                       f"task(s) wait: start workers, or run without --scheduler")
        time.sleep(0.02)  # as_completed's own wait polls too (0.1 s)


def scatter(client: Client, data: Any) -> Any:
    """``client.scatter(data, hash=False)``, waiting at most :func:`no_workers_timeout` seconds for a running
    worker to hold the data; a ClusterError naming the scheduler when none came."""
    patience = no_workers_timeout()
    try:
        return client.scatter(data, hash=False, timeout=patience)
    except TimeoutError:
        raise ClusterError(f"the Dask scheduler at {_address(client)} had no running worker to send the data "
                           f"to for {patience:.0f} s (they died or left): start workers, or run without "
                           "--scheduler") from None


def describe(client: Client) -> str:
    """``2 workers (2 threads) at tcp://127.0.0.1:8786, dashboard http://127.0.0.1:8787/status``."""
    threads = client.nthreads()
    dashboard = client.dashboard_link if client.scheduler_info().get("services", {}).get("dashboard") else None
    return (f"{len(threads)} worker(s) ({sum(threads.values())} threads) at {client.scheduler.address}"
            + (f", dashboard {dashboard}" if dashboard else ", no dashboard"))


# -- running tasks -----------------------------------------------------------------------------------

def run(client: Client, fn: Callable[..., Any], calls: Sequence[tuple], *, name: str,
        tick: Callable[[int], object] | None = None) -> Iterator[tuple[int, Any]]:
    """``(i, fn(*calls[i]))`` for every call, each a task on the cluster, in completion order.

    Arguments may be futures (``client.scatter``) that several calls share. An exception raised by a
    call is raised here; leaving the iteration early (Ctrl-C, an error) cancels what is left.
    """
    distributed = _distributed()
    token = uuid.uuid4().hex
    futures = {client.submit(pinned, fn, *args, key=f"{name}-{token}-{i}", pure=False): i
               for i, args in enumerate(calls)}
    try:
        for future in completions(client, distributed.as_completed(futures, loop=client.loop)):
            result = future.result()
            if tick is not None:
                tick(1)
            yield futures.pop(future), result
    finally:
        _cancel(client, futures)


def pinned(fn: Callable[..., Any], *args: Any) -> Any:
    """On a worker: ``fn(*args)`` with BLAS on one thread for good, as in a process of this machine.

    Not restored afterwards: tasks in other threads of the worker must never see a limit being lifted
    (``threadpool_limits`` changes the whole process).
    """
    threadpool_limits(limits=1)
    return fn(*args)


def _cancel(client: Client, futures: Iterable[Future]) -> None:
    pending = [f for f in futures if not f.done()]
    if pending:
        client.cancel(pending)


# -- feature extraction ------------------------------------------------------------------------------

class StoredLoader(Protocol):
    """A ``ScanSource.load`` that reads stored files (``scanner.storage.stored.StoredScan``)."""

    path: Any

    def __call__(self) -> Any:
        """The scan, loaded here from its files."""

    def load_seen(self) -> Any:
        """The scan from this machine's view of its path; ``NotOnThisMachine`` if it differs."""

    def visible(self) -> bool:
        """Whether this machine sees the scan's files as catalogued."""

    def shipped(self) -> Callable[[], Any]:
        """A loader that carries the files' bytes to a worker that cannot see them."""


def _stored(source: Any) -> StoredLoader | None:
    load = source.load
    return load if all(callable(getattr(load, m, None)) for m in ("load_seen", "visible", "shipped")) else None


def _versioned(fn: Callable[[Item], Any], version: Callable[[], str], item: Item) -> tuple[Any, str, str]:
    """On a worker: ``fn(item)`` (BLAS pinned as by :func:`pinned`), the worker's feature code version and
    its address."""
    return pinned(fn, item), version(), _distributed().get_worker().address


def blind_workers(client: Client, loader: StoredLoader) -> list[str]:
    """Workers that do not see ``loader``'s stored file as the client does (each reads it once)."""
    answers = client.run(loader.visible)
    return sorted(worker for worker, seen in answers.items() if not seen)


def extract(client: Client, fn: Callable[[Item], Any], sources: Sequence[Item], indices: Sequence[int],
            tick: Callable[[int], object], *, version: Callable[[], str],
            ship_data: bool = False) -> Iterator[tuple[int, Any]]:
    """``(index, fn(source))`` for every source, computed on the cluster, in completion order.

    ``sources`` are ``ScanSource``-like (a ``load`` attribute). Stored scans are read by the workers from
    the path the client names, unless ``ship_data`` or a worker does not see the first one as catalogued
    (:func:`blind_workers`, with a :class:`DataShipped` warning): then the client reads each scan's files
    and scatters them to a worker, at most :data:`SHIP_WINDOW_PER_THREAD` per worker thread at a time. A
    task whose worker cannot see its scan (``NotOnThisMachine``) is sent again with the bytes. Other
    sources (scans in memory) travel with their task. Every result must come from the feature code
    ``version()`` of this machine, or the run stops with a :class:`ClusterError`. A scan whose task
    killed its workers is reported as its failure ``(None, reason)``, and so is one whose files were
    lost with their worker more often than Dask's ``allowed-failures`` (each loss sends them again).
    """
    distributed = _distributed()
    dask_config = optional("dask.config", "cluster", "running on a Dask cluster", error=ClusterError)
    if not ship_data:
        first = next((loader for loader in map(_stored, sources) if loader is not None), None)
        blind = blind_workers(client, first) if first is not None else []
        if blind:
            warnings.warn(f"{len(blind)} Dask worker(s) do not see {first.path} as catalogued "
                          f"({', '.join(blind)}); this machine sends each scan's files", DataShipped,
                          stacklevel=3)
            ship_data = True
    expected = version()
    allowed_losses = int(dask_config.get("distributed.scheduler.allowed-failures"))
    losses: dict[int, int] = {}
    token, submissions = uuid.uuid4().hex, itertools.count()
    queue = deque((index, source, ship_data) for index, source in zip(indices, sources, strict=True))
    in_flight: dict[Future, tuple[int, Any, bool]] = {}
    completed = distributed.as_completed(loop=client.loop)

    def submit() -> None:
        window = None
        while queue:
            index, source, ship = queue[0]
            heavy = _heavy(source, ship)
            if heavy:
                window = window or _ship_window(client)
                if sum(_heavy(s, sh) for _, s, sh in in_flight.values()) >= window:
                    return
            queue.popleft()
            payload = _payload(source, ship)
            if heavy:
                payload = _scatter(client, payload, allowed_losses + 1)
            # A key per submission: one sent again must not meet the cancelled future of its first key.
            future = client.submit(_versioned, fn, version, payload,
                                   key=f"texplorer-extract-{token}-{next(submissions)}", pure=False)
            in_flight[future] = (index, source, ship)
            completed.add(future)

    try:
        submit()
        for future in completions(client, completed):
            index, source, ship = in_flight.pop(future)
            try:
                result, worker_version, worker = future.result()
            except NotOnThisMachine:
                queue.appendleft((index, source, True))
                submit()
                continue
            except distributed.CancelledError:
                if not _heavy(source, ship):
                    raise  # cancelled by someone else
                losses[index] = losses.get(index, 0) + 1
                if losses[index] <= allowed_losses:  # the worker holding its scattered data died: send it again
                    queue.appendleft((index, source, ship))
                    submit()
                    continue
                result = None, (f"KilledWorker: {losses[index]} Dask workers holding its data died before "
                                f"its features came back; see their logs")
            except distributed.KilledWorker as exc:
                result = None, (f"KilledWorker: {exc.allowed_failures + 1} Dask workers died while extracting "
                                f"its features (the last {exc.last_worker.address}); see their logs")
            else:
                if worker_version != expected:
                    raise ClusterError(f"Dask worker {worker} runs feature code {worker_version}, this machine "
                                       f"{expected}: install the same texplorer on the workers")
            tick(1)
            yield index, result
            submit()
    finally:
        _cancel(client, in_flight)


def _payload(source: Any, ship: bool) -> Any:
    """What a task gets: the source reading the worker's view of its files, or carrying their bytes."""
    loader = _stored(source)
    if loader is None:
        return source
    return dataclasses.replace(source, load=loader.shipped() if ship else loader.load_seen)


def _scatter(client: Client, payload: Any, attempts: int) -> Future:
    """``client.scatter``, again when the worker it sent the data to died meanwhile."""
    for attempt in range(1, attempts):
        try:
            return scatter(client, payload)
        except OSError:  # the dying worker's connection closed; the scheduler soon stops choosing it
            time.sleep(0.1 * attempt)
    return scatter(client, payload)


def _heavy(source: Any, ship: bool) -> bool:
    """Whether a task carries scan data (files sent by the client, or a scan in memory)."""
    return ship or _stored(source) is None


def _ship_window(client: Client) -> int:
    return SHIP_WINDOW_PER_THREAD * max(1, sum(client.nthreads().values()))
