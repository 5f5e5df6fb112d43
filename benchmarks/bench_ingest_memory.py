"""Peak memory of ``texplorer ingest`` against the number of photos it imports.

Each recording is written as it is read (``scanner.storage.ingest.SetWriter``), so the peak resident memory
of an import does not grow with the number of files. Two imports of the same kind of photos, ``FEW`` and
ten times as many, each in a fresh process (``VmHWM`` of that process: the peak of the import alone), are
set against each other: the ratio of their peaks is about 1 (4.1 when every recording was held until the
set was stored: 2 photos peaked at 402 MB, 20 at 1643 MB).
Time per photo is printed too; the photos are smooth gradients (PNG), quick to write and to compress.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

FEW = 2
SIDE = (3000, 4000)
"""12 megapixels, the photos of a phone (and of the paper's camera class)."""

CHILD = """
import sys
from scanner.cli import main
code = main(["ingest", sys.argv[1], "--db", sys.argv[2], "--name", "photos"])
with open("/proc/self/status") as status:
    peak = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))
print(code, peak // 1024)
"""


def photos(folder: Path, count: int) -> Path:
    """``count`` photos in ``folder/<class>/``, two classes, each a gradient of its own."""
    rows, columns = np.mgrid[0:SIDE[0], 0:SIDE[1]]
    for k in range(count):
        path = folder / f"class{k % 2}" / f"photo{k:03d}.png"
        path.parent.mkdir(parents=True, exist_ok=True)
        image = np.stack([(rows + k) % 256, (columns + 3 * k) % 256, (rows + columns) % 256], axis=2)
        cv2.imwrite(str(path), image.astype(np.uint8))
    return folder


def peak_of_ingest(folder: Path, db: Path) -> tuple[int, float]:
    """Peak resident MB and wall seconds of ``texplorer ingest folder`` in a fresh process."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", CHILD, str(folder), str(db)], capture_output=True, text=True,
                         check=True).stdout.splitlines()[-1].split()
    assert out[0] == "0", out
    return int(out[1]), time.perf_counter() - start


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench-ingest-") as scratch:
        root = Path(scratch)
        few = peak_of_ingest(photos(root / "few", FEW), root / "db-few")
        many = peak_of_ingest(photos(root / "many", 10 * FEW), root / "db-many")
    print(f"ingest of {FEW} photos of {SIDE[1]} x {SIDE[0]} px: peak {few[0]} MB, {few[1] / FEW:.2f} s a photo")
    print(f"ingest of {10 * FEW} photos: peak {many[0]} MB, {many[1] / (10 * FEW):.2f} s a photo")
    print(f"peak ratio {10 * FEW} / {FEW} photos: {many[0] / few[0]:.2f} (every recording held until stored: 4.1)")


if __name__ == "__main__":
    main()
