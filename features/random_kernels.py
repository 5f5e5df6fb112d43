"""MiniRocket and MultiRocket as a fitted step of the cross-validated pipeline.

The random-kernel transforms (MiniRocket: Dempster, Schmidt and Webb 2021; MultiRocket: Tan, Dempster,
Bergmeir and Webb 2022) are *fitted*: their dilations and biases come from quantiles of the convolution
outputs of training series. :class:`RandomKernels` is a scikit-learn transformer that reads the ``signal``
columns of a feature space (:mod:`features.modern`: every signal's instances by its length rule), fits one
sktime transform per signal on the training rows it is given, and outputs the columns it was not asked to
transform (the paper's features in a fusion) followed by the kernel features of every signal, each the mean
over the signal's instances. In the evaluation it is the first step of the pipeline, so it is fitted on the
training folds only, as the scaling and the FQ selection are (:mod:`taxonomy.learning.evaluation`).

The transforms are sktime's (``texplorer[modern]``): the step adds the wiring, not the arithmetic. sktime
rather than aeon: aeon 1.6 requires numba < 0.64, below the numba this project runs. Series are
transformed in chunks of :data:`CHUNK_INSTANCES` instances, so memory is bounded by the chunk, not by the
number of rows; a transform never holds more than a few copies of one instance's length per kernel
dilation (sktime's kernels run one series at a time).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted

from features.modern import EXTRA, FITTED_KINDS, GENERIC_RULE, ROLE_RULES, SCAN_SIGNALS, SIGNAL_PREFIX, LengthRule
from scanner.lazy import optional
from scanner.scan import is_generic
from taxonomy.errors import ParameterError

KINDS = FITTED_KINDS
"""The random-kernel transforms."""

CHUNK_INSTANCES = 256
"""Instances transformed at once: bounds the memory of a transform of many rows."""


def library(kind: str) -> type:
    """The sktime class of ``kind`` (``minirocket``, ``multirocket``); an error naming the extra if missing.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS`: ``"minirocket"`` or ``"multirocket"``.

    Returns
    -------
    type
        sktime's ``MiniRocket`` or ``MultiRocket`` transformer class (not an instance).

    Raises
    ------
    ParameterError
        If ``kind`` is not one of :data:`KINDS`, or sktime (``texplorer[modern]``) is not installed.

    Examples
    --------
    >>> library("minirocket").__name__, library("multirocket").__name__
    ('MiniRocket', 'MultiRocket')
    """
    if kind not in KINDS:
        raise ParameterError(f"unknown random-kernel transform {kind!r} (known: {', '.join(KINDS)})")
    # Imported on first use: sktime takes seconds to import and is an optional extra.
    rocket = optional("sktime.transformations.rocket", None, kind, install=f"pip install '{EXTRA}'",
                      error=ParameterError)
    return rocket.MiniRocket if kind == "minirocket" else rocket.MultiRocket


def signal_rule(name: str) -> LengthRule:
    """The length rule of the signal ``name``: a scan signal (``v_ts``) or an imported role (``audio``).

    Parameters
    ----------
    name : str
        A scan signal of :data:`features.modern.SCAN_SIGNALS`, a role of :data:`features.modern.ROLE_RULES`,
        or a generic channel ``signal_<channel>`` (:data:`features.modern.GENERIC_RULE`).

    Returns
    -------
    LengthRule
        How the signal is cut into instances: their length and number of windows.

    Raises
    ------
    ParameterError
        If ``name`` is none of these.

    Examples
    --------
    >>> signal_rule("v_ts").samples, signal_rule("audio").describe(), signal_rule("signal_z").describe()
    (3000, '8 windows of 2048 samples at 44100 Hz', '4 windows of 512 samples')
    """
    if name in SCAN_SIGNALS:
        return SCAN_SIGNALS[name].rule
    if name in ROLE_RULES:
        return ROLE_RULES[name].rule
    if is_generic(name):  # a generic channel, signal_<channel>
        return GENERIC_RULE
    raise ParameterError(f"no length rule for the signal {name!r}")


def signal_layout(columns: Sequence[str]) -> tuple[tuple[int, ...], tuple[tuple[str, int, LengthRule], ...]]:
    """The columns kept as they are, and every signal's ``(name, first column, rule)``.

    A signal's columns are ``signal.<name>.<k>``, consecutive, ``windows x length`` of them.

    Parameters
    ----------
    columns : sequence of str
        The column names of a feature space, in order.

    Returns
    -------
    keep : tuple of int
        The indices of the columns that are not signal samples, in order.
    signals : tuple of (str, int, LengthRule)
        Every signal's name, the index of its first column and its length rule, in column order.

    Raises
    ------
    ParameterError
        If a signal has no length rule, or its columns are not ``windows x length`` consecutive ones.

    Examples
    --------
    >>> from features.modern import signal_columns
    >>> columns = ("other.density", *signal_columns("signal.v_tt", signal_rule("v_tt")), "image.disp.color")
    >>> keep, signals = signal_layout(columns)
    >>> keep, [(name, first, rule.samples) for name, first, rule in signals]
    ((0, 1025), [('v_tt', 1, 1024)])
    """
    keep, signals, k = [], [], 0
    columns = list(columns)
    while k < len(columns):
        parts = columns[k].split(".")
        if parts[0] != SIGNAL_PREFIX:
            keep.append(k)
            k += 1
            continue
        rule = signal_rule(parts[1])
        block = columns[k:k + rule.samples]
        if len(block) != rule.samples or any(c.rsplit(".", 1)[0] != f"{SIGNAL_PREFIX}.{parts[1]}" for c in block):
            found = sum(c.rsplit(".", 1)[0] == f"{SIGNAL_PREFIX}.{parts[1]}" for c in columns)
            raise ParameterError(f"signal {parts[1]!r}: expected {rule.samples} consecutive columns "
                                 f"({rule.describe()}), found {found}")
        signals.append((parts[1], k, rule))
        k += rule.samples
    return tuple(keep), tuple(signals)


def signal_instances(X: np.ndarray, first: int, rule: LengthRule) -> np.ndarray:
    """The instances of one signal of every row, shape ``(rows x windows, 1, length)`` (sktime's panel).

    Parameters
    ----------
    X : numpy.ndarray
        (rows, columns) float values.
    first : int
        The index of the signal's first column (:func:`signal_layout`).
    rule : LengthRule
        The signal's length rule: ``rule.samples`` columns from ``first`` on, ``rule.windows`` instances of
        ``rule.length`` samples each.

    Returns
    -------
    numpy.ndarray
        ``(rows x windows, 1, length)``: the windows of row 0, then those of row 1, ..., a C-contiguous copy.

    Examples
    --------
    >>> from features.modern import GENERIC_RULE  # 4 windows of 512 samples
    >>> X = np.arange(2 * 2048.0).reshape(2, 2048)
    >>> panel = signal_instances(X, 0, GENERIC_RULE)
    >>> panel.shape, panel[:, 0, 0].tolist()  # the first sample of every window
    ((8, 1, 512), [0.0, 512.0, 1024.0, 1536.0, 2048.0, 2560.0, 3072.0, 3584.0])
    """
    block = X[:, first:first + rule.samples]
    return np.ascontiguousarray(block.reshape(-1, 1, rule.length))


class RandomKernels(TransformerMixin, BaseEstimator):
    """MiniRocket or MultiRocket on the ``signal`` columns of ``columns``; other columns pass through.

    Parameters
    ----------
    kind : str
        ``"minirocket"`` or ``"multirocket"``.
    columns : sequence of str
        The names of the columns of ``X``, in order (the signal columns are found by name).
    num_kernels : int or None
        Kernels per signal; None is the library's default (MiniRocket 10,000, MultiRocket 6,250).
    random_state : int
        Seed of the transform's random choices (the training series its biases are drawn from).

    Attributes
    ----------
    transforms_ : list
        The fitted sktime transform of every signal, in column order.
    widths_ : list of int
        The number of kernel features of every signal.
    """

    def __init__(self, kind: str = "minirocket", columns: Sequence[str] = (), num_kernels: int | None = None,
                 random_state: int = 0) -> None:
        self.kind = kind
        self.columns = columns
        self.num_kernels = num_kernels
        self.random_state = random_state

    def _layout(self) -> tuple[tuple[int, ...], tuple[tuple[str, int, LengthRule], ...]]:
        keep, signals = signal_layout(self.columns)
        if not signals:
            raise ParameterError(f"{self.kind} reads the signal columns (feature set 'signal'); none given")
        return keep, signals

    def fit(self, X: Any, y: Any = None) -> RandomKernels:
        """Fit one transform per signal on the instances of the rows of ``X``.

        Parameters
        ----------
        X : array-like
            (rows, len(columns)) float values, the columns named by ``columns``.
        y : array-like, optional
            Ignored: the transforms are unsupervised (scikit-learn's signature).

        Returns
        -------
        RandomKernels
            This transformer, fitted: :attr:`transforms_` and :attr:`widths_` are set.

        Raises
        ------
        ParameterError
            If ``X`` does not have one column per name, ``columns`` has no signal, ``kind`` is unknown or
            sktime is not installed.

        Examples
        --------
        >>> from features.modern import signal_columns
        >>> columns = ("other.density", *signal_columns("signal.v_tt", signal_rule("v_tt")))
        >>> X = np.hstack([np.arange(4.0)[:, None], np.random.default_rng(0).normal(size=(4, 1024))])
        >>> model = RandomKernels("minirocket", columns, num_kernels=84).fit(X)
        >>> model.widths_  # 84 kernel features of the one signal
        [84]
        """
        X = self._check(X)
        cls = library(self.kind)
        arguments = {"random_state": int(self.random_state)}
        if self.num_kernels is not None:
            arguments["num_kernels"] = int(self.num_kernels)
        keep, signals = self._layout()
        self.keep_ = keep
        self.signals_ = signals
        self.transforms_ = [cls(**arguments).fit(signal_instances(X, first, rule)) for _, first, rule in signals]
        self.widths_ = [np.asarray(t.transform(signal_instances(X[:1], first, rule)[:1])).shape[1]
                        for t, (_, first, rule) in zip(self.transforms_, signals, strict=True)]
        self.n_features_in_ = X.shape[1]
        return self

    def transform(self, X: Any) -> np.ndarray:
        """The kept columns, then every signal's kernel features averaged over its instances.

        Parameters
        ----------
        X : array-like
            (rows, len(columns)) float values, the columns named by ``columns``.

        Returns
        -------
        numpy.ndarray
            (rows, len(keep_) + sum(widths_)): the kept columns as they are, then the kernel features of
            every signal, each the mean over the row's instances of the signal.

        Raises
        ------
        ParameterError
            If ``X`` does not have one column per name.

        Examples
        --------
        >>> from features.modern import signal_columns
        >>> columns = ("other.density", *signal_columns("signal.v_tt", signal_rule("v_tt")))
        >>> X = np.hstack([np.arange(4.0)[:, None], np.random.default_rng(0).normal(size=(4, 1024))])
        >>> Z = RandomKernels("minirocket", columns, num_kernels=84).fit(X).transform(X)
        >>> Z.shape, Z[:, 0].tolist()  # the paper's column passes through
        ((4, 85), [0.0, 1.0, 2.0, 3.0])
        >>> bool(((Z[:, 1:] >= 0) & (Z[:, 1:] <= 1)).all())  # MiniRocket's features are shares (PPV)
        True
        """
        check_is_fitted(self, "transforms_")
        X = self._check(X)
        parts = [X[:, list(self.keep_)]]
        for transform, (_, first, rule) in zip(self.transforms_, self.signals_, strict=True):
            parts.append(_averaged(transform, X, first, rule))
        return np.hstack(parts)

    def get_feature_names_out(self, input_features: Any = None) -> np.ndarray:
        """The kept columns' names, then ``<kind>.<signal>.<k>`` for every kernel feature.

        Parameters
        ----------
        input_features : array-like of str, optional
            Ignored: the names come from ``columns`` (scikit-learn's signature).

        Returns
        -------
        numpy.ndarray
            The names of the columns of :meth:`transform`'s output, as an object array.

        Examples
        --------
        >>> from features.modern import signal_columns
        >>> columns = ("other.density", *signal_columns("signal.v_tt", signal_rule("v_tt")))
        >>> X = np.hstack([np.arange(4.0)[:, None], np.random.default_rng(0).normal(size=(4, 1024))])
        >>> names = RandomKernels("minirocket", columns, num_kernels=84).fit(X).get_feature_names_out()
        >>> len(names), names[:2].tolist(), names[-1]
        (85, ['other.density', 'minirocket.v_tt.00000'], 'minirocket.v_tt.00083')
        """
        check_is_fitted(self, "transforms_")
        names = [self.columns[k] for k in self.keep_]
        for width, (name, _, _) in zip(self.widths_, self.signals_, strict=True):
            names += [f"{self.kind}.{name}.{k:05d}" for k in range(width)]
        return np.asarray(names, dtype=object)

    def _check(self, X: Any) -> np.ndarray:
        X = np.asarray(X, dtype=np.float64)
        if X.ndim != 2 or X.shape[1] != len(self.columns):
            raise ParameterError(f"X has shape {X.shape}; expected {len(self.columns)} columns (one per name)")
        return X


def _averaged(transform: Any, X: np.ndarray, first: int, rule: LengthRule) -> np.ndarray:
    """The transform of every instance of one signal, in chunks of :data:`CHUNK_INSTANCES` instances,
    averaged over each row's instances."""
    rows_per_chunk = max(1, CHUNK_INSTANCES // rule.windows)
    out = []
    for start in range(0, X.shape[0], rows_per_chunk):
        panel = signal_instances(X[start:start + rows_per_chunk], first, rule)
        values = np.asarray(transform.transform(panel), dtype=np.float64)
        out.append(values.reshape(-1, rule.windows, values.shape[1]).mean(axis=1))
    return np.vstack(out) if out else np.empty((0, 0))
