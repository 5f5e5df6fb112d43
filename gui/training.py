"""Model versions trained in the background by the web application: enrolment of new or corrected materials.

The summary of a scan the model calls an unknown material (or names wrongly) offers to save it under a new or
corrected label and add it to the training set: the scan is saved, and :meth:`Trainings.start` trains a new
model version on every scan of the database (:func:`scanner.workflows.models.retrain`) while scanning goes on. The
features come from the database's cache (only new scans are extracted) and the training runs on one of the
workers every request shares, at their lower priority, so the pages stay quick. When the version is saved
it is current, and the next prediction loads it (:attr:`gui.context.Context.model`); every page says when it
is ready and what changed (classes added, cross-validated accuracy before and after).

One training at a time: a scan enrolled while one runs is trained into the next, which starts as soon as
the running one finishes (it holds every scan saved until then). A training that fails says why on the
models page; the versions before it are untouched.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from scanner.runtime.local import job_workers
from scanner.storage.database import Database
from scanner.workflows.models import ModelChange, retrain

RECENT_S = 15 * 60.0
"""How long every page says that a new model version is ready (or that a training failed)."""


@dataclass
class TrainingJob:
    """One background training: why it was started (the scans enrolled), its phase and its outcome."""

    reasons: list[str]
    phase: str = "training"
    change: ModelChange | None = None
    outcome: str = ""
    """What the pages say once the job ended: what changed, in the taxonomy's words, or why it failed."""
    started: float = field(default_factory=time.monotonic)
    finished: float | None = None

    @property
    def running(self) -> bool:
        return self.phase == "training"

    def notice(self) -> str:
        """One line for every page: running, ready (what changed) or failed."""
        if self.running:
            return (f"A new model version is being trained in the background ({', '.join(self.reasons[:3])}"
                    f"{' and more' if len(self.reasons) > 3 else ''}; {time.monotonic() - self.started:.0f} s so "
                    "far); scanning goes on, predictions use the current version until it is ready.")
        return self.outcome


class Trainings:
    """The app's background trainings: at most one runs; enrolments during it are trained next."""

    def __init__(self, db: Database, *, workers: int | None = None, seed: int = 0) -> None:
        self.db = db
        self.workers = workers
        self.seed = seed
        self.job: TrainingJob | None = None
        self._pending: list[str] = []
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None

    def start(self, reason: str) -> TrainingJob | None:
        """Train a new model version for ``reason`` (``"granite-01-003 enrolled as C6S1M1P2X1"``): now, or after
        the running training (returns None then: the next job is made when that one ends)."""
        with self._lock:
            if self._thread is not None and self._thread.is_alive():
                self._pending.append(reason)
                return None
            self.job = TrainingJob([reason])
            self._thread = threading.Thread(target=self._run, name="training", daemon=True)
            self._thread.start()
            return self.job

    @property
    def queued(self) -> list[str]:
        """Reasons waiting for the running training to end."""
        with self._lock:
            return list(self._pending)

    def recent(self) -> TrainingJob | None:
        """The running job, or the last one if it ended less than :data:`RECENT_S` ago."""
        job = self.job
        if job is None or job.running or (job.finished is not None and time.monotonic() - job.finished < RECENT_S):
            return job
        return None

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the running training and those queued behind it; True when none is left."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            thread = self._thread
            if thread is None or not thread.is_alive():
                return True
            thread.join(None if deadline is None else max(0.0, deadline - time.monotonic()))
            if deadline is not None and time.monotonic() >= deadline:
                return not thread.is_alive()

    def _run(self) -> None:
        """Train, then train again for the enrolments that arrived meanwhile, until none is left."""
        while True:
            job = self.job
            if job is None:
                return
            note = "web application: " + "; ".join(job.reasons)[:500]
            try:
                with job_workers(self.workers) as pool:
                    job.change = retrain(self.db, seed=self.seed, pool=pool, note=note)
                job.outcome = f"Ready: {job.change.describe(self.db.taxonomy())}."
                job.phase = "done"
            except Exception as exc:  # noqa: BLE001 - a job thread must never die silently: the pages say why
                reason = (f"{type(exc).__name__}: {exc}".splitlines() or ["?"])[0][:300]
                job.outcome = f"The model training failed: {reason}; the model versions before it are unchanged."
                job.phase = "failed"
            job.finished = time.monotonic()
            with self._lock:
                if not self._pending:
                    return
                self.job, self._pending = TrainingJob(self._pending), []
