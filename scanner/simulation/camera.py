"""The simulated camera of TU3: ``I_disp``, ``I_macro`` (4x lens) and ``I_illu`` (flash) from a procedural
texture, with the phone's placement, lighting, focus, exposure and tone curve."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import Rng, bank_normals
from scanner.simulation.textures import TEXTURE_FUNCTIONS
from scanner.simulation.variability import OperatorDraw

PHOTO_FOV_MM = {"I_disp": 60.0, "I_macro": 15.0, "I_illu": 60.0}
"""Field of view across the image width: the 4x lens shows a quarter of the normal view."""

RAMP_LEVELS = 256
"""Steps of the colour ramp's lookup table (a step moves a colour by less than one 8-bit count)."""


def _ramp(colors: np.ndarray, field: np.ndarray) -> np.ndarray:
    """Map a field in [0, 1] piecewise linearly through the colours (rows of RGB in [0, 1], dominant first),
    through a lookup table of :data:`RAMP_LEVELS` steps."""
    palette = np.asarray(colors, dtype=np.float32)
    position = np.linspace(0.0, len(palette) - 1, RAMP_LEVELS)
    table = np.column_stack([np.interp(position, np.arange(len(palette)), palette[:, c]) for c in range(3)])
    index = cv2.convertScaleAbs(np.clip(field, 0.0, 1.0), alpha=RAMP_LEVELS - 1)  # rounds to uint8
    return cv2.LUT(cv2.merge([index, index, index]), table.astype(np.float32).reshape(1, RAMP_LEVELS, 3))


def _place(image: np.ndarray, angle_deg: float, shift: np.ndarray, out: tuple[int, int]) -> np.ndarray:
    """Rotate the square material-frame canvas about its centre, shift it, and cut out an (h, w) view."""
    size = image.shape[0]
    h, w = out
    matrix = cv2.getRotationMatrix2D((size / 2, size / 2), angle_deg, 1.0)
    matrix[:, 2] += np.array([w / 2 - size / 2, h / 2 - size / 2]) + shift
    return cv2.warpAffine(image, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


SENSOR_NOISE_COUNTS = 2.0
"""Rms of the phone's pixel noise in 8-bit counts."""


@lru_cache(maxsize=8)
def _frame(h: int, w: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Image-plane coordinates in [-1, 1] (columns, rows) and the radius over the half-diagonal, read-only."""
    cols, rows = np.meshgrid(np.linspace(-1, 1, w, dtype=np.float32), np.linspace(-1, 1, h, dtype=np.float32))
    radius = np.hypot(cols, rows) / np.float32(np.sqrt(2))
    for array in (cols, rows, radius):
        array.flags.writeable = False
    return cols, rows, radius


@dataclass(frozen=True)
class _View:
    """The surface as the camera frames it, before light: the colour ramp's RGB (h, w, 3) in [0, 1] and the
    height's gradient (rows, columns), read-only, shared by the photos taken from one position."""

    rgb: np.ndarray
    gradient: tuple[np.ndarray, ...]
    """Empty for a flat surface."""


def _view(material: Material, rng: Rng, operator: OperatorDraw, kind: str, size: tuple[int, int]) -> _View:
    """The framed view of the surface: texture, rotation, zoom, position; its colours through the palette
    and white balance, and the gradient of its height."""
    look = material.appearance
    h, w = size
    ppm = w / PHOTO_FOV_MM[kind] * operator.camera_zoom
    canvas = int(np.ceil(np.hypot(h, w))) + 8
    field, height = TEXTURE_FUNCTIONS[look.texture](look, rng, canvas, ppm)
    layers = cv2.merge([np.asarray(field, np.float32), np.asarray(height, np.float32)])
    angle = look.orientation_deg + operator.photo_rotation_deg + rng.normal(0.0, 1.0)
    placed = _place(layers, angle, rng.uniform(-0.05, 0.05, 2) * w, (h, w))
    palette = np.asarray(look.colors, np.float32) / 255.0 * np.asarray(operator.white_balance, np.float32)
    rgb = _ramp(palette, placed[..., 0])
    height = placed[..., 1]
    gradient = tuple(np.gradient(cv2.GaussianBlur(height, (0, 0), 1.0))) if look.relief and height.any() else ()
    for array in (rgb, *gradient):
        array.flags.writeable = False
    return _View(rgb, gradient)


def _photo(material: Material, rng: Rng, operator: OperatorDraw, kind: str, view: _View) -> np.ndarray:
    """One RGB uint8 photo of a framed view: relief shading, lighting, vignetting, focus, exposure control,
    tone curve, sensor noise."""
    look = material.appearance
    h, w = view.rgb.shape[:2]
    flash = kind == "I_illu"
    relief = look.relief * (0.5 if flash else 1.0) * (1.5 if kind == "I_macro" else 1.0)
    cols, rows, _ = _frame(h, w)
    gain = _shading(view.gradient, relief, rng.uniform(-2.6, -2.0), (h, w))
    side = rng.uniform(0, 2 * np.pi)
    light = np.float32(operator.light_gain * rng.normal(1.0, 0.02) * (1.3 if flash else 1.0))
    gain *= _vignetting(h, w, 0.45 if kind == "I_macro" else 0.3)
    gain *= light + np.float32(light * 0.06 * np.cos(side)) * cols + np.float32(light * 0.06 * np.sin(side)) * rows
    rgb = view.rgb * gain[..., None]
    if flash:
        rgb += _highlight(look.gloss, rng, cols, rows)[..., None]
    focus = rng.uniform(0.6, 1.4) if kind == "I_macro" else rng.uniform(0.0, 0.8)
    if focus * w / 512 > 0.1:
        rgb = cv2.GaussianBlur(rgb, (0, 0), focus * w / 512)
    rgb = _tone(_auto_exposure(rgb))
    noise = bank_normals(rng, rgb.size).reshape(rgb.shape)
    # 255 rgb + noise, rounded to the nearest count and saturated to 0..255 in one pass.
    return cv2.addWeighted(rgb, 255.0, noise, SENSOR_NOISE_COUNTS, 0.0, dtype=cv2.CV_8U)


@lru_cache(maxsize=8)
def _vignetting(h: int, w: int, strength: float) -> np.ndarray:
    """The lens's fall-off ``1 - strength r^3`` over the frame (radius over the half-diagonal), read-only."""
    vignetting = 1 - np.float32(strength) * _frame(h, w)[2] ** 3
    vignetting.flags.writeable = False
    return vignetting


def _auto_exposure(rgb: np.ndarray, target: float = 0.72) -> np.ndarray:
    """The phone's exposure control: a frame brighter than ``target`` on average is darkened halfway (in
    log terms) toward it, so white surfaces and flash shots stay below white but remain brighter."""
    mean = float(np.mean(cv2.mean(rgb)[:3]))
    if mean > target:
        rgb *= np.float32(np.sqrt(target / mean))
    return rgb


def _tone(rgb: np.ndarray, knee: float = 0.8) -> np.ndarray:
    """The phone's tone curve: linear up to ``knee``, then a soft shoulder that never quite reaches white,
    so a bright or flash-lit surface keeps some texture instead of clipping flat (in place)."""
    if rgb.max() < knee:
        return rgb
    bright = rgb >= knee
    rgb[bright] = knee + (1 - knee) * np.tanh((rgb[bright] - knee) / (1 - knee))
    return rgb


def _shading(gradient: tuple[np.ndarray, ...], relief: float, light_angle: float,
             shape: tuple[int, int]) -> np.ndarray:
    """Lambert-like shading from the (smoothed) height gradient (rows, columns; empty: flat) along the light
    direction, strength ``relief``; a float32 array of ``shape`` of its own."""
    if relief == 0.0 or not gradient:
        return np.ones(shape, np.float32)
    gy, gx = gradient
    slope = gx * np.float32(np.cos(light_angle)) + gy * np.float32(np.sin(light_angle))
    spread = max(float(cv2.meanStdDev(slope)[1][0, 0]), 1e-6)
    return np.clip(1 + np.float32(0.35 * relief / spread) * slope, 0.3, 1.7)


def _highlight(gloss: float, rng: Rng, cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The flash's specular spot near the image centre, as strong as the surface is glossy."""
    centre = rng.normal(0.0, 0.08, 2).astype(np.float32)
    return np.float32(0.45 * gloss) * np.exp(-((cols - centre[0]) ** 2 + (rows - centre[1]) ** 2) / (2 * 0.15**2))


def photos(material: Material, rng: Rng, operator: OperatorDraw,
           image_size: tuple[int, int] = (512, 512)) -> dict[str, np.ndarray]:
    """TU3 photos ``I_disp``, ``I_macro`` (4x lens: a quarter of the field, coarser texture, softer) and
    ``I_illu`` (flash: brighter, specular highlight, flatter relief), RGB uint8 of ``image_size`` (h, w).

    ``I_disp`` and ``I_illu`` are taken from the same position, the flash switched on for the second, so
    they frame the same view of the surface.
    """
    size = (int(image_size[0]), int(image_size[1]))
    normal = _view(material, rng, operator, "I_disp", size)
    macro = _view(material, rng, operator, "I_macro", size)
    return {"I_disp": _photo(material, rng, operator, "I_disp", normal),
            "I_macro": _photo(material, rng, operator, "I_macro", macro),
            "I_illu": _photo(material, rng, operator, "I_illu", normal)}
