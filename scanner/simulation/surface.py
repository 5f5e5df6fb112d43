"""Tips, contact mechanics and the surface a tip follows along a slide path.

Vibration is modelled as the tip following a surface height profile ``z(x)`` along the path ``x(t)``: its
acceleration ``v^2 z''(x) + v' z'(x)`` (:mod:`~scanner.simulation.contact`) passes the tip-surface contact
resonance (the tap frequency) to the accelerometer and drives the sound the microphone hears, so the
spectrum scales with the slide speed; the IR sensor and the friction slide see the same macro-profile.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy import ndimage

from scanner.simulation.materials import Material, Roughness
from scanner.simulation.signals import Rng, smoothstep, times

G_MM_S2 = 9806.65
@dataclass(frozen=True)
class Tip:
    """What touches the surface in a TU1 step: the bare finger or the steel tool tip (paper III-B1)."""

    name: str
    radius_mm: float
    """Curvature radius: pits narrower than the tip are bridged (tip path = profile dilated by a ball)."""
    min_contact_mm: float
    """Smallest contact width: finer wavelengths are averaged out (finger ridges, Hertz patch)."""
    frequency_hz: float
    """The tip's own contact resonance, in series with the material's."""
    damping: float
    """Damping ratio added by the hand (and the finger pulp)."""
    gain: float
    """Share of the tip's vertical acceleration reaching the accelerometer."""
    tap_g: float
    """Peak tap acceleration at a 500 Hz contact resonance and unit tap strength (g)."""
    mass_g: float
    """Effective mass moving with the contact: the force on the surface is this mass times the tip's
    acceleration."""
    modulus_mpa: float
    """Young's modulus of the tip (steel; the finger pad's effective modulus) for the Hertz contact."""
    ridge_mm: float = 0.0
    """Spacing of the skin's ridges (0: a rigid tip). The skin conforms ridge by ridge, so a finger averages
    the texture over half a ridge rather than over its whole Hertz patch."""


TOOL = Tip("tool", radius_mm=3.0, min_contact_mm=0.02, frequency_hz=1400.0, damping=0.03, gain=0.03,
           tap_g=1.2, mass_g=10.0, modulus_mpa=200000.0)
FINGER = Tip("finger", radius_mm=6.0, min_contact_mm=0.3, frequency_hz=250.0, damping=0.25, gain=0.1,
             tap_g=0.4, mass_g=3.0, modulus_mpa=0.2, ridge_mm=0.45)
"""The steel tool tip (6 mm ball) and the bare finger (interpretation: an effective pad modulus of 0.2 MPa,
the order of magnitude of fingertip indentation stiffness, and 3 g of pad moving with the contact)."""


def contact_frequency_hz(material: Material, tip: Tip) -> float:
    """Resonance of the hand-held unit on the surface: rises with the material's stiffness.

    ``f_mat = 900 Hz (E / 210 GPa)^(1/4)`` (a steel tip on steel rings near 900 Hz; Hertz contact stiffness
    grows as E^(2/3) and the unit's effective mass falls for stiffer contacts), in series with the tip's
    own resonance: ``1/f^2 = 1/f_mat^2 + 1/f_tip^2``. Interpretation: a lumped model, not a measurement.
    """
    f_mat = 900.0 * (material.compliance.elastic_modulus_mpa / 210000.0) ** 0.25
    return float(1.0 / np.sqrt(1.0 / f_mat**2 + 1.0 / tip.frequency_hz**2))


def damping_ratio(material: Material, tip: Tip) -> float:
    return material.compliance.loss_factor / 2 + tip.damping


MACRO_DX_MM = 0.05


def _feature_train(rough: Roughness, rng: Rng, length_mm: float) -> tuple[np.ndarray, ...]:
    """Centres, widths and heights (mm) of the macro features along ``length_mm`` of path."""
    spacing, disorder = rough.macro_spacing_mm, 1.0 - rough.macro_regularity
    count = int(length_mm / spacing) + 3
    centres = (rng.uniform(0, spacing) + spacing * np.arange(-1, count - 1)
               + disorder * 0.35 * spacing * rng.standard_normal(count))
    widths = rough.macro_duty * spacing * np.clip(1 + disorder * 0.3 * rng.standard_normal(count), 0.3, 2.0)
    heights = rough.macro_height_um * 1e-3 * np.clip(1 + disorder * 0.3 * rng.standard_normal(count), 0.2, 2)
    return np.sort(centres), widths, heights


def macro_profile(rough: Roughness, rng: Rng, n: int, dx: float) -> np.ndarray:
    """Macro height (mm) on the grid: smoothed rectangular bumps (height > 0) or pits/holes (height < 0)."""
    if rough.macro_height_um == 0.0:
        return np.zeros(n)
    x = np.arange(n) * dx
    centres, widths, heights = _feature_train(rough, rng, n * dx)
    nearest = np.clip(np.searchsorted(centres, x), 1, centres.size - 1)
    profile = np.zeros(n)
    for index in (nearest - 1, nearest):
        c, w, h = centres[index], widths[index], heights[index]
        edge = 0.08 * w
        profile += h * 0.5 * (np.tanh((x - c + w / 2) / edge) - np.tanh((x - c - w / 2) / edge))
    return profile


BALL_POINTS = 25
"""Points of each half of the ball's lower surface the dilation tries: every ``radius / 25`` (0.12 mm for
the tool, 0.24 mm for the finger), so where the ball rests is found to that step."""


def tip_path(profile: np.ndarray, dx: float, radius_mm: float) -> np.ndarray:
    """Height of a ball tip riding on ``profile``: grey dilation by the ball's lower surface, tried every
    :data:`BALL_POINTS`-th of its radius."""
    half = int(radius_mm / dx)
    y = np.arange(-half, half + 1) * dx
    ball = np.sqrt(np.maximum(radius_mm**2 - y**2, 0.0)) - radius_mm
    footprint = np.abs(np.arange(-half, half + 1)) % max(1, half // BALL_POINTS) == 0
    return ndimage.grey_dilation(profile, footprint=footprint, structure=ball, mode="nearest")


@dataclass(frozen=True)
class SlidePath:
    """Kinematics of one slide sampled at one rate: speed (mm/s), acceleration (mm/s^2), position (mm)."""

    v: np.ndarray
    dv: np.ndarray
    x: np.ndarray

    @property
    def size(self) -> int:
        return self.x.size

    @property
    def end_mm(self) -> float:
        """Distance slid by the end of the step."""
        return float(self.x[-1])


def slide_path(seconds: float, fs: float, start_s: float, speed: float, motion: np.ndarray) -> SlidePath:
    """Rest until ``start_s``, ramp up within ``motion[0]`` s, then slide with a slow hand modulation.

    ``motion`` = (ramp time s, modulation Hz, modulation phase rad, modulation depth); the same values give
    the same path at every rate, so the audio, vibration and IR channels stay aligned.
    """
    ramp, f_mod, phase, depth = motion
    t = times(seconds, fs)
    moving = t - start_s
    hand = 1 + depth * np.sin(2 * np.pi * f_mod * np.maximum(moving, 0) + phase)
    v = speed * smoothstep(moving / ramp) * hand
    x = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1])) / fs))
    return SlidePath(v, np.gradient(v, 1 / fs), x)


class ResampledPath:
    """``path``, sampled at ``fs``, at another ``rate`` over ``samples`` samples: ``v``, ``dv`` and ``x``
    (as :class:`SlidePath`) interpolated linearly when first read, so a slide that needs only the speed
    (a surface without macro-profile, a contact without audible stick-slip) pays for the speed alone.

    The path is smooth on the slower grid (the hand's modulation is below 2 Hz, the ramp at least 80 ms),
    so the interpolated position differs from a direct integration at ``rate`` by far less than the
    macro-profile's grid (about 1e-4 mm); an interpolation costs less than the path's own arithmetic.
    """

    def __init__(self, path: SlidePath, fs: float, rate: float, samples: int) -> None:
        self._path = path
        self._position, self._grid = _positions(samples, fs / rate, path.size)
        self.size = samples

    def _at(self, values: np.ndarray) -> np.ndarray:
        return np.interp(self._position, self._grid, values)

    @cached_property
    def v(self) -> np.ndarray:
        return self._at(self._path.v)

    @cached_property
    def dv(self) -> np.ndarray:
        return self._at(self._path.dv)

    @cached_property
    def x(self) -> np.ndarray:
        return self._at(self._path.x)

    @property
    def end_mm(self) -> float:
        return self._path.end_mm


AnyPath = SlidePath | ResampledPath


@lru_cache(maxsize=8)
def _positions(samples: int, step: float, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Sample positions ``0, step, 2 step, ...`` on a grid of ``size`` samples, and that grid (read-only)."""
    position, grid = np.arange(samples) * step, np.arange(size, dtype=np.float64)
    position.flags.writeable = grid.flags.writeable = False
    return position, grid


def draw_motion(rng: Rng) -> np.ndarray:
    return np.array([rng.uniform(0.08, 0.2), rng.uniform(0.5, 1.5), rng.uniform(0, 2 * np.pi),
                     rng.uniform(0.05, 0.15)])


@dataclass(frozen=True)
class Surface:
    """Slope and curvature of the tip's path over the macro-profile, on its grid ``MACRO_DX_MM`` apart."""

    slope: np.ndarray
    curvature: np.ndarray

    def acceleration(self, path: AnyPath) -> np.ndarray:
        """Vertical tip acceleration ``v^2 z''(x) + v' z'(x)`` in g."""
        both = lookup(self.curvature + 1j * self.slope, path.x / MACRO_DX_MM)
        return (path.v**2 * both.real + path.dv * both.imag) / G_MM_S2


def lookup(grid: np.ndarray, position: np.ndarray) -> np.ndarray:
    return np.interp(position, np.arange(grid.size), grid)


def surface(material: Material, tip: Tip, macro: np.ndarray) -> Surface:
    """The macro-profile as the tip follows it: pits narrower than the tip are bridged."""
    path = tip_path(macro, MACRO_DX_MM, tip.radius_mm) if material.roughness.macro_height_um else macro
    slope = np.gradient(path, MACRO_DX_MM)
    return Surface(slope, np.gradient(slope, MACRO_DX_MM))
