"""A fused feature set classified family by family: one classifier per feature family, combined by ensemble
selection on probabilities out of inner folds (Caruana et al., "Ensemble selection from libraries of models",
ICML 2004).

One classifier over every column of a fused set lets the largest family drown the others: MiniRocket's
20,000 kernel features outnumber the paper's 145 a hundred to one, so a random forest's feature subsets
rarely hold one of the paper's (BorealTC, grouped by run: `fusion` 73.2 % against `paper` 86.6 %).
:class:`FamilyEnsembleClassifier` fits the classifier on each family's columns alone, scores every training
row out of inner folds grouped as the outer ones (a run's rows stay on one side), and chooses family weights
greedily, with replacement, to lower the log-loss of the weighted mean of those scores. A family that does
not lower it gets no weight, so the fused set is never chosen worse than its best family on the inner rows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.special import softmax
from sklearn.base import BaseEstimator, ClassifierMixin, clone

from taxonomy.errors import ParameterError
from taxonomy.learning.calibration import EPS, grouped_splits, logits

ROUNDS = 20
"""Greedy rounds of the selection; the weights are those of the round with the lowest inner log-loss."""
INNER_FOLDS = 5
"""Inner folds that score the training rows out of fold (fewer where there are fewer groups)."""


def probabilities(classifier: BaseEstimator, X: np.ndarray) -> np.ndarray:
    """Class probabilities of a fitted classifier: its ``predict_proba``, else the softmax of its decision
    values (a ridge classifier, an SVM without Platt scaling).

    Parameters
    ----------
    classifier : BaseEstimator
        A fitted scikit-learn classifier.
    X : numpy.ndarray, shape (n, f)
        The rows to score.

    Returns
    -------
    numpy.ndarray, shape (n, k)
        One column per class of ``classifier.classes_``; each row sums to 1.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.linear_model import RidgeClassifier
    >>> X, y = np.array([[-1.0], [1.0]]), np.array(["a", "b"])
    >>> probabilities(RidgeClassifier(alpha=0.0).fit(X, y), np.array([[0.0], [1.0]])).round(3)
    array([[0.5  , 0.5  ],
           [0.119, 0.881]])
    """
    if hasattr(classifier, "predict_proba"):
        return np.asarray(classifier.predict_proba(X), dtype=float)
    return softmax(logits(classifier, X), axis=1)


def ensemble_selection(scores: Sequence[np.ndarray], true_index: np.ndarray, rounds: int = ROUNDS) -> np.ndarray:
    """Weights of the members by greedy ensemble selection with replacement (Caruana et al. 2004): each round
    adds the member whose addition gives the lowest log-loss of the mean of the chosen members' probabilities;
    the weights are the chosen counts of the round with the lowest loss, divided by their sum.

    Parameters
    ----------
    scores : sequence of numpy.ndarray, each shape (n, k)
        Each member's probabilities of the ``n`` rows (scored out of fold), columns in one class order.
    true_index : numpy.ndarray of int, shape (n,)
        The column of each row's class.
    rounds : int
        Greedy rounds.

    Returns
    -------
    numpy.ndarray, shape (members,)
        Non-negative weights summing to 1; a tie goes to the member listed first.

    Examples
    --------
    A member that is always right and one that hesitates: the first alone is the lowest loss.

    >>> import numpy as np
    >>> right = np.array([[0.9, 0.1], [0.1, 0.9]])
    >>> unsure = np.full((2, 2), 0.5)
    >>> ensemble_selection([unsure, right], np.array([0, 1]))
    array([0., 1.])

    Two members each right on one row and unsure on the other: together they beat either.

    >>> a = np.array([[0.9, 0.1], [0.5, 0.5]])
    >>> b = np.array([[0.5, 0.5], [0.1, 0.9]])
    >>> ensemble_selection([a, b], np.array([0, 1]))
    array([0.5, 0.5])
    """
    rows = np.arange(len(true_index))
    counts = np.zeros(len(scores))
    total = np.zeros_like(np.asarray(scores[0], dtype=float))
    best, best_counts = np.inf, None
    for chosen in range(1, rounds + 1):
        losses = [-np.mean(np.log(np.maximum((total + s)[rows, true_index] / chosen, EPS))) for s in scores]
        member = int(np.argmin(losses))
        counts[member] += 1
        total = total + scores[member]
        if losses[member] < best - 1e-12:
            best, best_counts = losses[member], counts.copy()
    assert best_counts is not None
    return best_counts / best_counts.sum()


class FamilyEnsembleClassifier(ClassifierMixin, BaseEstimator):
    """``estimator`` fitted on each family's columns alone, the families weighted by
    :func:`ensemble_selection` on probabilities out of inner folds grouped by ``groups``.

    Parameters
    ----------
    estimator : BaseEstimator
        The classifier of every family (cloned; its random state as given).
    parts : sequence of int
        The family of each input column (:func:`features.feature_sets.column_parts`).
    inner_folds : int
        Inner folds scoring the training rows out of fold.
    seed : int
        Seed of the inner folds' shuffle.

    Attributes
    ----------
    weights_ : numpy.ndarray
        The weight of each family, in the order of their numbers.
    estimators_ : list
        Each family's classifier fitted on every training row (None for a family without weight).
    classes_ : numpy.ndarray
        The classes, sorted.
    """

    def __init__(self, estimator: BaseEstimator, parts: Sequence[int] = (), inner_folds: int = INNER_FOLDS,
                 seed: int = 0) -> None:
        self.estimator = estimator
        self.parts = parts
        self.inner_folds = inner_folds
        self.seed = seed

    def fit(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None = None) -> FamilyEnsembleClassifier:
        """Weigh the families on the training rows' inner out-of-fold probabilities, then fit each weighted
        family's classifier on every row.

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The training rows; column ``j`` belongs to family ``parts[j]``.
        y : numpy.ndarray, shape (n,)
            The class of each row.
        groups : numpy.ndarray of str, shape (n,), optional
            The group of each row (a run, a sample): a group's rows stay on one side of every inner split.
            None: every row is its own group.

        Returns
        -------
        FamilyEnsembleClassifier
            This classifier, fitted.

        Examples
        --------
        Family 0 tells the classes apart, family 1 is noise: family 0 takes all the weight.

        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> rng = np.random.default_rng(0)
        >>> y = np.repeat(["cork", "oak"], 20)
        >>> X = np.c_[np.repeat([0.0, 3.0], 20) + rng.normal(0, 0.3, 40), rng.normal(0, 1, 40)]
        >>> model = FamilyEnsembleClassifier(GaussianNB(), parts=(0, 1)).fit(X, y)
        >>> model.weights_, model.predict(np.array([[0.1, 0.0], [2.9, 0.0]]))
        (array([1., 0.]), array(['cork', 'oak'], dtype='<U4'))
        """
        X, y = np.asarray(X), np.asarray(y)
        parts = np.asarray(self.parts)
        if parts.shape != (X.shape[1],):
            raise ParameterError(f"parts names the family of {parts.size} columns; X has {X.shape[1]}")
        self.classes_ = np.unique(y)
        families = np.unique(parts)
        self.columns_ = [np.flatnonzero(parts == family) for family in families]
        self.weights_ = self._weights(X, y, groups)
        self.estimators_ = [clone(self.estimator).fit(X[:, columns], y) if weight > 0 else None
                            for columns, weight in zip(self.columns_, self.weights_, strict=True)]
        return self

    def _weights(self, X: np.ndarray, y: np.ndarray, groups: np.ndarray | None) -> np.ndarray:
        """The families' weights from inner out-of-fold probabilities; equal where no inner split exists."""
        splits = grouped_splits(y, groups, self.inner_folds, self.seed)
        if len(self.columns_) == 1 or not splits:
            return np.full(len(self.columns_), 1.0 / len(self.columns_))
        index = {c: k for k, c in enumerate(self.classes_)}
        scores = [np.zeros((len(y), self.classes_.size)) for _ in self.columns_]
        for train, test in splits:
            for columns, score in zip(self.columns_, scores, strict=True):
                inner = clone(self.estimator).fit(X[np.ix_(train, columns)], y[train])
                score[np.ix_(test, [index[c] for c in inner.classes_])] = probabilities(inner, X[np.ix_(test, columns)])
        tested = np.concatenate([test for _, test in splits])
        return ensemble_selection([score[tested] for score in scores], np.array([index[c] for c in y[tested]]))

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """The weighted mean of the families' probabilities.

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The rows to score, columns as in :meth:`fit`.

        Returns
        -------
        numpy.ndarray, shape (n, k)
            One column per class of ``classes_``.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> X, y = np.array([[0.0, 5.0], [0.2, 1.0], [3.0, 2.0], [3.2, 4.0]]), np.array(["a", "a", "b", "b"])
        >>> model = FamilyEnsembleClassifier(GaussianNB(), parts=(0, 1)).fit(X, y)
        >>> model.weights_, model.predict_proba(np.array([[0.1, 3.0]])).round(2)
        (array([1., 0.]), array([[1., 0.]]))
        """
        X = np.asarray(X)
        index = {c: k for k, c in enumerate(self.classes_)}
        total = np.zeros((len(X), self.classes_.size))
        for columns, weight, estimator in zip(self.columns_, self.weights_, self.estimators_, strict=True):
            if estimator is not None:
                total[:, [index[c] for c in estimator.classes_]] += weight * probabilities(estimator, X[:, columns])
        return total

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The class of the highest weighted probability.

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The rows to classify.

        Returns
        -------
        numpy.ndarray, shape (n,)
            A class of ``classes_`` per row.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> X, y = np.array([[0.0, 5.0], [0.2, 1.0], [3.0, 2.0], [3.2, 4.0]]), np.array(["a", "a", "b", "b"])
        >>> FamilyEnsembleClassifier(GaussianNB(), parts=(0, 1)).fit(X, y).predict(np.array([[3.1, 3.0]]))
        array(['b'], dtype='<U1')
        """
        return self.classes_[np.argmax(self.predict_proba(X), axis=1)]
