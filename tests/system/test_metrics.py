"""Calibration end to end: an evaluation keeps calibrated out-of-fold probabilities whose predictions are the
uncalibrated ones (the system test: a cross-validated evaluation with the temperature fitted per fold)."""

from __future__ import annotations

import math

import numpy as np

from taxonomy.learning.evaluation import evaluate


def test_evaluation_keeps_calibrated_out_of_fold_probabilities_and_the_same_predictions():
    from unit.test_evaluation import labelled_space

    space = labelled_space()
    plain = evaluate(space, "rf", "fine", n_features=3, folds=3, calibrate=False)
    calibrated = evaluate(space, "rf", "fine", n_features=3, folds=3)
    np.testing.assert_array_equal(plain.y_pred, calibrated.y_pred)
    assert plain.probability is None and math.isnan(plain.ece)
    np.testing.assert_allclose(calibrated.probability.sum(axis=1), 1.0)
    assert 0 <= calibrated.ece <= 1
    assert calibrated.to_dict()["ece"] == calibrated.ece
