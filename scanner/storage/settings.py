"""A database's own settings, ``<db>/settings.json``: what a lab sets once instead of on every command.

Today the export metadata: ``license`` (an SPDX identifier, a license URL or ``none``) and ``creator`` (a
person's or lab's name, or an ORCID), which ``texplorer export`` and the web application's export use when
not given (docs/export.md). The file lives beside the catalog, not in it, so ``texplorer db rebuild`` keeps
it; it is written atomically and read with a size bound.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from scanner.storage.files import atomic_write_bytes, read_json
from scanner.storage.metadata import MetadataError, checked_creator, license_url

SETTINGS = "settings.json"
KEYS = ("license", "creator")
MAX_BYTES = 64 << 10


def read_settings(db_root: str | os.PathLike[str]) -> dict[str, str]:
    """The database's settings (only :data:`KEYS`); empty if it has none.

    Raises
    ------
    MetadataError
        The file is larger than 64 KiB, not a JSON object of strings, or holds a value that cannot be used.
    """
    path = Path(db_root) / SETTINGS
    values = read_json(path, MAX_BYTES, MetadataError, {}, "; fix or delete it")
    if not isinstance(values, dict) or not all(isinstance(v, str) for v in values.values()):
        raise MetadataError(f"{path}: must be a JSON object of strings")
    settings = {key: values[key] for key in KEYS if key in values}
    _check(settings, path)
    return settings


def _check(settings: dict[str, str], where: Path | str) -> None:
    try:
        if "license" in settings:
            license_url(settings["license"])
        if "creator" in settings:
            checked_creator(settings["creator"])
    except MetadataError as exc:
        raise MetadataError(f"{where}: {exc}") from None


def write_settings(db_root: str | os.PathLike[str], **changes: str | None) -> dict[str, str]:
    """Set (a string) or remove (None) the given settings, atomically; returns the new settings. Nothing
    is written if a value cannot be used.

    Raises
    ------
    MetadataError
        An unknown key or a value that cannot be used.
    """
    unknown = sorted(set(changes) - set(KEYS))
    if unknown:
        raise MetadataError(f"unknown setting(s) {', '.join(unknown)} (known: {', '.join(KEYS)})")
    settings = read_settings(db_root)
    for key, value in changes.items():
        if value is None:
            settings.pop(key, None)
        else:
            settings[key] = value.strip()
    _check(settings, "setting")
    atomic_write_bytes(Path(db_root) / SETTINGS, (json.dumps(settings, indent=1) + "\n").encode("utf-8"))
    return settings
