"""texplorer scanner: the scan model, preprocessing, storage (:mod:`scanner.storage`), acquisition
(:mod:`scanner.acquisition`), the simulator (:mod:`scanner.simulation`), the shared workflows and the CLI.

This package's surface is the scan model and storage: ``Scan``, ``Recording``, ``Database``, ``load_scan``, ...
"""

from __future__ import annotations

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
from scanner.storage.database import Database, DatabaseError
from scanner.storage.matfile import ScanFormatError, load_scan, save_scan
from scanner.version import __version__
from taxonomy.errors import TexplorerError

__all__ = [
    "CHANNELS", "IMAGES", "JUDGED_SCALE", "ROLES", "SCHEMA_VERSION", "VOLUME_METHODS",
    "Database", "DatabaseError", "Recording", "Scan", "ScanError", "ScanFormatError", "ScanMeta", "TexplorerError",
    "Trace", "__version__", "load_scan", "save_scan",
]
