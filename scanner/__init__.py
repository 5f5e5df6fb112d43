"""texplorer scanner: data model, devices, guided session, preprocessing, storage and the CLI."""

from scanner.scan import (
    CHANNELS,
    IMAGES,
    JUDGED_SCALE,
    ROLES,
    SCHEMA_VERSION,
    Recording,
    Scan,
    ScanError,
    ScanMeta,
    Trace,
)

__version__ = "0.1.0"

__all__ = [
    "CHANNELS", "IMAGES", "JUDGED_SCALE", "ROLES", "SCHEMA_VERSION",
    "Recording", "Scan", "ScanError", "ScanMeta", "Trace", "__version__",
]
