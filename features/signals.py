"""The features of one signal at any rate, as the role families of :mod:`features.recordings` compute them
on a recording's windows (docs/ingest.md, docs/features.md#generic-signals).

- :func:`audio_features`: the 35 audio features of a whole signal, in bounded memory.
- :func:`band_limited`, :func:`vibration_band`, :func:`vibration_features`: a vibration band-limited as the
  scanner's preprocessing does, and TacTUM's and the other vibration features on it.
- :func:`friction_features`: TacTUM's FST and FRS from a three-axis force.
- :func:`signal_features`: statistics, band shares on a rate-aware band plan (:func:`signal_bands`) and the
  spectral shape of one column of a generic channel.
- :func:`slow_features`, :func:`log_ratio`: level, spread, slope and rate of change of a channel sampled at
  a few hertz, and the level ratio of two such channels.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from features import audio, other, tactum
from scanner.lazy import library
from scanner.preprocess import BAND_HZ
from taxonomy.errors import ParameterError

signal = library("scipy.signal")

FRICTION_WINDOW_S = 0.010
"""TacTUM's stiction window, 10 ms (30 samples at the scanner's 3 kHz), in samples at any rate."""

TARE_S = 0.1
"""The tangential force is tared by its mean over the first 0.1 s, as the scanner's friction offset."""

VIBRATION_NAMES = ("tactum.vibration.miro", "tactum.vibration.mico", "other.vibration.vib_std",
                   "other.vibration.vib_kurtosis", "other.vibration.vib_energy")
FRICTION_NAMES = ("tactum.force_xyz.fst", "tactum.force_xyz.frs")

AUDIO_CHUNK_FRAMES = 256
"""Frames computed at once on a long recording (bounded memory: ~4 MB per array at 44.1 kHz)."""


# -- one signal --------------------------------------------------------------------------------------

def audio_features(x: np.ndarray, fs: float) -> dict[str, float]:
    """The 35 audio features of a whole signal (docs/features.md#audio): each the mean over all its 50 ms frames.

    Equal to ``features.audio.compute(x, fs)``; the frames are computed :data:`AUDIO_CHUNK_FRAMES` at a
    time, each chunk starting one frame early so the spectral flux sees its true previous frame, so a long
    recording needs bounded memory. Several channels (n, channels) are averaged into one (a mono mix).

    Parameters
    ----------
    x : np.ndarray
        The signal, (n,) or (n, channels).
    fs : float
        Sampling rate in Hz; a 50 ms frame must hold at least 20 samples (fs >= 400 Hz).

    Returns
    -------
    dict of str to float
        The 35 features by name (``zcr``, ..., ``f0``, ``mfcc_01``, ..., ``chroma_12``), in
        ``features.audio.NAMES`` order.

    Examples
    --------
    A pure 250 Hz tone has that fundamental; 3000 samples at 400 Hz are 299 frames, computed in two chunks,
    whose mean is that of the one-pass computation to rounding:

    >>> import numpy as np
    >>> from features import audio
    >>> tone = np.sin(2 * np.pi * 250.0 * np.arange(2000) / 4000.0)
    >>> audio_features(tone, 4000.0)["f0"]
    250.0
    >>> noise = np.random.default_rng(0).standard_normal(3000)
    >>> chunked, whole = audio_features(noise, 400.0), audio.compute(noise, 400.0)
    >>> max(abs(chunked[name] - whole[name]) for name in whole) < 1e-9
    True
    """
    values = np.asarray(x, dtype=np.float64)
    values = values.mean(axis=1) if values.ndim == 2 else values
    window, step = audio.window_and_step(fs)
    count = (values.size - window) // step + 1 if values.size >= window else 0
    if count <= AUDIO_CHUNK_FRAMES:
        return audio.compute(values, fs)
    total = np.zeros(len(audio.NAMES))
    for first in range(0, count, AUDIO_CHUNK_FRAMES):
        last = min(first + AUDIO_CHUNK_FRAMES, count)
        begin = max(first - 1, 0)
        rows = audio.frame_features(values[begin * step:(last - 1) * step + window], fs)
        total += rows[first - begin:].sum(axis=0)
    return dict(zip(audio.NAMES, (total / count).tolist(), strict=True))


def vibration_band(fs: float) -> tuple[float, float]:
    """The band of ``v``: the 10-1000 Hz of docs/features.md#preprocessing, the upper edge lowered to 0.45 fs where fs
    cannot carry it.

    Parameters
    ----------
    fs : float
        The vibration's sampling rate in Hz.

    Returns
    -------
    (float, float)
        Lower and upper edge in Hz; the upper one is at or below the lower one for fs <= 22.2 Hz (no band).

    Examples
    --------
    >>> vibration_band(3000.0), vibration_band(1000.0), vibration_band(20.0)
    ((10.0, 1000.0), (10.0, 450.0), (10.0, 9.0))
    """
    return BAND_HZ[0], min(BAND_HZ[1], 0.45 * fs)


@lru_cache(maxsize=16)
def _band_filter(fs: float) -> np.ndarray:
    return signal.butter(4, list(vibration_band(fs)), btype="bandpass", fs=fs, output="sos")


def band_limited(v: np.ndarray, fs: float) -> np.ndarray:
    """Each axis of a vibration band-limited over the whole recording (:func:`vibration_band`,
    docs/features.md#preprocessing).

    Parameters
    ----------
    v : np.ndarray
        The vibration, (n,) or (n, axes).
    fs : float
        Its sampling rate in Hz.

    Returns
    -------
    np.ndarray
        The band-limited vibration, float64 in the shape of ``v`` (4th-order Butterworth band-pass, run
        forward and backward: no phase shift).

    Raises
    ------
    ParameterError
        If the rate is too low for a band above 10 Hz (<= 25 Hz) or the recording too short to filter.

    Examples
    --------
    A 100 Hz sine on an offset of 5: the offset (0 Hz) is removed, the sine in the pass band kept:

    >>> import numpy as np
    >>> t = np.arange(3000) / 3000.0
    >>> band = band_limited(np.sin(2 * np.pi * 100.0 * t) + 5.0, 3000.0)
    >>> middle = band[300:-300]  # away from the filter's start and end
    >>> bool(abs(middle.mean()) < 0.01), round(float(middle.std() * np.sqrt(2)), 3)
    (True, 1.0)
    """
    low, high = vibration_band(fs)
    if high <= low:
        raise ParameterError(f"a vibration at {fs:g} Hz has no band above {low:g} Hz")
    sos = _band_filter(float(fs))
    values = np.asarray(v, dtype=np.float64)
    padlen = 3 * (2 * len(sos) + 1)
    if values.shape[0] <= padlen:
        raise ParameterError(f"a vibration of {values.shape[0]} samples is too short to band-limit "
                             f"(needs more than {padlen})")
    return signal.sosfiltfilt(sos, values, axis=0)


def vibration_features(v: np.ndarray, fs: float) -> dict[str, float]:
    """MiRO, MiCo (paper eqs. 13-15), std, Pearson kurtosis and mean power (docs/features.md#other) of a slide signal
    ``v`` (band-limited, windowed, axes combined).

    Parameters
    ----------
    v : np.ndarray
        The slide signal, (n,).
    fs : float
        Its sampling rate in Hz.

    Returns
    -------
    dict of str to float
        The values of :data:`VIBRATION_NAMES`, in that order.

    Examples
    --------
    A 100 Hz sine of amplitude 2: standard deviation ``2 / sqrt(2)``, kurtosis 1.5, power ``2^2 / 2``, and
    MiCo (the spectral centroid) at its frequency:

    >>> import numpy as np
    >>> v = 2.0 * np.sin(2 * np.pi * 100.0 * np.arange(3000) / 3000.0)
    >>> values = vibration_features(v, 3000.0)
    >>> {name: round(value, 4) for name, value in values.items()}  # doctest: +NORMALIZE_WHITESPACE
    {'tactum.vibration.miro': 0.0001, 'tactum.vibration.mico': 100.0, 'other.vibration.vib_std': 1.4142,
     'other.vibration.vib_kurtosis': 1.5, 'other.vibration.vib_energy': 2.0}
    """
    return dict(zip(VIBRATION_NAMES, (tactum.miro(v), tactum.mico(v, fs), other.vib_std(v),
                                      other.vib_kurtosis(v), other.vib_energy(v)), strict=True))


def friction_features(xyz: np.ndarray, fs: float) -> dict[str, float]:
    """FST and FRS (paper eqs. 16, 17) of a 3-axis force: normal force z, tangential ``|(x, y)|`` after
    taring x and y by their mean over the first 0.1 s; the stiction window is 10 ms at any rate.

    Parameters
    ----------
    xyz : np.ndarray
        The force, (n, 3): x and y tangential, z normal.
    fs : float
        Its sampling rate in Hz.

    Returns
    -------
    dict of str to float
        The values of :data:`FRICTION_NAMES`: ``tactum.force_xyz.fst`` and ``tactum.force_xyz.frs``.

    Examples
    --------
    A load that grows after 0.2 s with a tangential force of ``|(0.3, 0.4)| = 0.5`` times the normal force
    throughout: a friction coefficient of 0.5, in static and in sliding friction alike:

    >>> import numpy as np
    >>> t = np.arange(400) / 200.0
    >>> fz = np.clip((t - 0.2) * 10, 0, 3)  # no load in the first 0.1 s, so the tare is 0
    >>> values = friction_features(np.column_stack([0.3 * fz, 0.4 * fz, fz]), 200.0)
    >>> {name: round(value, 6) for name, value in values.items()}
    {'tactum.force_xyz.fst': 0.5, 'tactum.force_xyz.frs': 0.5}
    """
    values = np.asarray(xyz, dtype=np.float64)
    tare = values[:max(1, int(round(TARE_S * fs))), :2].mean(axis=0)
    f_frt = np.hypot(*(values[:, :2] - tare).T)
    f_frn = values[:, 2]
    lag = max(1, int(round(FRICTION_WINDOW_S * fs)))
    return dict(zip(FRICTION_NAMES, (tactum.fst(f_frn, f_frt, lag), tactum.frs(f_frn, f_frt, lag)), strict=True))


SIGNAL_STATS = ("mean", "std", "rms", "skewness", "kurtosis", "p05", "p95")
SIGNAL_BANDS = 7
SIGNAL_SHAPE = ("centroid", "spread", "flatness", "rolloff", "peak")
SIGNAL_NAMES = (*SIGNAL_STATS, *(f"band{k}" for k in range(SIGNAL_BANDS)), *SIGNAL_SHAPE)
"""The features of one column of a generic channel (:func:`signal_features`)."""

SIGNAL_MIN_SAMPLES = 16
"""Fewest samples of a window the generic features are computed on."""

WELCH_SEGMENT = 256
"""Samples per segment of the Welch spectrum of a generic channel (fewer in a shorter window)."""

ROLLOFF = 0.85
"""The spectral roll-off is the frequency below which this share of the power lies."""


def signal_bands(fs: float) -> np.ndarray:
    """Edges (Hz) of the rate-aware band plan of a generic channel: ``0`` and ``fs / 2^k`` for k = 7 .. 1,
    seven bands of an octave each but the lowest: a 100 Hz IMU gets 0-0.78-1.56-3.1-6.25-12.5-25-50 Hz,
    a 3 kHz accelerometer 0-23-47-94-188-375-750-1500 Hz.

    Parameters
    ----------
    fs : float
        The channel's sampling rate in Hz.

    Returns
    -------
    np.ndarray, shape (8,)
        The band edges in Hz, increasing, from 0 to the Nyquist frequency ``fs / 2``.

    Examples
    --------
    >>> signal_bands(100.0).tolist()
    [0.0, 0.78125, 1.5625, 3.125, 6.25, 12.5, 25.0, 50.0]
    """
    return np.concatenate(([0.0], fs / 2.0 ** np.arange(SIGNAL_BANDS, 0, -1)))


def _window_of(x: np.ndarray, fewest: int, family: str) -> np.ndarray:
    """``x`` as float64; a :class:`ParameterError` if it has fewer than ``fewest`` samples."""
    x = np.asarray(x, dtype=np.float64)
    if x.size < fewest:
        raise ParameterError(f"a window of {x.size} samples is too short for the {family} features "
                             f"(needs {fewest})")
    return x


def signal_features(x: np.ndarray, fs: float) -> list[float]:
    """The features of one column of a generic channel (docs/features.md#generic-signals), in
    :data:`SIGNAL_NAMES` order.

    Statistics of the samples: mean, standard deviation, RMS, skewness, Pearson kurtosis (3 for a normal
    distribution), 5th and 95th percentiles. Band energies: the share of the power (Welch spectrum of the
    signal minus its mean, Hann segments of :data:`WELCH_SEGMENT` samples, half overlapping) in each band of
    :func:`signal_bands`, so they sum to 1 and describe the spectrum's shape while the standard deviation
    carries its level. Spectral shape (Peeters 2004, "A large set of audio features for sound description"):
    centroid and spread (Hz), flatness (geometric over arithmetic mean of the power, 1 for white noise),
    the 85 % roll-off (Hz) and the frequency of the largest power (Hz). A constant signal has no spectrum:
    its band energies and shape are NaN.

    Parameters
    ----------
    x : np.ndarray
        The window of one column, (n,), at least :data:`SIGNAL_MIN_SAMPLES` samples.
    fs : float
        Its sampling rate in Hz.

    Returns
    -------
    list of float
        The 19 values of :data:`SIGNAL_NAMES`, in that order.

    Raises
    ------
    ParameterError
        If the window has fewer than :data:`SIGNAL_MIN_SAMPLES` samples.

    Examples
    --------
    A unit sine of 187.5 Hz at 1 kHz, exactly on a line of the 256-sample Welch spectrum (spaced 1000 / 256 Hz):
    standard deviation and RMS ``1 / sqrt(2)``, kurtosis 1.5, all its power in the band 125-250 Hz, centroid
    and peak at the tone; a constant has no spectrum:

    >>> import numpy as np
    >>> tone = np.sin(2 * np.pi * 187.5 * np.arange(1000) / 1000.0)
    >>> values = dict(zip(SIGNAL_NAMES, signal_features(tone, 1000.0)))
    >>> [round(values[name], 4) for name in ("std", "rms", "kurtosis", "band5", "centroid", "peak")]
    [0.7071, 0.7071, 1.5, 1.0, 187.5, 187.5]
    >>> values = dict(zip(SIGNAL_NAMES, signal_features(np.full(32, 2.0), 1000.0)))
    >>> values["mean"], values["std"], values["band0"], values["centroid"]
    (2.0, 0.0, nan, nan)
    """
    x = _window_of(x, SIGNAL_MIN_SAMPLES, "generic")
    mean, std = float(x.mean()), float(x.std())
    centred = x - mean
    moments = [math.nan, math.nan] if std == 0 else [float(np.mean(centred ** 3) / std ** 3),
                                                     float(np.mean(centred ** 4) / std ** 4)]
    stats = [mean, std, float(np.sqrt(np.mean(x ** 2))), *moments, *np.percentile(x, [5, 95]).tolist()]
    frequencies, power = signal.welch(centred, fs, window="hann", nperseg=min(WELCH_SEGMENT, x.size))
    total = float(power.sum())
    if not total > 0:
        return stats + [math.nan] * (SIGNAL_BANDS + len(SIGNAL_SHAPE))
    share = power / total
    edges = signal_bands(fs)
    band = np.clip(np.searchsorted(edges, frequencies, side="right") - 1, 0, SIGNAL_BANDS - 1)
    bands = np.bincount(band, weights=share, minlength=SIGNAL_BANDS).tolist()
    centroid = float(np.sum(frequencies * share))
    spread = float(np.sqrt(np.sum((frequencies - centroid) ** 2 * share)))
    positive = power[power > 0]
    flatness = float(np.exp(np.mean(np.log(positive))) / np.mean(power)) if positive.size == power.size else 0.0
    rolloff = float(frequencies[min(int(np.searchsorted(np.cumsum(share), ROLLOFF)), frequencies.size - 1)])
    return stats + bands + [centroid, spread, flatness, rolloff, float(frequencies[int(np.argmax(power))])]


SLOW_NAMES = ("mean", "std", "p05", "p95", "slope", "change")
"""The features of one column of a slow generic channel (:func:`slow_features`)."""

SLOW_MIN_SAMPLES = 4
"""Fewest samples of a window the slow features are computed on."""

RATIO_BOUND = 3.0
"""The log10 ratio of two channels' levels is bounded to +-3 (where one of them is 0, a robot standing still)."""


def slow_features(x: np.ndarray, fs: float) -> list[float]:
    """The features of one column of a slow generic channel, in :data:`SLOW_NAMES` order: its level (mean),
    spread (standard deviation), 5th and 95th percentiles, slope (least-squares line over the window, units
    per second) and rate of change (mean absolute difference of neighbouring samples times fs, units per
    second: how much it moves within the window, which a slope misses when it goes up and down).

    Parameters
    ----------
    x : np.ndarray
        The window of one column, (n,), at least :data:`SLOW_MIN_SAMPLES` samples.
    fs : float
        Its sampling rate in Hz.

    Returns
    -------
    list of float
        The 6 values of :data:`SLOW_NAMES`, in that order.

    Raises
    ------
    ParameterError
        If the window has fewer than :data:`SLOW_MIN_SAMPLES` samples.

    Examples
    --------
    A line rising 2 units per second from 1 to 3, sampled at 10 Hz, has slope and rate of change 2; a
    triangle that goes up and down again has no slope but the same rate of change:

    >>> import numpy as np
    >>> ramp = 1.0 + 2.0 * np.arange(11) / 10.0
    >>> dict(zip(SLOW_NAMES, np.round(slow_features(ramp, 10.0), 6).tolist()))
    {'mean': 2.0, 'std': 0.632456, 'p05': 1.1, 'p95': 2.9, 'slope': 2.0, 'change': 2.0}
    >>> triangle = np.concatenate([ramp, ramp[-2::-1]])
    >>> slope, change = slow_features(triangle, 10.0)[4:]
    >>> bool(abs(slope) < 1e-9), round(change, 6)
    (True, 2.0)
    """
    x = _window_of(x, SLOW_MIN_SAMPLES, "slow")
    t = np.arange(x.size) / fs
    centred_t = t - t.mean()
    slope = float(np.dot(centred_t, x - x.mean()) / np.dot(centred_t, centred_t))
    return [float(x.mean()), float(x.std()), *np.percentile(x, [5, 95]).tolist(), slope,
            float(np.mean(np.abs(np.diff(x))) * fs)]


def log_ratio(a: np.ndarray, b: np.ndarray) -> float:
    """``log10(mean|a| / mean|b|)`` of two windows (motor current per wheel speed: the power a terrain
    takes per unit of speed), bounded to +-:data:`RATIO_BOUND`: each level is floored at 10^-3 of the
    larger one, so a window where one is 0 gives the bound, and one where both are 0 gives 0.

    Parameters
    ----------
    a, b : np.ndarray
        The two windows (any shape; their mean absolute values are compared).

    Returns
    -------
    float
        The log10 ratio of the levels, in [-:data:`RATIO_BOUND`, :data:`RATIO_BOUND`].

    Examples
    --------
    >>> import numpy as np
    >>> log_ratio(np.array([2.0, -2.0]), np.array([0.2, 0.2])), log_ratio(np.ones(3), np.zeros(3))
    (1.0, 3.0)
    >>> log_ratio(np.zeros(3), np.ones(3)), log_ratio(np.zeros(3), np.zeros(3))
    (-3.0, 0.0)
    """
    level_a, level_b = float(np.mean(np.abs(a))), float(np.mean(np.abs(b)))
    floor = 10.0 ** -RATIO_BOUND * max(level_a, level_b)
    if floor == 0:
        return 0.0
    return float(np.log10(max(level_a, floor) / max(level_b, floor)))
