"""Tips, contact mechanics and the surface a tip follows along a slide path.

Vibration is modelled as the tip following a surface height profile ``z(x)`` along the path ``x(t)``: its
acceleration ``v^2 z''(x) + v' z'(x)`` passes the tip-surface contact resonance (the tap frequency) to the
accelerometer and a radiation filter to the microphone, so the spectrum scales with the slide speed; the IR
sensor sees the same macro profile.
"""

from __future__ import annotations

from dataclasses import dataclass

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
    audio_gain: float
    """Microphone full scale per g of radiated contact acceleration."""


TOOL = Tip("tool", radius_mm=3.0, min_contact_mm=0.02, frequency_hz=1400.0, damping=0.03, gain=0.03,
           tap_g=1.2, audio_gain=0.004)
FINGER = Tip("finger", radius_mm=6.0, min_contact_mm=0.3, frequency_hz=250.0, damping=0.25, gain=0.1,
             tap_g=0.4, audio_gain=0.002)


def contact_frequency_hz(material: Material, tip: Tip) -> float:
    """Resonance of the hand-held unit on the surface: rises with the material's stiffness.

    ``f_mat = 900 Hz (E / 210 GPa)^(1/4)`` (a steel tip on steel rings near 900 Hz; Hertz contact stiffness
    grows as E^(2/3) and the unit's effective mass falls for stiffer contacts), in series with the tip's
    own resonance: ``1/f^2 = 1/f_mat^2 + 1/f_tip^2``. Interpretation: a lumped model, not a measurement.
    """
    f_mat = 900.0 * (material.compliance.elastic_modulus_mpa / 210000.0) ** 0.25
    return float(1.0 / np.sqrt(1.0 / f_mat**2 + 1.0 / tip.frequency_hz**2))


def _contact_width_mm(material: Material, tip: Tip) -> float:
    """Hertz contact radius ``(3 F R / 4 E)^(1/3)`` at 1 N, not below the tip's minimum, not above R."""
    e_pa = material.compliance.elastic_modulus_mpa * 1e6
    hertz = 1e3 * (3 * 1.0 * tip.radius_mm * 1e-3 / (4 * e_pa)) ** (1 / 3)
    return float(np.clip(hertz, tip.min_contact_mm, tip.radius_mm))


def damping_ratio(material: Material, tip: Tip) -> float:
    return material.compliance.loss_factor / 2 + tip.damping


MACRO_DX_MM = 0.05


def _micro_derivatives(rough: Roughness, rng: Rng, n: int, dx: float,
                       contact_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Slope and curvature (1/mm) of a self-affine micro-profile on a grid of ``n`` points ``dx`` mm apart.

    Height spectrum ``S(k) = (1 + (k/k_c)^2)^(-exponent/2)`` scaled to an rms of ``micro_um``, seen through
    the contact as ``1 / (1 + (pi k a)^2)`` with ``a = contact_mm``: wavelengths shorter than the contact
    are averaged out, but asperity impacts keep a power-law tail.
    """
    k = np.fft.rfftfreq(n, dx)
    amplitude = (1.0 + (k / rough.cutoff_per_mm) ** 2) ** (-rough.exponent / 4)
    amplitude[0] = 0.0
    spectrum = amplitude * (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size))
    rms = np.sqrt(2 * np.sum(np.abs(spectrum) ** 2)) / n
    spectrum *= (rough.micro_um * 1e-3 / rms if rms > 0 else 0.0) / (1 + (np.pi * k * contact_mm) ** 2)
    ik = 2j * np.pi * k
    return np.fft.irfft(ik * spectrum, n), np.fft.irfft(ik**2 * spectrum, n)


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


def tip_path(profile: np.ndarray, dx: float, radius_mm: float) -> np.ndarray:
    """Height of a ball tip riding on ``profile``: grey dilation by the ball's lower surface."""
    half = int(radius_mm / dx)
    y = np.arange(-half, half + 1) * dx
    ball = np.sqrt(np.maximum(radius_mm**2 - y**2, 0.0)) - radius_mm
    return ndimage.grey_dilation(profile, structure=ball, size=ball.size, mode="nearest")


@dataclass(frozen=True)
class SlidePath:
    """Kinematics of one slide sampled at one rate: speed (mm/s), acceleration (mm/s^2), position (mm)."""

    v: np.ndarray
    dv: np.ndarray
    x: np.ndarray


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


def draw_motion(rng: Rng) -> np.ndarray:
    return np.array([rng.uniform(0.08, 0.2), rng.uniform(0.5, 1.5), rng.uniform(0, 2 * np.pi),
                     rng.uniform(0.05, 0.15)])


@dataclass(frozen=True)
class Surface:
    """Slope and curvature of the tip's path on two grids: fine micro-profile and coarse macro-profile."""

    dx: float
    micro_slope: np.ndarray
    micro_curvature: np.ndarray
    macro_slope: np.ndarray
    macro_curvature: np.ndarray

    def acceleration(self, path: SlidePath) -> np.ndarray:
        """Vertical tip acceleration ``v^2 z''(x) + v' z'(x)`` in g."""
        fine = path.x / self.dx
        coarse = path.x / MACRO_DX_MM
        slope = lookup(self.micro_slope, fine) + lookup(self.macro_slope, coarse)
        curvature = lookup(self.micro_curvature, fine) + lookup(self.macro_curvature, coarse)
        return (path.v**2 * curvature + path.dv * slope) / G_MM_S2


def lookup(grid: np.ndarray, position: np.ndarray) -> np.ndarray:
    return np.interp(position, np.arange(grid.size), grid)


def surface(material: Material, rng: Rng, tip: Tip, length_mm: float,
             n_fine: int, macro: np.ndarray | None = None) -> Surface:
    """The surface the tip follows over ``length_mm``; pass ``macro`` to share one macro profile."""
    n = int(2 ** np.ceil(np.log2(max(n_fine, 1024))))
    dx = max(length_mm, 1.0) / n
    slope, curvature = _micro_derivatives(material.roughness, rng, n, dx, _contact_width_mm(material, tip))
    if macro is None:
        macro = macro_profile(material.roughness, rng, int(length_mm / MACRO_DX_MM) + 8, MACRO_DX_MM)
    path = tip_path(macro, MACRO_DX_MM, tip.radius_mm) if material.roughness.macro_height_um else macro
    macro_slope = np.gradient(path, MACRO_DX_MM)
    return Surface(dx, slope, curvature, macro_slope, np.gradient(macro_slope, MACRO_DX_MM))
