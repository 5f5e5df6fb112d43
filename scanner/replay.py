"""Replay of stored scans: the regression suite and the replay device's pacing (docs/devices.md; docs/export.md).

:func:`replay` runs stored ``.mat`` scans through preprocessing and the features (``features.extract``,
which does the preprocessing itself); :func:`predictions` adds a saved model's top classes;
:func:`compare` checks the feature values against an expected feature table (the CSV of
``FeatureSpace.to_csv``) with a relative and an absolute tolerance. ``tests/regression/`` holds a few
simulated scans and their expected values, so every change of a feature's numbers shows up in CI and must
be made on purpose by regenerating the table::

    texplorer replay tests/regression/scans --write-expected tests/regression/expected_features.csv

:func:`paced_steps` plays a stored scan back step by step in real time, on the clock the replay device
(docs/devices.md, :mod:`scanner.acquisition.devices`) plays it with to a guided session: :class:`scanner.pacing.Pacer`.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from features import ScanSource, extract_many
from features.space import FeatureSpace
from scanner.pacing import Pacer
from scanner.scan import CHANNELS, Scan
from scanner.storage.files import is_temp_file
from scanner.storage.matfile import load_scan
from scanner.storage.stored import StoredScan
from taxonomy.errors import TexplorerError
from taxonomy.learning.models import ModelError, TrainedModel, predict_top

DEFAULT_RTOL = 1e-9
"""Relative tolerance of :func:`compare` for closed-form features (sums, FFTs, filters), whose values differ
between machines and library versions only by rounding (~1e-12 relative and below); the features of
iterative fits get the tolerance of their solver (``features.SOLVER_RTOL``)."""
DEFAULT_ATOL = 1e-12
"""Absolute tolerance of :func:`compare`, for expected values at or near zero."""

STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press",
         "fold", "photos")
"""Recorded steps of the scanning procedure in the order of docs/operator.md#procedure (the photos come last)."""


class ReplayError(TexplorerError, ValueError):
    """Replay inputs that cannot be used (no scans found, duplicate scan ids, bad tolerance); one line."""


# -- replay ------------------------------------------------------------------------------------------

def scan_paths(paths: Iterable[str | Path]) -> list[Path]:
    """The ``.mat`` files named by ``paths``: files as given, folders searched recursively (sorted).

    Leftover temporary files of interrupted writes are skipped.
    """
    found: list[Path] = []
    for path in map(Path, paths):
        if path.is_dir():
            found.extend(sorted(p for p in path.rglob("*.mat") if p.is_file() and not is_temp_file(p)))
        elif path.is_file():
            found.append(path)
        else:
            raise ReplayError(f"{path}: no such file or folder")
    if not found:
        raise ReplayError(f"no .mat scans in {', '.join(map(str, paths))}")
    return found


def replay(paths: Sequence[Path], *, workers: int | None = None, progress: bool = True) -> FeatureSpace:
    """The features of the scans stored at ``paths``, extracted by the current code (nothing is cached),
    where the current runtime runs the work (:func:`scanner.runtime.current`: processes here, or a Dask
    cluster whose workers read the files at the same paths or get them from here).

    Parameters
    ----------
    paths : sequence of pathlib.Path
        ``.mat`` files (:func:`scan_paths` expands folders).
    workers : int, optional
        Worker processes (default: the number of cores); each scan is loaded (validated) and extracted there.
    progress : bool
        Show a progress bar.

    Returns
    -------
    features.FeatureSpace
        Rows in the order of ``paths``; scans that fail are listed in ``.failed`` with the reason.
    """
    sources = [ScanSource(str(path), "", "", StoredScan(path)) for path in paths]
    return _identified(extract_many(sources, workers=workers, progress=progress))


def _identified(space: FeatureSpace) -> FeatureSpace:
    """Rows named by the scan id, label and sample stored in each file (extraction named them by path)."""
    metas = [load_scan(path, images=False).meta for path in space.scan_ids]
    return FeatureSpace(space.X, space.columns, [m.scan_id for m in metas], [m.label for m in metas],
                        [m.sample_id for m in metas], space.failed)


def check_unique(space: FeatureSpace) -> None:
    """Refuse two rows with one scan id: expected values are matched by scan id."""
    twice = sorted(scan_id for scan_id, count in Counter(space.scan_ids).items() if count > 1)
    if twice:
        raise ReplayError(f"scan id(s) {', '.join(twice)} appear more than once; replay each scan once")


def predictions(space: FeatureSpace, model: TrainedModel, k: int = 3) -> list[list[tuple[str, float]] | str]:
    """Per row of ``space``: the model's ``k`` most probable classes, or why it cannot classify that scan."""
    results: list[list[tuple[str, float]] | str] = []
    for row in space.X:
        try:
            results.append(predict_top(model, dict(zip(space.columns, row, strict=True)), k))
        except ModelError as exc:
            results.append(str(exc))
    return results


# -- comparison with expected values -----------------------------------------------------------------

@dataclass(frozen=True)
class Difference:
    """One feature value outside the tolerance (NaN on one side only counts as a difference)."""

    scan_id: str
    feature: str
    expected: float
    actual: float

    @property
    def absolute(self) -> float:
        return abs(self.actual - self.expected)

    @property
    def relative(self) -> float:
        """|actual - expected| / |expected| (inf for an expected 0)."""
        return self.absolute / abs(self.expected) if self.expected else math.inf


@dataclass
class Comparison:
    """Result of :func:`compare`; ``ok`` when every expected scan and feature matched within tolerance."""

    compared: int = 0
    differences: list[Difference] = field(default_factory=list)
    missing_scans: list[str] = field(default_factory=list)
    """Scans in the expected table that were not replayed (or failed)."""
    unexpected_scans: list[str] = field(default_factory=list)
    """Replayed scans without expected values."""
    missing_features: list[str] = field(default_factory=list)
    unexpected_features: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not (self.differences or self.missing_scans or self.unexpected_scans or self.missing_features
                    or self.unexpected_features)


def within(actual: np.ndarray, expected: np.ndarray, rtol: float | np.ndarray = DEFAULT_RTOL,
           atol: float = DEFAULT_ATOL) -> np.ndarray:
    """Element-wise ``|actual - expected| <= atol + rtol * |expected|``; NaN matches NaN only.

    The tolerance scales with the expected value, so the check is not symmetric (as ``numpy.isclose``).
    """
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    both_nan = np.isnan(actual) & np.isnan(expected)
    with np.errstate(invalid="ignore"):
        close = np.abs(actual - expected) <= atol + rtol * np.abs(expected)
    return both_nan | close


def compare(space: FeatureSpace, expected: FeatureSpace, rtol: float = DEFAULT_RTOL,
            atol: float = DEFAULT_ATOL, feature_rtol: Mapping[str, float] | None = None,
            scans: Collection[str] | None = None) -> Comparison:
    """Compare replayed features with expected ones, matching rows by scan id and columns by name.

    With ``scans`` (the ids of the scans that were replayed), expected rows of other scans are left out:
    replaying part of a database checks that part, and reports no "missing" scans it was not given.

    ``feature_rtol`` raises the relative tolerance of single features to what their computation
    guarantees (``features.SOLVER_RTOL``: the features of iterative fits); ``rtol`` applies to the others
    and is the floor for all.
    """
    for name, value in (("rtol", rtol), ("atol", atol), *(feature_rtol or {}).items()):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ReplayError(f"{name} must be a finite number >= 0, got {value!r}")
    check_unique(space)
    check_unique(expected)
    given = None if scans is None else set(scans)
    rows = [(row, scan_id) for row, scan_id in enumerate(expected.scan_ids) if given is None or scan_id in given]
    result = Comparison(
        missing_scans=[s for _, s in rows if s not in space.scan_ids],
        unexpected_scans=[s for s in space.scan_ids if s not in expected.scan_ids],
        missing_features=[c for c in expected.columns if c not in space.columns],
        unexpected_features=[c for c in space.columns if c not in expected.columns])
    columns = [c for c in expected.columns if c in space.columns]
    actual_col = [space.columns.index(c) for c in columns]
    expected_col = [expected.columns.index(c) for c in columns]
    column_rtol = np.array([max(rtol, (feature_rtol or {}).get(c, 0.0)) for c in columns])
    for row, scan_id in rows:
        if scan_id not in space.scan_ids:
            continue
        got = space.X[space.scan_ids.index(scan_id), actual_col]
        want = expected.X[row, expected_col]
        ok = within(got, want, column_rtol, atol)
        result.compared += len(columns)
        result.differences.extend(Difference(scan_id, columns[i], float(want[i]), float(got[i]))
                                  for i in np.flatnonzero(~ok))
    return result


def format_comparison(comparison: Comparison, limit: int = 50) -> str:
    """The differences (largest relative difference first), then missing and unexpected scans and features,
    ``limit`` lines of them at most (a last line says how many more there are), and a summary."""
    ordered = sorted(comparison.differences, key=lambda d: (-_sortable(d.relative), d.scan_id, d.feature))
    width = max([28, *(len(d.scan_id) + 1 for d in ordered)])
    items = [f"{d.scan_id:<{width}} {d.feature:<28} {d.expected!r:>24} {d.actual!r:>24} "
             f"{d.absolute:>10.3g} {d.relative:>10.3g}" for d in ordered]
    for what, names in (("missing scan", comparison.missing_scans),
                        ("unexpected scan", comparison.unexpected_scans),
                        ("missing feature", comparison.missing_features),
                        ("unexpected feature", comparison.unexpected_features)):
        items.extend(f"{what:<18} {name}" for name in names)
    lines = []
    if ordered and limit > 0:
        lines.append(f"{'scan':<{width}} {'feature':<28} {'expected':>24} {'actual':>24} "
                     f"{'abs diff':>10} {'rel diff':>10}")
    lines.extend(items[:max(limit, 0)])
    if len(items) > limit:
        lines.append(f"... {len(items) - max(limit, 0)} more line(s) not shown (--max-rows {limit})")
    verdict = "all within tolerance" if comparison.ok else "MISMATCH"
    extra = [f"{len(names)} {what}" for what, names in (("missing scan(s)", comparison.missing_scans),
                                                        ("unexpected scan(s)", comparison.unexpected_scans),
                                                        ("missing feature(s)", comparison.missing_features),
                                                        ("unexpected feature(s)", comparison.unexpected_features))
             if names]
    lines.append(f"{comparison.compared} values compared, {len(comparison.differences)} differ"
                 f"{'; ' + ', '.join(extra) if extra else ''}: {verdict}")
    return "\n".join(lines)


def _sortable(value: float) -> float:
    return math.inf if math.isnan(value) else value


# -- real-time pacing --------------------------------------------------------------------------------

def _step_arrays(scan: Scan, step: str) -> dict[str, np.ndarray]:
    """The traces a step records (and their raw volts as ``<name>_raw``), by channel name."""
    arrays = {name: trace.data for name, trace in scan.traces.items() if CHANNELS[name].step == step}
    arrays.update({f"{name}_raw": trace.data for name, trace in scan.raw.items()
                   if CHANNELS[name].step == step})
    return arrays


def _step_seconds(scan: Scan, step: str) -> float:
    return max((trace.duration for name, trace in (*scan.traces.items(), *scan.raw.items())
                if CHANNELS[name].step == step), default=0.0)


def _sample_at(seconds: float, fs: float, n: int) -> int:
    """Samples recorded before time ``seconds``: those with i / fs < seconds (rounding-safe)."""
    return min(n, max(0, math.ceil(seconds * fs - 1e-6)))


def _chunk_ends(seconds: float, chunk_s: float | None) -> list[float]:
    """End times of the chunks of a step of ``seconds``; the last chunk may be shorter."""
    if chunk_s is None:
        return [seconds]
    count = max(1, math.ceil(seconds / chunk_s - 1e-9))
    return [k * chunk_s for k in range(1, count)] + [seconds]


def _between(data: np.ndarray, fs: float, start: float, end: float, *, last: bool) -> np.ndarray:
    """Samples recorded in [start, end); the last chunk takes everything left."""
    n = len(data)
    return data[_sample_at(start, fs, n):n if last else _sample_at(end, fs, n)]


def _rate(scan: Scan, name: str) -> float:
    return (scan.raw[name.removesuffix("_raw")] if name.endswith("_raw") else scan.traces[name]).fs


def paced_steps(scan: Scan, speed: float = 1.0, *, chunk_s: float | None = None,
                clock: Callable[[], float] = time.monotonic,
                sleep: Callable[[float], None] = time.sleep) -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """Play ``scan`` back as the scanner recorded it: ``(step, {channel: samples})`` in real time.

    Steps come in the procedure's order (:data:`STEPS`); steps the scan lacks are left out. A step's arrays
    are yielded once its duration (its longest channel, ``n / fs``) has passed, divided by ``speed``
    (2.0 = twice as fast, ``math.inf`` = no waiting). With ``chunk_s``, each step comes as consecutive
    chunks of ``chunk_s`` seconds of recording instead, each yielded when its last sample would have been
    recorded, as a live level display needs; concatenating a step's chunks gives its full traces. Raw volts
    come as ``<channel>_raw``. The photos come last as ``("photos", {"I_disp": rgb, ...})`` without waiting.

    Deadlines are measured from the first call on ``clock``, so time spent by the consumer is not added
    to the pacing. ``clock`` and ``sleep`` are replaceable for tests and simulations.

    Examples
    --------
    >>> for step, arrays in paced_steps(scan, speed=4.0):   # doctest: +SKIP
    ...     print(step, {name: a.shape for name, a in arrays.items()})
    """
    if not (isinstance(speed, (int, float)) and speed > 0) or math.isnan(speed):
        raise ReplayError(f"speed must be a positive number, got {speed!r}")
    if chunk_s is not None and not (isinstance(chunk_s, (int, float)) and math.isfinite(chunk_s)
                                    and chunk_s > 0):
        raise ReplayError(f"chunk_s must be a positive number of seconds, got {chunk_s!r}")
    return _paced(scan, float(speed), chunk_s, clock, sleep)


def _paced(scan: Scan, speed: float, chunk_s: float | None, clock: Callable[[], float],
           sleep: Callable[[float], None]) -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    pacer = Pacer(speed, clock=clock, sleep=sleep)  # started at the first next(): the origin of the deadlines
    elapsed = 0.0  # seconds of recording played so far
    for step in STEPS[:-1]:
        arrays = _step_arrays(scan, step)
        if not arrays:
            continue
        seconds = _step_seconds(scan, step)
        start = 0.0
        for end in _chunk_ends(seconds, chunk_s):
            pacer.wait(elapsed + end)
            yield step, {name: _between(data, _rate(scan, name), start, end, last=end == seconds)
                         for name, data in arrays.items()}
            start = end
        elapsed += seconds
    if scan.images:
        yield "photos", dict(scan.images)
