"""Timestamps that are a regular clock plus jitter: recognised, and the samples kept as the regular stream
they are.

A sensor sampled by its own clock at a fixed rate but logged with the host's receive times (a USB
tactile sensor at 100 Hz, say) carries timestamps ``t_k = a + n_k T + e_k``: sample k sits in slot
``n_k`` of a clock of period ``T``, and ``e_k`` is the host's jitter, unrelated to when the sensor sampled.
Resampling such a stream at its timestamps would mix neighbouring samples by the jitter, a low-pass filter
of random strength. :func:`regular_clock` instead fits the clock: slots ``n_k = round((t_k - a) / T)`` and a
least-squares line ``t = a + T n`` through them (fitting a line to the time of each sample against its index
is the usual way to recover a sampling clock from receive times; e.g. Moon et al. 1999, "Estimation and
removal of clock skew from network delay measurements"). The stream is a regular clock when the residual
jitter is small against the period and few slots are empty (dropped samples) or doubly filled (duplicated
samples); then the samples are placed in their slots, the duplicates dropped and the dropped samples bridged
linearly, all reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

JITTER_MAD = 0.15
"""Largest median absolute residual, in periods, of a regular clock's timestamps. White jitter of 0.2
periods rms has a median absolute residual of 0.13; timestamps spread uniformly over the period (no clock)
0.25."""

SLIP_FRACTION = 0.01
"""Largest share of dropped plus duplicated samples of a regular clock."""

FIT_ROUNDS = 5
"""Rounds of slots and line at most when samples slipped (they settle in one or two)."""


@dataclass(frozen=True)
class Clock:
    """A regular sampling clock found under a stream's timestamps.

    ``start`` and ``period`` (s) are the fitted line, ``slots`` the slot of every sample (the first 0),
    ``jitter_rms`` and ``jitter_max`` (s) the residuals of the timestamps about the line, ``dropped`` the
    empty slots and ``duplicated`` the samples that share a slot with an earlier one.
    """

    start: float
    period: float
    slots: np.ndarray
    jitter_rms: float
    jitter_max: float
    dropped: int
    duplicated: int

    @property
    def length(self) -> int:
        """Samples of the regular stream: every slot from the first to the last."""
        return int(self.slots[-1]) + 1

    @property
    def times(self) -> np.ndarray:
        """The time of every slot on the fitted clock."""
        return self.start + np.arange(self.length) * self.period

    def describe(self) -> str:
        """``a 100 Hz clock, jitter 1.2 ms rms (4.1 ms at most), 2 dropped, 0 duplicated``."""
        return (f"a {1.0 / self.period:.6g} Hz clock, jitter {_duration(self.jitter_rms)} rms "
                f"({_duration(self.jitter_max)} at most), {self.dropped} dropped, {self.duplicated} duplicated")


def _duration(seconds: float) -> str:
    return f"{seconds * 1e3:.3g} ms" if seconds < 1 else f"{seconds:.4g} s"


def _line(slots: np.ndarray, times: np.ndarray) -> tuple[float, float]:
    """``(a, T)`` of the least-squares line ``t = a + T n``."""
    period, start = np.polyfit(slots.astype(np.float64), times, 1)
    return float(start), float(period)


def _slipped(times: np.ndarray) -> np.ndarray:
    """Slots of a stream that may have dropped or duplicated samples.

    Each step is rounded to a whole number of median steps (0: a duplicate, 2: one sample dropped), which
    needs the jitter of a step to stay below half a period but does not drift with an error of the period;
    then the line through those slots gives every sample's slot, ``round((t - a) / T)``, which mends a
    step misread through jitter, until the slots settle.
    """
    step = float(np.median(np.diff(times)))
    slots = np.concatenate(([0], np.cumsum(np.rint(np.diff(times) / step)))).astype(np.int64)
    for _round in range(FIT_ROUNDS):
        start, period = _line(slots, times)
        if not period > 0:
            break
        new = np.rint((times - start) / period).astype(np.int64)
        new -= new[0]
        if np.array_equal(new, slots):
            break
        slots = new
    return slots


def _clock(times: np.ndarray, slots: np.ndarray) -> Clock | None:
    """The clock of ``slots`` if it passes :data:`JITTER_MAD` and :data:`SLIP_FRACTION`, else None."""
    if slots[-1] <= 0 or np.any(np.diff(slots) < 0):
        return None
    start, period = _line(slots, times)
    if not period > 0:
        return None
    residual = times - (start + slots * period)
    distinct = np.unique(slots).size
    dropped, duplicated = int(slots[-1] + 1 - distinct), int(times.size - distinct)
    if np.median(np.abs(residual)) > JITTER_MAD * period or dropped + duplicated > SLIP_FRACTION * times.size:
        return None
    return Clock(start, period, slots, float(np.sqrt(np.mean(residual ** 2))), float(np.max(np.abs(residual))),
                 dropped, duplicated)


def regular_clock(times: np.ndarray) -> Clock | None:
    """The regular clock under increasing timestamps (s), or None if they are not one.

    Sample k in slot k (none dropped or duplicated) is tried first: whatever the jitter, the line through
    every timestamp then gives the period. Otherwise the slots are found step by step (:func:`_slipped`).
    A clock is accepted when the median absolute residual about its line is at most :data:`JITTER_MAD`
    periods and at most :data:`SLIP_FRACTION` of the samples were dropped or duplicated.
    """
    times = np.asarray(times, dtype=np.float64)
    if times.size < 3 or not np.median(np.diff(times)) > 0:
        return None
    return _clock(times, np.arange(times.size)) or _clock(times, _slipped(times))


def on_slots(values: np.ndarray, clock: Clock) -> np.ndarray:
    """Rows of ``values`` (one per timestamp) placed in their clock slots: a duplicated sample (a later
    one in a filled slot) is left out, a dropped one (an empty slot) bridged linearly from its neighbours,
    each column on its own. With neither, ``values`` itself."""
    if not clock.dropped and not clock.duplicated:
        return values
    first = np.ones(clock.slots.size, dtype=bool)
    first[1:] = np.diff(clock.slots) > 0
    slots, kept = clock.slots[first], values[first]
    if not clock.dropped:
        return kept
    flat = kept.reshape(kept.shape[0], -1)
    every = np.arange(clock.length)
    columns = [np.interp(every, slots, flat[:, k]) for k in range(flat.shape[1])]
    return np.stack(columns, axis=1).reshape((clock.length, *kept.shape[1:]))
