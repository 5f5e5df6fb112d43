"""Simulated-scanner benchmark: whole scans per second at 512x512 photos and the time of every procedure step.

Reference, in the same process: drawing as many standard normal samples as one scan holds numbers
(``np.random.default_rng().standard_normal``), the floor any noise-based synthesis pays. Ratios, not absolute
times, compare across machines.
"""

from __future__ import annotations

import numpy as np
from timing import median_time

from scanner import simulation as sim

IMAGE_SIZE = (512, 512)
MATERIALS = ("oak-planed", "polyurethane-foam", "perforated-steel-plate", "granite-polished")


def numbers_in(scan) -> int:
    return sum(trace.data.size for trace in scan.traces.values()) + sum(i.size for i in scan.images.values())


def main() -> None:
    library = sim.load_materials()
    sample = sim.synthetic_scan(MATERIALS[0], seed=0, image_size=IMAGE_SIZE)
    count = numbers_in(sample)
    reference = median_time(lambda: np.random.default_rng(0).standard_normal(count), repeat=7)
    print(f"one scan holds {count:,} numbers; drawing as many standard normals takes "
          f"{reference * 1e3:.1f} ms (the reference of every ratio below)")

    print(f"whole scans at {IMAGE_SIZE[0]}x{IMAGE_SIZE[1]} photos, median of 3:")
    for slug in MATERIALS:
        seconds = median_time(lambda s=slug: sim.synthetic_scan(s, seed=1, image_size=IMAGE_SIZE), repeat=3)
        print(f"  {slug:24s} {seconds * 1e3:7.0f} ms  {1 / seconds:5.2f} scans/s"
              f"   ratio {seconds / reference:6.1f}x")

    draw = sim.draw_operator(np.random.default_rng(0))
    print("per step (oak), median of 5:")
    total = 0.0
    for step, function in sim.STEP_FUNCTIONS.items():
        def run(fn=function) -> object:
            return fn(library["oak-planed"], np.random.default_rng(0), draw)

        seconds = median_time(run, repeat=5)
        total += seconds
        print(f"  {step:14s} {seconds * 1e3:7.1f} ms   ratio {seconds / reference:6.2f}x")
    print(f"  {'sum of steps':14s} {total * 1e3:7.1f} ms")


if __name__ == "__main__":
    main()
