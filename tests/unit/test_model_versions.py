"""Model versions of a database (taxonomy/learning/versions.py): kept, listed, made current, never overwritten."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from features import FeatureSpace
from taxonomy.learning.models import load_model, save_model, train_model
from taxonomy.learning.versions import (
    VersionError,
    add_version,
    current_version,
    find_version,
    is_version,
    training_fingerprint,
    use_version,
    version_file,
    versions,
)


@pytest.fixture(scope="module")
def model():
    """A random forest on density alone: granite (2.6-2.8 g/cm^3) against oak (0.6-0.8 g/cm^3)."""
    density = np.concatenate([np.linspace(2.6, 2.8, 6), np.linspace(0.6, 0.8, 6)])
    space = FeatureSpace(X=density[:, None], columns=("other.density",), scan_ids=[f"s-{i}" for i in range(12)],
                         label_text=["C6S1M1P2X1"] * 6 + ["C1S1M1P4X1"] * 6, groups=[f"g-{i}" for i in range(12)])
    return train_model(space, "fine", 1, "rf")


def test_each_training_is_a_new_version_and_the_newest_is_current(tmp_path, model):
    assert versions(tmp_path) == [] and current_version(tmp_path) is None
    first = add_version(tmp_path, model, fingerprint="f" * 64, feature_code_version="abc",
                        figures={"cv_accuracy": 0.95, "broken": float("nan")}, note="test")
    data = version_file(tmp_path, first).read_bytes()
    second = add_version(tmp_path, model, fingerprint="f" * 64, feature_code_version="abc")
    assert (first.version, first.file) == (1, "v001-rf-fine-X1.skops")
    assert (second.version, second.file) == (2, "v002-rf-fine-X1.skops")
    assert version_file(tmp_path, first).read_bytes() == data  # the first kept as it was
    assert [v.version for v in versions(tmp_path)] == [1, 2] and current_version(tmp_path).version == 2
    assert first.classes == ("C1S1M1P4X1", "C6S1M1P2X1") and first.rows == 12
    # Two classes leave no class to hold out: the rule's inner AUROC is NaN, and NaN figures are left out.
    assert math.isnan(model.rejection.inner_auroc) and first.figures == {"cv_accuracy": 0.95}
    assert versions(tmp_path)[0] == first  # read back as written
    assert first.figures_text().startswith("CV accuracy 95.0 %")
    assert load_model(version_file(tmp_path, second)).classes == model.classes

    kept = add_version(tmp_path, model, fingerprint="e" * 64, feature_code_version="abc", make_current=False)
    assert kept.version == 3 and current_version(tmp_path).version == 2
    assert use_version(tmp_path, "v1").version == 1 and current_version(tmp_path).version == 1
    assert json.loads((tmp_path / "models/versions.json").read_text())["current"] == 1


def test_versions_are_named_by_number_and_refused_when_missing(tmp_path, model):
    add_version(tmp_path, model, fingerprint="", feature_code_version="")
    assert find_version(tmp_path, "v001").version == find_version(tmp_path, 1).version == 1
    with pytest.raises(VersionError, match=r"no model version 7 \(versions: v1\)"):
        find_version(tmp_path, "7")
    with pytest.raises(VersionError, match="is not a model version"):
        use_version(tmp_path, "latest")
    version_file(tmp_path, find_version(tmp_path, 1)).unlink()
    with pytest.raises(VersionError, match="the file of version 1 is missing"):
        find_version(tmp_path, 1)
    assert is_version("3") and is_version("v12") and not is_version("model.skops")
    (tmp_path / "7").write_text("")
    assert not is_version(tmp_path / "7")  # an existing file of that name is a file


def test_a_file_nobody_indexed_is_never_overwritten(tmp_path, model):
    (tmp_path / "models").mkdir()
    (tmp_path / "models/v001-rf-fine-X1.skops").write_bytes(b"someone's file")
    with pytest.raises(VersionError, match="exists but is not in"):
        add_version(tmp_path, model, fingerprint="", feature_code_version="")
    assert (tmp_path / "models/v001-rf-fine-X1.skops").read_bytes() == b"someone's file"
    assert not (tmp_path / "models/versions.json").exists()


def test_a_model_from_before_versions_is_version_zero_until_another_is_current(tmp_path, model):
    save_model(model, tmp_path / "models" / "rf-fine-X10.skops")
    assert [(v.version, v.file) for v in versions(tmp_path)] == [(0, "rf-fine-X10.skops")]
    assert current_version(tmp_path).version == 0
    add_version(tmp_path, model, fingerprint="", feature_code_version="")
    assert current_version(tmp_path).version == 1
    assert use_version(tmp_path, 0).version == 0 and current_version(tmp_path).file == "rf-fine-X10.skops"


@pytest.mark.parametrize(("text", "match"), [
    ("{", "not valid JSON"), ('{"versions": 3}', "not a model index"),
    ('{"versions": [{"version": 1}]}', "a version entry cannot be read"),
    ('{"versions": [' + json.dumps({"version": 1, "file": "../../etc/passwd", "created": "", "classifier": "rf",
                                    "level": "fine", "n_features": 1, "classes": [], "rows": 0, "fingerprint": "",
                                    "feature_code_version": ""}) + "]}", "names no model file"),
])
def test_a_damaged_index_is_one_line_naming_it(tmp_path, text, match):
    (tmp_path / "models").mkdir()
    (tmp_path / "models/versions.json").write_text(text)
    with pytest.raises(VersionError, match=match) as caught:
        versions(tmp_path)
    assert "\n" not in str(caught.value) and "versions.json" in str(caught.value)


def test_the_training_fingerprint_covers_the_scans_and_the_feature_code():
    rows = [("a-001", "1" * 64), ("b-001", "2" * 64)]
    assert training_fingerprint(rows, "v1") == training_fingerprint(rows[::-1], "v1")  # order does not matter
    assert training_fingerprint(rows, "v1") != training_fingerprint(rows, "v2")
    assert training_fingerprint(rows, "v1") != training_fingerprint([rows[0], ("b-001", "3" * 64)], "v1")
    assert training_fingerprint(rows, "v1") != training_fingerprint(rows[:1], "v1")


@pytest.mark.parametrize("entry", [
    {"file": 5}, {"version": "x"}, {"version": True}, {"rows": -1}, {"figures": {"cv_accuracy": float("nan")}},
    {"file": "..\\\\evil.skops"}])
def test_an_index_entry_of_the_wrong_type_is_refused_and_nothing_is_added(tmp_path, model, entry):
    add_version(tmp_path, model, fingerprint="", feature_code_version="")
    index = json.loads((tmp_path / "models/versions.json").read_text())
    index["versions"][0].update(entry)
    (tmp_path / "models/versions.json").write_text(json.dumps(index))
    before = sorted(p.name for p in (tmp_path / "models").iterdir())
    with pytest.raises(VersionError, match="versions.json: version entry|versions.json: a version entry"):
        add_version(tmp_path, model, fingerprint="", feature_code_version="")
    assert sorted(p.name for p in (tmp_path / "models").iterdir()) == before  # no model file without its row
