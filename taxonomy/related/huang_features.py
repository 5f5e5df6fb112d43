"""``huang7`` (Huang and Wu 2021): the mean FFT magnitude in seven 20 Hz bands from 0 to 140 Hz, the features of
:mod:`taxonomy.related.huang` (docs/features.md#related)."""

from __future__ import annotations

import math

import numpy as np

from scanner.scan import Recording
from taxonomy.related.inputs import _check_roles, _signal, _trace, one_axis

HUANG_BAND_HZ = 20.0
HUANG_BANDS = 7


def band_means(x: np.ndarray, fs: float, width: float = HUANG_BAND_HZ,
               bands: int = HUANG_BANDS) -> np.ndarray:
    """Mean FFT magnitude per frequency band, Huang and Wu section 2.2 (rectangular window).

    With ``x`` minus its mean, ``|rfft(x)| / len(x)`` at the bin frequencies ``k fs / N``; band b is the
    mean over the bins in ``[width b, width (b + 1))`` Hz, b = 0..bands-1 (NaN for a band without bins).
    A sine of amplitude A on a bin adds A / 2 to that bin.

    Parameters
    ----------
    x : array of shape (n,)
        A vibration of at least 2 samples.
    fs : float
        Sample rate in Hz.
    width : float
        Band width in Hz.
    bands : int
        Number of bands, from 0 Hz up.

    Returns
    -------
    ndarray of shape (bands,)
        Mean magnitude per band, in the unit of ``x``.

    Examples
    --------
    A 30 Hz tone of amplitude 2, 1 s at 200 Hz: the bins are 1 Hz apart, the tone's bin holds 2 / 2 = 1
    and band 1 (20-40 Hz) averages it over its 20 bins; no bin reaches 120 Hz (Nyquist is 100 Hz):

    >>> import numpy as np
    >>> from taxonomy.related.huang_features import band_means
    >>> t = np.arange(200) / 200.0
    >>> np.round(band_means(2.0 * np.sin(2 * np.pi * 30.0 * t), 200.0), 6).tolist()
    [0.0, 0.05, 0.0, 0.0, 0.0, 0.0, nan]
    """
    values = _signal(x, "vibration", 2)
    magnitude = np.abs(np.fft.rfft(values - values.mean())) / values.size
    frequency = np.arange(magnitude.size) * fs / values.size
    band = np.floor(frequency / width)
    return np.array([float(np.mean(magnitude[band == b])) if np.any(band == b) else math.nan
                     for b in range(bands)])


def huang7(recording: Recording) -> dict[str, float]:
    """Mean FFT magnitude of the vibration in the bands 0-20, ..., 120-140 Hz (Huang and Wu 2021).

    Parameters
    ----------
    recording : Recording
        A recording with the role ``vibration`` (several axes are combined by :func:`one_axis`).

    Returns
    -------
    dict of str to float
        ``huang7.band_000_020`` to ``huang7.band_120_140``: :func:`band_means` of the vibration.

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``vibration``.

    Examples
    --------
    A 30 Hz tone of amplitude 2, 1 s at 1000 Hz: its bin holds 1, averaged over the 20 bins of 20-40 Hz:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.huang_features import huang7
    >>> t = np.arange(1000) / 1000.0
    >>> recording = Recording("r1", {"acc": Trace(2.0 * np.sin(2 * np.pi * 30.0 * t), 1000.0, "g")},
    ...                       {"vibration": "acc"})
    >>> {name: round(value, 6) for name, value in huang7(recording).items()}
    {'huang7.band_000_020': 0.0, 'huang7.band_020_040': 0.05, 'huang7.band_040_060': 0.0,
     'huang7.band_060_080': 0.0, 'huang7.band_080_100': 0.0, 'huang7.band_100_120': 0.0,
     'huang7.band_120_140': 0.0}
    """
    _check_roles(recording, "huang7", ("vibration",))
    trace = _trace(recording, "vibration")
    means = band_means(one_axis(trace.data), trace.fs)
    return {f"huang7.band_{int(HUANG_BAND_HZ * b):03d}_{int(HUANG_BAND_HZ * (b + 1)):03d}": float(means[b])
            for b in range(HUANG_BANDS)}
