"""Feature sets of the related work (docs/features.md#related), one per seed method, on scans or generic recordings.

Every set reads its inputs by channel **role** (docs/database.md: ``vibration``, ``pressure_dc``, ``temperature``,
``heat_flow``, ``electrodes`` (n, k), ``taxels`` (n, h, w), ``force_xyz`` (n, 3), ``audio``), so the same
code runs on a BioTac recording, a pressure-array slide, a soft 3-axis sensor or a scan converted by
:func:`scan_recording`. A recording without a role a set needs raises :class:`RelatedFeatureError`, whose
one-line message names the set, the roles it needs and the ones missing.

Each set is a function ``recording -> dict[name, float]`` listed in :data:`FEATURE_SETS`; names are
``<set>.<feature>``. The array-level pieces (band means, covariance norm, wavelet L1 norms, threshold
crossings, ...) are public so they can be checked on signals with known answers.

- ``fishel3`` (Strese et al. 2020, Fig. 18, after Fishel and Loeb): traction, roughness, fineness; on scans.
- ``xie11`` (Xie et al. 2019): 11 features of the area, variance and sum sequences of a pressure
  array; the sequences are standardised per column across the training samples (:class:`XieFeatures`).
- ``huang7`` (Huang and Wu 2021): mean FFT magnitude in seven 20 Hz bands from 0 to 140 Hz.
- ``chathuranga4`` (Chathuranga et al. 2015): Frobenius norm of the 3x3 covariance and the three
  means of a 3-axis signal; with its baselines ``chathuranga_period`` (spatial period V / f_p) and
  ``chathuranga_net`` (friction coefficient, x variance, x kurtosis).
- Hoelscher et al. 2015 (BioTac evaluation): ``xu3``, ``chu``, ``mean23``, ``dallaire``, ``chitta``, ``temperature``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from types import MappingProxyType

import numpy as np
import pywt
from scipy import ndimage, optimize, signal
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.preprocessing import StandardScaler
from sklearn.utils.validation import check_is_fitted, validate_data

from features.tactum import frs, mico
from scanner.preprocess import QualityError, band_limit, dft321, remove_friction_offset, slide_signal
from scanner.scan import Recording, Scan, Trace
from taxonomy.errors import TexplorerError


class RelatedFeatureError(TexplorerError, ValueError):
    """Input a related-work feature set cannot use; the message names the set and what is wrong."""


# -- inputs ------------------------------------------------------------------------------------------

def _check_roles(recording: Recording, set_name: str, roles: Sequence[str]) -> None:
    missing = [role for role in roles if role not in recording.roles]
    if missing:
        raise RelatedFeatureError(f"{set_name} needs the role(s) {', '.join(roles)}; "
                                  f"recording {recording.name!r} lacks {', '.join(missing)}")


def _trace(recording: Recording, role: str) -> Trace:
    trace = recording.role(role)
    assert trace is not None  # _check_roles ran first
    return trace


def _signal(x: np.ndarray, name: str, min_samples: int = 1) -> np.ndarray:
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 1 or values.size < min_samples:
        raise RelatedFeatureError(f"{name} must be a 1-D signal of at least {min_samples} samples, "
                                  f"got shape {values.shape}")
    return values


def one_axis(x: np.ndarray) -> np.ndarray:
    """A vibration as one signal: 1-D as it is, several axes combined by DFT321 (docs/features.md#preprocessing)."""
    values = np.asarray(x, dtype=np.float64)
    return values if values.ndim == 1 else dft321(values)


def _ratio(numerator: float, denominator: float) -> float:
    return math.nan if denominator == 0 else float(numerator / denominator)


def _log(value: float) -> float:
    """Natural logarithm, NaN (not -inf or an error) for a value that is not positive."""
    return math.log(value) if value > 0 else math.nan


# -- fishel3 (Strese et al. 2020, Fig. 18) -----------------------------------------------------------

FISHEL_CHANNELS = ("v_ts", "f_frn", "f_frt")


def fishel3(scan: Scan) -> dict[str, float]:
    """Traction, roughness and fineness of a scan, as the paper adapts Fishel and Loeb's features (Fig. 18).

    ``traction = tactum.frs`` (sliding resistance, eq. 17), ``roughness = log10(mean(v^2))`` of the slide
    signal ``v`` (``v_ts`` band-passed 10-1000 Hz, 1 s window, DFT321; docs/features.md#preprocessing) and ``fineness =
    tactum.mico`` (its spectral centroid, eq. 15). A stored slide whose check fails gives NaN roughness
    and fineness, as for the TacTUM features.

    Raises
    ------
    RelatedFeatureError
        If the scan lacks ``v_ts``, ``f_frn`` or ``f_frt``.
    """
    missing = [name for name in FISHEL_CHANNELS if scan.get(name) is None]
    if missing:
        raise RelatedFeatureError(f"fishel3 needs the scan channels {', '.join(FISHEL_CHANNELS)}; scan "
                                  f"{scan.scan_id} lacks {', '.join(missing)}")
    f_frn, f_frt = scan["f_frn"], scan["f_frt"]
    traction = frs(f_frn.data, remove_friction_offset(f_frt.data, f_frt.fs))
    try:
        v = slide_signal(scan["v_ts"])
    except QualityError:
        return {"fishel3.traction": traction, "fishel3.roughness": math.nan, "fishel3.fineness": math.nan}
    energy = float(np.mean(v**2))
    return {"fishel3.traction": traction,
            "fishel3.roughness": math.log10(energy) if energy > 0 else math.nan,
            "fishel3.fineness": mico(v, scan["v_ts"].fs)}


# -- xie11 (Xie et al. 2019) -------------------------------------------------------------------------

XIE_SECONDS = 1.0
"""Xie et al. classify a 1 s slide: 100 tactile images at 100 Hz (section 3.3)."""

XIE_WAVELET = "db3"
XIE_LEVEL = 4
XIE_NAMES = ("mean_sa", "mean_sv", "mean_ss", "l1_ca4", "l1_cd4", "l1_cd3", "l1_cd2", "l1_cd1",
             "abs_energy", "cid", "std_ss")
"""The 11 features of Xie et al., Table 3, in docs/features.md#related order."""


def xie_sequences(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The area, variance and force-sum sequences S_a, S_v, S_s of tactile images (Xie et al., 3.3).

    Parameters
    ----------
    frames : array of shape (n, h, w) or (n, k)
        n tactile images (taxel intensities), or n rows of k electrodes treated as a 1-D array.

    Returns
    -------
    S_a, S_v, S_s : arrays of shape (n,)
        Number of taxels > 0, population variance over the taxels, sum of the taxels, per image.
    """
    values = np.asarray(frames, dtype=np.float64)
    if values.ndim not in (2, 3) or values.shape[0] == 0 or values[0].size == 0:
        raise RelatedFeatureError("xie11 needs images (n, h, w) or electrode rows (n, k), "
                                  f"got shape {values.shape}")
    flat = values.reshape(values.shape[0], -1)
    return (np.count_nonzero(flat > 0, axis=1).astype(np.float64), np.var(flat, axis=1), np.sum(flat, axis=1))


def wavelet_l1(x: np.ndarray, wavelet: str = XIE_WAVELET, level: int = XIE_LEVEL) -> np.ndarray:
    """L1 norms of cA4, cD4, cD3, cD2, cD1 of ``pywt.wavedec(x, "db3", level=4, mode="symmetric")``."""
    values = _signal(x, "S_s", 2)
    return np.array([float(np.sum(np.abs(c))) for c in pywt.wavedec(values, wavelet, level=level,
                                                                      mode="symmetric")])


def cid(x: np.ndarray) -> float:
    """Complexity-invariant distance of a sequence, Xie et al. eq. (2): ``sqrt(sum(diff(x)^2))``."""
    return float(np.sqrt(np.sum(np.diff(_signal(x, "S_s")) ** 2)))


def xie11_from_sequences(s_a: np.ndarray, s_v: np.ndarray, s_s: np.ndarray) -> np.ndarray:
    """The 11 features of Xie et al. (section 3.4, Table 3) from the three sequences.

    Means of S_a, S_v, S_s; L1 norms of the db3 level-4 wavelet coefficients cA4, cD4, cD3, cD2, cD1 of S_s;
    absolute energy ``sum(S_s^2)`` (eq. 1); CID (eq. 2); ``std(S_s)`` (population).
    """
    s_s = _signal(s_s, "S_s", 2)
    return np.array([np.mean(_signal(s_a, "S_a")), np.mean(_signal(s_v, "S_v")), np.mean(s_s),
                     *wavelet_l1(s_s), float(np.sum(s_s**2)), cid(s_s), float(np.std(s_s))])


def xie_sequence_vector(recording: Recording, seconds: float = XIE_SECONDS) -> np.ndarray:
    """The 3n-vector ``[S_a, S_v, S_s]`` of the first ``seconds`` of ``taxels`` (or ``electrodes``).

    Xie et al. standardise these vectors per column across the training samples before the features
    (:class:`XieFeatures`), so every recording must give the same n: its first 1 s.
    """
    role = "taxels" if "taxels" in recording.roles else "electrodes"
    if role not in recording.roles:
        raise RelatedFeatureError(f"xie11 needs the role taxels or electrodes; "
                                  f"recording {recording.name!r} has neither")
    trace = _trace(recording, role)
    n = int(round(seconds * trace.fs))
    if n < 2 or trace.n < n:
        raise RelatedFeatureError(f"xie11 needs {seconds:g} s of {role} ({n} frames at {trace.fs:g} Hz); "
                                  f"recording {recording.name!r} has {trace.n}")
    return np.concatenate(xie_sequences(trace.data[:n]))


def xie11_from_vector(vector: np.ndarray) -> np.ndarray:
    """The 11 features of one (standardised) 3n-vector ``[S_a, S_v, S_s]``."""
    values = np.asarray(vector, dtype=np.float64)
    if values.ndim != 1 or values.size % 3 or values.size < 6:
        raise RelatedFeatureError(f"a Xie sequence vector has 3n >= 6 entries, got shape {values.shape}")
    return xie11_from_sequences(*np.split(values, 3))


def xie11(recording: Recording, scaler: StandardScaler | None = None) -> dict[str, float]:
    """The 11 Xie features of a recording's ``taxels`` (or ``electrodes`` as a 1-D array).

    ``scaler`` is a ``StandardScaler`` fitted on the training samples' sequence vectors (columns ordered
    [S_a, S_v, S_s]), as the paper standardises them; without it the raw sequences are used.
    """
    vector = xie_sequence_vector(recording)
    if scaler is not None:
        vector = scaler.transform(vector[None, :])[0]
    return dict(zip((f"xie11.{name}" for name in XIE_NAMES), xie11_from_vector(vector).tolist(), strict=True))


class XieFeatures(TransformerMixin, BaseEstimator):
    """Sequence vectors -> the 11 Xie features, standardising the sequences on the training rows.

    ``fit`` learns a ``StandardScaler`` per column of the 3n-vectors (:func:`xie_sequence_vector`);
    ``transform`` standardises with it and computes :func:`xie11_from_vector` for every row. Nothing of a
    test row is used in fitting, so it can sit inside cross-validation.
    """

    def fit(self, X: np.ndarray, y: np.ndarray | None = None) -> XieFeatures:
        """Learn the standardisation of the sequence vectors ``X`` (one row per recording) on these rows."""
        X = validate_data(self, X)
        self.scaler_ = StandardScaler().fit(X)
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """The 11 Xie features of every row of ``X``, standardised as fitted."""
        check_is_fitted(self, "scaler_")
        standard = self.scaler_.transform(validate_data(self, X, reset=False))
        return np.array([xie11_from_vector(row) for row in standard]).reshape(len(standard), len(XIE_NAMES))


# -- huang7 (Huang and Wu 2021) ----------------------------------------------------------------------

HUANG_BAND_HZ = 20.0
HUANG_BANDS = 7


def band_means(x: np.ndarray, fs: float, width: float = HUANG_BAND_HZ,
               bands: int = HUANG_BANDS) -> np.ndarray:
    """Mean FFT magnitude per frequency band, Huang and Wu section 2.2 (rectangular window).

    With ``x`` minus its mean, ``|rfft(x)| / len(x)`` at the bin frequencies ``k fs / N``; band b is the
    mean over the bins in ``[width b, width (b + 1))`` Hz, b = 0..bands-1 (NaN for a band without bins).
    A sine of amplitude A on a bin adds A / 2 to that bin.
    """
    values = _signal(x, "vibration", 2)
    magnitude = np.abs(np.fft.rfft(values - values.mean())) / values.size
    frequency = np.arange(magnitude.size) * fs / values.size
    band = np.floor(frequency / width)
    return np.array([float(np.mean(magnitude[band == b])) if np.any(band == b) else math.nan
                     for b in range(bands)])


def huang7(recording: Recording) -> dict[str, float]:
    """Mean FFT magnitude of the vibration in the bands 0-20, ..., 120-140 Hz (Huang and Wu 2021)."""
    _check_roles(recording, "huang7", ("vibration",))
    trace = _trace(recording, "vibration")
    means = band_means(one_axis(trace.data), trace.fs)
    return {f"huang7.band_{int(HUANG_BAND_HZ * b):03d}_{int(HUANG_BAND_HZ * (b + 1)):03d}": float(means[b])
            for b in range(HUANG_BANDS)}


# -- chathuranga4 and its baselines (Chathuranga et al. 2015) ----------------------------------------

def _xyz(x: np.ndarray) -> np.ndarray:
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != 3 or values.shape[0] < 2:
        raise RelatedFeatureError(f"force_xyz must have shape (n >= 2, 3), got {values.shape}")
    return values


def covariance_frobenius(xyz: np.ndarray) -> float:
    """Frobenius norm ``sqrt(trace(M^T M))`` of the 3x3 population covariance M (ddof 0).

    Chathuranga et al. eq. (2)-(4).
    """
    return float(np.linalg.norm(np.cov(_xyz(xyz).T, ddof=0), "fro"))


def chathuranga4(recording: Recording) -> dict[str, float]:
    """Frobenius norm of the covariance of ``force_xyz`` and its three means (Chathuranga et al. eq. 4-5)."""
    _check_roles(recording, "chathuranga4", ("force_xyz",))
    xyz = _xyz(_trace(recording, "force_xyz").data)
    mean = xyz.mean(axis=0)
    return {"chathuranga4.frobenius": covariance_frobenius(xyz), "chathuranga4.mean_x": float(mean[0]),
            "chathuranga4.mean_y": float(mean[1]), "chathuranga4.mean_z": float(mean[2])}


def principal_frequency(x: np.ndarray, fs: float) -> float:
    """Frequency of the tallest FFT peak of ``x`` minus its mean, DC excluded (first on ties); NaN if flat."""
    values = _signal(x, "x", 2)
    magnitude = np.abs(np.fft.rfft(values - values.mean()))[1:]
    if magnitude.size == 0 or not np.any(magnitude > 0):
        return math.nan
    return float((int(np.argmax(magnitude)) + 1) * fs / values.size)


def spatial_period(x: np.ndarray, fs: float, velocity: float) -> float:
    """Spatial period ``lambda = V / f_p`` (Chathuranga eq. 6; Muhammad et al.), in the unit of V times s.

    Interpretation: the mean is removed before the FFT, otherwise the DC bin is the tallest "peak".
    """
    return _ratio(velocity, principal_frequency(x, fs))


def chathuranga_period(recording: Recording) -> dict[str, float]:
    """The spatial-period baseline's feature: ``V / f_p`` of the motion direction x of ``force_xyz`` (mm).

    The palpation velocity V (mm/s) is ``recording.meta["velocity_mm_s"]``.
    """
    _check_roles(recording, "chathuranga_period", ("force_xyz",))
    velocity = recording.meta.get("velocity_mm_s")
    if velocity is None:
        raise RelatedFeatureError(f"chathuranga_period needs the palpation velocity meta['velocity_mm_s'] "
                                  f"of recording {recording.name!r}")
    trace = _trace(recording, "force_xyz")
    return {"chathuranga_period.lambda": spatial_period(_xyz(trace.data)[:, 0], trace.fs, float(velocity))}


def pearson_kurtosis(x: np.ndarray) -> float:
    """``mu4 / sigma^4`` (3 for Gaussian noise, 1.5 for a sine); NaN for a constant signal."""
    centred = x - np.mean(x)
    variance = float(np.mean(centred**2))
    return _ratio(float(np.mean(centred**4)), variance**2)


def friction_features(xyz: np.ndarray) -> np.ndarray:
    """The neural-net baseline's inputs (Chathuranga III-D2, after de Boissieu et al.).

    Friction coefficient ``mean(sqrt(x^2 + y^2) / z)`` over the samples with z != 0 (eq. 7; interpretation:
    the per-sample ratio is averaged), the population variance of x and the Pearson kurtosis of x.
    """
    values = _xyz(xyz)
    x, y, z = values.T
    loaded = z != 0
    mu = float(np.mean(np.hypot(x[loaded], y[loaded]) / z[loaded])) if np.any(loaded) else math.nan
    return np.array([mu, float(np.var(x)), pearson_kurtosis(x)])


def chathuranga_net(recording: Recording) -> dict[str, float]:
    """Friction coefficient, x variance and x kurtosis of ``force_xyz`` (the neural-net baseline)."""
    _check_roles(recording, "chathuranga_net", ("force_xyz",))
    mu, var_x, kurt_x = friction_features(_trace(recording, "force_xyz").data)
    return {"chathuranga_net.friction": mu, "chathuranga_net.var_x": var_x, "chathuranga_net.kurt_x": kurt_x}


# -- Hoelscher et al. 2015: xu3 -----------------------------------------------------------------------------------

XU_ELECTRODE = 17
"""Column of electrode E18 (Xu et al.'s compliance electrode; 0-based)."""

XU_BAND_HZ = (20.0, 500.0)


@lru_cache(maxsize=16)
def _bandpass(fs: float, low: float, high: float) -> np.ndarray:
    return signal.butter(4, [low, high], btype="bandpass", fs=fs, output="sos")


def band_pass(x: np.ndarray, fs: float, low: float, high: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth band-pass (``sosfiltfilt``), the filter type of the preprocessing
    (docs/features.md)."""
    values = _signal(x, "vibration", 2)
    if fs <= 2 * high:
        raise RelatedFeatureError(f"a {high:g} Hz band edge needs a sample rate above {2 * high:g} Hz, "
                                  f"got {fs:g} Hz")
    sos = _bandpass(float(fs), float(low), float(high))
    padlen = 3 * (2 * len(sos) + 1)
    if values.size <= padlen:
        raise RelatedFeatureError(f"{values.size} samples are too few to band-pass "
                                  f"(needs more than {padlen})")
    return signal.sosfiltfilt(sos, values)


def compliance_electrode(electrodes: np.ndarray) -> np.ndarray:
    """Electrode 18 (column 17), or the mean electrode when there are fewer than 18 columns."""
    values = np.asarray(electrodes, dtype=np.float64)
    return values[:, XU_ELECTRODE] if values.shape[1] > XU_ELECTRODE else values.mean(axis=1)


def xu3(recording: Recording) -> dict[str, float]:
    """Xu et al.'s three physical features as Hoelscher et al. 2015 adapt them (section III-B).

    ``ln(max - min)`` of electrode 18 (compliance; the joint angle is not measured), ``ln(var)`` of the
    vibration band-passed 20-500 Hz (texture) and ``max - min`` of the heat flow (thermal conductivity).
    A logarithm of 0 is NaN.
    """
    _check_roles(recording, "xu3", ("electrodes", "vibration", "heat_flow"))
    e18 = compliance_electrode(_trace(recording, "electrodes").data)
    vibration = _trace(recording, "vibration")
    filtered = band_pass(one_axis(vibration.data), vibration.fs, *XU_BAND_HZ)
    heat_flow = _trace(recording, "heat_flow").data
    return {"xu3.compliance": _log(float(np.ptp(e18))), "xu3.texture": _log(float(np.var(filtered))),
            "xu3.thermal": float(np.ptp(heat_flow))}


# -- Hoelscher et al. 2015: chu -----------------------------------------------------------------------------------

HANNING_SECONDS = 0.1
"""Length of the Hanning window smoothing PDC in the Chu features (interpretation: 0.1 s, odd samples)."""

POLY_DEGREE = 5


def hanning_smooth(x: np.ndarray, fs: float, seconds: float = HANNING_SECONDS) -> np.ndarray:
    """``x`` convolved with a unit-sum symmetric Hanning window of ``2 round(seconds fs / 2) + 1`` samples.

    The ends repeat the edge sample (``scipy.ndimage`` mode "nearest"), so a constant stays constant and a
    ramp stays a ramp away from the ends.
    """
    values = _signal(x, "pressure_dc")
    half = max(1, int(round(seconds * fs / 2)))
    window = signal.windows.hann(2 * half + 3, sym=True)[1:-1]  # without the zero end points
    return ndimage.convolve1d(values, window / window.sum(), mode="nearest")


def pressure_statistics(pdc: np.ndarray, fs: float) -> np.ndarray:
    """Maximum, mean and greatest change of the Hanning-smoothed PDC (Chu et al.).

    Interpretation: the greatest change is the steepest slope, ``max |diff(smoothed)| * fs`` (per second).
    """
    smooth = hanning_smooth(pdc, fs)
    change = float(np.max(np.abs(np.diff(smooth)))) * fs if smooth.size > 1 else math.nan
    return np.array([float(np.max(smooth)), float(np.mean(smooth)), change])


def energy_spectral_density(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided energy spectral density of ``x`` minus its mean: frequencies (Hz) and energy per bin.

    ``E_k = w_k |X_k|^2 / (N fs)`` with ``X = rfft(x)`` and w_k = 2 except for the DC and (even N) Nyquist
    bins, so ``sum(E_k) = sum(x^2) / fs``, the signal's energy (Parseval).
    """
    values = _signal(x, "vibration", 2)
    n = values.size
    spectrum = np.fft.rfft(values - values.mean())
    weight = np.full(spectrum.size, 2.0)
    weight[0] = 1.0
    if n % 2 == 0:
        weight[-1] = 1.0
    return np.arange(spectrum.size) * fs / n, weight * (spectrum.real**2 + spectrum.imag**2) / (n * fs)


def spectral_moments(frequency: np.ndarray, energy: np.ndarray) -> np.ndarray:
    """Area, centroid, variance, skewness and Pearson kurtosis of a spectrum seen as a distribution.

    ``area = sum E``, ``c = sum f E / area``, ``var = sum (f - c)^2 E / area``, skewness and kurtosis are the
    third and fourth standardised moments. NaN where a moment divides by 0.
    """
    area = float(np.sum(energy))
    if area == 0:
        return np.array([0.0, math.nan, math.nan, math.nan, math.nan])
    p = energy / area
    centroid = float(p @ frequency)
    deviation = frequency - centroid
    variance = float(p @ deviation**2)
    return np.array([area, centroid, variance, _ratio(float(p @ deviation**3), variance**1.5),
                     _ratio(float(p @ deviation**4), variance**2)])


MAX_EXPONENT = math.log(np.finfo(np.float64).max) / 2
"""The largest exponent :func:`time_constant`'s model takes, 354.9: half of float64's range, so the curve times
any step a signal can have (below 1e154) stays finite."""


def _exponential(t: np.ndarray, final: float, step: float, tau: float) -> np.ndarray:
    # t >= 0, so a positive exponent means tau < 0: a growing curve the optimiser tries on its way, which
    # it rejects whether its value is 1e154 times the step or infinite; it is capped, not let overflow.
    return final + step * np.exp(np.minimum(-t / tau, MAX_EXPONENT))


def time_constant(x: np.ndarray, fs: float) -> float:
    """The time constant tau of the least-squares fit ``x(t) = a + b exp(-t / tau)``, t = 0 at the first sample (s).

    Start ``(x[-1], x[0] - x[-1], duration / 3)``. NaN for a constant signal, a failed fit, or a tau that is
    not finite and positive.
    """
    values = _signal(x, "temperature", 4)
    if np.ptp(values) == 0:
        return math.nan
    t = np.arange(values.size) / fs
    start = (values[-1], values[0] - values[-1], max(t[-1], 1.0 / fs) / 3.0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optimize.OptimizeWarning)
            params, _ = optimize.curve_fit(_exponential, t, values, p0=start, maxfev=5000)
    except (RuntimeError, ValueError):
        return math.nan
    tau = float(params[2])
    return tau if math.isfinite(tau) and tau > 0 else math.nan


def principal_components(x: np.ndarray, count: int = 2) -> np.ndarray:
    """Scores of the first ``count`` principal components of the rows of ``x`` (n, k), shape (n, count).

    Each component's sign is chosen so its largest-magnitude loading is positive, making the scores
    reproducible.
    """
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] < count:
        raise RelatedFeatureError(f"{count} principal components need at least {count} columns, "
                                  f"got {values.shape}")
    centred = values - values.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    components = vt[:count]
    signs = np.sign(components[np.arange(count), np.argmax(np.abs(components), axis=1)])
    return centred @ (components * signs[:, None]).T


def electrode_polynomials(electrodes: np.ndarray, degree: int = POLY_DEGREE) -> np.ndarray:
    """Coefficients (highest power first) of degree-5 fits of the first two electrode PCs over time.

    Time runs from 0 to 1 over the recording (``np.polyfit``), so the coefficients do not depend on the
    rate or duration. Chu et al.: PCA on the electrode data, then polynomials on PC1 and PC2.
    """
    values = np.asarray(electrodes, dtype=np.float64)
    if values.ndim != 2 or values.shape[0] <= degree:
        raise RelatedFeatureError(f"degree-{degree} fits need more than {degree} electrode rows, "
                                  f"got {values.shape}")
    scores = principal_components(values)
    t = np.linspace(0.0, 1.0, values.shape[0])
    return np.concatenate([np.polyfit(t, scores[:, i], degree) for i in range(2)])


CHU_ROLES = ("pressure_dc", "vibration", "heat_flow", "temperature", "electrodes")
CHU_NAMES = ("pdc_max", "pdc_mean", "pdc_change", "esd_area", "esd_centroid", "esd_variance", "esd_skewness",
             "esd_kurtosis", "tac_area", "tdc_tau",
             *(f"pc{pc}_p{power}" for pc in (1, 2) for power in range(POLY_DEGREE, -1, -1)))
"""The 22 Chu features in order; ``pc1_p5`` is the t^5 coefficient of the PC1 fit."""


def chu(recording: Recording) -> dict[str, float]:
    """Chu et al.'s temporal BioTac features as Hoelscher et al. 2015 use them (section III-B), 22 values.

    PDC: maximum, mean and greatest change of the Hanning-smoothed signal (:func:`pressure_statistics`);
    vibration: area, centroid, variance, skewness and kurtosis of its energy spectral density; heat flow:
    area under the curve ``sum(TAC) / fs``; temperature: exponential time constant (:func:`time_constant`);
    electrodes: degree-5 polynomial coefficients of the first two principal components.
    """
    _check_roles(recording, "chu", CHU_ROLES)
    pdc, vibration, tac, tdc, electrodes = (_trace(recording, role) for role in CHU_ROLES)
    moments = spectral_moments(*energy_spectral_density(one_axis(vibration.data), vibration.fs))
    tac_area = float(np.sum(_signal(tac.data, "heat_flow")) / tac.fs)
    values = [*pressure_statistics(pdc.data, pdc.fs), *moments, tac_area, time_constant(tdc.data, tdc.fs),
              *electrode_polynomials(electrodes.data)]
    return {f"chu.{name}": float(value) for name, value in zip(CHU_NAMES, values, strict=True)}


# -- Hoelscher et al. 2015: mean23 --------------------------------------------------------------------------------

MEAN_ROLES = ("pressure_dc", "vibration", "temperature", "heat_flow", "electrodes")


def mean23(recording: Recording) -> dict[str, float]:
    """The mean of every channel: PDC, vibration, temperature, heat flow and each electrode (23 on a BioTac).

    Hoelscher et al. 2015 then reduce them to 8 dimensions by PCA fitted on the training samples (the method does that).
    """
    _check_roles(recording, "mean23", MEAN_ROLES)
    values = {f"mean23.{role}": float(np.mean(one_axis(_trace(recording, role).data)))
              for role in MEAN_ROLES[:4]}
    electrodes = _trace(recording, "electrodes").data.mean(axis=0)
    values.update({f"mean23.electrode_{i + 1:02d}": float(v) for i, v in enumerate(electrodes)})
    return values


# -- Hoelscher et al. 2015: dallaire ------------------------------------------------------------------------------

THRESHOLDS = 20


def central_moment(x: np.ndarray, order: int) -> float:
    """``mean((x - mean(x))^order)`` (population, unnormalised)."""
    return float(np.mean((x - np.mean(x)) ** order))


def threshold_crossings(x: np.ndarray, count: int = THRESHOLDS) -> int:
    """Side changes between consecutive samples summed over ``count`` evenly spaced thresholds (Dallaire).

    Thresholds ``t_j = min + (max - min) j / (count + 1)``, j = 1..count; a side change at sample i is
    ``(x[i] >= t_j) != (x[i + 1] >= t_j)``. A monotonic ramp crosses each threshold once.
    """
    values = _signal(x, "vibration")
    low, high = float(values.min()), float(values.max())
    thresholds = low + (high - low) * np.arange(1, count + 1) / (count + 1)
    above = values[None, :] >= thresholds[:, None]
    return int(np.count_nonzero(above[:, 1:] != above[:, :-1]))


def upper_spectrum_sum(x: np.ndarray) -> float:
    """Sum of ``|rfft(x)|`` over the bins k >= N / 4 (the upper half of the amplitude spectrum)."""
    values = _signal(x, "vibration")
    magnitude = np.abs(np.fft.rfft(values))
    k = np.arange(magnitude.size)
    return float(np.sum(magnitude[4 * k >= values.size]))


def dallaire(recording: Recording) -> dict[str, float]:
    """Dallaire et al.'s vibration features as Hoelscher et al. 2015 compute them on the BioTac PAC signal.

    Variance, skewness ``m3 / m2^1.5``, Pearson kurtosis ``m4 / m2^2``, unnormalised fifth central moment
    ``m5``, total variation ``sum |diff(x)|``, threshold side changes (:func:`threshold_crossings`) and the
    upper-half amplitude spectrum sum (:func:`upper_spectrum_sum`).
    """
    _check_roles(recording, "dallaire", ("vibration",))
    x = _signal(one_axis(_trace(recording, "vibration").data), "vibration", 2)
    m2 = central_moment(x, 2)
    return {"dallaire.variance": m2, "dallaire.skewness": _ratio(central_moment(x, 3), m2**1.5),
            "dallaire.kurtosis": _ratio(central_moment(x, 4), m2**2),
            "dallaire.moment5": central_moment(x, 5),
            "dallaire.total_variation": float(np.sum(np.abs(np.diff(x)))),
            "dallaire.crossings": float(threshold_crossings(x)),
            "dallaire.upper_spectrum": upper_spectrum_sum(x)}


# -- Hoelscher et al. 2015: chitta --------------------------------------------------------------------------------

CHITTA_CUTOFF_HZ = 5.0
"""Cut-off of the first-order Butterworth filter on the electrodes (interpretation: high-pass at 5 Hz)."""


def electrode_norm(electrodes: np.ndarray, fs: float, cutoff: float = CHITTA_CUTOFF_HZ) -> np.ndarray:
    """Euclidean norm over the electrodes of their first-order Butterworth high-pass (Chitta et al.).

    Interpretation: Chitta et al. look at the high-frequency part of gripper pressure cells; Hoelscher et al. 2015 name
    only "a first-order Butterworth filter". The filter runs causally, as online, from the steady state of
    the first sample (``sosfilt_zi``), so constant electrodes give exactly 0.
    """
    values = np.asarray(electrodes, dtype=np.float64)
    if values.ndim != 2 or values.shape[0] < 2:
        raise RelatedFeatureError(f"electrodes must have shape (n >= 2, k), got {values.shape}")
    if fs <= 2 * cutoff:
        raise RelatedFeatureError(f"a {cutoff:g} Hz cut-off needs a sample rate above {2 * cutoff:g} Hz, "
                                  f"got {fs:g} Hz")
    sos = signal.butter(1, cutoff, btype="highpass", fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos)[:, :, None] * values[0][None, None, :]
    filtered, _ = signal.sosfilt(sos, values, axis=0, zi=zi)
    return np.sqrt(np.sum(filtered**2, axis=1))


def chitta(recording: Recording) -> dict[str, float]:
    """Mean and variance of the Euclidean norm of the filtered electrodes (:func:`electrode_norm`)."""
    _check_roles(recording, "chitta", ("electrodes",))
    trace = _trace(recording, "electrodes")
    norm = electrode_norm(trace.data, trace.fs)
    return {"chitta.mean": float(np.mean(norm)), "chitta.variance": float(np.var(norm))}


# -- Hoelscher et al. 2015: temperature ---------------------------------------------------------------------------

SETTLE_SECONDS = 6.0
"""Hoelscher et al. 2015 read the temperature features after 6 s of contact (Fig. 5a)."""


def settled(x: np.ndarray, fs: float, seconds: float = SETTLE_SECONDS) -> np.ndarray:
    """The samples after the first ``seconds``; interpretation for shorter recordings: the second half."""
    values = _signal(x, "temperature", 2)
    start = min(int(round(seconds * fs)), values.size // 2)
    return values[start:]


def change_after_peak(x: np.ndarray) -> float:
    """``x[p] - min(x[p:])`` with p the (first) maximum: the heat-flow change after its initial peak."""
    values = _signal(x, "heat_flow")
    peak = int(np.argmax(values))
    return float(values[peak] - np.min(values[peak:]))


def temperature(recording: Recording) -> dict[str, float]:
    """The temperature features of Hoelscher et al. 2015: means of heat flow and temperature after the first
    6 s, and the heat-flow change after its peak."""
    _check_roles(recording, "temperature", ("heat_flow", "temperature"))
    tac, tdc = _trace(recording, "heat_flow"), _trace(recording, "temperature")
    return {"temperature.tac_mean": float(np.mean(settled(tac.data, tac.fs))),
            "temperature.tdc_mean": float(np.mean(settled(tdc.data, tdc.fs))),
            "temperature.tac_change": change_after_peak(tac.data)}


# -- registry and scans ------------------------------------------------------------------------------

@dataclass(frozen=True)
class RelatedSet:
    """A related-work feature set: what it reads and the function computing it from a recording."""

    name: str
    roles: tuple[str, ...]
    source: str
    function: Callable[[Recording], dict[str, float]]

    def applies_to(self, recording: Recording) -> bool:
        """Whether the recording has every role this set reads (``xie11``: taxels or electrodes)."""
        if self.name == "xie11":
            return "taxels" in recording.roles or "electrodes" in recording.roles
        return all(role in recording.roles for role in self.roles)


FEATURE_SETS: Mapping[str, RelatedSet] = MappingProxyType({s.name: s for s in (
    RelatedSet("xie11", ("taxels",), "Xie et al. 2019", xie11),
    RelatedSet("huang7", ("vibration",), "Huang and Wu 2021", huang7),
    RelatedSet("chathuranga4", ("force_xyz",), "Chathuranga et al. 2015", chathuranga4),
    RelatedSet("chathuranga_period", ("force_xyz",), "Chathuranga et al. 2015, spatial-period baseline",
               chathuranga_period),
    RelatedSet("chathuranga_net", ("force_xyz",), "Chathuranga et al. 2015, neural-net baseline",
               chathuranga_net),
    RelatedSet("xu3", ("electrodes", "vibration", "heat_flow"), "Hoelscher et al. 2015 after Xu et al.", xu3),
    RelatedSet("chu", CHU_ROLES, "Hoelscher et al. 2015 after Chu et al.", chu),
    RelatedSet("mean23", MEAN_ROLES, "Hoelscher et al. 2015", mean23),
    RelatedSet("dallaire", ("vibration",), "Hoelscher et al. 2015 after Dallaire et al.", dallaire),
    RelatedSet("chitta", ("electrodes",), "Hoelscher et al. 2015 after Chitta et al.", chitta),
    RelatedSet("temperature", ("heat_flow", "temperature"), "Hoelscher et al. 2015", temperature),
)})
"""Feature sets on recordings by name; ``fishel3`` works on scans (:func:`fishel3`)."""


def compute(name: str, recording: Recording) -> dict[str, float]:
    """The feature set ``name`` of one recording (docs/features.md#related).

    Parameters
    ----------
    name : str
        A key of :data:`FEATURE_SETS`: ``fishel3``, ``xie11``, ``huang7``, ``chathuranga4``, ``xu3``,
        ``chu``, ``mean23``, ``dallaire``, ``chitta``, ``temperature``.
    recording : Recording
        A recording with the set's roles (a scan is one through :func:`scan_recording`).

    Returns
    -------
    dict of str to float

    Raises
    ------
    RelatedFeatureError
        The recording lacks a role the set reads, an unknown set name, or data the set cannot use.
    """
    if name not in FEATURE_SETS:
        raise RelatedFeatureError(f"unknown feature set {name!r} (known: {', '.join(FEATURE_SETS)})")
    return FEATURE_SETS[name].function(recording)


SCAN_ROLES = {"vibration": "v", "audio": "a_ts", "temperature": "t_cool"}
"""Roles of a scan as a generic recording: the tool-slide signal ``v``, the tool-slide audio and the
object temperature."""


def slide_vibration(v_ts: Trace) -> Trace:
    """The tool-slide signal ``v`` (docs/features.md#preprocessing: ``v_ts`` band-limited 10-1000 Hz, 1 s window,
    DFT321).

    When the slide check fails, the band-limited DFT321 of the whole recording, so the scan still has a
    vibration (the other roles' methods would otherwise lose the whole database over one bad slide).
    """
    try:
        return Trace(slide_signal(v_ts), v_ts.fs, v_ts.unit)
    except QualityError:
        return Trace(dft321(band_limit(v_ts.data, v_ts.fs)), v_ts.fs, v_ts.unit)


def scan_recording(scan: Scan) -> Recording:
    """A scan as a generic :class:`Recording`: every channel under its name plus ``v``
    (:func:`slide_vibration`), roles per :data:`SCAN_ROLES`.

    The label is the scan's taxonomy label; the groups are the sample (``object``) and the scan index
    (``trial``), so the scans of one sample count as repeated trials on one object.
    """
    channels = dict(scan.traces)
    if "v_ts" in channels:
        channels["v"] = slide_vibration(channels["v_ts"])
    roles = {role: channel for role, channel in SCAN_ROLES.items() if channel in channels}
    group = {"object": scan.meta.sample_id, "trial": f"{scan.meta.scan_index:03d}"}
    return Recording(scan.scan_id, channels, roles, scan.meta.label, group)
