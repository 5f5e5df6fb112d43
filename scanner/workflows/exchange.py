"""A database exported with its features: an export bundle whose feature tables come from the feature cache
(a module of its own: the bundle's writers load scipy.io, which reading features does not need)."""

from __future__ import annotations

import os
from collections.abc import Sequence

from features import REGISTRY, FeatureSpace, code_version
from scanner.storage.bundle import ExportReport, Progress, export_bundle
from scanner.storage.database import Database, ScanRecord
from scanner.storage.settings import read_settings
from scanner.workflows.database import extract_database


def export_database(db: Database, out: str | os.PathLike[str], *, label: str | None = None,
                    session: str | None = None, license: str | None = None, creator: str | None = None,
                    workers: int | None = None, progress: Progress = iter) -> ExportReport:
    """Write the scans of ``db`` (optionally a label or class prefix, or one session) as an export bundle
    with their features, read from the feature cache where possible (``workers`` processes extract the
    rest); see :func:`scanner.storage.bundle.export_bundle` for the bundle and its errors.

    ``license`` and ``creator`` default to the database's settings (``texplorer db settings``); without a
    license from either the export is refused (``"none"`` exports without one)."""
    def features(records: Sequence[ScanRecord]) -> FeatureSpace:
        return extract_database(db, records=records, workers=workers)

    settings = read_settings(db.root)
    return export_bundle(db, out, features, feature_code_version=code_version(),
                         license=license or settings.get("license"), creator=creator or settings.get("creator"),
                         feature_units=REGISTRY.units, label=label, session=session, progress=progress)
