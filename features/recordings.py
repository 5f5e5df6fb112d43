"""The project's own feature families on any recording, by channel role (docs/ingest.md).

A lab's recordings (a folder of tool-slide sounds, texture photos, accelerometer or force-sensor CSVs,
imported with ``texplorer ingest``) get the same features as the scanner's, wherever the role they need
exists. Column names are ``<family>.<role>.<feature>``, so the family prefix is the scan's modality
(``FeatureSpace.modality("audio")`` works) and the role says which signal it describes:

=================  =====================  =================================================================
family             role                   features
=================  =====================  =================================================================
``audio``          ``audio``              the 35 audio features of docs/features.md#audio (``features.audio``), on any
                                          rate whose 50 ms frame holds at least 20 samples (>= 400 Hz)
``audio``          ``vibration``          the same 35, where the vibration is sampled at >= 1 kHz
                                          (:data:`VIBRATION_AUDIO_MIN_FS`)
``image``          ``photo``              the 31 image features of docs/features.md#image (``features.image``); the
                                          border crop is a parameter (0 for imported photos and patches)
``tactum``/        ``vibration``          the vibration-based features (docs/features.md) on ``v``:
``other``                                 ``tactum.vibration.miro``, ``.mico``, ``other.vibration.vib_std``,
                                          ``.vib_kurtosis``, ``.vib_energy``
``tactum``         ``force_xyz``          TacTUM's friction features FST and FRS (eqs. 16, 17) with the
                                          normal force z and the tangential force ``|(x, y)|``
``generic``        ``signal_<channel>``,  statistics, band energies on a rate-aware band plan and the
                   ``vibration`` < 1 kHz  spectral shape of every column (:func:`~features.signals.signal_features`);
                                          below 20 Hz level, spread, slope and rate of change instead
                                          (:func:`~features.signals.slow_features`) and the level
                                          ratios of two such channels (:func:`~features.signals.log_ratio`)
=================  =====================  =================================================================

``v`` of a recording is its vibration as the preprocessing makes the scanner's: each axis band-limited (4th-order
Butterworth, zero phase) over the whole recording, then cut to the window, then the axes combined by
DFT321. The band is 10-1000 Hz as in the paper where the rate allows (fs > 2222 Hz); below, its upper
edge is lowered to 0.45 fs, so a 1 kHz accelerometer keeps 10-450 Hz.

Audio on a vibration (interpretation of "where meaningful"; each window minus its mean, as an AC-coupled
microphone gives a signal, axes combined by DFT321): the 50 ms frames resolve 20 Hz and the
toolbox's spectral features describe the spectrum's shape at any rate, but the Pacinian band that texture
vibration lives in reaches ~500 Hz (Bensmaia and Hollins 2003), which needs fs >= 1 kHz. Below that the
audio features would describe only the slow part of the contact, so they are left out.

The features of one signal are computed by :mod:`features.signals`; this module applies them to a
recording's channels by role, window by window. The families are registered in
:data:`features.registry.REGISTRY.roles` (at the end of the section "the families, registered" below); the
columns, the families that apply to a recording and the roles named when none does come from there, so a
new family is one registration (``docs/extending.md``).

Windowing (:class:`Windowing`): the whole recording (default), or windows of N seconds cut from the start
(a shorter recording is one window); the windows' values are combined by their ``mean`` or ``median``, or
each window becomes its own row (``rows``) named ``<recording>#w<k>`` in the recording's group, so folds
never split one recording's windows. Photos are not windowed.
"""

from __future__ import annotations

import contextlib
import functools
import math
import warnings
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from features import audio, image
from features.extraction import run_extraction
from features.registry import REGISTRY, RoleFamily
from features.signals import (
    FRICTION_NAMES,
    SIGNAL_NAMES,
    SLOW_NAMES,
    VIBRATION_NAMES,
    audio_features,
    band_limited,
    friction_features,
    log_ratio,
    signal_features,
    slow_features,
    vibration_band,
    vibration_features,
)
from features.space import FeatureSpace
from scanner.preprocess import BAND_HZ, QualityError, band_limit, dft321, slide_signal
from scanner.runtime.threads import one_blas_thread
from scanner.scan import IMAGE_ROLES, Recording, Scan, Trace, is_generic
from taxonomy.errors import ParameterError

VIBRATION_AUDIO_MIN_FS = 1000.0
"""Lowest vibration rate the audio features are computed on (see the module docstring)."""

COMBINE = ("mean", "median", "rows")

@dataclass(frozen=True)
class Windowing:
    """How a recording is cut: the whole recording (``seconds`` None) or ``seconds``-long windows whose
    values are combined by ``combine`` (``mean``, ``median``, or ``rows``: a row per window)."""

    seconds: float | None = None
    combine: str = "mean"

    def __post_init__(self) -> None:
        if self.seconds is not None and not (math.isfinite(self.seconds) and self.seconds > 0):
            raise ParameterError(f"the window must be a positive number of seconds, got {self.seconds!r}")
        if self.combine not in COMBINE:
            raise ParameterError(f"combine must be one of {', '.join(COMBINE)}, got {self.combine!r}")

    def describe(self) -> str:
        """The windowing in words, as the reports print it: ``whole recordings``, ``5 s windows, one row per
        window``.

        Returns
        -------
        str
            The window length and how the windows' values are combined.

        Examples
        --------
        >>> from features.recordings import Windowing
        >>> Windowing().describe(), Windowing(5, "rows").describe(), Windowing(2.5, "median").describe()
        ('whole recordings', '5 s windows, one row per window', '2.5 s windows, the median over the windows')
        """
        if self.seconds is None:
            return "whole recordings"
        rule = "one row per window" if self.combine == "rows" else f"the {self.combine} over the windows"
        return f"{self.seconds:g} s windows, {rule}"


SLOW_MAX_HZ = 20.0
"""Generic channels sampled below this rate (a robot's wheel service data at 6.5 Hz, a thermometer at 1 Hz)
get the slow family (:func:`slow_features`) instead of spectra: a 5 s window of a 6.5 Hz channel holds 32
samples, whose Welch spectrum resolves 0.2 Hz, so octave bands from fs/128 would all be its lowest bin."""

GENERIC_KINDS: dict[str, Callable[[str], RoleFamily]] = {}
"""Opt-in families made for any generic channel ``signal_<channel>`` by kind (``catch22`` -> the family
``catch22.signal_gyro``): :mod:`features.modern` registers its kinds here, as their libraries allow. They are
computed where a registered family of the same kind is chosen (``--feature-set catch22``)."""

def generic_columns(role: str, width: int) -> tuple[str, ...]:
    """Columns of the generic family on a channel of ``width`` columns: ``generic.<role>.<feature>``, with
    ``c<k>_`` before the feature for each column of a multi-column channel.

    Parameters
    ----------
    role : str
        The channel's role (``signal_<channel>`` or ``vibration``).
    width : int
        The channel's number of columns.

    Returns
    -------
    tuple of str
        ``width`` times the 19 :data:`SIGNAL_NAMES`, column after column.

    Examples
    --------
    >>> generic_columns("signal_gyro", 1)[:3]
    ('generic.signal_gyro.mean', 'generic.signal_gyro.std', 'generic.signal_gyro.rms')
    >>> columns = generic_columns("signal_gyro", 3)
    >>> len(columns), columns[0], columns[19]
    (57, 'generic.signal_gyro.c0_mean', 'generic.signal_gyro.c1_mean')
    """
    if width == 1:
        return tuple(f"generic.{role}.{name}" for name in SIGNAL_NAMES)
    return tuple(f"generic.{role}.c{k}_{name}" for k in range(width) for name in SIGNAL_NAMES)


def slow_columns(role: str, width: int) -> tuple[str, ...]:
    """Columns of the slow family on a channel of ``width`` columns, named as :func:`generic_columns`.

    Parameters
    ----------
    role : str
        The channel's role (``signal_<channel>`` or ``vibration``).
    width : int
        The channel's number of columns.

    Returns
    -------
    tuple of str
        ``width`` times the 6 :data:`SLOW_NAMES`, column after column.

    Examples
    --------
    >>> slow_columns("signal_speed", 1)
    ... # doctest: +NORMALIZE_WHITESPACE
    ('generic.signal_speed.mean', 'generic.signal_speed.std', 'generic.signal_speed.p05', 'generic.signal_speed.p95',
     'generic.signal_speed.slope', 'generic.signal_speed.change')
    >>> slow_columns("signal_speed", 2)[5:7]
    ('generic.signal_speed.c0_change', 'generic.signal_speed.c1_mean')
    """
    if width == 1:
        return tuple(f"generic.{role}.{name}" for name in SLOW_NAMES)
    return tuple(f"generic.{role}.c{k}_{name}" for k in range(width) for name in SLOW_NAMES)


def _generic(window: np.ndarray, fs: float) -> list[float]:
    columns = window.reshape(window.shape[0], -1)
    return [value for k in range(columns.shape[1]) for value in signal_features(columns[:, k], fs)]


def _slow(window: np.ndarray, fs: float) -> list[float]:
    columns = window.reshape(window.shape[0], -1)
    return [value for k in range(columns.shape[1]) for value in slow_features(columns[:, k], fs)]


def _below_vibration_audio(fs: float) -> bool:
    return SLOW_MAX_HZ <= fs < VIBRATION_AUDIO_MIN_FS


def _not_slow(fs: float) -> bool:
    return fs >= SLOW_MAX_HZ


def _slow_rate(fs: float) -> bool:
    return fs < SLOW_MAX_HZ


@lru_cache(maxsize=256)
def generic_family(role: str, width: int) -> RoleFamily:
    """The generic family of a channel playing ``role`` with ``width`` columns (docs/features.md#generic-
    signals): on every generic channel (``signal_<channel>``) and on a vibration sampled below
    :data:`VIBRATION_AUDIO_MIN_FS`, where the audio features do not apply. Not registered: its columns
    follow the channel's width, so a set's families are made for the channels it has.

    Parameters
    ----------
    role : str
        The channel's role: ``signal_<channel>`` or ``vibration``.
    width : int
        The channel's number of columns (:func:`generic_columns`).

    Returns
    -------
    RoleFamily
        Named ``generic.<role>``, or ``generic.<role>:<width>`` for several columns; it applies to a
        generic channel at :data:`SLOW_MAX_HZ` or more, to a vibration from there to
        :data:`VIBRATION_AUDIO_MIN_FS`.

    Examples
    --------
    >>> gyro = generic_family("signal_gyro", 3)
    >>> gyro.name, len(gyro.columns), gyro.applies(100.0), gyro.applies(10.0)
    ('generic.signal_gyro:3', 57, True, False)
    >>> vibration = generic_family("vibration", 1)
    >>> vibration.applies(500.0), vibration.applies(3000.0)
    (True, False)
    """
    name = f"generic.{role}" if width == 1 else f"generic.{role}:{width}"
    return RoleFamily(name, role, generic_columns(role, width), _generic,
                      applies=_below_vibration_audio if role == "vibration" else _not_slow)


@lru_cache(maxsize=256)
def slow_family(role: str, width: int) -> RoleFamily:
    """The slow family of a generic channel (or vibration) sampled below :data:`SLOW_MAX_HZ`
    (:func:`slow_features`): level, spread, slope and rate of change, no spectra. Named ``slow.<role>``;
    its columns are ``generic.<role>.<feature>`` like the generic family's, which it replaces there.

    Parameters
    ----------
    role : str
        The channel's role: ``signal_<channel>`` or ``vibration``.
    width : int
        The channel's number of columns (:func:`slow_columns`).

    Returns
    -------
    RoleFamily
        Named ``slow.<role>``, or ``slow.<role>:<width>`` for several columns; it applies below
        :data:`SLOW_MAX_HZ`.

    Examples
    --------
    >>> speed = slow_family("signal_speed", 1)
    >>> speed.name, speed.columns[0], speed.applies(6.5), speed.applies(100.0)
    ('slow.signal_speed', 'generic.signal_speed.mean', True, False)
    >>> import numpy as np
    >>> np.round(speed.compute(np.array([0.0, 1.0, 2.0, 3.0]), 2.0), 6).tolist()  # mean, std, p05, p95, slope, change
    [1.5, 1.118034, 0.15, 2.85, 2.0, 2.0]
    """
    name = f"slow.{role}" if width == 1 else f"slow.{role}:{width}"
    return RoleFamily(name, role, slow_columns(role, width), _slow, applies=_slow_rate)


def _channel_word(role: str) -> str:
    return role.removeprefix("signal_")


def ratio_columns(role: str, other: str, width: int, other_width: int) -> tuple[str, ...]:
    """Columns of the ratios of ``role`` to ``other``: ``generic.<role>.c<k>_log_per_<other channel>`` column
    by column where both have ``width`` columns (left current per left speed, ...), else one
    ``generic.<role>.log_per_<other channel>`` of their levels over all columns.

    Parameters
    ----------
    role, other : str
        The roles of the two channels (``signal_<channel>``).
    width, other_width : int
        Their numbers of columns.

    Returns
    -------
    tuple of str
        ``width`` names where the widths are equal and above 1, else one.

    Examples
    --------
    >>> ratio_columns("signal_current", "signal_speed", 2, 2)
    ('generic.signal_current.c0_log_per_speed', 'generic.signal_current.c1_log_per_speed')
    >>> ratio_columns("signal_current", "signal_speed", 2, 1)
    ('generic.signal_current.log_per_speed',)
    """
    word = _channel_word(other)
    if width == other_width and width > 1:
        return tuple(f"generic.{role}.c{k}_log_per_{word}" for k in range(width))
    return (f"generic.{role}.log_per_{word}",)


@lru_cache(maxsize=256)
def ratio_family(role: str, other: str, width: int, other_width: int) -> RoleFamily:
    """The level ratios (:func:`log_ratio`) of two slow channels of one recording sampled at the same rate:
    motor current per wheel speed, say. Named ``ratio.<role>.<other>:<width>x<other width>``; its window is
    both channels side by side (:func:`recording_rows` prepares it).

    Parameters
    ----------
    role, other : str
        The roles of the two channels (``signal_<channel>``), ``role`` the numerator.
    width, other_width : int
        Their numbers of columns.

    Returns
    -------
    RoleFamily
        The family, with the columns of :func:`ratio_columns`; it applies below :data:`SLOW_MAX_HZ`.

    Examples
    --------
    A current of 2 A at a speed of 0.2 m/s: ten times the level, a log10 ratio of 1:

    >>> import numpy as np
    >>> family = ratio_family("signal_current", "signal_speed", 1, 1)
    >>> family.name, family.columns
    ('ratio.signal_current.signal_speed:1x1', ('generic.signal_current.log_per_speed',))
    >>> family.compute(np.array([[2.0, 0.2], [2.0, 0.2]]), 10.0)
    [1.0]
    """

    def compute(window: np.ndarray, fs: float) -> list[float]:
        a, b = window[:, :width], window[:, width:]
        if width == other_width and width > 1:
            return [log_ratio(a[:, k], b[:, k]) for k in range(width)]
        return [log_ratio(a, b)]

    return RoleFamily(f"ratio.{role}.{other}:{width}x{other_width}", role,
                      ratio_columns(role, other, width, other_width), compute, applies=_slow_rate)


def _family(name: str) -> RoleFamily:
    """A registered family, or the generic, slow, ratio or modern generic family a name stands for."""
    if name in REGISTRY.roles:
        return REGISTRY.roles[name]
    kind, _, rest = name.partition(".")
    if kind in GENERIC_KINDS:
        return GENERIC_KINDS[kind](rest)
    if kind == "ratio":
        roles, _, widths = rest.partition(":")
        role, other = roles.split(".")
        width, other_width = (int(w) for w in widths.split("x"))
        return ratio_family(role, other, width, other_width)
    role, _, width = rest.partition(":")
    return (slow_family if kind == "slow" else generic_family)(role, int(width or 1))


def _as_is(name: str) -> bool:
    """Whether a family's name is kept as it is in a set's families: a ratio or a modern generic family
    (no width to widen)."""
    return name.startswith("ratio.") or name.partition(".")[0] in GENERIC_KINDS


def _generic_kinds(chosen: Sequence[str] | None) -> list[str]:
    """The kinds of :data:`GENERIC_KINDS` that ``chosen`` names a family of (``catch22.audio`` -> catch22)."""
    named = {name.partition(".")[0] for name in chosen or ()}
    return [kind for kind in GENERIC_KINDS if kind in named]


def _ratio_other(name: str) -> str | None:
    """The second role of a ratio family's name, else None."""
    return name.partition(":")[0].split(".")[2] if name.startswith("ratio.") else None


def _width(trace: Trace) -> int:
    return 1 if trace.data.ndim == 1 else int(np.prod(trace.data.shape[1:]))


# -- the families, registered ------------------------------------------------------------------------

def _audio_rate_ok(fs: float) -> bool:
    return audio.window_and_step(fs)[0] >= audio.MIN_WINDOW


def _vibration_audio_rate_ok(fs: float) -> bool:
    return fs >= VIBRATION_AUDIO_MIN_FS


def _vibration_band_ok(fs: float) -> bool:
    return vibration_band(fs)[1] > BAND_HZ[0]


def _sound_audio(window: np.ndarray, fs: float) -> list[float]:
    return list(audio_features(window, fs).values())


def _vibration_audio(window: np.ndarray, fs: float) -> list[float]:
    # Without its mean, as an AC-coupled microphone would give it (a BioTac's PAC sits at ~2000).
    return list(audio_features(dft321(window - window.mean(axis=0)), fs).values())


def _photo(photo: np.ndarray, border: int) -> list[float]:
    return list(image.compute(photo, border=border).values())


def _vibration(band: np.ndarray, fs: float) -> list[float]:
    return list(vibration_features(dft321(band), fs).values())


def _friction(xyz: np.ndarray, fs: float) -> list[float]:
    return list(friction_features(xyz, fs).values())


AUDIO_AUDIO = REGISTRY.roles.register(RoleFamily(
    "audio.audio", "audio", tuple(f"audio.audio.{name}" for name in audio.NAMES), _sound_audio,
    applies=_audio_rate_ok))
AUDIO_VIBRATION = REGISTRY.roles.register(RoleFamily(
    "audio.vibration", "vibration", tuple(f"audio.vibration.{name}" for name in audio.NAMES), _vibration_audio,
    applies=_vibration_audio_rate_ok))
IMAGE_PHOTO = REGISTRY.roles.register(RoleFamily(
    "image.photo", "photo", tuple(f"image.photo.{name}" for name in image.NAMES), _photo))
VIBRATION = REGISTRY.roles.register(RoleFamily(
    "vibration", "vibration", VIBRATION_NAMES, _vibration, applies=_vibration_band_ok, prepare=band_limited))
FRICTION = REGISTRY.roles.register(RoleFamily("friction", "force_xyz", FRICTION_NAMES, _friction))


def families(recording: Recording, chosen: Sequence[str] | None = None) -> list[str]:
    """The families that apply to a recording: the registered ones (``audio.audio``, ``image.photo``, ...)
    in order, among the default ones or those named in ``chosen`` (opt-in ones too: docs/modern-features.md),
    then the generic family of each generic channel and of a vibration below 1 kHz.

    Parameters
    ----------
    recording : Recording
        A recording with roles.
    chosen : sequence of str, optional
        Names of registered families to look at (default: the default ones); naming a family of a kind of
        :data:`GENERIC_KINDS` (``catch22.audio``) adds that kind's family on every generic channel.

    Returns
    -------
    list of str
        The names of the families whose role the recording has at a rate they apply to: the registered ones
        in registry order, then by role the generic or slow family of each generic channel and slow
        vibration (``generic.<role>``, ``slow.<role>``, ``:<width>`` for several columns), the ratio family
        of each two slow channels at one rate, and the families of the chosen kinds.

    Examples
    --------
    A 3-axis vibration at 3 kHz and a force: audio on the vibration, the vibration features and friction.
    A robot's gyroscope at 100 Hz, speed and current at 10 Hz: generic, slow and ratio families:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> slide = Recording("slide", {"acc": Trace(np.zeros((3000, 3)), 3000.0, "g"),
    ...                             "force": Trace(np.ones((300, 3)), 100.0, "N")},
    ...                   {"vibration": "acc", "force_xyz": "force"}, "cork")
    >>> families(slide)
    ['audio.vibration', 'vibration', 'friction']
    >>> run = Recording("run", {"gyro": Trace(np.zeros((500, 3)), 100.0, "rad/s"),
    ...                         "speed": Trace(np.ones(50), 10.0, "m/s"), "current": Trace(np.ones(50), 10.0, "A")},
    ...                 {"signal_gyro": "gyro", "signal_speed": "speed", "signal_current": "current"}, "grass")
    >>> families(run)  # doctest: +NORMALIZE_WHITESPACE
    ['slow.signal_current', 'generic.signal_gyro:3', 'slow.signal_speed',
     'ratio.signal_current.signal_speed:1x1']
    """
    found = []
    kinds = _generic_kinds(chosen)
    chosen = None if chosen is None else [n for n in chosen if n in REGISTRY.roles]
    for family in REGISTRY.roles.chosen(chosen):
        if family.role in IMAGE_ROLES:
            applies = recording.image(family.role) is not None
        else:
            trace = recording.role(family.role)
            applies = trace is not None and family.applies(trace.fs)
        if applies:
            found.append(family.name)
    slow = []
    for role in sorted(recording.roles):
        trace = recording.role(role)
        if trace is not None and (is_generic(role) or role == "vibration"):
            for family in (generic_family(role, _width(trace)), slow_family(role, _width(trace))):
                if family.applies(trace.fs):
                    found.append(family.name)
                    slow += [(role, trace)] if family.name.startswith("slow.") else []
    for k, (role, trace) in enumerate(slow):
        for second, second_trace in slow[k + 1:]:
            if math.isclose(trace.fs, second_trace.fs, rel_tol=1e-6):
                found.append(ratio_family(role, second, _width(trace), _width(second_trace)).name)
    for kind in kinds:
        for role in sorted(r for r in recording.roles if is_generic(r)):
            family, trace = GENERIC_KINDS[kind](role), recording.role(role)
            if trace is not None and family.applies(trace.fs):
                found.append(family.name)
    return found


def family_names(family: str) -> tuple[str, ...]:
    """The columns of one family.

    Parameters
    ----------
    family : str
        A registered family's name, or that of a generic, slow, ratio or modern generic family as
        :func:`families` gives it.

    Returns
    -------
    tuple of str
        Its column names, in order.

    Examples
    --------
    >>> family_names("friction")
    ('tactum.force_xyz.fst', 'tactum.force_xyz.frs')
    >>> len(family_names("generic.signal_gyro:3")), family_names("slow.signal_speed")[-2:]
    (57, ('generic.signal_speed.slope', 'generic.signal_speed.change'))
    """
    return _family(family).columns


# -- one recording -----------------------------------------------------------------------------------

def _windows(duration: float, windowing: Windowing) -> list[tuple[float, float]]:
    """``[start, stop)`` seconds of every window: the whole recording, or whole windows from the start."""
    if windowing.seconds is None or duration <= windowing.seconds:
        return [(0.0, duration)]
    count = int(math.floor(duration / windowing.seconds + 1e-9))
    return [(k * windowing.seconds, (k + 1) * windowing.seconds) for k in range(count)]


def _cut(trace: Trace | np.ndarray, fs: float, start: float, stop: float) -> np.ndarray:
    data = trace.data if isinstance(trace, Trace) else trace
    return data[int(round(start * fs)):int(round(stop * fs))]


def _sampled_features(recording: Recording, applied: Sequence[str], start: float, stop: float,
                      prepared: Mapping[str, np.ndarray]) -> dict[str, float]:
    values: dict[str, float] = {}
    for name in applied:
        family = _family(name)
        fs = recording.role(family.role).fs
        try:
            window = _cut(prepared[name], fs, start, stop)
            values.update(zip(family.columns, family.compute(window, fs), strict=True))
        except ValueError as problem:
            warnings.warn(f"recording {recording.name!r}: {name}: {problem}; its features are NaN",
                          stacklevel=2)
            values.update(dict.fromkeys(family.columns, math.nan))
    return values


def recording_rows(recording: Recording, windowing: Windowing = Windowing(), border: int = 0,
                   applied: Sequence[str] | None = None) -> list[dict[str, float]]:
    """The feature rows of one recording: one, or one per window with ``combine = "rows"``.

    ``applied`` are the families to compute (default :func:`families`); ``border`` the crop of its photo.
    A family whose input fails (too short to filter, a photo too small to crop) is NaN with a warning.

    Parameters
    ----------
    recording : Recording
        The recording.
    windowing : Windowing, optional
        How it is cut and its windows combined (default: the whole recording).
    border : int, default 0
        Pixels cropped from each edge of its photo.
    applied : sequence of str, optional
        Names of the families to compute (:func:`families`' names); default those that apply to it.

    Returns
    -------
    list of dict of str to float
        The values by column name: one row, or one per window in time order with ``combine = "rows"``.
        Windows cover the sampled channels only; a photo's values are in every row.

    Warns
    -----
    UserWarning
        Naming the recording and the family whose input failed; its values are NaN.

    Examples
    --------
    A speed rising at 2 m/s per second for 4 s, sampled at 10 Hz: the whole of it, its 2 s windows as rows,
    and the median over 1 s windows:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from features.recordings import Windowing
    >>> ramp = Recording("ramp", {"speed": Trace(2.0 * np.arange(40) / 10.0, 10.0, "m/s")},
    ...                  {"signal_speed": "speed"}, "grass")
    >>> def shown(rows):
    ...     return [(round(row["generic.signal_speed.mean"], 6), round(row["generic.signal_speed.slope"], 6))
    ...             for row in rows]
    >>> shown(recording_rows(ramp)), shown(recording_rows(ramp, Windowing(2.0, "rows")))
    ([(3.9, 2.0)], [(1.9, 2.0), (5.9, 2.0)])
    >>> shown(recording_rows(ramp, Windowing(1.0, "median")))
    [(3.9, 2.0)]
    """
    applied = list(families(recording) if applied is None else applied)
    fixed: dict[str, float] = {}
    prepared: dict[str, np.ndarray] = {}
    for name in applied:
        family = _family(name)
        try:
            if family.role in IMAGE_ROLES:
                fixed.update(zip(family.columns, family.compute(recording.image(family.role), border), strict=True))
            elif _ratio_other(name) is not None:  # both channels side by side, cut to the shorter
                a, b = (recording.role(role).data for role in (family.role, _ratio_other(name)))
                n = min(a.shape[0], b.shape[0])
                prepared[name] = np.column_stack([a[:n].reshape(n, -1), b[:n].reshape(n, -1)])
            else:
                trace = recording.role(family.role)
                prepared[name] = trace.data if family.prepare is None else family.prepare(trace.data, trace.fs)
        except ValueError as problem:
            warnings.warn(f"recording {recording.name!r}: {family.role}: {problem}; its features are NaN",
                          stacklevel=2)
            fixed.update(dict.fromkeys(family.columns, math.nan))
    if not prepared:
        return [fixed]
    duration = min(recording.role(_family(name).role).duration for name in prepared)
    rows = [_sampled_features(recording, list(prepared), start, stop, prepared)
            for start, stop in _windows(duration, windowing)]
    if windowing.combine != "rows" and len(rows) > 1:
        combine = np.mean if windowing.combine == "mean" else np.median
        rows = [{name: float(combine([row[name] for row in rows])) for name in rows[0]}]
    return [{**fixed, **row} for row in rows]


# -- a scan as a recording ----------------------------------------------------------------------------

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
    >>> from features.recordings import slide_vibration
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
    >>> from features.recordings import scan_recording
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


# -- a set -------------------------------------------------------------------------------------------

def fold_group(recording: Recording, group_by: str | None = "auto") -> str:
    """The cross-validation group of a recording: its group ``group_by``; with ``auto`` the ``object``,
    else the ``photo`` its patch was cut from, else the earlier recording whose samples it begins with
    (``repeats``, set at import: ``scanner.storage.ingest.assembly.Repeats``), else the recording itself;
    ``recording`` (or None): every recording alone, with its windows (``none``, every row alone, is
    :func:`feature_space`'s).

    Parameters
    ----------
    recording : Recording
        The recording.
    group_by : str or None, default "auto"
        A key of the recording's ``group``, ``auto``, ``recording``, ``none`` or None.

    Returns
    -------
    str
        The group's id.

    Raises
    ------
    ParameterError
        If the recording has no group ``group_by``.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> patch = Recording("patch-3", {"x": Trace(np.ones(4), 10.0, "-")}, group={"photo": "img-7", "site": "a"})
    >>> fold_group(patch), fold_group(patch, "site"), fold_group(patch, "recording")
    ('img-7', 'a', 'patch-3')
    >>> fold_group(Recording("run-13", {"x": Trace(np.ones(4), 10.0, "-")}, group={"repeats": "run-12"}))
    'run-12'
    """
    if group_by is None or group_by in ("none", "recording"):
        return recording.name
    if group_by == "auto":
        group = recording.group
        return group.get("object") or group.get("photo") or group.get("repeats") or recording.name
    if group_by not in recording.group:
        raise ParameterError(f"recording {recording.name!r} has no group {group_by!r} "
                             f"(groups: {', '.join(recording.group) or 'none'})")
    return recording.group[group_by]


def set_levels(recordings: Sequence[Recording]) -> tuple[str, dict[str, list[str]]]:
    """The label's level and the coarser levels every recording defines (``meta["levels"]``).

    Parameters
    ----------
    recordings : sequence of Recording
        The set, at least one recording; the first one's ``meta`` names the levels.

    Returns
    -------
    label_level : str
        The first recording's ``meta["label_level"]``, ``label`` if it has none.
    levels : dict of str to list of str
        Each coarser level that every recording defines, with every recording's class at it, in order.

    Examples
    --------
    ``hardness`` is defined by both recordings, ``colour`` by one only:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> def made(name, label, levels):
    ...     return Recording(name, {"x": Trace(np.ones(4), 10.0, "-")}, label=label,
    ...                      meta={"label_level": "material", "levels": levels})
    >>> set_levels([made("a", "cork", {"hardness": "soft", "colour": "brown"}),
    ...             made("b", "oak", {"hardness": "hard"})])
    ('material', {'hardness': ['soft', 'hard']})
    """
    label_level = str(recordings[0].meta.get("label_level", "label"))
    levels: dict[str, list[str]] = {}
    first = recordings[0].meta.get("levels") or {}
    for name in first:
        if name != label_level and all(name in (r.meta.get("levels") or {}) for r in recordings):
            levels[name] = [str(r.meta["levels"][name]) for r in recordings]
    return label_level, levels


@dataclass(frozen=True)
class RecordingJob:
    """One recording of a set to extract (:func:`extract_recording`) and how: ``load`` gives the recording
    where it is processed (it travels with its task), cut by ``windowing``, its photo cropped by ``border``,
    the set's families ``applied``."""

    load: Callable[[], Recording]
    windowing: Windowing
    border: int
    applied: tuple[str, ...]


def _given(recording: Recording) -> Recording:
    return recording


def extract_recording(job: RecordingJob) -> tuple[tuple[list[dict[str, float]], list[str]] | None, str | None]:
    """One recording's step of :func:`features.extraction.run_extraction`: its rows (:func:`recording_rows`)
    and the warnings raised meanwhile, one line each naming the recording; or why it could not be extracted,
    so that one broken recording does not stop the others. BLAS runs on one thread, as in
    :func:`features.extract`: the same bits here, in a worker process and on a Dask worker.

    Parameters
    ----------
    job : RecordingJob
        The recording and how to cut it.

    Returns
    -------
    ((list of dict of str to float, list of str) or None, str or None)
        ``((rows, warnings), None)``, or ``(None, "<error type>: <message>")``.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from features.recordings import RecordingJob, Windowing, extract_recording
    >>> rising = Recording("r0", {"v": Trace(np.arange(40.0) / 10, 10.0, "m/s")}, {"signal_speed": "v"}, "grass")
    >>> (rows, caught), error = extract_recording(RecordingJob(lambda: rising, Windowing(2.0, "rows"), 0,
    ...                                                        ("slow.signal_speed",)))
    >>> [round(row["generic.signal_speed.mean"], 2) for row in rows], caught, error
    ([0.95, 2.95], [], None)
    >>> def lost():
    ...     raise OSError("r1.mat: unreadable")
    >>> extract_recording(RecordingJob(lost, Windowing(), 0, ("slow.signal_speed",)))
    (None, 'OSError: r1.mat: unreadable')
    """
    try:
        recording = job.load()
        # One BLAS thread, as features.extract: the same bits here, in a pool and on a Dask worker.
        with warnings.catch_warnings(record=True) as caught, one_blas_thread():
            warnings.simplefilter("always")
            rows = recording_rows(recording, job.windowing, job.border, _own(recording, job.applied))
    except Exception as exc:  # one broken recording must not stop the others; reported with its name
        return None, f"{type(exc).__name__}: {exc}"
    messages = (str(w.message) for w in caught)
    return (rows, list(dict.fromkeys(m if m.startswith("recording ") else f"recording {recording.name!r}: {m}"
                                     for m in messages))), None


def set_code_version(applied: Sequence[str]) -> str:
    """The feature code version of a set's families ``applied``: the source of the role families' modules, of
    this module (the generic families it makes per set) and of the extraction, and the registered families'
    names and parameters.

    Parameters
    ----------
    applied : sequence of str
        The set's families (:func:`families`' names).

    Returns
    -------
    str
        20 hexadecimal digits.

    Examples
    --------
    >>> from features.recordings import set_code_version
    >>> version = set_code_version(["audio.audio", "slow.signal_speed"])
    >>> len(version), version == set_code_version(["audio.audio"]), version == set_code_version(["friction"])
    (20, True, False)
    """
    registered = [name for name in applied if name in REGISTRY.roles]
    return REGISTRY.roles.code_version(__name__, "features.extraction", families=registered)


def feature_space(recordings: Sequence[Recording], windowing: Windowing = Windowing(), border: int = 0,
                  group_by: str | None = "auto", workers: int | None = 1, progress: bool = False,
                  chosen: Sequence[str] | None = None) -> tuple[FeatureSpace, list[str]]:
    """The feature space of a set of recordings with its own labels, levels, groups and split, and the
    warnings raised while extracting (one line each, naming the recording).

    Columns are every family that applies to at least one recording (:func:`families`), in the order of
    the registry (:data:`features.registry.REGISTRY.roles`); a recording without a family's role has NaN
    there (evaluation then leaves the column out). Rows are in recording order (windows in time order with
    ``combine = "rows"``). ``group_by`` names the rows' cross-validation groups (:func:`fold_group`); ``none``
    makes every row its own group, so the windows of one recording fall in training and test (the
    protocol of published results that cut windows from runs, which leaks between them). ``workers``
    processes of this machine (1: in this process, None: one per core), or the workers of the current
    runtime's cluster (:func:`scanner.runtime.current`; the recordings are sent from here, the values are
    the same): the recordings go the way scans go (:func:`features.extraction.run_extraction`, each from the
    feature code of this process), and one that fails is left out, named in ``FeatureSpace.failed`` and in the
    first notes, while the others are kept. ``chosen`` names the registered families to compute (default: the
    default ones), opt-in ones too (``catch22.audio``, ...: docs/modern-features.md).

    Parameters
    ----------
    recordings : sequence of Recording
        The set, each recording labelled; the first one's ``meta`` names the label's level and coarser
        levels (:func:`set_levels`), and ``meta["split"]`` the split if every recording has one.
    windowing : Windowing, optional
        How each recording is cut (default: whole recordings).
    border : int, default 0
        Pixels cropped from each edge of a photo.
    group_by : str or None, default "auto"
        The rows' cross-validation groups (:func:`fold_group`), or ``none``: every row alone.
    workers : int or None, default 1
        Processes of this machine (None: one per core) or workers of the current runtime.
    progress : bool, default False
        Show a progress bar on stderr.
    chosen : sequence of str, optional
        Names of the registered families to compute (default: the default ones).

    Returns
    -------
    space : FeatureSpace
        One row per recording (or window), free labels at the set's level.
    notes : list of str
        One line per recording that could not be extracted, one per family some recordings lack
        (:func:`lacking`), then each warning raised while extracting, once.

    Raises
    ------
    ParameterError
        If no family applies to any recording, or a recording has no label.

    Examples
    --------
    Two recordings of a robot's speed at 10 Hz, a constant level plus a rise of 1 m/s per second, one
    with a current too; the other lacks its columns:

    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> from features.recordings import Windowing
    >>> def run(name, terrain, level, current):
    ...     speed = Trace(level + np.arange(20) / 10.0, 10.0, "m/s")
    ...     channels = {"speed": speed, "current": Trace(np.full(20, 2.0 * level), 10.0, "A")}
    ...     roles = {"signal_speed": "speed", "signal_current": "current"} if current else {"signal_speed": "speed"}
    ...     return Recording(name, channels, roles, terrain, {"object": f"{terrain}-1"}, {"label_level": "terrain"})
    >>> space, notes = feature_space([run("r0", "grass", 1.0, True), run("r1", "gravel", 2.0, False)])
    >>> space
    FeatureSpace(2 rows x 13 features, 2 groups, 2 classes at terrain)
    >>> space.subset(["generic.signal_speed.mean", "generic.signal_speed.slope"]).X.round(6).tolist()
    [[1.95, 1.0], [2.95, 1.0]]
    >>> space.groups, len(notes)
    (('grass-1', 'gravel-1'), 2)
    >>> print(notes[0])  # doctest: +NORMALIZE_WHITESPACE
    1 of 2 recording(s) lack the role signal_current (at a rate slow.signal_current applies to): its 6 column(s)
    are NaN there (r1)
    >>> windows, _ = feature_space([run("r0", "grass", 1.0, True)], Windowing(1.0, "rows"), group_by="none")
    >>> windows.scan_ids, windows.groups
    (('r0#w000', 'r0#w001'), ('r0#w000', 'r0#w001'))
    """
    recordings = list(recordings)
    if not recordings:
        raise ParameterError("no recordings")
    unlabelled = next((r.name for r in recordings if not r.label), None)
    if unlabelled is not None:
        raise ParameterError(f"recording {unlabelled!r} has no label")
    found = [families(r, chosen) for r in recordings]
    applied = _applied({f for names in found for f in names}, chosen)
    if not applied:
        roles = sorted({role for r in recordings for role in r.roles})
        needed = list(dict.fromkeys(family.role for family in REGISTRY.roles.chosen(chosen)))
        raise ParameterError(f"no feature family applies: the recordings have the roles "
                             f"{', '.join(roles) or 'none'}; the families need "
                             f"{', '.join(needed[:-1])} or {needed[-1]}")
    columns = tuple(name for family in applied for name in family_names(family))
    jobs = [RecordingJob(functools.partial(_given, r), windowing, border, applied) for r in recordings]
    results: list = [None] * len(jobs)
    with contextlib.closing(run_extraction(extract_recording, jobs, range(len(jobs)),
                                           functools.partial(set_code_version, applied),
                                           key=("recordings", columns), workers=workers, progress=progress,
                                           unit="recording")) as extracted:
        for i, result in extracted:
            results[i] = result
    kept = [k for k, (rows, _) in enumerate(results) if rows is not None]
    missing = lacking([recordings[k] for k in kept], [found[k] for k in kept], applied)
    label_level, levels = set_levels(recordings)
    X, ids, labels, groups, level_rows, split, notes = [], [], [], [], {k: [] for k in levels}, [], []
    failed = [(r.name, error) for r, (_, error) in zip(recordings, results, strict=True) if error is not None]
    has_split = all(r.meta.get("split") in ("train", "test") for r in recordings)
    for index, (recording, (extracted, _)) in enumerate(zip(recordings, results, strict=True)):
        if extracted is None:
            continue
        rows, caught = extracted
        notes += caught
        for k, row in enumerate(rows):
            X.append([row.get(name, math.nan) for name in columns])
            ids.append(recording.name if len(rows) == 1 else f"{recording.name}#w{k:03d}")
            labels.append(str(recording.label))
            groups.append(ids[-1] if group_by == "none" else fold_group(recording, group_by))
            for name in levels:
                level_rows[name].append(levels[name][index])
            if has_split:
                split.append(recording.meta["split"])
    space = FeatureSpace(np.array(X, dtype=np.float64).reshape(len(X), len(columns)), columns, ids, labels,
                         groups, failed, label_level, level_rows, split)
    failures = [f"recording {name!r} could not be extracted and is left out: {error}" for name, error in failed]
    return space, failures + missing + list(dict.fromkeys(notes))


def _applied(present: set[str], chosen: Sequence[str] | None = None) -> tuple[str, ...]:
    """The families of a set: the registered ones present (of the default ones or ``chosen``), in registry
    order, then one generic family per generic role, as wide as its widest channel (a narrower one fills
    the columns it has)."""
    widest: dict[tuple[str, str], int] = {}
    unregistered = present - {f.name for f in REGISTRY.roles.every}
    for name in {n for n in unregistered if not _as_is(n)}:
        family, kind = _family(name), name.partition(".")[0]
        per_column = len(SLOW_NAMES if kind == "slow" else SIGNAL_NAMES)
        widest[kind, family.role] = max(widest.get((kind, family.role), 0), len(family.columns) // per_column)
    made = {"generic": generic_family, "slow": slow_family}
    return (*(f.name for f in REGISTRY.roles.chosen(chosen) if f.name in present),
            *(made[kind](role, width).name for (kind, role), width in sorted(widest.items())),
            *sorted(n for n in unregistered if _as_is(n)))


def _has(own: Sequence[str], name: str) -> bool:
    """Whether families ``own`` (a recording's) cover ``name``: by name, or a generic or slow family by its
    kind and role."""
    if name in REGISTRY.roles or _as_is(name):
        return name in own
    kind, role = name.partition(".")[0], _family(name).role
    return any(f not in REGISTRY.roles and f.partition(".")[0] == kind and _family(f).role == role for f in own)


def _own(recording: Recording, applied: Sequence[str]) -> list[str]:
    """The families of a recording that cover one of ``applied``."""
    return [f for f in families(recording, list(applied)) if any(_has([f], name) for name in applied)]


def lacking(recordings: Sequence[Recording], found: Sequence[Sequence[str]], applied: Sequence[str],
            first: int = 3) -> list[str]:
    """One line per family that some recordings of the set lack (their columns are NaN there): the role it
    needs, how many lack it and the first few names.

    Parameters
    ----------
    recordings : sequence of Recording
        The set.
    found : sequence of sequence of str
        The families of each recording (:func:`families`), in the order of ``recordings``.
    applied : sequence of str
        The set's families.
    first : int, default 3
        How many names of recordings to show per line.

    Returns
    -------
    list of str
        One line per family of ``applied`` that a recording lacks, in the order of ``applied``.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Recording, Trace
    >>> both = Recording("both", {"f": Trace(np.ones((300, 3)), 100.0, "N"),
    ...                           "s": Trace(np.ones(100), 100.0, "-")},
    ...                  {"force_xyz": "f", "signal_s": "s"}, "cork")
    >>> bare = [Recording(f"bare{k}", {"s": Trace(np.ones(100), 100.0, "-")}, {"signal_s": "s"}, "oak")
    ...         for k in range(4)]
    >>> found = [families(r) for r in [both, *bare]]
    >>> found[0]
    ['friction', 'generic.signal_s']
    >>> for line in lacking([both, *bare], found, found[0], first=2):
    ...     print(line)  # doctest: +NORMALIZE_WHITESPACE
    4 of 5 recording(s) lack the role force_xyz (at a rate friction applies to): its 2 column(s) are NaN there
    (bare0, bare1 and 2 more)
    """
    lines = []
    for name in applied:
        family = _family(name)
        without = [r.name for r, own in zip(recordings, found, strict=True) if not _has(own, name)]
        if without:
            shown = ", ".join(without[:first]) + (f" and {len(without) - first} more" if len(without) > first else "")
            roles = _roles_of(name, family)
            needed = f"the role {roles[0]}" if len(roles) == 1 else f"one of the roles {', '.join(roles)}"
            lines.append(f"{len(without)} of {len(recordings)} recording(s) lack {needed} (at a rate {name} "
                         f"applies to): its {len(family.columns)} column(s) are NaN there ({shown})")
    return lines


def _roles_of(name: str, family: RoleFamily) -> tuple[str, ...]:
    """The roles a family reads: both channels of a ratio family (``ratio.<role>.<other>:...``), else its role."""
    kind, _, rest = name.partition(".")
    return tuple(rest.partition(":")[0].split(".")) if kind == "ratio" else (family.role,)


def describe_families(names: Iterable[str]) -> str:
    """``audio.audio (35), image.photo (31)``: the families of a list of columns with their sizes.

    Parameters
    ----------
    names : iterable of str
        Column names ``<family>.<role>.<feature>``.

    Returns
    -------
    str
        Each ``<family>.<role>`` in order of first appearance with its number of columns, comma-separated.

    Examples
    --------
    >>> describe_families(["audio.audio.zcr", "audio.audio.f0", "image.photo.color", "generic.signal_speed.mean"])
    'audio.audio (2), image.photo (1), generic.signal_speed (1)'
    """
    counts: dict[str, int] = {}
    for name in names:
        family = ".".join(name.split(".")[:2])
        counts[family] = counts.get(family, 0) + 1
    return ", ".join(f"{family} ({count})" for family, count in counts.items())
