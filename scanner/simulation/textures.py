"""Procedural textures of the simulated photos: a colour field and a surface height per material appearance."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import cv2
import numpy as np
from scipy import special

from scanner.simulation.materials import Appearance
from scanner.simulation.signals import Rng

Layers = tuple[np.ndarray, np.ndarray]
"""A texture's colour field (0 = dominant colour .. 1 = last colour) and its surface height."""
def _noise(rng: Rng, shape: tuple[int, int], scale_px: float, stretch: float = 1.0) -> np.ndarray:
    """Unit-variance smooth noise with correlation length ``scale_px`` (rows) and ``scale_px*stretch`` (cols).

    Features finer than a pixel average out: the amplitude falls with the scale below one pixel.
    """
    rows = max(2, int(np.ceil(shape[0] / max(scale_px, 1.0))) + 1)
    cols = max(2, int(np.ceil(shape[1] / max(scale_px * stretch, 1.0))) + 1)
    coarse = rng.standard_normal((rows, cols)).astype(np.float32)
    field = cv2.resize(coarse, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
    mean, std = (float(v[0, 0]) for v in cv2.meanStdDev(field))
    field -= np.float32(mean)
    field *= np.float32(min(1.0, scale_px) / max(std, 1e-6))
    return field


def _grid(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Column and row coordinates (px) of a square canvas."""
    axis = np.arange(size, dtype=np.float32)
    return np.meshgrid(axis, axis)


def _texture_smooth(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    clouds = 0.5 + 0.25 * _noise(rng, (size, size), ppm / look.frequency_per_mm)
    return look.contrast * clouds, np.zeros((size, size), np.float32)


def _texture_grain(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Growth rings along the columns, warped by slow noise; late wood is the ``duty`` share of each ring."""
    _, rows = _grid(size)
    period = ppm / look.frequency_per_mm
    warp = 0.6 * period * _noise(rng, (size, size), 4 * period, stretch=4.0)
    theta = 2 * np.pi * (rows + warp) / period + rng.uniform(0, 2 * np.pi)
    c0 = float(np.cos(np.pi * look.duty))
    late = np.clip((np.cos(theta) - c0) / (1 - c0), 0, 1)
    pores = _noise(rng, (size, size), 0.15 * ppm, stretch=12.0)
    return look.contrast * np.clip(late + 0.15 * pores, 0, 1), -late


def _texture_speckle(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Mineral grains: a dark phase (``0.4 duty`` of the area), a second phase (``duty``), the rest first."""
    grain = ppm / look.frequency_per_mm
    dark = _noise(rng, (size, size), 0.7 * grain)
    second = _noise(rng, (size, size), grain)
    # A quarter of the pixels set the phase shares as well as all of them, at a sixteenth of the cost.
    cut_dark = float(np.quantile(dark[::4, ::4], 1 - 0.4 * look.duty))
    cut_second = float(np.quantile(second[::4, ::4], 1 - look.duty))
    field = 0.5 * special.expit((second - cut_second) / 0.08) + special.expit((dark - cut_dark) / 0.08)
    field = np.clip(field, 0, 1) + 0.12 * _noise(rng, (size, size), 0.15 * grain)
    return look.contrast * field, _noise(rng, (size, size), 0.5 * grain)


def _texture_granular(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    grains = _noise(rng, (size, size), 0.5 * ppm / look.frequency_per_mm)
    field = 1 / (1 + np.exp(-2 * grains))
    return look.contrast * field, grains


def _texture_cellular(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Foam-like cells around random seeds: walls along the cell boundaries, cavities (``duty``) inside."""
    cell = ppm / look.frequency_per_mm
    count = int(size * size / max(cell, 1.0) ** 2)
    seeds = np.full((size, size), 255, np.uint8)
    seeds[rng.integers(0, size, count), rng.integers(0, size, count)] = 0
    _, owner = cv2.distanceTransformWithLabels(seeds, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    walls = np.zeros((size, size), bool)
    walls[:, 1:] |= owner[:, 1:] != owner[:, :-1]
    walls[1:, :] |= owner[1:, :] != owner[:-1, :]
    inside = cv2.distanceTransform(np.where(walls, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
    wall_half = (1 - look.duty) * cell / 4
    cavity = np.clip((inside - wall_half) / max(cell / 4, 0.5), 0, 1) * min(1.0, cell / 2)
    return look.contrast * cavity, -cavity


def _texture_fibrous(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    scale = 0.3 * ppm / look.frequency_per_mm
    fibres = _noise(rng, (size, size), scale, stretch=10.0) + 0.5 * _noise(rng, (size, size), scale)
    field = 1 / (1 + np.exp(-1.5 * fibres))
    return look.contrast * field, fibres


def _texture_brushed(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    streaks = _noise(rng, (size, size), 0.5 * ppm / look.frequency_per_mm, stretch=40.0)
    return look.contrast * (0.5 + 0.25 * streaks), 0.3 * streaks


def _texture_veined(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Marble: thin veins along the level lines of a turbulent field."""
    cols, rows = _grid(size)
    period = ppm / look.frequency_per_mm
    turbulence = _noise(rng, (size, size), period) + 0.3 * _noise(rng, (size, size), 0.25 * period)
    wave = np.sin(2 * np.pi * (cols + 0.3 * rows) / period + 2.0 * turbulence)
    veins = np.exp(-(wave / max(look.duty, 0.02)) ** 2)
    cloud = 0.15 * _noise(rng, (size, size), 0.3 * period)
    return look.contrast * np.clip(veins + cloud, 0, 1), np.zeros((size, size), np.float32)


def _texture_weave(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Plain weave: threads ``duty`` of the pitch wide, alternating over and under."""
    cols, rows = _grid(size)
    pitch = ppm / look.frequency_per_mm
    shift = [float(v) for v in rng.uniform(0, pitch, 2)]
    u, v = (cols + shift[0]) / pitch, (rows + shift[1]) / pitch
    warp_over = (np.floor(u) + np.floor(v)) % 2 == 0
    across = np.where(warp_over, u % 1.0, v % 1.0)
    gap = (1 - look.duty) / 2
    inside = np.clip((across - gap) / max(look.duty, 1e-3), 0, 1)
    thread = np.sqrt(np.maximum(np.sin(np.pi * inside), 0.0)) * ((across > gap) & (across < 1 - gap))
    fibres = 0.1 * np.where(warp_over, _noise(rng, (size, size), 0.05 * pitch, stretch=0.1),
                            _noise(rng, (size, size), 0.05 * pitch, stretch=10.0))
    return look.contrast * np.clip(1 - thread + fibres, 0, 1), thread


def _texture_perforated(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """A square grid of round holes, diameter ``duty`` of the pitch, with sharp edges."""
    cols, rows = _grid(size)
    pitch = ppm / look.frequency_per_mm
    shift = [float(v) for v in rng.uniform(0, pitch, 2)]
    du = ((cols + shift[0]) / pitch) % 1.0 - 0.5
    dv = ((rows + shift[1]) / pitch) % 1.0 - 0.5
    distance = np.hypot(du, dv) * pitch
    hole = 1 / (1 + np.exp(-(look.duty * pitch / 2 - distance) / max(0.05 * ppm, 0.4)))
    sheen = 0.05 * _noise(rng, (size, size), 0.2 * ppm, stretch=20.0)
    return look.contrast * np.clip(hole + sheen, 0, 1), -hole


def _texture_ribbed(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    _, rows = _grid(size)
    ridge = 0.5 + 0.5 * np.cos(2 * np.pi * rows / (ppm / look.frequency_per_mm) + rng.uniform(0, 2 * np.pi))
    fibres = 0.3 * _noise(rng, (size, size), 0.05 * ppm, stretch=6.0)
    return look.contrast * np.clip(0.7 * ridge + fibres, 0, 1), ridge


TEXTURE_FUNCTIONS: Mapping[str, Callable[[Appearance, Rng, int, float], Layers]] = {
    "smooth": _texture_smooth, "grain": _texture_grain, "speckle": _texture_speckle,
    "granular": _texture_granular, "cellular": _texture_cellular, "fibrous": _texture_fibrous,
    "brushed": _texture_brushed, "veined": _texture_veined, "weave": _texture_weave,
    "perforated": _texture_perforated, "ribbed": _texture_ribbed,
}
"""Procedural texture generators: (appearance, rng, canvas size px, px per mm) -> (colour field, height)."""
