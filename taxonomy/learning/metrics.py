"""Scores a reviewer accepts: pooled and per-fold macro F1, bootstrap intervals, calibration, AUROC, chance.

- Macro F1 over the pooled out-of-fold predictions (Forman and Scholz 2010, "Apples-to-apples in
  cross-validation studies", SIGKDD Explorations 12(1)): with folds grouped by sample a test fold holds
  only some of the classes, and a per-fold macro F1 counts every prediction into a class absent from the
  fold as a class with F1 0. The pooled figure is the headline; the per-fold figure is averaged over the
  classes present in each fold's true labels (:func:`present_class_f1`).
- 95 % confidence intervals by the percentile bootstrap over groups (Efron and Tibshirani 1993, *An
  Introduction to the Bootstrap*, ch. 13): the groups (samples, sessions, ...) of the out-of-fold
  predictions are drawn with replacement, as the groups, not the scans, are the independent units.
- Expected calibration error (Naeini et al. 2015, AAAI; Guo et al. 2017, ICML, eq. 3): the top-label
  confidence binned into equal-width bins, ``ECE = sum_m |B_m| / n |acc(B_m) - conf(B_m)|``.
- AUROC of a rejection score, known against unknown rows: the Mann-Whitney probability that an unknown
  row scores higher than a known one (ties count one half).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

BOOTSTRAP_RESAMPLES = 1000
"""Resamples of the group bootstrap (Efron and Tibshirani 1993 advise 1000 or more for percentile intervals)."""

CALIBRATION_BINS = 10
"""Equal-width confidence bins of the ECE and the reliability diagram (Guo et al. 2017 use 15 for
10,000 test images; with a few hundred scans, 10 keeps about 20 scans in a populated bin)."""


def macro_f1_from_confusion(confusion: np.ndarray) -> float:
    """Macro F1 over the classes that occur in the true or predicted labels of ``confusion`` (rows true,
    columns predicted): ``F1_c = 2 TP_c / (2 TP_c + FP_c + FN_c)``, averaged over those classes.

    Equal to scikit-learn's ``f1_score(average="macro")`` of the rows that make up the matrix.

    Parameters
    ----------
    confusion : array_like, shape (k, k)
        Counts of the rows, the true class in the rows and the predicted one in the columns.

    Returns
    -------
    float
        The mean ``F1_c`` of the classes that occur; NaN where no class does (a matrix of zeros).

    Examples
    --------
    Class 0: ``2 * 3 / (2 * 3 + 0 + 1) = 6/7``; class 1: ``2 * 4 / (2 * 4 + 1 + 0) = 8/9``; a third class
    that is neither true nor predicted counts for nothing:

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import macro_f1_from_confusion
    >>> round(macro_f1_from_confusion(np.array([[3, 1], [0, 4]])), 6), round((6 / 7 + 8 / 9) / 2, 6)
    (0.873016, 0.873016)
    >>> round(macro_f1_from_confusion(np.array([[3, 1, 0], [0, 4, 0], [0, 0, 0]])), 6)
    0.873016
    """
    confusion = np.asarray(confusion, dtype=np.float64)
    return float(macro_f1_of_counts(np.diag(confusion), confusion.sum(axis=1), confusion.sum(axis=0)))


def macro_f1_of_counts(tp: np.ndarray, true: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """:func:`macro_f1_from_confusion` of many confusion matrices at once, from their diagonals ``tp`` and
    their row (``true``) and column (``predicted``) sums, one matrix per row: ``F1_c = 2 TP_c / (n_c + m_c)``
    averaged over the classes with ``n_c + m_c > 0``; NaN for a matrix with no class.

    Parameters
    ----------
    tp : array_like, shape (..., k)
        The diagonal of each confusion matrix: the rows of each class predicted as that class.
    true, predicted : array_like, shape (..., k)
        Each matrix's row sums (``n_c``, the rows of each true class) and column sums (``m_c``, the rows
        predicted as each class).

    Returns
    -------
    numpy.ndarray, shape (...)
        The macro F1 of each matrix; NaN for a matrix in which no class occurs.

    Examples
    --------
    The matrices ``[[3, 1], [0, 4]]`` (``(6/7 + 8/9) / 2``) and a matrix of zeros:

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import macro_f1_of_counts
    >>> tp = np.array([[3, 4], [0, 0]])
    >>> true, predicted = np.array([[4, 4], [0, 0]]), np.array([[3, 5], [0, 0]])
    >>> np.round(macro_f1_of_counts(tp, true, predicted), 6).tolist()
    [0.873016, nan]
    """
    tp, denominator = np.asarray(tp, dtype=np.float64), np.asarray(true, np.float64) + np.asarray(predicted, np.float64)
    occurs = denominator > 0
    scores = np.divide(2 * tp, denominator, out=np.zeros_like(tp), where=occurs)
    counted = occurs.sum(axis=-1)
    with np.errstate(invalid="ignore"):
        return np.where(counted > 0, scores.sum(axis=-1) / np.maximum(counted, 1), np.nan)


def present_class_f1(y_true: Sequence[str], y_pred: Sequence[str]) -> float:
    """Macro F1 of one fold over the classes present in its true labels.

    A prediction into a class absent from the fold still costs the true class its recall; it no longer adds
    a class whose F1 is 0 by construction.

    Parameters
    ----------
    y_true, y_pred : sequence of str
        The true and the predicted class of each row of the fold.

    Returns
    -------
    float
        The mean F1 of the classes in ``y_true``; NaN for a fold without rows.

    Examples
    --------
    One ``a`` predicted as ``c``, a class the fold does not hold: ``a`` scores ``2 / (2 + 0 + 1) = 2/3``,
    ``b`` 1, and ``c`` is not averaged in (:func:`pooled_macro_f1` would count it as 0):

    >>> from taxonomy.learning.metrics import present_class_f1
    >>> round(present_class_f1(["a", "a", "b", "b"], ["a", "c", "b", "b"]), 6), round((2 / 3 + 1) / 2, 6)
    (0.833333, 0.833333)
    """
    y_true, y_pred = np.asarray(y_true), np.asarray(y_pred)
    scores = []
    for c in np.unique(y_true):
        tp = np.sum((y_true == c) & (y_pred == c))
        fp = np.sum((y_true != c) & (y_pred == c))
        fn = np.sum((y_true == c) & (y_pred != c))
        scores.append(2 * tp / (2 * tp + fp + fn))
    return float(np.mean(scores)) if scores else float("nan")


def pooled_macro_f1(y_true: Sequence[str], y_pred: Sequence[str]) -> float:
    """Macro F1 of all out-of-fold predictions at once (over the classes in the true or predicted labels).

    Parameters
    ----------
    y_true, y_pred : sequence of str
        The true and the predicted class of each row, all folds together.

    Returns
    -------
    float
        :func:`macro_f1_from_confusion` of their confusion matrix, as scikit-learn's
        ``f1_score(average="macro")``.

    Examples
    --------
    ``a`` scores 2/3, ``b`` 1 and ``c``, predicted once and never true, 0:

    >>> from taxonomy.learning.metrics import pooled_macro_f1
    >>> round(pooled_macro_f1(["a", "a", "b", "b"], ["a", "c", "b", "b"]), 6), round((2 / 3 + 1 + 0) / 3, 6)
    (0.555556, 0.555556)
    """
    y_true, y_pred = np.asarray(y_true), np.asarray(y_pred)
    classes = np.unique(np.concatenate([y_true, y_pred]))
    index = {c: k for k, c in enumerate(classes)}
    confusion = np.zeros((classes.size, classes.size))
    np.add.at(confusion, ([index[c] for c in y_true], [index[c] for c in y_pred]), 1)
    return macro_f1_from_confusion(confusion)


def accuracy(y_true: Sequence[str], y_pred: Sequence[str]) -> float:
    """The share of rows whose prediction is their class.

    Parameters
    ----------
    y_true, y_pred : sequence of str
        The true and the predicted class of each row.

    Returns
    -------
    float
        Between 0 and 1; NaN without rows.

    Examples
    --------
    >>> from taxonomy.learning.metrics import accuracy
    >>> accuracy(["a", "b", "b", "a"], ["a", "b", "a", "a"])
    0.75
    """
    return float(np.mean(np.asarray(y_true) == np.asarray(y_pred)))


def bootstrap_interval(statistic: Callable[[np.ndarray], float], groups: Sequence[str], seed: int = 0,
                       resamples: int = BOOTSTRAP_RESAMPLES, level: float = 0.95) -> tuple[float, float]:
    """Percentile interval of ``statistic(weights)`` over resamples of whole groups drawn with replacement.

    ``statistic`` takes the weight of every row in one resample: how often its group was drawn (the G
    draws of G groups, a multinomial count). A single group gives the degenerate interval of the
    statistic itself.

    Parameters
    ----------
    statistic : callable
        Maps the weights of the rows (numpy.ndarray, shape (n,)) to the statistic of that resample.
    groups : sequence of str
        The group of each row (sample, session, ...): the unit that is drawn.
    seed : int
        Seed of the draws (:func:`bootstrap_weights`).
    resamples : int
        The number of resamples.
    level : float
        The central share of the resampled statistics the interval holds.

    Returns
    -------
    tuple of float
        ``(low, high)``, the percentiles ``100 (1 - level) / 2`` and ``100 (1 + level) / 2``
        (:func:`percentile_interval`).

    Examples
    --------
    The accuracy of two samples, one classified right, one wrong: a resample draws two samples, so its
    accuracy is 0, 1/2 or 1 with probabilities 1/4, 1/2, 1/4, and the 95 % interval spans all of it; with
    a single sample every resample is the data itself:

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import bootstrap_interval
    >>> right = np.array([1.0, 1.0, 0.0, 0.0])
    >>> def weighted_accuracy(weights):
    ...     return float(np.sum(weights * right) / np.sum(weights))
    >>> bootstrap_interval(weighted_accuracy, ["s1", "s1", "s2", "s2"], resamples=200)
    (0.0, 1.0)
    >>> bootstrap_interval(weighted_accuracy, ["s1", "s1", "s1", "s1"], resamples=200)
    (0.5, 0.5)
    """
    weights = bootstrap_weights(groups, seed, resamples)
    return percentile_interval(np.array([statistic(row) for row in weights], dtype=np.float64), level)


def bootstrap_weights(groups: Sequence[str], seed: int = 0, resamples: int = BOOTSTRAP_RESAMPLES) -> np.ndarray:
    """The row weights of :func:`bootstrap_interval`'s resamples, one row per resample (``resamples`` x rows):
    how often each row's group was drawn, the multinomial count of G draws of G groups with replacement.

    Parameters
    ----------
    groups : sequence of str
        The group of each row.
    seed : int
        Seed of the draws; the same seed and number of groups give the same draws.
    resamples : int
        The number of resamples (rows of the result).

    Returns
    -------
    numpy.ndarray of int, shape (resamples, n)
        The weight of every row in every resample; read-only, shared by calls with the same arguments.

    Examples
    --------
    The rows of one group share their weight, and the weights of one row per group sum to the number of
    groups:

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import bootstrap_weights
    >>> weights = bootstrap_weights(["s1", "s1", "s2"], seed=0, resamples=5)
    >>> weights.shape, bool(np.all(weights[:, 0] == weights[:, 1])), np.unique(weights[:, 1:].sum(axis=1)).tolist()
    ((5, 3), True, [2])
    """
    names, inverse = np.unique(np.asarray(groups), return_inverse=True)
    return _group_draws(names.size, seed, resamples)[:, inverse]


@functools.lru_cache(maxsize=2)
def _group_draws(n_groups: int, seed: int, resamples: int) -> np.ndarray:
    """How often each of ``n_groups`` groups is drawn in each resample (read-only): the same for every
    result of one evaluation, so drawn once (a report's 70 results share their groups and seed). Two are
    kept (8 bytes per group and resample each: a data set of 10,000 groups holds 80 MB per entry, as much
    as one result's weights)."""
    rng = np.random.default_rng(seed)
    drawn = rng.multinomial(n_groups, np.full(n_groups, 1 / n_groups), size=resamples)
    drawn.setflags(write=False)
    return drawn


def percentile_interval(values: np.ndarray, level: float = 0.95) -> tuple[float, float]:
    """The central ``level`` percentile interval of the finite ``values``; NaN, NaN if none is finite.

    Parameters
    ----------
    values : array_like
        The values; NaN and infinite ones are left out.
    level : float
        The central share of the values the interval holds.

    Returns
    -------
    tuple of float
        ``(low, high)``, the percentiles ``100 (1 - level) / 2`` and ``100 (1 + level) / 2`` (numpy's linear
        interpolation).

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.learning.metrics import percentile_interval
    >>> low, high = percentile_interval(np.r_[np.arange(101.0), np.nan, np.inf])
    >>> round(low, 6), round(high, 6)
    (2.5, 97.5)
    >>> percentile_interval([np.nan])
    (nan, nan)
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return float("nan"), float("nan")
    tail = 100 * (1 - level) / 2
    low, high = np.percentile(values, [tail, 100 - tail])
    return float(low), float(high)


@dataclass(frozen=True)
class Reliability:
    """The reliability diagram's bins: mean confidence, accuracy and count per populated bin, and the ECE."""

    confidence: np.ndarray
    accuracy: np.ndarray
    count: np.ndarray
    ece: float


def reliability(probability: np.ndarray, true_index: np.ndarray, bins: int = CALIBRATION_BINS) -> Reliability:
    """Top-label reliability of predicted probabilities (rows x classes) against the true class indices.

    Bin ``m`` holds the rows whose top probability lies in ``((m - 1) / M, m / M]``; the ECE is the
    count-weighted mean gap between each bin's accuracy and mean confidence (Guo et al. 2017, eq. 3).

    Parameters
    ----------
    probability : array_like, shape (n, k)
        The predicted probability of each class for each row.
    true_index : array_like of int, shape (n,)
        The column of each row's true class.
    bins : int
        The number ``M`` of equal-width confidence bins.

    Returns
    -------
    Reliability
        The populated bins in order of confidence, and the ECE (NaN without rows).

    Examples
    --------
    Two rows 85 % sure, one of them right (gap 0.35), and two rows 65 % sure, both right (gap 0.35):

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import reliability
    >>> probability = np.array([[0.85, 0.15], [0.85, 0.15], [0.65, 0.35], [0.35, 0.65]])
    >>> bins = reliability(probability, np.array([0, 1, 0, 1]))
    >>> np.round(bins.confidence, 6).tolist(), bins.accuracy.tolist(), bins.count.tolist(), round(bins.ece, 6)
    ([0.65, 0.85], [1.0, 0.5], [2, 2], 0.35)
    """
    probability = np.asarray(probability, dtype=np.float64)
    true_index = np.asarray(true_index)
    confidence = probability.max(axis=1)
    correct = probability.argmax(axis=1) == true_index
    which = np.clip(np.ceil(confidence * bins).astype(int) - 1, 0, bins - 1)
    conf, acc, count = [], [], []
    for m in range(bins):
        inside = which == m
        if inside.any():
            conf.append(confidence[inside].mean())
            acc.append(correct[inside].mean())
            count.append(int(inside.sum()))
    count_arr = np.array(count)
    gaps = np.abs(np.array(acc) - np.array(conf))
    ece = float(np.sum(count_arr * gaps) / count_arr.sum()) if count_arr.size else float("nan")
    return Reliability(np.array(conf), np.array(acc), count_arr, ece)


def auroc(score: Sequence[float], unknown: Sequence[bool]) -> float:
    """Area under the ROC curve of ``score`` separating unknown (True) from known rows: the probability that
    a random unknown row scores above a random known one, ties counting one half (Mann-Whitney U / n1 n0).
    NaN without both kinds of row, or where a score is NaN (its rank, and so the area, is undefined).

    Parameters
    ----------
    score : sequence of float
        The rejection score of each row; higher means more likely unknown.
    unknown : sequence of bool
        Whether each row is of a class the model was not trained on.

    Returns
    -------
    float
        Between 0 (every known row scores higher) and 1 (every unknown row scores higher); 0.5 for scores
        that do not separate them.

    Examples
    --------
    Of the four (unknown, known) pairs, the unknown row scores higher in three:

    >>> from taxonomy.learning.metrics import auroc
    >>> auroc([0.1, 0.4, 0.35, 0.8], [False, False, True, True])
    0.75
    >>> auroc([0.5, 0.5, 0.5], [False, True, True]), auroc([0.1, 0.2], [False, False])
    (0.5, nan)
    >>> auroc([0.1, float("nan"), 0.9], [False, True, True])  # not 1.0: a NaN score ranks nowhere
    nan
    """
    score = np.asarray(score, dtype=np.float64)
    unknown = np.asarray(unknown, dtype=bool)
    n1, n0 = int(unknown.sum()), int((~unknown).sum())
    if n1 == 0 or n0 == 0 or np.isnan(score).any():
        return float("nan")
    order = np.argsort(score, kind="stable")
    ranks = np.empty(score.size)
    sorted_scores = score[order]
    # Average ranks of tied scores (1-based), as the Mann-Whitney statistic needs.
    starts = np.r_[0, np.flatnonzero(np.diff(sorted_scores)) + 1]
    ends = np.r_[starts[1:], score.size]
    for start, end in zip(starts, ends, strict=True):
        ranks[order[start:end]] = (start + end + 1) / 2
    return float((ranks[unknown].sum() - n1 * (n1 + 1) / 2) / (n1 * n0))


def chance_accuracy(y_true: Sequence[str]) -> float:
    """Accuracy of always answering the most frequent class.

    Parameters
    ----------
    y_true : sequence of str
        The true class of each row.

    Returns
    -------
    float
        The share of the most frequent class; NaN without rows.

    Examples
    --------
    >>> from taxonomy.learning.metrics import chance_accuracy
    >>> chance_accuracy(["oak", "oak", "oak", "granite"])
    0.75
    """
    _, counts = np.unique(np.asarray(y_true), return_counts=True)
    return float(counts.max() / counts.sum()) if counts.size else float("nan")


def chance_macro_f1(n_classes: int) -> float:
    """Expected macro F1 of guessing each class with its frequency: each class's precision and recall are
    its prior ``pi_c``, so ``F1_c = pi_c`` and the macro mean is ``1 / K``.

    Parameters
    ----------
    n_classes : int
        The number of classes ``K``.

    Returns
    -------
    float
        ``1 / K``; NaN for no class.

    Examples
    --------
    Four classes of shares 1/2, 1/4, 1/8 and 1/8, guessed with those shares: the expected confusion matrix
    is the outer product of the shares, and its macro F1 is ``1 / 4`` whatever the shares:

    >>> import numpy as np
    >>> from taxonomy.learning.metrics import chance_macro_f1, macro_f1_from_confusion
    >>> prior = np.array([0.5, 0.25, 0.125, 0.125])
    >>> chance_macro_f1(4), round(macro_f1_from_confusion(np.outer(prior, prior)), 6)
    (0.25, 0.25)
    >>> chance_macro_f1(0)
    nan
    """
    return 1.0 / n_classes if n_classes else float("nan")
