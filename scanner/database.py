"""The scan database: a folder of ``.mat`` files and photos plus a SQLite catalog (SPEC section 3).

Layout::

    <root>/catalog.sqlite                          SQLite in WAL mode: materials, samples, sessions, scans,
                                                   files (SHA-256 of every stored file), feature cache
    <root>/scans/<label>/<sample>/<scan_id>.mat    one scan, MATLAB v5
    <root>/scans/<label>/<sample>/<scan_id>_disp.png  ... its photos
    <root>/taxonomy.csv                            optional taxonomy extension: material codes this database
                                                   uses beyond the shipped table (e.g. added by an import)

The files are the truth; the catalog is an index that :meth:`Database.rebuild` recreates from them.

Crash safety of :meth:`Database.add`: the SQLite write lock is taken first (so two writers never write
the same scan's files), every file is written atomically (temp file + fsync + rename), and only then are
the catalog rows inserted and committed in one transaction. A process killed at any moment leaves either
no trace, a leftover temp file, or complete files without a catalog row (reported as "unknown" by
:meth:`check` and overwritten by the next add of that scan); never a row pointing to a missing or partial
file, and never a change to earlier scans. :meth:`Database.add_written` (import) moves complete files
into place under the same lock and catalogs a whole batch in one transaction, with the same guarantees.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import sqlite3
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from scanner.files import fsync_dir, is_temp_file, sha256_file
from scanner.matfile import ScanFormatError, load_scan, photo_file_name, save_scan, scan_files
from scanner.scan import IMAGES, Scan, ScanMeta, check_sample_id
from taxonomy.labels import parse_prefix

if TYPE_CHECKING:
    from taxonomy.table import Taxonomy

CATALOG = "catalog.sqlite"
SCANS = "scans"
TAXONOMY = "taxonomy.csv"
CATALOG_SCHEMA = 1

_SCHEMA = """
CREATE TABLE IF NOT EXISTS info (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS materials (label TEXT PRIMARY KEY);
CREATE TABLE IF NOT EXISTS samples (
    sample_id TEXT PRIMARY KEY,
    label TEXT NOT NULL REFERENCES materials(label)
);
CREATE TABLE IF NOT EXISTS sessions (
    session_id TEXT PRIMARY KEY,
    operator TEXT NOT NULL,
    started TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS scans (
    scan_id TEXT PRIMARY KEY,
    label TEXT NOT NULL REFERENCES materials(label),
    sample_id TEXT NOT NULL REFERENCES samples(sample_id),
    session_id TEXT NOT NULL REFERENCES sessions(session_id),
    operator TEXT NOT NULL,
    scan_index INTEGER NOT NULL,
    started TEXT NOT NULL,
    rigid INTEGER NOT NULL,
    path TEXT NOT NULL UNIQUE,
    content_hash TEXT NOT NULL,
    added TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS scans_label ON scans(label);
CREATE INDEX IF NOT EXISTS scans_sample ON scans(sample_id);
CREATE INDEX IF NOT EXISTS scans_session ON scans(session_id);
CREATE INDEX IF NOT EXISTS scans_operator ON scans(operator);
CREATE TABLE IF NOT EXISTS files (
    path TEXT PRIMARY KEY,
    scan_id TEXT NOT NULL REFERENCES scans(scan_id) ON DELETE CASCADE,
    role TEXT NOT NULL,
    sha256 TEXT NOT NULL,
    size INTEGER NOT NULL
);
CREATE INDEX IF NOT EXISTS files_scan ON files(scan_id);
CREATE TABLE IF NOT EXISTS feature_cache (
    content_hash TEXT NOT NULL,
    code_version TEXT NOT NULL,
    values_json TEXT NOT NULL,
    PRIMARY KEY (content_hash, code_version)
);
"""


class DatabaseError(RuntimeError):
    """The database cannot do what was asked; the message says why in one line."""


@dataclass(frozen=True)
class ScanRecord:
    """One catalog row: where a scan is and what it is, without loading its traces."""

    scan_id: str
    label: str
    sample_id: str
    session_id: str
    operator: str
    scan_index: int
    started: str
    rigid: bool
    path: str
    content_hash: str
    added: str


@dataclass(frozen=True)
class FileEntry:
    path: str
    role: str
    sha256: str
    size: int


@dataclass
class CheckReport:
    """Result of :meth:`Database.check`: paths relative to the database root."""

    checked: int = 0
    missing: list[str] = field(default_factory=list)
    changed: list[str] = field(default_factory=list)
    unknown: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not (self.missing or self.changed or self.unknown)


@dataclass
class RebuildReport:
    """Result of :meth:`Database.rebuild`."""

    scans: int = 0
    skipped: list[str] = field(default_factory=list)
    """``"<path>: <reason>"`` for every ``.mat`` file that could not be catalogued."""


def content_hash(entries: Iterable[FileEntry]) -> str:
    """SHA-256 over the roles and SHA-256s of a scan's files: the key of the feature cache."""
    digest = hashlib.sha256()
    for entry in sorted(entries, key=lambda e: e.role):
        digest.update(f"{entry.role}:{entry.sha256}\n".encode())
    return digest.hexdigest()


def file_roles(mat_path: Path, scan: Scan) -> list[tuple[Path, str]]:
    """``(path, role)`` of each file of ``scan`` stored at ``mat_path``: role ``"mat"`` or a photo variable."""
    photos = {mat_path.with_name(f"{mat_path.stem}_{short}.png"): var for var, short in IMAGES.items()}
    return [(path, photos.get(path, "mat")) for path in scan_files(mat_path, scan)]


def is_database(root: Path) -> bool:
    """Whether ``root`` is a database folder: it holds the catalog or the scans folder."""
    return (root / CATALOG).is_file() or (root / SCANS).is_dir()


class Database:
    """A scan database at ``root`` (created if missing). Safe for concurrent readers and writers.

    Each thread gets its own SQLite connection; writers are serialised by SQLite's write lock.
    """

    def __init__(self, root: str | os.PathLike[str], *, create: bool = True) -> None:
        """Open the database at ``root``; with ``create``, make it (folder, ``scans/``, catalog) if missing.

        Without ``create`` (the commands that only read or repair), ``root`` must already be a database: a
        folder holding ``catalog.sqlite`` or ``scans/`` (a database whose catalog was lost is rebuilt from
        ``scans/``). Nothing is written into any other folder.
        """
        self.root = Path(root)
        if not create and not is_database(self.root):
            raise DatabaseError(f"{self.root}: no texplorer database here (no {CATALOG} or {SCANS}/); pass --db "
                                "PATH, or create one with 'texplorer demo', 'texplorer import' or 'texplorer scan'")
        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / SCANS).mkdir(exist_ok=True)
        self.catalog_path = self.root / CATALOG
        self._local = threading.local()
        with contextlib.suppress(DatabaseError):  # a broken catalog still allows rebuild()
            self._create_schema()

    def _create_schema(self) -> None:
        conn = self._conn
        try:
            conn.executescript(_SCHEMA)
        except sqlite3.DatabaseError as exc:
            raise DatabaseError(f"{self.catalog_path}: catalog is unreadable ({exc}); "
                                "run 'texplorer db rebuild' to recreate it from the files") from None
        conn.execute("INSERT OR IGNORE INTO info VALUES ('catalog_schema', ?)", (str(CATALOG_SCHEMA),))

    # -- connections -------------------------------------------------------------------------------

    def _connect(self) -> sqlite3.Connection:
        try:
            conn = sqlite3.connect(self.catalog_path, timeout=60.0, isolation_level=None)
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute("PRAGMA synchronous=FULL")
            conn.execute("PRAGMA foreign_keys=ON")
            conn.execute("PRAGMA busy_timeout=60000")
        except sqlite3.DatabaseError as exc:
            raise DatabaseError(f"{self.catalog_path}: catalog is unreadable ({exc}); "
                                "run 'texplorer db rebuild' to recreate it from the files") from None
        conn.row_factory = sqlite3.Row
        return conn

    @property
    def _conn(self) -> sqlite3.Connection:
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = self._local.conn = self._connect()
        return conn

    def close(self) -> None:
        """Close this thread's connection (others close when their threads end)."""
        conn = getattr(self._local, "conn", None)
        if conn is not None:
            conn.close()
            self._local.conn = None

    def __enter__(self) -> Database:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """A write transaction that holds SQLite's write lock from its first statement."""
        conn = self._conn
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield conn
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        conn.execute("COMMIT")

    # -- writing -----------------------------------------------------------------------------------

    def scan_path(self, scan: Scan) -> Path:
        """Where ``scan`` is stored: ``scans/<label>/<sample>/<scan_id>.mat``."""
        meta = scan.meta
        return self.root / SCANS / meta.label / check_sample_id(meta.sample_id) / f"{scan.scan_id}.mat"

    def next_scan_index(self, sample_id: str) -> int:
        """The scan index a new scan of ``sample_id`` should get (1 for a new sample)."""
        row = self._conn.execute("SELECT MAX(scan_index) FROM scans WHERE sample_id = ?", (sample_id,)).fetchone()
        return (row[0] or 0) + 1

    def add(self, scan: Scan) -> str:
        """Store a scan (files, then catalog rows in one transaction); returns its scan id.

        Refuses a scan id that is already stored and a sample id that belongs to another material.
        """
        mat_path = self.scan_path(scan)
        with self._transaction() as conn:
            _refuse_clash(conn, scan.meta)
            save_scan(scan, mat_path)
            self._insert(conn, scan.meta, self._entries(file_roles(mat_path, scan)))
        return scan.scan_id

    def add_written(self, staged: Sequence[tuple[ScanMeta, Mapping[str, Path]]]) -> list[str]:
        """Catalog scans whose files are already complete on this file system, all in one transaction.

        For import, which keeps another lab's bytes exactly. ``staged`` pairs each scan's meta with its files
        by role (``"mat"`` and photo variables such as ``"I_disp"``), written and fsync'ed, named as
        :func:`save_scan` names them. Under the write lock every scan is first checked as in :meth:`add`,
        also against the others of the batch (nothing is moved if one fails); then each scan's files are
        moved into place with ``os.replace`` (photos first, the ``.mat`` last) and all rows are committed
        together. A crash leaves the catalog as it was and, at worst, complete uncatalogued files that
        :meth:`check` reports as unknown and the next add of their scan overwrites. Returns the scan ids.
        """
        with self._transaction() as conn:
            samples: dict[str, str] = {}
            ids: set[str] = set()
            for meta, files in staged:
                if meta.scan_id in ids:
                    raise DatabaseError(f"scan {meta.scan_id} is staged twice")
                _refuse_clash(conn, meta, samples)
                _check_staged_names(meta, files)
                samples[meta.sample_id] = meta.label
                ids.add(meta.scan_id)
            moved = [(meta, self._move_into_place(meta, files)) for meta, files in staged]
            for meta, placed in moved:
                self._insert(conn, meta, self._entries(placed))
        return [meta.scan_id for meta, _ in staged]

    def _move_into_place(self, meta: ScanMeta, files: Mapping[str, Path]) -> list[tuple[Path, str]]:
        folder = self.root / SCANS / meta.label / check_sample_id(meta.sample_id)
        folder.mkdir(parents=True, exist_ok=True)
        placed = []
        for role in sorted(files, key=lambda r: r == "mat"):
            target = folder / files[role].name
            os.replace(files[role], target)
            placed.append((target, role))
        fsync_dir(folder)
        return placed

    def _entries(self, files: Iterable[tuple[Path, str]]) -> list[FileEntry]:
        return [FileEntry(self._relative(path), role, sha256_file(path), path.stat().st_size)
                for path, role in files]

    def _insert(self, conn: sqlite3.Connection, meta: ScanMeta, entries: list[FileEntry]) -> None:
        mat = next(e for e in entries if e.role == "mat")
        conn.execute("INSERT OR IGNORE INTO materials VALUES (?)", (meta.label,))
        conn.execute("INSERT OR IGNORE INTO samples VALUES (?, ?)", (meta.sample_id, meta.label))
        conn.execute("INSERT OR IGNORE INTO sessions VALUES (?, ?, ?)",
                     (meta.session_id, meta.operator, meta.started))
        conn.execute("INSERT INTO scans VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                     (meta.scan_id, meta.label, meta.sample_id, meta.session_id, meta.operator,
                      meta.scan_index, meta.started, int(meta.rigid), mat.path, content_hash(entries),
                      datetime.now(UTC).isoformat(timespec="seconds")))
        conn.executemany("INSERT INTO files VALUES (?, ?, ?, ?, ?)",
                         [(e.path, meta.scan_id, e.role, e.sha256, e.size) for e in entries])

    def _relative(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()

    # -- taxonomy ----------------------------------------------------------------------------------

    @property
    def taxonomy_path(self) -> Path:
        """``<root>/taxonomy.csv``: this database's taxonomy extension (absent until a lab code is needed)."""
        return self.root / TAXONOMY

    def taxonomy(self) -> Taxonomy:
        """The shipped taxonomy merged with ``$TEXPLORER_TAXONOMY`` and this database's extension, if any."""
        from taxonomy.table import load_taxonomy

        return load_taxonomy(self.taxonomy_path if self.taxonomy_path.is_file() else None)

    # -- reading -----------------------------------------------------------------------------------

    def records(self, *, label: str | None = None, sample: str | None = None, session: str | None = None,
                operator: str | None = None) -> list[ScanRecord]:
        """Catalog rows, optionally filtered; ``label`` may be a class prefix ("C6" = every stone, not C60).

        A malformed ``label`` raises ``LabelError`` naming the valid forms; lower-case letters are accepted.
        """
        clauses, params = [], []
        if label:
            clauses.append("label >= ? AND label < ?")
            params.extend(_label_range(parse_prefix(label)))
        for column, value in (("sample_id", sample), ("session_id", session), ("operator", operator)):
            if value:
                clauses.append(f"{column} = ?")
                params.append(value)
        where = f"WHERE {' AND '.join(clauses)}" if clauses else ""
        rows = self._conn.execute(f"SELECT * FROM scans {where} ORDER BY label, sample_id, scan_index", params)
        return [_record(row) for row in rows]

    def record(self, scan_id: str) -> ScanRecord:
        row = self._conn.execute("SELECT * FROM scans WHERE scan_id = ?", (scan_id,)).fetchone()
        if row is None:
            raise DatabaseError(f"no scan {scan_id!r} in {self.root}")
        return _record(row)

    def files(self, scan_id: str) -> list[FileEntry]:
        rows = self._conn.execute("SELECT path, role, sha256, size FROM files WHERE scan_id = ? ORDER BY path",
                                  (scan_id,))
        return [FileEntry(*row) for row in rows]

    def get(self, scan_id: str, *, images: bool = True) -> Scan:
        """Load a stored scan from its ``.mat`` file."""
        return load_scan(self.root / self.record(scan_id).path, images=images)

    def scans(self, records: Iterable[ScanRecord] | None = None, *, images: bool = True) -> Iterator[Scan]:
        """Load scans lazily, all of them or those of ``records``."""
        for record in self.records() if records is None else records:
            yield load_scan(self.root / record.path, images=images)

    def __len__(self) -> int:
        return self._conn.execute("SELECT COUNT(*) FROM scans").fetchone()[0]

    def summary(self) -> dict[str, int]:
        """Counts of materials, samples, sessions, scans and files."""
        return {table: self._conn.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
                for table in ("materials", "samples", "sessions", "scans", "files")}

    # -- feature cache ---------------------------------------------------------------------------

    def cached_features(self, content_hash: str, code_version: str) -> dict[str, float] | None:
        row = self._conn.execute("SELECT values_json FROM feature_cache WHERE content_hash = ? AND code_version = ?",
                                 (content_hash, code_version)).fetchone()
        if row is None:
            return None
        return {name: (math.nan if value is None else value) for name, value in json.loads(row[0]).items()}

    def store_features(self, content_hash: str, code_version: str, values: dict[str, float]) -> None:
        payload = json.dumps({k: (None if math.isnan(v) else v) for k, v in values.items()})
        with self._transaction() as conn:
            conn.execute("INSERT OR REPLACE INTO feature_cache VALUES (?, ?, ?)", (content_hash, code_version, payload))

    # -- integrity ---------------------------------------------------------------------------------

    def stored_files(self) -> list[str]:
        """Every file under ``scans/``, relative to the root (including leftovers of interrupted writes)."""
        return sorted(self._relative(p) for p in (self.root / SCANS).rglob("*") if p.is_file())

    def check(self, progress: Callable[[Iterable], Iterable] = iter) -> CheckReport:
        """Verify every catalogued file's SHA-256; report missing, changed and unknown files."""
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
        report.unknown = [p for p in self.stored_files() if p not in known]
        return report

    def rebuild(self, progress: Callable[[Iterable], Iterable] = iter) -> RebuildReport:
        """Recreate the catalog from the ``.mat`` files alone (the feature cache is kept).

        A catalog that SQLite cannot open is moved aside as ``catalog.sqlite.broken-<time>`` first.
        Files that do not load as valid scans, and second copies of a scan id, are skipped and reported.
        """
        self._set_aside_if_broken()
        report = RebuildReport()
        found: list[tuple[Scan, list[FileEntry]]] = []
        seen: dict[str, str] = {}
        mats = sorted(p for p in (self.root / SCANS).rglob("*.mat") if not is_temp_file(p))
        for mat_path in progress(mats):
            relative = self._relative(mat_path)
            try:
                scan = load_scan(mat_path)
            except ScanFormatError as exc:
                report.skipped.append(f"{relative}: {str(exc).split(': ', 1)[-1]}")
                continue
            if scan.scan_id in seen:
                report.skipped.append(f"{relative}: scan id {scan.scan_id} is already in {seen[scan.scan_id]}")
                continue
            seen[scan.scan_id] = relative
            entries = [FileEntry(self._relative(p), role, sha256_file(p), p.stat().st_size)
                       for p, role in file_roles(mat_path, scan)]
            found.append((scan, entries))
        with self._transaction() as conn:
            for table in ("files", "scans", "sessions", "samples", "materials"):
                conn.execute(f"DELETE FROM {table}")
            for scan, entries in found:
                row = conn.execute("SELECT label FROM samples WHERE sample_id = ?", (scan.meta.sample_id,)).fetchone()
                if row and row[0] != scan.meta.label:
                    report.skipped.append(f"{entries[-1].path}: sample {scan.meta.sample_id} is already {row[0]}")
                    continue
                self._insert(conn, scan.meta, entries)
                report.scans += 1
        return report

    def _set_aside_if_broken(self) -> None:
        try:
            if self._conn.execute("PRAGMA quick_check").fetchone()[0] == "ok":
                self._create_schema()
                return
        except (sqlite3.DatabaseError, DatabaseError):
            pass
        self.close()
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
        for suffix in ("", "-wal", "-shm"):
            broken = self.root / (CATALOG + suffix)
            if broken.exists():
                os.replace(broken, self.root / f"{CATALOG}{suffix}.broken-{stamp}")
        self._create_schema()


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


_NEXT_PART = {"C": "S", "S": "M", "M": "P", "P": "X"}


def _label_range(prefix: str) -> tuple[str, str]:
    """Index-friendly range of labels under a class prefix: "C6" -> ["C6S", "C6S~"), a full label -> itself.

    Closing the prefix with the next part's letter keeps "C6" from matching "C60S1...".
    """
    last_letter = next((ch for ch in reversed(prefix) if ch.isalpha()), "")
    if last_letter == "X" or last_letter not in _NEXT_PART or not prefix[-1].isdigit():
        return prefix, prefix + "\x00"
    start = prefix + _NEXT_PART[last_letter]
    return start, start + "~"


def _record(row: sqlite3.Row) -> ScanRecord:
    values = dict(row)
    values["rigid"] = bool(values["rigid"])
    return ScanRecord(**values)
