"""Grouped folds stay grouped when a class has a single group; rows without features are left out, said."""

from __future__ import annotations

import numpy as np
import pytest

from features import FeatureSpace
from taxonomy.learning.evaluation import cv_splits, evaluate


def space_with(single: bool, seed: int = 0) -> FeatureSpace:
    """Classes a-d with three groups of four rows each, separable; with ``single`` a class e of one group,
    far from the others."""
    rng = np.random.default_rng(seed)
    classes = ["a", "b", "c", "d"] + (["e"] if single else [])
    rows, labels, groups = [], [], []
    for k, name in enumerate(classes):
        for g in range(1 if name == "e" else 3):
            centre = np.zeros(6)
            centre[k % 6] = 6.0 if name != "e" else 40.0
            rows.append(centre + rng.normal(size=(4, 6)))
            labels += [name] * 4
            groups += [f"{name}{g}"] * 4
    X = np.vstack(rows)
    return FeatureSpace(X, tuple(f"generic.x.f{j}" for j in range(6)), tuple(f"r{i}" for i in range(len(X))),
                        labels, groups, (), "label")


def test_a_single_group_class_never_switches_grouping_off_for_the_others():
    without, with_e = space_with(False), space_with(True)
    base, grouped = cv_splits(without.label_text, without.groups, folds=3, seed=4)
    with pytest.warns(UserWarning, match=r"1 of 5 classes have a single sample .* kept in training only; the "
                                         "folds of the others stay grouped: e"):
        kept, grouped_e = cv_splits(with_e.label_text, with_e.groups, folds=3, seed=4)
    assert grouped and grouped_e
    e_rows = set(np.flatnonzero(np.asarray(with_e.label_text) == "e"))
    groups = np.asarray(with_e.groups)
    for (train, test), (_, test0) in zip(kept, base, strict=True):
        assert np.array_equal(test, test0)  # the other classes' folds are the same rows (e comes last)
        assert e_rows <= set(train) and not e_rows & set(test)
        assert not set(groups[train]) & set(groups[test])
    with pytest.warns(UserWarning, match="left out"):
        dropped, _ = cv_splits(with_e.label_text, with_e.groups, folds=3, seed=4, single_group="drop")
    for (train, test), (train0, test0) in zip(dropped, base, strict=True):
        assert np.array_equal(train, train0) and np.array_equal(test, test0)


def test_the_grouped_score_does_not_change_when_a_single_group_class_is_added():
    without = evaluate(space_with(False), "rf", level="label", n_features=None, folds=3, seed=4, calibrate=False)
    for mode in ("drop", "train"):
        added = evaluate(space_with(True), "rf", level="label", n_features=None, folds=3, seed=4,
                         single_group=mode, calibrate=False)
        assert added.grouped and any("single sample" in note for note in added.notes)
        # e is far from the others, so keeping it in training changes no prediction either.
        assert np.array_equal(added.accuracy, without.accuracy)


def test_rows_without_any_feature_are_left_out_with_a_note():
    space = space_with(False)
    X = space.X.copy()
    X[[0, 13]] = np.nan  # two recordings that lacked every role the families need
    holed = FeatureSpace(X, space.columns, space.scan_ids, space.label_text, space.groups, (), "label")
    result = evaluate(holed, "lda", level="label", n_features=None, folds=3, seed=4)
    assert result.dropped == () and result.n_samples == len(X) - 2
    assert any("2 of 48 row(s) have no feature value (every column NaN) and are left out: r0, r13" in note
               for note in result.notes)
