"""Synthetic texture recordings whose classes differ in one property only (docs/modern-features.md).

Two sets of tool-slide vibrations (role ``vibration``, 3 kHz, 2 s, one axis), each class with the same
power (every recording scaled to unit RMS) and the same amplitude statistics, so a feature that
summarises the signal's level, spread or peakiness cannot tell them apart:

``spectral``  band noise of the same spectral centroid (300 Hz) and power in four spectral *shapes*: one
              narrow peak at 300 Hz; two peaks at 200 and 400 Hz; a flat band 150-450 Hz; two peaks at 250
              and 350 Hz. Each recording's centre frequencies move by up to 4 % (a texture at another speed).
``timing``    impulses of the same height, rate (20 per second) and ringing (a 400 Hz decaying tone) in the
              same background noise, in three *timings*: periodic every 50 ms; at random (Poisson) times;
              in pairs 12 ms apart every 100 ms. The impulse times vary by up to 2 ms.

With ``snr_db``, each recording's contrast is buried in white sensor noise at that signal-to-noise ratio
(noise of RMS ``10 ** (-snr_db / 20)`` added to the unit-RMS signal, then the sum scaled to unit RMS
again): the same contrast, harder to see, so that feature families that resolve it only when it is clean
part from those that still resolve it in noise.

Recordings are deterministic per seed (each draws from its own generator seeded by (seed, set, class,
recording); the noise is drawn after the signal, so a noisy recording holds its clean one). Every
recording is its own group.
"""

from __future__ import annotations

import numpy as np

from scanner.scan import Recording, Trace
from scanner.simulation.materials import SimulationError

FS = 3000.0
SECONDS = 2.0
SETS = ("spectral", "timing")

BAND_SHAPES: dict[str, tuple[tuple[float, float], ...]] = {
    "one-peak": ((300.0, 15.0),),
    "two-peaks-wide": ((200.0, 15.0), (400.0, 15.0)),
    "flat": ((300.0, 150.0),),
    "two-peaks-near": ((250.0, 15.0), (350.0, 15.0)),
}
"""Class -> bands (centre Hz, half-width Hz) of equal power; every class's power-weighted centroid is
300 Hz."""

TIMINGS = ("periodic", "random", "pairs")
IMPULSE_RATE = 20.0
PAIR_GAP_S = 0.012
RING_HZ = 400.0
RING_DECAY_S = 0.004
NOISE_RMS = 0.05


def _rng(seed: int, which: str, c: int, k: int) -> np.random.Generator:
    return np.random.default_rng([seed, SETS.index(which), c, k])


def _band_noise(rng: np.random.Generator, n: int, bands: tuple[tuple[float, float], ...], scale: float) -> np.ndarray:
    """White noise kept in ``bands`` (each of equal power), by masking its spectrum."""
    freqs = np.fft.rfftfreq(n, 1.0 / FS)
    total = np.zeros(n)
    for centre, half in bands:
        spectrum = np.fft.rfft(rng.standard_normal(n))
        spectrum[np.abs(freqs - centre * scale) > half * scale] = 0.0
        part = np.fft.irfft(spectrum, n)
        total += part / np.sqrt(np.mean(part**2))
    return total


def _impulse_times(rng: np.random.Generator, timing: str) -> np.ndarray:
    count = int(IMPULSE_RATE * SECONDS)
    if timing == "periodic":
        times = (np.arange(count) + 0.5) / IMPULSE_RATE
    elif timing == "random":
        times = np.sort(rng.uniform(0.0, SECONDS, count))
    else:
        starts = (np.arange(count // 2) + 0.25) * 2.0 / IMPULSE_RATE
        times = np.concatenate([starts, starts + PAIR_GAP_S])
    return np.clip(times + rng.uniform(-0.002, 0.002, times.size), 0.0, SECONDS - 0.05)


def _impulses(rng: np.random.Generator, timing: str, n: int) -> np.ndarray:
    t = np.arange(int(0.05 * FS)) / FS
    ring = np.sin(2 * np.pi * RING_HZ * t) * np.exp(-t / RING_DECAY_S)
    signal = NOISE_RMS * rng.standard_normal(n)
    for start in np.round(_impulse_times(rng, timing) * FS).astype(int):
        signal[start:start + ring.size] += ring[:n - start]
    return signal


def add_noise(rng: np.random.Generator, data: np.ndarray, snr_db: float) -> np.ndarray:
    """Unit-RMS ``data`` plus white noise of RMS exactly ``10 ** (-snr_db / 20)``, scaled to unit RMS."""
    noise = rng.standard_normal(data.size)
    noise *= 10.0 ** (-snr_db / 20.0) / np.sqrt(np.mean(noise**2))
    noisy = data + noise
    return noisy / np.sqrt(np.mean(noisy**2))


def contrast_recordings(which: str, per_class: int = 30, seed: int = 0,
                        snr_db: float | None = None) -> list[Recording]:
    """The recordings of the set ``which`` (``spectral`` or ``timing``), ``per_class`` of each class,
    clean or (``snr_db``) in white noise at that signal-to-noise ratio.

    Raises
    ------
    SimulationError
        If the set is unknown or ``per_class`` < 2.
    """
    if which not in SETS:
        raise SimulationError(f"unknown contrast set {which!r} (known: {', '.join(SETS)})")
    if per_class < 2:
        raise SimulationError(f"per_class must be at least 2, got {per_class}")
    if snr_db is not None and not np.isfinite(snr_db):
        raise SimulationError(f"snr_db must be a finite number of dB, got {snr_db!r}")
    n = int(FS * SECONDS)
    classes = list(BAND_SHAPES) if which == "spectral" else list(TIMINGS)
    recordings = []
    for c, label in enumerate(classes):
        for k in range(per_class):
            rng = _rng(seed, which, c, k)
            if which == "spectral":
                data = _band_noise(rng, n, BAND_SHAPES[label], rng.uniform(0.96, 1.04))
            else:
                data = _impulses(rng, label, n)
            data = data / np.sqrt(np.mean(data**2))
            if snr_db is not None:
                data = add_noise(rng, data, snr_db)
            name = f"{which}-{label}-{k:03d}"
            recordings.append(Recording(name, {"acc": Trace(data, FS, "g")}, {"vibration": "acc"}, label=label,
                                        group={"object": name}))
    return recordings
