"""The data model validates itself on construction (docs/database.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import make_meta, make_scan

from scanner.scan import CHANNELS, Recording, Scan, ScanError, Trace


def test_trace_stores_a_read_only_float64_copy():
    source = np.arange(6, dtype=np.int32).reshape(3, 2)
    trace = Trace(source, 3000, "g")
    source[0, 0] = 99
    assert trace.data.dtype == np.float64 and trace.data[0, 0] == 0.0
    with pytest.raises(ValueError):
        trace.data[0, 0] = 1.0
    assert trace.n == 3 and trace.duration == pytest.approx(1e-3)


@pytest.mark.parametrize(
    ("data", "fs", "unit", "message"),
    [
        ([1.0, math.nan, 2.0], 3000, "g", "non-finite samples (first at sample 1)"),
        ([1.0, math.inf], 3000, "g", "non-finite"),
        ([], 3000, "g", "empty"),
        (np.zeros((2, 2, 2, 2)), 3000, "g", "1-D, 2-D or 3-D"),
        ([1.0], 0, "g", "finite and positive"),
        ([1.0], -3000, "g", "finite and positive"),
        ([1.0], math.nan, "g", "finite and positive"),
        ([1.0], "fast", "g", "must be a number"),
        ([1.0], 3000, "", "unit"),
        (["a", "b"], 3000, "g", "not numeric"),
    ],
)
def test_trace_rejects_bad_input(data, fs, unit, message):
    with pytest.raises(ScanError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Trace(data, fs, unit)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("label", "C6S1M1P2", "meta.label: 'C6S1M1P2' is not a label"),
        ("label", "granite", "meta.label: 'granite' is not a label"),
        ("operator", "", "operator"),
        ("operator", "<script>", "operator"),
        ("sample_id", "../etc", "sample id"),
        ("sample_id", "a/b", "sample id"),
        ("session_id", "", "session_id"),
        ("sample_id", "a" * 65, "sample id"),
        ("sample_id", "granite-01\n", "sample id"),
        ("scan_index", 0, r"whole number 1\.\.9999, got 0"),
        ("scan_index", 1.5, "whole number"),
        ("scan_index", 10_000, "whole number 1..9999, got 10000"),
        ("scan_index", 2**63, "got 9.22337e\\+18"),
        ("scan_index", 1e300, "got 1e\\+300"),
        ("scan_index", math.nan, "whole number"),
        ("started", "yesterday", "ISO 8601"),
        ("started", "2026-11-21T08:00:00" + " " * 100, "ISO 8601"),
        ("atk", 0.3, "five-step scale"),
        ("cyd", 2.0, "five-step scale"),
        ("mass_g", -3.0, "positive"),
        ("mass_g", 2e6, "at most 1e\\+06"),
        ("volume_cm3", math.inf, "positive"),
        ("t_amb", math.inf, "between -40 and 85"),
        ("t_amb", 85.5, "between -40 and 85"),
        ("schema_version", 2, "not supported"),
        ("device", {"bad key": "x"}, "MATLAB field name"),
        ("device", {"daq": "x" * 257}, "meta.device.daq: 257 characters, at most 256"),
        ("device", {f"k{i}": "x" for i in range(65)}, "meta.device: 65 entries, at most 64"),
        ("calibration", {"gain": math.inf}, "meta.calibration.gain: inf must be between"),
        ("calibration", {"gain": 1e7}, "meta.calibration.gain"),
        ("notes", "n" * 4001, "meta.notes: 4001 characters"),
        ("software_version", "v" * 65, "meta.software_version"),
    ],
)
def test_meta_rejects_bad_fields(field, value, message):
    with pytest.raises(ScanError, match=message):
        make_meta(**{field: value})


def test_meta_allows_unknown_values_as_nan_and_compares_them_equal():
    a = make_meta(atk=math.nan, cyd=math.nan, mass_g=math.nan, t_amb=math.nan)
    b = make_meta(atk=math.nan, cyd=math.nan, mass_g=math.nan, t_amb=math.nan)
    assert a == b and a.scan_id == "granite-01-001"
    assert a != make_meta(atk=math.nan, cyd=math.nan, mass_g=1.0, t_amb=math.nan)


def test_scan_checks_rate_unit_and_shape_of_every_channel():
    meta = make_meta()
    with pytest.raises(ScanError, match="v_ts: sampled at 1000 Hz, expected 3000 Hz"):
        Scan(meta, {"v_ts": Trace(np.zeros((10, 3)), 1000, "g")})
    with pytest.raises(ScanError, match="v_ts: unit 'm/s\\^2', expected 'g'"):
        Scan(meta, {"v_ts": Trace(np.zeros((10, 3)), 3000, "m/s^2")})
    with pytest.raises(ScanError, match=r"v_ts: shape \(10, 2\), expected \(n, 3\)"):
        Scan(meta, {"v_ts": Trace(np.zeros((10, 2)), 3000, "g")})
    with pytest.raises(ScanError, match=r"f_press: shape \(10, 1\), expected \(n,\)"):
        Scan(meta, {"f_press": Trace(np.zeros((10, 1)), 3000, "N")})
    with pytest.raises(ScanError, match="'v_xx' is not a scan channel"):
        Scan(meta, {"v_xx": Trace(np.zeros((10, 3)), 3000, "g")})


def test_a_rigid_scan_may_store_its_fold_and_is_flagged():
    skipped = make_scan(rigid=True, drop=("f_fold", "alpha_f"))
    assert skipped.missing_channels() == [] and not skipped.fold_despite_rigid
    assert make_scan(drop=("alpha_f",)).missing_channels() == ["alpha_f"]
    assert make_scan(rigid=True).fold_despite_rigid and not make_scan().fold_despite_rigid


def test_channel_lengths_are_bounded_and_short_channels_are_named():
    meta = make_meta()
    with pytest.raises(ScanError, match=r"t_cool: 2401 samples, more than the 2400 \(120 s at 20 Hz\)"):
        Scan(meta, {"t_cool": Trace(np.zeros(2401), 20.0, "degC")})
    Scan(meta, {"t_cool": Trace(np.zeros(2400), 20.0, "degC")})
    with pytest.raises(ScanError, match="v_ts_raw: 360001 samples"):
        Scan(meta, raw={"v_ts": Trace(np.zeros((360_001, 3)), 3000.0, "V")})
    scan = make_scan(seconds=0.2)  # 600 samples at 3 kHz, 4 of t_cool, 8820 of audio
    assert scan.short_channels() == {"v_fs": 3000, "v_ts": 3000, "a_fs": 44100, "a_ts": 44100}
    one = Scan(meta, {name: Trace(np.zeros((1, 3) if spec.axes else 1), spec.fs, spec.unit)
                      for name, spec in CHANNELS.items()})
    assert set(one.short_channels()) == {name for name, spec in CHANNELS.items() if spec.min_n > 1}
    assert {"r_ts", "m", "dB"}.isdisjoint(one.short_channels())


def test_scan_images_must_be_rgb_uint8():
    meta = make_meta()
    with pytest.raises(ScanError, match="RGB uint8"):
        Scan(meta, images={"I_disp": np.zeros((10, 10), np.uint8)})
    with pytest.raises(ScanError, match="RGB uint8"):
        Scan(meta, images={"I_disp": np.zeros((10, 10, 3), np.float64)})
    with pytest.raises(ScanError, match="not a photo variable"):
        Scan(meta, images={"I_side": np.zeros((10, 10, 3), np.uint8)})


def test_scan_orders_channels_like_the_spec_and_gives_clear_key_errors(scan):
    assert list(scan.traces) == list(CHANNELS)
    assert scan.get("nope") is None
    with pytest.raises(KeyError, match="granite-01-001 has no channel 'nope'"):
        scan["nope"]


def test_recording_checks_roles():
    vib = Trace(np.zeros(100), 2200, "V")
    taxels = Trace(np.zeros((10, 4, 4)), 100, "kPa")
    rec = Recording("r1", {"vib": vib, "tax": taxels}, {"vibration": "vib", "taxels": "tax"}, label="felt",
                    group={"object": "felt-1"})
    assert rec.role("taxels") is taxels and rec.role("audio") is None
    with pytest.raises(ScanError, match="unknown role 'smell'"):
        Recording("r1", {"vib": vib}, {"smell": "vib"})
    with pytest.raises(ScanError, match="names missing channel 'nope'"):
        Recording("r1", {"vib": vib}, {"vibration": "nope"})
    with pytest.raises(ScanError, match="role 'taxels' needs a 3-D channel"):
        Recording("r1", {"vib": vib}, {"taxels": "vib"})
    with pytest.raises(ScanError, match="force_xyz"):
        Recording("r1", {"f": Trace(np.zeros((5, 2)), 100, "N")}, {"force_xyz": "f"})
    with pytest.raises(ScanError, match="no channels"):
        Recording("r1", {})


def test_scans_pickle_and_are_validated_again_on_arrival():
    import pickle

    scan = make_scan(raw=True)
    copy = pickle.loads(pickle.dumps(scan))
    assert copy == scan and copy is not scan
    assert pickle.loads(pickle.dumps(Recording("r", {"x": Trace([1.0], 10, "V")}, {"vibration": "x"}))).roles == {
        "vibration": "x"}


def test_volume_method_is_one_of_the_known_methods():
    assert make_meta(volume_method="known").volume_method == "known"
    assert make_meta(volume_method="").volume_method == ""
    with pytest.raises(ScanError, match="meta.volume_method: 'guess' is not one of water, micro-pearls, known"):
        make_meta(volume_method="guess")
