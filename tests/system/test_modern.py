"""The modern feature families end to end: no random-kernel transform sees a test fold (the leak test on noise),
each fold's kernels are fitted on its training rows, the paper's protocol refuses them, and a MiniRocket model
round trips: the system tests (whole cross-validated evaluations, seconds of CPU each)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pycatch22 = pytest.importorskip("pycatch22", reason="the modern families need texplorer[modern]")
kymatio_1d = pytest.importorskip("kymatio.scattering1d.frontend.numpy_frontend",
                                 reason="the modern families need texplorer[modern]")
rocket = pytest.importorskip("sktime.transformations.rocket", reason="the modern families need texplorer[modern]")
from features.random_kernels import RandomKernels  # noqa: E402
from features.recordings import feature_space  # noqa: E402
from scanner.scan import Recording, Trace  # noqa: E402
from taxonomy.learning.evaluation import EvaluationError, evaluate, make_pipeline  # noqa: E402


def test_minirocket_step_is_sktime_minirocket():
    rng = np.random.default_rng(1)
    X = rng.standard_normal((12, 3000))
    columns = [f"signal.v_ts.{k:05d}" for k in range(3000)]
    step = RandomKernels("minirocket", columns, random_state=7).fit(X)
    reference = rocket.MiniRocket(random_state=7).fit(X[:, None, :])
    np.testing.assert_array_equal(step.transform(X), np.asarray(reference.transform(X[:, None, :])))
    assert step.widths_ == [9996]


@pytest.fixture(scope="module")
def noise_space():
    """60 recordings of pure noise with labels drawn at random: nothing to learn."""
    rng = np.random.default_rng(11)
    labels = rng.permutation(["a"] * 30 + ["b"] * 30)
    recordings = [Recording(f"n{k:02d}", {"acc": Trace(rng.standard_normal(6000), 3000.0, "g")},
                            {"vibration": "acc"}, label=str(labels[k])) for k in range(60)]
    space, _ = feature_space(recordings, chosen=("signal.vibration",))
    return space


def test_leak_kernels_and_selection_stay_inside_the_folds(noise_space):
    """Fitted on every row before splitting (the transform, scaling and FQ selection of 10 of ~10,000
    kernel features), the shuffled labels are predicted well above chance: the selection saw the test
    rows. The evaluation's pipeline fits them on the training folds only and stays at chance.

    With 60 rows the accuracy of guessing has a standard deviation of sqrt(0.25 / 60) = 0.065: 0.70 is 3
    deviations above chance, 0.65 is 2.3."""
    space = noise_space
    y = space.y(space.label_level)
    nested = evaluate(space, "lda", space.label_level, n_features=10, feature_set="minirocket", folds=5)
    assert nested.accuracy.mean() < 0.65
    leaky_front = make_pipeline("lda", 10, kernels="minirocket", columns=space.columns)[:-1].fit(space.X, y)
    leaked = space.subset(list(space.columns[:10]))
    leaked = dataclasses.replace(leaked, X=leaky_front.transform(space.X))
    leaky = evaluate(leaked, "lda", space.label_level, n_features=None, folds=5)
    assert leaky.accuracy.mean() > 0.70


def test_each_folds_kernels_are_fitted_on_its_training_rows_only(noise_space):
    """The kernel step of a fold transforms exactly as one fitted on that fold's training rows, and not as
    one fitted on every row (MiniRocket's biases are quantiles of the training series' convolutions)."""
    from taxonomy.learning.evaluation import cv_splits

    space = noise_space
    y = space.y(space.label_level)
    splits, _ = cv_splits(y, space.groups, 5, 0)
    train, test = splits[0]
    pipeline = make_pipeline("lda", 10, kernels="minirocket", columns=space.columns)
    front = pipeline[:-1].fit(space.X[train], y[train])
    alone = RandomKernels("minirocket", space.columns).fit(space.X[train])
    every = RandomKernels("minirocket", space.columns).fit(space.X)
    kernels = front.named_steps["kernels"].transform(space.X[test])
    np.testing.assert_array_equal(kernels, alone.transform(space.X[test]))
    assert not np.array_equal(kernels, every.transform(space.X[test]))


def test_paper_protocol_refuses_random_kernels(noise_space):
    space = noise_space
    with pytest.raises(EvaluationError, match="nested protocol only"):
        evaluate(space, "lda", space.label_level, feature_set="minirocket", protocol="paper")


def test_a_minirocket_model_round_trips_and_classifies(noise_space, tmp_path):
    """train -> save -> load -> predict_top: the kernel step is saved (skops, its types trusted by name)
    and a row's signal columns are what it needs."""
    from taxonomy.learning.models import load_model, predict_top, required_inputs, save_model, train_model

    codes = {"a": "C1S1M1P1X1", "b": "C2S1M1P1X1"}  # models are of the taxonomy's labels
    noise_space = dataclasses.replace(noise_space, label_text=[codes[t] for t in noise_space.label_text],
                                      label_level=None, levels={})
    model = train_model(noise_space, level="fine", n_features=3, classifier="lda", feature_set="minirocket")
    assert all(name.startswith("minirocket.vibration.") for name in model.selected)
    loaded = load_model(save_model(model, tmp_path / "m.skops"))
    row = dict(zip(noise_space.columns, noise_space.X[0], strict=True))
    assert predict_top(loaded, row, 2) == predict_top(model, row, 2)
    assert set(required_inputs(loaded)) == set(noise_space.columns)
    del row[noise_space.columns[5]]
    from taxonomy.learning.models import ModelError

    with pytest.raises(ModelError, match="missing feature value"):
        predict_top(loaded, row, 2)


def test_an_open_set_evaluation_fits_the_kernel_step_of_its_set(monkeypatch):
    """Whole classes held out: every pipeline of a MiniRocket set (the calibrated one of each fold and those
    of its rejection rule) transforms the signal columns with kernels fitted on its own training rows."""
    from scanner.simulation.contrasts import contrast_recordings
    from taxonomy.learning import evaluation

    space, _ = feature_space(contrast_recordings("timing", per_class=6), chosen=("signal.vibration",))
    fitted = []
    original = evaluation.fit_pipeline

    def spy(*args, **kwargs):
        pipeline = original(*args, **kwargs)
        fitted.append(pipeline)
        return pipeline

    monkeypatch.setattr(evaluation, "fit_pipeline", spy)
    result = evaluation.evaluate_open_set(space, "lda", space.label_level, n_features=3, folds=3,
                                          feature_set="minirocket", calibrate=False)
    assert fitted and all("kernels" in pipeline.named_steps for pipeline in fitted)
    assert all(pipeline.named_steps["kernels"].widths_ for pipeline in fitted)
    assert np.isfinite(result.auroc)
