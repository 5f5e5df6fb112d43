"""``chathuranga``: Chathuranga et al.'s pairwise SVM elimination over three palpations (2015) and its
baselines, repeated holdout of 1/6 of the trials."""

from __future__ import annotations

import math
import warnings
from itertools import combinations

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC
from sklearn.utils import Tags
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from taxonomy.learning.results import Result
from taxonomy.related.datasets import Dataset, Extracted, ExtractedSets, MethodError, MethodSkipped, motion_of, trial_of
from taxonomy.related.scoring import holdout_splits, score, scored


class PairwiseEliminationSVM(ClassifierMixin, BaseEstimator):
    """Chathuranga et al.'s Algorithm 1: binary RBF SVMs for every pair of classes, voting over candidates.

    A row holds the features of ``palpations`` palpations side by side (4 each: Frobenius norm and the
    three means). Palpation k classifies the unknown material with every pair of the current candidates;
    after each palpation but the last the half with the most votes (ties: class order) stays; after the
    last, the class with the most votes wins. Training uses every palpation of every row as a sample,
    standardised (interpretation), with RBF kernels of scale ``sigma`` (gamma = 1 / (2 sigma^2)).
    The pair SVMs do not depend on the unknown, so they are trained once; their decision functions are
    evaluated together from the stacked support vectors.
    """

    def __init__(self, palpations: int = 3, sigma: float = 1.0, C: float = 1.0, keep: float = 0.5) -> None:
        self.palpations = palpations
        self.sigma = sigma
        self.C = C
        self.keep = keep

    def _split(self, X: np.ndarray) -> np.ndarray:
        if X.shape[1] % self.palpations:
            raise MethodError(f"rows must hold {self.palpations} palpations of equal width, "
                              f"got shape {X.shape}")
        return X.reshape(X.shape[0], self.palpations, -1)

    def fit(self, X: np.ndarray, y: np.ndarray) -> PairwiseEliminationSVM:
        X, y = validate_data(self, X, y)
        check_classification_targets(y)
        palpations = self._split(X)
        rows = palpations.reshape(-1, palpations.shape[2])
        labels = np.repeat(np.asarray(y), self.palpations)
        self.classes_ = np.unique(labels)
        self.scaler_ = StandardScaler().fit(rows)
        z = self.scaler_.transform(rows)
        self.gamma_ = 1.0 / (2.0 * self.sigma**2)
        pairs = list(combinations(range(self.classes_.size), 2))
        support, dual, starts, intercept = [], [], [], []
        for i, j in pairs:
            mask = (labels == self.classes_[i]) | (labels == self.classes_[j])
            svm = SVC(kernel="rbf", gamma=self.gamma_, C=self.C).fit(z[mask], labels[mask])
            starts.append(sum(len(s) for s in support))
            support.append(svm.support_vectors_)
            dual.append(svm.dual_coef_[0])
            intercept.append(svm.intercept_[0])
        self.pairs_ = np.array(pairs, dtype=np.intp).reshape(-1, 2)
        self.support_ = np.vstack(support) if support else np.empty((0, z.shape[1]))
        self.dual_ = np.concatenate(dual) if dual else np.empty(0)
        self.starts_ = np.array(starts, dtype=np.intp)
        self.intercept_ = np.array(intercept)
        return self

    def pair_winners(self, z: np.ndarray) -> np.ndarray:
        """Index of the class each pair's SVM picks for one standardised palpation.

        As scikit-learn's binary SVC: a positive decision picks the pair's second class.
        """
        kernel = np.exp(-self.gamma_ * np.sum((self.support_ - z) ** 2, axis=1))
        decision = np.add.reduceat(self.dual_ * kernel, self.starts_) + self.intercept_
        return np.where(decision > 0, self.pairs_[:, 1], self.pairs_[:, 0])

    def _classify(self, palpations: np.ndarray) -> int:
        candidates = np.arange(self.classes_.size)
        # The scaler's arithmetic without its input checks, which would cost more than the SVMs.
        standard = (palpations - self.scaler_.mean_) / self.scaler_.scale_
        for k, z in enumerate(standard):
            if candidates.size == 1:
                break
            inside = np.isin(self.pairs_, candidates).all(axis=1)
            votes = np.bincount(self.pair_winners(z)[inside], minlength=self.classes_.size)[candidates]
            ranked = candidates[np.argsort(-votes, kind="stable")]
            if k == self.palpations - 1:
                return int(ranked[0])
            candidates = np.sort(ranked[:max(1, math.ceil(self.keep * candidates.size))])
        return int(candidates[0])

    def predict(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "support_")
        X = validate_data(self, X, reset=False)
        return self.classes_[[self._classify(rows) for rows in self._split(X)]]


class NearestSpatialPeriod(ClassifierMixin, BaseEstimator):
    """The spatial-period baseline: the class whose mean period is nearest in units of its spread.

    Interpretation of "closest to the properties (mean, variance) of each class": the smallest
    ``|lambda - mean_c| / std_c`` (population std, floored at 1e-12 so a constant class still works).
    """

    def __sklearn_tags__(self) -> Tags:
        tags = super().__sklearn_tags__()
        tags.classifier_tags.poor_score = True  # a one-column baseline (the paper: 36 %), by design
        return tags

    def fit(self, X: np.ndarray, y: np.ndarray) -> NearestSpatialPeriod:
        X, y = validate_data(self, X, y)
        check_classification_targets(y)
        values = X[:, 0]
        self.classes_ = np.unique(y)
        self.mean_ = np.array([values[y == c].mean() for c in self.classes_])
        self.std_ = np.maximum(np.array([values[y == c].std() for c in self.classes_]), 1e-12)
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "mean_")
        values = validate_data(self, X, reset=False)[:, :1]
        return self.classes_[np.argmin(np.abs(values - self.mean_) / self.std_, axis=1)]


CHATHURANGA_PAPER = {"pairwise-svm": "89 %, 280 us", "spatial-period": "36 %, 8 us",
                     "neural-net": "81 %, 880 us"}
"""Chathuranga et al. Table I: accuracy and time per classification."""


def palpation_table(dataset: Dataset, extracted: Extracted,
                    count: int) -> tuple[list[str], np.ndarray, list[int]]:
    """Trials with at least ``count`` usable palpations: their keys, features side by side, first rows."""
    trials: dict[str, list[int]] = {}
    for i, recording in enumerate(dataset.recordings):
        if i not in extracted.failed and np.all(np.isfinite(extracted.X[i])):
            trials.setdefault(trial_of(recording), []).append(i)
    keys, table, first = [], [], []
    for key, rows in trials.items():
        rows = sorted(rows, key=lambda i: motion_of(dataset.recordings[i]))
        if len(rows) >= count:
            keys.append(key)
            table.append(np.concatenate([extracted.X[i] for i in rows[:count]]))
            first.append(rows[0])
    return keys, np.array(table).reshape(len(keys), -1), first


def run_chathuranga(dataset: Dataset, cache: ExtractedSets, seed: int, repeats: int) -> list[Result]:
    """Chathuranga et al.: elimination over (up to) three palpations; the two single-palpation baselines."""
    c4 = cache.get("chathuranga4")
    per_trial = {}
    for i, recording in enumerate(dataset.recordings):
        if i not in c4.failed:
            per_trial[trial_of(recording)] = per_trial.get(trial_of(recording), 0) + 1
    if not per_trial:
        raise MethodError(f"chathuranga4 failed on every recording: {next(iter(c4.failed.values()))}")
    count = min(3, min(per_trial.values()))
    _, X, first = palpation_table(dataset, c4, count)
    y = dataset.y(dataset.label_level, first)
    splits = holdout_splits(y, repeats, 1 / 6, seed)
    splitting = f"{len(splits)} x holdout 1/6"
    level = dataset.label_level
    seconds = float(np.nanmedian(c4.seconds[first])) * count
    scores = score(lambda _, __: PairwiseEliminationSVM(palpations=count), X, y, splits)
    results = [scored(scores, len(y), seconds, method="chathuranga", feature_set="chathuranga4",
                      classifier="pairwise-svm", motions=f"{count} palpation(s)", level=level, splitting=splitting,
                      seed=seed, paper=CHATHURANGA_PAPER["pairwise-svm"])]
    baselines = {"spatial-period": ("chathuranga_period", NearestSpatialPeriod),
                 "neural-net": ("chathuranga_net", lambda: Pipeline([
                     ("scale", StandardScaler()),
                     ("classify", MLPClassifier(hidden_layer_sizes=(10,), activation="logistic",
                                                solver="lbfgs", max_iter=2000, random_state=seed))]))}
    for name, (set_name, make) in baselines.items():
        extracted = cache.get(set_name)
        usable = [i for i in first if i not in extracted.failed and np.all(np.isfinite(extracted.X[i]))]
        if len(usable) < len(first):
            note = next(iter(extracted.failed.values()), "undefined values")
            results_note = [f"{name}: {len(first) - len(usable)} trial(s) without {set_name} ({note})"]
        else:
            results_note = []
        if not usable:
            reason = next(iter(extracted.failed.values()), "undefined values")
            warnings.warn(f"method chathuranga: the {name} baseline not run: {reason}", MethodSkipped,
                          stacklevel=2)
            continue
        X_b, y_b = extracted.X[usable], dataset.y(level, usable)
        b_splits = holdout_splits(y_b, len(splits), 1 / 6, seed)
        scores = score(lambda _, __, make=make: make(), X_b, y_b, b_splits)
        seconds = float(np.nanmedian(extracted.seconds[usable]))
        results.append(scored(scores, len(y_b), seconds, results_note, method="chathuranga", feature_set=set_name,
                              classifier=name, motions="1 palpation", level=level, splitting=splitting, seed=seed,
                              paper=CHATHURANGA_PAPER[name]))
    return results
