"""texplorer scanner: data model, devices, guided session, preprocessing, storage and the CLI."""

from __future__ import annotations

from scanner.database import Database, DatabaseError
from scanner.matfile import ScanFormatError, load_scan, save_scan
from scanner.scan import (
    CHANNELS,
    IMAGES,
    JUDGED_SCALE,
    ROLES,
    SCHEMA_VERSION,
    VOLUME_METHODS,
    Recording,
    Scan,
    ScanError,
    ScanMeta,
    Trace,
)
from scanner.version import __version__
from taxonomy.errors import TexplorerError

__all__ = [
    "CHANNELS", "IMAGES", "JUDGED_SCALE", "ROLES", "SCHEMA_VERSION", "VOLUME_METHODS",
    "Database", "DatabaseError", "Recording", "Scan", "ScanError", "ScanFormatError", "ScanMeta", "TexplorerError",
    "Trace", "__version__", "load_scan", "save_scan",
]
