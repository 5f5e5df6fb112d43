"""The tip-surface contact of a TU1 slide: Hertz contact, stick-slip and the excitation both sensors share.

One slide has one excitation: the vertical acceleration the surface imposes on the tip as it follows the
height profile, and the lateral (friction) acceleration, both in g. The accelerometer
(:mod:`~scanner.simulation.accelerometer`) sees them through the unit's contact resonance; the microphone
(:mod:`~scanner.simulation.microphone`) hears the force they put on the sample and on the unit. Nothing in
the sound is drawn apart from the vibration, so two materials sound different exactly where their surfaces,
stiffnesses and frictions differ.

Models and their sources:

- **Texture vibration.** The tip follows the surface profile ``z(x)`` at the hand's speed ``v``; its
  acceleration ``v^2 z''(x) + v' z'(x)`` has the height spectrum mapped to temporal frequency ``f = v k``:
  ``P_a(f) = (2 pi f)^4 S_z(f / v) / v``, so it grows and brightens with speed (the texture-vibration
  model behind the Penn Haptic Texture Toolkit: Culbertson, McDonald, Goodman and Kuchenbecker 2014,
  "One hundred data-driven haptic texture models and open-source methods for rendering on 3D objects",
  IEEE Haptics Symposium, whose models are indexed by speed and force
  because the spectrum moves with both). The micro-profile is stationary during the slide, so it is
  synthesised once at the slide's mean speed in the frequency domain and scaled by ``(v(t)/v_mean)^2``;
  the macro-profile (pores, holes, ridges) is followed sample by sample along the path.
- **Contact patch.** Hertz contact of a ball of radius ``R`` pressed with ``F_n``:
  ``a = (3 F_n R / 4 E*)^(1/3)``, ``1/E* = 1/E_surface + 1/E_tip`` (Johnson 1985, *Contact Mechanics*,
  eq. 4.22); wavelengths shorter than the patch are averaged out.
- **Stick-slip.** Between stick and slip the contact spring of tangential stiffness
  ``k_t = 8 G* a`` (Mindlin; Johnson 1985 eq. 7.41, ``G* ~ E*/2.6`` for Poisson's ratio 0.3) is loaded
  from ``mu_k F_n`` to ``mu_s F_n``, which at speed ``v`` takes ``(mu_s - mu_k) F_n / (k_t v)``: slips
  recur at ``f_ss = k_t v / (2 (mu_s - mu_k) F_n)`` (the relaxation oscillation of Rabinowicz 1965,
  *Friction and Wear of Materials*, ch. 4), each releasing ``(mu_s - mu_k) F_n`` at once. A soft or sticky
  contact squeaks within the audio band; a hard one slips far above it and only its broadband hiss remains.
- **Fingerprint ridges.** Skin ridges ``0.45 mm`` apart (:data:`~scanner.simulation.surface.FINGER`)
  modulate the finger's friction at ``v / 0.45 mm`` (Scheibert, Leurent, Prevost and Debregeas 2009,
  "The role of fingerprints in the coding of tactile information probed with a biomimetic sensor",
  Science 323).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import Rng, complex_normals
from scanner.simulation.surface import G_MM_S2, AnyPath, Surface, Tip

POISSON = 0.3
SMOOTH_STEP = 8
"""Frequency bins between the points where smooth spectral factors are evaluated (then interpolated): 1.4 Hz
on a slide's grid, a fraction of the narrowest resonance (a plate mode's bandwidth ``eta f``)."""
RIDGE_SHARE = 0.05
"""Share of the finger's friction force the ridges modulate (interpretation)."""


@dataclass(frozen=True)
class ContactMechanics:
    """The quasi-static contact of one slide: patch radius, tangential stiffness and stick-slip rate."""

    normal_n: float
    radius_mm: float
    averaging_mm: float
    """Width over which the tip averages the texture: the Hertz radius, or half a skin ridge."""
    tangential_n_per_mm: float
    stick_slip_per_mm: float
    """Slips per mm of sliding, ``k_t / (2 (mu_s - mu_k) F_n)``; 0 without a static-kinetic difference."""


def effective_modulus_mpa(material: Material, tip: Tip) -> float:
    """``E*`` of the tip on the surface: ``1/E* = (1 - nu^2) (1/E_surface + 1/E_tip)``."""
    return 1.0 / ((1 - POISSON**2) * (1.0 / material.compliance.elastic_modulus_mpa + 1.0 / tip.modulus_mpa))


def contact_mechanics(material: Material, tip: Tip, normal_n: float) -> ContactMechanics:
    """Hertz patch radius (not below the tip's smallest contact, not above its radius), Mindlin tangential
    stiffness and the stick-slip rate per mm of sliding at ``normal_n`` newtons."""
    e_star = effective_modulus_mpa(material, tip)
    hertz = (3 * normal_n * tip.radius_mm / (4 * e_star)) ** (1 / 3)  # N, mm, MPa = N/mm^2 -> mm
    radius = float(np.clip(hertz, tip.min_contact_mm, tip.radius_mm))
    k_t = 8 * (e_star / 2.6) * radius  # N/mm
    fric = material.friction
    drop = fric.static - fric.kinetic
    rate = k_t / (2 * drop * normal_n) if drop > 0 else 0.0
    averaging = tip.ridge_mm / 2 if tip.ridge_mm else radius
    return ContactMechanics(normal_n, radius, averaging, k_t, rate)


@dataclass(frozen=True)
class Excitation:
    """What the surface does to the tip over one slide, on the audio-rate grid of ``n_fft`` samples.

    The micro-profile's vertical and lateral tip acceleration (g) at the mean speed, to be scaled in time by
    ``envelope`` ``(v(t) / mean_speed)^2``, has the spectrum ``amplitude * draws``: ``amplitude`` (2, m),
    real, smooth in frequency and given every :data:`SMOOTH_STEP` bins (:func:`on_bins` interpolates it),
    ``draws`` (2, n_fft//2+1) complex standard normals. Every linear filter after it is smooth too, so the
    sensors multiply it in on the coarse grid and pay the fine grid once. ``timed`` (2, n) float32: the
    macro-profile's vertical acceleration and the lateral stick-slip and ridge excitation (g), already at
    their moments.
    """

    amplitude: np.ndarray
    draws: np.ndarray
    envelope: np.ndarray
    timed: np.ndarray
    contact: ContactMechanics
    mean_speed: float


def coarse_frequencies(n_fft: int, fs: float) -> np.ndarray:
    """The frequencies of every :data:`SMOOTH_STEP`-th bin of an ``n_fft``-sample grid, and of its last bin
    (so interpolation never extrapolates)."""
    return _coarse_frequencies(n_fft, fs)


@lru_cache(maxsize=4)
def _coarse_frequencies(n_fft: int, fs: float) -> np.ndarray:
    bins = n_fft // 2 + 1
    index = np.unique(np.append(np.arange(0, bins, SMOOTH_STEP), bins - 1))
    f = index * (fs / n_fft)
    f.flags.writeable = False
    return f


def on_bins(coarse: np.ndarray, n_fft: int, fs: float, bins: int | None = None) -> np.ndarray:
    """Values given at :func:`coarse_frequencies` (last axis), interpolated linearly onto the first
    ``bins`` bins (default all) of the ``n_fft``-sample grid, as complex64 or float32."""
    below, share = _interpolation(n_fft, fs)
    below, share = below[:bins], share[:bins]
    values = np.asarray(coarse, np.complex64 if np.iscomplexobj(coarse) else np.float32)
    steps = np.diff(values, axis=-1)
    return np.take(values, below, axis=-1) + np.take(steps, below, axis=-1) * share


@lru_cache(maxsize=4)
def _interpolation(n_fft: int, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """For every bin of the grid: the coarse point at or below it and its share of the way to the next one."""
    grid = np.rint(_coarse_frequencies(n_fft, fs) * (n_fft / fs)).astype(np.int64)
    bins = np.arange(n_fft // 2 + 1)
    below = np.clip(np.searchsorted(grid, bins, side="right") - 1, 0, grid.size - 2)
    share = ((bins - grid[below]) / (grid[below + 1] - grid[below])).astype(np.float32)
    below = below.astype(np.intp)
    below.flags.writeable = share.flags.writeable = False
    return below, share


def excitation(material: Material, rng: Rng, tip: Tip, path: AnyPath, fs: float, normal_n: float,
               surface: Surface, n_fft: int, background: Callable[[np.ndarray, float], np.ndarray]) -> Excitation:
    """The slide's excitation (:class:`Excitation`) for the tip pressed with ``normal_n`` along ``path``,
    its stationary part on a grid of ``n_fft`` samples; ``background(f, mean_speed)`` is the PSD (g^2/Hz) of
    independent stationary noise added to both tracks (the bearings' rolling)."""
    moving = path.v > 1e-3
    mean_speed = float(path.v[moving].mean()) if moving.any() else 1.0
    contact = contact_mechanics(material, tip, normal_n)
    amplitude = micro_amplitude(material, n_fft, fs, mean_speed, contact.averaging_mm, background)
    draws = complex_normals(rng, (2, n_fft // 2 + 1))
    envelope = np.square(path.v * (1 / mean_speed), dtype=np.float32)
    timed = np.empty((2, path.size), np.float32)
    timed[0] = surface.acceleration(path) if surface.slope.any() else 0.0  # a surface without macro-profile
    timed[1] = stick_slip(rng, path, contact, material, tip)
    if tip.ridge_mm:
        timed[1] += ridges(path, material, tip, normal_n)
    return Excitation(amplitude, draws, envelope, timed, contact, mean_speed)


def micro_amplitude(material: Material, n: int, fs: float, speed: float, contact_mm: float,
                    background: Callable[[np.ndarray, float], np.ndarray]) -> np.ndarray:
    """(2, m) amplitudes, at :func:`coarse_frequencies`, of the spectra of the vertical and the lateral tip
    acceleration (g) over the micro-profile: times complex standard normals, a spectrum for ``irfft(., n)``.

    Height PSD ``S_z(k) ~ (1 + (k/k_c)^2)^(-exponent/2)`` scaled to the rms ``micro_um`` over 0.01-100 /mm,
    seen through the contact patch as ``1 / (1 + (pi k a)^2)``; temporal PSD ``S_z(f/v)/v``; the lateral
    track is an independent profile of the same statistics times the kinetic friction coefficient (the
    friction force follows the normal load the asperities put on the tip). The ``background`` noise is
    independent of both, so it adds in power and shares their Gaussian draws.
    """
    rough = material.roughness
    coarse = coarse_frequencies(n, fs)
    k = coarse / speed
    shape = (1.0 + (k / rough.cutoff_per_mm) ** 2) ** (-rough.exponent / 2)
    shape[0] = 0.0
    density = (rough.micro_um * 1e-3) ** 2 / _shape_integral(rough.cutoff_per_mm, rough.exponent)
    psd = shape * (density / speed)  # mm^2 / Hz
    amplitude = np.sqrt(psd * (n * fs / 4)) / (1 + (np.pi * contact_mm * k) ** 2) * (2 * np.pi * coarse) ** 2 / G_MM_S2
    floor = background(coarse, speed) * (n * fs / 4)
    return np.stack([np.sqrt(amplitude**2 + floor), np.sqrt((material.friction.kinetic * amplitude) ** 2 + floor)])


@lru_cache(maxsize=256)
def _shape_integral(cutoff: float, exponent: float) -> float:
    """``int (1 + (k/k_c)^2)^(-exponent/2) dk`` over 0.01-100 /mm (the micro-profile's band)."""
    k = np.geomspace(0.01, 100.0, 400)
    values = (1.0 + (k / cutoff) ** 2) ** (-exponent / 2)
    return float(np.sum(0.5 * (values[1:] + values[:-1]) * np.diff(k)))


def stick_slip(rng: Rng, path: AnyPath, contact: ContactMechanics, material: Material,
               tip: Tip) -> np.ndarray:
    """Lateral tip acceleration (g) of the slips: one impulse of ``(mu_s - mu_k) F_n / m_tip`` each time
    the sliding distance crosses another stick length (+-15 % jitter), while sliding."""
    out = np.zeros(path.size)
    if contact.stick_slip_per_mm <= 0:
        return out
    count = int(contact.stick_slip_per_mm * path.end_mm)
    if count == 0 or count > path.size // 4:  # no slip yet, or slips faster than fs/4: broadband hiss only
        return out
    positions = (np.arange(1, count + 1) + rng.uniform(-0.15, 0.15, count)) / contact.stick_slip_per_mm
    index = np.clip(np.searchsorted(path.x, positions), 0, path.x.size - 1)
    drop = (material.friction.static - material.friction.kinetic) * contact.normal_n
    np.add.at(out, index, drop / (tip.mass_g * 1e-3) / (G_MM_S2 * 1e-3))
    return out


def ridges(path: AnyPath, material: Material, tip: Tip, normal_n: float) -> np.ndarray:
    """Lateral tip acceleration (g) of the skin's ridges: ``RIDGE_SHARE mu_k F_n / m`` at ``x / ridge``."""
    if not tip.ridge_mm:
        return np.zeros(path.size)
    force = RIDGE_SHARE * material.friction.kinetic * normal_n
    return force / (tip.mass_g * 1e-3) / (G_MM_S2 * 1e-3) * np.sin(2 * np.pi * path.x / tip.ridge_mm) * (path.v > 0)

