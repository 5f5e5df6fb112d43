"""Cross-validation, metrics and reports of ``taxonomy.learning.evaluation`` on small synthetic feature spaces."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import StratifiedKFold
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import MinMaxScaler

from features.selection import FQSelector
from features.space import FeatureSpace, FeatureSpaceError
from taxonomy.learning import evaluation
from taxonomy.learning.evaluation import (
    MLP_MAX_ITER,
    EvaluationError,
    cv_splits,
    evaluate,
    evaluate_grid,
    make_pipeline,
    with_values,
)
from taxonomy.learning.results import major_class, one_line, r_c
from taxonomy.reports.report import cell_text, convergence_note, format_table

MODALITIES = ("tactum", "image", "audio", "other")


def labelled_space(materials: int = 8, samples: int = 2, scans: int = 3, features: int = 12,
                   seed: int = 0) -> FeatureSpace:
    """Materials C1..C4 x S1..S2; half the columns shift per material, the rest are noise.

    Column 0 holds the row index, so a spy can tell which rows it was given.
    """
    rng = np.random.default_rng(seed)
    material = np.repeat(np.arange(materials), samples * scans)
    sample = np.tile(np.repeat(np.arange(samples), scans), materials)
    centres = rng.standard_normal((materials, features)) * 3 * (np.arange(features) % 2 == 0)
    X = centres[material] + rng.standard_normal((material.size, features))
    X[:, 0] = np.arange(material.size)
    columns = tuple(f"{MODALITIES[j % 4]}.f{j:02d}" for j in range(features))
    labels = tuple(f"C{m % 4 + 1}S{m // 4 % 2 + 1}M{m // 8 + 1}P1X1" for m in material)
    groups = tuple(f"m{m}-sample{s}" for m, s in zip(material, sample, strict=True))
    return FeatureSpace(X, columns, tuple(f"scan{i}" for i in range(material.size)), labels, groups)


# -- r_C ---------------------------------------------------------------------------------------------


def test_r_c_counts_misclassifications_across_major_classes():
    classes = ["C1S1M1P1X1", "C1S1M2P1X1", "C2S1M1P1X1"]
    confusion = np.array([[5, 2, 1],
                          [0, 4, 3],
                          [1, 0, 6]])
    # errors: 2 + 1 + 3 + 1 = 7; of them C1 -> C2: 1 + 3, C2 -> C1: 1
    assert r_c(confusion, classes) == pytest.approx(5 / 7)


def test_r_c_is_undefined_without_errors_and_at_the_coarse_level():
    assert np.isnan(r_c(np.diag([3, 4]), ["C1S1", "C2S1"]))
    # At the coarse level every error changes the major class by definition: 1 whatever happens, so NaN.
    assert np.isnan(r_c(np.array([[3, 1], [2, 4]]), ["C1", "C2"]))
    assert r_c(np.array([[3, 1], [2, 4]]), ["C1S1", "C1S2"]) == 0.0
    assert r_c(np.array([[3, 1], [2, 4]]), ["C1S1", "C2S1"]) == 1.0


def test_r_c_refuses_a_mismatched_confusion_and_codes_without_a_major_class():
    with pytest.raises(EvaluationError, match="shape"):
        r_c(np.zeros((2, 3)), ["C1", "C2"])
    with pytest.raises(EvaluationError, match="major class"):
        major_class("S1M1")
    assert major_class("C12S3M1P2X1") == "C12"


# -- splits ------------------------------------------------------------------------------------------


def test_grouped_splits_keep_every_sample_in_one_fold_and_test_every_row_once():
    space = labelled_space(samples=3, scans=2)
    y = space.y("fine")
    splits, grouped = cv_splits(y, space.groups, folds=3, seed=1)
    assert grouped
    tested = np.concatenate([test for _, test in splits])
    assert sorted(tested) == list(range(len(y)))
    groups = np.asarray(space.groups)
    for train, test in splits:
        assert not set(groups[train]) & set(groups[test])


def test_singleton_groups_are_plain_stratified_folds():
    y = np.repeat(["C1S1M1P1X1", "C2S1M1P1X1"], 5)
    splits, grouped = cv_splits(y, [f"s{i}" for i in range(10)], folds=5, seed=3)
    expected = StratifiedKFold(5, shuffle=True, random_state=3).split(np.zeros(10), y)
    assert grouped  # each group one row: no group can be in training and test at once
    for (train, test), (train_ref, test_ref) in zip(splits, expected, strict=True):
        np.testing.assert_array_equal(test, test_ref)
        np.testing.assert_array_equal(train, train_ref)


def test_every_class_with_a_single_sample_falls_back_to_ungrouped_folds_with_a_warning():
    space = labelled_space(samples=1, scans=5)
    with pytest.warns(UserWarning, match="every one of the 8 classes has a single sample"):
        splits, grouped = cv_splits(space.y("fine"), space.groups, folds=5)
    assert not grouped and len(splits) == 5


@pytest.mark.parametrize("folds", [1, 2.0, True])
def test_bad_fold_counts_are_refused(folds):
    with pytest.raises(EvaluationError, match="folds"):
        cv_splits(["a", "b"] * 3, ["g"] * 6, folds=folds)


# -- classifiers -------------------------------------------------------------------------------------


def test_the_balanced_forest_draws_every_class_equally_often():
    """Each tree's bootstrap draws n rows, row i with probability 1 / (k n_c(i)): every class 1 / k of them.
    16 rows of ``a``, 8 of ``b``: the forest draws ``b`` a third of the time, the balanced forest half. The
    mean share over 100 trees of 24 draws has the standard deviation sqrt(p (1 - p) / 2400) (binomial);
    the test allows four of them."""
    x, y = np.arange(24.0)[:, None], np.repeat(["a", "b"], [16, 8])
    forests = evaluation.classifier_estimators(seed=0)
    for name, share in (("rf", 1 / 3), ("brf", 1 / 2)):
        forest = forests[name].fit(x, y)
        drawn = np.mean([np.mean(y[rows] == "b") for rows in forest.estimators_samples_])
        assert abs(drawn - share) < 4 * np.sqrt(share * (1 - share) / 2400), (name, drawn)


def test_the_balanced_forest_gives_a_small_class_its_share_of_doubtful_rows():
    """At x = 1 six rows of ``a`` and four of ``b`` cannot be split apart. The forest's bootstraps draw
    there 6 / 24 x 24 = 6 ``a`` and 4 ``b`` on average: 0.6 ``a``; the balanced forest's draw a row of ``a``
    with probability 1 / 32 and one of ``b`` with 1 / 16: 6 x 24 / 32 = 4.5 ``a`` against 4 x 24 / 16 = 6 ``b``,
    0.43 ``a``. Elsewhere the classes are apart (10 ``a`` at 0, 4 ``b`` at 2) and both forests agree."""
    x = np.repeat([0.0, 1.0, 1.0, 2.0], [10, 6, 4, 4])[:, None]
    y = np.repeat(["a", "a", "b", "b"], [10, 6, 4, 4])
    forests = evaluation.classifier_estimators(seed=0)
    plain, balanced = forests["rf"].fit(x, y), forests["brf"].fit(x, y)
    assert plain.predict([[0.0], [1.0], [2.0]]).tolist() == ["a", "a", "b"]
    assert balanced.predict([[0.0], [1.0], [2.0]]).tolist() == ["a", "b", "b"]


# -- evaluate ----------------------------------------------------------------------------------------


class RowSpy(TransformerMixin, BaseEstimator):
    """Passes X through and records the row ids (column 0) it is fitted on and asked to transform."""

    log: list[tuple[str, list[int]]] = []

    def fit(self, X, y=None):
        RowSpy.log.append(("fit", X[:, 0].astype(int).tolist()))
        return self

    def transform(self, X):
        RowSpy.log.append(("transform", X[:, 0].astype(int).tolist()))
        return X


@pytest.fixture
def spied(monkeypatch):
    original = evaluation.make_pipeline

    def with_spy(classifier, n_features, seed, kernels=None, columns=()):
        return Pipeline([("spy", RowSpy()), *original(classifier, n_features, seed, kernels, columns).steps])

    monkeypatch.setattr(evaluation, "make_pipeline", with_spy)
    RowSpy.log = []
    return RowSpy.log


def test_nested_protocol_fits_scaler_and_selector_on_training_rows_only(spied):
    space = labelled_space()
    report = evaluate(space, "lda", level="medium", n_features=3, folds=4, seed=0, protocol="nested")
    starts = [i for i, (kind, _) in enumerate(spied) if kind == "fit"]
    assert len(starts) == 4
    for fold, (start, end) in enumerate(zip(starts, [*starts[1:], len(spied)], strict=True)):
        fitted = spied[start][1]
        test_rows = np.flatnonzero(report.fold == fold).tolist()
        assert sorted(fitted) == np.flatnonzero(report.fold != fold).tolist()
        predicted = [rows for _, rows in spied[start + 1:end] if rows != fitted]
        assert [sorted(rows) for rows in predicted] == [test_rows]
        assert set(fitted).isdisjoint(test_rows)


def test_paper_protocol_selects_once_on_all_rows(spied):
    space = labelled_space()
    report = evaluate(space, "lda", level="medium", n_features=3, folds=4, protocol="paper")
    fits = [rows for kind, rows in spied if kind == "fit"]
    assert fits == [list(range(len(space)))]
    scaled = MinMaxScaler().fit_transform(space.X)
    selector = FQSelector(n_features=3).fit(scaled, space.y("medium"))
    expected = tuple(space.columns[i] for i in selector.selected_)
    assert report.selected == (expected,) * 4


def test_selected_features_are_named_per_fold_in_acceptance_order():
    space = labelled_space()
    report = evaluate(space, "nb", level="fine", n_features=2, folds=3)
    assert len(report.selected) == 3
    for fold, names in enumerate(report.selected):
        train = report.fold != fold
        scaled = MinMaxScaler().fit_transform(space.X[train])
        selector = FQSelector(n_features=2).fit(scaled, space.y("fine")[train])
        assert names == tuple(space.columns[i] for i in selector.selected_)


def test_nan_columns_are_dropped_and_listed():
    space = labelled_space()
    X = space.X.copy()
    X[3, 5] = np.nan
    holed = FeatureSpace(X, space.columns, space.scan_ids, space.label_text, space.groups)
    report = evaluate(holed, "nb", level="coarse", n_features=3, folds=3)
    assert report.dropped == (space.columns[5],)
    assert space.columns[5] not in report.columns and len(report.columns) == len(space.columns) - 1


def test_feature_sets_pick_columns():
    space = labelled_space()
    by_modality = evaluate(space, "nb", level="coarse", n_features=2, folds=3, feature_set="image")
    assert by_modality.feature_set == "image"
    assert all(c.startswith("image.") for c in by_modality.columns)
    listed = evaluate(space, "nb", level="coarse", n_features=2, folds=3,
                      feature_set=["other.f03", "tactum.f04"])
    assert listed.columns == ("other.f03", "tactum.f04") and listed.feature_set == "2 columns"


def test_fallback_to_ungrouped_folds_is_reported():
    report = evaluate(labelled_space(samples=1, scans=5), "nb", level="fine", n_features=3)
    assert not report.grouped
    assert any("single sample" in note for note in report.notes)


def test_warnings_name_their_classifier_and_are_whole_on_one_line():
    from sklearn.neural_network import MLPClassifier

    report = evaluate(labelled_space(), MLPClassifier(max_iter=2, random_state=0), level="fine", n_features=3)
    (warning,) = [w for w in report.notes if "ConvergenceWarning" in w]
    assert warning.startswith("MLPClassifier: ConvergenceWarning: Stochastic Optimizer: Maximum iterations (2)")
    assert warning.endswith("the optimization hasn't converged yet.") and "\n" not in warning
    assert one_line("a\nb:\n  c\n\nadvice.") == "a b: c advice."
    assert report.unconverged == (0, 0)  # other settings than the paper's: a warning as any other


def test_the_paper_mlp_stopping_at_its_iterations_is_counted_not_warned():
    # 16 materials: the paper's MLP (L-BFGS, 200 iterations) stops before converging in some folds.
    space = labelled_space(materials=16)
    y = space.y("fine")
    report = evaluate(space, "mlp", level="fine", n_features=3, folds=3, calibrate=False)
    splits, _ = cv_splits(y, space.groups, folds=3, grouping_labels=space.label_text)
    stopped = 0
    for train, _ in splits:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)  # counted here by the iterations it ran
            fitted = make_pipeline("mlp", 3).fit(space.X[train], y[train])  # the fold's fit, repeated
        stopped += fitted[-1].n_iter_ == MLP_MAX_ITER
    assert stopped > 0 and report.unconverged == (stopped, len(splits))
    assert not any("ConvergenceWarning" in note for note in report.notes)
    note = f"note: {convergence_note([report])}"
    assert note == (f"note: The MLP stopped at the paper's 200 L-BFGS iterations before converging in {stopped} of "
                    f"{len(splits)} fits, as the paper's setting implies; scikit-learn's ConvergenceWarning about "
                    "it, which suggests scaling the data, is not repeated per fit: the pipeline scales every "
                    "feature to [0, 1] already.")
    assert format_table([report]).splitlines().count(note) == 1
    assert convergence_note([evaluate(space, "nb", level="fine", n_features=3, folds=3)]) == ""


@pytest.mark.parametrize(("kwargs", "error", "message"), [
    ({"protocol": "leaky"}, EvaluationError, "protocol"),
    ({"classifier": "tree"}, EvaluationError, "unknown classifier"),
    ({"level": "finest"}, ValueError, "level"),
    ({"feature_set": "smell"}, FeatureSpaceError, "modality"),
])
def test_bad_arguments_are_named(kwargs, error, message):
    with pytest.raises(error, match=message):
        evaluate(labelled_space(), **kwargs)


def test_report_serialises_and_summarises():
    report = evaluate(labelled_space(), "knn", level="coarse", n_features=3, folds=3)
    data = json.loads(json.dumps(report.to_dict(), allow_nan=False))  # strict JSON: no NaN left in
    assert data["accuracy"] == report.accuracy.tolist() and data["classifier"] == "knn"
    assert data["method"] == "texplorer" and data["splitting"] == report.splitting and data["folds"] == 3
    assert data["r_c"] is None and data["feature_seconds"] is None  # undefined at the coarse level; not timed
    assert data["confusion"] == report.confusion.tolist() and len(data["selected"]) == 3
    assert data["n_samples"] == len(report.y_true) and data["notes"] == list(report.notes)
    line = report.summary()
    assert line.startswith("knn coarse X3 all (nested): accuracy ") and "r_C" in line


# -- reports -----------------------------------------------------------------------------------------


def test_text_table_shows_the_report_numbers():
    space = labelled_space()
    reports = evaluate_grid(space, classifiers=("nb",), levels=("coarse", "fine"), set_sizes=(2,),
                            feature_sets={"all": None}, folds=3, workers=1)
    text = format_table(reports)
    header, row, chance = text.splitlines()[4:7]
    assert header.split()[3:] == ["coarse", "fine"]
    coarse, fine = reports
    assert row.split()[:2] == ["nb", "all"]
    low, high = coarse.accuracy_ci
    assert (f"{100 * coarse.accuracy_pooled:.1f} {100 * low:.1f}-{100 * high:.1f} {coarse.f1_pooled:.2f} "
            f"{coarse.f1_mean:.2f}") in " ".join(row.split())
    assert cell_text(fine).split()[-1] == ("-" if np.isnan(fine.r_c) else f"{fine.r_c:.2f}")
    assert np.isnan(coarse.r_c) and row.split()[6] == "-"  # undefined at the coarse level, not "1.00"
    # Chance in the table: four classes at the coarse level, eight at the fine, every class 6 of 48 scans.
    assert chance.split()[:2] == ["chance", "25.0"] and "12.5 %, F1 0.12" in chance
    derived = text.splitlines()[-1].split()
    assert derived[:3] == ["nb", "all", "coarse"] and float(derived[3]) == pytest.approx(
        100 * fine.derived_accuracy("coarse"), abs=0.05)
    assert "nan" not in text.lower()


def test_a_grid_calibrates_only_the_cells_it_names_and_predicts_the_same():
    space = labelled_space()
    grid = {"classifiers": ("nb",), "levels": ("coarse", "fine"), "set_sizes": (2,), "feature_sets": {"all": None},
            "folds": 3, "workers": 1}
    some = evaluate_grid(space, calibrate={("fine", "all", 2)}, **grid)
    every = evaluate_grid(space, calibrate=True, **grid)
    assert [r.level for r in some] == ["coarse", "fine"]
    assert some[0].probability is None and some[1].probability is not None
    np.testing.assert_array_equal(some[1].probability, every[1].probability)
    for mine, theirs in zip(some, every, strict=True):
        np.testing.assert_array_equal(mine.y_pred, theirs.y_pred)


def test_a_grid_evaluates_only_the_level_and_size_pairs_it_is_given():
    # As the demo's default (the paper's Figs. 16 and 17, coarse X10 and fine X10): only the pairs given.
    space = labelled_space()
    grid = {"classifiers": ("nb",), "levels": ("coarse", "fine"), "set_sizes": (1, 2), "feature_sets": {"all": None},
            "folds": 3, "workers": 1, "calibrate": False}
    some = evaluate_grid(space, pairs={("coarse", 2), ("fine", 2), ("fine", 1)}, **grid)
    every = evaluate_grid(space, **grid)
    assert sorted((r.level, r.n_features) for r in some) == [("coarse", 2), ("fine", 1), ("fine", 2)]
    for mine in some:  # the same folds and predictions as in the full grid
        [theirs] = [r for r in every if (r.level, r.n_features) == (mine.level, mine.n_features)]
        np.testing.assert_array_equal(mine.y_pred, theirs.y_pred)
    text = format_table(some)
    assert "X1, nested protocol" in text and "X2, nested protocol" in text
    with pytest.raises(EvaluationError, match=r"no \(level, set size\) pair of \[\('medium', 10\)\]"):
        evaluate_grid(space, pairs={("medium", 10)}, **grid)


def test_figure_labels_name_each_class_and_keep_its_code():
    from taxonomy.reports.plots import class_labels

    assert class_labels(["C6S1M1P2X1", "C6S1", "C6", "C99S1M1P1X1", "c3"]) \
        == ["granite, polished (C6S1M1P2X1)", "igneous stone (C6S1)", "stone (C6)", "C99S1M1P1X1", "c3"]
    short = class_labels(["C1S1M1P4X2"], width=14)[0]
    assert short == "oak, planed … (C1S1M1P4X2)"


def test_levels_of_one_space_share_the_split_policy():
    from taxonomy.learning.evaluation import cv_splits

    fine = np.repeat(["C1S1M1P1X1", "C1S1M2P1X1", "C2S1M1P1X1", "C2S1M2P1X1"], 5)
    coarse = np.array([label[:2] for label in fine])
    groups = np.repeat(["s1", "s2", "s3", "s4"], 5)  # one sample per material, scanned five times
    with pytest.warns(UserWarning, match="single sample"):
        _, grouped = cv_splits(coarse, groups, folds=2, seed=0, grouping_labels=fine)
    assert not grouped
    _, grouped_alone = cv_splits(coarse, groups, folds=2, seed=0)
    assert grouped_alone  # each major class has two samples: on its own the coarse level could be grouped


def _two_materials(X: np.ndarray) -> FeatureSpace:
    n = X.shape[0]
    return FeatureSpace(X, ("other.density", "other.metal", "tactum.matx"), tuple(f"x{i}" for i in range(n)),
                        tuple(("C6S1M1P2X1", "C7S1M1P1X1")[i % 2] for i in range(n)),
                        tuple(f"s{i % 6}" for i in range(n)))


def test_constant_or_overflowing_features_are_named_instead_of_a_library_error():
    from taxonomy.learning.evaluation import evaluate

    with pytest.raises(FeatureSpaceError, match=r"every one of the 3 feature column\(s\) is constant over the 24 "
                                              r"rows \(other.density = 1, ...\): no feature can tell the classes"):
        evaluate(_two_materials(np.ones((24, 3))), classifier="lda", level="fine", n_features=2)
    # +-1e308: the scaler's range (max - min) overflows to inf, and every scaled value becomes NaN.
    rng = np.random.default_rng(0)
    huge = rng.normal(size=(24, 3))
    huge[:, 1] = np.where(np.arange(24) % 2, -1e308, 1e308) * (1 - 0.1 * rng.random(24))
    with pytest.raises(FeatureSpaceError, match=r"1 feature column\(s\) hold infinite values or span more than "
                                              r"a 64-bit float can scale: other.metal \(-9.\d+e\+307 to "
                                              r"9.\d+e\+307\); check the data's units or scale"):
        evaluate(_two_materials(huge), classifier="lda", level="fine", n_features=2)
    usable = huge.copy()
    usable[:, 1] /= 1e300  # the same data in other units: evaluated
    assert evaluate(_two_materials(usable), classifier="lda", level="fine", n_features=1).accuracy_pooled == 1.0


def test_with_values_leaves_out_a_set_without_any_value():
    X = np.array([[1.0, np.nan, np.nan], [2.0, np.nan, np.nan]])
    space = FeatureSpace(X=X, columns=("other.a", "image.b", "image.c"), scan_ids=["s1", "s2"],
                         label_text=["C1S1M1P1X1", "C6S1M1P2X1"], groups=["g1", "g2"])
    kept, left_out = with_values(space, {"other": "other", "image": "image", "all": None})
    assert list(kept) == ["other", "all"]
    assert left_out == ["feature set image left out: none of its 2 columns has a value in any of the 2 rows"]
    with pytest.raises(EvaluationError, match=r"every one of the 2 rows holds only NaN in every feature set \(image\)"):
        with_values(space, {"image": "image"})
