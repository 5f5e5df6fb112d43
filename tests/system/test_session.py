"""The guided session: its state machine, operator values and photos, abort and save, the Peltier when a worker
thread fails, and whole ``texplorer scan`` runs through simulated devices and through the emulators: the
system tests (the emulators and fresh processes)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from unit.test_session import answers, fast_toml, run_cli

from features import extract
from scanner.storage.database import Database


@pytest.mark.skipif(sys.platform == "win32", reason="the board emulator needs pseudo-terminals")
def test_texplorer_scan_through_the_emulators(tmp_path, monkeypatch, capsys):
    pytest.importorskip("grpc")
    from scanner.acquisition.devices.sources import SimulatedSample
    from scanner.acquisition.emulators.board import BoardEmulator
    from scanner.acquisition.emulators.daq_grpc import DaqEmulator, DaqServicer

    sample = SimulatedSample("granite-polished", sample_id="granite-01", seed=21)
    with DaqEmulator(DaqServicer(sample)) as daq, BoardEmulator(sample) as board:
        devices = '[devices]\ndaq = "nidaqmx"\nboard = "serial"\n'
        config = fast_toml(tmp_path / "lab.toml", devices, f'[daq]\nserver = "grpc://{daq.address}"\n'
                           f'[board]\nport = "{board.path}"\n')
        daq.servicer.inject_overrun()                   # the first read of the first step
        argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
                "--operator", "ab", "--config", config]
        code, out = run_cli(monkeypatch, capsys, argv, answers(before="\n"))
        heat_intervals = board.heat_intervals()
    assert code == 0, out
    assert "failed: DAQ Dev1 on" in out and "buffer overrun" in out      # reported, then redone
    assert f"NI USB-6002 serial 1F2A3B4 (Dev1 on {daq.address})" in out
    assert "TEXPLORER-SB 1.2" in out
    scan = Database(tmp_path / "db").get("granite-01-001")
    assert scan.meta.device["daq"].startswith("NI USB-6002 serial 1F2A3B4")
    assert scan["v_ts"].n == 6000 and scan["t_cool"].n == 20 and scan["dB"].n == 40
    assert np.isfinite(np.array(list(extract(scan).values()))).all()
    [(on, off, _)] = heat_intervals
    assert off - on <= 0.3                                # 0.1 s asked, switched off by HEAT 0 or the board


def test_real_device_libraries_load_only_when_used():
    import subprocess

    code = ("import sys\nfrom scanner.cli import build_parser\nfrom scanner.acquisition.config import parse_config\n"
            "from scanner.acquisition.session import Session\n"
            "s = Session.open(parse_config({'simulated': {'realtime': False}}), label='C6S1M1P2X1', "
            "sample_id='g-01', operator='ab')\ns.record('press')\ns.abort()\n"
            "print(sorted(m for m in ('nidaqmx', 'sounddevice', 'serial', 'grpc') if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "[]"
