"""The workflows that the CLI, the web application, replay and the benchmarks share, each written once.

- **Extract a database with its feature cache**: :func:`database_sources` turns catalog rows into
  :class:`features.ScanSource` objects keyed by the scan's content hash; :func:`extract_database` extracts
  them with the database as the cache (a second run over unchanged scans only reads it);
  :func:`stored_features` gives one stored scan's values.
- **Simulate a database with its features**: :func:`simulated_database` (``texplorer demo``) extracts each
  simulated scan's features while it is in memory and fills the feature cache as the scans are stored.
- **Export a database with its features**: :func:`export_database` writes an export bundle
  (:func:`scanner.storage.bundle.export_bundle`) whose feature tables come from the database's feature cache.
- **The database's models**: :func:`train_default_model` trains the default one (``texplorer demo``, beside
  the evaluation), :func:`save_model_version` keeps a model as the database's next version;
  :func:`default_model` finds the current version, which ``serve`` and ``classify`` use when no model is
  given, and :func:`model_file` resolves a ``--model`` value (a version or a file).
- **Compile the feature kernels once**: :func:`compile_kernels` (``make install``) extracts simulated
  scans so that numba writes every kernel the features use into its cache before the first command needs it.
- **Predict a scan's top k with names**: :func:`predict_scan` extracts a scan's features and names the
  model's most probable labels with the taxonomy the caller gives (a database's own taxonomy, with its lab
  codes, where there is a database); :func:`name_predictions` names predictions made elsewhere.

This module sits above storage, features and learning and below the CLI and the web application, which
call it rather than wiring those layers together themselves (see ``docs/extending.md``).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from features import REGISTRY, FeatureSpace, ScanSource, WorkerPool, code_version, extract, extract_many, feature_sets
from features.memory import keep_freed_memory
from scanner.acquisition.config import Config
from scanner.acquisition.session import STEP_TITLES, step_seconds
from scanner.scan import Scan
from scanner.simulation.database import synthetic_database
from scanner.simulation.scans import synthetic_scan
from scanner.storage.bundle import ExportReport, Progress, export_bundle
from scanner.storage.database import Database, DatabaseError, ScanRecord
from scanner.storage.matfile import load_scan, save_scan
from scanner.storage.settings import read_settings
from taxonomy.labels import Label, LabelError
from taxonomy.learning.evaluation import EvaluationError, FeatureSet, evaluate
from taxonomy.learning.models import TrainedModel, classify_values, train_model
from taxonomy.learning.openset import Explanation
from taxonomy.learning.quick import (
    STOP_AT,
    QuickResult,
    StepModel,
    calibrate_walks,
    contrast,
    evaluate_quick,
    experts_of,
    fit_step_model,
    next_step,
)
from taxonomy.learning.versions import (
    ModelVersion,
    add_version,
    current_version,
    find_version,
    is_version,
    training_fingerprint,
    version_file,
)
from taxonomy.table import Taxonomy, UnknownLabelError

if TYPE_CHECKING:
    from distributed import Client

NOT_IN_TAXONOMY = "(not in the taxonomy table)"
"""Shown instead of the names of a predicted label the taxonomy does not know."""


# -- extract a database with its cache ---------------------------------------------------------------

def database_sources(db: Database, records: Iterable[ScanRecord]) -> list[ScanSource]:
    """One :class:`features.ScanSource` per catalog row: loaded where it is extracted (on a cluster worker,
    exactly the catalogued bytes: :meth:`scanner.storage.database.Database.stored_scans`), cached by content."""
    records = list(records)
    return [ScanSource(r.scan_id, r.label, r.sample_id, stored, cache_key=r.content_hash)
            for r, stored in zip(records, db.stored_scans(records), strict=True)]


def extract_database(db: Database, *, label: str | None = None, records: Sequence[ScanRecord] | None = None,
                     workers: int | None = None, progress: bool = True, client: Client | None = None,
                     ship_data: bool = False, pool: WorkerPool | None = None,
                     families: Sequence[str] | None = None, partial: bool = True) -> FeatureSpace:
    """The features of every scan of ``db`` (or of ``label``, a label or class prefix, or of ``records``),
    read from the database's feature cache where the scan and the feature code are unchanged; extracted in
    ``workers`` processes here (or those of ``pool``, kept across a job's batches), or on the Dask cluster
    of ``client`` (``ship_data``: send the files to the workers; see :func:`features.extract_many`). The
    catalog and the cache are read and written here only. ``families``: the feature families to compute
    (default: the paper's; opt-in ones such as :mod:`features.modern`'s too). Without ``partial``, quick
    scans that hold only some steps are left out (:func:`full_scans`): what models learn from and are
    measured on.

    Raises
    ------
    DatabaseError
        No scan to extract.
    """
    if records is None:
        records = db.records(label=label)
    if not partial:
        records = full_scans(records)
    if not records:
        raise DatabaseError(f"{db.root}: no scans{f' with label {label}' if label else ''} to extract")
    return extract_many(database_sources(db, records), workers=workers, cache=db, progress=progress, client=client,
                        ship_data=ship_data, pool=pool, families=families)


def full_scans(records: Sequence[ScanRecord]) -> list[ScanRecord]:
    """The full scans of ``records``; a one-line note on stderr names how many quick (partial) scans are left
    out, since a model learns from and is measured on every step."""
    full = [r for r in records if not r.partial]
    if len(full) < len(records):
        print(f"texplorer: note: {len(records) - len(full)} quick scan(s) holding only some steps left out: models "
              "learn from and are measured on full scans (docs/quick.md)", file=sys.stderr)
    return full


def simulated_database(root: str | os.PathLike[str], **options: Any) -> Database:
    """:func:`scanner.simulation.database.synthetic_database` (``options`` are its own) with each scan's
    features extracted by the process that simulated it, from the scan in memory, and stored in the
    feature cache once the scan is catalogued: the features stage that follows (:func:`extract_database`)
    then reads no file back, only verifies the files' hashes. The workers keep the memory a scan frees for
    the next (:func:`features.memory.keep_freed_memory`; docs/performance.md). The values are those an
    extraction from the stored files gives (the ``.mat`` and PNG files are lossless), and a scan whose
    extraction fails here is simply left to that stage, which reports it."""
    version = code_version()

    def cache(db: Database, scan_id: str, values: dict[str, float] | None) -> None:
        if values is not None:
            db.store_features(db.record(scan_id).content_hash, version, values)

    return synthetic_database(root, analyse=_features_or_none, on_stored=cache, worker_start=keep_freed_memory,
                              **options)


def _features_or_none(scan: Scan) -> dict[str, float] | None:
    """The default features of ``scan`` (missing-channel warnings are the features stage's to report), or
    None if the extraction fails."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return extract(scan)
    except Exception:  # noqa: BLE001 - the features stage extracts the scan again and names the failure
        return None


def stored_features(db: Database, record: ScanRecord) -> tuple[dict[str, float], str | None]:
    """One stored scan's named feature values from the cache (extracted and cached if missing), or ``{}``
    and the reason its extraction failed."""
    space = extract_database(db, records=[record], workers=1, progress=False)
    if space.failed:
        return {}, space.failed[0][1]
    return dict(zip(space.columns, space.X[0].tolist(), strict=True)), None


# -- compile the feature kernels once ---------------------------------------------------------------

KERNEL_SCANS = (("cotton-woven", 0.0), ("granite-polished", 1.0))
"""The simulated scans :func:`compile_kernels` extracts: (material, probability that the fold step is
skipped), a folded textile and a rigid stone whose fold step is skipped, between them every step's kernels."""


def compile_kernels(image_size: int = 384) -> float:
    """Extract the features of the :data:`KERNEL_SCANS`, each in memory and read back from its stored files,
    so that numba compiles every kernel the features use (for the array layouts of both paths) and writes it
    into its cache (``__pycache__`` beside the code); returns the seconds it took.

    ``make install`` runs this, so that the first ``make demo`` does not compile in each of its worker
    processes at once (docs/performance.md); a later process loads the cached machine code."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for index, (material, skip) in enumerate(KERNEL_SCANS):
            scan = synthetic_scan(material, seed=index, image_size=(image_size, image_size),
                                  fold_skip_probability=skip)
            path = Path(folder) / f"{material}.mat"
            save_scan(scan, path)
            extract(scan)
            extract(load_scan(path))
    return time.perf_counter() - started


# -- export a database with its features -----------------------------------------------------------

def export_database(db: Database, out: str | os.PathLike[str], *, label: str | None = None,
                    session: str | None = None, license: str | None = None, creator: str | None = None,
                    workers: int | None = None, progress: Progress = iter) -> ExportReport:
    """Write the scans of ``db`` (optionally a label or class prefix, or one session) as an export bundle
    with their features, read from the feature cache where possible (``workers`` processes extract the
    rest); see :func:`scanner.storage.bundle.export_bundle` for the bundle and its errors.

    ``license`` and ``creator`` default to the database's settings (``texplorer db settings``); without a
    license from either the export is refused (``"none"`` exports without one)."""
    def features(records: Sequence[ScanRecord]) -> FeatureSpace:
        return extract_database(db, records=records, workers=workers)

    settings = read_settings(db.root)
    return export_bundle(db, out, features, feature_code_version=code_version(),
                         license=license or settings.get("license"), creator=creator or settings.get("creator"),
                         feature_units=REGISTRY.units, label=label, session=session, progress=progress)


# -- the database's default model -------------------------------------------------------------------

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


def quick_evaluation(space: FeatureSpace, config: Config | None = None, level: str = "fine", folds: int = 5,
                     seed: int = 0, workers: int | None = None, open_set: bool = False) -> QuickResult:
    """``evaluate --quick``: the stored full scans walked as quick scans in grouped folds
    (:func:`taxonomy.learning.quick.evaluate_quick`), each step taking its recording and handling time from
    ``config`` (default: the default configuration), the fixed order the procedure's."""
    seconds = step_seconds(config or Config())
    return evaluate_quick(space, seconds, tuple(seconds), level, folds, seed, workers=workers, open_set=open_set)


def cross_validated(space: FeatureSpace, level: str, n_features: int, classifier: str, seed: int,
                    feature_set: FeatureSet = None) -> tuple[dict[str, float], str]:
    """The figures a model version records of its settings, ``{"cv_accuracy": pooled accuracy}`` over 5
    folds grouped by sample (calibration off: it changes no prediction), and a line for people; no figures
    and the reason where there are too few scans to cross-validate (the model is kept all the same)."""
    started = time.perf_counter()
    try:
        result = evaluate(space, classifier, level, n_features, seed=seed, calibrate=False, feature_set=feature_set)
    except EvaluationError as exc:
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
            return ", ".join(f"{_names(c, taxonomy)} ({c})" if taxonomy is not None else c for c in labels[:5]) \
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


# -- predict a scan's top k with names ---------------------------------------------------------------

@dataclass(frozen=True)
class Prediction:
    """One of a model's most probable labels for a scan, with the taxonomy's words for it."""

    label: str
    probability: float
    names: str


def name_predictions(top: Iterable[tuple[str, float]], taxonomy: Taxonomy) -> list[Prediction]:
    """``[(label, probability), ...]`` (:func:`taxonomy.learning.models.predict_top`) with each label's names."""
    return [Prediction(label, probability, _names(label, taxonomy)) for label, probability in top]


def _names(label: str, taxonomy: Taxonomy) -> str:
    try:
        return taxonomy.name(label)
    except (LabelError, UnknownLabelError):
        return NOT_IN_TAXONOMY


@dataclass(frozen=True)
class ScanPrediction:
    """A model's ``k`` most probable labels for a scan (``predictions``, most probable first), whether its
    rejection rule calls the scan an unknown material (:mod:`taxonomy.learning.openset`), and why: the
    trained material closest to the scan (``closest``, named) and the rule's explanation."""

    predictions: list[Prediction]
    unknown: bool = False
    score: float = float("nan")
    threshold: float = float("inf")
    closest: Prediction | None = None
    explanation: Explanation | None = None

    def headline(self) -> str:
        """``unknown material (closest: granite, polished (C6S1M1P2X1)): image: photo unlike every trained
        material`` when rejected, else the best label's name and probability."""
        if not self.predictions:
            return "no prediction"
        best = self.predictions[0]
        if not self.unknown:
            return f"{best.names} ({best.label}) {100 * best.probability:.1f} %"
        closest = self.closest or best
        return f"unknown material (closest: {closest.names} ({closest.label})): {self.reason()}"

    def reason(self) -> str:
        """Why the rule finds the scan unlike the trained materials, in words: the sensing steps whose
        features are unlike every trained material's, else what the largest term of the score says."""
        explanation = self.explanation
        if explanation is None:
            return "its rejection score is above the model's threshold"
        if explanation.unlike:
            steps = " and ".join(filter(None, (", ".join(explanation.unlike[:-1]), explanation.unlike[-1])))
            return f"{steps} {'is' if len(explanation.unlike) == 1 else 'are'} unlike every trained material"
        if explanation.largest == "surprisal" and len(self.predictions) > 1:
            first, second = self.predictions[:2]
            return (f"the model is split between {first.names} ({100 * first.probability:.0f} %) and "
                    f"{second.names} ({100 * second.probability:.0f} %)")
        if explanation.largest == "distance":
            return "the features the model classifies by lie outside every trained material's"
        return "its features as a whole are unlike every trained material's"


def predict_scan(model: TrainedModel, scan: Scan, k: int, taxonomy: Taxonomy) -> ScanPrediction:
    """The ``k`` most probable labels of ``scan`` by ``model``, most probable first, named by ``taxonomy``,
    and whether the model's rejection rule calls it an unknown material.

    Raises
    ------
    taxonomy.learning.models.ModelError
        A feature the model needs is missing or undefined for this scan.
    """
    return predict_values(model, extract(scan, feature_sets.families_of(model.feature_names)), k, taxonomy)


def predict_values(model: TrainedModel, values: dict[str, float], k: int, taxonomy: Taxonomy) -> ScanPrediction:
    """As :func:`predict_scan`, from the scan's feature values already extracted."""
    verdict = classify_values(model, values, k)
    explanation = verdict.explanation
    closest = None if explanation is None else Prediction(explanation.closest, float("nan"),
                                                          _names(explanation.closest, taxonomy))
    return ScanPrediction(name_predictions(verdict.top, taxonomy), verdict.unknown, verdict.score, verdict.threshold,
                          closest, explanation)


# -- the quick scan ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class QuickState:
    """Where a quick scan stands after the steps ``recorded`` (``seconds`` of recording and handling): the three
    most probable labels, whether it stopped (the top class at 0.95 and the recorded steps like those of
    trained materials), whether their novelty is accepted, the step proposed next and why."""

    predictions: list[Prediction]
    recorded: frozenset[str]
    seconds: float
    decided: bool
    accepted: bool
    next_step: str | None
    reason: str

    def why_stopped(self) -> str:
        """The stop in the operator's words."""
        top = self.predictions[0]
        if self.decided:
            return (f"{top.names} ({top.label}) reached {100 * top.probability:.1f} % (at least "
                    f"{100 * STOP_AT:.0f} %) and the recorded steps look like those of trained materials")
        if not self.accepted:
            return "the recorded steps are unlike every trained material: the full scan decides whether it is new"
        return f"no step is left that the model can learn from; the most probable is {top.names} ({top.label})"


def step_words(step: str) -> str:
    """A step as the operator reads it: ``TU1 tool slide``."""
    return STEP_TITLES[step][1] if step in STEP_TITLES else step


class QuickIdentifier:
    """The quick scan's live side (docs/quick.md): the :class:`~taxonomy.learning.quick.StepModel` of a
    database's scans, the protocol's step times, and the taxonomy that names its classes."""

    def __init__(self, model: StepModel, columns: Sequence[str], seconds: dict[str, float],
                 taxonomy: Taxonomy) -> None:
        self.model, self.columns, self.seconds, self.taxonomy = model, tuple(columns), seconds, taxonomy

    @classmethod
    def from_database(cls, db: Database, config: Config | None = None, seed: int = 0,
                      workers: int | None = None) -> QuickIdentifier:
        """Fit the quick scan's model on every scan of ``db`` at the fine level (features from the cache),
        its temperatures calibrated on the walks of the adaptive and the procedure's order."""
        if len(db) == 0:
            raise EvaluationError(f"{db.root}: no scans to learn a quick scan from")
        space = extract_database(db, workers=workers, progress=False, partial=False)
        seconds = step_seconds(config or Config())
        experts = experts_of(space.columns, REGISTRY.column_steps(space.columns))
        model = fit_step_model(space.X, space.y("fine"), np.asarray(space.groups), experts, seed)
        return cls(calibrate_walks(model, seconds, (None, tuple(seconds))), space.columns, seconds, db.taxonomy())

    def assess(self, scan: Scan, recorded: frozenset[str], k: int = 3) -> QuickState:
        """The prediction of the partial ``scan`` from its ``recorded`` steps, the stop and the next step."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the features of the steps not recorded are NaN by design
            values = extract(scan)
        x = np.array([values.get(c, np.nan) for c in self.columns], dtype=np.float64)
        ratios, novelty = self.model.ratios(x), self.model.novelty(x)
        p = self.model.predict(ratios, recorded)
        top = np.argsort(-p, kind="stable")[:k]
        predictions = name_predictions([(str(self.model.classes[i]), float(p[i])) for i in top], self.taxonomy)
        accepted = self.model.accepts(novelty, recorded, int(top[0]))
        decided = bool(recorded) and accepted and float(p.max()) >= STOP_AT
        step = None if decided else next_step(self.model, ratios, recorded, self.seconds)
        return QuickState(predictions, recorded, sum(self.seconds[s] for s in recorded), decided, accepted, step,
                          self._reason(ratios, recorded, step, predictions))

    def _reason(self, ratios: np.ndarray, recorded: frozenset[str], step: str | None,
                predictions: list[Prediction]) -> str:
        if step is None:
            return ""
        a, b, swing = contrast(self.model, ratios, recorded, step)
        first, second = (self.taxonomy_name(str(self.model.classes[i])) for i in (a, b))
        if not recorded:
            return f"the {step_words(step)} tells the most trained materials apart per second"
        if swing >= 1.0:
            return f"the {step_words(step)} separates {first} from {second}"
        return f"the {step_words(step)} adds the most information per second about {first}"

    def taxonomy_name(self, label: str) -> str:
        """The material's name, without its classes: ``granite``."""
        return _names(label, self.taxonomy).split(" (", 1)[0]


MODEL_LEVELS = ("coarse", "medium", "fine")
"""The levels of the taxonomy a model of scans predicts; a label's class at each is ``Label.at(level)``."""


@dataclass(frozen=True)
class LabelCheck:
    """Why the operator's label and the model's prediction disagree (one line), and the label the model
    predicts where it predicts whole labels (level ``fine``), offered in place of the operator's."""

    message: str
    predicted: str | None


def _named(label: str, taxonomy: Taxonomy) -> str:
    try:
        return f"{taxonomy.describe(label)} ({label})"
    except (LabelError, UnknownLabelError):
        return label


def check_label(label: str, prediction: ScanPrediction, model: TrainedModel, taxonomy: Taxonomy) -> LabelCheck | None:
    """The operator's ``label`` against the model's ``prediction`` of the scan, at the level the model
    predicts: None where they agree (or the scan is an unknown material, which the prediction says itself, or
    the model predicts free labels), else a :class:`LabelCheck` when the label names a class the model was
    never trained on, or differs from its most probable class."""
    if model.level not in MODEL_LEVELS or not prediction.predictions:
        return None
    try:
        mine = Label.parse(label).at(model.level)
    except LabelError:
        return None
    best = prediction.predictions[0]
    offered = best.label if model.level == "fine" and not prediction.unknown else None  # not a material it rejects
    predicted = f"the model predicts {best.names} ({best.label}) at {100 * best.probability:.1f} %"
    if mine not in model.classes:
        return LabelCheck(f"your label {_named(label, taxonomy)} names a class the model was never trained on "
                          f"({mine} at level {model.level}); {predicted}", offered)
    if prediction.unknown or best.label == mine:
        return None
    return LabelCheck(f"your label {_named(label, taxonomy)} differs from the prediction at level {model.level}: "
                      f"{predicted}", offered)


def format_predictions(prediction: ScanPrediction | Sequence[Prediction]) -> str:
    """Lines like ``1. C6S1M1P2X1   82.0 %  granite (igneous stone, stone), polished, plain``, after a first
    line ``unknown material (closest: ...): <why>`` when the model's rule rejects the scan."""
    head = []
    if isinstance(prediction, ScanPrediction):
        if prediction.unknown:
            head = [f"{prediction.headline()}; rejection score {prediction.score:.2f} > threshold "
                    f"{prediction.threshold:.2f}; the most probable trained materials:"]
        prediction = prediction.predictions
    width = max((len(p.label) for p in prediction), default=0)
    return "\n".join(head + [f"{rank}. {p.label:<{width}}  {100 * p.probability:5.1f} %  {p.names}"
                             for rank, p in enumerate(prediction, start=1)])
