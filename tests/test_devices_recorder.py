"""The recorder: Peltier safety on every exit path (proved on the emulators' line/HEAT timelines), the
audio/DAQ start alignment, the quality checks of each step, and board gaps."""

from __future__ import annotations

import _thread
import sys
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from scanner.acquisition.config import BoardConfig, Calibration, Config, parse_config
from scanner.acquisition.devices import Devices
from scanner.acquisition.devices.audio import PlaybackMicrophone
from scanner.acquisition.devices.board import BoardPeltier, PlaybackBoard, SerialBoard
from scanner.acquisition.devices.camera import PlaybackCamera
from scanner.acquisition.devices.daq import DaqPeltier, NidaqmxDaq, PlaybackDaq
from scanner.acquisition.devices.protocols import AudioCapture, ConnectionLost
from scanner.acquisition.devices.sources import SimulatedSample, rest_volts
from scanner.acquisition.recorder import Recorder, StepCancelled, heat
from scanner.pacing import Pacer

posix = pytest.mark.skipif(sys.platform == "win32", reason="the board emulator needs pseudo-terminals")


# -- Peltier on the serial board ---------------------------------------------------------------------

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


# -- Peltier on the DAQ's digital line (nidaqmx over gRPC) -------------------------------------------

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


def test_closing_the_devices_switches_off_first():
    order: list[str] = []

    class Logged:
        def __init__(self, name: str, fail: bool = False) -> None:
            self.name, self.fail = name, fail

        def off(self) -> None:
            order.append("peltier off")

        def close(self) -> None:
            order.append(f"{self.name} closed")
            if self.fail:
                raise OSError(f"{self.name} is stuck")

    devices = Devices(daq=Logged("daq", fail=True), board=Logged("board"), microphone=Logged("microphone"),
                      camera=Logged("camera"), peltier=Logged("peltier"))
    with pytest.raises(OSError, match="daq is stuck"):
        devices.close()
    assert order == ["peltier off", "daq closed", "board closed", "microphone closed", "camera closed"]


# -- the recorder ------------------------------------------------------------------------------------

class QuietSource:
    """A unit that never moves: every DAQ role at rest, room-temperature cooling, no field change."""

    kind = "simulated"
    t_amb = 21.0

    def __init__(self, volts: dict[int, float] | None = None) -> None:
        self.volts = volts or {}

    def describe(self) -> str:
        return "quiet"

    def daq_volts(self, step, calibration, device="daq"):
        volts = rest_volts(15000, calibration)
        for column, value in self.volts.items():
            volts[:, column] = value
        return volts

    def audio(self, step, device="microphone"):
        return np.zeros(5 * 44100)

    def cooling(self, device="board"):
        return np.full(200, 21.1)

    def field_change(self, device="board"):
        return np.zeros(80)

    def photos(self, device="camera"):
        return {}


FAST = {"steps": {"finger_tap": 2.0, "finger_slide": 2.0, "tool_tap": 2.0, "tool_slide": 2.0, "static": 0.5,
                  "heat": 0.1, "thermal": 0.5, "friction": 1.0, "press": 1.0, "fold": 1.0},
        "simulated": {"realtime": False}}


def playback_devices(source, microphone=None) -> Devices:
    pacer = Pacer(0.0)
    board = PlaybackBoard(source)
    return Devices(daq=PlaybackDaq(source, Calibration(), pacer=pacer),
                   board=board, microphone=microphone or PlaybackMicrophone(source, pacer=pacer),
                   camera=PlaybackCamera(source), peltier=BoardPeltier(board))


class OffsetMicrophone:
    """A microphone whose first sample was captured ``offset`` s after the DAQ's (negative: before)."""

    rate = 44100.0

    def __init__(self, daq_pacer: Pacer, offset: float) -> None:
        self.pacer, self.offset = daq_pacer, offset

    def describe(self):
        return {"microphone": "offset"}

    def start(self, step):
        return time.perf_counter()

    def read(self):
        return np.zeros(0)

    def stop(self):
        return AudioCapture(np.arange(3 * 44100) / 1e6, self.pacer.started + self.offset, 0)

    def close(self):
        pass


def test_audio_is_cut_to_start_with_the_daq():
    devices = playback_devices(SimulatedSample("cork-board", seed=1))
    devices.microphone = OffsetMicrophone(devices.daq.pacer, -0.010)
    result = Recorder(devices, parse_config(FAST)).record("finger_slide")
    audio = result.traces["a_fs"].data
    # 10 ms early = 441 samples to drop; then exactly the 2 s of the step
    assert audio[0] == pytest.approx(441 / 1e6) and audio.size == 2 * 44100
    assert result.info["audio_offset_s"] == pytest.approx(-0.010, abs=1e-6)
    assert result.traces["v_fs"].n == 6000 and result.traces["r_fs"].n == 6000


def test_a_late_microphone_is_padded_and_reported():
    devices = playback_devices(SimulatedSample("cork-board", seed=1))
    devices.microphone = OffsetMicrophone(devices.daq.pacer, 0.004)
    result = Recorder(devices, parse_config(FAST)).record("tool_slide")
    audio = result.traces["a_ts"].data
    # 4 ms late = 176.4 samples: 176 samples of silence, then the capture's first sample (0.0)
    assert not audio[:177].any() and audio[177] == pytest.approx(1e-6)
    assert "audio started 4.0 ms after the DAQ (silence padded)" in result.problems


def test_quality_checks_of_a_unit_that_never_moves():
    recorder = Recorder(playback_devices(QuietSource()), parse_config(FAST))
    assert recorder.record("finger_tap").problems == ("no tap detected: largest swing 0.000 g",)
    assert recorder.record("tool_slide").problems == ("no slide detected",)
    assert recorder.record("friction").problems[0].startswith("no contact force: peak 0.098 N")
    assert recorder.record("press").problems[0].startswith("no contact force")
    assert recorder.record("fold").problems[0].startswith("no contact force")
    thermal = recorder.record("thermal")
    assert thermal.problems == ("no cooling seen: the temperature fell 0.00 K from its peak",)
    assert thermal.traces["t_cool"].n == 10 and thermal.traces["t_cool"].fs == 20.0
    static = recorder.record("static")
    assert static.ok and static.traces["m"].n == 1500 and static.traces["dB"].n == 40
    assert set(static.traces["m"].data) == {-1.0}


def test_clipping_is_reported():
    # ai2 (z) at 0.462 V is -3.6 g, the ADXL335's rail; ai4 (normal FSR) at its 4.9 V rail
    recorder = Recorder(playback_devices(QuietSource({2: 0.462, 4: 4.9})), parse_config(FAST))
    tap = recorder.record("tool_tap").problems
    assert any(p.startswith("clipped: 6000 of 6000 samples") and p.endswith("(v_tt z)") for p in tap)
    press = recorder.record("press").problems
    assert press == ("clipped: 3000 of 3000 samples at the -1..4.9 V limits (f_press)",)


def test_a_real_simulated_scan_passes_every_check():
    recorder = Recorder(playback_devices(SimulatedSample("oak-planed", seed=8)), parse_config(FAST))
    for step in ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction",
                 "press", "fold"):
        result = recorder.record(step)
        assert result.ok, (step, result.problems)
    assert result.raw["f_fold"].unit == "V" and result.raw["alpha_f"].n == 3000


def test_level_readings_follow_the_recording():
    readings = []
    recorder = Recorder(playback_devices(SimulatedSample("oak-planed", seed=8)), parse_config(FAST))
    recorder.record("press", level=readings.append)
    assert len(readings) == 15 and readings[-1].elapsed_s == pytest.approx(1.0)   # 200-sample reads
    assert {r.signal for r in readings} == {"force"} and all(0 <= r.fraction <= 1 for r in readings)
    readings.clear()
    recorder.record("thermal", level=readings.append)
    assert {r.phase for r in readings} == {"heating", "cooling"}


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
