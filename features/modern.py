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

from features import recordings
from features.prepared import PreparedScan
from features.registry import REGISTRY, ROLE_REGISTRY, Family, RoleFamily
from scanner.lazy import library
from scanner.preprocess import QualityError, dft321
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
        """``8 windows of 2048 samples at 44100 Hz``, ``resampled to 1024 samples``."""
        if self.whole:
            return f"resampled to {self.length} samples"
        at = "" if self.rate is None else f" at {self.rate:g} Hz"
        return f"{self.windows} window{'s' if self.windows > 1 else ''} of {self.length} samples{at}"


def resample(x: np.ndarray, fs: float, rate: float) -> np.ndarray:
    """``x`` at ``rate`` Hz: polyphase resampling with scipy's anti-aliasing filter (the ratio as a fraction
    with a denominator of at most 1000)."""
    ratio = Fraction(rate / fs).limit_denominator(1000)
    if ratio == 1:
        return np.asarray(x, dtype=np.float64)
    return signal.resample_poly(np.asarray(x, dtype=np.float64), ratio.numerator, ratio.denominator)


def instances(x: np.ndarray, fs: float, rule: LengthRule) -> np.ndarray:
    """The instances of a 1-D signal by ``rule``, shape ``(windows, length)`` (see :class:`LengthRule`).

    Raises
    ------
    ParameterError
        If ``x`` is not 1-D or holds fewer than 2 samples.
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
    """catch22 of every instance, averaged over the instances (22 values, :data:`CATCH22_NAMES` order)."""
    library = require("catch22")
    values = [library.catch22_all(row.tolist())["values"] for row in windows]
    return np.mean(np.asarray(values, dtype=np.float64), axis=0)


def scattering_octaves(length: int) -> int:
    """J, the octaves of the scattering's averaging scale 2^J: the largest with 2^J <= length / 4, at most 9
    (a quarter of the instance leaves room for the filters' support at the edges); below 1024 samples an
    eighth (512 samples: J = 6), as kymatio's filters at J = 7 no longer fit 512 samples without border
    effects (it warns)."""
    return max(1, min(9, int(math.floor(math.log2(length / (4 if length >= 1024 else 8))))))


@lru_cache(maxsize=8)
def scattering_transform(length: int) -> object:
    """The ``Scattering1D`` of kymatio for instances of ``length`` samples (J by :func:`scattering_octaves`,
    Q = :data:`SCATTERING_Q`, orders 0 to 2), built once per process."""
    require("scattering")
    return kymatio_1d.ScatteringNumPy1D(J=scattering_octaves(length), shape=length, Q=SCATTERING_Q)


def scattering(windows: np.ndarray) -> np.ndarray:
    """Every scattering coefficient's mean over time, averaged over the instances; orders 1 and 2 (moduli,
    positive) as ``log(mean + 1e-12)``, as Andén and Mallat (2014, section 2.3) take their log. Order 0 is
    the low-passed signal itself, signed, and stays a mean."""
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
    (order 0, then 1, then 2; :data:`SCATTERING_SIZES`)."""
    first, second = SCATTERING_SIZES[scattering_octaves(length)]
    return ("s0", *(f"s1_{k:03d}" for k in range(first)), *(f"s2_{k:03d}" for k in range(second)))


def available(kind: str) -> bool:
    """Whether the library of ``catch22`` or ``scattering`` is installed (``signal`` needs none), found
    without importing it."""
    return kind not in LIBRARIES or importlib.util.find_spec(LIBRARIES[kind]) is not None


def require(kind: str) -> object:
    """The library of ``kind``; an error naming the extra where it is missing."""
    if not available(kind):
        raise ParameterError(f"the {kind} features need {EXTRA} (pip install '{EXTRA}')")
    return {"catch22": pycatch22, "scattering": kymatio_1d}.get(kind)


# -- the scan's signals -----------------------------------------------------------------------------

TAP_LEAD_S = 0.010
"""The tap signal starts 10 ms before the peak of ``|v_tt|``."""


def slide_vibration(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """``v`` of the tool slide: band-limited, in the 1 s slide window, DFT321 (paper section III)."""
    return prepared.slide_signal("v_ts"), prepared.scan["v_ts"].fs


def tap_vibration(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tool tap ``v_tt``: band-limited, DFT321, from :data:`TAP_LEAD_S` before its largest sample."""
    fs = prepared.scan["v_tt"].fs
    v = dft321(prepared.band_limited("v_tt"))
    start = max(0, int(np.argmax(np.abs(v))) - int(round(TAP_LEAD_S * fs)))
    return v[start:], fs


def slide_sound(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tool-slide sound ``a_ts`` in the slide window of ``v_ts``."""
    a = prepared.scan["a_ts"]
    window = prepared.slide_window("v_ts", audio_samples=a.n, audio_fs=a.fs)
    return a.data[window.audio], a.fs


def friction_force(prepared: PreparedScan) -> tuple[np.ndarray, float]:
    """The tangential force of the friction slide ``f_frt``, whole."""
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
    """``<prefix>.00000`` ...: one column per sample of every instance, windows in time order."""
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
    "vibration": RoleSignal(_vibration, LengthRule(3000, windows=4, rate=3000.0), recordings.band_limited,
                            lambda fs: recordings.vibration_band(fs)[1] > recordings.BAND_HZ[0]),
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
        ROLE_REGISTRY.register(RoleFamily(
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
    """The registered role families of ``kinds`` (``catch22`` -> ``catch22.audio``, ...)."""
    return tuple(f.name for f in ROLE_REGISTRY.every if f.name.split(".")[0] in kinds and f.opt_in)
