"""Labelled recordings to compare methods on (our scans, imported recordings, a simulated sensor), their
motions, objects and trials, and each method's features extracted once per dataset."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from features.recordings import scan_recording
from scanner.scan import Recording, Scan
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label
from taxonomy.related.fishel_features import fishel3
from taxonomy.related.inputs import RelatedFeatureError
from taxonomy.related.sets import FEATURE_SETS, compute
from taxonomy.related.xie_features import xie_sequence_vector

SEED = 0
REPEATS = 10
"""Default repetitions of the repeated protocols (Hoelscher et al. 2015 used 100 leave-one-per-object-out splits)."""

TIMED_ROWS = 5
"""Test rows of the first split whose single-row classification time is measured (the splits' models are
alike; timing every split would cost more than the evaluation)."""


class MethodError(TexplorerError, ValueError):
    """A dataset or method that cannot be compared as asked; the message says why."""


class MethodSkipped(UserWarning):
    """An applicable method that could not run on the dataset (e.g. too few trials); the message says why."""


def _levels_of(recording: Recording) -> Mapping[str, str]:
    levels = recording.meta.get("levels", {})
    return levels if isinstance(levels, Mapping) else {}


@dataclass(frozen=True, eq=False)
class Dataset:
    """Labelled recordings (and, for our own database, the scans they come from) to compare methods on.

    ``label_level`` names the level of ``Recording.label`` (``object``, ``material``, ``fine``, ...);
    coarser levels come from ``Recording.meta["levels"]`` (e.g. ``{"material": "wood"}``).
    """

    name: str
    recordings: tuple[Recording, ...]
    scans: tuple[Scan, ...] = ()
    label_level: str = "label"

    def __post_init__(self) -> None:
        object.__setattr__(self, "recordings", tuple(self.recordings))
        object.__setattr__(self, "scans", tuple(self.scans))
        if not self.recordings:
            raise MethodError(f"dataset {self.name!r} has no recordings")
        unlabelled = next((r.name for r in self.recordings if not r.label), None)
        if unlabelled is not None:
            raise MethodError(f"dataset {self.name!r}: recording {unlabelled!r} has no label")
        if self.scans and len(self.scans) != len(self.recordings):
            raise MethodError(f"dataset {self.name!r}: {len(self.scans)} scans for "
                              f"{len(self.recordings)} recordings")

    @classmethod
    def from_recordings(cls, name: str, recordings: Iterable[Recording]) -> Dataset:
        """A dataset of recordings; the label level is the first one's ``meta["label_level"]`` ("label")."""
        recordings = tuple(recordings)
        level = str(recordings[0].meta.get("label_level", "label")) if recordings else "label"
        return cls(name, recordings, label_level=level)

    @classmethod
    def from_scans(cls, name: str, scans: Iterable[Scan]) -> Dataset:
        """Scans as recordings (:func:`features.recordings.scan_recording`) labelled at the fine, medium and
        coarse taxonomy levels."""
        scans = tuple(scans)
        recordings = []
        for scan in scans:
            label = Label.parse(scan.meta.label)
            recording = scan_recording(scan)
            recordings.append(replace(recording, meta={"levels": {"medium": label.at("medium"),
                                                                  "coarse": label.at("coarse")}}))
        return cls(name, tuple(recordings), scans, "fine")

    def __len__(self) -> int:
        return len(self.recordings)

    def levels(self) -> tuple[str, ...]:
        """The label level, then the coarser levels every recording has."""
        shared = [key for key in _levels_of(self.recordings[0])
                  if all(key in _levels_of(r) for r in self.recordings)]
        return (self.label_level, *shared)

    def y(self, level: str, rows: Sequence[int] | None = None) -> np.ndarray:
        """Classes at ``level`` of the recordings ``rows`` (default all)."""
        chosen = [self.recordings[i] for i in (range(len(self)) if rows is None else rows)]
        if level == self.label_level:
            return np.array([str(r.label) for r in chosen])
        if level not in self.levels():
            raise MethodError(f"dataset {self.name!r} has no level {level!r} "
                              f"(levels: {', '.join(self.levels())})")
        return np.array([str(_levels_of(r)[level]) for r in chosen])

    def motions(self) -> list[str]:
        """Motion names in order of first appearance (``"-"`` for recordings without one)."""
        return list(dict.fromkeys(motion_of(r) for r in self.recordings))

    def summary(self) -> str:
        """One line: recordings, objects, levels with their class counts, roles."""
        objects = {object_of(r) for r in self.recordings}
        levels = ", ".join(f"{level} ({np.unique(self.y(level)).size})" for level in self.levels())
        roles = sorted(set.intersection(*(set(r.roles) for r in self.recordings)))
        kind = f"{len(self.scans)} scans" if self.scans else f"{len(self)} recordings"
        motions = self.motions()
        moves = f", motions {', '.join(motions)}" if motions != ["-"] else ""
        return (f"{self.name}: {kind} of {len(objects)} objects; levels {levels}; "
                f"roles {', '.join(roles) or 'none'}{moves}")


def object_of(recording: Recording) -> str:
    """The object (sample) a recording was made on: group ``object``, else its label."""
    return str(recording.group.get("object", recording.label))


def motion_of(recording: Recording) -> str:
    return str(recording.group.get("motion", "-"))


def trial_of(recording: Recording) -> str:
    """``<object>/<trial>``: recordings of one trial (several motions or palpations) share it."""
    trial = recording.group.get("trial")
    return f"{object_of(recording)}/{recording.name if trial is None else trial}"


@dataclass(frozen=True)
class Extracted:
    """A feature set of every recording: ``X`` rows in recording order (NaN where extraction failed)."""

    name: str
    columns: tuple[str, ...]
    X: np.ndarray
    seconds: np.ndarray
    failed: Mapping[int, str]


def _extractor(dataset: Dataset, name: str) -> Callable[[int], Mapping[str, float] | np.ndarray]:
    if name == "fishel3":
        if not dataset.scans:
            raise MethodError(f"fishel3 needs scans; dataset {dataset.name!r} has recordings only")
        return lambda i: fishel3(dataset.scans[i])
    if name == "xie_sequences":
        return lambda i: xie_sequence_vector(dataset.recordings[i])
    return lambda i: compute(name, dataset.recordings[i])


def extract(dataset: Dataset, name: str, rows: Sequence[int] | None = None) -> Extracted:
    """Feature set ``name`` (see :data:`features.FEATURE_SETS`, plus ``fishel3`` and
    ``xie_sequences``) of the recordings ``rows``, timed per recording; failures are recorded, not raised."""
    function = _extractor(dataset, name)
    rows = range(len(dataset)) if rows is None else rows
    values: dict[int, np.ndarray] = {}
    seconds: dict[int, float] = {}
    failed: dict[int, str] = {}
    columns: tuple[str, ...] | None = None
    for i in rows:
        started = time.perf_counter()
        try:
            result = function(i)
        except (RelatedFeatureError, ValueError) as exc:
            failed[i] = str(exc)
            continue
        seconds[i] = time.perf_counter() - started
        mapping = isinstance(result, Mapping)
        names = tuple(result) if mapping else tuple(f"{name}.{k}" for k in range(len(result)))
        if columns is None:
            columns = names
        if names != columns:
            failed[i] = f"{name} gives {len(names)} values here, {len(columns)} elsewhere"
            continue
        values[i] = np.fromiter(result.values(), float) if mapping else np.asarray(result, float)
    width = len(columns or ())
    X = np.full((len(dataset), width), np.nan)
    times = np.full(len(dataset), np.nan)
    for i, row in values.items():
        X[i] = row
        times[i] = seconds[i]
    return Extracted(name, columns or (), X, times, failed)


class ExtractedSets:
    """Feature sets extracted once per dataset and shared by the methods of one :func:`compare` run."""

    def __init__(self, dataset: Dataset) -> None:
        self.dataset = dataset
        self._sets: dict[str, Extracted] = {}

    def get(self, name: str) -> Extracted:
        if name not in self._sets:
            self._sets[name] = extract(self.dataset, name)
        return self._sets[name]


def slides_first(dataset: Dataset, rows: Sequence[int]) -> tuple[list[int], str]:
    """Xie and Huang classify slides: keep the sliding motions when the dataset has named motions."""
    slides = [i for i in rows if "slide" in motion_of(dataset.recordings[i])]
    return (slides, "slides") if slides else (list(rows), "all")


def every(dataset: Dataset, set_name: str) -> bool:
    return all(FEATURE_SETS[set_name].applies_to(r) for r in dataset.recordings)
