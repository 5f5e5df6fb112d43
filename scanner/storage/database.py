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

from scanner.storage.cache import FeatureCacheTable
from scanner.storage.catalog import (
    CATALOG,
    RECORDINGS,
    SCANS,
    STAGING_PREFIX,
    DatabaseError,
    FileEntry,
    ScanRecord,
    content_hash,
    file_roles,
    is_database,
)
from scanner.storage.maintenance import CheckReport, Maintenance, RebuildReport, recording_leftovers, repair_recordings

__all__ = ["CATALOG", "RECORDINGS", "SCANS", "STAGING_PREFIX", "CheckReport", "Database", "DatabaseError", "FileEntry",
           "RebuildReport", "ScanRecord", "content_hash", "file_roles", "is_database", "recording_leftovers",
           "repair_recordings"]


class Database(Maintenance, FeatureCacheTable):
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
