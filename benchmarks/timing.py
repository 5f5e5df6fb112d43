"""Timing helpers shared by the benchmarks: wall times of repeated runs of one callable."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np


def run_times(fn: Callable[[], object], repeat: int, *, warm_up: bool = True) -> np.ndarray:
    """Wall time in seconds of each of ``repeat`` runs of ``fn`` (after one untimed run if ``warm_up``)."""
    if warm_up:
        fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return np.array(times)


def median_time(fn: Callable[[], object], repeat: int = 15, *, warm_up: bool = True) -> float:
    """Median wall time of ``fn``: the typical run."""
    return float(np.median(run_times(fn, repeat, warm_up=warm_up)))


def best_time(fn: Callable[[], object], repeat: int = 5, *, warm_up: bool = True) -> float:
    """Shortest wall time of ``fn``: on a shared machine, the run least disturbed by other processes."""
    return float(np.min(run_times(fn, repeat, warm_up=warm_up)))
