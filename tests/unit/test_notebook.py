"""Notebook display: short reprs, HTML tables and pandas DataFrames of Scan, FeatureSpace and Result."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from conftest import make_scan

from features.space import FeatureSpace
from taxonomy.learning.results import EvaluationError, Result

pd = pytest.importorskip("pandas", reason="the pandas extra (pip install 'texplorer[pandas]') is not installed")

COLUMNS = ("tactum.matx", "tactum.maco", "other.density")
LABELS = ("C6S1M1P2X1", "C6S1M1P2X1", "C7S1M1P8X1", "C7S1M1P8X1")


@pytest.fixture
def space() -> FeatureSpace:
    X = np.array([[0.5, 1.0, 2650.0], [0.25, np.nan, 2700.0], [0.75, 3.0, 7850.0], [1.0, 4.0, 7800.0]])
    return FeatureSpace(X, COLUMNS, ("g-1", "g-2", "s-1", "s-2"), LABELS, ("granite-01", "granite-01", "steel-01",
                                                                           "steel-02"))


@pytest.fixture
def result() -> Result:
    confusion = np.array([[2, 0], [1, 1]])
    return Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", ("C6S1M1P2X1", "C7S1M1P8X1"),
                  accuracy=np.array([1.0, 0.5]), f1=np.array([1.0, 1 / 3]), confusion=confusion, n_samples=4, seed=0,
                  n_features=2, grouped=True, columns=COLUMNS,
                  selected=(("other.density", "tactum.matx"), ("other.density", "tactum.maco")),
                  y_true=np.array(LABELS), y_pred=np.array(LABELS[:3] + ("C6S1M1P2X1",)), fold=np.array([0, 1, 0, 1]))


def test_a_feature_space_repr_is_one_line_of_counts(space):
    assert repr(space) == "FeatureSpace(4 rows x 3 features, 3 groups, 2 classes at fine)"


def test_a_feature_space_html_shows_its_first_rows_and_columns(space):
    page = space._repr_html_(rows=2, features=2)
    assert page.count("<tr>") == 1 + 2 + 1  # header, two rows, the row of "..."
    assert "<th>tactum.maco</th>" in page and "other.density" not in page and "<td>g-2</td>" in page


def test_a_feature_space_as_a_data_frame(space):
    frame = space.to_pandas()
    assert list(frame.columns) == ["label", "group", *COLUMNS] and frame.index.name == "scan_id"
    assert list(frame.index) == list(space.scan_ids) and list(frame["label"]) == list(LABELS)
    assert list(frame["group"]) == list(space.groups)
    np.testing.assert_array_equal(frame[list(space.columns)].to_numpy(), space.X)  # NaN where NaN
    assert frame.groupby("label")["other.density"].mean()["C7S1M1P8X1"] == pytest.approx((7850 + 7800) / 2)


def test_a_recording_set_keeps_its_levels_and_split():
    free = FeatureSpace(np.eye(2), ("audio.mic.a", "audio.mic.b"), ("r1", "r2"), ("cup", "mug"), ("o1", "o2"),
                        label_level="object", levels={"material": ("glass", "clay")}, split=("train", "test"))
    assert repr(free) == ("FeatureSpace(2 rows x 2 features, 2 groups, 2 classes at object (coarser levels: "
                          "material), split 1 train / 1 test)")
    frame = free.to_pandas()
    assert list(frame.columns[:4]) == ["label", "group", "level:material", "split"]
    assert list(frame["level:material"]) == ["glass", "clay"] and list(frame["split"]) == ["train", "test"]


def test_to_pandas_without_pandas_says_which_extra_installs_it(space, result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # import pandas now fails as if it were not installed
    for call, who in ((space.to_pandas, "FeatureSpace.to_pandas()"), (result.to_pandas, "Result.to_pandas()")):
        with pytest.raises(ModuleNotFoundError) as missing:
            call()
        message = str(missing.value)
        assert "\n" not in message and message.startswith(f"{who} needs pandas")
        assert "pip install 'texplorer[pandas]'" in message


def test_a_scan_repr_is_one_line_and_its_html_lists_channels_and_photos():
    scan = make_scan(0, sample_id="granite-01", scan_index=1)
    assert repr(scan) == (f"Scan({scan.scan_id}, label {scan.meta.label}, sample granite-01, {len(scan.traces)} "
                          f"channels, {len(scan.images)} photos)")
    page = scan._repr_html_()
    assert page.count("<tr>") == 1 + len(scan.traces) + len(scan.images)
    first = next(iter(scan.traces))
    assert f"<td>{first}</td>" in page and "<td>240x320x3</td>" in page


def test_a_result_repr_is_its_summary_line(result):
    assert repr(result) == f"Result(texplorer: {result.summary()})" and "\n" not in repr(result)
    assert "accuracy 75.0 % +- 35.4 %" in repr(result)  # mean of 1 and 0.5; sample std 0.5 / sqrt(2)
    page = result._repr_html_()
    assert "<th>accuracy</th><td>75.0 % +- 35.4 %</td>" in page and "<th>level</th><td>fine (2 classes)</td>" in page


def test_a_result_as_data_frames(result):
    splits = result.to_pandas()
    assert splits.index.name == "split" and list(splits["accuracy"]) == [1.0, 0.5]
    assert splits["selected"][1] == ["other.density", "tactum.maco"]
    predictions = result.to_pandas("predictions")
    assert list(predictions.columns) == ["y_true", "y_pred", "fold"]
    assert (predictions["y_true"] == predictions["y_pred"]).mean() == pytest.approx(0.75)
    confusion = result.to_pandas("confusion")
    assert confusion.loc["C7S1M1P8X1", "C6S1M1P2X1"] == 1 and confusion.to_numpy().sum() == 4
    with pytest.raises(EvaluationError, match="none of 'splits'"):
        result.to_pandas("folds")
