"""The DAQ (docs/devices.md): eight analog inputs sampled continuously at 3 kHz and the Peltier's digital line.

:class:`NidaqmxDaq` is the NI USB-6002 through ``nidaqmx``, on this computer or on a remote NI gRPC Device
Server (``daq.server = "grpc://host:port"``, ``nidaqmx.GrpcSessionOptions``). Each recording is one DAQmx
task named ``texplorer-<step>``: continuous sampling into a DAQmx buffer of ``daq.buffer_s`` seconds, read
``daq.reads_per_second`` times per second by an ``AnalogMultiChannelReader`` into arrays the recorder
preallocates. A buffer overrun raises :class:`~scanner.acquisition.devices.protocols.AcquisitionError`: the step
fails, it never gets a silent gap.

:class:`PlaybackDaq` is the simulated and the replay DAQ: it plays the volts of a
:class:`~scanner.acquisition.devices.sources.SignalSource`, in real time or at once.

``nidaqmx`` (and ``grpcio`` for a remote server) are imported only when a real DAQ is opened; a missing
package or NI-DAQmx driver is a one-line :class:`~scanner.acquisition.devices.protocols.DeviceUnavailable`.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from scanner.acquisition.config import MAX_HEAT_S, Calibration, DaqConfig
from scanner.acquisition.devices.protocols import AcquisitionError, DeviceError, DeviceUnavailable
from scanner.acquisition.devices.sources import SignalSource
from scanner.lazy import optional
from scanner.pacing import Pacer
from taxonomy.errors import ParameterError

OVERRUN_ERRORS = {-200279: "samples no longer available", -200361: "onboard FIFO overflow",
                  -200010: "input FIFO overflow", -200283: "acquisition stopped to prevent an overflow"}
"""DAQmx error codes meaning that samples were lost because the host did not read in time."""
TIMEOUT_ERROR = -200284
"""DAQmx: the requested samples did not arrive within the read timeout."""


def _import_nidaqmx() -> Any:
    for module in ("nidaqmx.stream_readers", "nidaqmx.stream_writers"):
        optional(module, None, "the real DAQ", install="pip install nidaqmx", error=DeviceUnavailable)
    return optional("nidaqmx", None, "the real DAQ", install="pip install nidaqmx", error=DeviceUnavailable)


def _grpc_channel(address: str) -> Any:
    grpc = optional("grpc", None, "a remote DAQ (grpc://)", install="pip install 'nidaqmx[grpc]'",
                    error=DeviceUnavailable)
    return grpc.insecure_channel(address)


class NidaqmxDaq:
    """The NI USB-6002 through ``nidaqmx``, local or through an NI gRPC Device Server.

    Opening it switches the Peltier line off, which also proves that the driver (or the server) and the
    device answer.
    """

    def __init__(self, config: DaqConfig) -> None:
        self.config = config
        self.rate = float(config.rate_hz)
        self.block = config.block
        self.channels = config.physical_channels
        self._nidaqmx = _import_nidaqmx()
        address = config.grpc_address
        self._channel = _grpc_channel(address) if address else None
        self._where = f"{config.device} on {address}" if address else config.device
        self._task: Any = None
        self._armed = ""
        self._reader: Any = None
        self._peltier: Any = None
        self._peltier_writer: Any = None
        self._lock = threading.Lock()
        try:
            self.set_peltier(False)
        except DeviceError:
            self.close()
            raise

    def _options(self) -> Any:
        if self._channel is None:
            return None
        return self._nidaqmx.GrpcSessionOptions(self._channel, "")

    def _call(self, what: str, action: Any) -> Any:
        """Run a DAQmx call, translating the library's errors into one-line device errors."""
        errors = self._nidaqmx.errors
        try:
            return action()
        except errors.DaqNotFoundError:
            raise DeviceUnavailable("NI-DAQmx driver not found: install it (python -m nidaqmx "
                                    "installdriver), use a remote server (--daq grpc://host:port) "
                                    "or the simulated DAQ") from None
        except errors.RpcError as exc:
            raise DeviceUnavailable(f"DAQ {self._where}: {what} failed: {_first_line(str(exc))}") from None
        except errors.DaqError as exc:
            code = exc.error_code
            if code in OVERRUN_ERRORS:
                raise AcquisitionError(f"DAQ {self._where}: buffer overrun ({OVERRUN_ERRORS[code]}, DAQmx "
                                       f"{code}): samples were lost, redo the step") from None
            if code == TIMEOUT_ERROR:
                raise AcquisitionError(f"DAQ {self._where}: no samples within the read timeout") from None
            raise DeviceError(f"DAQ {self._where}: {what} failed: DAQmx {code}: "
                              f"{_first_line(str(exc))}") from None

    def describe(self) -> dict[str, str]:
        def identify() -> str:
            device = self._nidaqmx.system.Device(self.config.device, grpc_options=self._options())
            return f"NI {device.product_type} serial {device.serial_num:X}"

        try:
            name = self._call("identify", identify)
        except DeviceError:
            name = "NI-DAQmx device"
        return {"daq": f"{name} ({self._where})"}

    def arm(self, step: str) -> None:
        """Create and configure the task ``texplorer-<step>`` reading every mapped analog input, unstarted.

        The slow part of a start (several DAQmx calls, each a round trip to a remote server), so that
        :meth:`start` right after the microphone's start is one call.
        """
        nidaqmx = self._nidaqmx
        constants = nidaqmx.constants
        self.stop()

        def configure() -> Any:
            task = nidaqmx.Task(f"texplorer-{step}", grpc_options=self._options())
            try:
                names = ", ".join(f"{self.config.device}/{channel}" for channel in self.channels)
                task.ai_channels.add_ai_voltage_chan(
                    names, terminal_config=constants.TerminalConfiguration[self.config.terminal],
                    min_val=-self.config.range_v, max_val=self.config.range_v)
                buffer = int(self.config.buffer_s * self.rate)
                task.timing.cfg_samp_clk_timing(self.rate, sample_mode=constants.AcquisitionType.CONTINUOUS,
                                                samps_per_chan=buffer)
                # Exactly this buffer, not DAQmx's larger automatic one: how long a stall may last is a
                # configured promise.
                task.in_stream.input_buf_size = buffer
            except BaseException:
                task.close()
                raise
            return task

        self._task = self._call("configuring the analog inputs", configure)
        self._armed = step
        self._reader = nidaqmx.stream_readers.AnalogMultiChannelReader(self._task.in_stream)
        self._reader.verify_array_shape = False

    def start(self, step: str) -> float:
        """Start the armed task (arming it first if :meth:`arm` was not called for ``step``)."""
        if self._task is None or self._armed != step:
            self.arm(step)
        before = time.perf_counter()
        self._call("starting", self._task.start)
        return (before + time.perf_counter()) / 2

    def read_into(self, out: np.ndarray) -> None:
        """Fill ``out`` (channels, n) with the next n samples per channel; raises on overrun or timeout."""
        if self._reader is None:
            raise DeviceError("DAQ: read before start")
        n = out.shape[1]
        timeout = 2.0 * n / self.rate + 1.0
        read = self._call("reading", lambda: self._reader.read_many_sample(
            out, number_of_samples_per_channel=n, timeout=timeout))
        if read != n:
            raise AcquisitionError(f"DAQ {self._where}: read {read} of {n} samples per channel")

    def stop(self) -> None:
        task, self._task, self._reader = self._task, None, None
        if task is not None:
            try:
                self._call("stopping", task.stop)
            finally:
                task.close()

    def set_peltier(self, on: bool) -> None:
        """Drive the Peltier line (``daq.peltier_line``) high or low."""
        with self._lock:
            if self._peltier is None:
                self._peltier = self._call("opening the Peltier line", self._open_peltier)
                self._peltier_writer = self._nidaqmx.stream_writers.DigitalSingleChannelWriter(
                    self._peltier.out_stream)
            self._call("switching the Peltier", lambda: self._write_peltier(bool(on)))

    def _write_peltier(self, on: bool) -> None:
        self._peltier_writer.write_one_sample_one_line(on)

    def _open_peltier(self) -> Any:
        task = self._nidaqmx.Task("texplorer-peltier", grpc_options=self._options())
        try:
            task.do_channels.add_do_chan(f"{self.config.device}/{self.config.peltier_line}")
        except BaseException:
            task.close()
            raise
        return task

    def close(self) -> None:
        """Stop any acquisition, switch the Peltier off and release every task."""
        try:
            self.stop()
        finally:
            peltier, self._peltier = self._peltier, None
            try:
                if peltier is not None:
                    self._call("switching the Peltier off", lambda: self._write_peltier(False))
            finally:
                if peltier is not None:
                    peltier.close()
                if self._channel is not None:
                    self._channel.close()
                    self._channel = None


def _first_line(text: str) -> str:
    return text.strip().splitlines()[0] if text.strip() else "unknown error"


class PlaybackDaq:
    """The simulated or replay DAQ: plays ``source.daq_volts(step)`` block by block.

    ``pacer`` holds reads back to real time (or not, at speed 0). A recording longer than the source's take
    holds the take's last sample. The Peltier line is only remembered (``peltier_on``, ``peltier_log``).
    """

    def __init__(self, source: SignalSource, calibration: Calibration, *, rate: float = 3000.0,
                 block: int = 200, pacer: Pacer | None = None, name: str = "daq") -> None:
        self.source = source
        self.calibration = calibration
        self.rate = float(rate)
        self.block = int(block)
        self.channels = tuple(f"ai{i}" for i in range(8))
        self.pacer = pacer or Pacer(0.0)
        self.name = name
        self.peltier_on = False
        self.peltier_log: list[tuple[float, bool]] = []
        self._volts: np.ndarray | None = None
        self._armed = ""
        self._position = 0

    def describe(self) -> dict[str, str]:
        return {"daq": f"NI USB-6002 ({self.source.kind})", "source": self.source.describe()}

    def arm(self, step: str) -> None:
        self._volts = self.source.daq_volts(step, self.calibration, self.name)
        self._armed = step

    def start(self, step: str) -> float:
        if self._volts is None or self._armed != step:
            self.arm(step)
        self._position = 0
        return self.pacer.start()

    def read_into(self, out: np.ndarray) -> None:
        if self._volts is None:
            raise DeviceError("DAQ: read before start")
        n = out.shape[1]
        rows = np.arange(self._position, self._position + n).clip(max=len(self._volts) - 1)
        out[:] = self._volts[rows].T
        self._position += n
        self.pacer.wait(self._position / self.rate)

    def stop(self) -> None:
        self._volts = None

    def set_peltier(self, on: bool) -> None:
        self.peltier_on = bool(on)
        self.peltier_log.append((time.perf_counter(), self.peltier_on))

    def close(self) -> None:
        self.stop()
        if self.peltier_on:
            self.set_peltier(False)


class DaqPeltier:
    """The Peltier on the DAQ's digital line, with a watchdog thread that switches it off after the asked
    time even if the thread that switched it on is stuck (the USB-6002 has no hardware watchdog)."""

    def __init__(self, daq: Any) -> None:
        self.daq = daq
        self._timer: threading.Timer | None = None
        self._lock = threading.Lock()

    def on(self, seconds: float) -> None:
        if not 0 < seconds <= MAX_HEAT_S:
            raise ParameterError(f"Peltier heating of {seconds:g} s is outside (0, {MAX_HEAT_S:g}] s")
        with self._lock:
            self._cancel_timer()
            self.daq.set_peltier(True)
            self._timer = threading.Timer(seconds, self.off)
            self._timer.daemon = True
            self._timer.start()

    def off(self) -> None:
        with self._lock:
            self._cancel_timer()
            self.daq.set_peltier(False)

    def check(self) -> None:
        """The line is only driven by this process; a lost connection shows when switching it."""

    def _cancel_timer(self) -> None:
        if self._timer is not None and self._timer is not threading.current_thread():
            self._timer.cancel()
        self._timer = None
