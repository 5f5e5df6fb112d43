"""The related methods (docs/features.md#related): simulated sensors, classifiers and protocols, compare() end to
end."""

from __future__ import annotations

import math
import pickle
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import multivariate_normal
from sklearn.base import clone
from sklearn.neighbors import KNeighborsClassifier
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from scanner.scan import Recording, Trace
from scanner.simulation import recordings as sim
from taxonomy import related as methods
from taxonomy.learning.results import format_comparison, warning_notes
from taxonomy.related import Dataset, MethodError, compare
from taxonomy.related.inputs import RelatedFeatureError
from taxonomy.related.xie_features import XieFeatures

# -- simulated sensors -------------------------------------------------------------------------------


def test_simulated_recordings_are_deterministic_and_independent():
    one = sim.biotac_recordings(seed=3, classes=["metal", "sponge"], objects=1, trials=2,
                                motions=["slide_left"])
    again = sim.biotac_recordings(seed=3, classes=["sponge"], objects=1, trials=2,
                                  motions=["static", "slide_left"])
    # The same recording whatever else is simulated alongside it.
    assert one[2].name == again[1].name == "sponge-1-t01-slide_left"
    assert dict(one[2].channels) == dict(again[1].channels)
    other = sim.biotac_recordings(seed=4, classes=["sponge"], objects=1, trials=1, motions=["slide_left"])
    assert not np.array_equal(other[0].channels["pac"].data, one[2].channels["pac"].data)


def test_biotac_layout():
    r = sim.biotac_recordings(classes=["wood"], objects=1, trials=1, motions=["static"])[0]
    c = r.channels
    assert c["pac"].fs == 2200.0 and c["pdc"].fs == 100.0 and c["electrodes"].data.shape == (1500, 19)
    assert c["pac"].n == 22 * c["pdc"].n  # 22 vibration samples per 100 Hz row
    assert r.label == "wood-1" and r.meta["levels"] == {"material": "wood"}
    assert r.meta["label_level"] == "object"
    assert dict(r.group) == {"object": "wood-1", "trial": "01", "motion": "static"}
    columns, rows = sim.biotac_rows(r)
    assert columns[:4] == ["time", "pdc", "pac_01", "pac_02"] and columns[-1] == "e19"
    assert rows.shape == (1500, 45)
    assert np.array_equal(rows[:, 2:24].ravel(), c["pac"].data)
    assert np.array_equal(rows[:, 1], c["pdc"].data) and rows[1, 0] == 0.01


def test_array_and_soft_sensor_layout():
    frames = sim.array_recordings(materials=["sponge"], trials=1)[0].channels["taxels"]
    assert frames.data.shape == (100, 44, 44) and frames.fs == 100.0
    assert np.array_equal(frames.data, np.rint(frames.data))
    assert 0 <= frames.data.min() and frames.data.max() <= 255
    palpations = sim.soft3axis_recordings(materials=["denim"], trials=1)
    assert [r.group["motion"] for r in palpations] == ["palpation_1", "palpation_2", "palpation_3"]
    assert palpations[0].channels["sensor"].data.shape == (1000, 3)
    assert palpations[0].channels["force"].fs == 1000.0
    assert 10.0 <= palpations[0].meta["velocity_mm_s"] <= 20.0


def test_simulator_rejects_bad_arguments():
    with pytest.raises(sim.SimulationError, match="unknown simulated sensor 'gelsight'"):
        sim.simulate_recordings("gelsight")
    with pytest.raises(sim.SimulationError, match="unknown material class.*glass"):
        sim.biotac_recordings(classes=["glass"])
    with pytest.raises(sim.SimulationError, match="trials must be a positive integer, got 0"):
        sim.array_recordings(trials=0)


# -- splits and classifiers --------------------------------------------------------------------------


def test_one_per_object_splits():
    objects = ["a", "a", "a", "b", "b", "c"]
    splits = methods.one_per_object_splits(objects, 5, seed=1)
    assert len(splits) == 5
    for train, test in splits:
        assert sorted(objects[i] for i in test) == ["a", "b"]  # c has a single trial: always trained on
        assert set(train) | set(test) == set(range(6)) and not set(train) & set(test)
    held = methods.leave_object_out_splits(objects)
    assert [test.tolist() for _, test in held] == [[0, 1, 2], [3, 4], [5]]


def _clusters(positions, per_class=12, seed=0):
    rng = np.random.default_rng(seed)
    X = np.concatenate([p + 0.3 * rng.standard_normal((per_class, 4)) for p in positions])
    y = np.repeat([f"c{k}" for k in range(len(positions))], per_class)
    return X, y


def test_pairwise_svm_decisions_equal_the_binary_svms():
    X, y = _clusters([0.0, 3.0, 6.0])
    model = methods.PairwiseEliminationSVM(palpations=1).fit(X, y)
    z = model.scaler_.transform(X)
    for pair, (i, j) in enumerate(model.pairs_):
        mask = (y == model.classes_[i]) | (y == model.classes_[j])
        svm = SVC(kernel="rbf", gamma=0.5, C=1.0).fit(z[mask], y[mask])
        expected = np.searchsorted(model.classes_, svm.predict(z[:20]))
        assert [model.pair_winners(row)[pair] for row in z[:20]] == expected.tolist()


def test_pairwise_elimination_keeps_the_best_half():
    X, y = _clusters([0.0, 10.0, 20.0, 30.0])
    model = methods.PairwiseEliminationSVM(palpations=2).fit(np.hstack([X, X]), y)
    # Palpation 1 at 12 votes c1 (3 wins), c2 (2), c0 (1), c3 (0): c1 and c2 stay. Palpation 2 at 30 looks
    # like c3, which is gone, so the nearer candidate c2 wins; on its own palpation 2 would say c3.
    unknown = np.concatenate([np.full(4, 12.0), np.full(4, 30.0)])
    assert model.predict(unknown[None, :]).tolist() == ["c2"]
    single = methods.PairwiseEliminationSVM(palpations=1).fit(X, y)
    assert single.predict(np.full((1, 4), 30.0)).tolist() == ["c3"]
    with pytest.raises(MethodError, match="rows must hold 2 palpations of equal width"):
        methods.PairwiseEliminationSVM(palpations=2).fit(np.hstack([X, X[:, :3]]), y)
    with pytest.raises(ValueError, match="X has 7 features, but PairwiseEliminationSVM is expecting 8"):
        model.predict(np.zeros((1, 7)))


def test_nearest_spatial_period_uses_the_class_spread():
    X = np.array([[0.9], [1.1], [1.0], [1.0], [1.0], [3.0], [1.0], [2.0]])
    y = np.array(["fine"] * 4 + ["coarse"] * 4)
    model = methods.NearestSpatialPeriod().fit(X, y)
    # fine: mean 1.0, std 0.0707; coarse: mean 1.75, std 0.829. 1.4 is nearer fine's mean but 5.7 of its
    # standard deviations away, and 0.42 of coarse's.
    assert model.predict([[1.4], [1.02]]).tolist() == ["coarse", "fine"]


def test_shrunk_gaussian_is_bayes_rule_with_full_covariances():
    rng = np.random.default_rng(2)
    X = np.vstack([rng.normal(0, 1, (30, 2)) @ [[1, 0.8], [0, 0.5]], rng.normal(2, 1, (10, 2))])
    y = np.array(["a"] * 30 + ["b"] * 10)
    model = methods.ShrunkGaussian(shrinkage=0.0).fit(X, y)
    points = np.array([[0.5, 0.5], [1.5, 1.0], [3.0, 2.0]])
    a, b = X[:30], X[30:]
    density = np.column_stack([0.75 * multivariate_normal(a.mean(0), np.cov(a.T, ddof=0)).pdf(points),
                               0.25 * multivariate_normal(b.mean(0), np.cov(b.T, ddof=0)).pdf(points)])
    assert np.allclose(model.predict_proba(points), density / density.sum(axis=1, keepdims=True), rtol=1e-9)
    shrunk = methods.ShrunkGaussian(shrinkage=1.0).fit(X, y)  # identity covariances: nearest mean + prior
    assert np.allclose(shrunk.precisions_, np.eye(2))


def test_motion_combinations():
    # Three motions, two features each; 1-NN on training rows recalls their labels exactly.
    train = np.array([[0, 0, 0, 0, 0, 0], [9, 9, 9, 9, 9, 9]], dtype=float)
    y = np.array(["a", "b"])
    test = np.array([[0, 0, 9, 9, 9, 9], [0, 0, 0, 0, 9, 9]], dtype=float)
    def combination(mode, blocks=3, seed=0):
        return methods.MotionCombination(StandardScaler(), KNeighborsClassifier(1), blocks, mode, seed)

    assert combination("voting").fit(train, y).predict(test).tolist() == ["b", "a"]
    assert combination("probabilities").fit(train, y).predict(test).tolist() == ["b", "a"]
    joined = combination("concatenation").fit(train, y)
    # Standardised blocks side by side: the first test row is nearer "b" in 4 of 6 coordinates.
    assert joined.predict(test).tolist() == ["b", "a"]
    tie = combination("voting", blocks=2, seed=5)
    answers = tie.fit(train[:, :4], y).predict(np.tile([0, 0, 9, 9], (40, 1)).astype(float))
    assert set(answers) == {"a", "b"}  # one vote each: a seeded coin decides
    assert np.array_equal(answers, tie.predict(np.tile([0, 0, 9, 9], (40, 1)).astype(float)))


# -- datasets and compare ----------------------------------------------------------------------------


def test_dataset_levels_and_errors():
    data = Dataset.from_recordings("sim", sim.array_recordings(materials=["FSR", "copper"], trials=2))
    assert data.label_level == "material" and data.levels() == ("material", "property")
    assert data.y("property").tolist() == ["soft-rough"] * 2 + ["rigid-smooth"] * 2
    assert data.summary().startswith("sim: 4 recordings of 2 objects; levels material (2), property (2)")
    with pytest.raises(MethodError, match="has no level 'colour'"):
        data.y("colour")
    unlabelled = Recording("x", {"v": Trace(np.zeros(8), 10.0, "-")}, {"vibration": "v"})
    with pytest.raises(MethodError, match="recording 'x' has no label"):
        Dataset.from_recordings("d", [unlabelled])
    with pytest.raises(MethodError, match="unknown method.*nope"):
        compare(data, ["nope"])
    with pytest.raises(MethodError, match="method huang needs vibration, which dataset 'sim' lacks"):
        compare(data, ["huang"])
    assert methods.applicable(data) == ["xie"]


@pytest.fixture(scope="module")
def soft():
    return Dataset.from_recordings("sim:soft3axis", sim.soft3axis_recordings(
        materials=["aluminium", "rubber", "denim", "nylon"], trials=12))


def test_chathuranga_end_to_end(soft):
    results = compare(soft, repeats=4)
    by = {r.classifier: r for r in results}
    assert list(by) == ["pairwise-svm", "spatial-period", "neural-net"]
    assert by["pairwise-svm"].accuracy_mean > 0.7 and by["pairwise-svm"].motions == "3 palpation(s)"
    assert by["pairwise-svm"].n_samples == 48 and len(by["pairwise-svm"].accuracy) == 4  # repeats=4 holdouts
    assert all(r.accuracy_mean > 0.4 for r in results)  # chance: 0.25
    assert 0 < by["pairwise-svm"].classify_seconds < 0.1 and by["pairwise-svm"].paper == "89 %, 280 us"
    table = format_comparison(results)
    assert table.splitlines()[0].split()[:3] == ["method", "features", "classifier"]
    assert "pairwise-svm" in table


def test_compare_skips_a_method_the_data_cannot_feed():
    short = [Recording(f"r{i}", {"e": Trace(np.ones((20, 4)), 100.0, "-")}, {"electrodes": "e"},
                       label=f"c{i % 2}") for i in range(6)]
    # 20 rows at 100 Hz: Xie needs 1 s, so it cannot run; Hoelscher et al.'s electrode features can.
    with pytest.warns(methods.MethodSkipped, match="method xie skipped: xie_sequences works on none of 6"):
        results = compare(short, repeats=1)
    assert {r.method for r in results} == {"hoelscher"} and {r.feature_set for r in results} == {"chitta"}
    with pytest.raises(MethodError, match=r"method xie: xie_sequences works on none.*1 s of electrodes"):
        compare(short, ["xie"])


def test_a_baseline_without_its_value_is_reported_not_dropped(soft):
    no_speed = [replace(r, meta={k: v for k, v in r.meta.items() if k != "velocity_mm_s"})
                for r in soft.recordings]
    comparison = methods.compare_methods(no_speed, ["chathuranga"], repeats=2)
    assert {r.feature_set for r in comparison.results} == {"chathuranga4", "chathuranga_net"}
    assert comparison.outcome == {"chathuranga": "ran (2 results); the spatial-period baseline not run: "
                                                 "chathuranga_period needs the palpation velocity "
                                                 f"meta['velocity_mm_s'] of recording {soft.recordings[0].name!r}"}


def test_notes_name_their_method_and_are_whole():
    import warnings as w

    with w.catch_warnings(record=True) as caught:
        w.simplefilter("always")
        w.warn("lbfgs failed to converge:\nSTOP: TOTAL NO. OF ITERATIONS\n\n  Increase max_iter.", UserWarning,
               stacklevel=1)
    assert warning_notes(caught) == ("UserWarning: lbfgs failed to converge: STOP: TOTAL NO. OF ITERATIONS "
                                     "Increase max_iter.",)


# -- scikit-learn estimator checks ---------------------------------------------------------------------


def test_xie_features_keep_the_estimator_contract_on_sequence_vectors():
    """What the checks above cannot feed XieFeatures (3n-wide rows): pickling, repeated fits, row order and
    subsets, input types, an unchanged state after transform and a clear refusal of another width."""
    rng = np.random.default_rng(5)
    X = rng.normal(3.0, 1.5, (24, 3 * 100))  # 100 samples per sequence: wavelet level 4 without boundary effects
    step = XieFeatures()
    assert step.fit(X) is step and clone(step).get_params() == {}
    out = step.transform(X)
    state = pickle.dumps(step.__dict__)
    assert np.array_equal(step.transform(X), out) and pickle.dumps(step.__dict__) == state
    assert np.array_equal(XieFeatures().fit(X).transform(X), out)  # fit is idempotent
    assert np.array_equal(pickle.loads(pickle.dumps(step)).transform(X), out)
    order = rng.permutation(len(X))
    assert np.allclose(step.transform(X[order]), out[order], rtol=1e-12, atol=1e-12)
    assert np.allclose(step.transform(X[5:9]), out[5:9], rtol=1e-12, atol=1e-12)
    assert np.allclose(step.transform(X.tolist()), out, rtol=1e-12, atol=1e-12)
    assert np.allclose(XieFeatures().fit(np.asfortranarray(X)).transform(X), out, rtol=1e-12, atol=1e-12)
    whole = np.rint(X).astype(np.int64)
    assert np.allclose(XieFeatures().fit(whole).transform(whole),
                       XieFeatures().fit(whole.astype(np.float64)).transform(whole), rtol=1e-12)
    with pytest.raises(ValueError, match="features"):  # scikit-learn's own check of the width seen in fit
        step.transform(X[:, :30])
    with pytest.raises(RelatedFeatureError, match=r"3n >= 6 entries, got shape \(10,\)"):
        XieFeatures().fit(X[:, :10]).transform(X[:, :10])


@pytest.mark.parametrize(("classes", "defined"), [(("C6S1M1P2X1", "C7S1M1P8X1", "C6S2M1P1X1"), True),
                                                  (("C6S1", "C7S1", "C6S2"), True),
                                                  (("foam", "steel", "oak"), False),
                                                  (("c6", "C7", "C6S2"), False)])
def test_a_methods_r_c_is_defined_where_its_classes_are_taxonomy_codes(classes, defined):
    # r_C was set by hand for one method (fishel), so huang and hoelscher on scans had none.
    from taxonomy.related.scoring import Scores, scored

    confusion = np.array([[3, 1, 0], [0, 4, 0], [2, 0, 2]])  # one miss stays in C6, two change C
    scores = Scores(np.array([0.75]), np.array([0.7]), classes, confusion, 0.0, 0.0, ())
    result = scored(scores, 12, 0.0, method="huang", feature_set="f", classifier="rf", motions="m",
                    level="fine", splitting="s", seed=0)
    if defined:
        assert result.r_c == pytest.approx(1 / 3)
    else:
        assert math.isnan(result.r_c)
