"""The 15 TacTUM features (Strese et al. 2020, section IV-A; docs/features.md#tactum).

Each feature is a pure function of arrays, named as in the paper; :func:`compute` gathers the inputs of one
:class:`scanner.Scan` (preprocessed as in docs/features.md#preprocessing) and returns the 15 values in :data:`NAMES`
order. A value that is undefined (0/0, x/0, a missing channel, a stored slide that fails its quality check) is
NaN, never 0 or inf, except where docs/features.md#tactum says 0 (the compliance features of a rigid sample).

Notation: ``v`` is the tool-slide signal (``v_ts`` band-limited, 1 s window, DFT321), ``va = |v|``,
``mean`` and ``std`` are population statistics, ``MA100`` is MATLAB's ``movmean(x, 100)``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from features.corners import corner_scales, harris_corners
from features.image import PreparedPhoto, RealSpectrum, tamura_contrast
from features.prepared import PreparedScan
from scanner.lazy import library
from scanner.preprocess import (
    QualityError,
    remove_friction_offset,
)
from scanner.scan import JUDGED_SCALE, Scan
from taxonomy.errors import ParameterError

pywt = library("pywt")

NAMES = (
    "tactum.matx", "tactum.maco", "tactum.marg", "tactum.miro", "tactum.mico",
    "tactum.fst", "tactum.frs", "tactum.atk", "tactum.ccp", "tactum.cdf",
    "tactum.cdp", "tactum.crx", "tactum.cyd", "tactum.tco", "tactum.tpr",
)
"""The TacTUM feature names, in feature-space order (docs/features.md#tactum)."""

MATX_WEIGHTS = (3.0, 2.0, 4.0)
"""Weights of VS, FV and RV in MaTX (paper eq. 7, from the paper's feature optimisation)."""

MOVING_MEAN = 100
"""Window of the moving mean in MaTX (paper eq. 2, 5, 6)."""

TOP_SCALES = 10
"""Number of largest corner scales averaged in MaCo (paper eq. 8, n = 10)."""

PEAK_FRACTION = 0.75
"""Spectrum peaks kept in MaRG: at least this fraction of the maximum (paper eq. 10, a = 0.75)."""

GAUSS_SIGMA = 25.0
"""Standard deviation, in frequency bins, of the inverted Gaussian in MaRG (paper eq. 11)."""

GAUSS_HALF = 100
"""The inverted Gaussian covers offsets -100..99 around the spectrum centre (a 200 x 200 window)."""

WAVELET = "db8"
"""Wavelet of MiRO (paper section IV-A2)."""

SLOPE_LAG = 30
"""Samples between the two ends of a force slope: 10 ms at 3000 Hz (paper section IV-A3)."""

FORCE_RISE = 0.05
"""A force "has risen" above this fraction of its maximum (FRS segment end, CDP damping start)."""

INDENTATION_MM = 4.0
"""Indentation fixed by the TU2 casing when pressing (paper eq. 19, Delta x)."""

RIGID_STD_DEG = 1.0
"""A sample is rigid if the flex angle while folding varies by less than this (paper section IV-A4)."""

PEAK_SECONDS = 5.0
"""TPR looks for the heating peak in the first 5 s of ``t_cool`` (docs/features.md#tactum, item 15)."""


class MissingDataWarning(UserWarning):
    """A scan lacks an input (or a stored slide fails its check), so the features needing it are NaN."""


def _ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator``, NaN where that is 0/0 or x/0."""
    return math.nan if denominator == 0 else float(numerator / denominator)


def _samples(x: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(x, dtype=np.float64)
    if array.ndim != 1 or array.size == 0:
        raise ParameterError(f"{name} must be a non-empty 1-D array, got shape {array.shape}")
    return array


# --- 1. MaTX -------------------------------------------------------------------------------------------

def movmean(x: np.ndarray, window: int = MOVING_MEAN) -> np.ndarray:
    """Centred moving mean that shrinks at the ends, MATLAB ``movmean(x, window)``.

    Sample i averages ``x[i - window//2 .. i + window - window//2 - 1]`` clipped to the signal, so for the
    even window 100 of the paper (``MA100``, eq. 2) that is samples [i-50, i+49].

    Parameters
    ----------
    x : array of shape (n,)
        The signal.
    window : int
        Samples averaged where the window fits in the signal (default :data:`MOVING_MEAN`, 100).

    Returns
    -------
    ndarray of shape (n,)
        The moving mean; near the ends it averages the fewer samples there are.

    Raises
    ------
    ParameterError
        If ``x`` is not a non-empty 1-D array or ``window`` is below 1.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import movmean
    >>> movmean(np.array([1.0, 2.0, 3.0, 4.0]), 2)
    array([1. , 1.5, 2.5, 3.5])
    """
    values = _samples(x, "x")
    if window < 1:
        raise ParameterError(f"moving-mean window must be at least 1 sample, got {window}")
    before = window // 2
    after = window - before - 1
    n = values.size
    # Full convolution index j sums x[j - window + 1 .. j]; the window of sample i ends at i + after.
    sums = np.convolve(values, np.ones(window))[after:after + n]
    index = np.arange(n)
    counts = np.minimum(index + after, n - 1) - np.maximum(index - before, 0) + 1
    return sums / counts


def vs(va: np.ndarray) -> float:
    """Vibrotactile spikiness, paper eq. 2-4: ``log10(1 + mean(va_D))``.

    ``va_th = std(va) + mean(va) + MA100(va)`` (eq. 2), ``va_D = va * (va > va_th)`` (eq. 3).
    Interpretation (docs/features.md#tactum): the bar over ``va_D`` in eq. 4 that did not survive is a mean.

    Parameters
    ----------
    va : array of shape (n,)
        Absolute slide vibration ``|v|`` in g.

    Returns
    -------
    float
        VS; 0 when no sample rises above the threshold (a constant signal).

    Examples
    --------
    A single spike of 9 g in 1000 silent samples is kept whole, so VS is ``log10(1 + 9 / 1000)``:

    >>> import numpy as np
    >>> from features.tactum import vs
    >>> va = np.zeros(1000)
    >>> va[500] = 9.0
    >>> round(vs(va), 6), round(float(np.log10(1.009)), 6)
    (0.003891, 0.003891)
    >>> vs(np.full(1000, 0.3))
    0.0
    """
    va = _samples(va, "va")
    threshold = np.std(va) + np.mean(va) + movmean(va)
    return float(np.log10(1.0 + np.mean(va * (va > threshold))))


def fv(f_frt: np.ndarray) -> float:
    """Friction variation, paper eq. 5: ``std(f_frt - MA100(f_frt))`` over the whole friction slide (N).

    Parameters
    ----------
    f_frt : array of shape (n,)
        Tangential force of the friction slide in N, without its friction offset.

    Returns
    -------
    float
        FV in N: the spread of the force about its 100-sample moving mean.

    Examples
    --------
    A constant force does not vary; a force alternating by +-1 N about 2 N varies by 1 N (up to the ends,
    where the moving mean shrinks):

    >>> import numpy as np
    >>> from features.tactum import fv
    >>> fv(np.full(1000, 2.0))
    0.0
    >>> alternating = np.where(np.arange(1000) % 2 == 0, 3.0, 1.0)
    >>> round(fv(alternating), 4)
    1.0
    """
    f_frt = _samples(f_frt, "f_frt")
    return float(np.std(f_frt - movmean(f_frt)))


def rv(r_window: np.ndarray) -> float:
    """Reflectance variation, paper eq. 6: ``std(r_w - MA100(r_w))`` over the 1 s slide window of r_ts (V).

    Parameters
    ----------
    r_window : array of shape (n,)
        IR reflectance ``r_ts`` in the 1 s slide window, in V.

    Returns
    -------
    float
        RV in V: the spread of the reflectance about its 100-sample moving mean.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import rv
    >>> rv(np.full(3000, 1.5))
    0.0
    >>> round(rv(1.5 + 0.01 * np.where(np.arange(3000) % 2 == 0, 1.0, -1.0)), 4)
    0.01
    """
    r_window = _samples(r_window, "r_window")
    return float(np.std(r_window - movmean(r_window)))


def matx(v: np.ndarray, f_frt: np.ndarray, r_window: np.ndarray) -> float:
    """Macrotexture, paper eq. 7: ``3 VS + 2 FV + 4 RV`` (weights from the paper's optimisation).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g (signed; VS takes its absolute value).
    f_frt : array of shape (m,)
        Tangential force of the friction slide in N, without its friction offset.
    r_window : array of shape (k,)
        IR reflectance in the 1 s slide window, in V.

    Returns
    -------
    float
        MaTX, :data:`MATX_WEIGHTS` applied to :func:`vs`, :func:`fv` and :func:`rv`.

    Examples
    --------
    A silent slide and a constant friction force leave only the reflectance term: 4 RV, with RV the 0.01 V
    of a reflectance alternating by +-0.01 V:

    >>> import numpy as np
    >>> from features.tactum import matx, rv
    >>> r_window = 1.5 + 0.01 * np.where(np.arange(3000) % 2 == 0, 1.0, -1.0)
    >>> round(matx(np.zeros(3000), np.full(3000, 2.0), r_window), 4)
    0.04
    >>> matx(np.zeros(3000), np.full(3000, 2.0), r_window) == 4 * rv(r_window)
    True
    """
    w_vs, w_fv, w_rv = MATX_WEIGHTS
    return w_vs * vs(np.abs(_samples(v, "v"))) + w_fv * fv(f_frt) + w_rv * rv(r_window)


# --- 2. MaCo -------------------------------------------------------------------------------------------

def _photo_scales(photo: PreparedPhoto) -> np.ndarray:
    """``corner_scales(gray, harris_corners(gray))`` of a prepared photo, Harris on its float32 gray image."""
    return corner_scales(photo.gray, harris_corners(photo.gray32))


def top_scales_mean(scales: np.ndarray, n: int = TOP_SCALES) -> float:
    """Mean of the ``n`` largest scales (of all if fewer); NaN if there are none (paper eq. 8).

    Parameters
    ----------
    scales : array of shape (k,)
        Corner scales (:func:`features.corners.corner_scales`).
    n : int
        Number of largest scales averaged (default :data:`TOP_SCALES`, 10).

    Returns
    -------
    float
        The mean of the largest ``min(n, k)`` scales, NaN if ``k`` is 0.

    Examples
    --------
    The ten largest of 1..20 are 11..20, whose mean is 15.5:

    >>> import numpy as np
    >>> from features.tactum import top_scales_mean
    >>> top_scales_mean(np.arange(1.0, 21.0))
    15.5
    >>> top_scales_mean(np.array([2.0, 4.0]))
    3.0
    >>> top_scales_mean(np.array([]))
    nan
    """
    values = np.sort(np.asarray(scales, dtype=np.float64))[::-1]
    return math.nan if values.size == 0 else float(np.mean(values[:n]))


def maco(v: np.ndarray, gray: np.ndarray, *, contrast: float | None = None) -> float:
    """Macrotexture coarseness, paper eq. 8: ``mean(va) * C(I_disp) * mean(top-10 corner scales)``.

    ``C`` is the Tamura contrast of the gray photo (docs/features.md#image); pass it as ``contrast`` when it is already
    known. The photo is the cropped ``I_disp`` (docs/features.md#preprocessing: image features use the cropped photo).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.
    gray : array of shape (h, w)
        Gray image of the cropped ``I_disp``.
    contrast : float, optional
        Tamura contrast of ``gray`` (default: computed, :func:`features.image.tamura_contrast`).

    Returns
    -------
    float
        MaCo; NaN if the photo has no corners.

    See Also
    --------
    features.corners.harris_corners, features.corners.corner_scales, top_scales_mean

    Examples
    --------
    The four corners of a bright square all get the scale ``1.2 * 2^(11/4)`` = 8.0726 px, so with
    ``mean(va) = 0.5`` and a contrast of 2 MaCo is that scale:

    >>> import numpy as np
    >>> from features.tactum import maco
    >>> gray = np.zeros((64, 64))
    >>> gray[16:48, 16:48] = 200.0
    >>> round(maco(np.full(3000, 0.5), gray, contrast=2.0), 6), round(1.2 * 2 ** (11 / 4), 6)
    (8.072606, 8.072606)
    """
    if contrast is None:
        contrast = tamura_contrast(gray)
    return _maco(v, contrast, corner_scales(gray, harris_corners(gray)))


def _maco(v: np.ndarray, contrast: float, scales: np.ndarray) -> float:
    return float(np.mean(np.abs(_samples(v, "v")))) * contrast * top_scales_mean(scales)


# --- 3. MaRG -------------------------------------------------------------------------------------------

def kept_peak_mean(gray: np.ndarray) -> float:
    """Mean of the filtered spectrum over its kept peaks, paper eq. 9-11 (docs/features.md#tactum, item 3).

    ``X = Re(fft2(I - mean(I))) / sqrt(M N)`` centred at (M//2, N//2); the kept peaks are the elements with
    ``X >= 0.75 max(X)``; each is weighted by ``G' = 1 - G``, G a Gaussian of sigma 25 bins normalised to
    peak 1 on the offsets -100..99 around the centre, and ``G' = 1`` outside that window.
    Interpretations (docs/features.md#marg): the mean is removed, else the DC term is the only peak; the average runs
    over the kept peaks, else the zeros of the removed elements drown them.

    The spectrum is the half spectrum of :class:`features.image.RealSpectrum`, shared with the image
    features' ``dft_80`` and ``dft_85``.

    Parameters
    ----------
    gray : array of shape (M, N)
        Gray image (the cropped ``I_disp``).

    Returns
    -------
    float
        The mean of ``X (1 - G)`` over the kept peaks.

    Raises
    ------
    ParameterError
        If ``gray`` is not a non-empty 2-D image.

    Examples
    --------
    A cosine grating of amplitude 50 with 8 periods across a 64 x 64 image has its two peaks
    ``X = 50 * 64 / 2 = 1600`` at 8 bins from the centre, where ``G = exp(-8^2 / (2 * 25^2))``:

    >>> import math
    >>> import numpy as np
    >>> from features.tactum import kept_peak_mean
    >>> gray = np.tile(100.0 + 50.0 * np.cos(2 * np.pi * 8 * np.arange(64) / 64), (64, 1))
    >>> round(kept_peak_mean(gray), 6), round(1600 * (1 - math.exp(-8**2 / (2 * 25.0**2))), 6)
    (79.858186, 79.858186)
    """
    image = np.asarray(gray, dtype=np.float64)
    if image.ndim != 2 or image.size == 0:
        raise ParameterError(f"gray must be a non-empty 2-D image, got shape {image.shape}")
    return _kept_peak_mean(RealSpectrum(image - image.mean(), overwrite=True))


def _kept_peak_mean(spectrum: RealSpectrum) -> float:
    """:func:`kept_peak_mean` from the unscaled spectrum of the centred image; ``X`` is it over sqrt(M N)."""
    m, n = spectrum.shape
    threshold = PEAK_FRACTION * spectrum.peak
    total, count = spectrum.peak_sum(PEAK_FRACTION)
    dy, dx, gauss = _centre_gaussian(m, n)
    window = spectrum.at(dy, dx)
    # X * G' = X - X * G, and G' = 1 outside the window.
    total -= np.sum(np.where(window >= threshold, window * gauss, 0.0))
    return float(total / count / math.sqrt(m * n))


@lru_cache(maxsize=8)
def _centre_gaussian(m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The offsets -100..99 around the centre of an m x n spectrum that lie in it, and the Gaussian ``G``
    of MaRG (eq. 11) on them (made once per photo size; read-only)."""
    dy = np.arange(max(-GAUSS_HALF, -(m // 2)), min(GAUSS_HALF, m - m // 2))
    dx = np.arange(max(-GAUSS_HALF, -(n // 2)), min(GAUSS_HALF, n - n // 2))
    gauss = np.exp(-(dy[:, None] ** 2 + dx[None, :] ** 2) / (2.0 * GAUSS_SIGMA**2))
    for array in (dy, dx, gauss):
        array.flags.writeable = False
    return dy, dx, gauss


def marg(v: np.ndarray, gray: np.ndarray, *, contrast: float | None = None) -> float:
    """Macrotexture regularity, paper eq. 12: ``mean(va) * (mean(X_filt over kept peaks) - C(I_disp))``.

    See :func:`kept_peak_mean` for ``X_filt``; ``C`` is the Tamura contrast (pass it if known).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.
    gray : array of shape (M, N)
        Gray image of the cropped ``I_disp``.
    contrast : float, optional
        Tamura contrast of ``gray`` (default: computed, :func:`features.image.tamura_contrast`).

    Returns
    -------
    float
        MaRG.

    Examples
    --------
    The grating of :func:`kept_peak_mean` (kept-peak mean 79.858186), ``mean(va) = 0.5`` and a contrast
    of 1:

    >>> import numpy as np
    >>> from features.tactum import marg
    >>> gray = np.tile(100.0 + 50.0 * np.cos(2 * np.pi * 8 * np.arange(64) / 64), (64, 1))
    >>> round(marg(np.full(3000, 0.5), gray, contrast=1.0), 6), round(0.5 * (79.858186 - 1.0), 6)
    (39.429093, 39.429093)
    """
    if contrast is None:
        contrast = tamura_contrast(gray)
    return _marg(v, kept_peak_mean(gray), contrast)


def _marg(v: np.ndarray, peak_mean: float, contrast: float) -> float:
    return float(np.mean(np.abs(_samples(v, "v")))) * (peak_mean - contrast)


# --- 4, 5. MiRO, MiCO ------------------------------------------------------------------------------------

def wavelet_detail(v: np.ndarray, level: int, wavelet: str = WAVELET, levels: int = 5) -> np.ndarray:
    """The level-``level`` detail of ``v`` reconstructed to full length (MATLAB ``wrcoef("d", ...)``).

    ``pywt.wavedec(v, wavelet, level=levels, mode="symmetric")``, every coefficient array but that level's
    zeroed, ``pywt.waverec``, the first ``len(v)`` samples: the ``levels`` details plus the approximation
    sum to ``v``. Signed; MiRO takes its absolute value.

    Parameters
    ----------
    v : array of shape (n,)
        The signal.
    level : int
        Detail level, 1 (the highest band, ``fs/4 .. fs/2``) to ``levels``.
    wavelet : str
        PyWavelets wavelet name (default :data:`WAVELET`, ``"db8"``).
    levels : int
        Depth of the decomposition.

    Returns
    -------
    ndarray of shape (n,)
        The detail at the samples of ``v``.

    Raises
    ------
    ParameterError
        If ``v`` is not a non-empty 1-D array or ``level`` is not in 1..``levels``.

    Examples
    --------
    A signal alternating at half the sample rate lies wholly in the level-1 band: away from the ends, its
    level-1 detail is the signal and its level-3 detail is zero.

    >>> import numpy as np
    >>> from features.tactum import wavelet_detail
    >>> v = np.where(np.arange(1024) % 2 == 0, 1.0, -1.0)
    >>> np.round(wavelet_detail(v, 1)[500:504], 6).tolist()
    [1.0, -1.0, 1.0, -1.0]
    >>> bool(np.abs(wavelet_detail(v, 3)[100:-100]).max() < 1e-9)
    True
    """
    values = _samples(v, "v")
    if not 1 <= level <= levels:
        raise ParameterError(f"detail level must be in 1..{levels}, got {level}")
    return _detail_of(pywt.wavedec(values, wavelet, level=levels, mode="symmetric"), level, wavelet, values.size)


def _detail_of(coefficients: list[np.ndarray], level: int, wavelet: str, size: int) -> np.ndarray:
    """The level-``level`` detail reconstructed from a ``pywt.wavedec`` decomposition (see :func:`wavelet_detail`)."""
    only = [np.zeros_like(c) for c in coefficients]
    only[-level] = coefficients[-level]
    return pywt.waverec(only, wavelet, mode="symmetric")[:size]


def miro(v: np.ndarray) -> float:
    """Microtexture roughness, paper eq. 13-14: ``log10(1 + mean(|d|))``, ``d = D1 - (mean D1 / mean D5) D5``.

    ``Dk = |level-k detail of v|`` (db8, :func:`wavelet_detail`); ``d = D1`` if ``mean(D5) = 0``.
    Interpretation of eq. 13-14 (docs/features.md#tactum): the bars are means, so d removes from D1 the share of D5
    scaled to D1's level; MiRO grows with the signal's amplitude and does not change when D5 alone is scaled.

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.

    Returns
    -------
    float
        MiRO, 0 for a silent slide.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import miro
    >>> miro(np.zeros(3000))
    0.0
    >>> tone = np.sin(2 * np.pi * 1200.0 * np.arange(3000) / 3000.0)
    >>> round(miro(tone), 6), round(miro(2 * tone), 6)
    (0.313453, 0.493607)
    """
    values = _samples(v, "v")
    coefficients = pywt.wavedec(values, WAVELET, level=5, mode="symmetric")  # one decomposition for both
    d1 = np.abs(_detail_of(coefficients, 1, WAVELET, values.size))
    d5 = np.abs(_detail_of(coefficients, 5, WAVELET, values.size))
    mean_d5 = np.mean(d5)
    d = d1 if mean_d5 == 0 else d1 - (np.mean(d1) / mean_d5) * d5
    return float(np.log10(1.0 + np.mean(np.abs(d))))


def spectral_centroid(x: np.ndarray, fs: float) -> float:
    """Spectral centroid in Hz, paper eq. 15: ``fs * sum(f_i |X_i|) / sum(|X_i|)``.

    Over the ``rfft`` bins i = 0..N//2 with ``f_i = i / N`` (no window), so a pure tone on a bin returns its
    frequency. NaN for an all-zero signal.

    Parameters
    ----------
    x : array of shape (n,)
        The signal.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    float
        The centroid in Hz, NaN for an all-zero signal.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import spectral_centroid
    >>> t = np.arange(3000) / 3000.0
    >>> round(spectral_centroid(np.sin(2 * np.pi * 250.0 * t), 3000.0), 6)
    250.0
    >>> spectral_centroid(np.zeros(100), 3000.0)
    nan
    """
    values = _samples(x, "x")
    magnitude = np.abs(np.fft.rfft(values))
    bins = np.arange(magnitude.size) / values.size
    return _ratio(fs * float(bins @ magnitude), float(magnitude.sum()))


def mico(v: np.ndarray, fs: float = 3000.0) -> float:
    """Microtexture coarseness, paper eq. 15: the spectral centroid of ``v`` in Hz (fs = 3000 Hz).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    float
        MiCO in Hz, NaN for a silent slide.

    See Also
    --------
    spectral_centroid

    Examples
    --------
    A pure 250 Hz tone over one second:

    >>> import numpy as np
    >>> from features.tactum import mico
    >>> round(mico(np.sin(2 * np.pi * 250.0 * np.arange(3000) / 3000.0)), 6)
    250.0
    """
    return spectral_centroid(v, fs)


# --- 6, 7. FST, FRS ------------------------------------------------------------------------------------

def slope(f: np.ndarray, lag: int = SLOPE_LAG) -> np.ndarray:
    """Force change over a 10 ms window: ``slope[i] = f[i + lag] - f[i]`` (paper section IV-A3).

    Parameters
    ----------
    f : array of shape (n,)
        A force in N.
    lag : int
        Samples between the two ends of a slope (default :data:`SLOPE_LAG`, 30: 10 ms at 3 kHz).

    Returns
    -------
    ndarray of shape (n - lag,)
        The slopes in N.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import slope
    >>> slope(np.array([0.0, 1.0, 4.0, 9.0, 16.0]), lag=2)
    array([ 4.,  8., 12.])
    """
    values = _samples(f, "f")
    return values[lag:] - values[:-lag]


def fst(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Tactile stiction, paper eq. 16: ``max slope(f_frt) / max slope(f_frn)``.

    NaN if a trace is not longer than the 30-sample slope window or the normal slope maximum is 0.
    ``lag`` is the 10 ms window in samples (30 at the scanner's 3 kHz).

    Parameters
    ----------
    f_frn : array of shape (n,)
        Normal force of the friction slide in N.
    f_frt : array of shape (m,)
        Tangential force of the friction slide in N.
    lag : int
        Samples of the slope window.

    Returns
    -------
    float
        FST, NaN where undefined.

    Examples
    --------
    A tangential force rising at half the rate of the normal force:

    >>> import numpy as np
    >>> from features.tactum import fst
    >>> t = np.arange(100.0)
    >>> fst(2.0 * t, t)
    0.5
    >>> fst(t[:30], t[:30])
    nan
    """
    f_frn, f_frt = _samples(f_frn, "f_frn"), _samples(f_frt, "f_frt")
    if min(f_frn.size, f_frt.size) <= lag:
        return math.nan
    return _ratio(float(slope(f_frt, lag).max()), float(slope(f_frn, lag).max()))


def sliding_segment(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> tuple[int, int]:
    """First and last (inclusive) sample of the sliding phase (Strese et al. 2020, section IV-A3, eq. 17;
    docs/features.md#frs).

    Start: the first index of the largest friction slope plus 30 (the end of the stiction window).
    End: the last sample where ``f_frn`` exceeds 5 % of its maximum.

    Parameters
    ----------
    f_frn : array of shape (n,)
        Normal force of the friction slide in N.
    f_frt : array of shape (m,)
        Tangential force of the friction slide in N, longer than ``lag`` samples.
    lag : int
        Samples of the slope window.

    Returns
    -------
    (int, int)
        Start and end sample; the end is -1 if ``f_frn`` never exceeds 5 % of its maximum.

    Raises
    ------
    ParameterError
        If a force is not a non-empty 1-D array, or ``f_frt`` has no more than ``lag`` samples.

    Examples
    --------
    The friction force steps up at sample 50, so its largest 30-sample slope first starts at sample 20 and
    the sliding phase at 20 + 30; the normal force is released after sample 89:

    >>> import numpy as np
    >>> from features.tactum import sliding_segment
    >>> f_frt = np.r_[np.zeros(50), np.ones(50)]
    >>> f_frn = np.r_[np.full(90, 2.0), np.zeros(10)]
    >>> sliding_segment(f_frn, f_frt)
    (50, 89)
    """
    f_frn, f_frt = _samples(f_frn, "f_frn"), _samples(f_frt, "f_frt")
    if f_frt.size <= lag:
        raise ParameterError(f"the sliding phase needs more than {lag} samples of f_frt, got {f_frt.size}")
    start = int(np.argmax(slope(f_frt, lag))) + lag
    above = np.flatnonzero(f_frn > FORCE_RISE * np.max(f_frn))
    return start, int(above[-1]) if above.size else -1


def frs(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Sliding resistance, paper eq. 17: ``mean(f_frt[s..e]) / mean(f_frn[s..e])`` (e inclusive).

    ``f_frt`` after :func:`scanner.preprocess.remove_friction_offset`; ``s, e`` from
    :func:`sliding_segment`. NaN if the segment is empty or the normal force averages 0 over it.

    Parameters
    ----------
    f_frn : array of shape (n,)
        Normal force of the friction slide in N.
    f_frt : array of shape (m,)
        Tangential force of the friction slide in N, without its friction offset.
    lag : int
        Samples of the slope window.

    Returns
    -------
    float
        FRS, NaN where undefined (also if a trace is not longer than ``lag``).

    Examples
    --------
    1 N of friction under 2 N of normal force over the sliding phase of :func:`sliding_segment`'s example:

    >>> import numpy as np
    >>> from features.tactum import frs
    >>> frs(np.r_[np.full(90, 2.0), np.zeros(10)], np.r_[np.zeros(50), np.ones(50)])
    0.5
    """
    f_frn, f_frt = _samples(f_frn, "f_frn"), _samples(f_frt, "f_frt")
    if min(f_frn.size, f_frt.size) <= lag:
        return math.nan
    start, end = sliding_segment(f_frn, f_frt, lag)
    if end < start:
        return math.nan
    segment = slice(start, end + 1)
    return _ratio(float(np.mean(f_frt[segment])), float(np.mean(f_frn[segment])))


# --- 8, 13. ATK, CYD -----------------------------------------------------------------------------------

def judged(value: float, name: str) -> float:
    """An operator's judgement on the five-step scale {0, 0.25, 0.5, 0.75, 1}; NaN means not judged.

    Parameters
    ----------
    value : float
        The judged value, or NaN.
    name : str
        Feature name for the error message.

    Returns
    -------
    float
        ``value`` as a float.

    Raises
    ------
    ParameterError
        If ``value`` is neither NaN nor on the scale.

    Examples
    --------
    >>> from features.tactum import judged
    >>> judged(0.75, "tactum.atk")
    0.75
    >>> judged(0.3, "tactum.atk")
    Traceback (most recent call last):
    ...
    taxonomy.errors.ParameterError: tactum.atk = 0.3 is not on the five-step scale 0, 0.25, 0.5, 0.75, 1
    """
    number = float(value)
    if math.isnan(number) or number in JUDGED_SCALE:
        return number
    raise ParameterError(f"{name} = {value!r} is not on the five-step scale 0, 0.25, 0.5, 0.75, 1")


def atk(value: float) -> float:
    """Adhesive tack, paper eq. 18: the operator's value in {0, 0.25, 0.5, 0.75, 1}.

    Parameters
    ----------
    value : float
        ``meta.atk``, NaN if not judged.

    Returns
    -------
    float
        ATK, NaN if not judged.

    Raises
    ------
    ParameterError
        If ``value`` is neither NaN nor on the five-step scale.

    Examples
    --------
    >>> from features.tactum import atk
    >>> atk(0.5), atk(float("nan"))
    (0.5, nan)
    """
    return judged(value, "tactum.atk")


def cyd(value: float) -> float:
    """Yielding, paper eq. 24: the operator's value in {0, 0.25, 0.5, 0.75, 1}.

    Parameters
    ----------
    value : float
        ``meta.cyd``, NaN if not judged.

    Returns
    -------
    float
        CYD, NaN if not judged.

    Raises
    ------
    ParameterError
        If ``value`` is neither NaN nor on the five-step scale.

    Examples
    --------
    >>> from features.tactum import cyd
    >>> cyd(1), cyd(0.25)
    (1.0, 0.25)
    """
    return judged(value, "tactum.cyd")


# --- 9-12. Compliance ----------------------------------------------------------------------------------

def is_rigid(alpha_f: np.ndarray | None, skipped: bool) -> bool | None:
    """Whether a sample counts as rigid for the compliance features (Strese et al. 2020, section IV-A4, eqs. 19-20;
    docs/features.md#ccp).

    With a stored flex angle: ``std(alpha_f) < 1 deg`` (the skip flag is then ignored). Without one:
    rigid if the fold step was skipped as rigid (``meta.rigid``), else unknown (None).

    Parameters
    ----------
    alpha_f : array of shape (n,) or None
        Flex angle while folding in degrees, None if not stored.
    skipped : bool
        The fold step was skipped because the sample is rigid (``meta.rigid``).

    Returns
    -------
    bool or None
        True if rigid, False if not, None if unknown.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import is_rigid
    >>> is_rigid(np.full(100, 30.0), False), is_rigid(np.linspace(0.0, 40.0, 100), True)
    (True, False)
    >>> is_rigid(None, True), is_rigid(None, False)
    (True, None)
    """
    if alpha_f is not None:
        return bool(np.std(_samples(alpha_f, "alpha_f")) < RIGID_STD_DEG)
    return True if skipped else None


def ccp(f_press: np.ndarray, rigid: bool) -> float:
    """Tactile compliance, paper eq. 19-20: 0 if rigid, else ``max(f_press) / 4.0 mm`` (N/mm).

    Parameters
    ----------
    f_press : array of shape (n,)
        Normal force while pressing in N (not read if ``rigid``).
    rigid : bool
        The sample is rigid (:func:`is_rigid`).

    Returns
    -------
    float
        CCP in N/mm.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import ccp
    >>> press = np.array([0.0, 2.0, 6.0, 5.0])
    >>> ccp(press, False), ccp(press, True)
    (1.5, 0.0)
    """
    return 0.0 if rigid else float(np.max(_samples(f_press, "f_press"))) / INDENTATION_MM


def cdf(alpha_f: np.ndarray) -> float:
    """Local deformation, paper eq. 21: ``std(alpha_f)`` in degrees (0 for a fold skipped as rigid).

    Parameters
    ----------
    alpha_f : array of shape (n,)
        Flex angle while folding in degrees.

    Returns
    -------
    float
        CDF in degrees (population standard deviation).

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import cdf
    >>> cdf(np.array([10.0, 12.0]))
    1.0
    """
    return float(np.std(_samples(alpha_f, "alpha_f")))


def cdp(f_fold: np.ndarray, alpha_f: np.ndarray, rigid: bool, fs: float = 3000.0) -> float:
    """Damping, paper eq. 22: ``(f[n_max] - f[n_min]) / ((alpha[n_max] - alpha[n_min]) / dt)``.

    0 if rigid. The damping phase runs from the start of the force rise (``n_min``, the first sample of
    ``f_fold`` above 5 % of its peak) to the force maximum (``n_max``, first on ties), ``dt = (n_max -
    n_min) / fs``. NaN if the phase is empty (dt = 0) or the angle does not change over it.

    Parameters
    ----------
    f_fold : array of shape (n,)
        Normal force while folding in N.
    alpha_f : array of shape (n,)
        Flex angle while folding in degrees, at the same samples.
    rigid : bool
        The sample is rigid (:func:`is_rigid`).
    fs : float
        Sample rate in Hz.

    Returns
    -------
    float
        CDP in N s/deg, NaN where undefined.

    Raises
    ------
    ParameterError
        If ``f_fold`` and ``alpha_f`` differ in length.

    Examples
    --------
    The force rises from 1 N (sample 2) to 3 N (sample 4) while the angle turns 2 degrees in those 2 s
    (``fs = 1``): 2 N at 1 deg/s.

    >>> import numpy as np
    >>> from features.tactum import cdp
    >>> f_fold = np.array([0.0, 0.0, 1.0, 2.0, 3.0, 2.0])
    >>> alpha_f = np.array([0.0, 0.0, 0.0, 1.0, 2.0, 2.0])
    >>> cdp(f_fold, alpha_f, False, fs=1.0), cdp(f_fold, alpha_f, True)
    (2.0, 0.0)
    """
    if rigid:
        return 0.0
    f_fold, alpha_f = _samples(f_fold, "f_fold"), _samples(alpha_f, "alpha_f")
    if f_fold.size != alpha_f.size:
        raise ParameterError(f"f_fold ({f_fold.size}) and alpha_f ({alpha_f.size}) must have the same length")
    n_max = int(np.argmax(f_fold))
    rise = np.flatnonzero(f_fold > FORCE_RISE * f_fold[n_max])
    if rise.size == 0 or rise[0] >= n_max:
        return math.nan
    n_min = int(rise[0])
    dt = (n_max - n_min) / fs
    angular_speed = _ratio(alpha_f[n_max] - alpha_f[n_min], dt)
    return _ratio(float(f_fold[n_max] - f_fold[n_min]), angular_speed)


def crx(f_press: np.ndarray, rigid: bool) -> float:
    """Relaxation, paper eq. 23: 0 if rigid, else ``max(f_press) - f_press[-1]`` (N).

    Parameters
    ----------
    f_press : array of shape (n,)
        Normal force while pressing in N (not read if ``rigid``).
    rigid : bool
        The sample is rigid (:func:`is_rigid`).

    Returns
    -------
    float
        CRX in N.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import crx
    >>> crx(np.array([0.0, 4.0, 3.5]), False)
    0.5
    """
    if rigid:
        return 0.0
    f_press = _samples(f_press, "f_press")
    return float(np.max(f_press) - f_press[-1])


# --- 14, 15. TCO, TPR ----------------------------------------------------------------------------------

def tco(t_cool: np.ndarray, t_amb: float) -> float:
    """Thermal cooling, paper eq. 28-29: ``max(t_cool) - t_amb`` (K).

    Parameters
    ----------
    t_cool : array of shape (n,)
        Object temperature after heating in degC.
    t_amb : float
        Ambient temperature in degC.

    Returns
    -------
    float
        TCO in K.

    Examples
    --------
    >>> import numpy as np
    >>> from features.tactum import tco
    >>> tco(np.array([24.0, 31.5, 30.0]), 22.0)
    9.5
    """
    return float(np.max(_samples(t_cool, "t_cool")) - t_amb)


def tpr(t_cool: np.ndarray, t_amb: float, fs: float = 20.0) -> float:
    """Thermal persistence, paper eq. 30: ``sqrt((t_max,5s - t_amb)^2 + (t_cool[-1] - t_amb)^2)``.

    ``t_max,5s = max(t_cool[first 5 s])`` (Strese et al. 2020, eq. 30; docs/features.md#tpr).

    ``t_cool`` sampled at ``fs`` (20 Hz) with t = 0 at its first sample; the first 5 s are t < 5 s.

    Parameters
    ----------
    t_cool : array of shape (n,)
        Object temperature after heating in degC.
    t_amb : float
        Ambient temperature in degC.
    fs : float
        Sample rate of ``t_cool`` in Hz.

    Returns
    -------
    float
        TPR in K.

    Examples
    --------
    3 K above ambient for the first 5 s (100 samples) and 4 K at the end: the 3-4-5 triangle.

    >>> import numpy as np
    >>> from features.tactum import tpr
    >>> tpr(np.r_[np.full(100, 24.0), np.full(100, 25.0)], 21.0)
    5.0
    """
    t_cool = _samples(t_cool, "t_cool")
    early = t_cool[:max(1, int(round(PEAK_SECONDS * fs)))]
    return float(math.hypot(float(np.max(early)) - t_amb, float(t_cool[-1]) - t_amb))


# --- the scan ------------------------------------------------------------------------------------------

@dataclass
class _Inputs:
    """The preprocessed inputs of one scan; ``problems`` says why an absent input is absent."""

    values: dict[str, object] = field(default_factory=dict)
    problems: dict[str, str] = field(default_factory=dict)

    def put(self, key: str, value: object | None, problem: str = "") -> None:
        self.values[key] = value
        if value is None:
            self.problems[key] = problem

    def get(self, key: str) -> object | None:
        return self.values.get(key)


def _slide_inputs(prepared: PreparedScan, inputs: _Inputs) -> None:
    """``v`` and the IR window ``r_w`` of the tool slide; a failed slide check leaves both absent."""
    v_ts, r_ts = prepared.scan.get("v_ts"), prepared.scan.get("r_ts")
    if v_ts is None:
        inputs.put("v", None, "v_ts is missing")
        inputs.put("r_w", None, "v_ts is missing")
        return
    try:
        window = prepared.slide_window("v_ts")
    except QualityError as problem:
        inputs.put("v", None, f"v_ts: {problem}")
        inputs.put("r_w", None, f"v_ts: {problem}")
        return
    inputs.put("v", prepared.slide_signal("v_ts"))
    if r_ts is None:
        inputs.put("r_w", None, "r_ts is missing")
    elif r_ts.n < window.ir.stop:
        inputs.put("r_w", None, f"r_ts: window shorter than 1 s ({r_ts.n} samples, window ends at "
                                f"{window.ir.stop})")
    else:
        inputs.put("r_w", r_ts.data[window.ir])


def _photo_inputs(scan: Scan, inputs: _Inputs, disp: PreparedPhoto | None) -> None:
    """The prepared ``I_disp``: its cropped gray image, Tamura contrast and spectrum serve MaCo and MaRG."""
    image = scan.images.get("I_disp")
    if image is None:
        inputs.put("photo", None, "I_disp is missing")
        return
    try:
        inputs.put("photo", PreparedPhoto(image) if disp is None else disp)
    except ValueError as problem:
        inputs.put("photo", None, f"I_disp: {problem}")


def _gather(prepared: PreparedScan, disp: PreparedPhoto | None) -> _Inputs:
    scan = prepared.scan
    inputs = _Inputs()
    _slide_inputs(prepared, inputs)
    _photo_inputs(scan, inputs, disp)
    for name in ("f_frn", "f_press", "f_fold", "alpha_f", "t_cool"):
        trace = scan.get(name)
        inputs.put(name, None if trace is None else trace.data, f"{name} is missing")
    f_frt = scan.get("f_frt")
    inputs.put("f_frt", None if f_frt is None else remove_friction_offset(f_frt.data, f_frt.fs),
               "f_frt is missing")
    t_amb = scan.meta.t_amb
    inputs.put("t_amb", None if math.isnan(t_amb) else t_amb, "meta.t_amb (ambient temperature) is unknown")
    return inputs


def _compliance(inputs: _Inputs, skipped: bool) -> dict[str, tuple[Callable[..., float], tuple[str, ...]]]:
    """CCP, CDF, CDP, CRX as (function, input keys), after the rigidity decision of Strese et al. 2020, eqs. 19-20;
    docs/features.md#ccp."""
    rigid = is_rigid(inputs.get("alpha_f"), skipped)
    zero = (lambda: 0.0, ())
    if rigid and inputs.get("alpha_f") is None:
        return {"tactum.ccp": zero, "tactum.cdf": zero, "tactum.cdp": zero, "tactum.crx": zero}
    if rigid:
        return {"tactum.ccp": zero, "tactum.cdf": (cdf, ("alpha_f",)), "tactum.cdp": zero, "tactum.crx": zero}
    # Not rigid, or unknown because alpha_f is missing without the skip flag: then all four need alpha_f.
    unknown = ("alpha_f",) if rigid is None else ()
    return {"tactum.ccp": (lambda f, *_: ccp(f, False), ("f_press", *unknown)),
            "tactum.cdf": (cdf, ("alpha_f",)),
            "tactum.cdp": (lambda f, a: cdp(f, a, False), ("f_fold", "alpha_f")),
            "tactum.crx": (lambda f, *_: crx(f, False), ("f_press", *unknown))}


def _recipes(inputs: _Inputs, scan: Scan) -> dict[str, tuple[Callable[..., float], tuple[str, ...]]]:
    """Every feature as (function, input keys), in :data:`NAMES` order."""
    atk_value, cyd_value = atk(scan.meta.atk), cyd(scan.meta.cyd)
    recipes = {
        "tactum.matx": (matx, ("v", "f_frt", "r_w")),
        "tactum.maco": (lambda v, photo: _maco(v, photo.contrast, _photo_scales(photo)), ("v", "photo")),
        "tactum.marg": (lambda v, photo: _marg(v, _kept_peak_mean(photo.spectrum), photo.contrast),
                        ("v", "photo")),
        "tactum.miro": (miro, ("v",)),
        "tactum.mico": (mico, ("v",)),
        "tactum.fst": (fst, ("f_frn", "f_frt")),
        "tactum.frs": (frs, ("f_frn", "f_frt")),
        "tactum.atk": (lambda: atk_value, ()),
        "tactum.cyd": (lambda: cyd_value, ()),
        "tactum.tco": (tco, ("t_cool", "t_amb")),
        "tactum.tpr": (tpr, ("t_cool", "t_amb")),
    }
    recipes.update(_compliance(inputs, scan.meta.rigid))
    return {name: recipes[name] for name in NAMES}


def compute(scan: Scan, *, disp: PreparedPhoto | None = None, prepared: PreparedScan | None = None) -> dict[str, float]:
    """The 15 TacTUM features of a scan, in :data:`NAMES` order (docs/features.md#tactum).

    Inputs are preprocessed as in docs/features.md#preprocessing: ``v`` from ``v_ts`` (band limit, slide window,
    DFT321), the IR window of ``r_ts`` at the same samples, ``f_frt`` without its friction offset, the cropped gray
    ``I_disp``. A feature whose input is absent is NaN, and one :class:`MissingDataWarning` per absent
    channel (or failed slide check) names it and the features it made NaN.

    Parameters
    ----------
    scan : Scan
        The scan.
    disp : PreparedPhoto, optional
        ``PreparedPhoto(scan.images["I_disp"])`` when the caller shares it with the image features; the
        values are the same.
    prepared : PreparedScan, optional
        The scan prepared once for every feature family (:func:`features.extract`); the values are the same.

    Returns
    -------
    dict of str to float
        The 15 features of :data:`NAMES`, NaN where a value is undefined.

    Raises
    ------
    ValueError
        If ``meta.atk`` or ``meta.cyd`` is neither NaN nor on the five-step scale, or ``disp`` was not
        prepared from this scan's ``I_disp``.

    Warns
    -----
    MissingDataWarning
        Naming the absent channel and the features it made NaN.

    Examples
    --------
    A scan of a rigid sample (fold skipped) holding only its cooling curve: the judged values, the compliance
    zeros of a rigid sample and the thermal features (3 K, then 4 K above 21 degC) are defined, the seven
    features of the slides and the photo are NaN.

    >>> import math
    >>> import warnings
    >>> import numpy as np
    >>> from features import tactum
    >>> from scanner.scan import Scan, ScanMeta, Trace
    >>> meta = ScanMeta(label="C3S4M2P2X1", operator="op", sample_id="epoxy-01", scan_index=1, session_id="s-1",
    ...                 started="2026-11-21T09:00:00+00:00", t_amb=21.0, atk=0.25, cyd=0.75, rigid=True)
    >>> t_cool = Trace(np.r_[np.full(100, 24.0), np.full(100, 25.0)], 20.0, "degC")
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     values = tactum.compute(Scan(meta, {"t_cool": t_cool}))
    >>> values["tactum.atk"], values["tactum.ccp"], values["tactum.tco"], values["tactum.tpr"]
    (0.25, 0.0, 4.0, 5.0)
    >>> sum(math.isnan(value) for value in values.values()), len(caught)
    (7, 4)
    >>> print(caught[0].message)
    scan epoxy-01-001: v_ts is missing; tactum.matx, tactum.maco, tactum.marg, tactum.miro, tactum.mico set to NaN
    """
    if disp is not None and disp.source is not scan.images.get("I_disp"):
        raise ParameterError("disp was not prepared from this scan's I_disp photo")
    inputs = _gather(prepared if prepared is not None else PreparedScan(scan), disp)
    values: dict[str, float] = {}
    blocked: dict[str, list[str]] = {}
    for name, (function, keys) in _recipes(inputs, scan).items():
        absent = [key for key in keys if inputs.get(key) is None]
        for key in absent:
            blocked.setdefault(inputs.problems[key], []).append(name)
        values[name] = math.nan if absent else float(function(*(inputs.get(key) for key in keys)))
    for problem, names in blocked.items():
        warnings.warn(f"scan {scan.scan_id}: {problem}; {', '.join(dict.fromkeys(names))} set to NaN",
                      MissingDataWarning, stacklevel=2)
    return values
