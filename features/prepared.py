"""One scan prepared for extraction: what several feature families share, computed once per scan.

:func:`features.extract` makes one :class:`PreparedScan` per scan and hands it to every registered family
(:mod:`features.registry`), so a shared intermediate is computed by the first family that asks for it.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cached_property
from typing import Any

import numpy as np

from features import image
from scanner.preprocess import (
    AUDIO_FS,
    IMAGE_BORDER_PX,
    QualityError,
    SlideWindow,
    band_limit,
    dft321,
    slide_start,
    window_at,
)
from scanner.scan import Scan

MIN_PHOTO_SIDE = 2 * IMAGE_BORDER_PX + image.MIN_SIDE_PX
"""Smallest photo side with image features: the crop plus 2 px (202 px); Tamura coarseness needs the crop
plus its largest pair of windows (264 px) and is NaN below that (``image.FEATURE_MIN_SIDE_PX``)."""

TACTUM_PHOTO_SIDE = 2 * IMAGE_BORDER_PX + 2 * 2**image.TAMURA_KMAX
"""Smallest ``I_disp`` side TacTUM's MaCo and MaRG are computed on (264 px)."""


def prepared_disp(scan: Scan) -> image.PreparedPhoto | None:
    """``I_disp`` prepared once for TacTUM (MaCo, MaRG) and its image features, which share its gray image,
    Tamura contrast and spectrum; None if the photo is missing or smaller than :data:`TACTUM_PHOTO_SIDE`."""
    photo = scan.images.get("I_disp")
    if photo is None or min(photo.shape[:2]) < TACTUM_PHOTO_SIDE:
        return None
    return image.PreparedPhoto(photo)


class PreparedScan:
    """A scan and the intermediates its feature families share, each computed on first use: the slide start
    and window of a slide channel, its band-limited vibration and its slide signal (band limit, window,
    DFT321; docs/features.md#preprocessing), and the prepared ``I_disp``. Values equal those computed alone, bit for
    bit."""

    def __init__(self, scan: Scan) -> None:
        self.scan = scan
        self._memo: dict[tuple[str, str], Any] = {}

    def _once(self, what: str, name: str, compute: Callable[[], Any]) -> Any:
        """``compute()`` the first time, its value (or its exception, raised again) after that."""
        key = (what, name)
        if key not in self._memo:
            try:
                self._memo[key] = (compute(), None)
            except (QualityError, ValueError) as problem:
                self._memo[key] = (None, problem)
        value, problem = self._memo[key]
        if problem is not None:
            raise problem
        return value

    def slide_start(self, name: str) -> int | None:
        """:func:`scanner.preprocess.slide_start` of the channel ``name`` (``v_ts``, ``v_fs``)."""
        trace = self.scan[name]
        return self._once("start", name, lambda: slide_start(trace.data, fs=trace.fs))

    def slide_window(self, name: str, *, audio_samples: int | None = None, ir_samples: int | None = None,
                     audio_fs: float = AUDIO_FS) -> SlideWindow:
        """:func:`scanner.preprocess.slide_window` of the channel ``name`` from its slide start found once."""
        trace = self.scan[name]
        return window_at(self.slide_start(name), trace.n, fs=trace.fs, audio_samples=audio_samples,
                         ir_samples=ir_samples, audio_fs=audio_fs)

    def band_limited(self, name: str) -> np.ndarray:
        """:func:`scanner.preprocess.band_limit` of the whole channel ``name``."""
        trace = self.scan[name]
        return self._once("band", name, lambda: band_limit(trace.data, trace.fs))

    def slide_signal(self, name: str) -> np.ndarray:
        """:func:`scanner.preprocess.slide_signal` of the channel ``name``: band limit, window, DFT321."""
        return self._once("signal", name, lambda: dft321(self.band_limited(name)[self.slide_window(name).vibration]))

    @cached_property
    def disp(self) -> image.PreparedPhoto | None:
        """:func:`prepared_disp` of the scan (TacTUM first, then the image features, which release it)."""
        return prepared_disp(self.scan)
