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
    Tamura contrast and spectrum; None if the photo is missing or smaller than :data:`TACTUM_PHOTO_SIDE`.

    Parameters
    ----------
    scan : Scan
        Any scan.

    Returns
    -------
    PreparedPhoto or None
        The photo (:class:`features.image.PreparedPhoto`): its crop without the 100 px border as ``photo``,
        the shared images and statistics made on first use; or None.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta
    >>> from features.prepared import prepared_disp
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> prepared_disp(Scan(meta, images={"I_disp": np.zeros((264, 300, 3), np.uint8)})).photo.shape
    (64, 100, 3)
    >>> prepared_disp(Scan(meta, images={"I_disp": np.zeros((263, 300, 3), np.uint8)})) is None
    True
    """
    photo = scan.images.get("I_disp")
    if photo is None or min(photo.shape[:2]) < TACTUM_PHOTO_SIDE:
        return None
    return image.PreparedPhoto(photo)


class PreparedScan:
    """A scan and the intermediates its feature families share, each computed on first use: the slide start
    and window of a slide channel, its band-limited vibration and its slide signal (band limit, window,
    DFT321; docs/features.md#preprocessing), and the prepared ``I_disp``. Values equal those computed alone, bit for
    bit.

    Parameters
    ----------
    scan : Scan
        The scan to extract.
    """

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
        """:func:`scanner.preprocess.slide_start` of the channel ``name`` (``v_ts``, ``v_fs``).

        Parameters
        ----------
        name : str
            A slide channel of the scan.

        Returns
        -------
        int or None
            The start sample, or None if no slide is detected.

        Raises
        ------
        QualityError
            If the channel is too short for a noise level; raised again, not recomputed, on a later call.

        Examples
        --------
        A slide from 0.5 s (sample 1500) after a still start:

        >>> import numpy as np
        >>> from scanner import Scan, ScanMeta, Trace
        >>> from features.prepared import PreparedScan
        >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
        >>> v_ts = np.zeros((9000, 3))
        >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
        >>> prepared = PreparedScan(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
        >>> prepared.slide_start("v_ts")
        1500
        """
        trace = self.scan[name]
        return self._once("start", name, lambda: slide_start(trace.data, fs=trace.fs))

    def slide_window(self, name: str, *, audio_samples: int | None = None, ir_samples: int | None = None,
                     audio_fs: float = AUDIO_FS) -> SlideWindow:
        """:func:`scanner.preprocess.slide_window` of the channel ``name`` from its slide start found once.

        Parameters
        ----------
        name : str
            A slide channel of the scan.
        audio_samples, ir_samples : int, optional
            Lengths of the parallel audio and IR recordings, which must hold the window too.
        audio_fs : float
            Audio sample rate in Hz.

        Returns
        -------
        SlideWindow
            The 1 s window from the slide start.

        Raises
        ------
        QualityError
            If no slide is detected or less than 1 s of a recording follows its start.

        Examples
        --------
        >>> import numpy as np
        >>> from scanner import Scan, ScanMeta, Trace
        >>> from features.prepared import PreparedScan
        >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
        >>> v_ts = np.zeros((9000, 3))
        >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
        >>> prepared = PreparedScan(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
        >>> window = prepared.slide_window("v_ts", audio_samples=132300)
        >>> window.vibration, window.audio
        (slice(1500, 4500, None), slice(22050, 66150, None))
        """
        trace = self.scan[name]
        return window_at(self.slide_start(name), trace.n, fs=trace.fs, audio_samples=audio_samples,
                         ir_samples=ir_samples, audio_fs=audio_fs)

    def band_limited(self, name: str) -> np.ndarray:
        """:func:`scanner.preprocess.band_limit` of the whole channel ``name``.

        Parameters
        ----------
        name : str
            A vibration channel of the scan.

        Returns
        -------
        ndarray
            The channel band-limited to 10-1000 Hz, of its shape; the same array on every call.

        Examples
        --------
        >>> import numpy as np
        >>> from scanner import Scan, ScanMeta, Trace
        >>> from features.prepared import PreparedScan
        >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
        >>> v_ts = np.zeros((9000, 3))
        >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
        >>> prepared = PreparedScan(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
        >>> prepared.band_limited("v_ts").shape, prepared.band_limited("v_ts") is prepared.band_limited("v_ts")
        ((9000, 3), True)
        """
        trace = self.scan[name]
        return self._once("band", name, lambda: band_limit(trace.data, trace.fs))

    def slide_signal(self, name: str) -> np.ndarray:
        """:func:`scanner.preprocess.slide_signal` of the channel ``name``: band limit, window, DFT321.

        Parameters
        ----------
        name : str
            A slide channel of the scan (``v_ts`` gives ``v``, ``v_fs`` gives ``v_f``).

        Returns
        -------
        ndarray of shape (3000,)
            The 1 s slide signal.

        Raises
        ------
        QualityError
            If no slide is detected or less than 1 s follows its start.

        Examples
        --------
        A 0.4 g sine slide: 1 s of mean square ``0.4^2 / 2 = 0.08`` g^2:

        >>> import numpy as np
        >>> from scanner import Scan, ScanMeta, Trace
        >>> from features.prepared import PreparedScan
        >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
        >>> v_ts = np.zeros((9000, 3))
        >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
        >>> prepared = PreparedScan(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
        >>> v = prepared.slide_signal("v_ts")
        >>> v.shape, round(float(np.mean(v**2)), 3)
        ((3000,), 0.08)
        """
        return self._once("signal", name, lambda: dft321(self.band_limited(name)[self.slide_window(name).vibration]))

    @cached_property
    def disp(self) -> image.PreparedPhoto | None:
        """:func:`prepared_disp` of the scan (TacTUM first, then the image features, which release it)."""
        return prepared_disp(self.scan)
