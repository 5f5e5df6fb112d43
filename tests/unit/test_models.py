"""Trained models: skops round trip, refusal of foreign or damaged files, top-k prediction of one scan."""

from __future__ import annotations

import os
import sys
import types
import warnings
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import sklearn.utils
import skops.io
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import FunctionTransformer, MinMaxScaler

from features.selection import FQSelector
from features.space import FeatureSpace
from taxonomy.learning import models
from taxonomy.learning.evaluation import CLASSIFIERS
from taxonomy.learning.models import (
    MODEL_FORMAT,
    NO_PROBABILITIES,
    ModelError,
    TrainedModel,
    load_model,
    predict_top,
    save_model,
    train_model,
)

MATERIALS = ("C6S1M1P2X1", "C7S1M1P1X1", "C1S1M1P1X1", "C3S4M2P1X1")


def separated_space(scans: int = 6, seed: int = 0) -> FeatureSpace:
    """Four shipped materials; other.density and other.metal separate them, the rest is noise."""
    rng = np.random.default_rng(seed)
    material = np.repeat(np.arange(len(MATERIALS)), scans)
    X = rng.standard_normal((material.size, 6))
    X[:, 0] += material * 5.0
    X[:, 1] += (material % 2) * 4.0
    columns = ("other.density", "other.metal", "tactum.matx", "image.disp.color", "audio.tool.zcr",
               "other.vib_std")
    return FeatureSpace(X, columns, tuple(f"scan{i}" for i in range(material.size)),
                        tuple(MATERIALS[m] for m in material),
                        tuple(f"sample{m}-{i % 2}" for i, m in enumerate(material)))


@pytest.fixture(scope="module")
def space() -> FeatureSpace:
    return separated_space()


@pytest.fixture(scope="module")
def model(space) -> TrainedModel:
    return train_model(space, level="fine", n_features=2, classifier="lda")


def payload_of(model: TrainedModel) -> dict:
    """What save_model writes, to build tampered files from."""
    return {
        "format": MODEL_FORMAT, "format_version": 1, "pipeline": model.pipeline,
        "feature_names": list(model.feature_names), "level": model.level, "classifier": model.classifier,
        "n_features": model.n_features, "selected": list(model.selected), "classes": list(model.classes),
        "seed": model.seed, "software_version": model.software_version,
        "sklearn_version": model.sklearn_version, "dropped": list(model.dropped), "n_rows": model.n_rows,
    }


def test_training_keeps_the_metadata(space, model):
    assert model.feature_names == space.columns
    assert model.level == "fine" and model.classifier == "lda" and model.n_rows == len(space)
    assert model.selected == ("other.density", "other.metal")
    assert model.classes == tuple(sorted(MATERIALS))
    assert "lda at level fine, 4 classes" in model.describe()


@pytest.mark.parametrize("classifier", [c for c in CLASSIFIERS if c not in NO_PROBABILITIES])
def test_save_and_load_give_identical_predictions(space, tmp_path, classifier):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trained = train_model(space, level="medium", n_features=3, classifier=classifier)
    path = save_model(trained, tmp_path / "model.skops")
    loaded = load_model(path)
    expected = trained.pipeline.predict_proba(space.X)
    np.testing.assert_array_equal(loaded.pipeline.predict_proba(space.X), expected)
    for name in ("feature_names", "level", "classifier", "n_features", "selected", "classes", "seed",
                 "software_version", "sklearn_version", "dropped", "n_rows"):
        assert getattr(loaded, name) == getattr(trained, name)
    assert [p.name for p in tmp_path.iterdir()] == ["model.skops"]


def test_a_fused_sets_model_is_saved_and_loaded(space, tmp_path):
    """A model of a fused feature set (the paper's columns and a modern family's, each family's n best) loads
    as it was trained: its selector chooses family by family."""
    rng = np.random.default_rng(5)
    modern = tuple(f"catch22.v_ts.c{k:02d}" for k in range(6))
    fused = FeatureSpace(np.c_[space.X, rng.normal(size=(len(space), len(modern)))], (*space.columns, *modern),
                         space.scan_ids, space.label_text, space.groups)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        trained = train_model(fused, level="medium", n_features=2, feature_set="paper+catch22")
    assert type(trained.pipeline.named_steps["select"]).__name__ == "PartwiseFQSelector"
    loaded = load_model(save_model(trained, tmp_path / "fused.skops"))
    np.testing.assert_array_equal(loaded.pipeline.predict_proba(fused.X), trained.pipeline.predict_proba(fused.X))
    assert loaded.selected == trained.selected and any(name.startswith("catch22.") for name in loaded.selected)


def test_a_classifier_without_probabilities_is_not_trained_into_a_model(space):
    with pytest.raises(ModelError, match="ridge gives no class probabilities"):
        train_model(space, level="medium", n_features=3, classifier="ridge")


def test_saving_over_an_existing_model_replaces_it(space, model, tmp_path):
    path = tmp_path / "model.skops"
    path.write_bytes(b"old")
    save_model(model, path)
    assert load_model(path).selected == model.selected


def write_payload(path: Path, payload: dict) -> Path:
    path.write_bytes(skops.io.dumps(payload))
    return path


def test_a_file_with_foreign_code_is_refused_before_loading(model, tmp_path):
    hostile = Pipeline([("scale", MinMaxScaler()), ("select", FQSelector()),
                        ("classify", FunctionTransformer(func=os.system))])
    path = write_payload(tmp_path / "evil.skops", {**payload_of(model), "pipeline": hostile})
    with pytest.raises(ModelError, match=r"evil\.skops: refused, .*system"):
        load_model(path)


@pytest.mark.parametrize(("change", "message"), [
    ({"format": "other-tool"}, "not a texplorer model"),
    ({"format_version": 7}, "format version 7"),
    ({"level": "finest"}, "unknown level"),
    ({"selected": ["other.metal", "other.density"]}, "selected feature names do not match"),
    ({"classes": ["C1S1M1P1X1"]}, "class list does not match"),
    ({"feature_names": ["a", "b"]}, "2 distinct feature names for a pipeline of 6 inputs"),
    ({"n_rows": "many"}, "'n_rows' must be int"),
    ({"extra": 1}, "wrong model metadata fields: extra"),
])
def test_wrong_metadata_is_refused(model, tmp_path, change, message):
    path = write_payload(tmp_path / "meta.skops", {**payload_of(model), **change})
    with pytest.raises(ModelError, match=message):
        load_model(path)


def test_a_foreign_estimator_is_refused(model, space, tmp_path):
    foreign = Pipeline([("classify", LogisticRegression().fit(space.X, space.y("fine")))])
    path = write_payload(tmp_path / "lr.skops", {**payload_of(model), "pipeline": foreign})
    with pytest.raises(ModelError, match="not a scale -> select -> classify pipeline"):
        load_model(path)
    swapped = Pipeline([("scale", MinMaxScaler()), ("select", FQSelector()),
                        ("classify", LogisticRegression())])
    path = write_payload(tmp_path / "lr2.skops", {**payload_of(model), "pipeline": swapped})
    with pytest.raises(ModelError, match="MinMaxScaler -> FQSelector -> LogisticRegression"):
        load_model(path)


def test_damaged_and_foreign_files_are_refused_with_one_line(model, tmp_path):
    good = save_model(model, tmp_path / "good.skops").read_bytes()
    cases = {
        "text.skops": b"this is not a model\n",
        "half.skops": good[: len(good) // 2],
        "flipped.skops": good[:200] + bytes([good[200] ^ 0xFF]) + good[201:],
    }
    for name, data in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(ModelError) as caught:
            load_model(path)
        assert str(caught.value).startswith(f"{path}: ") and "\n" not in str(caught.value)
    with pytest.raises(ModelError, match="cannot read"):
        load_model(tmp_path / "missing.skops")


def test_a_model_the_loader_would_refuse_is_not_written(model, space, tmp_path):
    regression = LogisticRegression().fit(space.X, space.y("fine"))
    foreign = replace(model, pipeline=Pipeline([("classify", regression)]))
    with pytest.raises(ModelError):
        save_model(foreign, tmp_path / "no.skops")
    assert not any(tmp_path.iterdir())


# -- prediction --------------------------------------------------------------------------------------


def test_predict_top_ranks_the_classes_by_probability(space, model):
    values = dict(zip(space.columns, space.X[0], strict=True))
    top = predict_top(model, values, k=3)
    probability = model.pipeline.predict_proba(space.X[:1])[0]
    expected = sorted(zip(model.pipeline.classes_, probability, strict=True), key=lambda pair: -pair[1])[:3]
    assert [label for label, _ in top] == [label for label, _ in expected]
    assert [p for _, p in top] == pytest.approx([p for _, p in expected])
    assert top[0][0] == space.label_text[0]
    assert len(predict_top(model, values, k=10)) == 4


def test_nan_or_missing_selected_features_are_refused_by_name(space, model):
    values = dict(zip(space.columns, space.X[0], strict=True))
    with pytest.raises(ModelError, match="undefined .*: other.metal"):
        predict_top(model, {**values, "other.metal": float("nan")})
    with pytest.raises(ModelError, match="missing feature value.*: other.density"):
        predict_top(model, {k: v for k, v in values.items() if k != "other.density"})
    with pytest.raises(ModelError, match="k must be"):
        predict_top(model, values, k=0)


def test_unselected_features_may_be_undefined(space, model):
    values = dict(zip(space.columns, space.X[5], strict=True))
    holes = {**values, "tactum.matx": float("nan")}
    del holes["audio.tool.zcr"]
    assert predict_top(model, holes) == predict_top(model, values)



# -- fitted values checked on load: files from strangers -------------------------------------------------------

@pytest.fixture(scope="module")
def forest(space) -> TrainedModel:
    return train_model(space, level="fine", n_features=2, classifier="rf")


def tampered(model: TrainedModel, folder: Path, change) -> Path:
    """A genuine model file, loaded as skops loads it, changed by ``change(payload)`` and written back."""
    from taxonomy.learning.models import TRUSTED_TYPES

    genuine = save_model(model, folder / "genuine.skops")
    payload = skops.io.loads(genuine.read_bytes(), trusted=list(TRUSTED_TYPES))
    change(payload)
    path = folder / "tampered.skops"
    path.write_bytes(skops.io.dumps(payload, compression=zipfile.ZIP_DEFLATED))
    return path


def _first_tree(payload):
    return payload["pipeline"].steps[-1][1].estimator_.estimators_[0].tree_


def _wide_tree(payload):
    return payload["open_set"]["wide_forest"].estimators_[0].tree_


def _set(array, index, value):
    array[index] = value


@pytest.mark.parametrize(("change", "message"), [
    (lambda p: _set(_first_tree(p).children_left, 0, 2**40),
     r"tree 0: a child index points back, to itself or outside the \d+ nodes"),
    (lambda p: _set(_first_tree(p).children_left, 0, 0), "tree 0: a child index points back, to itself"),
    (lambda p: _set(_first_tree(p).feature, 0, 10**9), "tree 0 splits on feature 1000000000 of a model with 2"),
    (lambda p: _set(_first_tree(p).threshold, 0, np.nan), "tree 0's thresholds and leaf values must be finite"),
    (lambda p: setattr(p["pipeline"].steps[-1][1], "beta_", float("nan")),
     "the calibration temperature must be a positive number, got nan"),
    (lambda p: _set(p["pipeline"].named_steps["scale"].scale_, slice(None), np.nan),
     "the scaler's scale_ must hold 6 finite numbers"),
    (lambda p: p["open_set"].update(threshold=float("-inf")), r"the threshold a number or \+inf \(never reject\), "
                                                              r"got .* and -inf"),
    (lambda p: p["open_set"].update(threshold=float("nan")), r"the threshold a number or \+inf .* and nan"),
    (lambda p: _set(p["pipeline"].named_steps["select"].selected_, 0, 99), "selected_ must be distinct column"),
    (lambda p: p["open_set"].update(reference=np.zeros((3, 2))), "open-set field.* reference do not fit 6 inputs"),
    (lambda p: _set(p["open_set"]["reference"], (0, 0), np.nan), "open-set field.* reference must hold finite"),
    (lambda p: _set(p["open_set"]["term_sd"], 1, 0.0), "open-set field.* term_sd must hold finite"),
    (lambda p: _set(p["open_set"]["group_of"], 0, 50), "group or class indices outside their"),
    (lambda p: _set(p["open_set"]["reference_classes"], 0, -3), "group or class indices outside their"),
    (lambda p: p["open_set"].update(group_titles=[1]), "group titles must be text"),
    (lambda p: p["open_set"].pop("fill"), "the open_set field must hold"),
    (lambda p: p["open_set"].pop("wide_forest"), "the open_set field must hold .*wide_forest"),
    (lambda p: p["open_set"].update(wide_forest=p["pipeline"].named_steps["scale"]),
     "open_set field 'wide_forest' must be RandomForestClassifier or None"),
    (lambda p: p["open_set"].update(wide_forest=None),
     "the open-set forest over every feature is missing for a model of 6 grouped inputs"),
    (lambda p: _set(_wide_tree(p).children_left, 0, 2**40),
     r"the open-set forest's tree 0: a child index points back, to itself or outside the \d+ nodes"),
    (lambda p: _set(_wide_tree(p).feature, 0, 6), "the open-set forest's tree 0 splits on feature 6 of a model with 6"),
    (lambda p: p["open_set"]["wide_forest"].estimators_.__setitem__(0, MinMaxScaler()),
     "the open-set forest's tree 0 is not a fitted decision tree of 4 classes"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "n_features_in_", 3),
     r"the open-set forest's n_features_in_ must be whole numbers \(100 trees, 1 output, 4 classes, 6 inputs"),
    (lambda p: p["open_set"]["wide_forest"].estimators_.clear(),
     "the open-set forest must hold 1 to 10000 trees, not 0"),
    (lambda p: setattr(p["open_set"]["wide_forest"].estimators_[0], "tree_", MinMaxScaler()),
     "the open-set forest's tree 0 is not a fitted tree but a MinMaxScaler"),
    (lambda p: setattr(p["pipeline"].steps[-1][1].estimator_.estimators_[1], "tree_", MinMaxScaler()),
     "tree 1 is not a fitted tree but a MinMaxScaler"),
    (lambda p: p["pipeline"].steps[-1][1].estimator_.estimators_.__setitem__(2, MinMaxScaler()),
     "tree 2 is not a fitted decision tree of 4 classes and 2 inputs"),
    (lambda p: delattr(p["open_set"]["wide_forest"].estimators_[0], "tree_"),
     "the open-set forest's tree 0 is not a fitted tree but a NoneType"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "classes_", 5),
     "the open-set forest over every feature must be fitted on the model's 4 classes"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "n_classes_", np.array([4, 4])),
     "the open-set forest's n_classes_ must be whole numbers"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "n_classes_", 4.0),
     "the open-set forest's n_classes_ must be whole numbers"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "n_estimators", 0),
     "the open-set forest's n_estimators must be whole numbers"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "verbose", "x"), "the open-set forest's verbose must be"),
    (lambda p: setattr(p["open_set"]["wide_forest"], "n_jobs", 0), "the open-set forest's n_jobs must be"),
    (lambda p: setattr(p["open_set"]["wide_forest"].estimators_[0], "n_features_in_", 3),
     "the open-set forest's tree 0 is not a fitted decision tree of 4 classes and 6 inputs"),
    (lambda p: setattr(p["open_set"]["wide_forest"].estimators_[1], "n_classes_", 4.0),
     "the open-set forest's tree 1 is not a fitted decision tree"),
    (lambda p: setattr(p["pipeline"].steps[-1][1].estimator_, "n_jobs", 0), "the classifier's forest's n_jobs must"),
    (lambda p: setattr(p["pipeline"].steps[-1][1].estimator_, "estimators_", 3),
     "the classifier's forest must hold 1 to 10000 trees, not int"),
])
def test_a_model_with_parameters_prediction_cannot_use_is_refused_naming_the_part(forest, tmp_path, change,
                                                                                  message):
    path = tampered(forest, tmp_path, change)
    with pytest.raises(ModelError, match=message) as refused:
        load_model(path)
    assert str(refused.value).startswith(f"{path}: ") and "\n" not in str(refused.value)


def test_a_neighbour_model_with_an_index_outside_its_points_is_refused(space, tmp_path):
    knn = train_model(space, level="fine", n_features=2, classifier="knn")
    load_model(save_model(knn, tmp_path / "knn.skops"))  # genuine: loads

    def outside(payload):
        points = payload["pipeline"].steps[-1][1].estimator_
        points._fit_X[0, 0] = np.inf

    with pytest.raises(ModelError, match="neighbour"):
        load_model(tampered(knn, tmp_path, outside))


def test_a_small_file_that_would_unpack_to_more_than_the_limit_is_refused_before_loading(forest, tmp_path,
                                                                                         monkeypatch):
    from taxonomy.learning import models

    genuine = save_model(forest, tmp_path / "genuine.skops")
    load_model(genuine)
    # The rule at a size a test can hold: a zeros array of 8 MiB (a few kB compressed) against 4 MiB.
    monkeypatch.setattr(models, "MAX_MODEL_BYTES", 4 << 20)
    path = tampered(forest, tmp_path, lambda p: p.update(dropped=np.zeros(1 << 20)))
    assert path.stat().st_size < 1 << 20
    with pytest.raises(ModelError, match=r"refused, its arrays would take 1\d MiB once unpacked \(a model may take "
                                         r"at most 4 MiB\)"):
        load_model(path)


def test_an_open_set_rule_that_never_rejects_loads(forest, tmp_path):
    path = tampered(forest, tmp_path, lambda p: p["open_set"].update(threshold=float("inf")))
    assert load_model(path).rejection.threshold == float("inf")



def test_skops_sees_the_model_s_own_estimators_only_while_it_is_first_imported():
    crawl = sklearn.utils.all_estimators
    with models._estimators(models.SKLEARN_PARTS):
        listed = dict(sklearn.utils.all_estimators())
    assert sklearn.utils.all_estimators is crawl
    assert set(listed.values()) == set(models.SKLEARN_PARTS)
    assert {"RandomForestClassifier", "Pipeline", "MinMaxScaler", "DecisionTreeClassifier"} <= set(listed)


def test_the_module_index_names_the_first_module_holding_an_object_as_skops_search_does():
    held, other, unsearched = object(), object(), object()
    first, second, main = (types.ModuleType(name) for name in ("first", "second", "__main__"))
    main.unsearched = unsearched
    first.alias, second.held, second.other = held, held, other
    holders = models._first_holders({"__main__": main, "first": first, "second": second, "broken": None})
    assert (holders[id(held)], holders[id(other)]) == ("first", "second") and id(unsearched) not in holders
    searched = []

    def search(obj, name):
        searched.append(name)
        return "searched"

    with pytest.MonkeyPatch.context() as patch:
        for module in (first, second):
            patch.setitem(sys.modules, module.__name__, module)
        whichmodule = models._indexed(search)
        # "first" holds `held` before "second" does, but as `alias`: skops' search answers for the name `held`
        assert whichmodule(held, "held") == "searched" and searched == ["held"]
        assert whichmodule(other, "other") == "second" and searched == ["held"]
        assert whichmodule(models.save_model, "anything") == "taxonomy.learning.models"  # its own __module__
        assert whichmodule(object(), "loose") == "searched"


def test_a_package_runs_with_the_indexed_search_and_gets_its_own_back(tmp_path, monkeypatch):
    # The stand-in must answer while the package runs (skops computes its trusted names then) and be undone after;
    # a package without the function imports as it is.
    package = tmp_path / "toylib"
    package.mkdir()
    (package / "_utils.py").write_text("def whichmodule(obj, name):\n    return 'searched'\n")
    (package / "__init__.py").write_text(
        "from toylib import _utils\nimport math\n"
        "HOME = _utils.whichmodule(math.floor, 'floor')\nSTAND_IN = _utils.whichmodule.__name__\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("toylib", "toylib._utils"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    toylib = models._import_with_module_index("toylib", "_utils", "whichmodule")
    assert toylib is sys.modules["toylib"] and toylib.STAND_IN == "whichmodule"  # the index's closure ran
    assert toylib.HOME == "math"  # the first loaded module holding math.floor, not the package's own 'searched'
    assert toylib._utils.whichmodule(None, "x") == "searched"  # restored once the package ran
    assert models._import_with_module_index("json", "_utils", "whichmodule") is sys.modules["json"]  # imported
    plain = tmp_path / "plainlib"
    plain.mkdir()
    (plain / "__init__.py").write_text("VALUE = 7\n")
    monkeypatch.delitem(sys.modules, "plainlib", raising=False)
    assert models._import_with_module_index("plainlib", "_utils", "whichmodule").VALUE == 7  # no helper module
