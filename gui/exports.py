"""Export bundles built in the background for the database browser, streamed once, never kept.

A bundle of a whole database is as large as the database (hundreds of MB), so it is not built inside a
request: :meth:`Exports.start` starts an :class:`ExportJob` in a thread and the page polls its progress.
The job fills the database's feature cache first (in chunks, so it can report progress and be cancelled
between them), then calls :func:`scanner.workflows.exchange.export_database`, the same exporter as ``texplorer export``,
with the same filters (label or class prefix, session), counting the scans its progress callback hands on.

Where the bundle lives, and for how long:

- Each job builds its bundle in a private folder made by :func:`tempfile.mkdtemp` under
  ``Settings.export_dir`` (default the system's temporary folder, ``$TMPDIR``), never inside the database.
- :meth:`Exports.take` opens the finished bundle and deletes it and its folder at once; the open file keeps
  the data readable (POSIX) until the download has been sent or broken off, then the space is free. So a
  bundle is downloaded once, and nothing is left behind whether the download completes or not.
- A job nobody asks about for ``abandon_after_s`` (the page was closed) is cancelled, or its finished bundle
  deleted; :meth:`Exports.shutdown` (server stop) does the same for the job running then.
- One job at a time: a second export while one runs is refused (:class:`ExportBusy`); a finished bundle not
  yet downloaded is deleted when a new export starts. So at most one bundle is on disk, and a job is refused
  up front when the temporary folder has less free space than the scans' files take.
"""

from __future__ import annotations

import functools
import secrets
import shutil
import tempfile
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any

from scanner.runtime.local import job_workers
from scanner.storage.bundle import BundleError
from scanner.storage.database import Database, ScanRecord
from scanner.workflows.database import extract_database
from scanner.workflows.exchange import export_database
from taxonomy.errors import TexplorerError

FEATURE_CHUNK = 16
"""Scans whose features are extracted between two progress reports (and cancellation checks)."""

SPACE_MARGIN = 16 << 20
"""Free space kept beyond the scans' files: the bundle adds feature tables, manifest and zip headers."""

RUNNING = ("features", "copying")
PHASE_TEXT = {
    "features": "Computing the features of scans not in the feature cache yet",
    "copying": "Copying and checking the scans' files",
    "done": "The bundle is ready",
    "downloaded": "Downloaded, and no longer kept here",
    "failed": "The export failed",
    "cancelled": "The export was cancelled; nothing was kept",
}


class ExportError(TexplorerError, ValueError):
    """An export that cannot start or failed; one line for the page."""


class ExportBusy(ExportError):
    """Another export is running (one at a time: each takes as much space as its scans)."""

    def __init__(self, message: str, job: ExportJob) -> None:
        super().__init__(message)
        self.job = job


class _Cancelled(TexplorerError):
    """Raised inside the export to stop it; the exporter deletes its partial file on the way out."""


def filter_text(label: str | None, session: str | None) -> str:
    """``"label C6, session s-1"``, or ``"every scan"``."""
    parts = [text for text in (label and f"label {label}", session and f"session {session}") if text]
    return ", ".join(parts) or "every scan"


@dataclass
class ExportJob:
    """One export: its filters, phase and progress, and the bundle file while it waits for its download."""

    id: str
    db: Database
    records: list[ScanRecord]
    label: str | None
    session: str | None
    folder: Path
    workers: int | None = None
    license: str | None = None
    """As ``texplorer export --license``; None takes the database's setting."""
    creator: str | None = None
    phase: str = "features"
    done: int = 0
    error: str = ""
    path: Path | None = None
    name: str = ""
    size: int = 0
    started: float = field(default_factory=time.monotonic)
    last_seen: float = field(default_factory=time.monotonic)
    cancel: threading.Event = field(default_factory=threading.Event)
    thread: threading.Thread | None = None

    @property
    def total(self) -> int:
        return len(self.records)

    @property
    def running(self) -> bool:
        return self.phase in RUNNING

    @property
    def filters(self) -> str:
        return filter_text(self.label, self.session)

    def touch(self) -> None:
        """Someone is still waiting for this job."""
        self.last_seen = time.monotonic()

    def status(self) -> dict[str, Any]:
        """The job as the progress page shows it (JSON)."""
        fraction = self.done / self.total if self.total else 1.0
        if self.phase == "features":
            fraction *= 0.5  # two phases of one bar: features, then files
        elif self.phase == "copying":
            fraction = 0.5 + 0.5 * fraction
        elif self.phase in ("done", "downloaded"):
            fraction = 1.0
        text = PHASE_TEXT[self.phase]
        if self.phase in ("done", "downloaded"):
            text += f": {self.name} ({self.size / 2**20:.1f} MB)"
        count = (f"step {RUNNING.index(self.phase) + 1} of 2: {self.done} of {self.total} scans"
                 if self.running else "")
        return {"id": self.id, "phase": self.phase, "phase_text": text, "count_text": count, "done": self.done,
                "total": self.total, "fraction": round(fraction, 4), "running": self.running,
                "ready": self.phase == "done", "error": self.error, "bytes": self.size,
                "filters": self.filters, "seconds": round(time.monotonic() - self.started, 1)}

    # -- the worker thread ---------------------------------------------------------------------------

    def run(self, abandon_after_s: float) -> None:
        """Build the bundle, then keep it until it is taken, cancelled or abandoned; always clean up."""
        try:
            self._warm_feature_cache(abandon_after_s)
            self.phase, self.done = "copying", 0
            stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
            report = export_database(self.db, self.folder / f"texplorer-export-{stamp}.zip", label=self.label,
                                     session=self.session, license=self.license, creator=self.creator,
                                     workers=self.workers,
                                     progress=functools.partial(self._count, abandon_after_s=abandon_after_s))
            self.path, self.name, self.size = report.path, report.path.name, report.path.stat().st_size
            self.phase = "done"
            while not self.cancel.wait(0.5) and not self._abandoned(abandon_after_s):
                pass
        except _Cancelled:
            self.phase = "cancelled"
        except (BundleError, OSError) as exc:
            self.phase, self.error = "failed", str(exc).strip().splitlines()[0]
        except Exception as exc:  # a job thread must never die silently: the page shows why
            self.phase, self.error = "failed", f"{type(exc).__name__}: {exc}".splitlines()[0]
        finally:
            if self.phase == "done":  # not taken: cancelled or abandoned after it was built
                self.phase = "cancelled"
            self.path = None
            shutil.rmtree(self.folder, ignore_errors=True)

    def _abandoned(self, abandon_after_s: float) -> bool:
        return time.monotonic() - self.last_seen > abandon_after_s

    def _check(self, abandon_after_s: float) -> None:
        if self.cancel.is_set() or self._abandoned(abandon_after_s):
            raise _Cancelled

    def _warm_feature_cache(self, abandon_after_s: float) -> None:
        """Features of every exported scan into the cache, so the exporter only reads them. The chunks
        share one set of worker processes: forking them per chunk cost each chunk their start-up (in a server,
        the workers every request shares: ``scanner.runtime.local.share_workers``)."""
        with job_workers(self.workers) as pool:
            for start in range(0, len(self.records), FEATURE_CHUNK):
                self._check(abandon_after_s)
                extract_database(self.db, records=self.records[start:start + FEATURE_CHUNK], pool=pool,
                                 progress=False)
                self.done = min(start + FEATURE_CHUNK, len(self.records))

    def _count(self, records: Iterable[ScanRecord], abandon_after_s: float) -> Iterator[ScanRecord]:
        """The exporter's progress callback: hands on every scan, counts it, stops when cancelled."""
        for record in records:
            self._check(abandon_after_s)
            yield record
            self.done += 1


class Exports:
    """The app's export job (at most one at a time) and the files it may keep."""

    def __init__(self, db: Database, temp_root: Path | None = None, *, workers: int | None = None,
                 abandon_after_s: float = 120.0) -> None:
        self.db = db
        self.temp_root = temp_root
        self.workers = workers
        self.abandon_after_s = abandon_after_s
        self.job: ExportJob | None = None
        self._lock = threading.Lock()

    def start(self, label: str | None = None, session: str | None = None, license: str | None = None,
              creator: str | None = None) -> ExportJob:
        """Start exporting the scans matching the filters; refuses when another export is running, no scan
        matches, or the temporary folder has too little space."""
        with self._lock:
            old = self.job
            if old is not None and old.running and not old._abandoned(self.abandon_after_s):
                raise ExportBusy(f"an export of {old.filters} is running; wait for it or cancel it", old)
            if old is not None:
                self.cancel(old)  # its files are gone before the new job writes any
            records = sorted(self.db.records(label=label, session=session), key=lambda r: (r.started, r.scan_id))
            if not records:
                raise ExportError(f"no scans with {filter_text(label, session)} to export")
            root = Path(self.temp_root or tempfile.gettempdir())
            try:
                _check_space(root, sum(entry.size for r in records for entry in self.db.files(r.scan_id)))
                folder = Path(tempfile.mkdtemp(prefix="texplorer-export-", dir=root))
            except OSError as exc:
                raise ExportError(f"cannot build the bundle in {root}: {exc.strerror or exc}") from None
            job = ExportJob(secrets.token_urlsafe(16), self.db, records, label, session, folder, self.workers,
                            license, creator)
            job.thread = threading.Thread(target=job.run, args=(self.abandon_after_s,), name="export",
                                          daemon=True)
            self.job = job
            job.thread.start()
            return job

    def get(self, job_id: str) -> ExportJob | None:
        """The job with this id (it is the current one), or None."""
        job = self.job
        found = job is not None and secrets.compare_digest(job.id.encode(), job_id.encode("utf-8", "replace"))
        return job if found else None

    def take(self, job: ExportJob) -> tuple[IO[bytes], str, int]:
        """The finished bundle as an open file, its name and size; the file is deleted from disk now.

        Raises :class:`ExportError` when the job has no bundle (not finished, or already downloaded).
        """
        with self._lock:
            if job.phase != "done" or job.path is None:
                raise ExportError("this export has no bundle to download "
                                  + ("yet" if job.running else f"({PHASE_TEXT[job.phase].lower()})"))
            path = job.path
            try:
                handle = open(path, "rb")  # noqa: SIM115 -- closed by the response once sent
            except FileNotFoundError:  # deleted as abandoned a moment ago
                raise ExportError("this export was abandoned and deleted; start it again") from None
            path.unlink()
            # The bundle was the folder's last file (the job is done writing): removed now, so nothing is
            # left behind once the download starts; the thread, woken to end, finds it gone.
            shutil.rmtree(job.folder, ignore_errors=True)
            job.phase, job.path = "downloaded", None
            job.cancel.set()
            return handle, path.name, job.size

    @staticmethod
    def cancel(job: ExportJob) -> None:
        """Stop a running job or delete its finished bundle; returns when its files are gone."""
        job.cancel.set()
        if job.thread is not None:
            job.thread.join(30)

    def shutdown(self) -> None:
        """Cancel the job and delete its files (server stop)."""
        job = self.job
        if job is not None:
            self.cancel(job)


def _check_space(root: Path, needed: int) -> None:
    free = shutil.disk_usage(root).free
    if free < needed + SPACE_MARGIN:
        raise ExportError(f"not enough free space in {root} for the bundle: about "
                          f"{(needed + SPACE_MARGIN) / 2**20:.0f} MB needed, {free / 2**20:.0f} MB free "
                          "(set TMPDIR to a larger folder before 'texplorer serve', or export fewer scans)")

