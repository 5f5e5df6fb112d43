"""Open-set recognition: held-out materials rejected, a rule learned inside training and kept in the model."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from features.space import FeatureSpace
from scanner.workflows import Prediction, ScanPrediction, format_predictions
from taxonomy.learning.evaluation import evaluate_open_set
from taxonomy.learning.models import classify_values, load_model, save_model, train_model
from taxonomy.learning.openset import choose_threshold, class_folds, fit_distance, mahalanobis

CLASSES = 8
SAMPLES = 3
SCANS = 3


def material_space(spread: float, seed: int = 0, shuffled: bool = False) -> FeatureSpace:
    """Eight materials x three samples x three scans, six features; each material's centre is ``spread``
    standard deviations from the others in every feature. ``shuffled``: the features are pure noise,
    unrelated to the labels."""
    rng = np.random.default_rng(seed)
    material = np.repeat(np.arange(CLASSES), SAMPLES * SCANS)
    sample = np.tile(np.repeat(np.arange(SAMPLES), SCANS), CLASSES)
    centres = rng.standard_normal((CLASSES, 6)) * spread
    X = rng.standard_normal((material.size, 6)) + (0 if shuffled else centres[material])
    labels = tuple(f"C{m % 4 + 1}S{m // 4 + 1}M1P1X1" for m in material)
    groups = tuple(f"m{m}-{s}" for m, s in zip(material, sample, strict=True))
    columns = tuple(f"other.f{j}" for j in range(6))
    return FeatureSpace(X, columns, tuple(f"scan{i}" for i in range(material.size)), labels, groups)


def test_held_out_classes_of_separable_materials_are_rejected():
    result = evaluate_open_set(material_space(spread=8.0), "nb", "fine", n_features=None, folds=3)
    # Every scan is tested once as unknown (in the fold holding out its class), and as known in its sample's
    # fold unless that fold holds out its class.
    rows = CLASSES * SAMPLES * SCANS
    assert result.open_set and sorted(result.rows[~result.known]) == list(range(rows))
    assert np.unique(result.rows[result.known]).size == result.known.sum() > rows / 2
    assert result.auroc > 0.99  # every feature apart by eight standard deviations: near 1
    assert result.unknown_rejected > 0.8
    assert result.closed_accuracy == pytest.approx(1.0)
    # The rule was learned to cost at most 2 points on known scans; 72 of them: a 2-scan margin for chance.
    assert result.known_accuracy >= result.closed_accuracy - 0.02 - 2 / 72


def test_on_shuffled_features_known_and_unknown_scans_are_alike():
    result = evaluate_open_set(material_space(spread=8.0, shuffled=True), "nb", "fine", n_features=None,
                               folds=3)
    # Under no difference the AUROC is 0.5 with variance (n1 + n0 + 1) / (12 n1 n0) (Mann-Whitney). Scans of
    # one sample are alike, so count samples (24 each way), not scans; four standard errors.
    n = CLASSES * SAMPLES
    error = math.sqrt((2 * n + 1) / (12 * n * n))
    assert abs(result.auroc - 0.5) < 4 * error


def test_threshold_is_the_normal_quantile_of_the_right_known_scores():
    rng = np.random.default_rng(0)
    score = rng.standard_normal(20000)
    unknown = np.zeros(score.size, dtype=bool)
    correct = np.ones(score.size, dtype=bool)
    # Every known scan right: costing 2 points means rejecting the top 2 % of N(0, 1): Phi^-1(0.98).
    t = choose_threshold(score, unknown, correct, 0.02)
    # The estimate's error: sd(mean) + z sd(sd) = sqrt(1/n) + z sqrt(1/(2n)); four of them.
    z = norm.ppf(0.98)
    assert t == pytest.approx(z, abs=4 * (math.sqrt(1 / score.size) + z * math.sqrt(1 / (2 * score.size))))
    # Half the known scans wrong: each right one rejected costs twice as much of the known accuracy.
    correct[::2] = False
    assert choose_threshold(score, unknown, correct, 0.02) == pytest.approx(norm.ppf(0.96), abs=0.05)
    # Unknown scans do not move it; fewer than three right scans: never reject.
    assert choose_threshold(np.r_[score, score + 9], np.r_[unknown, ~unknown], np.r_[correct, correct], 0.02) \
        == choose_threshold(score, unknown, correct, 0.02)
    assert choose_threshold(np.array([1.0, 2.0]), np.zeros(2, bool), np.ones(2, bool)) == math.inf


def test_mahalanobis_distance_to_the_nearest_class_mean():
    # Two classes at x = 0 and x = 10, deviations of sd 1 along x and 2 along y (no correlation).
    Z = np.array([[-1, -2], [1, 2], [-1, 2], [1, -2], [9, -2], [11, 2], [9, 2], [11, -2]], dtype=float)
    y = np.array(["a"] * 4 + ["b"] * 4)
    distance = fit_distance(Z, y, np.array([f"g{i}" for i in range(8)]))
    np.testing.assert_allclose(distance.means, [[0, 0], [10, 0]])
    np.testing.assert_allclose(mahalanobis(np.array([[0.0, 4.0], [7.0, 0.0]]), distance.means, distance.precision),
                               [2.0, 3.0], rtol=1e-5)


def test_class_folds_deal_every_class_once():
    parts = class_folds(np.array(list("abcdefgh") * 2), 3, seed=1)
    assert sorted(np.concatenate(parts).tolist()) == list("abcdefgh") and len(parts) == 3


def test_a_trained_model_keeps_its_rule_and_rejects_a_material_it_never_saw(tmp_path):
    space = material_space(spread=8.0)
    model = train_model(space, "fine", n_features=3, classifier="nb")
    assert model.rejection is not None and np.isfinite(model.rejection.threshold)
    path = save_model(model, tmp_path / "m.skops")
    loaded = load_model(path)
    np.testing.assert_array_equal(loaded.rejection.means, model.rejection.means)
    assert loaded.rejection.threshold == model.rejection.threshold
    known = dict(zip(space.columns, space.X[0], strict=True))
    verdict = classify_values(loaded, known, 2)
    assert not verdict.unknown and verdict.top[0][0] == space.label_text[0]
    far = {name: value + 40.0 for name, value in known.items()}  # five spreads from every material
    verdict = classify_values(loaded, far, 2)
    assert verdict.unknown and verdict.score > verdict.threshold and len(verdict.top) == 2
    assert "rejects a scan scoring above" in loaded.describe()


def test_a_rejected_scan_is_reported_as_an_unknown_material_with_its_closest():
    top = [Prediction("C6S1M1P2X1", 0.45, "granite (igneous stone, stone), polished, plain"),
           Prediction("C7S1M1P1X1", 0.30, "oak")]
    rejected = ScanPrediction(top, unknown=True, score=4.2, threshold=3.1)
    assert rejected.headline() == ("unknown material (closest: granite (igneous stone, stone), polished, plain "
                                   "(C6S1M1P2X1) 45.0 %)")
    lines = format_predictions(rejected).splitlines()
    assert lines[0].startswith("unknown material (closest: granite") and "4.20 > threshold 3.10" in lines[0]
    assert lines[1].startswith("1. C6S1M1P2X1   45.0 %")
    accepted = ScanPrediction(top)
    assert format_predictions(accepted).splitlines()[0].startswith("1. C6S1M1P2X1")
