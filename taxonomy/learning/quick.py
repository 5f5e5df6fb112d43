"""The quick scan: a prediction after every step of the procedure, the most informative next step, and a stop
once the prediction is sure (docs/quick.md).

**One model for any subset of steps.** The columns are grouped by the steps they need
(:meth:`features.registry.ScanRegistry.column_steps`): the tool slide's 42 columns, the photos' 93, MATX's
tool slide *and* friction slide, ... Each such group is an *expert*: a random forest on its columns alone.
A scan with the steps ``S`` recorded is predicted by the experts whose steps are all in ``S``, combined as a
tempered product of experts (Hinton 2002, "Training products of experts by minimizing contrastive
divergence", Neural Computation 14(8); naive Bayes over the experts when the temperature is 1):

    log p(c | S) = log pi(c) + tau_m * sum over active experts E of [log q_E(c | x_E) - log pi(c)] + const

with ``pi`` the class frequencies of the training rows, ``q_E`` the expert's vote shares, mixed with ``pi``
and raised to its own power ``beta_E``, and ``tau_m`` one factor per number ``m`` of active experts. Both are
fitted by maximum likelihood on out-of-fold predictions of the training rows (temperature scaling, Guo et al.
2017): ``beta_E`` calibrates each expert on its own (a forest on two friction columns votes 0.4 for one of
32 materials and is right 12 % of the time: its beta is about 0.35; the photos' about 2.3), ``tau_m``
corrects for experts that see the same property (the two slides both feel roughness) and would otherwise
count it twice. Chosen over one model per
subset because the nine steps with features form 512 subsets, most of them with too few training
scans for their own selection and calibration, and because the product makes the next step's expected
information gain a closed-form sum over the training scans.

**The next step** maximises the expected information gain per second (Lindley 1956, "On a measure of the
information provided by an experiment", Ann. Math. Statist. 27(4)):

    EIG(s) = H(p) - sum_j w_j H(p'_j),   w_j = p(c_j | S) / n_{c_j}

where ``p'_j`` is the posterior after adding training scan ``j``'s out-of-fold expert ratios for the experts
step ``s`` completes: the outcomes of ``s`` are drawn from the training scans, each class weighted by its
current probability. Divided by the step's recording and handling time.

**Stopping**: the top class reaches ``stop_at`` (0.95) and the novelty of the recorded steps is within what
known materials show (:class:`Novelty`); or the operator stops; or the steps run out.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import log_softmax, softmax
from sklearn.ensemble import ExtraTreesClassifier
from sklearn.metrics.pairwise import euclidean_distances

from features.registry import REGISTRY
from features.space import FeatureSpace, drop_nan_columns
from scanner.runtime import executors
from taxonomy.learning.calibration import grouped_splits
from taxonomy.learning.evaluation import SEED, EvaluationError, cv_splits, fit_pipeline
from taxonomy.learning.openset import Neighbours, class_folds, fit_neighbours

MIXTURE = 0.05
"""Weight of the class frequencies mixed into an expert's vote shares, ``q = (1 - MIXTURE) votes + MIXTURE pi``:
a class no tree voted for keeps a small probability, so one expert cannot veto it against all the others."""

TREES = 100
"""Trees of each expert's forest."""

INNER_FOLDS = 4
"""Grouped splits of the training rows that give each training row's out-of-fold expert predictions."""

STOP_AT = 0.95
"""The calibrated probability of the top class at which a quick scan stops (with the novelty accepted)."""

KNOWN_QUANTILE = 0.9
"""The novelty of the recorded steps is accepted up to this quantile of the known training rows' novelty for
the same steps (:meth:`StepModel.accepts`): it holds back about a tenth of the scans of known materials at each
set of steps (they take another step), and halves the share of never-seen materials a quick scan names as
trained ones on the demo database (docs/quick.md#stopping-and-the-open-set)."""


@dataclass(frozen=True)
class Expert:
    """The columns measured by one set of steps."""

    steps: frozenset[str]
    columns: tuple[int, ...]

    @property
    def name(self) -> str:
        """The steps joined by ``+``, in name order."""
        return "+".join(sorted(self.steps))


def experts_of(columns: Sequence[str], needs: Mapping[str, frozenset[str]]) -> tuple[Expert, ...]:
    """The columns grouped by the steps they need, in order of first appearance; columns that need the whole
    scan (no steps declared) are left out.

    Parameters
    ----------
    columns : sequence of str
        The feature space's columns.
    needs : mapping of str to frozenset of str
        The steps each column needs (:meth:`~features.registry.ScanRegistry.column_steps`).

    Returns
    -------
    tuple of Expert

    Examples
    --------
    >>> experts_of(["a.x", "a.y", "b.z"], {"a.x": frozenset({"tap"}), "a.y": frozenset({"tap"}),
    ...                                    "b.z": frozenset()})
    (Expert(steps=frozenset({'tap'}), columns=(0, 1)),)
    """
    grouped: dict[frozenset[str], list[int]] = {}
    for index, column in enumerate(columns):
        steps = needs.get(column, frozenset())
        if steps:
            grouped.setdefault(frozenset(steps), []).append(index)
    return tuple(Expert(steps, tuple(indices)) for steps, indices in grouped.items())


def log_ratios(forest: ExtraTreesClassifier, X: np.ndarray, classes: np.ndarray,
               log_prior: np.ndarray) -> np.ndarray:
    """``log q(c | x) - log pi(c)`` of the forest's vote shares mixed with the class frequencies (:data:`MIXTURE`),
    rows x ``classes``; a class the forest never saw has only the mixture's share.

    Parameters
    ----------
    forest : ExtraTreesClassifier
        A fitted forest: an expert's, on the expert's columns.
    X : numpy.ndarray
        (rows, columns) values of the forest's columns.
    classes : numpy.ndarray
        Every class of the model, sorted; the forest may know only some of them.
    log_prior : numpy.ndarray
        ``log pi(c)`` of each of ``classes``.

    Returns
    -------
    numpy.ndarray
        (rows, classes) log ratios.

    Examples
    --------
    A forest that saw only ``a`` and ``b`` of three equally frequent classes, one row of each: every tree
    votes ``a`` for the first row, so ``q(a) = 0.95 + 0.05 / 3``, ``q(a) / pi(a) = 2.9``; ``b`` and the unseen
    ``c`` keep the mixture's share, ``q / pi = 0.05``.

    >>> import numpy as np
    >>> from sklearn.ensemble import ExtraTreesClassifier
    >>> forest = ExtraTreesClassifier(n_estimators=5, random_state=0).fit([[0.0], [1.0]], ["a", "b"])
    >>> ratios = log_ratios(forest, np.array([[0.0]]), np.array(["a", "b", "c"]), np.log(np.full(3, 1 / 3)))
    >>> np.round(np.exp(ratios), 6).tolist()
    [[2.9, 0.05, 0.05]]
    """
    votes = np.zeros((len(X), classes.size))
    votes[:, np.searchsorted(classes, forest.classes_)] = forest.predict_proba(X)
    prior = np.exp(log_prior)
    return np.log((1.0 - MIXTURE) * votes + MIXTURE * prior) - log_prior


def posterior(log_prior: np.ndarray, ratio_sum: np.ndarray, tau: float) -> np.ndarray:
    """``p(c | S)`` of the tempered product (module docstring) from the summed log ratios of the active experts
    (last axis: classes).

    Parameters
    ----------
    log_prior : numpy.ndarray
        ``log pi(c)`` per class.
    ratio_sum : numpy.ndarray
        The active experts' summed log ratios ``log q_E(c | x_E) - log pi(c)``, classes on the last axis: one
        scan's, or rows of them.
    tau : float
        The factor ``tau_m`` of the active experts.

    Returns
    -------
    numpy.ndarray
        The class probabilities, shaped as ``ratio_sum``, summing to 1 over the last axis.

    Examples
    --------
    One expert that says 0.9 for the first of two equally frequent classes: untempered its odds are 9;
    tempered by ``tau = 0.5``, ``9 ** 0.5 = 3``.

    >>> import numpy as np
    >>> log_prior, ratios = np.log([0.5, 0.5]), np.log(np.array([0.9, 0.1]) / 0.5)
    >>> [np.round(posterior(log_prior, ratios, tau), 6).tolist() for tau in (1.0, 0.5)]
    [[0.9, 0.1], [0.75, 0.25]]
    """
    return softmax(log_prior + tau * ratio_sum, axis=-1)


def entropy(p: np.ndarray) -> np.ndarray:
    """Shannon entropy in bits over the last axis.

    Parameters
    ----------
    p : numpy.ndarray
        Probabilities summing to 1 over the last axis; a zero adds nothing.

    Returns
    -------
    numpy.ndarray
        The entropy of each distribution: the leading shape of ``p`` (0-d for one distribution).

    Examples
    --------
    >>> import numpy as np
    >>> entropy(np.array([[0.5, 0.5, 0.0, 0.0], [0.25, 0.25, 0.25, 0.25]])).tolist()  # one coin, two coins
    [1.0, 2.0]
    >>> bool(entropy(np.array([1.0, 0.0])) == 0)  # a sure answer
    True
    """
    return -np.sum(np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0)), 0.0), axis=-1)


def fit_tau(ratio_sums: np.ndarray, true_index: np.ndarray, log_prior: np.ndarray) -> float:
    """The factor ``tau`` minimising the negative log likelihood of :func:`posterior` on held-out rows, searched
    over ``log tau`` in [-5, 2] (a single expert's ratios give its ``beta``); 1 without rows.

    Parameters
    ----------
    ratio_sums : numpy.ndarray
        (rows, classes) summed log ratios of the held-out rows.
    true_index : numpy.ndarray
        Each row's true class, as an index into the classes.
    log_prior : numpy.ndarray
        ``log pi(c)`` per class.

    Returns
    -------
    float
        The fitted factor, between ``exp(-5)`` and ``exp(2)``.

    Examples
    --------
    An expert that says 0.75 for the first of two equally frequent classes (odds 3) and is right 9 times in
    10 (odds 9) is too modest: ``3 ** tau = 9``, ``tau = 2``.

    >>> import numpy as np
    >>> sums = np.tile(np.log([1.5, 0.5]), (10, 1))
    >>> round(fit_tau(sums, np.array([0] * 9 + [1]), np.log([0.5, 0.5])), 3)
    2.0
    >>> fit_tau(np.zeros((0, 2)), np.zeros(0, dtype=int), np.log([0.5, 0.5]))
    1.0
    """
    if len(ratio_sums) == 0:
        return 1.0
    rows = np.arange(len(ratio_sums))

    def loss(log_tau: float) -> float:
        logp = log_softmax(log_prior + np.exp(log_tau) * ratio_sums, axis=1)
        return float(-np.mean(logp[rows, true_index]))

    return float(np.exp(minimize_scalar(loss, bounds=(-5.0, 2.0), method="bounded").x))


@dataclass(frozen=True)
class StepModel:
    """The quick scan's model (module docstring): experts, their forests, ``tau`` per number of active experts,
    and the training scans' out-of-fold log ratios the information gain draws outcomes from.

    ``beta`` is each expert's power; ``train_ratios`` (experts, training rows, classes) holds the calibrated
    ratios ``beta_E (log q_E - log pi)``; ``train_class`` each training row's class index.
    """

    experts: tuple[Expert, ...]
    forests: tuple[ExtraTreesClassifier, ...]
    classes: np.ndarray
    log_prior: np.ndarray
    beta: np.ndarray
    tau: np.ndarray
    train_ratios: np.ndarray
    train_class: np.ndarray
    calibrating: np.ndarray
    """Training rows whose out-of-fold ratios fit ``beta`` and ``tau``: those whose class is in their inner
    training part. As in :class:`~taxonomy.learning.calibration.TemperatureScaledClassifier`, a row of a class
    its inner training part lacks is left out: every expert is wrong about it, and with such rows in, the tool
    slide's ``beta`` (its expert is 95 % right on new samples of known materials) fell from about 3.5 to 0.8
    and almost no scan reached 0.95."""
    neighbours: Neighbours
    """The training rows' nearest-neighbour model, one group per expert (:func:`expert_neighbours`)."""
    novelty_scale: np.ndarray
    """Mean and standard deviation of each expert's ``log d`` over the calibrating rows' out-of-fold
    distances to the nearest scan of their own class (2 x experts)."""
    train_novelty: np.ndarray
    """The calibrating rows' standardised out-of-fold ``z_E`` to their own class (rows x experts)."""
    tau_sets: Mapping[bytes, float] = field(default_factory=dict)
    """``tau`` of the active sets the walks of the training rows meet often (:func:`calibrate_walks`), by
    :meth:`key`; other sets take ``tau[m]``."""

    @property
    def steps(self) -> frozenset[str]:
        """Every step some expert needs."""
        return frozenset().union(*(expert.steps for expert in self.experts))

    def active(self, recorded: frozenset[str] | set[str]) -> np.ndarray:
        """Which experts the recorded steps complete (boolean per expert).

        Parameters
        ----------
        recorded : set of str
            The steps recorded so far.

        Returns
        -------
        numpy.ndarray
            (experts,) booleans: whether every step of the expert is in ``recorded``.

        Examples
        --------
        An expert of the slide and one of the slide and the friction together:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> experts = (Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"slide", "friction"}), (1,)))
        >>> model = StepModel(experts, (), np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
        ...                   np.zeros((2, 2, 2)), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
        >>> model.active({"slide"}).tolist(), model.active({"slide", "friction", "photos"}).tolist()
        ([True, False], [True, True])
        """
        return np.array([expert.steps <= recorded for expert in self.experts])

    def ratios(self, X: np.ndarray) -> np.ndarray:
        """Every expert's calibrated log ratio ``beta_E (log q_E(c | x_E) - log pi(c))`` for the scans' rows ``X``
        (rows x experts x classes; one row ``x`` gives experts x classes).

        Parameters
        ----------
        X : numpy.ndarray
            (rows, columns) feature values in the columns the experts index, or one row.

        Returns
        -------
        numpy.ndarray
            (rows, experts, classes), or (experts, classes) for one row.

        Examples
        --------
        Forests of five trees: the slide's column tells cork from oak, the photos' column is the same for
        both. For a scan of cork every tree of the slide votes cork: ``q / pi = (0.95 + 0.025) / 0.5 = 1.95``
        for cork and ``0.025 / 0.5 = 0.05`` for oak, squared by the slide's ``beta = 2``; the photos' votes are
        even, ratio 1:

        >>> import numpy as np
        >>> from sklearn.ensemble import ExtraTreesClassifier
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> X, y = np.array([[0.0, 5.0], [1.0, 5.0]]), np.array(["cork", "oak"])
        >>> forests = tuple(ExtraTreesClassifier(n_estimators=5, random_state=0).fit(X[:, [j]], y) for j in (0, 1))
        >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), forests,
        ...                   np.unique(y), np.log([0.5, 0.5]), np.array([2.0, 1.0]), np.ones(3),
        ...                   np.zeros((2, 2, 2)), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.zeros((2, 2)), np.zeros((2, 2)))
        >>> np.round(np.exp(model.ratios(np.array([0.0, 5.0]))), 6).tolist()
        [[3.8025, 0.0025], [1.0, 1.0]]
        """
        X = np.asarray(X, dtype=np.float64)
        rows = X[None, :] if X.ndim == 1 else X
        out = np.stack([b * log_ratios(forest, rows[:, list(expert.columns)], self.classes, self.log_prior)
                        for expert, forest, b in zip(self.experts, self.forests, self.beta, strict=True)], axis=1)
        return out[0] if X.ndim == 1 else out

    def predict(self, ratios: np.ndarray, recorded: frozenset[str] | set[str]) -> np.ndarray:
        """``p(c | S)`` from a scan's expert ratios (:meth:`ratios`) and its recorded steps ``S``.

        Parameters
        ----------
        ratios : numpy.ndarray
            (experts, classes) the scan's calibrated log ratios.
        recorded : set of str
            The steps recorded so far.

        Returns
        -------
        numpy.ndarray
            (classes,) probabilities.

        Examples
        --------
        Two equally frequent classes, one training scan of each; the slide's expert gives each scan 0.9 for its
        own class, the photos' expert 0.7 (``tau = 1``). A scan the experts see as their training scan of
        cork: 0.9 from the slide alone, odds ``9 x 7 / 3 = 21`` from both:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
        >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
        ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
        ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
        >>> scan = np.stack([own(0.9)[0], own(0.7)[0]])
        >>> np.round(model.predict(scan, {"slide"}), 6).tolist()
        [0.9, 0.1]
        >>> np.round(model.predict(scan, {"slide", "photos"}), 6).tolist()  # 21 / 22, 1 / 22
        [0.954545, 0.045455]
        """
        active = self.active(recorded)
        return posterior(self.log_prior, ratios[active].sum(axis=0), self.tau_of(active))

    @staticmethod
    def key(active: np.ndarray) -> bytes:
        """An active set as a dictionary key.

        Parameters
        ----------
        active : numpy.ndarray
            Booleans, one per expert.

        Returns
        -------
        bytes
            The booleans packed into bits, eight experts a byte.

        Examples
        --------
        >>> import numpy as np
        >>> from taxonomy.learning.quick import StepModel
        >>> key = StepModel.key(np.array([True, False, True]))
        >>> key == StepModel.key(np.array([1, 0, 1], dtype=bool)), key.hex()  # bits 1010 0000
        (True, 'a0')
        """
        return np.packbits(active).tobytes()

    def tau_of(self, active: np.ndarray) -> float:
        """``tau`` of the active experts ``active``: fitted for the set itself, else for their number.

        Parameters
        ----------
        active : numpy.ndarray
            Booleans, one per expert (:meth:`active`).

        Returns
        -------
        float

        Examples
        --------
        A model whose ``tau`` is 0.5 for two active experts, and 0.8 fitted for the set of both:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
        >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
        ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.array([1.0, 1.0, 0.5]),
        ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
        >>> from dataclasses import replace
        >>> both = np.array([True, True])
        >>> model.tau_of(both), replace(model, tau_sets={model.key(both): 0.8}).tau_of(both)
        (0.5, 0.8)
        """
        fitted = self.tau_sets.get(self.key(active))
        return float(fitted if fitted is not None else self.tau[min(int(active.sum()), len(self.tau) - 1)])

    def novelty(self, X: np.ndarray) -> np.ndarray:
        """Every expert's ``z_E(c)`` for the scans' rows ``X`` and every class ``c`` (rows x experts x classes;
        one row gives experts x classes): the log distance, in the expert's standardised columns, to the
        nearest training scan of class ``c``, standardised as the known rows' distance to their own class.

        Parameters
        ----------
        X : numpy.ndarray
            (rows, columns) feature values, or one row; NaN where a value is missing.

        Returns
        -------
        numpy.ndarray
            (rows, experts, classes), or (experts, classes) for one row; NaN where the row has no value in
            the expert's columns.

        Examples
        --------
        Training scans of cork and oak at slide values 0 and 2 (standardised: -1 and 1), with the same
        photos' value 5. A scan at 1.5 (standardised 0.5) lies 1.5 from cork and 0.5 from oak; its photos'
        value 7, 2 from both. With the known rows' log distances at mean 0 and standard deviation 1, ``z`` is
        the log distance itself:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel, expert_neighbours
        >>> X, y = np.array([[0.0, 5.0], [2.0, 5.0]]), np.array(["cork", "oak"])
        >>> experts = (Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,)))
        >>> model = StepModel(experts, (), np.unique(y), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
        ...                   np.zeros((2, 2, 2)), np.array([0, 1]), np.ones(2, dtype=bool),
        ...                   expert_neighbours(X, y, np.unique(y), experts), np.array([[0.0, 0.0], [1.0, 1.0]]),
        ...                   np.zeros((2, 2)))
        >>> np.round(np.exp(model.novelty(np.array([1.5, 7.0]))), 6).tolist()
        [[1.5, 0.5], [2.0, 2.0]]
        """
        X = np.asarray(X, dtype=np.float64)
        log_d = class_log_distances(self.neighbours, X[None, :] if X.ndim == 1 else X, self.classes.size)
        z = (log_d - self.novelty_scale[0][:, None]) / self.novelty_scale[1][:, None]
        return z[0] if X.ndim == 1 else z

    def accepts(self, novelty: np.ndarray, recorded: frozenset[str] | set[str], top: int) -> bool:
        """Whether the scan is as close to the class ``top`` it would be named as a new sample of a known
        material is to its own: the largest ``z_E(top)`` of the active experts within :data:`KNOWN_QUANTILE` of
        the known training rows' largest ``z_E`` (to their own class) over the same experts; nothing recorded
        is accepted. The largest, not the mean: one step that finds the sample unlike the named material (its
        tool slide between two trained ones') is not outvoted by steps that cannot tell (a plain photo).

        Parameters
        ----------
        novelty : numpy.ndarray
            (experts, classes) the scan's ``z_E(c)`` (:meth:`novelty`).
        recorded : set of str
            The steps recorded so far.
        top : int
            Index of the class the scan would be named as.

        Returns
        -------
        bool

        Examples
        --------
        Two known rows whose ``z`` are -1 and 1 in the slide's expert (their 0.9 quantile: 0.8), 0 and 2 at
        most in both experts (1.8). A scan 0.5 from cork by its slide is accepted as cork; by both, its
        photos' 3.0 is too far:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
        >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
        ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
        ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([[-1.0, 0.0], [1.0, 2.0]]))
        >>> novelty = np.array([[0.5, 4.0], [3.0, 4.0]])  # experts x classes
        >>> model.accepts(novelty, {"slide"}, 0), model.accepts(novelty, {"slide", "photos"}, 0)
        (True, False)
        >>> model.accepts(novelty, set(), 0)  # nothing recorded
        True
        """
        active = self.active(recorded)
        z = novelty[:, top]
        if not active.any() or not np.isfinite(z[active]).any():
            return True
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a row without any value in these experts
            known = np.nanmax(self.train_novelty[:, active], axis=1)
        known = known[np.isfinite(known)]
        limit = np.quantile(known, KNOWN_QUANTILE) if known.size else np.inf
        return bool(np.nanmax(z[active]) <= limit)

    def gains(self, ratios: np.ndarray, recorded: frozenset[str] | set[str]) -> dict[str, float]:
        """The expected information gain (bits) of every step not yet recorded that completes an expert
        (module docstring).

        Parameters
        ----------
        ratios : numpy.ndarray
            (experts, classes) the scan's calibrated log ratios (:meth:`ratios`).
        recorded : set of str
            The steps recorded so far.

        Returns
        -------
        dict of str to float
            Gain in bits by step, in step name order.

        Examples
        --------
        Two equally frequent classes, one training scan of each; the slide's expert gives each scan 0.9 for its
        own class, the photos' expert 0.7 (``tau = 1``). With nothing recorded, both classes at 0.5 (1 bit),
        the slide leaves 0.9 for one class, whichever it is, and promises ``1 - H(0.9) = 0.531`` bits; the
        photos ``1 - H(0.7) = 0.119``:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import Expert, StepModel
        >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
        >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
        ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
        ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
        ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
        >>> {step: round(gain, 6) for step, gain in model.gains(np.zeros((2, 2)), set()).items()}
        {'photos': 0.118709, 'slide': 0.531004}
        """
        recorded = frozenset(recorded)
        active = self.active(recorded)
        now = self.predict(ratios, recorded)
        summed = ratios[active].sum(axis=0)
        counts = np.bincount(self.train_class, minlength=self.classes.size)
        weights = now[self.train_class] / np.maximum(counts[self.train_class], 1)
        weights = weights / weights.sum()
        gains = {}
        for step in sorted(self.steps - recorded):
            completed = self.active(recorded | {step}) & ~active
            if not completed.any():
                continue
            tau = self.tau_of(active | completed)
            after = posterior(self.log_prior, summed + self.train_ratios[completed].sum(axis=0), tau)
            gains[step] = float(entropy(now) - weights @ entropy(after))
        return gains


def contrast(model: StepModel, ratios: np.ndarray, recorded: frozenset[str] | set[str], step: str
             ) -> tuple[int, int, float]:
    """Why ``step`` is worth recording now: the two most probable classes ``a``, ``b`` and the mean log-odds
    swing (nats) between them the step's newly completed experts gave the training scans of the two classes,
    ``mean_{j in a} d_j - mean_{j in b} d_j`` with ``d_j = sum_E (r_E^j(a) - r_E^j(b))``: large when the step
    tells ``a`` from ``b`` ("the tool slide separates granite from marble").

    Parameters
    ----------
    model : StepModel
        The quick scan's model.
    ratios : numpy.ndarray
        (experts, classes) the scan's calibrated log ratios (:meth:`StepModel.ratios`).
    recorded : set of str
        The steps recorded so far.
    step : str
        The step to explain.

    Returns
    -------
    a, b : int
        Indices (into ``model.classes``) of the most and the second most probable class now.
    swing : float
        The mean log-odds swing in nats; 0 where no training scan is of class ``a`` or of ``b``.

    Examples
    --------
    A swing of 2 log(9) = 4.39 nats: the expert gives each class's scans 0.9 for their own class. Here two
    equally frequent classes have one training scan each; the slide's expert gives each scan 0.9 for its own
    class, the photos' expert 0.7 (``tau = 1``). After the photos said cork, recording the slide would swing
    the training scans of cork and oak ``log 9`` apart each way:

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, StepModel
    >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
    >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
    ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
    ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
    ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
    >>> scan = np.stack([own(0.9)[0], own(0.7)[0]])
    >>> a, b, swing = contrast(model, scan, {"photos"}, "slide")
    >>> str(model.classes[a]), str(model.classes[b]), round(swing, 6)
    ('cork', 'oak', 4.394449)
    """
    recorded = frozenset(recorded)
    completed = model.active(recorded | {step}) & ~model.active(recorded)
    a, b = (int(k) for k in np.argsort(-model.predict(ratios, recorded), kind="stable")[:2])
    d = model.train_ratios[completed][:, :, a].sum(axis=0) - model.train_ratios[completed][:, :, b].sum(axis=0)
    of_a, of_b = model.train_class == a, model.train_class == b
    swing = float(d[of_a].mean() - d[of_b].mean()) if of_a.any() and of_b.any() else 0.0
    return a, b, swing


def fit_step_model(X: np.ndarray, y: np.ndarray, groups: np.ndarray, experts: Sequence[Expert],
                   seed: int = 0) -> StepModel:
    """Fit every expert's forest on all rows, the out-of-fold ratios of the rows on grouped inner splits, each
    expert's ``beta`` on its own out-of-fold ratios, and ``tau`` per number of active experts on the calibrated
    ratios for the active sets of random step orders.

    Parameters
    ----------
    X : numpy.ndarray
        (rows, columns) feature values, NaN where undefined (the forests route missing values).
    y : numpy.ndarray
        Each row's class.
    groups : numpy.ndarray
        Each row's sample: the inner splits keep a sample's scans together.
    experts : sequence of Expert
        From :func:`experts_of`.
    seed : int
        Seed of the forests, the inner splits and the random orders.

    Returns
    -------
    StepModel

    Raises
    ------
    EvaluationError
        No expert: no column names the steps it needs.

    Examples
    --------
    Two materials, four samples of each scanned twice: the slide's column tells them apart, the photos' is
    noise. The slide's expert is right on every held-out row, and its ``beta`` goes to the top of the search
    (``e ** 2 = 7.39``); the photos' is far below 1. (Ten trees per forest instead of :data:`TREES`: the
    example runs faster.)

    >>> import numpy as np
    >>> from unittest import mock
    >>> import taxonomy.learning.quick as quick
    >>> from taxonomy.learning.quick import Expert, fit_step_model
    >>> rng = np.random.default_rng(0)
    >>> y = np.repeat(["cork", "oak"], 8)
    >>> X = np.column_stack([np.repeat([0.0, 3.0], 8) + rng.normal(0, 0.1, 16), rng.normal(0, 1, 16)])
    >>> groups = np.repeat([f"sample{k}" for k in range(8)], 2)
    >>> experts = (Expert(frozenset({"tool_slide"}), (0,)), Expert(frozenset({"photos"}), (1,)))
    >>> with mock.patch.object(quick, "TREES", 10):
    ...     model = fit_step_model(X, y, groups, experts, seed=0)
    >>> model.classes.tolist(), float(model.beta[0].round(2)), bool(model.beta[1] < 0.5)
    (['cork', 'oak'], 7.39, True)
    >>> np.round(model.predict(model.ratios(np.array([3.0, 0.0])), {"tool_slide"}), 3).tolist()
    [0.0, 1.0]
    """
    if not experts:
        raise EvaluationError("no column names the steps it needs: a quick scan has nothing to go on")
    X, y = np.asarray(X, dtype=np.float64), np.asarray(y)
    classes, train_class = np.unique(y, return_inverse=True)
    log_prior = np.log(np.bincount(train_class) / len(y))
    forests = tuple(_forest(seed).fit(X[:, list(e.columns)], y) for e in experts)
    groups = np.asarray(groups)
    ratios = np.zeros((len(experts), len(y), classes.size))
    log_d = np.full((len(y), len(experts)), np.nan)
    calibrating = np.zeros(len(y), dtype=bool)
    for train, test in grouped_splits(y, groups, INNER_FOLDS, seed):
        for k, expert in enumerate(experts):
            inner = _forest(seed).fit(X[np.ix_(train, expert.columns)], y[train])
            ratios[k, test] = log_ratios(inner, X[np.ix_(test, expert.columns)], classes, log_prior)
        own = class_log_distances(expert_neighbours(X[train], y[train], classes, experts), X[test], classes.size)
        log_d[test] = own[np.arange(len(test)), :, train_class[test]]
        calibrating[test] = np.isin(y[test], y[train])
    if not calibrating.any():
        calibrating[:] = True
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an expert with no finite distance: scale 0, 1
        scale = np.nan_to_num(np.stack([np.nanmean(log_d[calibrating], axis=0),
                                        np.nanstd(log_d[calibrating], axis=0)]), nan=0.0)
    scale[1] = np.where(scale[1] > 1e-12, scale[1], 1.0)
    novelty = (log_d[calibrating] - scale[0]) / scale[1]
    beta = np.array([fit_tau(ratios[k, calibrating], train_class[calibrating], log_prior)
                     for k in range(len(experts))])
    ratios *= beta[:, None, None]
    tau = _fit_taus(ratios[:, calibrating], train_class[calibrating], log_prior, experts,
                    np.random.default_rng(seed))
    return StepModel(tuple(experts), forests, classes, log_prior, beta, tau, ratios, train_class, calibrating,
                     expert_neighbours(X, y, classes, experts), scale, novelty)


def class_log_distances(neighbours: Neighbours, X: np.ndarray, classes: int) -> np.ndarray:
    """``log d_E(c)`` of every row of ``X`` (rows x experts x classes): the Euclidean distance, in the expert's
    standardised columns, to the nearest reference row of class ``c``; NaN where the row has no finite value
    in them or the class no reference row.

    Unlike the full scan's neighbour term, the vectors are not scaled to unit length: an expert of two
    columns (the friction slide) would keep only their direction, and a material between two trained ones
    along it (twice the roughness of one, half of the other) would be at distance 0 from both; ``z_E``
    standardises each expert's distances instead.

    Parameters
    ----------
    neighbours : Neighbours
        The training rows' model, one group per expert (:func:`expert_neighbours`).
    X : numpy.ndarray
        (rows, columns) feature values; NaN where a value is missing.
    classes : int
        The number of classes.

    Returns
    -------
    numpy.ndarray
        (rows, experts, classes) natural log distances.

    Examples
    --------
    Training scans of cork and oak at slide values 0 and 2 (standardised: -1 and 1), with the same photos'
    value 5 (spread 0, taken as 1). A scan at slide 1.5 (standardised 0.5) lies 1.5 from cork and 0.5 from
    oak, and at photos 7, 2 from both; a scan without photos has no distance there:

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, class_log_distances, expert_neighbours
    >>> X, y = np.array([[0.0, 5.0], [2.0, 5.0]]), np.array(["cork", "oak"])
    >>> experts = (Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,)))
    >>> neighbours = expert_neighbours(X, y, np.unique(y), experts)
    >>> np.round(np.exp(class_log_distances(neighbours, np.array([[1.5, 7.0], [1.5, np.nan]]), 2)), 6).tolist()
    [[[1.5, 0.5], [2.0, 2.0]], [[1.5, 0.5], [nan, nan]]]
    """
    Z, present = neighbours.standardise(X)
    out = np.full((len(X), len(neighbours.titles), classes), np.nan)
    for g in range(len(neighbours.titles)):
        columns = neighbours.group_of == g
        has = present[:, columns].any(axis=1)
        if not has.any() or not len(neighbours.reference):
            continue
        d = euclidean_distances(Z[has][:, columns], neighbours.reference[:, columns])
        for c in np.unique(neighbours.classes):
            out[has, g, c] = np.log(np.maximum(d[:, neighbours.classes == c].min(axis=1), 1e-12))
    return out


def expert_neighbours(X: np.ndarray, y: np.ndarray, classes: np.ndarray, experts: Sequence[Expert]) -> Neighbours:
    """The nearest-neighbour model of the rows ``X`` (:func:`~taxonomy.learning.openset.fit_neighbours`: the rows
    standardised, missing values at the median) with one group per expert (:func:`class_log_distances`).

    Parameters
    ----------
    X : numpy.ndarray
        (rows, columns) feature values of the training rows; NaN where a value is missing.
    y : numpy.ndarray
        Each row's class.
    classes : numpy.ndarray
        The model's classes, sorted.
    experts : sequence of Expert
        The experts; a column of none of them belongs to no group (-1).

    Returns
    -------
    Neighbours
        Group ``k`` is expert ``k``, titled by its name.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, expert_neighbours
    >>> X, y = np.array([[0.0, 5.0, 1.0], [2.0, np.nan, 1.0]]), np.array(["cork", "oak"])
    >>> experts = (Expert(frozenset({"tool_slide"}), (0,)), Expert(frozenset({"photos"}), (1,)))
    >>> neighbours = expert_neighbours(X, y, np.unique(y), experts)
    >>> neighbours.titles, neighbours.group_of.tolist(), neighbours.classes.tolist()
    (('tool_slide', 'photos'), [0, 1, -1], [0, 1])
    >>> neighbours.reference.tolist()  # standardised; the missing photo value at the median, 5
    [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    """
    group_of = np.full(X.shape[1], -1, dtype=np.int64)
    for k, expert in enumerate(experts):
        group_of[list(expert.columns)] = k
    fitted = fit_neighbours(X, y, classes, [f"c{j}" for j in range(X.shape[1])])
    return replace(fitted, titles=tuple(e.name for e in experts), group_of=group_of)



def _forest(seed: int) -> ExtraTreesClassifier:
    return ExtraTreesClassifier(n_estimators=TREES, random_state=seed, n_jobs=1)


def _fit_taus(ratios: np.ndarray, true_index: np.ndarray, log_prior: np.ndarray, experts: Sequence[Expert],
              rng: np.random.Generator, orders: int = 8) -> np.ndarray:
    """``tau[m]`` for m = 0..len(experts) active experts, from the active sets met along ``orders`` random step
    orders per row; a count never met takes the nearest fitted one's."""
    steps = sorted(frozenset().union(*(e.steps for e in experts)))
    sums: dict[int, list[np.ndarray]] = {}
    truth: dict[int, list[int]] = {}
    for row in range(ratios.shape[1]):
        for _ in range(orders):
            recorded: set[str] = set()
            for step in rng.permutation(steps):
                recorded.add(str(step))
                active = np.array([e.steps <= recorded for e in experts])
                m = int(active.sum())
                if m:
                    sums.setdefault(m, []).append(ratios[active, row].sum(axis=0))
                    truth.setdefault(m, []).append(int(true_index[row]))
    fitted = {m: fit_tau(np.array(sums[m]), np.array(truth[m]), log_prior) for m in sums}
    tau = np.ones(len(experts) + 1)
    for m in range(1, len(tau)):
        tau[m] = fitted[m] if m in fitted else fitted[min(fitted, key=lambda k: abs(k - m))]
    return tau


@dataclass(frozen=True)
class Decision:
    """One step of a quick scan: the step recorded, the time spent so far, the prediction after it."""

    step: str
    seconds: float
    probabilities: np.ndarray
    recorded: frozenset[str]
    accepted: bool = True
    """Whether the novelty of the recorded steps is within what known materials show."""

    @property
    def top(self) -> int:
        """Index of the most probable class."""
        return int(np.argmax(self.probabilities))

    def decided(self, stop_at: float) -> bool:
        """Whether a quick scan stops here: the top class at ``stop_at`` or above, and the novelty accepted.

        Parameters
        ----------
        stop_at : float
            The probability of the top class at which a quick scan stops (:data:`STOP_AT`).

        Returns
        -------
        bool

        Examples
        --------
        >>> import numpy as np
        >>> from taxonomy.learning.quick import Decision
        >>> sure = Decision("tool_slide", 10.0, np.array([0.96, 0.04]), frozenset({"tool_slide"}))
        >>> sure.decided(0.95), sure.decided(0.99)
        (True, False)
        >>> unlike = Decision("tool_slide", 10.0, np.array([0.96, 0.04]), frozenset({"tool_slide"}), accepted=False)
        >>> unlike.decided(0.95)  # sure, but the novelty is not accepted
        False
        """
        return bool(self.probabilities.max() >= stop_at and self.accepted)


def next_step(model: StepModel, ratios: np.ndarray, recorded: frozenset[str], costs: Mapping[str, float],
              order: Sequence[str] | None = None) -> str | None:
    """The step to record next: with ``order`` (a fixed protocol), its first step not yet recorded; else the step
    of largest expected information gain per second of ``costs``, None when no step left completes an expert.

    The gain can be negative: a larger set of experts has a smaller ``tau``, so a step may promise a flatter
    posterior on average; the scan still goes on (with the least harmful step) until it is sure or the steps
    run out, as the full protocol would.

    Parameters
    ----------
    model : StepModel
        The quick scan's model.
    ratios : numpy.ndarray
        (experts, classes) the scan's calibrated log ratios (:meth:`StepModel.ratios`).
    recorded : frozenset of str
        The steps recorded so far.
    costs : mapping of str to float
        Seconds each step takes, recording and handling.
    order : sequence of str, optional
        A fixed protocol's steps in order; None for the adaptive order.

    Returns
    -------
    str or None

    Examples
    --------
    Two equally frequent classes, one training scan of each; the slide's expert gives each scan 0.9 for its
    own class, the photos' expert 0.7 (``tau = 1``). The slide promises 0.531 bits, the photos 0.119: at
    equal costs the slide comes first, at ten times the photos' cost the photos:

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, StepModel
    >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
    >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
    ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
    ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
    ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
    >>> nothing = np.zeros((2, 2))
    >>> next_step(model, nothing, frozenset(), {"slide": 1.0, "photos": 1.0})
    'slide'
    >>> next_step(model, nothing, frozenset(), {"slide": 10.0, "photos": 1.0})
    'photos'
    >>> next_step(model, nothing, frozenset({"photos"}), {}, order=["photos", "tu4", "slide"])  # a fixed order
    'tu4'
    >>> next_step(model, nothing, frozenset({"slide", "photos"}), {"slide": 1.0, "photos": 1.0}) is None
    True
    """
    if order is not None:
        return next((step for step in order if step not in recorded), None)
    rates = {step: gain / costs[step] for step, gain in model.gains(ratios, recorded).items()}
    return max(rates, key=lambda step: (rates[step], -costs[step])) if rates else None


def replay(model: StepModel, ratios: np.ndarray, costs: Mapping[str, float], stop_at: float = STOP_AT,
           order: Sequence[str] | None = None, novelty: np.ndarray | None = None) -> tuple[Decision, ...]:
    """A quick scan of a scan whose every step is recorded (its expert ``ratios``, and its ``novelty`` for the
    open-set check): the steps in the adaptive order (or ``order``) until the top class reaches ``stop_at``
    and the novelty is accepted, or no step is left.

    Parameters
    ----------
    model : StepModel
        The quick scan's model.
    ratios : numpy.ndarray
        (experts, classes) the scan's calibrated log ratios (:meth:`StepModel.ratios`).
    costs : mapping of str to float
        Seconds each step takes, recording and handling.
    stop_at : float
        The probability of the top class at which the scan stops.
    order : sequence of str, optional
        A fixed protocol's steps in order; None for the adaptive order.
    novelty : numpy.ndarray, optional
        (experts, classes) the scan's ``z_E(c)`` (:meth:`StepModel.novelty`); None accepts every step.

    Returns
    -------
    tuple of Decision
        One per step taken, in order; the last one decided unless the steps ran out.

    Examples
    --------
    Two equally frequent classes, one training scan of each; the slide's expert gives each scan 0.9 for its
    own class, the photos' expert 0.7 (``tau = 1``). A scan both see as their training scan of cork is at
    0.9 after the slide, at ``21 / 22`` after the photos too, where it stops (0.95):

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, StepModel
    >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
    >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
    ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
    ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
    ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
    >>> scan = np.stack([own(0.9)[0], own(0.7)[0]])
    >>> path = replay(model, scan, {"slide": 1.0, "photos": 1.0})
    >>> [(d.step, d.seconds, round(float(d.probabilities[0]), 6)) for d in path]
    [('slide', 1.0, 0.9), ('photos', 2.0, 0.954545)]
    >>> [d.step for d in replay(model, scan, {"slide": 1.0, "photos": 1.0}, stop_at=0.85)]
    ['slide']
    """
    recorded: frozenset[str] = frozenset()
    seconds = 0.0
    path = []
    while (step := next_step(model, ratios, recorded, costs, order)) is not None:
        recorded = recorded | {step}
        seconds += costs[step]
        probabilities = model.predict(ratios, recorded)
        accepted = True if novelty is None else model.accepts(novelty, recorded, int(np.argmax(probabilities)))
        decision = Decision(step, seconds, probabilities, recorded, accepted)
        path.append(decision)
        if decision.decided(stop_at):
            break
    return tuple(path)


WALK_ROWS = 20
"""Training rows an active set needs before :func:`calibrate_walks` fits its own ``tau``."""


def calibrate_walks(model: StepModel, costs: Mapping[str, float], orders: Sequence[Sequence[str] | None] = (None,),
                    min_rows: int = WALK_ROWS) -> StepModel:
    """The model with ``tau`` fitted for every active set that at least ``min_rows`` training rows meet when
    walked, with their out-of-fold ratios, in each of ``orders`` (None: the adaptive order) to the end.

    The count-based ``tau[m]`` is fitted over random orders, where weak experts (the static touch) count as
    much as strong ones (the photos) and drag it down; the sets a quick scan actually meets are few and each
    is met by most training rows, so each gets its own.

    Parameters
    ----------
    model : StepModel
        The model, its training rows' out-of-fold ratios included.
    costs : mapping of str to float
        Seconds each step takes, recording and handling.
    orders : sequence of (sequence of str or None)
        The orders to walk in: a fixed protocol's steps, or None for the adaptive order.
    min_rows : int
        Training rows an active set needs to get its own ``tau``.

    Returns
    -------
    StepModel
        ``model`` with ``tau_sets`` replaced.

    Examples
    --------
    One expert that says 0.75 for one class or the other (odds 3) and is right on 18 of its 20 training rows
    (odds 9): its set's ``tau`` is 2, as ``3 ** 2 = 9``:

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, StepModel, calibrate_walks
    >>> ratios = np.repeat(np.log([[1.5, 0.5], [0.5, 1.5]]), 10, axis=0)[None]  # 1 expert x 20 rows x 2 classes
    >>> truth = np.array([0] * 9 + [1] + [1] * 9 + [0])
    >>> model = StepModel((Expert(frozenset({"slide"}), (0,)),), (), np.array(["cork", "oak"]), np.log([0.5, 0.5]),
    ...                   np.ones(1), np.ones(2), ratios, truth, np.ones(20, dtype=bool), None,
    ...                   np.zeros((2, 1)), np.zeros((20, 1)))
    >>> calibrated = calibrate_walks(model, {"slide": 10.0})
    >>> model.tau_of(np.array([True])), round(calibrated.tau_of(np.array([True])), 3)
    (1.0, 2.0)
    >>> calibrate_walks(model, {"slide": 10.0}, min_rows=21).tau_sets  # too few rows: tau[m] stays
    {}
    """
    sets: dict[bytes, list[int]] = {}
    masks: dict[bytes, np.ndarray] = {}
    for row in np.flatnonzero(model.calibrating):
        ratios = model.train_ratios[:, row]
        for order in orders:
            seen = set()
            for decision in replay(model, ratios, costs, stop_at=np.inf, order=order):
                active = model.active(decision.recorded)
                key = model.key(active)
                if key not in seen:
                    seen.add(key)
                    masks[key] = active
                    sets.setdefault(key, []).append(row)
    fitted = {}
    for key, rows in sets.items():
        if len(rows) >= min_rows:
            sums = model.train_ratios[masks[key]][:, rows].sum(axis=0)
            fitted[key] = fit_tau(sums, model.train_class[rows], model.log_prior)
    return replace(model, tau_sets=fitted)


# -- measuring the quick scan on stored full scans -------------------------------------------------------


@dataclass(frozen=True)
class Walk:
    """One stored scan walked as a quick scan: the steps taken, the cumulative seconds after each, whether
    the top class after each step was right, and whether (and after how many steps) it stopped."""

    steps: tuple[str, ...]
    seconds: tuple[float, ...]
    correct: tuple[bool, ...]
    decided: bool


@dataclass(frozen=True)
class QuickResult:
    """:func:`evaluate_quick`'s figures: per order (``adaptive``, ``fixed``) every test scan's :class:`Walk`,
    each scan's full-scan prediction right or not, the full protocol's seconds and how the folds split."""

    walks: Mapping[str, tuple[Walk, ...]]
    full_correct: np.ndarray
    full_seconds: float
    full_steps: int
    stop_at: float
    splitting: str
    level: str = "fine"
    notes: tuple[str, ...] = ()

    def summary(self, order: str = "adaptive") -> dict[str, float]:
        """Median steps and seconds to a decision (the whole protocol for a scan that never stops), the share
        decided, the accuracy of the decided scans and of every scan (a scan that never stops is answered
        by the full scan), the mean time as a share of the full protocol, and the full scan's accuracy.

        Parameters
        ----------
        order : str
            ``adaptive`` or ``fixed``.

        Returns
        -------
        dict of str to float
            ``median_steps``, ``median_seconds``, ``decided``, ``accuracy_decided`` (NaN without a decided
            scan), ``accuracy``, ``time_share`` and ``full_accuracy``.

        Examples
        --------
        Three scans of a 190 s protocol of three steps: one decided, rightly, after the slide (10 s), one after
        the photos (70 s), one never (its full scan was wrong): the median scan took two steps and 70 s, the mean
        ``(10 + 70 + 190) / 3 = 90`` s, 47 % of the protocol's time:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import QuickResult, Walk
        >>> walks = (Walk(("slide",), (10.0,), (True,), True),
        ...          Walk(("slide", "photos"), (10.0, 70.0), (False, True), True),
        ...          Walk(("slide", "photos", "tu4"), (10.0, 70.0, 190.0), (False, False, True), False))
        >>> result = QuickResult({"adaptive": walks}, np.array([True, True, False]), 190.0, 3, 0.95, "2 grouped folds")
        >>> {name: round(value, 4) for name, value in result.summary().items()}  # doctest: +NORMALIZE_WHITESPACE
        {'median_steps': 2.0, 'median_seconds': 70.0, 'decided': 0.6667, 'accuracy_decided': 1.0,
         'accuracy': 0.6667, 'time_share': 0.4737, 'full_accuracy': 0.6667}
        """
        walks = self.walks[order]
        decided = np.array([w.decided for w in walks])
        taken = np.array([len(w.steps) if w.decided else self.full_steps for w in walks])
        seconds = np.array([w.seconds[-1] if w.decided else self.full_seconds for w in walks])
        right = np.array([w.correct[-1] for w in walks])
        answered = np.where(decided, right, self.full_correct)
        return {"median_steps": float(np.median(taken)), "median_seconds": float(np.median(seconds)),
                "decided": float(decided.mean()), "accuracy_decided": float(right[decided].mean())
                if decided.any() else float("nan"), "accuracy": float(answered.mean()),
                "time_share": float(seconds.mean() / self.full_seconds),
                "full_accuracy": float(np.mean(self.full_correct))}

    def unseen(self) -> dict[str, float] | None:
        """With held-out materials (``open_set``): the share of their scans a quick scan stopped on (each one a
        material named wrongly), the median steps to that stop, and how many scans were walked. None without.

        Returns
        -------
        dict of str to float or None
            ``decided``, ``median_steps`` (NaN where none stopped) and ``scans``.

        Examples
        --------
        Two scans of a material the model never saw: one was named (wrongly) after the slide, one never:

        >>> import numpy as np
        >>> from taxonomy.learning.quick import QuickResult, Walk
        >>> unseen = (Walk(("slide",), (10.0,), (False,), True),
        ...           Walk(("slide", "photos"), (10.0, 70.0), (False, False), False))
        >>> known = (Walk(("slide",), (10.0,), (True,), True),)
        >>> QuickResult({"adaptive": known, "unseen": unseen}, np.array([True]), 70.0, 2, 0.95, "").unseen()
        {'decided': 0.5, 'median_steps': 1.0, 'scans': 2.0}
        >>> QuickResult({"adaptive": known}, np.array([True]), 70.0, 2, 0.95, "").unseen() is None
        True
        """
        walks = self.walks.get("unseen")
        if not walks:
            return None
        decided = np.array([w.decided for w in walks])
        taken = np.array([len(w.steps) for w in walks if w.decided])
        return {"decided": float(decided.mean()), "median_steps": float(np.median(taken)) if taken.size
                else float("nan"), "scans": float(len(walks))}

    def by_steps(self, order: str = "adaptive") -> list[tuple[int, float, float, float, float]]:
        """Per number of steps k: the mean seconds of the scans still going at k, the share decided by k,
        the accuracy of those decided by k, and of every scan's top class after k steps (its last).

        Parameters
        ----------
        order : str
            ``adaptive`` or ``fixed``.

        Returns
        -------
        list of (int, float, float, float, float)
            ``(k, seconds, decided, accuracy of the decided, accuracy of all)`` for k = 1 to the longest walk.

        Examples
        --------
        Three scans of a 190 s protocol of three steps: one decided, rightly, after the slide (10 s), one after
        the photos (70 s), one never (its full scan was wrong):

        >>> import numpy as np
        >>> from taxonomy.learning.quick import QuickResult, Walk
        >>> walks = (Walk(("slide",), (10.0,), (True,), True),
        ...          Walk(("slide", "photos"), (10.0, 70.0), (False, True), True),
        ...          Walk(("slide", "photos", "tu4"), (10.0, 70.0, 190.0), (False, False, True), False))
        >>> result = QuickResult({"adaptive": walks}, np.array([True, True, False]), 190.0, 3, 0.95, "2 grouped folds")
        >>> [tuple(round(value, 4) for value in row) for row in result.by_steps()]
        [(1, 10.0, 0.3333, 1.0, 0.3333), (2, 70.0, 0.6667, 1.0, 0.6667), (3, 190.0, 0.6667, 1.0, 1.0)]
        """
        walks = self.walks[order]
        rows = []
        for k in range(1, max(len(w.steps) for w in walks) + 1):
            decided = np.array([w.decided and len(w.steps) <= k for w in walks])
            going = [w.seconds[k - 1] for w in walks if len(w.steps) >= k]
            current = np.array([w.correct[min(k, len(w.steps)) - 1] for w in walks])
            rows.append((k, float(np.mean(going)) if going else float("nan"), float(decided.mean()),
                         float(current[decided].mean()) if decided.any() else float("nan"), float(current.mean())))
        return rows

    def by_seconds(self, order: str = "adaptive", marks: Sequence[float] = (15, 30, 60, 120, 240)
                   ) -> list[tuple[float, float, float]]:
        """Per time mark (and the full protocol): the share decided by then and the accuracy of those.

        Parameters
        ----------
        order : str
            ``adaptive`` or ``fixed``.
        marks : sequence of float
            Seconds; those not shorter than the full protocol are left out.

        Returns
        -------
        list of (float, float, float)
            ``(seconds, decided, accuracy of the decided)``, NaN where none was decided.

        Examples
        --------
        Three scans of a 190 s protocol of three steps: one decided, rightly, after the slide (10 s), one after
        the photos (70 s), one never (its full scan was wrong):

        >>> import numpy as np
        >>> from taxonomy.learning.quick import QuickResult, Walk
        >>> walks = (Walk(("slide",), (10.0,), (True,), True),
        ...          Walk(("slide", "photos"), (10.0, 70.0), (False, True), True),
        ...          Walk(("slide", "photos", "tu4"), (10.0, 70.0, 190.0), (False, False, True), False))
        >>> result = QuickResult({"adaptive": walks}, np.array([True, True, False]), 190.0, 3, 0.95, "2 grouped folds")
        >>> [tuple(round(value, 4) for value in row) for row in result.by_seconds(marks=(5, 60, 300))]
        [(5.0, 0.0, nan), (60.0, 0.3333, 1.0), (190.0, 0.6667, 1.0)]
        """
        walks = self.walks[order]
        rows = []
        for mark in (*[m for m in marks if m < self.full_seconds], self.full_seconds):
            decided = np.array([w.decided and w.seconds[-1] <= mark for w in walks])
            right = np.array([w.correct[-1] for w in walks])
            rows.append((float(mark), float(decided.mean()), float(right[decided].mean()) if decided.any()
                         else float("nan")))
        return rows

    def line(self) -> str:
        """``quick: median N steps (S s) to a decision, accuracy A % of decided scans, full scan F %``.

        Returns
        -------
        str
            The adaptive order's figures (:meth:`summary`) in one line.

        Examples
        --------
        Three scans of a 190 s protocol of three steps: one decided, rightly, after the slide (10 s), one after
        the photos (70 s), one never (its full scan was wrong):

        >>> import numpy as np
        >>> from taxonomy.learning.quick import QuickResult, Walk
        >>> walks = (Walk(("slide",), (10.0,), (True,), True),
        ...          Walk(("slide", "photos"), (10.0, 70.0), (False, True), True),
        ...          Walk(("slide", "photos", "tu4"), (10.0, 70.0, 190.0), (False, False, True), False))
        >>> QuickResult({"adaptive": walks}, np.array([True, True, False]), 190.0, 3, 0.95, "2 grouped folds").line()
        'quick: median 2 steps (70 s) to a decision, accuracy 100.0 % of decided scans, full scan 66.7 %'
        """
        s = self.summary("adaptive")
        return (f"quick: median {s['median_steps']:g} steps ({s['median_seconds']:.0f} s) to a decision, accuracy "
                f"{100 * s['accuracy_decided']:.1f} % of decided scans, full scan {100 * s['full_accuracy']:.1f} %")


def walk(model: StepModel, ratios: np.ndarray, novelty: np.ndarray, truth: str, costs: Mapping[str, float],
         order: Sequence[str] | None, stop_at: float) -> Walk:
    """One stored scan walked as a quick scan (:func:`replay`) from its expert ``ratios`` and ``novelty``.

    Parameters
    ----------
    model : StepModel
        The quick scan's model.
    ratios : numpy.ndarray
        (experts, classes) the scan's calibrated log ratios (:meth:`StepModel.ratios`).
    novelty : numpy.ndarray
        (experts, classes) the scan's ``z_E(c)`` (:meth:`StepModel.novelty`).
    truth : str
        The scan's class.
    costs : mapping of str to float
        Seconds each step takes, recording and handling.
    order : sequence of str or None
        A fixed protocol's steps in order; None for the adaptive order.
    stop_at : float
        The probability of the top class at which the scan stops.

    Returns
    -------
    Walk

    Examples
    --------
    Two equally frequent classes, one training scan of each; the slide's expert gives each scan 0.9 for its
    own class, the photos' expert 0.7 (``tau = 1``). A scan of cork both see as their training scan of cork,
    as close to it as the known rows to their own class: named cork after each step, decided after the
    photos (``21 / 22 >= 0.95``):

    >>> import numpy as np
    >>> from taxonomy.learning.quick import Expert, StepModel
    >>> own = lambda p: np.log(np.array([[p, 1 - p], [1 - p, p]]) / 0.5)  # a training scan of each class
    >>> model = StepModel((Expert(frozenset({"slide"}), (0,)), Expert(frozenset({"photos"}), (1,))), (),
    ...                   np.array(["cork", "oak"]), np.log([0.5, 0.5]), np.ones(2), np.ones(3),
    ...                   np.stack([own(0.9), own(0.7)]), np.array([0, 1]), np.ones(2, dtype=bool), None,
    ...                   np.array([[0.0, 0.0], [1.0, 1.0]]), np.zeros((2, 2)))
    >>> scan = np.stack([own(0.9)[0], own(0.7)[0]])
    >>> walk(model, scan, np.zeros((2, 2)), "cork", {"slide": 1.0, "photos": 1.0}, None, 0.95)
    Walk(steps=('slide', 'photos'), seconds=(1.0, 2.0), correct=(True, True), decided=True)
    """
    path = replay(model, ratios, costs, stop_at, order, novelty)
    return Walk(tuple(d.step for d in path), tuple(d.seconds for d in path),
                tuple(bool(model.classes[d.top] == truth) for d in path),
                bool(path) and path[-1].decided(stop_at))


def evaluate_quick(space: FeatureSpace, costs: Mapping[str, float], order: Sequence[str], level: str = "fine",
                   folds: int = 5, seed: int = SEED, stop_at: float = STOP_AT, n_features: int = 10,
                   workers: int | None = None, open_set: bool = False) -> QuickResult:
    """Every full scan of ``space`` walked as a quick scan in held-out folds grouped by sample
    (:func:`~taxonomy.learning.evaluation.cv_splits`): a :class:`StepModel` fitted on each fold's training rows
    (and calibrated on their walks) walks each test scan in the adaptive order and in the fixed ``order``;
    the full-scan figure is the product's own model (scale, FQ selection of ``n_features``, random forest)
    on the same folds.

    Parameters
    ----------
    space : FeatureSpace
        Full scans with the paper's columns (each column's steps from
        :meth:`~features.registry.ScanRegistry.column_steps`).
    costs : mapping of str to float
        Seconds each step of ``order`` takes, recording and handling.
    order : sequence of str
        The fixed protocol's steps in order (the paper's).
    level, folds, seed, stop_at, n_features
        Classification level, folds, seed, the probability that stops a quick scan, the full model's features.
    workers : int, optional
        Processes of this machine the folds run in (default one per CPU), or the current runtime's cluster
        (:func:`scanner.runtime.current`).
    open_set : bool
        Also hold out a fifth of the materials per fold (:func:`~taxonomy.learning.openset.class_folds`, as
        ``evaluate --open-set``) and walk their scans on a model that never saw them: ``walks["unseen"]``, of
        which every decided scan is a material named wrongly.

    Returns
    -------
    QuickResult

    Raises
    ------
    EvaluationError
        A step of ``order`` without a time, or a step of the feature columns that ``order`` lacks.

    Examples
    --------
    Two materials, four samples of each scanned twice: the tool slide tells them apart, the photos cannot.
    The fixed protocol takes the photos first (70 s to a decision); the adaptive order goes to the slide
    (10 s). (Ten trees per expert instead of :data:`TREES`: the example runs faster.)

    >>> import numpy as np
    >>> from unittest import mock
    >>> import taxonomy.learning.quick as quick
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.quick import evaluate_quick
    >>> rng = np.random.default_rng(0)
    >>> X = np.column_stack([np.repeat([0.0, 3.0], 8) + rng.normal(0, 0.1, 16), rng.normal(0, 1, 16)])
    >>> samples = tuple(f"sample{k}" for k in range(8) for _ in range(2))
    >>> space = FeatureSpace(X, ("audio.tool.zcr", "image.disp.brightness"), tuple(f"scan{i}" for i in range(16)),
    ...                      ("C1S1M1P1X1",) * 8 + ("C2S1M1P1X1",) * 8, samples)
    >>> with mock.patch.object(quick, "TREES", 10):
    ...     result = evaluate_quick(space, {"tool_slide": 10.0, "photos": 60.0}, ("photos", "tool_slide"),
    ...                             "coarse", folds=2, workers=1)
    >>> result.line()
    'quick: median 1 steps (10 s) to a decision, accuracy 100.0 % of decided scans, full scan 100.0 %'
    >>> result.summary("fixed")["median_seconds"], result.splitting
    (70.0, '2 grouped folds')
    """
    missing = [step for step in order if step not in costs]
    if missing:
        raise EvaluationError(f"no time given for step {missing[0]!r}")
    level = space.check_level(level)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        y = space.y(level)
        groups = np.asarray(space.groups)
        experts = experts_of(space.columns, REGISTRY.column_steps(space.columns))
        strays = sorted(set().union(*(e.steps for e in experts)) - set(order))
        if strays:
            raise EvaluationError(f"step {strays[0]!r} of the feature columns is not in the protocol's order")
        full_space, _ = drop_nan_columns(space)
        splits, grouped = cv_splits(y, groups, folds, seed, grouping_labels=space.label_text)
        jobs = [_FoldJob(space.X, y, groups, experts, train, test, dict(costs), tuple(order), stop_at, seed,
                         full_space.X, full_space.columns, n_features) for train, test in splits]
        if open_set:
            jobs += _open_set_jobs(jobs, y, seed)
        walks: dict[str, list[tuple[int, Walk]]] = {"adaptive": [], "fixed": [], "unseen": []}
        full_correct = np.zeros(len(y), dtype=bool)
        tested = np.zeros(len(y), dtype=bool)
        folds_done = executors.current().map_unordered(_quick_fold, [(job,) for job in jobs], workers=workers,
                                                       name="texplorer-quick-fold")
        for k, (adaptive, fixed, right) in folds_done:
            test = jobs[k].test
            if jobs[k].unseen:
                walks["unseen"] += zip(test, adaptive, strict=True)
                continue
            walks["adaptive"] += zip(test, adaptive, strict=True)
            walks["fixed"] += zip(test, fixed, strict=True)
            full_correct[test] = right
            tested[test] = True
    return QuickResult({name: tuple(w for _, w in sorted(pairs, key=lambda p: p[0])) for name, pairs in walks.items()
                        if pairs or name != "unseen"},
                       full_correct[tested],
                       float(sum(costs[step] for step in order)), len(order), stop_at,
                       f"{len(splits)} {'grouped' if grouped else 'ungrouped'} folds", level,
                       tuple(sorted({str(w.message).splitlines()[0] for w in caught})))


def _open_set_jobs(closed: Sequence[_FoldJob], y: np.ndarray, seed: int) -> list[_FoldJob]:
    """Fold k trains on the rows outside its test part whose class is not in class part k, and walks every row
    of class part k (adaptive order only)."""
    parts = class_folds(y, len(closed), seed)
    jobs = []
    for k, job in enumerate(closed):
        held = np.isin(y, parts[k % len(parts)])
        keep = job.train[~held[job.train]]
        jobs.append(replace(job, train=keep, test=np.flatnonzero(held), unseen=True))
    return jobs


@dataclass(frozen=True)
class _FoldJob:
    X: np.ndarray
    y: np.ndarray
    groups: np.ndarray
    experts: tuple[Expert, ...]
    train: np.ndarray
    test: np.ndarray
    costs: dict[str, float]
    order: tuple[str, ...]
    stop_at: float
    seed: int
    full_X: np.ndarray
    full_columns: tuple[str, ...]
    n_features: int
    unseen: bool = False


def _quick_fold(job: _FoldJob) -> tuple[list[Walk], list[Walk], np.ndarray]:
    """One fold of :func:`evaluate_quick`: the test rows' adaptive and fixed walks, and whether the full
    scan's model named them right (for held-out materials, the adaptive walks only)."""
    train, test, y = job.train, job.test, job.y
    model = fit_step_model(job.X[train], y[train], job.groups[train], job.experts, job.seed)
    model = calibrate_walks(model, job.costs, (None, job.order))
    ratios, novelty = model.ratios(job.X[test]), model.novelty(job.X[test])
    adaptive = [walk(model, ratios[k], novelty[k], y[i], job.costs, None, job.stop_at) for k, i in enumerate(test)]
    if job.unseen:
        return adaptive, [], np.zeros(0, dtype=bool)
    fixed = [walk(model, ratios[k], novelty[k], y[i], job.costs, job.order, job.stop_at) for k, i in enumerate(test)]
    pipeline = fit_pipeline(job.full_X[train], y[train], job.groups[train], "rf", job.n_features, job.seed,
                            calibrate=False, columns=job.full_columns)
    return adaptive, fixed, pipeline.predict(job.full_X[test]) == y[test]
