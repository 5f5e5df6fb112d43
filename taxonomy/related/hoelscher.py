"""``hoelscher``: Hoelscher, Peters and Hermans' BioTac features and classifiers (2015), every single
motion and the motions combined, repeated leave-one-trial-per-object-out splits."""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping, Sequence

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.decomposition import PCA
from sklearn.ensemble import RandomForestClassifier
from sklearn.model_selection import GridSearchCV, StratifiedShuffleSplit
from sklearn.naive_bayes import GaussianNB
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC
from sklearn.utils.multiclass import check_classification_targets
from sklearn.utils.validation import check_is_fitted, validate_data

from taxonomy.learning.results import Result
from taxonomy.related.datasets import (
    SEED,
    Dataset,
    Extracted,
    ExtractedSets,
    MethodError,
    MethodSkipped,
    every,
    motion_of,
    object_of,
    trial_of,
)
from taxonomy.related.scoring import (
    Scores,
    Split,
    leave_object_out_splits,
    one_per_object_splits,
    score,
    scored,
    usable_rows,
)

HOELSCHER_SETS = ("xu3", "chu", "mean23", "dallaire", "chitta", "temperature")
HOELSCHER_CLASSIFIERS = ("nb", "gaussian", "linear-svm", "rbf-svm", "rf")
MEAN_DIMENSIONS = 8
"""Hoelscher et al. 2015 reduce the 23 channel means to 8 principal components (~98 % of their variance)."""


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
    """The "Gaussian classifier" of Hoelscher et al. 2015: a full-covariance Gaussian per class, Bayes' rule
    with the class frequencies as priors.

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
    """The classifiers of Hoelscher et al. 2015 (section III-C)."""
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
    """The combination of the motions of Hoelscher et al. 2015 of one trial (section IV-B).

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


def _single_motion(dataset: Dataset, cache: ExtractedSets, set_name: str, classifier: str, seed: int,
                   repeats: int) -> Result:
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
        result = score(make, extracted.X[np.ix_(rows, columns)], y, splits)
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
    return scored(merged, int(np.mean(sizes)), float(np.median(seconds)), notes, method="hoelscher",
                  feature_set=set_name, classifier=classifier, motions=motions, level=level,
                  splitting=f"{repeats} x one per object", seed=seed,
                  paper=HOELSCHER_PAPER.get((set_name, classifier, motions), ""),
                  detail="per motion: " + ", ".join(f"{m} {100 * a:.1f} %" for m, a in per_motion.items()))


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


def _combined(dataset: Dataset, cache: ExtractedSets, mode: str, classifier: str, level: str,
              protocol: str, seed: int, repeats: int) -> Result | None:
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
    seconds = float(np.nanmedian(extracted.seconds[first])) * len(motions)
    return scored(score(make, X, y, splits), len(first), seconds, method="hoelscher", feature_set="mean23",
                  classifier=classifier, motions=label, level=level, splitting=shown, seed=seed, paper=paper)


def run_hoelscher(dataset: Dataset, cache: ExtractedSets, seed: int, repeats: int) -> list[Result]:
    """Hoelscher et al. 2015: every applicable feature set x classifier per motion, then motion combinations, the
    material-class level and held-out objects with the mean features."""
    sets = [s for s in HOELSCHER_SETS if every(dataset, s)]
    results, problems = [], []
    for set_name in sets:
        for classifier in HOELSCHER_CLASSIFIERS:
            try:
                results.append(_single_motion(dataset, cache, set_name, classifier, seed, repeats))
            except MethodError as exc:
                problems.append(str(exc))
    if not results:
        raise MethodError(problems[0] if problems else "no feature set of Hoelscher et al. 2015 applies")
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
            result = _combined(dataset, cache, mode, classifier, level, protocol, seed, repeats)
        except MethodError as exc:
            warnings.warn(f"method hoelscher: {mode} of the motions ({classifier}, {level}, {protocol}) "
                          f"skipped: {exc}", MethodSkipped, stacklevel=2)
            continue
        if result is not None:
            results.append(result)
    return results
