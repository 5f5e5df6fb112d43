"""Checking, repairing and rebuilding a scan database: every file's SHA-256 against the catalog, the leftovers
of interrupted writes removed, and the catalog recreated from the files, with what cannot be catalogued moved
to ``quarantine/``."""

from __future__ import annotations

import os
import shutil
import sqlite3
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from scanner.scan import Scan
from scanner.storage.catalog import (
    CATALOG,
    CATALOG_SCHEMA,
    MODELS,
    PHOTO_SUFFIXES,
    QUARANTINE,
    RECORDINGS,
    SCANS,
    SCHEMA,
    STAGING_PREFIX,
    DatabaseError,
    FileEntry,
    catalog_call,
    file_roles,
)
from scanner.storage.files import (
    fsync_dir,
    is_abandoned,
    is_temp_file,
    recover_swaps,
    remove_stale_temp_files,
    sha256_file,
    stale_temp_files,
    swap_leftovers,
    temp_path_for,
)
from scanner.storage.journal import FileJournal
from scanner.storage.matfile import ScanFormatError, load_scan


@dataclass
class CheckReport:
    """Result of :meth:`Database.check`: paths relative to the database root.

    ``missing``, ``changed`` and ``unknown`` (a file no scan owns) are problems; ``leftovers`` are what an
    interrupted write leaves (temp files, the files of a write that never committed, photos without their
    ``.mat``, the staging folder of a killed import), which :meth:`Database.repair` removes.
    """

    checked: int = 0
    missing: list[str] = field(default_factory=list)
    changed: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)
    leftovers: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not (self.missing or self.changed or self.unknown)


@dataclass
class RebuildReport:
    """Result of :meth:`Database.rebuild`."""

    scans: int = 0
    skipped: list[str] = field(default_factory=list)
    """``"<path>: <reason>"`` for every ``.mat`` file that could not be catalogued."""
    quarantine: Path | None = None
    """Where those files (with their photos) were moved, or None if there were none."""
    removed: list[str] = field(default_factory=list)
    """Crash leftovers removed on the way."""


class Maintenance(FileJournal):
    """``check``, ``repair`` and ``rebuild`` of the database (``texplorer db check|repair|rebuild``)."""

    def stored_files(self) -> list[str]:
        """Every file under ``scans/``, relative to the root (including leftovers of interrupted writes)."""
        return sorted(self._relative(p) for p in (self.root / SCANS).rglob("*") if p.is_file())

    @catalog_call
    def check(self, progress: Callable[[Iterable], Iterable] = iter) -> CheckReport:
        """Verify every catalogued file's SHA-256; report missing, changed and unknown files, and leftovers.

        Runs without the write lock, so a write in progress at that moment may show as leftovers;
        :meth:`repair` decides under the lock.
        """
        report = CheckReport()
        known = {}
        for row in progress(self._conn.execute("SELECT path, sha256 FROM files ORDER BY path").fetchall()):
            path, digest = row
            known[path] = digest
            report.checked += 1
            full = self.root / path
            if not full.is_file():
                report.missing.append(path)
            elif sha256_file(full) != digest:
                report.changed.append(path)
        stored = self.stored_files()
        ids = {row[0] for row in self._conn.execute("SELECT scan_id FROM scans")}
        leftovers = set(self._leftovers(stored, set(known), ids))
        report.unknown = [p for p in stored if p not in known and p not in leftovers]
        report.leftovers = sorted(leftovers) + [f"{folder.name}/" for folder in self._abandoned_staging()]
        report.leftovers += recording_leftovers(self.root)
        return report

    def _leftovers(self, stored: list[str], catalogued: set[str], ids: set[str] | None) -> list[str]:
        """Uncatalogued files under ``scans/`` that a crash left: temp files, photos whose ``.mat`` is not
        beside them (photos are written first), and, given the catalogued scan ``ids``, the files of
        pending writes that never committed."""
        present = set(stored)
        found = {path for path in stored if is_temp_file(Path(path))}
        for path in stored:
            stem = _photo_stem(path)
            if stem is not None and f"{stem}.mat" not in present:
                found.add(path)
        for intent in self._intents() if ids is not None else ():
            if not ids & set(intent.scan_ids):
                found.update(f for f in intent.files if f in present)
        return sorted(found - catalogued)

    def _abandoned_staging(self) -> list[Path]:
        """Import staging folders whose importer is no longer running (:func:`scanner.storage.files.is_abandoned`)."""
        return sorted(p for p in self.root.glob(f"{STAGING_PREFIX}.tmp-*")
                      if p.is_dir() and is_temp_file(p) and is_abandoned(p))

    @catalog_call
    def repair(self) -> list[str]:
        """Remove the crash leftovers :meth:`check` lists, under the write lock (nothing in flight is
        touched), and finish or undo a recording set's replacement that a killed ingest left
        (:func:`scanner.storage.files.recover_swaps`); returns their paths. Files that belong to no scan and
        are not leftovers stay."""
        with self._transaction() as conn:
            removed = self._remove_leftovers(conn)
        return removed + repair_recordings(self.root)

    def _remove_leftovers(self, conn: sqlite3.Connection) -> list[str]:
        removed = self._discard_uncommitted(conn)
        catalogued = {row[0] for row in conn.execute("SELECT path FROM files")}
        ids = {row[0] for row in conn.execute("SELECT scan_id FROM scans")}
        for relative in self._leftovers(self.stored_files(), catalogued, ids):
            self._remove_file(relative)
            removed.append(relative)
        return sorted(set(removed))

    @catalog_call
    def rebuild(self, progress: Callable[[Iterable], Iterable] = iter) -> RebuildReport:
        """Recreate the catalog from the ``.mat`` files alone; every good file is catalogued.

        A file that does not load as a valid scan (or that the catalog refuses), a second copy of a scan id
        (the copy at the scan's own path wins), a scan whose sample is another material elsewhere, and a
        photo left without its scan (its ``.mat`` gone or bad) are reported with the reason and moved to
        ``quarantine/<time>/`` after the new catalog is committed, ``.mat`` files with their photos.
        Crash leftovers are removed first. With a readable catalog this is one transaction under the
        write lock (the feature cache is kept); a catalog SQLite cannot read is rebuilt beside it and
        swapped in, and kept as ``catalog.sqlite.broken-<time>``.
        """
        report = RebuildReport()
        if self._readable():
            with self._transaction() as conn:
                report.removed = self._remove_leftovers(conn)
                previous = {row[0] for row in conn.execute("SELECT path FROM files")}
                found, bad = self._survey(progress)
                for table in ("files", "scans", "sessions", "samples", "materials"):
                    conn.execute(f"DELETE FROM {table}")
                report.scans, refused = self._fill(conn, found)
                now = {row[0] for row in conn.execute("SELECT path FROM files")}
            bad += refused
            with_their_mat = {path[:-len(".mat")] for path, _ in bad if path.endswith(".mat")}
            bad += [(path, "a photo whose scan's .mat is missing") for path in sorted(previous - now)
                    if path.endswith(PHOTO_SUFFIXES) and _photo_stem(path) not in with_their_mat]
        else:
            report.removed = [p for p in self.stored_files() if is_temp_file(Path(p))]
            for relative in report.removed:
                self._remove_file(relative)
            # Without a catalog nobody can say whether a photo without its .mat was ever part of a scan.
            orphans = self._leftovers(self.stored_files(), set(), None)
            found, bad = self._survey(progress)
            report.scans, refused = self._replace_broken_catalog(found)
            bad += refused + [(path, "a photo without its .mat") for path in orphans]
            for intent in self._intents():  # the pending scans were adopted: their records are done
                intent.record.unlink(missing_ok=True)
        report.skipped = [f"{path}: {reason}" for path, reason in bad]
        report.quarantine = self._quarantine([path for path, _ in bad])
        return report

    def _readable(self) -> bool:
        try:
            if self._conn.execute("PRAGMA quick_check").fetchone()[0] != "ok":
                return False
            self._create_schema()
        except (sqlite3.Error, DatabaseError):
            return False
        return True

    def _survey(self, progress: Callable[[Iterable], Iterable]) -> tuple[list[tuple[Scan, list[FileEntry]]],
                                                                          list[tuple[str, str]]]:
        """Every ``.mat`` under ``scans/``, loaded and validated: the scans to catalogue with their file
        entries, and ``(path, reason)`` of the files that cannot be."""
        loaded: list[tuple[Path, Scan]] = []
        bad: list[tuple[str, str]] = []
        mats = sorted(p for p in (self.root / SCANS).rglob("*.mat") if p.is_file() and not is_temp_file(p))
        for mat_path in progress(mats):
            try:
                loaded.append((mat_path, load_scan(mat_path)))
            except ScanFormatError as exc:
                reason = exc.reason if exc.field is None else f"{exc.field}: {exc.reason}"
                bad.append((self._relative(mat_path), reason))
        # The copy at a scan's own path wins over copies elsewhere; then the first in path order.
        loaded.sort(key=lambda item: (item[0] != self.scan_path(item[1]), item[0]))
        found, owner, sample_label = [], {}, {}
        for mat_path, scan in loaded:
            relative, meta = self._relative(mat_path), scan.meta
            if scan.scan_id in owner:
                bad.append((relative, f"scan id {scan.scan_id} is already in {owner[scan.scan_id]}"))
            elif sample_label.setdefault(meta.sample_id, (meta.label, relative))[0] != meta.label:
                label, where = sample_label[meta.sample_id]
                bad.append((relative, f"sample {meta.sample_id} is {label} in {where}"))
            else:
                owner[scan.scan_id] = relative
                found.append((scan, [FileEntry(self._relative(p), role, sha256_file(p), p.stat().st_size)
                                     for p, role in file_roles(mat_path, scan)]))
        return found, sorted(bad)

    def _fill(self, conn: sqlite3.Connection, found: list[tuple[Scan, list[FileEntry]]]) -> tuple[int, list]:
        """Insert every scan in its own savepoint, so one the catalog refuses does not stop the others."""
        inserted, refused = 0, []
        for scan, entries in found:
            conn.execute("SAVEPOINT scan")
            try:
                self._insert(conn, scan.meta, entries)
            except (sqlite3.Error, OverflowError, ValueError) as exc:
                conn.execute("ROLLBACK TO scan")
                refused.append((entries[-1].path, f"the catalog refused it ({exc})"))
            else:
                inserted += 1
            conn.execute("RELEASE scan")
        return inserted, refused

    def _replace_broken_catalog(self, found: list[tuple[Scan, list[FileEntry]]]) -> tuple[int, list]:
        """Build a new catalog beside the broken one, then swap it in: there is always a catalog file, and a
        crash before the swap leaves the broken one (and a temp file) as they were."""
        for stale in self.root.glob(f".{CATALOG}.tmp-*"):
            stale.unlink(missing_ok=True)
        temp = temp_path_for(self.catalog_path)
        conn = sqlite3.connect(temp, isolation_level=None)
        try:
            conn.executescript(SCHEMA)
            conn.execute("INSERT INTO info VALUES ('catalog_schema', ?)", (str(CATALOG_SCHEMA),))
            conn.execute("PRAGMA foreign_keys=ON")
            conn.execute("BEGIN IMMEDIATE")
            result = self._fill(conn, found)
            conn.execute("COMMIT")
            conn.execute("PRAGMA journal_mode=WAL")
        finally:
            conn.close()
        with open(temp, "rb+") as handle:
            os.fsync(handle.fileno())
        self.close()
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
        for suffix in ("-wal", "-shm"):  # a stale WAL must never be applied to the new file
            side = self.root / (CATALOG + suffix)
            if side.exists():
                os.replace(side, _unused(self.root / f"{CATALOG}{suffix}.broken-{stamp}"))
        if self.catalog_path.exists():
            kept = _unused(self.root / f"{CATALOG}.broken-{stamp}")
            try:
                os.link(self.catalog_path, kept)
            except OSError:
                shutil.copy2(self.catalog_path, kept)
        os.replace(temp, self.catalog_path)
        fsync_dir(self.root)
        return result

    def _quarantine(self, paths: list[str]) -> Path | None:
        """Move files (a ``.mat`` with its photos) out of ``scans/`` into ``quarantine/<time>/``."""
        if not paths:
            return None
        folder = _unused(self.root / QUARANTINE / datetime.now(UTC).strftime("%Y%m%dT%H%M%S"))
        for relative in paths:
            path = self.root / relative
            photos = [path.with_name(f"{path.stem}{end}") for end in PHOTO_SUFFIXES] if path.suffix == ".mat" else []
            for moving in [*photos, path]:
                if moving.is_file():
                    target = folder / self._relative(moving)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    os.replace(moving, target)
            self._prune_folders(path.parent)
        fsync_dir(folder)
        return folder


def _unused(path: Path) -> Path:
    """``path``, or ``path-2``, ``path-3``, ... the first name not taken (two runs in the same second)."""
    candidate, n = path, 1
    while candidate.exists() or candidate.is_symlink():
        n += 1
        candidate = path.with_name(f"{path.name}-{n}")
    return candidate


def _photo_stem(path: str) -> str | None:
    """``scans/.../x-001`` for a photo ``scans/.../x-001_disp.png`` (or ``_macro``, ``_illu``), else None."""
    return next((path[:-len(end)] for end in PHOTO_SUFFIXES if path.endswith(end)), None)


def recording_leftovers(root: str | os.PathLike[str]) -> list[str]:
    """What killed ingests and trainings left in a database folder outside its catalog, as paths relative to
    it: staging and swap folders of recording sets, temporary model files (:func:`stale_temp_files`). Works
    on a folder holding only recording sets (no catalog)."""
    root = Path(root)
    return ([f"{RECORDINGS}/{folder.name}/" for folder in swap_leftovers(root / RECORDINGS)]
            + [f"{MODELS}/{path.name}" for path in stale_temp_files(root / MODELS)])


def repair_recordings(root: str | os.PathLike[str]) -> list[str]:
    """:meth:`Database.repair`'s part outside the catalog, for a folder holding only recording sets: finish
    or undo interrupted set replacements and remove stale model temporaries; returns what was done."""
    root = Path(root)
    return ([f"{RECORDINGS}/{line}" for line in recover_swaps(root / RECORDINGS)]
            + [f"{MODELS}/{path.name}" for path in remove_stale_temp_files(root / MODELS)])
