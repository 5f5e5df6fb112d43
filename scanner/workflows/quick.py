"""The quick scan: its evaluation on stored full scans, and its live side, which names the most probable
materials after each step, decides when to stop and proposes the next step (docs/quick.md)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from features import REGISTRY, FeatureSpace, extract
from scanner.acquisition.config import Config
from scanner.acquisition.session import STEP_TITLES, step_seconds
from scanner.scan import Scan
from scanner.storage.database import Database
from scanner.workflows.database import extract_database
from scanner.workflows.predictions import Prediction, label_names, name_predictions
from taxonomy.learning.evaluation import EvaluationError
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
from taxonomy.table import Taxonomy


def quick_evaluation(space: FeatureSpace, config: Config | None = None, level: str = "fine", folds: int = 5,
                     seed: int = 0, workers: int | None = None, open_set: bool = False) -> QuickResult:
    """``evaluate --quick``: the stored full scans walked as quick scans in grouped folds
    (:func:`taxonomy.learning.quick.evaluate_quick`), each step taking its recording and handling time from
    ``config`` (default: the default configuration), the fixed order the procedure's."""
    seconds = step_seconds(config or Config())
    return evaluate_quick(space, seconds, tuple(seconds), level, folds, seed, workers=workers, open_set=open_set)


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
        return label_names(label, self.taxonomy).split(" (", 1)[0]
