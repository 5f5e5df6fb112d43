"""The data model: a sampled ``Trace``, a generic ``Recording`` and one ``Scan`` of a material sample.

docs/database.md. Every object validates itself on construction, so a ``Scan`` that exists is a scan the
rest of the pipeline can trust: every channel has the shape, rate and unit of the table below and only
finite samples. Missing channels are allowed (features that need them become NaN); wrong ones are not.
"""

from __future__ import annotations

import html
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from datetime import datetime
from types import MappingProxyType
from typing import Any

import numpy as np

from scanner.photo import PhotoError, check_size
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label, LabelError

SCHEMA_VERSION = 1
JUDGED_SCALE = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The five-step scale of the operator's judged adhesive tack and yielding (paper section IV-A)."""
VOLUME_METHODS = ("water", "micro-pearls", "known")
"""How the TU4 volume was measured: water or micro-pearl displacement, or known (dimensions, supplier)."""

MAX_SCAN_INDEX = 9999
"""Scan indices are 1..9999: ``<sample>-<nnnn>`` ids stay short, and SQLite's 64-bit integers hold them."""
T_AMB_RANGE = (-40.0, 85.0)
"""Ambient temperature in degC: the MLX90614's ambient range."""
MAX_MASS_G = 1e6
MAX_VOLUME_CM3 = 1e6
"""A sample of up to a tonne and a cubic metre: anything larger is a typing error."""
MAX_CALIBRATION = 1e6
"""Calibration values (volts, g, degrees, seconds) are finite and at most this in magnitude, or NaN."""
MAX_META_KEYS = 64
MAX_TEXT = {"software_version": 64, "notes": 4000, "device": 256}
"""Longest text of ``meta.software_version``, ``meta.notes`` and each ``meta.device`` value."""
MAX_CHANNEL_SECONDS = 120.0
"""Longest recording of one channel: every step of the procedure takes seconds (docs/operator.md#procedure), and the
limit keeps a scan (and the memory its features need) bounded."""


class ScanError(TexplorerError, ValueError):
    """A trace, recording or scan violates the data model; the message names the field.

    ``field`` (e.g. ``"meta.atk"``) is set where one field is at fault, so file readers can report it.
    """

    def __init__(self, reason: str, field: str | None = None) -> None:
        self.reason = reason
        self.field = field
        super().__init__(f"{field}: {reason}" if field else reason)


@dataclass(frozen=True)
class ChannelSpec:
    """Expected layout of one scan channel: rate in Hz, unit, axes (0 = 1-D) and the step recording it."""

    fs: float
    unit: str
    axes: int
    step: str
    description: str
    min_n: int = 1
    """Samples the channel's features need (docs/features.md); a shorter channel is "too short", see
    :meth:`Scan.short_channels`."""

    @property
    def max_n(self) -> int:
        """Most samples a channel may hold: :data:`MAX_CHANNEL_SECONDS` at its rate."""
        return int(MAX_CHANNEL_SECONDS * self.fs)


CHANNELS: Mapping[str, ChannelSpec] = MappingProxyType({
    "v_ft": ChannelSpec(3000.0, "g", 3, "finger_tap", "TU1 acceleration, finger tap"),
    "v_fs": ChannelSpec(3000.0, "g", 3, "finger_slide", "TU1 acceleration, finger slide", 3000),
    "v_tt": ChannelSpec(3000.0, "g", 3, "tool_tap", "TU1 acceleration, tool tap", 30),
    "v_ts": ChannelSpec(3000.0, "g", 3, "tool_slide", "TU1 acceleration, tool slide", 3000),
    "a_fs": ChannelSpec(44100.0, "FS", 0, "finger_slide", "audio during the finger slide, full scale", 44100),
    "a_ts": ChannelSpec(44100.0, "FS", 0, "tool_slide", "audio during the tool slide, full scale", 44100),
    "r_fs": ChannelSpec(3000.0, "V", 0, "finger_slide", "IR reflectance during the finger slide"),
    "r_ts": ChannelSpec(3000.0, "V", 0, "tool_slide", "IR reflectance during the tool slide"),
    "f_frn": ChannelSpec(3000.0, "N", 0, "friction", "normal force during the friction slide", 331),
    "f_frt": ChannelSpec(3000.0, "N", 0, "friction", "tangential force during the friction slide", 331),
    "f_press": ChannelSpec(3000.0, "N", 0, "press", "normal force while pressing 4.0 mm", 2),
    "f_fold": ChannelSpec(3000.0, "N", 0, "fold", "normal force while folding", 2),
    "alpha_f": ChannelSpec(3000.0, "deg", 0, "fold", "flex angle while folding", 2),
    "t_cool": ChannelSpec(20.0, "degC", 0, "thermal", "MLX90614 object temperature after heating", 3),
    "m": ChannelSpec(3000.0, "-", 0, "static", "metal electrode, +1 conductive, -1 not"),
    "dB": ChannelSpec(80.0, "uT", 0, "static", "change of magnetic field magnitude"),
})
"""The scan channels of docs/database.md, in file order.

``min_n``: the 1 s slide window (3000 vibration, 44100 audio samples; docs/features.md#preprocessing), 30 samples after
the tap
peak (docs/features.md#other), the 0.1 s friction offset plus one 10 ms slope lag (docs/features.md#preprocessing,
docs/features.md#frs), two samples
for a spread or a relaxation (a single sample has zero spread: a silent 0, docs/features.md), three for the cooling fit.
The IR channels need one sample: ``reflect_static`` uses whatever precedes the slide start.
"""

IMAGES: Mapping[str, str] = MappingProxyType({
    "I_disp": "disp",
    "I_macro": "macro",
    "I_illu": "illu",
})
"""Photo variables -> short name used in file names and feature names (docs/database.md; docs/features.md#image)."""

PROCEDURE_STEPS: tuple[str, ...] = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal",
                                     "friction", "press", "fold", "photos", "tu4")
"""The steps of the scanning procedure in order (docs/operator.md#procedure): the recorded ones (each channel's
``ChannelSpec.step``), the photos and the TU4 values."""


def check_steps(steps: Any) -> str:
    """``meta.steps``: "" for a full scan (every file written before partial scans existed), or the steps a
    partial (quick) scan holds, comma-separated; returned in procedure order. A ScanError names a step that
    is not one of :data:`PROCEDURE_STEPS`, a repeated one, or a list naming every step (write "")."""
    if not isinstance(steps, str) or len(steps) > 200:
        raise ScanError(f"{_short(steps)} must be step names separated by commas", "meta.steps")
    if not steps:
        return ""
    names = [name.strip() for name in steps.split(",")]
    unknown = [name for name in names if name not in PROCEDURE_STEPS]
    if unknown:
        raise ScanError(f"{_short(unknown[0])} is not a step of the procedure ({', '.join(PROCEDURE_STEPS)})",
                        "meta.steps")
    if len(set(names)) < len(names):
        raise ScanError(f"{_short(steps)} names a step twice", "meta.steps")
    if len(names) == len(PROCEDURE_STEPS):
        raise ScanError("names every step: a full scan stores meta.steps as empty text", "meta.steps")
    return ",".join(step for step in PROCEDURE_STEPS if step in names)


ROLES = frozenset({
    "vibration", "pressure_dc", "temperature", "heat_flow", "electrodes", "taxels", "force_xyz", "audio",
    "photo", "signal",
})
"""Channel roles read by the feature sets (docs/database.md; docs/features.md#related); ``photo`` names an image of the
recording; ``signal`` is any other numeric sensor channel (a gyroscope, a motor current, a wheel speed), which
a recording may have several of (:func:`role_key`)."""

GENERIC_ROLE = "signal"
"""The role of any numeric channel that plays none of the others; its key in ``Recording.roles`` names the
channel (:func:`role_key`)."""


def role_key(role: str, channel: str) -> str:
    """The key of ``channel`` playing ``role`` in ``Recording.roles``: the role, or for the generic role
    ``signal_<channel>`` (a recording may have any number of generic channels)."""
    return f"{GENERIC_ROLE}_{channel}" if role == GENERIC_ROLE else role


def is_generic(role: str) -> bool:
    """Whether a ``Recording.roles`` key is a generic channel's (``signal_<channel>``)."""
    return role.startswith(GENERIC_ROLE + "_") and _FIELD.fullmatch(role) is not None

IMAGE_ROLES = frozenset({"photo"})
"""Roles played by images (RGB uint8 (h, w, 3)) instead of sampled channels."""

_SAFE_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
_OPERATOR = re.compile(r"[^\x00-\x1f\x7f/\\<>\"']{1,64}")
_FIELD = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,62}")
"""MATLAB struct field names: device and calibration keys become fields of ``meta``."""


def _taken_as_is(data: object) -> bool:
    """Whether a :class:`Trace` takes ``data`` without copying it: a float64 array that owns its memory and
    is read-only (another trace's data, or an array :func:`handed_over`) cannot change under the trace."""
    return (isinstance(data, np.ndarray) and data.dtype == np.float64 and data.flags.owndata
            and not data.flags.writeable)


def handed_over(array: np.ndarray) -> np.ndarray:
    """``array``, made read-only so that a :class:`Trace` takes it without a copy (a reader's 320 MB channel
    would otherwise be held twice). Only for an array its caller just made and keeps no writeable view of."""
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class Trace:
    """A uniformly sampled signal.

    Parameters
    ----------
    data : numpy.ndarray
        Samples of shape (n,) or (n, channels), or (n, h, w) for taxels; stored read-only as float64, so
        features can never modify a scan in place.
    fs : float
        Sample rate in Hz.
    unit : str
        Physical unit of the samples (``"g"``, ``"N"``, ``"V"``, ``"FS"``, ...).

    Raises
    ------
    ScanError
        If the data are not finite, empty, of another shape, or the rate is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Trace
    >>> t = Trace(np.zeros((3000, 3)), 3000.0, "g")
    >>> t.data.shape, t.fs
    ((3000, 3), 3000.0)
    """

    data: np.ndarray
    fs: float
    unit: str

    def __post_init__(self) -> None:
        try:
            array = self.data if _taken_as_is(self.data) else np.array(self.data, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as exc:
            raise ScanError(f"trace data is not numeric: {exc}") from None
        if array.ndim not in (1, 2, 3):
            raise ScanError(f"trace data must be 1-D, 2-D or 3-D, got shape {array.shape}")
        if array.shape[0] == 0 or array.size == 0:
            raise ScanError(f"trace is empty (shape {array.shape})")
        bad = ~np.isfinite(array)
        if bad.any():
            first = int(np.argwhere(bad)[0][0])
            raise ScanError(f"trace has {int(bad.sum())} non-finite samples (first at sample {first})")
        try:
            fs = float(self.fs)
        except (TypeError, ValueError):
            raise ScanError(f"sample rate must be a number, got {self.fs!r}") from None
        if not math.isfinite(fs) or fs <= 0:
            raise ScanError(f"sample rate must be finite and positive, got {self.fs!r}")
        if not isinstance(self.unit, str) or not self.unit.strip():
            raise ScanError(f"unit must be a non-empty string, got {self.unit!r}")
        array.flags.writeable = False
        object.__setattr__(self, "data", array)
        object.__setattr__(self, "fs", fs)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.data.shape[0])

    @property
    def duration(self) -> float:
        """Length in seconds (n / fs)."""
        return self.n / self.fs

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Trace):
            return NotImplemented
        return (self.fs == other.fs and self.unit == other.unit
                and self.data.shape == other.data.shape and bool(np.array_equal(self.data, other.data)))

    __hash__ = None  # type: ignore[assignment]


def _rebuild_args(obj: Any) -> tuple[Any, ...]:
    """Constructor arguments of a frozen dataclass with read-only mappings turned back into dicts."""
    return tuple(dict(v) if isinstance(v, MappingProxyType) else v for v in (getattr(obj, f.name) for f in fields(obj)))


class _Picklable:
    """Pickle by re-running the validating constructor: mapping proxies cannot be pickled, and a scan that
    crosses a process boundary (parallel feature extraction) is checked again on arrival."""

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return self.__class__, _rebuild_args(self)


def _check_judged(name: str, value: float) -> float:
    value = float(value)
    if math.isnan(value):
        return value
    if value not in JUDGED_SCALE:
        raise ScanError(f"{value!r} is not on the five-step scale {JUDGED_SCALE} (or NaN)", f"meta.{name}")
    return value


def _check_optional_number(name: str, value: Any, low: float, high: float, *, positive: bool = False) -> float:
    """A number in ``[low, high]`` (``(0, high]`` if ``positive``), or NaN for "not measured"."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ScanError(f"must be a number or NaN, got {value!r}", f"meta.{name}") from None
    if math.isnan(number):
        return number
    if positive and not 0 < number <= high:
        raise ScanError(f"{value!r} must be positive and at most {high:g}, or NaN", f"meta.{name}")
    if not low <= number <= high:
        raise ScanError(f"{value!r} must be between {low:g} and {high:g}, or NaN", f"meta.{name}")
    return number


def _check_text(name: str, value: Any, limit: int) -> str:
    if not isinstance(value, str):
        raise ScanError(f"must be text, got {type(value).__name__}", f"meta.{name}")
    if len(value) > limit:
        raise ScanError(f"{len(value)} characters, at most {limit} are allowed", f"meta.{name}")
    return value


def check_scan_index(scan_index: Any) -> int:
    """Scan indices are whole numbers 1..:data:`MAX_SCAN_INDEX` (the ``nnn`` of ``<sample>-<nnn>``)."""
    if isinstance(scan_index, bool):
        raise ScanError(f"must be a whole number 1..{MAX_SCAN_INDEX}, got {scan_index!r}", "meta.scan_index")
    try:
        number = float(scan_index)
    except (TypeError, ValueError, OverflowError):
        raise ScanError(f"must be a whole number 1..{MAX_SCAN_INDEX}, got {scan_index!r}", "meta.scan_index") from None
    if not (math.isfinite(number) and number.is_integer() and 1 <= number <= MAX_SCAN_INDEX):
        shown = f"{number:.6g}" if math.isfinite(number) else repr(scan_index)
        raise ScanError(f"must be a whole number 1..{MAX_SCAN_INDEX}, got {shown}", "meta.scan_index")
    return int(number)


def check_sample_id(sample_id: str) -> str:
    """Sample ids become folder names: 1-64 characters of letters, digits, '.', '_', '-'."""
    if not isinstance(sample_id, str) or not _SAFE_ID.fullmatch(sample_id):
        raise ScanError(f"sample id {_short(sample_id)} must be 1-64 letters, digits, '.', '_' or '-' "
                        "and start with a letter or digit", "meta.sample_id")
    return sample_id


@dataclass(frozen=True)
class ScanMeta(_Picklable):
    """The ``meta`` struct of docs/database.md (``fs``, ``units`` and ``raw_volts`` derive from the traces).

    Unknown numeric values (ambient temperature not read, mass not weighed, tack not judged) are NaN.
    """

    label: str
    operator: str
    sample_id: str
    scan_index: int
    session_id: str
    started: str
    t_amb: float = math.nan
    mass_g: float = math.nan
    volume_cm3: float = math.nan
    volume_method: str = ""
    atk: float = math.nan
    cyd: float = math.nan
    rigid: bool = False
    device: Mapping[str, str] = field(default_factory=dict)
    calibration: Mapping[str, float] = field(default_factory=dict)
    software_version: str = ""
    schema_version: int = SCHEMA_VERSION
    notes: str = ""
    steps: str = ""
    """"" for a full scan; for a partial (quick) scan the steps it holds, comma-separated in procedure order
    (:func:`check_steps`): the features of the others are missing (NaN), not zero."""

    def __post_init__(self) -> None:
        try:
            object.__setattr__(self, "label", Label.parse(self.label).format())
        except LabelError as exc:
            raise ScanError(str(exc), "meta.label") from None
        if not isinstance(self.operator, str) or not _OPERATOR.fullmatch(self.operator.strip() or "\x00"):
            raise ScanError(f"{_short(self.operator)} must be 1-64 printable characters "
                            "without quotes, slashes or angle brackets", "meta.operator")
        check_sample_id(self.sample_id)
        if not isinstance(self.session_id, str) or not _SAFE_ID.fullmatch(self.session_id):
            raise ScanError(f"{_short(self.session_id)} must be 1-64 letters, digits, '.', '_', '-'", "meta.session_id")
        object.__setattr__(self, "scan_index", check_scan_index(self.scan_index))
        if not isinstance(self.started, str) or len(self.started) > 64 or not _is_iso8601(self.started):
            raise ScanError(f"{_short(self.started)} is not an ISO 8601 date-time", "meta.started")
        object.__setattr__(self, "t_amb", _check_optional_number("t_amb", self.t_amb, *T_AMB_RANGE))
        object.__setattr__(self, "mass_g", _check_optional_number("mass_g", self.mass_g, 0, MAX_MASS_G,
                                                                  positive=True))
        object.__setattr__(self, "volume_cm3", _check_optional_number("volume_cm3", self.volume_cm3, 0,
                                                                      MAX_VOLUME_CM3, positive=True))
        if self.volume_method not in ("", *VOLUME_METHODS):
            raise ScanError(f"{_short(self.volume_method)} is not one of {', '.join(VOLUME_METHODS)} (or empty)",
                            "meta.volume_method")
        object.__setattr__(self, "atk", _check_judged("atk", self.atk))
        object.__setattr__(self, "cyd", _check_judged("cyd", self.cyd))
        object.__setattr__(self, "rigid", bool(self.rigid))
        if self.schema_version != SCHEMA_VERSION:
            raise ScanError(f"{self.schema_version!r} is not supported (this software reads {SCHEMA_VERSION})",
                            "meta.schema_version")
        _check_text("software_version", self.software_version, MAX_TEXT["software_version"])
        _check_text("notes", self.notes, MAX_TEXT["notes"])
        object.__setattr__(self, "steps", check_steps(self.steps))
        for name in ("device", "calibration"):
            keys = list(getattr(self, name))
            if len(keys) > MAX_META_KEYS:
                raise ScanError(f"{len(keys)} entries, at most {MAX_META_KEYS} are allowed", f"meta.{name}")
            for key in keys:
                if not isinstance(key, str) or not _FIELD.fullmatch(key):
                    raise ScanError(f"key {_short(key)} is not a valid MATLAB field name", f"meta.{name}")
        object.__setattr__(self, "device", MappingProxyType(
            {k: _check_text(f"device.{k}", str(v), MAX_TEXT["device"]) for k, v in self.device.items()}))
        object.__setattr__(self, "calibration", MappingProxyType(
            {str(k): _check_optional_number(f"calibration.{k}", v, -MAX_CALIBRATION, MAX_CALIBRATION)
             for k, v in self.calibration.items()}))

    @property
    def scan_id(self) -> str:
        """``<sample_id>-<scan_index:03d>``: unique within a database."""
        return f"{self.sample_id}-{self.scan_index:03d}"

    @property
    def partial(self) -> bool:
        """A quick scan that holds only some steps (:attr:`steps`)."""
        return bool(self.steps)

    @property
    def step_list(self) -> tuple[str, ...]:
        """The steps the scan holds, in procedure order (all of them for a full scan)."""
        return tuple(self.steps.split(",")) if self.steps else PROCEDURE_STEPS

    def __eq__(self, other: object) -> bool:
        # NaN marks "not measured"; two metas that both lack a value are equal.
        if not isinstance(other, ScanMeta):
            return NotImplemented
        return all(_same(getattr(self, f.name), getattr(other, f.name)) for f in fields(self))

    __hash__ = None  # type: ignore[assignment]


def _short(value: Any) -> str:
    """``repr`` of at most 60 characters, so a hostile value still gives a one-line message."""
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, Mapping) and isinstance(b, Mapping):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


def _is_iso8601(text: str) -> bool:
    try:
        datetime.fromisoformat(text)
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class Scan(_Picklable):
    """One pass of all exploratory procedures over one material sample (docs/database.md).

    A scan validates itself on construction, so a ``Scan`` that exists is one the ``.mat`` format can store.

    Parameters
    ----------
    meta : ScanMeta
        Label, operator, sample and session ids, ambient temperature, mass, volume, judged values, device.
    traces : mapping of str to Trace
        Channels of :data:`CHANNELS` (``v_ts``, ``a_ts``, ``f_frn``, ...); missing optional channels are
        allowed, and the features that need them are NaN.
    images : mapping of str to numpy.ndarray
        ``I_disp``, ``I_macro``, ``I_illu`` as RGB ``uint8`` arrays of shape (h, w, 3).
    raw : mapping of str to Trace
        The DAQ volts of a channel (saved as ``<name>_raw``), so a calibration can be redone.

    Raises
    ------
    ScanError
        A channel of the wrong rate, unit, shape or length, an unknown channel, or a bad photo.

    See Also
    --------
    scanner.load_scan, scanner.save_scan, scanner.Database.get
    """

    meta: ScanMeta
    traces: Mapping[str, Trace] = field(default_factory=dict)
    images: Mapping[str, np.ndarray] = field(default_factory=dict)
    raw: Mapping[str, Trace] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.meta, ScanMeta):
            raise ScanError("scan.meta must be a ScanMeta")
        for name, trace in self.traces.items():
            _check_channel(name, trace)
        for name, trace in self.raw.items():
            if name not in CHANNELS:
                raise ScanError(f"raw channel {_short(name)} is not a scan channel")
            if not isinstance(trace, Trace) or trace.unit != "V":
                raise ScanError(f"raw channel {name}_raw must be a Trace in V")
            _check_length(f"{name}_raw", trace, CHANNELS[name])
        images = {}
        for name, image in self.images.items():
            images[name] = _check_image(name, image)
        ordered = {name: self.traces[name] for name in CHANNELS if name in self.traces}
        object.__setattr__(self, "traces", MappingProxyType(ordered))
        object.__setattr__(self, "images", MappingProxyType(images))
        object.__setattr__(self, "raw", MappingProxyType(dict(self.raw)))

    @property
    def scan_id(self) -> str:
        return self.meta.scan_id

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Scan):
            return NotImplemented
        return (self.meta == other.meta and dict(self.traces) == dict(other.traces)
                and dict(self.raw) == dict(other.raw) and self.images.keys() == other.images.keys()
                and all(np.array_equal(self.images[k], other.images[k]) for k in self.images))

    __hash__ = None  # type: ignore[assignment]

    def __getitem__(self, name: str) -> Trace:
        try:
            return self.traces[name]
        except KeyError:
            raise KeyError(f"scan {self.scan_id} has no channel {name!r}") from None

    def get(self, name: str) -> Trace | None:
        """The trace of a channel, or None if the scan does not have it."""
        return self.traces.get(name)

    def missing_channels(self) -> list[str]:
        """Channels of docs/database.md this scan does not have (fold channels count as present when rigid)."""
        absent = [name for name in CHANNELS if name not in self.traces]
        if self.meta.rigid:
            absent = [name for name in absent if name not in ("f_fold", "alpha_f")]
        return absent

    def short_channels(self) -> dict[str, int]:
        """Channels holding fewer samples than their features need -> that need (``ChannelSpec.min_n``).

        Such a scan is valid (a test session with short steps records them); its features treat these
        channels as missing, so they are NaN rather than computed from too little data.
        """
        return {name: CHANNELS[name].min_n for name, trace in self.traces.items() if trace.n < CHANNELS[name].min_n}

    def __repr__(self) -> str:
        """One line: id, label, sample, channels and photos (the values: ``scan.traces``, ``scan.images``)."""
        return f"Scan({self._summary()})"

    def _summary(self) -> str:
        meta = self.meta
        return (f"{meta.scan_id}, label {meta.label}, sample {meta.sample_id}, {len(self.traces)} channels, "
                f"{len(self.images)} photos" + (f", {len(self.raw)} raw" if self.raw else ""))

    def _repr_html_(self) -> str:
        """The :meth:`__repr__` line and a table of the channels (samples, rate, duration, unit) and photos."""
        rows = [(name, "x".join(map(str, trace.data.shape)), f"{trace.fs:g} Hz", f"{trace.duration:.2f} s",
                 trace.unit) for name, trace in self.traces.items()]
        rows += [(name, "x".join(map(str, image.shape)), "", "", "RGB") for name, image in self.images.items()]
        cells = "".join("<tr>" + "".join(f"<td>{html.escape(cell)}</td>" for cell in row) + "</tr>" for row in rows)
        meta = self.meta
        return (f"<p>Scan {html.escape(self._summary())}; session {html.escape(meta.session_id)}, operator "
                f"{html.escape(meta.operator)}, started {html.escape(meta.started)}</p><table><thead><tr><th>"
                "channel</th><th>shape</th><th>rate</th><th>duration</th><th>unit</th></tr></thead>"
                f"<tbody>{cells}</tbody></table>")

    @property
    def fold_despite_rigid(self) -> bool:
        """``meta.rigid`` = 1 while a fold is stored: the stored fold wins (Strese et al. 2020, eq. 21;
        docs/features.md#cdf)."""
        return self.meta.rigid and bool({"f_fold", "alpha_f"} & set(self.traces))


def _check_channel(name: str, trace: Trace) -> None:
    spec = CHANNELS.get(name)
    if spec is None:
        raise ScanError(f"{name!r} is not a scan channel (known: {', '.join(CHANNELS)})")
    if not isinstance(trace, Trace):
        raise ScanError(f"{name} must be a Trace, got {type(trace).__name__}")
    if trace.fs != spec.fs:
        raise ScanError(f"sampled at {trace.fs:g} Hz, expected {spec.fs:g} Hz", name)
    if trace.unit != spec.unit:
        raise ScanError(f"unit {trace.unit!r}, expected {spec.unit!r}", name)
    expected = (trace.n, spec.axes) if spec.axes else (trace.n,)
    if trace.data.shape != expected:
        want = f"(n, {spec.axes})" if spec.axes else "(n,)"
        raise ScanError(f"shape {trace.data.shape}, expected {want}", name)
    _check_length(name, trace, spec)


def _check_length(name: str, trace: Trace, spec: ChannelSpec) -> None:
    if trace.n > spec.max_n:
        raise ScanError(f"{trace.n} samples, more than the {spec.max_n} ({MAX_CHANNEL_SECONDS:g} s at "
                        f"{spec.fs:g} Hz) a channel may hold", name)


def _check_image(name: str, image: np.ndarray) -> np.ndarray:
    if name not in IMAGES:
        raise ScanError(f"{name!r} is not a photo variable (known: {', '.join(IMAGES)})")
    array = np.asarray(image)
    if array.dtype != np.uint8 or array.ndim != 3 or array.shape[2] != 3 or min(array.shape[:2]) < 1:
        raise ScanError(f"{name} must be an RGB uint8 image of shape (h, w, 3), "
                        f"got {array.dtype} {array.shape}")
    try:
        check_size(array.shape[1], array.shape[0], name=name)
    except PhotoError as problem:
        raise ScanError(str(problem).removeprefix(f"{name}: "), name) from None
    view = array.view()
    view.flags.writeable = False
    return view


@dataclass(frozen=True)
class Recording(_Picklable):
    """A generic recording from another sensor or dataset (docs/ingest.md).

    Parameters
    ----------
    name : str
        Identifier of the recording within its set.
    channels : mapping of str to Trace
        Named traces, each at its own rate.
    roles : mapping of str to str
        A role of :data:`ROLES` (``vibration``, ``audio``, ``force_xyz``, ``photo``, ...) to a channel name
        (an image name for ``photo``): how the feature sets (docs/features.md#related) find their inputs.
    label : str, optional
        The class: any string, a taxonomy label where known.
    group : mapping of str to str
        Object or sample ids used for grouped splits (``{"object": "cork-1"}``).
    meta : mapping of str to object
        Free metadata kept with the recording.
    images : mapping of str to numpy.ndarray
        Named RGB photos (uint8, (h, w, 3)), e.g. a texture photo or one patch of it.

    Raises
    ------
    ScanError
        A role naming a missing channel, an unknown role, or a channel of the wrong shape for its role.
    """

    name: str
    channels: Mapping[str, Trace]
    roles: Mapping[str, str] = field(default_factory=dict)
    label: str | None = None
    group: Mapping[str, str] = field(default_factory=dict)
    meta: Mapping[str, Any] = field(default_factory=dict)
    images: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ScanError("recording name must be a non-empty string")
        if not self.channels and not self.images:
            raise ScanError(f"recording {self.name!r} has no channels")
        for channel, trace in self.channels.items():
            if not isinstance(trace, Trace):
                raise ScanError(f"recording {self.name!r}: channel {channel!r} must be a Trace")
        images = {name: _checked_image(self.name, name, image) for name, image in self.images.items()}
        for role, channel in self.roles.items():
            if role not in ROLES - {GENERIC_ROLE} and not is_generic(role):
                raise ScanError(f"recording {self.name!r}: unknown role {role!r} (known: {', '.join(sorted(ROLES))})")
            if role in IMAGE_ROLES:
                if channel not in images:
                    raise ScanError(f"recording {self.name!r}: role {role!r} names missing image {channel!r}")
                continue
            if channel not in self.channels:
                raise ScanError(f"recording {self.name!r}: role {role!r} names missing channel {channel!r}")
            _check_role_shape(self.name, role, self.channels[channel])
        object.__setattr__(self, "channels", MappingProxyType(dict(self.channels)))
        object.__setattr__(self, "images", MappingProxyType(images))
        object.__setattr__(self, "roles", MappingProxyType(dict(self.roles)))
        object.__setattr__(self, "group", MappingProxyType({str(k): str(v) for k, v in self.group.items()}))
        object.__setattr__(self, "meta", MappingProxyType(dict(self.meta)))

    def role(self, role: str) -> Trace | None:
        """The trace playing ``role``, or None (see :meth:`image` for ``photo``)."""
        channel = self.roles.get(role)
        return None if channel is None or role in IMAGE_ROLES else self.channels[channel]

    def image(self, role: str = "photo") -> np.ndarray | None:
        """The image playing ``role``, or None."""
        name = self.roles.get(role)
        return None if name is None or role not in IMAGE_ROLES else self.images[name]


def _checked_image(recording: str, name: str, image: Any) -> np.ndarray:
    """A read-only RGB uint8 (h, w, 3) copy of ``image``; ScanError naming the recording otherwise."""
    array = np.array(image, copy=True)
    if array.dtype != np.uint8 or array.ndim != 3 or array.shape[2] != 3 or min(array.shape[:2]) == 0:
        raise ScanError(f"recording {recording!r}: image {name!r} must be RGB uint8 (h, w, 3), "
                        f"got {array.dtype} of shape {array.shape}")
    array.flags.writeable = False
    return array


_ROLE_NDIM = {"electrodes": 2, "taxels": 3, "force_xyz": 2}


def _check_role_shape(name: str, role: str, trace: Trace) -> None:
    ndim = _ROLE_NDIM.get(role, 1)
    if (role in ("vibration", "audio") or is_generic(role)) and trace.data.ndim == 2:
        return  # multi-axis vibration/audio is combined by the feature set (DFT321 or mean)
    if trace.data.ndim != ndim:
        raise ScanError(f"recording {name!r}: role {role!r} needs a {ndim}-D channel, got shape {trace.data.shape}")
    if role == "force_xyz" and trace.data.shape[1] != 3:
        raise ScanError(f"recording {name!r}: role 'force_xyz' needs shape (n, 3), got {trace.data.shape}")
