"""Open-set recognition: a score of how unlike the trained materials a scan is, a threshold learned without
test data, and which sensing steps make a rejected scan unlike them.

The rejection score of a scan ``x`` averages four standardised terms (docs/trust.md compares them with
the other candidates tried, on the simulated database and on BorealTC):

- the surprisal of the classifier's top class, ``u(x) = -log max_c p(c | x)`` (the maximum softmax
  probability baseline of Hendrycks and Gimpel 2017, "A Baseline for Detecting Misclassified and
  Out-of-Distribution Examples", ICLR), high where the forest's trees disagree: a new material between
  known ones;
- the Mahalanobis distance ratio ``m(x) = log(M(x) / M_0)``, ``M(x) = min_c sqrt((z - mu_c)^T Sigma^-1
  (z - mu_c))`` from the scan's features ``z`` in the model's own feature space (min-max scaled,
  FQ-selected) to the nearest class mean ``mu_c``, one covariance ``Sigma`` shared by the classes (Lee et
  al. 2018, "A Simple Unified Framework for Detecting Out-of-Distribution Samples and Adversarial
  Attacks", NeurIPS, eq. 2) estimated from the rows' deviations from their class means (a ridge of 1e-6 of
  the mean variance keeps it invertible); ``M_0`` is the median distance of a training scan from the class
  means with its own sample left out of its class's mean: high on the far side of a single class;
- the nearest-neighbour distance per sensing step, ``n(x) = mean_g z_g(x)`` over the feature groups ``g``
  of every input column (the TacTUM, each photo, each slide's sound, the other features:
  :meth:`features.registry.ScanRegistry.column_groups`) in which the scan has a value, ``z_g(x) = (log
  d_g(x) - a_g) / b_g`` with ``d_g`` the Euclidean distance from the scan's group vector to the nearest
  training scan's, after standardising every column on the training rows (a missing value takes the
  training median) and scaling each group vector to unit length (the deep nearest neighbours of Sun et
  al. 2022, "Out-of-Distribution Detection with Deep Nearest Neighbors", ICML, with ``k = 1``: a material
  has 3-6 scans, so the 5th or 10th neighbour already lies in another class), ``a_g``, ``b_g`` the mean
  and standard deviation of ``log d_g`` over the known rows of the leave-classes-out rounds below. The
  selected features separate the known classes; a new material shows in the features no classifier uses.
  Per group, so that a photo's 31 features weigh as much as the 15 of the TacTUM. A unit vector keeps a
  group's pattern, not its size: a scan whose values are a multiple of a known scan's lies at distance 0,
  and a distance is at most 2, so one very unlike group raises ``n`` by a bounded amount (docs/trust.md
  compares the largest group instead of the mean, and distances without the unit length: both rejected
  fewer held-out materials, or more known scans, on the simulated database).
- the surprisal of a forest over every feature, ``w(x) = -log max_c q(c | x)``, ``q`` the class shares of
  the trees of a balanced random forest (each tree's bootstrap drawn with every class equally likely: Chen,
  Liaw and Breiman 2004) grown on every input feature of the training rows, a missing value at the training
  median (:func:`fit_wide`): the model's classifier sees the selected features, this forest all of them, and
  its trees disagree where a new material is like one known material in some features and another in the
  others.

``s(x) = mean_i (t_i(x) - alpha_i) / beta_i`` over the four terms ``t = (u, m, n, w)``, each standardised by
its mean and standard deviation over the same known rows, so no term dominates by its units. A scan is
rejected, "unknown material", where ``s(x) > t``. A model file written before the neighbour term (format
version 2) keeps its score, ``s(x) = m(x) + u(x)``, and threshold; one written before the forest over every
feature (version 3) its mean of ``u``, ``m`` and ``n``.

The rule is learned inside the training rows by leave-classes-out (Scheirer et al. 2013, "Toward Open Set
Recognition", IEEE TPAMI 35(7), whose protocol holds out whole classes): in each of a few rounds a share of
the training classes is held out as "unknown", together with a grouped part of the other classes' rows as
"known"; a model fitted on the rest scores both. These rounds give the scales and the inner AUROC. The
threshold ``t`` is the lowest at which the accuracy on known rows (a rejected scan counts as an error)
stays within ``max_accuracy_drop`` of their accuracy without rejection: as many unknown scans rejected as
that cost in known-class accuracy allows. The known rows it is read from are scored by models of grouped
folds that keep every training class (:func:`known_scores`), as the final model does.

A rejected scan is explained (:class:`Explanation`) by the groups whose ``z_g`` exceeds what 98 % of the
known rows of the rounds showed, the closest trained material by the same group distances, and, where no
group is unlike, whether the classifier is split between materials or the selected features lie outside
every one.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from sklearn.ensemble import RandomForestClassifier
from sklearn.metrics import euclidean_distances, pairwise_distances_argmin_min
from sklearn.pipeline import Pipeline

from features.random_kernels import SIGNAL_PREFIX
from features.registry import REGISTRY
from taxonomy.learning.calibration import TemperatureScaledClassifier, grouped_splits
from taxonomy.learning.metrics import auroc

MAX_ACCURACY_DROP = 0.02
"""Known-class accuracy the rejection rule may cost, as a fraction (2 points)."""

ROUNDS = 5
"""Leave-classes-out rounds inside the training rows; each holds out a fifth of the classes."""

UNLIKE_QUANTILE = 0.98
"""A group is unlike the trained materials where its ``z_g`` exceeds this quantile of the known rows'."""

TERMS = ("surprisal", "distance", "neighbours", "wide")
"""The score's terms ``u``, ``m``, ``n``, ``w`` (module docstring), in the order of :attr:`Scales.term_mean`
(a rule of format version 3 has the first three)."""

WIDE_TREES = 100
"""Trees of the forest over every feature (term ``w``), as many as the model's own random forest."""

FitPipeline = Callable[[np.ndarray, np.ndarray, np.ndarray], Pipeline]
"""``fit(X, y, groups)`` -> a fitted ``scale -> select -> classify`` pipeline."""


@dataclass(frozen=True)
class Distance:
    """The Mahalanobis model of the training rows: class means, shared precision and ``M_0``."""

    means: np.ndarray
    precision: np.ndarray
    scale: float


@dataclass(frozen=True)
class Neighbours:
    """The nearest-neighbour model of the training rows (module docstring, term ``n``).

    ``titles[g]`` names group ``g``; ``group_of[j]`` is the group of input column ``j`` (-1: none, a raw
    signal column); ``fill``, ``centre``, ``spread`` the training median, mean and standard deviation of
    every input column; ``reference`` the training rows standardised; ``classes[i]`` the index of row
    ``i``'s class in the pipeline's ``classes_``.
    """

    titles: tuple[str, ...]
    group_of: np.ndarray
    fill: np.ndarray
    centre: np.ndarray
    spread: np.ndarray
    reference: np.ndarray
    classes: np.ndarray

    def standardise(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows of ``X`` standardised as the reference, missing values at the training median; and where
        the values were finite.

        Parameters
        ----------
        X : numpy.ndarray
            (n, columns) values of the input columns; NaN where missing.

        Returns
        -------
        Z : numpy.ndarray
            (n, columns) standardised values.
        present : numpy.ndarray
            (n, columns) booleans: where ``X`` was finite.

        Examples
        --------
        Training columns of mean 1 and 20, standard deviation 1 and 10, medians 1 and 20:

        >>> import numpy as np
        >>> from taxonomy.learning.openset import fit_neighbours
        >>> neighbours = fit_neighbours(np.array([[0.0, 10.0], [2.0, 30.0]]), np.array(["a", "b"]), ["a", "b"],
        ...                             ["tactum.matx", "other.density"])
        >>> Z, present = neighbours.standardise(np.array([[4.0, np.nan]]))
        >>> Z.tolist(), present.tolist()
        ([[3.0, 0.0]], [[True, False]])
        """
        X = np.asarray(X, dtype=np.float64)
        present = np.isfinite(X)
        filled = np.where(present, X, self.fill)
        return (filled - self.centre) / self.spread, present

    def filled(self, X: np.ndarray) -> np.ndarray:
        """The grouped input columns of ``X`` (those of a feature, not a raw signal's samples), a missing value
        at its training median and a value beyond single precision at its largest (trees compare in float32):
        what the forest over every feature (term ``w``) reads.

        Parameters
        ----------
        X : numpy.ndarray
            (n, columns) values of the input columns; NaN where missing.

        Returns
        -------
        numpy.ndarray
            (n, grouped columns) values.

        Examples
        --------
        Training medians 1 and 20; the raw signal column is left out:

        >>> import numpy as np
        >>> from taxonomy.learning.openset import fit_neighbours
        >>> neighbours = fit_neighbours(np.array([[0.0, 10.0, 5.0], [2.0, 30.0, 6.0]]), np.array(["a", "b"]),
        ...                             ["a", "b"], ["tactum.matx", "other.density", "signal.v_ts.00001"])
        >>> neighbours.filled(np.array([[4.0, np.nan, 7.0], [-1e39, 1e300, 7.0]])).tolist()
        [[4.0, 20.0], [-3.4028234663852886e+38, 3.4028234663852886e+38]]
        """
        X = np.asarray(X, dtype=np.float64)
        grouped = self.group_of >= 0
        largest = float(np.finfo(np.float32).max)
        return np.clip(np.where(np.isfinite(X), X, self.fill)[:, grouped], -largest, largest)

    def log_distances(self, X: np.ndarray) -> np.ndarray:
        """``log d_g`` of every row of ``X`` (n, groups) to the nearest reference row; NaN in a group where
        the row has no finite value.

        Parameters
        ----------
        X : numpy.ndarray
            (n, columns) values of the input columns; NaN where missing.

        Returns
        -------
        numpy.ndarray
            (n, groups) natural log distances.

        Examples
        --------
        Four training scans whose TacTUM vectors point along the axes, class ``a`` along x, ``b`` along y. A scan at 45
        degrees between two of them lies ``2 sin(22.5 deg) = 0.7654`` from the nearest; a multiple of a training scan's
        vector, at distance 0 (the groups are unit vectors):

        >>> import numpy as np
        >>> from taxonomy.learning.openset import fit_neighbours
        >>> X = np.array([[1.0, 0.0, 1.0], [-1.0, 0.0, 2.0], [0.0, 1.0, 3.0], [0.0, -1.0, 4.0]])
        >>> neighbours = fit_neighbours(X, np.array(["a", "a", "b", "b"]), ["a", "b"],
        ...                             ["tactum.x", "tactum.y", "other.density"])
        >>> neighbours.titles
        ('TacTUM', 'other')
        >>> np.round(np.exp(neighbours.log_distances(np.array([[1.0, 1.0, np.nan], [3.0, 0.0, 4.0]]))), 4).tolist()
        [[0.7654, nan], [0.0, 0.0]]
        """
        out = np.full((len(X), len(self.titles)), np.nan)
        for g, has, query, reference in self._groups(X):
            out[has, g] = np.log(np.maximum(pairwise_distances_argmin_min(query, reference)[1], 1e-12))
        return out

    def class_log_distances(self, X: np.ndarray) -> np.ndarray:
        """``log d_g`` of every row of ``X`` to the nearest reference row of each class: (n, groups,
        classes); for a few rows (it holds their distances to every reference row).

        Parameters
        ----------
        X : numpy.ndarray
            (n, columns) values of the input columns; NaN where missing.

        Returns
        -------
        numpy.ndarray
            (n, groups, classes) natural log distances; NaN in a group where the row has no finite value.

        Examples
        --------
        Four training scans whose TacTUM vectors point along the axes, class ``a`` along x, ``b`` along y. A scan along
        x lies at distance 0 from class ``a`` and at a right angle, ``sqrt 2``, from ``b``:

        >>> import numpy as np
        >>> from taxonomy.learning.openset import fit_neighbours
        >>> X = np.array([[1.0, 0.0, 1.0], [-1.0, 0.0, 2.0], [0.0, 1.0, 3.0], [0.0, -1.0, 4.0]])
        >>> neighbours = fit_neighbours(X, np.array(["a", "a", "b", "b"]), ["a", "b"],
        ...                             ["tactum.x", "tactum.y", "other.density"])
        >>> np.round(np.exp(neighbours.class_log_distances(np.array([[1.0, 0.0, np.nan]]))), 4).tolist()
        [[[0.0, 1.4142], [nan, nan]]]
        """
        classes = int(self.classes.max(initial=-1)) + 1
        out = np.full((len(X), len(self.titles), classes), np.nan)
        for g, has, query, reference in self._groups(X):
            d = euclidean_distances(query, reference)
            nearest = np.stack([d[:, self.classes == c].min(axis=1, initial=np.inf) for c in range(classes)], axis=-1)
            out[has, g] = np.log(np.maximum(nearest, 1e-12))
        return out

    def _groups(self, X: np.ndarray) -> Iterator[tuple[int, np.ndarray, np.ndarray, np.ndarray]]:
        """Per group ``g`` with a value in some row of ``X``: the rows that have one, their group vectors and
        the reference rows', standardised and scaled to unit length."""
        Z, present = self.standardise(X)
        for g in range(len(self.titles)):
            columns = self.group_of == g
            has = present[:, columns].any(axis=1)
            if has.any() and len(self.reference):
                yield g, has, unit_rows(Z[has][:, columns]), unit_rows(self.reference[:, columns])


@dataclass(frozen=True)
class Scales:
    """Where the known rows of the leave-classes-out rounds lie: per group the mean ``a_g``, standard
    deviation ``b_g`` and the :data:`UNLIKE_QUANTILE` of ``z_g`` (``limit``); per term of :data:`TERMS` the
    mean ``alpha_i`` and standard deviation ``beta_i`` (three terms in a rule of format version 3, which
    has no ``w``)."""

    group_mean: np.ndarray
    group_sd: np.ndarray
    group_limit: np.ndarray
    term_mean: np.ndarray
    term_sd: np.ndarray

    def group_z(self, log_distances: np.ndarray) -> np.ndarray:
        """Log distances per feature group standardised by the known scans' mean and spread.

        Parameters
        ----------
        log_distances : numpy.ndarray
            ``log d_g``, groups on the last axis.

        Returns
        -------
        numpy.ndarray
            ``z_g = (log d_g - a_g) / b_g``, shaped as ``log_distances``.

        Examples
        --------
        >>> import numpy as np
        >>> from taxonomy.learning.openset import Scales
        >>> scales = Scales(np.array([-1.0, 0.0]), np.array([0.5, 2.0]), np.zeros(2), np.zeros(3), np.ones(3))
        >>> scales.group_z(np.array([[0.0, 1.0]])).tolist()
        [[2.0, 0.5]]
        """
        return (log_distances - self.group_mean) / self.group_sd

    def combine(self, terms: np.ndarray) -> np.ndarray:
        """``s = mean_i (t_i - alpha_i) / beta_i`` of rows of terms (n, 4); a missing term (a scan with no
        value in any group) is left out of the mean, and so is every term after those the scales have.

        Parameters
        ----------
        terms : numpy.ndarray
            (n, 4) raw terms ``(u, m, n, w)`` (:meth:`RejectionRule.terms`), or their first three.

        Returns
        -------
        numpy.ndarray
            (n,) scores.

        Examples
        --------
        Terms of standard deviations 1, 2 and 4 around 0: ``(3 + 1 + 1) / 3``, and without the last term
        ``(3 + 1) / 2``:

        >>> import numpy as np
        >>> from taxonomy.learning.openset import Scales
        >>> scales = Scales(np.zeros(1), np.ones(1), np.zeros(1), np.zeros(3), np.array([1.0, 2.0, 4.0]))
        >>> np.round(scales.combine(np.array([[3.0, 2.0, 4.0], [3.0, 2.0, np.nan]])), 6).tolist()
        [1.666667, 2.0]
        """
        return _mean_present((terms[:, :self.term_mean.size] - self.term_mean) / self.term_sd)


@dataclass(frozen=True)
class Explanation:
    """Why a scan scores as it does: the trained class closest to it by the group distances, the groups
    that find it unlike every trained material (their ``z_g`` above the known rows' limit, most unlike
    first), and its largest standardised term (one of :data:`TERMS`)."""

    closest: str
    unlike: tuple[str, ...]
    largest: str


@dataclass(frozen=True)
class RejectionRule:
    """What a model needs to reject a scan (module docstring): the class means ``mu_c`` and shared precision
    ``Sigma^-1`` in its feature space, ``M_0``, the threshold ``t``, the neighbour model and scales of
    the combined score (None in a rule of format version 2, whose score is ``m + u``), and the forest over
    every feature of term ``w`` (None in a rule of version 2 or 3).

    ``inner_auroc`` is the AUROC of the score on the held-out rounds inside training, ``max_accuracy_drop``
    the known-class accuracy ``t`` was allowed to cost there.
    """

    means: np.ndarray
    precision: np.ndarray
    distance_scale: float
    threshold: float
    max_accuracy_drop: float = MAX_ACCURACY_DROP
    inner_auroc: float = float("nan")
    neighbours: Neighbours | None = None
    scales: Scales | None = None
    wide: RandomForestClassifier | None = None

    def to_dict(self) -> dict[str, object]:
        """The rule as plain values and arrays, as a model file stores it.

        Returns
        -------
        dict of str to object
            Floats and float arrays; with a neighbour model and scales also their arrays, group titles and
            each reference row's class; with the forest over every feature also that fitted forest
            (``wide_forest``).

        Examples
        --------
        A rule of the previous format (no neighbour model): its threshold, scale and budget, and two arrays:

        >>> import numpy as np
        >>> from taxonomy.learning.openset import RejectionRule
        >>> stored = RejectionRule(np.zeros((2, 1)), np.eye(1), 2.0, 1.5, inner_auroc=0.9).to_dict()
        >>> {name: value for name, value in stored.items() if isinstance(value, float)}
        {'distance_scale': 2.0, 'threshold': 1.5, 'max_accuracy_drop': 0.02, 'inner_auroc': 0.9}
        >>> stored["means"].tolist(), stored["precision"].tolist()
        ([[0.0], [0.0]], [[1.0]])
        """
        stored: dict[str, object] = {
            "means": np.asarray(self.means, dtype=np.float64),
            "precision": np.asarray(self.precision, dtype=np.float64),
            "distance_scale": float(self.distance_scale), "threshold": float(self.threshold),
            "max_accuracy_drop": float(self.max_accuracy_drop), "inner_auroc": float(self.inner_auroc)}
        if self.neighbours is not None and self.scales is not None:
            n, s = self.neighbours, self.scales
            stored.update({
                "group_titles": list(n.titles), "group_of": np.asarray(n.group_of, dtype=np.int64),
                "fill": n.fill, "centre": n.centre, "spread": n.spread, "reference": n.reference,
                "reference_classes": np.asarray(n.classes, dtype=np.int64), "group_mean": s.group_mean,
                "group_sd": s.group_sd, "group_limit": s.group_limit, "term_mean": s.term_mean,
                "term_sd": s.term_sd})
            if s.term_mean.size > 3:
                stored["wide_forest"] = self.wide
        return stored

    def terms(self, pipeline: Pipeline, X: np.ndarray) -> np.ndarray:
        """The raw terms ``(u, m, n, w)`` of every row of ``X`` (n, 4); ``n`` is NaN in a rule of format
        version 2, ``w`` in one of version 2 or 3.

        Parameters
        ----------
        pipeline : Pipeline
            The fitted model this rule was fitted for.
        X : numpy.ndarray
            (n, columns) values of the input columns.

        Returns
        -------
        numpy.ndarray
            (n, 4) surprisal, log distance ratio, mean group ``z_g`` and the surprisal of the forest over
            every feature.

        Examples
        --------
        Two samples of cork (0 and 0.2) and of oak (0.8 and 1); ``M_0 = 2``: a training scan lies 0.2 from the mean of
        its class's other sample, twice the classes' standard deviation of 0.1. A rule of the previous format (no
        neighbour term) with threshold 1. A scan at 0.2 is sure cork (``u = 0``), ``1 = M_0 / 2`` from its mean; one
        halfway, at 0.5, is split 50:50 (``u = log 2``) and ``4 = 2 M_0`` from either mean:

        >>> import numpy as np
        >>> from taxonomy.learning.evaluation import fit_pipeline
        >>> from taxonomy.learning.openset import Learned, fit_rule
        >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
        >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
        >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
        >>> rule = fit_rule(pipeline, X, y, groups, Learned(1.0, float("nan"), None), ["other.density"])
        >>> np.round(rule.terms(pipeline, np.array([[0.2], [0.5]])), 4).tolist()
        [[0.0, -0.6931, nan, nan], [0.6931, 0.6931, nan, nan]]
        """
        return score_terms(pipeline, X, Distance(self.means, self.precision, self.distance_scale),
                           self.neighbours, self.scales, self.wide)

    def score(self, pipeline: Pipeline, X: np.ndarray) -> np.ndarray:
        """``s(x)`` of every row of ``X`` under ``pipeline``, the model this rule was fitted for.

        Parameters
        ----------
        pipeline : Pipeline
            The fitted model this rule was fitted for.
        X : numpy.ndarray
            (n, columns) values of the input columns.

        Returns
        -------
        numpy.ndarray
            (n,) scores; a scan is rejected where its score exceeds ``threshold``.

        Examples
        --------
        Two samples of cork (0 and 0.2) and of oak (0.8 and 1); ``M_0 = 2``: a training scan lies 0.2 from the mean of
        its class's other sample, twice the classes' standard deviation of 0.1. A rule of the previous format (no
        neighbour term) with threshold 1: its score is ``u + m``, ``0 - log 2`` for a scan of cork at 0.2, and
        ``log 2 + log 2`` for one halfway between the classes, which is rejected:

        >>> import numpy as np
        >>> from taxonomy.learning.evaluation import fit_pipeline
        >>> from taxonomy.learning.openset import Learned, fit_rule
        >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
        >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
        >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
        >>> rule = fit_rule(pipeline, X, y, groups, Learned(1.0, float("nan"), None), ["other.density"])
        >>> score = rule.score(pipeline, np.array([[0.2], [0.5]]))
        >>> np.round(score, 4).tolist(), (score > rule.threshold).tolist()
        ([-0.6931, 1.3863], [False, True])
        """
        terms = self.terms(pipeline, X)
        if self.scales is None:
            return terms[:, 0] + terms[:, 1]
        return self.scales.combine(terms)

    def assess(self, pipeline: Pipeline, X: np.ndarray) -> tuple[np.ndarray, list[Explanation]]:
        """``s(x)`` and an :class:`Explanation` of every row of ``X``, from one computation of the terms (a
        scan being classified needs both). The closest class is the classifier's top one in a rule of the
        previous format (which names no group) and for a row without a value in any group.

        Parameters
        ----------
        pipeline : Pipeline
            The fitted model this rule was fitted for.
        X : numpy.ndarray
            (n, columns) values of the input columns.

        Returns
        -------
        score : numpy.ndarray
            (n,) scores, as :meth:`score` gives them.
        explanations : list of Explanation
            One per row.

        Examples
        --------
        Two samples of cork and of oak, told apart by their density; their TacTUM vectors point one way or
        another, alike in both materials. With scales that leave ``z_g = log d_g`` and limit it at 0 (a
        distance of 1), a scan whose TacTUM vector lies at a right angle to every trained one (distance
        ``sqrt 2``) is unlike in that group:

        >>> import numpy as np
        >>> from taxonomy.learning.evaluation import fit_pipeline
        >>> from taxonomy.learning.openset import Learned, Scales, fit_rule
        >>> X = np.array([[0.0, 1.0, 0.0], [0.2, 0.0, 1.0], [0.8, 1.0, 0.0], [1.0, 0.0, 1.0]])
        >>> y, groups = np.array(["cork", "cork", "oak", "oak"]), np.array(["cork1", "cork2", "oak1", "oak2"])
        >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
        >>> scales = Scales(np.zeros(2), np.ones(2), np.zeros(2), np.zeros(3), np.ones(3))
        >>> rule = fit_rule(pipeline, X, y, groups, Learned(0.0, float("nan"), scales),
        ...                 ["other.density", "tactum.a", "tactum.b"])
        >>> score, why = rule.assess(pipeline, np.array([[0.1, 1.0, 0.0], [0.1, 1.0, 1.0]]))
        >>> [(e.closest, e.unlike) for e in why], bool(score[1] > score[0])
        ([('cork', ()), ('cork', ('TacTUM',))], True)
        """
        classes = [str(c) for c in pipeline.classes_]
        if self.neighbours is None or self.scales is None:
            top = pipeline.predict_proba(X).argmax(axis=1)
            terms = self.terms(pipeline, X)
            largest = np.where(terms[:, 0] > terms[:, 1], TERMS[0], TERMS[1])
            return terms[:, 0] + terms[:, 1], [Explanation(classes[b], (), str(w))
                                               for b, w in zip(top, largest, strict=True)]
        distance = Distance(self.means, self.precision, self.distance_scale)
        terms = score_terms(pipeline, X, distance, self.neighbours, None, self.wide)
        z_groups = self.scales.group_z(self.neighbours.log_distances(X))
        terms[:, 2] = _mean_present(z_groups)
        used = self.scales.term_mean.size
        z_terms = (terms[:, :used] - self.scales.term_mean) / self.scales.term_sd
        by_class = self.scales.group_z(self.neighbours.class_log_distances(X).transpose(2, 0, 1))
        with warnings_ignored():  # a scan without a value in any group has no closest by distance
            closest = np.nanmean(by_class, axis=2).T  # (n, classes)
        unplaced = ~np.isfinite(closest).any(axis=1)
        if unplaced.any():
            closest[unplaced] = -pipeline.predict_proba(X[unplaced])  # the classifier's top class is closest
        out = []
        for i in range(len(terms)):
            over = np.flatnonzero(z_groups[i] > self.scales.group_limit)
            over = over[np.argsort(-z_groups[i][over], kind="stable")]
            finite = np.where(np.isfinite(z_terms[i]), z_terms[i], -np.inf)
            nearest = classes[int(np.nanargmin(closest[i]))]
            out.append(Explanation(nearest, tuple(self.neighbours.titles[g] for g in over),
                                   TERMS[int(np.argmax(finite))]))
        return self.scales.combine(terms), out


def unit_rows(Z: np.ndarray) -> np.ndarray:
    """Every row of ``Z`` scaled to unit Euclidean length (a zero row stays zero).

    Parameters
    ----------
    Z : numpy.ndarray
        (n, d) vectors.

    Returns
    -------
    numpy.ndarray
        (n, d) unit vectors, or zeros.

    Examples
    --------
    >>> import numpy as np
    >>> unit_rows(np.array([[3.0, 4.0], [0.0, 0.0]])).tolist()
    [[0.6, 0.8], [0.0, 0.0]]
    """
    return Z / np.maximum(np.linalg.norm(Z, axis=1, keepdims=True), 1e-12)


def _class_means(Z: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    classes, index = np.unique(y, return_inverse=True)
    means = np.array([Z[index == k].mean(axis=0) for k in range(classes.size)])
    return means, index


def mahalanobis(Z: np.ndarray, means: np.ndarray, precision: np.ndarray) -> np.ndarray:
    """Distance of every row of ``Z`` to its nearest class mean under the shared ``precision``.

    Parameters
    ----------
    Z : numpy.ndarray
        (n, d) rows in the model's feature space.
    means : numpy.ndarray
        (classes, d) class means.
    precision : numpy.ndarray
        (d, d) inverse of the shared covariance.

    Returns
    -------
    numpy.ndarray
        (n,) Mahalanobis distances.

    Examples
    --------
    A 3-4-5 triangle: with unit covariance the Euclidean distance, with variance 4 (precision 1/4) half of it:

    >>> import numpy as np
    >>> Z, means = np.array([[0.0, 0.0], [3.0, 4.0]]), np.array([[0.0, 0.0], [10.0, 10.0]])
    >>> mahalanobis(Z, means, np.eye(2)).tolist(), mahalanobis(Z, means, np.eye(2) / 4).tolist()
    ([0.0, 5.0], [0.0, 2.5])
    """
    Z = np.asarray(Z, dtype=np.float64)
    squared = np.stack([np.einsum("ij,jk,ik->i", Z - m, precision, Z - m) for m in means])
    return np.sqrt(np.maximum(squared.min(axis=0), 0.0))


def fit_distance(Z: np.ndarray, y: np.ndarray, groups: np.ndarray) -> Distance:
    """Class means, the covariance of the rows' deviations from their class means (with a ridge,
    inverted) and ``M_0``: the median over the training rows whose class has another group (sample) of
    the distance to the nearest class mean, the row's own class's mean taken without the row's group. Rows
    of a class with a single sample are left out of ``M_0``: without their own class they would measure
    the distance between classes, and models fitted on fewer samples would get a larger scale.

    Parameters
    ----------
    Z : numpy.ndarray
        (n, d) training rows in the model's feature space.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample.

    Returns
    -------
    Distance

    Examples
    --------
    Two samples of cork (0 and 0.2) and of oak (0.8 and 1): class means 0.1 and 0.9, variance 0.01
    (precision 100), and ``M_0 = 0.2 * 10 = 2``, a scan's distance from its class's other sample:

    >>> import numpy as np
    >>> distance = fit_distance(np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"]),
    ...                         np.array(["cork1", "cork2", "oak1", "oak2"]))
    >>> np.round(distance.means, 6).tolist(), round(float(distance.precision[0, 0]), 3), round(distance.scale, 4)
    ([[0.1], [0.9]], 100.0, 2.0)
    """
    Z, y, groups = np.asarray(Z, dtype=np.float64), np.asarray(y), np.asarray(groups)
    means, index = _class_means(Z, y)
    deviations = Z - means[index]
    covariance = deviations.T @ deviations / len(Z)
    ridge = 1e-6 * max(float(np.trace(covariance)) / len(covariance), 1e-12)
    precision = np.linalg.pinv(covariance + ridge * np.eye(len(covariance)))
    nearest = []
    for i in range(len(Z)):
        mates = (index == index[i]) & (groups != groups[i])
        if mates.any():
            others = np.vstack([np.delete(means, index[i], axis=0), Z[mates].mean(axis=0)])
            nearest.append(mahalanobis(Z[i:i + 1], others, precision)[0])
    scale = float(np.median(nearest)) if nearest else 1.0
    return Distance(means, precision, max(scale, 1e-12))


def feature_groups(columns: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
    """The group titles of the input ``columns`` and each column's group index (-1 for a raw signal column,
    whose values are samples, not features).

    Parameters
    ----------
    columns : sequence of str
        The input column names (:meth:`features.registry.ScanRegistry.column_groups`).

    Returns
    -------
    titles : tuple of str
        The groups' titles, in order of first appearance.
    group_of : numpy.ndarray
        Each column's group index, or -1.

    Examples
    --------
    >>> titles, group_of = feature_groups(["tactum.matx", "other.density", "other.metal", "signal.v_ts.00001"])
    >>> titles, group_of.tolist()
    (('TacTUM', 'other'), [0, 1, 1, -1])
    """
    titles: list[str] = []
    group_of = np.full(len(columns), -1, dtype=np.int64)
    for title, indices in REGISTRY.column_groups(columns):
        kept = [j for j in indices if not columns[j].startswith(f"{SIGNAL_PREFIX}.")]
        if kept:
            group_of[kept] = len(titles)
            titles.append(title)
    return tuple(titles), group_of


def fit_neighbours(X: np.ndarray, y: np.ndarray, classes: Sequence[str], columns: Sequence[str]) -> Neighbours:
    """The nearest-neighbour model of the training rows ``X`` (classes ``y``, the pipeline's ``classes``).

    Parameters
    ----------
    X : numpy.ndarray
        (n, columns) training rows; NaN where a value is missing.
    y : numpy.ndarray
        Each row's class.
    classes : sequence of str
        The pipeline's classes (``classes_``), sorted.
    columns : sequence of str
        The input column names, which name the groups (:func:`feature_groups`).

    Returns
    -------
    Neighbours

    Examples
    --------
    Three scans; the missing density takes the median, 20, and every column is standardised (mean 2 and 20,
    standard deviation ``sqrt(8 / 3)`` and ``10 sqrt(2 / 3)``):

    >>> import numpy as np
    >>> X = np.array([[0.0, 10.0], [2.0, np.nan], [4.0, 30.0]])
    >>> neighbours = fit_neighbours(X, np.array(["a", "b", "b"]), ["a", "b"], ["tactum.matx", "other.density"])
    >>> neighbours.titles, neighbours.fill.tolist(), neighbours.classes.tolist()
    (('TacTUM', 'other'), [2.0, 20.0], [0, 1, 1])
    >>> np.round(neighbours.reference, 4).tolist()
    [[-1.2247, -1.2247], [0.0, 0.0], [1.2247, 1.2247]]
    """
    X = np.asarray(X, dtype=np.float64)
    titles, group_of = feature_groups(columns)
    finite = np.isfinite(X)
    fill = np.array([np.median(X[finite[:, j], j]) if finite[:, j].any() else 0.0 for j in range(X.shape[1])])
    filled = np.where(finite, X, fill)
    centre, spread = filled.mean(axis=0), filled.std(axis=0)
    spread = np.where(spread > 1e-12, spread, 1.0)
    return Neighbours(titles, group_of, fill, centre, spread, (filled - centre) / spread,
                      np.searchsorted(np.asarray(classes), np.asarray(y)))


def confidence(pipeline: Pipeline, X: np.ndarray) -> np.ndarray:
    """The classifier's own largest class probability per row: of the forest's trees (not the calibrated
    probability, whose temperature changes from model to model), or the calibrated one where the classifier
    has no probabilities of its own.

    Parameters
    ----------
    pipeline : Pipeline
        A fitted ``scale -> select -> classify`` pipeline.
    X : numpy.ndarray
        (n, columns) values of the input columns.

    Returns
    -------
    numpy.ndarray
        (n,) the largest class probability of each row.

    Examples
    --------
    Two samples of cork (0 and 0.2) and of oak (0.8 and 1), the classes' standard deviation 0.1: sure at a class mean,
    split 50:50 halfway between them:

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
    >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
    >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
    >>> np.round(confidence(pipeline, np.array([[0.1], [0.5]])), 6).tolist()
    [1.0, 0.5]
    """
    classifier = pipeline[-1]
    Z = pipeline[:-1].transform(X)
    if isinstance(classifier, TemperatureScaledClassifier) and hasattr(classifier.estimator_, "predict_proba"):
        classifier = classifier.estimator_
    return classifier.predict_proba(Z).max(axis=1)


def score_terms(pipeline: Pipeline, X: np.ndarray, distance: Distance, neighbours: Neighbours | None,
                scales: Scales | None, wide: RandomForestClassifier | None = None) -> np.ndarray:
    """``(u, m, n, w)`` of every row of ``X`` (module docstring); ``n`` is NaN without ``scales`` (it needs
    the groups' ``a_g``, ``b_g``), ``w`` without ``wide`` or ``neighbours`` (whose training medians fill its
    missing values).

    Parameters
    ----------
    pipeline : Pipeline
        A fitted ``scale -> select -> classify`` pipeline.
    X : numpy.ndarray
        (n, columns) values of the input columns.
    distance : Distance
        The Mahalanobis model of the pipeline's training rows (:func:`fit_distance`).
    neighbours : Neighbours or None
        The nearest-neighbour model of the training rows (:func:`fit_neighbours`).
    scales : Scales or None
        The groups' and terms' scales.
    wide : RandomForestClassifier or None
        The forest over every feature (:func:`fit_wide`).

    Returns
    -------
    numpy.ndarray
        (n, 4) surprisal ``u``, log distance ratio ``m``, mean group ``z_g`` ``n`` and the surprisal of the
        forest over every feature ``w``.

    Examples
    --------
    Two samples of cork (0 and 0.2) and of oak (0.8 and 1), the classes' standard deviation 0.1; ``M_0 = 2``. A scan at
    0.2 is sure cork (``u = 0``), 1 from its mean (``m = log(1 / 2)``); one at 0.5 is split 50:50 (``u = log 2``), 4
    from either mean (``m = log 2``):

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
    >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
    >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
    >>> distance = fit_distance(pipeline[:-1].transform(X), y, groups)
    >>> np.round(score_terms(pipeline, np.array([[0.2], [0.5]]), distance, None, None), 4).tolist()
    [[0.0, -0.6931, nan, nan], [0.6931, 0.6931, nan, nan]]
    """
    u = -np.log(np.maximum(confidence(pipeline, X), 1e-12))
    m = np.log(np.maximum(mahalanobis(pipeline[:-1].transform(X), distance.means, distance.precision)
                          / distance.scale, 1e-12))
    n = np.full(len(u), np.nan)
    if neighbours is not None and scales is not None:
        n = _mean_present(scales.group_z(neighbours.log_distances(X)))
    w = wide_surprisal(wide, neighbours, X) if wide is not None and neighbours is not None else np.full(len(u), np.nan)
    return np.column_stack([u, m, n, w])


def fit_wide(X: np.ndarray, y: np.ndarray, neighbours: Neighbours, seed: int) -> RandomForestClassifier | None:
    """The forest of term ``w``: a balanced random forest of :data:`WIDE_TREES` trees (each tree's bootstrap
    drawn with every class equally likely, Chen, Liaw and Breiman 2004) on every grouped input column of the
    training rows ``X``, a missing value at the training median (:meth:`Neighbours.filled`); None where every
    input column is a raw signal's samples (a random-kernel model's), which leaves ``w`` out of the score.

    Parameters
    ----------
    X : numpy.ndarray
        (n, columns) the training rows; NaN where a value is missing.
    y : numpy.ndarray
        Each row's class.
    neighbours : Neighbours
        The neighbour model of the same rows (its groups and medians).
    seed : int
        The forest's random state.

    Returns
    -------
    RandomForestClassifier or None
        Fitted; None without a grouped input column.

    Examples
    --------
    >>> import numpy as np
    >>> X, y = np.array([[0.0, 1.0], [0.2, 1.1], [0.8, 5.0], [1.0, 5.2]]), np.array(["cork", "cork", "oak", "oak"])
    >>> neighbours = fit_neighbours(X, y, ["cork", "oak"], ["other.density", "tactum.matx"])
    >>> forest = fit_wide(X, y, neighbours, seed=0)
    >>> forest.n_features_in_, forest.class_weight, forest.predict(neighbours.filled([[0.1, np.nan]])).tolist()
    (2, 'balanced', ['cork'])
    """
    if not np.any(neighbours.group_of >= 0):
        return None
    forest = RandomForestClassifier(n_estimators=WIDE_TREES, class_weight="balanced", random_state=seed, n_jobs=1)
    return forest.fit(neighbours.filled(X), np.asarray(y))


def wide_surprisal(wide: RandomForestClassifier, neighbours: Neighbours, X: np.ndarray) -> np.ndarray:
    """``w(x) = -log max_c q(c | x)`` of every row of ``X`` (module docstring).

    Parameters
    ----------
    wide : RandomForestClassifier
        The forest over every feature (:func:`fit_wide`).
    neighbours : Neighbours
        The neighbour model it was fitted with (its groups and medians).
    X : numpy.ndarray
        (n, columns) values of the input columns; NaN where missing.

    Returns
    -------
    numpy.ndarray
        (n,) surprisals, 0 where every tree names one class, ``log K`` where ``K`` classes share the votes.

    Examples
    --------
    Six scans of cork and of oak; either feature tells them apart on its own, and each tree splits on one
    drawn at random. A scan of cork gets every vote (``w = 0``); one with cork's density and oak's TacTUM
    value splits the trees about evenly (``w`` near ``log 2 = 0.69``):

    >>> import numpy as np
    >>> step = np.arange(6) / 10
    >>> X = np.r_[np.c_[step, 5 + step], np.c_[1 + step, step]]
    >>> y = np.repeat(["cork", "oak"], 6)
    >>> neighbours = fit_neighbours(X, y, ["cork", "oak"], ["other.density", "tactum.matx"])
    >>> w = wide_surprisal(fit_wide(X, y, neighbours, seed=0), neighbours, np.array([[0.2, 5.2], [0.2, 0.2]]))
    >>> (np.round(w, 2) + 0.0).tolist()
    [0.0, 0.67]
    """
    return -np.log(np.maximum(wide.predict_proba(neighbours.filled(X)).max(axis=1), 1e-12))


def _mean_present(values: np.ndarray) -> np.ndarray:
    """Mean of every row's finite values; NaN for a row without any."""
    counts = np.isfinite(values).sum(axis=1)
    return np.where(counts > 0, np.nansum(values, axis=1) / np.maximum(counts, 1), np.nan)


def choose_threshold(score: np.ndarray, unknown: np.ndarray, correct: np.ndarray,
                     max_accuracy_drop: float = MAX_ACCURACY_DROP) -> float:
    """The threshold ``t`` (reject ``s > t``) at which the known rows' accuracy, a rejected row counting as
    an error, is expected to fall by ``max_accuracy_drop``.

    A known row that is classified right costs accuracy when rejected, so ``t`` is the upper
    ``q = max_accuracy_drop * n_known / n_right`` quantile of the right rows' scores (linear interpolation
    between order statistics). The previous rule's threshold was the quantile of a normal distribution
    fitted to them; the combined score has a heavier right tail than a normal one on the simulated database,
    where the fit put ``t`` too high (read from the leave-classes-out rounds' known scores: 77 % of the
    held-out materials' scans rejected against 85 % with the order statistics, at the same 2.1 % of known
    scans). +inf (reject nothing) with
    fewer than three right rows; ``unknown`` rows do not set ``t``, which is the lowest that keeps the
    known-class accuracy: the most unknown rows rejected for that cost.

    Parameters
    ----------
    score : numpy.ndarray
        (n,) the rows' scores ``s``.
    unknown : numpy.ndarray
        (n,) booleans: rows of a class the scoring model did not know.
    correct : numpy.ndarray
        (n,) booleans: rows the model classified right.
    max_accuracy_drop : float
        The known-class accuracy the rule may cost, as a fraction.

    Returns
    -------
    float
        The threshold; -inf (reject everything) where the budget covers every right row.

    Examples
    --------
    Ten known rows, all right, scored 1 to 10, and a budget of 10 %: ``q = 0.1``, the 0.9 quantile
    ``1 + 0.9 * 9 = 9.1``. Unknown rows leave it where it is; two right rows set nothing:

    >>> import numpy as np
    >>> round(choose_threshold(np.arange(1.0, 11.0), np.zeros(10, bool), np.ones(10, bool), 0.1), 6)
    9.1
    >>> unknown = np.r_[np.zeros(10, bool), np.ones(2, bool)]
    >>> round(choose_threshold(np.arange(1.0, 13.0), unknown, np.ones(12, bool), 0.1), 6)
    9.1
    >>> choose_threshold(np.array([1.0, 2.0]), np.zeros(2, bool), np.ones(2, bool))
    inf
    """
    score, unknown, correct = np.asarray(score), np.asarray(unknown, dtype=bool), np.asarray(correct, dtype=bool)
    right = score[~unknown & correct & np.isfinite(score)]
    if right.size < 3:
        return float("inf")
    q = max_accuracy_drop * int((~unknown).sum()) / right.size
    if q >= 1:
        return float(-np.inf)
    return float(np.quantile(right, 1 - q))


def class_folds(y: np.ndarray, folds: int, seed: int) -> list[np.ndarray]:
    """The classes of ``y`` shuffled with ``seed`` and dealt into ``folds`` parts (each class in one).

    Parameters
    ----------
    y : numpy.ndarray
        Each row's class.
    folds : int
        The number of parts; fewer where there are fewer classes (no part is empty).
    seed : int
        Seed of the shuffle.

    Returns
    -------
    list of numpy.ndarray
        Each part's classes, sorted.

    Examples
    --------
    >>> import numpy as np
    >>> y = np.array(["a", "a", "b", "b", "c", "c", "d", "d", "e"])
    >>> [part.tolist() for part in class_folds(y, 2, seed=0)]
    [['b', 'c', 'd'], ['a', 'e']]
    >>> len(class_folds(y, 9, seed=0))  # five classes: five parts
    5
    """
    classes = np.unique(y)
    shuffled = np.random.default_rng(seed).permutation(classes)
    return [np.sort(shuffled[k::folds]) for k in range(folds) if shuffled[k::folds].size]


@dataclass(frozen=True)
class Learned:
    """What :func:`learn_rejection` learns inside the training rows: the threshold (from folds that keep every
    class), the inner AUROC and the scales (from the leave-classes-out rounds)."""

    threshold: float
    inner_auroc: float
    scales: Scales | None


def fit_scales(terms: np.ndarray, log_distances: np.ndarray, known: np.ndarray) -> Scales:
    """The :class:`Scales` from the rounds' raw terms ``u``, ``m`` and ``w`` (n, 3; or without ``w``, n, 2) and
    group ``log d_g`` (n, groups), over the ``known`` rows; ``n`` takes its place between ``m`` and ``w``.

    Parameters
    ----------
    terms : numpy.ndarray
        (n, 3) raw ``u``, ``m`` and ``w`` of the rounds' test rows, or (n, 2) without ``w``.
    log_distances : numpy.ndarray
        (n, groups) their ``log d_g``; NaN where a row has no value in a group.
    known : numpy.ndarray
        (n,) booleans: rows of a class their round's model knew.

    Returns
    -------
    Scales
        Means and (sample) standard deviations over the known rows; a spread of 0 or NaN becomes 1.

    Examples
    --------
    Three known rows with ``log d`` 0, 1, 2 (mean 1, standard deviation 1: ``z`` = -1, 0, 1, their 0.98
    quantile 0.96) and a constant ``m`` (its spread of 0 taken as 1); the unknown fourth row counts for
    nothing:

    >>> import numpy as np
    >>> terms = np.array([[0.0, 1.0], [1.0, 1.0], [2.0, 1.0], [9.0, 9.0]])
    >>> scales = fit_scales(terms, np.array([[0.0], [1.0], [2.0], [9.0]]), np.array([True, True, True, False]))
    >>> scales.group_mean.tolist(), scales.group_sd.tolist(), np.round(scales.group_limit, 6).tolist()
    ([1.0], [1.0], [0.96])
    >>> scales.term_mean.tolist(), scales.term_sd.tolist()
    ([1.0, 1.0, 0.0], [1.0, 1.0, 1.0])
    """
    def mean_sd(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        with np.errstate(invalid="ignore"), warnings_ignored():
            mean, sd = np.nanmean(values, axis=0), np.nanstd(values, axis=0, ddof=1)
        return np.nan_to_num(mean), np.where(np.isfinite(sd) & (sd > 1e-12), sd, 1.0)

    group_mean, group_sd = mean_sd(log_distances[known])
    z = (log_distances - group_mean) / group_sd
    with warnings_ignored():
        limit = np.nanquantile(z[known], UNLIKE_QUANTILE, axis=0) if known.any() else np.zeros(z.shape[1])
    neighbour = _mean_present(z)
    term_mean, term_sd = mean_sd(with_neighbours(terms, neighbour)[known])
    return Scales(group_mean, group_sd, np.nan_to_num(limit, nan=np.inf), term_mean, term_sd)


def with_neighbours(terms: np.ndarray, neighbours: np.ndarray) -> np.ndarray:
    """The terms in :data:`TERMS` order: ``n`` put between ``m`` and ``w`` of the rounds' ``(u, m[, w])``.

    Parameters
    ----------
    terms : numpy.ndarray
        (n, 2) or (n, 3) raw ``u``, ``m`` and, where the rule has it, ``w``.
    neighbours : numpy.ndarray
        (n,) the neighbour term ``n``.

    Returns
    -------
    numpy.ndarray
        (n, 3) or (n, 4): ``(u, m, n[, w])``.

    Examples
    --------
    >>> import numpy as np
    >>> with_neighbours(np.array([[1.0, 2.0, 4.0]]), np.array([3.0])).tolist()
    [[1.0, 2.0, 3.0, 4.0]]
    """
    return np.column_stack([terms[:, :2], neighbours, terms[:, 2:]])


@contextmanager
def warnings_ignored() -> Iterator[None]:
    """Quiet numpy's warnings of a mean or quantile over an all-NaN column (a group no row had).

    Yields
    ------
    None
        Inside the ``with`` block RuntimeWarnings are ignored; after it, the filters are as before.

    Examples
    --------
    >>> import warnings
    >>> import numpy as np
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     with warnings_ignored():
    ...         quiet = np.nanmean(np.array([np.nan, np.nan]))
    ...     loud = np.nanmean(np.array([np.nan]))
    >>> float(quiet), float(loud), [str(w.message) for w in caught]
    (nan, nan, ['Mean of empty slice'])
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def fit_models(pipeline: Pipeline, X: np.ndarray, y: np.ndarray, groups: np.ndarray,
               columns: Sequence[str], seed: int = 0) -> tuple[Distance, Neighbours, RandomForestClassifier | None]:
    """The distance and neighbour models and the forest over every feature of a fitted ``pipeline``'s training
    rows (input ``columns``).

    Parameters
    ----------
    pipeline : Pipeline
        A ``scale -> select -> classify`` pipeline fitted on ``X``.
    X : numpy.ndarray
        (n, columns) its training rows.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample.
    columns : sequence of str
        The input column names.
    seed : int
        The random state of the forest over every feature.

    Returns
    -------
    distance : Distance
        In the pipeline's feature space (:func:`fit_distance`).
    neighbours : Neighbours
        On the input columns (:func:`fit_neighbours`).
    wide : RandomForestClassifier or None
        On the grouped input columns (:func:`fit_wide`).

    Examples
    --------
    Two samples of cork (0 and 0.2) and of oak (0.8 and 1), the classes' standard deviation 0.1 (``M_0 = 2``):

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
    >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
    >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
    >>> distance, neighbours, wide = fit_models(pipeline, X, y, groups, ["other.density"])
    >>> round(distance.scale, 4), neighbours.titles, neighbours.classes.tolist(), wide.classes_.tolist()
    (2.0, ('other',), [0, 0, 1, 1], ['cork', 'oak'])
    """
    neighbours = fit_neighbours(X, y, [str(c) for c in pipeline.classes_], columns)
    return fit_distance(pipeline[:-1].transform(X), y, groups), neighbours, fit_wide(X, y, neighbours, seed)


def fit_rule(pipeline: Pipeline, X: np.ndarray, y: np.ndarray, groups: np.ndarray, learned: Learned,
             columns: Sequence[str], max_accuracy_drop: float = MAX_ACCURACY_DROP, seed: int = 0) -> RejectionRule:
    """The rule of a fitted ``pipeline``: its distance and neighbour models and forest over every feature on
    its training rows (input ``columns``), and the threshold and scales that :func:`learn_rejection` learned.

    Parameters
    ----------
    pipeline : Pipeline
        A ``scale -> select -> classify`` pipeline fitted on ``X``.
    X : numpy.ndarray
        (n, columns) its training rows.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample.
    learned : Learned
        The threshold, inner AUROC and scales (:func:`learn_rejection`).
    columns : sequence of str
        The input column names.
    max_accuracy_drop : float
        The known-class accuracy the threshold was allowed to cost, as a fraction.
    seed : int
        The random state of the forest over every feature.

    Returns
    -------
    RejectionRule
        Without a neighbour model and forest where ``learned`` has no scales (format version 2's score).

    Examples
    --------
    Two samples of cork (0 and 0.2) and of oak (0.8 and 1), the classes' standard deviation 0.1 (``M_0 = 2``):

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> X, y = np.array([[0.0], [0.2], [0.8], [1.0]]), np.array(["cork", "cork", "oak", "oak"])
    >>> groups = np.array(["cork1", "cork2", "oak1", "oak2"])
    >>> pipeline = fit_pipeline(X, y, groups, "nb", n_features=None, calibrate=False)
    >>> rule = fit_rule(pipeline, X, y, groups, Learned(1.5, 0.9, None), ["other.density"])
    >>> rule.threshold, rule.inner_auroc, round(rule.distance_scale, 4), rule.neighbours is None
    (1.5, 0.9, 2.0, True)
    """
    distance, neighbours, wide = fit_models(pipeline, X, y, groups, columns, seed)
    scored = learned.scales is not None
    return RejectionRule(distance.means, distance.precision, distance.scale, learned.threshold, max_accuracy_drop,
                         learned.inner_auroc, neighbours if scored else None, learned.scales,
                         wide if scored else None)


def learn_rejection(X: np.ndarray, y: np.ndarray, groups: np.ndarray, fit: FitPipeline, columns: Sequence[str],
                    rounds: int = ROUNDS, seed: int = 0,
                    max_accuracy_drop: float = MAX_ACCURACY_DROP) -> Learned:
    """The threshold ``t``, the inner AUROC and the scales from rounds inside ``X, y`` (module docstring).

    A leave-classes-out round holds out one part of :func:`class_folds` as unknown and one grouped part of
    the other classes' rows as known: the scales and the inner AUROC come from these rounds. The threshold
    is read from the known rows' scores of :func:`known_scores`: grouped folds of every training class,
    whose models, like the final one, know every class. With fewer than three classes there is nothing to
    hold out and ``t`` is +inf (never reject).

    Parameters
    ----------
    X : numpy.ndarray
        (n, columns) the training rows.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample.
    fit : FitPipeline
        Fits a ``scale -> select -> classify`` pipeline on ``(X, y, groups)``.
    columns : sequence of str
        The input column names.
    rounds : int
        Leave-classes-out rounds and grouped folds.
    seed : int
        Seed of the class parts and the splits.
    max_accuracy_drop : float
        The known-class accuracy the rule may cost, as a fraction.

    Returns
    -------
    Learned

    Examples
    --------
    Four classes at the corners of a square 10 wide, two samples of each scanned twice, 0.2 of noise: a held-out class
    scores above every known row (inner AUROC 1). Two classes leave nothing to hold out:

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> rng = np.random.default_rng(0)
    >>> y = np.repeat(["a", "b", "c", "d"], 4)
    >>> X = np.repeat([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]], 4, axis=0) + rng.normal(0, 0.2, (16, 2))
    >>> groups = np.repeat([f"sample{k}" for k in range(8)], 2)  # two samples of each class, two scans each
    >>> fit = lambda X, y, g: fit_pipeline(X, y, g, "nb", n_features=None, calibrate=False)
    >>> learned = learn_rejection(X, y, groups, fit, ["other.density", "other.metal"], rounds=3)
    >>> learned.inner_auroc, bool(np.isfinite(learned.threshold)), learned.scales.term_mean.size
    (1.0, True, 4)
    >>> learn_rejection(X[:8], y[:8], groups[:8], fit, ["other.density", "other.metal"])
    Learned(threshold=inf, inner_auroc=nan, scales=None)
    """
    X, y, groups = np.asarray(X), np.asarray(y), np.asarray(groups)
    never = Learned(float("inf"), float("nan"), None)
    if np.unique(y).size < 3:
        return never
    terms, distances, unknowns, corrects = [], [], [], []
    for r, held_classes in enumerate(class_folds(y, rounds, seed)):
        is_held = np.isin(y, held_classes)
        known_rows = np.flatnonzero(~is_held)
        splits = grouped_splits(y[known_rows], groups[known_rows], rounds, seed + r)
        if not splits or np.unique(y[known_rows]).size < 2:
            continue
        train_part, test_part = splits[r % len(splits)]
        train, test_known = known_rows[train_part], known_rows[test_part]
        if np.unique(y[train]).size < 2:
            continue
        pipeline = fit(X[train], y[train], groups[train])
        test = np.concatenate([test_known, np.flatnonzero(is_held)])
        distance, neighbours, wide = fit_models(pipeline, X[train], y[train], groups[train], columns, seed)
        terms.append(score_terms(pipeline, X[test], distance, neighbours, None, wide)[:, [0, 1, 3]])
        distances.append(neighbours.log_distances(X[test]))
        # A held-out "known" row whose class lost its only sample to the held-out part is unknown to this model.
        unknowns.append(~np.isin(y[test], y[train]))
        corrects.append(pipeline.predict(X[test]) == y[test])
    if not terms:
        return never
    unknown, correct = np.concatenate(unknowns), np.concatenate(corrects)
    log_distances = np.concatenate(distances)
    scales = fit_scales(np.concatenate(terms), log_distances, ~unknown)
    score = scales.combine(with_neighbours(np.concatenate(terms), _mean_present(scales.group_z(log_distances))))
    known = known_scores(X, y, groups, fit, columns, scales, rounds, seed)
    threshold = choose_threshold(*known, max_accuracy_drop=max_accuracy_drop) if known is not None else \
        choose_threshold(score, unknown, correct, max_accuracy_drop)
    return Learned(threshold, auroc(score, unknown), scales)


def known_scores(X: np.ndarray, y: np.ndarray, groups: np.ndarray, fit: FitPipeline, columns: Sequence[str],
                 scales: Scales, rounds: int = ROUNDS,
                 seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Scores of every training row by a model of the other grouped folds, all classes kept: ``(score,
    unknown, correct)`` for :func:`choose_threshold` (``unknown`` marks a row whose class its model lacks:
    a class of a single sample). None where the rows cannot be split.

    The threshold is a quantile of the known rows' scores, and those depend on how many classes the model
    knows: a leave-classes-out round's model knows a fifth fewer and is surer of the rest, so its known rows
    score lower than the final model's. With five terrains (BorealTC) that put ``t`` so low that 10.4 % of
    the known windows were rejected against the 2 % budgeted; read from these folds, 3.9 % (docs/trust.md).

    Parameters
    ----------
    X : numpy.ndarray
        (n, columns) the training rows.
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample.
    fit : FitPipeline
        Fits a ``scale -> select -> classify`` pipeline on ``(X, y, groups)``.
    columns : sequence of str
        The input column names.
    scales : Scales
        The scales of the leave-classes-out rounds (:func:`fit_scales`).
    rounds : int
        Grouped folds (fewer where there are fewer samples).
    seed : int
        Seed of the splits.

    Returns
    -------
    tuple of numpy.ndarray or None
        ``(score, unknown, correct)``, rows in fold order.

    Examples
    --------
    Four classes at the corners of a square 10 wide, two samples of each scanned twice, 0.2 of noise: each fold keeps a
    sample of every class, and every row is classified right. A single sample cannot be split:

    >>> import numpy as np
    >>> from taxonomy.learning.evaluation import fit_pipeline
    >>> rng = np.random.default_rng(0)
    >>> y = np.repeat(["a", "b", "c", "d"], 4)
    >>> X = np.repeat([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]], 4, axis=0) + rng.normal(0, 0.2, (16, 2))
    >>> groups = np.repeat([f"sample{k}" for k in range(8)], 2)  # two samples of each class, two scans each
    >>> fit = lambda X, y, g: fit_pipeline(X, y, g, "nb", n_features=None, calibrate=False)
    >>> from taxonomy.learning.openset import Scales
    >>> scales = Scales(np.zeros(1), np.ones(1), np.zeros(1), np.zeros(3), np.ones(3))
    >>> score, unknown, correct = known_scores(X, y, groups, fit, ["other.density", "other.metal"], scales, rounds=3)
    >>> len(score), int(unknown.sum()), int(correct.sum())
    (16, 0, 16)
    >>> known_scores(X, y, np.full(16, "one"), fit, ["other.density", "other.metal"], scales) is None
    True
    """
    splits = grouped_splits(y, groups, rounds, seed)
    if not splits:
        return None
    scores, unknowns, corrects = [], [], []
    for train, test in splits:
        if np.unique(y[train]).size < 2:
            continue
        pipeline = fit(X[train], y[train], groups[train])
        distance, neighbours, wide = fit_models(pipeline, X[train], y[train], groups[train], columns, seed)
        scores.append(scales.combine(score_terms(pipeline, X[test], distance, neighbours, scales, wide)))
        unknowns.append(~np.isin(y[test], y[train]))
        corrects.append(pipeline.predict(X[test]) == y[test])
    if not scores:
        return None
    return np.concatenate(scores), np.concatenate(unknowns), np.concatenate(corrects)
