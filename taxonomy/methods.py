"""The related methods on the same footing: each seed paper's features, classifiers and protocol (SPEC 7.5).

:func:`compare` runs every method that applies to a :class:`Dataset` (our scans, imported recordings or a
simulated sensor) and returns one :class:`MethodResult` per (method, feature set, classifier, motions,
level): accuracy and macro F1 over the splits of the method's published protocol, and the time per
classification split into feature extraction and the classifier itself.

=============  =========================================================================================
method         features, classifiers and protocol
=============  =========================================================================================
``fishel``     ``fishel3`` on scans (Strese et al. 2020, Fig. 18) with the project's six classifiers,
               5-fold CV grouped by sample, coarse, medium and fine levels.
``xie``        ``xie11`` (seed 000): sequences standardised on the training rows -> 11 features ->
               standardised -> PCA -> linear SVM (L2 penalty, squared hinge, C = 1), RBF SVM (C = 1),
               kNN (k = 10 at the label level, 5 at coarser levels), LDA (SVD), Gaussian NB, random forest
               (10 trees), MLP 100-50-25-8; the PCA dimension (1..11) is swept with the linear SVM by an
               inner 5-fold CV on the training folds; 5-fold CV; every level of the dataset (Xie's
               property and material levels).
``huang``      ``huang7`` (seed 001): RBF SVM (C = 30, gamma = 0.1), random forest (100 trees, depth not
               limited), kNN (k = 5); 10-fold CV.
``chathuranga``  ``chathuranga4`` (seed 002): pairwise RBF SVMs (sigma = 1) keeping the top 50 % of the
               candidates after each of three palpations; baselines: nearest spatial period V / f_p and a
               two-layer net (10 sigmoid units) on friction coefficient, x variance and x kurtosis of
               one palpation; repeated holdout of 1/6 of the trials (the paper: 20 of 120 per class).
``hoelscher``  seed 004 (Hoelscher, Peters and Hermans 2015, BioTac): ``xu3``, ``chu``, ``mean23`` (PCA to
               8), ``dallaire``, ``chitta``, ``temperature``, each standardised on the training rows, with
               naive Bayes, a full-covariance Gaussian, linear and RBF SVMs (grid search on a 20 %
               validation split of the training rows) and a random forest (100 trees, depth 3); every
               single motion under repeated leave-one-trial-per-object-out splits; the mean features of
               all motions combined by concatenation (linear SVM), voting (linear SVM, Gaussian) and summed
               probabilities (Gaussian); the material-class level and held-out objects.
=============  =========================================================================================

Interpretations (the papers leave them open): features entering an SVM, kNN or net are standardised on
the training rows; Xie's PCA dimension is chosen inside the training folds, not once on all data; the
Gaussian classifier shrinks each class covariance by 10 % towards the identity
(:class:`ShrunkGaussian`), since nine training rows cannot fill an 8x8 covariance; voting ties are broken
by a seeded random choice, as the paper breaks them at random.

Timing: ``feature_seconds`` is the extraction time of the recordings one classification needs (measured
while extracting, plus any feature step inside the fitted pipeline), ``classify_seconds`` the median time
to classify one row with the fitted model (rows timed one at a time, as a deployed classifier sees them).
"""

from __future__ import annotations

import contextlib
import math
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from itertools import combinations
from typing import TYPE_CHECKING

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.decomposition import PCA
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.ensemble import RandomForestClassifier
from sklearn.metrics import confusion_matrix, f1_score
from sklearn.model_selection import GridSearchCV, StratifiedKFold, StratifiedShuffleSplit
from sklearn.naive_bayes import GaussianNB
from sklearn.neighbors import KNeighborsClassifier
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import MinMaxScaler, StandardScaler
from sklearn.svm import SVC, LinearSVC
from sklearn.utils import Tags
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data
from threadpoolctl import threadpool_limits

from features import cluster, related
from scanner.scan import Recording, Scan
from taxonomy.errors import TexplorerError
from taxonomy.evaluation import classifier_estimators, cv_splits
from taxonomy.labels import Label

if TYPE_CHECKING:
    from distributed import Client

SEED = 0
REPEATS = 10
"""Default repetitions of the repeated protocols (seed 004 used 100 leave-one-per-object-out splits)."""

TIMED_ROWS = 5
"""Test rows of the first split whose single-row classification time is measured (the splits' models are
alike; timing every split would cost more than the evaluation)."""


class MethodError(TexplorerError, ValueError):
    """A dataset or method that cannot be compared as asked; the message says why."""


class MethodSkipped(UserWarning):
    """An applicable method that could not run on the dataset (e.g. too few trials); the message says why."""


# -- datasets ----------------------------------------------------------------------------------------

def _levels_of(recording: Recording) -> Mapping[str, str]:
    levels = recording.meta.get("levels", {})
    return levels if isinstance(levels, Mapping) else {}


@dataclass(frozen=True, eq=False)
class Dataset:
    """Labelled recordings (and, for our own database, the scans they come from) to compare methods on.

    ``label_level`` names the level of ``Recording.label`` (``object``, ``material``, ``fine``, ...);
    coarser levels come from ``Recording.meta["levels"]`` (e.g. ``{"material": "wood"}``).
    """

    name: str
    recordings: tuple[Recording, ...]
    scans: tuple[Scan, ...] = ()
    label_level: str = "label"

    def __post_init__(self) -> None:
        object.__setattr__(self, "recordings", tuple(self.recordings))
        object.__setattr__(self, "scans", tuple(self.scans))
        if not self.recordings:
            raise MethodError(f"dataset {self.name!r} has no recordings")
        unlabelled = next((r.name for r in self.recordings if not r.label), None)
        if unlabelled is not None:
            raise MethodError(f"dataset {self.name!r}: recording {unlabelled!r} has no label")
        if self.scans and len(self.scans) != len(self.recordings):
            raise MethodError(f"dataset {self.name!r}: {len(self.scans)} scans for "
                              f"{len(self.recordings)} recordings")

    @classmethod
    def from_recordings(cls, name: str, recordings: Iterable[Recording]) -> Dataset:
        """A dataset of recordings; the label level is the first one's ``meta["label_level"]`` ("label")."""
        recordings = tuple(recordings)
        level = str(recordings[0].meta.get("label_level", "label")) if recordings else "label"
        return cls(name, recordings, label_level=level)

    @classmethod
    def from_scans(cls, name: str, scans: Iterable[Scan]) -> Dataset:
        """Scans as recordings (:func:`features.related.scan_recording`) labelled at the fine, medium and
        coarse taxonomy levels."""
        scans = tuple(scans)
        recordings = []
        for scan in scans:
            label = Label.parse(scan.meta.label)
            recording = related.scan_recording(scan)
            recordings.append(replace(recording, meta={"levels": {"medium": label.at("medium"),
                                                                  "coarse": label.at("coarse")}}))
        return cls(name, tuple(recordings), scans, "fine")

    def __len__(self) -> int:
        return len(self.recordings)

    def levels(self) -> tuple[str, ...]:
        """The label level, then the coarser levels every recording has."""
        shared = [key for key in _levels_of(self.recordings[0])
                  if all(key in _levels_of(r) for r in self.recordings)]
        return (self.label_level, *shared)

    def y(self, level: str, rows: Sequence[int] | None = None) -> np.ndarray:
        """Classes at ``level`` of the recordings ``rows`` (default all)."""
        chosen = [self.recordings[i] for i in (range(len(self)) if rows is None else rows)]
        if level == self.label_level:
            return np.array([str(r.label) for r in chosen])
        if level not in self.levels():
            raise MethodError(f"dataset {self.name!r} has no level {level!r} "
                              f"(levels: {', '.join(self.levels())})")
        return np.array([str(_levels_of(r)[level]) for r in chosen])

    def motions(self) -> list[str]:
        """Motion names in order of first appearance (``"-"`` for recordings without one)."""
        return list(dict.fromkeys(motion_of(r) for r in self.recordings))

    def summary(self) -> str:
        """One line: recordings, objects, levels with their class counts, roles."""
        objects = {object_of(r) for r in self.recordings}
        levels = ", ".join(f"{level} ({np.unique(self.y(level)).size})" for level in self.levels())
        roles = sorted(set.intersection(*(set(r.roles) for r in self.recordings)))
        kind = f"{len(self.scans)} scans" if self.scans else f"{len(self)} recordings"
        motions = self.motions()
        moves = f", motions {', '.join(motions)}" if motions != ["-"] else ""
        return (f"{self.name}: {kind} of {len(objects)} objects; levels {levels}; "
                f"roles {', '.join(roles) or 'none'}{moves}")


def object_of(recording: Recording) -> str:
    """The object (sample) a recording was made on: group ``object``, else its label."""
    return str(recording.group.get("object", recording.label))


def motion_of(recording: Recording) -> str:
    return str(recording.group.get("motion", "-"))


def trial_of(recording: Recording) -> str:
    """``<object>/<trial>``: recordings of one trial (several motions or palpations) share it."""
    trial = recording.group.get("trial")
    return f"{object_of(recording)}/{recording.name if trial is None else trial}"


# -- feature extraction ------------------------------------------------------------------------------

@dataclass(frozen=True)
class Extracted:
    """A feature set of every recording: ``X`` rows in recording order (NaN where extraction failed)."""

    name: str
    columns: tuple[str, ...]
    X: np.ndarray
    seconds: np.ndarray
    failed: Mapping[int, str]


def _extractor(dataset: Dataset, name: str) -> Callable[[int], Mapping[str, float] | np.ndarray]:
    if name == "fishel3":
        if not dataset.scans:
            raise MethodError(f"fishel3 needs scans; dataset {dataset.name!r} has recordings only")
        return lambda i: related.fishel3(dataset.scans[i])
    if name == "xie_sequences":
        return lambda i: related.xie_sequence_vector(dataset.recordings[i])
    return lambda i: related.compute(name, dataset.recordings[i])


def extract(dataset: Dataset, name: str, rows: Sequence[int] | None = None) -> Extracted:
    """Feature set ``name`` (see :data:`features.related.FEATURE_SETS`, plus ``fishel3`` and
    ``xie_sequences``) of the recordings ``rows``, timed per recording; failures are recorded, not raised."""
    function = _extractor(dataset, name)
    rows = range(len(dataset)) if rows is None else rows
    values: dict[int, np.ndarray] = {}
    seconds: dict[int, float] = {}
    failed: dict[int, str] = {}
    columns: tuple[str, ...] | None = None
    for i in rows:
        started = time.perf_counter()
        try:
            result = function(i)
        except (related.RelatedFeatureError, ValueError) as exc:
            failed[i] = str(exc)
            continue
        seconds[i] = time.perf_counter() - started
        mapping = isinstance(result, Mapping)
        names = tuple(result) if mapping else tuple(f"{name}.{k}" for k in range(len(result)))
        if columns is None:
            columns = names
        if names != columns:
            failed[i] = f"{name} gives {len(names)} values here, {len(columns)} elsewhere"
            continue
        values[i] = np.fromiter(result.values(), float) if mapping else np.asarray(result, float)
    width = len(columns or ())
    X = np.full((len(dataset), width), np.nan)
    times = np.full(len(dataset), np.nan)
    for i, row in values.items():
        X[i] = row
        times[i] = seconds[i]
    return Extracted(name, columns or (), X, times, failed)


class FeatureCache:
    """Feature sets extracted once per dataset and shared by the methods of one :func:`compare` run."""

    def __init__(self, dataset: Dataset) -> None:
        self.dataset = dataset
        self._sets: dict[str, Extracted] = {}

    def get(self, name: str) -> Extracted:
        if name not in self._sets:
            self._sets[name] = extract(self.dataset, name)
        return self._sets[name]


# -- results -----------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class MethodResult:
    """One configuration of one method on one dataset.

    ``accuracy`` and ``f1`` (macro, over the classes in each split's true or predicted labels) hold one
    value per split; ``confusion`` sums all splits (rows true, columns predicted, order of ``classes``).
    Times are per classification in seconds. ``paper`` is the figure the paper reports for this
    configuration, where it reports one.
    """

    method: str
    features: str
    classifier: str
    motions: str
    level: str
    protocol: str
    accuracy: np.ndarray
    f1: np.ndarray
    classes: tuple[str, ...]
    confusion: np.ndarray
    n_samples: int
    feature_seconds: float
    classify_seconds: float
    paper: str = ""
    detail: str = ""
    notes: tuple[str, ...] = field(default=())

    @property
    def accuracy_mean(self) -> float:
        return float(np.mean(self.accuracy))

    @property
    def accuracy_std(self) -> float:
        return float(np.std(self.accuracy, ddof=1)) if len(self.accuracy) > 1 else 0.0

    @property
    def f1_mean(self) -> float:
        return float(np.mean(self.f1))

    @property
    def chance(self) -> float:
        """Accuracy of always answering the most frequent class."""
        counts = self.confusion.sum(axis=1)
        return float(counts.max() / counts.sum()) if counts.sum() else math.nan

    def cells(self) -> tuple[str, ...]:
        """The row of the comparison table, in :data:`COLUMNS` order."""
        return (self.method, self.features, self.classifier, self.motions,
                f"{self.level} ({len(self.classes)})", self.protocol,
                f"{100 * self.accuracy_mean:5.1f} +- {100 * self.accuracy_std:4.1f}", f"{self.f1_mean:4.2f}",
                f"{1e3 * self.feature_seconds:8.3f}", f"{1e6 * self.classify_seconds:9.1f}", self.paper)


COLUMNS = ("method", "features", "classifier", "motions", "level (classes)", "protocol", "accuracy %",
           "macro F1", "features ms", "classify us", "paper")
"""Columns of the comparison table (times per classification)."""


def format_comparison(results: Sequence[MethodResult]) -> str:
    """The comparison table as text: one row per result, then the notes."""
    if not results:
        return "no method applies to this dataset"
    rows = [COLUMNS, *(r.cells() for r in results)]
    widths = [max(len(row[k]) for row in rows) for k in range(len(COLUMNS))]
    lines = ["  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
             for row in rows]
    lines.insert(1, "  ".join("-" * width for width in widths))
    return "\n".join(lines + [f"note: {note}" for note in result_notes(results)])


def result_notes(results: Sequence[MethodResult]) -> list[str]:
    """Every note once, naming the method (and feature set) that raised it."""
    return list(dict.fromkeys(f"{r.method} {r.features}: {note}" for r in results for note in r.notes))


# -- splits and scoring ------------------------------------------------------------------------------

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
    """Seed 004's protocol: each split tests one randomly chosen row of every object, trains on the rest.

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


def one_line(text: str) -> str:
    """A message whole on one line: its lines joined, runs of white space made one space."""
    return " ".join(str(text).split())


def _messages(caught: list[warnings.WarningMessage]) -> list[str]:
    return [f"{w.category.__name__}: {one_line(str(w.message))}" for w in caught]


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
    """Cross-validated scores of one model: per-split accuracy and F1, summed confusion, row timings."""

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
    with warnings.catch_warnings(record=True) as caught, threadpool_limits(limits=1):
        warnings.simplefilter("always")
        model = make(k, y[train]).fit(X[train], y[train])
        predicted = model.predict(X[test])
        if k == 0:
            feature, classify = _single_row_seconds(model, X[test[:TIMED_ROWS]])
    return predicted, _messages(caught), feature, classify


def score(make: Maker, X: np.ndarray, y: np.ndarray, splits: Sequence[Split],
          client: Client | None = None) -> Scores:
    """Fit ``make(k, y_train)`` on split k's training rows and score its predictions on the test rows;
    the splits one after the other here, or side by side on the Dask cluster of ``client``."""
    calls = [(make, X, y, k, train, test) for k, (train, test) in enumerate(splits)]
    if client is None:
        fitted = [_fit_split(*call) for call in calls]
    else:
        fitted = [None] * len(calls)
        with contextlib.closing(cluster.run(client, _fit_split, calls, name="texplorer-split")) as results:
            for k, outcome in results:
                fitted[k] = outcome
    classes = np.unique(y)
    confusion = np.zeros((classes.size, classes.size), dtype=np.int64)
    accuracy, f1, notes = [], [], []
    feature, classify = fitted[0][2:] if fitted else ([], [])
    for (_, test), (predicted, messages, _, _) in zip(splits, fitted, strict=True):
        notes += messages
        accuracy.append(float(np.mean(predicted == y[test])))
        f1.append(float(f1_score(y[test], predicted, average="macro", zero_division=0.0)))
        confusion += confusion_matrix(y[test], predicted, labels=classes)
    return Scores(np.array(accuracy), np.array(f1), tuple(classes.tolist()), confusion,
                  float(np.median(feature)), float(np.median(classify)), tuple(dict.fromkeys(notes)))


@dataclass(frozen=True)
class _Run:
    """What a result row says about its configuration besides the scores."""

    method: str
    features: str
    classifier: str
    motions: str
    level: str
    protocol: str
    paper: str = ""
    detail: str = ""


def _result(run: _Run, scores: Scores, n_samples: int, extraction_seconds: float,
            notes: Sequence[str] = ()) -> MethodResult:
    return MethodResult(run.method, run.features, run.classifier, run.motions, run.level, run.protocol,
                        scores.accuracy, scores.f1, scores.classes, scores.confusion, n_samples,
                        extraction_seconds + scores.feature_seconds, scores.classify_seconds, run.paper,
                        run.detail, tuple(dict.fromkeys([*notes, *scores.notes])))


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


# -- fishel ------------------------------------------------------------------------------------------

def run_fishel(dataset: Dataset, cache: FeatureCache, seed: int, repeats: int,
               client: Client | None = None) -> list[MethodResult]:
    """``fishel3`` with the project's six classifiers, 5-fold CV grouped by sample (fewer folds when a class
    has fewer scans), every taxonomy level."""
    extracted = cache.get("fishel3")
    rows, columns, notes = usable_rows(extracted, range(len(dataset)))
    X = extracted.X[np.ix_(rows, columns)]
    groups = [object_of(dataset.recordings[i]) for i in rows]
    # The fine labels decide the grouping, so every level is split alike (as taxonomy.evaluation.evaluate does).
    fine = dataset.y(dataset.label_level, rows)
    folds = max(2, min(5, int(np.unique(fine, return_counts=True)[1].min())))
    results = []
    for level in dataset.levels():
        y = dataset.y(level, rows)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            splits, grouped = cv_splits(y, groups, folds, seed, grouping_labels=fine)
        protocol = f"{len(splits)}-fold CV{' by sample' if grouped else ''}"
        for name in classifier_estimators(seed):
            def make(_: int, __: np.ndarray, name: str = name) -> Pipeline:
                return Pipeline([("scale", MinMaxScaler()),
                                 ("classify", _without_probability(classifier_estimators(seed)[name]))])
            run = _Run("fishel", "fishel3", name, "tool slide + friction", level, protocol)
            seconds = float(np.nanmedian(extracted.seconds[rows]))
            results.append(_result(run, score(make, X, y, splits, client), len(rows), seconds,
                                   [*notes, *_messages(caught)]))
    return results


def _without_probability(classifier: BaseEstimator) -> BaseEstimator:
    """The classifier without Platt scaling (the SVM's ``probability``): predictions do not use it, it
    costs an internal 5-fold fit, and scikit-learn 1.9 deprecates the argument."""
    params = classifier.get_params(deep=False)
    if "probability" not in params:
        return classifier
    del params["probability"]
    return type(classifier)(**params)


# -- xie ---------------------------------------------------------------------------------------------

XIE_CLASSIFIERS = ("linear-svm", "rbf-svm", "knn", "lda", "nb", "rf", "mlp")
XIE_PAPER = {
    "property": {"linear-svm": "92.0 %, 4.6 ms + 0.7 us", "rbf-svm": "94.1 %, 4.3 ms + 23 us",
                 "knn": "95.8 %, 4.6 ms + 17 us", "lda": "91.0 %, 4.7 ms + 0.7 us",
                 "nb": "77.4 %, 4.4 ms + 1.4 us",
                 "rf": "90.6 %, 4.8 ms + 2.8 us", "mlp": "94.8 %, 4.5 ms + 3.5 us"},
    "material": {"linear-svm": "84.0 %, 4.9 ms + 1.4 us", "rbf-svm": "85.4 %, 4.6 ms + 49 us",
                 "knn": "85.8 %, 4.9 ms + 212 us", "lda": "80.6 %, 5.0 ms + 1.4 us",
                 "nb": "73.6 %, 4.2 ms + 2.1 us",
                 "rf": "80.2 %, 4.4 ms + 118 us", "mlp": "90.3 %, 4.8 ms + 3.5 us"},
}
"""Xie et al. Tables 4 and 5: accuracy, feature extraction time and classification time per sample."""

XIE_MAX_DIMENSIONS = 11


def xie_classifier(name: str, k: int, seed: int) -> BaseEstimator:
    """One of Xie et al.'s seven classifiers (section 3.5)."""
    return {
        "linear-svm": lambda: LinearSVC(penalty="l2", loss="squared_hinge", C=1.0, random_state=seed),
        "rbf-svm": lambda: SVC(kernel="rbf", C=1.0),
        "knn": lambda: KNeighborsClassifier(n_neighbors=k),
        "lda": lambda: LinearDiscriminantAnalysis(solver="svd"),
        "nb": GaussianNB,
        "rf": lambda: RandomForestClassifier(n_estimators=10, random_state=seed, n_jobs=1),
        "mlp": lambda: MLPClassifier(hidden_layer_sizes=(100, 50, 25, 8), max_iter=1000, random_state=seed),
    }[name]()


def xie_pipeline(classifier: BaseEstimator, dimensions: int) -> Pipeline:
    """Sequence vectors -> standardised sequences -> 11 features -> standardised -> PCA -> classifier."""
    return Pipeline([("features", related.XieFeatures()), ("scale", StandardScaler()),
                     ("pca", PCA(n_components=dimensions)), ("classify", classifier)])


def pca_sweep(X: np.ndarray, y: np.ndarray, seed: int, folds: int = 5) -> np.ndarray:
    """Mean inner-CV accuracy of the linear SVM for 1..11 principal components (Xie et al. Fig. 4).

    The 11 features of each inner training fold are computed once and shared by every dimension.
    """
    inner = kfold_splits(y, folds, seed)
    most = min(XIE_MAX_DIMENSIONS, *(len(train) for train, _ in inner))
    accuracy = np.zeros(most)
    for train, test in inner:
        features = Pipeline([("features", related.XieFeatures()), ("scale", StandardScaler())]).fit(X[train])
        F_train, F_test = features.transform(X[train]), features.transform(X[test])
        for d in range(1, most + 1):
            pca = PCA(n_components=d).fit(F_train)
            svm = xie_classifier("linear-svm", 1, seed).fit(pca.transform(F_train), y[train])
            accuracy[d - 1] += np.mean(svm.predict(pca.transform(F_test)) == y[test]) / len(inner)
    return accuracy


def _slides_first(dataset: Dataset, rows: Sequence[int]) -> tuple[list[int], str]:
    """Xie and Huang classify slides: keep the sliding motions when the dataset has named motions."""
    slides = [i for i in rows if "slide" in motion_of(dataset.recordings[i])]
    return (slides, "slides") if slides else (list(rows), "all")


def run_xie(dataset: Dataset, cache: FeatureCache, seed: int, repeats: int,
            client: Client | None = None) -> list[MethodResult]:
    """Xie et al.: PCA dimension swept per training fold with the linear SVM, then seven classifiers."""
    extracted = cache.get("xie_sequences")
    chosen, motions = _slides_first(dataset, range(len(dataset)))
    rows, columns, notes = usable_rows(extracted, chosen)
    X = extracted.X[np.ix_(rows, columns)]
    seconds = float(np.nanmedian(extracted.seconds[rows]))
    results = []
    for level in dataset.levels():
        y = dataset.y(level, rows)
        splits = kfold_splits(y, 5, seed)
        dims = [int(np.argmax(pca_sweep(X[train], y[train], seed)) + 1) for train, _ in splits]
        kind = "property" if level == "property" else "material"
        neighbours = 10 if level == dataset.label_level else 5
        for name in XIE_CLASSIFIERS:
            def make(fold: int, y_train: np.ndarray, name: str = name, dims: list[int] = dims,
                     neighbours: int = neighbours) -> Pipeline:
                # The paper's k, at most the smallest training class (a class of 5 has no 10 neighbours).
                k = min(neighbours, int(np.unique(y_train, return_counts=True)[1].min()))
                return xie_pipeline(xie_classifier(name, k, seed), dims[fold])
            scores = score(make, X, y, splits, client)
            stages = (f"per sample: images -> sequences {1e3 * seconds:.2f} ms, standardised sequences -> "
                      f"11 features {1e3 * scores.feature_seconds:.2f} ms, PCA + classifier "
                      f"{1e6 * scores.classify_seconds:.0f} us; PCA dimensions per fold {dims}")
            run = _Run("xie", "xie11", name, motions, level, f"{len(splits)}-fold CV", XIE_PAPER[kind][name],
                       stages)
            results.append(_result(run, scores, len(rows), seconds, notes))
    return results


# -- huang -------------------------------------------------------------------------------------------

HUANG_PAPER = {"svm": "95 +- 2.3 %, 0.47 s features", "rf": "94 +- 2.2 %, 0.47 s features",
               "knn": "94 +- 2.2 %, 0.47 s features"}
"""Huang and Wu Table 4 and section 2.2."""


def huang_classifier(name: str, seed: int) -> BaseEstimator:
    """Huang and Wu's grid-searched classifiers: RBF SVM C = 30, gamma = 0.1; 100 trees; k = 5."""
    return {
        "svm": lambda: Pipeline([("scale", StandardScaler()),
                                 ("classify", SVC(kernel="rbf", C=30.0, gamma=0.1))]),
        "rf": lambda: RandomForestClassifier(n_estimators=100, max_depth=None, random_state=seed, n_jobs=1),
        "knn": lambda: Pipeline([("scale", StandardScaler()),
                                 ("classify", KNeighborsClassifier(n_neighbors=5))]),
    }[name]()


def run_huang(dataset: Dataset, cache: FeatureCache, seed: int, repeats: int,
              client: Client | None = None) -> list[MethodResult]:
    """Huang and Wu: seven band means, RBF SVM / random forest / kNN, 10-fold CV at the label level."""
    extracted = cache.get("huang7")
    chosen, motions = _slides_first(dataset, range(len(dataset)))
    rows, columns, notes = usable_rows(extracted, chosen)
    X = extracted.X[np.ix_(rows, columns)]
    y = dataset.y(dataset.label_level, rows)
    splits = kfold_splits(y, 10, seed)
    seconds = float(np.nanmedian(extracted.seconds[rows]))
    results = []
    for name in HUANG_PAPER:
        run = _Run("huang", "huang7", name, motions, dataset.label_level, f"{len(splits)}-fold CV",
                   HUANG_PAPER[name])
        def make(_: int, __: np.ndarray, name: str = name) -> BaseEstimator:
            return huang_classifier(name, seed)
        results.append(_result(run, score(make, X, y, splits, client), len(rows), seconds, notes))
    return results


# -- chathuranga -------------------------------------------------------------------------------------

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


def run_chathuranga(dataset: Dataset, cache: FeatureCache, seed: int, repeats: int,
                    client: Client | None = None) -> list[MethodResult]:
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
    splits = holdout_splits(y, max(repeats // 2, 2), 1 / 6, seed)
    protocol = f"{len(splits)} x holdout 1/6"
    level = dataset.label_level
    seconds = float(np.nanmedian(c4.seconds[first])) * count
    run = _Run("chathuranga", "chathuranga4", "pairwise-svm", f"{count} palpation(s)", level, protocol,
               CHATHURANGA_PAPER["pairwise-svm"])
    scores = score(lambda _, __: PairwiseEliminationSVM(palpations=count), X, y, splits, client)
    results = [_result(run, scores, len(y), seconds)]
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
        run = _Run("chathuranga", set_name, name, "1 palpation", level, protocol, CHATHURANGA_PAPER[name])
        scores = score(lambda _, __, make=make: make(), X_b, y_b, b_splits, client)
        results.append(_result(run, scores, len(y_b), float(np.nanmedian(extracted.seconds[usable])), results_note))
    return results


# -- hoelscher (seed 004) ----------------------------------------------------------------------------

HOELSCHER_SETS = ("xu3", "chu", "mean23", "dallaire", "chitta", "temperature")
HOELSCHER_CLASSIFIERS = ("nb", "gaussian", "linear-svm", "rbf-svm", "rf")
MEAN_DIMENSIONS = 8
"""Seed 004 reduces the 23 channel means to 8 principal components (~98 % of their variance)."""


class ValidationSplit:
    """One stratified validation split of 20 % of the training rows, at least one row per class
    (a scikit-learn CV splitter for grid searches on small training sets)."""

    def __init__(self, seed: int = SEED) -> None:
        self.seed = seed

    def get_n_splits(self, X: object = None, y: object = None, groups: object = None) -> int:
        return 1

    def split(self, X: np.ndarray, y: np.ndarray, groups: object = None) -> Iterator[Split]:
        classes = np.unique(y).size
        size = max(classes, int(round(0.2 * len(y))))
        yield from StratifiedShuffleSplit(n_splits=1, test_size=size, random_state=self.seed).split(X, y)


def _validated(svm: SVC, grid: Mapping[str, Sequence[float]], seed: int) -> GridSearchCV:
    """Grid search on one validation split of the training rows (:class:`ValidationSplit`)."""
    return GridSearchCV(svm, dict(grid), cv=ValidationSplit(seed))


class ShrunkGaussian(ClassifierMixin, BaseEstimator):
    """Seed 004's "Gaussian classifier": a full-covariance Gaussian per class, Bayes' rule with the class
    frequencies as priors.

    Interpretation: each class covariance ``S`` (maximum likelihood) is shrunk to ``(1 - r) S + r I`` with
    ``r = shrinkage``, because a class has fewer training rows (9 in the paper) than a covariance needs;
    the features are standardised first, so the identity is their scale.
    """

    def __init__(self, shrinkage: float = 0.1) -> None:
        self.shrinkage = shrinkage

    def fit(self, X: np.ndarray, y: np.ndarray) -> ShrunkGaussian:
        X, y = validate_data(self, X, y)
        check_classification_targets(y)
        self.classes_, counts = np.unique(y, return_counts=True)
        eye = np.eye(X.shape[1])
        self.means_ = np.array([X[y == c].mean(axis=0) for c in self.classes_])
        covariances = [np.atleast_2d(np.cov(X[y == c].T, ddof=0)) if counts[k] > 1 else eye
                       for k, c in enumerate(self.classes_)]
        shrunk = [(1 - self.shrinkage) * S + self.shrinkage * eye for S in covariances]
        self.precisions_ = np.array([np.linalg.inv(S) for S in shrunk])
        log_det = np.array([np.linalg.slogdet(S)[1] for S in shrunk])
        self.log_norm_ = log_det / 2 - np.log(counts / counts.sum())
        return self

    def _log_posterior(self, X: np.ndarray) -> np.ndarray:
        centred = validate_data(self, X, reset=False)[:, None, :] - self.means_[None]
        distance = np.einsum("ncj,cjk,nck->nc", centred, self.precisions_, centred)
        return -0.5 * distance - self.log_norm_

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "means_")
        log = self._log_posterior(X)
        weights = np.exp(log - log.max(axis=1, keepdims=True))
        return weights / weights.sum(axis=1, keepdims=True)

    def predict(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "means_")
        return self.classes_[np.argmax(self._log_posterior(X), axis=1)]


def hoelscher_classifier(name: str, seed: int) -> BaseEstimator:
    """Seed 004's classifiers (section III-C)."""
    return {
        "nb": GaussianNB,
        "gaussian": ShrunkGaussian,
        "linear-svm": lambda: _validated(SVC(kernel="linear"), {"C": [0.01, 0.1, 1.0, 10.0, 100.0]}, seed),
        "rbf-svm": lambda: _validated(SVC(kernel="rbf"), {"C": [0.1, 1.0, 10.0, 100.0],
                                                          "gamma": [0.01, 0.1, 1.0]}, seed),
        "rf": lambda: RandomForestClassifier(n_estimators=100, max_depth=3, random_state=seed, n_jobs=1),
    }[name]()


def hoelscher_features(set_name: str) -> BaseEstimator:
    """Standardisation on the training rows; the mean features then go to 8 principal components."""
    if set_name == "mean23":
        return Pipeline([("scale", StandardScaler()), ("pca", PCA(n_components=MEAN_DIMENSIONS))])
    return StandardScaler()


COMBINATIONS = ("concatenation", "voting", "probabilities")


class MotionCombination(ClassifierMixin, BaseEstimator):
    """Seed 004's combination of the motions of one trial (section IV-B).

    A row holds the features of ``blocks`` motions side by side, in a fixed motion order.
    ``concatenation``: each block through its own fitted ``features`` step, side by side into one
    ``classifier``. ``voting``: one ``features`` + ``classifier`` per motion, the most frequent answer wins
    (ties broken by a random choice seeded by ``seed``). ``probabilities``: one model per motion, the class
    with the largest summed probability wins.
    """

    def __init__(self, features: BaseEstimator, classifier: BaseEstimator, blocks: int,
                 mode: str = "concatenation", seed: int = SEED) -> None:
        self.features = features
        self.classifier = classifier
        self.blocks = blocks
        self.mode = mode
        self.seed = seed

    def _split(self, X: np.ndarray) -> list[np.ndarray]:
        if X.shape[1] % self.blocks:
            raise MethodError(f"{X.shape[1]} columns do not split into {self.blocks} motions")
        return np.split(X, self.blocks, axis=1)

    def fit(self, X: np.ndarray, y: np.ndarray) -> MotionCombination:
        if self.mode not in COMBINATIONS:
            raise MethodError(f"unknown combination {self.mode!r} (known: {', '.join(COMBINATIONS)})")
        X, y = validate_data(self, X, y)
        check_classification_targets(y)
        parts = self._split(X)
        self.classes_ = np.unique(y)
        if self.mode == "concatenation":
            self.steps_ = [clone(self.features).fit(part) for part in parts]
            self.model_ = clone(self.classifier).fit(self._joined(parts), y)
        else:
            self.models_ = [Pipeline([("features", clone(self.features)),
                                      ("classify", clone(self.classifier))]).fit(part, y) for part in parts]
        return self

    def _joined(self, parts: list[np.ndarray]) -> np.ndarray:
        return np.hstack([step.transform(part) for step, part in zip(self.steps_, parts, strict=True)])

    def predict(self, X: np.ndarray) -> np.ndarray:
        check_is_fitted(self, "classes_")
        parts = self._split(validate_data(self, X, reset=False))
        if self.mode == "concatenation":
            return self.model_.predict(self._joined(parts))
        if self.mode == "probabilities":
            total = sum(model.predict_proba(part) for model, part in zip(self.models_, parts, strict=True))
            return self.classes_[np.argmax(total, axis=1)]
        answers = np.column_stack([model.predict(part)
                                   for model, part in zip(self.models_, parts, strict=True)])
        rng = np.random.default_rng(self.seed)
        return np.array([self._vote(row, rng) for row in answers])

    def _vote(self, answers: np.ndarray, rng: np.random.Generator) -> str:
        names, counts = np.unique(answers, return_counts=True)
        tied = names[counts == counts.max()]
        return tied[0] if tied.size == 1 else tied[rng.integers(tied.size)]


HOELSCHER_PAPER = {("mean23", "linear-svm", "concatenation"): "97.6 +- 2.1 % (5 motions, 49 objects)",
                   ("mean23", "gaussian", "static"): "87.5 +- 4.0 % (static, mean features)"}


def _motion_rows(dataset: Dataset, motion: str) -> list[int]:
    return [i for i, r in enumerate(dataset.recordings) if motion_of(r) == motion]


def _single_motion(dataset: Dataset, cache: FeatureCache, set_name: str, classifier: str, seed: int,
                   repeats: int, client: Client | None = None) -> MethodResult:
    """One feature set and classifier on every motion separately; the accuracies of all motions together.
    Motions it cannot run on are noted; if that is every motion, a :class:`MethodError` says why."""
    extracted = cache.get(set_name)
    level = dataset.label_level
    per_motion, scores, notes, sizes, seconds = {}, [], [], [], []
    for motion in dataset.motions():
        try:
            rows, columns, dropped = usable_rows(extracted, _motion_rows(dataset, motion))
            objects = [object_of(dataset.recordings[i]) for i in rows]
            splits = one_per_object_splits(objects, repeats, seed)
        except MethodError as exc:
            notes.append(f"{set_name}, motion {motion}: {exc}")
            continue
        y = dataset.y(level, rows)
        def make(_: int, __: np.ndarray) -> Pipeline:
            return Pipeline([("features", hoelscher_features(set_name)),
                             ("classify", hoelscher_classifier(classifier, seed))])
        result = score(make, extracted.X[np.ix_(rows, columns)], y, splits, client)
        per_motion[motion] = float(np.mean(result.accuracy))
        scores.append(result)
        notes += dropped
        sizes.append(rows.size)
        seconds.append(float(np.nanmedian(extracted.seconds[rows])))
    if not scores:
        raise MethodError("; ".join(dict.fromkeys(notes)))
    merged = Scores(np.concatenate([s.accuracy for s in scores]), np.concatenate([s.f1 for s in scores]),
                    scores[0].classes, sum(s.confusion for s in scores if s.classes == scores[0].classes),
                    float(np.median([s.feature_seconds for s in scores])),
                    float(np.median([s.classify_seconds for s in scores])),
                    tuple(dict.fromkeys(n for s in scores for n in s.notes)))
    motions = "static" if list(per_motion) == ["static"] else (
        "each" if len(per_motion) > 1 else next(iter(per_motion)))
    run = _Run("hoelscher", set_name, classifier, motions, level, f"{repeats} x one per object",
               HOELSCHER_PAPER.get((set_name, classifier, motions), ""),
               "per motion: " + ", ".join(f"{m} {100 * a:.1f} %" for m, a in per_motion.items()))
    return _result(run, merged, int(np.mean(sizes)), float(np.median(seconds)), notes)


def combined_table(dataset: Dataset, extracted: Extracted,
                   motions: Sequence[str]) -> tuple[np.ndarray, list[int]]:
    """Trials with every motion usable: features of ``motions`` side by side, and each trial's first row."""
    trials: dict[str, dict[str, int]] = {}
    for i, recording in enumerate(dataset.recordings):
        if i not in extracted.failed and np.all(np.isfinite(extracted.X[i])):
            trials.setdefault(trial_of(recording), {})[motion_of(recording)] = i
    complete = [t for t in trials.values() if all(m in t for m in motions)]
    table = np.array([np.concatenate([extracted.X[t[m]] for m in motions]) for t in complete])
    return table.reshape(len(complete), -1), [t[motions[0]] for t in complete]


def _combined(dataset: Dataset, cache: FeatureCache, mode: str, classifier: str, level: str,
              protocol: str, seed: int, repeats: int, client: Client | None = None) -> MethodResult | None:
    extracted = cache.get("mean23")
    motions = dataset.motions()
    X, first = combined_table(dataset, extracted, motions)
    if len(first) == 0:
        return None
    y = dataset.y(level, first)
    objects = [object_of(dataset.recordings[i]) for i in first]
    splits = (one_per_object_splits(objects, repeats, seed) if protocol == "one per object"
              else leave_object_out_splits(objects))
    def make(_: int, __: np.ndarray) -> MotionCombination:
        return MotionCombination(hoelscher_features("mean23"), hoelscher_classifier(classifier, seed),
                                 len(motions), mode, seed)
    label = f"{len(motions)} motions, {mode}"
    shown = f"{repeats} x one per object" if protocol == "one per object" else "held-out objects"
    paper = HOELSCHER_PAPER.get(("mean23", classifier, mode), "") if level == dataset.label_level else ""
    run = _Run("hoelscher", "mean23", classifier, label, level, shown, paper)
    seconds = float(np.nanmedian(extracted.seconds[first])) * len(motions)
    return _result(run, score(make, X, y, splits, client), len(first), seconds)


def run_hoelscher(dataset: Dataset, cache: FeatureCache, seed: int, repeats: int,
                  client: Client | None = None) -> list[MethodResult]:
    """Seed 004: every applicable feature set x classifier per motion, then motion combinations, the
    material-class level and held-out objects with the mean features."""
    sets = [s for s in HOELSCHER_SETS if _every(dataset, s)]
    results, problems = [], []
    for set_name in sets:
        for classifier in HOELSCHER_CLASSIFIERS:
            try:
                results.append(_single_motion(dataset, cache, set_name, classifier, seed, repeats, client))
            except MethodError as exc:
                problems.append(str(exc))
    if not results:
        raise MethodError(problems[0] if problems else "no seed-004 feature set applies")
    if "mean23" not in sets:
        return results
    label = dataset.label_level
    runs = []
    if len(dataset.motions()) > 1:
        runs += [(mode, classifier, label, "one per object")
                 for mode, classifier in (("concatenation", "linear-svm"), ("voting", "linear-svm"),
                                          ("voting", "gaussian"), ("probabilities", "gaussian"))]
    for level in dataset.levels()[1:]:
        runs += [("concatenation", "linear-svm", level, "one per object"),
                 ("concatenation", "linear-svm", level, "held-out objects")]
    for mode, classifier, level, protocol in runs:
        try:
            result = _combined(dataset, cache, mode, classifier, level, protocol, seed, repeats, client)
        except MethodError as exc:
            warnings.warn(f"method hoelscher: {mode} of the motions ({classifier}, {level}, {protocol}) "
                          f"skipped: {exc}", MethodSkipped, stacklevel=2)
            continue
        if result is not None:
            results.append(result)
    return results


# -- registry and compare ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Method:
    """A related method: the paper, what it needs and how it runs."""

    name: str
    paper: str
    needs: str
    applies: Callable[[Dataset], bool]
    run: Callable[[Dataset, FeatureCache, int, int, Client | None], list[MethodResult]]


def _every(dataset: Dataset, set_name: str) -> bool:
    return all(related.FEATURE_SETS[set_name].applies_to(r) for r in dataset.recordings)


METHODS: Mapping[str, Method] = {m.name: m for m in (
    Method("fishel", "Strese et al. 2020 Fig. 18 (features after Fishel and Loeb 2012)",
           "scans (v_ts, f_frn, f_frt)", lambda d: bool(d.scans), run_fishel),
    Method("xie", "Xie et al. 2019, Applied Sciences", "taxels or electrodes",
           lambda d: _every(d, "xie11"), run_xie),
    Method("huang", "Huang and Wu 2021, Sensors", "vibration", lambda d: _every(d, "huang7"),
           run_huang),
    Method("chathuranga", "Chathuranga et al. 2015, IROS", "force_xyz",
           lambda d: _every(d, "chathuranga4"), run_chathuranga),
    Method("hoelscher", "Hoelscher, Peters and Hermans 2015, Humanoids",
           "one of vibration, electrodes, heat_flow + temperature",
           lambda d: any(_every(d, s) for s in HOELSCHER_SETS), run_hoelscher),
)}
"""The related methods by name, in the order :func:`compare` runs them."""


def applicable(dataset: Dataset) -> list[str]:
    """Names of the methods whose inputs every recording of ``dataset`` has."""
    return [name for name, method in METHODS.items() if method.applies(dataset)]


METHOD_ROLES: Mapping[str, tuple[tuple[str, ...], ...]] = {
    "xie": (("taxels", "electrodes"),), "huang": (("vibration",),), "chathuranga": (("force_xyz",),),
    "hoelscher": (("vibration",), ("electrodes",), ("heat_flow", "temperature")),
}
"""What each method reads: alternatives (any one suffices) of roles that must all be present."""


def not_applicable(dataset: Dataset, name: str) -> str | None:
    """Why method ``name`` does not apply to ``dataset`` (the missing role or input), or None if it does."""
    method = METHODS[name]
    if method.applies(dataset):
        return None
    if name == "fishel":
        return f"needs scans ({method.needs.split('(')[-1].rstrip(')')}); {dataset.name} has recordings only"
    have = sorted(set.union(*(set(r.roles) for r in dataset.recordings)))
    options = METHOD_ROLES[name]
    lacking = min(([role for role in option if not all(role in r.roles for r in dataset.recordings)]
                   for option in options), key=len)
    count = sum(1 for r in dataset.recordings if not all(role in r.roles for role in lacking))
    lacks = "taxels or electrodes" if name == "xie" else " + ".join(lacking)
    needs = f"the role {lacks}" if len(options) == 1 else method.needs
    return (f"needs {needs}; {count} of {len(dataset)} recordings lack {lacks} "
            f"(roles present: {', '.join(have) or 'none'})")


@dataclass(frozen=True)
class Comparison:
    """The results of :func:`compare_methods` and, for every method, ``ran`` or why it did not run."""

    results: list[MethodResult]
    outcome: dict[str, str]

    def format_outcome(self) -> str:
        width = max(len(name) for name in self.outcome)
        return "\n".join(f"{name:<{width}}  {status}" for name, status in self.outcome.items())


def compare_methods(dataset: Dataset | Sequence[Recording] | Sequence[Scan], methods: Sequence[str] | None = None,
                    *, seed: int = SEED, repeats: int = REPEATS,
                    progress: Callable[[Iterable[str]], Iterable[str]] = iter,
                    client: Client | None = None) -> Comparison:
    """:func:`compare` (on the Dask cluster of ``client`` if given), with the outcome of every method:
    ``ran (n results)`` (and the parts it skipped), or ``not run:`` the role or value it lacks, or why the
    data could not feed it."""
    data = _as_dataset(dataset)
    outcome = {name: f"not run: {reason}" for name in METHODS
               if methods is None and (reason := not_applicable(data, name))}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MethodSkipped)
        results = compare(data, methods, seed=seed, repeats=repeats, progress=progress, client=client)
    skipped = [str(w.message) for w in caught if issubclass(w.category, MethodSkipped)]
    for w in caught:
        if not issubclass(w.category, MethodSkipped):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    for name in METHODS if methods is None else methods:
        if name in outcome:
            continue
        count = sum(1 for r in results if r.method == name)
        own = [line.split(":", 1)[1].strip() if line.startswith(f"method {name} skipped:") else
               line.removeprefix(f"method {name}: ") for line in skipped
               if line.startswith((f"method {name} skipped:", f"method {name}:"))]
        if count == 0:
            outcome[name] = "not run: " + ("; ".join(own) or "no result")
        else:
            outcome[name] = f"ran ({count} results)" + "".join(f"; {line}" for line in own)
    return Comparison(results, {name: outcome[name] for name in METHODS if name in outcome})


def compare(dataset: Dataset | Sequence[Recording] | Sequence[Scan], methods: Sequence[str] | None = None, *,
            seed: int = SEED, repeats: int = REPEATS, progress: Callable[[Iterable[str]], Iterable[str]] = iter,
            client: Client | None = None) -> list[MethodResult]:
    """Run the related methods on one dataset, each with its published features, classifiers and protocol.

    Parameters
    ----------
    dataset : Dataset, or a sequence of recordings or scans
    methods : names from :data:`METHODS`, optional
        Default: every method that applies (:func:`applicable`); one that then cannot run on the data (too
        few rows per class, recordings too short, ...) is skipped with a :class:`MethodSkipped` warning.
        A named method that does not apply or cannot run is an error.
    seed : int
        Seed of every split and classifier.
    repeats : int
        Repetitions of the repeated protocols (seed 004's one-per-object splits; Chathuranga's holdouts use
        half as many, at least two).
    progress : callable
        Wraps the iteration over the methods (e.g. a tqdm bar).
    client : distributed.Client, optional
        Fit the splits of each configuration side by side on this Dask cluster (:mod:`features.cluster`)
        instead of one after the other here; the scores are the same.

    Returns
    -------
    list of MethodResult
        In method order; see :func:`format_comparison` for the table.
    """
    data = _as_dataset(dataset)
    names = applicable(data) if methods is None else list(methods)
    unknown = [name for name in names if name not in METHODS]
    if unknown:
        raise MethodError(f"unknown method(s) {', '.join(unknown)} (known: {', '.join(METHODS)})")
    for name in names:
        if not METHODS[name].applies(data):
            raise MethodError(f"method {name} needs {METHODS[name].needs}, which dataset {data.name!r} lacks")
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise MethodError(f"repeats must be a positive integer, got {repeats!r}")
    cache = FeatureCache(data)
    results: list[MethodResult] = []
    for name in progress(names):
        try:
            results += METHODS[name].run(data, cache, seed, repeats, client)
        except ValueError as exc:
            # A method the caller asked for must run; one merely applicable may find the data too small.
            reason = str(exc) if isinstance(exc, MethodError) else f"{type(exc).__name__}: {exc}"
            if methods is not None:
                raise MethodError(f"method {name}: {reason}") from None
            warnings.warn(f"method {name} skipped: {reason}", MethodSkipped, stacklevel=2)
    return results


def _as_dataset(dataset: Dataset | Sequence[Recording] | Sequence[Scan]) -> Dataset:
    if isinstance(dataset, Dataset):
        return dataset
    items = list(dataset)
    if items and all(isinstance(item, Scan) for item in items):
        return Dataset.from_scans("scans", items)
    if items and all(isinstance(item, Recording) for item in items):
        return Dataset.from_recordings("recordings", items)
    raise MethodError("compare needs a Dataset, or a non-empty list of only scans or only recordings")


def best_per_method(results: Sequence[MethodResult]) -> Iterator[MethodResult]:
    """The most accurate result of every method (first on ties), in method order."""
    for method in dict.fromkeys(r.method for r in results):
        yield max((r for r in results if r.method == method), key=lambda r: r.accuracy_mean)
