"""A database's features: catalog rows as cached feature sources, the features of every scan read from the
database's feature cache where they are current, and one stored scan's values."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence

from features import FeatureSpace, ScanSource, extract_many
from scanner.runtime.local import WorkerPool
from scanner.storage.database import Database, DatabaseError, ScanRecord

# -- extract a database with its cache ---------------------------------------------------------------

def database_sources(db: Database, records: Iterable[ScanRecord]) -> list[ScanSource]:
    """One :class:`features.ScanSource` per catalog row: loaded where it is extracted (on a cluster worker,
    exactly the catalogued bytes: :meth:`scanner.storage.database.Database.stored_scans`), cached by content."""
    records = list(records)
    return [ScanSource(r.scan_id, r.label, r.sample_id, stored, cache_key=r.content_hash)
            for r, stored in zip(records, db.stored_scans(records), strict=True)]


def extract_database(db: Database, *, label: str | None = None, records: Sequence[ScanRecord] | None = None,
                     workers: int | None = None, progress: bool = True, pool: WorkerPool | None = None,
                     families: Sequence[str] | None = None, partial: bool = True) -> FeatureSpace:
    """The features of every scan of ``db`` (or of ``label``, a label or class prefix, or of ``records``),
    read from the database's feature cache where the scan and the feature code are unchanged; extracted in
    ``workers`` processes here (or those of ``pool``, kept across a job's batches), or on the current
    runtime's Dask cluster (:func:`scanner.runtime.current`; see :func:`features.extract_many`). The
    catalog and the cache are read and written here only. ``families``: the feature families to compute
    (default: the paper's; opt-in ones such as :mod:`features.modern`'s too). Without ``partial``, quick
    scans that hold only some steps are left out (:func:`full_scans`): what models learn from and are
    measured on.

    Raises
    ------
    DatabaseError
        No scan to extract.
    """
    if records is None:
        records = db.records(label=label)
    if not partial:
        records = full_scans(records)
    if not records:
        raise DatabaseError(f"{db.root}: no scans{f' with label {label}' if label else ''} to extract")
    return extract_many(database_sources(db, records), workers=workers, cache=db, progress=progress, pool=pool,
                        families=families)


def full_scans(records: Sequence[ScanRecord]) -> list[ScanRecord]:
    """The full scans of ``records``; a one-line note on stderr names how many quick (partial) scans are left
    out, since a model learns from and is measured on every step."""
    full = [r for r in records if not r.partial]
    if len(full) < len(records):
        print(f"texplorer: note: {len(records) - len(full)} quick scan(s) holding only some steps left out: models "
              "learn from and are measured on full scans (docs/quick.md)", file=sys.stderr)
    return full

def stored_features(db: Database, record: ScanRecord) -> tuple[dict[str, float], str | None]:
    """One stored scan's named feature values from the cache (extracted and cached if missing), or ``{}``
    and the reason its extraction failed."""
    space = extract_database(db, records=[record], workers=1, progress=False)
    if space.failed:
        return {}, space.failed[0][1]
    return dict(zip(space.columns, space.X[0].tolist(), strict=True)), None
