"""Feature quality (FQ) and the FQ + Spearman selector (docs/evaluation.md; Strese et al. 2020, section V-A).

Feature quality, eq. (31): ``FQ = 100 % * (1 - mean p)``, where p are the p-values of all pairwise
comparisons of the classes' mean Kruskal-Wallis ranks, as MATLAB's ``multcompare`` computes them from
``kruskalwallis`` statistics with the Tukey-Kramer procedure. A feature whose classes do not overlap gets
small p-values and an FQ near 100 %; a feature that does not tell any two classes apart gets 0 %.

Selection (``FQSelector``): walk the features by decreasing FQ and accept one if its absolute Spearman rank
correlation with every feature accepted so far is below ``max_corr`` (0.5 in the paper), until ``n``
features are accepted (the paper's X3 and X10).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import scipy.stats
from scipy.interpolate import CubicHermiteSpline
from scipy.special import erfcinv
from sklearn.base import BaseEstimator
from sklearn.feature_selection import SelectorMixin
from sklearn.preprocessing import MinMaxScaler
from sklearn.utils.validation import check_is_fitted, validate_data

from features.feature_sets import column_parts
from features.random_kernels import RandomKernels
from taxonomy.errors import ParameterError

SF_TOLERANCE = 1e-9
"""Largest absolute error allowed for a studentized-range p-value taken from the interpolation table."""

_SF_NEGLIGIBLE = 1e-12
"""p-values below this are returned as 0 (far inside :data:`SF_TOLERANCE`)."""

_SF_FIRST_STEP = 0.01
"""First node spacing of the interpolation table; halved until the table meets the tolerance."""

_SF_REFINEMENTS = 4


# -- feature quality ---------------------------------------------------------------------------------


def feature_quality(X: Any, y: Any) -> np.ndarray:
    """Feature quality FQ in percent of every column of ``X`` for the classes ``y`` (paper eq. 31).

    Per column: Kruskal-Wallis ranks over all N rows (average ranks for ties), the mean rank R_i of each
    of the k classes present, and for every pair of classes (i, j) the Tukey-Kramer p-value of MATLAB's
    ``multcompare`` on ``kruskalwallis`` statistics::

        v    = N (N + 1) / 12 - sum(t^3 - t) / (12 (N - 1))        t = sizes of the groups of tied values
        se   = sqrt(v (1 / n_i + 1 / n_j))
        p_ij = min(1, P(Q_{k, inf} > sqrt(2) |R_i - R_j| / se))     Q = studentized range, infinite df

    and ``FQ = 100 (1 - mean p)`` over the k (k - 1) / 2 pairs.

    Parameters
    ----------
    X : array-like, shape (n_rows, n_features)
        Feature values; NaN marks an undefined value.
    y : array-like, shape (n_rows,)
        Class of every row (any hashable labels).

    Returns
    -------
    np.ndarray, shape (n_features,)
        FQ in percent, in [0, 100]. A column with any non-finite value, a constant column, and every
        column when fewer than two classes are present get 0.

    Notes
    -----
    All columns and all pairs are computed at once. The p-values come from
    ``scipy.stats.studentized_range.sf``; with many distinct statistics (a 920-row, 184-class space has
    millions) they are read from a cubic Hermite table of that function that is checked against it to
    :data:`SF_TOLERANCE` (see :func:`studentized_range_sf`).

    Examples
    --------
    Two classes that do not overlap, two rows each: ``dR = 2``, ``v = 5 / 3``, ``se = sqrt(5 / 3)`` and
    ``p = erfc(dR / se / sqrt(2))``, the two-sided normal p-value:

    >>> feature_quality([[1.0], [2.0], [3.0], [4.0]], ["a", "a", "b", "b"]).round(2)
    array([87.87])
    """
    X, codes, counts = _check_input(X, y)
    fq = np.zeros(X.shape[1])
    usable = usable_columns(X)
    if counts.size < 2 or not usable.any():
        return fq
    ranks, tie_sum = _tied_ranks(X[:, usable])
    n = X.shape[0]
    v = n * (n + 1) / 12 - tie_sum / (12 * (n - 1))
    mean_ranks = _class_means(ranks, codes, counts)
    fq[usable] = 100.0 * (1.0 - _pairwise_p(mean_ranks, counts, v).mean(axis=0))
    return fq


def usable_columns(X: np.ndarray) -> np.ndarray:
    """Mask of the columns FQ is defined for: every value finite and not all values equal.

    Parameters
    ----------
    X : np.ndarray, shape (n_rows, n_features)
        Feature values; NaN marks an undefined value.

    Returns
    -------
    np.ndarray of bool, shape (n_features,)
        True where the column is usable (with no rows, no column is).

    Examples
    --------
    A varying column, a constant one, one with a NaN, and one that varies again:

    >>> import numpy as np
    >>> usable_columns(np.array([[1.0, 5.0, np.nan, 0.0], [2.0, 5.0, 1.0, 3.0]])).tolist()
    [True, False, False, True]
    """
    finite = np.isfinite(X).all(axis=0)
    varying = np.zeros(X.shape[1], dtype=bool)
    if X.shape[0]:
        varying[finite] = (X[:, finite] != X[:1, finite]).any(axis=0)
    return finite & varying


def _check_input(X: Any, y: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``X`` as a float array, ``y`` as class codes 0..k-1, and the row count of each class."""
    try:
        X = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"X must be a numeric matrix ({exc})") from None
    if X.ndim != 2:
        raise ParameterError(f"X must be 2-D (rows x features), got shape {X.shape}")
    y = np.asarray(y)
    if y.ndim != 1 or y.shape[0] != X.shape[0]:
        raise ParameterError(f"y must hold one class per row of X: y has shape {y.shape}, "
                             f"X has {X.shape[0]} rows")
    _, codes, counts = np.unique(y, return_inverse=True, return_counts=True)
    return X, codes.ravel(), counts


def _tied_ranks(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Average ranks per column and the tie term ``sum(t^3 - t)`` of each column.

    A run of t tied values occupies ranks ``lo .. lo + t - 1``: its average rank is ``(lo + hi) / 2`` and
    each of its t members has ``t = hi - lo + 1``, so ``sum over members of (t^2 - 1)`` is ``t^3 - t``.
    """
    low = scipy.stats.rankdata(X, method="min", axis=0)
    high = scipy.stats.rankdata(X, method="max", axis=0)
    tie_size = high - low + 1
    return (low + high) / 2, (tie_size**2 - 1).sum(axis=0)


def _class_means(ranks: np.ndarray, codes: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Mean rank of every class in every column, shape (k, n_features)."""
    membership = np.zeros((counts.size, codes.size))
    membership[codes, np.arange(codes.size)] = 1.0
    return membership @ ranks / counts[:, None]


def _pairwise_p(mean_ranks: np.ndarray, counts: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Tukey-Kramer p-values of all class pairs (rows) in all columns (columns)."""
    k = counts.size
    i, j = np.triu_indices(k, 1)
    se = np.sqrt(np.outer(1.0 / counts[i] + 1.0 / counts[j], v))
    q = np.sqrt(2.0) * np.abs(mean_ranks[i] - mean_ranks[j]) / se
    return np.minimum(studentized_range_sf(q, k), 1.0)


# -- studentized range tail --------------------------------------------------------------------------


def studentized_range_sf(q: np.ndarray, k: int) -> np.ndarray:
    """``P(Q > q)`` for the studentized range of ``k`` groups with infinite degrees of freedom.

    Equal to ``scipy.stats.studentized_range.sf(q, k, inf)`` within :data:`SF_TOLERANCE` absolute.
    scipy integrates numerically (~50 us per value), so when there are more ``q`` than the table has nodes
    they are read from a cubic Hermite table of the sf and its derivative -pdf (built once per process and
    k, about three scipy values per node, see :func:`_sf_table`; cross-validation asks for the same k in
    every fold, so the table pays for itself over a few calls); otherwise scipy is called on the distinct
    values. The path depends on ``q`` and ``k`` only, never on earlier calls. Values with ``q`` beyond the
    Bonferroni cut
    ``P(Q > q) <= k (k - 1) / 2 * erfc(q / 2) <= 1e-12`` are 0.

    Parameters
    ----------
    q : np.ndarray
        Studentized range values (any shape), non-negative.
    k : int
        Number of groups, at least 2.

    Returns
    -------
    np.ndarray
        ``P(Q > q)`` of every value, in the shape of ``q``, in [0, 1].

    Examples
    --------
    The range of two standard normals is ``|Z1 - Z2|``, a normal of variance 2 folded at 0, so for ``k = 2``
    the tail is ``erfc(q / 2)``:

    >>> import math
    >>> import numpy as np
    >>> p = studentized_range_sf(np.array([0.0, 1.0, 2.0, 20.0]), 2)
    >>> p.round(6).tolist(), bool(abs(p[1] - math.erfc(0.5)) < 1e-9)
    ([1.0, 0.4795, 0.157299, 0.0], True)
    """
    q = np.asarray(q, dtype=np.float64)
    cut = _negligible_from(k)
    p = np.zeros(q.shape)
    inside = q < cut
    wanted = q[inside]
    table = _sf_table(k) if wanted.size > cut / _SF_FIRST_STEP else None
    if table is not None:
        p[inside] = table(wanted)
    elif wanted.size:
        values, inverse = np.unique(wanted, return_inverse=True)
        p[inside] = _exact_sf(values, k)[inverse.ravel()]
    return np.clip(p, 0.0, None)


def _negligible_from(k: int) -> float:
    """The q beyond which the Bonferroni bound puts P(Q > q) below :data:`_SF_NEGLIGIBLE`."""
    return float(2.0 * erfcinv(_SF_NEGLIGIBLE / (k * (k - 1) / 2)))


def _exact_sf(q: np.ndarray, k: int) -> np.ndarray:
    return scipy.stats.studentized_range.sf(q, k, np.inf)


@functools.lru_cache(maxsize=16)
def _sf_table(k: int) -> CubicHermiteSpline | None:
    """A cubic Hermite interpolant of the sf on [0, cut] meeting the tolerance, or None if none does.

    The spacing starts at :data:`_SF_FIRST_STEP` and is halved until the error at every interval midpoint
    (where the Hermite error bound ``(x - a)^2 (x - b)^2 max|f^(4)| / 24`` peaks) is below a tenth of
    :data:`SF_TOLERANCE`. Cross-validation asks for the same k in every fold, hence the cache.
    """
    step = _SF_FIRST_STEP
    top = _negligible_from(k)
    for _ in range(_SF_REFINEMENTS):
        nodes = np.arange(0.0, top + 2 * step, step)
        slopes = -scipy.stats.studentized_range.pdf(nodes, k, np.inf)
        table = CubicHermiteSpline(nodes, _exact_sf(nodes, k), slopes)
        midpoints = nodes[:-1] + step / 2
        if np.max(np.abs(table(midpoints) - _exact_sf(midpoints, k))) < SF_TOLERANCE / 10:
            return table
        step /= 2
    return None


# -- selection ---------------------------------------------------------------------------------------


def spearman_matrix(X: np.ndarray) -> np.ndarray:
    """|Spearman rho| is read from this (m, m) matrix of ``scipy.stats.spearmanr`` over the columns of X.

    Parameters
    ----------
    X : np.ndarray, shape (n_rows, m)
        Feature values, one column per feature.

    Returns
    -------
    np.ndarray, shape (m, m)
        Spearman's rho of every pair of columns (1 on the diagonal; NaN where a column is constant or has a
        NaN); all ones for fewer than two columns.

    Examples
    --------
    A column, its square (the same order), its reverse and a column whose order is unrelated to them:

    >>> import numpy as np
    >>> X = np.array([[1.0, 1.0, 4.0, 3.0], [2.0, 4.0, 3.0, 1.0], [3.0, 9.0, 2.0, 4.0], [4.0, 16.0, 1.0, 2.0]])
    >>> spearman_matrix(X).round(6).tolist()
    [[1.0, 1.0, -1.0, 0.0], [1.0, 1.0, -1.0, 0.0], [-1.0, -1.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    """
    m = X.shape[1]
    if m < 2:
        return np.ones((m, m))
    rho = scipy.stats.spearmanr(X).statistic
    if m == 2:
        return np.array([[1.0, rho], [rho, 1.0]])
    return np.asarray(rho, dtype=np.float64)


def accept_uncorrelated(order: Sequence[int], rho: np.ndarray, n_features: int, max_corr: float) -> list[int]:
    """Walk ``order`` and keep an index whose |rho| with every kept one is below ``max_corr``; stop at n.

    A NaN correlation rejects (``|nan| < max_corr`` is false).

    Parameters
    ----------
    order : sequence of int
        Column indices in the order to walk them (by decreasing FQ).
    rho : np.ndarray, shape (m, m)
        Spearman's rho between the columns (:func:`spearman_matrix`).
    n_features : int
        How many indices to keep at most.
    max_corr : float
        Critical |rho|: an index at or above it with a kept one is skipped.

    Returns
    -------
    list of int
        The kept indices in the order they were accepted.

    Examples
    --------
    Columns 0 and 1 are perfectly correlated, column 2 anti-correlated with both, column 3 with none:

    >>> import numpy as np
    >>> rho = np.array([[1.0, 1.0, -1.0, 0.0], [1.0, 1.0, -1.0, 0.0], [-1.0, -1.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    >>> accept_uncorrelated([1, 0, 2, 3], rho, n_features=3, max_corr=0.5)
    [1, 3]
    >>> accept_uncorrelated([1, 0, 2, 3], rho, n_features=1, max_corr=0.5)
    [1]
    """
    accepted: list[int] = []
    for j in order:
        if np.all(np.abs(rho[j, accepted]) < max_corr):
            accepted.append(int(j))
            if len(accepted) == n_features:
                break
    return accepted


FULL_SPEARMAN_MAX = 2000
"""Up to this many usable columns the selector reads |rho| from the whole Spearman matrix; above it (the
thousands of random-kernel features, :mod:`features.random_kernels`) it computes only the correlations of
each column it walks with those accepted (:func:`walk_uncorrelated`), not m x m of them."""


def walk_uncorrelated(X: np.ndarray, order: Sequence[int], n_features: int,
                      max_corr: float) -> tuple[list[int], np.ndarray]:
    """:func:`accept_uncorrelated` without the whole matrix: Spearman's rho is Pearson's correlation of the
    average ranks, so each column's centred, unit-norm ranks are made once and a walked column's rho with
    the accepted ones is one product with them. Returns the accepted indices and their rho matrix.

    Parameters
    ----------
    X : np.ndarray, shape (n_rows, m)
        Feature values of usable columns (finite, not constant).
    order : sequence of int
        Column indices in the order to walk them (by decreasing FQ).
    n_features : int
        How many columns to keep at most.
    max_corr : float
        Critical |rho|: a column at or above it with an accepted one is skipped.

    Returns
    -------
    accepted : list of int
        The kept columns in acceptance order, as :func:`accept_uncorrelated` keeps them.
    rho : np.ndarray, shape (len(accepted), len(accepted))
        Spearman's rho among the kept columns, in acceptance order.

    Examples
    --------
    The columns of :func:`spearman_matrix`'s example: the square and the reverse of the first column are
    rejected, the unrelated last one is kept:

    >>> import numpy as np
    >>> X = np.array([[1.0, 1.0, 4.0, 3.0], [2.0, 4.0, 3.0, 1.0], [3.0, 9.0, 2.0, 4.0], [4.0, 16.0, 1.0, 2.0]])
    >>> accepted, rho = walk_uncorrelated(X, [0, 1, 2, 3], n_features=3, max_corr=0.5)
    >>> accepted, bool(np.allclose(rho, np.eye(2), atol=1e-12))
    ([0, 3], True)
    >>> accepted == accept_uncorrelated([0, 1, 2, 3], spearman_matrix(X), 3, 0.5)
    True
    """
    ranks = scipy.stats.rankdata(X, axis=0)
    ranks -= ranks.mean(axis=0)
    ranks /= np.linalg.norm(ranks, axis=0)
    accepted: list[int] = []
    for j in order:
        if not accepted or np.all(np.abs(ranks[:, accepted].T @ ranks[:, j]) < max_corr):
            accepted.append(int(j))
            if len(accepted) == n_features:
                break
    kept = ranks[:, accepted]
    return accepted, kept.T @ kept


class FQSelector(SelectorMixin, BaseEstimator):
    """Keep the ``n_features`` best features by FQ that are not rank-correlated (paper section V-A5).

    Fitting computes :func:`feature_quality` on the training rows, sorts the usable columns (finite, not
    constant) by FQ descending with a stable sort (the lower column index first on equal FQ) and accepts a
    column if its absolute Spearman rho (``scipy.stats.spearmanr`` on the training rows) with every column
    accepted before is below ``max_corr``; a NaN rho rejects. It stops after ``n_features`` acceptances,
    or earlier when the usable columns run out, so it may select fewer. Columns with NaN on the training
    rows are never selected.

    Parameters
    ----------
    n_features : int, default 10
        How many features to keep (the paper's X3 and X10).
    max_corr : float, default 0.5
        Critical |Spearman rho|; a feature at or above it with an accepted one is rejected.

    Attributes
    ----------
    fq_ : np.ndarray, shape (n_features_in_,)
        FQ in percent of every input column on the training rows.
    selected_ : np.ndarray of int
        Indices of the kept columns in acceptance order (best FQ first). ``transform`` returns them in
        column order, as every scikit-learn selector does.
    rho_ : np.ndarray, shape (len(selected_), len(selected_))
        Spearman rho among the kept columns, in acceptance order.
    n_features_in_ : int
    feature_names_in_ : np.ndarray of str
        Only when fitted on a table with string column names.

    Examples
    --------
    >>> X = [[0.0, 5.0, 0.0], [1.0, 5.0, 2.0], [2.0, 5.0, 4.0], [3.0, 5.0, 6.0]]
    >>> FQSelector(n_features=2).fit(X, [0, 0, 1, 1]).selected_.tolist()
    [0]
    """

    def __init__(self, n_features: int = 10, max_corr: float = 0.5) -> None:
        self.n_features = n_features
        self.max_corr = max_corr

    def fit(self, X: Any, y: Any) -> FQSelector:
        """Rank the columns of ``X`` by FQ for the classes ``y`` and pick the uncorrelated best ones.

        Parameters
        ----------
        X : array-like, shape (n_rows, n_features)
            Training rows; NaN marks an undefined value (such a column is never selected).
        y : array-like, shape (n_rows,)
            Class of every row, at least two classes.

        Returns
        -------
        FQSelector
            This selector, fitted (:attr:`fq_`, :attr:`selected_`, :attr:`rho_`).

        Raises
        ------
        ParameterError
            If ``y`` has fewer than two classes, or ``n_features`` or ``max_corr`` is out of range.

        Examples
        --------
        Two classes that do not overlap in the first and last columns, which rank the rows alike; the middle
        column is constant:

        >>> import numpy as np
        >>> X = np.array([[0.0, 5.0, 0.0], [1.0, 5.0, 2.0], [2.0, 5.0, 4.0], [3.0, 5.0, 6.0]])
        >>> selector = FQSelector(n_features=2).fit(X, [0, 0, 1, 1])
        >>> selector.fq_.round(2).tolist(), selector.selected_.tolist(), selector.transform(X).ravel().tolist()
        ([87.87, 0.0, 87.87], [0], [0.0, 1.0, 2.0, 3.0])
        """
        self._check_params()
        X, y = validate_data(self, X, y, ensure_all_finite="allow-nan", dtype=np.float64)
        n_classes = np.unique(y).size
        if n_classes < 2:
            raise ParameterError(f"FQSelector needs at least two classes in y, got {n_classes} class")
        self.fq_ = feature_quality(X, y)
        candidates = np.flatnonzero(usable_columns(X))
        order = np.argsort(-self.fq_[candidates], kind="stable")
        if candidates.size > FULL_SPEARMAN_MAX:
            accepted, self.rho_ = walk_uncorrelated(X[:, candidates], order, self.n_features, self.max_corr)
        else:
            rho = spearman_matrix(X[:, candidates])
            accepted = accept_uncorrelated(order, rho, self.n_features, self.max_corr)
            self.rho_ = rho[np.ix_(accepted, accepted)]
        self.selected_ = candidates[accepted]
        return self

    def _check_params(self) -> None:
        n = self.n_features
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ParameterError(f"n_features must be a positive integer, got {n!r}")
        if isinstance(self.max_corr, bool) or not isinstance(self.max_corr, int | float | np.floating) \
                or not 0.0 < self.max_corr <= 1.0:
            raise ParameterError(f"max_corr must be a number in (0, 1], got {self.max_corr!r}")

    def _get_support_mask(self) -> np.ndarray:
        check_is_fitted(self, "selected_")
        mask = np.zeros(self.n_features_in_, dtype=bool)
        mask[self.selected_] = True
        return mask

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        tags.target_tags.required = True
        return tags


class PartwiseFQSelector(FQSelector):
    """:class:`FQSelector` within each part of the columns, keeping the union: how a fused feature set
    (``paper+catch22+scattering+minirocket``) is selected, so that no family crowds out another.

    A joint FQ ranking over tens of thousands of random-kernel columns and the paper's 193 keeps mostly the
    random-kernel ones whose FQ on the training rows is high by chance (the largest of many noisy estimates
    is biased upwards), and the fused set then did worse than the paper's features alone. Here each part
    keeps its own ``n_features`` best by FQ + Spearman, and the classifier sees all of them: up to
    ``n_features`` times the number of parts.

    Parameters
    ----------
    n_features : int, default 10
        Features kept per part.
    parts : tuple of int
        The part of each leading input column; the columns after them (a random-kernel step's output, which
        follows the columns it passes through) are one further part.
    max_corr : float, default 0.5
        As :class:`FQSelector`'s, within a part.

    Attributes
    ----------
    fq_ : np.ndarray, shape (n_features_in_,)
        FQ of every input column within its part's fit.
    selected_ : np.ndarray of int
        The kept columns, part after part, each part's in acceptance order.
    n_features_in_ : int
    """

    def __init__(self, n_features: int = 10, parts: tuple[int, ...] = (), max_corr: float = 0.5) -> None:
        super().__init__(n_features, max_corr)
        self.parts = parts

    def fit(self, X: Any, y: Any) -> PartwiseFQSelector:
        """Select within each part of the columns of ``X`` for the classes ``y`` (see the class).

        Parameters
        ----------
        X : array-like, shape (n_rows, n_features)
            Training rows; NaN marks an undefined value.
        y : array-like, shape (n_rows,)
            Class of every row, at least two classes.

        Returns
        -------
        PartwiseFQSelector
            This selector, fitted (:attr:`fq_`, :attr:`selected_`).

        Raises
        ------
        ParameterError
            If ``parts`` names more columns than ``X`` has, ``y`` has fewer than two classes, or
            ``n_features`` or ``max_corr`` is out of range.

        Examples
        --------
        Three columns that separate the classes equally well: the first two one part, the last one
        another. A joint selection of one feature keeps the first column only; each part keeps its own:

        >>> import numpy as np
        >>> X = np.array([[0.0, 0.0, 1.0], [1.0, 2.0, 0.0], [2.0, 4.0, 3.0], [3.0, 6.0, 2.0]])
        >>> FQSelector(n_features=1).fit(X, [0, 0, 1, 1]).selected_.tolist()
        [0]
        >>> PartwiseFQSelector(n_features=1, parts=(0, 0)).fit(X, [0, 0, 1, 1]).selected_.tolist()
        [0, 2]
        """
        self._check_params()
        X, y = validate_data(self, X, y, ensure_all_finite="allow-nan", dtype=np.float64)
        labels = np.asarray(self.parts, dtype=np.int64)
        if labels.size > X.shape[1]:
            raise ParameterError(f"{labels.size} column parts for {X.shape[1]} columns")
        labels = np.concatenate([labels, np.full(X.shape[1] - labels.size, labels.max(initial=-1) + 1)])
        self.fq_ = np.full(X.shape[1], np.nan)
        selected = []
        for part in dict.fromkeys(labels.tolist()):
            columns = np.flatnonzero(labels == part)
            within = FQSelector(self.n_features, self.max_corr).fit(X[:, columns], y)
            self.fq_[columns] = within.fq_
            selected.extend(columns[within.selected_].tolist())
        self.selected_ = np.asarray(selected, dtype=np.int64)
        return self


class KeepAll(SelectorMixin, BaseEstimator):
    """The selector's place in a pipeline when every feature is kept (the set size ``all``): no FQ, no
    Spearman filter. ``selected_`` lists every column, as :class:`FQSelector`'s does its choice."""

    def fit(self, X: Any, y: Any = None) -> KeepAll:
        """Keep every column of ``X`` (NaN allowed, as the other selectors).

        Parameters
        ----------
        X : array-like, shape (n_rows, n_features)
            Training rows.
        y : array-like, optional
            Ignored; there for the pipeline's call.

        Returns
        -------
        KeepAll
            This selector, fitted: :attr:`selected_` is every column index.

        Examples
        --------
        >>> import numpy as np
        >>> X = np.array([[1.0, np.nan, 5.0], [2.0, 3.0, 5.0]])
        >>> selector = KeepAll().fit(X)
        >>> selector.selected_.tolist(), selector.transform(X).shape
        ([0, 1, 2], (2, 3))
        """
        X = validate_data(self, X, ensure_all_finite="allow-nan", dtype=np.float64)
        self.selected_ = np.arange(X.shape[1])
        return self

    def _get_support_mask(self) -> np.ndarray:
        check_is_fitted(self, "selected_")
        return np.ones(self.n_features_in_, dtype=bool)

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags


# -- the selection of a whole feature space (``texplorer select``) --------------------------------------


class _LabelledSpace(Protocol):
    """What selection needs of ``features.space.FeatureSpace``."""

    X: np.ndarray
    columns: tuple[str, ...]

    def y(self, level: str = ...) -> np.ndarray: ...


@dataclass(frozen=True)
class Selection:
    """FQ of every column of a feature space and the features ``FQSelector`` keeps on all its rows.

    ``ranking`` lists (name, FQ %) by decreasing FQ; ``selected`` the kept names in acceptance order and
    ``rho`` their Spearman correlations.
    """

    level: str
    n_features: int
    max_corr: float
    ranking: tuple[tuple[str, float], ...]
    selected: tuple[str, ...]
    rho: np.ndarray

    def format(self, top: int = 20) -> str:
        """Text for a terminal: the ``top`` FQ ranking with the selected features marked, then rho.

        Parameters
        ----------
        top : int, default 20
            How many of the best features by FQ to list.

        Returns
        -------
        str
            A title line, one line per listed feature (rank, ``*`` if selected, name, FQ in percent), and a
            line naming the selected features in acceptance order.

        Examples
        --------
        >>> import numpy as np
        >>> selection = Selection("coarse", 2, 0.5, (("tactum.matx", 87.87), ("other.metal", 56.14),
        ...                                         ("other.density", 0.0)), ("tactum.matx", "other.metal"), np.eye(2))
        >>> print(selection.format(top=2))
        feature quality at level coarse (3 features, top 2):
           1 * tactum.matx   87.87 %
           2 * other.metal   56.14 %
        selected (|Spearman rho| < 0.5, n = 2): tactum.matx, other.metal
        """
        chosen = set(self.selected)
        width = max((len(name) for name, _ in self.ranking[:top]), default=4)
        lines = [f"feature quality at level {self.level} ({len(self.ranking)} features, top {top}):"]
        for rank, (name, fq) in enumerate(self.ranking[:top], start=1):
            mark = "*" if name in chosen else " "
            lines.append(f"{rank:4d} {mark} {name:<{width}}  {fq:6.2f} %")
        lines.append(f"selected (|Spearman rho| < {self.max_corr:g}, n = {self.n_features}): "
                     + ", ".join(self.selected))
        return "\n".join(lines)


def select_features(space: _LabelledSpace, level: str = "fine", n_features: int = 10,
                    max_corr: float = 0.5) -> Selection:
    """Fit :class:`FQSelector` on every row of ``space`` at classification ``level`` (coarse/medium/fine).

    This is the paper's exploratory view (Table IV): the selection a model trained on the whole space
    would use. Cross-validated scores must come from ``taxonomy.learning.evaluation.evaluate`` instead.

    Parameters
    ----------
    space : FeatureSpace
        The rows, columns and labels (anything with ``X``, ``columns`` and ``y(level)``).
    level : str, default "fine"
        The classification level whose classes FQ tells apart (:meth:`FeatureSpace.y`).
    n_features : int, default 10
        How many features to keep.
    max_corr : float, default 0.5
        Critical |Spearman rho| (:class:`FQSelector`).

    Returns
    -------
    Selection
        FQ of every column by decreasing FQ and the kept features with their correlations.

    Raises
    ------
    ParameterError
        If the space has fewer than two classes at ``level``, or ``n_features`` or ``max_corr`` is out of
        range.

    Examples
    --------
    Two coarse classes: ``tactum.matx`` separates them, ``other.metal`` in part, ``other.density`` is
    constant:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> X = np.array([[1.0, 5.0, 0.3], [2.0, 5.0, 0.1], [3.0, 5.0, 0.4], [4.0, 5.0, 0.2]])
    >>> space = FeatureSpace(X, ("tactum.matx", "other.density", "other.metal"), ("a", "b", "c", "d"),
    ...                      ("C1S1M1P1X1",) * 2 + ("C6S1M1P1X1",) * 2, ("w1", "w2", "g1", "g2"))
    >>> selection = select_features(space, "coarse", n_features=2)
    >>> [(name, round(fq, 2)) for name, fq in selection.ranking], selection.selected
    ([('tactum.matx', 87.87), ('other.metal', 56.14), ('other.density', 0.0)], ('tactum.matx', 'other.metal'))
    """
    y = space.y(level)
    selector = FQSelector(n_features=n_features, max_corr=max_corr).fit(space.X, y)
    order = np.argsort(-selector.fq_, kind="stable")
    ranking = tuple((space.columns[i], float(selector.fq_[i])) for i in order)
    selected = tuple(space.columns[i] for i in selector.selected_)
    return Selection(level, n_features, max_corr, ranking, selected, selector.rho_)


def feature_steps(columns: Sequence[str] = (), n_features: int | None = 10, kernels: str | None = None,
                  seed: int = 0) -> list[tuple[str, BaseEstimator]]:
    """The steps of a classifier's pipeline before the classifier, unfitted: a ``kernels`` transform where
    given (``minirocket``, ``multirocket``: :class:`features.random_kernels.RandomKernels` on the ``signal``
    columns of ``columns``, seeded with ``seed``; fitted on the training folds, as the scaling and the
    selection), min-max scaling, and the selection of ``n_features``: :class:`FQSelector`, or
    :class:`PartwiseFQSelector` (``n_features`` per family) where ``columns`` hold several families (a fused set:
    :func:`features.feature_sets.column_parts`), or :class:`KeepAll` for ``n_features`` None.

    Parameters
    ----------
    columns : sequence of str
        The names of the input columns.
    n_features : int or None
        Features the selector keeps; None keeps every one, unselected.
    kernels : str, optional
        ``minirocket`` or ``multirocket``: a random-kernel step first.
    seed : int
        Random state of the random kernels.

    Returns
    -------
    list of (str, estimator)
        ``[("kernels", ...)?, ("scale", MinMaxScaler), ("select", selector)]``.

    Examples
    --------
    >>> from features.selection import feature_steps
    >>> [(name, type(step).__name__) for name, step in feature_steps(("tactum.matx", "other.density"), 1)]
    [('scale', 'MinMaxScaler'), ('select', 'FQSelector')]
    >>> type(feature_steps(("tactum.matx", "catch22.v_tt.mode_5"), 1)[-1][1]).__name__
    'PartwiseFQSelector'
    >>> feature_steps(n_features=None)[-1][1]
    KeepAll()
    """
    parts = column_parts(columns, kernels is not None)
    if n_features is None:
        select: BaseEstimator = KeepAll()
    elif parts is None:
        select = FQSelector(n_features=n_features)
    else:
        select = PartwiseFQSelector(n_features=n_features, parts=parts)
    transform = [] if kernels is None else [("kernels", RandomKernels(kernels, tuple(columns), random_state=seed))]
    return [*transform, ("scale", MinMaxScaler()), ("select", select)]
