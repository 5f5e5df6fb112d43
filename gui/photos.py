"""Photo uploads (docs/operator.md#procedure, step 9): size-limited, checked before decoding, staged under random names.

An uploaded file is trusted for nothing: its name and declared type are ignored. Before the session decodes
it (``Session.set_photo`` -> ``scanner.acquisition.devices.camera.decode_photo``: PNG or JPEG by content, OpenCV),
:func:`check_upload` refuses files above the size limit and PNG/JPEG headers that announce more pixels
than the photo limit (:mod:`scanner.photo`), so a small compressed file cannot expand into gigabytes when decoded.
Each photo the session holds is written as PNG under a random name in a staging folder for the page's
preview until the scan is saved or abandoned; the uploaded bytes themselves are never stored.
"""

from __future__ import annotations

import re
import secrets
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from scanner.photo import DEFAULT_MAX_PIXELS, PhotoError, check_pixels, decode, encode_png
from scanner.storage.files import atomic_write_bytes
from taxonomy.errors import TexplorerError

DEFAULT_MAX_BYTES = 20 * 1024 * 1024

_STAGED_NAME = re.compile(r"^[0-9a-f]{32}\.png$")


class UploadError(TexplorerError, ValueError):
    """An uploaded photo is refused; the message is one line for the operator."""


def file_size(n: int) -> str:
    """Bytes for people: ``"264 KB"``, ``"20.0 MB"``."""
    return f"{n / 1024:.0f} KB" if n < 1024 * 1024 else f"{n / (1024 * 1024):.1f} MB"


def check_size(size: int, max_bytes: int = DEFAULT_MAX_BYTES) -> None:
    """Refuse an empty file or one larger than ``max_bytes`` (checked before the file is read)."""
    if size == 0:
        raise UploadError("the file is empty")
    if size > max_bytes:
        raise UploadError(f"the file is {file_size(size)}; photos may be at most {file_size(max_bytes)}")


def check_upload(data: bytes, *, max_bytes: int = DEFAULT_MAX_BYTES,
                 max_pixels: int = DEFAULT_MAX_PIXELS) -> None:
    """Refuse an upload that is empty, too large, or announces too many pixels (UploadError, one line).

    Content that is not PNG or JPEG passes here; decoding refuses it with its own reason.
    """
    check_size(len(data), max_bytes)
    try:
        check_pixels(data, max_pixels)
    except PhotoError as exc:
        raise UploadError(str(exc)) from None


class PhotoStore:
    """Staged photos: PNG files with random 128-bit names in ``folder`` (created on first use)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)

    def put(self, rgb: np.ndarray) -> str:
        """Store an RGB image; returns its generated name."""
        self.folder.mkdir(parents=True, exist_ok=True)
        name = f"{secrets.token_hex(16)}.png"
        atomic_write_bytes(self.folder / name, encode_png(rgb))
        return name

    def path(self, name: str) -> Path:
        """The file of a staged photo; refuses anything that is not a generated name (no path tricks)."""
        if not _STAGED_NAME.match(name or ""):
            raise UploadError(f"{name!r} is not a staged photo name")
        return self.folder / name

    def load(self, name: str) -> np.ndarray:
        """The RGB image of a staged photo."""
        try:
            return decode(self.path(name).read_bytes(), f"staged photo {name}")
        except PhotoError as problem:
            raise UploadError(str(problem)) from None

    def discard(self, names: Iterable[str]) -> None:
        """Delete staged photos (missing ones are ignored)."""
        for name in names:
            self.path(name).unlink(missing_ok=True)
