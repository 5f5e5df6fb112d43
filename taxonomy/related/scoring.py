"""The splits of the methods' protocols, scoring a method on them, and its
:class:`~taxonomy.learning.results.Result`."""

from __future__ import annotations

import contextlib
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.metrics import confusion_matrix
from sklearn.model_selection import StratifiedKFold, StratifiedShuffleSplit
from sklearn.pipeline import Pipeline

from scanner.runtime import executors
from scanner.runtime.threads import one_blas_thread
from taxonomy import labels
from taxonomy.labels import LabelError
from taxonomy.learning.metrics import present_class_f1
from taxonomy.learning.results import Result, warning_notes
from taxonomy.related.datasets import TIMED_ROWS, Extracted, MethodError

Split = tuple[np.ndarray, np.ndarray]


def kfold_splits(y: np.ndarray, folds: int, seed: int) -> list[Split]:
    """Stratified shuffled k-fold; fewer folds when the smallest class has fewer rows (at least 2)."""
    smallest = int(np.unique(y, return_counts=True)[1].min())
    folds = min(folds, smallest)
    if folds < 2:
        raise MethodError(f"cross-validation needs two rows of every class; "
                          f"the smallest class has {smallest}")
    splitter = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
    return list(splitter.split(np.zeros(len(y)), y))


def holdout_splits(y: np.ndarray, repeats: int, test_size: float, seed: int) -> list[Split]:
    """``repeats`` stratified random holdouts of ``test_size`` of the rows."""
    splitter = StratifiedShuffleSplit(n_splits=repeats, test_size=test_size, random_state=seed)
    return list(splitter.split(np.zeros(len(y)), y))


def one_per_object_splits(objects: Sequence[str], repeats: int, seed: int) -> list[Split]:
    """The protocol of Hoelscher et al. 2015: each split tests one randomly chosen row of every object and
    trains on the rest.

    Objects with a single row are always in training.
    """
    objects = np.asarray(objects)
    rng = np.random.default_rng(seed)
    groups = [np.flatnonzero(objects == o) for o in dict.fromkeys(objects.tolist())]
    groups = [g for g in groups if g.size > 1]
    if not groups:
        raise MethodError("leave-one-per-object-out needs objects with at least two trials")
    splits = []
    for _ in range(repeats):
        test = np.sort(np.array([rng.choice(g) for g in groups]))
        splits.append((np.setdiff1d(np.arange(objects.size), test), test))
    return splits


def leave_object_out_splits(objects: Sequence[str]) -> list[Split]:
    """One split per object: all its rows test, every other object's rows train."""
    objects = np.asarray(objects)
    return [(np.flatnonzero(objects != o), np.flatnonzero(objects == o))
            for o in dict.fromkeys(objects.tolist())]


def _single_row_seconds(model: BaseEstimator, rows: np.ndarray) -> tuple[list[float], list[float]]:
    """Per-row (feature step, classifier) times of a fitted model; a pipeline's steps up to one named
    ``features`` count as feature extraction."""
    steps = model.steps if isinstance(model, Pipeline) else [("classify", model)]
    names = [name for name, _ in steps]
    last_feature = names.index("features") if "features" in names else -1
    feature, classify = [], []
    for row in rows:
        x = row[None, :]
        spent = [0.0, 0.0]
        for index, (_, step) in enumerate(steps[:-1]):
            started = time.perf_counter()
            x = step.transform(x)
            spent[index > last_feature] += time.perf_counter() - started
        started = time.perf_counter()
        steps[-1][1].predict(x)
        spent[1] += time.perf_counter() - started
        feature.append(spent[0])
        classify.append(spent[1])
    return feature, classify


@dataclass(frozen=True)
class Scores:
    """Cross-validated scores of one model: per-split accuracy and macro F1 (over the classes present in
    the split, :func:`taxonomy.learning.metrics.present_class_f1`), summed confusion, row timings."""

    accuracy: np.ndarray
    f1: np.ndarray
    classes: tuple[str, ...]
    confusion: np.ndarray
    feature_seconds: float
    classify_seconds: float
    notes: tuple[str, ...]


Maker = Callable[[int, np.ndarray], BaseEstimator]
"""``make(split_index, y_train)`` -> an unfitted model for that split."""


def _fit_split(make: Maker, X: np.ndarray, y: np.ndarray, k: int, train: np.ndarray,
               test: np.ndarray) -> tuple[np.ndarray, list[str], list[float], list[float]]:
    """Split k: predictions of the test rows, the warnings of fitting, and for k = 0 the single-row times."""
    feature: list[float] = []
    classify: list[float] = []
    with warnings.catch_warnings(record=True) as caught, one_blas_thread():
        warnings.simplefilter("always")
        model = make(k, y[train]).fit(X[train], y[train])
        predicted = model.predict(X[test])
        if k == 0:
            feature, classify = _single_row_seconds(model, X[test[:TIMED_ROWS]])
    return predicted, list(warning_notes(caught)), feature, classify


def score(make: Maker, X: np.ndarray, y: np.ndarray, splits: Sequence[Split]) -> Scores:
    """Fit ``make(k, y_train)`` on split k's training rows and score its predictions on the test rows;
    the splits one after the other in this process, or side by side on the current runtime's Dask cluster
    (:func:`scanner.runtime.current`); the scores are the same."""
    calls = [(make, X, y, k, train, test) for k, (train, test) in enumerate(splits)]
    fitted: list = [None] * len(calls)
    results = executors.current().map_unordered(_fit_split, calls, workers=1, name="texplorer-split")
    with contextlib.closing(results):
        for k, outcome in results:
            fitted[k] = outcome
    classes = np.unique(y)
    confusion = np.zeros((classes.size, classes.size), dtype=np.int64)
    accuracy, f1, notes = [], [], []
    feature, classify = fitted[0][2:] if fitted else ([], [])
    for (_, test), (predicted, messages, _, _) in zip(splits, fitted, strict=True):
        notes += messages
        accuracy.append(float(np.mean(predicted == y[test])))
        f1.append(present_class_f1(y[test], predicted))
        confusion += confusion_matrix(y[test], predicted, labels=classes)
    return Scores(np.array(accuracy), np.array(f1), tuple(classes.tolist()), confusion,
                  float(np.median(feature)), float(np.median(classify)), tuple(dict.fromkeys(notes)))


def scored(scores: Scores, n_samples: int, extraction_seconds: float, notes: Sequence[str] = (), *, method: str,
           feature_set: str, classifier: str, motions: str, level: str, splitting: str, seed: int, paper: str = "",
           detail: str = "") -> Result:
    """The :class:`Result` of one configuration of a related method from its :func:`score`.

    ``extraction_seconds`` is the extraction time of the recordings one classification needs (added to any
    feature step inside the fitted model); ``notes`` come first, the warnings of fitting after them.
    ``r_C`` is defined where every class is a taxonomy code (any method on scans of this project's
    database, at any level). Every method fits its scaling and features inside the training rows of each
    split, so the protocol is ``nested``.
    """
    return Result(method=method, feature_set=feature_set, classifier=classifier, level=level, protocol="nested",
                  splitting=splitting, classes=scores.classes, accuracy=scores.accuracy, f1=scores.f1,
                  confusion=scores.confusion, n_samples=n_samples, seed=seed,
                  notes=tuple(dict.fromkeys([*notes, *scores.notes])), taxonomy=_taxonomy_codes(scores.classes),
                  motions=motions,
                  feature_seconds=extraction_seconds + scores.feature_seconds,
                  classify_seconds=scores.classify_seconds, paper=paper, detail=detail)


def _taxonomy_codes(classes: Sequence[str]) -> bool:
    """Whether every class is a taxonomy code or class prefix in its canonical form (``C6``, ``C6S1``, ...)."""
    try:
        return all(labels.parse_prefix(c) == c for c in classes)
    except LabelError:
        return False


def usable_rows(extracted: Extracted, rows: Sequence[int]) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The rows whose extraction worked and the columns without NaN among them, with notes on what was left
    out. A set whose every column has a NaN keeps its columns and loses the rows with NaN instead.

    Raises
    ------
    MethodError
        If no row is left, naming the first extraction failure.
    """
    wanted = list(rows)
    rows = np.array([i for i in wanted if i not in extracted.failed], dtype=np.int64)
    failures = [extracted.failed[i] for i in wanted if i in extracted.failed]
    notes = [f"{extracted.name}: {len(failures)} recording(s) left out, e.g. {failures[0]}"
             for _ in failures[:1]]
    if rows.size == 0:
        raise MethodError(f"{extracted.name} works on none of {len(wanted)} recording(s)"
                          + (f", e.g. {failures[0]}" if failures else ""))
    finite = np.isfinite(extracted.X[rows])
    columns = np.flatnonzero(finite.all(axis=0))
    if columns.size == 0:
        keep = finite.all(axis=1)
        notes.append(f"{extracted.name}: {int((~keep).sum())} row(s) with undefined values left out")
        return rows[keep], np.arange(extracted.X.shape[1]), notes
    if columns.size < extracted.X.shape[1]:
        kept = set(columns.tolist())
        dropped = [extracted.columns[k] for k in range(extracted.X.shape[1]) if k not in kept]
        notes.append(f"{extracted.name}: column(s) with undefined values left out: {', '.join(dropped)}")
    return rows, columns, notes
