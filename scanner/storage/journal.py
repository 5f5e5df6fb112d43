"""Writing scans into a database crash-safely: every file written atomically, the catalog rows committed in
one transaction, and a ``.pending`` record of the files a write puts into ``scans/`` until it commits, so
that a process killed at any moment leaves nothing, or leftovers the record names (module docstring of
:mod:`scanner.storage.database`)."""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import sqlite3
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from scanner.scan import IMAGES, Scan, ScanMeta, check_sample_id
from scanner.storage.catalog import (
    PENDING,
    SCANS,
    Catalog,
    DatabaseError,
    FileEntry,
    catalog_call,
    content_hash,
    file_roles,
)
from scanner.storage.files import (
    atomic_write_bytes,
    fsync_dir,
    is_temp_file,
    sha256_file,
)
from scanner.storage.matfile import photo_file_name, save_scan


@dataclass(frozen=True)
class _Intent:
    """A ``.pending`` record: the scans a write is adding and the files it puts into ``scans/``."""

    record: Path
    scan_ids: tuple[str, ...]
    files: tuple[str, ...]


class FileJournal(Catalog):
    """Adding scans (one, or an imported batch whose files are already written) under the write journal."""

    @catalog_call
    def add(self, scan: Scan) -> str:
        """Store a scan (files, then catalog rows in one transaction); returns its scan id.

        Refuses a scan id that is already stored and a sample id that belongs to another material. Crash
        leftovers of earlier writes are removed first. If anything fails, the files written are removed.
        """
        mat_path = self.scan_path(scan)
        roles = file_roles(mat_path, scan)
        with self._transaction() as conn:
            self._discard_uncommitted(conn)
            _refuse_clash(conn, scan.meta)
            intent = self._begin_intent([scan.scan_id], [path for path, _ in roles])
            try:
                save_scan(scan, mat_path)
                self._insert(conn, scan.meta, self._entries(roles))
            except BaseException:
                self._undo(intent)
                raise
        self._end_intent(intent)
        return scan.scan_id

    @catalog_call
    def add_written(self, staged: Sequence[tuple[ScanMeta, Mapping[str, Path]]]) -> list[str]:
        """Catalog scans whose files are already complete on this file system, all in one transaction.

        For import, which keeps another lab's bytes exactly. ``staged`` pairs each scan's meta with its files
        by role (``"mat"`` and photo variables such as ``"I_disp"``), written and fsync'ed, named as
        :func:`save_scan` names them. Under the write lock every scan is first checked as in :meth:`add`,
        also against the others of the batch, and its catalog rows are inserted; only then are the files
        moved into place with ``os.replace`` (photos first, the ``.mat`` last), and all rows are committed
        together. If a check, an insert or a move fails, every file moved so far is moved back and the
        catalog is unchanged. A crash leaves the catalog as it was and, at worst, crash leftovers that the
        next write or :meth:`repair` removes. Returns the scan ids.
        """
        with self._transaction() as conn:
            self._discard_uncommitted(conn)
            samples: dict[str, str] = {}
            ids: set[str] = set()
            for meta, files in staged:
                if meta.scan_id in ids:
                    raise DatabaseError(f"scan {meta.scan_id} is staged twice")
                _refuse_clash(conn, meta, samples)
                _check_staged_names(meta, files)
                samples[meta.sample_id] = meta.label
                ids.add(meta.scan_id)
            moves = [(meta, self._placement(meta, files)) for meta, files in staged]
            for meta, placement in moves:
                self._insert(conn, meta, [FileEntry(self._relative(target), role, sha256_file(source),
                                                    source.stat().st_size) for source, target, role in placement])
            intent = self._begin_intent(list(ids), [target for _, placement in moves for _, target, _ in placement])
            moved: list[tuple[Path, Path]] = []
            try:
                for _, placement in moves:
                    for source, target, _ in placement:
                        target.parent.mkdir(parents=True, exist_ok=True)
                        os.replace(source, target)
                        moved.append((source, target))
                    fsync_dir(placement[-1][1].parent)
            except BaseException:
                for source, target in reversed(moved):
                    with contextlib.suppress(OSError):
                        os.replace(target, source)
                self._undo(intent)
                raise
        self._end_intent(intent)
        return [meta.scan_id for meta, _ in staged]

    def _placement(self, meta: ScanMeta, files: Mapping[str, Path]) -> list[tuple[Path, Path, str]]:
        """``(staged file, target, role)`` of one scan, photos first and the ``.mat`` last."""
        folder = self.root / SCANS / meta.label / check_sample_id(meta.sample_id)
        return [(files[role], folder / files[role].name, role) for role in sorted(files, key=lambda r: r == "mat")]

    def _entries(self, files: Iterable[tuple[Path, str]]) -> list[FileEntry]:
        return [FileEntry(self._relative(path), role, sha256_file(path), path.stat().st_size)
                for path, role in files]

    def _insert(self, conn: sqlite3.Connection, meta: ScanMeta, entries: list[FileEntry]) -> None:
        mat = next(e for e in entries if e.role == "mat")
        conn.execute("INSERT OR IGNORE INTO materials VALUES (?)", (meta.label,))
        conn.execute("INSERT OR IGNORE INTO samples VALUES (?, ?)", (meta.sample_id, meta.label))
        conn.execute("INSERT OR IGNORE INTO sessions VALUES (?, ?, ?)",
                     (meta.session_id, meta.operator, meta.started))
        conn.execute("INSERT INTO scans VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                     (meta.scan_id, meta.label, meta.sample_id, meta.session_id, meta.operator,
                      meta.scan_index, meta.started, int(meta.rigid), mat.path, content_hash(entries),
                      datetime.now(UTC).isoformat(timespec="seconds"), meta.steps))
        conn.executemany("INSERT INTO files VALUES (?, ?, ?, ?, ?)",
                         [(e.path, meta.scan_id, e.role, e.sha256, e.size) for e in entries])

    def _begin_intent(self, scan_ids: Iterable[str], files: Iterable[Path]) -> _Intent:
        """Record (atomically, before any of them is written) the files a write puts into ``scans/``."""
        folder = self.root / PENDING
        folder.mkdir(exist_ok=True)
        intent = _Intent(folder / f"{secrets.token_hex(8)}.json", tuple(sorted(scan_ids)),
                         tuple(self._relative(path) for path in files))
        atomic_write_bytes(intent.record, json.dumps({"scan_ids": intent.scan_ids, "files": intent.files}).encode())
        return intent

    def _end_intent(self, intent: _Intent) -> None:
        """The write committed: its record goes (a crash before this leaves a record of committed scans,
        which the next cleanup simply deletes)."""
        intent.record.unlink(missing_ok=True)

    def _undo(self, intent: _Intent) -> None:
        """The write failed before its commit: remove what it put into ``scans/`` (the lock is still held)."""
        for relative in intent.files:
            self._remove_file(relative, with_temps=True)
        intent.record.unlink(missing_ok=True)

    def _intents(self) -> list[_Intent]:
        intents = []
        for record in sorted((self.root / PENDING).glob("*.json")):
            try:
                content = json.loads(record.read_text(encoding="utf-8"))
                scan_ids = tuple(str(i) for i in content["scan_ids"])
                files = tuple(str(f) for f in content["files"])
            except (OSError, ValueError, KeyError, TypeError):
                continue  # not a record this program wrote: never acted on
            if all(_inside_scans(f) for f in files):
                intents.append(_Intent(record, scan_ids, files))
        return intents

    def _discard_uncommitted(self, conn: sqlite3.Connection) -> list[str]:
        """Under the write lock: remove the files of every pending write that never committed (a crash),
        every record, and the staging folders of killed imports; returns what was removed. Cheap when
        there is nothing to do: two directory listings."""
        removed = []
        for folder in self._abandoned_staging():
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(f"{folder.name}/")
        intents = self._intents()
        if not intents:
            return removed
        catalogued_ids = {row[0] for row in conn.execute("SELECT scan_id FROM scans")}
        for intent in intents:
            if not catalogued_ids & set(intent.scan_ids):
                removed += [f for f in intent.files if self._remove_file(f, with_temps=True, conn=conn)]
            intent.record.unlink(missing_ok=True)
        return removed

    def _remove_file(self, relative: str, *, with_temps: bool = False,
                     conn: sqlite3.Connection | None = None) -> bool:
        """Delete an uncatalogued file under ``scans/`` (and the temp files of its interrupted writes), then
        its folders if that left them empty. True if the file was there."""
        if conn is not None and conn.execute("SELECT 1 FROM files WHERE path = ?", (relative,)).fetchone():
            return False
        path = self.root / relative
        if with_temps:
            for temp in path.parent.glob(f".{_glob_escape(path.name)}.tmp-*"):
                if is_temp_file(temp):
                    temp.unlink(missing_ok=True)
        existed = path.is_file()
        path.unlink(missing_ok=True)
        self._prune_folders(path.parent)
        return existed

    def _prune_folders(self, folder: Path) -> None:
        scans = self.root / SCANS
        while folder != scans and scans in folder.parents:
            try:
                folder.rmdir()
            except OSError:
                return
            folder = folder.parent


def _inside_scans(relative: str) -> bool:
    """A path a pending record may name: under ``scans/``, relative, no ``..``."""
    parts = relative.split("/")
    return parts[0] == SCANS and len(parts) > 1 and not any(part in ("", ".", "..") for part in parts)


def _glob_escape(name: str) -> str:
    return "".join(f"[{ch}]" if ch in "*?[" else ch for ch in name)


def _refuse_clash(conn: sqlite3.Connection, meta: ScanMeta, batch: Mapping[str, str] | None = None) -> None:
    """Refuse a stored scan id and a sample id that belongs to another material (here or in ``batch``)."""
    batch = batch or {}
    if conn.execute("SELECT 1 FROM scans WHERE scan_id = ?", (meta.scan_id,)).fetchone():
        raise DatabaseError(f"scan {meta.scan_id} is already in the database; "
                            "a new scan of this sample needs a new scan index")
    row = conn.execute("SELECT label FROM samples WHERE sample_id = ?", (meta.sample_id,)).fetchone()
    known = row[0] if row else batch.get(meta.sample_id)
    if known is not None and known != meta.label:
        raise DatabaseError(f"sample {meta.sample_id} is {known} in the database, not {meta.label}")


def _check_staged_names(meta: ScanMeta, files: Mapping[str, Path]) -> None:
    mat_path = Path(f"{meta.scan_id}.mat")
    expected = {"mat": mat_path.name, **{var: photo_file_name(mat_path, var) for var in IMAGES}}
    for role, path in files.items():
        if expected.get(role) != path.name:
            raise DatabaseError(f"scan {meta.scan_id}: staged file {path.name} cannot have role {role!r}")
    if "mat" not in files:
        raise DatabaseError(f"scan {meta.scan_id}: no staged .mat file")
