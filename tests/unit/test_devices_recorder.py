"""The recorder: Peltier safety on every exit path (proved on the emulators' line/HEAT timelines), the
audio/DAQ start alignment, the quality checks of each step, and board gaps."""

from __future__ import annotations

import time

import numpy as np
import pytest

from scanner.acquisition.config import Calibration, parse_config
from scanner.acquisition.devices import Devices
from scanner.acquisition.devices.audio import PlaybackMicrophone
from scanner.acquisition.devices.board import BoardPeltier, PlaybackBoard
from scanner.acquisition.devices.camera import PlaybackCamera
from scanner.acquisition.devices.daq import PlaybackDaq
from scanner.acquisition.devices.protocols import AudioCapture
from scanner.acquisition.devices.sources import SimulatedSample, rest_volts
from scanner.acquisition.recorder import Recorder
from scanner.pacing import Pacer

# -- Peltier on the serial board ---------------------------------------------------------------------


# -- Peltier on the DAQ's digital line (nidaqmx over gRPC) -------------------------------------------


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

    def stop(self, until=None):
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


def test_the_microphone_records_on_until_it_covers_a_daq_that_ended_early():
    # The DAQ's blocks come back at once (its own clock, not the microphone's); the microphone plays on a
    # real-time clock of its own, so when the DAQ's last block is read the audio is short of the step.
    source = SimulatedSample("cork-board", seed=1)
    devices = playback_devices(source, microphone=PlaybackMicrophone(source, pacer=Pacer(1.0)))
    config = parse_config({**FAST, "steps": {**FAST["steps"], "tool_slide": 0.5}})
    started = time.perf_counter()
    result = Recorder(devices, config).record("tool_slide")
    assert result.traces["a_ts"].n == int(round(0.5 * 44100))
    assert time.perf_counter() - started >= 0.5          # the microphone's clock was waited for


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


