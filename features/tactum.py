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

    Examples
    --------
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
    """
    va = _samples(va, "va")
    threshold = np.std(va) + np.mean(va) + movmean(va)
    return float(np.log10(1.0 + np.mean(va * (va > threshold))))


def fv(f_frt: np.ndarray) -> float:
    """Friction variation, paper eq. 5: ``std(f_frt - MA100(f_frt))`` over the whole friction slide (N)."""
    f_frt = _samples(f_frt, "f_frt")
    return float(np.std(f_frt - movmean(f_frt)))


def rv(r_window: np.ndarray) -> float:
    """Reflectance variation, paper eq. 6: ``std(r_w - MA100(r_w))`` over the 1 s slide window of r_ts (V)."""
    r_window = _samples(r_window, "r_window")
    return float(np.std(r_window - movmean(r_window)))


def matx(v: np.ndarray, f_frt: np.ndarray, r_window: np.ndarray) -> float:
    """Macrotexture, paper eq. 7: ``3 VS + 2 FV + 4 RV`` (weights from the paper's optimisation)."""
    w_vs, w_fv, w_rv = MATX_WEIGHTS
    return w_vs * vs(np.abs(_samples(v, "v"))) + w_fv * fv(f_frt) + w_rv * rv(r_window)


# --- 2. MaCo -------------------------------------------------------------------------------------------

def _photo_scales(photo: PreparedPhoto) -> np.ndarray:
    """``corner_scales(gray, harris_corners(gray))`` of a prepared photo, Harris on its float32 gray image."""
    return corner_scales(photo.gray, harris_corners(photo.gray32))


def top_scales_mean(scales: np.ndarray, n: int = TOP_SCALES) -> float:
    """Mean of the ``n`` largest scales (of all if fewer); NaN if there are none (paper eq. 8)."""
    values = np.sort(np.asarray(scales, dtype=np.float64))[::-1]
    return math.nan if values.size == 0 else float(np.mean(values[:n]))


def maco(v: np.ndarray, gray: np.ndarray, *, contrast: float | None = None) -> float:
    """Macrotexture coarseness, paper eq. 8: ``mean(va) * C(I_disp) * mean(top-10 corner scales)``.

    ``C`` is the Tamura contrast of the gray photo (docs/features.md#image); pass it as ``contrast`` when it is already
    known. The photo is the cropped ``I_disp`` (docs/features.md#preprocessing: image features use the cropped photo).
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

    Examples
    --------
    >>> t = np.arange(3000) / 3000.0
    >>> round(spectral_centroid(np.sin(2 * np.pi * 250.0 * t), 3000.0), 6)
    250.0
    """
    values = _samples(x, "x")
    magnitude = np.abs(np.fft.rfft(values))
    bins = np.arange(magnitude.size) / values.size
    return _ratio(fs * float(bins @ magnitude), float(magnitude.sum()))


def mico(v: np.ndarray, fs: float = 3000.0) -> float:
    """Microtexture coarseness, paper eq. 15: the spectral centroid of ``v`` in Hz (fs = 3000 Hz)."""
    return spectral_centroid(v, fs)


# --- 6, 7. FST, FRS ------------------------------------------------------------------------------------

def slope(f: np.ndarray, lag: int = SLOPE_LAG) -> np.ndarray:
    """Force change over a 10 ms window: ``slope[i] = f[i + lag] - f[i]`` (paper section IV-A3)."""
    values = _samples(f, "f")
    return values[lag:] - values[:-lag]


def fst(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Tactile stiction, paper eq. 16: ``max slope(f_frt) / max slope(f_frn)``.

    NaN if a trace is not longer than the 30-sample slope window or the normal slope maximum is 0.
    ``lag`` is the 10 ms window in samples (30 at the scanner's 3 kHz).
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
    """
    start = int(np.argmax(slope(f_frt, lag))) + lag
    above = np.flatnonzero(f_frn > FORCE_RISE * np.max(f_frn))
    return start, int(above[-1]) if above.size else -1


def frs(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Sliding resistance, paper eq. 17: ``mean(f_frt[s..e]) / mean(f_frn[s..e])`` (e inclusive).

    ``f_frt`` after :func:`scanner.preprocess.remove_friction_offset`; ``s, e`` from
    :func:`sliding_segment`. NaN if the segment is empty or the normal force averages 0 over it.
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
    """An operator's judgement on the five-step scale {0, 0.25, 0.5, 0.75, 1}; NaN means not judged."""
    number = float(value)
    if math.isnan(number) or number in JUDGED_SCALE:
        return number
    raise ParameterError(f"{name} = {value!r} is not on the five-step scale 0, 0.25, 0.5, 0.75, 1")


def atk(value: float) -> float:
    """Adhesive tack, paper eq. 18: the operator's value in {0, 0.25, 0.5, 0.75, 1}."""
    return judged(value, "tactum.atk")


def cyd(value: float) -> float:
    """Yielding, paper eq. 24: the operator's value in {0, 0.25, 0.5, 0.75, 1}."""
    return judged(value, "tactum.cyd")


# --- 9-12. Compliance ----------------------------------------------------------------------------------

def is_rigid(alpha_f: np.ndarray | None, skipped: bool) -> bool | None:
    """Whether a sample counts as rigid for the compliance features (Strese et al. 2020, section IV-A4, eqs. 19-20;
    docs/features.md#ccp).

    With a stored flex angle: ``std(alpha_f) < 1 deg`` (the skip flag is then ignored). Without one:
    rigid if the fold step was skipped as rigid (``meta.rigid``), else unknown (None).
    """
    if alpha_f is not None:
        return bool(np.std(_samples(alpha_f, "alpha_f")) < RIGID_STD_DEG)
    return True if skipped else None


def ccp(f_press: np.ndarray, rigid: bool) -> float:
    """Tactile compliance, paper eq. 19-20: 0 if rigid, else ``max(f_press) / 4.0 mm`` (N/mm)."""
    return 0.0 if rigid else float(np.max(_samples(f_press, "f_press"))) / INDENTATION_MM


def cdf(alpha_f: np.ndarray) -> float:
    """Local deformation, paper eq. 21: ``std(alpha_f)`` in degrees (0 for a fold skipped as rigid)."""
    return float(np.std(_samples(alpha_f, "alpha_f")))


def cdp(f_fold: np.ndarray, alpha_f: np.ndarray, rigid: bool, fs: float = 3000.0) -> float:
    """Damping, paper eq. 22: ``(f[n_max] - f[n_min]) / ((alpha[n_max] - alpha[n_min]) / dt)``.

    0 if rigid. The damping phase runs from the start of the force rise (``n_min``, the first sample of
    ``f_fold`` above 5 % of its peak) to the force maximum (``n_max``, first on ties), ``dt = (n_max -
    n_min) / fs``. NaN if the phase is empty (dt = 0) or the angle does not change over it.
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
    """Relaxation, paper eq. 23: 0 if rigid, else ``max(f_press) - f_press[-1]`` (N)."""
    if rigid:
        return 0.0
    f_press = _samples(f_press, "f_press")
    return float(np.max(f_press) - f_press[-1])


# --- 14, 15. TCO, TPR ----------------------------------------------------------------------------------

def tco(t_cool: np.ndarray, t_amb: float) -> float:
    """Thermal cooling, paper eq. 28-29: ``max(t_cool) - t_amb`` (K)."""
    return float(np.max(_samples(t_cool, "t_cool")) - t_amb)


def tpr(t_cool: np.ndarray, t_amb: float, fs: float = 20.0) -> float:
    """Thermal persistence, paper eq. 30: ``sqrt((t_max,5s - t_amb)^2 + (t_cool[-1] - t_amb)^2)``.

    ``t_max,5s = max(t_cool[first 5 s])`` (Strese et al. 2020, eq. 30; docs/features.md#tpr).

    ``t_cool`` sampled at ``fs`` (20 Hz) with t = 0 at its first sample; the first 5 s are t < 5 s.
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
    disp : PreparedPhoto, optional
        ``PreparedPhoto(scan.images["I_disp"])`` when the caller shares it with the image features; the
        values are the same.
    prepared : PreparedScan, optional
        The scan prepared once for every feature family (:func:`features.extract`); the values are the same.

    Raises
    ------
    ValueError
        If ``meta.atk`` or ``meta.cyd`` is neither NaN nor on the five-step scale, or ``disp`` was not
        prepared from this scan's ``I_disp``.
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
