"""Scores a reviewer accepts: pooled and per-fold macro F1, intervals, calibration, grouping and voting."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.special import expit
from sklearn.metrics import confusion_matrix as sk_confusion
from sklearn.metrics import f1_score
from sklearn.naive_bayes import GaussianNB

from features.space import FeatureSpace
from taxonomy.learning import metrics
from taxonomy.learning.calibration import TemperatureScaledClassifier
from taxonomy.learning.evaluation import EvaluationError, evaluate, recording_of, running_vote, vote
from taxonomy.learning.results import OWN_METHOD, Result

# -- macro F1: per fold over present classes, pooled as the headline ------------------------------------

# Two folds, each holding two of four classes; one error per fold goes to a class absent from that fold.
Y_TRUE = np.array(["a", "a", "b", "b", "c", "c", "d", "d"])
Y_PRED = np.array(["a", "c", "b", "b", "c", "c", "d", "a"])
FOLD = np.array([0, 0, 0, 0, 1, 1, 1, 1])


def closed_form_result() -> Result:
    from sklearn.metrics import confusion_matrix

    classes = np.array(["a", "b", "c", "d"])
    folds = [np.flatnonzero(FOLD == k) for k in range(2)]
    return Result(
        method=OWN_METHOD, feature_set="all", classifier="x", level="fine", protocol="nested",
        splitting="2 grouped folds", classes=tuple(classes), n_samples=8, seed=0, taxonomy=False,
        accuracy=np.array([np.mean(Y_PRED[f] == Y_TRUE[f]) for f in folds]),
        f1=np.array([metrics.present_class_f1(Y_TRUE[f], Y_PRED[f]) for f in folds]),
        confusion=confusion_matrix(Y_TRUE, Y_PRED, labels=classes), y_true=Y_TRUE, y_pred=Y_PRED, fold=FOLD,
        groups=np.array(["g0", "g0", "g1", "g1", "g2", "g2", "g3", "g3"]))


def test_per_fold_f1_over_present_classes_and_pooled_f1_differ_as_described():
    # Fold 0 over its true or predicted classes {a, b, c}: F1 a = 2/3, b = 1, c = 0 (never in the fold): 5/9.
    fold0 = np.flatnonzero(FOLD == 0)
    assert f1_score(Y_TRUE[fold0], Y_PRED[fold0], average="macro") == pytest.approx(5 / 9)
    # Over the classes present in the fold, {a, b}: (2/3 + 1) / 2 = 5/6.
    assert metrics.present_class_f1(Y_TRUE[fold0], Y_PRED[fold0]) == pytest.approx(5 / 6)
    # Pooled: a 2 TP... a: TP 1, FP 1, FN 1 -> 1/2; b: 1; c: TP 2, FP 1 -> 4/5; d: TP 1, FN 1 -> 2/3.
    pooled = (1 / 2 + 1 + 4 / 5 + 2 / 3) / 4
    result = closed_form_result()
    assert result.f1_pooled == pytest.approx(pooled)
    assert result.f1_pooled == pytest.approx(f1_score(Y_TRUE, Y_PRED, average="macro"))
    np.testing.assert_allclose(result.f1, [5 / 6, 5 / 6])
    assert result.accuracy_pooled == pytest.approx(6 / 8)


def test_evaluate_reports_pooled_f1_and_per_fold_f1_over_present_classes():
    from unit.test_evaluation import labelled_space

    space = labelled_space()
    result = evaluate(space, "nb", "fine", n_features=3, folds=4, calibrate=False)
    for k in range(result.folds):
        test = result.fold == k
        assert result.f1[k] == pytest.approx(metrics.present_class_f1(result.y_true[test], result.y_pred[test]))
    assert result.f1_pooled == pytest.approx(f1_score(result.y_true, result.y_pred, average="macro"))
    # The fold's classes are fewer than all of them, so an error into an absent class would count as a 0.
    assert all(np.unique(result.y_true[result.fold == k]).size < len(result.classes) for k in range(result.folds))


def test_bootstrap_interval_over_groups_holds_the_pooled_figure():
    result = closed_form_result()
    low, high = result.accuracy_ci
    assert low <= result.accuracy_pooled <= high
    # Groups g0 and g3 hold one error each out of two rows: a resample of only g1 and g2 is all right.
    assert high == 1.0 and 0.0 <= low < 0.75
    # A statistic that does not depend on the rows has a degenerate interval.
    assert metrics.bootstrap_interval(lambda weights: 0.5, ["a", "b", "c"]) == (0.5, 0.5)
    # Each resample draws as many groups as there are, with replacement.
    seen = []
    metrics.bootstrap_interval(lambda weights: seen.append(weights) or 0.0, ["a", "a", "b", "c"], resamples=50)
    assert all(w[1] + w[2] + w[3] == 3 and w[0] == w[1] for w in seen)  # group a's two rows drawn together


def test_bootstrap_weights_are_drawn_once_and_each_call_gets_its_own_copy():
    groups = ["b", "a", "b", "c", "a"]
    first = metrics.bootstrap_weights(groups, seed=3, resamples=40)
    # The draws are those of one multinomial sample of the groups (a, b, c in sorted order) per resample.
    drawn = np.random.default_rng(3).multinomial(3, np.full(3, 1 / 3), size=40)
    np.testing.assert_array_equal(first, drawn[:, [1, 0, 1, 2, 0]])
    first[:] = -1  # the caller's copy: the next call is unchanged
    np.testing.assert_array_equal(metrics.bootstrap_weights(groups, seed=3, resamples=40), drawn[:, [1, 0, 1, 2, 0]])
    assert not metrics._group_draws(3, 3, 40).flags.writeable


def test_auroc_is_the_mann_whitney_probability_with_ties_halved():
    assert metrics.auroc([1, 2, 3, 4], [False, False, True, True]) == 1.0
    assert metrics.auroc([4, 3, 2, 1], [False, False, True, True]) == 0.0
    # One unknown at 2 against knowns at 1, 2, 3: above one, tied with one, below one -> (1 + 0.5) / 3.
    assert metrics.auroc([1, 2, 3, 2], [False, False, False, True]) == pytest.approx(0.5)
    assert math.isnan(metrics.auroc([1, 2], [False, False]))


def test_chance_levels():
    assert metrics.chance_accuracy(["a", "a", "a", "b"]) == 0.75
    assert metrics.chance_macro_f1(4) == 0.25
    assert closed_form_result().chance == 0.25


# -- calibration ------------------------------------------------------------------------------------------


def two_gaussians(n: int, copies: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x ~ N(-1, 1) for class 0 and N(+1, 1) for class 1, equally likely: the true posterior is
    p(1 | x) = sigmoid(2 x). The feature is repeated ``copies`` times: naive Bayes takes the copies for
    independent evidence and its log odds become ``copies * 2 x``, ``copies`` times too confident."""
    rng = np.random.default_rng(seed)
    y = rng.integers(0, 2, n)
    x = rng.standard_normal(n) + (2 * y - 1)
    return np.repeat(x[:, None], copies, axis=1), y, expit(2 * x)


def test_temperature_scaling_recovers_the_true_probabilities_of_an_overconfident_model():
    copies = 5
    X, y, _ = two_gaussians(6000, copies, seed=1)
    calibrated = TemperatureScaledClassifier(GaussianNB(), inner_folds=3, seed=0).fit(X, y)
    # Naive Bayes' log odds are copies * 2x (its fitted means and variances are those of the data, so up to
    # their sampling error), so the temperature that undoes it is beta = 1 / copies. Its standard error is
    # that of a logistic slope on z = log odds: 1 / sqrt(sum p (1 - p) z^2); four of them are the tolerance.
    z = np.log(calibrated.estimator_.predict_proba(X)[:, 1]) - np.log(calibrated.estimator_.predict_proba(X)[:, 0])
    p = expit(z / copies)
    slope_error = 1 / np.sqrt(np.sum(p * (1 - p) * z**2))
    assert calibrated.beta_ == pytest.approx(1 / copies, abs=4 * slope_error + 0.01)
    X_new, y_new, truth = two_gaussians(4000, copies, seed=2)
    probability = calibrated.predict_proba(X_new)[:, 1]
    raw = calibrated.estimator_.predict_proba(X_new)[:, 1]
    # Calibrated probabilities lie on the true posterior; the raw ones are far from it.
    assert np.max(np.abs(probability - truth)) < 0.05 < np.max(np.abs(raw - truth))
    # ECE with 10 bins of 4000 rows: binning and sampling each add about 0.01; the raw model's is far above.
    ece = metrics.reliability(np.column_stack([1 - probability, probability]), y_new).ece
    ece_raw = metrics.reliability(np.column_stack([1 - raw, raw]), y_new).ece
    assert ece < 0.03 < 0.1 < ece_raw
    np.testing.assert_array_equal(calibrated.predict(X_new), calibrated.estimator_.predict(X_new))


def test_reliability_of_a_perfectly_calibrated_forecast():
    # Bin (0.7, 0.8]: confidence 0.75 for 4 rows of which 3 are right -> gap 0; bin (0.9, 1]: 1.0, all right.
    probability = np.array([[0.75, 0.25]] * 4 + [[0.0, 1.0]] * 2)
    truth = np.array([0, 0, 0, 1, 1, 1])
    bins = metrics.reliability(probability, truth)
    np.testing.assert_allclose(bins.confidence, [0.75, 1.0])
    np.testing.assert_allclose(bins.accuracy, [0.75, 1.0])
    assert bins.ece == pytest.approx(0.0)
    assert metrics.reliability(np.array([[0.9, 0.1]] * 2), np.array([1, 1])).ece == pytest.approx(0.9)


# -- grouping and voting ----------------------------------------------------------------------------------


def sessions_space() -> FeatureSpace:
    """Four materials, each scanned in four sessions (operator ``op0`` runs sessions 0 and 1, ``op1`` 2 and
    3), one two-window recording per material and session; grouped by sample, every row is its own."""
    rng = np.random.default_rng(3)
    rows = [(m, s, w) for m in range(4) for s in range(4) for w in range(2)]
    X = rng.standard_normal((len(rows), 4)) + np.array([[3.0 * m, 0, 0, 0] for m, _, _ in rows])
    labels = tuple(f"C{m + 1}S1M1P1X1" for m, _, _ in rows)
    ids = tuple(f"m{m}-s{s}#w{w}" for m, s, w in rows)
    return FeatureSpace(X, ("other.a", "other.b", "other.c", "other.d"), ids, labels, ids)


GROUPINGS = {
    "session": lambda scan_id: scan_id.split("-")[1].split("#")[0],
    "operator": lambda scan_id: f"op{int(scan_id.split('-s')[1][0]) // 2}",
    "recording": recording_of,
}


@pytest.mark.parametrize("group_by", list(GROUPINGS))
def test_no_session_operator_or_recording_is_in_training_and_test_at_once(group_by):
    space = sessions_space()
    space = replace(space, groups=tuple(GROUPINGS[group_by](s) for s in space.scan_ids))
    result = evaluate(space, "nb", "fine", n_features=2, folds=2, group_by=group_by, calibrate=False)
    assert result.grouped and result.group_by == group_by
    assert np.unique(result.groups).size == {"session": 4, "operator": 2, "recording": 16}[group_by]
    for group in np.unique(result.groups):
        assert np.unique(result.fold[result.groups == group]).size == 1  # all its rows tested in one fold
    # Each fold's model never saw the group it is tested on: the training rows are the other folds' rows.
    for k in range(result.folds):
        assert not set(result.groups[result.fold == k]) & set(result.groups[result.fold != k])


def test_the_cli_regroups_scans_by_session_and_operator(tmp_path):
    from conftest import make_scan

    from scanner.cli.analysis import regroup_scans
    from scanner.cli.common import UsageError
    from scanner.storage.database import Database

    db = Database(tmp_path / "db", create=True)
    for k, (session, operator) in enumerate([("s1", "ab"), ("s1", "ab"), ("s2", "cd")]):
        db.add(make_scan(k, images=False, sample_id=f"piece-{k}", session_id=session, operator=operator))
    ids = tuple(r.scan_id for r in db.records())
    space = FeatureSpace(np.zeros((3, 1)), ("other.a",), ids, ("C6S1M1P2X1",) * 3, ("x", "y", "z"))

    class Args:
        db = tmp_path / "db"
        group_by = "session"

    records = {r.scan_id: r for r in db.records()}
    assert regroup_scans(space, Args).groups == tuple(records[s].session_id for s in ids)
    Args.group_by = "operator"
    assert regroup_scans(space, Args).groups == tuple(records[s].operator for s in ids)
    Args.group_by = "recording"
    assert regroup_scans(space, Args).groups == ids
    Args.group_by = "auto"
    assert regroup_scans(space, Args) is space
    Args.group_by = "colour"
    with pytest.raises(UsageError, match="sample, session, operator, recording"):
        regroup_scans(space, Args)


def test_a_recording_is_scored_once_by_its_windows_vote():
    result = closed_form_result()
    recordings = [recording_of(f"rec{k // 2}#w{k % 2}") for k in range(8)]
    assert recordings[:2] == ["rec0", "rec0"]
    voted = vote(result, recordings)
    # rec0: a, c -> tie broken by class order: a (right); rec1: b, b (right); rec2: c, c; rec3: d, a -> a (wrong).
    np.testing.assert_array_equal(voted.y_pred, ["a", "b", "c", "a"])
    assert voted.voted and voted.accuracy_pooled == pytest.approx(3 / 4)
    assert voted.confusion.sum() == 4


def windows_result(y_pred: list[str], probability: np.ndarray | None, fold: list[int] | None = None) -> Result:
    """Two recordings of ``a``, three windows each, as ``ids`` names them (the second listed out of order)."""
    y_true = np.array(["a"] * 6)
    fold_a = np.array(fold or [0, 0, 0, 1, 1, 1])
    return Result(method=OWN_METHOD, feature_set="all", classifier="x", level="fine", protocol="nested",
                  splitting="2 grouped folds", classes=("a", "b"), n_samples=6, seed=0, taxonomy=False,
                  accuracy=np.array([0.0, 0.0]), f1=np.array([0.0, 0.0]), confusion=np.zeros((2, 2), int),
                  y_true=y_true, y_pred=np.array(y_pred), fold=fold_a, probability=probability)


IDS = ["r0#w000", "r0#w001", "r0#w002", "r1#w002", "r1#w000", "r1#w001"]


def test_a_running_vote_averages_each_window_with_those_before_it_and_never_after():
    # r0: P(a) 0.9, 0.3, 0.45 -> with one window before: 0.9 (a), 0.6 (a), 0.375 (b).
    # r1 in time order w000 0.2, w001 0.7, w002 0.8 -> 0.2 (b), 0.45 (b), 0.75 (a); listed w002, w000, w001.
    p_a = np.array([0.9, 0.3, 0.45, 0.8, 0.2, 0.7])
    probability = np.column_stack([p_a, 1 - p_a])
    result = windows_result(["a", "b", "b", "a", "b", "a"], probability)
    voted = running_vote(result, IDS, 1)
    np.testing.assert_array_equal(voted.y_pred, ["a", "a", "b", "a", "b", "b"])
    assert voted.accuracy_pooled == pytest.approx(3 / 6) and voted.confusion.sum() == 6
    assert not voted.voted and "each window voted with the 1 window before it" in voted.splitting
    # The whole history: r0 0.9, 0.6, 0.55 (a, a, a); r1 0.2, 0.45, 0.567 (b, b, a).
    np.testing.assert_array_equal(running_vote(result, IDS, 5).y_pred, ["a", "a", "a", "a", "b", "b"])
    assert running_vote(result, IDS, 0) is result


def test_a_running_vote_keeps_the_mean_probabilities_it_answered_by():
    p_a = np.array([0.9, 0.3, 0.45, 0.8, 0.2, 0.7])
    voted = running_vote(windows_result(["a"] * 6, np.column_stack([p_a, 1 - p_a])), IDS, 1)
    np.testing.assert_allclose(voted.probability[:, 0], [0.9, 0.6, 0.375, 0.75, 0.2, 0.45])
    assert voted.history == 1 and voted.to_dict()["history"] == 1


def test_a_running_vote_without_probabilities_counts_answers_and_a_tie_goes_to_the_latest():
    # r0 answers a, b, b: w001 ties a/b -> b (latest); w002 b, b -> b. r1 in time order b, a, a -> b, a, a.
    result = windows_result(["a", "b", "b", "a", "b", "a"], None)
    np.testing.assert_array_equal(running_vote(result, IDS, 1).y_pred, ["a", "b", "b", "a", "b", "a"])
    # Two windows before outvote a window's own answer: r0 a, a, b -> a, a, a; r1 b, b, a -> b, b, b.
    outvoted = windows_result(["a", "a", "b", "a", "b", "b"], None)
    np.testing.assert_array_equal(running_vote(outvoted, IDS, 2).y_pred, ["a", "a", "a", "b", "b", "b"])


def test_a_running_vote_leaves_untested_rows_alone_and_votes_softly_where_the_history_has_probabilities():
    # r1 is a training row of the set's own split (fold -1, no probabilities); r0 is tested, its history
    # soft: one NaN row elsewhere does not turn every recording to counting answers.
    p_a = np.array([0.9, 0.3, 0.45, np.nan, np.nan, np.nan])
    result = windows_result(["a", "b", "b", "a", "a", "a"], np.column_stack([p_a, 1 - p_a]),
                            fold=[0, 0, 0, -1, -1, -1])
    voted = running_vote(result, IDS, 1)
    np.testing.assert_array_equal(voted.y_pred, ["a", "a", "b", "a", "a", "a"])
    assert np.isnan(voted.probability[3:]).all() and voted.confusion.sum() == 3


def test_votes_name_the_rows_an_evaluation_kept():
    # The space's row 2 held no value and was left out: the result's rows are the space's 0, 1, 3, 4, 5, 6.
    ids = ["r0#w000", "r0#w001", "r9#w000", "r0#w002", "r1#w000", "r1#w001", "r1#w002"]
    result = replace(windows_result(["a", "b", "b", "b", "b", "a"], None), rows=np.array([0, 1, 3, 4, 5, 6]))
    np.testing.assert_array_equal(running_vote(result, ids, 2).y_pred, ["a", "b", "b", "b", "b", "b"])
    np.testing.assert_array_equal(vote(result, [recording_of(i) for i in ids]).y_pred, ["b", "b"])
    with pytest.raises(EvaluationError, match="5 row names for a result of 6 rows"):
        running_vote(replace(result, rows=None), ids[:5], 1)


@pytest.mark.parametrize("before", [-1, 1.5, True, "2"])
def test_a_running_vote_refuses_a_history_that_is_not_a_count(before):
    with pytest.raises(EvaluationError, match="whole number of windows"):
        running_vote(windows_result(["a"] * 6, None), IDS, before)


def test_a_running_vote_refuses_windows_of_one_recording_in_different_folds():
    # Ungrouped folds: the window before would have been voted by a model trained on this very window.
    with pytest.raises(EvaluationError, match="recording 'r0': its windows lie in different folds"):
        running_vote(windows_result(["a"] * 6, None, fold=[0, 1, 0, 1, 1, 1]), IDS, 1)


def test_an_evaluation_names_the_space_rows_it_kept_and_the_votes_follow_them():
    # Six recordings of three windows, two classes; window 1 of r0 holds no value and is left out.
    ids = tuple(f"r{r}#w{w:03d}" for r in range(6) for w in range(3))
    rng = np.random.default_rng(2)
    X = np.repeat([0.0, 3.0], 9)[:, None] + rng.standard_normal((18, 2))
    X[1] = np.nan
    space = FeatureSpace(X, ("other.a", "other.b"), ids, ("C1S1M1P1X1",) * 9 + ("C2S1M1P1X1",) * 9,
                         tuple(recording_of(i) for i in ids))
    result = evaluate(space, "nb", "coarse", n_features=None, folds=3, calibrate=False, group_by="recording")
    assert any("1 of 18 row(s) have no feature value" in note for note in result.notes), result.notes
    assert result.rows.tolist() == [0, *range(2, 18)] and len(result.y_true) == 17
    assert len(vote(result, [recording_of(i) for i in ids]).y_true) == 6
    voted = running_vote(result, ids, 2)
    assert voted.history == 2 and voted.confusion.sum() == 17


def test_intervals_of_every_resample_at_once_equal_those_resample_by_resample():
    # The result's intervals weigh all 1000 resamples in three products; the same weights through
    # bootstrap_interval, one weighted confusion matrix per resample, give the same bounds: the counts are
    # integers (exact in both), and a macro F1 averages at most 12 per-class scores in [0, 1], summed in
    # another order, so the two differ by at most 12 rounding errors of a number below one.
    rng = np.random.default_rng(1)
    classes = np.array([f"C{c}" for c in range(12)])
    y_true = classes[rng.integers(0, 12, 90)]
    y_pred = np.where(rng.random(90) < 0.7, y_true, classes[rng.integers(0, 12, 90)])
    groups = (np.arange(90) // 3).astype(str)
    result = Result(method=OWN_METHOD, feature_set="all", classifier="rf", level="fine", protocol="nested",
                    splitting="5 grouped folds", classes=tuple(classes), accuracy=np.array([0.7]),
                    f1=np.array([0.6]), confusion=sk_confusion(y_true, y_pred, labels=classes), n_samples=90,
                    seed=3, taxonomy=False, y_true=y_true, y_pred=y_pred, fold=np.zeros(90, dtype=np.int64),
                    groups=groups)
    index = {c: k for k, c in enumerate(classes)}
    true, pred = np.array([index[c] for c in y_true]), np.array([index[c] for c in y_pred])

    def f1(weights):
        cells = np.bincount(true * 12 + pred, weights=weights, minlength=144)
        return metrics.macro_f1_from_confusion(cells.reshape(12, 12))

    np.testing.assert_allclose(result.f1_ci, metrics.bootstrap_interval(f1, groups, seed=3), rtol=0,
                               atol=12 * np.finfo(np.float64).eps)
    assert result.accuracy_ci == metrics.bootstrap_interval(lambda w: w @ (true == pred) / w.sum(), groups, seed=3)
