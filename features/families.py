"""The paper's feature families (Strese et al. 2020, section IV; docs/features.md), registered in extraction order.

=========  ==================================================  ==========================================
family     columns                                             module
=========  ==================================================  ==========================================
``tactum`` 15 TacTUM features (paper section IV-A)            :mod:`features.tactum`
``image``  31 per photo: ``image.disp``, ``image.macro``,      :mod:`features.image`
           ``image.illu``
``audio``  35 per slide: ``audio.finger`` (``a_fs``),          :mod:`features.audio`
           ``audio.tool`` (``a_ts``), in the 1 s slide window
``other``  15 more (docs/features.md#other)                                  :mod:`features.other`
=========  ==================================================  ==========================================

A new family is registered the same way (``REGISTRY.register(Family(...))``, see ``docs/extending.md``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterable

from features import audio, image, other, tactum
from features.prepared import MIN_PHOTO_SIDE, PreparedScan
from features.registry import REGISTRY, Family
from scanner.preprocess import QualityError
from scanner.scan import IMAGES, Scan

AUDIO_SIGNALS = {"finger": ("v_fs", "a_fs"), "tool": ("v_ts", "a_ts")}
"""Audio feature prefix -> (vibration that fixes the slide window, audio channel)."""

PHOTO_TITLES = {"disp": "image: photo", "macro": "image: macro lens", "illu": "image: flash"}
SLIDE_TITLES = {"finger": "audio: finger slide", "tool": "audio: tool slide"}


def _nan(names: Iterable[str]) -> dict[str, float]:
    return dict.fromkeys(names, math.nan)


def image_features(scan: Scan, disp: image.PreparedPhoto | None = None) -> dict[str, float]:
    """31 features for each photo (docs/features.md#image); NaN with a warning for a missing or too small photo.

    ``disp`` is ``I_disp`` already prepared (:func:`prepared_disp`); the other photos are prepared here.
    Each photo releases its memory once its features are computed (``disp`` too) and the next photo's
    gray image is computed in it: fresh memory is slow to fault in.

    Parameters
    ----------
    scan : Scan
        A scan with (some of) the photos ``I_disp``, ``I_macro``, ``I_illu``.
    disp : PreparedPhoto, optional
        ``I_disp`` prepared by :func:`features.prepared.prepared_disp`.

    Returns
    -------
    dict of str to float
        ``image.<photo>.<name>`` for the photos ``disp``, ``macro``, ``illu`` and each name of
        :data:`features.image.NAMES`, 93 values.

    Warns
    -----
    UserWarning
        Naming the scan and the photo that is missing or too small.

    Examples
    --------
    A uniform gray display photo: brightness 128 / 255, no edges; the two missing photos give NaN:

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> import math, warnings
    >>> from features.families import image_features
    >>> scan = Scan(meta, images={"I_disp": np.full((264, 264, 3), 128, dtype=np.uint8)})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     values = image_features(scan)
    >>> len(values), round(values["image.disp.brightness"] * 255, 6), values["image.disp.edginess"]
    (93, 128.0, 0.0)
    >>> math.isnan(values["image.macro.color"]), [str(warning.message) for warning in caught]
    (True, ['scan granite-01-001: no photo I_macro; its image features are NaN',
            'scan granite-01-001: no photo I_illu; its image features are NaN'])
    """
    values: dict[str, float] = {}
    spare = None
    for variable, short in IMAGES.items():
        names = [f"image.{short}.{name}" for name in image.NAMES]
        photo = scan.images.get(variable)
        if photo is None:
            warnings.warn(f"scan {scan.scan_id}: no photo {variable}; its image features are NaN", stacklevel=2)
            values.update(_nan(names))
        elif min(photo.shape[:2]) < MIN_PHOTO_SIDE:
            warnings.warn(f"scan {scan.scan_id}: photo {variable} of {photo.shape[1]}x{photo.shape[0]} px is smaller "
                          f"than {MIN_PHOTO_SIDE} px; its image features are NaN", stacklevel=2)
            values.update(_nan(names))
        else:
            shared = variable == "I_disp" and disp is not None
            prepared = disp if shared else image.PreparedPhoto(photo, keep_gray=False, buffer=spare)
            computed = image.compute(photo, prepared=prepared)
            spare = prepared.release()
            values.update({f"image.{short}.{name}": computed[name] for name in image.NAMES})
    return values


def audio_features(scan: Scan, prepared: PreparedScan | None = None) -> dict[str, float]:
    """35 features of the finger and of the tool audio in the 1 s slide window (docs/features.md#audio).

    Parameters
    ----------
    scan : Scan
        A scan with the slides' vibrations ``v_fs``, ``v_ts`` and audio ``a_fs``, ``a_ts``.
    prepared : PreparedScan, optional
        The scan prepared for extraction, whose slide windows are found once.

    Returns
    -------
    dict of str to float
        ``audio.<slide>.<name>`` for the slides ``finger``, ``tool`` and each name of
        :data:`features.audio.NAMES`, 70 values.

    Warns
    -----
    UserWarning
        Naming the scan and the channel that is missing or whose slide check fails.

    Examples
    --------
    The tool slide starts at 0.5 s, so its window holds 1 s of a 441 Hz tone from 0.5 s on; the
    scan has no finger slide:

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> import warnings
    >>> from features.families import audio_features
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> a_ts = 0.5 * np.sin(2 * np.pi * 441.0 * np.arange(132300) / 44100.0)
    >>> scan = Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g"), "a_ts": Trace(a_ts, 44100.0, "FS")})
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     values = audio_features(scan)
    >>> len(values), round(values["audio.tool.f0"], 6), values["audio.finger.f0"]
    (70, 441.0, nan)
    >>> [str(warning.message) for warning in caught]
    ['scan granite-01-001: no a_fs or v_fs; audio.finger features are NaN']
    """
    values: dict[str, float] = {}
    prepared = prepared or PreparedScan(scan)
    for which, (vibration, sound) in AUDIO_SIGNALS.items():
        names = [f"audio.{which}.{name}" for name in audio.NAMES]
        v, a = scan.get(vibration), scan.get(sound)
        missing = [name for name, trace in ((sound, a), (vibration, v)) if trace is None]
        if missing:
            warnings.warn(f"scan {scan.scan_id}: no {' or '.join(missing)}; audio.{which} features are NaN",
                          stacklevel=2)
            values.update(_nan(names))
            continue
        try:
            window = prepared.slide_window(vibration, audio_samples=a.n, audio_fs=a.fs)
        except QualityError as problem:
            warnings.warn(f"scan {scan.scan_id}: {vibration}: {problem}; audio.{which} features are NaN",
                          stacklevel=2)
            values.update(_nan(names))
            continue
        computed = audio.compute(a.data[window.audio], fs=a.fs)
        values.update({f"audio.{which}.{name}": computed[name] for name in audio.NAMES})
    return values


def _tactum(prepared: PreparedScan) -> dict[str, float]:
    return tactum.compute(prepared.scan, disp=prepared.disp, prepared=prepared)


def _image(prepared: PreparedScan) -> dict[str, float]:
    return image_features(prepared.scan, prepared.disp)


def _audio(prepared: PreparedScan) -> dict[str, float]:
    return audio_features(prepared.scan, prepared)


def _other(prepared: PreparedScan) -> dict[str, float]:
    return other.compute(prepared.scan, prepared=prepared)


TACTUM_UNITS = {"mico": "Hz", "ccp": "N/mm", "cdf": "deg", "cdp": "N.s/deg", "crx": "N", "tco": "K", "tpr": "K"}
"""Units of the TacTUM features that have one (docs/features.md#tactum; ``matx``, ``maco`` and ``marg`` mix units)."""
IMAGE_UNITS = {"color": "deg", "dft_80": "gray level", "dft_85": "gray level", "tamura_coarseness": "px",
               "tamura_contrast": "gray level"}
"""Units of one photo's features that have one (docs/features.md#image)."""
AUDIO_UNITS = {"zcr": "1/sample", "energy": "FS^2", "energy_entropy": "bit", "spectral_entropy": "bit", "f0": "Hz"}
"""Units of one slide's audio features that have one (docs/features.md#audio)."""
OTHER_UNITS = {"density": "g/cm^3", "magnet_mean": "uT", "magnet_peak": "uT", "reflect_static": "V",
               "reflect_mean": "V", "cooling_rate": "1/s", "vib_std": "g", "vib_energy": "g^2",
               "finger_vib_energy": "g^2", "finger_vib_centroid": "Hz", "tap_peak": "g", "tap_centroid": "Hz",
               "tap_decay": "s"}
"""Units of the other features that have one (docs/features.md#other)."""

TACTUM_STEPS = {"matx": ("tool_slide", "friction"), "maco": ("tool_slide", "photos"), "marg": ("tool_slide", "photos"),
                "miro": ("tool_slide",), "mico": ("tool_slide",), "fst": ("friction",), "frs": ("friction",),
                "atk": ("tu4",), "ccp": ("press", "fold"), "cdf": ("fold",), "cdp": ("fold",),
                "crx": ("press", "fold"), "cyd": ("tu4",), "tco": ("thermal",), "tpr": ("thermal",)}
"""The steps of the procedure each TacTUM feature needs: MATX mixes the tool slide with the friction slide, MACO
and MARG the tool slide with the display photo, and the press features are 0 for a sample the fold finds rigid."""
OTHER_STEPS = {"density": ("tu4",), "metal": ("static",), "magnet_mean": ("static",), "magnet_peak": ("static",),
               "reflect_static": ("tool_slide",), "reflect_mean": ("tool_slide",), "cooling_rate": ("thermal",),
               "vib_std": ("tool_slide",), "vib_kurtosis": ("tool_slide",), "vib_energy": ("tool_slide",),
               "finger_vib_energy": ("finger_slide",), "finger_vib_centroid": ("finger_slide",),
               "tap_peak": ("tool_tap",), "tap_centroid": ("tool_tap",), "tap_decay": ("tool_tap",)}
"""The step of the procedure each other feature needs."""

TACTUM = REGISTRY.register(Family("tactum", "TacTUM (paper section IV-A)", tactum.NAMES, _tactum,
                                  units={f"tactum.{name}": unit for name, unit in TACTUM_UNITS.items()},
                                  steps={f"tactum.{name}": steps for name, steps in TACTUM_STEPS.items()}))
IMAGE = REGISTRY.register(Family(
    "image", "image", tuple(f"image.{short}.{name}" for short in IMAGES.values() for name in image.NAMES), _image,
    groups=tuple((f"image.{short}", PHOTO_TITLES[short]) for short in IMAGES.values()),
    units={f"image.{short}.{name}": unit for short in IMAGES.values() for name, unit in IMAGE_UNITS.items()},
    steps={"image": ("photos",)}))
AUDIO = REGISTRY.register(Family(
    "audio", "audio", tuple(f"audio.{which}.{name}" for which in AUDIO_SIGNALS for name in audio.NAMES), _audio,
    groups=tuple((f"audio.{which}", SLIDE_TITLES[which]) for which in AUDIO_SIGNALS),
    units={f"audio.{which}.{name}": unit for which in AUDIO_SIGNALS for name, unit in AUDIO_UNITS.items()},
    steps={f"audio.{which}": (f"{which}_slide",) for which in AUDIO_SIGNALS}))
OTHER = REGISTRY.register(Family("other", "other", other.NAMES, _other, solver_rtol=other.SOLVER_RTOL,
                                 units={f"other.{name}": unit for name, unit in OTHER_UNITS.items()},
                                 steps={f"other.{name}": steps for name, steps in OTHER_STEPS.items()}))

NAMES: tuple[str, ...] = REGISTRY.names
"""The paper's 193 feature names in the order of docs/features.md: 15 TacTUM, 93 image (disp, macro, illu x 31), 70
audio (finger, tool x 35), 15 other."""

SOLVER_RTOL: dict[str, float] = REGISTRY.solver_rtol
"""Relative tolerance of each of these features computed by an iterative fit (the others are closed-form)."""
