"""``chathuranga4`` (Chathuranga et al. 2015): the Frobenius norm of the 3x3 covariance and the three means of a
3-axis signal, with its baselines ``chathuranga_period`` (spatial period V / f_p) and ``chathuranga_net``
(friction coefficient, x variance, x kurtosis); the features of :mod:`taxonomy.related.chathuranga`
(docs/features.md#related)."""

from __future__ import annotations

import math

import numpy as np

from scanner.scan import Recording
from taxonomy.related.inputs import RelatedFeatureError, _check_roles, _ratio, _signal, _trace


def _xyz(x: np.ndarray) -> np.ndarray:
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 2 or values.shape[1] != 3 or values.shape[0] < 2:
        raise RelatedFeatureError(f"force_xyz must have shape (n >= 2, 3), got {values.shape}")
    return values


def covariance_frobenius(xyz: np.ndarray) -> float:
    """Frobenius norm ``sqrt(trace(M^T M))`` of the 3x3 population covariance M (ddof 0).

    Chathuranga et al. eq. (2)-(4).

    Parameters
    ----------
    xyz : array of shape (n, 3)
        A 3-axis signal of at least 2 samples.

    Returns
    -------
    float
        The norm, in the unit of ``xyz`` squared.

    Examples
    --------
    x and y alternate together between 1 and -1, z is constant: M has four entries 1, the rest 0, so the
    norm is ``sqrt(4) = 2``:

    >>> import numpy as np
    >>> from taxonomy.related.chathuranga_features import covariance_frobenius
    >>> covariance_frobenius(np.array([[1.0, 1.0, 5.0], [-1.0, -1.0, 5.0], [1.0, 1.0, 5.0], [-1.0, -1.0, 5.0]]))
    2.0
    """
    return float(np.linalg.norm(np.cov(_xyz(xyz).T, ddof=0), "fro"))


def chathuranga4(recording: Recording) -> dict[str, float]:
    """Frobenius norm of the covariance of ``force_xyz`` and its three means (Chathuranga et al. eq. 4-5).

    Parameters
    ----------
    recording : Recording
        A recording with the role ``force_xyz`` (n >= 2, 3).

    Returns
    -------
    dict of str to float
        ``chathuranga4.frobenius`` (:func:`covariance_frobenius`), ``chathuranga4.mean_x``, ``mean_y``,
        ``mean_z``.

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``force_xyz``.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.chathuranga_features import chathuranga4
    >>> xyz = np.array([[1.0, 1.0, 5.0], [-1.0, -1.0, 5.0], [1.0, 1.0, 5.0], [-1.0, -1.0, 5.0]])
    >>> chathuranga4(Recording("r1", {"force": Trace(xyz, 100.0, "N")}, {"force_xyz": "force"}))
    {'chathuranga4.frobenius': 2.0, 'chathuranga4.mean_x': 0.0, 'chathuranga4.mean_y': 0.0,
     'chathuranga4.mean_z': 5.0}
    """
    _check_roles(recording, "chathuranga4", ("force_xyz",))
    xyz = _xyz(_trace(recording, "force_xyz").data)
    mean = xyz.mean(axis=0)
    return {"chathuranga4.frobenius": covariance_frobenius(xyz), "chathuranga4.mean_x": float(mean[0]),
            "chathuranga4.mean_y": float(mean[1]), "chathuranga4.mean_z": float(mean[2])}


def principal_frequency(x: np.ndarray, fs: float) -> float:
    """Frequency of the tallest FFT peak of ``x`` minus its mean, DC excluded (first on ties); NaN if flat.

    Parameters
    ----------
    x : array of shape (n,)
        A signal of at least 2 samples.
    fs : float
        Sample rate in Hz.

    Returns
    -------
    float
        The peak's bin frequency ``k fs / n`` in Hz; NaN if ``x`` is constant.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.chathuranga_features import principal_frequency
    >>> t = np.arange(100) / 100.0
    >>> principal_frequency(3.0 + np.sin(2 * np.pi * 5.0 * t), 100.0), principal_frequency(np.ones(10), 100.0)
    (5.0, nan)
    """
    values = _signal(x, "x", 2)
    magnitude = np.abs(np.fft.rfft(values - values.mean()))[1:]
    if magnitude.size == 0 or not np.any(magnitude > 0):
        return math.nan
    return float((int(np.argmax(magnitude)) + 1) * fs / values.size)


def spatial_period(x: np.ndarray, fs: float, velocity: float) -> float:
    """Spatial period ``lambda = V / f_p`` (Chathuranga eq. 6; Muhammad et al.), in the unit of V times s.

    Interpretation: the mean is removed before the FFT, otherwise the DC bin is the tallest "peak".

    Parameters
    ----------
    x : array of shape (n,)
        A force signal of at least 2 samples.
    fs : float
        Sample rate in Hz.
    velocity : float
        Sliding velocity V (mm/s for a period in mm).

    Returns
    -------
    float
        ``velocity / principal_frequency(x, fs)``; NaN if ``x`` is constant.

    Examples
    --------
    Ridges felt 5 times a second at 20 mm/s lie 4 mm apart:

    >>> import numpy as np
    >>> from taxonomy.related.chathuranga_features import spatial_period
    >>> t = np.arange(100) / 100.0
    >>> spatial_period(np.sin(2 * np.pi * 5.0 * t), 100.0, 20.0)
    4.0
    """
    return _ratio(velocity, principal_frequency(x, fs))


def chathuranga_period(recording: Recording) -> dict[str, float]:
    """The spatial-period baseline's feature: ``V / f_p`` of the motion direction x of ``force_xyz`` (mm).

    The palpation velocity V (mm/s) is ``recording.meta["velocity_mm_s"]``.

    Parameters
    ----------
    recording : Recording
        A recording with the role ``force_xyz`` and ``meta["velocity_mm_s"]``.

    Returns
    -------
    dict of str to float
        ``chathuranga_period.lambda`` (:func:`spatial_period`), in mm.

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``force_xyz`` or no velocity.

    Examples
    --------
    A 5 Hz force in x at 20 mm/s: a spatial period of 4 mm:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.chathuranga_features import chathuranga_period
    >>> t = np.arange(100) / 100.0
    >>> xyz = np.column_stack([np.sin(2 * np.pi * 5.0 * t), np.zeros(100), np.ones(100)])
    >>> recording = Recording("r1", {"force": Trace(xyz, 100.0, "N")}, {"force_xyz": "force"},
    ...                       meta={"velocity_mm_s": 20.0})
    >>> chathuranga_period(recording)
    {'chathuranga_period.lambda': 4.0}
    """
    _check_roles(recording, "chathuranga_period", ("force_xyz",))
    velocity = recording.meta.get("velocity_mm_s")
    if velocity is None:
        raise RelatedFeatureError(f"chathuranga_period needs the palpation velocity meta['velocity_mm_s'] "
                                  f"of recording {recording.name!r}")
    trace = _trace(recording, "force_xyz")
    return {"chathuranga_period.lambda": spatial_period(_xyz(trace.data)[:, 0], trace.fs, float(velocity))}


def pearson_kurtosis(x: np.ndarray) -> float:
    """``mu4 / sigma^4`` (3 for Gaussian noise, 1.5 for a sine); NaN for a constant signal.

    Parameters
    ----------
    x : array of shape (n,)
        A signal.

    Returns
    -------
    float
        The kurtosis (not the excess over 3).

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.chathuranga_features import pearson_kurtosis
    >>> t = np.arange(100) / 100.0
    >>> round(pearson_kurtosis(np.sin(2 * np.pi * t)), 6), pearson_kurtosis(np.array([1.0, -1.0, 1.0, -1.0]))
    (1.5, 1.0)
    >>> pearson_kurtosis(np.full(4, 2.0)), pearson_kurtosis(np.full(100, 0.2))
    (nan, nan)
    """
    if np.min(x) == np.max(x):  # constant: the rounding of its mean must not pass for a signal (0.2)
        return math.nan
    centred = x - np.mean(x)
    variance = float(np.mean(centred**2))
    return _ratio(float(np.mean(centred**4)), variance**2)


def friction_features(xyz: np.ndarray) -> np.ndarray:
    """The neural-net baseline's inputs (Chathuranga III-D2, after de Boissieu et al.).

    Friction coefficient ``mean(sqrt(x^2 + y^2) / z)`` over the samples with z != 0 (eq. 7; interpretation:
    the per-sample ratio is averaged), the population variance of x and the Pearson kurtosis of x.

    Parameters
    ----------
    xyz : array of shape (n, 3)
        Forces in the motion direction x, across it (y) and normal (z), at least 2 samples.

    Returns
    -------
    ndarray of shape (3,)
        Friction coefficient (NaN if z is 0 throughout), variance of x, kurtosis of x.

    Examples
    --------
    A tangential force of +-1 N under 2 N: friction coefficient 1 / 2, variance 1, kurtosis 1:

    >>> import numpy as np
    >>> from taxonomy.related.chathuranga_features import friction_features
    >>> friction_features(np.array([[1.0, 0.0, 2.0], [-1.0, 0.0, 2.0], [1.0, 0.0, 2.0], [-1.0, 0.0, 2.0]])).tolist()
    [0.5, 1.0, 1.0]
    """
    values = _xyz(xyz)
    x, y, z = values.T
    loaded = z != 0
    mu = float(np.mean(np.hypot(x[loaded], y[loaded]) / z[loaded])) if np.any(loaded) else math.nan
    return np.array([mu, float(np.var(x)), pearson_kurtosis(x)])


def chathuranga_net(recording: Recording) -> dict[str, float]:
    """Friction coefficient, x variance and x kurtosis of ``force_xyz`` (the neural-net baseline).

    Parameters
    ----------
    recording : Recording
        A recording with the role ``force_xyz``.

    Returns
    -------
    dict of str to float
        ``chathuranga_net.friction``, ``chathuranga_net.var_x``, ``chathuranga_net.kurt_x``
        (:func:`friction_features`).

    Raises
    ------
    RelatedFeatureError
        If the recording has no ``force_xyz``.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.chathuranga_features import chathuranga_net
    >>> xyz = np.array([[1.0, 0.0, 2.0], [-1.0, 0.0, 2.0], [1.0, 0.0, 2.0], [-1.0, 0.0, 2.0]])
    >>> values = chathuranga_net(Recording("r1", {"force": Trace(xyz, 100.0, "N")}, {"force_xyz": "force"}))
    >>> {name: float(value) for name, value in values.items()}
    {'chathuranga_net.friction': 0.5, 'chathuranga_net.var_x': 1.0, 'chathuranga_net.kurt_x': 1.0}
    """
    _check_roles(recording, "chathuranga_net", ("force_xyz",))
    mu, var_x, kurt_x = friction_features(_trace(recording, "force_xyz").data)
    return {"chathuranga_net.friction": mu, "chathuranga_net.var_x": var_x, "chathuranga_net.kurt_x": kurt_x}
