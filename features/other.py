"""The 15 "other" features: density, metal, magnetism, IR reflectance, cooling, vibration and tap
(docs/features.md#other).

The paper's Table III of these features is an image that did not survive, so this set is the project's own
(docs/features.md#other). Each feature (or family) is a pure function of arrays; :func:`compute` gathers the inputs of
one :class:`scanner.Scan`, preprocessed as in docs/features.md#preprocessing, and returns the 15 values in
:data:`NAMES` order. A value that is undefined (0/0, a missing channel or meta value, a failed fit, a stored slide that
fails
its quality check) is NaN, never 0 or inf.

Notation: ``v`` is the tool-slide signal (``v_ts`` band-limited, 1 s window, DFT321), ``v_f`` the same for
the finger slide ``v_fs``; ``mean`` and ``std`` are population statistics.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np

from features.prepared import PreparedScan
from features.tactum import MissingDataWarning, spectral_centroid
from scanner.lazy import library
from scanner.preprocess import NO_SLIDE, QualityError, dft321
from scanner.scan import Scan, Trace
from taxonomy.errors import ParameterError, TexplorerError

optimize = library("scipy.optimize")
signal = library("scipy.signal")

NAMES = (
    "other.density", "other.metal", "other.magnet_mean", "other.magnet_peak", "other.reflect_static",
    "other.reflect_mean", "other.cooling_rate", "other.vib_std", "other.vib_kurtosis", "other.vib_energy",
    "other.finger_vib_energy", "other.finger_vib_centroid", "other.tap_peak", "other.tap_centroid",
    "other.tap_decay",
)
"""The other feature names, in feature-space order (docs/features.md#other)."""

VIBRATION_FS = 3000.0
"""Sample rate of the accelerometer and IR channels, Hz."""

T_COOL_FS = 20.0
"""Sample rate of the MLX90614 object temperature ``t_cool``, Hz."""

TAP_SAMPLES = 150
"""Samples of the tap response analysed from the tap peak on: 50 ms at 3000 Hz (docs/features.md#other)."""

TAP_MIN_SAMPLES = 30
"""Fewer tap-response samples than this (10 ms) leave the tap centroid and decay undefined (docs/features.md#other)."""

TAP_TAU0 = 0.01
"""Starting guess of the tap decay time constant, s (docs/features.md#other)."""
TAP_FIT_TOL = 1.49012e-08
"""``xtol`` and ``ftol`` of the tap-decay fit: ``curve_fit``'s (MINPACK ``lmdif``) defaults, sqrt(eps)."""
COOLING_FIT_TOL = 1e-14
"""``xtol``, ``ftol`` and ``gtol`` of the cooling-rate fit."""

SOLVER_RTOL = {"other.tap_decay": math.sqrt(TAP_FIT_TOL), "other.cooling_rate": math.sqrt(COOLING_FIT_TOL)}
"""Relative tolerance of the features that come out of an iterative fit, for comparing runs on different
machines or library versions (``texplorer replay``, the regression suite); every other feature is
closed-form (sums, FFTs, filters) and keeps the replay default, 1e-9.

Levenberg-Marquardt stops as soon as one step reduces the sum of squared residuals S by a relative amount
below ``ftol`` (or moves the parameters by less than ``xtol``). Near the optimum S grows with the square of
the parameter error, so the ``ftol`` test leaves a relative error of the order of sqrt(ftol) -- slow
(large-residual) fits such as a noisy tap envelope do stop that far out -- and a different BLAS/LAPACK
build or CPU, taking slightly different steps, may stop at another iterate of the same approach:
tap_decay sqrt(1.49e-8) = 1.2e-4, cooling_rate sqrt(1e-14) = 1e-7.
"""


def _samples(x: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(x, dtype=np.float64)
    if array.ndim != 1 or array.size == 0:
        raise ParameterError(f"{name} must be a non-empty 1-D array, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise ParameterError(f"{name} has non-finite samples")
    return array


def _axes(a: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(a, dtype=np.float64)
    if array.ndim != 2 or array.shape[0] == 0:
        raise ParameterError(f"{name} must be a non-empty (n, axes) array, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise ParameterError(f"{name} has non-finite samples")
    return array


# --- density, metal, magnetism ------------------------------------------------------------------------

def density(mass_g: float, volume_cm3: float) -> float:
    """Density ``mass / volume`` in g/cm^3 (docs/features.md#other); NaN if either was not measured (NaN).

    Parameters
    ----------
    mass_g : float
        Mass in g (``meta.mass_g``), NaN if not weighed.
    volume_cm3 : float
        Volume in cm^3 (``meta.volume_cm3``), NaN if not measured.

    Returns
    -------
    float
        Density in g/cm^3, NaN if either value is NaN.

    Raises
    ------
    ParameterError
        If a value is zero, negative or infinite.

    Examples
    --------
    >>> from features.other import density
    >>> density(27.0, 10.0)
    2.7
    >>> density(27.0, float("nan"))
    nan
    """
    mass, volume = float(mass_g), float(volume_cm3)
    for name, value in (("mass_g", mass), ("volume_cm3", volume)):
        if math.isinf(value) or value <= 0:
            raise ParameterError(f"{name} must be positive and finite (or NaN if not measured), got {value!r}")
    return mass / volume


def metal(m: np.ndarray) -> float:
    """1 if the sample conducts, ``mean(m) > 0``, else 0 (docs/features.md#other); ``m`` is the electrode in {-1, +1}.

    A tie (as many +1 as -1 samples) is not conductive: the electrodes did not close for most of the time.

    Parameters
    ----------
    m : array of shape (n,)
        Metal electrode samples, +1 conductive, -1 not.

    Returns
    -------
    float
        1.0 or 0.0.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import metal
    >>> metal(np.array([1.0, 1.0, -1.0])), metal(np.array([1.0, -1.0]))
    (1.0, 0.0)
    """
    return 1.0 if float(np.mean(_samples(m, "m"))) > 0 else 0.0


def magnet_mean(dB: np.ndarray) -> float:
    """Mean change of the magnetic field magnitude against the calibration, ``mean(dB)`` in uT
    (docs/features.md#other).

    Parameters
    ----------
    dB : array of shape (n,)
        Change of the magnetic field magnitude in uT.

    Returns
    -------
    float
        The mean in uT.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import magnet_mean
    >>> magnet_mean(np.array([0.5, 1.5, -0.5, 2.5]))
    1.0
    """
    return float(np.mean(_samples(dB, "dB")))


def magnet_peak(dB: np.ndarray) -> float:
    """The ``dB`` sample of largest magnitude, with its sign, in uT (docs/features.md#other); the first one on ties.

    A ferromagnetic sample pulls the field strongly in either direction depending on the pole facing the
    sensor, so the sign is kept and the magnitude decides.

    Parameters
    ----------
    dB : array of shape (n,)
        Change of the magnetic field magnitude in uT.

    Returns
    -------
    float
        The sample of largest magnitude in uT.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import magnet_peak
    >>> magnet_peak(np.array([1.0, 3.0, -7.0, 5.0]))
    -7.0
    >>> magnet_peak(np.array([2.0, -2.0]))
    2.0
    """
    values = _samples(dB, "dB")
    return float(values[np.argmax(np.abs(values))])


# --- IR reflectance -----------------------------------------------------------------------------------

def reflect_static(r_ts: np.ndarray, start: int) -> float:
    """Mean IR reflectance of the tool slide while the unit rests, ``mean(r_ts[:start])`` in V (docs/features.md#other).

    ``start`` is the slide start of ``v_ts`` (:func:`scanner.preprocess.slide_start`); NaN if it is 0
    (no resting samples).

    Parameters
    ----------
    r_ts : array of shape (n,)
        IR reflectance during the tool slide in V.
    start : int
        Slide start, a sample index in 0..n.

    Returns
    -------
    float
        The mean reflectance before the start in V, NaN if ``start`` is 0.

    Raises
    ------
    ParameterError
        If ``start`` is not an integer index in 0..n.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import reflect_static
    >>> r_ts = np.array([2.0, 2.2, 3.0, 3.1])
    >>> round(reflect_static(r_ts, 2), 6), reflect_static(r_ts, 0)
    (2.1, nan)
    """
    values = _samples(r_ts, "r_ts")
    if isinstance(start, bool) or int(start) != start or not 0 <= start <= values.size:
        raise ParameterError(f"slide start must be a sample index in 0..{values.size}, got {start!r}")
    return math.nan if start == 0 else float(np.mean(values[:int(start)]))


def reflect_mean(r_window: np.ndarray) -> float:
    """Mean IR reflectance in the 1 s slide window of the tool slide, in V (docs/features.md#other).

    Parameters
    ----------
    r_window : array of shape (n,)
        IR reflectance ``r_ts`` in the slide window of ``v_ts``, in V.

    Returns
    -------
    float
        The mean reflectance in V.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import reflect_mean
    >>> round(reflect_mean(np.array([1.1, 1.3, 1.2])), 6)
    1.2
    """
    return float(np.mean(_samples(r_window, "r_window")))


# --- cooling ------------------------------------------------------------------------------------------

def cooling_rate(t_cool: np.ndarray, t_amb: float, fs: float = T_COOL_FS) -> float:
    """Rate r (1/s) of the least-squares fit ``T(t) = t_amb + (T_max - t_amb) exp(-r t)`` (docs/features.md#other).

    Fitted from the maximum of ``t_cool`` on (the first maximum on ties), with T_max the measured maximum,
    t = 0 at it, only r free and residuals in degC (``scipy.optimize.least_squares``, Levenberg-Marquardt,
    started at the log-linear estimate).

    NaN if ``t_amb`` is NaN, fewer than two samples follow from the maximum on, ``T_max == t_amb`` (r does
    not change the model), or the least-squares optimum is r = infinity (every later sample fits the
    instant drop to ``t_amb`` at least as well as any finite rate does).

    Parameters
    ----------
    t_cool : array of shape (n,)
        Object temperature after heating in degC.
    t_amb : float
        Ambient temperature in degC, NaN if unknown.
    fs : float
        Sample rate of ``t_cool`` in Hz (default :data:`T_COOL_FS`, 20).

    Returns
    -------
    float
        The rate in 1/s, NaN where undefined; reproducible to :data:`SOLVER_RTOL`.

    Raises
    ------
    ParameterError
        If ``fs`` is not positive and finite, or ``t_amb`` is infinite.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import cooling_rate
    >>> t = np.arange(200) / 20.0
    >>> round(cooling_rate(22.0 + 8.0 * np.exp(-0.3 * t), 22.0), 9)
    0.3
    >>> cooling_rate(np.full(10, 22.0), 22.0)
    nan
    """
    values = _samples(t_cool, "t_cool")
    if not math.isfinite(fs) or fs <= 0:
        raise ParameterError(f"t_cool sample rate must be positive and finite, got {fs!r}")
    if math.isinf(t_amb):
        raise ParameterError(f"t_amb must be finite (or NaN if unknown), got {t_amb!r}")
    tail = values[int(np.argmax(values)):]
    excess = float(tail[0] - t_amb)
    if math.isnan(excess) or tail.size < 2 or excess == 0:
        return math.nan
    t = np.arange(tail.size) / fs

    def residuals(r: np.ndarray) -> np.ndarray:
        return t_amb + excess * np.exp(-r[0] * t) - tail

    def jacobian(r: np.ndarray) -> np.ndarray:
        return (-excess * t * np.exp(-r[0] * t))[:, None]

    with np.errstate(over="ignore", invalid="ignore"):
        fit = optimize.least_squares(residuals, [_log_linear_rate(tail - t_amb, excess, t)], jac=jacobian,
                                     method="lm", xtol=COOLING_FIT_TOL, ftol=COOLING_FIT_TOL,
                                     gtol=COOLING_FIT_TOL)
    rate = float(fit.x[0])
    if not (fit.success and math.isfinite(rate) and np.all(np.isfinite(fit.fun))):
        return math.nan
    instant_drop = float(np.sum((t_amb - tail[1:]) ** 2))
    return rate if float(np.sum(fit.fun**2)) < instant_drop else math.nan


def _log_linear_rate(above: np.ndarray, excess: float, t: np.ndarray) -> float:
    """Starting rate: ``log((T - t_amb) / excess) = -r t`` fitted through the origin where the log exists."""
    ratio = above / excess
    usable = (ratio > 0) & (t > 0)
    if not usable.any():
        return 1.0 / t[-1]
    return float(-np.sum(t[usable] * np.log(ratio[usable])) / np.sum(t[usable] ** 2))


# --- slide vibration ----------------------------------------------------------------------------------

def vib_std(v: np.ndarray) -> float:
    """Standard deviation (population) of the slide signal, ``std(v)`` in g (docs/features.md#other).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.

    Returns
    -------
    float
        ``std(v)`` in g.

    Examples
    --------
    A sine of amplitude 1 over whole periods has the standard deviation ``1 / sqrt(2)``:

    >>> import math
    >>> import numpy as np
    >>> from features.other import vib_std
    >>> round(vib_std(np.sin(2 * np.pi * 50.0 * np.arange(3000) / 3000.0)), 6), round(1 / math.sqrt(2), 6)
    (0.707107, 0.707107)
    """
    return float(np.std(_samples(v, "v")))


def vib_kurtosis(v: np.ndarray) -> float:
    """Pearson kurtosis (not excess) of the slide signal, ``mu4 / sigma^4`` (docs/features.md#other).

    3 for Gaussian noise, 1.5 for a sine; NaN for a constant signal (0/0).

    Parameters
    ----------
    v : array of shape (n,)
        Tool-slide signal in g.

    Returns
    -------
    float
        The kurtosis, NaN for a constant signal.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import vib_kurtosis
    >>> round(vib_kurtosis(np.sin(2 * np.pi * np.arange(3000) / 30.0)), 9)
    1.5
    >>> vib_kurtosis(np.full(100, 0.2))  # constant, though 0.2 has no exact binary mean
    nan
    """
    values = _samples(v, "v")
    if values.min() == values.max():  # constant: the rounding of its mean must not pass for a signal (0.2)
        return math.nan
    centred = values - values.mean()
    variance = float(np.mean(centred**2))
    return math.nan if variance == 0 else float(np.mean(centred**4)) / variance**2


def vib_energy(v: np.ndarray) -> float:
    """Mean power of a slide signal, ``mean(v^2)`` in g^2 (docs/features.md#other): vib_energy and finger_vib_energy.

    Parameters
    ----------
    v : array of shape (n,)
        Tool- or finger-slide signal in g.

    Returns
    -------
    float
        ``mean(v^2)`` in g^2.

    Examples
    --------
    A sine of amplitude 2 over whole periods has the mean power ``2^2 / 2``:

    >>> import numpy as np
    >>> from features.other import vib_energy
    >>> round(vib_energy(2.0 * np.sin(2 * np.pi * 50.0 * np.arange(3000) / 3000.0)), 6)
    2.0
    """
    return float(np.mean(_samples(v, "v") ** 2))


def vib_centroid(v: np.ndarray, fs: float = VIBRATION_FS) -> float:
    """Spectral centroid of a slide signal in Hz, as ``tactum.mico`` (Strese et al. 2020, eq. 15;
    docs/features.md#mico).

    ``finger_vib_centroid`` is that of ``v_f``. NaN for an all-zero signal.

    Parameters
    ----------
    v : array of shape (n,)
        Slide signal in g.
    fs : float
        Sample rate in Hz (default :data:`VIBRATION_FS`, 3000).

    Returns
    -------
    float
        The centroid in Hz, NaN for an all-zero signal.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import vib_centroid
    >>> round(vib_centroid(np.sin(2 * np.pi * 400.0 * np.arange(3000) / 3000.0)), 6)
    400.0
    """
    return spectral_centroid(_samples(v, "v"), fs)


# --- tool tap -----------------------------------------------------------------------------------------

def tap_energy(a: np.ndarray) -> np.ndarray:
    """Per-sample energy of the band-limited tool tap summed over the axes, ``sum over axes a^2`` (g^2).

    Parameters
    ----------
    a : array of shape (n, axes)
        Band-limited tool tap in g.

    Returns
    -------
    ndarray of shape (n,)
        The energy of each sample in g^2.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import tap_energy
    >>> tap_energy(np.array([[3.0, 4.0, 0.0], [1.0, 2.0, 2.0]]))
    array([25.,  9.])
    """
    return _energy_of_axes(_axes(a, "v_tt"))


def _energy_of_axes(array: np.ndarray) -> np.ndarray:
    # Axis by axis, in order: the additions of np.sum(array**2, axis=1) on a few axes, without its slow
    # reduction over a short axis.
    energy = array[:, 0] ** 2
    for axis in range(1, array.shape[1]):
        energy += array[:, axis] ** 2
    return energy


def tap_peak(a: np.ndarray) -> float:
    """Tap peak ``sqrt(energy[p])`` in g, p = argmax of :func:`tap_energy` (docs/features.md#other).

    Parameters
    ----------
    a : array of shape (n, axes)
        Band-limited tool tap in g.

    Returns
    -------
    float
        The largest magnitude of the acceleration vector in g.

    Examples
    --------
    >>> import numpy as np
    >>> from features.other import tap_peak
    >>> tap_peak(np.array([[3.0, 4.0, 0.0], [1.0, 2.0, 2.0]]))
    5.0
    """
    return float(np.sqrt(np.max(tap_energy(a))))


def tap_response(a: np.ndarray, length: int = TAP_SAMPLES,
                 min_length: int = TAP_MIN_SAMPLES) -> np.ndarray | None:
    """DFT321 of the ``length`` samples from the tap peak p on (fewer if the recording ends sooner).

    ``a`` is the band-limited tool tap (n, 3); p = argmax of :func:`tap_energy`, the first on ties.
    None if fewer than ``min_length`` samples remain from p on (docs/features.md#other).

    Parameters
    ----------
    a : array of shape (n, axes)
        Band-limited tool tap in g.
    length : int
        Samples taken from p on (default :data:`TAP_SAMPLES`, 150).
    min_length : int
        Fewest samples from p on that make a response (default :data:`TAP_MIN_SAMPLES`, 30).

    Returns
    -------
    ndarray of shape (m,) or None
        The response in g, ``m = min(length, n - p)``; None if ``m < min_length``.

    Examples
    --------
    The same decaying 600 Hz tap on all three axes, its peak at sample 10: DFT321 keeps the energy, so the
    response is the tap times ``sqrt(3)``.

    >>> import numpy as np
    >>> from features.other import tap_response
    >>> t = np.arange(290) / 3000.0
    >>> x = np.r_[np.zeros(10), np.exp(-t / 0.01) * np.cos(2 * np.pi * 600.0 * t)]
    >>> y = tap_response(np.column_stack([x, x, x]))
    >>> y.shape, bool(np.allclose(y, np.sqrt(3) * x[10:160]))
    ((150,), True)
    >>> print(tap_response(np.column_stack([x, x, x])[:30]))
    None
    """
    array = _axes(a, "v_tt")
    return _tap_response(array, _energy_of_axes(array), length, min_length)


def _tap_response(array: np.ndarray, energy: np.ndarray, length: int = TAP_SAMPLES,
                  min_length: int = TAP_MIN_SAMPLES) -> np.ndarray | None:
    p = int(np.argmax(energy))
    segment = array[p:p + length]
    return None if segment.shape[0] < min_length else dft321(segment)


def tap_centroid(y: np.ndarray, fs: float = VIBRATION_FS) -> float:
    """Spectral centroid of the tap response y in Hz (Strese et al. 2020, eq. 15; docs/features.md#other).

    Parameters
    ----------
    y : array of shape (n,)
        Tap response in g (:func:`tap_response`).
    fs : float
        Sample rate in Hz (default :data:`VIBRATION_FS`, 3000).

    Returns
    -------
    float
        The centroid in Hz, NaN for an all-zero response.

    Examples
    --------
    30 periods of a 600 Hz tone in 150 samples:

    >>> import numpy as np
    >>> from features.other import tap_centroid
    >>> round(tap_centroid(np.sin(2 * np.pi * 600.0 * np.arange(150) / 3000.0)), 6)
    600.0
    """
    return spectral_centroid(_samples(y, "y"), fs)


def _decay(t: np.ndarray, amplitude: float, tau: float) -> np.ndarray:
    return amplitude * np.exp(-t / tau)


def tap_decay(y: np.ndarray, fs: float = VIBRATION_FS) -> float:
    """Decay time constant tau (s) of the tap response: ``A exp(-t / tau)`` fitted to ``|hilbert(y)|``.

    ``scipy.optimize.curve_fit`` (Levenberg-Marquardt with its default tolerances, :data:`TAP_FIT_TOL`;
    reproducible to :data:`SOLVER_RTOL`) with p0 = (max envelope, 0.01 s), t = 0 at the first sample of y
    (docs/features.md#other). NaN if the envelope is all zero, if the fit raises, or if tau is non-finite or not
    positive.

    Parameters
    ----------
    y : array of shape (n,)
        Tap response in g (:func:`tap_response`).
    fs : float
        Sample rate in Hz (default :data:`VIBRATION_FS`, 3000).

    Returns
    -------
    float
        tau in s, NaN where undefined.

    Examples
    --------
    A 500 Hz tone dying away with tau = 10 ms:

    >>> import numpy as np
    >>> from features.other import tap_decay
    >>> t = np.arange(150) / 3000.0
    >>> round(tap_decay(np.exp(-t / 0.01) * np.cos(2 * np.pi * 500.0 * t)), 3)
    0.01
    >>> tap_decay(np.zeros(150))
    nan
    """
    envelope = np.abs(signal.hilbert(_samples(y, "y")))
    if not envelope.any():
        return math.nan
    t = np.arange(envelope.size) / fs
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            # An undetermined covariance says nothing about tau itself; docs/features.md#other rejects only bad taus.
            warnings.simplefilter("ignore", optimize.OptimizeWarning)
            (_, tau), _ = optimize.curve_fit(_decay, t, envelope, p0=(float(envelope.max()), TAP_TAU0),
                                              xtol=TAP_FIT_TOL, ftol=TAP_FIT_TOL)
    except (RuntimeError, ValueError):
        return math.nan
    tau = float(tau)
    return tau if math.isfinite(tau) and tau > 0 else math.nan


def tap_features(a: np.ndarray, fs: float = VIBRATION_FS) -> tuple[float, float, float]:
    """``(tap_peak, tap_centroid, tap_decay)`` of the band-limited tool tap ``a`` (n, 3) (docs/features.md#other).

    Centroid and decay are NaN if fewer than 30 samples follow the tap peak (see :func:`tap_response`).

    Parameters
    ----------
    a : array of shape (n, axes)
        Band-limited tool tap in g.
    fs : float
        Sample rate in Hz (default :data:`VIBRATION_FS`, 3000).

    Returns
    -------
    (float, float, float)
        Peak in g, centroid in Hz and decay time constant in s.

    Examples
    --------
    A 600 Hz tap of peak 1 g dying away with tau = 10 ms on one axis; cut 20 samples after its peak, only
    the peak is defined:

    >>> import numpy as np
    >>> from features.other import tap_features
    >>> t = np.arange(290) / 3000.0
    >>> x = np.r_[np.zeros(10), np.exp(-t / 0.01) * np.cos(2 * np.pi * 600.0 * t)]
    >>> a = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    >>> peak, centroid, decay = tap_features(a)
    >>> peak, round(decay, 3)
    (1.0, 0.01)
    >>> tap_features(a[:30])
    (1.0, nan, nan)
    """
    array = _axes(a, "v_tt")
    energy = _energy_of_axes(array)  # shared by the peak and the response
    peak = float(np.sqrt(np.max(energy)))
    y = _tap_response(array, energy)
    if y is None:
        return peak, math.nan, math.nan
    return peak, tap_centroid(y, fs), tap_decay(y, fs)


# --- the scan -----------------------------------------------------------------------------------------

class _Unavailable(TexplorerError):
    """An input of a feature group is missing or fails its check; the message names it."""


def _trace(scan: Scan, name: str) -> Trace:
    trace = scan.get(name)
    if trace is None:
        raise _Unavailable(f"{name} is missing")
    return trace


def _meta_value(scan: Scan, name: str, meaning: str) -> float:
    value = float(getattr(scan.meta, name))
    if math.isnan(value):
        raise _Unavailable(f"meta.{name} ({meaning}) is unknown")
    return value


def _density(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    return (density(_meta_value(scan, "mass_g", "mass"), _meta_value(scan, "volume_cm3", "volume")),)


def _metal(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    return (metal(_trace(scan, "m").data),)


def _magnet(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    dB = _trace(scan, "dB").data
    return magnet_mean(dB), magnet_peak(dB)


def _reflectance(prepared: PreparedScan) -> tuple[float, ...]:
    """``reflect_static`` from the IR samples before the slide start, even if the slide window fails
    (docs/features.md#other; an IR record ending before the start gives the mean of all its samples), and
    ``reflect_mean``."""
    scan = prepared.scan
    _trace(scan, "v_ts")
    r_ts = _trace(scan, "r_ts")
    try:
        start = prepared.slide_start("v_ts")
    except QualityError as problem:
        raise _Unavailable(f"v_ts/r_ts: {problem}") from None
    if start is None:
        raise _Unavailable(f"v_ts/r_ts: {NO_SLIDE}")
    static = reflect_static(r_ts.data, min(start, r_ts.n))
    try:
        window = prepared.slide_window("v_ts", ir_samples=r_ts.n)
    except QualityError as problem:
        warnings.warn(f"scan {scan.scan_id}: v_ts/r_ts: {problem}; other.reflect_mean set to NaN",
                      MissingDataWarning, stacklevel=3)
        return static, math.nan
    return static, reflect_mean(r_ts.data[window.ir])


def _cooling(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    t_cool = _trace(scan, "t_cool")
    return (cooling_rate(t_cool.data, _meta_value(scan, "t_amb", "ambient temperature"), t_cool.fs),)


def _slide(prepared: PreparedScan, name: str) -> np.ndarray:
    _trace(prepared.scan, name)
    try:
        return prepared.slide_signal(name)
    except QualityError as problem:
        raise _Unavailable(f"{name}: {problem}") from None


def _tool_vibration(prepared: PreparedScan) -> tuple[float, ...]:
    v = _slide(prepared, "v_ts")
    return vib_std(v), vib_kurtosis(v), vib_energy(v)


def _finger_vibration(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    v_f = _slide(prepared, "v_fs")
    return vib_energy(v_f), vib_centroid(v_f, scan["v_fs"].fs)


def _tap(prepared: PreparedScan) -> tuple[float, ...]:
    scan = prepared.scan
    v_tt = _trace(scan, "v_tt")
    try:
        a = prepared.band_limited("v_tt")
    except ValueError as problem:
        raise _Unavailable(f"v_tt: {problem}") from None
    return tap_features(a, v_tt.fs)


_GROUPS: tuple[tuple[tuple[str, ...], Callable[[PreparedScan], tuple[float, ...]]], ...] = (
    (("other.density",), _density),
    (("other.metal",), _metal),
    (("other.magnet_mean", "other.magnet_peak"), _magnet),
    (("other.reflect_static", "other.reflect_mean"), _reflectance),
    (("other.cooling_rate",), _cooling),
    (("other.vib_std", "other.vib_kurtosis", "other.vib_energy"), _tool_vibration),
    (("other.finger_vib_energy", "other.finger_vib_centroid"), _finger_vibration),
    (("other.tap_peak", "other.tap_centroid", "other.tap_decay"), _tap),
)
"""Feature groups sharing their inputs: (names, function of the scan returning their values)."""


def compute(scan: Scan, *, prepared: PreparedScan | None = None) -> dict[str, float]:
    """The 15 other features of a scan, in :data:`NAMES` order (docs/features.md#other).

    Inputs are preprocessed as in docs/features.md#preprocessing: ``v`` and ``v_f`` (band limit, slide window, DFT321),
    the IR of ``r_ts`` at the slide start and in the slide window of ``v_ts``, the band-limited ``v_tt``. The
    features of a group whose input is missing (a channel, ``meta.mass_g``, ``meta.volume_cm3`` or
    ``meta.t_amb``) or fails its slide check are NaN, with one :class:`MissingDataWarning` naming the
    input and the features it made NaN.

    Parameters
    ----------
    scan : Scan
        The scan.
    prepared : PreparedScan, optional
        The scan prepared once for every feature family (:func:`features.extract`); the values are the same.

    Returns
    -------
    dict of str to float
        The 15 features of :data:`NAMES`, NaN where a value is undefined.

    Warns
    -----
    MissingDataWarning
        Naming the missing input and the features it made NaN.

    Examples
    --------
    A scan holding only the static channels, the cooling curve and the mass and volume: those features are
    defined, the ten of the IR reflectance, the slides and the tap are NaN.

    >>> import math
    >>> import warnings
    >>> import numpy as np
    >>> from features import other
    >>> from scanner.scan import Scan, ScanMeta, Trace
    >>> meta = ScanMeta(label="C6S1M1P2X1", operator="op", sample_id="granite-01", scan_index=1, session_id="s-1",
    ...                 started="2026-11-21T09:00:00+00:00", t_amb=22.0, mass_g=27.0, volume_cm3=10.0)
    >>> t = np.arange(200) / 20.0
    >>> traces = {"m": Trace(np.array([1.0, 1.0, -1.0]), 3000.0, "-"),
    ...           "dB": Trace(np.array([0.5, 1.5, -0.5, 2.5]), 80.0, "uT"),
    ...           "t_cool": Trace(22.0 + 8.0 * np.exp(-0.3 * t), 20.0, "degC")}
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     values = other.compute(Scan(meta, traces))
    >>> values["other.density"], values["other.metal"], values["other.magnet_mean"], values["other.magnet_peak"]
    (2.7, 1.0, 1.0, 2.5)
    >>> round(values["other.cooling_rate"], 9), sum(math.isnan(value) for value in values.values()), len(caught)
    (0.3, 10, 4)
    """
    prepared = prepared if prepared is not None else PreparedScan(scan)
    values: dict[str, float] = {}
    for names, group in _GROUPS:
        try:
            values.update(zip(names, (float(x) for x in group(prepared)), strict=True))
        except _Unavailable as problem:
            values.update(dict.fromkeys(names, math.nan))
            warnings.warn(f"scan {scan.scan_id}: {problem}; {', '.join(names)} set to NaN",
                          MissingDataWarning, stacklevel=2)
    return {name: values[name] for name in NAMES}
