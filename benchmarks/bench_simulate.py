"""Simulated-scanner benchmark: demo scans per second against the simulator of 2026-11 and per-step times.

Reference, in the same process: drawing as many standard normal samples as one scan holds numbers
(``np.random.default_rng().standard_normal``), the floor any noise-based synthesis pays. Every time is printed
as a ratio to it, so ratios compare across machines.

The simulator before the contact-excitation rewrite (commit :data:`OLD_COMMIT`) runs alongside, in the same
run: ``git archive`` extracts that commit into a temporary folder and this file runs again in a subprocess
with it first on the path (``--ratio-only``), so the old simulator's ``demo_ratio`` is measured the same way
(its own reference in its own process, the same jobs, OpenCV on one thread in both); the speed-up printed is
its ratio over today's. Without git or the commit (an installed copy), the benchmark falls back to
:data:`OLD_RATIO`, measured that way on the 2-core development machine (docs/performance.md); by hand:

    git worktree add --detach /tmp/old 7eeaefc
    PYTHONPATH=/tmp/old python benchmarks/bench_simulate.py --ratio-only 3088576

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/bench_simulate.py``
"""

from __future__ import annotations

import io
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from timing import median_time

from scanner import simulation as sim
from scanner.simulation.scans import scan_jobs, simulate_one

IMAGE_SIZE = (512, 512)
DEMO_SUBSET = 4
"""Every 4th material of the library: 8 demo scans (first piece, first scan) stand for the demo's 192."""
OLD_COMMIT = "7eeaefc"
OLD_RATIO = 11.0
"""Demo-scan time over the reference of the simulator at :data:`OLD_COMMIT` (10.1-11.8 in three runs on the
2-core development machine, 2026-11-27), used when that commit cannot be run alongside."""


def numbers_in(scan) -> int:
    return sum(trace.data.size for trace in scan.traces.values()) + sum(i.size for i in scan.images.values())


PASSES = 3
"""Passes over the demo subset; the least CPU of them counts, as the least of the reference's draws: on a
shared machine, the runs least disturbed by other processes' use of the caches."""


def reference_seconds(count: int) -> float:
    """Least CPU seconds of 9 draws of ``count`` standard normals (CPU time: the machine may be shared)."""
    times = []
    for _ in range(9):
        started = time.process_time()
        np.random.default_rng(0).standard_normal(count)
        times.append(time.process_time() - started)
    return float(np.min(times))


def demo_ratio(reference: float) -> tuple[float, float]:
    """Seconds of CPU per demo scan (a subset of the demo's jobs, the least of :data:`PASSES` passes) and
    its ratio to ``reference``."""
    jobs = scan_jobs(None, 2, 3, 0, IMAGE_SIZE, 0.5)[:: 6 * DEMO_SUBSET]
    simulate_one(jobs[0])
    passes = []
    for _ in range(PASSES):
        started = time.process_time()
        for job in jobs:
            simulate_one(job)
        passes.append((time.process_time() - started) / len(jobs))
    seconds = min(passes)
    return seconds, seconds / reference


def old_ratio(count: int) -> tuple[float, float] | None:
    """The CPU seconds per demo scan and demo ratio of the simulator at :data:`OLD_COMMIT`, measured now in
    a subprocess on that commit's files (``git archive``), with the reference of ``count`` numbers; None
    where git or the commit is missing."""
    root = Path(__file__).resolve().parents[1]
    try:
        archive = subprocess.run(["git", "-C", str(root), "archive", OLD_COMMIT], capture_output=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    with tempfile.TemporaryDirectory() as folder:
        with tarfile.open(fileobj=io.BytesIO(archive.stdout)) as tar:
            tar.extractall(folder, filter="data")
        environment = {**os.environ, "PYTHONPATH": folder}
        run = subprocess.run([sys.executable, __file__, "--ratio-only", str(count)], env=environment,
                             capture_output=True, text=True)
    if run.returncode != 0:
        print(f"  (the simulator of {OLD_COMMIT} did not run: {run.stderr.strip().splitlines()[-1:]})")
        return None
    seconds, ratio = run.stdout.split()[-2:]
    return float(seconds), float(ratio)


def ratio_only(count: int) -> None:
    """Print this checkout's CPU seconds per demo scan and demo ratio for a reference of ``count`` numbers
    (the old simulator's run)."""
    seconds, ratio = demo_ratio(reference_seconds(count))
    print(f"seconds and ratio {seconds:.4f} {ratio:.3f}")


def main() -> None:
    library = sim.load_materials()
    count = numbers_in(sim.synthetic_scan("oak-planed", seed=0, image_size=IMAGE_SIZE))
    reference = reference_seconds(count)
    print(f"one scan holds {count:,} numbers; drawing as many standard normals takes "
          f"{reference * 1e3:.1f} ms of CPU (the reference of the demo ratio)")
    seconds, ratio = demo_ratio(reference)
    print(f"demo scans ({IMAGE_SIZE[0]}x{IMAGE_SIZE[1]} photos, every {DEMO_SUBSET}th material): "
          f"{seconds * 1e3:.0f} ms CPU each, ratio {ratio:.1f}x")
    measured = old_ratio(count)
    if measured is None:
        print(f"  the simulator of commit {OLD_COMMIT} (fixed, measured on the development machine): ratio "
              f"{OLD_RATIO:.1f}x -> {OLD_RATIO / ratio:.1f}x faster today")
    else:
        old_seconds, old = measured
        print(f"  the simulator of commit {OLD_COMMIT}, measured now: {old_seconds * 1e3:.0f} ms CPU each, ratio "
              f"{old:.1f}x -> {old / ratio:.1f}x faster today ({old_seconds / seconds:.1f}x by CPU time)")

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


cv2.setNumThreads(1)  # as in the demo's workers; CPU time would otherwise count OpenCV's idle threads

if __name__ == "__main__":
    if sys.argv[1:2] == ["--ratio-only"]:
        ratio_only(int(sys.argv[2]))
    else:
        main()
