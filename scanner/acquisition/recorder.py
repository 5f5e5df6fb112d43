"""Recording the procedure steps (docs/operator.md#procedure) from the devices, and assembling a
:class:`~scanner.scan.Scan`.

:meth:`Recorder.record` records one step and returns a :class:`StepResult`: the step's scan channels in the
units of docs/database.md, the DAQ volts they came from, the quality problems the operator should see, and
diagnostics. How each step is recorded:

=================  ==========================================================================================
step               devices
=================  ==========================================================================================
taps               DAQ (accelerometer)
slides             DAQ task set up, microphone started, then the DAQ; the measured start offset is removed
                   so the audio and the vibration start at the same instant (docs/devices.md), then both are cut to
                   the step's duration
static             ``CAL M`` with the unit in the air, then the DAQ (metal electrode) and the board's ``M``
                   stream (80 Hz) together
thermal            Peltier on for ``steps.heat`` s (at most 5 s), off on every exit path; then the board's
                   ``T`` stream (20 Hz) for ``steps.thermal`` s
friction, press,   DAQ (FSRs, flex)
fold
=================  ==========================================================================================

The DAQ is read block by block into one array preallocated for the whole step. A lost sample is never
hidden: a DAQ overrun, a lost serial connection or 1 s of serial silence raise
:class:`~scanner.acquisition.devices.protocols.AcquisitionError` (the step fails and can be redone); samples the board's
counter shows missing are interpolated and reported as a problem.

Peltier safety (:func:`heat`): the host never asks for more than 5 s (the board refuses more anyway), and the
element is switched off when heating ends, is cancelled (abort), is interrupted (Ctrl-C), or fails
(a lost connection, an exception from the level callback). A DAQ-driven Peltier also has a watchdog timer
thread (:class:`~scanner.acquisition.devices.daq.DaqPeltier`); a board-driven one is switched off by the board itself.
"""

from __future__ import annotations

import concurrent.futures
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from datetime import UTC, datetime

import numpy as np

from scanner.acquisition.config import CHANNEL_ROLES, DAQ_ROLES, MAX_HEAT_S, Config, ConfigError
from scanner.acquisition.devices import Devices
from scanner.acquisition.devices.board import collect, field_change
from scanner.acquisition.devices.protocols import AcquisitionError, AudioCapture, Peltier
from scanner.preprocess import check_clipped, check_contact, check_slide
from scanner.scan import CHANNELS, Scan, ScanMeta, Trace
from taxonomy.errors import ParameterError

DAQ_STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "friction", "press", "fold")
AUDIO_CHANNEL = {"finger_slide": "a_fs", "tool_slide": "a_ts"}
ACCEL_RANGE_G = 3.6
"""ADXL335 output range: samples within 0.01 g of it count as clipped."""
FSR_RAIL_V = 4.9
"""The FSR voltage dividers saturate here."""
AUDIO_RAIL = 1.0 - 2.0 / 32768
"""Two 16-bit steps below full scale."""
MIN_TAP_G = 0.04
"""A tap step whose acceleration never leaves its median by this much has no tap in it."""
MIN_COOLING_K = 0.05
"""A cooling record that never drops this much below its peak shows no heated spot."""
FULL_FORCE_N = 20.0
FULL_VIBRATION_G = 0.5


class StepCancelled(AcquisitionError):
    """The recording was cancelled (abort, or the operator stopped it)."""


@dataclass(frozen=True)
class Level:
    """The live signal level while a step records: ``signal`` (e.g. "vibration"), its current ``value`` in
    ``unit``, ``fraction`` 0..1 of a full meter, and the step's ``phase`` ("recording", "heating",
    "cooling")."""

    step: str
    phase: str
    elapsed_s: float
    duration_s: float
    signal: str
    value: float
    unit: str
    fraction: float


LevelCallback = Callable[[Level], None]
_Recorded = tuple[dict[str, Trace], dict[str, Trace], tuple[str, ...], dict[str, float]]
"""A step's traces, raw volts, quality problems and diagnostics."""


@dataclass(frozen=True)
class StepResult:
    """One recorded step: scan channels (docs/database.md units), their DAQ volts, quality problems, diagnostics."""

    step: str
    traces: Mapping[str, Trace]
    raw: Mapping[str, Trace] = field(default_factory=dict)
    problems: tuple[str, ...] = ()
    info: Mapping[str, float] = field(default_factory=dict)
    started: str = ""

    @property
    def ok(self) -> bool:
        return not self.problems


def heat(peltier: Peltier, seconds: float, *, cancel: threading.Event | None = None,
         tick: Callable[[float], None] | None = None) -> None:
    """Heat for ``seconds`` (at most 5 s) and switch the Peltier off on every way out.

    ``tick(elapsed)`` is called about 20 times per second; ``cancel`` ends the heating early with
    :class:`StepCancelled`; ``peltier.check()`` turns a lost connection into an error. If switching off
    fails while another error is on its way, that failure is added to the error's notes.
    """
    if not 0 < seconds <= MAX_HEAT_S:
        raise ParameterError(f"Peltier heating of {seconds:g} s is outside (0, {MAX_HEAT_S:g}] s")
    cancel = cancel or threading.Event()
    started = time.monotonic()
    peltier.on(seconds)
    try:
        while (elapsed := time.monotonic() - started) < seconds:
            if cancel.wait(min(0.05, seconds - elapsed)):
                raise StepCancelled("cancelled while heating")
            peltier.check()
            if tick is not None:
                tick(time.monotonic() - started)
    except BaseException as error:
        try:
            peltier.off()
        except Exception as failure:  # noqa: BLE001 - the original error matters more; keep both
            error.add_note(f"switching the Peltier off failed too: {failure}")
        raise
    peltier.off()


class Recorder:
    """Records steps with ``devices`` as ``config`` says (durations, calibration, rates)."""

    def __init__(self, devices: Devices, config: Config) -> None:
        if devices.daq.rate != CHANNELS["v_ts"].fs:
            raise ConfigError(f"{config.source}: daq.rate_hz: scans are sampled at "
                              f"{CHANNELS['v_ts'].fs:g} Hz (the scan format), not {devices.daq.rate:g} Hz")
        if devices.microphone.rate != CHANNELS["a_ts"].fs:
            raise ConfigError(f"{config.source}: microphone.rate_hz: scans record audio at "
                              f"{CHANNELS['a_ts'].fs:g} Hz (the scan format), not {devices.microphone.rate:g} Hz")
        self.devices = devices
        self.config = config

    def duration(self, step: str) -> float:
        return float(getattr(self.config.steps, step))

    def record(self, step: str, *, cancel: threading.Event | None = None,
               level: LevelCallback | None = None) -> StepResult:
        """Record ``step`` (one of :data:`DAQ_STEPS` or "thermal"); blocks until done.

        Raises
        ------
        AcquisitionError
            Data was lost (overrun, lost connection, silence) or the recording was cancelled.
        """
        cancel = cancel or threading.Event()
        started = datetime.now(UTC).isoformat(timespec="seconds")
        if step == "thermal":
            result = self._thermal(cancel, level)
        elif step == "static":
            result = self._static(cancel, level)
        elif step in DAQ_STEPS:
            result = self._daq_step(step, cancel, level)
        else:
            raise ParameterError(f"{step!r} is not a recorded step (known: {', '.join((*DAQ_STEPS, 'thermal'))})")
        return StepResult(step, *result, started=started)

    def ambient(self) -> float:
        """The room temperature from the board's MLX90614 (ambient column), degC."""
        return self.devices.board.ambient()

    # -- DAQ steps -------------------------------------------------------------------------------

    def _acquire(self, step: str, seconds: float, cancel: threading.Event, level: LevelCallback | None,
                 audio: bool = False) -> tuple[np.ndarray, float, AudioCapture | None]:
        """(n, 8) volts of ``seconds`` of DAQ samples, the DAQ start time and the microphone's capture."""
        daq, microphone = self.devices.daq, self.devices.microphone
        n = int(round(seconds * daq.rate))
        blocks = -(-n // daq.block)
        buffer = np.empty((blocks, len(daq.channels), daq.block))
        capture = None
        daq_ended: float | None = None
        daq.arm(step)
        if audio:
            microphone.start(step)
        try:
            daq_started = daq.start(step)
            try:
                for k in range(blocks):
                    if cancel.is_set():
                        raise StepCancelled("recording cancelled")
                    daq.read_into(buffer[k])
                    if audio:
                        microphone.read()
                    if level is not None:
                        level(self._daq_level(step, buffer[k], (k + 1) * daq.block / daq.rate, seconds))
                daq_ended = daq_started + seconds
            finally:
                daq.stop()
        finally:
            if audio:
                # The DAQ's last block can come back before the microphone's (its start time is an estimate
                # and the audio has its own latency): the microphone records on until it covers the step.
                capture = microphone.stop(until=daq_ended)
        return buffer.transpose(0, 2, 1).reshape(-1, len(daq.channels))[:n], daq_started, capture

    def _daq_level(self, step: str, block: np.ndarray, elapsed: float, seconds: float) -> Level:
        calibration = self.config.calibration
        if step in ("friction", "press", "fold"):
            force = float(calibration.to_physical("fsr_normal", block[DAQ_ROLES.index("fsr_normal")]).max())
            fraction = min(force / FULL_FORCE_N, 1.0)
            return Level(step, "recording", elapsed, seconds, "force", force, "N", fraction)
        if step == "static":
            metal = float(calibration.to_physical("metal", block[DAQ_ROLES.index("metal")]).mean())
            return Level(step, "recording", elapsed, seconds, "metal", metal, "-", (metal + 1) / 2)
        axes = [calibration.to_physical(f"accel_{a}", block[DAQ_ROLES.index(f"accel_{a}")]) for a in "xyz"]
        rms = float(np.sqrt(sum(np.var(axis) for axis in axes)))
        fraction = min(rms / FULL_VIBRATION_G, 1.0)
        return Level(step, "recording", elapsed, seconds, "vibration", rms, "g", fraction)

    def _channels(self, step: str, volts: np.ndarray) -> tuple[dict[str, Trace], dict[str, Trace]]:
        """The scan channels of ``step`` in docs/database.md units and their raw volts."""
        traces, raw = {}, {}
        for name, roles in CHANNEL_ROLES.items():
            if CHANNELS[name].step != step:
                continue
            columns = [DAQ_ROLES.index(role) for role in roles]
            values = np.column_stack([self.config.calibration.to_physical(role, volts[:, c])
                                      for role, c in zip(roles, columns, strict=True)])
            spec = CHANNELS[name]
            traces[name] = Trace(values if spec.axes else values[:, 0], spec.fs, spec.unit)
            data = volts[:, columns]
            raw[name] = Trace(data if spec.axes else data[:, 0], spec.fs, "V")
        return traces, raw

    def _daq_step(self, step: str, cancel: threading.Event,
                  level: LevelCallback | None) -> _Recorded:
        seconds = self.duration(step)
        slide = step in AUDIO_CHANNEL
        volts, daq_started, capture = self._acquire(step, seconds, cancel, level, audio=slide)
        traces, raw = self._channels(step, volts)
        info: dict[str, float] = {}
        problems = self._daq_problems(step, traces, raw)
        if slide and capture is not None:
            audio, offset, audio_problems = self._align(capture, daq_started, seconds)
            traces[AUDIO_CHANNEL[step]] = Trace(audio, CHANNELS["a_ts"].fs, "FS")
            info.update(audio_offset_s=offset, audio_overflows=float(capture.overflows))
            problems += audio_problems
            accel = next(t for n, t in traces.items() if CHANNELS[n].axes)
            ir = next(t for n, t in traces.items() if n.startswith("r_"))
            problems += check_slide(accel.data, audio_samples=len(audio), ir_samples=ir.n)
        return traces, (raw if self.config.daq.keep_raw else {}), tuple(problems), info

    def _align(self, capture: AudioCapture, daq_started: float,
               seconds: float) -> tuple[np.ndarray, float, list[str]]:
        """Cut the audio to start with the DAQ's first sample and last ``seconds`` (docs/devices.md)."""
        rate = self.devices.microphone.rate
        offset = capture.first_sample_time - daq_started
        skip = int(round(-offset * rate))
        problems = []
        samples = capture.samples
        if skip < 0:
            problems.append(f"audio started {-skip / rate * 1000:.1f} ms after the DAQ (silence padded)")
            samples = np.concatenate([np.zeros(-skip), samples])
            skip = 0
        need = int(round(seconds * rate))
        audio = samples[skip:skip + need]
        if len(audio) < need:
            raise AcquisitionError(f"microphone delivered {len(audio)} of the {need} samples of the "
                                   f"{seconds:g} s step")
        if capture.overflows:
            problems.append(f"audio: {capture.overflows} input overflow(s), samples were lost")
        clipped = int(np.count_nonzero(np.abs(audio) >= AUDIO_RAIL))
        if clipped:
            problems.append(f"clipped: {clipped} audio samples at full scale")
        return audio, offset, problems

    def _daq_problems(self, step: str, traces: Mapping[str, Trace], raw: Mapping[str, Trace]) -> list[str]:
        problems: list[str] = []
        calibration = self.config.calibration
        for name, trace in traces.items():
            volts = raw[name].data
            if CHANNELS[name].axes:
                for axis, letter in enumerate("xyz"):
                    margin = (ACCEL_RANGE_G - 0.01) * calibration.accel_v_per_g[axis]
                    zero = calibration.accel_zero_v[axis]
                    problems += [f"{p} ({name} {letter})" for p in
                                 check_clipped(volts[:, axis], zero - margin, zero + margin)]
                if step.endswith("_tap"):
                    swing = float(np.abs(trace.data - np.median(trace.data, axis=0)).max())
                    if swing < MIN_TAP_G:
                        problems.append(f"no tap detected: largest swing {swing:.3f} g")
            elif name.startswith("f_"):
                problems += [f"{p} ({name})" for p in check_clipped(volts, -1.0, FSR_RAIL_V)]
        contact = {"friction": "f_frn", "press": "f_press", "fold": "f_fold"}.get(step)
        if contact:
            problems += check_contact(traces[contact].data)
        return problems

    # -- board steps -----------------------------------------------------------------------------

    def _static(self, cancel: threading.Event, level: LevelCallback | None) -> _Recorded:
        """Metal electrode on the DAQ and the field change on the board, recorded together."""
        board, seconds, hz = self.devices.board, self.duration("static"), self.config.board.magnet_hz
        board.calibrate_magnetometer()
        stop_stream = threading.Event()
        with concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="board-stream") as pool:
            stream = pool.submit(collect, board, "M", hz, seconds, cancel=stop_stream,
                                 timeout=self.config.board.timeout_s)
            try:
                volts, _, _ = self._acquire("static", seconds, cancel, level)
            except BaseException:
                stop_stream.set()
                raise
            record = stream.result()
        traces, raw = self._channels("static", volts)
        traces["dB"] = Trace(field_change(record.values), CHANNELS["dB"].fs, CHANNELS["dB"].unit)
        problems = _missing(record.missing)
        kept = raw if self.config.daq.keep_raw else {}
        return traces, kept, problems, {"board_missing": float(record.missing)}

    def _thermal(self, cancel: threading.Event, level: LevelCallback | None) -> _Recorded:
        """Heat (bounded, always switched off), then record the cooling."""
        heat_s, cool_s = self.duration("heat"), self.duration("thermal")

        def heating(elapsed: float) -> None:
            if level is not None:
                level(Level("thermal", "heating", elapsed, heat_s, "heating", elapsed, "s", elapsed / heat_s))

        heat(self.devices.peltier, heat_s, cancel=cancel, tick=heating)
        hz = self.config.board.thermal_hz

        def cooling(count: int, latest: tuple[float, ...]) -> None:
            if level is not None:
                level(Level("thermal", "cooling", count / hz, cool_s, "temperature", latest[0], "degC",
                            min(count / (cool_s * hz), 1.0)))

        record = collect(self.devices.board, "T", hz, cool_s, cancel=cancel, on_samples=cooling,
                         timeout=self.config.board.timeout_s)
        t_cool = record.values[:, 0]
        problems = _missing(record.missing)
        drop = float(t_cool.max() - t_cool[-1])
        if drop < MIN_COOLING_K:
            problems += (f"no cooling seen: the temperature fell {drop:.2f} K from its peak",)
        traces = {"t_cool": Trace(t_cool, CHANNELS["t_cool"].fs, CHANNELS["t_cool"].unit)}
        return traces, {}, problems, {"board_missing": float(record.missing), "heat_s": heat_s}

    # -- the scan ---------------------------------------------------------------------------------

    def device_meta(self, results: Mapping[str, StepResult]) -> tuple[dict[str, str], dict[str, float]]:
        """``meta.device`` (names, serials, diagnostics) and ``meta.calibration`` (calibration and the
        measured audio offsets)."""
        device = self.devices.describe()
        stats = self.devices.board.stats
        device.update(board_bad_checksums=str(stats.bad_checksums), board_reconnects=str(stats.reconnects),
                      board_missing_samples=str(stats.missing_samples))
        calibration = self.config.calibration.as_meta()
        for step, channel in AUDIO_CHANNEL.items():
            result = results.get(step)
            if result is not None and "audio_offset_s" in result.info:
                calibration[f"audio_offset_{channel[2:]}_s"] = result.info["audio_offset_s"]
                device[f"audio_overflows_{channel[2:]}"] = str(int(result.info["audio_overflows"]))
        return device, calibration


def _missing(count: int) -> tuple[str, ...]:
    if count:
        return (f"serial board: {count} sample(s) lost and interpolated",)
    return ()


def build_scan(meta: ScanMeta, results: Mapping[str, StepResult], photos: Mapping[str, np.ndarray]) -> Scan:
    """The scan of ``meta`` from the recorded steps and the photos (raw volts kept where recorded)."""
    traces: dict[str, Trace] = {}
    raw: dict[str, Trace] = {}
    for result in results.values():
        traces.update(result.traces)
        raw.update(result.raw)
    return Scan(meta, traces, dict(photos), raw)
