"""The DAQ through the real nidaqmx client over gRPC against the in-process servicer: channel set-up, continuous
reads, overruns (injected and real), the Peltier line; the playback DAQ; one-line errors: the system tests
(the DAQ's gRPC emulator)."""

from __future__ import annotations

import threading
import time
from dataclasses import replace

import numpy as np
import pytest
from unit.test_devices_daq import RampSource, read_blocks

from scanner.acquisition.config import Calibration, Config, DaqConfig  # noqa: E402
from scanner.acquisition.devices.daq import NidaqmxDaq  # noqa: E402
from scanner.acquisition.devices.protocols import AcquisitionError, DeviceUnavailable  # noqa: E402
from scanner.acquisition.devices.sources import SimulatedSample  # noqa: E402
from scanner.acquisition.emulators.daq_grpc import DaqEmulator, DaqServicer  # noqa: E402

pytest.importorskip("grpc")


def daq_config(emulator: DaqEmulator, **changes) -> DaqConfig:
    """The DAQ section of a config that reads the emulator over gRPC."""
    return replace(Config().with_daq_server(f"grpc://{emulator.address}").daq, **changes)


@pytest.fixture
def ramp():
    with DaqEmulator(DaqServicer(RampSource())) as emulator:
        yield emulator


def test_channel_setup_over_grpc(ramp):
    daq = NidaqmxDaq(daq_config(ramp))
    try:
        daq.start("finger_tap")
        [task] = [task for name, task in ramp.servicer.tasks.items() if name != "texplorer-peltier"]
        assert task.name == "texplorer-finger_tap"
        assert task.inputs == [f"ai{i}" for i in range(8)]
        assert task.rate == 3000.0 and task.buffer == 6000   # 2 s buffer
        assert ramp.servicer.calls.count("CreateAIVoltageChan") == 1
        daq.stop()
        assert list(ramp.servicer.tasks) == ["texplorer-peltier"]   # the step's task was cleared
    finally:
        daq.close()
    assert ramp.servicer.tasks == {}


def test_describe_reads_the_device_over_grpc(ramp):
    daq = NidaqmxDaq(daq_config(ramp))
    try:
        assert daq.describe() == {"daq": f"NI USB-6002 serial 1F2A3B4 (Dev1 on {ramp.address})"}
    finally:
        daq.close()


def test_continuous_reads_deliver_every_sample_in_order(ramp):
    daq = NidaqmxDaq(daq_config(ramp, reads_per_second=20.0))
    try:
        started = time.perf_counter()
        daq.start("tool_slide")
        volts = read_blocks(daq, 10)                          # 10 reads of 150 samples at 3 kHz = 0.5 s
        elapsed = time.perf_counter() - started
    finally:
        daq.close()
    k = np.arange(1500)[:, None]
    assert volts.shape == (1500, 8)
    assert np.array_equal(volts, np.arange(8)[None, :] + k / 10000.0)
    assert 0.45 <= elapsed < 1.5                              # the emulated clock runs in real time


def test_channel_map_decides_which_input_carries_which_sensor():
    wiring = {**DaqConfig().channels, "ir": "ai7", "metal": "ai3"}
    servicer = DaqServicer(RampSource(), channel_map=wiring)
    with DaqEmulator(servicer) as emulator:
        daq = NidaqmxDaq(daq_config(emulator, channels=wiring))
        try:
            daq.start("static")
            volts = read_blocks(daq, 1)
        finally:
            daq.close()
    # the host asks for the inputs in role order, so the columns come back as roles again
    assert volts[0].tolist() == [float(j) for j in range(8)]


def test_simulated_material_signals_arrive_bit_exact():
    sample = SimulatedSample("oak-planed", seed=11)
    with DaqEmulator(DaqServicer(sample)) as emulator:
        daq = NidaqmxDaq(daq_config(emulator))
        try:
            daq.start("press")
            volts = read_blocks(daq, 3)
        finally:
            daq.close()
    expected = SimulatedSample("oak-planed", seed=11).daq_volts("press", Calibration(), "other")
    assert np.array_equal(volts, expected[:600])


def test_injected_overrun_is_an_acquisition_error(ramp):
    daq = NidaqmxDaq(daq_config(ramp))
    try:
        daq.start("friction")
        read_blocks(daq, 1)
        ramp.servicer.inject_overrun()
        with pytest.raises(AcquisitionError, match="buffer overrun .*DAQmx -200279.*redo the step"):
            read_blocks(daq, 1)
    finally:
        daq.close()


def test_reading_too_slowly_overruns_the_buffer(ramp):
    daq = NidaqmxDaq(daq_config(ramp, buffer_s=0.2))
    try:
        daq.start("friction")
        read_blocks(daq, 1)
        time.sleep(0.5)                                        # the 0.2 s buffer overflows meanwhile
        with pytest.raises(AcquisitionError, match="buffer overrun"):
            read_blocks(daq, 1)
    finally:
        daq.close()


def test_peltier_line_is_switched_and_left_off(ramp):
    daq = NidaqmxDaq(daq_config(ramp))
    daq.set_peltier(True)
    assert ramp.servicer.line_state("port0/line0") is True
    daq.set_peltier(False)
    daq.set_peltier(True)
    daq.close()                                                # closing switches it off
    assert [value for _, line, value in ramp.servicer.line_log] == [False, True, False, True, False]
    assert ramp.servicer.line_state() is False


def test_unreachable_server_is_one_line():
    with DaqEmulator() as emulator:
        address = emulator.address
    with pytest.raises(DeviceUnavailable, match=f"DAQ Dev1 on {address}") as error:
        NidaqmxDaq(DaqConfig(server=f"grpc://{address}"))
    assert "\n" not in str(error.value)


def test_servicer_reads_from_another_thread_while_the_line_switches(ramp):
    daq = NidaqmxDaq(daq_config(ramp))
    errors: list[BaseException] = []

    def toggle() -> None:
        try:
            for _ in range(5):
                daq.set_peltier(True)
                daq.set_peltier(False)
        except BaseException as exc:  # noqa: BLE001 - reported by the assertion below
            errors.append(exc)

    try:
        daq.start("press")
        thread = threading.Thread(target=toggle)
        thread.start()
        read_blocks(daq, 3)
        thread.join()
    finally:
        daq.close()
    assert errors == [] and ramp.servicer.line_state() is False


def test_texplorer_emulate_daq_prints_its_address():
    import signal
    import subprocess
    import sys

    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "emulate", "daq"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        address = process.stdout.readline().strip()
        assert address.startswith("grpc://127.0.0.1:")
        daq = NidaqmxDaq(DaqConfig(server=address))
        try:
            assert daq.describe()["daq"].startswith("NI USB-6002 serial 1F2A3B4")
        finally:
            daq.close()
    finally:
        if sys.platform != "win32":
            process.send_signal(signal.SIGINT)
        else:
            process.terminate()
        process.communicate(timeout=10)
