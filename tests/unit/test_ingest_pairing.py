"""Other labs' files as they come: prefix-paired files, unmapped text columns, any sensor channel, labels
in file names, patch rows and columns."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from features.recordings import families, feature_space
from features.signals import SIGNAL_NAMES, signal_bands, signal_features
from scanner.scan import Recording, Trace
from scanner.storage import ingest
from scanner.storage.ingest import IngestError
from taxonomy.learning.evaluation import evaluate

TERRAIN = """
[groups]
pattern = '^(?P<run>\\d+)$'
[[files]]
glob = "**/imu_*.csv"
stem_pattern = '^imu_(?P<stem>\\d+)\\.csv$'
rate = 100.0
  [[files.channels]]
  name = "gyro"
  role = "signal"
  columns = ["gx", "gy", "gz"]
  unit = "rad/s"
[[files]]
glob = "**/pro_*.csv"
stem_pattern = '^pro_(?P<stem>\\d+)\\.csv$'
rate = 50.0
  [[files.channels]]
  name = "current"
  role = "signal"
  columns = "i_motor"
  unit = "A"
"""


def band_noise(rng: np.random.Generator, rows: int, low: bool) -> np.ndarray:
    """Unit-variance noise whose power lies below (``low``) or above a quarter of the rate."""
    spectrum = np.fft.rfft(rng.normal(size=rows))
    keep = np.arange(spectrum.size) < spectrum.size // 2
    spectrum[~keep if low else keep] = 0
    x = np.fft.irfft(spectrum, rows)
    return x / x.std()


def write_terrain(root, runs: int = 4) -> None:
    rng = np.random.default_rng(0)
    for terrain, low in (("grass", True), ("gravel", False)):
        folder = root / terrain
        folder.mkdir(parents=True)
        for run in range(runs):
            stem = f"{run + 10 * low:02d}"
            gyro = np.stack([band_noise(rng, 400, low) for _ in range(3)], axis=1)
            (folder / f"imu_{stem}.csv").write_text("gx,gy,gz,terrain\n" + "".join(
                f"{a!r},{b!r},{c!r},{terrain.upper()}\n" for a, b, c in gyro.tolist()))
            current = 2.0 + 0.1 * band_noise(rng, 200, not low)
            (folder / f"pro_{stem}.csv").write_text("i_motor\n" + "".join(f"{a!r}\n" for a in current.tolist()))


def test_files_paired_by_a_pattern_with_text_columns_ignored(tmp_path):
    write_terrain(tmp_path)
    report = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    assert report.skipped == [] and len(report.recordings) == 8
    by = {r.name: r for r in report.recordings}
    first = by["00"]
    assert first.label == "gravel" and by["10"].label == "grass"
    assert dict(first.roles) == {"signal_gyro": "gyro", "signal_current": "current"}
    assert first.channels["gyro"].data.shape == (400, 3) and first.channels["current"].fs == 50.0
    notes = [str(n) for n in report.notes]
    assert "imu_00.csv: text column(s) not in the mapping ignored: terrain ('GRAVEL')" in notes


def test_a_stem_pattern_needs_its_group_and_names_files_it_does_not_match(tmp_path):
    with pytest.raises(IngestError, match=r"needs a \(\?P<stem>...\) group"):
        ingest.parse_mapping(TERRAIN.replace("(?P<stem>", "("), "terrain")
    write_terrain(tmp_path, runs=1)
    (tmp_path / "grass" / "imu_notes.csv").write_text("gx,gy,gz\n1,2,3\n")
    report = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    assert any("imu_notes.csv: name does not match stem_pattern" in line for line in report.skipped)


def test_generic_features_of_a_pure_tone_sit_in_its_band():
    fs, f0 = 100.0, 20.0
    t = np.arange(4096) / fs
    values = dict(zip(SIGNAL_NAMES, signal_features(3.0 + np.sin(2 * np.pi * f0 * t), fs), strict=True))
    edges = signal_bands(fs)  # 0, 0.78, 1.56, 3.1, 6.25, 12.5, 25, 50 Hz
    band = int(np.searchsorted(edges, f0, side="right")) - 1
    assert band == 5 and values[f"band{band}"] > 0.999  # Hann leakage outside the band is < 1e-3
    assert values["mean"] == pytest.approx(3.0, abs=1e-3) and values["std"] == pytest.approx(2 ** -0.5, rel=1e-3)
    # Welch bins are fs / 256 = 0.39 Hz apart: the peak, centroid and roll-off are within a bin of f0.
    for name in ("peak", "centroid", "rolloff"):
        assert values[name] == pytest.approx(f0, abs=fs / 256)
    assert values["kurtosis"] == pytest.approx(1.5, rel=1e-2)  # a sine's Pearson kurtosis is 3/2


def test_white_noise_spreads_its_power_over_the_band_plan_by_bandwidth():
    fs = 200.0
    x = np.random.default_rng(1).normal(size=200_000)
    values = dict(zip(SIGNAL_NAMES, signal_features(x, fs), strict=True))
    widths = np.diff(signal_bands(fs)) / (fs / 2)  # a flat spectrum: the share of each band is its width
    shares = np.array([values[f"band{k}"] for k in range(7)])
    assert shares == pytest.approx(widths, abs=0.01) and values["flatness"] > 0.95


def test_a_generic_channel_separates_classes_only_through_its_band_energies(tmp_path):
    write_terrain(tmp_path, runs=6)
    recordings = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain")).recordings
    assert families(recordings[0]) == ["generic.signal_current", "generic.signal_gyro:3"]
    space, notes = feature_space(recordings, group_by="run")
    assert notes == [] and space.X.shape == (12, len(SIGNAL_NAMES) * 4)
    bands = [c for c in space.columns if "_band" in c or c.endswith(tuple(f"band{k}" for k in range(7)))]
    # Both classes have unit variance and mean 0 on the gyro: only the spectrum tells them apart.
    result = evaluate(space, "lda", level="label", n_features=None, folds=3, seed=0, feature_set=bands)
    assert result.grouped and float(np.mean(result.accuracy)) == 1.0
    shuffled = [Recording(r.name, r.channels, r.roles, ("a", "b")[i % 2], r.group, r.meta)
                for i, r in enumerate(recordings)]
    control, _ = feature_space(shuffled, group_by="run")
    chance = evaluate(control, "lda", level="label", n_features=None, folds=3, seed=0, feature_set=bands)
    assert float(np.mean(chance.accuracy)) < 0.85


def test_recordings_lacking_a_role_are_listed():
    rng = np.random.default_rng(2)
    full = [Recording(f"r{k}", {"g": Trace(rng.normal(size=300), 100.0, "-"),
                                "f": Trace(rng.normal(size=(300, 3)), 100.0, "N")},
                      {"signal_g": "g", "force_xyz": "f"}, "x") for k in range(3)]
    bare = Recording("r9", {"g": Trace(rng.normal(size=300), 100.0, "-")}, {"signal_g": "g"}, "x")
    space, notes = feature_space([*full, bare])
    assert notes == ["1 of 4 recording(s) lack the role force_xyz (at a rate friction applies to): its 2 "
                     "column(s) are NaN there (r9)"]
    assert np.isnan(space.X[3, :2]).all() and not np.isnan(space.X[:3]).any()


def test_a_recording_without_one_channel_of_a_ratio_is_named_by_both_roles():
    # Current per speed reads two slow channels: the note names both roles, not only the numerator's.
    rng = np.random.default_rng(4)
    both = [Recording(f"r{k}", {"i": Trace(rng.uniform(1, 2, size=40), 6.5, "A"),
                                "v": Trace(rng.uniform(0.1, 0.2, size=40), 6.5, "m/s")},
                      {"signal_current": "i", "signal_speed": "v"}, "x") for k in range(3)]
    current_only = Recording("r9", {"i": Trace(rng.uniform(1, 2, size=40), 6.5, "A")}, {"signal_current": "i"}, "x")
    _, notes = feature_space([*both, current_only])
    ratio = [n for n in notes if "ratio." in n]
    assert len(ratio) == 1 and ratio[0].startswith("1 of 4 recording(s) lack one of the roles signal_current, "
                                                   "signal_speed (at a rate ratio.signal_current.signal_speed:1x1")
    assert ratio[0].endswith("(r9)")


def test_a_flat_folder_of_photos_labelled_by_file_name_cut_into_rows(tmp_path):
    rng = np.random.default_rng(3)
    for name in ("cork_01", "cork_02", "felt_01"):
        cv2.imwrite(str(tmp_path / f"{name}.png"), rng.integers(0, 255, size=(40, 60, 3), dtype=np.uint8))
    plain = ingest.ingest(tmp_path, ingest.with_grid(ingest.default_mapping("flat"), (2, 3)))
    assert plain.recordings == [] and "--label-pattern" in plain.skipped[0]
    mapping = ingest.with_label_pattern(ingest.default_mapping("flat"), r"^(?P<label>[a-z]+)_(?P<photo_no>\d+)")
    report = ingest.ingest(tmp_path, ingest.with_grid(mapping, (2, 3)))
    assert len(report.recordings) == 18 and {r.label for r in report.recordings} == {"cork", "felt"}
    patch = next(r for r in report.recordings if r.name == "cork_02_r1c2")
    assert dict(patch.group) == {"photo_no": "02", "photo": "cork_02", "row": "1", "column": "2"}
    space, _ = feature_space(report.recordings, group_by="row")
    assert sorted(set(space.groups)) == ["0", "1"]  # hold out a row of patches of every photo
    with pytest.raises(IngestError, match="needs a"):
        ingest.with_label_pattern(ingest.default_mapping("flat"), "^[a-z]+")


def test_ingest_lists_recordings_lacking_a_role_the_others_have(tmp_path):
    write_terrain(tmp_path, runs=3)
    (tmp_path / "grass" / "pro_11.csv").unlink()  # run 11's motor log is missing
    report = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    assert len(report.recordings) == 6 and report.skipped == []
    assert "1 of 6 recording(s) lack the role signal_current that the others have: 11" in map(str, report.notes)


def _wheel_only(root) -> None:
    """A folder holding one wheel file and no IMU file, as BorealTC's MIXED."""
    folder = root / "MIXED"
    folder.mkdir(parents=True)
    (folder / "pro_90.csv").write_text("i_motor\n" + "".join(f"{2.0 + 0.01 * k!r}\n" for k in range(200)))


def test_files_of_a_required_entry_pair_a_recording_and_the_unpaired_are_named(tmp_path):
    write_terrain(tmp_path, runs=2)
    (tmp_path / "grass" / "imu_10.csv").unlink()  # grass run 10 keeps only its wheel file
    _wheel_only(tmp_path)
    loose = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    assert len(loose.recordings) == 5 and loose.skipped == []  # not required: a recording of one file each
    required = TERRAIN.replace('glob = "**/imu_*.csv"', 'glob = "**/imu_*.csv"\nrequired = true')
    report = ingest.ingest(tmp_path, ingest.parse_mapping(required, "terrain"))
    assert sorted(r.name for r in report.recordings) == ["00", "01", "11"]
    assert sorted(report.skipped) == [
        f"{where}: unpaired: no file of the required [[files]] '**/imu_*.csv' with the stem '{stem}' in its "
        "folder; not read" for where, stem in (("MIXED/pro_90.csv", "90"), ("grass/pro_10.csv", "10"))]


def test_a_class_without_a_role_every_other_class_has_is_named_and_can_be_left_out(tmp_path):
    write_terrain(tmp_path, runs=2)
    _wheel_only(tmp_path)
    report = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    lines = [n.text for n in report.notes if n.kind == "class_roles"]
    assert lines == ["class MIXED: none of its 1 recording(s) has the role(s) signal_gyro that every other class "
                     "has; leave it out with [labels] exclude = ['MIXED'] or --exclude-label MIXED"]
    for mapping in (ingest.parse_mapping(TERRAIN + '[labels]\nexclude = ["MIXED"]\n', "terrain"),
                    ingest.with_excluded(ingest.parse_mapping(TERRAIN, "terrain"), ["MIXED"])):
        left = ingest.ingest(tmp_path, mapping)
        assert sorted({r.label for r in left.recordings}) == ["grass", "gravel"] and left.skipped == []
        assert [n.text for n in left.notes if n.kind == "excluded"] == [
            "class MIXED: 1 file(s) not read (MIXED/pro_90.csv), as asked"]
        assert not [n for n in left.notes if n.kind == "class_roles"]
    with pytest.raises(IngestError, match="exclude must be a class name or a list of class names"):
        ingest.parse_mapping(TERRAIN + "[labels]\nexclude = [1]\n", "terrain")


def test_a_channel_mapped_without_a_role_is_a_generic_signal_with_a_note(tmp_path):
    write_terrain(tmp_path, runs=1)
    unroled = TERRAIN.replace('  role = "signal"\n  columns = ["gx", "gy", "gz"]', '  columns = ["gx", "gy", "gz"]')
    assert unroled != TERRAIN
    report = ingest.ingest(tmp_path, ingest.parse_mapping(unroled, "terrain"))
    first = report.recordings[0]
    assert first.roles["signal_gyro"] == "gyro" and first.channels["gyro"].data.shape == (400, 3)
    notes = [n.text for n in report.notes if n.kind == "role"]
    assert notes and notes[0].endswith("channel gyro has no role: read as the generic role signal (signal_gyro); "
                                       "give it role = ... in the mapping to say otherwise")
    space, _ = feature_space(report.recordings)
    assert any(c.startswith("generic.signal_gyro.") for c in space.columns)


def test_slow_features_of_a_ramp_and_a_square_wave_are_their_closed_forms():
    from features.signals import SLOW_NAMES, slow_features

    fs = 6.5
    t = np.arange(33) / fs
    ramp = dict(zip(SLOW_NAMES, slow_features(2.0 + 0.5 * t, fs), strict=True))
    assert ramp["slope"] == pytest.approx(0.5, rel=1e-12) and ramp["change"] == pytest.approx(0.5, rel=1e-12)
    assert ramp["mean"] == pytest.approx(2.0 + 0.5 * t.mean(), rel=1e-12)
    assert ramp["std"] == pytest.approx(0.5 * t.std(), rel=1e-12)
    square = dict(zip(SLOW_NAMES, slow_features(np.tile([1.0, -1.0, -1.0, 1.0], 8), fs), strict=True))
    # Up and down, symmetric in every block of four: no trend, but 16 of its 31 steps move by 2.
    assert square["slope"] == pytest.approx(0.0, abs=1e-12)
    assert square["change"] == pytest.approx(2 * 16 / 31 * fs, rel=1e-12)
    with pytest.raises(ValueError, match="too short for the slow features"):
        slow_features(np.ones(3), fs)


def test_the_level_ratio_is_the_log_of_current_per_speed_and_bounded_where_one_is_zero():
    from features.signals import RATIO_BOUND, log_ratio

    assert log_ratio(np.full(30, 4.0), np.full(30, -0.4)) == pytest.approx(1.0, rel=1e-12)  # 4 A per 0.4 m/s
    assert log_ratio(np.full(30, 4.0), np.zeros(30)) == RATIO_BOUND  # standing still: the bound, not inf
    assert log_ratio(np.zeros(30), np.full(30, 2.0)) == -RATIO_BOUND
    assert log_ratio(np.zeros(30), np.zeros(30)) == 0.0


def test_channels_at_a_few_hz_get_slow_features_and_ratios_not_spectra():
    from features.signals import SLOW_NAMES

    rng = np.random.default_rng(3)
    imu = Trace(rng.normal(size=(1000, 3)), 100.0, "rad/s")
    current = Trace(2.0 + 0.1 * rng.normal(size=(65, 2)), 6.5, "A")
    speed = Trace(np.full((65, 2), 0.5), 6.5, "m/s")
    recording = Recording("run", {"gyro": imu, "current": current, "speed": speed},
                          {"signal_gyro": "gyro", "signal_current": "current", "signal_speed": "speed"}, "snow")
    assert families(recording) == ["slow.signal_current:2", "generic.signal_gyro:3", "slow.signal_speed:2",
                                   "ratio.signal_current.signal_speed:2x2"]
    space, notes = feature_space([recording])
    columns = list(space.columns)
    assert notes == [] and len(columns) == 3 * len(SIGNAL_NAMES) + 2 * 2 * len(SLOW_NAMES) + 2
    assert not any(c.startswith("generic.signal_current.") and "band" in c for c in columns)
    row = dict(zip(columns, space.X[0], strict=True))
    level = np.log10(np.abs(current.data[:, 0]).mean() / 0.5)
    assert row["generic.signal_current.c0_log_per_speed"] == pytest.approx(level, rel=1e-12)
    assert row["generic.signal_speed.c1_mean"] == pytest.approx(0.5) and row["generic.signal_speed.c1_slope"] == 0


def _runs_with_their_own_level(runs: int = 6) -> list[Recording]:
    """Two classes whose slow channel differs only by a level each run has of its own (a sensor's drift):
    the windows of one run share it, so a test window is matched by its run's training windows."""
    rng = np.random.default_rng(7)
    recordings = []
    for label in ("asphalt", "snow"):
        for run in range(runs):
            level = rng.normal(0.0, 5.0)
            data = level + 0.05 * rng.normal(size=(60 * 10,))
            recordings.append(Recording(f"{label}-{run}", {"current": Trace(data, 10.0, "A")},
                                        {"signal_current": "current"}, label))
    return recordings


def test_group_by_none_splits_the_windows_of_one_run_and_shows_the_leakage_beside_the_grouped_figure():
    from features.recordings import Windowing
    from taxonomy.learning.evaluation import evaluate_grid
    from taxonomy.reports.report import format_protocols, format_table

    recordings = _runs_with_their_own_level()
    grouped, _ = feature_space(recordings, Windowing(5.0, "rows"))
    alone, _ = feature_space(recordings, Windowing(5.0, "rows"), group_by="none")
    assert len(set(grouped.groups)) == 12 and len(set(alone.groups)) == len(alone) == 12 * 12
    cells = {"classifiers": ["rf"], "set_sizes": [None], "feature_sets": {"all": None}, "calibrate": False}
    kept, = evaluate_grid(grouped, group_by="recording", **cells)
    leaked, = evaluate_grid(alone, group_by="none", **cells)
    # A run's level names its class only through its own other windows: held out, it is a coin toss.
    assert leaked.accuracy_pooled >= 0.95 and kept.accuracy_pooled < 0.8
    assert kept.grouped and not leaked.grouped and leaked.splitting == "5 ungrouped folds"
    assert "NOT grouped: every row its own group, so windows of one recording are in training and test" in (
        format_table([leaked]))
    side = format_protocols([kept], [leaked]).splitlines()
    assert side[1].split() == ["classifier", "feature", "set", "level", "features", "grouped", "by", "recording",
                               "%", "NOT", "grouped", "%", "difference"]
    difference = f"{100 * (leaked.accuracy_pooled - kept.accuracy_pooled):+.1f}"
    assert side[2].split() == ["rf", "all", "label", "all", f"{100 * kept.accuracy_pooled:.1f}",
                               f"{100 * leaked.accuracy_pooled:.1f}", difference, "points"]


def _rows(path) -> list[str]:
    return path.read_text().splitlines(keepends=True)


def test_a_run_that_begins_with_another_runs_samples_shares_its_fold_group(tmp_path):
    """A file holding a copy of an earlier run followed by more (two runs saved again as one, as in one of
    BorealTC's snow runs): named in a note, and kept in the earlier run's cross-validation group, through a
    chain; runs that only begin at rest alike (constant samples) are not taken for copies."""
    write_terrain(tmp_path, runs=3)
    gravel, grass = tmp_path / "gravel", tmp_path / "grass"
    for kind in ("imu", "pro"):  # 01 = 00 + its own rows; 02 = 01 + its own rows
        for later, earlier in (("01", "00"), ("02", "01")):
            (gravel / f"{kind}_{later}.csv").write_text("".join(
                _rows(gravel / f"{kind}_{earlier}.csv") + _rows(gravel / f"{kind}_{later}.csv")[1:]))
    for stem in ("10", "11"):  # both begin with a second at rest
        rows = _rows(grass / f"imu_{stem}.csv")
        (grass / f"imu_{stem}.csv").write_text("".join(rows[:1] + ["0.0,0.0,0.0,GRASS\n"] * 100 + rows[1:]))
    report = ingest.ingest(tmp_path, ingest.parse_mapping(TERRAIN, "terrain"))
    assert [n.text for n in report.notes if n.kind == "repeats"] == [
        "recording 01: at least its first 3.8 s (current, gyro) are the samples of recording 00: one "
        "cross-validation group with it (group repeats = 00)",
        "recording 02: at least its first 7.7 s (current, gyro) are the samples of recording 01: one "
        "cross-validation group with it (group repeats = 00)"]
    by = {r.name: r for r in report.recordings}
    assert by["01"].channels["gyro"].data.shape == (800, 3) and "repeats" not in by["00"].group
    space, _ = feature_space(report.recordings)
    assert dict(zip(space.scan_ids, space.groups, strict=True)) == {
        "00": "00", "01": "00", "02": "00", "10": "10", "11": "11", "12": "12"}


def test_block_digests_skip_a_constant_start_and_count_whole_blocks():
    ramp = np.arange(200.0)
    assert len(ingest.assembly.block_digests(ramp)) == 3  # 200 // 64 whole blocks
    assert ingest.assembly.block_digests(np.ones(200)) == []
    assert ingest.assembly.block_digests(ramp[:63]) == []
    assert len(ingest.assembly.block_digests(np.arange(64.0 * 2000))) == ingest.assembly.REPEAT_BLOCKS_KEPT
    copy = np.concatenate([ramp[:128], -ramp])
    assert ingest.assembly.block_digests(copy)[:2] == ingest.assembly.block_digests(ramp)[:2]
