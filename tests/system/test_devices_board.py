"""The serial sensor board: protocol parsing by hand, exact byte exchanges through pyserial on a pseudo-terminal
(PyMeasure style), and the driver against the emulator with every injected fault: the system tests (the board
and its emulator on pseudo-terminals)."""

from __future__ import annotations

import contextlib
import os
import select
import sys
import threading
import time
import tty

import numpy as np
import pytest

from scanner.acquisition.config import BoardConfig  # noqa: E402
from scanner.acquisition.devices.board import (  # noqa: E402
    SerialBoard,
    StreamCollector,
    collect,
)
from scanner.acquisition.devices.protocols import (  # noqa: E402
    BoardSample,
    BoardTimeout,
    ConnectionLost,
    DeviceError,
    DeviceUnavailable,
)
from scanner.acquisition.devices.sources import SimulatedSample  # noqa: E402
from scanner.acquisition.emulators.board import BoardEmulator, FaultPlan  # noqa: E402

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals are POSIX only")


serial = pytest.importorskip("serial")


@contextlib.contextmanager
def expected_protocol(exchanges: list[tuple[bytes, bytes]]):
    """A scripted board on a pseudo-terminal: each host message must arrive exactly, then its reply is sent.

    Yields the port path; on exit asserts that every exchange happened, in order, with the exact bytes.
    """
    master, slave = os.openpty()
    tty.setraw(slave)
    received: list[bytes] = []
    done = threading.Event()

    def device() -> None:
        buffer = b""
        for host, reply in exchanges:
            deadline = time.monotonic() + 5.0
            while len(buffer) < len(host) and time.monotonic() < deadline:
                if select.select([master], [], [], 0.05)[0]:
                    buffer += os.read(master, 1024)
            received.append(buffer[:len(host)])
            buffer = buffer[len(host):]
            if received[-1] != host:
                break
            os.write(master, reply)
        done.set()

    thread = threading.Thread(target=device, daemon=True)
    thread.start()
    try:
        yield os.ttyname(slave)
        assert done.wait(5.0), "the host did not send every expected message"
        assert received == [host for host, _ in exchanges]
    finally:
        thread.join(5.0)
        os.close(master)
        os.close(slave)


OPEN = [(b"ID?\n", b"ID TEXPLORER-SB 1.2\n"), (b"HEAT 0\n", b"OK HEAT\n")]


CLOSE = [(b"STOP\n", b""), (b"HEAT 0\n", b"OK HEAT\n")]


def test_open_identifies_the_board_and_switches_the_peltier_off():
    with expected_protocol(OPEN + CLOSE) as port:
        board = SerialBoard(BoardConfig(port=port))
        assert board.identity == "1.2"
        assert board.describe() == {"sensor_board": f"TEXPLORER-SB 1.2 ({port})"}
        board.close()


def test_commands_and_a_temperature_stream_byte_by_byte():
    lines = b"T,1000,25.00,21.50*78\nT,1050,24.98,21.50*7D\nT,1100,24.96,21.52*75\n"
    with expected_protocol(OPEN + [(b"CAL M\n", b"OK CAL\n"), (b"HEAT 3000\n", b"OK HEAT\n"),
                                   (b"START T 20\n", lines), (b"STOP\n", b""),
                                   (b"HEAT 4000\n", b"ERR relay fault\n")] + CLOSE) as port:
        board = SerialBoard(BoardConfig(port=port))
        board.calibrate_magnetometer()
        board.heat(3000)
        board.start("T", 20)
        samples: list[BoardSample] = []
        while len(samples) < 3:
            samples += board.read(1.0)
        board.stop()
        assert samples == [BoardSample("T", 1000, (25.0, 21.5)), BoardSample("T", 1050, (24.98, 21.5)),
                           BoardSample("T", 1100, (24.96, 21.52))]
        with pytest.raises(DeviceError, match="'HEAT 4000' refused: ERR relay fault"):
            board.heat(4000)
        board.close()


def test_an_err_line_while_streaming_fails_the_recording():
    lines = b"T,1000,25.00,21.50*78\nERR MLX90614 not answering\n"
    with expected_protocol(OPEN + [(b"START T 20\n", lines), (b"STOP\n", b"")] + CLOSE) as port:
        board = SerialBoard(BoardConfig(port=port))
        with pytest.raises(DeviceError, match="serial board on .*: ERR MLX90614 not answering"):
            collect(board, "T", 20, 1.0)
        assert board.errors == ["ERR MLX90614 not answering"]
        board.close()


def test_the_host_never_asks_for_more_than_5_s_of_heating():
    with expected_protocol(OPEN + CLOSE) as port:
        board = SerialBoard(BoardConfig(port=port))
        for ms in (5001, 0, -5):
            with pytest.raises(ValueError, match="outside 1..5000 ms"):
                board.heat(ms)
        board.close()


def test_a_device_that_is_not_the_board_is_refused():
    with expected_protocol([(b"ID?\n", b"ID ARDUINO-UNO 3\n")]) as port:
        with pytest.raises(DeviceUnavailable, match="'ID ARDUINO-UNO 3' is not a TEXPLORER-SB"):
            SerialBoard(BoardConfig(port=port))


def test_a_silent_device_times_out_after_one_second():
    with expected_protocol([(b"ID?\n", b""), (b"STOP\n", b""), (b"HEAT 0\n", b"")]) as port:
        started = time.monotonic()
        with pytest.raises(BoardTimeout, match="no reply to 'ID\\?' within 1 s"):
            SerialBoard(BoardConfig(port=port))
        assert 0.9 <= time.monotonic() - started < 2.0


@pytest.fixture
def sample():
    return SimulatedSample("granite-polished", seed=5)


def _exchange(port: serial.Serial, command: bytes) -> bytes:
    port.write(command)
    return port.readline()


def test_emulator_answers_the_protocol_exactly(sample):
    with BoardEmulator(sample) as emulator, serial.Serial(str(emulator.path), 115200, timeout=1.0) as port:
        assert _exchange(port, b"ID?\n") == b"ID TEXPLORER-SB 1.2\n"
        assert _exchange(port, b"CAL M\n") == b"OK CAL\n"
        assert _exchange(port, b"HEAT 6000\n") == b"ERR HEAT 6000 ms exceeds 5000 ms\n"
        assert _exchange(port, b"HEAT abc\n") == b"ERR HEAT needs milliseconds, got abc\n"
        assert _exchange(port, b"START T 500\n") == b"ERR START T rate must be 1..200 Hz\n"
        assert _exchange(port, b"FOO\n") == b"ERR unknown command FOO\n"
        port.write(b"START M 80\n")
        lines = [port.readline() for _ in range(4)]
        port.write(b"STOP\n")
        for line in lines:
            body, _, given = line.decode().strip().partition("*")
            fields = body.split(",")
            assert fields[0] == "M" and len(fields) == 5
            xor = 0
            for char in body:
                xor ^= ord(char)
            assert given == f"{xor:02X}"
        counters = [int(line.split(b",")[1]) for line in lines]
        assert set(np.diff(counters)) <= {12, 13}  # 80 Hz: 12.5 ms on a millisecond counter
        assert emulator.heat_log == []


def test_emulator_switches_the_peltier_off_by_itself(sample):
    with BoardEmulator(sample) as emulator, serial.Serial(str(emulator.path), 115200, timeout=1.0) as port:
        assert _exchange(port, b"HEAT 200\n") == b"OK HEAT\n"
        time.sleep(0.4)
        [(on, off, why)] = emulator.heat_intervals()
        assert why == "board timer" and 0.19 <= off - on <= 0.25


@pytest.fixture
def board_pair(sample):
    """A board emulator and the driver connected to it (reconnects within 2 s)."""
    def make(faults: FaultPlan | None = None):
        emulator = BoardEmulator(sample, faults=faults)
        board = SerialBoard(BoardConfig(port=str(emulator.path), reconnect_s=2.0))
        opened.append((board, emulator))
        return board, emulator

    opened: list = []
    yield make
    for board, emulator in opened:
        board.close()
        emulator.close()


def test_clean_stream_has_no_losses(board_pair):
    board, _ = board_pair()
    record = collect(board, "T", 20, 1.0)
    assert record.values.shape == (20, 2) and record.missing == 0
    assert board.stats.bad_checksums == 0 and board.stats.garbage_bytes == 0


def test_bad_checksums_are_dropped_counted_and_show_as_gaps(board_pair):
    board, _ = board_pair(FaultPlan(bad_checksum_every=4))
    record = collect(board, "T", 20, 1.0)
    # lines 4, 8, 12, 16 and 20 of the stream are dropped; the counter shows the 5 holes
    assert record.missing == 5 and board.stats.missing_samples == 5
    assert board.stats.bad_checksums in (5, 6)
    assert np.isfinite(record.values).all()


def test_garbage_is_skipped_and_the_frames_after_it_kept(board_pair):
    board, emulator = board_pair(FaultPlan(garbage_every=3))
    record = collect(board, "T", 20, 1.0)
    assert record.missing == 0
    # 5 bytes of noise in front of lines 3, 6, ..., 18 (and maybe 21)
    assert board.stats.garbage_bytes in (30, 35)
    emulator.faults = FaultPlan()
    emulator.inject_garbage(b"noise\n")
    record = collect(board, "T", 20, 0.5)
    assert record.missing == 0 and board.stats.garbage_bytes in (35, 40)


def test_counter_gap_is_detected(board_pair):
    board, emulator = board_pair()
    board.start("T", 20)
    collector = StreamCollector(20, 20, 2)
    while collector.last < 4:
        for sample_line in board.read(1.0):
            collector.add(sample_line)
    emulator.skip_lines(3)
    while not collector.done:
        for sample_line in board.read(1.0):
            collector.add(sample_line)
    board.stop()
    assert collector.missing == 3


def test_silence_times_out_after_one_second_then_the_board_recovers(board_pair):
    board, emulator = board_pair()
    board.start("T", 20)
    assert board.read(1.0)
    emulator.silence(1.5)
    started = time.monotonic()
    with pytest.raises(BoardTimeout, match="no data for 1.0 s"):
        while True:
            board.read(1.0)
    assert 0.9 <= time.monotonic() - started <= 1.6
    record = collect(board, "T", 20, 0.5)
    assert record.missing == 0 and board.stats.reconnects == 1
    assert emulator.received.count("ID?") == 2


def test_disconnect_fails_the_recording_then_the_board_reconnects(board_pair):
    board, emulator = board_pair()
    board.start("T", 20)
    assert board.read(1.0)
    emulator.disconnect(0.3)
    with pytest.raises(ConnectionLost, match="disconnected"):
        while True:
            board.read(1.0)
    time.sleep(0.6)
    record = collect(board, "T", 20, 0.5)
    assert record.missing == 0 and board.stats.reconnects == 1
    # the first thing the host sends on the new connection makes the board safe
    after = emulator.received[emulator.received.index("START T 20") + 1:]
    assert after[:2] == ["HEAT 0", "STOP"]


def test_a_board_that_does_not_come_back_fails_every_call(sample):
    emulator = BoardEmulator(sample)
    board = SerialBoard(BoardConfig(port=str(emulator.path), reconnect_s=0.3))
    try:
        emulator.disconnect(60.0)
        deadline = time.monotonic() + 5.0
        # a write may still vanish into the dying link; then "disconnected"; then, once the driver gave up,
        # "not back"
        while True:
            try:
                board.start("T", 20)
            except ConnectionLost as error:
                if "not back within 0.3 s" in str(error):
                    break
            assert time.monotonic() < deadline
            time.sleep(0.05)
        with pytest.raises(ConnectionLost, match="not back within 0.3 s"):
            board.heat_off()
    finally:
        board.close()
        emulator.close()


def test_texplorer_emulate_board_prints_its_port(tmp_path):
    import signal
    import subprocess

    link = tmp_path / "ttyBOARD"
    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "emulate", "board", "--link", str(link),
                                "--material", "cork-board"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    try:
        assert process.stdout.readline().strip() == str(link)
        with serial.Serial(str(link), 115200, timeout=2.0) as port:
            assert _exchange(port, b"ID?\n") == b"ID TEXPLORER-SB 1.2\n"
    finally:
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=10)
    assert process.returncode == 0 and "cork-board" in err
    assert not link.exists()
