"""A scan's top k with names: the model's most probable labels named by the taxonomy, whether its rejection
rule calls the scan an unknown material and why, and the operator's label checked against them."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from features import extract, feature_sets
from scanner.scan import Scan
from taxonomy.labels import Label, LabelError
from taxonomy.learning.models import TrainedModel, classify_values
from taxonomy.learning.openset import Explanation
from taxonomy.table import Taxonomy, UnknownLabelError

NOT_IN_TAXONOMY = "(not in the taxonomy table)"
"""Shown instead of the names of a predicted label the taxonomy does not know."""


# -- predict a scan's top k with names ---------------------------------------------------------------

@dataclass(frozen=True)
class Prediction:
    """One of a model's most probable labels for a scan, with the taxonomy's words for it."""

    label: str
    probability: float
    names: str


def name_predictions(top: Iterable[tuple[str, float]], taxonomy: Taxonomy) -> list[Prediction]:
    """``[(label, probability), ...]`` (:func:`taxonomy.learning.models.predict_top`) with each label's names."""
    return [Prediction(label, probability, label_names(label, taxonomy)) for label, probability in top]


def label_names(label: str, taxonomy: Taxonomy) -> str:
    """The taxonomy's words for ``label`` (``granite (igneous stone, stone), polished, plain``), or
    :data:`NOT_IN_TAXONOMY` for a label it does not know."""
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
                                                          label_names(explanation.closest, taxonomy))
    return ScanPrediction(name_predictions(verdict.top, taxonomy), verdict.unknown, verdict.score, verdict.threshold,
                          closest, explanation)


# -- the operator's label against the prediction -----------------------------------------------------

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
