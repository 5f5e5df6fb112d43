"""Ingest of a timestamped CSV set against the same files read as regular streams, in one process.

400 files (200 recordings of a 100 Hz tactile stream with jittered host timestamps and a 200 Hz force
stream, 30 s each) are written to a temporary folder once. ``texplorer ingest`` is timed on them with the
time columns (clock fit, common time base) and against the same files mapped with a rate and no time column
(no alignment at all: the floor of reading and assembling them). The ratio shows what the time base costs;
ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from timing import best_time

from scanner.storage import ingest

RECORDINGS = 100
SECONDS = 10

TIMED = """
[[files]]
glob = "**/*_tactile.csv"
suffix = "_tactile.csv"
time_column = "t"
  [[files.channels]]
  name = "pdc"
  role = "pressure_dc"
  columns = "p"
[[files]]
glob = "**/*_force.csv"
suffix = "_force.csv"
time_column = "t"
  [[files.channels]]
  name = "force"
  role = "force_xyz"
  columns = ["fx", "fy", "fz"]
"""

REGULAR = (TIMED.replace('time_column = "t"\n  [[files.channels]]\n  name = "pdc"',
                         'rate = 100.0\n  [[files.channels]]\n  name = "pdc"')
           .replace('time_column = "t"\n  [[files.channels]]\n  name = "force"',
                    'rate = 200.0\n  [[files.channels]]\n  name = "force"'))


def write_set(root: Path) -> None:
    rng = np.random.default_rng(0)
    for k in range(RECORDINGS):
        folder = root / f"class{k % 4}"
        folder.mkdir(parents=True, exist_ok=True)
        start = 1.58e9 + 100 * k  # host Unix times
        rows = int(100 * SECONDS)
        t = start + np.arange(rows) / 100 + rng.normal(scale=1e-3, size=rows)
        p = rng.normal(size=rows)
        (folder / f"r{k:03d}_tactile.csv").write_text(
            "t,p\n" + "".join(f"{a:.6f},{b:.6g}\n" for a, b in zip(t.tolist(), p.tolist(), strict=True)))
        rows = int(200 * SECONDS)
        t = start + np.arange(rows) / 200 + rng.normal(scale=4e-4, size=rows)
        f = rng.normal(size=(rows, 3))
        (folder / f"r{k:03d}_force.csv").write_text(
            "t,fx,fy,fz\n" + "".join(f"{a:.6f},{x:.6g},{y:.6g},{z:.6g}\n"
                                     for a, (x, y, z) in zip(t.tolist(), f.tolist(), strict=True)))


def main() -> None:
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        write_set(root)
        timed, regular = ingest.parse_mapping(TIMED, "timed"), ingest.parse_mapping(REGULAR, "regular")
        report = ingest.ingest(root, timed)
        assert len(report.recordings) == RECORDINGS and not report.skipped, report.skipped[:3]
        kept = sum(not c["resampled"] for r in report.recordings for c in r.meta["time_base"]["channels"].values())
        ours = best_time(lambda: ingest.ingest(root, timed), repeat=3)
        floor = best_time(lambda: ingest.ingest(root, regular), repeat=3)
    print(f"ingest of {2 * RECORDINGS} CSV files ({RECORDINGS} recordings, {SECONDS} s each, jittered host "
          f"timestamps); best of 3")
    print(f"  with time columns (clock fit, common time base) {ours:7.2f} s   {kept} of {2 * RECORDINGS} "
          "streams kept as regular clocks")
    print(f"  the same files at a given rate, no time column  {floor:7.2f} s   ratio {ours / floor:5.2f}x")


if __name__ == "__main__":
    main()
