"""The TU3 camera (docs/devices.md): OpenCV ``VideoCapture`` on a camera index, a stream URL or a video file, or an
uploaded photo file (PNG or JPEG; HEIC photos must be converted to PNG first).

:class:`OpenCvCamera` lets the exposure settle for ``camera.warmup_frames`` frames and keeps the next one; the
operator mounts the 4x lens for ``I_macro`` and switches the flash on for ``I_illu`` when the session says
so. :class:`PlaybackCamera` is the simulated and replay camera. :func:`decode_photo` turns uploaded bytes
into an RGB array.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from scanner.acquisition.config import CameraConfig
from scanner.acquisition.devices.protocols import DeviceError, DeviceUnavailable
from scanner.acquisition.devices.sources import SignalSource
from scanner.photo import PhotoError, check_size, decode
from scanner.scan import IMAGES
from taxonomy.errors import ParameterError

MAX_PHOTO_BYTES = 40 << 20
"""Uploads larger than this are refused (a 12 MP PNG is about 25 MB)."""
MIN_PHOTO_PX = 16


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
        announced = (int(self._capture.get(cv2.CAP_PROP_FRAME_WIDTH)),
                     int(self._capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if min(announced) > 0:  # 0 where the backend cannot tell before the first frame
            self._check_frame_size(*announced)

    def _check_frame_size(self, width: int, height: int) -> None:
        """Refuse frames beyond the photo limit (:mod:`scanner.photo`), announced or delivered."""
        try:
            check_size(width, height, name=f"camera {self.config.source!r}")
        except PhotoError as problem:
            self._capture.release()
            raise DeviceError(str(problem)) from None

    def describe(self) -> dict[str, str]:
        return {"camera": f"OpenCV {self._capture.getBackendName()} {self.config.source}"}

    def capture(self, photo: str) -> np.ndarray:
        """One RGB uint8 frame after ``warmup_frames`` frames (auto exposure and focus settle)."""
        if photo not in IMAGES:
            raise ParameterError(f"{photo!r} is not a photo (known: {', '.join(IMAGES)})")
        frame = None
        for _ in range(self.config.warmup_frames + 1):
            ok, grabbed = self._capture.read()
            if not ok:
                break
            frame = grabbed
        if frame is None:
            raise DeviceError(f"camera {self.config.source!r}: no frame for {photo}")
        self._check_frame_size(frame.shape[1], frame.shape[0])
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
            raise ParameterError(f"{photo!r} is not a photo (known: {', '.join(IMAGES)})")
        if not self._take or photo in self._taken:
            self._take, self._taken = dict(self.source.photos("camera")), set()
        self._taken.add(photo)
        if photo not in self._take:
            raise DeviceError(f"camera: the replayed scan has no {photo}")
        return np.array(self._take[photo], dtype=np.uint8)

    def close(self) -> None:
        self._take = {}


def decode_photo(data: bytes, name: str = "upload", max_pixels: int | None = None) -> np.ndarray:
    """An uploaded PNG or JPEG file -> RGB uint8 (h, w, 3); :class:`PhotoError` for anything else.

    The pixel limit is ``max_pixels``, else :func:`scanner.photo.max_pixels`. HEIC (the iPhone default)
    is recognised and refused with the advice to convert it to PNG.
    """
    if len(data) > MAX_PHOTO_BYTES:
        raise PhotoError(f"{name}: {len(data) >> 20} MB is larger than the {MAX_PHOTO_BYTES >> 20} MB limit")
    if data[4:12] in (b"ftypheic", b"ftypheix", b"ftypmif1", b"ftyphevc"):
        raise PhotoError(f"{name}: HEIC photos are not read directly; convert it to PNG first")
    image = decode(data, name, max_pixels)
    if min(image.shape[:2]) < MIN_PHOTO_PX:
        raise PhotoError(f"{name}: {image.shape[1]}x{image.shape[0]} px is too small")
    return image
