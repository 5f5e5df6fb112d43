"""The DAQ through the real nidaqmx client over gRPC against the in-process servicer: channel set-up,
continuous reads, overruns (injected and real), the Peltier line; the playback DAQ; one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("grpc")
nidaqmx = pytest.importorskip("nidaqmx")

from scanner.acquisition.config import DAQ_ROLES, Calibration, DaqConfig  # noqa: E402
from scanner.acquisition.devices.daq import NidaqmxDaq, PlaybackDaq  # noqa: E402
from scanner.acquisition.devices.protocols import DeviceUnavailable  # noqa: E402
from scanner.acquisition.devices.sources import rest_volts  # noqa: E402
from scanner.acquisition.emulators.daq_grpc import expand_channels  # noqa: E402
from scanner.pacing import Pacer  # noqa: E402


class RampSource:
    """Known volts: role j carries j + k / 10000 V at sample k (k = 0..5999) whatever the step."""

    kind = "simulated"
    t_amb = 21.0

    def describe(self) -> str:
        return "ramp"

    def daq_volts(self, step, calibration, device="daq"):
        k = np.arange(6000)[:, None]
        return np.arange(len(DAQ_ROLES))[None, :] + k / 10000.0


def read_blocks(daq, blocks: int) -> np.ndarray:
    """``blocks`` reads into one preallocated (blocks, channels, block) array, as the recorder does."""
    buffer = np.empty((blocks, len(daq.channels), daq.block))
    for k in range(blocks):
        daq.read_into(buffer[k])
    return buffer.transpose(0, 2, 1).reshape(-1, len(daq.channels))


def test_expand_daqmx_channel_lists():
    assert expand_channels("Dev1/ai0:2, Dev1/ai7") == [("Dev1", "ai0"), ("Dev1", "ai1"), ("Dev1", "ai2"),
                                                       ("Dev1", "ai7")]
    assert expand_channels("Dev1/ai3:1") == [("Dev1", "ai3"), ("Dev1", "ai2"), ("Dev1", "ai1")]
    assert expand_channels("Dev1/port0/line0") == [("Dev1", "port0/line0")]


def test_local_daq_without_the_driver_is_one_line():
    try:
        with nidaqmx.Task("probe"):
            pytest.skip("an NI-DAQmx driver is installed here")
    except nidaqmx.errors.DaqNotFoundError:
        pass
    with pytest.raises(DeviceUnavailable, match="NI-DAQmx driver not found") as error:
        NidaqmxDaq(DaqConfig())
    assert "\n" not in str(error.value)


def test_playback_daq_plays_the_source_then_holds_the_last_sample():
    daq = PlaybackDaq(RampSource(), Calibration(), block=2500, pacer=Pacer(0.0))
    daq.start("press")
    volts = read_blocks(daq, 3)                                 # 7500 samples from a 6000-sample take
    assert np.array_equal(volts[:6000, 2], 2 + np.arange(6000) / 10000.0)
    assert np.all(volts[6000:] == volts[5999])
    daq.set_peltier(True)
    daq.close()
    assert [on for _, on in daq.peltier_log] == [True, False]


def test_playback_daq_paces_in_real_time():
    now, slept = [0.0], []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        now[0] += seconds

    pacer = Pacer(1.0, clock=lambda: now[0], sleep=sleep)
    daq = PlaybackDaq(RampSource(), Calibration(), block=300, pacer=pacer)
    daq.start("tap")
    read_blocks(daq, 3)                                        # 900 samples = 0.3 s
    assert slept == pytest.approx([0.1, 0.1, 0.1])             # each block when its last sample is due


def test_rest_volts_by_hand():
    volts = rest_volts(2, Calibration())
    # 0 g on x and y, 1 g on z (1.65 + 0.33 V), ambient IR, unloaded FSRs (eq. 1 floor = 0 V), open electrodes
    assert volts[0].tolist() == pytest.approx([1.65, 1.65, 1.98, 0.1, 0.0, 0.0, 0.0, 4.8])


