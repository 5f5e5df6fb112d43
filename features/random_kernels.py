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
from scanner.scan import is_generic
from taxonomy.errors import ParameterError

KINDS = FITTED_KINDS
"""The random-kernel transforms."""

CHUNK_INSTANCES = 256
"""Instances transformed at once: bounds the memory of a transform of many rows."""


def library(kind: str) -> type:
    """The sktime class of ``kind`` (``minirocket``, ``multirocket``); an error naming the extra if missing."""
    if kind not in KINDS:
        raise ParameterError(f"unknown random-kernel transform {kind!r} (known: {', '.join(KINDS)})")
    try:
        # Imported on first use: sktime takes seconds to import and is an optional extra.
        from sktime.transformations.rocket import MiniRocket, MultiRocket
    except ImportError:
        raise ParameterError(f"{kind} needs {EXTRA} (pip install '{EXTRA}')") from None
    return MiniRocket if kind == "minirocket" else MultiRocket


def signal_rule(name: str) -> LengthRule:
    """The length rule of the signal ``name``: a scan signal (``v_ts``) or an imported role (``audio``)."""
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
    """The instances of one signal of every row, shape ``(rows x windows, 1, length)`` (sktime's panel)."""
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
        """Fit one transform per signal on the instances of the rows of ``X``."""
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
        """The kept columns, then every signal's kernel features averaged over its instances."""
        check_is_fitted(self, "transforms_")
        X = self._check(X)
        parts = [X[:, list(self.keep_)]]
        for transform, (_, first, rule) in zip(self.transforms_, self.signals_, strict=True):
            parts.append(_averaged(transform, X, first, rule))
        return np.hstack(parts)

    def get_feature_names_out(self, input_features: Any = None) -> np.ndarray:
        """The kept columns' names, then ``<kind>.<signal>.<k>`` for every kernel feature."""
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
