"""Building blocks shared by the simulated sensors: sample rates and step lengths of the scanning procedure,
the DAQ's quantisation, smooth ramps, band-limited noise, a bank of Gaussian draws, a contact resonance, the
unit's tilt and gravity."""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from scipy import fft, signal

from scanner.scan import CHANNELS

FS_DAQ = CHANNELS["v_ts"].fs
FS_AUDIO = CHANNELS["a_ts"].fs
FS_THERMAL = CHANNELS["t_cool"].fs
FS_MAGNET = CHANNELS["dB"].fs
STEP_S = 5.0
"""Length of every tap, slide, friction, press and fold recording (docs/operator.md#procedure)."""
STATIC_S = 1.0
Rng = np.random.Generator
Arrays = dict[str, np.ndarray]
DAQ_LSB_V = 20.0 / 65536
"""NI USB-6002: 16 bits over +-10 V."""
def quantise(x: Any, step: float) -> Any:
    return np.round(np.asarray(x, dtype=np.float64) / step) * step if np.ndim(x) else round(x / step) * step

def smoothstep(x: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero first and second derivatives at both ends (quintic)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def times(seconds: float, fs: float) -> np.ndarray:
    return np.arange(int(round(seconds * fs))) / fs


def band_noise(rng: Rng, n: int, fs: float, lo: float, hi: float) -> np.ndarray:
    """Unit-rms Gaussian noise band-limited to [lo, hi] Hz (brick-wall in the frequency domain)."""
    freqs = np.fft.rfftfreq(n, 1.0 / fs)
    inside = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    spectrum = np.zeros(n // 2 + 1, np.complex128)
    if inside.size:
        spectrum[inside[0]:inside[-1] + 1] = complex_normals(rng, inside.size)
    x = fft.irfft(spectrum, n)
    rms = np.sqrt(np.mean(x**2))
    return x / rms if rms > 0 else x


NORMAL_BANK_SIZE = 2**23
"""Standard normal draws in the bank (32 MB of float32) that the audio-rate spectra and the photos' pixel
noise read their Gaussian numbers from."""


@lru_cache(maxsize=1)
def _normal_bank() -> np.ndarray:
    """:data:`NORMAL_BANK_SIZE` standard normal float32 draws of a fixed seed, read-only, made once per process."""
    bank = np.random.default_rng(20241127).standard_normal(NORMAL_BANK_SIZE, dtype=np.float32)
    bank.flags.writeable = False
    return bank


def bank_normals(rng: Rng, count: int) -> np.ndarray:
    """``count`` standard normal float32 numbers (read-only): a stretch of the bank from an even offset that
    ``rng`` draws, or fresh draws where a stretch would exceed half the bank.

    Each stretch is an exact sample of independent standard normals, and ``rng`` fixes which one, so a
    seed still fixes the result; two stretches may overlap, shifted against each other, which no
    feature of a scan can tell from independent draws. Drawing costs the offset, not ``count`` numbers:
    a slide's spectra hold a million of them.
    """
    bank = _normal_bank()
    if count > bank.size // 2:
        return rng.standard_normal(count, dtype=np.float32)
    start = 2 * int(rng.integers(0, (bank.size - count) // 2 + 1))
    return bank[start:start + count]


def complex_normals(rng: Rng, shape: int | tuple[int, ...]) -> np.ndarray:
    """Complex64 numbers of ``shape`` whose real and imaginary parts are independent standard normals
    (:func:`bank_normals`, read-only)."""
    size = int(np.prod(shape))
    return bank_normals(rng, 2 * size).view(np.complex64).reshape(shape)


def noise_spectrum(rng: Rng, n: int, fs: float, psd: np.ndarray) -> np.ndarray:
    """Spectrum (``n//2+1`` bins, for ``irfft(., n)``) of Gaussian noise with the one-sided PSD ``psd``.

    Each bin is ``sqrt(psd n fs / 4) (a + i b)`` with ``a, b`` standard normal, so the signal's variance is
    ``sum(psd) fs / n``, the PSD integrated over the bins.
    """
    scale = np.sqrt(np.asarray(psd, np.float32) * np.float32(n * fs / 4))
    return scale * complex_normals(rng, n // 2 + 1)


def resonance(f: np.ndarray, f0: float, zeta: float) -> np.ndarray:
    """Frequency response of ``w0^2 / (s^2 + 2 zeta w0 s + w0^2)`` (unit DC gain) at the frequencies ``f``."""
    r = f / f0
    return 1.0 / (1.0 - r * r + 2j * zeta * r)


def resonance_sos(f0: float, zeta: float, fs: float) -> np.ndarray:
    """Second-order low-pass ``w0^2 / (s^2 + 2 zeta w0 s + w0^2)`` (unit DC gain), bilinear, pre-warped."""
    f0 = min(f0, 0.45 * fs)
    w0 = 2 * fs * np.tan(np.pi * f0 / fs)
    b, a = signal.bilinear([w0**2], [1.0, 2 * zeta * w0, w0**2], fs)
    return signal.tf2sos(b, a)


def tilt(pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Rotation from the unit's frame to the accelerometer axes for a unit held slightly tilted."""
    p, r = np.radians(pitch_deg), np.radians(roll_deg)
    about_y = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    about_x = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    return about_x @ about_y


def gravity(n: int, tilt_deg: tuple[float, float]) -> np.ndarray:
    """1 g along the unit's vertical, seen through the operator's tilt: mostly on z."""
    return np.tile(tilt(*tilt_deg) @ np.array([0.0, 0.0, 1.0]), (n, 1))

def envelope(t: np.ndarray, on: float, rise: float, off: float, fall: float) -> np.ndarray:
    return smoothstep((t - on) / rise) * (1.0 - smoothstep((t - off) / fall))
