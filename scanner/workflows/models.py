"""The database's models: the default one (``texplorer demo``), a new version trained and kept with its
figures (``texplorer train``, the web app's enrolment), and the file a ``--model`` value names."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

from features import FeatureSpace, code_version
from features.feature_sets import FeatureSet
from features.space import FeatureSpaceError
from scanner.runtime.local import WorkerPool
from scanner.storage.database import Database
from scanner.workflows.database import extract_database
from scanner.workflows.predictions import label_names
from taxonomy.learning.evaluation import EvaluationError, evaluate
from taxonomy.learning.models import TrainedModel, train_model
from taxonomy.learning.versions import (
    ModelVersion,
    add_version,
    current_version,
    find_version,
    is_version,
    training_fingerprint,
    version_file,
)
from taxonomy.table import Taxonomy

DEFAULT_MODEL = Path("models") / "rf-fine-X10.skops"
"""Where ``texplorer demo`` saved its model before model versions (``taxonomy.learning.versions``: version 0)."""


DEFAULT_MODEL_SETTINGS = ("fine", 10, "rf")
"""Level, set size and classifier of the default model (the paper's Fig. 17 setting)."""


def train_default_model(space: FeatureSpace, seed: int) -> TrainedModel:
    """Train the database's default model on every row of ``space`` (:data:`DEFAULT_MODEL_SETTINGS`,
    :func:`taxonomy.learning.models.train_model`); :func:`save_model_version` keeps it."""
    level, n_features, classifier = DEFAULT_MODEL_SETTINGS
    return train_model(space, level, n_features, classifier, seed)


def train_and_measure(space: FeatureSpace, level: str, n_features: int, classifier: str, seed: int,
                      cv: bool = True) -> tuple[TrainedModel, dict[str, float]]:
    """A model of ``space`` and the headline figures its version records (:func:`cross_validated`, unless
    not ``cv``)."""
    model = train_model(space, level, n_features, classifier, seed)
    return model, (cross_validated(space, level, n_features, classifier, seed)[0] if cv else {})

def cross_validated(space: FeatureSpace, level: str, n_features: int, classifier: str, seed: int,
                    feature_set: FeatureSet = None) -> tuple[dict[str, float], str]:
    """The figures a model version records of its settings, ``{"cv_accuracy": pooled accuracy}`` over 5
    folds grouped by sample (calibration off: it changes no prediction), and a line for people; no figures
    and the reason where there are too few scans to cross-validate (the model is kept all the same)."""
    started = time.perf_counter()
    try:
        result = evaluate(space, classifier, level, n_features, seed=seed, calibrate=False, feature_set=feature_set)
    except (EvaluationError, FeatureSpaceError) as exc:
        return {}, f"no cross-validated accuracy for this version: {exc}"
    return {"cv_accuracy": float(result.accuracy_pooled)}, (
        f"cross-validated accuracy of these settings: {100 * result.accuracy_pooled:.1f} % "
        f"({result.splitting}, {time.perf_counter() - started:.1f} s)")


@dataclass(frozen=True)
class ModelChange:
    """What a new model version changed against the version that was current before it."""

    after: ModelVersion
    before: ModelVersion | None
    current: ModelVersion | None

    @property
    def added(self) -> tuple[str, ...]:
        """Classes the new version predicts that the one before did not (all of them after a first model)."""
        known = set(self.before.classes) if self.before is not None else set()
        return tuple(c for c in self.after.classes if c not in known)

    @property
    def removed(self) -> tuple[str, ...]:
        """Classes the version before predicted and the new one does not."""
        if self.before is None or not self.before.classes:  # version 0 records no classes
            return ()
        return tuple(c for c in self.before.classes if c not in set(self.after.classes))

    def describe(self, taxonomy: Taxonomy | None = None) -> str:
        """``model version 5 (rf, fine level, 10 features; 198 scans) is current: 1 class added, granite ...
        (C6S1M1P2X1); cross-validated accuracy 95.1 % (version 4) -> 95.3 %``."""
        def named(labels: tuple[str, ...]) -> str:
            return ", ".join(f"{label_names(c, taxonomy)} ({c})" if taxonomy is not None else c for c in labels[:5]) \
                + (f" and {len(labels) - 5} more" if len(labels) > 5 else "")

        after, before = self.after, self.before
        in_use = self.current is not None and self.current.version == after.version
        parts = [f"model version {after.version} ({after.protocol()}; {after.rows} scans) "
                 + ("is current" if in_use else f"is kept; version {self.current.version if self.current else '-'} "
                    "stays current")]
        if before is None:
            parts.append(f"{len(after.classes)} classes")
        else:
            changed = [f"{len(labels)} class{'es' if len(labels) > 1 else ''} {kind}: {named(labels)}"
                       for kind, labels in (("added", self.added), ("removed", self.removed)) if labels]
            parts.append("; ".join(changed) or f"the same {len(after.classes)} classes as version {before.version}")
        old, new = (None if before is None else before.figures.get("cv_accuracy")), after.figures.get("cv_accuracy")
        if new is not None:
            parts.append("cross-validated accuracy " + (f"{100 * old:.1f} % (version {before.version}) -> "
                                                         if old is not None and before is not None else "")
                         + f"{100 * new:.1f} %")
        return "; ".join(parts)


def retrain(db: Database, *, seed: int = 0, pool: WorkerPool | None = None, cv: bool = True, note: str = "",
            make_current: bool = True) -> ModelChange:
    """Train a new model version on every scan of ``db`` with the current version's classifier, level and
    number of features (:data:`DEFAULT_MODEL_SETTINGS` without one, or after a version 0), its figures
    measured as :func:`train_and_measure`; the features of ``pool`` (a job's workers, read from the feature
    cache where they are current), the training too where a pool is given (on one of its workers, at their
    priority). Returns what changed against the version current before.

    Raises
    ------
    DatabaseError
        No scans.
    taxonomy.learning.evaluation.EvaluationError
        Scans the model cannot be trained on (a single class).
    """
    before = current_version(db.root)
    level, n_features, classifier = DEFAULT_MODEL_SETTINGS
    if before is not None and before.version > 0:
        level, n_features, classifier = before.level, before.n_features, before.classifier
    space = extract_database(db, pool=pool, progress=False, partial=False)
    arguments = (space, level, n_features, classifier, seed, cv)
    model, figures = (pool.submit(train_and_measure, *arguments).result() if pool is not None
                      else train_and_measure(*arguments))
    version = save_model_version(db, model, space, figures, note=note, make_current=make_current)
    return ModelChange(version, before, current_version(db.root))


def save_model_version(db: Database, model: TrainedModel, space: FeatureSpace,
                       figures: dict[str, float] | None = None, note: str = "",
                       make_current: bool = True) -> ModelVersion:
    """Keep ``model``, trained on ``space`` (the database's scans), as the database's next model version
    (:func:`taxonomy.learning.versions.add_version`), with the fingerprint of its training scans (their ids
    and content hashes) and the feature code version; the current version unless ``make_current`` is false."""
    stored = {record.scan_id: record.content_hash for record in db.records()}
    version = code_version()
    fingerprint = training_fingerprint(((scan_id, stored.get(scan_id, "")) for scan_id in space.scan_ids), version)
    return add_version(db.root, model, fingerprint=fingerprint, feature_code_version=version, figures=figures,
                       note=note, make_current=make_current)


def default_model(db_root: str | os.PathLike[str]) -> Path | None:
    """The database's current model (``texplorer models``): the file of its current version, else None.

    Parameters
    ----------
    db_root : str or os.PathLike
        The database folder.

    Returns
    -------
    pathlib.Path or None
        The model file, or None if the database has none (``texplorer demo`` and ``train`` make one).
    """
    current = current_version(db_root)
    return None if current is None else version_file(db_root, current)


def model_file(db_root: str | os.PathLike[str], spec: str | os.PathLike[str] | None) -> Path | None:
    """The model a ``--model`` value names: a version of the database (``3``, ``v3``), a file, or with None
    the database's current model (None if it has none).

    Raises
    ------
    VersionError
        A version the database does not have.
    """
    if spec is None:
        return default_model(db_root)
    if is_version(spec):
        return version_file(db_root, find_version(db_root, str(spec)))
    return Path(spec)
