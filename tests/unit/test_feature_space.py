"""FeatureSpace (docs/evaluation.md): consistent shape, labels at three levels, exact CSV and .mat round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.io

from features.space import FeatureSpace, FeatureSpaceError


def small_space() -> FeatureSpace:
    X = np.array([[1.0, 0.1, math.nan], [2.0, 1 / 3, 5e-300], [3.0, -7.25, 1e300]])
    return FeatureSpace(X, ("tactum.matx", "image.disp.color", "other.density"),
                        ("a-001", "a-002", "b-001"), ("C6S1M1P2X1", "C6S1M1P2X1", "C7S1M1P8X1"), ("a", "a", "b"))


def test_labels_and_levels():
    space = small_space()
    np.testing.assert_array_equal(space.labels, [[6, 1, 1, 2, 1], [6, 1, 1, 2, 1], [7, 1, 1, 8, 1]])
    assert list(space.y("coarse")) == ["C6", "C6", "C7"]
    assert list(space.y("medium")) == ["C6S1", "C6S1", "C7S1"]
    assert list(space.y("fine")) == ["C6S1M1P2X1", "C6S1M1P2X1", "C7S1M1P8X1"]
    with pytest.raises(ValueError, match="level"):
        space.y("finest")


def test_modalities_and_subsets():
    space = small_space()
    assert space.modality("image").columns == ("image.disp.color",)
    assert space.modality("other").X[:, 0].tolist()[1] == 5e-300
    with pytest.raises(FeatureSpaceError, match="unknown modality 'smell'"):
        space.modality("smell")
    with pytest.raises(FeatureSpaceError, match="no such feature column"):
        space.subset(["tactum.nope"])


def test_csv_round_trip_is_exact(tmp_path):
    space = small_space()
    space.to_csv(tmp_path / "f.csv")
    header = (tmp_path / "f.csv").read_text().splitlines()[0]
    assert header == "scan_id,sample_id,label,C,S,M,P,X,tactum.matx,image.disp.color,other.density"
    back = FeatureSpace.from_csv(tmp_path / "f.csv")
    np.testing.assert_array_equal(back.X, space.X)  # NaN == NaN here, and every bit of the floats
    assert (back.columns, back.scan_ids, back.label_text, back.groups) == (
        space.columns, space.scan_ids, space.label_text, space.groups)


def test_mat_round_trip_and_plain_scipy_reading(tmp_path):
    space = small_space()
    space.to_mat(tmp_path / "f.mat")
    raw = scipy.io.loadmat(tmp_path / "f.mat", simplify_cells=True)
    assert raw["X"].shape == (3, 3) and list(raw["columns"]) == list(space.columns)
    np.testing.assert_array_equal(raw["labels"], space.labels)
    back = FeatureSpace.from_mat(tmp_path / "f.mat")
    np.testing.assert_array_equal(back.X, space.X)
    assert back.label_text == space.label_text and back.groups == space.groups


def test_inconsistent_spaces_and_files_are_refused(tmp_path):
    with pytest.raises(FeatureSpaceError, match="2 column names for 3 feature columns"):
        FeatureSpace(np.zeros((1, 3)), ("a", "b"), ("s",), ("C1S1M1P1X1",), ("g",))
    with pytest.raises(FeatureSpaceError, match="inf"):
        FeatureSpace(np.array([[math.inf]]), ("a",), ("s",), ("C1S1M1P1X1",), ("g",))
    with pytest.raises(FeatureSpaceError, match="not unique"):
        FeatureSpace(np.zeros((1, 2)), ("a", "a"), ("s",), ("C1S1M1P1X1",), ("g",))
    small_space().to_csv(tmp_path / "f.csv")
    lines = (tmp_path / "f.csv").read_text().splitlines()
    (tmp_path / "short.csv").write_text("\n".join([lines[0], lines[1].rsplit(",", 1)[0]]) + "\n")
    with pytest.raises(FeatureSpaceError, match="short.csv: line 2: 10 fields, header has 11"):
        FeatureSpace.from_csv(tmp_path / "short.csv")
    (tmp_path / "word.csv").write_text("\n".join([lines[0], lines[1].replace("NaN", "many")]) + "\n")
    with pytest.raises(FeatureSpaceError, match="word.csv: line 2: could not convert string to float: 'many'"):
        FeatureSpace.from_csv(tmp_path / "word.csv")
    (tmp_path / "junk.mat").write_bytes(b"junk")
    with pytest.raises(FeatureSpaceError, match="junk.mat: not a readable"):
        FeatureSpace.from_mat(tmp_path / "junk.mat")
