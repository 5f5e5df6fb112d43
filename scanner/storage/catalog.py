"""The catalog of a scan database: the SQLite index of its scans and files, one connection per thread, and the
queries (docs/database.md). :class:`~scanner.storage.database.Database` adds writing, repair and the feature cache."""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import sqlite3
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Self

from scanner.scan import IMAGES, Scan, check_sample_id
from scanner.storage.matfile import load_scan, scan_files
from scanner.storage.stored import StatLedger, StoredScan
from taxonomy.errors import TexplorerError
from taxonomy.table import Taxonomy, load_taxonomy, material_code, select_labels

CATALOG = "catalog.sqlite"


SCANS = "scans"


RECORDINGS = "recordings"
"""Imported recording sets (``texplorer ingest``, :mod:`scanner.storage.ingest`): checked for the leftovers
of killed ingests, not catalogued."""


MODELS = "models"
"""Trained models (``texplorer train``, the demo's): checked for the temporary files of killed writes."""


TAXONOMY = "taxonomy.csv"


PENDING = ".pending"


QUARANTINE = "quarantine"


STAGING_PREFIX = ".import"
"""Import stages a bundle in ``<root>/.import.tmp-<hex>/`` (:func:`scanner.storage.files.owned_folder`)."""


CATALOG_SCHEMA = 2
"""1: the first catalog; 2: ``scans.steps``, the steps a partial (quick) scan holds ("" for a full scan), added to
a catalog of schema 1 when it is opened."""


PHOTO_SUFFIXES = tuple(f"_{short}.png" for short in IMAGES.values())


_CORRUPTION = ("malformed", "not a database", "encrypted", "corrupt")
"""Words of SQLite's messages for a damaged file (SQLITE_CORRUPT, SQLITE_NOTADB)."""


_REBUILD_HINT = "run 'texplorer db rebuild' to recreate it from the files"


SCHEMA = """
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
    added TEXT NOT NULL,
    steps TEXT NOT NULL DEFAULT ''
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
CREATE TABLE IF NOT EXISTS file_stats (
    path TEXT PRIMARY KEY REFERENCES files(path) ON DELETE CASCADE,
    stat TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS feature_cache (
    content_hash TEXT NOT NULL,
    code_version TEXT NOT NULL,
    values_json TEXT NOT NULL,
    PRIMARY KEY (content_hash, code_version)
);
"""


class DatabaseError(TexplorerError, RuntimeError):
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
    steps: str = ""
    """"" for a full scan; the steps a partial (quick) scan holds, comma-separated (``ScanMeta.steps``)."""

    @property
    def partial(self) -> bool:
        """A quick scan that holds only some steps."""
        return bool(self.steps)


@dataclass(frozen=True)
class FileEntry:
    path: str
    role: str
    sha256: str
    size: int


def _catalog_error(path: Path, exc: sqlite3.Error) -> DatabaseError:
    text = str(exc)
    if any(word in text for word in _CORRUPTION):
        return DatabaseError(f"{path}: catalog is unreadable ({text}); {_REBUILD_HINT}")
    return DatabaseError(f"{path}: {text}")


def catalog_call(method):
    """Turn SQLite's errors in a :class:`Database` method into one-line :class:`DatabaseError`s."""

    @functools.wraps(method)
    def call(self: Catalog, *args, **kwargs):
        try:
            return method(self, *args, **kwargs)
        except sqlite3.Error as exc:
            raise _catalog_error(self.catalog_path, exc) from None

    return call


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


class Catalog:
    """The catalog of the database at ``root``: connections (one per thread, WAL, foreign keys), the schema, and
    the queries of scans and files. The parts of :class:`~scanner.storage.database.Database` build on it."""

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

    @catalog_call
    def _create_schema(self) -> None:
        conn = self._conn
        conn.executescript(SCHEMA)
        if "steps" not in {row[1] for row in conn.execute("PRAGMA table_info(scans)")}:
            # A catalog of schema 1: every scan it knows is a full scan.
            conn.execute("ALTER TABLE scans ADD COLUMN steps TEXT NOT NULL DEFAULT ''")
            conn.execute("DELETE FROM info WHERE key = 'catalog_schema'")
        conn.execute("INSERT OR IGNORE INTO info VALUES ('catalog_schema', ?)", (str(CATALOG_SCHEMA),))

    def _connect(self) -> sqlite3.Connection:
        if self._truncated():
            raise DatabaseError(f"{self.catalog_path}: catalog is empty (0 bytes) although {SCANS}/ holds scans; "
                                f"{_REBUILD_HINT}")
        try:
            conn = sqlite3.connect(self.catalog_path, timeout=60.0, isolation_level=None)
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute("PRAGMA synchronous=FULL")
            conn.execute("PRAGMA foreign_keys=ON")
            conn.execute("PRAGMA busy_timeout=60000")
        except sqlite3.Error as exc:
            raise _catalog_error(self.catalog_path, exc) from None
        conn.row_factory = sqlite3.Row
        return conn

    def _truncated(self) -> bool:
        """A zero-length catalog beside stored scans: SQLite would read it as an empty database.

        A new catalog is zero bytes only until its first write (WAL mode writes the header then), and a new
        database has no scans, so this is a file cut short (a failed copy, a full disk), not a fresh one.
        """
        try:
            if self.catalog_path.stat().st_size > 0:
                return False
        except FileNotFoundError:
            return False
        wal = self.catalog_path.with_name(CATALOG + "-wal")
        if wal.is_file() and wal.stat().st_size > 0:
            return False
        return next((self.root / SCANS).rglob("*.mat"), None) is not None

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

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """A write transaction that holds SQLite's write lock from its first statement."""
        conn = self._conn
        try:
            # BEGIN inside the try: a Ctrl-C arriving just after it must roll back too, or the connection
            # stays in the transaction and every later write fails ("cannot start a transaction within a
            # transaction").
            conn.execute("BEGIN IMMEDIATE")
            yield conn
            conn.execute("COMMIT")
        except BaseException:
            if conn.in_transaction:  # SQLite may have rolled back already (a full disk, an I/O error)
                conn.execute("ROLLBACK")
            raise

    @property
    def taxonomy_path(self) -> Path:
        """``<root>/taxonomy.csv``: this database's taxonomy extension (absent until a lab code is needed)."""
        return self.root / TAXONOMY

    def taxonomy(self) -> Taxonomy:
        """The shipped taxonomy merged with ``$TEXPLORER_TAXONOMY`` and this database's extension, if any."""
        return load_taxonomy(self.taxonomy_path if self.taxonomy_path.is_file() else None)

    @catalog_call
    def records(self, *, label: str | None = None, sample: str | None = None, session: str | None = None,
                operator: str | None = None) -> list[ScanRecord]:
        """Catalog rows, optionally filtered; ``label`` may be a class prefix ("C6" = every stone, not C60) or
        part of a material, sub-class or class name ("granite", "stone"), as the web app's label field.

        A ``label`` that is neither raises ``LabelError`` naming the valid forms; lower-case letters are accepted.
        """
        clauses, params = [], []
        prefix, materials = select_labels(label or "", self.taxonomy)
        if prefix:
            clauses.append("label >= ? AND label < ?")
            params.extend(_label_range(prefix))
        for column, value in (("sample_id", sample), ("session_id", session), ("operator", operator)):
            if value:
                clauses.append(f"{column} = ?")
                params.append(value)
        where = f"WHERE {' AND '.join(clauses)}" if clauses else ""
        rows = self._conn.execute(f"SELECT * FROM scans {where} ORDER BY label, sample_id, scan_index", params)
        records = [_record(row) for row in rows]
        return records if materials is None else [r for r in records if material_code(r.label) in materials]

    @catalog_call
    def record(self, scan_id: str) -> ScanRecord:
        row = self._conn.execute("SELECT * FROM scans WHERE scan_id = ?", (scan_id,)).fetchone()
        if row is None:
            raise DatabaseError(f"no scan {scan_id!r} in {self.root}")
        return _record(row)

    @catalog_call
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

    @catalog_call
    def stored_scans(self, records: Iterable[ScanRecord]) -> list[StoredScan]:
        """A loader of each record's scan that carries the catalogued size and SHA-256 of its files, so a
        cluster worker loads exactly these bytes or none (:mod:`scanner.storage.stored`); here it is ``load_scan``.
        It carries the files' stat records too, with which it verifies unchanged files without hashing them."""
        catalogued: dict[str, dict[str, tuple[int, str]]] = {}
        stats: dict[str, dict[str, str]] = {}
        for scan_id, path, size, sha256, stat in self._conn.execute(
                "SELECT files.scan_id, files.path, files.size, files.sha256, file_stats.stat FROM files "
                "LEFT JOIN file_stats ON file_stats.path = files.path"):
            name = PurePosixPath(path).name
            catalogued.setdefault(scan_id, {})[name] = (size, sha256)
            if stat is not None:
                stats.setdefault(scan_id, {})[name] = stat
        ledger = StatLedger(self.root, self.catalog_path)
        return [StoredScan(self.root / record.path, catalogued.get(record.scan_id, {}), stats.get(record.scan_id, {}),
                           ledger) for record in records]

    @catalog_call
    def __len__(self) -> int:
        return self._conn.execute("SELECT COUNT(*) FROM scans").fetchone()[0]

    @catalog_call
    def summary(self) -> dict[str, int]:
        """Counts of materials, samples, sessions, scans and files."""
        return {table: self._conn.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
                for table in ("materials", "samples", "sessions", "scans", "files")}

    def _relative(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()

    def scan_path(self, scan: Scan) -> Path:
        """Where ``scan`` is stored: ``scans/<label>/<sample>/<scan_id>.mat``."""
        meta = scan.meta
        return self.root / SCANS / meta.label / check_sample_id(meta.sample_id) / f"{scan.scan_id}.mat"

    @catalog_call
    def next_scan_index(self, sample_id: str) -> int:
        """The scan index a new scan of ``sample_id`` should get (1 for a new sample)."""
        row = self._conn.execute("SELECT MAX(scan_index) FROM scans WHERE sample_id = ?", (sample_id,)).fetchone()
        return (row[0] or 0) + 1


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
