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

import inspect
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
    (at least 2); an empty list where no split is possible.

    Parameters
    ----------
    y : array_like, shape (n,)
        The class of each row; every part holds the classes in about their shares.
    groups : array_like of str, shape (n,), or None
        The group of each row (e.g. its sample): a group's rows stay in one part. None: every row is its
        own group.
    folds : int
        The number of splits wanted; fewer where there are fewer groups, or fewer rows in the largest
        class.
    seed : int
        Seed of the shuffle before splitting.

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray)
        The ``(train, test)`` row indices of each split; each row is tested once.

    Examples
    --------
    Four samples of two scans each give four splits, not five, and a sample is never on both sides; one
    row per class leaves nothing to split:

    >>> import numpy as np
    >>> from taxonomy.learning.calibration import grouped_splits
    >>> y = np.array(["granite"] * 4 + ["oak"] * 4)
    >>> groups = np.array(["g1", "g1", "g2", "g2", "o1", "o1", "o2", "o2"])
    >>> splits = grouped_splits(y, groups, folds=5, seed=0)
    >>> len(splits), all(set(groups[train]).isdisjoint(groups[test]) for train, test in splits)
    (4, True)
    >>> sorted(np.concatenate([test for _, test in splits]).tolist())
    [0, 1, 2, 3, 4, 5, 6, 7]
    >>> grouped_splits(np.array(["granite", "oak"]), None, folds=3, seed=0)
    []
    """
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


def fit_grouped(classifier: BaseEstimator, X: np.ndarray, y: np.ndarray, groups: np.ndarray) -> BaseEstimator:
    """``classifier.fit(X, y)``, with the rows' ``groups`` where its ``fit`` takes them (a family ensemble's
    inner folds keep a group's rows together).

    Parameters
    ----------
    classifier : BaseEstimator
        An unfitted classifier.
    X : numpy.ndarray, shape (n, f)
        The training rows.
    y : numpy.ndarray, shape (n,)
        The class of each row.
    groups : numpy.ndarray, shape (n,)
        The group of each row.

    Returns
    -------
    BaseEstimator
        ``classifier``, fitted.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.naive_bayes import GaussianNB
    >>> from taxonomy.learning.calibration import fit_grouped
    >>> fit_grouped(GaussianNB(), np.array([[0.0], [1.0]]), np.array(["a", "b"]), np.array(["g1", "g2"])).classes_
    array(['a', 'b'], dtype='<U1')
    """
    if "groups" in inspect.signature(classifier.fit).parameters:
        return classifier.fit(X, y, groups=groups)
    return classifier.fit(X, y)


def logits(classifier: BaseEstimator, X: np.ndarray) -> np.ndarray:
    """The scores temperature scaling rescales: log probabilities, or the decision values (rows x classes).

    A binary decision function's single score ``s`` (for the second class) becomes the columns ``-s, s``.

    Parameters
    ----------
    classifier : BaseEstimator
        A fitted scikit-learn classifier with ``predict_proba`` or ``decision_function``.
    X : numpy.ndarray, shape (n, f)
        The rows to score.

    Returns
    -------
    numpy.ndarray, shape (n, k)
        One column per class of ``classifier.classes_``: ``log(max(p, EPS))``, or the decision values.

    Examples
    --------
    Always answering the class shares 3/4 and 1/4; a least-squares line through (-1, -1) and (1, 1), whose
    decision value at ``x`` is ``x``:

    >>> import numpy as np
    >>> from sklearn.dummy import DummyClassifier
    >>> from sklearn.linear_model import RidgeClassifier
    >>> from taxonomy.learning.calibration import logits
    >>> prior = DummyClassifier(strategy="prior").fit(np.zeros((4, 1)), ["oak", "oak", "oak", "granite"])
    >>> np.round(np.exp(logits(prior, np.zeros((1, 1)))), 6).tolist()
    [[0.25, 0.75]]
    >>> line = RidgeClassifier(alpha=0.0).fit(np.array([[-1.0], [1.0]]), ["granite", "oak"])
    >>> np.round(logits(line, np.array([[2.0], [-0.5]])), 6).tolist()
    [[-2.0, 2.0], [0.5, -0.5]]
    """
    if hasattr(classifier, "predict_proba"):
        return np.log(np.maximum(classifier.predict_proba(X), EPS))
    scores = np.asarray(classifier.decision_function(X), dtype=np.float64)
    return np.column_stack([-scores, scores]) if scores.ndim == 1 else scores


def fit_temperature(z: np.ndarray, true_index: np.ndarray) -> float:
    """The inverse temperature ``beta`` minimising the negative log likelihood of ``softmax(beta z)``
    (Guo et al. 2017, section 4.2), searched over ``log beta`` in [-10, 10]; 1 without rows.

    Parameters
    ----------
    z : numpy.ndarray, shape (n, k)
        The held-out rows' logits (:func:`logits`).
    true_index : numpy.ndarray of int, shape (n,)
        The column of each row's true class.

    Returns
    -------
    float
        ``beta``: above 1 sharpens the probabilities, below 1 flattens them.

    Examples
    --------
    Three rows with the logits (1, -1), two of them of the first class: the likelihood is highest where
    ``softmax(beta z)`` gives the first class 2/3, that is ``2 beta = log 2``:

    >>> import math
    >>> import numpy as np
    >>> from taxonomy.learning.calibration import fit_temperature
    >>> beta = fit_temperature(np.array([[1.0, -1.0]] * 3), np.array([0, 0, 1]))
    >>> round(beta, 4), round(math.log(2) / 2, 4)
    (0.3466, 0.3466)
    >>> fit_temperature(np.empty((0, 2)), np.empty(0, dtype=int))
    1.0
    """
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
        label) leave out rows of a material absent from their inner training part.

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The training rows.
        y : numpy.ndarray, shape (n,)
            The class of each row.
        groups : numpy.ndarray of str, shape (n,), optional
            The group of each row; None: every row is its own group.
        materials : numpy.ndarray of str, shape (n,), optional
            The full label of each row; None: its class.

        Returns
        -------
        TemperatureScaledClassifier
            This classifier, fitted.

        Examples
        --------
        Two well separated classes of three samples each: three inner splits, every row scored out of fold,
        and naive Bayes' probabilities sharpened:

        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> from taxonomy.learning.calibration import TemperatureScaledClassifier
        >>> X = np.r_[np.linspace(0.0, 1.0, 6), np.linspace(5.0, 6.0, 6)][:, None]
        >>> y = np.array(["granite"] * 6 + ["oak"] * 6)
        >>> groups = np.repeat(["g1", "g2", "g3", "o1", "o2", "o3"], 2)
        >>> model = TemperatureScaledClassifier(GaussianNB(), inner_folds=3).fit(X, y, groups)
        >>> model.n_fits_, model.n_calibration_, bool(model.beta_ > 1)
        (4, 12, True)
        """
        X, y = np.asarray(X), np.asarray(y)
        groups = None if groups is None else np.asarray(groups)
        materials = np.asarray(materials) if materials is not None else y
        self.estimator_ = fit_grouped(clone(self.estimator), X, y, groups)
        self.classes_ = self.estimator_.classes_
        index = {c: k for k, c in enumerate(self.classes_)}
        held_z, held_true = [], []
        splits = grouped_splits(y, groups, self.inner_folds, self.seed)
        for train, test in splits:
            inner = fit_grouped(clone(self.estimator), X[train], y[train], None if groups is None else groups[train])
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
        """The classifier's probabilities, tempered: ``softmax(beta * logits)``.

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The rows to classify.

        Returns
        -------
        numpy.ndarray, shape (n, k)
            The probability of each class of ``classes_``; each row sums to 1.

        Examples
        --------
        With probabilities ``p`` the tempered ones are ``p**beta / sum(p**beta)``:

        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> from taxonomy.learning.calibration import TemperatureScaledClassifier
        >>> X = np.r_[np.linspace(0.0, 1.0, 6), np.linspace(5.0, 6.0, 6)][:, None]
        >>> y, groups = np.array(["granite"] * 6 + ["oak"] * 6), np.repeat(["g1", "g2", "g3", "o1", "o2", "o3"], 2)
        >>> model = TemperatureScaledClassifier(GaussianNB()).fit(X, y, groups)
        >>> p = model.estimator_.predict_proba(np.array([[2.9], [3.1]]))
        >>> bool(np.allclose(model.predict_proba(np.array([[2.9], [3.1]])),
        ...                  p**model.beta_ / (p**model.beta_).sum(axis=1, keepdims=True)))
        True
        """
        return softmax(self.beta_ * logits(self.estimator_, X), axis=1)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The classifier's own predictions (a temperature changes no ranking).

        Parameters
        ----------
        X : numpy.ndarray, shape (n, f)
            The rows to classify.

        Returns
        -------
        numpy.ndarray, shape (n,)
            The class ``estimator_`` predicts for each row.

        Examples
        --------
        >>> import numpy as np
        >>> from sklearn.naive_bayes import GaussianNB
        >>> from taxonomy.learning.calibration import TemperatureScaledClassifier
        >>> X = np.r_[np.linspace(0.0, 1.0, 6), np.linspace(5.0, 6.0, 6)][:, None]
        >>> y, groups = np.array(["granite"] * 6 + ["oak"] * 6), np.repeat(["g1", "g2", "g3", "o1", "o2", "o3"], 2)
        >>> model = TemperatureScaledClassifier(GaussianNB()).fit(X, y, groups)
        >>> new = np.array([[0.5], [2.9], [3.1], [5.5]])
        >>> model.predict(new).tolist(), model.classes_[model.predict_proba(new).argmax(axis=1)].tolist()
        (['granite', 'granite', 'oak', 'oak'], ['granite', 'granite', 'oak', 'oak'])
        """
        return self.estimator_.predict(X)
