"""The TU3 camera (SPEC 5): OpenCV ``VideoCapture`` on a camera index, a stream URL or a video file, or an
uploaded photo file (PNG or JPEG; HEIC photos must be converted to PNG first).

:class:`OpenCvCamera` lets the exposure settle for ``camera.warmup_frames`` frames and keeps the next one; the
operator mounts the 4x lens for ``I_macro`` and switches the flash on for ``I_illu`` when the session says
so. :class:`PlaybackCamera` is the simulated and replay camera. :func:`decode_photo` turns uploaded bytes
into an RGB array.
"""

from __future__ import annotations

import struct
from typing import Any

import cv2
import numpy as np

from scanner.config import CameraConfig
from scanner.devices.protocols import DeviceError, DeviceUnavailable
from scanner.devices.sources import SignalSource
from scanner.scan import IMAGES

MAX_PHOTO_BYTES = 40 << 20
MAX_PHOTO_PIXELS = 50_000_000
"""Four times a 12-megapixel phone photo (3024 x 4032, the paper's camera)."""
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
JPEG_SIGNATURE = b"\xff\xd8\xff"
_JPEG_FRAME_MARKERS = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""Start-of-frame markers SOF0-SOF15; C4 (Huffman tables), C8 (reserved) and CC (arithmetic) are not."""
"""Uploads larger than this are refused (a 12 MP PNG is about 25 MB)."""
MIN_PHOTO_PX = 16


class PhotoError(ValueError):
    """An uploaded photo cannot be used; the message says why in one line."""


def _source(text: str) -> int | str:
    text = text.strip()
    return int(text) if text.isdigit() else text


class OpenCvCamera:
    """A camera (or stream, or video file) through OpenCV's ``VideoCapture``."""

    def __init__(self, config: CameraConfig) -> None:
        self.config = config
        self.source = _source(config.source)
        self._capture = cv2.VideoCapture(self.source)
        if not self._capture.isOpened():
            self._capture.release()
            raise DeviceUnavailable(f"camera {config.source!r} cannot be opened "
                                    "(no such camera, URL or file)")

    def describe(self) -> dict[str, str]:
        return {"camera": f"OpenCV {self._capture.getBackendName()} {self.config.source}"}

    def capture(self, photo: str) -> np.ndarray:
        """One RGB uint8 frame after ``warmup_frames`` frames (auto exposure and focus settle)."""
        if photo not in IMAGES:
            raise ValueError(f"{photo!r} is not a photo (known: {', '.join(IMAGES)})")
        frame = None
        for _ in range(self.config.warmup_frames + 1):
            ok, grabbed = self._capture.read()
            if not ok:
                break
            frame = grabbed
        if frame is None:
            raise DeviceError(f"camera {self.config.source!r}: no frame for {photo}")
        return _rgb(frame)

    def close(self) -> None:
        self._capture.release()


def _rgb(frame: np.ndarray) -> np.ndarray:
    if frame.ndim == 2:
        return cv2.cvtColor(frame, cv2.COLOR_GRAY2RGB)
    if frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2RGB)
    return cv2.cvtColor(frame, cv2.COLOR_BGR2RGB)


class PlaybackCamera:
    """The simulated or replay camera: the source's photos, a new take when a photo is taken again."""

    def __init__(self, source: SignalSource) -> None:
        self.source = source
        self._take: dict[str, Any] = {}
        self._taken: set[str] = set()

    def describe(self) -> dict[str, str]:
        return {"camera": f"TU3 camera ({self.source.kind})"}

    def capture(self, photo: str) -> np.ndarray:
        if photo not in IMAGES:
            raise ValueError(f"{photo!r} is not a photo (known: {', '.join(IMAGES)})")
        if not self._take or photo in self._taken:
            self._take, self._taken = dict(self.source.photos("camera")), set()
        self._taken.add(photo)
        if photo not in self._take:
            raise DeviceError(f"camera: the replayed scan has no {photo}")
        return np.array(self._take[photo], dtype=np.uint8)

    def close(self) -> None:
        self._take = {}


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


def image_size(data: bytes) -> tuple[str, int, int] | None:
    """``(kind, width, height)`` of PNG or JPEG bytes from the header alone, or None for other content.

    Raises
    ------
    PhotoError
        A PNG or JPEG signature with a damaged header.
    """
    if data.startswith(PNG_SIGNATURE):
        return ("PNG", *_png_size(data))
    if data.startswith(JPEG_SIGNATURE):
        return ("JPEG", *_jpeg_size(data))
    return None


def check_pixels(data: bytes, max_pixels: int = MAX_PHOTO_PIXELS, name: str = "the photo") -> None:
    """Refuse PNG/JPEG bytes whose header announces an empty image or more than ``max_pixels`` pixels.

    Checked before decoding, so a small compressed file cannot expand into gigabytes. Other content
    passes here; decoding refuses it with its own reason.
    """
    size = image_size(data)
    if size is None:
        return
    kind, width, height = size
    if width < 1 or height < 1:
        raise PhotoError(f"{name}: the {kind} header gives an empty image ({width} x {height} px)")
    if width * height > max_pixels:
        raise PhotoError(f"{name}: the image has {width * height / 1e6:.1f} megapixels ({width} x {height} px); "
                         f"at most {max_pixels / 1e6:g} are accepted")


def decode_photo(data: bytes, name: str = "upload", max_pixels: int = MAX_PHOTO_PIXELS) -> np.ndarray:
    """An uploaded PNG or JPEG file -> RGB uint8 (h, w, 3); :class:`PhotoError` for anything else.

    HEIC (the iPhone default) is recognised and refused with the advice to convert it to PNG.
    """
    if len(data) > MAX_PHOTO_BYTES:
        raise PhotoError(f"{name}: {len(data) >> 20} MB is larger than the {MAX_PHOTO_BYTES >> 20} MB limit")
    if data[4:12] in (b"ftypheic", b"ftypheix", b"ftypmif1", b"ftyphevc"):
        raise PhotoError(f"{name}: HEIC photos are not read directly; convert it to PNG first")
    if not (data.startswith(PNG_SIGNATURE) or data.startswith(JPEG_SIGNATURE)):
        raise PhotoError(f"{name}: not a PNG or JPEG file")
    check_pixels(data, max_pixels, name)
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise PhotoError(f"{name}: the file is damaged and cannot be decoded")
    if min(image.shape[:2]) < MIN_PHOTO_PX:
        raise PhotoError(f"{name}: {image.shape[1]}x{image.shape[0]} px is too small")
    return _rgb(image)
