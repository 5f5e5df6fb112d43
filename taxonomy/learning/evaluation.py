"""Classifiers, cross-validation and metrics of the material classification (docs/evaluation.md; paper section V-B/C).

Every classifier is a scikit-learn ``Pipeline``: min-max scaling to [0, 1] -> ``FQSelector`` (the n best
features by FQ with |Spearman rho| < 0.5) -> classifier. Two protocols:

- ``nested`` (default): the whole pipeline is fitted on the training folds only, so no test row influences
  the scaling, the feature selection or the classifier.
- ``paper``: as published, scaling and selection are fitted once on all rows, then the classifier alone is
  cross-validated on the selected features (the test rows did take part in the selection).

Interpretation: the selector ranks features by FQ over the classes of the level being classified (the y
the pipeline is fitted with, as any scikit-learn selector); the paper computed FQ over its 184 material
classes, which is the same thing at the fine level.

Metrics (:mod:`taxonomy.learning.metrics`): accuracy per fold; macro F1 over the pooled out-of-fold predictions
(the headline) and per fold over the classes present in the fold's true labels; 95 % intervals by the
bootstrap over the folds' groups; calibrated probabilities (:mod:`taxonomy.learning.calibration`) and their
expected calibration error. ``r_C`` (eq. 32) is the share of misclassifications
whose predicted major class C differs from the true one; it is NaN (shown as "-") where undefined: without
misclassifications, and at the coarse level, where every misclassification changes C by definition.

A feature space of an imported set carries its own class names and levels (``FeatureSpace.label_level``;
``r_C`` is then undefined, NaN) and may carry its own train/test split, which is then used instead of
cross-validation: one fit on the training rows, scored on the test rows. A set size of None (``all``)
keeps every feature, without FQ selection.
"""

from __future__ import annotations

import contextlib
import sys
import time
import warnings
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from sklearn.base import BaseEstimator, clone
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.ensemble import RandomForestClassifier
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import RidgeClassifierCV
from sklearn.metrics import confusion_matrix
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold
from sklearn.naive_bayes import GaussianNB
from sklearn.neighbors import KNeighborsClassifier
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.svm import SVC
from tqdm import tqdm

from features import feature_sets
from features.feature_sets import FeatureSet, learning_subset, resolve_feature_set
from features.registry import REGISTRY
from features.selection import KeepAll, feature_steps
from features.space import FeatureSpace
from scanner.runtime import executors
from scanner.runtime.threads import one_blas_thread
from taxonomy.learning.calibration import TemperatureScaledClassifier, fit_grouped
from taxonomy.learning.fusion import FamilyEnsembleClassifier
from taxonomy.learning.metrics import present_class_f1
from taxonomy.learning.openset import MAX_ACCURACY_DROP, class_folds, fit_rule, learn_rejection
from taxonomy.learning.results import OWN_METHOD, EvaluationError, Result, history_words, warning_notes

PROTOCOLS = ("nested", "paper")

SEED = 0
"""Default seed of every random choice: fold assignment, forest bootstraps, SVM Platt scaling, MLP weights."""

MLP_MAX_ITER = 200
"""The paper's MLP's limit of L-BFGS iterations (:func:`classifier_estimators`)."""



def default_feature_sets() -> dict[str, FeatureSet]:
    """The paper's Figs. 16-18 columns: one modality (registered feature family) at a time, then all of them
    (X3 of "all" is the best-3).

    Returns
    -------
    dict of str to FeatureSet
        Display name -> feature set: each modality of :data:`features.registry.REGISTRY` by its name, then
        ``all`` (None).

    Examples
    --------
    >>> default_feature_sets()
    {'tactum': 'tactum', 'image': 'image', 'audio': 'audio', 'other': 'other', 'all': None}
    """
    return {**{name: name for name in REGISTRY.modalities}, "all": None}


def classifier_estimators(seed: int) -> dict[str, BaseEstimator]:
    """The paper's six classifiers (section V-B), each with its random state fixed to ``seed``, a ridge
    classifier, the usual head of random-kernel features (Dempster et al. 2020, section 3.3), and a random
    forest for classes of unequal size.

    Interpretations where the paper used MATLAB defaults or gave no value: SVM with an RBF kernel and
    Platt-scaled probabilities (``predict_top`` needs them); kNN with k = 3 and distance weights (five
    scans per material leave four in a training fold); the paper's net of 500 neurons trained by scaled
    conjugate gradient, a full-batch method, becomes one hidden layer of 100 ReLU units trained by
    L-BFGS, scikit-learn's full-batch quasi-Newton solver, for at most 200 iterations; "bagged trees" is a
    random forest of 100 trees (MATLAB's Classification Learner bags 30), each split drawing sqrt(f)
    candidate features. ``ridge``: ``RidgeClassifierCV`` choosing its penalty among 10 values from 1e-3 to
    1e3 by efficient leave-one-out on the training rows, as Dempster et al. ``brf``: the same forest, each
    tree grown on a bootstrap drawn with every class equally likely (row i drawn with probability
    proportional to 1 / n_c(i), the rows of its class; scikit-learn's ``class_weight="balanced"``, which
    draws the bootstrap by the weights since scikit-learn 1.9): the balanced random forest of Chen, Liaw and
    Breiman 2004 ("Using random forest to learn imbalanced data"), whose trees see the classes as large as
    each other, so the largest class of a lab's real runs or of a grouped fold does not take the doubtful rows.

    Parameters
    ----------
    seed : int
        The random state of every classifier that has one.

    Returns
    -------
    dict of str to estimator
        Name -> unfitted scikit-learn classifier, in the order of :data:`CLASSIFIERS`.

    Examples
    --------
    >>> estimators = classifier_estimators(seed=7)
    >>> list(estimators)
    ['svm', 'lda', 'knn', 'mlp', 'rf', 'nb', 'ridge', 'brf']
    >>> estimators["rf"].random_state, estimators["rf"].n_estimators, estimators["knn"].n_neighbors
    (7, 100, 3)
    >>> estimators["brf"].class_weight, estimators["brf"].n_estimators
    ('balanced', 100)
    """
    return {
        "svm": SVC(kernel="rbf", probability=True, random_state=seed),
        "lda": LinearDiscriminantAnalysis(),
        "knn": KNeighborsClassifier(n_neighbors=3, weights="distance"),
        "mlp": MLPClassifier(hidden_layer_sizes=(100,), solver="lbfgs", max_iter=MLP_MAX_ITER,
                             random_state=seed),
        "rf": RandomForestClassifier(n_estimators=100, random_state=seed, n_jobs=1),
        "nb": GaussianNB(),
        "ridge": RidgeClassifierCV(alphas=np.logspace(-3, 3, 10)),
        "brf": RandomForestClassifier(n_estimators=100, class_weight="balanced", random_state=seed, n_jobs=1),
    }


def _pipeline(classifier: BaseEstimator, n_features: int | None, kernels: str | None = None,
              columns: Sequence[str] = (), seed: int = SEED) -> Pipeline:
    return Pipeline([*feature_steps(columns, n_features, kernels, seed), ("classify", classifier)])


CLASSIFIERS: dict[str, Pipeline] = {
    name: _pipeline(estimator, 10) for name, estimator in classifier_estimators(SEED).items()
}
"""The classifier pipelines (scale -> select 10 -> classify) of :func:`classifier_estimators`, unfitted; use
:func:`make_pipeline`."""


def make_pipeline(classifier: str | BaseEstimator = "rf", n_features: int | None = 10,
                  seed: int = SEED, kernels: str | None = None, columns: Sequence[str] = ()) -> Pipeline:
    """A fresh, unfitted ``MinMaxScaler -> FQSelector(n_features) -> classifier`` pipeline (``KeepAll``
    instead of the selector for ``n_features`` None), after a ``kernels`` step (``minirocket``,
    ``multirocket``: :class:`features.random_kernels.RandomKernels` on the ``signal`` columns of
    ``columns``, the names of the input columns, seeded with ``seed``) where given. Where ``columns`` hold
    several families (a fused set: :func:`features.feature_sets.column_parts`), the selector is a
    :class:`~features.selection.PartwiseFQSelector`: ``n_features`` per family.

    ``classifier`` is a key of :data:`CLASSIFIERS` or any unfitted scikit-learn classifier (it is cloned;
    its random state is set to ``seed`` when it has one).

    Parameters
    ----------
    classifier : str or estimator
        A key of :data:`CLASSIFIERS` or an unfitted scikit-learn classifier.
    n_features : int or None
        Features the selector keeps; None keeps every one, unselected.
    seed : int
        Random state of the classifier and of the random kernels.
    kernels : str, optional
        ``minirocket`` or ``multirocket``: a random-kernel step first.
    columns : sequence of str
        The names of the input columns.

    Returns
    -------
    Pipeline
        Unfitted.

    Raises
    ------
    EvaluationError
        An unknown classifier name, or a classifier that is neither a name nor an estimator.

    Examples
    --------
    The selector keeps the one column that tells ``a`` from ``b``, and the classifier names a new row by it:

    >>> pipeline = make_pipeline("knn", n_features=1)
    >>> [name for name, _ in pipeline.steps]
    ['scale', 'select', 'classify']
    >>> pipeline.fit([[0.0, 5.0], [1.0, 3.0], [9.0, 4.0], [10.0, 5.0]], ["a", "a", "b", "b"]).predict([[8.0, 3.0]])
    array(['b'], dtype='<U1')
    >>> pipeline.named_steps["select"].selected_.tolist()
    [0]
    >>> type(make_pipeline("rf", n_features=None).named_steps["select"]).__name__
    'KeepAll'
    """
    if isinstance(classifier, str):
        if classifier not in CLASSIFIERS:
            raise EvaluationError(f"unknown classifier {classifier!r} (known: {', '.join(CLASSIFIERS)})")
        estimator = classifier_estimators(seed)[classifier]
    elif isinstance(classifier, BaseEstimator):
        estimator = clone(classifier)
        if "random_state" in estimator.get_params():
            estimator.set_params(random_state=seed)
    else:
        raise EvaluationError(f"classifier must be a name or a scikit-learn estimator, got {classifier!r}")
    return _pipeline(estimator, n_features, kernels, columns, seed)


def classifier_name(classifier: str | BaseEstimator) -> str:
    """A classifier's name as the tables print it: its key, or its class name.

    Parameters
    ----------
    classifier : str or estimator
        A key of :data:`CLASSIFIERS` or a scikit-learn classifier.

    Returns
    -------
    str

    Examples
    --------
    >>> from sklearn.naive_bayes import GaussianNB
    >>> classifier_name("rf"), classifier_name(GaussianNB())
    ('rf', 'GaussianNB')
    """
    return classifier if isinstance(classifier, str) else type(classifier).__name__


def iteration_limit_stops(estimator: BaseEstimator,
                          caught: Sequence[warnings.WarningMessage]) -> tuple[int, list[warnings.WarningMessage]]:
    """How many fits of the paper's MLP stopped at its L-BFGS iteration limit before converging, counted from
    the warnings ``caught`` while fitting ``estimator`` (unfitted), and the other warnings.

    With the paper's 200 iterations the MLP stops before converging in many fits: an expected outcome of
    the setting, which the report states once with this count
    (:func:`taxonomy.reports.report.convergence_note`) instead of a ConvergenceWarning per fit, whose advice
    to scale the data does not apply (the pipeline scales every feature to [0, 1]). Every other warning
    stays a warning, an MLP's that stopped for another reason (a failed line search) or with other
    settings included. The stop is recognised by scipy's L-BFGS-B message, which scikit-learn's warning quotes.

    Parameters
    ----------
    estimator : estimator
        The unfitted classifier whose fits raised the warnings.
    caught : sequence of warnings.WarningMessage
        The warnings recorded while fitting.

    Returns
    -------
    stops : int
        Fits of the paper's MLP that stopped at the iteration limit (0 for any other classifier).
    others : list of warnings.WarningMessage
        Every other warning, in order.

    Examples
    --------
    >>> import warnings
    >>> from sklearn.exceptions import ConvergenceWarning
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn("lbfgs failed to converge (status=1): STOP: TOTAL NO. OF ITERATIONS REACHED LIMIT.",
    ...                   ConvergenceWarning)
    ...     warnings.warn("lbfgs failed to converge (status=2): ABNORMAL: a failed line search", ConvergenceWarning)
    >>> stops, others = iteration_limit_stops(classifier_estimators(0)["mlp"], caught)
    >>> stops, [str(w.message) for w in others]
    (1, ['lbfgs failed to converge (status=2): ABNORMAL: a failed line search'])
    >>> iteration_limit_stops(classifier_estimators(0)["rf"], caught)[0]  # not the paper's MLP
    0
    """
    stops = [w for w in caught if paper_mlp(estimator) and issubclass(w.category, ConvergenceWarning)
             and "ITERATIONS REACHED LIMIT" in str(w.message).upper()]
    return len(stops), [w for w in caught if not any(w is stop for stop in stops)]


def paper_mlp(estimator: BaseEstimator) -> bool:
    """Whether ``estimator`` is an MLP trained as the paper's: by L-BFGS for at most 200 iterations.

    Parameters
    ----------
    estimator : estimator
        A scikit-learn classifier.

    Returns
    -------
    bool

    Examples
    --------
    >>> from sklearn.neural_network import MLPClassifier
    >>> paper_mlp(classifier_estimators(0)["mlp"]), paper_mlp(MLPClassifier(solver="lbfgs", max_iter=500))
    (True, False)
    """
    return (isinstance(estimator, MLPClassifier) and estimator.solver == "lbfgs"
            and estimator.max_iter == MLP_MAX_ITER)


def _fits(classifier: BaseEstimator) -> int:
    """The fits a fitted classifier took: one, or with calibration one on every row and one per inner split."""
    return classifier.n_fits_ if isinstance(classifier, TemperatureScaledClassifier) else 1


# -- splits ------------------------------------------------------------------------------------------


SINGLE_GROUP = ("train", "drop")
"""What grouped folds do with a class that has a single group (:func:`cv_splits`)."""


def cv_splits(y: Sequence[str], groups: Sequence[str], folds: int = 5, seed: int = SEED,
              grouping_labels: Sequence[str] | None = None,
              single_group: str = "train") -> tuple[list[tuple[np.ndarray, np.ndarray]], bool]:
    """Stratified folds, grouped by sample where a sample was scanned several times.

    Returns the (train, test) row indices of every fold and whether the folds are grouped (no group in the
    training and the test part of one fold).
    ``grouping_labels`` (default ``y``) are the classes that decide whether grouping is possible;
    :func:`evaluate` passes the full (fine) labels, so the coarse, medium and fine results of one feature
    space are split the same way and stay comparable (otherwise coarse folds would be grouped, testing on
    unseen materials, while fine folds, with one sample per material, could not be).

    - Every group a single row: ``StratifiedKFold(folds, shuffle=True, random_state=seed)``.
    - Groups with several rows: ``StratifiedGroupKFold`` with the same arguments on the rows of the classes
      with at least two groups; all scans of a sample stay in one fold. A class with fewer groups than
      folds then appears in the test rows of fewer folds, and always in training.
    - A class with a single group could never be tested without its group in training too. It never turns
      grouping off for the others: the folds are made without it, and its rows are added to every
      training part (``single_group = "train"``) or left out (``"drop"``), with a warning naming the
      classes, so the other classes' folds are the same with or without it.
    - Only when every class has a single group, or there are fewer groups than folds, no grouped split
      exists: the split falls back to the ungrouped ``StratifiedKFold`` of the paper (scans of one sample in
      both training and test) with a warning saying why.

    Parameters
    ----------
    y : sequence of str
        Each row's class at the level being classified.
    groups : sequence of str
        Each row's group (sample).
    folds : int
        Number of folds, at least 2.
    seed : int
        Seed of the shuffle.
    grouping_labels : sequence of str, optional
        The classes that decide whether grouping is possible (default ``y``).
    single_group : str
        ``"train"`` or ``"drop"``: what becomes of a class with a single group.

    Returns
    -------
    splits : list of (numpy.ndarray, numpy.ndarray)
        The (train, test) row indices of every fold.
    grouped : bool
        Whether no group lies in the training and the test part of one fold.

    Raises
    ------
    EvaluationError
        ``folds`` not an integer of at least 2, an unknown ``single_group``, or no class with ``folds`` rows.

    Examples
    --------
    Two samples of each class, scanned twice: each fold tests one sample of each class, and no sample is on
    both sides of a fold:

    >>> y = ["a", "a", "a", "a", "b", "b", "b", "b"]
    >>> groups = ["a1", "a1", "a2", "a2", "b1", "b1", "b2", "b2"]
    >>> splits, grouped = cv_splits(y, groups, folds=2)
    >>> grouped, [sorted({groups[i] for i in test}) for _, test in splits]
    (True, [['a2', 'b1'], ['a1', 'b2']])
    >>> all(not {groups[i] for i in train} & {groups[i] for i in test} for train, test in splits)
    True
    """
    y = np.asarray(y)
    groups = np.asarray(groups)
    if isinstance(folds, bool) or not isinstance(folds, int | np.integer) or folds < 2:
        raise EvaluationError(f"folds must be an integer >= 2, got {folds!r}")
    if single_group not in SINGLE_GROUP:
        raise EvaluationError(f"single_group must be one of {', '.join(SINGLE_GROUP)}, got {single_group!r}")
    classes, counts = np.unique(y, return_counts=True)
    if len(y) < folds or counts.max() < folds:
        raise EvaluationError(f"{folds} folds need a class with at least {folds} rows "
                              f"(largest class has {counts.max() if counts.size else 0})")
    if np.unique(groups).size == groups.size:  # grouped by construction: no group can be on both sides
        return _stratified(y, np.arange(len(y)), folds, seed), True
    deciding = y if grouping_labels is None else np.asarray(grouping_labels)
    deciding_classes = np.unique(deciding)
    single = [c for c in deciding_classes if np.unique(groups[deciding == c]).size < 2]
    testable = np.flatnonzero(~np.isin(deciding, single))
    if testable.size == 0 or np.unique(groups[testable]).size < folds:
        reason = (f"every one of the {deciding_classes.size} classes has a single sample (group)" if not testable.size
                  else f"{np.unique(groups[testable]).size} groups of classes with two or more are fewer than "
                       f"{folds} folds")
        warnings.warn(f"{reason}; folds are not grouped, so scans of one sample are in both training and test "
                      "folds", stacklevel=2)
        return _stratified(y, np.arange(len(y)), folds, seed), False
    if single:
        shown = ", ".join(map(str, single[:5])) + (f" and {len(single) - 5} more" if len(single) > 5 else "")
        fate = "kept in training only" if single_group == "train" else "left out"
        warnings.warn(f"{len(single)} of {deciding_classes.size} classes have a single sample (group) and are "
                      f"{fate}; the folds of the others stay grouped: {shown}", stacklevel=2)
    splitter = StratifiedGroupKFold(n_splits=folds, shuffle=True, random_state=seed)
    extra = np.flatnonzero(np.isin(deciding, single)) if single_group == "train" else np.array([], dtype=int)
    return [(np.sort(np.concatenate([testable[train], extra])), testable[test])
            for train, test in splitter.split(np.zeros(testable.size), y[testable], groups[testable])], True


def _stratified(y: np.ndarray, rows: np.ndarray, folds: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    splitter = StratifiedKFold(n_splits=folds, shuffle=True, random_state=seed)
    return [(rows[train], rows[test]) for train, test in splitter.split(np.zeros(rows.size), y[rows])]


def given_split(split: Sequence[str]) -> list[tuple[np.ndarray, np.ndarray]]:
    """The set's own split as the one (train, test) pair of row indices; an error without both parts.

    Parameters
    ----------
    split : sequence of str
        ``train`` or ``test`` per row (``FeatureSpace.split``).

    Returns
    -------
    list of (numpy.ndarray, numpy.ndarray)
        One (train, test) pair.

    Raises
    ------
    EvaluationError
        No training or no test row.

    Examples
    --------
    >>> [(train.tolist(), test.tolist()) for train, test in given_split(["train", "test", "train", "test"])]
    [([0, 2], [1, 3])]
    """
    split = np.asarray(split)
    train, test = np.flatnonzero(split == "train"), np.flatnonzero(split == "test")
    if train.size == 0 or test.size == 0:
        raise EvaluationError(f"the set's split has {train.size} training and {test.size} test rows; "
                              "both are needed (or evaluate without the split)")
    return [(train, test)]


# -- evaluation --------------------------------------------------------------------------------------


def evaluate(space: FeatureSpace, classifier: str | BaseEstimator = "rf", level: str = "fine",
             n_features: int | None = 10, folds: int = 5, seed: int = SEED, protocol: str = "nested",
             feature_set: FeatureSet = None, use_split: bool = True,
             single_group: str = "train", calibrate: bool = True, group_by: str = "sample") -> Result:
    """Cross-validate one classifier pipeline on ``space`` at classification ``level`` (paper section V-C).

    Parameters
    ----------
    space : features.space.FeatureSpace
        Rows = scans; ``space.groups`` (sample ids) keep the scans of a sample in one fold, see
        :func:`cv_splits` for what happens when a class has a single sample.
    classifier : str or estimator
        A key of :data:`CLASSIFIERS` (``"svm"``, ``"lda"``, ``"knn"``, ``"mlp"``, ``"rf"``, ``"nb"``, ``"ridge"``,
        ``"brf"``) or an unfitted scikit-learn classifier.
    level : str
        ``"coarse"`` (C), ``"medium"`` (C+S) or ``"fine"`` (the full label); for free labels one of
        ``space.level_names`` (``"fine"`` is the label's own level).
    n_features : int or None
        Features kept by the selector (the paper's X3 and X10); None keeps every feature, unselected.
    folds, seed : int
        Number of folds and the seed of the fold assignment and of the classifier.
    protocol : str
        ``"nested"`` (everything fitted inside the folds) or ``"paper"`` (scaling and selection on all rows).
    feature_set : None, str or list of str
        None / ``"all"``, a modality (``"tactum"``, ``"image"``, ``"audio"``, ``"other"``) or column names.
        Columns that hold NaN in any row are left out (listed in ``Result.dropped``).
    use_split : bool
        Use the space's own train/test split where it has one (``space.split``) instead of ``folds``.
    single_group : str
        ``"train"`` or ``"drop"``: a class with a single sample (group) is kept in training only, or left
        out, while the folds of the others stay grouped (:func:`cv_splits`).
    calibrate : bool
        Also fit each fold's temperature (:mod:`taxonomy.learning.calibration`, on grouped splits of the fold's
        training rows) and keep the calibrated out-of-fold probabilities (``Result.probability``); the
        predictions are the same either way.
    group_by : str
        What ``space.groups`` are, for the report: ``sample`` (the default), ``session``, ``operator``,
        ``recording`` or a set's group key.

    Returns
    -------
    Result
        Identical on every rerun with the same arguments. Warnings raised while fitting (the fallback to
        ungrouped folds, an MLP of other settings that did not converge) are collected in ``Result.notes``;
        the fits of the paper's MLP that stopped at its 200 iterations are counted in ``Result.unconverged``
        (:func:`iteration_limit_stops`).

    Examples
    --------
    Two classes, two samples of each scanned twice; the density tells the classes apart, the TacTUM value
    (0 or 1 in both) does not. Naive Bayes on the density (the one feature selected) names every scan right:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> X = np.array([[0.0, 0.0], [0.1, 1.0], [0.2, 0.0], [0.3, 1.0], [1.0, 0.0], [1.1, 1.0], [1.2, 0.0], [1.3, 1.0]])
    >>> labels, samples = ("C1S1M1P1X1",) * 4 + ("C2S1M1P1X1",) * 4, ("a1", "a1", "a2", "a2", "b1", "b1", "b2", "b2")
    >>> space = FeatureSpace(X, ("other.density", "tactum.matx"), tuple(f"scan{i}" for i in range(8)), labels, samples)
    >>> result = evaluate(space, "nb", "coarse", n_features=1, folds=2, calibrate=False)
    >>> result.accuracy.tolist(), result.confusion.tolist(), result.splitting
    ([1.0, 1.0], [[4, 0], [0, 4]], '2 grouped folds')
    """
    cell = _Cell(space.check_level(level), _set_name(feature_set), feature_set, n_features)
    return _run(space, [classifier], [cell], folds, seed, protocol, workers=1, progress=False,
                use_split=use_split, single_group=single_group, calibrate=calibrate,
                group_by=group_by)[0]


def evaluate_grid(space: FeatureSpace, classifiers: Iterable[str | BaseEstimator] = tuple(CLASSIFIERS),
                  levels: Iterable[str] | None = None, set_sizes: Iterable[int | None] = (3, 10),
                  feature_sets: Mapping[str, FeatureSet] | None = None, folds: int = 5, seed: int = SEED,
                  protocol: str = "nested", workers: int | None = None,
                  progress: bool = False, use_split: bool = True,
                  single_group: str = "train", calibrate: bool | Collection[tuple[str, str, int | None]] = True,
                  group_by: str = "sample", pairs: Collection[tuple[str, int | None]] | None = None) -> list[Result]:
    """Every classifier x feature set x level x set size (the paper's Figs. 16-18), folds in parallel.

    Each fold of each (level, feature set, size) is one job in one of ``workers`` processes, or one task on
    the current runtime's Dask cluster (:func:`scanner.runtime.current`; each cell's data sent once), the
    fine level first because it takes longest. Results equal those of :func:`evaluate` with the same arguments.

    Parameters
    ----------
    space : features.FeatureSpace
        Rows = scans (or recordings), with labels and groups.
    classifiers : iterable of str or estimator
        Keys of :data:`CLASSIFIERS` or unfitted scikit-learn classifiers.
    levels : iterable of str, optional
        Default: every level of the space (``space.level_names``).
    set_sizes : iterable of int or None
        Features kept by the selector; None is ``all`` (every feature, unselected).
    feature_sets : mapping of str to feature set, optional
        Display name -> feature set (see :func:`evaluate`); default :func:`default_feature_sets`
        restricted to the modalities present in ``space``.
    folds, seed : int
        Number of folds; seed of the fold assignment and of the classifiers.
    protocol : str
        ``"nested"`` or ``"paper"``.
    workers : int, optional
        Processes of this machine (default: all cores); a cluster has its own.
    progress : bool
        Show a progress bar.
    use_split : bool
        Use the space's own train/test split where it has one.
    single_group : str
        ``"train"`` or ``"drop"``: a class with a single sample (group) is kept in training only, or left
        out (:func:`cv_splits`).
    calibrate : bool or collection of (str, str, int or None)
        Calibrate every cell (see :func:`evaluate`), none, or only the cells named by (level, feature set
        name, set size); the predictions are the same either way.
    group_by : str
        What ``space.groups`` are, for the report (see :func:`evaluate`).
    pairs : collection of (str, int or None), optional
        Only these (level, set size) pairs of ``levels`` x ``set_sizes`` (default: every pair), e.g. the
        paper's figures: ``{("coarse", 10), ("fine", 10), ("fine", 3)}``.

    Returns
    -------
    list of Result
        Ordered by classifier, feature set, level and size; :func:`taxonomy.reports.report.format_table` prints them.

    Raises
    ------
    EvaluationError
        An unknown classifier or protocol, or too few rows per class for the folds.
    FeatureSpaceError
        A level the space does not have, only NaN, or values that cannot be scaled or are constant
        (:func:`learning_subset`).

    Examples
    --------
    Two classes, two samples of each scanned twice; the density tells the classes apart, the TacTUM value
    (0 or 1 in both) does not: each classifier is at chance (0.5) on the TacTUM set and right on every
    scan with the density:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> X = np.array([[0.0, 0.0], [0.1, 1.0], [0.2, 0.0], [0.3, 1.0], [1.0, 0.0], [1.1, 1.0], [1.2, 0.0], [1.3, 1.0]])
    >>> labels, samples = ("C1S1M1P1X1",) * 4 + ("C2S1M1P1X1",) * 4, ("a1", "a1", "a2", "a2", "b1", "b1", "b2", "b2")
    >>> space = FeatureSpace(X, ("other.density", "tactum.matx"), tuple(f"scan{i}" for i in range(8)), labels, samples)
    >>> results = evaluate_grid(space, ["nb", "lda"], ["coarse"], [1], folds=2, workers=1, calibrate=False)
    >>> [(r.classifier, r.feature_set, r.accuracy_mean) for r in results]  # doctest: +NORMALIZE_WHITESPACE
    [('nb', 'tactum', 0.5), ('nb', 'other', 1.0), ('nb', 'all', 1.0),
     ('lda', 'tactum', 0.5), ('lda', 'other', 1.0), ('lda', 'all', 1.0)]
    """
    classifiers = list(classifiers)
    levels = list(dict.fromkeys(space.check_level(level) for level in (levels or space.level_names)))
    set_sizes = list(set_sizes)
    sets = dict(feature_sets) if feature_sets is not None else present_feature_sets(space)
    cells = [_Cell(level, name, feature_set, size)
             for name, feature_set in sets.items() for level in levels for size in set_sizes
             if pairs is None or (level, size) in pairs]
    if pairs is not None and not cells:
        raise EvaluationError(f"no (level, set size) pair of {sorted(pairs or ())} among the levels "
                              f"{', '.join(levels)} and the set sizes {', '.join(map(str, set_sizes))}")
    chosen = None if isinstance(calibrate, bool) else set(calibrate)
    flags = [calibrate if chosen is None else (c.level, c.set_name, c.n_features) in chosen for c in cells]
    reports = _run(space, classifiers, cells, folds, seed, protocol, workers, progress, use_split,
                   single_group, flags, group_by)
    per_cell = len(classifiers)
    return [reports[c * per_cell + k] for k in range(per_cell) for c in range(len(cells))]


def present_feature_sets(space: FeatureSpace) -> dict[str, FeatureSet]:
    """The modalities present, then all of them; a single modality only once (it is all of them).

    Parameters
    ----------
    space : FeatureSpace
        The feature space.

    Returns
    -------
    dict of str to FeatureSet
        Display name -> feature set, in the order of :func:`default_feature_sets`.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> space = FeatureSpace(np.array([[1.0, 2.0]]), ("other.density", "tactum.matx"), ("a",), ("C1S1M1P1X1",), ("a",))
    >>> present_feature_sets(space)
    {'tactum': 'tactum', 'other': 'other', 'all': None}
    >>> present_feature_sets(space.modality("other"))
    {'other': 'other'}
    """
    prefixes = {c.split(".", 1)[0] for c in space.columns}
    present = {name: fs for name, fs in default_feature_sets().items() if fs in prefixes}
    return present if len(present) == 1 else {**present, "all": None}


def with_values(space: FeatureSpace, sets: dict[str, FeatureSet]) -> tuple[dict[str, FeatureSet], list[str]]:
    """The feature sets of ``sets`` that hold a value somewhere, and one line for each left out because
    every one of its columns is missing in every row (photos smaller than the border crop leave the image
    family without a value): such a set cannot be evaluated, the others can.

    Parameters
    ----------
    space : FeatureSpace
        The feature space.
    sets : dict of str to FeatureSet
        Display name -> feature set.

    Returns
    -------
    kept : dict of str to FeatureSet
        The sets with a value somewhere.
    left_out : list of str
        One line per set left out.

    Raises
    ------
    EvaluationError
        No set has a value.

    Examples
    --------
    Photos too small for the image features:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> X = np.array([[1.0, np.nan, 3.0], [2.0, np.nan, 1.0]])
    >>> space = FeatureSpace(X, ("tactum.matx", "image.disp.brightness", "other.density"), ("a", "b"),
    ...                      ("C1S1M1P1X1", "C2S1M1P1X1"), ("a", "b"))
    >>> kept, left_out = with_values(space, present_feature_sets(space))
    >>> list(kept), left_out
    (['tactum', 'other', 'all'], ['feature set image left out: none of its 1 columns has a value in any of the 2 rows'])
    """
    kept, left_out = {}, []
    for name, feature_set in sets.items():
        subset, _ = resolve_feature_set(space, feature_set)
        if subset.X.size and np.isnan(subset.X).all():
            left_out.append(f"feature set {name} left out: none of its {len(subset.columns)} columns has a value "
                            f"in any of the {len(subset.X)} rows")
        else:
            kept[name] = feature_set
    if not kept:
        raise EvaluationError(f"every one of the {len(space.X)} rows holds only NaN in every feature set "
                              f"({', '.join(sets)}): no feature could be computed")
    return kept, left_out


def _set_name(feature_set: FeatureSet) -> str:
    if feature_set is None or isinstance(feature_set, str):
        return feature_set or "all"
    return f"{len(list(feature_set))} columns"


@dataclass(frozen=True)
class _Cell:
    """One entry of the results table, for every classifier: level, feature set and set size."""

    level: str
    set_name: str
    feature_set: FeatureSet
    n_features: int | None


@dataclass(frozen=True)
class _Prepared:
    """A cell's data, folds and unfitted pipelines, as every fold job of the cell needs them."""

    cell: _Cell
    X: np.ndarray
    y: np.ndarray
    groups: np.ndarray
    materials: np.ndarray
    columns: tuple[str, ...]
    dropped: tuple[str, ...]
    splits: list[tuple[np.ndarray, np.ndarray]]
    grouped: bool
    given_split: bool
    taxonomy: bool
    pipelines: list[Pipeline]
    shared: Pipeline | None
    notes: tuple[str, ...]
    calibrate: bool = True
    group_by: str = "sample"
    seed: int = SEED
    rows: np.ndarray | None = None


def _run(space: FeatureSpace, classifiers: Sequence[str | BaseEstimator], cells: Sequence[_Cell], folds: int,
         seed: int, protocol: str, workers: int | None, progress: bool, use_split: bool = True,
         single_group: str = "train", calibrate: bool | Sequence[bool] = True,
         group_by: str = "sample") -> list[Result]:
    """Results of every classifier in every cell, in that order (cells outer, classifiers inner);
    ``calibrate`` for every cell or one flag per cell."""
    if protocol not in PROTOCOLS:
        raise EvaluationError(f"unknown protocol {protocol!r} (expected one of {', '.join(PROTOCOLS)})")
    flags = [calibrate] * len(cells) if isinstance(calibrate, bool) else list(calibrate)
    prepared = [_prepare(space, cell, classifiers, folds, seed, protocol, use_split, single_group, flag,
                         group_by) for cell, flag in zip(cells, flags, strict=True)]
    jobs = sorted(((c, f) for c, p in enumerate(prepared) for f in range(len(p.splits))),
                  key=lambda job: -space.level_names.index(cells[job[0]].level))
    # disable=None hides the bar when stderr is not a terminal (logs, CI).
    bar = tqdm(total=len(jobs), desc="evaluating", unit="fold", file=sys.stderr, disable=None if progress else True,
               leave=False)
    runtime = executors.current()
    shared = runtime.share(prepared)  # each cell's data travels to a cluster once, not with each fold
    results = runtime.map_unordered(_fold, [(shared[c], f, protocol) for c, f in jobs], workers=workers,
                                    name="texplorer-fold")
    outcome: dict[tuple[int, int], _FoldOutcome] = {}
    with contextlib.closing(results):  # leaving early (Ctrl-C) cancels the cluster's remaining folds now
        for j, result in results:
            outcome[jobs[j]] = result
            bar.update(1)
    bar.close()
    reports = []
    for c, p in enumerate(prepared):
        per_fold = [outcome[(c, f)] for f in range(len(p.splits))]
        reports.extend(_reports(p, classifiers, per_fold, seed, protocol))
    return reports


def _prepare(space: FeatureSpace, cell: _Cell, classifiers: Sequence[str | BaseEstimator], folds: int,
             seed: int, protocol: str, use_split: bool = True, single_group: str = "train",
             calibrate: bool = True, group_by: str = "sample") -> _Prepared:
    own = use_split and bool(space.split)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        subset, dropped = learning_subset(space, cell.level, cell.feature_set)
        y = subset.y(cell.level)
        if own:
            splits, grouped = given_split(subset.split), False
        else:
            splits, grouped = cv_splits(y, subset.groups, folds, seed, grouping_labels=subset.label_text,
                                        single_group=single_group)
            grouped = grouped and group_by != "none"  # every row its own group: not grouped, as asked
        kernels = _kernels(cell.feature_set, protocol)
        pipelines = [_without_probabilities(make_pipeline(c, cell.n_features, seed, kernels, subset.columns))
                     for c in classifiers]
        shared = None
        if protocol == "paper":
            with one_blas_thread():
                shared = clone(pipelines[0][:-1]).fit(subset.X, y)
    return _Prepared(cell, subset.X, y, np.asarray(subset.groups), np.asarray(subset.label_text), subset.columns,
                     dropped, splits, grouped, own,
                     space.label_level is None, pipelines, shared, warning_notes(caught), calibrate, group_by,
                     seed, _space_rows(space.scan_ids, subset.scan_ids))


def _space_rows(ids: Sequence[str], kept: Sequence[str]) -> np.ndarray | None:
    """The row of ``ids`` each of ``kept`` is (a subset keeps the rows' order); None where ids repeat."""
    index = {scan_id: k for k, scan_id in enumerate(ids)}
    return np.array([index[scan_id] for scan_id in kept], dtype=np.int64) if len(index) == len(ids) else None


def _kernels(feature_set: FeatureSet, protocol: str) -> str | None:
    """The random-kernel transform of a feature set; refused under the ``paper`` protocol, which would fit it
    on every row before splitting."""
    if not (isinstance(feature_set, str) and feature_sets.is_named_set(feature_set)):
        return None
    kernels = feature_sets.kernels_of(feature_set)
    if kernels is not None and protocol != "nested":
        raise EvaluationError(f"feature set {feature_set!r}: {kernels} is fitted inside the folds; "
                              "it runs under the nested protocol only")
    return kernels


def _without_probabilities(pipeline: Pipeline) -> Pipeline:
    """Turn off an SVM's Platt scaling: ``predict`` does not use it, so predictions are the same.

    libsvm fits the decision function on all training rows either way; the probability model is an
    extra internal 5-fold fit that would take ~8x the time of the SVM itself and is not needed here.
    """
    classifier = pipeline[-1]
    params = classifier.get_params(deep=False)
    if "probability" in params:
        # Rebuilt without the argument: scikit-learn 1.9 deprecates it, and its default is "off".
        del params["probability"]
        pipeline.steps[-1] = (pipeline.steps[-1][0], type(classifier)(**params))
    return pipeline


@dataclass(frozen=True)
class _FoldOutcome:
    """One fold's predictions per classifier, the selected column names, the warnings, the seconds per
    classifier (the shared part's time included), and the test rows' calibrated probabilities per classifier
    (columns in the order of the cell's classes; None without calibration), and per classifier the fits of
    the paper's MLP that stopped at its iteration limit and all its fits (``Result.unconverged``)."""

    predictions: list[np.ndarray]
    selected: tuple[str, ...]
    notes: tuple[str, ...]
    seconds: list[float]
    probabilities: list[np.ndarray | None]
    unconverged: list[tuple[int, int]]


def _fold(prepared: _Prepared, fold: int, protocol: str) -> _FoldOutcome:
    """One fold: fit the shared scale -> select part (nested protocol) and every classifier on its output.

    A pipeline's fit is its transformers' ``fit_transform`` followed by the classifier's ``fit``, so fitting
    the shared part once gives exactly the predictions of fitting each full pipeline. Returns the
    predictions of the test rows per classifier, the selected column names, the warnings raised and the
    time each classifier took with the shared part. With calibration each classifier is wrapped in a
    :class:`~taxonomy.learning.calibration.TemperatureScaledClassifier` fitted on the fold's training rows and
    their groups; its predictions are the classifier's own.
    """
    train, test = prepared.splits[fold]
    X, y = prepared.X, prepared.y
    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught, one_blas_thread():
        # Small dense matrices: BLAS threads cost more than they gain, and folds run side by side.
        warnings.simplefilter("always")
        shared = prepared.shared
        if protocol == "nested":
            shared = clone(prepared.pipelines[0][:-1]).fit(X[train], y[train])
        X_train, X_test = shared.transform(X[train]), shared.transform(X[test])
    shared_seconds = time.perf_counter() - started
    messages = warning_notes(caught)
    classes = np.unique(y)
    predictions, seconds, probabilities, unconverged = [], [], [], []
    for pipeline in prepared.pipelines:
        started = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught, one_blas_thread():
            warnings.simplefilter("always")
            name = type(pipeline[-1]).__name__
            classifier = by_family(clone(pipeline[-1]), shared, prepared.columns, prepared.seed)
            if prepared.calibrate:
                classifier = TemperatureScaledClassifier(classifier, seed=prepared.seed)
                classifier.fit(X_train, y[train], groups=prepared.groups[train], materials=prepared.materials[train])
                probability = np.zeros((len(test), classes.size))
                probability[:, np.searchsorted(classes, classifier.classes_)] = classifier.predict_proba(X_test)
                probabilities.append(probability)
            else:
                fit_grouped(classifier, X_train, y[train], prepared.groups[train])
                probabilities.append(None)
            predictions.append(classifier.predict(X_test))
        seconds.append(shared_seconds + time.perf_counter() - started)
        stopped, others = iteration_limit_stops(pipeline[-1], caught)
        unconverged.append((stopped, _fits(classifier)) if paper_mlp(pipeline[-1]) else (0, 0))
        messages += warning_notes(others, f"{name}: ")
    return _FoldOutcome(predictions, _selected_names(shared, prepared.columns), tuple(dict.fromkeys(messages)),
                        seconds, probabilities, unconverged)


def _selected_names(shared: Pipeline, columns: tuple[str, ...]) -> tuple[str, ...]:
    """The names of the columns the selector kept (a random-kernel step names its outputs)."""
    if "kernels" in shared.named_steps:
        columns = tuple(shared.named_steps["kernels"].get_feature_names_out())
    return tuple(columns[i] for i in shared.named_steps["select"].selected_)


def by_family(classifier: BaseEstimator, shared: Pipeline, columns: tuple[str, ...], seed: int) -> BaseEstimator:
    """``classifier`` for the columns the fitted ``shared`` steps pass on: a
    :class:`~taxonomy.learning.fusion.FamilyEnsembleClassifier` fitting it on each family's columns where they
    hold every column of several families (a fused set, :func:`features.feature_sets.column_parts`, with
    ``KeepAll``: the widest family would drown the others), else ``classifier`` as it is (one family, or
    each family's ``n`` best kept by a :class:`~features.selection.PartwiseFQSelector`, balanced already).

    Parameters
    ----------
    classifier : BaseEstimator
        An unfitted classifier.
    shared : Pipeline
        The fitted steps before it (random kernels, scaling, selection).
    columns : tuple of str
        The names of the input columns; none: one family.
    seed : int
        Seed of the ensemble's inner folds.

    Returns
    -------
    BaseEstimator
        ``classifier`` or the ensemble around it, unfitted.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.naive_bayes import GaussianNB
    >>> X, y = np.array([[0.0, 1.0, 2.0], [1.0, 0.0, 5.0]]), np.array(["cork", "oak"])
    >>> shared = make_pipeline("nb", None)[:-1].fit(X, y)
    >>> type(by_family(GaussianNB(), shared, ("tactum.matx", "audio.tool.f0", "other.density"), 0)).__name__
    'GaussianNB'
    >>> fused = by_family(GaussianNB(), shared, ("tactum.matx", "catch22.v_ts.CO_f1ecac", "other.density"), 0)
    >>> type(fused).__name__, fused.parts
    ('FamilyEnsembleClassifier', (0, 1, 0))
    """
    if not columns or not isinstance(shared.named_steps["select"], KeepAll):
        return classifier
    parts = feature_sets.column_parts(_selected_names(shared, columns))
    return classifier if parts is None else FamilyEnsembleClassifier(classifier, parts, seed=seed)


def _reports(prepared: _Prepared, classifiers: Sequence[str | BaseEstimator],
             per_fold: list[_FoldOutcome], seed: int, protocol: str) -> list[Result]:
    y, splits, cell = prepared.y, prepared.splits, prepared.cell
    fold_of_row = np.full(len(y), -1, dtype=np.int64)  # -1: a training row of the set's own split
    for index, (_, test) in enumerate(splits):
        fold_of_row[test] = index
    tested = fold_of_row >= 0
    selected = tuple(outcome.selected for outcome in per_fold)
    notes = tuple(dict.fromkeys(prepared.notes + sum((outcome.notes for outcome in per_fold), ())))
    classes = np.unique(y)
    reports = []
    for k, classifier in enumerate(classifiers):
        y_pred = np.full_like(y, "")
        probability = np.full((len(y), classes.size), np.nan) if prepared.calibrate else None
        for (_, test), outcome in zip(splits, per_fold, strict=True):
            y_pred[test] = outcome.predictions[k]
            if probability is not None:
                probability[test] = outcome.probabilities[k]
        accuracy = np.array([np.mean(y_pred[test] == y[test]) for _, test in splits])
        f1 = np.array([present_class_f1(y[test], y_pred[test]) for _, test in splits])
        reports.append(Result(
            method=OWN_METHOD, feature_set=cell.set_name, classifier=classifier_name(classifier),
            level=cell.level, protocol=protocol, splitting=_splitting(prepared), classes=tuple(classes.tolist()),
            accuracy=accuracy, f1=f1, confusion=confusion_matrix(y[tested], y_pred[tested], labels=classes),
            n_samples=len(y), seed=seed, notes=notes, taxonomy=prepared.taxonomy, n_features=cell.n_features,
            grouped=prepared.grouped, given_split=prepared.given_split, columns=prepared.columns,
            dropped=prepared.dropped, selected=selected, y_true=y, y_pred=y_pred, fold=fold_of_row,
            seconds=float(sum(outcome.seconds[k] for outcome in per_fold)),
            unconverged=(sum(o.unconverged[k][0] for o in per_fold), sum(o.unconverged[k][1] for o in per_fold)),
            groups=prepared.groups, probability=probability, group_by=prepared.group_by, rows=prepared.rows,
        ))
    return reports


def _splitting(prepared: _Prepared) -> str:
    """How the rows were split: ``5 grouped folds``, ``the set's train/test split``, ..."""
    if prepared.given_split:
        return "the set's train/test split"
    return f"{len(prepared.splits)} {'grouped' if prepared.grouped else 'ungrouped'} folds"


# -- fitting a whole model, voting, the open set ---------------------------------------------------------


def fit_pipeline(X: np.ndarray, y: np.ndarray, groups: np.ndarray, classifier: str | BaseEstimator = "rf",
                 n_features: int | None = 10, seed: int = SEED, calibrate: bool = True,
                 materials: np.ndarray | None = None, kernels: str | None = None,
                 columns: Sequence[str] = ()) -> Pipeline:
    """A fitted ``scale -> select -> classify`` pipeline on every row; with ``calibrate`` its classifier is a
    :class:`~taxonomy.learning.calibration.TemperatureScaledClassifier` whose inner splits keep ``groups`` together
    and leave out rows whose ``materials`` (full labels) their inner training part lacks (scikit-learn's
    ``Pipeline.fit`` cannot hand these to the last step, so the steps are fitted here one after the other,
    as ``Pipeline.fit`` would). ``kernels`` and ``columns`` are :func:`make_pipeline`'s.

    Parameters
    ----------
    X : numpy.ndarray
        (rows, columns) training values, without NaN.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's group (sample), for the calibration's inner splits.
    classifier : str or estimator
        A key of :data:`CLASSIFIERS` or an unfitted scikit-learn classifier.
    n_features : int or None
        Features the selector keeps; None keeps every one, unselected.
    seed : int
        Random state of the classifier, the kernels and the calibration's splits.
    calibrate : bool
        Wrap the classifier in a temperature-scaled one.
    materials : numpy.ndarray, optional
        Each row's full label, for the calibration's inner splits.
    kernels : str, optional
        ``minirocket`` or ``multirocket``: a random-kernel step first.
    columns : sequence of str
        The names of the input columns.

    Returns
    -------
    Pipeline
        Fitted on every row.

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[0.0], [0.1], [0.2], [0.3], [1.0], [1.1], [1.2], [1.3]])
    >>> y, groups = np.repeat(["cork", "oak"], 4), np.repeat(["c1", "c2", "o1", "o2"], 2)
    >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None)
    >>> type(pipeline[-1]).__name__, pipeline.predict(np.array([[0.05], [1.25]])).tolist()
    ('TemperatureScaledClassifier', ['cork', 'oak'])
    >>> type(fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)[-1]).__name__
    'GaussianNB'
    """
    pipeline = make_pipeline(classifier, n_features, seed, kernels, columns)
    with one_blas_thread():
        Z = pipeline[:-1].fit_transform(X, y)
        estimator = by_family(pipeline.steps[-1][1], pipeline[:-1], tuple(columns), seed)
        if calibrate:
            estimator = TemperatureScaledClassifier(estimator, seed=seed).fit(Z, y, groups=np.asarray(groups),
                                                                              materials=materials)
        else:
            fit_grouped(estimator, Z, y, np.asarray(groups))
    pipeline.steps[-1] = ("classify", estimator)
    return pipeline


def recording_of(scan_id: str) -> str:
    """The recording a row belongs to: ``<recording>#w<k>`` is window k of a recording (``--combine rows``).

    Parameters
    ----------
    scan_id : str
        A row's scan id.

    Returns
    -------
    str
        The id without its window suffix.

    Examples
    --------
    >>> recording_of("oak-01-003#w2"), recording_of("oak-01-003")
    ('oak-01-003', 'oak-01-003')
    """
    return scan_id.rsplit("#w", 1)[0]


def vote(result: Result, recordings: Sequence[str]) -> Result:
    """The result with every recording scored once, by its windows' vote (``--vote``).

    ``recordings`` names the recording of every row of the feature space evaluated (or of the result, where
    it left no row out: :attr:`Result.rows`). A recording's prediction is the class of
    the highest mean calibrated probability over its windows (soft voting) where the result has
    probabilities, else the most frequent prediction (ties: the first in class order). Its fold is its
    windows' fold (they share one: folds keep a recording's windows together); a recording whose windows
    lie in different folds is an error.

    Parameters
    ----------
    result : Result
        A result with its out-of-fold predictions (``y_true``, ``y_pred``, ``fold``).
    recordings : sequence of str
        The recording of every row of the space (:func:`recording_of`).

    Returns
    -------
    Result
        One row per recording, in order of first appearance; accuracy, F1 and confusion recomputed.

    Raises
    ------
    EvaluationError
        A result without its out-of-fold predictions, or a recording whose windows lie in different folds
        or classes.

    Examples
    --------
    Three recordings of cork and three of oak, three windows each, folds grouped by recording; one window of
    a cork recording looks like oak and is named oak, but its recording's two other windows outvote it:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> ids = tuple(f"{material}{k}#w{w}" for material in ("cork", "oak") for k in range(3) for w in range(3))
    >>> X = np.repeat([0.0, 1.0], 9)[:, None] + np.tile([0.0, 0.1, -0.1], 6)[:, None]
    >>> X[2, 0] = 1.0
    >>> space = FeatureSpace(X, ("other.density",), ids, ("C1S1M1P1X1",) * 9 + ("C2S1M1P1X1",) * 9,
    ...                      tuple(recording_of(i) for i in ids))
    >>> result = evaluate(space, "nb", "coarse", n_features=None, folds=3, calibrate=False, group_by="recording")
    >>> voted = vote(result, [recording_of(i) for i in space.scan_ids])
    >>> int(np.sum(result.y_pred == result.y_true)), len(result.y_true), voted.accuracy_pooled, len(voted.y_true)
    (17, 18, 1.0, 6)
    """
    if result.y_true is None or result.y_pred is None or result.fold is None:
        raise EvaluationError("only a result with its out-of-fold predictions can be voted")
    windows = _windows_by_recording(result, _of_rows(result, recordings))
    names = list(windows)
    classes = np.asarray(result.classes)
    y_true, y_pred, fold, groups, probability = [], [], [], [], []
    for name, rows in windows.items():
        if result.probability is not None and np.isfinite(result.probability[rows]).all():
            mean = result.probability[rows].mean(axis=0)
            probability.append(mean)
            y_pred.append(classes[int(np.argmax(mean))])
        else:
            counts = np.array([np.sum(result.y_pred[rows] == c) for c in classes])
            y_pred.append(classes[int(np.argmax(counts))])
        y_true.append(result.y_true[rows[0]])
        fold.append(result.fold[rows[0]])
        groups.append(result.groups[rows[0]] if result.groups is not None else name)
    y_true_a, y_pred_a, fold_a = np.array(y_true), np.array(y_pred), np.array(fold)
    return replace(
        result, y_true=y_true_a, y_pred=y_pred_a, fold=fold_a, groups=np.array(groups),
        probability=np.array(probability) if len(probability) == len(names) else None,
        **_fold_scores(y_true_a, y_pred_a, fold_a, classes),
        voted=True, splitting=f"{result.splitting}, recordings voted by their windows")


def _fold_scores(y_true: np.ndarray, y_pred: np.ndarray, fold: np.ndarray, classes: np.ndarray) -> dict:
    """A result's scores of new predictions: accuracy and present-class F1 per fold, and the confusion of every
    tested row (fold >= 0; -1 is a training row of the set's own split)."""
    folds, tested = np.unique(fold[fold >= 0]), fold >= 0
    return {"accuracy": np.array([np.mean(y_pred[fold == f] == y_true[fold == f]) for f in folds]),
            "f1": np.array([present_class_f1(y_true[fold == f], y_pred[fold == f]) for f in folds]),
            "confusion": confusion_matrix(y_true[tested], y_pred[tested], labels=classes)}


def window_index(scan_id: str) -> int:
    """The window a row holds: ``<recording>#w<k>`` is window k of a recording (``--combine rows``); a row
    without the suffix is a whole recording, window 0.

    Parameters
    ----------
    scan_id : str
        A row's scan id.

    Returns
    -------
    int
        k.

    Examples
    --------
    >>> window_index("SNOW_12#w017"), window_index("oak-01-003")
    (17, 0)
    """
    _, _, k = scan_id.rpartition("#w")
    return int(k) if "#w" in scan_id and k.isdigit() else 0


def running_vote(result: Result, scan_ids: Sequence[str], before: int) -> Result:
    """The result with every window scored by its own answer and those of the ``before`` windows that precede
    it in its recording (``--history``): what a robot driving on, or an operator sliding on, knows at the end
    of each window. Terrain classifiers combine such a history of window answers (Komma, Weiss and Zell
    2009, "Adaptive Bayesian filtering for vibration-based terrain classification", a Bayes filter over the
    answers); here the answer of window t is the class of the highest mean calibrated probability over
    windows t - ``before`` .. t of its recording (fewer at its start), or where the result has no
    probabilities the most frequent prediction among them, a tie going to the latest. Nothing after window
    t is used. Every row stays a row, scored once; each window's answers come from the fold that tested
    its recording, so the folds must keep a recording's windows together.

    Parameters
    ----------
    result : Result
        A result with its out-of-fold predictions (``y_true``, ``y_pred``, ``fold``), one row per window.
    scan_ids : sequence of str
        The scan id of every row (``<recording>#w<k>``, :func:`recording_of`, :func:`window_index`).
    before : int
        Windows before each one that join its vote (0: the result, unchanged).

    Returns
    -------
    Result
        The same rows with their running-vote predictions; accuracy, F1 and confusion recomputed, the
        splitting naming the history.

    Raises
    ------
    EvaluationError
        A negative ``before``, a result without its out-of-fold predictions, or a recording whose windows
        lie in different folds or classes.

    Examples
    --------
    One recording of cork, five windows; the third looks like oak. With the window before it, its vote is
    cork; the first window has no history and keeps its own answer:

    >>> import numpy as np
    >>> from taxonomy.learning.results import Result
    >>> classes = ("C1S1M1P1X1", "C2S1M1P1X1")
    >>> p = np.array([[0.9, 0.1], [0.8, 0.2], [0.4, 0.6], [0.7, 0.3], [0.9, 0.1]])
    >>> result = Result("texplorer", "all", "rf", "fine", "nested", "1 fold", classes, accuracy=np.array([0.8]),
    ...                 f1=np.array([0.44]), confusion=np.array([[4, 1], [0, 0]]), n_samples=5, seed=0,
    ...                 y_true=np.array([classes[0]] * 5), y_pred=np.array(classes)[p.argmax(axis=1)],
    ...                 fold=np.zeros(5, int), probability=p)
    >>> ids = [f"cork-1#w{k:03d}" for k in range(5)]
    >>> str(result.y_pred[2]), running_vote(result, ids, 1).y_pred.tolist() == [classes[0]] * 5
    ('C2S1M1P1X1', True)
    >>> running_vote(result, ids, 1).accuracy_pooled
    1.0
    """
    if isinstance(before, bool) or not isinstance(before, int | np.integer) or before < 0:
        raise EvaluationError(f"the history must be a whole number of windows >= 0, got {before!r}")
    if result.y_true is None or result.y_pred is None or result.fold is None:
        raise EvaluationError("only a result with its out-of-fold predictions can be voted")
    if before == 0:
        return result
    ids = _of_rows(result, scan_ids)
    windows = np.array([window_index(s) for s in ids])
    classes = np.asarray(result.classes)
    y_pred = result.y_pred.copy()
    probability = None if result.probability is None else result.probability.copy()
    for rows in _windows_by_recording(result, [recording_of(s) for s in ids]).values():
        if result.fold[rows[0]] < 0:
            continue  # a training row of the set's own split, or of a class kept in training only: not tested
        rows = rows[np.argsort(windows[rows], kind="stable")]
        for k, row in enumerate(rows):
            history = rows[max(0, k - before):k + 1]
            y_pred[row], mean = _history_answer(result, history, classes)
            if probability is not None:
                probability[row] = mean
    return replace(result, y_pred=y_pred, probability=probability, history=before,
                   **_fold_scores(result.y_true, y_pred, result.fold, classes),
                   splitting=f"{result.splitting}, {history_words(before)}")


def _history_answer(result: Result, history: np.ndarray, classes: np.ndarray) -> tuple[str, np.ndarray]:
    """The answer of the last of ``history``'s rows voted with the others, and its probabilities: the class
    of the highest mean calibrated probability where every row has them, else the most frequent answer, a
    tie going to the latest (probabilities NaN)."""
    if result.probability is not None and np.isfinite(result.probability[history]).all():
        mean = result.probability[history].mean(axis=0)
        return classes[int(np.argmax(mean))], mean
    latest = history[::-1]
    counts = [int(np.sum(result.y_pred[history] == result.y_pred[r])) for r in latest]
    return result.y_pred[latest[int(np.argmax(counts))]], np.full(classes.size, np.nan)


def _windows_by_recording(result: Result, recordings: Sequence[str]) -> dict[str, np.ndarray]:
    """The result's rows of each recording, in order of first appearance; an :class:`EvaluationError` where a
    recording's windows lie in different folds or classes (nothing to vote over together)."""
    recordings = np.asarray(recordings)
    windows = {}
    for name in dict.fromkeys(recordings.tolist()):
        rows = np.flatnonzero(recordings == name)
        if np.unique(result.fold[rows]).size != 1 or np.unique(result.y_true[rows]).size != 1:
            raise EvaluationError(f"recording {name!r}: its windows lie in different folds or classes; group "
                                  "the folds by recording to vote over its windows")
        windows[name] = rows
    return windows


def _of_rows(result: Result, ids: Sequence[str]) -> np.ndarray:
    """``ids`` of the space's rows as the result's rows: those it evaluated (:attr:`Result.rows`), where it
    left rows out."""
    ids = np.asarray(ids)
    if result.rows is not None and len(ids) != len(result.y_true):
        ids = ids[result.rows]
    if len(ids) != len(result.y_true):
        raise EvaluationError(f"{len(ids)} row names for a result of {len(result.y_true)} rows")
    return ids


def evaluate_open_set(space: FeatureSpace, classifier: str = "rf", level: str = "fine", n_features: int | None = 10,
                      folds: int = 5, seed: int = SEED, feature_set: FeatureSet = None,
                      group_by: str = "sample", max_accuracy_drop: float = MAX_ACCURACY_DROP,
                      calibrate: bool = True) -> Result:
    """Open-set cross-validation: whole classes held out per fold (Scheirer et al. 2013's protocol).

    The classes are dealt into ``folds`` parts (:func:`taxonomy.learning.openset.class_folds`) and the rows into the
    usual grouped folds (:func:`cv_splits`). Fold k trains a whole model -- pipeline, calibration and the
    rejection rule learned by leave-classes-out inside its training rows (:mod:`taxonomy.learning.openset`) -- on
    the rows of the other class parts outside sample fold k, and tests the rows of sample fold k whose
    class it knows ("known") and every row of class part k ("unknown"). So every scan is tested once as
    unknown, and once as known unless its sample's fold is the one that holds out its class. The result's
    arrays are per test instance (``Result.rows``); ``auroc``, ``known_accuracy``, ``closed_accuracy`` and
    ``unknown_rejected`` hold the figures.

    Parameters
    ----------
    space : FeatureSpace
        Rows = scans, with labels and groups.
    classifier : str
        A key of :data:`CLASSIFIERS`.
    level : str
        The classification level.
    n_features : int or None
        Features kept by the selector; None keeps every feature, unselected.
    folds, seed : int
        Number of folds (and of class parts); seed of the folds, the class parts and the classifier.
    feature_set : FeatureSet
        None / ``"all"``, a named set, a modality or column names (see :func:`evaluate`).
    group_by : str
        What ``space.groups`` are, for the report.
    max_accuracy_drop : float
        The known-class accuracy the rejection rule may cost, as a fraction.
    calibrate : bool
        Calibrate each fold's classifier and keep the calibrated probabilities (``Result.probability``).

    Returns
    -------
    Result
        One row per test instance; ``Result.open_set`` is true.

    Raises
    ------
    EvaluationError
        Fewer than two classes to hold out in turn, or too few rows for the folds.

    Examples
    --------
    Four classes at the corners of a square 10 wide, two samples of each scanned twice. Each scan is tested
    once as unknown, and the score ranks every unknown scan above every known one. Each fold trains on two
    classes, too few to hold one out inside training: its threshold stays +inf and nothing is rejected.

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> rng = np.random.default_rng(0)
    >>> X = np.repeat([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]], 4, axis=0) + rng.normal(0, 0.2, (16, 2))
    >>> space = FeatureSpace(X, ("other.density", "other.metal"), tuple(f"scan{i}" for i in range(16)),
    ...                      tuple(f"C{c}S1M1P1X1" for c in np.repeat([1, 2, 3, 4], 4)),
    ...                      tuple(f"sample{k}" for k in range(8) for _ in range(2)))
    >>> result = evaluate_open_set(space, "nb", "coarse", n_features=None, folds=2, calibrate=False)
    >>> result.splitting
    '2 grouped folds, 1/2 of the classes held out per fold'
    >>> int(np.sum(~result.known)), result.auroc, result.closed_accuracy, result.unknown_rejected
    (16, 1.0, 1.0, 0.0)
    """
    level = space.check_level(level)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        subset, dropped = learning_subset(space, level, feature_set)
        y = subset.y(level)
        groups = np.asarray(subset.groups)
        splits, grouped = cv_splits(y, groups, folds, seed, grouping_labels=subset.label_text)
        parts = class_folds(y, len(splits), seed)
        if len(parts) < 2:
            raise EvaluationError("an open-set evaluation needs at least two classes to hold out in turn")

        kernels = _kernels(feature_set, "nested")
        fits = 0  # of the classifier, for Result.unconverged

        def fit(X: np.ndarray, y_fit: np.ndarray, g: np.ndarray) -> Pipeline:
            nonlocal fits
            fits += 1
            return fit_pipeline(X, y_fit, g, classifier, n_features, seed, calibrate=False, kernels=kernels,
                                columns=subset.columns)

        classes = np.unique(y)
        rows, fold, known, score, rejected, y_pred, probability = [], [], [], [], [], [], []
        accuracy, f1 = [], []
        for k, (_, sample_test) in enumerate(splits):
            held = np.isin(y, parts[k % len(parts)])
            in_test = np.zeros(len(y), dtype=bool)
            in_test[sample_test] = True
            train = np.flatnonzero(~held & ~in_test)
            test = np.flatnonzero((in_test & ~held) | held)
            pipeline = fit_pipeline(subset.X[train], y[train], groups[train], classifier, n_features, seed,
                                    calibrate, materials=np.asarray(subset.label_text)[train], kernels=kernels,
                                    columns=subset.columns)
            fits += _fits(pipeline.steps[-1][1])
            learned = learn_rejection(subset.X[train], y[train], groups[train], fit, subset.columns, seed=seed,
                                      max_accuracy_drop=max_accuracy_drop)
            rule = fit_rule(pipeline, subset.X[train], y[train], groups[train], learned, subset.columns,
                            max_accuracy_drop, seed)
            threshold = learned.threshold
            s = rule.score(pipeline, subset.X[test])
            predicted = pipeline.predict(subset.X[test])
            p = np.zeros((len(test), classes.size))
            p[:, np.searchsorted(classes, pipeline.classes_)] = pipeline.predict_proba(subset.X[test])
            is_known = ~held[test]
            rows.append(test)
            fold.append(np.full(len(test), k))
            known.append(is_known)
            score.append(s)
            rejected.append(s > threshold)
            y_pred.append(predicted)
            probability.append(p)
            accuracy.append(np.mean(predicted[is_known] == y[test][is_known]))
            f1.append(present_class_f1(y[test][is_known], predicted[is_known]))
    rows_a, known_a, y_pred_a = np.concatenate(rows), np.concatenate(known), np.concatenate(y_pred)
    y_true = y[rows_a]
    estimator = make_pipeline(classifier, n_features, seed)[-1]
    stopped, others = iteration_limit_stops(estimator, caught)
    return Result(
        method=OWN_METHOD, feature_set=_set_name(feature_set), classifier=classifier_name(classifier), level=level,
        protocol="nested", splitting=f"{len(splits)} {'grouped' if grouped else 'ungrouped'} folds, "
        f"1/{len(parts)} of the classes held out per fold", classes=tuple(classes.tolist()),
        accuracy=np.array(accuracy), f1=np.array(f1),
        confusion=confusion_matrix(y_true[known_a], y_pred_a[known_a], labels=classes), n_samples=len(y),
        seed=seed, notes=warning_notes(others), taxonomy=subset.label_level is None, n_features=n_features,
        unconverged=(stopped, fits) if paper_mlp(estimator) else (0, 0),
        grouped=grouped, columns=subset.columns, dropped=dropped, y_true=y_true, y_pred=y_pred_a,
        fold=np.concatenate(fold), groups=groups[rows_a],
        probability=np.concatenate(probability) if calibrate else None,
        group_by=group_by, rows=rows_a, known=known_a, open_score=np.concatenate(score),
        rejected=np.concatenate(rejected))
