"""A fused feature set classified family by family (taxonomy.learning.fusion): the families weighted by
ensemble selection on inner out-of-fold probabilities, the inner folds grouped as the outer ones."""

from __future__ import annotations

import numpy as np
from sklearn.ensemble import RandomForestClassifier
from sklearn.naive_bayes import GaussianNB

from features import FeatureSpace
from taxonomy.learning.evaluation import evaluate, fit_pipeline
from taxonomy.learning.fusion import FamilyEnsembleClassifier, ensemble_selection
from unit.test_evaluation import labelled_space


def test_selection_keeps_the_best_member_and_adds_one_only_where_the_loss_falls():
    true = np.array([0, 1, 0, 1])
    good = np.array([[0.8, 0.2], [0.2, 0.8], [0.8, 0.2], [0.2, 0.8]])
    wrong = good[:, ::-1]
    assert ensemble_selection([wrong, good], true).tolist() == [0.0, 1.0]
    # Log-loss of the mean of 'good' and 'half' at weights (1 - w, w) is lowest at w = 0: one member only.
    half = np.full((4, 2), 0.5)
    assert ensemble_selection([good, half, wrong], true).tolist() == [1.0, 0.0, 0.0]


def _leaky(groups: int = 12, rows: int = 4, seed: int = 0):
    """Family 0: a real class signal; family 1: a random code per group, the same for every row of
    a group, so it names the class of rows whose group was seen and nothing about a new group."""
    rng = np.random.default_rng(seed)
    group = np.repeat(np.arange(groups), rows)
    y = np.where(group % 2 == 0, "cork", "oak")
    signal = (group % 2) * 1.0 + rng.normal(0, 0.3, group.size)
    code = rng.normal(0, 1, (groups, 3))[group]
    return np.c_[signal, code], y, np.array([f"g{g}" for g in group])


def test_inner_folds_keep_a_groups_rows_together():
    """Split by row, the per-group code looks perfect (every group is seen in training) and takes the weight;
    split by group, it tells nothing and the real signal keeps it."""
    X, y, groups = _leaky()
    parts = (0, 1, 1, 1)
    forest = RandomForestClassifier(50, random_state=0)
    by_row = FamilyEnsembleClassifier(forest, parts).fit(X, y)
    by_group = FamilyEnsembleClassifier(forest, parts).fit(X, y, groups=groups)
    assert by_row.weights_[1] > 0.5 and by_group.weights_[0] > 0.5, (by_row.weights_, by_group.weights_)


def test_a_fused_set_is_not_drowned_by_a_wide_family():
    """The paper's four informative columns beside 300 columns of noise of one modern family: one forest over
    every column rarely draws an informative one; classified family by family, the fused set does as well
    as the paper's columns alone, in evaluation and in a trained pipeline."""
    paper = labelled_space(materials=8, samples=3, scans=3, features=8, seed=2)
    rng = np.random.default_rng(3)
    noise = rng.normal(size=(len(paper), 300))
    columns = (*paper.columns, *(f"catch22.v_ts.n{k:03d}" for k in range(300)))
    fused = FeatureSpace(np.c_[paper.X, noise], columns, paper.scan_ids, paper.label_text, paper.groups)
    cells = {"level": "fine", "n_features": None, "folds": 3, "calibrate": False}
    alone = evaluate(fused, "rf", feature_set="paper", **cells)
    together = evaluate(fused, "rf", feature_set="paper+catch22", **cells)
    assert together.accuracy_pooled >= alone.accuracy_pooled - 1 / len(fused), (together.accuracy_pooled,
                                                                               alone.accuracy_pooled)
    pipeline = fit_pipeline(fused.X, np.array(fused.label_text), np.array(fused.groups), "rf", None,
                            columns=fused.columns, calibrate=True)
    assert type(pipeline[-1].estimator_).__name__ == "FamilyEnsembleClassifier"
    assert pipeline[-1].estimator_.weights_[0] >= 0.5
    # Each family's n best: balanced by the selection, one classifier over them as before.
    balanced = fit_pipeline(fused.X, np.array(fused.label_text), np.array(fused.groups), "rf", 2,
                            columns=fused.columns, calibrate=False)
    assert type(balanced[-1]) is RandomForestClassifier and balanced[-1].n_features_in_ == 4


def test_one_family_is_classified_as_before():
    space = labelled_space()
    X, y, groups = space.X, np.array(space.label_text), np.array(space.groups)
    plain = fit_pipeline(X, y, groups, "nb", None, calibrate=False, columns=space.columns)
    assert type(plain[-1]) is GaussianNB
