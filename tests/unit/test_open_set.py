"""Open-set recognition: held-out materials rejected, a rule learned inside training and kept in the model."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import norm

from features.space import FeatureSpace
from scanner.workflows.predictions import Prediction, ScanPrediction, format_predictions
from taxonomy.learning.evaluation import evaluate_open_set
from taxonomy.learning.metrics import auroc
from taxonomy.learning.models import classify_values, load_model, save_model, train_model
from taxonomy.learning.openset import (
    Explanation,
    choose_threshold,
    class_folds,
    feature_groups,
    fit_distance,
    fit_neighbours,
    mahalanobis,
)

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


def quantile_error(p: float, n: int) -> float:
    """Standard error of the sample p-quantile of n standard normal draws: sqrt(p (1 - p) / n) / phi(x_p)."""
    return math.sqrt(p * (1 - p) / n) / norm.pdf(norm.ppf(p))


def test_threshold_is_the_upper_quantile_of_the_right_known_scores():
    rng = np.random.default_rng(0)
    score = rng.standard_normal(20000)
    unknown = np.zeros(score.size, dtype=bool)
    correct = np.ones(score.size, dtype=bool)
    # Every known scan right: costing 2 points means rejecting the top 2 % of the scores; of N(0, 1) draws
    # that is Phi^-1(0.98) within four standard errors of the sample quantile.
    t = choose_threshold(score, unknown, correct, 0.02)
    assert t == pytest.approx(np.quantile(score, 0.98), abs=1e-12)
    assert t == pytest.approx(norm.ppf(0.98), abs=4 * quantile_error(0.98, score.size))
    # Half the known scans wrong: each right one rejected costs twice as much of the known accuracy.
    correct[::2] = False
    assert choose_threshold(score, unknown, correct, 0.02) == pytest.approx(
        norm.ppf(0.96), abs=4 * quantile_error(0.96, int(correct.sum())))
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


def test_a_rejected_scan_is_reported_as_an_unknown_material_with_its_closest_and_why():
    top = [Prediction("C6S1M1P2X1", 0.45, "granite (igneous stone, stone), polished, plain"),
           Prediction("C7S1M1P1X1", 0.30, "oak")]
    granite = Prediction("C6S1M1P2X1", math.nan, "granite (igneous stone, stone), polished, plain")
    unlike = Explanation("C6S1M1P2X1", ("image: photo", "image: flash", "audio: tool slide"), "neighbours")
    rejected = ScanPrediction(top, unknown=True, score=4.2, threshold=3.1, closest=granite, explanation=unlike)
    assert rejected.headline() == ("unknown material (closest: granite (igneous stone, stone), polished, plain "
                                   "(C6S1M1P2X1)): image: photo, image: flash and audio: tool slide are unlike "
                                   "every trained material")
    lines = format_predictions(rejected).splitlines()
    assert lines[0].startswith("unknown material (closest: granite") and "4.20 > threshold 3.10" in lines[0]
    assert lines[1].startswith("1. C6S1M1P2X1   45.0 %")
    split = replace(rejected, explanation=Explanation("C6S1M1P2X1", (), "surprisal"))
    assert split.reason() == ("the model is split between granite (igneous stone, stone), polished, plain (45 %) "
                              "and oak (30 %)")
    one = replace(rejected, explanation=Explanation("C6S1M1P2X1", ("TacTUM",), "distance"))
    assert one.reason() == "TacTUM is unlike every trained material"
    accepted = ScanPrediction(top)
    assert format_predictions(accepted).splitlines()[0].startswith("1. C6S1M1P2X1")


# -- the neighbour term: new materials unlike the known ones in features the classifier does not use ----------

WIDTH = 10
GROUPS = {"tactum": "TacTUM", "image.disp": "image: photo", "audio.tool": "audio: tool slide", "other": "other"}


def grouped_space(seed: int = 0) -> tuple[FeatureSpace, np.ndarray]:
    """Twelve materials x three samples x three scans, ten features in each of four groups. The TacTUM
    features separate the materials by ten standard deviations, the others by three, so a model of three
    features selects TacTUM ones. Materials 8 and 9 are new materials with the TacTUM values of materials 0
    and 1 and their own elsewhere: the classifier's own features cannot tell them from those; 10 and 11 are
    new in every group. Returns the space and each row's material."""
    rng = np.random.default_rng(seed)
    materials = 12
    material = np.repeat(np.arange(materials), SAMPLES * SCANS)
    sample = np.tile(np.repeat(np.arange(SAMPLES), SCANS), materials)
    centres = {prefix: rng.standard_normal((materials, WIDTH)) * (10.0 if prefix == "tactum" else 3.0)
               for prefix in GROUPS}
    centres["tactum"][8:10] = centres["tactum"][0:2]
    X = np.hstack([rng.standard_normal((material.size, WIDTH)) + centres[prefix][material] for prefix in GROUPS])
    columns = tuple(f"{prefix}.f{j}" for prefix in GROUPS for j in range(WIDTH))
    labels = tuple(f"C{m % 4 + 1}S{m // 4 + 1}M1P1X1" for m in material)
    groups = tuple(f"m{m}-{s}" for m, s in zip(material, sample, strict=True))
    return FeatureSpace(X, columns, tuple(f"scan{i}" for i in range(material.size)), labels, groups), material


def test_feature_groups_follow_the_sensing_steps():
    space, _ = grouped_space()
    titles, group_of = feature_groups(space.columns + ("signal.v_ts.00001",))
    assert titles == tuple(GROUPS.values())
    np.testing.assert_array_equal(group_of, [*np.repeat(np.arange(4), WIDTH), -1])


def test_neighbour_distance_is_the_log_distance_of_unit_group_vectors():
    # Two columns per group, standardised on the three training rows, each group vector scaled to length 1.
    X = np.array([[0.0, 0.0, 1.0, 1.0], [1.0, 2.0, 0.0, 2.0], [2.0, 4.0, 2.0, 0.0]])
    neighbours = fit_neighbours(X, np.array(["a", "a", "b"]), ["a", "b"],
                                ["tactum.x", "tactum.y", "other.x", "other.y"])
    centre, spread = X.mean(axis=0), X.std(axis=0)
    np.testing.assert_allclose(neighbours.centre, centre)
    query = np.array([[1.0, 0.0, np.nan, np.nan]])
    z = (query[0, :2] - centre[:2]) / spread[:2]
    reference = (X[:, :2] - centre[:2]) / spread[:2]
    unit = lambda v: v / max(np.linalg.norm(v), 1e-12)  # noqa: E731
    expected = min(np.linalg.norm(unit(z) - unit(r)) for r in reference)
    distances = neighbours.log_distances(query)
    assert distances[0, 0] == pytest.approx(np.log(expected), rel=1e-12)
    assert np.isnan(distances[0, 1])  # no value in the group: no distance, not the median's
    by_class = neighbours.class_log_distances(query)
    assert by_class.shape == (1, 2, 2) and np.nanmin(by_class[0, 0]) == pytest.approx(distances[0, 0])


def known_and_new(seed: int = 0):
    """A model trained on two samples of materials 0-7; the third samples (known) and materials 8-11 (new)."""
    space, material = grouped_space(seed)
    sample = np.array([int(g.rsplit("-", 1)[1]) for g in space.groups])
    model = train_model(space.rows(np.flatnonzero((material < 8) & (sample < 2))), "fine", n_features=3,
                        classifier="rf")
    return space, material, sample, model


def test_new_materials_the_classifier_cannot_see_are_rejected_by_their_other_features():
    space, material, sample, model = known_and_new()
    assert all(name.startswith("tactum.") for name in model.selected)
    known = (material < 8) & (sample == 2)
    rule = model.rejection
    score, terms = rule.score(model.pipeline, space.X), rule.terms(model.pipeline, space.X)
    rejected = score > rule.threshold
    hidden = (material == 8) | (material == 9)
    # The previous score, surprisal plus distance ratio, lives in the selected features: it ranks the new
    # materials with TacTUM values of known ones among the known scans; the neighbour term does not.
    assert auroc(np.r_[(terms[:, 0] + terms[:, 1])[known], (terms[:, 0] + terms[:, 1])[hidden]],
                 np.r_[np.zeros(known.sum()), np.ones(hidden.sum())].astype(bool)) < 0.8
    assert auroc(np.r_[score[known], score[hidden]],
                 np.r_[np.zeros(known.sum()), np.ones(hidden.sum())].astype(bool)) > 0.99
    assert rejected[material >= 8].mean() >= 0.8
    # 24 known scans under a 2-point budget: 0.5 expected; a binomial sd of 0.7 - at most three.
    assert rejected[known].sum() <= 3


def test_the_forest_over_every_feature_is_split_where_the_classifier_s_own_features_are_sure():
    space, material, sample, model = known_and_new()
    known, hidden = (material < 8) & (sample == 2), (material == 8) | (material == 9)
    terms = model.rejection.terms(model.pipeline, space.X)
    u, w = terms[:, 0], terms[:, 3]
    is_hidden = np.r_[np.zeros(known.sum()), np.ones(hidden.sum())].astype(bool)
    # Materials 8 and 9 have the TacTUM values of 0 and 1: the model's three TacTUM features are sure of them
    # (surprisal at or below the known scans'), while the trees that split on the other groups name other
    # materials: the forest over every feature puts every one of them above every known scan.
    assert auroc(np.r_[u[known], u[hidden]], is_hidden) < 0.5
    assert w[hidden].min() > w[known].max()
    assert model.rejection.wide.n_features_in_ == space.X.shape[1] and model.rejection.wide.class_weight == "balanced"


def test_a_value_beyond_single_precision_in_a_feature_the_model_does_not_select_still_gets_a_verdict():
    space, material, sample, model = known_and_new()
    row = np.flatnonzero((material == 3) & (sample == 2))[0]
    values = dict(zip(space.columns, space.X[row], strict=True))
    unselected = next(name for name in space.columns if name not in model.selected)
    # 1e39 is finite in float64 and infinite in the float32 that trees compare in.
    verdict = classify_values(model, {**values, unselected: 1e39}, 2)
    assert np.isfinite(verdict.score) and verdict.top[0][0] == space.label_text[row]


def test_an_unknown_scan_is_explained_by_its_unlike_groups_and_closest_material():
    space, material, sample, model = known_and_new()
    row = np.flatnonzero((material == 3) & (sample == 2))[0]
    stranger = np.flatnonzero(material == 10)[0]
    values = dict(zip(space.columns, space.X[row], strict=True))
    # The tool slide's sound of a new material, the rest of a known piece of material 3.
    swapped = {**values, **{name: space.X[stranger, j] for j, name in enumerate(space.columns)
                            if name.startswith("audio.tool.")}}
    verdict = classify_values(model, swapped, 2)
    assert verdict.explanation.unlike == ("audio: tool slide",)
    assert verdict.explanation.closest == space.label_text[row] == verdict.top[0][0]
    assert classify_values(model, values, 2).explanation.unlike == ()
    # A new material in every group: rejected, named unlike in most of its groups; the largest term is one of
    # those that read every feature (the neighbours' or the forest's), not of the three the model selected.
    verdict = classify_values(model, dict(zip(space.columns, space.X[stranger], strict=True)), 2)
    assert verdict.unknown and len(verdict.explanation.unlike) >= 2
    assert verdict.explanation.largest in ("neighbours", "wide")


def test_a_model_of_the_previous_format_keeps_its_score(tmp_path):
    space, material, _, model = known_and_new()
    previous = replace(model, rejection=replace(model.rejection, neighbours=None, scales=None))
    loaded = load_model(save_model(previous, tmp_path / "v2.skops"))
    assert loaded.rejection.scales is None and loaded.rejection.neighbours is None
    terms = model.rejection.terms(model.pipeline, space.X)
    np.testing.assert_allclose(loaded.rejection.score(loaded.pipeline, space.X), terms[:, 0] + terms[:, 1])
    # Version 3: the mean of u, m and n, without the forest over every feature.
    scales = model.rejection.scales
    three = replace(model, rejection=replace(model.rejection, wide=None, scales=replace(
        scales, term_mean=scales.term_mean[:3], term_sd=scales.term_sd[:3])))
    loaded = load_model(save_model(three, tmp_path / "v3.skops"))
    assert loaded.rejection.wide is None and loaded.rejection.scales.term_mean.size == 3
    z = (terms[:, :3] - scales.term_mean[:3]) / scales.term_sd[:3]
    np.testing.assert_allclose(loaded.rejection.score(loaded.pipeline, space.X), z.mean(axis=1), rtol=1e-12)
    current = load_model(save_model(model, tmp_path / "v4.skops"))
    assert current.rejection.wide is not None
    np.testing.assert_array_equal(current.rejection.score(current.pipeline, space.X),
                                  model.rejection.score(model.pipeline, space.X))
    np.testing.assert_allclose(model.rejection.score(model.pipeline, space.X),
                               ((terms - scales.term_mean) / scales.term_sd).mean(axis=1), rtol=1e-12)


def test_one_pass_gives_the_score_and_a_closest_class_even_without_group_values():
    space, material, sample, model = known_and_new()
    rule, rows = model.rejection, space.X[::7]
    score, explanations = rule.assess(model.pipeline, rows)
    np.testing.assert_allclose(score, rule.score(model.pipeline, rows), rtol=1e-12)
    # No value in any group: no distance to place the scan, so the classifier's top class is the closest.
    empty = np.full((1, space.X.shape[1]), np.nan)
    score, (explanation,) = rule.assess(model.pipeline, empty)
    top = model.pipeline.classes_[model.pipeline.predict_proba(empty).argmax()]
    assert explanation.closest == top and explanation.unlike == () and np.isfinite(score[0])
