"""Simulated-scanner benchmark: demo scans per second against the simulator of 2026-11 and per-step times.

Reference, in the same process: drawing as many standard normal samples as one scan holds numbers
(``np.random.default_rng().standard_normal``), the floor any noise-based synthesis pays. Every time is printed
as a ratio to it, so ratios compare across machines. The simulator before the contact-excitation rewrite
(commit 7eeaefc) took :data:`OLD_RATIO` references per demo scan, measured with this benchmark's
``demo_ratio`` on the same machine; the speed-up printed is that ratio over today's.

    PYTHONPATH=. .venv/bin/python benchmarks/bench_simulate.py
"""

from __future__ import annotations

import time

import numpy as np
from timing import median_time

from scanner import simulation as sim
from scanner.simulation.scans import scan_jobs, simulate_one

IMAGE_SIZE = (512, 512)
DEMO_SUBSET = 4
"""Every 4th material of the library: 8 demo scans (first piece, first scan) stand for the demo's 192."""
OLD_RATIO = 12.5
"""Demo-scan time over the reference of the simulator at commit 7eeaefc (see the module docstring)."""


def numbers_in(scan) -> int:
    return sum(trace.data.size for trace in scan.traces.values()) + sum(i.size for i in scan.images.values())


def reference_seconds(count: int) -> float:
    """Median CPU seconds of drawing ``count`` standard normals (CPU time: the machine may be shared)."""
    times = []
    for _ in range(9):
        started = time.process_time()
        np.random.default_rng(0).standard_normal(count)
        times.append(time.process_time() - started)
    return float(np.median(times))


def demo_ratio(reference: float) -> tuple[float, float]:
    """Seconds of CPU per demo scan (a subset of the demo's jobs) and its ratio to ``reference``."""
    jobs = scan_jobs(None, 2, 3, 0, IMAGE_SIZE, 0.5)[:: 6 * DEMO_SUBSET]
    simulate_one(jobs[0])
    started = time.process_time()
    for job in jobs:
        simulate_one(job)
    seconds = (time.process_time() - started) / len(jobs)
    return seconds, seconds / reference


def main() -> None:
    library = sim.load_materials()
    count = numbers_in(sim.synthetic_scan("oak-planed", seed=0, image_size=IMAGE_SIZE))
    reference = reference_seconds(count)
    print(f"one scan holds {count:,} numbers; drawing as many standard normals takes "
          f"{reference * 1e3:.1f} ms of CPU (the reference of the demo ratio)")
    seconds, ratio = demo_ratio(reference)
    print(f"demo scans ({IMAGE_SIZE[0]}x{IMAGE_SIZE[1]} photos, every {DEMO_SUBSET}th material): "
          f"{seconds * 1e3:.0f} ms CPU each, ratio {ratio:.1f}x")
    if OLD_RATIO:
        print(f"  the simulator of commit 7eeaefc: ratio {OLD_RATIO:.1f}x -> {OLD_RATIO / ratio:.1f}x faster today")

    draw = sim.draw_operator(np.random.default_rng(0))
    reference = median_time(lambda: np.random.default_rng(0).standard_normal(count), repeat=7)
    print(f"per step (oak), median of 5 wall times, ratio to the reference's wall time {reference * 1e3:.1f} ms:")
    total = 0.0
    for step, function in sim.STEP_FUNCTIONS.items():
        def run(fn=function) -> object:
            return fn(library["oak-planed"], np.random.default_rng(0), draw)

        step_seconds = median_time(run, repeat=5)
        total += step_seconds
        print(f"  {step:14s} {step_seconds * 1e3:7.1f} ms   ratio {step_seconds / reference:6.2f}x")
    print(f"  {'sum of steps':14s} {total * 1e3:7.1f} ms")


if __name__ == "__main__":
    main()
