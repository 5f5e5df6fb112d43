"""The simulated lavalier microphone of TU1: the tip's contact vibration through a radiation filter, the
bearings' rolling noise and room noise, 16-bit audio at 44100 Hz."""

from __future__ import annotations

import numpy as np
from scipy import signal

from scanner.simulation.signals import FS_AUDIO, Rng, band_noise, quantise
from scanner.simulation.surface import SlidePath, Tip


def microphone(rng: Rng, tip_g: np.ndarray, path: SlidePath, tip: Tip) -> np.ndarray:
    """Microphone signal: the tip's contact vibration through a radiation filter, room noise, 16 bits.

    Radiation from the small contact region rises as f^2 below ~1 kHz (second-order high-pass); the
    lavalier's band is 10-7500 Hz (paper III-B1b). The bearings' rolling noise grows with speed.
    """
    n = tip_g.size
    radiation = signal.butter(2, 1000.0, btype="highpass", fs=FS_AUDIO, output="sos")
    microphone = signal.butter(2, [10.0, 7500.0], btype="bandpass", fs=FS_AUDIO, output="sos")
    radiated = signal.sosfilt(radiation, tip_g) * tip.audio_gain
    rolling = 0.001 * (path.v / 130.0) * band_noise(rng, n, FS_AUDIO, 200.0, 6000.0)
    room = rng.uniform(0.0002, 0.001) * _pink(rng, n)
    audio = signal.sosfilt(microphone, radiated + rolling + room)
    return quantise(np.clip(audio, -1.0, 1.0 - 2.0**-15), 2.0**-15)


def _pink(rng: Rng, n: int) -> np.ndarray:
    """Unit-rms 1/f noise (room noise)."""
    spectrum = rng.standard_normal(n // 2 + 1) + 1j * rng.standard_normal(n // 2 + 1)
    f = np.fft.rfftfreq(n, 1.0 / FS_AUDIO)
    spectrum /= np.sqrt(np.maximum(f, 20.0))
    x = np.fft.irfft(spectrum, n)
    return x / np.sqrt(np.mean(x**2))
