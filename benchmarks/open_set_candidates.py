"""Novelty scores compared on the folds of ``texplorer evaluate --open-set`` (docs/trust.md#choosing-the-score).

    python benchmarks/open_set_candidates.py FEATURES.csv [FEATURES.csv ...]

For each feature table (``texplorer features`` of a database, or of a set such as BorealTC's windows) the
outer folds are those of :func:`taxonomy.learning.evaluation.evaluate_open_set` (random forest, fine level,
10 FQ features, 5 folds grouped by the table's ``sample_id``, a fifth of the classes held out per fold, seed
0) and the inner rounds those of :func:`taxonomy.learning.openset.learn_rejection`. Every candidate score is
computed on the same inner rounds and outer test rows; each combination averages its parts after
standardising them on the inner rounds' known rows; each threshold is learned inside the training rows as the
product's rule learns its own (:func:`taxonomy.learning.openset.choose_threshold` on the scores of grouped
folds that keep every training class, :func:`taxonomy.learning.openset.known_scores`). The previous rule's row
uses its own threshold, a normal fit to the leave-classes-out rounds' known rows. A final row is the
product's ``evaluate_open_set`` itself. Prints one markdown
table per file; it takes a few minutes per file on two cores.

Candidates: ``u`` surprisal of the forest's top class (Hendrycks and Gimpel 2017); ``m`` Mahalanobis
distance ratio in the model's selected features (Lee et al. 2018); ``knn-k`` distance to the k-th nearest
training scan over all features, standardised, rows scaled to unit length (Sun et al. 2022) or not
(``raw``); ``lw`` Mahalanobis over all features with a Ledoit-Wolf shrunk covariance shared by the classes
(``pca`` in the principal components holding 95 % of the variance); ``iforest`` an isolation forest (Liu et
al. 2008) over all features; ``groups-mean``/``groups-max`` the nearest-scan distance per feature group
(:meth:`features.registry.ScanRegistry.column_groups`), standardised, averaged or the largest; ``w`` the
surprisal of a balanced random forest over every feature (:func:`taxonomy.learning.openset.fit_wide`); ``learned``
a logistic regression on the standardised parts, fitted to tell the inner rounds' held-out classes from their
known rows (stacked generalisation, Wolpert 1992), instead of their plain mean.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Callable

import numpy as np
from scipy.stats import norm
from sklearn.covariance import LedoitWolf
from sklearn.decomposition import PCA
from sklearn.ensemble import IsolationForest
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import euclidean_distances

from features.space import FeatureSpace, drop_nan_columns
from taxonomy.learning.calibration import grouped_splits
from taxonomy.learning.evaluation import cv_splits, evaluate_open_set, fit_pipeline
from taxonomy.learning.metrics import auroc
from taxonomy.learning.openset import (
    MAX_ACCURACY_DROP,
    ROUNDS,
    choose_threshold,
    class_folds,
    confidence,
    feature_groups,
    fit_distance,
    fit_neighbours,
    fit_wide,
    mahalanobis,
    unit_rows,
    wide_surprisal,
)

SEED = 0
Scorer = Callable[[np.ndarray, np.ndarray], Callable[[np.ndarray], np.ndarray]]
"""``fit(X_train, y_train)`` -> ``score(X)``, higher = more novel."""


def _standardise(X: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    median = np.nan_to_num(np.nanmedian(X, axis=0))
    filled = np.where(np.isfinite(X), X, median)
    mean, sd = filled.mean(axis=0), filled.std(axis=0)
    sd = np.where(sd > 1e-12, sd, 1.0)
    return lambda Z: (np.where(np.isfinite(Z), Z, median) - mean) / sd


def knn(k: int, unit: bool) -> Scorer:
    def fit(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        scale = _standardise(X)
        reference = unit_rows(scale(X)) if unit else scale(X)

        def score(Z: np.ndarray) -> np.ndarray:
            query = unit_rows(scale(Z)) if unit else scale(Z)
            d = euclidean_distances(query, reference)
            return np.log(np.maximum(np.partition(d, min(k, len(reference)) - 1, axis=1)[:, min(k, len(reference)) - 1],
                                     1e-12))
        return score
    return fit


def ledoit_wolf(variance: float | None) -> Scorer:
    def fit(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        scale = _standardise(X)
        Z = scale(X)
        pca = PCA(n_components=variance, svd_solver="full", random_state=SEED).fit(Z) if variance else None
        Z = pca.transform(Z) if pca is not None else Z
        classes, index = np.unique(y, return_inverse=True)
        means = np.array([Z[index == c].mean(axis=0) for c in range(classes.size)])
        precision = LedoitWolf(assume_centered=True).fit(Z - means[index]).precision_

        def score(Q: np.ndarray) -> np.ndarray:
            Q = scale(Q)
            Q = pca.transform(Q) if pca is not None else Q
            return np.log(np.maximum(mahalanobis(Q, means, precision), 1e-12))
        return score
    return fit


def class_conditional(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """The negative Gaussian log-likelihood of the most likely class, each class with its own covariance: in the
    principal components holding 95 % of the variance, ``S_c`` shrunk towards the shared Ledoit-Wolf covariance
    ``S`` by the class's size, ``(n_c S_c + p S) / (n_c + p)`` for ``p`` components (regularised discriminant
    analysis, Friedman 1989: a material has 3-6 scans, too few for a covariance of its own)."""
    scale = _standardise(X)
    pca = PCA(n_components=0.95, svd_solver="full", random_state=SEED).fit(scale(X))
    Z = pca.transform(scale(X))
    classes, index = np.unique(y, return_inverse=True)
    means = np.array([Z[index == c].mean(axis=0) for c in range(classes.size)])
    shared = LedoitWolf(assume_centered=True).fit(Z - means[index]).covariance_
    p = Z.shape[1]
    precisions, log_dets = [], []
    for c in range(classes.size):
        rows = Z[index == c] - means[c]
        covariance = (rows.T @ rows + p * shared) / (len(rows) + p)
        precisions.append(np.linalg.inv(covariance))
        log_dets.append(np.linalg.slogdet(covariance)[1])

    def score(Q: np.ndarray) -> np.ndarray:
        Q = pca.transform(scale(Q))
        terms = [np.einsum("ij,jk,ik->i", Q - mean, precision, Q - mean) + log_det
                 for mean, precision, log_det in zip(means, precisions, log_dets, strict=True)]
        return 0.5 * np.min(terms, axis=0)
    return score


def isolation_forest(X: np.ndarray, y: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    scale = _standardise(X)
    forest = IsolationForest(n_estimators=300, random_state=SEED).fit(scale(X))
    return lambda Z: -forest.score_samples(scale(Z))


BASE: dict[str, Scorer] = {"knn-1": knn(1, True), "knn-1 raw": knn(1, False), "knn-5": knn(5, True),
                           "knn-10": knn(10, True), "lw": ledoit_wolf(None), "lw pca": ledoit_wolf(0.95),
                           "class-conditional": class_conditional, "iforest": isolation_forest}

COMBINATIONS = [("u",), ("m",), ("u", "m"), *((name,) for name in BASE), ("groups-mean",), ("groups-max",), ("w",),
                ("u", "m", "knn-1"), ("u", "lw pca"), ("u", "m", "lw pca"), ("u", "m", "groups-max"),
                ("u", "m", "class-conditional"), ("u", "m", "groups-mean", "class-conditional"),
                ("u", "m", "groups-mean"), ("m", "groups-mean", "w"), ("u", "m", "groups-mean", "w")]

LEARNED = {"learned (u, m, groups-mean)": ("u", "m", "groups-mean"),
           "learned (every score above)": ("u", "m", "groups-mean", *BASE, "groups-max", "w")}
"""Combinations whose weights a logistic regression learns on the inner rounds (:func:`_learned`)."""


def scores(pipeline, X_train, y_train, g_train, X_test, columns) -> dict[str, np.ndarray]:
    """Every base score of the rows ``X_test`` for a model fitted on ``X_train``; group distances by group."""
    distance = fit_distance(pipeline[:-1].transform(X_train), y_train, g_train)
    out = {"u": -np.log(np.maximum(confidence(pipeline, X_test), 1e-12)),
           "m": np.log(np.maximum(mahalanobis(pipeline[:-1].transform(X_test), distance.means, distance.precision)
                                  / distance.scale, 1e-12))}
    for name, fit in BASE.items():
        out[name] = fit(X_train, y_train)(X_test)
    neighbours = fit_neighbours(X_train, y_train, [str(c) for c in pipeline.classes_], columns)
    out["groups"] = neighbours.log_distances(X_test)
    out["w"] = wide_surprisal(fit_wide(X_train, y_train, neighbours, SEED), neighbours, X_test)
    return out


def compare(path: str) -> None:
    space = FeatureSpace.from_csv(path)
    subset, _ = drop_nan_columns(space)
    X, y, groups = np.asarray(subset.X), subset.y("fine"), np.asarray(subset.groups)
    splits, _ = cv_splits(y, groups, 5, SEED, grouping_labels=subset.label_text)
    parts = class_folds(y, len(splits), SEED)
    _, group_of = feature_groups(subset.columns)
    folds = []

    def fit(rows: np.ndarray, calibrate: bool):
        return fit_pipeline(X[rows], y[rows], groups[rows], "rf", 10, SEED, calibrate, columns=subset.columns,
                            materials=np.asarray(subset.label_text)[rows] if calibrate else None)

    for k, (_, sample_test) in enumerate(splits):
        held = np.isin(y, parts[k % len(parts)])
        in_test = np.zeros(len(y), dtype=bool)
        in_test[sample_test] = True
        train, test = np.flatnonzero(~held & ~in_test), np.flatnonzero((in_test & ~held) | held)
        inner, inner_unknown, inner_correct = [], [], []
        for r, held_classes in enumerate(class_folds(y[train], ROUNDS, SEED)):
            is_held = np.isin(y[train], held_classes)
            known = np.flatnonzero(~is_held)
            splits_r = grouped_splits(y[train][known], groups[train][known], ROUNDS, SEED + r)
            if not splits_r:
                continue
            part_train, part_test = splits_r[r % len(splits_r)]
            rows_train = train[known[part_train]]
            rows_test = np.concatenate([train[known[part_test]], train[np.flatnonzero(is_held)]])
            if np.unique(y[rows_train]).size < 2:
                continue
            pipeline = fit(rows_train, False)
            inner.append(scores(pipeline, X[rows_train], y[rows_train], groups[rows_train], X[rows_test],
                                subset.columns))
            inner_unknown.append(~np.isin(y[rows_test], y[rows_train]))
            inner_correct.append(pipeline.predict(X[rows_test]) == y[rows_test])
        known, known_unknown, known_correct = [], [], []
        for part_train, part_test in grouped_splits(y[train], groups[train], ROUNDS, SEED):
            rows_train, rows_test = train[part_train], train[part_test]
            pipeline = fit(rows_train, False)
            known.append(scores(pipeline, X[rows_train], y[rows_train], groups[rows_train], X[rows_test],
                                subset.columns))
            known_unknown.append(~np.isin(y[rows_test], y[rows_train]))
            known_correct.append(pipeline.predict(X[rows_test]) == y[rows_test])
        pipeline = fit(train, True)
        fold = {"inner": {n: np.concatenate([s[n] for s in inner]) for n in inner[0]},
                "unknown": np.concatenate(inner_unknown), "correct": np.concatenate(inner_correct),
                "known": {n: np.concatenate([s[n] for s in known]) for n in known[0]},
                "known_unknown": np.concatenate(known_unknown), "known_correct": np.concatenate(known_correct),
                "outer": scores(pipeline, X[train], y[train], groups[train], X[test], subset.columns),
                "is_known": ~held[test], "right": pipeline.predict(X[test]) == y[test]}
        _add_group_scores(fold)
        folds.append(fold)
    print(f"\n{path}: {len(y)} rows, {np.unique(y).size} classes, {int(group_of.max()) + 1} feature groups")
    print("| candidate | AUROC | unseen rejected % | known rejected % | known accuracy % before -> after |")
    print("| --- | --- | --- | --- | --- |")
    print(_row("u + m, normal threshold (the first rule)", folds, lambda f, w: f[w]["u"] + f[w]["m"], normal=True))
    for combination in COMBINATIONS:
        print(_row(" + ".join(combination), folds, lambda f, w, c=combination: _combined(f, w, c)))
    for name, combination in LEARNED.items():
        print(_row(name, folds, lambda f, w, c=combination: _learned(f, w, c)))
    started = time.perf_counter()
    result = evaluate_open_set(space, "rf", "fine", 10, 5, SEED)
    rejected = result.rejected
    known_right = result.y_pred[result.known] == result.y_true[result.known]
    print(f"| texplorer evaluate --open-set ({time.perf_counter() - started:.0f} s) | {result.auroc:.3f} | "
          f"{100 * rejected[~result.known].mean():.1f} | {100 * rejected[result.known].mean():.1f} | "
          f"{100 * known_right.mean():.1f} -> {100 * (known_right & ~rejected[result.known]).mean():.1f} |")


def _standardised(fold: dict, where: str, values: Callable[[dict], np.ndarray]) -> np.ndarray:
    """``values`` of ``where`` (inner or outer rows) standardised on the inner rounds' known rows."""
    reference = values(fold["inner"])[~fold["unknown"]]
    reference = reference[np.isfinite(reference)]
    return (values(fold[where]) - reference.mean()) / max(reference.std(ddof=1), 1e-12)


def _add_group_scores(fold: dict) -> None:
    """``groups-mean`` and ``groups-max`` of the inner and outer rows: each group's log distance standardised
    on the inner rounds' known rows, then averaged or the largest over the groups with a value."""
    known = fold["inner"]["groups"][~fold["unknown"]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mean, sd = np.nanmean(known, axis=0), np.maximum(np.nanstd(known, axis=0, ddof=1), 1e-12)
        for side in ("inner", "known", "outer"):
            z = (fold[side]["groups"] - mean) / sd
            fold[side]["groups-mean"], fold[side]["groups-max"] = np.nanmean(z, axis=1), np.nanmax(z, axis=1)


def _combined(fold: dict, where: str, combination: tuple[str, ...]) -> np.ndarray:
    if len(combination) == 1:
        return fold[where][combination[0]]
    return np.mean([_standardised(fold, where, lambda side, n=name: side[n]) for name in combination], axis=0)


def _learned(fold: dict, where: str, combination: tuple[str, ...]) -> np.ndarray:
    """The log-odds of "held out" by a logistic regression (balanced classes) on the standardised parts, fitted
    on the inner rounds' rows; a missing part counts as its known rows' mean."""
    def parts(side: str) -> np.ndarray:
        return np.nan_to_num(np.column_stack([_standardised(fold, side, lambda s, n=name: s[n])
                                              for name in combination]))
    model = LogisticRegression(class_weight="balanced").fit(parts("inner"), fold["unknown"])
    return model.decision_function(parts(where))


def _row(name: str, folds: list[dict], score: Callable[[dict, str], np.ndarray], normal: bool = False) -> str:
    outer, unknown, right, rejected = [], [], [], []
    for fold in folds:
        inner = score(fold, "inner")
        if normal:  # the previous rule: a normal distribution fitted to the right known rows' scores
            kept = inner[~fold["unknown"] & fold["correct"]]
            q = MAX_ACCURACY_DROP * int((~fold["unknown"]).sum()) / kept.size
            threshold = kept.mean() + kept.std(ddof=1) * norm.ppf(1 - q)
        else:  # the rule's: the known rows of grouped folds that keep every class
            threshold = choose_threshold(score(fold, "known"), fold["known_unknown"], fold["known_correct"])
        s = score(fold, "outer")
        outer.append(s)
        unknown.append(~fold["is_known"])
        right.append(fold["right"])
        rejected.append(s > threshold)
    s, u, c, r = map(np.concatenate, (outer, unknown, right, rejected))
    return (f"| {name} | {auroc(s, u):.3f} | {100 * r[u].mean():.1f} | {100 * r[~u].mean():.1f} | "
            f"{100 * c[~u].mean():.1f} -> {100 * (c & ~r)[~u].mean():.1f} |")


if __name__ == "__main__":
    warnings.filterwarnings("ignore")
    for argument in sys.argv[1:]:
        compare(argument)
