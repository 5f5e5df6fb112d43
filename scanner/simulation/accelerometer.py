"""The simulated ADXL335 accelerometer of TU1 (0.330 V/g around 1.65 V through the DAQ's 16 bits over
+-10 V, +-3.6 g rails): the finger and tool taps, and the unit's vibration while it slides.

While sliding, the unit carries the tip's acceleration (:mod:`~scanner.simulation.contact`: texture,
stick-slip, the finger's ridges) through the tip-surface contact resonance, plus its bearings' rolling, the
hand's own motion and the jolt as it breaks loose. The contact resonance is a lumped model: the unit's
effective mass on the Hertz contact stiffness, in series with the tip's own resonance.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft

from scanner.calibration import ACCEL_V_PER_G, ACCEL_ZERO_V, accel_g
from scanner.simulation.contact import Excitation, coarse_frequencies, on_bins
from scanner.simulation.materials import Material
from scanner.simulation.signals import (
    DAQ_LSB_V,
    FS_AUDIO,
    FS_DAQ,
    STEP_S,
    Arrays,
    Rng,
    band_noise,
    bank_normals,
    gravity,
    quantise,
    resonance,
    tilt,
    times,
)
from scanner.simulation.surface import FINGER, G_MM_S2, TOOL, SlidePath, Tip, contact_frequency_hz, damping_ratio
from scanner.simulation.variability import OperatorDraw

ADXL_RANGE_G = 3.6
ADXL_NOISE_G = np.array([0.003, 0.003, 0.005])
"""ADXL335 noise over the 1.5 kHz band (x/y 150, z 300 ug/sqrt(Hz) datasheet densities, band-limited)."""
def adxl335(acceleration: np.ndarray, rng: Rng) -> np.ndarray:
    """Acceleration (n, 3) in g as the DAQ reads it: sensor noise, +-3.6 g rails, DAQ quantisation."""
    noisy = acceleration + bank_normals(rng, acceleration.size).reshape(acceleration.shape) * ADXL_NOISE_G
    volts = ACCEL_ZERO_V + ACCEL_V_PER_G * np.clip(noisy, -ADXL_RANGE_G, ADXL_RANGE_G)
    return accel_g(quantise(volts, DAQ_LSB_V))

def _tap_train(material: Material, rng: Rng, operator: OperatorDraw, tip: Tip) -> np.ndarray:
    """(n, 3) acceleration in g of 3-5 taps: each a decaying contact resonance plus the hand's stop.

    ``a(t) = A exp(-t/tau) sin(2 pi f t)`` with f the contact resonance, ``tau = 1 / (2 pi f zeta)`` and
    ``A = tap_g * strength * sqrt(f / 500 Hz)`` (harder contacts decelerate the unit more abruptly).
    """
    t = times(STEP_S, FS_DAQ)
    f = contact_frequency_hz(material, tip)
    tau = 1.0 / (2 * np.pi * f * damping_ratio(material, tip))
    count = int(rng.integers(3, 6))
    onsets = 0.6 + (np.arange(count) + rng.uniform(0.1, 0.6, count)) * (3.9 / count)
    unit = np.zeros((t.size, 3))
    for onset, strength in zip(onsets, operator.tap_strength * rng.uniform(0.8, 1.2, count), strict=True):
        # The hand's stop (a 30 ms Gaussian) is below 1e-9 of its peak beyond 0.2 s, the ring beyond 20 tau.
        start, stop = np.searchsorted(t, (onset - 0.2, onset + max(0.2, 20 * tau)))
        since = t[start:stop] - onset
        ring = np.where(since >= 0, np.exp(-np.maximum(since, 0.0) / tau) * np.sin(2 * np.pi * f * since), 0.0)
        approach = -since / 0.03 * np.exp(-0.5 * (since / 0.03) ** 2)
        amplitude = tip.tap_g * strength * np.sqrt(f / 500.0)
        direction = np.array([rng.normal(0, 0.15), rng.normal(0, 0.15), 1.0])
        unit[start:stop] += np.outer(amplitude * ring + 0.15 * strength * approach, direction)
    return unit @ tilt(*operator.tilt_deg).T + gravity(t.size, operator.tilt_deg)


def finger_tap(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 finger tap: ``v_ft`` (docs/operator.md#procedure step 1)."""
    return {"v_ft": adxl335(_tap_train(material, rng, operator, FINGER), rng)}


def tool_tap(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 tool tap: ``v_tt`` (docs/operator.md#procedure step 3)."""
    return {"v_tt": adxl335(_tap_train(material, rng, operator, TOOL), rng)}


ROLLING_G = 0.2
"""Broadband excitation of the unit by its rolling bearings at 130 mm/s (g, before the contact resonance)."""
ROLLING_BAND_HZ = (50.0, 3000.0)


def onset_jolt(rng: Rng, t: np.ndarray, start_s: float) -> np.ndarray:
    """(n, 3) g: the hand's jerk and the unit's ringing as it breaks loose (what the start detector sees)."""
    since = t - start_s
    width = rng.uniform(0.004, 0.008)
    pulse = np.where((since >= 0) & (since < width), np.sin(np.pi * np.clip(since, 0, None) / width), 0.0)
    after = np.clip(since, 0, None)
    ring = np.where(since >= 0, np.exp(-after / 0.006), 0.0) * np.sin(2 * np.pi * 1150 * since)
    amplitude = rng.uniform(0.15, 0.35)
    return amplitude * np.column_stack([pulse + 0.5 * ring, 0.3 * ring, 0.5 * pulse + 0.4 * ring])


def rolling_psd(f: np.ndarray, speed: float) -> np.ndarray:
    """One-sided PSD (g^2/Hz) of the bearings' rolling noise at the slide's mean ``speed`` (mm/s): flat over
    50-3000 Hz with rms ``ROLLING_G speed / 130 mm/s``."""
    lo, hi = ROLLING_BAND_HZ
    level = (ROLLING_G * speed / 130.0) ** 2 / (hi - lo)
    return np.where((f >= lo) & (f <= hi), level, 0.0)


def tip_response(material: Material, tip: Tip, n_fft: int) -> np.ndarray:
    """The tip-surface contact resonance (:func:`contact_frequency_hz`, :func:`damping_ratio`) at the coarse
    frequencies of an ``n_fft``-sample audio-rate grid (:func:`~scanner.simulation.contact.coarse_frequencies`):
    how the tip's acceleration follows the acceleration the surface imposes. The same for every slide of a
    material and tip (cached)."""
    return _resonance_on_grid(contact_frequency_hz(material, tip), damping_ratio(material, tip), n_fft)


@lru_cache(maxsize=64)
def _resonance_on_grid(f0: float, zeta: float, n_fft: int) -> np.ndarray:
    response = resonance(coarse_frequencies(n_fft, FS_AUDIO), f0, zeta).astype(np.complex64)
    response.flags.writeable = False
    return response


def unit_vibration(exc: Excitation, response: np.ndarray, timed: list[np.ndarray | None], tip: Tip,
                   envelope: np.ndarray, n_fft: int, n_out: int) -> np.ndarray:
    """(n_out, 3) g at the DAQ rate: the tip's vertical (z) and lateral (x) acceleration on the unit.

    The excitation's stationary spectra and the ``timed`` ones (a row of None: silent) are on the
    audio-rate grid of ``n_fft`` samples, ``response`` the contact resonance on its coarse frequencies
    (:func:`tip_response`); the bins up to 1500 Hz are the same signal at 3000 Hz (``n_fft`` FS_DAQ /
    FS_AUDIO samples), band-limited exactly as the ADXL335's 1.6 kHz bandwidth and the DAQ's anti-aliasing
    leave it. The stationary part is scaled in time by ``envelope`` (at the DAQ rate); y sees a little of
    both axes.
    """
    n_daq = int(round(n_fft * FS_DAQ / FS_AUDIO))
    bins = n_daq // 2 + 1
    rows = np.zeros((4, bins), np.complex64)
    rows[:2] = on_bins(response * exc.amplitude, n_fft, FS_AUDIO, bins) * exc.draws[:, :bins]
    for row, spectrum in zip(rows[2:], timed, strict=True):
        if spectrum is not None:
            row[:] = on_bins(response, n_fft, FS_AUDIO, bins) * spectrum[:bins]
    seen = fft.irfft(rows, n_daq)[:, :n_out].astype(np.float64) * (n_daq / n_fft) * tip.gain
    z = seen[0] * envelope + seen[2]
    x = seen[1] * envelope + seen[3]
    return np.column_stack([x, 0.3 * z + 0.2 * x, z])


def hand_motion(rng: Rng, path: SlidePath) -> np.ndarray:
    """(n, 3) g: the unit's own acceleration along the path and the hand's slow sway (below 5 Hz)."""
    n = path.x.size
    hand = np.zeros((n, 3))
    hand[:, 0] = path.dv / G_MM_S2
    sway = np.column_stack([band_noise(rng, n, FS_DAQ, 0.3, 5.0) for _ in range(2)])
    hand[:, :2] += 0.02 * (path.v / 130.0)[:, None] * sway
    return hand
