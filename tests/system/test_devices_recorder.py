"""The recorder: Peltier safety on every exit path (proved on the emulators' line/HEAT timelines), the audio/DAQ
start alignment, the quality checks of each step, and board gaps: the system tests (the recorder against the
emulators)."""

from __future__ import annotations

import _thread
import sys
import threading
import time
from dataclasses import replace

import numpy as np
import pytest
from unit.test_devices_recorder import FAST, playback_devices

from scanner.acquisition.config import BoardConfig, Config, parse_config
from scanner.acquisition.devices.board import BoardPeltier, SerialBoard
from scanner.acquisition.devices.daq import DaqPeltier, NidaqmxDaq
from scanner.acquisition.devices.protocols import ConnectionLost
from scanner.acquisition.devices.sources import SimulatedSample
from scanner.acquisition.recorder import Recorder, StepCancelled, heat

posix = pytest.mark.skipif(sys.platform == "win32", reason="the board emulator needs pseudo-terminals")


@pytest.fixture
def board_emulator():
    from scanner.acquisition.emulators.board import BoardEmulator

    emulator = BoardEmulator(SimulatedSample("granite-polished", seed=1))
    board = SerialBoard(BoardConfig(port=str(emulator.path), reconnect_s=2.0))
    yield emulator, board
    board.close()
    emulator.close()


def once(action):
    """A heating tick that runs ``action`` on the first call only (the connection drops while heating)."""
    done = []

    def tick(elapsed: float) -> None:
        if not done:
            done.append(elapsed)
            action()

    return tick


def heat_commands(emulator) -> list[str]:
    return [line for line in emulator.received if line.startswith("HEAT")]


@posix
def test_heating_ends_with_heat_0(board_emulator):
    emulator, board = board_emulator
    ticks: list[float] = []
    heat(BoardPeltier(board), 0.3, tick=ticks.append)
    [(on, off, why)] = emulator.heat_intervals()
    # the host's HEAT 0 and the board's own 300 ms timer race; either ends it on time
    assert why in ("HEAT 0", "board timer") and 0.28 <= off - on <= 0.45
    assert heat_commands(emulator) == ["HEAT 0", "HEAT 300", "HEAT 0"]   # open, heat, off
    assert ticks and all(0 < t <= 0.35 for t in ticks)


@posix
def test_the_host_refuses_more_than_5_s(board_emulator):
    emulator, board = board_emulator
    for seconds in (5.01, 0.0, -1.0):
        with pytest.raises(ValueError, match=r"outside \(0, 5\] s"):
            heat(BoardPeltier(board), seconds)
    assert heat_commands(emulator) == ["HEAT 0"] and emulator.heat_intervals() == []


@posix
def test_abort_from_another_thread_switches_off_at_once(board_emulator):
    emulator, board = board_emulator
    cancel = threading.Event()
    threading.Timer(0.2, cancel.set).start()
    with pytest.raises(StepCancelled, match="cancelled while heating"):
        heat(BoardPeltier(board), 3.0, cancel=cancel)
    [(on, off, why)] = emulator.heat_intervals()
    assert why == "HEAT 0" and off - on < 0.5


@posix
def test_ctrl_c_switches_off(board_emulator):
    emulator, board = board_emulator
    threading.Timer(0.2, _thread.interrupt_main).start()
    with pytest.raises(KeyboardInterrupt):
        heat(BoardPeltier(board), 3.0)
    [(on, off, why)] = emulator.heat_intervals()
    assert why == "HEAT 0" and off - on < 0.5


@posix
def test_an_exception_in_the_level_callback_switches_off(board_emulator):
    emulator, board = board_emulator

    def broken_display(elapsed: float) -> None:
        raise RuntimeError("display crashed")

    with pytest.raises(RuntimeError, match="display crashed"):
        heat(BoardPeltier(board), 3.0, tick=broken_display)
    [(on, off, why)] = emulator.heat_intervals()
    assert why == "HEAT 0" and off - on < 0.5


@posix
def test_a_lost_connection_fails_the_heating_and_the_reconnect_switches_off(board_emulator):
    emulator, board = board_emulator
    with pytest.raises(ConnectionLost, match="disconnected"):
        heat(BoardPeltier(board), 3.0, tick=once(lambda: emulator.disconnect(0.3)))
    time.sleep(0.6)
    [(on, off, why)] = emulator.heat_intervals()
    assert why == "HEAT 0" and off - on < 1.5


@posix
def test_a_board_that_stays_away_switches_off_by_itself(board_emulator):
    emulator, board = board_emulator
    board.config = replace(board.config, reconnect_s=0.2)
    with pytest.raises(ConnectionLost) as error:
        heat(BoardPeltier(board), 1.0, tick=once(lambda: emulator.disconnect(60.0)))
    time.sleep(1.1)
    [(on, off, why)] = emulator.heat_intervals()
    # the host could not reach the board: the board's own bound ended the heating
    assert why == "board timer" and off - on == pytest.approx(1.0, abs=0.05)
    notes = getattr(error.value, "__notes__", [])
    assert any("switching the Peltier off failed too" in note for note in notes)


@pytest.fixture
def line():
    pytest.importorskip("grpc")
    from scanner.acquisition.emulators.daq_grpc import DaqEmulator, DaqServicer

    with DaqEmulator(DaqServicer()) as emulator:
        daq = NidaqmxDaq(Config().with_daq_server(f"grpc://{emulator.address}").daq)
        yield emulator.servicer, daq
        daq.close()


def switches(servicer) -> list[tuple[float, bool]]:
    return [(when, value) for when, name, value in servicer.line_log if name == "port0/line0"]


def test_daq_line_heating_is_bounded(line):
    servicer, daq = line
    heat(DaqPeltier(daq), 0.3)
    timeline = switches(servicer)
    # opened off, on, then off: by heat() and maybe also by the watchdog, whichever is first at 0.3 s
    assert [value for _, value in timeline[:3]] == [False, True, False]
    assert not any(value for _, value in timeline[3:])
    assert 0.28 <= timeline[2][0] - timeline[1][0] <= 0.45


def test_daq_line_switches_off_on_abort(line):
    servicer, daq = line
    cancel = threading.Event()
    threading.Timer(0.2, cancel.set).start()
    with pytest.raises(StepCancelled):
        heat(DaqPeltier(daq), 3.0, cancel=cancel)
    (on_at, on), (off_at, off) = switches(servicer)[1:]
    assert (on, off) == (True, False) and off_at - on_at < 0.5


def test_daq_watchdog_switches_off_when_nobody_does(line):
    servicer, daq = line
    peltier = DaqPeltier(daq)
    peltier.on(0.3)                                  # the switching thread is stuck from here on
    time.sleep(0.6)
    (on_at, on), (off_at, off) = switches(servicer)[1:]
    assert (on, off) == (True, False) and off_at - on_at == pytest.approx(0.3, abs=0.1)


@posix
def test_board_gaps_during_cooling_are_interpolated_and_reported():
    from scanner.acquisition.emulators.board import BoardEmulator, FaultPlan

    sample = SimulatedSample("granite-polished", seed=1)
    with BoardEmulator(sample, faults=FaultPlan(gap_every=7)) as emulator:
        board = SerialBoard(BoardConfig(port=str(emulator.path)))
        devices = playback_devices(sample)
        devices.board, devices.peltier = board, BoardPeltier(board)
        try:
            result = Recorder(devices, parse_config(FAST)).record("thermal")
        finally:
            board.close()
    # the T stream's lines 7 (and 14, 21 if they fall in the 0.5 s) never arrive
    assert result.problems[0].endswith("sample(s) lost and interpolated")
    assert result.info["board_missing"] >= 1 and np.isfinite(result.traces["t_cool"].data).all()
