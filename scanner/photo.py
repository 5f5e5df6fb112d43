"""Photo files (docs/database.md: PNG or JPEG beside the ``.mat``): one size limit, read from the header before
decoding.

Every way a photo enters goes through :func:`decode`: :func:`scanner.load_scan` (and with it import, replay,
rebuild and feature extraction), web uploads and uploaded files in a session
(:func:`scanner.acquisition.devices.camera.decode_photo`). The camera checks the frame size it announces with
:func:`check_size` before the first frame is read, and :class:`scanner.Scan` refuses an image array beyond
the limit, so a scan that is saved can always be loaded again.

The limit is :func:`max_pixels`: ``$TEXPLORER_MAX_PHOTO_PIXELS`` if set, else :data:`DEFAULT_MAX_PIXELS`
(25 megapixels, a 12-megapixel phone photo twice over), and no side longer than :data:`MAX_SIDE`. A
PNG or JPEG header is a few dozen bytes, so a 1 MB file announcing 20000 x 20000 pixels (1.2 GB decoded, and
about 15 GB while its features are computed) is refused after reading those bytes. Files that are neither
PNG nor JPEG are refused before OpenCV sees them: its other decoders (TIFF, BMP, WebP, ...) would decode
without this check.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import numpy as np

from scanner.lazy import library
from taxonomy.errors import TexplorerError

cv2 = library("cv2")

MAX_PIXELS_ENV = "TEXPLORER_MAX_PHOTO_PIXELS"
DEFAULT_MAX_PIXELS = 25_000_000
"""A 12-megapixel phone photo (4032 x 3024, the paper's camera class) with a factor of two to spare."""
MAX_SIDE = 16_384
"""Longest side in pixels, whatever the pixel limit (a 25 MP photo of this width is 1525 px high)."""

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8\xff"
BMP_SIGNATURE = b"BM"
TIFF_SIGNATURES = {b"II*\x00": ("<", False), b"MM\x00*": (">", False), b"II+\x00": ("<", True),
                   b"MM\x00+": (">", True)}
"""Byte order and BigTIFF of the four TIFF signatures."""
_JPEG_FRAME_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""Start-of-frame markers SOF0-SOF15; C4 (Huffman tables), C8 (reserved) and CC (arithmetic) are not."""


def _imread_rgb() -> int:
    """OpenCV >= 4.11 decodes straight to RGB (``IMREAD_COLOR_RGB``; 0 before), the same values as
    ``IMREAD_COLOR`` with the channels reversed (PNG: libpng's output order; JPEG: libjpeg's colour space),
    faster and without a second full-size image (docs/performance.md). Older versions decode to BGR and
    convert."""
    return getattr(cv2, "IMREAD_COLOR_RGB", 0)


class PhotoError(TexplorerError, ValueError):
    """A photo cannot be used; the message says why in one line."""


def max_pixels() -> int:
    """The photo pixel limit: ``$TEXPLORER_MAX_PHOTO_PIXELS`` (a positive integer) or :data:`DEFAULT_MAX_PIXELS`."""
    text = os.environ.get(MAX_PIXELS_ENV, "").strip().replace("_", "")
    if not text:
        return DEFAULT_MAX_PIXELS
    if not text.isdigit() or int(text) < 1:
        raise ValueError(f"${MAX_PIXELS_ENV} must be a positive whole number of pixels, got {text!r}")
    return int(text)


def _png_size(data: bytes) -> tuple[int, int]:
    if len(data) < 24 or data[12:16] != b"IHDR":
        raise PhotoError("the PNG file is damaged (no image header)")
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def _jpeg_size(data: bytes) -> tuple[int, int]:
    """Width and height from the first start-of-frame segment, walking the marker segments after SOI."""
    position = 2
    while position + 4 <= len(data):
        if data[position] != 0xFF:
            raise PhotoError("the JPEG file is damaged (bad marker)")
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
    raise PhotoError("the JPEG file is damaged (no frame header)")


def _bmp_size(data: bytes) -> tuple[int, int]:
    """From the DIB header: 16-bit sides in the old OS/2 header (12 bytes), 32-bit (height signed) after."""
    if len(data) < 26:
        raise PhotoError("the BMP file is damaged (no image header)")
    if struct.unpack_from("<I", data, 14)[0] == 12:
        return struct.unpack_from("<HH", data, 18)
    width, height = struct.unpack_from("<ii", data, 18)
    return width, abs(height)


def _tiff_size(data: bytes) -> tuple[int, int]:
    """ImageWidth (tag 256) and ImageLength (257) of the first image file directory, the page decoded."""
    order, big = TIFF_SIGNATURES[data[:4]]
    count_format, entry, offset_format = ("Q", 20, "Q") if big else ("H", 12, "I")
    try:
        first = struct.unpack_from(order + offset_format, data, 8 if big else 4)[0]
        (entries,) = struct.unpack_from(order + count_format, data, first)
        start = first + struct.calcsize(count_format)
        sides = {}
        for k in range(min(entries, 4096)):
            tag, kind = struct.unpack_from(order + "HH", data, start + k * entry)
            if tag in (256, 257) and kind in (3, 4, 16):  # SHORT, LONG, LONG8
                value_at = start + k * entry + (12 if big else 8)
                sides[tag] = struct.unpack_from(order + {3: "H", 4: "I", 16: "Q"}[kind], data, value_at)[0]
    except struct.error:
        raise PhotoError("the TIFF file is damaged (no complete image directory)") from None
    if len(sides) < 2:
        raise PhotoError("the TIFF file is damaged (no image width and length)")
    return sides[256], sides[257]


def image_size(data: bytes) -> tuple[str, int, int] | None:
    """``(kind, width, height)`` of PNG, JPEG, BMP or TIFF bytes from the header alone, or None for others.

    Raises
    ------
    PhotoError
        One of these signatures with a damaged header.
    """
    if data.startswith(PNG_SIGNATURE):
        return ("PNG", *_png_size(data))
    if data.startswith(JPEG_SIGNATURE):
        return ("JPEG", *_jpeg_size(data))
    if data.startswith(BMP_SIGNATURE):
        return ("BMP", *_bmp_size(data))
    if data[:4] in TIFF_SIGNATURES:
        return ("TIFF", *_tiff_size(data))
    return None


def check_size(width: int, height: int, limit: int | None = None, name: str = "the photo") -> None:
    """Refuse an image of ``width`` x ``height`` px that is empty or beyond the limit (PhotoError, one line).

    ``limit`` is the pixel limit, :func:`max_pixels` when None.
    """
    limit = max_pixels() if limit is None else limit
    if width < 1 or height < 1:
        raise PhotoError(f"{name}: an empty image ({width} x {height} px)")
    if width * height > limit:
        raise PhotoError(f"{name}: the image has {width * height:,} pixels ({width} x {height}); "
                         f"at most {limit:,} are accepted (${MAX_PIXELS_ENV})")
    if width > MAX_SIDE or height > MAX_SIDE:
        raise PhotoError(f"{name}: {width} x {height} px has a side longer than {MAX_SIDE} px")


def check_pixels(data: bytes, limit: int | None = None, name: str = "the photo") -> None:
    """Refuse PNG, JPEG, BMP or TIFF bytes whose header announces an empty image or one beyond the limit.

    Checked before decoding, so a small compressed file cannot expand into gigabytes. Other content
    passes here; :func:`decode` refuses it.
    """
    try:
        size = image_size(data)
    except PhotoError as problem:
        raise PhotoError(f"{name}: {problem}") from None
    if size is not None:
        check_size(size[1], size[2], limit, name)


def decode(data: bytes, name: str = "the photo", limit: int | None = None) -> np.ndarray:
    """PNG or JPEG bytes -> RGB uint8 (h, w, 3), the size checked from the header first.

    Raises
    ------
    PhotoError
        Not PNG or JPEG, a damaged header, too many pixels (``limit``, default :func:`max_pixels`), or
        content OpenCV cannot decode.
    """
    if not (data.startswith(PNG_SIGNATURE) or data.startswith(JPEG_SIGNATURE)):
        raise PhotoError(f"{name}: not a PNG or JPEG file")
    check_pixels(data, limit, name)
    rgb = _imread_rgb()
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), rgb or cv2.IMREAD_COLOR)
    if image is None:
        raise PhotoError(f"{name}: the file is damaged and cannot be decoded")
    return image if rgb else cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


def max_file_bytes(limit: int | None = None, bytes_per_pixel: int = 4) -> int:
    """The largest photo file worth reading: ``bytes_per_pixel`` (4: an uncompressed RGBA PNG; 8 for the
    16-bit images :mod:`scanner.storage.ingest` reads) for each pixel of the limit, and 1 MB of headers."""
    return bytes_per_pixel * (max_pixels() if limit is None else limit) + (1 << 20)


def read_photo(path: str | os.PathLike[str], name: str = "the photo", limit: int | None = None) -> np.ndarray:
    """:func:`decode` a photo file, refusing one too large for the pixel limit before reading it.

    Raises PhotoError, or OSError if the file cannot be read.
    """
    path = Path(path)
    check_file_size(path.stat().st_size, name, limit)
    return decode(path.read_bytes(), name, limit)


def check_file_size(size: int, name: str = "the photo", limit: int | None = None) -> None:
    """Refuse a photo file of ``size`` bytes, too large for the pixel limit, before reading it."""
    if size > max_file_bytes(limit):
        raise PhotoError(f"{name}: {size / 1e6:.0f} MB is more than a photo within the pixel limit can take")


def encode_png(rgb: np.ndarray) -> bytes:
    """Lossless PNG bytes of an RGB uint8 image."""
    ok, buffer = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR),
                              [cv2.IMWRITE_PNG_COMPRESSION, 3])
    if not ok:
        raise PhotoError(f"cannot encode an image of shape {rgb.shape} as PNG")
    return buffer.tobytes()
