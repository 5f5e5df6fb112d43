"""Feature families of the time-series field since 2020, beside the paper's, on every 1-D signal.

Three kinds, all opt-in (the paper's 193 features stay the default; ``docs/modern-features.md``):

- ``catch22``: the 22 canonical time-series characteristics of Lubba et al. (2019), computed by
  ``pycatch22`` (the authors' C implementation).
- ``scattering``: the time-averaged 1-D wavelet scattering transform of Andén and Mallat (2014), orders 0,
  1 and 2, computed by ``kymatio``; each coefficient of orders 1 and 2 is the log of its mean over the
  instance.
- ``signal``: the signal itself, cut by its length rule. These columns are the input of the *fitted*
  random-kernel transforms MiniRocket (Dempster et al. 2021) and MultiRocket (Tan et al. 2022), which
  live inside the cross-validated pipeline (:mod:`features.random_kernels`), fitted on the training folds
  only, never here.

Every signal gets instances by one :class:`LengthRule` per signal, chosen per role (the module's
:data:`SCAN_SIGNALS` and :data:`ROLE_RULES`): resampled to a fixed rate and cut into ``windows`` windows of
``length`` samples spread evenly over it, or resampled as a whole to ``length`` samples. A window
shorter than ``length`` (a short recording) is zero-padded at its end. The catch22 and scattering values of
a signal are the mean of their values over its windows; the random-kernel features are averaged the same
way. So a long recording costs at most ``windows x length`` samples per signal, whatever its duration.

Scan signals: ``v_ts`` the tool-slide vibration in its 1 s slide window (band limit, DFT321; paper
section III), ``v_tt`` the tool tap from 10 ms before its peak, ``a_ts`` the tool-slide sound in the same
window, ``f_frt`` the tangential force of the friction slide. Roles of imported recordings: ``audio``,
``vibration`` (band-limited, DFT321, as :mod:`features.recordings` makes it), ``force_xyz`` (the
tangential force ``|(x, y)|``), and the slow 1-D roles ``pressure_dc``, ``temperature`` and ``heat_flow``
(several columns averaged).

The libraries are the optional extra ``texplorer[modern]``; a family whose library is missing is not
registered, and asking for it names the extra (:func:`require`).
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

from features import recordings, signals
from features.prepared import PreparedScan
from features.registry import REGISTRY, Family, RoleFamily
from scanner.lazy import library
from scanner.preprocess import BAND_HZ, QualityError, dft321
from taxonomy.errors import ParameterError

signal = library("scipy.signal")
pycatch22 = library("pycatch22")  # the optional extra texplorer[modern], loaded at first use
# The 1-D frontend alone: kymatio.numpy also imports the 3-D frontend, which needs scipy.special.sph_harm
# (removed in SciPy 1.15).
kymatio_1d = library("kymatio.scattering1d.frontend.numpy_frontend")

LIBRARIES = {"catch22": "pycatch22", "scattering": "kymatio"}
"""The library each family needs (the random-kernel transforms need sktime: features.random_kernels)."""

SCATTERING_SIZES = {9: (62, 237), 8: (54, 179), 6: (38, 87)}
"""Coefficients of orders 1 and 2 of kymatio's ``Scattering1D`` with Q = 8, by J: the column names are
known without building the filter bank (tests check them against kymatio)."""

EXTRA = "texplorer[modern]"
"""The optional extra that installs the libraries of these families."""

CATCH22_NAMES = (
    "DN_HistogramMode_5", "DN_HistogramMode_10", "DN_OutlierInclude_p_001_mdrmd",
    "DN_OutlierInclude_n_001_mdrmd", "CO_FirstCrossing_acf_1e_pointOfCrossing", "CO_FirstMin_ac",
    "SP_Summaries_fft_area_5_1", "SP_Summaries_fft_wq_50", "FC_LocalSimple_mean3_stde",
    "FC_LocalSimple_mean1_taurat", "MD_pNN_pnn40", "SB_BinaryStats_mean_longstretch1",
    "SB_BinaryStats_diff_longstretch0", "SB_MotifThree_quantile_hh", "CO_HistogramAMI_even_5bin_ami2",
    "CO_trev_1_num", "IN_AutoMutualInfoStats_40_gaussian_fmmi", "SB_TransitionMatrix_quantile_3_ac_sumdiagcov",
    "PD_PeriodicityWang_th0_01", "CO_Embed2_Dist_tau_d_expfit_meandiff",
    "SC_FluctAnal_2_rsrangefit_50_1_logi_prop_r1", "SC_FluctAnal_2_dfa_50_1_2_logi_prop_r1",
)
"""The 22 features of catch22 (Lubba et al. 2019, Table 1), as ``pycatch22.catch22_all`` names and orders them."""

SCATTERING_Q = 8
"""Wavelets per octave of the first order (Andén and Mallat 2014 use Q = 8 for audio)."""

SCATTERING_LOG_FLOOR = 1e-12
"""Added before the log so a silent instance has a finite value."""


@dataclass(frozen=True)
class LengthRule:
    """How a signal of any duration becomes instances of ``length`` samples.

    ``rate``: resample to this rate (Hz) first (None keeps the signal's rate); then ``windows`` windows of
    ``length`` samples spread evenly from its first to its last sample. ``whole``: instead, resample the
    whole signal to ``length`` samples (a slow signal of any duration: a force, a temperature).
    """

    length: int
    windows: int = 1
    rate: float | None = None
    whole: bool = False

    def __post_init__(self) -> None:
        if self.length < 16 or self.windows < 1 or (self.rate is not None and self.rate <= 0):
            raise ParameterError(f"a length rule needs length >= 16, windows >= 1 and a positive rate, "
                                 f"got {self}")

    @property
    def samples(self) -> int:
        """Samples of all instances: ``windows x length``."""
        return self.windows * self.length

    def describe(self) -> str:
        """``8 windows of 2048 samples at 44100 Hz``, ``resampled to 1024 samples``.

        Returns
        -------
        str
            The rule in words, for people.

        Examples
        --------
        >>> from features.modern import LengthRule
        >>> LengthRule(2048, windows=8, rate=44100.0).describe()
        '8 windows of 2048 samples at 44100 Hz'
        >>> LengthRule(3000).describe(), LengthRule(1024, whole=True).describe()
        ('1 window of 3000 samples', 'resampled to 1024 samples')
        """
        if self.whole:
            return f"resampled to {self.length} samples"
        at = "" if self.rate is None else f" at {self.rate:g} Hz"
        return f"{self.windows} window{'s' if self.windows > 1 else ''} of {self.length} samples{at}"


def resample(x: np.ndarray, fs: float, rate: float) -> np.ndarray:
    """``x`` at ``rate`` Hz: polyphase resampling with scipy's anti-aliasing filter (the ratio as a fraction
    with a denominator of at most 1000).

    Parameters
    ----------
    x : numpy.ndarray
        The signal, samples along the first axis.
    fs : float
        Its sample rate in Hz.
    rate : float
        The rate wanted, in Hz.

    Returns
    -------
    numpy.ndarray
        ``x`` as float64 at ``rate`` (``x`` itself, converted, where the rates are equal).

    Examples
    --------
    One second of a 50 Hz tone at 1000 Hz, halved to 500 Hz: 500 samples, still a 50 Hz tone:

    >>> import numpy as np
    >>> from features.modern import resample
    >>> tone = np.sin(2 * np.pi * 50 * np.arange(1000) / 1000)
    >>> y = resample(tone, 1000.0, 500.0)
    >>> y.size, float(np.argmax(np.abs(np.fft.rfft(y))) * 500 / y.size)
    (500, 50.0)
    """
    ratio = Fraction(rate / fs).limit_denominator(1000)
    if ratio == 1:
        return np.asarray(x, dtype=np.float64)
    return signal.resample_poly(np.asarray(x, dtype=np.float64), ratio.numerator, ratio.denominator)


def instances(x: np.ndarray, fs: float, rule: LengthRule) -> np.ndarray:
    """The instances of a 1-D signal by ``rule``, shape ``(windows, length)`` (see :class:`LengthRule`).

    Parameters
    ----------
    x : numpy.ndarray
        The signal, 1-D.
    fs : float
        Its sample rate in Hz (used where ``rule.rate`` resamples it).
    rule : LengthRule
        How it is cut or resampled.

    Returns
    -------
    numpy.ndarray
        float64 of shape ``(rule.windows, rule.length)``: the windows in time order, zero-padded at their end
        where the signal is shorter than ``rule.length`` (every window is then the same).

    Raises
    ------
    ParameterError
        If ``x`` is not 1-D or holds fewer than 2 samples.

    Examples
    --------
    Three windows of 16 samples spread evenly over 100 samples start at samples 0, 42 and 84:

    >>> import numpy as np
    >>> from features.modern import LengthRule, instances
    >>> windows = instances(np.arange(100.0), 1000.0, LengthRule(16, windows=3))
    >>> windows.shape, windows[:, 0].tolist()
    ((3, 16), [0.0, 42.0, 84.0])

    A signal of 10 samples is zero-padded to one instance of 16:

    >>> instances(np.ones(10), 1000.0, LengthRule(16)).tolist()
    [[1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1 or x.size < 2:
        raise ParameterError(f"a signal needs at least 2 samples in one column, got shape {x.shape}")
    if rule.whole:
        return signal.resample(x, rule.length)[None, :]
    if rule.rate is not None:
        x = resample(x, fs, rule.rate)
    if x.size <= rule.length:
        return np.pad(x, (0, rule.length - x.size))[None, :].repeat(rule.windows, axis=0)
    starts = np.round(np.linspace(0, x.size - rule.length, rule.windows)).astype(np.int64)
    return np.stack([x[s:s + rule.length] for s in starts])


# -- the transforms ---------------------------------------------------------------------------------

def catch22(windows: np.ndarray) -> np.ndarray:
    """catch22 of every instance, averaged over the instances (22 values, :data:`CATCH22_NAMES` order).

    Parameters
    ----------
    windows : numpy.ndarray
        The instances, shape ``(instances, length)`` (:func:`instances`).

    Returns
    -------
    numpy.ndarray
        The 22 mean values, float64.

    Raises
    ------
    ParameterError
        If ``pycatch22`` is not installed (:func:`require`).

    Examples
    --------
    A sine of period 20 samples: its periodicity (Wang et al.) is 20 samples, its autocorrelation's first
    minimum half of that (only where the extra ``texplorer[modern]`` is installed):

    >>> import numpy as np
    >>> from features.modern import CATCH22_NAMES, available, catch22
    >>> tone = np.sin(2 * np.pi * np.arange(200) / 20)
    >>> values = dict(zip(CATCH22_NAMES, catch22(np.stack([tone, tone])))) if available("catch22") else None
    >>> values is None or (values["PD_PeriodicityWang_th0_01"], values["CO_FirstMin_ac"]) == (20.0, 10.0)
    True
    """
    library = require("catch22")
    values = [library.catch22_all(row.tolist())["values"] for row in windows]
    return np.mean(np.asarray(values, dtype=np.float64), axis=0)


def scattering_octaves(length: int) -> int:
    """J, the octaves of the scattering's averaging scale 2^J: the largest with 2^J <= length / 4, at most 9
    (a quarter of the instance leaves room for the filters' support at the edges); below 1024 samples an
    eighth (512 samples: J = 6), as kymatio's filters at J = 7 no longer fit 512 samples without border
    effects (it warns).

    Parameters
    ----------
    length : int
        Samples of an instance.

    Returns
    -------
    int
        J, from 1 to 9.

    Examples
    --------
    >>> from features.modern import scattering_octaves
    >>> [scattering_octaves(n) for n in (512, 1023, 1024, 2048, 3000, 8192)]
    [6, 6, 8, 9, 9, 9]
    """
    return max(1, min(9, int(math.floor(math.log2(length / (4 if length >= 1024 else 8))))))


@lru_cache(maxsize=8)
def scattering_transform(length: int) -> object:
    """The ``Scattering1D`` of kymatio for instances of ``length`` samples (J by :func:`scattering_octaves`,
    Q = :data:`SCATTERING_Q`, orders 0 to 2), built once per process.

    Parameters
    ----------
    length : int
        Samples of an instance.

    Returns
    -------
    kymatio.scattering1d.frontend.numpy_frontend.ScatteringNumPy1D
        The transform, the same object for the same ``length``.

    Raises
    ------
    ParameterError
        If ``kymatio`` is not installed (:func:`require`).

    Examples
    --------
    Where the extra ``texplorer[modern]`` is installed, instances of 512 samples get J = 6:

    >>> from features.modern import available, scattering_transform
    >>> transform = scattering_transform(512) if available("scattering") else None
    >>> transform is None or (transform.J, transform is scattering_transform(512)) == (6, True)
    True
    """
    require("scattering")
    return kymatio_1d.ScatteringNumPy1D(J=scattering_octaves(length), shape=length, Q=SCATTERING_Q)


def scattering(windows: np.ndarray) -> np.ndarray:
    """Every scattering coefficient's mean over time, averaged over the instances; orders 1 and 2 (moduli,
    positive) as ``log(mean + 1e-12)``, as Andén and Mallat (2014, section 2.3) take their log. Order 0 is
    the low-passed signal itself, signed, and stays a mean.

    Parameters
    ----------
    windows : numpy.ndarray
        The instances, shape ``(instances, length)`` (:func:`instances`).

    Returns
    -------
    numpy.ndarray
        One value per coefficient, in the order of :func:`scattering_names`.

    Raises
    ------
    ParameterError
        If ``kymatio`` is not installed (:func:`require`).

    Examples
    --------
    A silent signal: order 0 is 0, every coefficient of orders 1 and 2 the log floor, ``log(1e-12)`` (only
    where the extra ``texplorer[modern]`` is installed):

    >>> import numpy as np
    >>> from features.modern import available, scattering, scattering_names
    >>> values = scattering(np.zeros((2, 512))) if available("scattering") else None
    >>> values is None or (values.size == len(scattering_names(512)) == 126 and values[0] == 0.0
    ...                    and bool(np.allclose(values[1:], np.log(1e-12))))
    True
    """
    transform = scattering_transform(windows.shape[1])
    coefficients = transform(np.ascontiguousarray(windows)).mean(axis=-1)  # (instances, coefficients)
    modulus = _orders(windows.shape[1]) > 0
    coefficients[:, modulus] = np.log(coefficients[:, modulus] + SCATTERING_LOG_FLOOR)
    return coefficients.mean(axis=0)


@lru_cache(maxsize=8)
def _orders(length: int) -> np.ndarray:
    return np.asarray(scattering_transform(length).meta()["order"])


def scattering_names(length: int) -> tuple[str, ...]:
    """``s0``, ``s1_000``, ..., ``s2_000``, ...: the coefficients of :func:`scattering` in kymatio's order
    (order 0, then 1, then 2; :data:`SCATTERING_SIZES`).

    Parameters
    ----------
    length : int
        Samples of an instance, at least 512 (J of 6, 8 or 9: :func:`scattering_octaves`).

    Returns
    -------
    tuple of str
        One name per coefficient; known without kymatio.

    Examples
    --------
    Instances of 512 samples (J = 6) have 1 + 38 + 87 coefficients:

    >>> from features.modern import scattering_names
    >>> names = scattering_names(512)
    >>> len(names), names[:3], names[38:40], names[-1]
    (126, ('s0', 's1_000', 's1_001'), ('s1_037', 's2_000'), 's2_086')
    """
    first, second = SCATTERING_SIZES[scattering_octaves(length)]
    return ("s0", *(f"s1_{k:03d}" for k in range(first)), *(f"s2_{k:03d}" for k in range(second)))


def available(kind: str) -> bool:
    """Whether the library of ``catch22`` or ``scattering`` is installed (``signal`` needs none), found
    without importing it.

    Parameters
    ----------
    kind : str
        ``"catch22"``, ``"scattering"`` or ``"signal"``.

    Returns
    -------
    bool
        True where the kind's library can be imported, or the kind needs none.

    Raises
    ------
    ParameterError
        For any other kind (a misspelt ``catch23`` is not taken for one that needs no library).

    Examples
    --------
    >>> import importlib.util
    >>> from features.modern import available
    >>> available("signal"), available("catch22") == (importlib.util.find_spec("pycatch22") is not None)
    (True, True)
    >>> available("catch23")
    Traceback (most recent call last):
    ...
    taxonomy.errors.ParameterError: unknown modern feature kind 'catch23' (known: signal, catch22, scattering)
    """
    if kind != "signal" and kind not in LIBRARIES:
        raise ParameterError(f"unknown modern feature kind {kind!r} (known: signal, {', '.join(LIBRARIES)})")
    return kind not in LIBRARIES or importlib.util.find_spec(LIBRARIES[kind]) is not None


def require(kind: str) -> object:
    """The library of ``kind``; an error naming the extra where it is missing.

    Parameters
    ----------
    kind : str
        ``"catch22"``, ``"scattering"`` or ``"signal"``.

    Returns
    -------
    module or None
        ``pycatch22``, kymatio's 1-D frontend, or None for a kind that needs no library (``signal``); each
        imported at its first use.

    Raises
    ------
    ParameterError
        If the kind's library is not installed, naming the extra ``texplorer[modern]``.

    Examples
    --------
    >>> from features.modern import require
    >>> from taxonomy.errors import ParameterError
    >>> require("signal") is None
    True
    >>> try:
    ...     found = require("catch22").__name__
    ... except ParameterError as error:  # without the extra
    ...     found = str(error)
    >>> found in ("pycatch22", "the catch22 features need texplorer[modern] (pip install 'texplorer[modern]')")
    True
    """
    if not available(kind):
        raise ParameterError(f"the {kind} features need {EXTRA} (pip install '{EXTRA}')")
    return {"catch22": pycatch22, "scattering": kymatio_1d}.get(kind)


# -- the scan's signals -----------------------------------------------------------------------------

TAP_LEAD_S = 0.010
"""The tap signal starts 10 ms before the peak of ``|v_tt|``."""


def slide_vibration(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """``v`` of the tool slide: band-limited, in the 1 s slide window, DFT321 (paper section III).

    Parameters
    ----------
    prepared : PreparedScan
        A scan with ``v_ts``.

    Returns
    -------
    signal : numpy.ndarray
        The 1 s window from the slide start, 1-D.
    fs : float
        Its sample rate in Hz.

    Raises
    ------
    QualityError
        If no slide is detected or less than 1 s follows its start.

    Examples
    --------
    At rest for 0.5 s, then a 200 Hz slide along x: the second from the slide start, a 200 Hz tone:

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.prepared import PreparedScan
    >>> meta = ScanMeta("C6S1M1P2X1", "op", "granite-01", 1, "s1", "2024-01-01T00:00:00")
    >>> from features.modern import slide_vibration
    >>> t = np.arange(6000) / 3000
    >>> v = np.zeros((6000, 3))
    >>> v[1500:, 0] = np.sin(2 * np.pi * 200 * t[1500:])
    >>> x, fs = slide_vibration(PreparedScan(Scan(meta, {"v_ts": Trace(v, 3000.0, "g")})))
    >>> x.size, fs, float(np.argmax(np.abs(np.fft.rfft(x))) * fs / x.size)
    (3000, 3000.0, 200.0)
    """
    return prepared.slide_signal("v_ts"), prepared.scan["v_ts"].fs


def tap_vibration(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tool tap ``v_tt``: band-limited, DFT321, from :data:`TAP_LEAD_S` before its largest sample.

    Parameters
    ----------
    prepared : PreparedScan
        A scan with ``v_tt``.

    Returns
    -------
    signal : numpy.ndarray
        The tap to the end of the recording, 1-D.
    fs : float
        Its sample rate in Hz.

    Examples
    --------
    A tap rings down from 0.3 s: the signal's largest sample is 10 ms after its start:

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.prepared import PreparedScan
    >>> meta = ScanMeta("C6S1M1P2X1", "op", "granite-01", 1, "s1", "2024-01-01T00:00:00")
    >>> from features.modern import tap_vibration
    >>> t = np.arange(2100) / 3000
    >>> v = np.zeros((3000, 3))
    >>> v[900:, 2] = np.exp(-t / 0.02) * np.sin(2 * np.pi * 300 * t)
    >>> x, fs = tap_vibration(PreparedScan(Scan(meta, {"v_tt": Trace(v, 3000.0, "g")})))
    >>> int(np.argmax(np.abs(x))) / fs, fs
    (0.01, 3000.0)
    """
    fs = prepared.scan["v_tt"].fs
    v = dft321(prepared.band_limited("v_tt"))
    start = max(0, int(np.argmax(np.abs(v))) - int(round(TAP_LEAD_S * fs)))
    return v[start:], fs


def slide_sound(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tool-slide sound ``a_ts`` in the slide window of ``v_ts``.

    Parameters
    ----------
    prepared : PreparedScan
        A scan with ``a_ts`` and ``v_ts``.

    Returns
    -------
    signal : numpy.ndarray
        The sound of the 1 s slide window, 1-D.
    fs : float
        Its sample rate in Hz.

    Raises
    ------
    QualityError
        If no slide is detected or less than 1 s of sound follows its start.

    Examples
    --------
    A slide from 0.5 s: the sound's second from 0.5 s on:

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.prepared import PreparedScan
    >>> meta = ScanMeta("C6S1M1P2X1", "op", "granite-01", 1, "s1", "2024-01-01T00:00:00")
    >>> from features.modern import slide_sound
    >>> v = np.zeros((6000, 3))
    >>> v[1500:, 0] = np.sin(2 * np.pi * 200 * np.arange(4500) / 3000)
    >>> a = np.sin(2 * np.pi * 440 * np.arange(88200) / 44100)
    >>> scan = Scan(meta, {"v_ts": Trace(v, 3000.0, "g"), "a_ts": Trace(a, 44100.0, "FS")})
    >>> x, fs = slide_sound(PreparedScan(scan))
    >>> x.size, fs, bool(np.array_equal(x, a[22050:66150]))
    (44100, 44100.0, True)
    """
    a = prepared.scan["a_ts"]
    window = prepared.slide_window("v_ts", audio_samples=a.n, audio_fs=a.fs)
    return a.data[window.audio], a.fs


def friction_force(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tangential force of the friction slide ``f_frt``, whole.

    Parameters
    ----------
    prepared : PreparedScan
        A scan with ``f_frt``.

    Returns
    -------
    signal : numpy.ndarray
        The recorded force in N, 1-D.
    fs : float
        Its sample rate in Hz.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> from features.prepared import PreparedScan
    >>> meta = ScanMeta("C6S1M1P2X1", "op", "granite-01", 1, "s1", "2024-01-01T00:00:00")
    >>> from features.modern import friction_force
    >>> force = np.linspace(0.0, 3.0, 600)
    >>> x, fs = friction_force(PreparedScan(Scan(meta, {"f_frt": Trace(force, 3000.0, "N")})))
    >>> x.size, fs, bool(np.array_equal(x, force))
    (600, 3000.0, True)
    """
    trace = prepared.scan["f_frt"]
    return trace.data, trace.fs


@dataclass(frozen=True)
class ScanSignal:
    """A 1-D signal of a scan: the channels it needs, how it is cut from the prepared scan, and its rule."""

    channels: tuple[str, ...]
    cut: Callable[[PreparedScan], tuple[np.ndarray, float]]
    rule: LengthRule


SCAN_SIGNALS: Mapping[str, ScanSignal] = {
    # 3000 samples: the whole 1 s window at 3 kHz, so the kernels see the paper's 10-1000 Hz band.
    "v_ts": ScanSignal(("v_ts",), slide_vibration, LengthRule(3000)),
    # 0.34 s: a tap rings down within ~0.1 s; the rest is the contact's quiet.
    "v_tt": ScanSignal(("v_tt",), tap_vibration, LengthRule(1024)),
    # 8 windows of 46 ms spread over the 1 s window: the full audio band at a bounded cost.
    "a_ts": ScanSignal(("a_ts", "v_ts"), slide_sound, LengthRule(2048, windows=8)),
    # A slow signal of any duration.
    "f_frt": ScanSignal(("f_frt",), friction_force, LengthRule(1024, whole=True)),
}
"""The scan's signals of the modern families and the length rule of each (see the module docstring)."""


def _scan_values(prepared: PreparedScan, kind: str, columns: Sequence[str],
                 transform: Callable[[np.ndarray], np.ndarray]) -> dict[str, float]:
    """``transform`` of the instances of every scan signal, NaN with a warning where a signal is missing."""
    values: dict[str, float] = {}
    for name, spec in SCAN_SIGNALS.items():
        prefix = f"{kind}.{name}."
        names = [c for c in columns if c.startswith(prefix)]
        missing = [c for c in spec.channels if c not in prepared.scan.traces]
        try:
            if missing:
                raise ParameterError(f"no {' or '.join(missing)}")
            x, fs = spec.cut(prepared)
            computed = transform(instances(x, fs, spec.rule))
        except (QualityError, ValueError) as problem:
            warnings.warn(f"scan {prepared.scan.scan_id}: {name}: {problem}; {kind}.{name} features are NaN",
                          stacklevel=2)
            computed = np.full(len(names), math.nan)
        values.update(zip(names, np.asarray(computed, dtype=np.float64).tolist(), strict=True))
    return values


def _flat(windows: np.ndarray) -> np.ndarray:
    return windows.reshape(-1)


def signal_columns(prefix: str, rule: LengthRule) -> tuple[str, ...]:
    """``<prefix>.00000`` ...: one column per sample of every instance, windows in time order.

    Parameters
    ----------
    prefix : str
        The columns' prefix, ``signal.<signal>``.
    rule : LengthRule
        The signal's rule: ``rule.samples`` columns.

    Returns
    -------
    tuple of str
        The column names.

    Examples
    --------
    >>> from features.modern import LengthRule, signal_columns
    >>> columns = signal_columns("signal.v_tt", LengthRule(16, windows=2))
    >>> len(columns), columns[:2], columns[-1]
    (32, ('signal.v_tt.00000', 'signal.v_tt.00001'), 'signal.v_tt.00031')
    """
    return tuple(f"{prefix}.{k:05d}" for k in range(rule.samples))


def _scan_rules() -> dict[str, object]:
    return {name: spec.rule for name, spec in SCAN_SIGNALS.items()}


SIGNAL = REGISTRY.register(Family(
    "signal", "signals (input of MiniRocket, MultiRocket)",
    tuple(c for name, spec in SCAN_SIGNALS.items() for c in signal_columns(f"signal.{name}", spec.rule)),
    lambda prepared: _scan_values(prepared, "signal", SIGNAL.columns, _flat),
    groups=tuple((f"signal.{name}", f"signal: {name}") for name in SCAN_SIGNALS),
    params=_scan_rules(), opt_in=True))
"""The signals themselves, as the fitted random-kernel transforms read them."""

CATCH22 = REGISTRY.register(Family(
    "catch22", "catch22 (Lubba et al. 2019)",
    tuple(f"catch22.{name}.{feature}" for name in SCAN_SIGNALS for feature in CATCH22_NAMES),
    lambda prepared: _scan_values(prepared, "catch22", CATCH22.columns, catch22),
    groups=tuple((f"catch22.{name}", f"catch22: {name}") for name in SCAN_SIGNALS),
    params=_scan_rules(), opt_in=True)) if available("catch22") else None

SCATTERING = REGISTRY.register(Family(
    "scattering", "wavelet scattering (Andén and Mallat 2014)",
    tuple(f"scattering.{name}.{c}" for name, spec in SCAN_SIGNALS.items() for c in scattering_names(spec.rule.length)),
    lambda prepared: _scan_values(prepared, "scattering", SCATTERING.columns, scattering),
    groups=tuple((f"scattering.{name}", f"scattering: {name}") for name in SCAN_SIGNALS),
    params={**_scan_rules(), "Q": SCATTERING_Q, "log_floor": SCATTERING_LOG_FLOOR},
    opt_in=True)) if available("scattering") else None


# -- imported recordings, by role -------------------------------------------------------------------

def _mono(data: np.ndarray) -> np.ndarray:
    """A 1-D signal: several columns averaged (a stereo sound, a taxel-free pressure pair)."""
    data = np.asarray(data, dtype=np.float64)
    return data if data.ndim == 1 else data.mean(axis=1)


def _vibration(band: np.ndarray) -> np.ndarray:
    return dft321(band)


def _tangential(xyz: np.ndarray) -> np.ndarray:
    values = np.asarray(xyz, dtype=np.float64)
    return np.hypot(values[:, 0], values[:, 1]) if values.ndim == 2 and values.shape[1] >= 2 else _mono(values)


@dataclass(frozen=True)
class RoleSignal:
    """The 1-D signal of a role (``to_1d`` of a window of the role's prepared data) and its rule."""

    to_1d: Callable[[np.ndarray], np.ndarray]
    rule: LengthRule
    prepare: Callable[[np.ndarray, float], np.ndarray] | None = None
    applies: Callable[[float], bool] = lambda fs: True


ROLE_RULES: Mapping[str, RoleSignal] = {
    "audio": RoleSignal(_mono, LengthRule(2048, windows=8, rate=44100.0)),
    "vibration": RoleSignal(_vibration, LengthRule(3000, windows=4, rate=3000.0), signals.band_limited,
                            lambda fs: signals.vibration_band(fs)[1] > BAND_HZ[0]),
    "force_xyz": RoleSignal(_tangential, LengthRule(1024, whole=True)),
    "pressure_dc": RoleSignal(_mono, LengthRule(1024, whole=True)),
    "temperature": RoleSignal(_mono, LengthRule(1024, whole=True)),
    "heat_flow": RoleSignal(_mono, LengthRule(1024, whole=True)),
}
"""The 1-D roles of imported recordings and the length rule of each (see the module docstring)."""


def _role_compute(role: str, transform: Callable[[np.ndarray], np.ndarray]) -> Callable:
    spec = ROLE_RULES[role]

    def compute(window: np.ndarray, fs: float) -> list[float]:
        return np.asarray(transform(instances(spec.to_1d(window), fs, spec.rule)), dtype=np.float64).tolist()

    return compute


def _register_roles(kind: str, features: Callable[[LengthRule], Sequence[str]],
                    transform: Callable[[np.ndarray], np.ndarray], extra: Mapping[str, object]) -> None:
    for role, spec in ROLE_RULES.items():
        REGISTRY.roles.register(RoleFamily(
            f"{kind}.{role}", role, tuple(f"{kind}.{role}.{f}" for f in features(spec.rule)),
            _role_compute(role, transform), applies=spec.applies, prepare=spec.prepare,
            params={"rule": spec.rule, **extra}, opt_in=True))


_register_roles("signal", lambda rule: [f"{k:05d}" for k in range(rule.samples)], _flat, {})
if available("catch22"):
    _register_roles("catch22", lambda rule: CATCH22_NAMES, catch22, {})
if available("scattering"):
    _register_roles("scattering", lambda rule: scattering_names(rule.length), scattering,
                    {"Q": SCATTERING_Q, "log_floor": SCATTERING_LOG_FLOOR})

GENERIC_RULE = LengthRule(512, windows=4)
"""The length rule of a generic channel (``signal_<channel>``, any rate from 20 Hz up): four instances of 512
samples at the channel's own rate spread over the window (5.12 s each at 100 Hz: a 5 s window is one
instance, zero-padded by 12 samples), its columns combined by DFT321 (:func:`scanner.preprocess.dft321`:
one signal with their spectral energy, as for a vibration)."""


def _combined(data: np.ndarray) -> np.ndarray:
    """A generic channel's window as one signal: its columns combined by DFT321, each minus its mean (the
    level is the generic family's; these families describe the signal's shape)."""
    values = np.asarray(data, dtype=np.float64)
    values = values.reshape(values.shape[0], -1) - values.reshape(values.shape[0], -1).mean(axis=0)
    return values[:, 0] if values.shape[1] == 1 else dft321(values)


def _generic_factory(kind: str, features: Sequence[str], transform: Callable[[np.ndarray], np.ndarray],
                     params: Mapping[str, object]) -> Callable[[str], RoleFamily]:
    """The ``kind`` family of any generic channel (``catch22.signal_gyro``), for
    :data:`features.recordings.GENERIC_KINDS`; channels below :data:`features.recordings.SLOW_MAX_HZ` are
    left to the slow family (a 5 s window at 6.5 Hz is 32 samples)."""

    @lru_cache(maxsize=256)
    def family(role: str) -> RoleFamily:
        def compute(window: np.ndarray, fs: float) -> list[float]:
            return np.asarray(transform(instances(_combined(window), fs, GENERIC_RULE)), dtype=np.float64).tolist()

        return RoleFamily(f"{kind}.{role}", role, tuple(f"{kind}.{role}.{f}" for f in features), compute,
                          applies=lambda fs: fs >= recordings.SLOW_MAX_HZ, params={"rule": GENERIC_RULE, **params},
                          opt_in=True)

    return family


recordings.GENERIC_KINDS["signal"] = _generic_factory(
    "signal", [f"{k:05d}" for k in range(GENERIC_RULE.samples)], _flat, {})
if available("catch22"):
    recordings.GENERIC_KINDS["catch22"] = _generic_factory("catch22", CATCH22_NAMES, catch22, {})
if available("scattering"):
    recordings.GENERIC_KINDS["scattering"] = _generic_factory(
        "scattering", scattering_names(GENERIC_RULE.length), scattering,
        {"Q": SCATTERING_Q, "log_floor": SCATTERING_LOG_FLOOR})

FITTED_KINDS = ("minirocket", "multirocket")
"""The random-kernel transforms, fitted inside the folds on the ``signal`` columns (features.random_kernels)."""

SIGNAL_PREFIX = "signal"
"""The family whose columns the random-kernel transforms read."""

KINDS = ("signal", "catch22", "scattering")
"""The modern extraction families, by kind (a scan family's name; a role family is ``<kind>.<role>``)."""


def role_families(kinds: Sequence[str]) -> tuple[str, ...]:
    """The registered role families of ``kinds`` (``catch22`` -> ``catch22.audio``, ...).

    Parameters
    ----------
    kinds : sequence of str
        Kinds of :data:`KINDS`.

    Returns
    -------
    tuple of str
        The names of their opt-in role families, in registration order (none for a kind whose library is
        missing).

    Examples
    --------
    >>> from features.modern import role_families
    >>> names = role_families(["signal"])
    >>> names[0], [name.removeprefix("signal.") for name in names]
    ('signal.audio', ['audio', 'vibration', 'force_xyz', 'pressure_dc', 'temperature', 'heat_flow'])
    """
    return tuple(f.name for f in REGISTRY.roles.every if f.name.split(".")[0] in kinds and f.opt_in)
