"""An NI gRPC Device Server for the DAQ, in process: the real ``nidaqmx`` client talks to it over
``nidaqmx.GrpcSessionOptions`` exactly as to a remote NI USB-6002 (docs/devices.md#emulators).

:class:`DaqServicer` implements the part of the ``nidaqmx_grpc.NiDAQmx`` service (the stubs that ship with
``nidaqmx[grpc]``) that the scanner uses: tasks, analog voltage inputs with a continuous sample clock,
``ReadAnalogF64`` in both fill modes, a digital output line, device identification and error strings. The
analog inputs carry the volts of a :class:`~scanner.acquisition.devices.sources.SignalSource` wired by the channel map
of docs/devices.md, produced in real time from the moment the task starts: sample k of a task exists ``k / rate`` s
after ``StartTask``. Whoever reads too slowly overruns the task's buffer and gets DAQmx error -200279,
as from real hardware; :meth:`DaqServicer.inject_overrun` forces that on the next read.

The emulator plays the operator too: a task named ``texplorer-<step>`` (how :class:`NidaqmxDaq` names its
tasks) gets the signals of that procedure step, as a real operator performs the step the host's instructions
name; other tasks see the unit at rest. Every write to a digital line is logged with its time
(``line_log``), so tests can check the Peltier timeline.

Errors are reported like the real server: gRPC status UNKNOWN with the DAQmx code in the ``ni-error``
trailing metadata.

Run one by hand with ``texplorer emulate daq`` and point the scanner at it with ``--daq grpc://host:port``.
"""

from __future__ import annotations

import itertools
import re
import threading
import time
from collections.abc import Mapping
from concurrent import futures
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from scanner.acquisition.config import DAQ_ROLES, DEFAULT_CHANNEL_MAP, Calibration
from scanner.acquisition.devices.sources import SignalSource, rest_volts
from scanner.simulation import STEPS
from taxonomy.errors import TexplorerError

try:
    import grpc
    from nidaqmx._stubs import nidaqmx_pb2 as pb
    from nidaqmx._stubs import nidaqmx_pb2_grpc as pb_grpc
    from session_pb2 import Session
except ImportError as exc:  # pragma: no cover - depends on the installed extras
    raise ImportError(f"the DAQ emulator needs nidaqmx[grpc] (grpcio, protobuf): {exc}") from None

DRIVER_VERSION = {0x1272: 23, 0x1923: 8, 0x2F22: 0}
"""System attributes major/minor/update version of the emulated NI-DAQmx."""
ATTR_TASK_NAME, ATTR_TASK_CHANNELS, ATTR_TASK_NUM_CHANS = 0x1276, 0x1273, 0x2181
ATTR_READ_NUM_CHANS, ATTR_WRITE_NUM_CHANS = 0x217B, 0x217E
ATTR_PRODUCT_TYPE, ATTR_SERIAL = 0x0631, 0x0632
ATTR_INPUT_BUFFER = 0x186C
CONTINUOUS, GROUP_BY_CHANNEL = 10123, 0
ERROR_TEXT = {
    -200279: "The application is not able to keep up with the hardware acquisition.",
    -200284: "Some or all of the samples requested have not yet been acquired.",
    -200220: "Device identifier is invalid.",
    -200088: "Task specified is invalid or does not exist.",
    -200479: "Specified operation cannot be performed while the task is running.",
    -200478: "Specified operation cannot be performed when there are no channels in the task.",
    -200170: "Physical channel specified does not exist on this device.",
    -200089: "Task name specified conflicts with an existing task name.",
}
_RANGE = re.compile(r"^(?P<device>[^/]+)/(?P<kind>ai|port\d+/line)(?P<first>\d+)(?::(?P<last>\d+))?$")


class _Failure(TexplorerError):
    def __init__(self, code: int, read: int | None = None) -> None:
        super().__init__(code)
        self.code, self.read = code, read


def expand_channels(text: str) -> list[tuple[str, str]]:
    """``"Dev1/ai0:2, Dev1/ai7"`` -> ``[("Dev1", "ai0"), ("Dev1", "ai1"), ("Dev1", "ai2"), ("Dev1", "ai7")]``.

    DAQmx physical channel lists: comma-separated names, ``first:last`` ranges.
    """
    out = []
    for part in (p.strip() for p in text.split(",")):
        match = _RANGE.match(part)
        if not match:
            raise _Failure(-200170)
        first = int(match["first"])
        last = int(match["last"]) if match["last"] else first
        step = 1 if last >= first else -1
        out += [(match["device"], f"{match['kind']}{i}") for i in range(first, last + step, step)]
    return out


@dataclass
class _Task:
    name: str
    inputs: list[str] = field(default_factory=list)
    lines: list[str] = field(default_factory=list)
    rate: float = 0.0
    buffer: int = 0
    started: float | None = None
    position: int = 0
    volts: np.ndarray | None = None


class DaqServicer(pb_grpc.NiDAQmxServicer):
    """The emulated NI-DAQmx service: one device (default ``Dev1``, an NI USB-6002).

    Parameters
    ----------
    source : SignalSource, optional
        What the inputs carry; None keeps the unit at rest.
    calibration : Calibration
        Converts the source's physical signals to volts.
    channel_map : mapping role -> "aiN"
        How the sensors are wired (docs/devices.md default).
    """

    def __init__(self, source: SignalSource | None = None, calibration: Calibration | None = None, *,
                 device: str = "Dev1", product: str = "USB-6002", serial: int = 0x1F2A3B4,
                 channel_map: Mapping[str, str] = DEFAULT_CHANNEL_MAP) -> None:
        self.source = source
        self.calibration = calibration or Calibration()
        self.device, self.product, self.serial = device, product, serial
        self.columns = {channel: DAQ_ROLES.index(role) for role, channel in channel_map.items()}
        self.tasks: dict[str, _Task] = {}
        self.line_log: list[tuple[float, str, bool]] = []
        self.calls: list[str] = []
        self._lock = threading.Lock()
        self._ids = itertools.count(1)
        self._overruns = 0

    # -- helpers ---------------------------------------------------------------------------------

    def inject_overrun(self, reads: int = 1) -> None:
        """Make the next ``reads`` reads fail with DAQmx -200279 (samples no longer available)."""
        with self._lock:
            self._overruns += reads

    def _task(self, session: Any) -> _Task:
        task = self.tasks.get(session.name)
        if task is None:
            raise _Failure(-200088)
        return task

    def _record(self, name: str) -> None:
        with self._lock:
            self.calls.append(name)

    def _volts(self, task: _Task) -> np.ndarray:
        """(n, channels) volts of the task's inputs for the step its name asks for."""
        step = task.name.removeprefix("texplorer-")
        if self.source is not None and step in STEPS:
            volts = self.source.daq_volts(step, self.calibration, "daq")
        else:
            volts = rest_volts(int(task.rate) or 1, self.calibration)
        columns = [self.columns.get(channel) for channel in task.inputs]
        served = np.zeros((len(volts), len(columns)))
        for k, column in enumerate(columns):
            if column is not None:
                served[:, k] = volts[:, column]
        return served

    # -- system and tasks ------------------------------------------------------------------------

    def GetSystemInfoAttributeUInt32(self, request, context):  # noqa: N802 - gRPC method names
        self._record("GetSystemInfoAttributeUInt32")
        return pb.GetSystemInfoAttributeUInt32Response(value=DRIVER_VERSION.get(request.attribute_raw, 0))

    def GetErrorString(self, request, context):  # noqa: N802
        text = ERROR_TEXT.get(request.error_code, "Unknown DAQmx error.")
        return pb.GetErrorStringResponse(error_string=text)

    def CreateTask(self, request, context):  # noqa: N802
        self._record("CreateTask")
        with self._lock:
            name = request.session_name or f"_unnamedTask<{next(self._ids)}>"
            if name in self.tasks:
                return _fail(context, -200089)
            self.tasks[name] = _Task(name)
        return pb.CreateTaskResponse(task=Session(name=name), new_session_initialized=True)

    def ClearTask(self, request, context):  # noqa: N802
        self._record("ClearTask")
        with self._lock:
            self.tasks.pop(request.task.name, None)
        return pb.ClearTaskResponse()

    def GetTaskAttributeString(self, request, context):  # noqa: N802
        return self._guard(context, lambda: pb.GetTaskAttributeStringResponse(value=self._task_text(request)))

    def _task_text(self, request: Any) -> str:
        task = self._task(request.task)
        if request.attribute_raw == ATTR_TASK_CHANNELS:
            return ", ".join(f"{self.device}/{name}" for name in task.inputs + task.lines)
        return task.name

    def GetTaskAttributeUInt32(self, request, context):  # noqa: N802
        return self._guard(context, lambda: pb.GetTaskAttributeUInt32Response(
            value=self._channel_count(request)))

    def GetReadAttributeUInt32(self, request, context):  # noqa: N802
        return self._guard(context, lambda: pb.GetReadAttributeUInt32Response(
            value=self._channel_count(request)))

    def GetWriteAttributeUInt32(self, request, context):  # noqa: N802
        return self._guard(context, lambda: pb.GetWriteAttributeUInt32Response(
            value=self._channel_count(request)))

    def _channel_count(self, request: Any) -> int:
        task = self._task(request.task)
        return len(task.inputs) + len(task.lines)

    def GetDeviceAttributeString(self, request, context):  # noqa: N802
        if request.device_name != self.device:
            return _fail(context, -200220)
        return pb.GetDeviceAttributeStringResponse(
            value=self.product if request.attribute_raw == ATTR_PRODUCT_TYPE else "")

    def GetDeviceAttributeUInt32(self, request, context):  # noqa: N802
        if request.device_name != self.device:
            return _fail(context, -200220)
        value = self.serial if request.attribute_raw == ATTR_SERIAL else 0
        return pb.GetDeviceAttributeUInt32Response(value=value)

    # -- analog input ----------------------------------------------------------------------------

    def CreateAIVoltageChan(self, request, context):  # noqa: N802
        self._record("CreateAIVoltageChan")
        return self._guard(context, lambda: self._add_inputs(request))

    def _add_inputs(self, request: Any) -> Any:
        task = self._task(request.task)
        channels = expand_channels(request.physical_channel)
        if any(device != self.device for device, _ in channels):
            raise _Failure(-200220)
        if any(not name.startswith("ai") or int(name[2:]) > 7 for _, name in channels):
            raise _Failure(-200170)
        task.inputs += [name for _, name in channels]
        return pb.CreateAIVoltageChanResponse()

    def CfgSampClkTiming(self, request, context):  # noqa: N802
        self._record("CfgSampClkTiming")
        return self._guard(context, lambda: self._timing(request))

    def _timing(self, request: Any) -> Any:
        task = self._task(request.task)
        if task.started is not None:
            raise _Failure(-200479)
        task.rate = float(request.rate)
        task.buffer = int(request.samps_per_chan)
        if request.sample_mode_raw == CONTINUOUS:
            task.buffer = max(task.buffer, _default_buffer(task.rate))
        # The operator's take is simulated now, so that StartTask is as quick as on hardware.
        task.volts = self._volts(task) if task.inputs else None
        return pb.CfgSampClkTimingResponse()

    def SetBufferAttributeUInt32(self, request, context):  # noqa: N802
        self._record("SetBufferAttributeUInt32")

        def set_size() -> Any:
            task = self._task(request.task)
            if request.attribute_raw == ATTR_INPUT_BUFFER:
                task.buffer = int(request.value)
            return pb.SetBufferAttributeUInt32Response()

        return self._guard(context, set_size)

    def StartTask(self, request, context):  # noqa: N802
        self._record("StartTask")
        return self._guard(context, lambda: self._start(request))

    def _start(self, request: Any) -> Any:
        task = self._task(request.task)
        if task.inputs:
            if not task.rate:
                raise _Failure(-200478)
            if task.volts is None or task.volts.shape[1] != len(task.inputs):
                task.volts = self._volts(task)
            task.position = 0
        task.started = time.perf_counter()
        return pb.StartTaskResponse()

    def StopTask(self, request, context):  # noqa: N802
        self._record("StopTask")

        def stop() -> Any:
            self._task(request.task).started = None
            return pb.StopTaskResponse()

        return self._guard(context, stop)

    def ReadAnalogF64(self, request, context):  # noqa: N802
        try:
            values, count = self._read(request)
        except _Failure as failure:
            return _fail(context, failure.code, read=0 if failure.read is None else failure.read)
        return pb.ReadAnalogF64Response(read_array=values, samps_per_chan_read=count)

    def _read(self, request: Any) -> tuple[list[float], int]:
        task = self._task(request.task)
        if task.started is None or task.volts is None:
            raise _Failure(-200088)
        with self._lock:
            if self._overruns:
                self._overruns -= 1
                raise _Failure(-200279, 0)
        wanted = request.num_samps_per_chan
        acquired = int((time.perf_counter() - task.started) * task.rate)
        if wanted < 0:
            wanted = max(acquired - task.position, 0)
        deadline = time.perf_counter() + max(request.timeout, 0.0)
        while acquired < task.position + wanted:
            if acquired - task.position > task.buffer:
                raise _Failure(-200279, 0)
            if time.perf_counter() >= deadline:
                raise _Failure(-200284, 0)
            time.sleep(min((task.position + wanted - acquired) / task.rate, 0.005))
            acquired = int((time.perf_counter() - task.started) * task.rate)
        if acquired - task.position > task.buffer:
            raise _Failure(-200279, 0)
        rows = np.arange(task.position, task.position + wanted).clip(max=len(task.volts) - 1)
        block = task.volts[rows]
        task.position += wanted
        ordered = block.T if request.fill_mode_raw == GROUP_BY_CHANNEL else block
        return ordered.ravel().tolist(), wanted

    # -- digital output --------------------------------------------------------------------------

    def CreateDOChan(self, request, context):  # noqa: N802
        self._record("CreateDOChan")

        def add() -> Any:
            task = self._task(request.task)
            channels = expand_channels(request.lines)
            if any(device != self.device for device, _ in channels):
                raise _Failure(-200220)
            task.lines += [name for _, name in channels]
            return pb.CreateDOChanResponse()

        return self._guard(context, add)

    def WriteDigitalLines(self, request, context):  # noqa: N802
        self._record("WriteDigitalLines")

        def write() -> Any:
            task = self._task(request.task)
            values = np.frombuffer(request.write_array, dtype=np.uint8)
            with self._lock:
                for line, value in zip(task.lines, values, strict=False):
                    self.line_log.append((time.perf_counter(), line, bool(value)))
            return pb.WriteDigitalLinesResponse(samps_per_chan_written=1)

        return self._guard(context, write)

    def line_state(self, line: str = "port0/line0") -> bool:
        """The last value written to ``line`` (False if never written)."""
        with self._lock:
            values = [value for _, name, value in self.line_log if name == line]
        return values[-1] if values else False

    def _guard(self, context: Any, action: Any) -> Any:
        try:
            return action()
        except _Failure as failure:
            return _fail(context, failure.code)


def _default_buffer(rate: float) -> int:
    """NI-DAQmx's smallest automatic buffer of a continuous acquisition at ``rate`` S/s."""
    if rate <= 100:
        return 1_000
    if rate <= 10_000:
        return 10_000
    return 100_000 if rate <= 1_000_000 else 1_000_000


def _fail(context: Any, code: int, read: int | None = None) -> Any:
    metadata = [("ni-error", str(code))]
    if read is not None:
        metadata.append(("ni-samps-per-chan-read", str(read)))
    context.set_trailing_metadata(tuple(metadata))
    context.abort(grpc.StatusCode.UNKNOWN, ERROR_TEXT.get(code, "DAQmx error"))


class DaqEmulator:
    """A running in-process gRPC server with one :class:`DaqServicer`; ``address`` is ``host:port``.

    >>> with DaqEmulator() as emulator:                     # doctest: +SKIP
    ...     config = Config().with_daq_server(f"grpc://{emulator.address}")
    """

    def __init__(self, servicer: DaqServicer | None = None, host: str = "127.0.0.1", port: int = 0,
                 workers: int = 8) -> None:
        self.servicer = servicer or DaqServicer()
        self.server = grpc.server(futures.ThreadPoolExecutor(max_workers=workers),
                                  options=[("grpc.max_send_message_length", 64 << 20)])
        pb_grpc.add_NiDAQmxServicer_to_server(self.servicer, self.server)
        bound = self.server.add_insecure_port(f"{host}:{port}")
        if bound == 0:
            raise OSError(f"cannot listen on {host}:{port}")
        self.address = f"{host}:{bound}"
        self.server.start()

    def stop(self) -> None:
        self.server.stop(grace=0.5).wait()

    def __enter__(self) -> DaqEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
