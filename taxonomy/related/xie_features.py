"""``xie11`` (Xie et al. 2019): 11 features of the area, variance and sum sequences of a pressure array, the
sequences standardised per column across the training samples (:class:`XieFeatures`); the features of
:mod:`taxonomy.related.xie` (docs/features.md#related)."""

from __future__ import annotations

import numpy as np
import pywt
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.preprocessing import StandardScaler
from sklearn.utils.validation import check_is_fitted, validate_data

from scanner.scan import Recording
from taxonomy.related.inputs import RelatedFeatureError, _signal, _trace

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

    Raises
    ------
    RelatedFeatureError
        If ``frames`` is neither (n, h, w) nor (n, k), or empty.

    Examples
    --------
    Two 2 x 2 images: three taxels pressed, then one:

    >>> import numpy as np
    >>> from taxonomy.related.xie_features import xie_sequences
    >>> s_a, s_v, s_s = xie_sequences(np.array([[[0.0, 1.0], [2.0, 3.0]], [[0.0, 0.0], [0.0, 4.0]]]))
    >>> s_a.tolist(), s_v.tolist(), s_s.tolist()
    ([3.0, 1.0], [1.25, 3.0], [6.0, 4.0])
    """
    values = np.asarray(frames, dtype=np.float64)
    if values.ndim not in (2, 3) or values.shape[0] == 0 or values[0].size == 0:
        raise RelatedFeatureError("xie11 needs images (n, h, w) or electrode rows (n, k), "
                                  f"got shape {values.shape}")
    flat = values.reshape(values.shape[0], -1)
    return (np.count_nonzero(flat > 0, axis=1).astype(np.float64), np.var(flat, axis=1), np.sum(flat, axis=1))


def wavelet_l1(x: np.ndarray, wavelet: str = XIE_WAVELET, level: int = XIE_LEVEL) -> np.ndarray:
    """L1 norms of cA4, cD4, cD3, cD2, cD1 of ``pywt.wavedec(x, "db3", level=4, mode="symmetric")``.

    Parameters
    ----------
    x : array of shape (n,)
        The force-sum sequence S_s, at least 2 samples (80 or more for 4 levels of db3 without boundary
        effects).
    wavelet : str
        PyWavelets wavelet name.
    level : int
        Decomposition level.

    Returns
    -------
    ndarray of shape (level + 1,)
        L1 norms of the approximation, then of the details from the coarsest level to the finest.

    Examples
    --------
    db3 has vanishing moments, so a constant has no details; each of the nine level-4 approximation
    coefficients of 80 ones is ``sqrt(2)^4 = 4``:

    >>> import numpy as np
    >>> from taxonomy.related.xie_features import wavelet_l1
    >>> np.round(wavelet_l1(np.ones(80)), 6).tolist()
    [36.0, 0.0, 0.0, 0.0, 0.0]
    """
    values = _signal(x, "S_s", 2)
    return np.array([float(np.sum(np.abs(c))) for c in pywt.wavedec(values, wavelet, level=level,
                                                                      mode="symmetric")])


def cid(x: np.ndarray) -> float:
    """Complexity-invariant distance of a sequence, Xie et al. eq. (2): ``sqrt(sum(diff(x)^2))``.

    Parameters
    ----------
    x : array of shape (n,)
        A sequence of at least 1 sample.

    Returns
    -------
    float
        The length of the sequence's steps; 0 for a constant.

    Examples
    --------
    Steps of 3, 0 and 4:

    >>> import numpy as np
    >>> from taxonomy.related.xie_features import cid
    >>> cid(np.array([0.0, 3.0, 3.0, 7.0]))
    5.0
    """
    return float(np.sqrt(np.sum(np.diff(_signal(x, "S_s")) ** 2)))


def xie11_from_sequences(s_a: np.ndarray, s_v: np.ndarray, s_s: np.ndarray) -> np.ndarray:
    """The 11 features of Xie et al. (section 3.4, Table 3) from the three sequences.

    Means of S_a, S_v, S_s; L1 norms of the db3 level-4 wavelet coefficients cA4, cD4, cD3, cD2, cD1 of S_s;
    absolute energy ``sum(S_s^2)`` (eq. 1); CID (eq. 2); ``std(S_s)`` (population).

    Parameters
    ----------
    s_a, s_v, s_s : array of shape (n,)
        The area, variance and force-sum sequences (:func:`xie_sequences`); S_s of at least 2 samples.

    Returns
    -------
    ndarray of shape (11,)
        The features in the order of :data:`XIE_NAMES`.

    Examples
    --------
    A constant force sum of 2 over 80 images: energy ``80 * 2^2 = 320``, no change (CID and std 0), and
    nine approximation coefficients of ``2 * 4`` (:func:`wavelet_l1`):

    >>> import numpy as np
    >>> from taxonomy.related.xie_features import XIE_NAMES, xie11_from_sequences
    >>> values = xie11_from_sequences(np.ones(80), np.zeros(80), np.full(80, 2.0))
    >>> dict(zip(XIE_NAMES, np.round(values, 6).tolist()))
    {'mean_sa': 1.0, 'mean_sv': 0.0, 'mean_ss': 2.0, 'l1_ca4': 72.0, 'l1_cd4': 0.0, 'l1_cd3': 0.0,
     'l1_cd2': 0.0, 'l1_cd1': 0.0, 'abs_energy': 320.0, 'cid': 0.0, 'std_ss': 0.0}
    """
    s_s = _signal(s_s, "S_s", 2)
    return np.array([np.mean(_signal(s_a, "S_a")), np.mean(_signal(s_v, "S_v")), np.mean(s_s),
                     *wavelet_l1(s_s), float(np.sum(s_s**2)), cid(s_s), float(np.std(s_s))])


def xie_sequence_vector(recording: Recording, seconds: float = XIE_SECONDS) -> np.ndarray:
    """The 3n-vector ``[S_a, S_v, S_s]`` of the first ``seconds`` of ``taxels`` (or ``electrodes``).

    Xie et al. standardise these vectors per column across the training samples before the features
    (:class:`XieFeatures`), so every recording must give the same n: its first 1 s.

    Parameters
    ----------
    recording : Recording
        A recording with the role ``taxels`` (n, h, w) or ``electrodes`` (n, k).
    seconds : float
        The length read from the start, ``round(seconds fs)`` frames (at least 2).

    Returns
    -------
    ndarray of shape (3 n,)
        S_a, S_v and S_s of those n frames (:func:`xie_sequences`), one after the other.

    Raises
    ------
    RelatedFeatureError
        If the recording has neither role or fewer frames than ``seconds`` takes.

    Examples
    --------
    1.5 s of a 2 x 2 array at 100 Hz, every taxel at 1: the first 100 frames have area 4, variance 0 and
    sum 4:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from taxonomy.related.xie_features import xie_sequence_vector
    >>> recording = Recording("r1", {"array": Trace(np.ones((150, 2, 2)), 100.0, "-")}, {"taxels": "array"})
    >>> vector = xie_sequence_vector(recording)
    >>> vector.shape, vector[[0, 100, 200]].tolist()
    ((300,), [4.0, 0.0, 4.0])
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
    """The 11 features of one (standardised) 3n-vector ``[S_a, S_v, S_s]``.

    Parameters
    ----------
    vector : array of shape (3 n,)
        ``[S_a, S_v, S_s]`` (:func:`xie_sequence_vector`), n >= 2, standardised or not.

    Returns
    -------
    ndarray of shape (11,)
        :func:`xie11_from_sequences` of its three thirds, in the order of :data:`XIE_NAMES`.

    Raises
    ------
    RelatedFeatureError
        If ``vector`` is not 1-D of 3n >= 6 entries.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.xie_features import xie11_from_vector
    >>> vector = np.concatenate([np.ones(80), np.zeros(80), np.full(80, 2.0)])
    >>> np.round(xie11_from_vector(vector), 6).tolist()
    [1.0, 0.0, 2.0, 72.0, 0.0, 0.0, 0.0, 0.0, 320.0, 0.0, 0.0]
    """
    values = np.asarray(vector, dtype=np.float64)
    if values.ndim != 1 or values.size % 3 or values.size < 6:
        raise RelatedFeatureError(f"a Xie sequence vector has 3n >= 6 entries, got shape {values.shape}")
    return xie11_from_sequences(*np.split(values, 3))


def xie11(recording: Recording, scaler: StandardScaler | None = None) -> dict[str, float]:
    """The 11 Xie features of a recording's ``taxels`` (or ``electrodes`` as a 1-D array).

    ``scaler`` is a ``StandardScaler`` fitted on the training samples' sequence vectors (columns ordered
    [S_a, S_v, S_s]), as the paper standardises them; without it the raw sequences are used.

    Parameters
    ----------
    recording : Recording
        A recording with the role ``taxels`` or ``electrodes``, at least 1 s long.
    scaler : StandardScaler, optional
        Fitted on the training samples' sequence vectors (:func:`xie_sequence_vector`).

    Returns
    -------
    dict of str to float
        ``xie11.<name>`` for each name of :data:`XIE_NAMES`.

    Examples
    --------
    Two recordings press all four taxels of a 2 x 2 array, with 1 and with 3 each. Raw, the light one has
    area 4 and force sum 4 in each of its 100 frames; standardised over the two, its (constant) area
    column becomes 0 and its sums ``(4 - 8) / 4 = -1``, of energy 100:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from sklearn.preprocessing import StandardScaler
    >>> from taxonomy.related.xie_features import xie11, xie_sequence_vector
    >>> light, firm = (Recording(name, {"array": Trace(np.full((100, 2, 2), force), 100.0, "-")},
    ...                          {"taxels": "array"}) for name, force in (("light", 1.0), ("firm", 3.0)))
    >>> shown = ("xie11.mean_sa", "xie11.mean_ss", "xie11.abs_energy")
    >>> raw = xie11(light)
    >>> [round(raw[name], 6) for name in shown]
    [4.0, 4.0, 1600.0]
    >>> scaler = StandardScaler().fit([xie_sequence_vector(light), xie_sequence_vector(firm)])
    >>> standard = xie11(light, scaler)
    >>> [round(standard[name], 6) for name in shown]
    [0.0, -1.0, 100.0]
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
        """Learn the standardisation of the sequence vectors ``X`` (one row per recording) on these rows.

        Parameters
        ----------
        X : array of shape (m, 3 n)
            Sequence vectors ``[S_a, S_v, S_s]`` (:func:`xie_sequence_vector`) of m training recordings.
        y : array of shape (m,), optional
            Ignored; there for the scikit-learn interface.

        Returns
        -------
        XieFeatures
            This transformer, with the per-column ``StandardScaler`` as ``scaler_``.

        Examples
        --------
        Two recordings of 100 frames: the column means lie between the rows, a constant column keeps scale 1:

        >>> import numpy as np
        >>> from taxonomy.related.xie_features import XieFeatures
        >>> X = np.array([np.concatenate([np.full(100, 1.0), np.zeros(100), np.full(100, 2.0)]),
        ...               np.concatenate([np.full(100, 3.0), np.zeros(100), np.full(100, 4.0)])])
        >>> model = XieFeatures().fit(X)
        >>> model.scaler_.mean_[[0, 100, 200]].tolist(), model.scaler_.scale_[[0, 100, 200]].tolist()
        ([2.0, 0.0, 3.0], [1.0, 1.0, 1.0])
        """
        X = validate_data(self, X)
        self.scaler_ = StandardScaler().fit(X)
        return self

    def transform(self, X: np.ndarray) -> np.ndarray:
        """The 11 Xie features of every row of ``X``, standardised as fitted.

        Parameters
        ----------
        X : array of shape (m, 3 n)
            Sequence vectors of the same n as the fitted ones.

        Returns
        -------
        ndarray of shape (m, 11)
            The features of each row, in the order of :data:`XIE_NAMES`.

        Examples
        --------
        Standardised over the two rows, every column that varies is -1 in the first row and +1 in the
        second; shown are ``mean_sa``, ``mean_ss``, ``abs_energy``, ``cid`` and ``std_ss``:

        >>> import numpy as np
        >>> from taxonomy.related.xie_features import XieFeatures
        >>> X = np.array([np.concatenate([np.full(100, 1.0), np.zeros(100), np.full(100, 2.0)]),
        ...               np.concatenate([np.full(100, 3.0), np.zeros(100), np.full(100, 4.0)])])
        >>> features = XieFeatures().fit(X).transform(X)
        >>> np.round(features[:, [0, 2, 8, 9, 10]], 6).tolist()
        [[-1.0, -1.0, 100.0, 0.0, 0.0], [1.0, 1.0, 100.0, 0.0, 0.0]]
        """
        check_is_fitted(self, "scaler_")
        standard = self.scaler_.transform(validate_data(self, X, reset=False))
        return np.array([xie11_from_vector(row) for row in standard]).reshape(len(standard), len(XIE_NAMES))
