"""Photo uploads (SPEC 4 step 9, SPEC 10): size-limited, checked before decoding, staged under random names.

An uploaded file is trusted for nothing: its name and declared type are ignored. Before the session decodes
it (``Session.set_photo`` -> ``scanner.devices.camera.decode_photo``: PNG or JPEG by content, OpenCV),
:func:`check_upload` refuses files above the size limit and PNG/JPEG headers that announce more pixels
than :data:`DEFAULT_MAX_PIXELS`, so a small compressed file cannot expand into gigabytes when decoded.
Each photo the session holds is written as PNG under a random name in a staging folder for the page's
preview until the scan is saved or abandoned; the uploaded bytes themselves are never stored.
"""

from __future__ import annotations

import re
import secrets
import struct
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from scanner.files import atomic_write_bytes
from scanner.matfile import decode_image, encode_png

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8\xff"
DEFAULT_MAX_BYTES = 20 * 1024 * 1024
DEFAULT_MAX_PIXELS = 50_000_000
"""Four times a 12-megapixel phone photo (3024 x 4032, the paper's camera)."""

_STAGED_NAME = re.compile(r"^[0-9a-f]{32}\.png$")
_JPEG_FRAME_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""Start-of-frame markers SOF0-SOF15; C4 (Huffman tables), C8 (reserved) and CC (arithmetic) are not."""


class UploadError(ValueError):
    """An uploaded photo is refused; the message is one line for the operator."""


def file_size(n: int) -> str:
    """Bytes for people: ``"264 KB"``, ``"20.0 MB"``."""
    return f"{n / 1024:.0f} KB" if n < 1024 * 1024 else f"{n / (1024 * 1024):.1f} MB"


def _png_size(data: bytes) -> tuple[int, int]:
    if len(data) < 24 or data[12:16] != b"IHDR":
        raise UploadError("the PNG file is damaged (no image header)")
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def _jpeg_size(data: bytes) -> tuple[int, int]:
    """Width and height from the first start-of-frame segment, walking the marker segments after SOI."""
    position = 2
    while position + 4 <= len(data):
        if data[position] != 0xFF:
            raise UploadError("the JPEG file is damaged (bad marker)")
        marker = data[position + 1]
        if marker == 0xFF:  # fill byte before a marker
            position += 1
            continue
        if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a length field
            position += 2
            continue
        (length,) = struct.unpack(">H", data[position + 2:position + 4])
        if marker in _JPEG_FRAME_MARKERS:
            if position + 9 > len(data):
                break
            height, width = struct.unpack(">HH", data[position + 5:position + 9])
            return width, height
        position += 2 + length
    raise UploadError("the JPEG file is damaged (no frame header)")


def image_size(data: bytes) -> tuple[str, int, int] | None:
    """``(kind, width, height)`` of PNG or JPEG bytes from the header alone, or None for other content.

    Raises
    ------
    UploadError
        A PNG or JPEG signature with a damaged header.
    """
    if data.startswith(PNG_SIGNATURE):
        return ("PNG", *_png_size(data))
    if data.startswith(JPEG_SIGNATURE):
        return ("JPEG", *_jpeg_size(data))
    return None


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
    size = image_size(data)
    if size is None:
        return
    kind, width, height = size
    if width < 1 or height < 1:
        raise UploadError(f"the {kind} header gives an empty image ({width} x {height} px)")
    if width * height > max_pixels:
        raise UploadError(f"the image has {width * height / 1e6:.1f} megapixels ({width} x {height} px); "
                          f"at most {max_pixels / 1e6:g} are accepted")


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
        rgb = decode_image(self.path(name).read_bytes())
        if rgb is None:
            raise UploadError(f"staged photo {name} cannot be read")
        return rgb

    def discard(self, names: Iterable[str]) -> None:
        """Delete staged photos (missing ones are ignored)."""
        for name in names:
            self.path(name).unlink(missing_ok=True)
