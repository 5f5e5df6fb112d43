"""A common time base for the streams of one recording: samples on a shared grid, gaps bridged,
streams cut to their common time span.
"""

from __future__ import annotations

import datetime
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from scanner.scan import ScanError, Trace
from scanner.storage.ingest.mapping import IngestError
from scanner.storage.ingest.readers import HELD_ITEMSIZE, RATE_TOLERANCE, Note, Stream

GAP_STEPS = 1.5
"""A time step longer than this many sample periods is a gap: at least one sample is missing."""
MAX_BRIDGED_BYTES = 1 << 28
"""Bridging is bounded in memory, not relative to the stream: the samples a channel's gaps add to the
common grid may take at most 256 MiB as held (float64, every column counted), 33.5 million samples of a
one-column channel (93 hours at 100 Hz, 12.7 minutes at 44.1 kHz). A USB sensor's stream with a gap every
few samples is kept however much it is bridged; a jump of the clock (a 5-line CSV whose timestamps jump by
4e9 s would ask for 3.2 TB) refuses the file, naming the gap."""


def check_bridged_length(name: str, stream: Stream, count: int, file: str) -> None:
    """Refuse a stream whose gaps would add more than :data:`MAX_BRIDGED_BYTES` of samples to its
    ``count`` samples on the common grid, before any grid is made."""
    assert stream.times is not None
    real = int(stream.times.size)
    width = int(np.prod(stream.data.shape[1:], dtype=np.int64)) if stream.data.ndim > 1 else 1
    added = count - real
    if added * width * HELD_ITEMSIZE > MAX_BRIDGED_BYTES:
        steps = np.diff(stream.times)
        at = int(np.argmax(steps)) if steps.size else 0
        raise IngestError(f"{file}: channel {name}: a gap of {float(steps[at]) if steps.size else 0.0:.6g} s at "
                          f"t = {float(stream.times[at]):.6g} s would bridge {added:,} samples into "
                          f"{real:,} real ones (at most {MAX_BRIDGED_BYTES >> 20} MiB of bridged samples "
                          "per channel)")


EPOCH_AFTER_S = 1e8
"""Timestamps beyond this many seconds (March 1973 as Unix time) are taken as Unix times in notes."""


def moment(t: float) -> str:
    """A timestamp for a note: a UTC date and time for a Unix time, else seconds (``t = 0.295 s``)."""
    if abs(t) >= EPOCH_AFTER_S:
        stamp = datetime.datetime.fromtimestamp(t, datetime.UTC)
        return stamp.strftime("%Y-%m-%d %H:%M:%S.") + f"{stamp.microsecond // 1000:03d} UTC"
    return f"t = {t:.6g} s"


def span(start: float, stop: float) -> str:
    """A time span for a note: its start and its length."""
    return f"{stop - start:.6g} s from {moment(start)}"


def _on_grid(times: np.ndarray, grid: np.ndarray, step: float) -> int | None:
    """The index of the sample at ``grid[0]`` if the samples from there lie on the grid, else None."""
    first = int(np.searchsorted(times, grid[0] - 1e-6 * step))
    chosen = times[first:first + grid.size]
    if chosen.size == grid.size and np.all(np.abs(chosen - grid) <= 1e-6 * step):
        return first
    return None


def _interpolated(stream: Stream, grid: np.ndarray) -> np.ndarray:
    """The stream's values at the grid times, linear between samples (each column on its own)."""
    assert stream.times is not None
    flat = stream.data.reshape(stream.data.shape[0], -1)
    columns = [np.interp(grid, stream.times, flat[:, k]) for k in range(flat.shape[1])]
    return np.stack(columns, axis=1).reshape((grid.size, *stream.data.shape[1:]))


def gaps(times: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Start times and lengths (s) of the gaps in a timestamp column: steps longer than 1.5 periods."""
    steps = np.diff(times)
    where = np.flatnonzero(steps > GAP_STEPS * step)
    return times[where], steps[where]


@dataclass(frozen=True)
class Aligned:
    """Streams on a common time base: traces, notes and what was done (``meta["time_base"]``)."""

    traces: dict[str, Trace]
    notes: list[Note]
    info: dict[str, Any]


def align(streams: Mapping[str, Stream], files: Mapping[str, str], missing: str = "interpolate") -> Aligned:
    """Put the timestamped streams of one recording on a common time base.

    A sample stands for the period from its time to the next one, so a stream covers ``[first time, last
    time + 1 / rate)``. Every stream with timestamps is cut to the span all of them cover and sampled on
    its own grid ``t0 + k / rate`` from the common start ``t0``: sample
    k of every stream then means the same moment. A stream whose samples already lie on that grid (to
    1e-6 of a period) is taken as it is; otherwise it is resampled by linear interpolation, with a note.
    A step longer than 1.5 periods is a gap: the grid samples inside it are bridged by the interpolation
    (at most :data:`MAX_BRIDGED_BYTES` per channel; more refuse the file) and reported
    (``missing = "interpolate"``) or the recording is refused (``missing = "error"``), never
    filled silently. Streams without timestamps are taken as they are. ``files`` names each stream's file.
    """
    timed = {name: s for name, s in streams.items() if s.times is not None}
    traces: dict[str, Trace] = {}
    notes: list[Note] = []
    info: dict[str, Any] = {}
    if timed:
        start = max(float(s.times[0]) for s in timed.values())
        stop = min(float(s.times[-1]) + 1.0 / s.rate for s in timed.values())
        if stop <= start:
            spans = ", ".join(f"{n} {span(s.times[0], s.times[-1])}" for n, s in timed.items())
            raise IngestError(f"the timestamped streams do not overlap in time ({spans})")
        info = {"start_s": start, "seconds": stop - start, "channels": {}}
    for name, stream in streams.items():
        data = stream.data
        if stream.times is not None:
            data, channel_notes, channel_info = _on_common_grid(name, stream, start, stop, files[name], missing)
            notes += channel_notes
            info["channels"][name] = channel_info
        try:
            traces[name] = Trace(data, stream.rate, stream.unit)
        except ScanError as exc:
            raise IngestError(f"{files[name]}: channel {name}: {exc}") from None
    if len(timed) > 1:
        cut = [n for n, s in timed.items() if s.times[0] < start - 0.5 / s.rate or s.times[-1] > stop - 0.5 / s.rate]
        if cut:
            notes.append(Note("aligned", files[cut[0]], len(cut), f"{files[cut[0]]}: channel(s) {', '.join(cut)} "
                              f"cut to the span ({span(start, stop)}) that {', '.join(timed)} share"))
    return Aligned(traces, notes, info)


def _on_common_grid(name: str, stream: Stream, start: float, stop: float, file: str,
                    missing: str) -> tuple[np.ndarray, list[Note], dict[str, Any]]:
    assert stream.times is not None
    step = 1.0 / stream.rate
    count = max(1, int(math.floor((stop - start) * stream.rate + 1e-6)))
    check_bridged_length(name, stream, count, file)
    grid = start + np.arange(count) * step
    notes = []
    gap_start, gap_length = gaps(stream.times, step)
    inside = (gap_start >= start - step) & (gap_start < stop)
    gap_start, gap_length = gap_start[inside], gap_length[inside]
    bridged = int(sum(np.count_nonzero((grid > t + 0.5 * step) & (grid < t + length - 0.5 * step))
                      for t, length in zip(gap_start, gap_length, strict=True)))
    if gap_start.size:
        longest = int(np.argmax(gap_length))
        text = (f"{file}: channel {name}: {gap_start.size} gap(s) in the timestamps, {bridged} sample(s) "
                f"missing; the longest {gap_length[longest]:.4g} s at {moment(gap_start[longest])}")
        if missing == "error":
            raise IngestError(text)
        notes.append(Note("gap", file, float(gap_length[longest]), text + " (bridged linearly)"))
    first = None if gap_start.size else _on_grid(stream.times, grid, step)
    if first is not None:
        data = stream.data[first:first + count]
    else:
        data = _interpolated(stream, grid)
        steps = np.diff(stream.times)
        regular = steps[steps <= GAP_STEPS * step]
        spread = float(np.max(np.abs(regular - step)) / step) if regular.size else 0.0
        if spread > RATE_TOLERANCE:
            notes.append(Note("irregular", file, spread, f"{file}: channel {name}: time steps vary by up to "
                              f"{100 * spread:.0f} %; resampled to {stream.rate:.6g} Hz"))
    info = {"resampled": first is None, "gaps": int(gap_start.size), "bridged_samples": bridged,
            "longest_gap_s": float(gap_length.max()) if gap_length.size else 0.0}
    if stream.clock is not None:
        info["clock"] = stream.clock
    return data, notes, info

