"""The serial sensor board on a pseudo-terminal, speaking the protocol of docs/devices.md (see
:mod:`scanner.acquisition.devices.board`), with faults a test (or a person trying the app) can inject.

The host opens :attr:`BoardEmulator.path` with ``pyserial`` like any serial port. The path is a symbolic
link to the current pseudo-terminal, so after an injected :meth:`~BoardEmulator.disconnect` the board comes
back under the same name, as a USB board does. The sensors read a
:class:`~scanner.acquisition.devices.board.BoardModel` of a
:class:`~scanner.acquisition.devices.sources.SignalSource`: the cooling curve after ``HEAT``, the field
change after ``CAL M``.

Faults: :meth:`~BoardEmulator.corrupt_checksums` (the next n data lines),
:meth:`~BoardEmulator.inject_garbage` (bytes in front of the next data line),
:meth:`~BoardEmulator.skip_lines` (the next n data lines are not sent, so the counter jumps),
:meth:`~BoardEmulator.silence` (nothing in or out for a while) and :meth:`~BoardEmulator.disconnect`;
periodic faults with :class:`FaultPlan`. The Peltier's every switch is
logged with its time and cause in :attr:`~BoardEmulator.heat_log`; the board switches it off by itself
when the asked time has passed and refuses more than 5000 ms.

POSIX only (pseudo-terminals): ``texplorer emulate board`` prints the device path and runs until Ctrl-C.
"""

from __future__ import annotations

import os
import select
import tempfile
import threading
import time
import tty
from dataclasses import dataclass
from pathlib import Path

from scanner.acquisition.devices.board import BOARD_ID, DATA_FIELDS, MAX_HEAT_MS, BoardModel, format_data_line
from scanner.acquisition.devices.sources import SignalSource

VERSION = "1.2"
MAX_STREAM_HZ = 200.0


@dataclass
class FaultPlan:
    """Periodic faults: every n-th data line gets a bad checksum, garbage in front, or is not sent
    (0 = never)."""

    bad_checksum_every: int = 0
    garbage_every: int = 0
    gap_every: int = 0


@dataclass
class _Stream:
    hz: float
    started: float
    sent: int = 0


class BoardEmulator:
    """A TEXPLORER-SB sensor board on a pseudo-terminal; ``path`` is the port name for the host.

    Parameters
    ----------
    source : SignalSource
        What the MLX90614 and the MAG3110 observe.
    link : path, optional
        Where to put the stable symbolic link (default: a new temporary folder).
    faults : FaultPlan, optional
        Periodic faults.
    """

    def __init__(self, source: SignalSource, *, link: str | Path | None = None,
                 faults: FaultPlan | None = None, seed: int = 0) -> None:
        self.model = BoardModel(source, seed=seed)
        self.faults = faults or FaultPlan()
        folder = Path(tempfile.mkdtemp(prefix="texplorer-board-")) if link is None else None
        self.path = Path(link) if link else folder / "ttyTEXPLORER0"
        self.received: list[str] = []
        self.heat_log: list[tuple[float, bool, str]] = []
        self.heating_until: float | None = None
        self.boot = time.monotonic()
        self.lines_sent = 0
        self._lock = threading.Lock()
        self._streams: dict[str, _Stream] = {}
        self._bad_checksums = 0
        self._skips = 0
        self._garbage = b""
        self._silent_until = 0.0
        self._offline_until: float | None = None
        self._input = b""
        self._stop = threading.Event()
        self._master = self._slave = -1
        self._open_pty()
        self._thread = threading.Thread(target=self._run, name="board-emulator", daemon=True)
        self._thread.start()

    # -- faults and inspection -------------------------------------------------------------------

    def corrupt_checksums(self, lines: int = 1) -> None:
        """The next ``lines`` data lines carry a wrong checksum."""
        with self._lock:
            self._bad_checksums += lines

    def inject_garbage(self, data: bytes) -> None:
        """Send ``data`` right before the next data line (no newline in between)."""
        with self._lock:
            self._garbage += data

    def skip_lines(self, lines: int = 1) -> None:
        """Do not send the next ``lines`` data lines (the board's counter jumps over them)."""
        with self._lock:
            self._skips += lines

    def silence(self, seconds: float) -> None:
        """Send nothing and ignore every command for ``seconds`` (a hung board)."""
        with self._lock:
            self._silent_until = time.monotonic() + seconds

    def disconnect(self, downtime: float = 0.5) -> None:
        """Drop the connection (the host's port fails) and come back at the same path after ``downtime``.

        Meanwhile the path is gone, as a USB serial device's node is while it is unplugged.
        """
        with self._lock:
            self._offline_until = time.monotonic() + downtime
            self.path.unlink(missing_ok=True)
            self._close_pty()

    @property
    def heating(self) -> bool:
        return self.heating_until is not None

    def heat_intervals(self) -> list[tuple[float, float, str]]:
        """(on, off, why off) for every heating in :attr:`heat_log` (``off`` = inf while still on)."""
        intervals, started = [], None
        for when, on, why in self.heat_log:
            if on and started is None:
                started = when
            elif not on and started is not None:
                intervals.append((started, when, why))
                started = None
        if started is not None:
            intervals.append((started, float("inf"), "still on"))
        return intervals

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        with self._lock:
            self._close_pty()
            self.path.unlink(missing_ok=True)

    def __enter__(self) -> BoardEmulator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the pseudo-terminal ---------------------------------------------------------------------

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        temporary = self.path.with_name(self.path.name + ".new")
        temporary.unlink(missing_ok=True)
        temporary.symlink_to(os.ttyname(slave))
        os.replace(temporary, self.path)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                os.close(fd)
        self._master = self._slave = -1
        self._input = b""
        self._streams.clear()

    # -- the board's main loop -------------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop.is_set():
            now = time.monotonic()
            self._peltier_timer(now)
            with self._lock:
                offline = self._master < 0
                if offline and self._offline_until is not None and now >= self._offline_until:
                    self._offline_until = None
                    self._open_pty()
                    offline = False
                master = self._master
            if offline:
                time.sleep(0.01)
                continue
            try:
                ready, _, _ = select.select([master], [], [], self._wait(now))
                data = os.read(master, 4096) if ready else b""
            except OSError:
                data = b""
            with self._lock:
                if self._master != master:
                    continue
                if now < self._silent_until:
                    for stream in self._streams.values():
                        stream.sent = int((now - stream.started) * stream.hz) + 1
                    continue
                self._input += data
                *lines, self._input = self._input.split(b"\n")
                for line in lines:
                    self._command(line.strip(b"\r").decode("ascii", errors="replace").strip())
                self._emit_due(time.monotonic())

    def _wait(self, now: float) -> float:
        due = [s.started + s.sent / s.hz for s in self._streams.values()]
        if self.heating_until is not None:
            due.append(self.heating_until)
        return max(0.0, min([now + 0.01, *due]) - now)

    def _peltier_timer(self, now: float) -> None:
        with self._lock:
            if self.heating_until is not None and now >= self.heating_until:
                self._switch(False, "board timer")

    def _switch(self, on: bool, why: str, ms: int = 0) -> None:
        now = time.monotonic()
        self.heating_until = now + ms / 1000 if on else None
        self.heat_log.append((now, on, why))

    def _send(self, text: str) -> None:
        try:
            os.write(self._master, text.encode("ascii") + b"\n")
        except (BlockingIOError, OSError):
            pass  # nobody reads the port: the bytes are lost, as on a real board's full USB buffer

    def _send_raw(self, data: bytes) -> None:
        try:
            os.write(self._master, data)
        except (BlockingIOError, OSError):
            pass

    # -- protocol --------------------------------------------------------------------------------

    def _command(self, text: str) -> None:
        if not text:
            return
        self.received.append(text)
        words = text.split()
        if text == "ID?":
            self._send(f"ID {BOARD_ID} {VERSION}")
        elif words[0] == "START" and len(words) == 3 and words[1] in DATA_FIELDS:
            self._start(words[1], words[2])
        elif text == "STOP":
            self._streams.clear()
        elif words[0] == "HEAT" and len(words) == 2:
            self._heat(words[1])
        elif text == "CAL M":
            self.model.calibrate()
            self._send("OK CAL")
        else:
            self._send(f"ERR unknown command {text[:40]}")

    def _start(self, kind: str, rate: str) -> None:
        try:
            hz = float(rate)
        except ValueError:
            hz = -1.0
        if not 0 < hz <= MAX_STREAM_HZ:
            self._send(f"ERR START {kind} rate must be 1..{MAX_STREAM_HZ:g} Hz")
            return
        self.model.begin(kind, hz)
        self._streams[kind] = _Stream(hz, time.monotonic())

    def _heat(self, value: str) -> None:
        if not value.isdigit():
            self._send(f"ERR HEAT needs milliseconds, got {value[:12]}")
            return
        ms = int(value)
        if ms > MAX_HEAT_MS:
            self._send(f"ERR HEAT {ms} ms exceeds {MAX_HEAT_MS} ms")
            return
        if ms == 0:
            if self.heating_until is not None:
                self._switch(False, "HEAT 0")
        else:
            self.model.heat()
            self._switch(True, f"HEAT {ms}", ms)
        self._send("OK HEAT")

    def _emit_due(self, now: float) -> None:
        for kind, stream in list(self._streams.items()):
            while stream.started + stream.sent / stream.hz <= now:
                scheduled = stream.started + stream.sent / stream.hz
                line = format_data_line(kind, int(round((scheduled - self.boot) * 1000)),
                                        self.model.values(kind, stream.sent))
                stream.sent += 1
                self._emit(line)

    def _emit(self, line: str) -> None:
        self.lines_sent += 1
        plan, n = self.faults, self.lines_sent
        if self._skips or (plan.gap_every and n % plan.gap_every == 0):
            self._skips = max(0, self._skips - 1)
            return
        if self._garbage or (plan.garbage_every and n % plan.garbage_every == 0):
            self._send_raw(self._garbage or b"\x00\xff#~*")
            self._garbage = b""
        if self._bad_checksums or (plan.bad_checksum_every and n % plan.bad_checksum_every == 0):
            self._bad_checksums = max(0, self._bad_checksums - 1)
            body, _, given = line.partition("*")
            line = f"{body}*{int(given, 16) ^ 0x55:02X}"
        self._send(line)
