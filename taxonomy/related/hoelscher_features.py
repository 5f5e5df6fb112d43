"""The BioTac feature sets Hoelscher et al. 2015 compare (:mod:`taxonomy.related.hoelscher`): ``xu3`` (after Xu
et al.), ``chu`` (after Chu et al.), ``mean23``, ``dallaire`` (after Dallaire et al.), ``chitta`` (after Chitta
et al.) and ``temperature`` (docs/features.md#related). The array-level pieces (band-pass, spectral moments,
time constants, threshold crossings, ...) are public so they can be checked on signals with known answers."""

from __future__ import annotations

import math
import warnings
from functools import lru_cache

import numpy as np
from scipy import ndimage, optimize, signal

from scanner.scan import Recording
from taxonomy.related.inputs import RelatedFeatureError, _check_roles, _log, _ratio, _signal, _trace, one_axis

XU_ELECTRODE = 17
"""Column of electrode E18 (Xu et al.'s compliance electrode; 0-based)."""

XU_BAND_HZ = (20.0, 500.0)


@lru_cache(maxsize=16)
def _bandpass(fs: float, low: float, high: float) -> np.ndarray:
    return signal.butter(4, [low, high], btype="bandpass", fs=fs, output="sos")


def band_pass(x: np.ndarray, fs: float, low: float, high: float) -> np.ndarray:
    """Zero-phase 4th-order Butterworth band-pass (``sosfiltfilt``), the filter type of the preprocessing
    (docs/features.md).

    Parameters
    ----------
    x : array of shape (n,)
        A signal of more than 27 samples (the filter's pad length).
    fs : float
        Sample rate in Hz, above ``2 high``.
    low, high : float
        Band edges in Hz.

    Returns
    -------
    ndarray of shape (n,)
        The filtered signal.

    Raises
    ------
    RelatedFeatureError
        If ``high`` is not below Nyquist or ``x`` is too short.

    Examples
    --------
    A 100 Hz tone passes 20-500 Hz, a 2 Hz drift does not:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import band_pass
    >>> t = np.arange(3000) / 3000.0
    >>> tone = np.sin(2 * np.pi * 100.0 * t)
    >>> filtered = band_pass(tone + np.sin(2 * np.pi * 2.0 * t), 3000.0, 20.0, 500.0)
    >>> bool(np.max(np.abs(filtered - tone)[1000:2000]) < 1e-6)
    True
    """
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
    """Electrode 18 (column 17), or the mean electrode when there are fewer than 18 columns.

    Parameters
    ----------
    electrodes : array of shape (n, k)
        Electrode values, one column per electrode.

    Returns
    -------
    ndarray of shape (n,)
        Column 17, or the mean over the columns.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import compliance_electrode
    >>> electrodes = np.tile(np.arange(19.0), (2, 1))
    >>> compliance_electrode(electrodes).tolist(), compliance_electrode(electrodes[:, :3]).tolist()
    ([17.0, 17.0], [1.0, 1.0])
    """
    values = np.asarray(electrodes, dtype=np.float64)
    return values[:, XU_ELECTRODE] if values.shape[1] > XU_ELECTRODE else values.mean(axis=1)


def xu3(recording: Recording) -> dict[str, float]:
    """Xu et al.'s three physical features as Hoelscher et al. 2015 adapt them (section III-B).

    ``ln(max - min)`` of electrode 18 (compliance; the joint angle is not measured), ``ln(var)`` of the
    vibration band-passed 20-500 Hz (texture) and ``max - min`` of the heat flow (thermal conductivity).
    A logarithm of 0 is NaN.

    Parameters
    ----------
    recording : Recording
        A recording with the roles ``electrodes``, ``vibration`` and ``heat_flow``.

    Returns
    -------
    dict of str to float
        ``xu3.compliance``, ``xu3.texture``, ``xu3.thermal``.

    Raises
    ------
    RelatedFeatureError
        If a role is missing or the vibration cannot be band-passed (:func:`band_pass`).

    Examples
    --------
    Electrode 18 spans e, so the compliance is ``ln(e) = 1``; a 100 Hz tone of amplitude ``sqrt(2) e``
    has variance e^2, so the texture is 2; the heat flow spans 3:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import xu3
    >>> electrodes = np.zeros((4, 19))
    >>> electrodes[:, 17] = [0.0, 1.0, np.e, 2.0]
    >>> vibration = np.sqrt(2) * np.e * np.sin(2 * np.pi * 100.0 * np.arange(3000) / 3000.0)
    >>> recording = Recording("r1", {"e": Trace(electrodes, 100.0, "-"), "pac": Trace(vibration, 3000.0, "-"),
    ...                              "tac": Trace(np.array([0.0, 3.0, 1.0, 2.0]), 100.0, "-")},
    ...                       {"electrodes": "e", "vibration": "pac", "heat_flow": "tac"})
    >>> {name: round(value, 2) for name, value in xu3(recording).items()}
    {'xu3.compliance': 1.0, 'xu3.texture': 2.0, 'xu3.thermal': 3.0}
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

    Parameters
    ----------
    x : array of shape (n,)
        A signal (PDC).
    fs : float
        Sample rate in Hz.
    seconds : float
        Window length in s.

    Returns
    -------
    ndarray of shape (n,)
        The smoothed signal.

    Examples
    --------
    At 10 Hz the 0.1 s window has 3 samples, ``[1/4, 1/2, 1/4]``:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import hanning_smooth
    >>> hanning_smooth(np.array([0.0, 0.0, 4.0, 0.0, 0.0]), 10.0).tolist()
    [0.0, 1.0, 2.0, 1.0, 0.0]
    >>> hanning_smooth(np.full(5, 3.0), 10.0).tolist()
    [3.0, 3.0, 3.0, 3.0, 3.0]
    """
    values = _signal(x, "pressure_dc")
    half = max(1, int(round(seconds * fs / 2)))
    window = signal.windows.hann(2 * half + 3, sym=True)[1:-1]  # without the zero end points
    return ndimage.convolve1d(values, window / window.sum(), mode="nearest")


def pressure_statistics(pdc: np.ndarray, fs: float) -> np.ndarray:
    """Maximum, mean and greatest change of the Hanning-smoothed PDC (Chu et al.).

    Interpretation: the greatest change is the steepest slope, ``max |diff(smoothed)| * fs`` (per second).

    Parameters
    ----------
    pdc : array of shape (n,)
        The static pressure PDC.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    ndarray of shape (3,)
        Maximum, mean, greatest change per second (NaN for one sample), of the smoothed PDC.

    Examples
    --------
    An impulse of 4 at 10 Hz smooths to ``[0, 1, 2, 1, 0]`` (:func:`hanning_smooth`): maximum 2, mean
    0.8, steepest step 1 per 0.1 s:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import pressure_statistics
    >>> np.round(pressure_statistics(np.array([0.0, 0.0, 4.0, 0.0, 0.0]), 10.0), 6).tolist()
    [2.0, 0.8, 10.0]
    """
    smooth = hanning_smooth(pdc, fs)
    change = float(np.max(np.abs(np.diff(smooth)))) * fs if smooth.size > 1 else math.nan
    return np.array([float(np.max(smooth)), float(np.mean(smooth)), change])


def energy_spectral_density(x: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided energy spectral density of ``x`` minus its mean: frequencies (Hz) and energy per bin.

    ``E_k = w_k |X_k|^2 / (N fs)`` with ``X = rfft(x)`` and w_k = 2 except for the DC and (even N) Nyquist
    bins, so ``sum(E_k) = sum(x^2) / fs``, the signal's energy (Parseval).

    Parameters
    ----------
    x : array of shape (n,)
        A signal of at least 2 samples.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    frequency, energy : ndarray of shape (n // 2 + 1,)
        Bin frequencies ``k fs / n`` in Hz, and the energy of each bin.

    Examples
    --------
    A 10 Hz sine, 1 s at 100 Hz: all its energy ``sum(x^2) / fs = 50 / 100`` lies in the 10 Hz bin:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import energy_spectral_density
    >>> frequency, energy = energy_spectral_density(np.sin(2 * np.pi * 10.0 * np.arange(100) / 100.0), 100.0)
    >>> float(frequency[np.argmax(energy)]), round(float(energy.sum()), 6), round(float(energy.max()), 6)
    (10.0, 0.5, 0.5)
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

    Parameters
    ----------
    frequency, energy : array of shape (m,)
        Bin frequencies and their energies (:func:`energy_spectral_density`).

    Returns
    -------
    ndarray of shape (5,)
        Area, centroid, variance, skewness, kurtosis; ``[0, NaN, NaN, NaN, NaN]`` for no energy.

    Examples
    --------
    Equal energy at 1 and 3 Hz: centroid 2, variance 1, no skew, kurtosis 1:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import spectral_moments
    >>> spectral_moments(np.arange(5.0), np.array([0.0, 1.0, 0.0, 1.0, 0.0])).tolist()
    [2.0, 2.0, 1.0, 0.0, 1.0]
    >>> spectral_moments(np.arange(3.0), np.zeros(3)).tolist()
    [0.0, nan, nan, nan, nan]
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

    Parameters
    ----------
    x : array of shape (n,)
        A settling signal (temperature) of at least 4 samples.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    float
        tau in s, or NaN.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import time_constant
    >>> t = np.arange(200) / 100.0
    >>> round(time_constant(1.0 + 2.0 * np.exp(-t / 0.5), 100.0), 6), time_constant(np.full(5, 30.0), 100.0)
    (0.5, nan)
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

    Parameters
    ----------
    x : array of shape (n, k)
        Rows of k >= ``count`` values.
    count : int
        Number of components.

    Returns
    -------
    ndarray of shape (n, count)
        The scores of the mean-centred rows.

    Raises
    ------
    RelatedFeatureError
        If ``x`` is not 2-D or has fewer than ``count`` columns.

    Examples
    --------
    Three points on the line through (1, 2) lie at ``-sqrt(5)``, 0 and ``sqrt(5)`` along it, whichever
    way the points are listed:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import principal_components
    >>> points = np.array([[-1.0, -2.0], [0.0, 0.0], [1.0, 2.0]])
    >>> np.round(principal_components(points, 1), 6).tolist()
    [[-2.236068], [0.0], [2.236068]]
    >>> np.round(principal_components(-points, 1), 6).tolist()
    [[2.236068], [0.0], [-2.236068]]
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

    Parameters
    ----------
    electrodes : array of shape (n, k)
        n > ``degree`` rows of k >= 2 electrodes.
    degree : int
        Polynomial degree.

    Returns
    -------
    ndarray of shape (2 (degree + 1),)
        The PC1 fit's coefficients, then the PC2 fit's.

    Raises
    ------
    RelatedFeatureError
        If there are not more rows than ``degree`` or fewer than 2 columns.

    Examples
    --------
    One electrode ramps from 0 to 2 while the other stays at 0: PC1 is the centred ramp ``2 t - 1`` and
    PC2 is 0:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import electrode_polynomials
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> coefficients = electrode_polynomials(np.column_stack([2 * t, np.zeros(11)]))
    >>> coefficients.shape, bool(np.allclose(coefficients, [0, 0, 0, 0, 2, -1, 0, 0, 0, 0, 0, 0]))
    ((12,), True)
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

    Parameters
    ----------
    recording : Recording
        A recording with the roles ``pressure_dc``, ``vibration``, ``heat_flow``, ``temperature`` and
        ``electrodes`` (at least 6 rows, 2 columns).

    Returns
    -------
    dict of str to float
        ``chu.<name>`` for each name of :data:`CHU_NAMES`.

    Raises
    ------
    RelatedFeatureError
        If a role is missing or its data are too short.

    Examples
    --------
    A PDC impulse (:func:`pressure_statistics`), 10 and 20 Hz tones of energy 0.5 each (centroid 15 Hz,
    variance ``5^2``, kurtosis 1), a heat flow of 2 for 1 s and a temperature settling with tau 0.25 s:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import chu
    >>> t = np.arange(100) / 100.0
    >>> recording = Recording("r1", {
    ...     "pdc": Trace(np.array([0.0, 0.0, 4.0, 0.0, 0.0]), 10.0, "-"),
    ...     "pac": Trace(np.sin(2 * np.pi * 10.0 * t) + np.sin(2 * np.pi * 20.0 * t), 100.0, "-"),
    ...     "tac": Trace(np.full(100, 2.0), 100.0, "-"), "tdc": Trace(1.0 + 2.0 * np.exp(-t / 0.25), 100.0, "-"),
    ...     "e": Trace(np.column_stack([2 * t, np.zeros(100)]), 100.0, "-")},
    ...     {"pressure_dc": "pdc", "vibration": "pac", "heat_flow": "tac", "temperature": "tdc", "electrodes": "e"})
    >>> values = chu(recording)
    >>> shown = ("pdc_max", "pdc_mean", "pdc_change", "esd_area", "esd_centroid", "esd_variance", "esd_kurtosis",
    ...          "tac_area", "tdc_tau")
    >>> len(values), [round(values[f"chu.{name}"], 6) for name in shown]
    (22, [2.0, 0.8, 10.0, 1.0, 15.0, 25.0, 1.0, 2.0, 0.25])
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

    Parameters
    ----------
    recording : Recording
        A recording with the roles ``pressure_dc``, ``vibration``, ``temperature``, ``heat_flow`` and
        ``electrodes``.

    Returns
    -------
    dict of str to float
        ``mean23.pressure_dc``, ``mean23.vibration``, ``mean23.temperature``, ``mean23.heat_flow``, then
        ``mean23.electrode_01``, ... one per electrode.

    Raises
    ------
    RelatedFeatureError
        If a role is missing.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import mean23
    >>> recording = Recording("r1", {
    ...     "pdc": Trace(np.full(4, 2.0), 10.0, "-"), "pac": Trace(np.array([1.0, -1.0, 1.0, -1.0]), 100.0, "-"),
    ...     "tdc": Trace(np.full(4, 30.0), 10.0, "-"), "tac": Trace(np.full(4, 5.0), 10.0, "-"),
    ...     "e": Trace(np.tile(np.arange(1.0, 20.0), (4, 1)), 10.0, "-")},
    ...     {"pressure_dc": "pdc", "vibration": "pac", "heat_flow": "tac", "temperature": "tdc", "electrodes": "e"})
    >>> values = mean23(recording)
    >>> len(values), [values[f"mean23.{name}"] for name in ("pressure_dc", "vibration", "temperature",
    ...                                                     "heat_flow", "electrode_01", "electrode_19")]
    (23, [2.0, 0.0, 30.0, 5.0, 1.0, 19.0])
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
    """``mean((x - mean(x))^order)`` (population, unnormalised).

    Parameters
    ----------
    x : array of shape (n,)
        A signal.
    order : int
        The moment's order.

    Returns
    -------
    float
        The central moment, in the unit of ``x`` to the power ``order``.

    Examples
    --------
    ``[0, 0, 0, 4]`` has mean 1 and deviations ``[-1, -1, -1, 3]``:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import central_moment
    >>> x = np.array([0.0, 0.0, 0.0, 4.0])
    >>> central_moment(x, 2), central_moment(x, 3)
    (3.0, 6.0)
    """
    return float(np.mean((x - np.mean(x)) ** order))


def threshold_crossings(x: np.ndarray, count: int = THRESHOLDS) -> int:
    """Side changes between consecutive samples summed over ``count`` evenly spaced thresholds (Dallaire).

    Thresholds ``t_j = min + (max - min) j / (count + 1)``, j = 1..count; a side change at sample i is
    ``(x[i] >= t_j) != (x[i + 1] >= t_j)``. A monotonic ramp crosses each threshold once.

    Parameters
    ----------
    x : array of shape (n,)
        A signal.
    count : int
        Number of thresholds.

    Returns
    -------
    int
        The side changes over all thresholds.

    Examples
    --------
    A ramp crosses each of the 20 thresholds once; ``[0, 1, 0, 1]`` crosses each three times:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import threshold_crossings
    >>> threshold_crossings(np.linspace(0.0, 1.0, 50)), threshold_crossings(np.array([0.0, 1.0, 0.0, 1.0]))
    (20, 60)
    """
    values = _signal(x, "vibration")
    low, high = float(values.min()), float(values.max())
    thresholds = low + (high - low) * np.arange(1, count + 1) / (count + 1)
    above = values[None, :] >= thresholds[:, None]
    return int(np.count_nonzero(above[:, 1:] != above[:, :-1]))


def upper_spectrum_sum(x: np.ndarray) -> float:
    """Sum of ``|rfft(x)|`` over the bins k >= N / 4 (the upper half of the amplitude spectrum).

    Parameters
    ----------
    x : array of shape (n,)
        A signal (its mean is not removed; the DC bin lies below N / 4 anyway).

    Returns
    -------
    float
        The sum of the magnitudes, in the unit of ``x``.

    Examples
    --------
    ``[1, -1, 1, -1]`` is all at Nyquist (magnitude 4), a constant all at DC:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import upper_spectrum_sum
    >>> upper_spectrum_sum(np.array([1.0, -1.0, 1.0, -1.0])), upper_spectrum_sum(np.ones(4))
    (4.0, 0.0)
    """
    values = _signal(x, "vibration")
    magnitude = np.abs(np.fft.rfft(values))
    k = np.arange(magnitude.size)
    return float(np.sum(magnitude[4 * k >= values.size]))


def dallaire(recording: Recording) -> dict[str, float]:
    """Dallaire et al.'s vibration features as Hoelscher et al. 2015 compute them on the BioTac PAC signal.

    Variance, skewness ``m3 / m2^1.5``, Pearson kurtosis ``m4 / m2^2``, unnormalised fifth central moment
    ``m5``, total variation ``sum |diff(x)|``, threshold side changes (:func:`threshold_crossings`) and the
    upper-half amplitude spectrum sum (:func:`upper_spectrum_sum`).

    Parameters
    ----------
    recording : Recording
        A recording with the role ``vibration``, at least 2 samples.

    Returns
    -------
    dict of str to float
        ``dallaire.variance``, ``skewness``, ``kurtosis``, ``moment5``, ``total_variation``, ``crossings``
        and ``upper_spectrum``.

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``vibration``.

    Examples
    --------
    Eight samples alternating between 1 and -1: variance 1, symmetric, kurtosis 1, seven steps of 2,
    each crossing all 20 thresholds, and the magnitude 8 at Nyquist:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import dallaire
    >>> recording = Recording("r1", {"pac": Trace(np.array([1.0, -1.0] * 4), 100.0, "-")}, {"vibration": "pac"})
    >>> {name: round(value, 6) for name, value in dallaire(recording).items()}
    {'dallaire.variance': 1.0, 'dallaire.skewness': 0.0, 'dallaire.kurtosis': 1.0, 'dallaire.moment5': 0.0,
     'dallaire.total_variation': 14.0, 'dallaire.crossings': 140.0, 'dallaire.upper_spectrum': 8.0}
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

    Parameters
    ----------
    electrodes : array of shape (n, k)
        n >= 2 rows of k electrodes.
    fs : float
        Sample rate in Hz, above ``2 cutoff``.
    cutoff : float
        Cut-off frequency in Hz.

    Returns
    -------
    ndarray of shape (n,)
        The norm of the filtered electrodes at each sample.

    Raises
    ------
    RelatedFeatureError
        If ``electrodes`` is not (n >= 2, k) or ``cutoff`` is not below Nyquist.

    Examples
    --------
    Two electrodes step from 0 to 1 at 0.5 s: 0 before the step, about ``sqrt(2)`` (times the filter's
    first output, 0.985) at it, decaying with the time constant ``1 / (2 pi 5 Hz) = 32 ms``:

    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import electrode_norm
    >>> electrodes = np.zeros((1000, 2))
    >>> electrodes[500:] = 1.0
    >>> norm = electrode_norm(electrodes, 1000.0)
    >>> float(norm[:500].max()), round(float(norm[500]), 3), bool(norm[-1] < 1e-3)
    (0.0, 1.392, True)
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
    """Mean and variance of the Euclidean norm of the filtered electrodes (:func:`electrode_norm`).

    Parameters
    ----------
    recording : Recording
        A recording with the role ``electrodes``.

    Returns
    -------
    dict of str to float
        ``chitta.mean`` and ``chitta.variance`` (population) of the norm.

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``electrodes`` or :func:`electrode_norm` cannot filter them.

    Examples
    --------
    The step of :func:`electrode_norm`: about ``sqrt(2)`` over 32 ms of the 1 s, a mean of about
    ``1.41 * 0.032 = 0.045``:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import chitta
    >>> electrodes = np.zeros((1000, 2))
    >>> electrodes[500:] = 1.0
    >>> values = chitta(Recording("r1", {"e": Trace(electrodes, 1000.0, "-")}, {"electrodes": "e"}))
    >>> {name: round(value, 3) for name, value in values.items()}
    {'chitta.mean': 0.045, 'chitta.variance': 0.03}
    """
    _check_roles(recording, "chitta", ("electrodes",))
    trace = _trace(recording, "electrodes")
    norm = electrode_norm(trace.data, trace.fs)
    return {"chitta.mean": float(np.mean(norm)), "chitta.variance": float(np.var(norm))}


# -- Hoelscher et al. 2015: temperature ---------------------------------------------------------------------------

SETTLE_SECONDS = 6.0
"""Hoelscher et al. 2015 read the temperature features after 6 s of contact (Fig. 5a)."""


def settled(x: np.ndarray, fs: float, seconds: float = SETTLE_SECONDS) -> np.ndarray:
    """The samples after the first ``seconds``; interpretation for shorter recordings: the second half.

    Parameters
    ----------
    x : array of shape (n,)
        A signal of at least 2 samples.
    fs : float
        Sample rate in Hz.
    seconds : float
        The settling time skipped.

    Returns
    -------
    ndarray
        ``x[min(round(seconds fs), n // 2):]``: a recording shorter than twice ``seconds`` keeps only its
        second half.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import settled
    >>> settled(np.arange(20.0), 1.0).tolist()
    [6.0, 7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0, 14.0, 15.0, 16.0, 17.0, 18.0, 19.0]
    >>> settled(np.arange(4.0), 1.0).tolist()
    [2.0, 3.0]
    """
    values = _signal(x, "temperature", 2)
    start = min(int(round(seconds * fs)), values.size // 2)
    return values[start:]


def change_after_peak(x: np.ndarray) -> float:
    """``x[p] - min(x[p:])`` with p the (first) maximum: the heat-flow change after its initial peak.

    Parameters
    ----------
    x : array of shape (n,)
        The heat flow.

    Returns
    -------
    float
        The fall from the peak to the lowest later value (0 if the peak is the last sample).

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.hoelscher_features import change_after_peak
    >>> change_after_peak(np.array([0.0, 5.0, 3.0, 4.0, 2.0, 3.0]))
    3.0
    """
    values = _signal(x, "heat_flow")
    peak = int(np.argmax(values))
    return float(values[peak] - np.min(values[peak:]))


def temperature(recording: Recording) -> dict[str, float]:
    """The temperature features of Hoelscher et al. 2015: means of heat flow and temperature after the first
    6 s, and the heat-flow change after its peak.

    Parameters
    ----------
    recording : Recording
        A recording with the roles ``heat_flow`` and ``temperature``.

    Returns
    -------
    dict of str to float
        ``temperature.tac_mean``, ``temperature.tdc_mean`` (:func:`settled`) and
        ``temperature.tac_change`` (:func:`change_after_peak`).

    Raises
    ------
    RelatedFeatureError
        If a role is missing.

    Examples
    --------
    20 s at 1 Hz: the heat flow peaks at 5 and settles at 2, the temperature is 25 after 6 s:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.hoelscher_features import temperature
    >>> tac = np.array([0.0, 5.0, 4.0, 3.0] + [2.0] * 16)
    >>> tdc = np.array([20.0, 21.0, 22.0, 23.0, 24.0, 25.0] + [25.0] * 14)
    >>> recording = Recording("r1", {"tac": Trace(tac, 1.0, "-"), "tdc": Trace(tdc, 1.0, "degC")},
    ...                       {"heat_flow": "tac", "temperature": "tdc"})
    >>> temperature(recording)
    {'temperature.tac_mean': 2.0, 'temperature.tdc_mean': 25.0, 'temperature.tac_change': 3.0}
    """
    _check_roles(recording, "temperature", ("heat_flow", "temperature"))
    tac, tdc = _trace(recording, "heat_flow"), _trace(recording, "temperature")
    return {"temperature.tac_mean": float(np.mean(settled(tac.data, tac.fs))),
            "temperature.tdc_mean": float(np.mean(settled(tdc.data, tdc.fs))),
            "temperature.tac_change": change_after_peak(tac.data)}
