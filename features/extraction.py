"""The features of a scan (docs/features.md) and their parallel, cached extraction into a feature space.

The features are those of the registered families (:mod:`features.registry`), in their order; the paper's
193 (:mod:`features.families`) are registered when this package is imported.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import sys
import warnings
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

import numpy as np
from tqdm import tqdm

from features import tactum
from features.prepared import PreparedScan
from features.registry import REGISTRY, fix_code_version
from features.space import FeatureSpace
from scanner.runtime import cluster, executors
from scanner.runtime.local import WorkerPool
from scanner.runtime.memory import reusing_freed_memory
from scanner.runtime.threads import one_blas_thread
from scanner.scan import Scan
from taxonomy.errors import ParameterError, TexplorerError


def code_version(families: Sequence[str] | None = None) -> str:
    """Hash of the feature code (every registered family's module, this module and what they import): a
    cached feature vector is reused only with the code that computed it. ``families`` (default: the
    default families) adds the chosen families' names and parameters (:meth:`Registry.code_version`).

    Parameters
    ----------
    families : sequence of str, optional
        Names of registered families whose names and parameters count too (default: the default families,
        by their source alone).

    Returns
    -------
    str
        20 hexadecimal digits of a SHA-256 hash.

    Examples
    --------
    The same code gives the same version; choosing other families gives another:

    >>> from features import code_version
    >>> version = code_version()
    >>> len(version), set(version) <= set("0123456789abcdef")
    (20, True)
    >>> code_version() == version, code_version(["signal"]) == version
    (True, False)
    """
    return REGISTRY.code_version(__name__, families=families)


fix_code_version(__name__)  # this module's source and its imports, as imported now


def without_short_channels(scan: Scan) -> Scan:
    """``scan`` without the channels too short for their features (``Scan.short_channels``), with a warning.

    Their features are then NaN like those of a missing channel: a single sample has no spread, no
    relaxation and no cooling curve, and computing them anyway gives silent zeros (docs/features.md).

    Parameters
    ----------
    scan : Scan
        A stored or simulated scan.

    Returns
    -------
    Scan
        ``scan`` itself if no channel is too short, else a copy without the short channels.

    Warns
    -----
    MissingDataWarning
        Naming each short channel, its samples and the samples its features need.

    Examples
    --------
    A cooling curve of 2 samples (its fit needs 3) is left out; the magnetic field of 2 samples is kept:

    >>> import warnings
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.extraction import without_short_channels
    >>> meta = ScanMeta("C6S1M1P2X1", "op", "granite-01", 1, "s1", "2024-01-01T00:00:00")
    >>> scan = Scan(meta, {"t_cool": Trace([30.0, 29.5], 20.0, "degC"), "dB": Trace([0.1, 0.2], 80.0, "uT")})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     kept = without_short_channels(scan)
    >>> list(kept.traces), list(scan.traces)
    (['dB'], ['t_cool', 'dB'])
    >>> print(caught[0].message)
    scan granite-01-001: too short: t_cool (2 of the 3 samples its features need); treated as missing
    """
    short = scan.short_channels()
    if not short:
        return scan
    described = ", ".join(f"{name} ({scan[name].n} of the {need} samples its features need)"
                          for name, need in short.items())
    warnings.warn(f"scan {scan.scan_id}: too short: {described}; treated as missing", tactum.MissingDataWarning,
                  stacklevel=3)  # the caller of features.extract
    return dataclasses.replace(scan, traces={k: v for k, v in scan.traces.items() if k not in short})


T = TypeVar("T")
R = TypeVar("R")

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
        """The values stored for this content and feature code, or None.

        Parameters
        ----------
        content_hash : str
            The scan's content hash (:attr:`ScanSource.cache_key`).
        code_version : str
            The feature code's version (:func:`code_version`).

        Returns
        -------
        dict of str to float or None
            The stored feature values in their order, NaN where a value is undefined; None if nothing is
            stored for this content and code.

        Examples
        --------
        A ``scanner.Database`` keeps the values of one code version; another version finds nothing:

        >>> import math
        >>> import tempfile
        >>> from scanner import Database
        >>> with tempfile.TemporaryDirectory() as folder, Database(folder) as cache:
        ...     cache.store_features("3f2a", "v1", {"other.metal": 1.0, "other.density": math.nan})
        ...     stored, other = cache.cached_features("3f2a", "v1"), cache.cached_features("3f2a", "v2")
        >>> stored["other.metal"], math.isnan(stored["other.density"]), other
        (1.0, True, None)
        """

    def store_features(self, content_hash: str, code_version: str, values: dict[str, float]) -> None:
        """Keep ``values`` for this content and feature code.

        Parameters
        ----------
        content_hash : str
            The scan's content hash (:attr:`ScanSource.cache_key`).
        code_version : str
            The feature code's version (:func:`code_version`).
        values : dict of str to float
            The scan's feature values in their order, NaN where a value is undefined; they replace any
            stored for the same content and code.

        Examples
        --------
        Storing again replaces the values, in a ``scanner.Database``:

        >>> import tempfile
        >>> from scanner import Database
        >>> with tempfile.TemporaryDirectory() as folder, Database(folder) as cache:
        ...     cache.store_features("3f2a", "v1", {"other.metal": -1.0})
        ...     cache.store_features("3f2a", "v1", {"other.metal": 1.0})
        ...     stored = cache.cached_features("3f2a", "v1")
        >>> stored
        {'other.metal': 1.0}
        """


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
    """Wrap an in-memory scan (no cache key: it has no stored content hash).

    Parameters
    ----------
    scan : Scan
        A scan in memory.

    Returns
    -------
    ScanSource
        With the scan's id, label and sample id as the row's identity; ``load`` gives ``scan`` back.

    Examples
    --------
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.extraction import source_of
    >>> scan = Scan(ScanMeta("C6S1M1P2X1", "op", "granite-01", 3, "s1", "2024-01-01T00:00:00"),
    ...             {"dB": Trace([0.1, 0.2], 80.0, "uT")})
    >>> source = source_of(scan)
    >>> source.scan_id, source.label, source.group, source.cache_key, source.load() is scan
    ('granite-01-003', 'C6S1M1P2X1', 'granite-01', None, True)
    """
    return ScanSource(scan.scan_id, scan.meta.label, scan.meta.sample_id, functools.partial(_return, scan))


def extract_source(source: ScanSource,
                   families: tuple[str, ...] | None = None) -> tuple[list[float] | None, str | None]:
    """One scan's step of :func:`run_extraction`: its features in column order, or why they could not be
    computed (the scan's files unreadable or changed, a family's error), so that one broken scan does not stop
    the others.

    Parameters
    ----------
    source : ScanSource
        The scan, loaded here.
    families : tuple of str, optional
        The families to compute (default: the default ones).

    Returns
    -------
    (list of float or None, str or None)
        ``(values, None)``, or ``(None, "<error type>: <message>")``.

    Examples
    --------
    >>> from features.extraction import ScanSource, extract_source
    >>> from scanner.simulation import synthetic_scan
    >>> scan = synthetic_scan("oak-planed", seed=1, image_size=(320, 320))
    >>> values, error = extract_source(ScanSource(scan.scan_id, "C1S1M1P4X1", "oak-01", lambda: scan))
    >>> len(values), error
    (193, None)
    >>> def lost():
    ...     raise FileNotFoundError("oak-01-001.mat")
    >>> extract_source(ScanSource("oak-01-001", "C1S1M1P4X1", "oak-01", lost))
    (None, 'FileNotFoundError: oak-01-001.mat')
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # missing-channel warnings are expected on partial scans
            values = extract(source.load(), families)
    except cluster.NotOnThisMachine:
        raise  # a cluster worker without the scan's files: the client sends them (scanner.runtime.cluster)
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


def with_code(version: str, current: Callable[[], str], extract_one: Callable[[T], tuple[R | None, str | None]],
              item: T) -> tuple[R | None, str | None]:
    """``extract_one(item)`` -- ``(value, None)`` or ``(None, why it failed)`` -- in a worker process, refused
    where the worker's feature code, ``current()``, is not ``version`` (the caller's): a worker started by a
    server (``scanner.runtime.local.start_workers_from_a_server``) imported the code when that server started,
    which may be after the caller imported it and the files changed.

    Parameters
    ----------
    version : str
        The calling process's feature code version.
    current : callable returning str
        The feature code version of the process this runs in (:func:`code_version` of the families).
    extract_one : callable
        Extracts one item; ``(value, None)``, or ``(None, reason)`` where the item failed.
    item : object
        The item.

    Returns
    -------
    (value or None, str or None)
        ``extract_one(item)``, or ``(None, reason)`` where the code differs.

    Examples
    --------
    >>> from features.extraction import with_code
    >>> with_code("abc", lambda: "abc", lambda x: (x * 2, None), 21)
    (42, None)
    >>> with_code("abc", lambda: "def", lambda x: (x * 2, None), 21)[1]  # doctest: +ELLIPSIS
    'this worker runs feature code def, the calling process abc: the code changed on disk since the process ...'
    """
    if current() != version:
        return None, (f"this worker runs feature code {current()}, the calling process {version}: "
                      "the code changed on disk since the process started; restart it")
    return extract_one(item)


def run_extraction(extract_one: Callable[[T], tuple[R | None, str | None]], items: Sequence[T],
                   indices: Sequence[int], current: Callable[[], str], *, key: Hashable,
                   keys: Sequence[Hashable | None] | None = None, workers: int | None = None,
                   pool: WorkerPool | None = None, progress: bool = True,
                   unit: str = "scan") -> Iterator[tuple[int, tuple[R | None, str | None]]]:
    """The one way the features of scans and of recordings are computed: ``(indices[i], extract_one(items[i]))``
    for every item, in completion order, where the current runtime runs the work
    (:func:`scanner.runtime.current`: this machine's processes, kept between calls, or a Dask cluster), each
    result from the feature code of this process (:func:`with_code`; a cluster stops the run), an item that
    fails reported as ``(None, reason)`` while the others go on, with a progress bar; leaving early (Ctrl-C,
    an error) ends the workers' tasks at once.

    Parameters
    ----------
    extract_one : callable
        Extracts one item in a worker: ``(value, None)``, or ``(None, reason)`` where the item failed. It and
        the items are pickled to the workers.
    items : sequence
        ``ScanSource``-like items (a ``load`` attribute giving what to extract where it is processed).
    indices : sequence of int
        The items' indices, given back with their results.
    current : callable returning str
        The feature code version of the families computed (:func:`code_version`), asked here and in each
        worker.
    key : hashable
        Names the work as a whole, beside the feature code version: workers kept for other work, or for other
        feature code, are not used.
    keys : sequence of hashable or None, optional
        Each item's work, for a server's shared workers (the same work queued twice runs once).
    workers : int, optional
        Processes of this machine (default: the number of cores; 1 = in this process).
    pool : WorkerPool, optional
        Workers of this machine kept across the calls of a job (default: the process's shared workers).
    progress : bool
        Show a progress bar.
    unit : str
        What an item is, for the progress bar.

    Yields
    ------
    (int, (value or None, str or None))
        Each item's index and result.

    Examples
    --------
    >>> from features.extraction import run_extraction
    >>> class Item:
    ...     def __init__(self, value):
    ...         self.load = lambda: value
    >>> def halve(item):
    ...     value = item.load()
    ...     return (value / 2, None) if value else (None, "nothing to halve")
    >>> sorted(run_extraction(halve, [Item(4), Item(0)], [0, 1], lambda: "v1", key="halves", workers=1,
    ...                       progress=False))
    [(0, (2.0, None)), (1, (None, 'nothing to halve'))]
    """
    bar = _Bar(total=len(items), desc="features", unit=unit, file=sys.stderr, disable=None if progress else True,
               leave=False)
    version = current()
    results = executors.current().extract(
        functools.partial(with_code, version, current, extract_one), items, indices, bar.update, version=current,
        key=(version, key), keys=[None] * len(items) if keys is None else keys, workers=workers, pool=pool)
    try:
        with contextlib.closing(results):  # leaving early (Ctrl-C) ends the workers' tasks now, not at exit
            yield from results
    finally:
        bar.close()


def extract_many(scans: Iterable[Scan | ScanSource], workers: int | None = None, *,
                 cache: FeatureCache | None = None, progress: bool = True, pool: WorkerPool | None = None,
                 families: Sequence[str] | None = None) -> FeatureSpace:
    """Features of many scans as a :class:`FeatureSpace`, rows in input order.

    A scan that fails is reported in ``FeatureSpace.failed`` with its id and the reason, the others are kept.
    With a ``cache``, sources with a ``cache_key`` (the scan's content hash) are looked up first and stored
    after, keyed by :func:`code_version` too, so a second run over unchanged scans only reads the cache. A
    cached row is served only once the source's files are verified to be the bytes it was computed from (a
    stored scan's ``load.verify()``: their SHA-256), and a stored scan is extracted only from its catalogued
    bytes: a file changed since it was stored fails its row, naming the file, and nothing is cached. The
    uncached scans are extracted where the current runtime runs the work (:func:`scanner.runtime.current`:
    this machine's processes, or a Dask cluster chosen by the command), with the same results.

    Parameters
    ----------
    scans : iterable of Scan or ScanSource
        Scans, or sources that load them where they are extracted (with label, group and cache key).
    workers : int, optional
        Processes of this machine (default: the number of cores; 1 = in this process), kept for the next
        call (:data:`scanner.runtime.local.KEEP_WORKERS_S`; ``release_workers`` ends them at once); a
        cluster has its own.
    cache : FeatureCache, optional
        Where cached rows are read and new ones written (a ``scanner.Database``); only this process uses it.
    progress : bool
        Show a progress bar.
    pool : WorkerPool, optional
        Workers of this machine kept across the calls of a job that extracts in batches (default: the
        process's shared workers, if it has them).
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
    if pool is not None and not pool.shared and workers not in (None, pool.size):
        raise ParameterError(f"workers={workers} with a pool of {pool.size} workers")
    sources = [s if isinstance(s, ScanSource) else source_of(s) for s in scans]
    families = None if families is None else tuple(f.name for f in REGISTRY.chosen(families))
    names = REGISTRY.columns_of(families)
    version = code_version(families)
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
    results = run_extraction(
        functools.partial(extract_source, families=families), [sources[i] for i in todo], todo,
        functools.partial(code_version, families), key=(names, _working_directory()),
        keys=[(version, sources[i].cache_key) if sources[i].cache_key else None for i in todo],
        workers=workers, pool=pool, progress=progress)
    with contextlib.closing(results):  # an error here (the cache's disk full) ends the workers' tasks now
        for i, (row, error) in results:
            if error is not None:
                errors[i] = error
                continue
            rows[i] = row
            if cache is not None and sources[i].cache_key:
                cache.store_features(sources[i].cache_key, version, dict(zip(names, row, strict=True)))
    kept = [i for i in range(len(sources)) if rows[i] is not None]
    return FeatureSpace(
        X=np.array([rows[i] for i in kept], dtype=np.float64).reshape(len(kept), len(names)),
        columns=names,
        scan_ids=[sources[i].scan_id for i in kept],
        label_text=[sources[i].label for i in kept],
        groups=[sources[i].group for i in kept],
        failed=[(sources[i].scan_id, errors[i]) for i in sorted(errors)],
    )


WORKER_SERVER_PRELOAD = ("features", "scanner.storage.stored")
"""Modules a worker server imports once (``scanner.runtime.local.start_workers_from_a_server``), so that
each worker it forks starts with them loaded."""


def _working_directory() -> str | None:
    """The working directory of this process, None where it was removed (its scans' relative paths are then
    found nowhere, by kept workers or new ones)."""
    try:
        return os.getcwd()
    except OSError:
        return None
