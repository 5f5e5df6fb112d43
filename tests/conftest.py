"""Shared test fixtures: hand-built scans with every channel, independent of the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from scanner.scan import CHANNELS, Scan, ScanMeta, Trace


def make_meta(**overrides) -> ScanMeta:
    values = dict(label="C6S1M1P2X1", operator="ab", sample_id="granite-01", scan_index=1, session_id="s-1",
                  started="2026-11-21T08:00:00+00:00", t_amb=21.5, mass_g=512.0, volume_cm3=190.0,
                  volume_method="water", atk=0.0, cyd=0.25,
                  device={"daq": "USB-6002 1F2A3B4", "board": "TEXPLORER-SB 1.2"},
                  calibration={"accel_zero_V": 1.65, "accel_V_per_g": 0.33}, software_version="0.1.0")
    values.update(overrides)
    return ScanMeta(**values)


def make_scan(seed: int = 0, *, seconds: float = 0.2, images: bool = True, drop: tuple[str, ...] = (),
              raw: bool = False, image_shape: tuple[int, int] = (240, 320), **meta) -> Scan:
    """A scan with random but valid data on every channel of SPEC 3 (short, so tests stay fast)."""
    rng = np.random.default_rng(seed)
    traces = {}
    for name, spec in CHANNELS.items():
        if name in drop:
            continue
        n = max(2, int(round(seconds * spec.fs)))
        shape = (n, spec.axes) if spec.axes else (n,)
        traces[name] = Trace(rng.standard_normal(shape), spec.fs, spec.unit)
    photos = {}
    if images:
        h, w = image_shape
        photos = {v: rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for v in ("I_disp", "I_macro", "I_illu")}
    raw_volts = {"v_ts": Trace(rng.uniform(0, 3.3, traces["v_ts"].data.shape), 3000.0, "V")} if raw else {}
    return Scan(make_meta(**meta), traces, photos, raw_volts)


@pytest.fixture
def scan() -> Scan:
    return make_scan()
