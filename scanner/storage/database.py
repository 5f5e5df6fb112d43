"""The scan database: a folder of ``.mat`` files and photos plus a SQLite catalog (docs/database.md).

Layout::

    <root>/catalog.sqlite                          SQLite in WAL mode: materials, samples, sessions, scans,
                                                   files (SHA-256 of every stored file), feature cache
    <root>/scans/<label>/<sample>/<scan_id>.mat    one scan, MATLAB v5
    <root>/scans/<label>/<sample>/<scan_id>_disp.png  ... its photos
    <root>/taxonomy.csv                            optional taxonomy extension: material codes this database
                                                   uses beyond the shipped table (e.g. added by an import)
    <root>/.pending/<random>.json                  the files a write is putting into scans/, until it commits
    <root>/quarantine/<time>/scans/...             files ``rebuild`` could not catalogue, moved out of scans/

The files are the truth; the catalog is an index that :meth:`Database.rebuild` recreates from them.

Crash safety of :meth:`Database.add` follows SQLite's own rollback journal: under the SQLite write lock, a
record of the files about to be written goes to ``.pending/`` (atomically) before any of them, every file
is written atomically (temp file + fsync + rename), the catalog rows are inserted and committed in one
transaction, and the record is removed. A process killed at any moment leaves either nothing, or crash
leftovers that the record (or the temp-file name, or a photo without its ``.mat``) identifies: never a row
pointing to a missing or partial file, and never a change to earlier scans. The next write (under the same
lock, so nothing in flight is touched), :meth:`repair` and :meth:`rebuild` remove leftovers; files that
belong to no scan and are not leftovers are reported by :meth:`check` as unknown and never deleted.
:meth:`Database.add_written` (import) inserts a whole batch's rows first and then moves its complete files
into place, with the same record, and moves them back if anything fails before the commit.

A catalog SQLite cannot read (random bytes, a malformed page, a zero-length file beside stored scans) makes
every call raise :class:`DatabaseError` saying so and naming ``texplorer db rebuild``.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import math
import os
import secrets
import shutil
import sqlite3
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path, PurePosixPath

from scanner.scan import IMAGES, Scan, ScanMeta, check_sample_id
from scanner.storage.files import (
    atomic_write_bytes,
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
from scanner.storage.matfile import ScanFormatError, load_scan, photo_file_name, save_scan, scan_files
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


@dataclass(frozen=True)
class _Intent:
    """A ``.pending`` record: the scans a write is adding and the files it puts into ``scans/``."""

    record: Path
    scan_ids: tuple[str, ...]
    files: tuple[str, ...]


def _catalog_error(path: Path, exc: sqlite3.Error) -> DatabaseError:
    text = str(exc)
    if any(word in text for word in _CORRUPTION):
        return DatabaseError(f"{path}: catalog is unreadable ({text}); {_REBUILD_HINT}")
    return DatabaseError(f"{path}: {text}")


def _catalog(method):
    """Turn SQLite's errors in a :class:`Database` method into one-line :class:`DatabaseError`s."""

    @functools.wraps(method)
    def call(self: Database, *args, **kwargs):
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


class Database:
    """A scan database: ``.mat`` files and photos under ``root/scans`` plus the SQLite catalog (docs/database.md).

    Safe for concurrent readers and writers: each thread gets its own SQLite connection, and writers are
    serialised by SQLite's write lock. Every file is written atomically and catalogued only when complete.

    Parameters
    ----------
    root : str or os.PathLike
        The database folder.
    create : bool
        Create the folder and catalog if missing; with False a folder that is not a database is refused.

    Raises
    ------
    DatabaseError
        An unreadable catalog (``texplorer db rebuild`` recreates it), or no database at ``root`` with
        ``create=False``.

    Examples
    --------
    >>> import tempfile
    >>> from scanner import Database
    >>> from scanner.simulation import synthetic_scan
    >>> db = Database(tempfile.mkdtemp())
    >>> scan_id = db.add(synthetic_scan("oak-planed", seed=1, image_size=(256, 256)))
    >>> [r.scan_id for r in db.records(label="C1")] == [scan_id]
    True
    >>> db.get(scan_id).meta.label
    'C1S1M1P4X1'
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

    @_catalog
    def _create_schema(self) -> None:
        conn = self._conn
        conn.executescript(_SCHEMA)
        if "steps" not in {row[1] for row in conn.execute("PRAGMA table_info(scans)")}:
            # A catalog of schema 1: every scan it knows is a full scan.
            conn.execute("ALTER TABLE scans ADD COLUMN steps TEXT NOT NULL DEFAULT ''")
            conn.execute("DELETE FROM info WHERE key = 'catalog_schema'")
        conn.execute("INSERT OR IGNORE INTO info VALUES ('catalog_schema', ?)", (str(CATALOG_SCHEMA),))

    # -- connections -------------------------------------------------------------------------------

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

    def __enter__(self) -> Database:
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

    # -- writing -----------------------------------------------------------------------------------

    def scan_path(self, scan: Scan) -> Path:
        """Where ``scan`` is stored: ``scans/<label>/<sample>/<scan_id>.mat``."""
        meta = scan.meta
        return self.root / SCANS / meta.label / check_sample_id(meta.sample_id) / f"{scan.scan_id}.mat"

    @_catalog
    def next_scan_index(self, sample_id: str) -> int:
        """The scan index a new scan of ``sample_id`` should get (1 for a new sample)."""
        row = self._conn.execute("SELECT MAX(scan_index) FROM scans WHERE sample_id = ?", (sample_id,)).fetchone()
        return (row[0] or 0) + 1

    @_catalog
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

    @_catalog
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

    def _relative(self, path: Path) -> str:
        return path.relative_to(self.root).as_posix()

    # -- the pending record of a write (a rollback journal for files) ---------------------------------

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

    # -- taxonomy ----------------------------------------------------------------------------------

    @property
    def taxonomy_path(self) -> Path:
        """``<root>/taxonomy.csv``: this database's taxonomy extension (absent until a lab code is needed)."""
        return self.root / TAXONOMY

    def taxonomy(self) -> Taxonomy:
        """The shipped taxonomy merged with ``$TEXPLORER_TAXONOMY`` and this database's extension, if any."""
        return load_taxonomy(self.taxonomy_path if self.taxonomy_path.is_file() else None)

    # -- reading -----------------------------------------------------------------------------------

    @_catalog
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

    @_catalog
    def record(self, scan_id: str) -> ScanRecord:
        row = self._conn.execute("SELECT * FROM scans WHERE scan_id = ?", (scan_id,)).fetchone()
        if row is None:
            raise DatabaseError(f"no scan {scan_id!r} in {self.root}")
        return _record(row)

    @_catalog
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

    @_catalog
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

    @_catalog
    def __len__(self) -> int:
        return self._conn.execute("SELECT COUNT(*) FROM scans").fetchone()[0]

    @_catalog
    def summary(self) -> dict[str, int]:
        """Counts of materials, samples, sessions, scans and files."""
        return {table: self._conn.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
                for table in ("materials", "samples", "sessions", "scans", "files")}

    # -- feature cache ---------------------------------------------------------------------------

    @_catalog
    def cached_features(self, content_hash: str, code_version: str) -> dict[str, float] | None:
        row = self._conn.execute("SELECT values_json FROM feature_cache WHERE content_hash = ? AND code_version = ?",
                                 (content_hash, code_version)).fetchone()
        if row is None:
            return None
        return {name: (math.nan if value is None else value) for name, value in json.loads(row[0]).items()}

    @_catalog
    def store_features(self, content_hash: str, code_version: str, values: dict[str, float]) -> None:
        payload = json.dumps({k: (None if math.isnan(v) else v) for k, v in values.items()})
        with self._transaction() as conn:
            conn.execute("INSERT OR REPLACE INTO feature_cache VALUES (?, ?, ?)", (content_hash, code_version, payload))

    # -- integrity ---------------------------------------------------------------------------------

    def stored_files(self) -> list[str]:
        """Every file under ``scans/``, relative to the root (including leftovers of interrupted writes)."""
        return sorted(self._relative(p) for p in (self.root / SCANS).rglob("*") if p.is_file())

    @_catalog
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

    @_catalog
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

    @_catalog
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
            conn.executescript(_SCHEMA)
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
