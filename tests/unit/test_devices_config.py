"""The device configuration: defaults, the documented example, one-line errors, calibration both ways."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from scanner.acquisition.config import (
    DAQ_ROLES,
    DEFAULT_CHANNEL_MAP,
    Calibration,
    Config,
    ConfigError,
    load_config,
)

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "texplorer.example.toml"


def test_defaults_are_the_simulated_scanner_of_spec_5():
    config = load_config(None)
    assert dict(config.devices) == {"daq": "simulated", "board": "simulated", "microphone": "simulated",
                                    "camera": "simulated", "peltier": "board"}
    assert config.daq.physical_channels == ("ai0", "ai1", "ai2", "ai3", "ai4", "ai5", "ai6", "ai7")
    assert config.daq.rate_hz == 3000.0 and config.daq.block == 200  # 3000 Hz / 15 reads per second
    assert config.steps.heat == 3.0 and config.steps.thermal == 10.0 and config.steps.static == 1.0
    assert config.board.baudrate == 115200 and config.board.timeout_s == 1.0


def test_documented_example_lists_every_key_with_its_default(tmp_path):
    example = load_config(EXAMPLE)
    assert replace(example, source="defaults") == Config()
    text = EXAMPLE.read_text()
    for role in DAQ_ROLES:
        assert f"{role} = " in text


def test_values_from_a_file(tmp_path):
    path = tmp_path / "lab.toml"
    path.write_text('[devices]\ndaq = "nidaqmx"\nboard = "serial"\n[daq]\nserver = "grpc://10.0.0.5:31763"\n'
                    '[daq.channels]\nir = "ai7"\nmetal = "ai3"\n[board]\nport = "COM3"\n'
                    '[calibration]\naccel_zero_v = [1.6, 1.65, 1.7]\n[steps]\nheat = 5\n')
    config = load_config(path)
    assert config.implementation("daq") == "nidaqmx" and config.board.port == "COM3"
    assert config.daq.grpc_address == "10.0.0.5:31763"
    assert config.daq.channels["ir"] == "ai7" and config.daq.channels["metal"] == "ai3"
    assert config.daq.channels["accel_x"] == "ai0"
    assert config.calibration.accel_zero_v == (1.6, 1.65, 1.7)
    assert config.steps.heat == 5.0


@pytest.mark.parametrize(("toml", "message"), [
    ('[cameras]\nsource = "0"', "unknown section [cameras]"),
    ('[daq]\nrate = 3000', "daq.rate: unknown key"),
    ('[devices]\ndaq = "usb"', "devices.daq: 'usb' is not one of simulated, nidaqmx, replay"),
    ('[devices]\nscale = "x"', "devices.scale: unknown device"),
    ('[steps]\nheat = 6.0', "steps.heat: 6 s exceeds the 5 s Peltier limit"),
    ('[steps]\npress = 0', "steps.press: must be > 0"),
    ('[daq]\nrate_hz = "fast"', "daq.rate_hz: must be a finite number"),
    ('[daq]\nkeep_raw = 1', "daq.keep_raw: must be true or false"),
    ('[daq]\nserver = "10.0.0.5:31763"', "daq.server: '10.0.0.5:31763' must look like grpc://host:port"),
    ('[daq.channels]\nir = "ai0"', "ai0 is mapped to more than one role"),
    ('[daq.channels]\nir = "a3"', "daq.channels.ir: 'a3' is not an analog input name"),
    ('[daq.channels]\nthermo = "ai9"', "daq.channels.thermo: unknown role"),
    ('[devices]\ndaq = "replay"', "replay.scan: replay devices need the path of a stored scan"),
    ('[calibration]\naccel_v_per_g = [0.33, 0.0, 0.33]', "accel_v_per_g: sensitivities must be > 0"),
    ('[calibration]\naccel_zero_v = [1.65, 1.65]', "calibration.accel_zero_v: must be a list of 3 numbers"),
    ('[calibration]\nflex_v1 = 0.0', "the two flex points must differ"),
    ('[steps]\nthermal = 121.0', "steps.thermal: at most 120 s, the longest a scan channel may hold"),
    ('[simulated]\nimage_size = [6000, 6000]', "simulated.image_size: the image has 36,000,000 pixels"),
])
def test_bad_values_name_the_file_and_key(tmp_path, toml, message):
    path = tmp_path / "bad.toml"
    path.write_text(toml)
    with pytest.raises(ConfigError) as error:
        load_config(path)
    assert message in str(error.value) and str(error.value).startswith(str(path))
    assert "\n" not in str(error.value)


def test_unreadable_and_malformed_files(tmp_path):
    with pytest.raises(ConfigError, match="cannot read the config"):
        load_config(tmp_path / "missing.toml")
    (tmp_path / "broken.toml").write_text("[daq\nrate_hz = 3")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(tmp_path / "broken.toml")


def test_command_line_overrides_choose_the_real_device():
    config = Config().with_daq_server("grpc://localhost:31763").with_board_port("COM7")
    assert config.implementation("daq") == "nidaqmx" and config.daq.grpc_address == "localhost:31763"
    assert config.implementation("board") == "serial" and config.board.port == "COM7"
    assert config.implementation("microphone") == "simulated"
    with pytest.raises(ConfigError, match="grpc://host:port"):
        Config().with_daq_server("localhost:31763")
    with pytest.raises(ConfigError, match="devices.camera: 'webcam' is not one of"):
        Config().with_devices(camera="webcam")


def test_calibration_to_physical_by_hand():
    calibration = Calibration()
    # ADXL335: (V - 1.65 V) / 0.330 V/g
    assert calibration.to_physical("accel_z", np.array([1.98, 1.65, 0.66])) == pytest.approx([1.0, 0.0, -3.0])
    # eq. (1): 9.81 * 0.01 * exp(1.33 * V); 0 V reads the 10 g reference
    assert calibration.to_physical("fsr_normal", np.array([0.0]))[0] == pytest.approx(0.0981)
    one_volt = calibration.to_physical("fsr_tangential", np.array([1.0]))[0]
    assert one_volt == pytest.approx(0.0981 * np.exp(1.33))
    # flex through (0 V, 0 deg) and (1 V, 100 deg)
    assert calibration.to_physical("flex", np.array([0.5, 0.9])) == pytest.approx([50.0, 90.0])
    assert list(calibration.to_physical("metal", np.array([0.2, 2.49, 2.5, 4.8]))) == [1.0, 1.0, -1.0, -1.0]
    assert calibration.to_physical("ir", np.array([3.3]))[0] == 3.3
    tilted = Calibration(accel_zero_v=(1.5, 1.6, 1.7), accel_v_per_g=(0.3, 0.32, 0.34))
    assert tilted.to_physical("accel_x", np.array([1.8]))[0] == pytest.approx(1.0)
    assert tilted.to_physical("accel_y", np.array([1.6]))[0] == pytest.approx(0.0)


def test_calibration_to_volts_inverts_it():
    calibration = Calibration(accel_zero_v=(1.5, 1.6, 1.7), flex_v0=0.2, flex_deg0=-10.0, flex_v1=1.2,
                              flex_deg1=170.0)
    values = np.array([-2.5, 0.0, 0.7, 3.1])
    for role in ("accel_x", "accel_y", "accel_z", "ir", "flex"):
        assert calibration.to_physical(role, calibration.to_volts(role, values)) == pytest.approx(values)
    forces = np.array([0.0981, 1.0, 12.5])
    volts = calibration.to_volts("fsr_normal", forces)
    assert calibration.to_physical("fsr_normal", volts) == pytest.approx(forces)
    assert calibration.to_volts("fsr_normal", np.array([0.01]))[0] == 0.0  # below the eq. (1) floor
    assert list(calibration.to_volts("metal", np.array([1.0, -1.0]))) == [0.2, 4.8]
    with pytest.raises(ConfigError, match="unknown DAQ role 'thermo'"):
        calibration.to_volts("thermo", values)


def test_calibration_goes_into_the_scan_meta():
    meta = Calibration().as_meta()
    assert meta["accel_zero_V_x"] == 1.65 and meta["accel_V_per_g_z"] == 0.330
    assert meta["flex_deg1"] == 100.0 and meta["metal_threshold_V"] == 2.5
    assert DEFAULT_CHANNEL_MAP["metal"] == "ai7"
