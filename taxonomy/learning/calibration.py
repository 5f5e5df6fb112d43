"""Calibrated class probabilities: temperature scaling fitted on out-of-fold scores inside the training rows.

A random forest's probabilities are vote shares, an SVM's decision values are no probabilities at all, and
a kNN's are distance-weighted neighbour shares: "93 %" means little until it is calibrated. Temperature
scaling (Guo et al. 2017, "On Calibration of Modern Neural Networks", ICML, section 4.2) rescales the
classifier's logits ``z`` by one inverse temperature ``beta`` fitted by maximum likelihood on held-out
rows: ``p = softmax(beta z)``. One parameter suits a few hundred scans of 32 classes, where per-class
methods (Platt's sigmoids, isotonic regression) overfit; a monotone rescaling also keeps the classifier's
own predictions.

The held-out rows are the out-of-fold rows of a grouped split *inside* the training rows (as
scikit-learn's ``CalibratedClassifierCV(method="temperature", ensemble=False)``), grouped as the outer
folds are, so the temperature is learned on new samples of known classes, as it will be used. Unlike
``CalibratedClassifierCV``, rows whose class is absent from their inner training part (a class with a
single sample in the training rows) are left out of the fit: the classifier cannot score them, and they
would drag the temperature towards uniform probabilities. So are rows whose material is absent from
their inner training part, when the materials are given: at the coarse level such a row's class is
there (other stones), but a material never seen is harder than the outer folds' new pieces of seen
materials, and it flattened the forest's coarse probabilities to an ECE of 0.5 on the demo database.

Logits: ``decision_function`` where the classifier has no ``predict_proba`` (the SVM), else
``log(max(p, eps))`` (a power transform of the probabilities: ``p_c^beta / sum p^beta``).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import log_softmax, softmax
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold

EPS = 1e-12
"""Floor of a probability before its logarithm: a class no tree voted for gets logit -27.6, not -inf."""


def grouped_splits(y: np.ndarray, groups: np.ndarray | None, folds: int,
                   seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Stratified splits of the rows, grouped where groups repeat; fewer folds where there are fewer groups
    (at least 2); an empty list where no split is possible."""
    y = np.asarray(y)
    if groups is None:
        groups = np.arange(len(y)).astype(str)
    groups = np.asarray(groups)
    folds = min(folds, np.unique(groups).size, int(np.unique(y, return_counts=True)[1].max(initial=0)))
    if folds < 2:  # too few groups, or every class smaller than two folds: nothing to calibrate on
        return []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a class with fewer groups than folds is expected in inner splits
        if np.unique(groups).size < groups.size:
            splitter = StratifiedGroupKFold(n_splits=folds, shuffle=True, random_state=seed)
            return list(splitter.split(np.zeros(len(y)), y, groups))
        splitter = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
        return list(splitter.split(np.zeros(len(y)), y))


def logits(classifier: BaseEstimator, X: np.ndarray) -> np.ndarray:
    """The scores temperature scaling rescales: log probabilities, or the decision values (rows x classes)."""
    if hasattr(classifier, "predict_proba"):
        return np.log(np.maximum(classifier.predict_proba(X), EPS))
    scores = np.asarray(classifier.decision_function(X), dtype=np.float64)
    return np.column_stack([-scores, scores]) if scores.ndim == 1 else scores


def fit_temperature(z: np.ndarray, true_index: np.ndarray) -> float:
    """The inverse temperature ``beta`` minimising the negative log likelihood of ``softmax(beta z)``
    (Guo et al. 2017, section 4.2), searched over ``log beta`` in [-10, 10]; 1 without rows."""
    if len(z) == 0:
        return 1.0
    rows = np.arange(len(z))

    def loss(log_beta: float) -> float:
        return float(-np.mean(log_softmax(np.exp(log_beta) * z, axis=1)[rows, true_index]))

    return float(np.exp(minimize_scalar(loss, bounds=(-10.0, 10.0), method="bounded").x))


class TemperatureScaledClassifier(ClassifierMixin, BaseEstimator):
    """A classifier with temperature-scaled probabilities (module docstring).

    Parameters
    ----------
    estimator : classifier
        Fitted on all training rows; its ``predict`` is this classifier's ``predict``.
    inner_folds : int
        Grouped splits of the training rows whose out-of-fold scores fit the temperature.
    seed : int
        Seed of the inner split.

    Attributes
    ----------
    estimator_ : the fitted classifier;  beta_ : float, the inverse temperature;  classes_ : array;
    n_calibration_ : int, the out-of-fold rows the temperature was fitted on;  n_fits_ : int, the fits of the
    classifier, one on every row and one per inner split.
    """

    def __init__(self, estimator: BaseEstimator, inner_folds: int = 3, seed: int = 0) -> None:
        self.estimator = estimator
        self.inner_folds = inner_folds
        self.seed = seed

    def fit(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None,
            materials: np.ndarray | None = None) -> TemperatureScaledClassifier:
        """Fit the classifier on every row and the temperature on the inner out-of-fold scores; ``groups``
        (e.g. the sample of each row) keep a group's rows in one inner part; ``materials`` (each row's full
        label) leave out rows of a material absent from their inner training part."""
        X, y = np.asarray(X), np.asarray(y)
        materials = np.asarray(materials) if materials is not None else y
        self.estimator_ = clone(self.estimator).fit(X, y)
        self.classes_ = self.estimator_.classes_
        index = {c: k for k, c in enumerate(self.classes_)}
        held_z, held_true = [], []
        splits = grouped_splits(y, groups, self.inner_folds, self.seed)
        for train, test in splits:
            inner = clone(self.estimator).fit(X[train], y[train])
            columns = np.array([index[c] for c in inner.classes_])
            known = np.isin(y[test], inner.classes_) & np.isin(materials[test], materials[train])
            if not known.any() or columns.size < 2:
                continue
            z = np.full((int(known.sum()), self.classes_.size), np.log(EPS))
            z[:, columns] = logits(inner, X[test][known])
            held_z.append(z)
            held_true.append([index[c] for c in y[test][known]])
        z = np.concatenate(held_z) if held_z else np.empty((0, self.classes_.size))
        true = np.concatenate(held_true).astype(int) if held_true else np.empty(0, dtype=int)
        self.beta_ = fit_temperature(z, true)
        self.n_calibration_ = len(true)
        self.n_fits_ = 1 + len(splits)
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """The classifier's probabilities, tempered: ``softmax(beta * logits)``."""
        return softmax(self.beta_ * logits(self.estimator_, X), axis=1)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The classifier's own predictions (a temperature changes no ranking)."""
        return self.estimator_.predict(X)
