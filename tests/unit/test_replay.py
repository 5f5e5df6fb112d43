"""Replay (docs/export.md): the regression suite of stored scans, tolerance checks, the CLI, real-time pacing."""

from __future__ import annotations

import math
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import make_scan

from features import NAMES, SOLVER_RTOL, FeatureSpace
from scanner.cli import main
from scanner.cli.exchange import EXIT_MISMATCH
from scanner.replay import (
    STEPS,
    Difference,
    ReplayError,
    compare,
    format_comparison,
    paced_steps,
    predictions,
    replay,
    scan_paths,
    within,
)
from scanner.storage.matfile import save_scan

REGRESSION = Path(__file__).parents[1] / "regression"
SCANS = REGRESSION / "scans"
EXPECTED = REGRESSION / "expected_features.csv"


# -- the regression suite ----------------------------------------------------------------------------

def test_stored_scans_replay_to_their_expected_193_features():
    """Fails when any feature's numbers change; if the change is intended, regenerate the expectations with
    ``texplorer replay tests/regression/scans --write-expected tests/regression/expected_features.csv``."""
    expected = FeatureSpace.from_csv(EXPECTED)
    assert expected.columns == NAMES and len(expected) == 4
    space = replay(scan_paths([SCANS]), workers=1, progress=False)
    assert space.failed == ()
    comparison = compare(space, expected, feature_rtol=SOLVER_RTOL)
    assert comparison.compared == 4 * 193
    assert comparison.ok, format_comparison(comparison)


def test_regression_suite_is_compact_and_covers_four_materials():
    size = sum(p.stat().st_size for p in SCANS.iterdir())
    assert size < 10e6
    labels = FeatureSpace.from_csv(EXPECTED).label_text
    assert len({label[:2] for label in labels}) == 4  # four major classes


# -- comparison --------------------------------------------------------------------------------------

def test_within_scales_the_tolerance_with_the_expected_value():
    # |a - e| <= 1e-12 + 1e-9 |e|: for e = 1 the bound is 1.000000000001e-9, for e = 0 it is 1e-12,
    # for e = -1e6 it is 1e-3 + 1e-12.
    expected = np.array([1.0, 1.0, 0.0, 0.0, -1e6, -1e6, np.nan, np.nan, 1.0])
    actual = np.array([1 + 0.9e-9, 1 + 1.1e-9, 0.9e-12, -1.1e-12, -1e6 + 0.99e-3, -1e6 - 1.01e-3, np.nan, 1.0,
                       np.nan])
    assert within(actual, expected).tolist() == [True, False, True, False, True, False, True, False, False]
    assert within(np.array([1.5]), np.array([1.0]), rtol=0.5, atol=0.0).tolist() == [True]
    assert within(np.array([1.5]), np.array([1.0]), rtol=0.49, atol=0.0).tolist() == [False]


def _space(ids, columns, X) -> FeatureSpace:
    return FeatureSpace(np.array(X, dtype=float), columns, ids, ["C6S1M1P2X1"] * len(ids), ids)


def test_compare_matches_rows_by_scan_id_and_columns_by_name():
    expected = _space(["a", "b"], ["f1", "f2", "f3"], [[1.0, 2.0, 3.0], [4.0, 5.0, np.nan]])
    actual = _space(["c", "b"], ["f3", "f2", "f4"], [[0.0, 0.0, 0.0], [np.nan, 5.0 * (1 + 2e-9), 7.0]])
    comparison = compare(actual, expected)
    assert comparison.compared == 2  # row b, columns f2 and f3
    assert comparison.differences == [Difference("b", "f2", 5.0, 5.0 * (1 + 2e-9))]
    assert comparison.differences[0].relative == pytest.approx(2e-9)
    assert comparison.missing_scans == ["a"] and comparison.unexpected_scans == ["c"]
    assert comparison.missing_features == ["f1"] and comparison.unexpected_features == ["f4"]
    assert not comparison.ok
    text = format_comparison(comparison)
    assert "b                            f2" in text and "2e-09" in text
    assert "missing scan       a" in text and "unexpected feature f4" in text
    assert text.endswith("2 values compared, 1 differ; 1 missing scan(s), 1 unexpected scan(s), "
                         "1 missing feature(s), 1 unexpected feature(s): MISMATCH")
    assert compare(actual, expected, rtol=1e-8).differences == []


def test_compare_refuses_duplicate_scan_ids_and_bad_tolerances():
    twice = _space(["a", "a"], ["f"], [[1.0], [1.0]])
    with pytest.raises(ReplayError, match="scan id\\(s\\) a appear more than once"):
        compare(twice, _space(["a"], ["f"], [[1.0]]))
    for bad in (-1e-9, math.nan, math.inf):
        with pytest.raises(ReplayError, match="rtol must be a finite number >= 0"):
            compare(twice, twice, rtol=bad)


def test_scan_paths_searches_folders_and_skips_temporary_files(tmp_path):
    save_scan(make_scan(0, images=False), tmp_path / "b" / "x.mat")
    save_scan(make_scan(1, images=False), tmp_path / "a.mat")
    (tmp_path / "b" / ".y.mat.tmp-0123456789ab").write_bytes(b"partial")
    assert scan_paths([tmp_path]) == [tmp_path / "a.mat", tmp_path / "b" / "x.mat"]
    with pytest.raises(ReplayError, match="nothing.mat: no such file or folder"):
        scan_paths([tmp_path / "nothing.mat"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ReplayError, match="no .mat scans in"):
        scan_paths([tmp_path / "empty"])


def test_predictions_of_a_model_trained_on_the_regression_scans():
    from taxonomy.learning.models import train_model

    expected = FeatureSpace.from_csv(EXPECTED)
    model = train_model(expected, level="coarse", n_features=3, classifier="rf")
    results = predictions(expected, model, k=2)
    assert [r[0][0] for r in results] == [label[:2] for label in expected.label_text]
    assert all(len(r) == 2 and r[0][1] >= r[1][1] for r in results)
    broken = FeatureSpace(np.full_like(expected.X, np.nan), expected.columns, expected.scan_ids,
                          expected.label_text, expected.groups)
    assert all("undefined (NaN" in r for r in predictions(broken, model))


# -- command line ------------------------------------------------------------------------------------

def test_cli_replay_writes_and_checks_expected_values(tmp_path, capsys):
    one = tmp_path / "scans"
    one.mkdir()
    for path in SCANS.glob("oak-planed-01-001*"):
        shutil.copy(path, one)
    table = tmp_path / "expected.csv"
    assert main(["replay", str(one), "--write-expected", str(table), "--workers", "1"]) == 0
    assert "oak-planed-01-001" in capsys.readouterr().out
    # The regression contract is the replay tolerance (rtol 1e-9, atol 1e-12, the solver's for fitted
    # features), not the last bit: a summation-order change in a feature must not force new expectations.
    written = compare(FeatureSpace.from_csv(table), FeatureSpace.from_csv(EXPECTED), feature_rtol=SOLVER_RTOL,
                      scans=["oak-planed-01-001"])
    assert written.ok and written.compared == 193, format_comparison(written)

    assert main(["replay", str(one), "--expect", str(table), "--workers", "1"]) == 0
    assert "193 values compared, 0 differ: all within tolerance" in capsys.readouterr().out

    lines = table.read_text().splitlines()
    header, row = lines[0].split(","), lines[1].split(",")
    column = header.index("tactum.matx")
    row[column] = repr(float(row[column]) * (1 + 1e-6))
    table.write_text("\n".join([lines[0], ",".join(row)]) + "\n")
    assert main(["replay", str(one), "--expect", str(table), "--workers", "1"]) == EXIT_MISMATCH
    out = capsys.readouterr().out
    assert "oak-planed-01-001            tactum.matx" in out and "1e-06" in out
    assert out.rstrip().endswith("193 values compared, 1 differ: MISMATCH")
    # A looser tolerance accepts the change.
    assert main(["replay", str(one), "--expect", str(table), "--rtol", "2e-6", "--workers", "1"]) == 0
    capsys.readouterr()
    assert main(["replay", str(one), "--pace", "1000", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "playing oak-planed-01-001 at 1000x" in out and "\n  tool_slide    rms v_ts " in out
    assert out.index("finger_tap") < out.index("thermal") < out.index("photos") < out.index("1 scan(s) replayed")


def test_cli_replay_of_part_of_a_database_compares_only_the_scans_given(tmp_path, capsys):
    part = tmp_path / "part"
    part.mkdir()
    for path in SCANS.glob("oak-planed-01-001*"):
        shutil.copy(path, part)
    assert main(["replay", str(part), "--expect", str(EXPECTED), "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "missing scan" not in out
    assert out.rstrip().endswith("193 values compared, 0 differ: all within tolerance")


def test_format_comparison_limits_every_listed_line_and_says_how_many_were_left_out():
    expected = _space([f"s{i}" for i in range(5)], ["f1", "f2"], np.ones((5, 2)))
    actual = _space(["s0"], ["f1", "f2"], [[2.0, 1.0]])
    text = format_comparison(compare(actual, expected), limit=2)
    lines = text.splitlines()
    assert lines[1].startswith("s0") and "f1" in lines[1]
    assert lines[2] == "missing scan       s1"
    assert lines[3] == "... 3 more line(s) not shown (--max-rows 2)"
    assert lines[4] == "2 values compared, 1 differ; 4 missing scan(s): MISMATCH"
    assert len(lines) == 5


def test_format_comparison_keeps_columns_aligned_for_long_scan_ids():
    long_id = "polyurethane-foam-open-cell-01-001"
    text = format_comparison(compare(_space([long_id, "a"], ["f"], [[2.0], [2.0]]),
                                     _space([long_id, "a"], ["f"], [[1.0], [1.0]])))
    header, first, second = text.splitlines()[:3]
    assert header.index("feature") == first.index("f ") == second.index("f ")


def test_cli_replay_reports_broken_files_and_missing_expectations(tmp_path, capsys):
    (tmp_path / "broken.mat").write_bytes(b"MATLAB 5.0 MAT-file, but truncated")
    assert main(["replay", str(tmp_path / "broken.mat"), "--workers", "1"]) == 1
    out = capsys.readouterr().out
    assert "failed   " in out and "broken.mat" in out and "0 scan(s) replayed" in out
    assert main(["replay", str(tmp_path / "nothing"), "--workers", "1"]) == 1
    assert "texplorer: error: " in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "broken.mat"), "--write-expected", str(tmp_path / "x.csv"),
                 "--workers", "1"]) == 1
    assert "expected values not written: 1 scan(s) failed" in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


# -- real-time pacing --------------------------------------------------------------------------------

class FakeClock:
    """A clock that only moves when slept on (or when the test moves it)."""

    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def test_paced_steps_yield_each_step_after_its_duration_divided_by_speed():
    scan = make_scan(0, seconds=0.2, raw=True)  # every channel 0.2 s long
    clock = FakeClock()
    seen = []
    for step, arrays in paced_steps(scan, speed=2.0, clock=clock, sleep=clock.sleep):
        seen.append((step, round(clock.now - 100.0, 9), sorted(arrays)))
        if step != "photos":
            for name, data in arrays.items():
                source = scan.raw[name[:-4]] if name.endswith("_raw") else scan.traces[name]
                assert data is source.data or np.array_equal(data, source.data)
    assert [s[0] for s in seen] == list(STEPS)
    # 0.2 s of recording per step at twice the speed: one step every 0.1 s; photos without waiting.
    assert [s[1] for s in seen] == [round(0.1 * k, 9) for k in range(1, 10)] + [0.9]
    assert dict((s[0], s[2]) for s in seen)["tool_slide"] == ["a_ts", "r_ts", "v_ts", "v_ts_raw"]
    assert dict((s[0], s[2]) for s in seen)["static"] == ["dB", "m"]
    assert dict((s[0], s[2]) for s in seen)["photos"] == ["I_disp", "I_illu", "I_macro"]
    assert sum(clock.sleeps) == pytest.approx(0.9)


def test_paced_chunks_split_each_step_at_sample_boundaries():
    scan = make_scan(1, seconds=0.2, images=False)
    clock = FakeClock()
    chunks: dict[str, list[dict[str, np.ndarray]]] = {}
    times = []
    for step, arrays in paced_steps(scan, chunk_s=0.05, clock=clock, sleep=clock.sleep):
        chunks.setdefault(step, []).append(arrays)
        times.append(round(clock.now - 100.0, 9))
    assert list(chunks) == list(STEPS[:-1])  # no photos in this scan
    assert times == [round(0.05 * k, 9) for k in range(1, 37)]  # 9 steps x 4 chunks, one every 0.05 s
    slide = chunks["finger_slide"]
    # 0.05 s is 150 samples at 3000 Hz and 2205 at 44100 Hz; t_cool (20 Hz, 4 samples) gives 1 per chunk.
    assert [len(c["v_fs"]) for c in slide] == [150] * 4 and [len(c["a_fs"]) for c in slide] == [2205] * 4
    assert [len(c["t_cool"]) for c in chunks["thermal"]] == [1, 1, 1, 1]
    assert [len(c["dB"]) for c in chunks["static"]] == [4, 4, 4, 4]
    for parts in chunks.values():
        for name in parts[0]:
            np.testing.assert_array_equal(np.concatenate([p[name] for p in parts]), scan.traces[name].data)
    fast = paced_steps(scan, speed=math.inf, chunk_s=0.08)
    uneven = [arrays["v_ft"] for step, arrays in fast if step == "finger_tap"]
    assert [len(a) for a in uneven] == [240, 240, 120]  # 0.08 s = 240 samples, the rest is shorter


def test_pacing_leaves_out_missing_steps_and_does_not_add_the_consumers_time():
    scan = make_scan(2, seconds=0.2, images=False, rigid=True, drop=("f_fold", "alpha_f", "t_cool"))
    clock = FakeClock()
    steps = []
    for step, _ in paced_steps(scan, clock=clock, sleep=clock.sleep):
        steps.append(step)
        clock.now += 0.15  # a slow consumer: only the remaining 0.05 s of the next step are waited for
    assert steps == ["finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "friction", "press"]
    assert clock.sleeps[0] == pytest.approx(0.2) and clock.sleeps[1:] == pytest.approx([0.05] * 6)


def test_pacing_in_real_time_takes_the_recording_time():
    scan = make_scan(3, seconds=0.2, images=False)
    started = time.monotonic()
    steps = [step for step, _ in paced_steps(scan, speed=10.0)]
    assert len(steps) == 9
    assert time.monotonic() - started >= 9 * 0.2 / 10.0 - 1e-3


@pytest.mark.parametrize("speed", [0, -1.0, math.nan, "fast"])
def test_pacing_refuses_a_bad_speed(speed):
    with pytest.raises(ReplayError, match="speed must be a positive number"):
        paced_steps(make_scan(0, images=False), speed=speed)
    with pytest.raises(ReplayError, match="chunk_s must be a positive number of seconds"):
        paced_steps(make_scan(0, images=False), chunk_s=0.0)
