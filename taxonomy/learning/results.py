"""The result of classifying: one type for the project's evaluation and for the related methods.

A :class:`Result` is one classifier on one feature set at one classification level, scored over the
splits of a protocol: accuracy and macro F1 per split, the confusion matrix summed over the splits, and
notes (what scikit-learn or the split reported while fitting, rows or columns left out).
:func:`taxonomy.learning.evaluation.evaluate` returns one per (classifier, feature set, level, set size), with the
out-of-fold predictions and the features each fold selected; :func:`taxonomy.related.compare` one per
configuration of each related method, with the time per classification and the figure its paper reports.
The text table of the evaluation (:func:`taxonomy.reports.report.format_table`), the comparison table
(:func:`format_comparison`), the HTML reports and the figures all read this one type.

The metric ``r_C`` (Strese et al. 2020, eq. 32) is defined here too, as a result's property needs it.
"""

from __future__ import annotations

import functools
import html
import math
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from scanner.lazy import optional
from taxonomy import labels
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label, LabelError
from taxonomy.learning import metrics

OWN_METHOD = "texplorer"
"""The ``method`` of the project's own evaluation (the paper's scale -> FQ selection -> classifier pipeline)."""


class EvaluationError(TexplorerError, ValueError):
    """An evaluation that cannot run as asked; the message says why."""


def one_line(message: str) -> str:
    r"""A message whole on one line: its lines joined, runs of white space made one space.

    Parameters
    ----------
    message : str
        Any message (or object, as its ``str``).

    Returns
    -------
    str
        The message without line breaks, tabs or repeated spaces, stripped.

    Examples
    --------
    >>> from taxonomy.learning.results import one_line
    >>> one_line("lbfgs failed to converge\n    (status=1):\tSTOP ")
    'lbfgs failed to converge (status=1): STOP'
    """
    return " ".join(str(message).split())


def warning_notes(caught: Sequence[warnings.WarningMessage], source: str = "") -> tuple[str, ...]:
    r"""Each warning once, as one line: who raised it (``source``), its category and its whole text.

    Parameters
    ----------
    caught : sequence of warnings.WarningMessage
        The warnings recorded by ``warnings.catch_warnings(record=True)``.
    source : str
        Put before each note, e.g. ``"mlp: "``.

    Returns
    -------
    tuple of str
        ``<source><category>: <message on one line>``, in the order first raised, without repeats.

    Examples
    --------
    >>> import warnings
    >>> from taxonomy.learning.results import warning_notes
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     for _ in range(3):
    ...         warnings.warn("lbfgs failed\n  to converge", UserWarning)
    >>> warning_notes(caught, "mlp: ")
    ('mlp: UserWarning: lbfgs failed to converge',)
    """
    return tuple(dict.fromkeys(f"{source}{w.category.__name__}: {one_line(str(w.message))}" for w in caught))


def size_name(n_features: int | None) -> str:
    """``X10`` for a selected set size, ``all`` for every feature without selection.

    Parameters
    ----------
    n_features : int or None
        The number of features selected; None: every feature, unselected.

    Returns
    -------
    str
        The size as reports name it.

    Examples
    --------
    >>> from taxonomy.learning.results import size_name
    >>> size_name(10), size_name(None)
    ('X10', 'all')
    """
    return "all" if n_features is None else f"X{n_features}"


# -- r_C ---------------------------------------------------------------------------------------------

def major_class(code: str) -> str:
    """The major class C of a class code at any level (:func:`taxonomy.labels.major_class`), as an
    :class:`EvaluationError` for a class without one.

    Parameters
    ----------
    code : str
        A class code at the coarse, medium or fine level.

    Returns
    -------
    str
        Its major class, ``C<c>``.

    Raises
    ------
    EvaluationError
        ``code`` does not start with a major class code.

    Examples
    --------
    >>> from taxonomy.learning.results import major_class
    >>> major_class("C6S1M1P2X1"), major_class("C6S1"), major_class("C6")
    ('C6', 'C6', 'C6')
    >>> major_class("oak")
    Traceback (most recent call last):
    ...
    taxonomy.learning.results.EvaluationError: class 'oak' does not start with a major class code C<c>
    """
    try:
        return labels.major_class(code)
    except LabelError as exc:
        raise EvaluationError(str(exc)) from None


def r_c(confusion: np.ndarray, classes: Sequence[str]) -> float:
    """Share of misclassifications whose predicted major class differs from the true one (paper eq. 32).

    ``r_C = sum over misclassified n of (1 - delta(yhat_C,n, y_C,n)) / N_miss``, read from a confusion
    matrix (rows true, columns predicted, in the order of ``classes``).

    NaN where the metric is undefined (reports show "-"): when nothing is misclassified (no N_miss), and
    at the coarse level, where the classes are the major classes themselves: every misclassification
    changes C by definition, so the ratio would be 1 whatever the classifier does and says nothing.

    Parameters
    ----------
    confusion : numpy.ndarray, shape (k, k)
        Counts, rows the true class, columns the predicted one.
    classes : sequence of str
        The k class codes, in the order of the rows and columns.

    Returns
    -------
    float
        ``r_C`` between 0 and 1, or NaN where it is undefined.

    Raises
    ------
    EvaluationError
        A matrix whose shape does not fit ``classes``, or a class that is no taxonomy code.

    Examples
    --------
    Four misclassifications: one granite (C6S1) taken for marble (C6S2), the same major class, and three
    across major classes:

    >>> import numpy as np
    >>> from taxonomy.learning.results import r_c
    >>> classes = ["C6S1M1P2X1", "C6S2M1P1X1", "C1S1M1P4X1"]
    >>> r_c(np.array([[5, 1, 1], [0, 4, 0], [2, 0, 3]]), classes)
    0.75
    >>> r_c(np.diag([5, 4, 3]), classes), r_c(np.array([[3, 1], [2, 4]]), ["C1", "C6"])
    (nan, nan)
    """
    confusion = np.asarray(confusion)
    if confusion.shape != (len(classes), len(classes)):
        raise EvaluationError(f"confusion matrix of shape {confusion.shape} for {len(classes)} classes")
    majors = np.array([major_class(c) for c in classes])
    if all(major == code for major, code in zip(majors, classes, strict=True)):
        return float("nan")
    wrong = ~np.eye(len(classes), dtype=bool)
    errors = confusion[wrong].sum()
    if errors == 0:
        return float("nan")
    other_major = majors[:, None] != majors[None, :]
    return float(confusion[other_major].sum() / errors)


def format_r_c(value: float) -> str:
    """r_C with two decimals, or "-" where it is undefined (NaN, see :func:`r_c`).

    Parameters
    ----------
    value : float
        An ``r_C`` value, or NaN.

    Returns
    -------
    str
        The text reports show.

    Examples
    --------
    >>> from taxonomy.learning.results import format_r_c
    >>> format_r_c(0.75), format_r_c(1 / 3), format_r_c(float("nan"))
    ('0.75', '0.33', '-')
    """
    return "-" if np.isnan(value) else f"{value:.2f}"


def _split_std(values: np.ndarray) -> float:
    return float(np.std(values, ddof=1)) if len(values) > 1 else 0.0


# -- the result --------------------------------------------------------------------------------------


def history_words(before: int) -> str:
    """How the tables name a running vote (:func:`taxonomy.learning.evaluation.running_vote`).

    Parameters
    ----------
    before : int
        The windows before each one in its vote.

    Returns
    -------
    str
        The phrase.

    Examples
    --------
    >>> history_words(1)
    'each window voted with the 1 window before it in its recording'
    >>> history_words(2)
    'each window voted with the 2 windows before it in its recording'
    """
    return f"each window voted with the {before} window{'s' * (before != 1)} before it in its recording"


@dataclass(frozen=True, eq=False)
class Result:
    """One classifier on one feature set at one level, scored over the splits of a protocol.

    What ran: ``method`` (:data:`OWN_METHOD` for the project's evaluation, else the related method's
    name), ``feature_set`` (``all``, a modality, ``fishel3``, ...), ``classifier``, ``level``,
    ``protocol`` (where scaling and selection were fitted: ``nested``, inside the training rows of each
    split, as every related method does, or ``paper``, once on all rows), ``splitting`` (how the rows
    were split: ``5 grouped folds``, ``the set's train/test split``, ``10-fold CV``, ``5 x holdout
    1/6``, ...), ``motions`` (a related method's motions), ``n_features`` (the selected set size; None:
    every feature, unselected) and ``seed``.

    Scores: ``accuracy`` and ``f1`` (macro, over the classes present in each split's true labels, see
    :func:`taxonomy.learning.metrics.present_class_f1`) hold one value per split; ``f1_pooled``, the headline, is
    the macro F1 of all splits' predictions at once; ``confusion`` sums all splits (rows true, columns
    predicted, in the order of ``classes``); ``notes`` what scikit-learn or the split reported while
    fitting (e.g. an MLP that did not converge) and what was left out; ``taxonomy`` that the classes are
    taxonomy codes (else ``r_c`` is NaN); ``n_samples`` the rows of the set used, training and test (with
    a set's own split, the training rows too; the rows classified are those of ``confusion``).

    The evaluation's own: ``grouped`` (the folds keep the scans of a sample together), ``given_split``
    (the set's own train/test split was used: one "fold"), ``columns`` (the feature columns evaluated),
    ``dropped`` (those left out because they hold NaN), ``selected`` (the names each fold's selector kept,
    best FQ first), and per row of the feature space ``y_true``, ``y_pred`` (out-of-fold predictions),
    ``fold`` (the split that tested it; -1 for a training row of the set's own split), ``groups`` (what the
    folds kept together: ``group_by``, the sample by default) and ``probability`` (calibrated out-of-fold
    class probabilities, columns in the order of ``classes``; None when not calibrated), ``rows`` (the
    feature-space row of each: rows holding no value are left out of an evaluation). ``voted``: each row
    is a recording scored by the vote of its windows (:func:`taxonomy.learning.evaluation.vote`);
    ``history``: each window answered with that many windows before it in its recording
    (:func:`taxonomy.learning.evaluation.running_vote`), 0 for a window alone.
    ``seconds``: the wall time of fitting and predicting over all splits (the shared transform, scaling and
    selection, and this classifier). ``unconverged``: ``(n, m)``, n of the classifier's m fits (calibration's
    inner fits included) stopped at the paper's L-BFGS iteration limit before converging; counted for the
    paper's MLP only, ``(0, 0)`` for every other classifier
    (:func:`taxonomy.learning.evaluation.iteration_limit_stops`).

    An open-set evaluation's own (:func:`taxonomy.learning.evaluation.evaluate_open_set`): the arrays above
    are per test *instance* (a scan is tested once as an unknown, in the fold that holds out its class,
    and once as a known scan, in its sample's fold, unless that is the same fold), ``rows`` the
    feature-space row of each, ``known`` whether its class was trained, ``open_score`` its rejection
    score, ``rejected`` whether the model's rule rejected it; ``accuracy`` per split and ``confusion`` are
    over the known instances without rejection.

    A related method's own: ``feature_seconds`` and ``classify_seconds``, the time per classification
    (feature extraction and the classifier itself), ``paper``, the figure its paper reports for this
    configuration where it reports one, and ``detail``.
    """

    method: str
    feature_set: str
    classifier: str
    level: str
    protocol: str
    splitting: str
    classes: tuple[str, ...]
    accuracy: np.ndarray
    f1: np.ndarray
    confusion: np.ndarray
    n_samples: int
    seed: int
    notes: tuple[str, ...] = field(default=())
    taxonomy: bool = True
    motions: str = ""
    n_features: int | None = None
    grouped: bool = False
    given_split: bool = False
    columns: tuple[str, ...] = ()
    dropped: tuple[str, ...] = ()
    selected: tuple[tuple[str, ...], ...] = ()
    y_true: np.ndarray | None = None
    y_pred: np.ndarray | None = None
    fold: np.ndarray | None = None
    feature_seconds: float = math.nan
    classify_seconds: float = math.nan
    paper: str = ""
    detail: str = ""
    seconds: float = math.nan
    groups: np.ndarray | None = None
    probability: np.ndarray | None = None
    group_by: str = "sample"
    voted: bool = False
    history: int = 0
    rows: np.ndarray | None = None
    known: np.ndarray | None = None
    open_score: np.ndarray | None = None
    rejected: np.ndarray | None = None
    unconverged: tuple[int, int] = (0, 0)

    @property
    def folds(self) -> int:
        """The number of splits scored."""
        return len(self.accuracy)

    @property
    def accuracy_mean(self) -> float:
        """Mean accuracy over the folds."""
        return float(np.mean(self.accuracy))

    @property
    def accuracy_std(self) -> float:
        """Sample standard deviation over splits (ddof = 1, MATLAB's ``std``, as the paper's +- values)."""
        return _split_std(self.accuracy)

    @property
    def f1_mean(self) -> float:
        """Mean macro F1 over the folds."""
        return float(np.mean(self.f1))

    @property
    def f1_std(self) -> float:
        """Spread of the macro F1 over the folds."""
        return _split_std(self.f1)

    @property
    def r_c(self) -> float:
        """Paper eq. (32) over all splits' misclassifications; NaN where undefined (no misclassification, the
        coarse level, or classes that are not taxonomy codes), see :func:`r_c`."""
        return r_c(self.confusion, self.classes) if self.taxonomy else float("nan")

    @property
    def chance(self) -> float:
        """Accuracy of always answering the most frequent class."""
        counts = self.confusion.sum(axis=1)
        return float(counts.max() / counts.sum()) if counts.sum() else math.nan

    @property
    def chance_f1(self) -> float:
        """Expected macro F1 of guessing with the class frequencies, ``1 / K`` (:func:`metrics.chance_macro_f1`)."""
        return metrics.chance_macro_f1(int((self.confusion.sum(axis=1) > 0).sum()))

    @property
    def accuracy_pooled(self) -> float:
        """The share of all out-of-fold predictions that are right (the confusion matrix's trace)."""
        total = self.confusion.sum()
        return float(np.trace(self.confusion) / total) if total else math.nan

    @property
    def f1_pooled(self) -> float:
        """Macro F1 over the pooled out-of-fold predictions, the headline F1 (:mod:`taxonomy.learning.metrics`)."""
        return metrics.macro_f1_from_confusion(self.confusion)

    def _scored_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """True and predicted labels and groups of the scored instances (known instances of an open-set
        result); rebuilt from the confusion matrix, one group per row, where the result has no rows."""
        if self.y_true is not None and self.y_pred is not None and self.fold is not None:
            tested = self.fold >= 0
            if self.known is not None:
                tested &= self.known
            groups = self.groups if self.groups is not None else np.arange(len(self.y_true)).astype(str)
            return self.y_true[tested], self.y_pred[tested], np.asarray(groups)[tested]
        true, pred = np.nonzero(self.confusion)
        counts = self.confusion[true, pred]
        classes = np.asarray(self.classes)
        y_true, y_pred = np.repeat(classes[true], counts), np.repeat(classes[pred], counts)
        return y_true, y_pred, np.arange(len(y_true)).astype(str)

    @functools.cached_property
    def intervals(self) -> dict[str, tuple[float, float]]:
        """95 % percentile-bootstrap intervals of the pooled ``accuracy`` and ``f1`` over the folds' groups
        (:func:`metrics.bootstrap_interval`, 1000 resamples with the result's seed); over single rows for a
        result without groups (a related method's splits).

        Returns
        -------
        dict of str to (float, float)
            ``accuracy`` and ``f1``, each a ``(low, high)`` interval; NaN, NaN where nothing was scored.

        Examples
        --------
        Two samples, one classified right, one wrong: a resample holds both of them (accuracy 1/2), the
        right one twice (1) or the wrong one twice (0), and the 95 % interval spans all three:

        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> granite, oak = "C6S1M1P2X1", "C1S1M1P4X1"
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", (oak, granite),
        ...                 accuracy=np.array([1.0, 0.0]), f1=np.array([1.0, 0.0]),
        ...                 confusion=np.array([[0, 2], [0, 2]]), n_samples=4, seed=0,
        ...                 y_true=np.array([granite, granite, oak, oak]), y_pred=np.array([granite] * 4),
        ...                 fold=np.array([0, 0, 1, 1]),
        ...                 groups=np.array(["granite-01", "granite-01", "oak-01", "oak-01"]))
        >>> result.intervals
        {'accuracy': (0.0, 1.0), 'f1': (0.0, 1.0)}
        """
        y_true, y_pred, groups = self._scored_rows()
        if y_true.size == 0:
            return {"accuracy": (math.nan, math.nan), "f1": (math.nan, math.nan)}
        # Every resample at once: its row weights times each row's indicators give its counts per class.
        classes, codes = np.unique(np.concatenate([y_true, y_pred]), return_inverse=True)
        true, pred = codes[:len(y_true)], codes[len(y_true):]
        one_hot = np.eye(classes.size)
        right = (true == pred).astype(np.float64)
        weights = metrics.bootstrap_weights(groups, self.seed).astype(np.float64)
        f1 = metrics.macro_f1_of_counts(weights @ (one_hot[true] * right[:, None]), weights @ one_hot[true],
                                        weights @ one_hot[pred])
        return {"accuracy": metrics.percentile_interval(weights @ right / weights.sum(axis=1)),
                "f1": metrics.percentile_interval(f1)}

    @property
    def accuracy_ci(self) -> tuple[float, float]:
        """The accuracy's confidence interval."""
        return self.intervals["accuracy"]

    @property
    def f1_ci(self) -> tuple[float, float]:
        """The macro F1's confidence interval."""
        return self.intervals["f1"]

    @functools.cached_property
    def reliability(self) -> metrics.Reliability | None:
        """The reliability bins and ECE of the calibrated out-of-fold probabilities; None without them.

        Returns
        -------
        metrics.Reliability or None
            Over the tested rows with finite probabilities (the known instances of an open-set result).

        Examples
        --------
        Two scans 85 % sure, one of them right, and two 65 % sure, both right: both bins are 0.35 off:

        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> granite, oak = "C6S1M1P2X1", "C1S1M1P4X1"
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", (oak, granite),
        ...                 accuracy=np.array([0.5, 1.0]), f1=np.array([0.5, 1.0]),
        ...                 confusion=np.array([[1, 1], [0, 2]]), n_samples=4, seed=0,
        ...                 y_true=np.array([oak, granite, oak, granite]), y_pred=np.array([oak, oak, oak, granite]),
        ...                 fold=np.array([0, 0, 1, 1]),
        ...                 probability=np.array([[0.85, 0.15], [0.85, 0.15], [0.65, 0.35], [0.35, 0.65]]))
        >>> result.reliability.count.tolist(), result.reliability.accuracy.tolist(), round(result.ece, 6)
        ([2, 2], [1.0, 0.5], 0.35)
        """
        if self.probability is None or self.y_true is None:
            return None
        tested = np.all(np.isfinite(self.probability), axis=1)
        if self.known is not None:
            tested &= self.known
        if not tested.any():
            return None
        index = np.searchsorted(np.asarray(self.classes), self.y_true[tested])
        return metrics.reliability(self.probability[tested], index)

    @property
    def ece(self) -> float:
        """Expected calibration error of the calibrated probabilities (Guo et al. 2017, eq. 3); NaN without."""
        return self.reliability.ece if self.reliability is not None else math.nan

    def derived_accuracy(self, level: str) -> float:
        """Accuracy at a coarser ``level`` of this fine result's predictions cut to that level (``C6S1M1P2X1``
        -> ``C6`` at the coarse level); NaN where it does not apply (not the fine level of taxonomy codes).

        Parameters
        ----------
        level : str
            ``"coarse"`` or ``"medium"`` (``"fine"`` gives the result's own pooled accuracy).

        Returns
        -------
        float
            The share of scored rows whose cut prediction is their cut class.

        Examples
        --------
        Granite (C6S1) taken for marble (C6S2) is wrong at the fine and medium levels, right at the coarse:

        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> granite, marble = "C6S1M1P2X1", "C6S2M1P1X1"
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", (granite, marble),
        ...                 accuracy=np.array([0.0, 1.0]), f1=np.array([0.0, 1.0]),
        ...                 confusion=np.array([[0, 1], [0, 1]]), n_samples=2, seed=0,
        ...                 y_true=np.array([granite, marble]), y_pred=np.array([marble, marble]),
        ...                 fold=np.array([0, 1]))
        >>> result.derived_accuracy("coarse"), result.derived_accuracy("medium"), result.derived_accuracy("fine")
        (1.0, 0.5, 0.5)
        """
        if self.level != "fine" or not self.taxonomy or self.y_true is None or self.y_pred is None:
            return math.nan
        y_true, y_pred, _ = self._scored_rows()
        try:  # each distinct code parsed once
            cut = {code: Label.parse(code).at(level) for code in set(y_true) | set(y_pred)}
        except (LabelError, ValueError):
            return math.nan
        cut_true, cut_pred = [cut[t] for t in y_true], [cut[p] for p in y_pred]
        return metrics.accuracy(cut_true, cut_pred) if cut_true else math.nan

    # -- open set ------------------------------------------------------------------------------------

    @property
    def open_set(self) -> bool:
        """Whether the result holds the open-set figures (known accuracy, scores, rejections)."""
        return self.known is not None and self.open_score is not None and self.rejected is not None

    @property
    def auroc(self) -> float:
        """AUROC of the rejection score, unknown against known instances; NaN for a closed-set result."""
        return metrics.auroc(self.open_score, ~self.known) if self.open_set else math.nan

    @property
    def closed_accuracy(self) -> float:
        """Accuracy on the known instances without rejection."""
        if not self.open_set:
            return self.accuracy_pooled
        return metrics.accuracy(self.y_true[self.known], self.y_pred[self.known])

    @property
    def known_accuracy(self) -> float:
        """Accuracy on the known instances with the rejection rule, a rejected instance counting as wrong."""
        if not self.open_set:
            return math.nan
        right = (self.y_true == self.y_pred) & ~self.rejected
        return float(np.mean(right[self.known]))

    @property
    def unknown_rejected(self) -> float:
        """The share of unknown instances (classes never trained) that the rule rejected."""
        if not self.open_set or self.known.all():
            return math.nan
        return float(np.mean(self.rejected[~self.known]))

    def summary(self) -> str:
        """One line: ``rf fine X10 all (nested): accuracy 90.2 % +- 1.2 % (95 % CI 86.0-93.1), macro F1 0.90
        pooled, 0.91 per fold, r_C 0.05, chance 3.1 % ...``.

        Returns
        -------
        str
            What ran, the mean accuracy with its spread over the splits and its 95 % interval, the pooled and
            per-fold macro F1, ``r_C``, the chance accuracy, the splitting, the classes and the seed.

        Examples
        --------
        >>> import textwrap
        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> classes = ("C1S1M1P4X1", "C6S1M1P2X1")
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", classes,
        ...                 accuracy=np.array([1.0, 0.5]), f1=np.array([1.0, 1 / 3]),
        ...                 confusion=np.array([[1, 1], [0, 2]]), n_samples=4, seed=0, n_features=10)
        >>> print(textwrap.fill(result.summary(), 100))
        rf fine X10 all (nested): accuracy 75.0 % +- 35.4 % (95 % CI 25.0-100.0), macro F1 0.73 pooled, 0.67
        per fold, r_C 1.00, chance 50.0 % (2 grouped folds, 2 classes, seed 0)
        """
        low, high = self.accuracy_ci
        return (f"{self.classifier} {self.level} {size_name(self.n_features)} {self.feature_set} "
                f"({self.protocol}): accuracy {100 * self.accuracy_mean:.1f} % +- {100 * self.accuracy_std:.1f} % "
                f"(95 % CI {100 * low:.1f}-{100 * high:.1f}), macro F1 {self.f1_pooled:.2f} pooled, "
                f"{self.f1_mean:.2f} per fold, r_C {format_r_c(self.r_c)}, chance {100 * self.chance:.1f} % "
                f"({self.splitting}, {len(self.classes)} classes, seed {self.seed})")

    def __repr__(self) -> str:
        """One line: :meth:`summary` with the method (the scores per split: :meth:`to_pandas`)."""
        return f"Result({self.method}: {self.summary()})"

    def _repr_html_(self) -> str:
        """What ran and the scores, as an HTML table of two columns."""
        rows = [("method", self.method), ("classifier", self.classifier), ("feature set", self.feature_set),
                ("features", size_name(self.n_features)), ("level", f"{self.level} ({len(self.classes)} classes)"),
                ("protocol", f"{self.protocol}, {self.splitting}"),
                ("accuracy", f"{100 * self.accuracy_mean:.1f} % +- {100 * self.accuracy_std:.1f} %"),
                ("macro F1", f"{self.f1_mean:.3f} +- {self.f1_std:.3f}"), ("r_C", format_r_c(self.r_c)),
                ("samples", str(self.n_samples)), ("seed", str(self.seed)), *(("note", n) for n in self.notes)]
        cells = "".join(f"<tr><th>{html.escape(key)}</th><td>{html.escape(value)}</td></tr>" for key, value in rows)
        return f"<table><tbody>{cells}</tbody></table>"

    def to_pandas(self, what: str = "splits"):
        """The result as a ``pandas.DataFrame``.

        Parameters
        ----------
        what : {"splits", "predictions", "confusion"}
            ``splits``: one row per split (index ``split``) with its ``accuracy``, macro ``f1`` and, from the
            project's evaluation, the feature names its selector kept (``selected``, best FQ first).
            ``predictions``: one row per row of the feature space evaluated, the true label ``y_true``, the
            out-of-fold prediction ``y_pred`` and the split that tested it (``fold``; -1 for a training row
            of a set's own split); the project's evaluation only. ``confusion``: the confusion matrix summed
            over the splits, rows the true class, columns the predicted one.

        Returns
        -------
        pandas.DataFrame

        Raises
        ------
        ModuleNotFoundError
            pandas is not installed (``pip install 'texplorer[pandas]'``).
        EvaluationError
            ``what`` is none of the three, or ``predictions`` of a result that has none.

        Examples
        --------
        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> classes = ("C1S1M1P4X1", "C6S1M1P2X1")
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", classes,
        ...                 accuracy=np.array([1.0, 0.5]), f1=np.array([1.0, 1 / 3]),
        ...                 confusion=np.array([[1, 1], [0, 2]]), n_samples=4, seed=0)
        >>> print(result.to_pandas().round(4))
               accuracy      f1
        split
        0           1.0  1.0000
        1           0.5  0.3333
        >>> print(result.to_pandas("confusion"))
        predicted   C1S1M1P4X1  C6S1M1P2X1
        true
        C1S1M1P4X1           1           1
        C6S1M1P2X1           0           2
        """
        pd = optional("pandas", "pandas", "Result.to_pandas()")
        if what == "splits":
            frame = pd.DataFrame({"accuracy": self.accuracy, "f1": self.f1},
                                 index=pd.RangeIndex(self.folds, name="split"))
            if len(self.selected) == self.folds:
                frame["selected"] = [list(names) for names in self.selected]
            return frame
        if what == "confusion":
            return pd.DataFrame(self.confusion, index=pd.Index(self.classes, name="true"),
                                columns=pd.Index(self.classes, name="predicted"))
        if what == "predictions":
            if self.y_true is None or self.y_pred is None:
                raise EvaluationError(f"{self.method} keeps no out-of-fold predictions; use 'splits' or 'confusion'")
            fold = self.fold if self.fold is not None else np.full(len(self.y_true), -1)
            return pd.DataFrame({"y_true": self.y_true, "y_pred": self.y_pred, "fold": fold})
        raise EvaluationError(f"to_pandas: {what!r} is none of 'splits', 'predictions', 'confusion'")

    def cells(self) -> tuple[str, ...]:
        """The row of the comparison table, in :data:`COLUMNS` order.

        Returns
        -------
        tuple of str
            One cell per column: the mean accuracy in % with its spread over the splits, the mean macro F1,
            the feature time in milliseconds and the classifier's in microseconds per classification.

        Examples
        --------
        >>> import numpy as np
        >>> from taxonomy.learning.results import COLUMNS, Result
        >>> classes = ("C1S1M1P4X1", "C6S1M1P2X1")
        >>> result = Result("fishel", "fishel3", "bayes", "fine", "nested", "10-fold CV", classes,
        ...                 accuracy=np.array([0.9, 0.8]), f1=np.array([0.9, 0.8]),
        ...                 confusion=np.array([[9, 1], [2, 8]]), n_samples=20, seed=0, motions="tap, slide",
        ...                 feature_seconds=0.0021, classify_seconds=3.5e-05, paper="95.0 %")
        >>> for column, cell in zip(COLUMNS, result.cells()):
        ...     print(f"{column}: {cell.strip()}")
        method: fishel
        features: fishel3
        classifier: bayes
        motions: tap, slide
        level (classes): fine (2)
        protocol: 10-fold CV
        accuracy %: 85.0 +-  7.1
        macro F1: 0.85
        features ms: 2.100
        classify us: 35.0
        paper: 95.0 %
        """
        return (self.method, self.feature_set, self.classifier, self.motions,
                f"{self.level} ({len(self.classes)})", self.splitting,
                f"{100 * self.accuracy_mean:5.1f} +- {100 * self.accuracy_std:4.1f}", f"{self.f1_mean:4.2f}",
                f"{1e3 * self.feature_seconds:8.3f}", f"{1e6 * self.classify_seconds:9.1f}", self.paper)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready values (lists, numbers, strings; an undefined r_C or time becomes None).

        Returns
        -------
        dict of str to object
            What ran, the scores per split and their summaries, the intervals, the confusion matrix, the
            selected features, the notes and the times; ``json.dumps`` writes it as it is.

        Examples
        --------
        >>> import json
        >>> import numpy as np
        >>> from taxonomy.learning.results import Result
        >>> classes = ("C1S1M1P4X1", "C6S1M1P2X1")
        >>> result = Result("texplorer", "all", "rf", "fine", "nested", "2 grouped folds", classes,
        ...                 accuracy=np.array([1.0, 0.5]), f1=np.array([1.0, 1 / 3]),
        ...                 confusion=np.array([[1, 1], [0, 2]]), n_samples=4, seed=0)
        >>> plain = result.to_dict()
        >>> plain["accuracy"], plain["accuracy_mean"], plain["confusion"], plain["feature_seconds"]
        ([1.0, 0.5], 0.75, [[1, 1], [0, 2]], None)
        >>> json.loads(json.dumps(plain)) == plain
        True
        """
        def number(value: float) -> float | None:
            return None if math.isnan(value) else value

        return {
            "method": self.method, "classifier": self.classifier, "level": self.level,
            "n_features": self.n_features, "protocol": self.protocol, "feature_set": self.feature_set,
            "splitting": self.splitting, "folds": self.folds, "seed": self.seed, "grouped": self.grouped,
            "given_split": self.given_split, "motions": self.motions, "n_samples": self.n_samples,
            "accuracy": self.accuracy.tolist(), "f1": self.f1.tolist(),
            "accuracy_mean": self.accuracy_mean, "accuracy_std": self.accuracy_std,
            "f1_mean": self.f1_mean, "f1_std": self.f1_std, "r_c": number(self.r_c),
            "f1_pooled": number(self.f1_pooled), "accuracy_pooled": number(self.accuracy_pooled),
            "accuracy_ci": [number(v) for v in self.accuracy_ci], "f1_ci": [number(v) for v in self.f1_ci],
            "chance": number(self.chance), "chance_f1": number(self.chance_f1), "ece": number(self.ece),
            "group_by": self.group_by, "voted": self.voted, "history": self.history, "auroc": number(self.auroc),
            "known_accuracy": number(self.known_accuracy), "unknown_rejected": number(self.unknown_rejected),
            "classes": list(self.classes), "confusion": self.confusion.tolist(),
            "selected": [list(s) for s in self.selected], "columns": list(self.columns),
            "dropped": list(self.dropped), "notes": list(self.notes), "unconverged": list(self.unconverged),
            "feature_seconds": number(self.feature_seconds), "classify_seconds": number(self.classify_seconds),
            "paper": self.paper, "detail": self.detail,
        }


# -- the comparison table ----------------------------------------------------------------------------

COLUMNS = ("method", "features", "classifier", "motions", "level (classes)", "protocol", "accuracy %",
           "macro F1", "features ms", "classify us", "paper")
"""Columns of the comparison table (times per classification)."""


def format_comparison(results: Sequence[Result]) -> str:
    """The comparison table as text: one row per result, then the notes.

    Parameters
    ----------
    results : sequence of Result
        The rows, in order (:func:`taxonomy.related.compare` gives them).

    Returns
    -------
    str
        The :data:`COLUMNS` header, a rule, one row per result (:meth:`Result.cells`), then ``note:`` lines
        (:func:`result_notes`); a sentence saying so where there are no results.

    Examples
    --------
    The table is wide; here it is in two halves:

    >>> import numpy as np
    >>> from taxonomy.learning.results import Result, format_comparison
    >>> classes = ("C1S1M1P4X1", "C6S1M1P2X1")
    >>> fishel = Result("fishel", "fishel3", "bayes", "fine", "nested", "10-fold CV", classes,
    ...                 accuracy=np.array([0.9, 0.8]), f1=np.array([0.9, 0.8]), confusion=np.array([[9, 1], [2, 8]]),
    ...                 n_samples=20, seed=0, motions="tap, slide", feature_seconds=0.0021,
    ...                 classify_seconds=3.5e-05, paper="95.0 %",
    ...                 notes=("ConvergenceWarning: lbfgs failed to converge",))
    >>> huang = Result("huang", "huang6", "svm", "fine", "nested", "5 x holdout 1/6", classes,
    ...                accuracy=np.array([1.0, 0.9]), f1=np.array([1.0, 0.9]), confusion=np.array([[10, 0], [1, 9]]),
    ...                n_samples=20, seed=0, feature_seconds=0.0125, classify_seconds=2e-06)
    >>> lines = format_comparison([fishel, huang]).splitlines()
    >>> cut = lines[0].index("accuracy %")
    >>> for line in lines[:4]:
    ...     print(line[:cut].rstrip())
    method  features  classifier  motions     level (classes)  protocol
    ------  --------  ----------  ----------  ---------------  ---------------
    fishel  fishel3   bayes       tap, slide  fine (2)         10-fold CV
    huang   huang6    svm                     fine (2)         5 x holdout 1/6
    >>> for line in lines[:4]:
    ...     print(line[cut:])
    accuracy %     macro F1  features ms  classify us  paper
    -------------  --------  -----------  -----------  ------
     85.0 +-  7.1  0.85         2.100          35.0    95.0 %
     95.0 +-  7.1  0.95        12.500           2.0
    >>> lines[4]
    'note: fishel fishel3: ConvergenceWarning: lbfgs failed to converge'
    >>> format_comparison([])
    'no method applies to this dataset'
    """
    if not results:
        return "no method applies to this dataset"
    rows = [COLUMNS, *(r.cells() for r in results)]
    widths = [max(len(row[k]) for row in rows) for k in range(len(COLUMNS))]
    lines = ["  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
             for row in rows]
    lines.insert(1, "  ".join("-" * width for width in widths))
    return "\n".join(lines + [f"note: {note}" for note in result_notes(results)])


def result_notes(results: Sequence[Result]) -> list[str]:
    """Every note once, naming the method (and feature set) that raised it.

    Parameters
    ----------
    results : sequence of Result
        The results whose ``notes`` are gathered.

    Returns
    -------
    list of str
        ``<method> <feature set>: <note>``, in the order of the results, without repeats.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.learning.results import Result, result_notes
    >>> def result(method, notes):
    ...     return Result(method, "all", "svm", "fine", "nested", "10-fold CV", ("C1S1M1P4X1", "C6S1M1P2X1"),
    ...                   accuracy=np.array([1.0]), f1=np.array([1.0]), confusion=np.eye(2, dtype=int), n_samples=2,
    ...                   seed=0, notes=notes)
    >>> result_notes([result("xie", ("2 rows left out",)), result("xie", ("2 rows left out",)), result("huang", ())])
    ['xie all: 2 rows left out']
    """
    return list(dict.fromkeys(f"{r.method} {r.feature_set}: {note}" for r in results for note in r.notes))


def best_per_method(results: Sequence[Result]) -> Iterator[Result]:
    """The most accurate result of every method (first on ties), in method order.

    Parameters
    ----------
    results : sequence of Result
        Results of one or more methods.

    Yields
    ------
    Result
        The result of highest mean accuracy of each method, the methods in the order they first occur.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.learning.results import Result, best_per_method
    >>> def result(method, classifier, accuracy):
    ...     return Result(method, "all", classifier, "fine", "nested", "10-fold CV", ("C1S1M1P4X1", "C6S1M1P2X1"),
    ...                   accuracy=np.array([accuracy]), f1=np.array([accuracy]), confusion=np.eye(2, dtype=int),
    ...                   n_samples=2, seed=0)
    >>> results = [result("xie", "svm", 0.8), result("huang", "knn", 0.7), result("xie", "rf", 0.9),
    ...            result("huang", "svm", 0.7)]
    >>> [(r.method, r.classifier) for r in best_per_method(results)]
    [('xie', 'rf'), ('huang', 'knn')]
    """
    for method in dict.fromkeys(r.method for r in results):
        yield max((r for r in results if r.method == method), key=lambda r: r.accuracy_mean)
