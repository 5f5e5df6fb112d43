"""What else was tried on the BorealTC terrain runs grouped by run (docs/ingest.md, "A real set").

    python benchmarks/borealtc_variants.py [--seeds 5]

Ingests ``../shared/realdata/borealtc`` with the mapping docs/ingest.md shows, cuts 5 s windows (every window
a row, every feature) and prints the pooled accuracy of 5 folds grouped by run at seeds 0 to N-1 (the folds
and the forest's random state), their mean and range, for:

- ``rf``, ``brf``: the product's forests (:func:`taxonomy.learning.evaluation.evaluate_grid`, uncalibrated);
- forest settings, on ``brf``: 500 trees instead of 100; log2 instead of sqrt candidate features per split;
  at least 3 rows per leaf; half the rows per tree; balanced extremely randomised trees (Geurts, Ernst and
  Wehenkel 2006);
- every run weighted alike: a window weighs 1 / (its run's windows), a class's runs share the class's weight
  (the product's pipeline, its forest fitted with these sample weights);
- more training windows: the windows shifted by half a window (2.5 s) added to every fold's training runs;
  the tested windows are the same;
- band energies over spatial frequency: each IMU axis' Welch spectrum read at ``f / v`` cycles per metre (``v``
  the window's mean wheel speed), ten log-spaced bands from 0.5 to 200 per metre, and ``log v``: roughness is a
  property of the ground, its temporal frequency one of the speed it is driven at.

It then prints each terrain's one-vs-rest AUROC of ``brf`` trained *with* that terrain (same folds): what the
features can tell of a terrain once it is labelled, beside what a novelty score can tell of it unseen
(docs/trust.md, open set). Takes about a minute and a half on two cores; skips with a line where the recordings are
not there.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import tempfile
import warnings
from collections import Counter
from collections.abc import Callable

import numpy as np
from bench_realdata import BOREALTC, docs_mapping
from scipy.signal import welch
from sklearn.ensemble import ExtraTreesClassifier, RandomForestClassifier
from sklearn.metrics import roc_auc_score

from features import recordings
from features.recordings import Windowing, feature_space
from features.space import FeatureSpace, drop_nan_columns
from scanner.storage import ingest
from taxonomy.learning.evaluation import cv_splits, evaluate_grid, make_pipeline

WINDOW = 5.0
SPATIAL_EDGES = np.geomspace(0.5, 200.0, 11)
"""Band edges in cycles per metre."""


def forest(seed: int, **settings) -> RandomForestClassifier:
    return RandomForestClassifier(**{"n_estimators": 100, "class_weight": "balanced", "random_state": seed,
                                     "n_jobs": 1, **settings})


FORESTS: dict[str, Callable[[int], object]] = {
    "rf": lambda seed: "rf",
    "brf": lambda seed: "brf",
    "brf, 500 trees": lambda seed: forest(seed, n_estimators=500),
    "brf, log2 features per split": lambda seed: forest(seed, max_features="log2"),
    "brf, >= 3 rows per leaf": lambda seed: forest(seed, min_samples_leaf=3),
    "brf, half the rows per tree": lambda seed: forest(seed, max_samples=0.5),
    "balanced extra trees": lambda seed: ExtraTreesClassifier(n_estimators=100, class_weight="balanced",
                                                              random_state=seed, n_jobs=1),
}


def grouped_accuracy(space: FeatureSpace, classifier, seed: int) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        (result,) = evaluate_grid(space, classifiers=[classifier], set_sizes=[None], feature_sets={"all": None},
                                  seed=seed, workers=2, calibrate=False, group_by="recording")
    return result.accuracy_pooled


def run_weights(y: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Each row 1 / (rows of its group) / (groups of its class): every run alike, every class alike."""
    rows = Counter(groups)
    runs = Counter(y[np.unique(groups, return_index=True)[1]])
    return np.array([1.0 / rows[g] / runs[c] for c, g in zip(y, groups, strict=True)])


def loop_accuracy(space: FeatureSpace, seed: int, weighted: bool = False,
                  extra: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> float:
    """The product's pipeline (``brf``, every feature) on the product's grouped folds, fitted here so that it can
    take sample weights or extra training rows ``(X, y, groups)``."""
    X, y, groups = space.X, np.asarray(space.label_text), np.asarray(space.groups)
    splits, _ = cv_splits(y, groups, 5, seed)
    right = np.zeros(len(y), dtype=bool)
    for train, test in splits:
        X_train, y_train, g_train = X[train], y[train], groups[train]
        if extra is not None:
            keep = np.isin(extra[2], g_train)
            X_train = np.vstack([X_train, extra[0][keep]])
            y_train, g_train = np.concatenate([y_train, extra[1][keep]]), np.concatenate([g_train, extra[2][keep]])
        fit = {"classify__sample_weight": run_weights(y_train, g_train)} if weighted else {}
        pipeline = make_pipeline("brf", None, seed, columns=space.columns).fit(X_train, y_train, **fit)
        right[test] = pipeline.predict(X[test]) == y[test]
    return float(right.mean())


def without_first(run, seconds: float):
    """The run with every channel's first ``seconds`` cut off: its windows then start that much later."""
    channels = {name: dataclasses.replace(trace, data=trace.data[int(round(seconds * trace.fs)):])
                for name, trace in run.channels.items()}
    return dataclasses.replace(run, channels=channels)


def shifted_rows(runs, space: FeatureSpace) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The feature rows of the windows shifted by half a window, with their class and fold group."""
    group_of = {scan.split("#")[0]: (label, group)
                for scan, label, group in zip(space.scan_ids, space.label_text, space.groups, strict=True)}
    rows = [(row, *group_of[run.name]) for run in runs if run.name in group_of
            for row in recordings.recording_rows(without_first(run, WINDOW / 2), Windowing(WINDOW, "rows"))]
    X = np.array([[row.get(c, np.nan) for c in space.columns] for row, _, _ in rows])
    keep = np.isfinite(X).all(axis=1)
    return X[keep], np.array([r[1] for r in rows])[keep], np.array([r[2] for r in rows])[keep]


def spatial_bands(run, start: float, stop: float) -> list[float]:
    """``log v`` and the log band energies over spatial frequency of the six IMU axes in ``[start, stop)``."""
    speed = run.channels["speed"]
    wheels = speed.data[int(round(start * speed.fs)):int(round(stop * speed.fs))]
    v = max(float(np.mean(np.abs(wheels))) if len(wheels) else 0.0, 0.02)
    values = [math.log(v)]
    for name in ("accel", "gyro"):
        trace = run.channels[name]
        x = trace.data[int(round(start * trace.fs)):int(round(stop * trace.fs))]
        f, power = welch(x - x.mean(axis=0), fs=trace.fs, nperseg=min(128, len(x)), axis=0)
        k = f / v
        for axis in range(x.shape[1]):
            for low, high in zip(SPATIAL_EDGES[:-1], SPATIAL_EDGES[1:], strict=True):
                band = (k >= low) & (k < high)
                values.append(math.log(power[band, axis].sum() * v + 1e-12) if band.any() else math.nan)
    return values


def with_spatial_bands(runs, space: FeatureSpace) -> FeatureSpace:
    by_name = {run.name: run for run in runs}
    rows = []
    for scan in space.scan_ids:
        name, _, window = scan.partition("#w")
        k = int(window) if window else 0
        rows.append(spatial_bands(by_name[name], k * WINDOW, (k + 1) * WINDOW))
    names = ["log_speed"] + [f"{s}{axis}_band{b}" for s in ("accel", "gyro") for axis in range(3)
                             for b in range(len(SPATIAL_EDGES) - 1)]
    columns = (*space.columns, *(f"generic.spatial.{n}" for n in names))
    return dataclasses.replace(space, X=np.hstack([space.X, np.array(rows)]), columns=columns)


def one_vs_rest(space: FeatureSpace, seed: int) -> dict[str, float]:
    X, y, groups = space.X, np.asarray(space.label_text), np.asarray(space.groups)
    splits, _ = cv_splits(y, groups, 5, seed)
    classes = sorted(set(y))
    probability = np.zeros((len(y), len(classes)))
    for train, test in splits:
        pipeline = make_pipeline("brf", None, seed, columns=space.columns).fit(X[train], y[train])
        probability[test] = pipeline.predict_proba(X[test])
    return {c: roc_auc_score(y == c, probability[:, j]) for j, c in enumerate(classes)}


def line(name: str, values: list[float]) -> None:
    shown = " ".join(f"{100 * v:5.1f}" for v in values)
    print(f"  {name:38s} {shown}   mean {100 * np.mean(values):5.1f} ({100 * min(values):.1f}-{100 * max(values):.1f})",
          flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", type=int, default=5)
    seeds = range(parser.parse_args().seeds)
    if not BOREALTC.is_dir():
        print(f"skipped: the real recordings are not at {BOREALTC}")
        return
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as folder:
        with ingest.SetWriter(folder, "borealtc") as writer:
            ingest.ingest(BOREALTC, ingest.parse_mapping(docs_mapping(), "borealtc"), sink=writer)
            writer.commit()
        runs = ingest.load_recordings(ingest.set_folder(folder, "borealtc"))
        space, _ = feature_space(runs, Windowing(WINDOW, "rows"), workers=2)
        space, _ = drop_nan_columns(space)
        shifted = shifted_rows(runs, space)
        spatial, _ = drop_nan_columns(with_spatial_bands(runs, space))
    print(f"BorealTC: {len(space)} windows x {space.X.shape[1]} features, 5 folds grouped by run; "
          f"pooled accuracy % at seeds {', '.join(map(str, seeds))}")
    for name, classifier in FORESTS.items():
        line(name, [grouped_accuracy(space, classifier(seed), seed) for seed in seeds])
    line("brf, fitted here (as brf)", [loop_accuracy(space, seed) for seed in seeds])
    line("brf, every run weighted alike", [loop_accuracy(space, seed, weighted=True) for seed in seeds])
    line(f"brf, + {len(shifted[0])} shifted training windows", [loop_accuracy(space, seed, extra=shifted)
                                                                for seed in seeds])
    line(f"brf, + spatial bands ({spatial.X.shape[1] - space.X.shape[1]} kept)",
         [grouped_accuracy(spatial, "brf", seed) for seed in seeds])
    auroc = [one_vs_rest(space, seed) for seed in seeds]
    print("one terrain against the rest, brf trained with it, AUROC (mean over the seeds): "
          + ", ".join(f"{c} {np.mean([a[c] for a in auroc]):.3f}" for c in auroc[0]))


if __name__ == "__main__":
    main()
