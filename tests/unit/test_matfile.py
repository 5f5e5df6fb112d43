"""The .mat scan format (docs/database.md): lossless round trip, readable without project code, clear errors."""

from __future__ import annotations

import hashlib
import re
import warnings

import numpy as np
import pytest
import scipy.io
from conftest import make_scan

from features import tactum
from scanner.scan import CHANNELS, Scan, Trace
from scanner.storage.matfile import ScanFormatError, ScanFormatWarning, load_scan, save_scan

META_FIELDS = {"label", "operator", "sample_id", "scan_index", "session_id", "started", "t_amb", "mass_g",
               "volume_cm3", "volume_method", "atk", "cyd", "rigid", "fs", "units", "raw_volts", "device",
               "software_version", "schema_version"}


def test_round_trip_is_lossless(tmp_path):
    scan = make_scan(raw=True)
    written = save_scan(scan, tmp_path / "scan.mat")
    assert [p.name for p in written] == ["scan_disp.png", "scan_macro.png", "scan_illu.png", "scan.mat"]
    loaded = load_scan(tmp_path / "scan.mat")
    assert loaded == scan
    for name, trace in scan.traces.items():
        assert loaded[name].data.tobytes() == trace.data.tobytes()
    assert loaded.raw["v_ts"] == scan.raw["v_ts"]


def test_plain_scipy_reads_every_variable_and_meta_field(tmp_path):
    scan = make_scan()
    save_scan(scan, tmp_path / "scan.mat")
    raw = scipy.io.loadmat(tmp_path / "scan.mat")  # no project code involved
    for name, spec in CHANNELS.items():
        n = scan[name].n
        assert raw[name].shape == ((n, 3) if spec.axes else (n, 1)), name
        assert raw[name].dtype == np.float64
        np.testing.assert_array_equal(raw[name].reshape(scan[name].data.shape), scan[name].data)
    simple = scipy.io.loadmat(tmp_path / "scan.mat", simplify_cells=True)
    meta = simple["meta"]
    assert META_FIELDS <= set(meta)
    assert meta["label"] == "C6S1M1P2X1" and meta["scan_index"] == 1 and meta["schema_version"] == 1
    assert meta["fs"]["a_ts"] == 44100 and meta["fs"]["t_cool"] == 20 and meta["fs"]["dB"] == 80
    assert meta["units"]["f_press"] == "N" and meta["units"]["alpha_f"] == "deg"
    assert meta["device"]["daq"] == "USB-6002 1F2A3B4"
    for variable in ("I_disp", "I_macro", "I_illu"):
        assert (tmp_path / simple[variable]).is_file()


def test_same_scan_gives_the_same_bytes(tmp_path):
    scan = make_scan()
    save_scan(scan, tmp_path / "a" / "x.mat")
    save_scan(scan, tmp_path / "b" / "x.mat")
    digests = {hashlib.sha256((tmp_path / d / "x.mat").read_bytes()).hexdigest() for d in "ab"}
    assert len(digests) == 1


def test_missing_optional_channels_and_photos_load(tmp_path):
    scan = make_scan(images=False, drop=("a_fs", "a_ts", "t_cool", "dB"))
    save_scan(scan, tmp_path / "s.mat")
    loaded = load_scan(tmp_path / "s.mat")
    assert loaded == scan and set(loaded.missing_channels()) == {"a_fs", "a_ts", "t_cool", "dB"}


def test_matlab_row_vectors_are_accepted(tmp_path):
    scan = make_scan(images=False)
    save_scan(scan, tmp_path / "s.mat")
    variables = scipy.io.loadmat(tmp_path / "s.mat")
    variables["t_cool"] = variables["t_cool"].T  # a MATLAB user saved a row vector
    scipy.io.savemat(tmp_path / "row.mat", {k: v for k, v in variables.items() if not k.startswith("__")})
    np.testing.assert_array_equal(load_scan(tmp_path / "row.mat")["t_cool"].data, scan["t_cool"].data)


def _rewrite(tmp_path, change):
    """Save a valid scan, let ``change`` edit its variables (a dict, meta as a dict), save as bad.mat."""
    save_scan(make_scan(images=False), tmp_path / "good.mat")
    variables = scipy.io.loadmat(tmp_path / "good.mat", simplify_cells=True)
    variables = {k: v for k, v in variables.items() if not k.startswith("__")}
    change(variables)
    scipy.io.savemat(tmp_path / "bad.mat", variables, long_field_names=True)
    return tmp_path / "bad.mat"


def _set(path, value):
    def change(variables):
        target = variables
        *parents, last = path.split(".")
        for key in parents:
            target = target[key]
        if value is None:
            del target[last]
        else:
            target[last] = value
    return change


@pytest.mark.parametrize(
    ("change", "field", "reason"),
    [
        (_set("v_ts", np.zeros((50, 2))), "v_ts", r"wrong shape \(50, 2\), expected \(n, 3\)"),
        (_set("f_press", np.zeros((5, 5))), "f_press", "wrong shape"),
        (_set("f_frn", np.array([1.0, np.nan, np.inf, 2.0])), "f_frn", r"2 non-finite samples \(first at sample 1\)"),
        (_set("meta", None), "meta", "required variable is missing"),
        (_set("meta.label", None), "meta.label", "required field is missing"),
        (_set("meta.fs", None), "meta.fs", "required field is missing"),
        (_set("meta.fs.v_ts", None), "meta.fs.v_ts", "sample rate is missing"),
        (_set("meta.fs.a_fs", 48000.0), "meta.fs.a_fs", "sample rate 48000 Hz, expected 44100 Hz"),
        (_set("meta.units.t_cool", "K"), "meta.units.t_cool", "unit 'K', expected 'degC'"),
        (_set("meta.schema_version", 7.0), "meta.schema_version", "unknown schema version 7"),
        (_set("meta.atk", 0.3), "meta.atk", "0.3 is not on the five-step scale"),
        (_set("meta.label", "granite"), "meta.label", "'granite' is not a label"),
        (_set("meta.started", "last tuesday"), "meta.started", "not an ISO 8601 date-time"),
        (_set("I_disp", "../../etc/passwd"), "I_disp", "plain file name"),
        (_set("I_disp", "nowhere.png"), "I_disp", "cannot be read"),
    ],
)
def test_bad_content_names_file_and_field(tmp_path, change, field, reason):
    bad = _rewrite(tmp_path, change)
    with pytest.raises(ScanFormatError, match=reason) as info:
        load_scan(bad)
    assert str(info.value).startswith(f"{bad}: {field}: ")
    assert info.value.field == field and "\n" not in str(info.value)


@pytest.mark.parametrize("keep", [0, 10, 128, 300, -40])
def test_truncated_file_is_a_clear_error(tmp_path, keep):
    save_scan(make_scan(images=False), tmp_path / "s.mat")
    data = (tmp_path / "s.mat").read_bytes()
    (tmp_path / "cut.mat").write_bytes(data[:keep] if keep >= 0 else data[:keep])
    with pytest.raises(ScanFormatError, match="cut.mat") as info:
        load_scan(tmp_path / "cut.mat")
    assert "\n" not in str(info.value)


def test_foreign_and_missing_files(tmp_path):
    (tmp_path / "notes.mat").write_text("these are my notes, not a MAT file\n" * 20)
    with pytest.raises(ScanFormatError, match="notes.mat: not a readable MATLAB v5 .mat file"):
        load_scan(tmp_path / "notes.mat")
    with pytest.raises(ScanFormatError, match="absent.mat: file not found"):
        load_scan(tmp_path / "absent.mat")
    scipy.io.savemat(tmp_path / "other.mat", {"x": np.arange(3.0)})
    with pytest.raises(ScanFormatError, match="other.mat: meta: required variable is missing"):
        load_scan(tmp_path / "other.mat")


def test_corrupt_photo_is_reported(tmp_path):
    save_scan(make_scan(), tmp_path / "s.mat")
    (tmp_path / "s_macro.png").write_bytes(b"\x89PNG broken")
    with pytest.raises(ScanFormatError, match="I_macro: photo s_macro.png: not a PNG or JPEG file"):
        load_scan(tmp_path / "s.mat")
    assert load_scan(tmp_path / "s.mat", images=False).images == {}


def test_failed_write_leaves_the_previous_file_untouched(tmp_path, monkeypatch):
    import scanner.storage.matfile as matfile

    first = make_scan(images=False)
    save_scan(first, tmp_path / "s.mat")
    before = (tmp_path / "s.mat").read_bytes()

    def explode(variables):
        raise OSError("disk full")

    monkeypatch.setattr(matfile, "encode_mat", explode)
    with pytest.raises(OSError, match="disk full"):
        save_scan(make_scan(seed=5, images=False), tmp_path / "s.mat")
    assert (tmp_path / "s.mat").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.mat"]


def test_a_rigid_flag_with_a_stored_fold_loads_with_a_warning_and_the_stored_fold_wins(tmp_path):
    scan = make_scan(images=False)
    folding = Trace(10.0 * scan["alpha_f"].data, 3000.0, "deg")  # std about 10 deg: not rigid by its fold
    scan = Scan(scan.meta, {**scan.traces, "alpha_f": folding})
    save_scan(scan, tmp_path / "good.mat")
    variables = scipy.io.loadmat(tmp_path / "good.mat", simplify_cells=True)
    variables["meta"]["rigid"] = 1.0
    scipy.io.savemat(tmp_path / "rigid.mat", {k: v for k, v in variables.items() if not k.startswith("__")},
                     long_field_names=True)
    with pytest.warns(ScanFormatWarning, match=r"rigid.mat: meta.rigid is 1 but the fold is stored "
                                               r"\(f_fold, alpha_f\); the stored fold is used"):
        loaded = load_scan(tmp_path / "rigid.mat")
    assert loaded.meta.rigid and loaded["alpha_f"] == folding and loaded.fold_despite_rigid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        values = tactum.compute(loaded)
    # docs/features.md#tactum, items 9-12: with alpha_f stored the flag is ignored; std(alpha_f) >= 1 deg is not rigid.
    assert values["tactum.cdf"] == pytest.approx(np.std(folding.data), rel=1e-12)
    assert values["tactum.ccp"] == pytest.approx(np.max(scan["f_press"].data) / 4.0, rel=1e-12)
    assert values["tactum.crx"] == pytest.approx(np.max(scan["f_press"].data) - scan["f_press"].data[-1])


@pytest.mark.parametrize(("value", "reason"), [
    (np.zeros((0, 0)), "must be 0 or 1, got a float64 array of shape (0, 0)"),
    (0.5, "must be 0 or 1, got 0.5"), ("yes", "must be 0 or 1, got text")])
def test_a_flag_that_is_neither_0_nor_1_is_a_format_error(tmp_path, value, reason):
    for field in ("raw_volts", "rigid"):
        bad = _rewrite(tmp_path, _set(f"meta.{field}", value))
        with pytest.raises(ScanFormatError, match=re.escape(f"bad.mat: meta.{field}: {reason}")):
            load_scan(bad)


def test_a_compressed_variable_inflating_beyond_the_limit_is_refused_without_inflating_it(tmp_path, monkeypatch):
    import scanner.storage.matfile as matfile

    noisy = make_scan(images=False, seconds=2.0)
    scan = Scan(noisy.meta, {name: Trace(np.zeros_like(trace.data), trace.fs, trace.unit)
                             for name, trace in noisy.traces.items()})  # 2.4 MB of zeros: a few kB compressed
    save_scan(scan, tmp_path / "s.mat")
    assert (tmp_path / "s.mat").stat().st_size < 1 << 16
    monkeypatch.setattr(matfile, "MAX_SCAN_BYTES", 1 << 20)
    with pytest.raises(ScanFormatError, match="s.mat: not a readable MATLAB v5 .mat file "
                                              r"\(its variables inflate beyond the size limit\)"):
        load_scan(tmp_path / "s.mat")
    monkeypatch.setattr(matfile, "MAX_SCAN_BYTES", 4 << 20)
    assert load_scan(tmp_path / "s.mat") == scan


def test_photo_pixel_limit_comes_from_the_environment(tmp_path, monkeypatch):
    save_scan(make_scan(image_shape=(60, 80)), tmp_path / "s.mat")
    monkeypatch.setenv("TEXPLORER_MAX_PHOTO_PIXELS", "4799")
    with pytest.raises(ScanFormatError, match=r"I_disp: photo s_disp.png: the image has 4,800 pixels "
                                              r"\(80 x 60\); at most 4,799 are accepted"):
        load_scan(tmp_path / "s.mat")
    monkeypatch.setenv("TEXPLORER_MAX_PHOTO_PIXELS", "4800")
    assert load_scan(tmp_path / "s.mat").images["I_disp"].shape == (60, 80, 3)
    monkeypatch.setenv("TEXPLORER_MAX_PHOTO_PIXELS", "many")
    with pytest.raises(ValueError, match=r"\$TEXPLORER_MAX_PHOTO_PIXELS must be a positive whole number"):
        load_scan(tmp_path / "s.mat")


