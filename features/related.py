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
    """A vibration as one signal: 1-D as it is, several axes combined by DFT321 (docs/features.md#preprocessing).

    Parameters
    ----------
    x : array of shape (n,) or (n, axes)
        A vibration of one or several axes.

    Returns
    -------
    ndarray of shape (n,)
        ``x`` for one axis; else :func:`scanner.preprocess.dft321` of the axes, which keeps their energy
        ``sum(x^2)`` over all axes.

    Examples
    --------
    >>> import numpy as np
    >>> from features.related import one_axis
    >>> one_axis(np.array([1.0, -2.0, 3.0])).tolist()
    [1.0, -2.0, 3.0]

    Three axes of energy 9, 16 and 0 become one signal of energy 25:

    >>> combined = one_axis(np.array([[3.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    >>> combined.shape, round(float(np.sum(combined**2)), 6)
    ((4,), 25.0)
    """
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

    Parameters
    ----------
    scan : Scan
        A scan with the tool slide ``v_ts`` and the friction slide ``f_frn``, ``f_frt``.

    Returns
    -------
    dict of str to float
        ``fishel3.traction``, ``fishel3.roughness`` (log10 of g^2) and ``fishel3.fineness`` (Hz).

    Raises
    ------
    RelatedFeatureError
        If the scan lacks ``v_ts``, ``f_frn`` or ``f_frt``.

    Examples
    --------
    A tool slide of 0.4 g at 250 Hz after 0.5 s of rest, and a friction force of 1 N under a normal force
    of 2 N: the traction is 1 / 2 and the roughness ``log10(0.4^2 / 2) = log10(0.08) = -1.097``. The
    fineness lies above the tone: the band-pass spreads a little of the slide onset over all the bins.

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> f_frt = np.where(np.arange(9000) >= 600, 1.0, 0.0)
    >>> scan = Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g"), "f_frn": Trace(np.full(9000, 2.0), 3000.0, "N"),
    ...                    "f_frt": Trace(f_frt, 3000.0, "N")})
    >>> from features.related import fishel3
    >>> values = fishel3(scan)
    >>> values["fishel3.traction"], round(values["fishel3.roughness"], 3), 250 < values["fishel3.fineness"] < 300
    (0.5, -1.097, True)
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

    Raises
    ------
    RelatedFeatureError
        If ``frames`` is neither (n, h, w) nor (n, k), or empty.

    Examples
    --------
    Two 2 x 2 images: three taxels pressed, then one:

    >>> import numpy as np
    >>> from features.related import xie_sequences
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
    >>> from features.related import wavelet_l1
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
    >>> from features.related import cid
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
    >>> from features.related import XIE_NAMES, xie11_from_sequences
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
    >>> from features.related import xie_sequence_vector
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
    >>> from features.related import xie11_from_vector
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
    >>> from features.related import xie11, xie_sequence_vector
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
        >>> from features.related import XieFeatures
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
        >>> from features.related import XieFeatures
        >>> X = np.array([np.concatenate([np.full(100, 1.0), np.zeros(100), np.full(100, 2.0)]),
        ...               np.concatenate([np.full(100, 3.0), np.zeros(100), np.full(100, 4.0)])])
        >>> features = XieFeatures().fit(X).transform(X)
        >>> np.round(features[:, [0, 2, 8, 9, 10]], 6).tolist()
        [[-1.0, -1.0, 100.0, 0.0, 0.0], [1.0, 1.0, 100.0, 0.0, 0.0]]
        """
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
    >>> from features.related import band_means
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
    >>> from features.related import huang7
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


# -- chathuranga4 and its baselines (Chathuranga et al. 2015) ----------------------------------------

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
    >>> from features.related import covariance_frobenius
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
    >>> from features.related import chathuranga4
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
    >>> from features.related import principal_frequency
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
    >>> from features.related import spatial_period
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
    >>> from features.related import chathuranga_period
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
    >>> from features.related import pearson_kurtosis
    >>> t = np.arange(100) / 100.0
    >>> round(pearson_kurtosis(np.sin(2 * np.pi * t)), 6), pearson_kurtosis(np.array([1.0, -1.0, 1.0, -1.0]))
    (1.5, 1.0)
    >>> pearson_kurtosis(np.full(4, 2.0))
    nan
    """
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
    >>> from features.related import friction_features
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
    >>> from features.related import chathuranga_net
    >>> xyz = np.array([[1.0, 0.0, 2.0], [-1.0, 0.0, 2.0], [1.0, 0.0, 2.0], [-1.0, 0.0, 2.0]])
    >>> values = chathuranga_net(Recording("r1", {"force": Trace(xyz, 100.0, "N")}, {"force_xyz": "force"}))
    >>> {name: float(value) for name, value in values.items()}
    {'chathuranga_net.friction': 0.5, 'chathuranga_net.var_x': 1.0, 'chathuranga_net.kurt_x': 1.0}
    """
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
    >>> from features.related import band_pass
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
    >>> from features.related import compliance_electrode
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
    >>> from features.related import xu3
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
    >>> from features.related import hanning_smooth
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
    >>> from features.related import pressure_statistics
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
    >>> from features.related import energy_spectral_density
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
    >>> from features.related import spectral_moments
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
    >>> from features.related import time_constant
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
    >>> from features.related import principal_components
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
    >>> from features.related import electrode_polynomials
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
    >>> from features.related import chu
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
    >>> from features.related import mean23
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
    >>> from features.related import central_moment
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
    >>> from features.related import threshold_crossings
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
    >>> from features.related import upper_spectrum_sum
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
    >>> from features.related import dallaire
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
    >>> from features.related import electrode_norm
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
    >>> from features.related import chitta
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
    >>> from features.related import settled
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
    >>> from features.related import change_after_peak
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
    >>> from features.related import temperature
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


# -- registry and scans ------------------------------------------------------------------------------

@dataclass(frozen=True)
class RelatedSet:
    """A related-work feature set: what it reads and the function computing it from a recording."""

    name: str
    roles: tuple[str, ...]
    source: str
    function: Callable[[Recording], dict[str, float]]

    def applies_to(self, recording: Recording) -> bool:
        """Whether the recording has every role this set reads (``xie11``: taxels or electrodes).

        Parameters
        ----------
        recording : Recording
            Any recording.

        Returns
        -------
        bool
            True if :attr:`function` can compute the set from the recording's roles.

        Examples
        --------
        >>> import numpy as np
        >>> from scanner import Recording, Trace
        >>> from features.related import FEATURE_SETS
        >>> channels = {"e": Trace(np.zeros((4, 19)), 100.0, "-"), "pac": Trace(np.zeros(4), 100.0, "-")}
        >>> recording = Recording("r1", channels, {"electrodes": "e", "vibration": "pac"})
        >>> [name for name, found in FEATURE_SETS.items() if found.applies_to(recording)]
        ['xie11', 'huang7', 'dallaire', 'chitta']
        """
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
        The set's features, ``<set>.<feature>``.

    Raises
    ------
    RelatedFeatureError
        The recording lacks a role the set reads, an unknown set name, or data the set cannot use.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from features.related import RelatedFeatureError, compute
    >>> recording = Recording("r1", {"pac": Trace(np.array([1.0, -1.0] * 4), 100.0, "-")}, {"vibration": "pac"})
    >>> compute("dallaire", recording)["dallaire.total_variation"]
    14.0
    >>> try:
    ...     compute("chitta", recording)
    ... except RelatedFeatureError as problem:
    ...     print(problem)
    chitta needs the role(s) electrodes; recording 'r1' lacks electrodes
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

    Parameters
    ----------
    v_ts : Trace
        The tool-slide acceleration (n, 3) at 3000 Hz, in g.

    Returns
    -------
    Trace
        The 1-D signal at the rate and in the unit of ``v_ts``.

    Examples
    --------
    A slide starting at 0.5 s gives its 1 s window; a recording without a slide keeps all its 3 s:

    >>> import numpy as np
    >>> from scanner import Trace
    >>> from features.related import slide_vibration
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> slide_vibration(Trace(v_ts, 3000.0, "g")).n, slide_vibration(Trace(np.zeros((9000, 3)), 3000.0, "g")).n
    (3000, 9000)
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

    Parameters
    ----------
    scan : Scan
        Any scan.

    Returns
    -------
    Recording
        Named by the scan id, with the scan's channels, the roles found among them, label and groups.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> from features.related import scan_recording
    >>> recording = scan_recording(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
    >>> recording.name, sorted(recording.channels), dict(recording.roles), recording.role("vibration").n
    ('granite-01-001', ['v', 'v_ts'], {'vibration': 'v'}, 3000)
    >>> recording.label, dict(recording.group)
    ('C6S1M1P2X1', {'object': 'granite-01', 'trial': '001'})
    """
    channels = dict(scan.traces)
    if "v_ts" in channels:
        channels["v"] = slide_vibration(channels["v_ts"])
    roles = {role: channel for role, channel in SCAN_ROLES.items() if channel in channels}
    group = {"object": scan.meta.sample_id, "trial": f"{scan.meta.scan_index:03d}"}
    return Recording(scan.scan_id, channels, roles, scan.meta.label, group)
