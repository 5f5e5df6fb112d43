"""The guided scanning session (docs/operator.md#procedure) as a state machine that knows nothing about its user
interface.

The terminal (``texplorer scan``) and the web page (``texplorer serve``) are thin layers over the same
:class:`Session`::

    session = Session.open(config, label="C6S1M1P2X1", sample_id="granite-01", operator="ab", db=db)
    for step in session.steps:                      # StepInfo: id, title, instruction, duration_s, ...
        if step.kind == "record":
            status = session.record(step.id, level=show)   # blocking; or start_step() + wait()
            if status.problems: ...                  # the quality check: redo(step.id) or keep it
    session.capture_photo("I_disp")                 # or set_photo("I_disp", rgb array or file bytes)
    session.set_values(atk=0.0, cyd=0.25, mass_g=512.0, volume_cm3=190.0, volume_method="water")
    scan_id = session.save(db)                      # or session.abort(): the database is untouched

Steps, in the order of docs/operator.md#procedure (durations from the configuration):

========  ==============  ==========================================================================
step      kind            channels
========  ==============  ==========================================================================
1-4       record          TU1 finger tap, finger slide (+ audio, IR), tool tap, tool slide (+ audio, IR)
5         record          TU2 static touch: metal electrode ``m``, magnetometer ``dB``
6         record          TU2 thermal: the Peltier heats (at most 5 s), then ``t_cool`` while cooling
7-9       record          TU2 friction slide, press, fold (skippable: rigid sample, ``meta.rigid`` = 1)
10        photos          TU3 ``I_disp``, ``I_macro`` (4x lens), ``I_illu`` (flash)
11        form            TU4 mass, volume (and how it was measured), judged tack and yielding
========  ==============  ==========================================================================

Every state change is explicit and checked; a refused one raises :class:`SessionError` saying why.
A step is ``pending`` -> ``recording`` -> ``recorded`` (with its quality problems, maybe none) or
``failed`` (a device lost data: no recording kept). ``redo`` returns a recorded, failed or skipped step to
``pending``; only the fold can be ``skipped``. The session is ``open`` until ``save`` (all recording steps
recorded or skipped, three photos, the TU4 values) or ``abort``; both release the devices, with the Peltier
switched off first. ``t_amb`` is read from the board's ambient sensor when the session opens and can be
edited.
"""

from __future__ import annotations

import enum
import math
import secrets
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from typing import Any

import numpy as np

from scanner.acquisition.config import Config
from scanner.acquisition.devices import Devices, open_devices
from scanner.acquisition.devices.camera import decode_photo
from scanner.acquisition.devices.protocols import DeviceError
from scanner.acquisition.devices.sources import Specimen
from scanner.acquisition.recorder import Level, Recorder, StepResult, build_scan
from scanner.photo import PhotoError, check_size
from scanner.preprocess import small_photo_note
from scanner.scan import (
    CHANNELS,
    IMAGES,
    JUDGED_SCALE,
    T_AMB_RANGE,
    VOLUME_METHODS,
    Scan,
    ScanError,
    ScanMeta,
    check_sample_id,
)
from scanner.version import __version__
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label, LabelError


class SessionError(TexplorerError, ValueError):
    """A session action that is not allowed now (or a bad value); the message says why in one line."""


class StepState(enum.StrEnum):
    PENDING = "pending"
    RECORDING = "recording"
    RECORDED = "recorded"
    FAILED = "failed"
    SKIPPED = "skipped"


class SessionState(enum.StrEnum):
    OPEN = "open"
    SAVED = "saved"
    ABORTED = "aborted"


@dataclass(frozen=True)
class StepInfo:
    """One step of docs/operator.md#procedure as a user interface shows it."""

    id: str
    number: int
    title: str
    instruction: str
    duration_s: float
    channels: tuple[str, ...]
    skippable: bool
    kind: str
    """"record" (devices), "photos" (camera or upload) or "form" (typed values)."""
    handling_s: float = 0.0
    """The operator's time for the step besides its recording (``[handling]`` of the configuration)."""

    @property
    def seconds(self) -> float:
        """The whole step: recording and handling."""
        return self.duration_s + self.handling_s


@dataclass(frozen=True)
class StepStatus:
    """Where a step is: its state, the quality problems of its recording, the error that failed it."""

    step: str
    state: StepState
    problems: tuple[str, ...] = ()
    error: str = ""


_STEPS = (
    ("finger_tap", "TU1 finger tap", "Rest a finger on TU1's accelerometer pad and tap the surface with "
     "it, about twice a second, until the recording ends."),
    ("finger_slide", "TU1 finger slide", "Hold TU1 still on the surface with your finger for a moment, "
     "then slide it over the surface at a steady pace until the recording ends."),
    ("tool_tap", "TU1 tool tap", "Mount the steel tool tip, then tap the surface with it about twice a "
     "second until the recording ends."),
    ("tool_slide", "TU1 tool slide", "With the tool tip mounted, hold TU1 still on the surface for a "
     "moment, then slide the tip over the surface at a steady pace."),
    ("static", "TU2 static touch", "Hold TU2 in the air (the magnetometer is zeroed now), then place it "
     "flat on the sample and keep it still."),
    ("thermal", "TU2 heating and cooling", "Press TU2's Peltier element onto the surface while it heats; "
     "when told, lift TU2 and hold the temperature sensor over the heated spot."),
    ("friction", "TU2 friction slide", "Press TU2's finger contact onto the surface, push until it slips, "
     "slide a few centimetres, then release."),
    ("press", "TU2 press", "Press TU2 into the sample until the casing stops it (4.0 mm) and hold it "
     "there until the recording ends."),
    ("fold", "TU2 fold", "Grip the sample edge in TU2 and fold it once or twice, then release. Skip this "
     "step for a rigid sample."),
    ("photos", "TU3 photos", "Take the display photo, mount the 4x lens for the macro photo, then switch "
     "the flash on for the illuminated photo (or upload three PNG/JPEG files)."),
    ("tu4", "TU4 mass, volume and judgement", "Weigh the sample, measure its volume by water or "
     "micro-pearl displacement, and judge its adhesive tack and yielding on the five-step scale."),
)


STEP_TITLES: dict[str, tuple[int, str]] = {step: (number, title)
                                           for number, (step, title, _) in enumerate(_STEPS, start=1)}
"""Step id -> (number, title), as :func:`procedure` numbers them, for pages that show a stored scan."""


def procedure(config: Config) -> tuple[StepInfo, ...]:
    """The steps of docs/operator.md#procedure with the configured durations."""
    steps = []
    # Numbered by position, so every step has its own number: the static touch and the heating and cooling
    # are one part of the procedure but two steps here, each recorded and redone on its own.
    for number, (step, title, instruction) in enumerate(_STEPS, start=1):
        if step == "photos":
            info = StepInfo(step, number, title, instruction, 0.0, tuple(IMAGES), False, "photos")
        elif step == "tu4":
            info = StepInfo(step, number, title, instruction, 0.0, (), False, "form")
        else:
            duration = getattr(config.steps, step) + (config.steps.heat if step == "thermal" else 0.0)
            channels = tuple(name for name, spec in CHANNELS.items() if spec.step == step)
            info = StepInfo(step, number, title, instruction, duration, channels, step == "fold", "record")
        steps.append(replace(info, handling_s=getattr(config.handling, step)))
    return tuple(steps)


def step_seconds(config: Config) -> dict[str, float]:
    """Each step's whole time, recording and handling, in the order of the procedure."""
    return {step.id: step.seconds for step in procedure(config)}


@dataclass
class _Values:
    atk: float = math.nan
    cyd: float = math.nan
    mass_g: float = math.nan
    volume_cm3: float = math.nan
    volume_method: str = ""
    notes: str = ""


@dataclass
class _Step:
    state: StepState = StepState.PENDING
    result: StepResult | None = None
    error: str = ""


class Session:
    """One guided scan of one sample by one operator (see the module docstring).

    Use :meth:`open` to build the devices from a configuration; the constructor takes open devices.
    """

    def __init__(self, devices: Devices, config: Config, *, label: str, sample_id: str, operator: str,
                 t_amb: float | None = None, session_id: str | None = None) -> None:
        now = datetime.now(UTC)
        self.config = config
        self.devices = devices
        self.recorder = Recorder(devices, config)
        self.started = now.isoformat(timespec="seconds")
        self.session_id = session_id or f"{now:%Y%m%dT%H%M%S}-{secrets.token_hex(2)}"
        try:
            probe = ScanMeta(label=label, operator=operator, sample_id=sample_id, scan_index=1,
                             session_id=self.session_id, started=self.started)
        except ScanError as exc:
            raise SessionError(str(exc)) from None
        self.label, self.operator, self.sample_id = probe.label, probe.operator, probe.sample_id
        self.steps = procedure(config)
        self.state = SessionState.OPEN
        self.warnings: list[str] = []
        if config.implementation("camera") == "simulated":
            self._warn_small_photos(*config.simulated.image_size)
        self.level: Level | None = None
        self._steps = {step.id: _Step() for step in self.steps}
        self._photos: dict[str, np.ndarray] = {}
        self._values = _Values()
        self._cancel = threading.Event()
        self._idle = threading.Event()
        self._idle.set()
        self.worker_error: BaseException | None = None
        self._lock = threading.RLock()
        self._t_amb = math.nan
        if t_amb is None:
            t_amb = self._read_ambient()
        self.t_amb = t_amb

    @classmethod
    def open(cls, config: Config, *, label: str, sample_id: str, operator: str, db: Any = None,
             **kwargs: Any) -> Session:
        """Open the configured devices and start a session.

        The configuration chooses the devices; simulated ones observe the library material with ``label``
        as the piece ``sample_id`` (:func:`scanner.acquisition.devices.sources.simulated_sample`), seeded by the scan
        index this scan will get in ``db``, so repeated scans of a sample differ like real ones.
        """
        try:
            check_sample_id(sample_id)
            canonical = Label.parse(label).format()
        except (ScanError, LabelError) as exc:
            raise SessionError(str(exc)) from None
        if db is not None:
            # A sample is one piece of one material: refuse now rather than after a whole scan.
            stored = {record.label for record in db.records(sample=sample_id)}
            if stored and canonical not in stored:
                raise SessionError(f"sample {sample_id} is {', '.join(sorted(stored))} in the database, "
                                   f"not {canonical}")
        index = db.next_scan_index(sample_id) if db is not None else 1
        devices = open_devices(config, specimen=Specimen(canonical, sample_id, index))
        try:
            return cls(devices, config, label=label, sample_id=sample_id, operator=operator, **kwargs)
        except BaseException:
            devices.close()
            raise

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        if self.state is SessionState.OPEN:
            self.abort()

    # -- inspection ------------------------------------------------------------------------------

    def step(self, step_id: str) -> StepInfo:
        for step in self.steps:
            if step.id == step_id:
                return step
        raise SessionError(f"unknown step {step_id!r} (known: {', '.join(s.id for s in self.steps)})")

    def status(self, step_id: str) -> StepStatus:
        """The state of a step; photos and TU4 are recorded once complete."""
        step = self.step(step_id)
        if step.kind == "photos":
            done = all(name in self._photos for name in IMAGES)
            return StepStatus(step_id, StepState.RECORDED if done else StepState.PENDING)
        if step.kind == "form":
            return StepStatus(step_id, StepState.PENDING if self._missing_values() else StepState.RECORDED)
        entry = self._steps[step_id]
        problems = entry.result.problems if entry.result is not None else ()
        return StepStatus(step_id, entry.state, problems, entry.error)

    def result(self, step_id: str) -> StepResult | None:
        """The recording of a step, if it has one."""
        self.step(step_id)
        return self._steps[step_id].result if step_id in self._steps else None

    @property
    def rigid(self) -> bool:
        return self._steps["fold"].state is StepState.SKIPPED

    @property
    def values(self) -> dict[str, Any]:
        """The operator's TU4 values and notes as entered so far (NaN / "" where not yet)."""
        return dict(vars(self._values))

    @property
    def photos(self) -> Mapping[str, np.ndarray]:
        return dict(self._photos)

    @property
    def running(self) -> bool:
        """True while a step is recording (in this or a worker thread)."""
        return any(entry.state is StepState.RECORDING for entry in self._steps.values())

    def missing(self) -> list[str]:
        """What still has to be done before :meth:`save`, in procedure order (empty: ready)."""
        missing = []
        for step in self.steps:
            if step.kind == "record":
                state = self._steps[step.id].state
                if state not in (StepState.RECORDED, StepState.SKIPPED):
                    missing.append(f"{step.id} ({state})")
            elif step.kind == "photos":
                missing += [f"photo {name}" for name in IMAGES if name not in self._photos]
        return missing + self._missing_values()

    def work(self) -> list[str]:
        """What an abort would discard, in the operator's words, one line per kind (empty: nothing yet).

        ``["3 recorded steps: TU1 finger tap, TU1 finger slide, TU1 tool tap", "the fold's skip (rigid
        sample)", "2 of 3 photos", "the TU4 values: mass, volume"]``
        """
        recorded = [step.title for step in self.steps
                    if step.kind == "record" and self._steps[step.id].state is StepState.RECORDED]
        lines = []
        if recorded:
            lines.append(f"{_count(len(recorded), 'recorded step')}: {', '.join(recorded)}")
        if self.rigid:
            lines.append("the fold's skip (rigid sample)")
        if self._photos:
            lines.append(f"{len(self._photos)} of {len(IMAGES)} photos")
        values = self._values
        entered = [words for name, words in (("mass_g", "mass"), ("volume_cm3", "volume"), ("atk", "tack"),
                                             ("cyd", "yielding")) if not math.isnan(getattr(values, name))]
        entered += ["notes"] if values.notes else []
        if entered:
            lines.append(f"the TU4 values: {', '.join(entered)}")
        return lines

    def recorded_steps(self) -> frozenset[str]:
        """The steps done so far: recorded (or the fold skipped as rigid), the three photos taken, the TU4
        values entered."""
        return frozenset(step.id for step in self.steps
                         if self.status(step.id).state in (StepState.RECORDED, StepState.SKIPPED))

    def _missing_values(self) -> list[str]:
        values = self._values
        numbers = ("mass_g", "volume_cm3", "atk", "cyd")
        missing = [name for name in numbers if math.isnan(getattr(values, name))]
        return missing + ([] if values.volume_method else ["volume_method"])

    # -- recording -------------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self.state is not SessionState.OPEN:
            raise SessionError(f"the session is {self.state}")

    def _begin(self, step_id: str, cancel: threading.Event | None = None) -> _Step:
        with self._lock:
            self._check_open()
            step = self.step(step_id)
            if step.kind != "record":
                raise SessionError(f"{step_id} is not recorded with the devices")
            if self.running:
                raise SessionError(f"cannot record {step_id}: another step is recording")
            entry = self._steps[step_id]
            if entry.state not in (StepState.PENDING, StepState.FAILED):
                raise SessionError(f"{step_id} is {entry.state}: redo it first")
            entry.state, entry.result, entry.error = StepState.RECORDING, None, ""
            self._cancel = cancel or threading.Event()
            self._idle.clear()
            return entry

    def record(self, step_id: str, level: Callable[[Level], None] | None = None,
               cancel: threading.Event | None = None) -> StepStatus:
        """Record a pending or failed step; blocks until it is done and returns its status.

        A device that lost data fails the step (state ``failed``, ``error`` says why); the quality check's
        problems come with a recorded step. An interrupt (Ctrl-C) leaves the step failed and propagates.
        """
        entry = self._begin(step_id, cancel)
        self._run(step_id, entry, level)
        return self.status(step_id)

    def _run(self, step_id: str, entry: _Step, level: Callable[[Level], None] | None) -> None:
        def show(reading: Level) -> None:
            self.level = reading
            if level is not None:
                level(reading)

        try:
            result = self.recorder.record(step_id, cancel=self._cancel, level=show)
        except DeviceError as exc:
            entry.state, entry.error = StepState.FAILED, str(exc)
        except BaseException as exc:
            entry.state, entry.error = StepState.FAILED, f"{type(exc).__name__}: {exc}".rstrip(": ")
            raise
        else:
            entry.state, entry.result = StepState.RECORDED, result
        finally:
            self.level = None
            self._idle.set()

    def start_step(self, step_id: str, level: Callable[[Level], None] | None = None) -> None:
        """Start recording a step in a worker thread; poll :meth:`status` / :attr:`level`, or :meth:`wait`."""
        entry = self._begin(step_id)
        self.worker_error = None

        def work() -> None:
            try:
                self._run(step_id, entry, level)
            except BaseException as exc:  # noqa: BLE001 - a bug, kept for the caller; the step is failed
                self.worker_error = exc

        threading.Thread(target=work, name=f"record-{step_id}", daemon=True).start()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the recording step (from :meth:`start_step` or another thread); True once none runs."""
        return self._idle.wait(timeout)

    def cancel_step(self, timeout: float | None = None) -> bool:
        """Stop the step that is recording (it ends ``failed``, the Peltier goes off); True once stopped."""
        self._cancel.set()
        return self._idle.wait(timeout)

    def redo(self, step_id: str) -> None:
        """Discard a step's recording (or its skip, or the photos) so it can be done again."""
        with self._lock:
            self._check_open()
            step = self.step(step_id)
            if step.kind == "photos":
                self._photos.clear()
                return
            if step.kind == "form":
                raise SessionError("tu4 values are edited with set_values, not redone")
            entry = self._steps[step_id]
            if entry.state is StepState.RECORDING:
                raise SessionError(f"{step_id} is recording: cancel it first")
            entry.state, entry.result, entry.error = StepState.PENDING, None, ""

    def skip(self, step_id: str) -> None:
        """Skip the fold for a rigid sample (``meta.rigid`` = 1); no other step can be skipped."""
        with self._lock:
            self._check_open()
            step = self.step(step_id)
            if not step.skippable:
                raise SessionError(f"{step_id} cannot be skipped (only the fold, for a rigid sample)")
            entry = self._steps[step_id]
            if entry.state is StepState.RECORDING:
                raise SessionError(f"{step_id} is recording: cancel it first")
            entry.state, entry.result, entry.error = StepState.SKIPPED, None, ""

    # -- operator values and photos --------------------------------------------------------------

    @property
    def t_amb(self) -> float:
        """Ambient temperature, degC (pre-filled from the board, editable; NaN if unknown)."""
        return self._t_amb

    @t_amb.setter
    def t_amb(self, value: float) -> None:
        number = _number("t_amb", value)
        if not math.isnan(number) and not T_AMB_RANGE[0] <= number <= T_AMB_RANGE[1]:
            raise SessionError(f"t_amb: {number:g} degC is outside the sensor's {T_AMB_RANGE[0]:g}.."
                               f"{T_AMB_RANGE[1]:g} degC")
        self._t_amb = number

    def _read_ambient(self) -> float:
        try:
            return self.recorder.ambient()
        except DeviceError as exc:
            self.warnings.append(f"ambient temperature not read: {exc}")
            return math.nan

    def set_values(self, **values: Any) -> None:
        """Set any of ``atk``, ``cyd`` (five-step scale), ``mass_g``, ``volume_cm3`` (positive),
        ``volume_method`` (one of ``scanner.scan.VOLUME_METHODS``) and ``notes``; each is checked on its own."""
        self._check_open()
        checked = {}
        for name, value in values.items():
            if name in ("atk", "cyd"):
                number = _number(name, value)
                if not math.isnan(number) and number not in JUDGED_SCALE:
                    raise SessionError(f"{name}: {value!r} is not on the five-step scale "
                                       f"{', '.join(f'{v:g}' for v in JUDGED_SCALE)}")
                checked[name] = number
            elif name in ("mass_g", "volume_cm3"):
                number = _number(name, value)
                if not math.isnan(number) and number <= 0:
                    raise SessionError(f"{name}: must be positive, got {value!r}")
                checked[name] = number
            elif name == "volume_method":
                if value not in VOLUME_METHODS:
                    raise SessionError(f"volume_method: {value!r} is not one of {', '.join(VOLUME_METHODS)}")
                checked[name] = value
            elif name == "notes":
                if not _printable(value):
                    raise SessionError("notes: must be printable text of at most 2000 characters")
                checked[name] = value
            else:
                raise SessionError(f"unknown value {name!r} (known: atk, cyd, mass_g, volume_cm3, "
                                   "volume_method, notes)")
        self._values = replace(self._values, **checked)

    def set_photo(self, name: str, photo: np.ndarray | bytes) -> None:
        """Use an RGB uint8 array or the bytes of an uploaded PNG/JPEG file as photo ``name``."""
        self._check_open()
        if name not in IMAGES:
            raise SessionError(f"{name!r} is not a photo (known: {', '.join(IMAGES)})")
        if isinstance(photo, bytes | bytearray):
            try:
                photo = decode_photo(bytes(photo), name)
            except PhotoError as exc:
                raise SessionError(str(exc)) from None
        array = np.asarray(photo)
        if array.dtype != np.uint8 or array.ndim != 3 or array.shape[2] != 3 or min(array.shape[:2]) < 16:
            raise SessionError(f"{name}: must be an RGB uint8 image of at least 16x16 px, "
                               f"got {array.dtype} {array.shape}")
        try:
            check_size(array.shape[1], array.shape[0], name=name)  # the photo limit, or it could not be saved
        except PhotoError as exc:
            raise SessionError(str(exc)) from None
        self._warn_small_photos(*array.shape[:2])
        self._photos[name] = array.copy()

    def relabel(self, label: str) -> None:
        """Store the scan under ``label`` instead (the operator corrects the label at the summary, say
        after the model's prediction disagreed); checked as the label given when the session opened."""
        self._check_open()
        try:
            probe = ScanMeta(label=label, operator=self.operator, sample_id=self.sample_id, scan_index=1,
                             session_id=self.session_id, started=self.started)
        except ScanError as exc:
            raise SessionError(str(exc)) from None
        self.label = probe.label

    def _warn_small_photos(self, height: int, width: int) -> None:
        """A warning (once) when the photos are too small for the image features (``small_photo_note``)."""
        note = small_photo_note(height, width)
        if note is not None and note not in self.warnings:
            self.warnings.append(note)

    def capture_photo(self, name: str) -> np.ndarray:
        """Take photo ``name`` with the camera; returns it."""
        self._check_open()
        if name not in IMAGES:
            raise SessionError(f"{name!r} is not a photo (known: {', '.join(IMAGES)})")
        self.set_photo(name, self.devices.camera.capture(name))
        return self._photos[name]

    # -- the end ---------------------------------------------------------------------------------

    def scan(self, scan_index: int = 1, partial: bool = False) -> Scan:
        """The scan as it would be saved (raises :class:`SessionError` listing what is missing); with
        ``partial``, the scan of what is done so far (a quick scan's prediction after each step): the channels
        of the recorded steps, the photos taken, the TU4 values entered (NaN where not)."""
        missing = self.missing()
        if missing and not partial:
            raise SessionError(f"cannot save yet, missing: {', '.join(missing)}")
        done = self.recorded_steps()
        steps = ",".join(step.id for step in self.steps if step.id in done) if missing else ""
        results = {step: entry.result for step, entry in self._steps.items() if entry.result is not None}
        device, calibration = self.recorder.device_meta(results)
        values = self._values
        try:
            meta = ScanMeta(label=self.label, operator=self.operator, sample_id=self.sample_id,
                            scan_index=scan_index, session_id=self.session_id, started=self.started,
                            t_amb=self.t_amb, mass_g=values.mass_g, volume_cm3=values.volume_cm3,
                            volume_method=values.volume_method, atk=values.atk, cyd=values.cyd, rigid=self.rigid,
                            device=device, calibration=calibration, software_version=__version__,
                            notes=values.notes, steps=steps)
            return build_scan(meta, results, self._photos)
        except ScanError as exc:
            raise SessionError(f"the scan is not valid: {exc}") from None

    def save(self, db: Any, partial: bool = False) -> str:
        """Store the scan in ``db`` (a :class:`scanner.Database`) as the sample's next scan; returns its id.

        Only when every step is recorded or skipped, the photos are there and the TU4 values entered; with
        ``partial``, a quick scan of the steps done so far (at least one), which records them in
        ``meta.steps``. The devices are released afterwards.
        """
        with self._lock:
            self._check_open()
            if self.running:
                raise SessionError("cannot save while a step is recording")
            if partial and not self.recorded_steps():
                raise SessionError("cannot save a quick scan before its first step")
            scan = self.scan(db.next_scan_index(self.sample_id), partial=partial)
            scan_id = db.add(scan)
            self.state = SessionState.SAVED
        self.close()
        return scan_id

    def abort(self) -> None:
        """Stop any recording, switch the Peltier off, release the devices; nothing is saved."""
        with self._lock:
            if self.state is not SessionState.OPEN:
                return
            self.state = SessionState.ABORTED
        self.cancel_step()
        self.close()

    def close(self) -> None:
        """Release the devices (Peltier off first); safe to call more than once."""
        devices, self.devices = self.devices, None
        if devices is not None:
            devices.close()


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise SessionError(f"{name}: must be a number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SessionError(f"{name}: must be a number, got {value!r}") from None
    if math.isinf(number):
        raise SessionError(f"{name}: must be finite, got {value!r}")
    return number


def _printable(text: Any, limit: int = 2000) -> bool:
    return isinstance(text, str) and len(text) <= limit and all(c >= " " or c in "\n\t" for c in text)
