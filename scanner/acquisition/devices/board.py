"""The serial sensor board (docs/devices.md): MLX90614 thermometer, MAG3110 magnetometer and the Peltier relay on an
Arduino-class board, 115200 baud 8N1, newline-terminated ASCII.

=====================  ==========================================  ====================================
host -> board          board -> host                               meaning
=====================  ==========================================  ====================================
``ID?``                ``ID TEXPLORER-SB <version>``               identify
``START T <hz>``       ``T,<ms>,<object_degC>,<ambient_degC>*CS``  temperature stream
``START M <hz>``       ``M,<ms>,<bx_uT>,<by_uT>,<bz_uT>*CS``       magnetometer stream
``STOP``               (nothing)                                   stop every stream
``HEAT <ms>``          ``OK HEAT`` (``ERR ...`` above 5000 ms)     Peltier on for ms, ``HEAT 0`` = off
``CAL M``              ``OK CAL``                                  zero the magnetometer
(any problem)          ``ERR <text>``
=====================  ==========================================  ====================================

``CS`` is the two-hex-digit XOR of every character between the line start and ``*``
(:func:`checksum`). :class:`SerialBoard` is the ``pyserial`` driver: a reader thread splits the byte stream
into lines, drops and counts lines with a bad checksum, resynchronises on garbage (a frame start inside a
damaged line is kept), detects gaps from the board's millisecond counter, raises
:class:`~scanner.acquisition.devices.protocols.BoardTimeout` after 1 s of silence and reconnects by port name when the
connection is lost (sending ``HEAT 0`` and ``STOP`` first thing after reconnecting). :class:`PlaybackBoard`
is the simulated and replay board; :class:`BoardModel` is what its sensors read (shared with the emulator).
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

try:
    from termios import error as _TermiosError  # POSIX: pyserial's flush (tcdrain) raises it on a dead link
except ImportError:  # Windows
    _TermiosError = OSError

from scanner.acquisition.config import MAX_HEAT_S, BoardConfig
from scanner.acquisition.devices.protocols import (
    AcquisitionError,
    BoardSample,
    BoardStats,
    BoardTimeout,
    ConnectionLost,
    DeviceError,
    DeviceUnavailable,
)
from scanner.acquisition.devices.sources import SignalSource
from scanner.lazy import optional
from scanner.pacing import Pacer
from taxonomy.errors import ParameterError, TexplorerError

BOARD_ID = "TEXPLORER-SB"
MAX_HEAT_MS = int(MAX_HEAT_S * 1000)
DATA_FIELDS = {"T": 2, "M": 3}
"""Values per data line: T object and ambient degC; M bx, by, bz uT."""
REPLIES = ("ID ", "OK ", "ERR ")
MAX_LINE = 256
"""Longer runs of bytes without a newline are garbage (a data line has fewer than 60 characters)."""
MAGNET_DIRECTION = np.array([0.10, -0.05, 1.0]) / np.linalg.norm([0.10, -0.05, 1.0])
"""Direction of a sample's field change at the MAG3110 (mostly z, normal to the surface; simulated boards)."""
EARTH_FIELD_UT = np.array([18.0, -4.0, 41.0])
"""What the MAG3110 reads before ``CAL M`` zeroes it: the earth's field plus the unit's own offsets."""


class LineError(TexplorerError, ValueError):
    """A line from the board that is not a valid frame; ``garbage`` says whether it is noise (no frame)."""

    def __init__(self, reason: str, *, garbage: bool) -> None:
        super().__init__(reason)
        self.garbage = garbage


def checksum(body: str) -> str:
    """Two upper-case hex digits: the XOR of the character codes of ``body`` (docs/devices.md).

    >>> checksum("T,1000,25.00,21.50")
    '78'
    """
    value = 0
    for char in body:
        value ^= ord(char)
    return f"{value:02X}"


def format_data_line(kind: str, ms: int, values: tuple[float, ...]) -> str:
    """A board data line, e.g. ``T,1000,25.00,21.50*0C`` (two decimals, no newline)."""
    body = ",".join([kind, str(int(ms)), *(f"{v:.2f}" for v in values)])
    return f"{body}*{checksum(body)}"


def parse_data_line(line: str) -> BoardSample:
    """A checksummed ``T`` or ``M`` line -> :class:`BoardSample`; raises :class:`LineError`."""
    body, star, given = line.partition("*")
    if not star or len(given) != 2:
        raise LineError(f"no checksum in {line!r}", garbage=True)
    fields = body.split(",")
    kind = fields[0]
    if kind not in DATA_FIELDS or len(fields) != 2 + DATA_FIELDS[kind]:
        raise LineError(f"not a T or M line: {line!r}", garbage=True)
    if given.upper() != checksum(body):
        raise LineError(f"bad checksum {given} (expected {checksum(body)}) in {line!r}", garbage=False)
    try:
        ms = int(fields[1])
        values = tuple(float(v) for v in fields[2:])
    except ValueError:
        raise LineError(f"malformed numbers in {line!r}", garbage=False) from None
    if ms < 0 or not all(math.isfinite(v) for v in values):
        raise LineError(f"out-of-range numbers in {line!r}", garbage=False)
    return BoardSample(kind, ms, values)


def resync(raw: bytes) -> tuple[str | None, int]:
    """The frame in a received line and the count of garbage bytes before it.

    A line may start with noise (a corrupted byte run, half a line after a reconnect); the frame is the last
    ``T,``, ``M,``, ``ID ``, ``OK `` or ``ERR `` that starts a valid line within it. Returns (None, len)
    if there is none.
    """
    text = raw.decode("ascii", errors="replace")
    starts = [i for marker in ("T,", "M,", *REPLIES) for i in _find_all(text, marker)]
    for start in sorted(starts):
        candidate = text[start:]
        if "\ufffd" in candidate:
            continue
        if candidate.startswith(REPLIES):
            return candidate, start
        try:
            parse_data_line(candidate)
        except LineError as error:
            if not error.garbage:
                return candidate, start
            continue
        return candidate, start
    return None, len(raw)


def _find_all(text: str, marker: str) -> list[int]:
    found, start = [], text.find(marker)
    while start >= 0:
        found.append(start)
        start = text.find(marker, start + 1)
    return found


def field_change(b: np.ndarray) -> np.ndarray:
    """``dB`` from zeroed MAG3110 readings (n, 3) uT: ``sign(bz) * |b|``.

    Interpretation: after ``CAL M`` (unit in the air) a reading is the field change the sample causes. Its
    magnitude is the change; its sign is that of the z component, normal to the surface, where ferro- and
    paramagnetic samples raise the field and diamagnetic ones lower it (docs/database.md ``dB`` is signed).
    """
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3)
    return np.where(b[:, 2] < 0, -1.0, 1.0) * np.sqrt(np.sum(b**2, axis=1))


@dataclass
class StreamRecord:
    """Samples of one stream placed on the board's clock: ``values`` (n, k), ``missing`` samples the
    counter says never arrived (filled by linear interpolation and reported), ``duplicates`` dropped."""

    values: np.ndarray
    missing: int
    duplicates: int


class StreamCollector:
    """Places the samples of one stream by the board's millisecond counter and detects gaps.

    Sample index = round((ms - ms0) * hz / 1000); an index more than one past the last is a gap, an index
    not past the last is a duplicate (dropped).
    """

    def __init__(self, hz: float, count: int, fields: int) -> None:
        self.hz, self.count = float(hz), int(count)
        self.values = np.full((self.count, fields), np.nan)
        self.first_ms: int | None = None
        self.last = -1
        self.missing = 0
        self.duplicates = 0

    @property
    def done(self) -> bool:
        return self.last >= self.count - 1

    def add(self, sample: BoardSample) -> None:
        if self.first_ms is None:
            self.first_ms = sample.ms
        index = int(round((sample.ms - self.first_ms) * self.hz / 1000.0))
        if index <= self.last:
            self.duplicates += 1
            return
        if index >= self.count:
            self.missing += self.count - 1 - self.last
            self.last = self.count - 1
            return
        self.missing += index - self.last - 1
        self.values[index] = sample.values
        self.last = index

    def record(self) -> StreamRecord:
        """The filled samples with every gap linearly interpolated (never left as NaN)."""
        values = self.values.copy()
        known = ~np.isnan(values[:, 0])
        if not known.any():
            raise AcquisitionError("serial board: no samples received")
        index = np.arange(self.count)
        for column in range(values.shape[1]):
            values[:, column] = np.interp(index, index[known], values[known, column])
        return StreamRecord(values, self.missing, self.duplicates)


def collect(board: Any, kind: str, hz: float, seconds: float, *, cancel: threading.Event | None = None,
            on_samples: Callable[[int, tuple[float, ...]], None] | None = None,
            timeout: float = 1.0) -> StreamRecord:
    """Start the ``kind`` stream at ``hz``, gather ``seconds`` of it by the board's counter, stop it.

    ``on_samples(n, latest)`` is told how many samples have arrived and the latest values (for a level
    meter); ``cancel`` stops early with :class:`AcquisitionError`. The stream is stopped on every exit.
    """
    collector = StreamCollector(hz, int(round(seconds * hz)), DATA_FIELDS[kind])
    board.start(kind, hz)
    try:
        while not collector.done:
            if cancel is not None and cancel.is_set():
                raise AcquisitionError("recording cancelled")
            samples = [sample for sample in board.read(timeout) if sample.kind == kind]
            for sample in samples:
                collector.add(sample)
            if on_samples is not None and samples:
                on_samples(collector.last + 1, samples[-1].values)
    finally:
        board.stop()
    board.stats.missing_samples += collector.missing
    return collector.record()


def _import_serial() -> Any:
    return optional("serial", None, "the serial sensor board", install="pip install pyserial",
                    error=DeviceUnavailable)


class SerialBoard:
    """The sensor board through ``pyserial`` on a port given by name (``COM3``, ``/dev/ttyACM0``).

    Opening identifies the board (``ID?``) and switches the Peltier off. A reader thread turns received
    bytes into data samples (queued for :meth:`read`) and replies (for the command that waits for one).
    """

    def __init__(self, config: BoardConfig) -> None:
        self.config = config
        self.port = config.port
        self.stats = BoardStats()
        self.identity = ""
        self.errors: list[str] = []
        self._serial_module = _import_serial()
        # TypeError/AttributeError: the reader thread closed the port under a writer while reconnecting.
        self._link_errors = (self._serial_module.SerialException, OSError, _TermiosError, TypeError, AttributeError)
        self._serial: Any = None
        self._write_lock = threading.Lock()
        self._samples: queue.Queue[BoardSample] = queue.Queue()
        self._replies: queue.Queue[str] = queue.Queue()
        self._stop = threading.Event()
        self._reopen = threading.Event()
        self._lost: str | None = None
        self._failed: str | None = None
        self._streaming = False
        self._last_data = time.monotonic()
        self._stale = False
        self._open_port()
        self._thread = threading.Thread(target=self._reader, name=f"board-reader {self.port}", daemon=True)
        self._thread.start()
        try:
            self._handshake()
        except BaseException:
            self.close(confirm=False)
            raise

    # -- connection ------------------------------------------------------------------------------

    def _open_port(self) -> None:
        serial = self._serial_module
        try:
            self._serial = serial.Serial(self.port, self.config.baudrate, bytesize=8, parity="N", stopbits=1,
                                         timeout=0.05, write_timeout=1.0)
        except Exception as exc:  # noqa: BLE001 - pyserial lets termios.error through on POSIX
            raise DeviceUnavailable(f"serial board: cannot open {self.port}: {_reason(exc)}") from None

    def _handshake(self) -> None:
        reply = self.command("ID?", expect="ID ")
        if not reply.startswith(f"ID {BOARD_ID} "):
            raise DeviceUnavailable(f"serial board on {self.port}: {reply!r} is not a {BOARD_ID}")
        self.identity = reply.removeprefix(f"ID {BOARD_ID} ")
        self.heat_off()

    def _reader(self) -> None:
        buffer = b""
        while not self._stop.is_set():
            if self._reopen.is_set():
                buffer = b""
                self._reconnect()
                self._reopen.clear()
                continue
            try:
                chunk = self._serial.read(max(1, self._serial.in_waiting))
            except self._link_errors as exc:
                if self._stop.is_set():
                    return
                buffer = b""
                self._lost = f"serial board on {self.port} disconnected ({_reason(exc)})"
                self._reconnect()
                continue
            if not chunk:
                continue
            buffer += chunk
            *lines, buffer = buffer.split(b"\n")
            if len(buffer) > MAX_LINE:
                self.stats.garbage_bytes += len(buffer)
                buffer = b""
            for line in lines:
                self._take_line(line.rstrip(b"\r"))

    def _take_line(self, raw: bytes) -> None:
        if not raw:
            return
        line, skipped = resync(raw)
        self.stats.garbage_bytes += skipped
        if line is None:
            return
        if line.startswith(REPLIES):
            self._replies.put(line)
            return
        try:
            sample = parse_data_line(line)
        except LineError:
            self.stats.bad_checksums += 1
            return
        self._last_data = time.monotonic()
        self._samples.put(sample)

    def _reconnect(self) -> None:
        """Close the port and reopen it by name until ``reconnect_s`` runs out, then make the board safe."""
        try:
            self._serial.close()
        except Exception:  # noqa: BLE001 - the port is already broken; closing is best effort
            pass
        deadline = time.monotonic() + self.config.reconnect_s
        while not self._stop.is_set():
            try:
                self._open_port()
            except DeviceUnavailable:
                if time.monotonic() > deadline:
                    lost = self._lost or f"serial board on {self.port} stopped answering"
                    self._failed = f"{lost} and not back within {self.config.reconnect_s:g} s"
                    return
                time.sleep(0.1)
                continue
            self.stats.reconnects += 1
            # First thing on a new connection: nothing heats and nothing streams until the host asks again.
            try:
                self._write("HEAT 0")
                self._write("STOP")
            except ConnectionLost:
                continue
            return

    def _write(self, text: str) -> None:
        with self._write_lock:
            try:
                self._serial.write(f"{text}\n".encode("ascii"))
                self._serial.flush()
            except self._link_errors as exc:
                raise ConnectionLost(f"serial board on {self.port}: cannot send {text!r}: "
                                     f"{_reason(exc)}") from None

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the connection failed, or dropped since the last check."""
        if self._failed:
            raise ConnectionLost(self._failed)
        if self._lost:
            lost, self._lost = self._lost, None
            raise ConnectionLost(f"{lost}: redo the step")

    def _recover(self) -> None:
        """After a silence timeout: reopen the port (which resets an Arduino) and identify the board again."""
        self._stale = False
        self._streaming = False
        self._reopen.set()
        deadline = time.monotonic() + self.config.reconnect_s + 1.0
        while self._reopen.is_set() and time.monotonic() < deadline:
            time.sleep(0.01)
        self._check_failed()
        while True:
            try:
                self._handshake()
                return
            except BoardTimeout:
                if time.monotonic() > deadline:
                    raise

    # -- commands --------------------------------------------------------------------------------

    def command(self, text: str, expect: str = "OK ") -> str:
        """Send one command and wait (1 s) for its reply line; ``ERR ...`` raises :class:`DeviceError`."""
        while not self._replies.empty():
            stale = self._replies.get_nowait()
            if stale.startswith("ERR"):
                self.errors.append(stale)
        self._write(text)
        try:
            reply = self._replies.get(timeout=self.config.timeout_s)
        except queue.Empty:
            self.check()
            raise BoardTimeout(f"serial board on {self.port}: no reply to {text!r} within "
                               f"{self.config.timeout_s:g} s") from None
        if reply.startswith("ERR"):
            raise DeviceError(f"serial board on {self.port}: {text!r} refused: {reply}")
        if not reply.startswith(expect):
            raise DeviceError(f"serial board on {self.port}: unexpected reply {reply!r} to {text!r}")
        return reply

    def describe(self) -> dict[str, str]:
        return {"sensor_board": f"{BOARD_ID} {self.identity} ({self.port})"}

    def ambient(self) -> float:
        """Ambient temperature from one T line (the MLX90614's die sensor), degC."""
        record = collect(self, "T", self.config.thermal_hz, 1 / self.config.thermal_hz)
        return float(record.values[0, 1])

    def calibrate_magnetometer(self) -> None:
        self._prepare()
        self.command("CAL M", expect="OK CAL")

    def start(self, kind: str, hz: float) -> None:
        if kind not in DATA_FIELDS:
            raise ParameterError(f"board stream must be T or M, got {kind!r}")
        self._prepare()
        while not self._samples.empty():
            self._samples.get_nowait()
        self._write(f"START {kind} {_number(hz)}")
        self._streaming = True
        self._last_data = time.monotonic()

    def _prepare(self) -> None:
        self.check()
        if self._stale:
            self._recover()

    def read(self, timeout: float) -> list[BoardSample]:
        """Samples since the last call; :class:`BoardTimeout` after ``config.timeout_s`` without data."""
        self.check()
        try:
            samples = [self._samples.get(timeout=min(timeout, self.config.timeout_s))]
        except queue.Empty:
            samples = []
        while not self._samples.empty():
            samples.append(self._samples.get_nowait())
        self.check()
        if self._streaming:
            self._raise_board_error()
        silent = time.monotonic() - self._last_data
        if self._streaming and not samples and silent >= self.config.timeout_s:
            self._stale = True
            raise BoardTimeout(f"serial board on {self.port}: no data for {silent:.1f} s")
        return samples

    def _raise_board_error(self) -> None:
        """An ``ERR`` line nobody asked for (a sensor failed while streaming) fails the recording."""
        while not self._replies.empty():
            line = self._replies.get_nowait()
            if line.startswith("ERR"):
                self.errors.append(line)
                raise DeviceError(f"serial board on {self.port}: {line}")

    def stop(self) -> None:
        self._streaming = False
        if self._failed:
            return
        try:
            self._write("STOP")
        except ConnectionLost:
            return
        # Lines already on their way are not part of the next stream.
        deadline = time.monotonic() + 0.2
        quiet_since = time.monotonic()
        while time.monotonic() < deadline and time.monotonic() - quiet_since < 0.06:
            try:
                self._samples.get(timeout=0.02)
                quiet_since = time.monotonic()
            except queue.Empty:
                pass

    def heat(self, ms: int) -> None:
        """``HEAT <ms>``: the board heats for ``ms`` and switches off itself; more than 5000 ms is refused."""
        ms = int(ms)
        if not 0 < ms <= MAX_HEAT_MS:
            raise ParameterError(f"Peltier heating of {ms} ms is outside 1..{MAX_HEAT_MS} ms")
        self._prepare()
        self.command(f"HEAT {ms}", expect="OK HEAT")

    def heat_off(self) -> None:
        """``HEAT 0``: Peltier off now."""
        self._check_failed()
        self.command("HEAT 0", expect="OK HEAT")

    def _check_failed(self) -> None:
        if self._failed:
            raise ConnectionLost(self._failed)

    def close(self, confirm: bool = True) -> None:
        """Stop streams, switch the Peltier off (waiting for ``OK HEAT`` if ``confirm``), release the port."""
        try:
            if self._serial is not None and not self._failed and self._thread.is_alive():
                self._write("STOP")
                if confirm:
                    self.command("HEAT 0", expect="OK HEAT")
                else:
                    self._write("HEAT 0")
        except DeviceError:
            pass
        finally:
            self._stop.set()
            if self._thread.is_alive() and self._thread is not threading.current_thread():
                self._thread.join(timeout=1.0)
            if self._serial is not None:
                self._serial.close()


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


def _reason(exc: BaseException) -> str:
    text = str(exc).strip() or type(exc).__name__
    return text.splitlines()[0]


class BoardModel:
    """What the sensors of a simulated board read, given a :class:`SignalSource`.

    After ``HEAT`` the next temperature stream plays the source's cooling curve (the operator has moved the
    MLX90614 over the heated spot); otherwise the object is at room temperature. After ``CAL M`` (unit in
    the air) the next magnetometer stream plays the field change as the unit is placed, along
    :data:`MAGNET_DIRECTION`; before any ``CAL M`` the readings include the earth's field.
    """

    def __init__(self, source: SignalSource, device: str = "board", seed: int = 0) -> None:
        self.source = source
        self.device = device
        self.rng = np.random.default_rng(seed)
        self.offset = np.zeros(3)
        self.heated = False
        self.calibrated = False
        self._trace: np.ndarray | None = None
        self._hz = 20.0

    def calibrate(self) -> None:
        self.offset = EARTH_FIELD_UT.copy()
        self.calibrated = True

    def heat(self) -> None:
        self.heated = True

    def begin(self, kind: str, hz: float) -> None:
        """A stream starts: decide what it plays."""
        self._hz = float(hz)
        if kind == "T":
            self._trace = self.source.cooling(self.device) if self.heated else None
            self.heated = False
        else:
            self._trace = self.source.field_change(self.device) if self.calibrated else None
            self.calibrated = False

    def values(self, kind: str, index: int) -> tuple[float, ...]:
        """The ``index``-th sample of the running stream."""
        if kind == "T":
            ambient = _steps(self.source.t_amb + self.rng.normal(0.0, 0.02), 0.02)
            if self._trace is None:
                return _steps(self.source.t_amb + 0.1 + self.rng.normal(0.0, 0.02), 0.02), ambient
            position = min(int(index * 20.0 / self._hz), len(self._trace) - 1)
            return float(self._trace[position]), ambient
        change = 0.0
        if self._trace is not None:
            change = float(self._trace[min(int(index * 80.0 / self._hz), len(self._trace) - 1)])
        b = EARTH_FIELD_UT - self.offset + change * MAGNET_DIRECTION
        return tuple(float(v) for v in b)


def _steps(value: float, step: float) -> float:
    return round(value / step) * step


class PlaybackBoard:
    """The simulated or replay sensor board: :class:`BoardModel` readings on the board's clock."""

    def __init__(self, source: SignalSource, *, pacer: Pacer | None = None, chunk_s: float = 0.1) -> None:
        self.model = BoardModel(source)
        self.source = source
        self.pacer = pacer or Pacer(0.0)
        self.chunk_s = chunk_s
        self.stats = BoardStats()
        self.heat_log: list[tuple[float, int]] = []
        self._kind: str | None = None
        self._hz = 0.0
        self._sent = 0
        self._ms0 = 0

    def describe(self) -> dict[str, str]:
        return {"sensor_board": f"{BOARD_ID} ({self.source.kind})"}

    def ambient(self) -> float:
        return float(self.model.values("T", 0)[1])

    def calibrate_magnetometer(self) -> None:
        self.model.calibrate()

    def start(self, kind: str, hz: float) -> None:
        if kind not in DATA_FIELDS:
            raise ParameterError(f"board stream must be T or M, got {kind!r}")
        self.model.begin(kind, hz)
        self._kind, self._hz, self._sent = kind, float(hz), 0
        self._ms0 += 100_000
        self.pacer.start()

    def read(self, timeout: float) -> list[BoardSample]:
        if self._kind is None:
            return []
        count = max(1, int(round(self.chunk_s * self._hz)))
        first, self._sent = self._sent, self._sent + count
        self.pacer.wait(self._sent / self._hz)
        return [BoardSample(self._kind, self._ms0 + int(round(i * 1000 / self._hz)),
                            self.model.values(self._kind, i)) for i in range(first, self._sent)]

    def stop(self) -> None:
        self._kind = None

    def heat(self, ms: int) -> None:
        if not 0 < int(ms) <= MAX_HEAT_MS:
            raise ParameterError(f"Peltier heating of {ms} ms is outside 1..{MAX_HEAT_MS} ms")
        self.model.heat()
        self.heat_log.append((time.perf_counter(), int(ms)))

    def heat_off(self) -> None:
        self.heat_log.append((time.perf_counter(), 0))

    def check(self) -> None:
        """A playback board never loses its connection."""

    def close(self) -> None:
        self.heat_off()


class BoardPeltier:
    """The Peltier on the board's relay: ``HEAT <ms>`` (the board switches off by itself) and ``HEAT 0``."""

    def __init__(self, board: Any) -> None:
        self.board = board

    def on(self, seconds: float) -> None:
        if not 0 < seconds <= MAX_HEAT_S:
            raise ParameterError(f"Peltier heating of {seconds:g} s is outside (0, {MAX_HEAT_S:g}] s")
        self.board.heat(int(round(seconds * 1000)))

    def off(self) -> None:
        self.board.heat_off()

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the board's connection dropped (it has switched off itself)."""
        self.board.check()
