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

The sizes are those the decoder will use: a JPEG's first frame header (libjpeg's), a TIFF's every page
(:func:`tiff_pages`: a directory naming its width or length twice, or as anything but one whole number, is
refused, as are files of more than :data:`MAX_TIFF_PAGES` pages or whose directories loop). Decoding is
bounded in time as well: a progressive JPEG is decoded once per scan, so one whose markers count more than
:data:`MAX_JPEG_SCANS` scans is refused from those markers (a 25-megapixel image repeating its last scan
3000 times took 68 s to decode).
"""

from __future__ import annotations

import os
import re
import struct
from pathlib import Path

import numpy as np

from scanner.lazy import library
from taxonomy.errors import ParameterError, TexplorerError

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
MAX_JPEG_SCANS = 32
"""Most scans a JPEG may have: a baseline JPEG has one (three when its colours are not interleaved),
libjpeg's progressive mode writes 10 for a colour image and mozjpeg's about as many; each scan costs a full
pass over the image (some 20 ms for 25 megapixels)."""
MAX_TIFF_PAGES = 16
"""Most pages (image file directories) a TIFF may have, every one within the pixel limit."""
MAX_TIFF_ENTRIES = 4096
"""Most entries one TIFF image directory may have (a real one has a few dozen)."""
_JPEG_MARKER_IN_SCAN = re.compile(rb"\xff+[^\x00\xff\xd0-\xd7]")
"""The first marker after a scan's entropy-coded data: 0xFF then neither a stuffed zero, a fill byte nor a
restart marker (which sit inside the scan)."""


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
        raise ParameterError(f"${MAX_PIXELS_ENV} must be a positive whole number of pixels, got {text!r}")
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


def jpeg_scans(data: bytes, stop_after: int = MAX_JPEG_SCANS) -> int:
    """The number of scans (start-of-scan segments) of JPEG bytes, counted from the markers up to the end
    of image, or ``stop_after + 1`` as soon as it is exceeded (a hostile file is not walked to its end)."""
    position, scans = 2, 0
    while position + 4 <= len(data):
        if data[position] != 0xFF:
            raise PhotoError("the JPEG file is damaged (bad marker)")
        marker = data[position + 1]
        if marker == 0xFF:  # fill byte before a marker
            position += 1
            continue
        if marker == 0xD9:  # end of image: the decoder reads nothing after it
            break
        if marker in (0x01, *range(0xD0, 0xD8)):  # markers without a length field
            position += 2
            continue
        (length,) = struct.unpack(">H", data[position + 2:position + 4])
        position += 2 + length
        if marker == 0xDA:
            scans += 1
            if scans > stop_after:
                break
            found = _JPEG_MARKER_IN_SCAN.search(data, position)
            if found is None:
                break
            position = found.end() - 2
    return scans


def _bmp_size(data: bytes) -> tuple[int, int]:
    """From the DIB header: 16-bit sides in the old OS/2 header (12 bytes), 32-bit (height signed) after."""
    if len(data) < 26:
        raise PhotoError("the BMP file is damaged (no image header)")
    if struct.unpack_from("<I", data, 14)[0] == 12:
        return struct.unpack_from("<HH", data, 18)
    width, height = struct.unpack_from("<ii", data, 18)
    return width, abs(height)


_TIFF_KINDS = {3: "H", 4: "I", 16: "Q"}
"""The TIFF field types a side may have: SHORT, LONG, LONG8."""


def tiff_pages(data: bytes) -> list[tuple[int, int]]:
    """``(width, length)`` of every page of TIFF bytes, following the chain of image file directories.

    Raises
    ------
    PhotoError
        A damaged directory; a side named twice in one directory (decoders differ in which they take: a
        0.4 MB file announcing 10 x 10 px decoded as 20000 x 10), given with a count other than one or as
        another type; directories that loop; more than :data:`MAX_TIFF_PAGES` pages.
    """
    order, big = TIFF_SIGNATURES[data[:4]]
    count_format, entry, offset_format = ("Q", 20, "Q") if big else ("H", 12, "I")
    pages: list[tuple[int, int]] = []
    seen: set[int] = set()
    try:
        directory = struct.unpack_from(order + offset_format, data, 8 if big else 4)[0]
        while directory:
            if directory in seen:
                raise PhotoError("the TIFF file is damaged (its image directories loop)")
            if len(pages) == MAX_TIFF_PAGES:
                raise PhotoError(f"the TIFF file has more than {MAX_TIFF_PAGES} pages")
            seen.add(directory)
            (entries,) = struct.unpack_from(order + count_format, data, directory)
            if entries > MAX_TIFF_ENTRIES:
                raise PhotoError(f"the TIFF file is damaged ({entries} entries in one image directory)")
            start = directory + struct.calcsize(count_format)
            sides: dict[int, int] = {}
            for k in range(entries):
                tag, kind = struct.unpack_from(order + "HH", data, start + k * entry)
                if tag not in (256, 257):
                    continue
                (count,) = struct.unpack_from(order + offset_format, data, start + k * entry + 4)
                if tag in sides:
                    raise PhotoError(f"the TIFF file names its image {'width' if tag == 256 else 'length'} twice")
                if kind not in _TIFF_KINDS or count != 1:
                    raise PhotoError("the TIFF file gives an image side as other than one whole number")
                value_at = start + k * entry + (12 if big else 8)
                sides[tag] = struct.unpack_from(order + _TIFF_KINDS[kind], data, value_at)[0]
            if len(sides) < 2:
                raise PhotoError("the TIFF file is damaged (no image width and length)")
            pages.append((sides[256], sides[257]))
            directory = struct.unpack_from(order + offset_format, data, start + entries * entry)[0]
    except struct.error:
        raise PhotoError("the TIFF file is damaged (no complete image directory)") from None
    return pages


def _tiff_size(data: bytes) -> tuple[int, int]:
    """The largest side of any page in each direction: every page is within the limit if this is."""
    pages = tiff_pages(data)
    return max(width for width, _ in pages), max(length for _, length in pages)


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

    Checked before decoding, so a small compressed file cannot expand into gigabytes, and neither can a
    JPEG of more than :data:`MAX_JPEG_SCANS` scans take minutes to decode. Other content passes here;
    :func:`decode` refuses it.
    """
    try:
        size = image_size(data)
        scans = jpeg_scans(data) if size is not None and size[0] == "JPEG" else 0
    except PhotoError as problem:
        raise PhotoError(f"{name}: {problem}") from None
    if size is not None:
        check_size(size[1], size[2], limit, name)
    if scans > MAX_JPEG_SCANS:
        raise PhotoError(f"{name}: the JPEG file has more than {MAX_JPEG_SCANS} scans (each a full decoding pass)")


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
    """Lossless PNG bytes of an RGB uint8 image: every row through PNG's "average" filter, then zlib level 1
    with run-length matching only (``Z_RLE``). On camera photos and on the simulated ones PNG's row filters
    leave little that longer matches find, so the files are smaller than at level 3 with the default
    strategy. One fixed filter instead of libpng's trial of five per row writes the 32 simulated materials'
    512 px photos in 0.55x the time for 2 % more bytes (one material's photo up to 11 %), and a 2048 px
    camera-like photo with sensor noise in 0.58x the time for the same size (docs/performance.md). OpenCV
    before 4.11 cannot choose the filter and tries all five."""
    options = [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]
    if hasattr(cv2, "IMWRITE_PNG_FILTER"):
        options += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_AVG]
    ok, buffer = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR), options)
    if not ok:
        raise PhotoError(f"cannot encode an image of shape {rgb.shape} as PNG")
    return buffer.tobytes()
