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
    """
    confusion = np.asarray(confusion, dtype=np.float64)
    return float(macro_f1_of_counts(np.diag(confusion), confusion.sum(axis=1), confusion.sum(axis=0)))


def macro_f1_of_counts(tp: np.ndarray, true: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """:func:`macro_f1_from_confusion` of many confusion matrices at once, from their diagonals ``tp`` and
    their row (``true``) and column (``predicted``) sums, one matrix per row: ``F1_c = 2 TP_c / (n_c + m_c)``
    averaged over the classes with ``n_c + m_c > 0``; NaN for a matrix with no class."""
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
    """Macro F1 of all out-of-fold predictions at once (over the classes in the true or predicted labels)."""
    y_true, y_pred = np.asarray(y_true), np.asarray(y_pred)
    classes = np.unique(np.concatenate([y_true, y_pred]))
    index = {c: k for k, c in enumerate(classes)}
    confusion = np.zeros((classes.size, classes.size))
    np.add.at(confusion, ([index[c] for c in y_true], [index[c] for c in y_pred]), 1)
    return macro_f1_from_confusion(confusion)


def accuracy(y_true: Sequence[str], y_pred: Sequence[str]) -> float:
    """The share of rows whose prediction is their class."""
    return float(np.mean(np.asarray(y_true) == np.asarray(y_pred)))


def bootstrap_interval(statistic: Callable[[np.ndarray], float], groups: Sequence[str], seed: int = 0,
                       resamples: int = BOOTSTRAP_RESAMPLES, level: float = 0.95) -> tuple[float, float]:
    """Percentile interval of ``statistic(weights)`` over resamples of whole groups drawn with replacement.

    ``statistic`` takes the weight of every row in one resample: how often its group was drawn (the G
    draws of G groups, a multinomial count). A single group gives the degenerate interval of the
    statistic itself.
    """
    weights = bootstrap_weights(groups, seed, resamples)
    return percentile_interval(np.array([statistic(row) for row in weights], dtype=np.float64), level)


def bootstrap_weights(groups: Sequence[str], seed: int = 0, resamples: int = BOOTSTRAP_RESAMPLES) -> np.ndarray:
    """The row weights of :func:`bootstrap_interval`'s resamples, one row per resample (``resamples`` x rows):
    how often each row's group was drawn, the multinomial count of G draws of G groups with replacement."""
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
    """The central ``level`` percentile interval of the finite ``values``; NaN, NaN if none is finite."""
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
    NaN without both kinds of row."""
    score = np.asarray(score, dtype=np.float64)
    unknown = np.asarray(unknown, dtype=bool)
    n1, n0 = int(unknown.sum()), int((~unknown).sum())
    if n1 == 0 or n0 == 0:
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
    """Accuracy of always answering the most frequent class."""
    _, counts = np.unique(np.asarray(y_true), return_counts=True)
    return float(counts.max() / counts.sum()) if counts.size else float("nan")


def chance_macro_f1(n_classes: int) -> float:
    """Expected macro F1 of guessing each class with its frequency: each class's precision and recall are
    its prior ``pi_c``, so ``F1_c = pi_c`` and the macro mean is ``1 / K``."""
    return 1.0 / n_classes if n_classes else float("nan")
