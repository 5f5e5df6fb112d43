"""Feature extraction benchmark (SPEC 7, 8): all 193 features per scan, parallel and cached extraction.

- per-scan time of ``features.extract`` with 512 x 512 and 3024 x 4032 photos on one core (target <= 3 s at
  full resolution), as a ratio against a same-process reference (one ``scipy.fft.rfft2`` of the photo);
- speed-up of ``extract_many`` on 2 workers against 1 (target >= 1.7x);
- a synthetic database extracted cold and again from the feature cache.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import dataclasses  # noqa: E402
import functools  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import scipy.fft  # noqa: E402

from features import ScanSource, extract, extract_many  # noqa: E402
from scanner.database import Database  # noqa: E402
from scanner.matfile import load_scan  # noqa: E402
from scanner.simulate import synthetic_database, synthetic_scan  # noqa: E402

cv2.setNumThreads(1)


def best_of(fn, repeat: int = 3) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def per_scan() -> None:
    for size in ((512, 512), (3024, 4032)):
        scan = synthetic_scan("granite-polished", seed=1, image_size=size)
        gray = np.asarray(scan.images["I_disp"][..., 1], dtype=np.float64)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t_extract = best_of(lambda scan=scan: extract(scan), 2 if size[0] > 1000 else 3)
        t_ref = best_of(lambda gray=gray: scipy.fft.rfft2(gray))
        print(f"extract, photos {size[0]}x{size[1]}: {t_extract:6.2f} s per scan (one core)   "
              f"rfft2 of one photo {t_ref * 1e3:6.1f} ms   ratio {t_extract / t_ref:6.1f}x")


def many(folder: Path, materials: list[str], scans: int) -> None:
    db = synthetic_database(folder / "db", materials=materials, scans_per_material=scans, progress=False)
    records = db.records()
    sources = [ScanSource(r.scan_id, r.label, r.sample_id, functools.partial(load_scan, db.root / r.path),
                          cache_key=r.content_hash) for r in records]
    t1 = best_of(lambda: extract_many(sources, workers=1, progress=False), 1)
    t2 = best_of(lambda: extract_many(sources, workers=2, progress=False), 1)
    print(f"extract_many over {len(sources)} scans (512x512): 1 worker {t1:6.1f} s, 2 workers {t2:6.1f} s, "
          f"speed-up {t1 / t2:4.2f}x (os.cpu_count() = {os.cpu_count()})")
    fresh = Database(folder / "db")
    start = time.perf_counter()
    extract_many(sources, workers=2, cache=fresh, progress=False)
    cold = time.perf_counter() - start
    start = time.perf_counter()
    cached = extract_many([dataclasses.replace(s) for s in sources], workers=2, cache=fresh, progress=False)
    warm = time.perf_counter() - start
    print(f"database of {len(cached)} scans: cold {cold:6.1f} s, from the cache {warm:6.3f} s, "
          f"ratio {cold / warm:6.0f}x")


def main() -> None:
    per_scan()
    with tempfile.TemporaryDirectory() as tmp:
        many(Path(tmp), ["polyurethane-foam", "mild-steel-brushed", "granite-polished", "oak-planed",
                         "sandpaper-p80", "float-glass"], 2)


if __name__ == "__main__":
    main()
