"""One scan prepared for extraction: what several feature families share, computed once per scan.

:func:`features.extract` makes one :class:`PreparedScan` per scan and hands it to every registered family
(:mod:`features.registry`), so a shared intermediate is computed by the first family that asks for it.
"""

from __future__ import annotations

import dataclasses
import warnings
from functools import cached_property

from features import image, tactum
from scanner.preprocess import IMAGE_BORDER_PX
from scanner.scan import Scan

MIN_PHOTO_SIDE = 2 * IMAGE_BORDER_PX + image.MIN_SIDE_PX
"""Smallest photo side with image features: the crop plus 2 px (202 px); Tamura coarseness needs the crop
plus its largest pair of windows (264 px) and is NaN below that (``image.FEATURE_MIN_SIDE_PX``)."""

TACTUM_PHOTO_SIDE = 2 * IMAGE_BORDER_PX + 2 * 2**image.TAMURA_KMAX
"""Smallest ``I_disp`` side TacTUM's MaCo and MaRG are computed on (264 px)."""


def prepared_disp(scan: Scan) -> image.PreparedPhoto | None:
    """``I_disp`` prepared once for TacTUM (MaCo, MaRG) and its image features, which share its gray image,
    Tamura contrast and spectrum; None if the photo is missing or too small for image features."""
    photo = scan.images.get("I_disp")
    if photo is None or min(photo.shape[:2]) < TACTUM_PHOTO_SIDE:
        return None
    return image.PreparedPhoto(photo)


def without_short_channels(scan: Scan) -> Scan:
    """``scan`` without the channels too short for their features (``Scan.short_channels``), with a warning.

    Their features are then NaN like those of a missing channel: a single sample has no spread, no
    relaxation and no cooling curve, and computing them anyway gives silent zeros (SPEC 7).
    """
    short = scan.short_channels()
    if not short:
        return scan
    described = ", ".join(f"{name} ({scan[name].n} of the {need} samples its features need)"
                          for name, need in short.items())
    warnings.warn(f"scan {scan.scan_id}: too short: {described}; treated as missing", tactum.MissingDataWarning,
                  stacklevel=4)  # the caller of features.extract
    return dataclasses.replace(scan, traces={k: v for k, v in scan.traces.items() if k not in short})


class PreparedScan:
    """A scan and the intermediates its feature families share, each computed on first use.

    Channels too short for their features count as missing (:func:`without_short_channels`).
    """

    def __init__(self, scan: Scan) -> None:
        self.scan = without_short_channels(scan)

    @cached_property
    def disp(self) -> image.PreparedPhoto | None:
        """:func:`prepared_disp` of the scan (TacTUM first, then the image features, which release it)."""
        return prepared_disp(self.scan)
