"""Trained classification models: train on a whole feature space, store safely, predict a scan (docs/evaluation.md).

A model file is a skops archive (``skops.io``), a format that rebuilds objects from a declared schema and
never executes code on load. It holds one dict::

    format "texplorer-model", format_version 4, pipeline (MinMaxScaler -> FQSelector -> classifier),
    feature_names (input columns in order), level, classifier, n_features, selected (kept feature names,
    best FQ first), classes, seed, software_version, sklearn_version, dropped, n_rows,
    open_set (means, precision, distance_scale, threshold, max_accuracy_drop, inner_auroc, group_titles,
              group_of, fill, centre, spread, reference, reference_classes, group_mean, group_sd,
              group_limit, term_mean, term_sd, wide_forest)

The classifier is a :class:`~taxonomy.learning.calibration.TemperatureScaledClassifier`: its probabilities are
calibrated on grouped out-of-fold scores inside the training scans. ``open_set`` is the rejection rule
of :mod:`taxonomy.learning.openset`: the class means and shared precision matrix of the training scans in the
model's feature space, the distance scale ``M_0``, the standardised training scans of the neighbour term with
their feature groups, the balanced random forest over every feature, the scales of the four terms and the
threshold ``t`` learned by leave-classes-out inside the training scans; a scan scoring above ``t`` is an
unknown material. A version 3 file (before the forest over every feature) and a version 2 file (before the
neighbour term) load with their previous scores; a version 1 file (before calibration and the rule) as a
model that never rejects.

Loading first lists the file's types that skops does not trust by default and refuses the file unless
they are all in :data:`TRUSTED_TYPES`; then it checks that the dict has exactly this shape and that the
pipeline is made of the classes in :data:`MODEL_TYPES`. Anything else -- a foreign or tampered file, a
truncated archive, a file that is not skops at all, metadata that does not match the pipeline -- is
refused with a one-line :class:`ModelError` naming the file and the reason.
"""

from __future__ import annotations

import importlib
import importlib.util
import io
import math
import numbers
import os
import sys
import threading
import warnings
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import sklearn
import sklearn.utils
from sklearn.ensemble import RandomForestClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import LabelBinarizer, MinMaxScaler
from sklearn.tree import DecisionTreeClassifier
from sklearn.tree._tree import Tree

from features import feature_sets
from features.feature_sets import FeatureSet, learning_subset
from features.random_kernels import SIGNAL_PREFIX, RandomKernels
from features.selection import FQSelector, PartwiseFQSelector
from features.space import FeatureSpace
from scanner.storage.files import atomic_write_bytes, remove_stale_temp_files
from scanner.version import __version__
from taxonomy.errors import TexplorerError
from taxonomy.labels import LEVELS, check_level
from taxonomy.learning.calibration import TemperatureScaledClassifier
from taxonomy.learning.evaluation import (
    CLASSIFIERS,
    SEED,
    classifier_estimators,
    fit_pipeline,
)
from taxonomy.learning.openset import (
    MAX_ACCURACY_DROP,
    Explanation,
    Neighbours,
    RejectionRule,
    Scales,
    fit_rule,
    learn_rejection,
)
from taxonomy.table import Taxonomy

MODEL_FORMAT = "texplorer-model"
MODEL_FORMAT_VERSION = 4
READABLE_VERSIONS = (1, 2, 3, 4)
"""Version 1 files have no calibration and no rejection rule; they load as models that never reject. Version 2
files have the rule's first score (distance ratio and surprisal, without the neighbour term); version 3 files
the mean of three terms (without the forest over every feature)."""

TRUSTED_TYPES = (
    "features.modern.LengthRule",
    "features.random_kernels.RandomKernels",
    "features.selection.FQSelector",
    "features.selection.PartwiseFQSelector",
    "taxonomy.learning.calibration.TemperatureScaledClassifier",
    "sklearn.metrics._dist_metrics.EuclideanDistance64",
    "sklearn.neighbors._kd_tree.KDTree",
    "sklearn.neural_network._stochastic_optimizers.AdamOptimizer",
    "sklearn.tree._tree.Tree",
    "sktime.transformations.rocket._minirocket.MiniRocket",
    "sktime.transformations.rocket._multirocket.MultiRocket",
)
"""The types of our fitted pipelines that skops does not trust by default (it trusts builtins, numpy
arrays and scikit-learn estimators); a file with any other such type is refused before it is loaded."""

MODEL_TYPES = (MinMaxScaler, FQSelector, *(type(est) for est in classifier_estimators(SEED).values()))
"""The estimator classes a model's pipeline may consist of, step by step: scale, select, classify (the
classifier bare, in a version 1 file, or inside a :class:`TemperatureScaledClassifier`)."""
SELECTORS = (FQSelector, PartwiseFQSelector)
"""A model's select step: FQ + Spearman over every column, or family by family for a fused feature set."""
SKLEARN_PARTS = (Pipeline, MinMaxScaler, *MODEL_TYPES[2:], DecisionTreeClassifier, LabelBinarizer)
"""The scikit-learn estimators a model file holds: the pipeline, its scaler, the classifiers and what they fit
inside themselves (a forest's trees, a network's label binarizer). skops trusts these by default, in place of
every estimator of scikit-learn (:func:`_skops`)."""
_OPEN_SET_TYPES = {"means": np.ndarray, "precision": np.ndarray, "distance_scale": float, "threshold": float,
                   "max_accuracy_drop": float, "inner_auroc": float}
_NEIGHBOUR_TYPES = {"group_titles": list, "group_of": np.ndarray, "fill": np.ndarray, "centre": np.ndarray,
                    "spread": np.ndarray, "reference": np.ndarray, "reference_classes": np.ndarray,
                    "group_mean": np.ndarray, "group_sd": np.ndarray, "group_limit": np.ndarray,
                    "term_mean": np.ndarray, "term_sd": np.ndarray}
"""The open-set fields a version 3 file adds (:class:`taxonomy.learning.openset.Neighbours` and ``Scales``)."""
_WIDE_TYPES = {"wide_forest": (RandomForestClassifier, type(None))}
"""The open-set field a version 4 file adds: the forest over every feature (term ``w``), None for a model whose
inputs are all raw signal samples (no feature to grow it on)."""

_STEPS = ("scale", "select", "classify")
_META_TYPES: dict[str, type | tuple[type, ...]] = {
    "format": str, "format_version": int, "feature_names": list, "level": str, "classifier": str,
    "n_features": int, "selected": list, "classes": list, "seed": int, "software_version": str,
    "sklearn_version": str, "dropped": list, "n_rows": int,
}


MAX_MODEL_BYTES = 1 << 29
"""The most a model file's arrays may take once unpacked (512 MiB, every member of the archive counted, read
from the archive's directory before anything is unpacked): a small file cannot make loading take gigabytes."""
MAX_TREES = 10_000
"""The most trees a forest in a model file may have."""
MAX_TREE_NODES = 1 << 22
"""The most nodes one tree in a model file may have (4.2 million; the demo's trees have a few hundred)."""


class ModelError(TexplorerError, ValueError):
    """A model file that cannot be used, or feature values a model cannot classify; one line saying why."""


@dataclass(frozen=True, eq=False)
class TrainedModel:
    """A fitted pipeline with what is needed to use it on new scans.

    ``feature_names`` are the pipeline's input columns in order; ``selected`` the features its
    ``FQSelector`` kept (best FQ first); ``classes`` the labels it predicts at ``level``.
    """

    pipeline: Pipeline
    feature_names: tuple[str, ...]
    level: str
    classifier: str
    n_features: int
    selected: tuple[str, ...]
    classes: tuple[str, ...]
    seed: int
    software_version: str
    sklearn_version: str
    dropped: tuple[str, ...] = ()
    n_rows: int = 0
    rejection: RejectionRule | None = None

    def describe(self) -> str:
        """One line for people: classifier, level, classes, rows, the rejection rule and the features.

        Returns
        -------
        str
            The line, its parts separated by ``"; "``.

        Examples
        --------
        Two classes leave none to hold out, so the rule never rejects (its threshold is +inf):

        >>> import numpy as np
        >>> from features import FeatureSpace
        >>> from taxonomy.learning.models import train_model
        >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
        >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
        ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
        ...                      [f"sample{i // 2}" for i in range(8)])
        >>> model = train_model(space, n_features=1, classifier="nb")
        >>> for part in model.describe().replace(model.software_version, "X.Y").split("; "):
        ...     print(part)
        nb at level fine, 2 classes, trained on 8 scans, texplorer X.Y
        rejects a scan scoring above inf (leave-classes-out AUROC nan inside training)
        features: other.density
        >>> from dataclasses import replace
        >>> replace(model, rejection=None).describe().split("; ")[1]
        'no rejection rule (a version 1 model)'
        """
        rule = ("; no rejection rule (a version 1 model)" if self.rejection is None else
                f"; rejects a scan scoring above {self.rejection.threshold:.2f} (leave-classes-out AUROC "
                f"{self.rejection.inner_auroc:.2f} inside training)")
        return (f"{self.classifier} at level {self.level}, {len(self.classes)} classes, "
                f"trained on {self.n_rows} scans, texplorer {self.software_version}{rule}; "
                f"features: {', '.join(self.selected)}")


NO_PROBABILITIES = ("ridge",)
"""Classifiers without ``predict_proba``: evaluated, not trained into models (which rank classes by it)."""


def selected_names(pipeline: Pipeline, columns: Sequence[str]) -> tuple[str, ...]:
    """The names of the features the pipeline's selector kept: input columns, or the random-kernel step's
    outputs (``minirocket.v_ts.00042``) where the pipeline has one.

    Parameters
    ----------
    pipeline : sklearn.pipeline.Pipeline
        A fitted pipeline with a ``select`` step (and perhaps a ``kernels`` step).
    columns : sequence of str
        The pipeline's input columns in order.

    Returns
    -------
    tuple of str
        The kept features' names, in the selector's order (best FQ first).

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> from taxonomy.learning.models import selected_names
    >>> selected_names(model.pipeline, space.columns), selected_names(model.pipeline, ["density", "metal"])
    (('other.density',), ('density',))
    """
    if "kernels" in pipeline.named_steps:
        columns = list(pipeline.named_steps["kernels"].get_feature_names_out())
    return tuple(columns[i] for i in np.asarray(pipeline.named_steps["select"].selected_, dtype=np.int64)
                 if 0 <= i < len(columns))


def required_inputs(model: TrainedModel) -> tuple[str, ...]:
    """The inputs that must be finite to classify: the selected features, and with a random-kernel step
    every signal column (each signal is transformed whole).

    Parameters
    ----------
    model : TrainedModel
        A trained or loaded model.

    Returns
    -------
    tuple of str
        The names of the inputs :func:`predict_top` needs.

    Examples
    --------
    Of the two inputs of a model that selects one feature, only that one is needed:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> from taxonomy.learning.models import required_inputs
    >>> model.feature_names, required_inputs(model)
    (('other.density', 'other.metal'), ('other.density',))
    """
    if "kernels" not in model.pipeline.named_steps:
        return model.selected
    signals = tuple(n for n in model.feature_names if n.startswith(f"{SIGNAL_PREFIX}."))
    return tuple(n for n in model.selected if n in set(model.feature_names)) + signals


def train_model(space: FeatureSpace, level: str = "fine", n_features: int = 10, classifier: str = "rf",
                seed: int = SEED, feature_set: FeatureSet = None,
                max_accuracy_drop: float = MAX_ACCURACY_DROP) -> TrainedModel:
    """Fit ``scale -> select n_features -> calibrated classifier`` on every row of ``space`` at ``level``,
    and learn its rejection rule by leave-classes-out inside the same rows (:mod:`taxonomy.learning.openset`).

    The calibration's inner splits and the rule's rounds keep a sample's scans together (``space.groups``).
    Columns that hold NaN in any row are left out, as in :func:`taxonomy.learning.evaluation.evaluate`
    (listed in ``dropped``). Cross-validated scores of the same settings come from
    :func:`taxonomy.learning.evaluation.evaluate` and, for the rule, ``evaluate_open_set``.

    Parameters
    ----------
    space : features.FeatureSpace
        The training rows.
    level : str
        ``"coarse"``, ``"medium"`` or ``"fine"`` (or a level of the space's own labels).
    n_features : int
        Features the FQ + Spearman selector keeps.
    classifier : str
        ``"svm"``, ``"lda"``, ``"knn"``, ``"mlp"``, ``"rf"`` or ``"nb"``.
    seed : int
        Seed of the classifier.
    feature_set : None, str or list of str
        None / ``"all"``, a modality or column names.
    max_accuracy_drop : float
        The known classes' accuracy the rejection rule may cost, as a fraction (default: 0.02).

    Returns
    -------
    TrainedModel
        With the feature names, the fitted pipeline, the level and the software version; see
        :func:`save_model`.

    Raises
    ------
    ModelError
        An unknown classifier, or one without class probabilities (:data:`NO_PROBABILITIES`).
    FeatureSpaceError
        An unknown level, only NaN, or values that cannot be scaled or are constant
        (:func:`features.feature_sets.learning_subset`).

    Examples
    --------
    Two materials that ``other.density`` separates; ``other.metal`` is noise and is not selected:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> model.selected, model.classes, model.n_rows
    (('other.density',), ('C1S1M1P4X1', 'C6S1M1P2X1'), 8)
    >>> model.rejection.threshold  # two classes leave none to hold out: the rule never rejects
    inf
    """
    check_level(level)
    if classifier not in CLASSIFIERS:
        raise ModelError(f"unknown classifier {classifier!r} (known: {', '.join(CLASSIFIERS)})")
    if classifier in NO_PROBABILITIES:
        raise ModelError(f"{classifier} gives no class probabilities, which classify and the web application "
                         f"show; train one of {', '.join(c for c in CLASSIFIERS if c not in NO_PROBABILITIES)}")
    subset, dropped = learning_subset(space, level, feature_set)
    y = subset.y(level)
    kernels = feature_sets.kernels_of(feature_set) if feature_sets.is_named_set(feature_set) else None
    groups = np.asarray(subset.groups)
    pipeline = fit_pipeline(subset.X, y, groups, classifier, n_features, seed, calibrate=True,
                            materials=np.asarray(subset.label_text), kernels=kernels, columns=subset.columns)

    def fit(X: np.ndarray, y_fit: np.ndarray, g: np.ndarray) -> Pipeline:
        return fit_pipeline(X, y_fit, g, classifier, n_features, seed, calibrate=False, kernels=kernels,
                            columns=subset.columns)

    learned = learn_rejection(subset.X, y, groups, fit, subset.columns, seed=seed,
                              max_accuracy_drop=max_accuracy_drop)
    rule = fit_rule(pipeline, subset.X, y, groups, learned, subset.columns, max_accuracy_drop, seed)
    return TrainedModel(
        pipeline=pipeline, feature_names=subset.columns, level=level, classifier=classifier,
        n_features=n_features, selected=selected_names(pipeline, subset.columns),
        classes=tuple(str(c) for c in pipeline.classes_), seed=seed, software_version=__version__,
        sklearn_version=sklearn.__version__, dropped=dropped, n_rows=len(y), rejection=rule,
    )


# -- files -------------------------------------------------------------------------------------------

def _skops() -> ModuleType:
    """``skops.io``, imported when a model file is read or written (it takes a third of a second, which every
    command and page that never touches a model file would pay).

    skops lists the estimators it trusts by default when it is imported, by importing every module of
    scikit-learn (``sklearn.utils.all_estimators``: a second of CPU, more than the rest of ``classify``).
    The first import here hands it :data:`SKLEARN_PARTS` instead, the estimators a model file may hold; the
    check of a file's types (:func:`_loads`) is against the model's own lists either way. Threads wait for the
    import under one lock (the package is in ``sys.modules`` before it has run), then share the module.
    """
    if not _imported:
        with _import_lock:
            if not _imported:
                with _estimators(SKLEARN_PARTS):
                    _imported.append(sys.modules.get("skops.io")
                                     or _import_with_module_index("skops.io", "_utils", "whichmodule"))
    return _imported[0]


_import_lock = threading.Lock()
_imported: list[ModuleType] = []
"""``skops.io`` once :func:`_skops` has it whole."""
_PART_NAMES = frozenset(f"{part.__module__}.{part.__qualname__}" for part in SKLEARN_PARTS)
_TRUSTED = [*TRUSTED_TYPES, *sorted(_PART_NAMES)]
"""Every type a model file may hold beyond builtins and numpy arrays, as skops names them."""


@contextmanager
def _estimators(parts: Sequence[type]) -> Iterator[None]:
    """``sklearn.utils.all_estimators`` answering with ``parts`` while the block runs: only while skops is
    first imported, under :data:`_import_lock` (a thread of the process that called it meanwhile would get the
    same short list; nothing of the project does)."""
    crawl = sklearn.utils.all_estimators
    sklearn.utils.all_estimators = lambda type_filter=None: [(part.__name__, part) for part in parts]
    try:
        yield
    finally:
        sklearn.utils.all_estimators = crawl


def _import_with_module_index(package: str, helper: str, function: str) -> ModuleType:
    """Import ``package`` with its ``helper`` module's ``function(obj, name)`` -- skops' ``whichmodule``, the
    module a function without ``__module__`` lives in -- answered from one index of the loaded modules.

    At its import skops names every public ufunc of numpy and ``scipy.special`` (they carry no ``__module__``):
    for each of ~230 ufuncs it tries every loaded module in import order until one holds it, ~160,000 failed
    attribute reads in a ``classify`` process (~700 modules come before ``scipy.special``), 85 ms of CPU. The
    index (:func:`_first_holders`) is built once from the same modules in the same order, so it gives the same
    first module; an object it cannot place (held under another name first, or made by a module only on
    request) goes to skops' own search. The package is imported as the import system does it (the recipe
    "approximating importlib.import_module" of the importlib documentation: find its spec, make the module,
    run it, bind it in its parent), with ``helper`` imported, and ``function`` replaced, before the package
    runs; the replacement is undone once it has run. A package imported already is given as it is, and one
    without ``helper`` or ``function`` is imported as it is.
    """
    if package in sys.modules:
        return sys.modules[package]
    spec = importlib.util.find_spec(package)  # imports the parent package
    if spec is None or spec.loader is None:
        return importlib.import_module(package)  # ModuleNotFoundError, with the import system's own message
    module = importlib.util.module_from_spec(spec)
    sys.modules[package] = module
    try:
        helpers = importlib.import_module(f"{package}.{helper}") if importlib.util.find_spec(
            f"{package}.{helper}") is not None else None
        search = getattr(helpers, function, None)
        if callable(search):
            setattr(helpers, function, _indexed(search))
        try:
            spec.loader.exec_module(module)
        finally:
            if callable(search):
                setattr(helpers, function, search)
    except BaseException:
        sys.modules.pop(package, None)
        raise
    parent, _, child = package.rpartition(".")
    if parent:
        setattr(sys.modules[parent], child, module)
    return module


def _indexed(search: Callable[[Any, str], str]) -> Callable[[Any, str], str]:
    """``search(obj, name)``, the first loaded module holding ``obj`` as ``name``, answered from
    :func:`_first_holders` (built at the first call) where it can be: the first module holding ``obj`` under
    any name is the answer when it holds it as ``name``; otherwise (``obj`` held under another name there
    first, or not at all) ``search`` walks the modules itself."""
    holders: dict[int, str] = {}

    def whichmodule(obj: Any, name: str) -> str:
        module = getattr(obj, "__module__", None)
        if module is not None:
            return module
        if not holders:
            holders.update(_first_holders(sys.modules.copy()))
        holder = sys.modules.get(holders.get(id(obj), ""))
        namespace = getattr(holder, "__dict__", None)
        if isinstance(namespace, dict) and namespace.get(name) is obj:
            return holders[id(obj)]
        return search(obj, name)

    return whichmodule


def _first_holders(modules: Mapping[str, Any]) -> dict[int, str]:
    """``id(value) -> the first module whose namespace holds that value``, over ``modules`` in their order
    (``sys.modules``: import order), ``__main__`` left out as skops leaves it out. Built from the last module
    to the first, so that an earlier module's entry replaces a later one's, with one C-level pass per module
    (13 ms for the ~1,800 modules of a ``classify`` process)."""
    holders: dict[int, str] = {}
    for name, module in reversed(list(modules.items())):
        namespace = getattr(module, "__dict__", None) if name not in ("__main__", "__mp_main__") else None
        if isinstance(namespace, dict):
            holders.update(dict.fromkeys(map(id, namespace.values()), name))
    return holders


def save_model(model: TrainedModel, path: str | os.PathLike[str]) -> Path:
    """Write ``model`` to ``path`` as a skops archive, atomically (temp file + fsync + rename); the temporary
    files of earlier writes of ``path`` that were killed (untouched for 10 minutes) are removed.

    Parameters
    ----------
    model : TrainedModel
    path : str or os.PathLike

    Returns
    -------
    pathlib.Path
        The written file.

    Raises
    ------
    ModelError
        A model that :func:`load_model` would refuse, so no unreadable file is written.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.models import load_model, save_model
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = save_model(model, Path(folder) / "granite-oak.skops")
    ...     loaded = load_model(path)
    >>> path.name, loaded.selected, loaded.classes == model.classes
    ('granite-oak.skops', ('other.density',), True)
    """
    path = Path(path)
    payload = {
        "format": MODEL_FORMAT, "format_version": MODEL_FORMAT_VERSION, "pipeline": model.pipeline,
        "feature_names": list(model.feature_names), "level": model.level, "classifier": model.classifier,
        "n_features": int(model.n_features), "selected": list(model.selected), "classes": list(model.classes),
        "seed": int(model.seed), "software_version": model.software_version,
        "sklearn_version": model.sklearn_version, "dropped": list(model.dropped), "n_rows": int(model.n_rows),
    }
    if model.rejection is not None:
        payload["open_set"] = model.rejection.to_dict()
        if model.rejection.scales is None:  # fewer than three classes: nothing to learn the neighbour term on
            payload["format_version"] = 2
        elif model.rejection.scales.term_mean.size == 3:  # a rule before the forest over every feature
            payload["format_version"] = 3
    else:
        payload["format_version"] = 1
    data = _skops().dumps(payload)
    _model_from(path, _loads(path, data))
    atomic_write_bytes(path, data)
    remove_stale_temp_files(path.parent, path.name)  # a train killed at its rename left one
    return path


def load_model(path: str | os.PathLike[str]) -> TrainedModel:
    """Read a model written by :func:`save_model`; loading cannot run code (skops with a list of trusted types).

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    TrainedModel

    Raises
    ------
    ModelError
        One line, for anything else: not a skops archive, an untrusted type, an inconsistent pipeline.

    Warns
    -----
    UserWarning
        If the model was trained with another scikit-learn version.

    Examples
    --------
    A model saved and loaded back predicts the same; a file that is not a model is refused:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> import tempfile
    >>> from pathlib import Path
    >>> from taxonomy.learning.models import ModelError, load_model, predict_top, save_model
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     loaded = load_model(save_model(model, Path(folder) / "model.skops"))
    ...     _ = (Path(folder) / "notes.skops").write_text("not a model")
    ...     try:
    ...         load_model(Path(folder) / "notes.skops")
    ...     except ModelError as error:
    ...         refused = str(error).removeprefix(f"{folder}/notes.skops: ")
    >>> predict_top(loaded, {"other.density": 5.1}) == predict_top(model, {"other.density": 5.1})
    True
    >>> refused
    'not a readable model file, damaged, truncated or not a skops archive (File is not a zip file)'
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ModelError(f"{path}: cannot read the model file ({exc.strerror or exc})") from None
    _check_unpacked_size(path, data)
    model = _model_from(path, _loads(path, data))
    if model.sklearn_version != sklearn.__version__:
        warnings.warn(f"{path}: trained with scikit-learn {model.sklearn_version}, running "
                      f"{sklearn.__version__}; retrain if predictions look wrong", stacklevel=2)
    return model


def _loads(path: Path, data: bytes) -> Any:
    """The payload of a model archive, built by skops only if every type in it is one a model holds
    (:data:`_TRUSTED`): skops audits the whole schema before it makes any object, and a refusal names the
    foreign types (listed again only then, so that a good file's schema is walked once)."""
    skops = _skops()
    try:
        return skops.loads(data, trusted=_TRUSTED)
    except skops.exceptions.UntrustedTypesFoundException:
        foreign = [t for t in skops.get_untrusted_types(data=data) if t not in _TRUSTED]
        raise ModelError(f"{path}: refused, it holds types a texplorer model never contains: "
                         f"{', '.join(foreign[:5])}") from None
    except Exception as exc:  # skops raises many types for damaged archives (load_model checked the zip first)
        raise ModelError(f"{path}: damaged model file ({type(exc).__name__}: {_first_line(exc)})") from None


def _check_unpacked_size(path: Path, data: bytes) -> None:
    """Refuse an archive whose members would unpack to more than :data:`MAX_MODEL_BYTES` (the sizes its
    directory declares; the zip reader stops a member at its declared size), before any array is made."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            unpacked = sum(info.file_size for info in archive.infolist())
    except zipfile.BadZipFile as exc:
        raise ModelError(f"{path}: not a readable model file, damaged, truncated or not a skops archive "
                         f"({_first_line(exc)})") from None
    if unpacked > MAX_MODEL_BYTES:
        raise ModelError(f"{path}: refused, its arrays would take {unpacked / 2**20:,.0f} MiB once unpacked "
                         f"(a model may take at most {MAX_MODEL_BYTES >> 20} MiB)")


def _first_line(exc: BaseException) -> str:
    return str(exc).strip().splitlines()[0][:200] if str(exc).strip() else "no detail"


def _model_from(path: Path, payload: Any) -> TrainedModel:
    """The model in a loaded payload, after checking that every part has the shape save_model writes."""
    if not isinstance(payload, dict) or payload.get("format") != MODEL_FORMAT:
        raise ModelError(f"{path}: not a texplorer model (no format tag {MODEL_FORMAT!r})")
    version = payload.get("format_version")
    if isinstance(version, bool) or version not in READABLE_VERSIONS:
        raise ModelError(f"{path}: model format version {version!r} is not supported "
                         f"(this program reads versions {', '.join(map(str, READABLE_VERSIONS))})")
    expected = {*_META_TYPES, "pipeline", *(("open_set",) if version >= 2 else ())}
    if set(payload) != expected:
        odd = sorted(set(payload) ^ expected)
        raise ModelError(f"{path}: wrong model metadata fields: {', '.join(odd)}")
    for key, kind in _META_TYPES.items():
        if not isinstance(payload[key], kind) or isinstance(payload[key], bool):
            raise ModelError(f"{path}: metadata field {key!r} must be {kind.__name__}")
    for key in ("feature_names", "selected", "classes", "dropped"):
        if not all(isinstance(v, str) for v in payload[key]):
            raise ModelError(f"{path}: metadata field {key!r} must list text")
    if payload["level"] not in LEVELS:
        raise ModelError(f"{path}: unknown level {payload['level']!r}")
    pipeline = payload["pipeline"]
    _check_pipeline(path, pipeline)
    _check_consistent(path, payload, pipeline)
    rule = _rule_from(path, payload["open_set"], pipeline, payload["feature_names"], version) if version >= 2 \
        else None
    return TrainedModel(
        pipeline=pipeline, feature_names=tuple(payload["feature_names"]), level=payload["level"],
        classifier=payload["classifier"], n_features=payload["n_features"],
        selected=tuple(payload["selected"]), classes=tuple(payload["classes"]), seed=payload["seed"],
        software_version=payload["software_version"], sklearn_version=payload["sklearn_version"],
        dropped=tuple(payload["dropped"]), n_rows=payload["n_rows"], rejection=rule,
    )


def _rule_from(path: Path, stored: Any, pipeline: Pipeline, inputs: Sequence[str], version: int) -> RejectionRule:
    """The rejection rule of a version 2, 3 or 4 file, after checking its fields' types and the arrays'
    shapes."""
    kinds = _OPEN_SET_TYPES | (_NEIGHBOUR_TYPES if version >= 3 else {}) | (_WIDE_TYPES if version >= 4 else {})
    if not isinstance(stored, dict) or set(stored) != set(kinds):
        raise ModelError(f"{path}: the open_set field must hold {', '.join(kinds)}")
    for key, kind in kinds.items():
        if not isinstance(stored[key], kind):
            raise ModelError(f"{path}: open_set field {key!r} must be {_type_names(kind)}")
    means, precision = stored["means"], stored["precision"]
    width = len(pipeline.named_steps["select"].selected_)
    if means.shape != (len(pipeline.classes_), width) or precision.shape != (width, width) \
            or not (np.isfinite(means).all() and np.isfinite(precision).all()):
        raise ModelError(f"{path}: the open-set class means and precision must be finite, of "
                         f"{len(pipeline.classes_)} classes x {width} selected features")
    # +inf is a rule that never rejects (no threshold could be learned); -inf would reject every scan.
    if not (math.isfinite(stored["distance_scale"]) and stored["distance_scale"] > 0) \
            or not stored["threshold"] > -math.inf:
        raise ModelError(f"{path}: the open-set distance scale must be a positive number and the threshold a "
                         f"number or +inf (never reject), got {stored['distance_scale']!r} and "
                         f"{stored['threshold']!r}")
    terms = 4 if version >= 4 else 3
    neighbours, scales = (_neighbours_from(path, stored, len(inputs), len(pipeline.classes_), terms)
                          if version >= 3 else (None, None))
    wide = stored["wide_forest"] if version >= 4 else None
    if version >= 4:
        _check_wide(path, wide, int(np.count_nonzero(neighbours.group_of >= 0)),
                    [str(c) for c in pipeline.classes_])
    return RejectionRule(means, precision, stored["distance_scale"], stored["threshold"], stored["max_accuracy_drop"],
                         stored["inner_auroc"], neighbours, scales, wide)


def _type_names(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join("None" if k is type(None) else k.__name__ for k in kinds)


def _check_wide(path: Path, forest: RandomForestClassifier | None, inputs: int, classes: Sequence[str]) -> None:
    """The forest over every feature of a version 4 rule: None exactly where the model has no grouped input
    column; else fitted on the model's ``inputs`` grouped columns and its ``classes``, at most
    :data:`MAX_TREES` decision trees, each checked as the classifier's are."""
    if (forest is None) != (inputs == 0):
        raise ModelError(f"{path}: the open-set forest over every feature is {'missing' if forest is None else 'there'}"
                         f" for a model of {inputs} grouped inputs")
    if forest is None:
        return
    classes_ = getattr(forest, "classes_", None)
    if not isinstance(classes_, np.ndarray) or classes_.ndim != 1 or [str(c) for c in classes_] != list(classes):
        raise ModelError(f"{path}: the open-set forest over every feature must be fitted on the model's "
                         f"{len(classes)} classes")
    _check_forest(path, "the open-set forest", forest, inputs, len(classes))


def _is_count(value: Any, expected: int) -> bool:
    """``value`` is the whole number ``expected`` (not a float, an array or a bool that equals it)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool) and value == expected


def _check_forest(path: Path, where: str, forest: Any, inputs: int, classes: int) -> None:
    """A fitted random forest, as scikit-learn's prediction reads it: 1 to :data:`MAX_TREES` decision trees and
    as many estimators declared, one job and no progress output, whole-number counts of the ``inputs`` and
    ``classes`` (forest and each tree), each tree's node arrays checked by :func:`_check_tree`. The
    classifier's trees are named ``tree k``, another forest's ``<where>'s tree k``."""
    trees = getattr(forest, "estimators_", None)
    if not isinstance(trees, list) or not 0 < len(trees) <= MAX_TREES:
        count = len(trees) if isinstance(trees, list) else type(trees).__name__
        raise ModelError(f"{path}: {where} must hold 1 to {MAX_TREES} trees, not {count}")
    declared = {"n_estimators": len(trees), "n_outputs_": 1, "n_classes_": classes, "n_features_in_": inputs,
                "verbose": 0}
    wrong = [name for name, value in declared.items() if not _is_count(getattr(forest, name, None), value)]
    jobs = getattr(forest, "n_jobs", None)
    if wrong or not (jobs is None or _is_count(jobs, 1)):
        raise ModelError(f"{path}: {where}'s {', '.join(wrong) or 'n_jobs'} must be whole numbers "
                         f"({len(trees)} trees, 1 output, {classes} classes, {inputs} inputs, no output, one job)")
    prefix = "" if where == "the classifier's forest" else f"{where}'s "
    for k, tree in enumerate(trees):
        if not isinstance(tree, DecisionTreeClassifier) or not all(
                _is_count(getattr(tree, name, None), value)
                for name, value in (("n_classes_", classes), ("n_outputs_", 1), ("n_features_in_", inputs))):
            raise ModelError(f"{path}: {prefix}tree {k} is not a fitted decision tree of {classes} classes and "
                             f"{inputs} inputs")
        _check_tree(path, f"{prefix}tree {k}", getattr(tree, "tree_", None), inputs, classes)


def _neighbours_from(path: Path, stored: dict[str, Any], inputs: int, classes: int,
                     terms: int) -> tuple[Neighbours, Scales]:
    """The neighbour model and scales of a version 3 or 4 rule: every array of the shape the model's ``inputs``
    columns, its groups, ``classes`` and score ``terms`` give, finite (a group's limit may be +inf), spreads
    and standard deviations positive, indices inside what they index."""
    titles = stored["group_titles"]
    groups = len(titles)
    if not all(isinstance(t, str) for t in titles):
        raise ModelError(f"{path}: the open-set group titles must be text")
    shapes = {"group_of": (inputs,), "fill": (inputs,), "centre": (inputs,), "spread": (inputs,),
              "group_mean": (groups,), "group_sd": (groups,), "group_limit": (groups,), "term_mean": (terms,),
              "term_sd": (terms,)}
    reference, owners = stored["reference"], stored["reference_classes"]
    wrong = [key for key, shape in shapes.items() if stored[key].shape != shape]
    if reference.ndim != 2 or reference.shape[1:] != (inputs,) or owners.shape != reference.shape[:1] \
            or not len(owners):
        wrong.append("reference")
    if wrong:
        raise ModelError(f"{path}: open-set field(s) {', '.join(wrong)} do not fit {inputs} inputs, {groups} "
                         f"groups and the reference scans")
    finite = [key for key in (*shapes, "reference") if key not in ("group_of", "group_limit")
              and not (stored[key].dtype.kind == "f" and np.isfinite(stored[key]).all())]
    positive = [key for key in ("spread", "group_sd", "term_sd") if not np.all(stored[key] > 0)]
    if finite or positive or np.isnan(stored["group_limit"]).any():
        raise ModelError(f"{path}: open-set field(s) {', '.join(finite + positive) or 'group_limit'} must hold "
                         f"finite (spreads: positive) numbers")
    group_of = stored["group_of"]
    if group_of.dtype.kind not in "iu" or owners.dtype.kind not in "iu" or np.any(group_of < -1) \
            or np.any(group_of >= groups) or np.any(owners < 0) or np.any(owners >= classes):
        raise ModelError(f"{path}: open-set group or class indices outside their {groups} groups and {classes} "
                         f"classes")
    neighbours = Neighbours(tuple(titles), group_of, stored["fill"], stored["centre"], stored["spread"], reference,
                            owners)
    scales = Scales(stored["group_mean"], stored["group_sd"], stored["group_limit"], stored["term_mean"],
                    stored["term_sd"])
    return neighbours, scales


def _check_pipeline(path: Path, pipeline: Any) -> None:
    names = [name for name, _ in pipeline.steps] if isinstance(pipeline, Pipeline) else []
    if names not in (list(_STEPS), ["kernels", *_STEPS]):
        raise ModelError(f"{path}: the model is not a {' -> '.join(_STEPS)} pipeline")
    if names[0] == "kernels" and not isinstance(pipeline.steps[0][1], RandomKernels):
        raise ModelError(f"{path}: unexpected first step {type(pipeline.steps[0][1]).__name__}")
    scale, select, classify = (step for _, step in pipeline.steps[-3:])
    if isinstance(classify, TemperatureScaledClassifier):
        classify = getattr(classify, "estimator_", classify.estimator)
    kinds = (type(scale), type(select), type(classify))
    if kinds[0] is not MinMaxScaler or kinds[1] not in SELECTORS or kinds[2] not in MODEL_TYPES[2:]:
        raise ModelError(f"{path}: unexpected pipeline steps {' -> '.join(k.__name__ for k in kinds)}")
    calibrated = pipeline.steps[-1][1]
    if isinstance(calibrated, TemperatureScaledClassifier) and not isinstance(getattr(calibrated, "beta_", None),
                                                                               float):
        raise ModelError(f"{path}: the classifier's calibration in the file is not fitted")
    if not all(hasattr(step, "n_features_in_") for step in (scale, select, classify)):
        raise ModelError(f"{path}: the pipeline in the file is not fitted")
    _check_fitted_values(path, pipeline, scale, select, classify)


def _check_fitted_values(path: Path, pipeline: Pipeline, scale: MinMaxScaler, select: FQSelector,
                         classify: Any) -> None:
    """Refuse fitted parameters that prediction cannot use safely, whoever wrote the file: a NaN or infinite
    scale or weight (oak named "100 % metal"), a calibration temperature that is not a positive number, a
    selector index outside its input, and trees or neighbour indexes whose arrays point outside themselves
    (scikit-learn's compiled prediction follows them unchecked: a crash or an endless loop)."""
    width = int(select.n_features_in_)
    for name in ("scale_", "min_"):
        values = np.asarray(getattr(scale, name, np.nan), dtype=np.float64)
        if values.shape != (scale.n_features_in_,) or not np.isfinite(values).all():
            raise ModelError(f"{path}: the scaler's {name} must hold {scale.n_features_in_} finite numbers")
    selected = np.asarray(getattr(select, "selected_", ()))
    if (selected.dtype.kind not in "iu" or selected.ndim != 1 or np.unique(selected).size != selected.size
            or np.any(selected < 0) or np.any(selected >= width)):
        raise ModelError(f"{path}: the selector's selected_ must be distinct column indices below {width}")
    calibrated = pipeline.steps[-1][1]
    if isinstance(calibrated, TemperatureScaledClassifier):
        beta = calibrated.beta_
        if not (math.isfinite(beta) and beta > 0):
            raise ModelError(f"{path}: the calibration temperature must be a positive number, got {beta!r}")
    inputs = int(classify.n_features_in_)
    if inputs != selected.size:
        raise ModelError(f"{path}: the classifier reads {inputs} features, the selector keeps {selected.size}")
    bad = _non_finite(classify, type(classify).__name__)
    if bad:
        raise ModelError(f"{path}: the classifier's {bad} must be finite numbers")
    if isinstance(classify, RandomForestClassifier):
        _check_forest(path, "the classifier's forest", classify, inputs, len(classify.classes_))
    index = getattr(classify, "_tree", None)
    if index is not None:
        _check_index(path, index, inputs)
    points = getattr(classify, "_fit_X", None)
    if points is not None and (np.ndim(points) != 2 or np.shape(points)[1] != inputs
                               or not np.isfinite(points).all()):
        raise ModelError(f"{path}: the neighbour classifier's points must be finite, of {inputs} features")


def _non_finite(estimator: Any, name: str, depth: int = 0) -> str | None:
    """The first fitted float parameter of ``estimator`` (attributes ``*_``, lists of arrays) that holds NaN
    or infinity, as ``SVC.dual_coef_``; None when every one is finite."""
    for key, value in vars(estimator).items():
        if not key.endswith("_") or key.startswith("_") or key == "estimators_":
            continue
        values = value if isinstance(value, list | tuple) else [value]
        for item in values:
            if isinstance(item, float | np.floating) and not math.isfinite(item):
                return f"{name}.{key}"
            if isinstance(item, np.ndarray) and item.dtype.kind == "f" and not np.isfinite(item).all():
                return f"{name}.{key}"
    return None


def _check_tree(path: Path, where: str, tree: Any, inputs: int, classes: int) -> None:
    """A fitted tree's node arrays, checked as scikit-learn's builder makes them: every inner node's two
    children after it and inside the tree (so every path ends at a leaf), its split feature below the
    model's input width and its threshold finite, every leaf's values finite, at most
    :data:`MAX_TREE_NODES` nodes."""
    if not isinstance(tree, Tree):
        raise ModelError(f"{path}: {where} is not a fitted tree but a {type(tree).__name__}")
    count = int(tree.node_count)
    if not 0 < count <= MAX_TREE_NODES:
        raise ModelError(f"{path}: {where} has {count:,} nodes (1 to {MAX_TREE_NODES:,})")
    state = tree.__getstate__()
    nodes, values = state["nodes"], np.asarray(state["values"])
    if nodes.shape != (count,) or values.shape != (count, 1, classes) or int(tree.n_features) != inputs \
            or int(tree.n_outputs) != 1:
        raise ModelError(f"{path}: {where}'s arrays do not match its {count} nodes, {inputs} inputs and "
                         f"{classes} classes")
    left, right = nodes["left_child"], nodes["right_child"]
    leaf = left == -1
    inner = np.flatnonzero(~leaf)
    wrong = (leaf != (right == -1))
    wrong[inner] |= (left[inner] <= inner) | (right[inner] <= inner) | (left[inner] >= count) | (right[inner] >= count)
    if wrong.any():
        node = int(np.flatnonzero(wrong)[0])
        raise ModelError(f"{path}: {where}: a child index points back, to itself or outside the {count} "
                         f"nodes (node {node}: children {int(left[node])} and {int(right[node])})")
    feature = nodes["feature"][inner]
    if np.any(feature < 0) or np.any(feature >= inputs):
        raise ModelError(f"{path}: {where} splits on feature {int(feature[(feature < 0) | (feature >= inputs)][0])} "
                         f"of a model with {inputs} inputs")
    if not np.isfinite(nodes["threshold"][inner]).all() or not np.isfinite(values).all():
        raise ModelError(f"{path}: {where}'s thresholds and leaf values must be finite")


def _check_index(path: Path, index: Any, inputs: int) -> None:
    """A neighbour classifier's KD-tree: its points finite and of the model's width, its index array a
    permutation of them, its node ranges inside it."""
    data, order, nodes, _ = index.get_arrays()
    data, order = np.asarray(data), np.asarray(order)
    if data.ndim != 2 or data.shape[1] != inputs or not np.isfinite(data).all() \
            or np.sort(order).tolist() != list(range(data.shape[0])):
        raise ModelError(f"{path}: the neighbour index's points or order do not fit its {inputs} inputs")
    ranges = np.asarray(nodes)
    if ranges.size and (np.any(ranges["idx_start"] < 0) or np.any(ranges["idx_end"] > data.shape[0])
                        or np.any(ranges["idx_start"] > ranges["idx_end"])):
        raise ModelError(f"{path}: the neighbour index's nodes point outside its {data.shape[0]} points")


def _check_consistent(path: Path, payload: dict[str, Any], pipeline: Pipeline) -> None:
    names = payload["feature_names"]
    if len(set(names)) != len(names) or pipeline.n_features_in_ != len(names):
        raise ModelError(f"{path}: {len(names)} distinct feature names for a pipeline of "
                         f"{pipeline.n_features_in_} inputs")
    if list(selected_names(pipeline, names)) != payload["selected"]:
        raise ModelError(f"{path}: the selected feature names do not match the pipeline's selector")
    if [str(c) for c in pipeline.classes_] != payload["classes"]:
        raise ModelError(f"{path}: the class list does not match the pipeline's classes")


# -- prediction --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Verdict:
    """A model's answer for one scan: its ``k`` most probable classes, the rejection score and threshold
    (NaN and +inf for a model without a rule), whether the rule rejects the scan as an unknown material, and
    the rule's :class:`~taxonomy.learning.openset.Explanation` (None without a rule)."""

    top: list[tuple[str, float]]
    score: float
    threshold: float
    explanation: Explanation | None = None

    @property
    def unknown(self) -> bool:
        """Whether the rejection score is above the model's threshold: an unknown material."""
        return bool(self.score > self.threshold)


def classify_values(model: TrainedModel, feature_values: Mapping[str, float], k: int = 3) -> Verdict:
    """:func:`predict_top` with the model's rejection rule applied (:mod:`taxonomy.learning.openset`).

    Parameters
    ----------
    model : TrainedModel
        A trained or loaded model.
    feature_values : mapping of str to float
        Feature names to values (``features.extract(scan)``); extra names are ignored.
    k : int
        How many classes.

    Returns
    -------
    Verdict
        The ``k`` most probable classes, the rejection score and threshold and whether the scan is an
        unknown material; score NaN and threshold +inf for a model without a rule.

    Raises
    ------
    ModelError
        As :func:`predict_top`.

    Examples
    --------
    A model of two classes has a rule that never rejects (threshold +inf); a version 1 model has none:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> from dataclasses import replace
    >>> from taxonomy.learning.models import classify_values, predict_top
    >>> verdict = classify_values(model, {"other.density": 5.1})
    >>> verdict.top == predict_top(model, {"other.density": 5.1}), verdict.threshold, verdict.unknown
    (True, inf, False)
    >>> verdict.explanation.closest
    'C1S1M1P4X1'
    >>> verdict = classify_values(replace(model, rejection=None), {"other.density": 5.1})
    >>> verdict.score, verdict.threshold, verdict.unknown, verdict.explanation
    (nan, inf, False, None)
    """
    top = predict_top(model, feature_values, k)
    if model.rejection is None:
        return Verdict(top, math.nan, math.inf)
    score, explanation = model.rejection.assess(model.pipeline, _row(model, feature_values))
    return Verdict(top, float(score[0]), model.rejection.threshold, explanation[0])


def _row(model: TrainedModel, feature_values: Mapping[str, float]) -> np.ndarray:
    return np.array([[_as_float(feature_values.get(n, math.nan)) for n in model.feature_names]])


def predict_top(model: TrainedModel, feature_values: Mapping[str, float],
                k: int = 3) -> list[tuple[str, float]]:
    """The ``k`` most probable classes of one scan, most probable first.

    Only the selected features reach the classifier, so only they must be present and finite; other model
    inputs may be missing or NaN (they are passed on as NaN and dropped by the selector). Equal
    probabilities keep the model's class order.

    Parameters
    ----------
    model : TrainedModel
    feature_values : mapping of str to float
        Feature names to values (``features.extract(scan)``); extra names are ignored.
    k : int
        How many classes.

    Returns
    -------
    list of (str, float)
        ``[(label, probability), ...]``.

    Raises
    ------
    ModelError
        A selected feature missing or NaN, naming them (a guess would look like a real prediction).

    Examples
    --------
    ``other.metal`` is not selected, so it may be missing:

    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from taxonomy.learning.models import train_model
    >>> density = [0.0, 0.2, 0.1, 0.3, 5.0, 5.2, 5.1, 5.3]  # granite, then oak: perfectly separated
    >>> space = FeatureSpace(np.column_stack([density, [1.0, 0.0] * 4]), ("other.density", "other.metal"),
    ...                      [f"scan{i}" for i in range(8)], ["C6S1M1P2X1"] * 4 + ["C1S1M1P4X1"] * 4,
    ...                      [f"sample{i // 2}" for i in range(8)])
    >>> model = train_model(space, n_features=1, classifier="nb")
    >>> from taxonomy.learning.models import predict_top
    >>> top = predict_top(model, {"other.density": 5.1})
    >>> [(label, round(probability, 3)) for label, probability in top]
    [('C1S1M1P4X1', 1.0), ('C6S1M1P2X1', 0.0)]
    >>> predict_top(model, {"other.density": 0.1, "other.metal": float("nan")}, k=1)[0][0]
    'C6S1M1P2X1'
    >>> predict_top(model, {"other.metal": 1.0})
    Traceback (most recent call last):
    ...
    taxonomy.learning.models.ModelError: missing feature value(s) the model needs: other.density
    """
    if isinstance(k, bool) or not isinstance(k, int) or k < 1:
        raise ModelError(f"k must be a positive integer, got {k!r}")
    required = required_inputs(model)
    missing = [n for n in required if n not in feature_values]
    if missing:
        raise ModelError(f"missing feature value(s) the model needs: {', '.join(missing[:10])}")
    undefined = [n for n in required if not _finite(feature_values[n])]
    if undefined:
        raise ModelError(f"undefined (NaN or non-numeric) feature value(s) the model needs: "
                         f"{', '.join(undefined)}")
    probability = model.pipeline.predict_proba(_row(model, feature_values))[0]
    order = np.argsort(-probability, kind="stable")[:k]
    return [(str(model.pipeline.classes_[i]), float(probability[i])) for i in order]


def _as_float(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _finite(value: Any) -> bool:
    return math.isfinite(_as_float(value))


def format_predictions(predictions: Sequence[tuple[str, float]], taxonomy: Taxonomy | None = None) -> str:
    """Lines like ``1. C6S1M1P2X1   82.0 %  granite (igneous stone, stone), polished, plain``.

    Parameters
    ----------
    predictions : sequence of (str, float)
        ``[(label, probability), ...]`` (:func:`predict_top`), in rank order.
    taxonomy : Taxonomy, optional
        Names the labels; a label it lacks is marked ``(not in the taxonomy table)``.

    Returns
    -------
    str
        One line per prediction: rank, label (padded to the longest), probability in percent and the name.

    Examples
    --------
    >>> from taxonomy import SHIPPED_TABLE, Taxonomy
    >>> from taxonomy.learning.models import format_predictions
    >>> predictions = [("C6S1M1P2X1", 0.82), ("C1S1M1P4X1", 0.18)]
    >>> print(format_predictions(predictions))
    1. C6S1M1P2X1   82.0 %
    2. C1S1M1P4X1   18.0 %
    >>> print(format_predictions(predictions, Taxonomy.from_csv(SHIPPED_TABLE)))
    1. C6S1M1P2X1   82.0 %  granite (igneous stone, stone), polished, plain
    2. C1S1M1P4X1   18.0 %  oak (hardwood, wood), planed, plain
    """
    width = max((len(label) for label, _ in predictions), default=0)
    lines = []
    for rank, (label, probability) in enumerate(predictions, start=1):
        line = f"{rank}. {label:<{width}}  {100 * probability:5.1f} %"
        if taxonomy is not None:
            try:
                line += f"  {taxonomy.name(label)}"
            except ValueError:
                line += "  (not in the taxonomy table)"
        lines.append(line)
    return "\n".join(lines)
