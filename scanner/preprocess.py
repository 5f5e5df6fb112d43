"""Preprocessing of raw scanner signals (SPEC section 6): pure functions, no state, no I/O."""

from __future__ import annotations

import numpy as np

IMAGE_BORDER_PX = 100
"""Pixels cropped from every border of a photo before any image feature (SPEC 6)."""


def crop_image(image: np.ndarray, border: int = IMAGE_BORDER_PX) -> np.ndarray:
    """Remove ``border`` pixels from every side of an (h, w[, 3]) image (SPEC 6, "Images").

    The scanner's photo unit TU3 vignettes at the borders; cropping keeps only the evenly lit centre.
    """
    h, w = image.shape[:2]
    if h <= 2 * border or w <= 2 * border:
        raise ValueError(f"image of {h}x{w} px is too small to crop {border} px from every border")
    return image[border:h - border, border:w - border]


def grayscale(rgb: np.ndarray) -> np.ndarray:
    """Luma ``0.299 R + 0.587 G + 0.114 B`` as float64 in 0..255, not rounded (SPEC 6, ITU-R BT.601)."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an RGB image of shape (h, w, 3), got {rgb.shape}")
    rgb = rgb.astype(np.float64)
    return 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]


def gray_uint8(gray: np.ndarray) -> np.ndarray:
    """8-bit version of a float gray image: ``floor(gray + 0.5)`` clipped to 0..255 (SPEC 6)."""
    return np.clip(np.floor(np.asarray(gray, dtype=np.float64) + 0.5), 0, 255).astype(np.uint8)
