"""Image-feature benchmark: ``features.image.compute`` on one core, against a same-process reference.

Photos of 512 x 512 (the simulator's default) and 3024 x 4032 px (a 12-megapixel phone photo) with a
procedural texture. The reference is ``cv2.cvtColor`` to gray plus one 5 x 5 ``cv2.GaussianBlur`` of the
same cropped photo, the least any image pipeline pays; ratios against it compare across machines, absolute
times do not. The per-family rows time the public functions on the prepared gray image; they include
each function's own input check, which ``compute`` does once, and ``compute`` runs the grayscale
conversions band by band (cheaper than the whole-image calls timed here), so they add up to a little more.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import time  # noqa: E402  (the thread limits must be set before numpy loads its BLAS)
from collections.abc import Callable  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from features import image  # noqa: E402
from scanner.preprocess import crop_image, gray_uint8, grayscale  # noqa: E402

TARGET_S = 0.8
"""All 31 features of a 12-megapixel photo on one core."""


def median_time(fn: Callable[[], object], repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def textured_photo(h: int, w: int, seed: int = 0) -> np.ndarray:
    """A woven-looking colour texture with grain: every feature does real work on it."""
    rng = np.random.default_rng(seed)
    rows = np.arange(h, dtype=np.float32)[:, None]
    cols = np.arange(w, dtype=np.float32)[None, :]
    weave = np.sin(2 * np.pi * cols / 37) * np.cos(2 * np.pi * rows / 53)
    grain = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 1.5)
    gray = 120 + 50 * weave + 40 * grain
    tint = np.array([1.0, 0.8, 0.55], np.float32)
    return np.clip(gray[..., None] * tint, 0, 255).astype(np.uint8)


def reference(photo: np.ndarray) -> np.ndarray:
    return cv2.GaussianBlur(cv2.cvtColor(photo, cv2.COLOR_RGB2GRAY), (5, 5), 0)


def families(photo: np.ndarray) -> dict[str, Callable[[], object]]:
    gray = grayscale(photo)
    gray_u8 = gray_uint8(gray)
    return {
        "grayscale + gray_uint8 (whole image)": lambda: (grayscale(photo), gray_uint8(gray)),
        "color": lambda: image.color(photo),
        "brightness": lambda: image.brightness(gray),
        "edginess": lambda: image.edginess(gray_u8),
        "dft_80, dft_85": lambda: image.dft_peak_means(gray),
        "haralick_01..14": lambda: image.haralick(gray),
        "tamura_coarseness": lambda: image.tamura_coarseness(gray),
        "tamura_contrast": lambda: image.tamura_contrast(gray),
        "lbp_0..9": lambda: image.lbp_histogram(gray),
    }


def main() -> None:
    cv2.setNumThreads(1)
    print("features.image.compute on one core (cv2.setNumThreads(1), BLAS/OpenMP threads 1), median times")
    for h, w, repeat in ((512, 512, 15), (3024, 4032, 5)):
        photo = textured_photo(h, w)
        cropped = crop_image(photo)
        floor = median_time(lambda p=cropped: reference(p), repeat)
        ours = median_time(lambda p=photo: image.compute(p), repeat)
        print(f"\n{h} x {w} px photo ({cropped.shape[0]} x {cropped.shape[1]} after the crop)")
        print(f"  reference cvtColor + GaussianBlur   {floor * 1e3:8.1f} ms")
        print(f"  compute, all 31 features            {ours * 1e3:8.1f} ms   ratio {ours / floor:6.1f}x")
        if (h, w) == (3024, 4032):
            verdict = "ok" if ours < TARGET_S else "SLOWER than"
            print(f"  {verdict} the {TARGET_S:.1f} s target for a 12-megapixel photo")
        for name, fn in families(cropped).items():
            spent = median_time(fn, repeat)
            print(f"    {name:32s} {spent * 1e3:8.1f} ms   ratio {spent / floor:6.1f}x")


if __name__ == "__main__":
    main()
