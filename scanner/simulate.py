"""The simulated Texplorer2: physically plausible scans from a material library (SPEC 5 "Simulated scanner").

The material library is data (``scanner/data/materials.toml``, one table per material); this module turns a
material, a seed and a per-scan operator draw into every channel of SPEC 3 at its true rate, following the
scanning procedure of SPEC 4 one step at a time:

======================  ========================================================================
step                    what is synthesised
======================  ========================================================================
``finger_tap``          ``v_ft``: decaying contact resonances, frequency rising with stiffness
``finger_slide``        ``v_fs``, ``a_fs``, ``r_fs``: rest, then the finger slides over the surface
``tool_tap``            ``v_tt``: as the finger tap, through the steel tool tip
``tool_slide``          ``v_ts``, ``a_ts``, ``r_ts``: rest, then the tool tip slides
``static``              ``m`` (metal electrodes) and ``dB`` (magnetometer), 1 s
``thermal``             ``t_cool``: 10 s of MLX90614 readings after 3 s of Peltier heating
``friction``            ``f_frn``, ``f_frt``: press, static peak, kinetic sliding, release
``press``               ``f_press``: 4.0 mm indentation held, with relaxation
``fold``                ``f_fold``, ``alpha_f`` (absent when the operator skips it for a rigid sample)
``photos``              ``I_disp``, ``I_macro`` (4x lens), ``I_illu`` (flash): procedural textures
``tu4``                 mass, volume, judged adhesive tack and yielding
======================  ========================================================================

Every step function has the signature ``step(material, rng, operator)`` and returns that step's arrays, so a
simulated device can produce one step at a time. Vibration is modelled as the tip following a surface
height profile ``z(x)`` along the path ``x(t)``: its acceleration ``v^2 z''(x) + v' z'(x)`` passes the
tip-surface contact resonance (the tap frequency) to the accelerometer and a radiation filter to the
microphone, so the spectrum scales with the slide speed; the IR sensor sees the same macro profile.

Sensors are modelled at the level the host sees them: the ADXL335 through the DAQ (1.65 V zero,
0.330 V/g, 16-bit over +-10 V, +-3.6 g), FSR volts mapped through paper eq. (1), the MLX90614's 0.02 degC
steps, the MAG3110's 0.1 uT steps and 16-bit audio.
"""

from __future__ import annotations

import concurrent.futures
import math
import os
import re
import sys
import tomllib
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, fields, replace
from datetime import datetime, timedelta
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from scipy import ndimage, signal, special
from tqdm import tqdm

import scanner
from scanner.database import Database
from scanner.preprocess import ACCEL_V_PER_G, ACCEL_ZERO_V, accel_g, fsr_newtons, fsr_volts
from scanner.scan import CHANNELS, JUDGED_SCALE, Scan, ScanMeta, Trace
from taxonomy.errors import TexplorerError

DEFAULT_LIBRARY = Path(__file__).with_name("data") / "materials.toml"

FS_DAQ = CHANNELS["v_ts"].fs
FS_AUDIO = CHANNELS["a_ts"].fs
FS_THERMAL = CHANNELS["t_cool"].fs
FS_MAGNET = CHANNELS["dB"].fs
STEP_S = 5.0
"""Length of every tap, slide, friction, press and fold recording (SPEC 4)."""
STATIC_S = 1.0
COOL_S = 10.0
INDENTATION_MM = 4.0
"""The TU2 casing stops the hemisphere at this indentation (paper Fig. 12)."""
G_MM_S2 = 9806.65

TEXTURES = ("smooth", "grain", "speckle", "granular", "cellular", "fibrous", "brushed", "veined", "weave",
            "perforated", "ribbed")
MAGNETIC_TYPES = ("ferro", "para", "none", "dia")
STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press",
         "fold", "photos", "tu4")
"""Procedure steps in the order of SPEC 4; each has a step function in :data:`STEP_FUNCTIONS`."""


Rng = np.random.Generator
Arrays = dict[str, np.ndarray]
Layers = tuple[np.ndarray, np.ndarray]
"""A texture's colour field (0 = dominant colour .. 1 = last colour) and its surface height."""


class MaterialLibraryError(TexplorerError, ValueError):
    """The material library file is malformed; the message names the file, the material and the field."""


# --------------------------------------------------------------------------------------------------
# The material model
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Roughness:
    """Surface profile: micro-roughness spectrum and macro-structure (bump or pit train)."""

    micro_um: float
    cutoff_per_mm: float
    exponent: float
    macro_spacing_mm: float
    macro_height_um: float
    macro_duty: float
    macro_regularity: float


@dataclass(frozen=True)
class Friction:
    """Coulomb coefficients against the TU2 finger contact."""

    static: float
    kinetic: float


@dataclass(frozen=True)
class Compliance:
    """Press stiffness (``inf`` = rigid), tap resonance inputs, relaxation and folding."""

    stiffness_n_per_mm: float
    elastic_modulus_mpa: float
    loss_factor: float
    relaxation: float
    relaxation_time_s: float
    foldable: bool
    fold_angle_deg: float = 0.0
    fold_stiffness_n_per_deg: float = 0.0
    fold_damping_n_s_per_deg: float = 0.0

    @property
    def rigid(self) -> bool:
        """True when an operator cannot indent the sample by 4.0 mm at all."""
        return math.isinf(self.stiffness_n_per_mm)


@dataclass(frozen=True)
class Thermal:
    """Heated-spot rise seen by the MLX90614 and the cooling rate r of paper eq. (26)."""

    heat_rise_k: float
    cooling_rate_per_s: float


@dataclass(frozen=True)
class Reflectance:
    """IR reflectance level (0..1) and its relative variation along a slide."""

    level: float
    variation: float


@dataclass(frozen=True)
class Appearance:
    """Photo appearance: procedural texture, colours (RGB 0..255, dominant first) and pattern parameters."""

    texture: str
    colors: tuple[tuple[float, float, float], ...]
    frequency_per_mm: float
    orientation_deg: float
    contrast: float
    duty: float
    relief: float
    gloss: float


@dataclass(frozen=True)
class Material:
    """One material of the library (SPEC 5): every property the simulated scanner draws on."""

    slug: str
    label: str
    name: str
    density_g_cm3: float
    sample_volume_cm3: float
    conductive: bool
    magnetic: str
    magnet_response_ut: float
    adhesive_tack: float
    yielding: float
    roughness: Roughness
    friction: Friction
    compliance: Compliance
    thermal: Thermal
    reflectance: Reflectance
    appearance: Appearance


# --------------------------------------------------------------------------------------------------
# Loading and validating the library
# --------------------------------------------------------------------------------------------------

_LABEL_FORM = "C<c>S<s>M<m>P<p>X<x>"


class _Where:
    """Names the place of a value in the library for one-line error messages."""

    def __init__(self, path: Path, slug: str, section: str = "") -> None:
        self.path, self.slug, self.section = path, slug, section

    def fail(self, key: str, problem: str) -> MaterialLibraryError:
        field_name = f"{self.section}.{key}" if self.section else key
        return MaterialLibraryError(f"{self.path.name}: material {self.slug!r}: {field_name} {problem}")


def _take(table: Mapping[str, Any], key: str, where: _Where) -> Any:
    if key not in table:
        raise where.fail(key, "is missing")
    return table[key]


def _number(table: Mapping[str, Any], key: str, where: _Where, lo: float, hi: float) -> float:
    value = _take(table, key, where)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise where.fail(key, f"must be a number, got {type(value).__name__} {value!r}")
    if not (lo <= value <= hi):
        raise where.fail(key, f"= {value!r} is out of range [{lo:g}, {hi:g}]")
    return float(value)


def _boolean(table: Mapping[str, Any], key: str, where: _Where) -> bool:
    value = _take(table, key, where)
    if not isinstance(value, bool):
        raise where.fail(key, f"must be true or false, got {value!r}")
    return value


def _text(table: Mapping[str, Any], key: str, where: _Where, choices: tuple[str, ...] | None = None) -> str:
    value = _take(table, key, where)
    if not isinstance(value, str) or not value.strip():
        raise where.fail(key, f"must be a non-empty string, got {value!r}")
    if choices is not None and value not in choices:
        raise where.fail(key, f"= {value!r} is unknown (one of: {', '.join(choices)})")
    return value


def _judged(table: Mapping[str, Any], key: str, where: _Where) -> float:
    value = _number(table, key, where, 0.0, 1.0)
    if value not in JUDGED_SCALE:
        raise where.fail(key, f"= {value!r} is not on the five-step scale {JUDGED_SCALE}")
    return value


def _section(table: Mapping[str, Any], key: str, where: _Where) -> tuple[Mapping[str, Any], _Where]:
    value = _take(table, key, where)
    if not isinstance(value, dict):
        raise where.fail(key, "must be a table")
    return value, _Where(where.path, where.slug, key)


def _no_extra(table: Mapping[str, Any], allowed: Iterable[str], where: _Where) -> None:
    extra = sorted(set(table) - set(allowed))
    if extra:
        raise where.fail(extra[0], "is not a known field")


def _names(cls: type) -> list[str]:
    return [f.name for f in fields(cls)]


def _roughness(table: Mapping[str, Any], where: _Where) -> Roughness:
    _no_extra(table, _names(Roughness), where)
    return Roughness(
        micro_um=_number(table, "micro_um", where, 0.0, 500.0),
        cutoff_per_mm=_number(table, "cutoff_per_mm", where, 0.05, 50.0),
        exponent=_number(table, "exponent", where, 1.0, 6.0),
        macro_spacing_mm=_number(table, "macro_spacing_mm", where, 0.2, 50.0),
        macro_height_um=_number(table, "macro_height_um", where, -5000.0, 5000.0),
        macro_duty=_number(table, "macro_duty", where, 0.05, 0.95),
        macro_regularity=_number(table, "macro_regularity", where, 0.0, 1.0),
    )


def _friction(table: Mapping[str, Any], where: _Where) -> Friction:
    _no_extra(table, _names(Friction), where)
    static = _number(table, "static", where, 0.05, 3.0)
    kinetic = _number(table, "kinetic", where, 0.05, 3.0)
    if kinetic > static:
        raise where.fail("kinetic", f"= {kinetic!r} exceeds static = {static!r}")
    return Friction(static, kinetic)


def _compliance(table: Mapping[str, Any], where: _Where) -> Compliance:
    fold_fields = ("fold_angle_deg", "fold_stiffness_n_per_deg", "fold_damping_n_s_per_deg")
    _no_extra(table, _names(Compliance), where)
    stiffness = _take(table, "stiffness_n_per_mm", where)
    if stiffness == "rigid":
        stiffness = math.inf
    else:
        stiffness = _number(table, "stiffness_n_per_mm", where, 0.01, 1000.0)
    foldable = _boolean(table, "foldable", where)
    if foldable:
        fold = (_number(table, "fold_angle_deg", where, 5.0, 180.0),
                _number(table, "fold_stiffness_n_per_deg", where, 1e-4, 1.0),
                _number(table, "fold_damping_n_s_per_deg", where, 0.0, 0.1))
    else:
        present = [key for key in fold_fields if key in table]
        if present:
            raise where.fail(present[0], "is only allowed for foldable materials")
        fold = (0.0, 0.0, 0.0)
    return Compliance(stiffness, _number(table, "elastic_modulus_mpa", where, 0.001, 1e6),
                      _number(table, "loss_factor", where, 0.0, 1.0),
                      _number(table, "relaxation", where, 0.0, 0.9),
                      _number(table, "relaxation_time_s", where, 0.05, 20.0), foldable, *fold)


def _thermal(table: Mapping[str, Any], where: _Where) -> Thermal:
    _no_extra(table, _names(Thermal), where)
    return Thermal(_number(table, "heat_rise_k", where, 0.0, 30.0),
                   _number(table, "cooling_rate_per_s", where, 0.005, 10.0))


def _reflectance(table: Mapping[str, Any], where: _Where) -> Reflectance:
    _no_extra(table, _names(Reflectance), where)
    return Reflectance(_number(table, "level", where, 0.0, 1.0), _number(table, "variation", where, 0.0, 1.0))


def _colors(table: Mapping[str, Any], where: _Where) -> tuple[tuple[float, float, float], ...]:
    value = _take(table, "colors", where)
    ok = (isinstance(value, list) and 1 <= len(value) <= 3
          and all(isinstance(c, list) and len(c) == 3
                  and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in c)
                  for c in value))
    if not ok:
        raise where.fail("colors", f"must be 1-3 RGB triples of integers 0..255, got {value!r}")
    return tuple((float(c[0]), float(c[1]), float(c[2])) for c in value)


def _appearance(table: Mapping[str, Any], where: _Where) -> Appearance:
    _no_extra(table, _names(Appearance), where)
    return Appearance(
        texture=_text(table, "texture", where, TEXTURES),
        colors=_colors(table, where),
        frequency_per_mm=_number(table, "frequency_per_mm", where, 0.01, 50.0),
        orientation_deg=_number(table, "orientation_deg", where, -180.0, 180.0),
        contrast=_number(table, "contrast", where, 0.0, 1.0),
        duty=_number(table, "duty", where, 0.0, 1.0),
        relief=_number(table, "relief", where, 0.0, 1.0),
        gloss=_number(table, "gloss", where, 0.0, 1.0),
    )


def _magnet(table: Mapping[str, Any], where: _Where) -> tuple[str, float]:
    kind = _text(table, "magnetic", where, MAGNETIC_TYPES)
    ranges = {"ferro": (5.0, 500.0), "para": (1e-3, 2.0), "none": (0.0, 0.0), "dia": (-1.0, -1e-3)}
    lo, hi = ranges[kind]
    value = _number(table, "magnet_response_ut", where, -1.0, 500.0)
    if not lo <= value <= hi:
        raise where.fail("magnet_response_ut", f"= {value!r} does not fit magnetic = {kind!r} "
                                               f"(expected [{lo:g}, {hi:g}])")
    return kind, value


_SECTIONS: dict[str, Callable[[Mapping[str, Any], _Where], Any]] = {
    "roughness": _roughness, "friction": _friction, "compliance": _compliance, "thermal": _thermal,
    "reflectance": _reflectance, "appearance": _appearance,
}
_TOP_LEVEL = ("label", "name", "density_g_cm3", "sample_volume_cm3", "conductive", "magnetic",
              "magnet_response_ut", "adhesive_tack", "yielding")


def _material(slug: str, table: Any, path: Path) -> Material:
    where = _Where(path, slug)
    if not isinstance(table, dict):
        raise MaterialLibraryError(f"{path.name}: material {slug!r} must be a table")
    _no_extra(table, (*_TOP_LEVEL, *_SECTIONS), where)
    label = _text(table, "label", where)
    if not _is_label(label):
        raise where.fail("label", f"= {label!r} is not of the form {_LABEL_FORM}")
    sections = {name: build(*_section(table, name, where)) for name, build in _SECTIONS.items()}
    magnetic, response = _magnet(table, where)
    return Material(
        slug=slug, label=label, name=_text(table, "name", where),
        density_g_cm3=_number(table, "density_g_cm3", where, 0.005, 25.0),
        sample_volume_cm3=_number(table, "sample_volume_cm3", where, 1.0, 5000.0),
        conductive=_boolean(table, "conductive", where), magnetic=magnetic, magnet_response_ut=response,
        adhesive_tack=_judged(table, "adhesive_tack", where), yielding=_judged(table, "yielding", where),
        **sections)


def _is_label(text: str) -> bool:
    return re.fullmatch(r"C[1-9]\d*S[1-9]\d*M[1-9]\d*P[1-9]\d*X[1-9]\d*", text) is not None


def load_materials(path: str | Path | None = None) -> dict[str, Material]:
    """Read and validate a material library (default: the shipped ``scanner/data/materials.toml``).

    Returns materials keyed by slug, in file order. Any problem raises :class:`MaterialLibraryError` with
    one line naming the file, the material and the field (missing, wrong type, out of range, unknown
    magnetic type or texture, malformed label, unknown field).
    """
    if path is None:
        return dict(_default_library())
    return _read_library(Path(path))


@lru_cache(maxsize=1)
def _default_library() -> Mapping[str, Material]:
    return _read_library(DEFAULT_LIBRARY)


def _read_library(path: Path) -> dict[str, Material]:
    try:
        with path.open("rb") as handle:
            document = tomllib.load(handle)
    except FileNotFoundError:
        raise MaterialLibraryError(f"{path}: material library not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise MaterialLibraryError(f"{path.name}: not valid TOML ({exc})") from None
    if not document:
        raise MaterialLibraryError(f"{path.name}: the library has no materials")
    return {slug: _material(slug, table, path) for slug, table in document.items()}


class UnknownMaterialError(TexplorerError, KeyError):
    """A slug that is not in the default material library."""

    def __str__(self) -> str:
        return str(self.args[0])


def _known(slugs: Iterable[str]) -> list[str]:
    library = _default_library()
    slugs = list(slugs)
    unknown = [slug for slug in slugs if slug not in library]
    if unknown:
        raise UnknownMaterialError(f"unknown material {unknown[0]!r} (known: {', '.join(library)})")
    return slugs


def _resolve(material: Material | str) -> Material:
    if isinstance(material, Material):
        return material
    return _default_library()[_known([material])[0]]


# --------------------------------------------------------------------------------------------------
# The operator and the sample
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class OperatorDraw:
    """What one operator does differently in one scan (SPEC 5): speeds, forces, timing, judgement, camera.

    Speeds are in mm/s within the 20-240 mm/s range of hand-held exploration (Culbertson et al., paper
    section III-D); ``*_start_s`` is when the unit starts moving after resting still.
    """

    t_amb: float
    finger_speed_mm_s: float
    tool_speed_mm_s: float
    friction_speed_mm_s: float
    finger_slide_start_s: float
    tool_slide_start_s: float
    friction_start_s: float
    friction_normal_n: float
    friction_factor: float
    press_force_n: float
    press_start_s: float
    fold_force_n: float
    fold_extent: float
    tap_strength: float
    tilt_deg: tuple[float, float]
    heat_delay_s: float
    skips_rigid_fold: bool
    atk_offset: float
    cyd_offset: float
    light_gain: float
    white_balance: tuple[float, float, float]
    camera_zoom: float
    photo_rotation_deg: float


SPEED_RANGE_MM_S = (20.0, 240.0)
SLIDE_START_RANGE_S = (0.42, 0.75)


def draw_operator(rng: Rng, *, t_amb: float | None = None,
                  fold_skip_probability: float = 0.5) -> OperatorDraw:
    """Draw one scan's operator variability.

    The judged tack and yielding are off by +-0.25 in about one scan in six; a rigid sample's fold step is
    skipped with ``fold_skip_probability``. ``friction_factor`` scales both friction coefficients for the
    operator's finger that day (skin moisture, contact angle: about +-12 %); the camera draws exposure,
    white balance, distance (zoom +-8 %) and rotation. ``t_amb`` (degC) is the session's MLX90614 ambient
    reading, drawn around 21.5 degC when not given and quantised to the sensor's 0.02 degC steps.
    """
    if not 0.0 <= fold_skip_probability <= 1.0:
        raise ValueError(f"fold_skip_probability must be in [0, 1], got {fold_skip_probability!r}")
    ambient = rng.normal(21.5, 1.2) if t_amb is None else float(t_amb)
    speeds = rng.uniform(*SPEED_RANGE_MM_S, size=3)
    starts = rng.uniform(*SLIDE_START_RANGE_S, size=3)
    disagree = rng.random(2) < 1 / 6
    return OperatorDraw(
        t_amb=_quantise(ambient, 0.02),
        finger_speed_mm_s=float(speeds[0]), tool_speed_mm_s=float(speeds[1]),
        friction_speed_mm_s=float(speeds[2]),
        finger_slide_start_s=float(starts[0]), tool_slide_start_s=float(starts[1]),
        friction_start_s=float(starts[2]),
        friction_normal_n=float(rng.uniform(3.0, 7.0)),
        friction_factor=float(rng.lognormal(0.0, 0.12)),
        press_force_n=float(rng.uniform(6.0, 15.0)),
        press_start_s=float(rng.uniform(0.3, 0.8)),
        fold_force_n=float(rng.uniform(1.0, 3.0)),
        fold_extent=float(rng.uniform(0.7, 1.1)),
        tap_strength=float(rng.uniform(0.6, 1.4)),
        tilt_deg=(float(rng.normal(0.0, 6.0)), float(rng.normal(0.0, 6.0))),
        heat_delay_s=float(rng.uniform(0.6, 1.4)),
        skips_rigid_fold=bool(rng.random() < fold_skip_probability),
        atk_offset=float(disagree[0] * rng.choice([-0.25, 0.25])),
        cyd_offset=float(disagree[1] * rng.choice([-0.25, 0.25])),
        light_gain=float(np.clip(rng.normal(1.0, 0.1), 0.7, 1.3)),
        white_balance=tuple(float(g) for g in np.clip(rng.normal(1.0, 0.04, 3), 0.9, 1.1)),
        camera_zoom=float(rng.uniform(0.92, 1.08)),
        photo_rotation_deg=float(rng.normal(0.0, 10.0)),
    )


def sample_of(material: Material, sample_id: str) -> Material:
    """The material as one physical sample: a few percent off the library's typical values.

    Deterministic in (slug, sample_id), so every scan of a sample sees the same piece: its volume (80-125 %
    of the typical sample), density (+-1 %, at most 2 %), roughness and friction (+-5 %), heat rise (+-5 %)
    and colour.
    """
    rng = np.random.default_rng(zlib.crc32(f"{material.slug}/{sample_id}".encode()))
    scale = rng.normal(1.0, 0.05, size=5)
    rough, fric, thermal, look = material.roughness, material.friction, material.thermal, material.appearance
    tint = np.clip(rng.normal(1.0, 0.03, size=3), 0.85, 1.15)
    colors = tuple(tuple(float(min(255.0, c * t)) for c, t in zip(color, tint, strict=True))
                   for color in look.colors)
    return replace(
        material,
        density_g_cm3=material.density_g_cm3 * float(np.clip(rng.normal(1.0, 0.01), 0.98, 1.02)),
        sample_volume_cm3=material.sample_volume_cm3 * float(rng.uniform(0.8, 1.25)),
        roughness=replace(rough, micro_um=rough.micro_um * scale[0],
                          macro_height_um=rough.macro_height_um * min(scale[1], 1.1)),
        friction=replace(fric, static=fric.static * scale[2], kinetic=fric.kinetic * min(scale[2], scale[3])),
        thermal=replace(thermal, heat_rise_k=thermal.heat_rise_k * scale[4]),
        appearance=replace(look, colors=colors),
    )


# --------------------------------------------------------------------------------------------------
# Sensors
# --------------------------------------------------------------------------------------------------

DAQ_LSB_V = 20.0 / 65536
"""NI USB-6002: 16 bits over +-10 V."""
ADXL_RANGE_G = 3.6
ADXL_NOISE_G = np.array([0.003, 0.003, 0.005])
"""ADXL335 noise over the 1.5 kHz band (x/y 150, z 300 ug/sqrt(Hz) datasheet densities, band-limited)."""
FSR_MAX_V = 4.9
FLEX_V_PER_DEG = 0.01


def _quantise(x: Any, step: float) -> Any:
    return np.round(np.asarray(x, dtype=np.float64) / step) * step if np.ndim(x) else round(x / step) * step


def _adxl335(acceleration: np.ndarray, rng: Rng) -> np.ndarray:
    """Acceleration (n, 3) in g as the DAQ reads it: sensor noise, +-3.6 g rails, DAQ quantisation."""
    noisy = acceleration + rng.standard_normal(acceleration.shape) * ADXL_NOISE_G
    volts = ACCEL_ZERO_V + ACCEL_V_PER_G * np.clip(noisy, -ADXL_RANGE_G, ADXL_RANGE_G)
    return accel_g(_quantise(volts, DAQ_LSB_V))


def _fsr(force_n: np.ndarray, rng: Rng) -> np.ndarray:
    """An FSR400 reading in N: the force through its volts and back with paper eq. (1).

    Eq. (1) maps 0 V to 0.098 N, so forces below that read as 0.098 N: the FSR's turn-on floor.
    """
    volts = fsr_volts(force_n)
    volts = np.clip(volts + rng.normal(0.0, 0.002, volts.shape), 0.0, FSR_MAX_V)
    return fsr_newtons(_quantise(volts, DAQ_LSB_V))


def _mlx90614(temperature: np.ndarray, rng: Rng) -> np.ndarray:
    """Object temperature with 0.02 degC noise, quantised to the MLX90614's 0.02 degC steps."""
    return _quantise(temperature + rng.normal(0.0, 0.02, temperature.shape), 0.02)


# --------------------------------------------------------------------------------------------------
# Signal building blocks
# --------------------------------------------------------------------------------------------------

def _smoothstep(x: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero first and second derivatives at both ends (quintic)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _times(seconds: float, fs: float) -> np.ndarray:
    return np.arange(int(round(seconds * fs))) / fs


def _band_noise(rng: Rng, n: int, fs: float, lo: float, hi: float) -> np.ndarray:
    """Unit-rms Gaussian noise band-limited to [lo, hi] Hz (brick-wall in the frequency domain)."""
    spectrum = rng.standard_normal(n // 2 + 1) + 1j * rng.standard_normal(n // 2 + 1)
    freqs = np.fft.rfftfreq(n, 1.0 / fs)
    spectrum[(freqs < lo) | (freqs > hi)] = 0.0
    x = np.fft.irfft(spectrum, n)
    rms = np.sqrt(np.mean(x**2))
    return x / rms if rms > 0 else x


def _resonance_sos(f0: float, zeta: float, fs: float) -> np.ndarray:
    """Second-order low-pass ``w0^2 / (s^2 + 2 zeta w0 s + w0^2)`` (unit DC gain), bilinear, pre-warped."""
    f0 = min(f0, 0.45 * fs)
    w0 = 2 * fs * np.tan(np.pi * f0 / fs)
    b, a = signal.bilinear([w0**2], [1.0, 2 * zeta * w0, w0**2], fs)
    return signal.tf2sos(b, a)


def _tilt(pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Rotation from the unit's frame to the accelerometer axes for a unit held slightly tilted."""
    p, r = np.radians(pitch_deg), np.radians(roll_deg)
    about_y = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    about_x = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    return about_x @ about_y


def _gravity(n: int, tilt_deg: tuple[float, float]) -> np.ndarray:
    """1 g along the unit's vertical, seen through the operator's tilt: mostly on z."""
    return np.tile(_tilt(*tilt_deg) @ np.array([0.0, 0.0, 1.0]), (n, 1))


# --------------------------------------------------------------------------------------------------
# Tips and contact mechanics
# --------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Tip:
    """What touches the surface in a TU1 step: the bare finger or the steel tool tip (paper III-B1)."""

    name: str
    radius_mm: float
    """Curvature radius: pits narrower than the tip are bridged (tip path = profile dilated by a ball)."""
    min_contact_mm: float
    """Smallest contact width: finer wavelengths are averaged out (finger ridges, Hertz patch)."""
    frequency_hz: float
    """The tip's own contact resonance, in series with the material's."""
    damping: float
    """Damping ratio added by the hand (and the finger pulp)."""
    gain: float
    """Share of the tip's vertical acceleration reaching the accelerometer."""
    tap_g: float
    """Peak tap acceleration at a 500 Hz contact resonance and unit tap strength (g)."""
    audio_gain: float
    """Microphone full scale per g of radiated contact acceleration."""


TOOL = Tip("tool", radius_mm=3.0, min_contact_mm=0.02, frequency_hz=1400.0, damping=0.03, gain=0.03,
           tap_g=1.2, audio_gain=0.004)
FINGER = Tip("finger", radius_mm=6.0, min_contact_mm=0.3, frequency_hz=250.0, damping=0.25, gain=0.1,
             tap_g=0.4, audio_gain=0.002)


def contact_frequency_hz(material: Material, tip: Tip) -> float:
    """Resonance of the hand-held unit on the surface: rises with the material's stiffness.

    ``f_mat = 900 Hz (E / 210 GPa)^(1/4)`` (a steel tip on steel rings near 900 Hz; Hertz contact stiffness
    grows as E^(2/3) and the unit's effective mass falls for stiffer contacts), in series with the tip's
    own resonance: ``1/f^2 = 1/f_mat^2 + 1/f_tip^2``. Interpretation: a lumped model, not a measurement.
    """
    f_mat = 900.0 * (material.compliance.elastic_modulus_mpa / 210000.0) ** 0.25
    return float(1.0 / np.sqrt(1.0 / f_mat**2 + 1.0 / tip.frequency_hz**2))


def _contact_width_mm(material: Material, tip: Tip) -> float:
    """Hertz contact radius ``(3 F R / 4 E)^(1/3)`` at 1 N, not below the tip's minimum, not above R."""
    e_pa = material.compliance.elastic_modulus_mpa * 1e6
    hertz = 1e3 * (3 * 1.0 * tip.radius_mm * 1e-3 / (4 * e_pa)) ** (1 / 3)
    return float(np.clip(hertz, tip.min_contact_mm, tip.radius_mm))


def _damping_ratio(material: Material, tip: Tip) -> float:
    return material.compliance.loss_factor / 2 + tip.damping


# --------------------------------------------------------------------------------------------------
# Surface profile along a slide path
# --------------------------------------------------------------------------------------------------

MACRO_DX_MM = 0.05


def _micro_derivatives(rough: Roughness, rng: Rng, n: int, dx: float,
                       contact_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Slope and curvature (1/mm) of a self-affine micro-profile on a grid of ``n`` points ``dx`` mm apart.

    Height spectrum ``S(k) = (1 + (k/k_c)^2)^(-exponent/2)`` scaled to an rms of ``micro_um``, seen through
    the contact as ``1 / (1 + (pi k a)^2)`` with ``a = contact_mm``: wavelengths shorter than the contact
    are averaged out, but asperity impacts keep a power-law tail.
    """
    k = np.fft.rfftfreq(n, dx)
    amplitude = (1.0 + (k / rough.cutoff_per_mm) ** 2) ** (-rough.exponent / 4)
    amplitude[0] = 0.0
    spectrum = amplitude * (rng.standard_normal(k.size) + 1j * rng.standard_normal(k.size))
    rms = np.sqrt(2 * np.sum(np.abs(spectrum) ** 2)) / n
    spectrum *= (rough.micro_um * 1e-3 / rms if rms > 0 else 0.0) / (1 + (np.pi * k * contact_mm) ** 2)
    ik = 2j * np.pi * k
    return np.fft.irfft(ik * spectrum, n), np.fft.irfft(ik**2 * spectrum, n)


def _feature_train(rough: Roughness, rng: Rng, length_mm: float) -> tuple[np.ndarray, ...]:
    """Centres, widths and heights (mm) of the macro features along ``length_mm`` of path."""
    spacing, disorder = rough.macro_spacing_mm, 1.0 - rough.macro_regularity
    count = int(length_mm / spacing) + 3
    centres = (rng.uniform(0, spacing) + spacing * np.arange(-1, count - 1)
               + disorder * 0.35 * spacing * rng.standard_normal(count))
    widths = rough.macro_duty * spacing * np.clip(1 + disorder * 0.3 * rng.standard_normal(count), 0.3, 2.0)
    heights = rough.macro_height_um * 1e-3 * np.clip(1 + disorder * 0.3 * rng.standard_normal(count), 0.2, 2)
    return np.sort(centres), widths, heights


def _macro_profile(rough: Roughness, rng: Rng, n: int, dx: float) -> np.ndarray:
    """Macro height (mm) on the grid: smoothed rectangular bumps (height > 0) or pits/holes (height < 0)."""
    if rough.macro_height_um == 0.0:
        return np.zeros(n)
    x = np.arange(n) * dx
    centres, widths, heights = _feature_train(rough, rng, n * dx)
    nearest = np.clip(np.searchsorted(centres, x), 1, centres.size - 1)
    profile = np.zeros(n)
    for index in (nearest - 1, nearest):
        c, w, h = centres[index], widths[index], heights[index]
        edge = 0.08 * w
        profile += h * 0.5 * (np.tanh((x - c + w / 2) / edge) - np.tanh((x - c - w / 2) / edge))
    return profile


def _tip_path(profile: np.ndarray, dx: float, radius_mm: float) -> np.ndarray:
    """Height of a ball tip riding on ``profile``: grey dilation by the ball's lower surface."""
    half = int(radius_mm / dx)
    y = np.arange(-half, half + 1) * dx
    ball = np.sqrt(np.maximum(radius_mm**2 - y**2, 0.0)) - radius_mm
    return ndimage.grey_dilation(profile, structure=ball, size=ball.size, mode="nearest")


@dataclass(frozen=True)
class _Path:
    """Kinematics of one slide sampled at one rate: speed (mm/s), acceleration (mm/s^2), position (mm)."""

    v: np.ndarray
    dv: np.ndarray
    x: np.ndarray


def _slide_path(seconds: float, fs: float, start_s: float, speed: float, motion: np.ndarray) -> _Path:
    """Rest until ``start_s``, ramp up within ``motion[0]`` s, then slide with a slow hand modulation.

    ``motion`` = (ramp time s, modulation Hz, modulation phase rad, modulation depth); the same values give
    the same path at every rate, so the audio, vibration and IR channels stay aligned.
    """
    ramp, f_mod, phase, depth = motion
    t = _times(seconds, fs)
    moving = t - start_s
    hand = 1 + depth * np.sin(2 * np.pi * f_mod * np.maximum(moving, 0) + phase)
    v = speed * _smoothstep(moving / ramp) * hand
    x = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1])) / fs))
    return _Path(v, np.gradient(v, 1 / fs), x)


def _draw_motion(rng: Rng) -> np.ndarray:
    return np.array([rng.uniform(0.08, 0.2), rng.uniform(0.5, 1.5), rng.uniform(0, 2 * np.pi),
                     rng.uniform(0.05, 0.15)])


@dataclass(frozen=True)
class _Surface:
    """Slope and curvature of the tip's path on two grids: fine micro-profile and coarse macro-profile."""

    dx: float
    micro_slope: np.ndarray
    micro_curvature: np.ndarray
    macro_slope: np.ndarray
    macro_curvature: np.ndarray

    def acceleration(self, path: _Path) -> np.ndarray:
        """Vertical tip acceleration ``v^2 z''(x) + v' z'(x)`` in g."""
        fine = path.x / self.dx
        coarse = path.x / MACRO_DX_MM
        slope = _lookup(self.micro_slope, fine) + _lookup(self.macro_slope, coarse)
        curvature = _lookup(self.micro_curvature, fine) + _lookup(self.macro_curvature, coarse)
        return (path.v**2 * curvature + path.dv * slope) / G_MM_S2


def _lookup(grid: np.ndarray, position: np.ndarray) -> np.ndarray:
    return np.interp(position, np.arange(grid.size), grid)


def _surface(material: Material, rng: Rng, tip: Tip, length_mm: float,
             n_fine: int, macro: np.ndarray | None = None) -> _Surface:
    """The surface the tip follows over ``length_mm``; pass ``macro`` to share one macro profile."""
    n = int(2 ** np.ceil(np.log2(max(n_fine, 1024))))
    dx = max(length_mm, 1.0) / n
    slope, curvature = _micro_derivatives(material.roughness, rng, n, dx, _contact_width_mm(material, tip))
    if macro is None:
        macro = _macro_profile(material.roughness, rng, int(length_mm / MACRO_DX_MM) + 8, MACRO_DX_MM)
    path = _tip_path(macro, MACRO_DX_MM, tip.radius_mm) if material.roughness.macro_height_um else macro
    macro_slope = np.gradient(path, MACRO_DX_MM)
    return _Surface(dx, slope, curvature, macro_slope, np.gradient(macro_slope, MACRO_DX_MM))


# --------------------------------------------------------------------------------------------------
# TU1: taps
# --------------------------------------------------------------------------------------------------

def _tap_train(material: Material, rng: Rng, operator: OperatorDraw, tip: Tip) -> np.ndarray:
    """(n, 3) acceleration in g of 3-5 taps: each a decaying contact resonance plus the hand's stop.

    ``a(t) = A exp(-t/tau) sin(2 pi f t)`` with f the contact resonance, ``tau = 1 / (2 pi f zeta)`` and
    ``A = tap_g * strength * sqrt(f / 500 Hz)`` (harder contacts decelerate the unit more abruptly).
    """
    t = _times(STEP_S, FS_DAQ)
    f = contact_frequency_hz(material, tip)
    tau = 1.0 / (2 * np.pi * f * _damping_ratio(material, tip))
    count = int(rng.integers(3, 6))
    onsets = 0.6 + (np.arange(count) + rng.uniform(0.1, 0.6, count)) * (3.9 / count)
    unit = np.zeros((t.size, 3))
    for onset, strength in zip(onsets, operator.tap_strength * rng.uniform(0.8, 1.2, count), strict=True):
        since = t - onset
        hit = since >= 0
        ring = np.zeros(t.size)
        ring[hit] = np.exp(-since[hit] / tau) * np.sin(2 * np.pi * f * since[hit])
        approach = -since / 0.03 * np.exp(-0.5 * (since / 0.03) ** 2)
        amplitude = tip.tap_g * strength * np.sqrt(f / 500.0)
        direction = np.array([rng.normal(0, 0.15), rng.normal(0, 0.15), 1.0])
        unit += np.outer(amplitude * ring + 0.15 * strength * approach, direction)
    return unit @ _tilt(*operator.tilt_deg).T + _gravity(t.size, operator.tilt_deg)


def finger_tap(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 finger tap: ``v_ft`` (SPEC 4 step 1)."""
    return {"v_ft": _adxl335(_tap_train(material, rng, operator, FINGER), rng)}


def tool_tap(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 tool tap: ``v_tt`` (SPEC 4 step 3)."""
    return {"v_tt": _adxl335(_tap_train(material, rng, operator, TOOL), rng)}


# --------------------------------------------------------------------------------------------------
# TU1: slides
# --------------------------------------------------------------------------------------------------

IR_SPOT_MM = 0.8
"""Standard deviation of the IR sensor's spot on the surface."""
IR_DEPTH_MM = 1.5
"""Depth below the top surface at which the reflected IR has halved."""


ROLLING_G = 0.2
"""Broadband excitation of the unit by its rolling bearings at 130 mm/s (g, before the contact resonance)."""
STICK_SLIP_G = 0.2
"""Tangential stick-slip excitation per unit kinetic friction at 130 mm/s (g)."""


def _onset_jolt(rng: Rng, t: np.ndarray, start_s: float) -> np.ndarray:
    """(n, 3) g: the hand's jerk and the unit's ringing as it breaks loose (what the start detector sees)."""
    since = t - start_s
    width = rng.uniform(0.004, 0.008)
    pulse = np.where((since >= 0) & (since < width), np.sin(np.pi * np.clip(since, 0, None) / width), 0.0)
    after = np.clip(since, 0, None)
    ring = np.where(since >= 0, np.exp(-after / 0.006), 0.0) * np.sin(2 * np.pi * 1150 * since)
    amplitude = rng.uniform(0.15, 0.35)
    return amplitude * np.column_stack([pulse + 0.5 * ring, 0.3 * ring, 0.5 * pulse + 0.4 * ring])


def _slide(material: Material, rng: Rng, operator: OperatorDraw, tip: Tip,
           speed: float, start_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration (n, 3) g at 3000 Hz, audio at 44100 Hz and IR volts at 3000 Hz of one TU1 slide."""
    motion = _draw_motion(rng)
    fast = _slide_path(STEP_S, FS_AUDIO, start_s, speed, motion)
    slow = _slide_path(STEP_S, FS_DAQ, start_s, speed, motion)
    length = float(fast.x[-1]) + 1.0
    macro = _macro_profile(material.roughness, rng, int(length / MACRO_DX_MM) + 8, MACRO_DX_MM)
    normal = _surface(material, rng, tip, length, fast.x.size, macro).acceleration(fast)
    lateral = _surface(material, rng, tip, length, fast.x.size, macro).acceleration(fast)
    unit = (_contact_vibration(material, rng, tip, fast, normal, lateral) + _hand_motion(rng, slow)
            + _onset_jolt(rng, _times(STEP_S, FS_DAQ), start_s))
    accel = unit @ _tilt(*operator.tilt_deg).T + _gravity(unit.shape[0], operator.tilt_deg)
    return _adxl335(accel, rng), _audio(rng, normal, fast, tip), _ir(material, rng, slow.x, macro)


def _contact_vibration(material: Material, rng: Rng, tip: Tip, path: _Path, normal: np.ndarray,
                       lateral: np.ndarray) -> np.ndarray:
    """(n, 3) g at 3000 Hz: tip accelerations and the bearings' rolling through the contact resonance.

    The normal track drives z, the lateral track (scaled by the kinetic friction, plus stick-slip) drives x;
    y sees a little of both. Computed at 44100 Hz, then resampled to the DAQ rate (anti-aliased).
    """
    n = path.x.size
    contact = _resonance_sos(contact_frequency_hz(material, tip), _damping_ratio(material, tip), FS_AUDIO)
    rolling = ROLLING_G * (path.v / 130.0) * _band_noise(rng, n, FS_AUDIO, 50.0, 3000.0)
    stick_slip = STICK_SLIP_G * np.sqrt(path.v / 130.0) * _band_noise(rng, n, FS_AUDIO, 50.0, 3000.0)
    seen_z = signal.sosfilt(contact, normal + rolling) * tip.gain
    seen_x = signal.sosfilt(contact, material.friction.kinetic * (lateral + stick_slip) + rolling) * tip.gain
    unit = np.column_stack([seen_x, 0.3 * seen_z + 0.2 * seen_x, seen_z])
    return signal.resample_poly(unit, 10, 147, axis=0)


def _hand_motion(rng: Rng, path: _Path) -> np.ndarray:
    """(n, 3) g: the unit's own acceleration along the path and the hand's slow sway (below 5 Hz)."""
    n = path.x.size
    hand = np.zeros((n, 3))
    hand[:, 0] = path.dv / G_MM_S2
    sway = np.column_stack([_band_noise(rng, n, FS_DAQ, 0.3, 5.0) for _ in range(2)])
    hand[:, :2] += 0.02 * (path.v / 130.0)[:, None] * sway
    return hand


def _audio(rng: Rng, tip_g: np.ndarray, path: _Path, tip: Tip) -> np.ndarray:
    """Microphone signal: the tip's contact vibration through a radiation filter, room noise, 16 bits.

    Radiation from the small contact region rises as f^2 below ~1 kHz (second-order high-pass); the
    lavalier's band is 10-7500 Hz (paper III-B1b). The bearings' rolling noise grows with speed.
    """
    n = tip_g.size
    radiation = signal.butter(2, 1000.0, btype="highpass", fs=FS_AUDIO, output="sos")
    microphone = signal.butter(2, [10.0, 7500.0], btype="bandpass", fs=FS_AUDIO, output="sos")
    radiated = signal.sosfilt(radiation, tip_g) * tip.audio_gain
    rolling = 0.001 * (path.v / 130.0) * _band_noise(rng, n, FS_AUDIO, 200.0, 6000.0)
    room = rng.uniform(0.0002, 0.001) * _pink(rng, n)
    audio = signal.sosfilt(microphone, radiated + rolling + room)
    return _quantise(np.clip(audio, -1.0, 1.0 - 2.0**-15), 2.0**-15)


def _pink(rng: Rng, n: int) -> np.ndarray:
    """Unit-rms 1/f noise (room noise)."""
    spectrum = rng.standard_normal(n // 2 + 1) + 1j * rng.standard_normal(n // 2 + 1)
    f = np.fft.rfftfreq(n, 1.0 / FS_AUDIO)
    spectrum /= np.sqrt(np.maximum(f, 20.0))
    x = np.fft.irfft(spectrum, n)
    return x / np.sqrt(np.mean(x**2))


def _ir(material: Material, rng: Rng, x: np.ndarray, macro: np.ndarray) -> np.ndarray:
    """IR reflectance volts along the path: albedo texture and the depth of the macro profile.

    ``V = V_amb + 4.6 g level (1 + variation n(x)) / (1 + depth / 1.5 mm)``, both seen through the sensor's
    spot, with the ambient light ``V_amb`` (0.05-0.2 V) and the emitter's gain ``g`` (+-4 %, temperature)
    varying from scan to scan; the unit rests first, so the first ~0.5 s read the static reflectance.
    """
    reflect = material.reflectance
    spot = IR_SPOT_MM / MACRO_DX_MM
    scale = max(0.5 / material.appearance.frequency_per_mm, IR_SPOT_MM) / MACRO_DX_MM
    albedo = ndimage.gaussian_filter1d(rng.standard_normal(macro.size), scale, mode="wrap")
    albedo = ndimage.gaussian_filter1d(albedo / max(float(albedo.std()), 1e-12), spot, mode="nearest")
    depth = ndimage.gaussian_filter1d(np.maximum(-macro, 0.0), spot, mode="nearest")
    level = reflect.level * np.clip(1 + reflect.variation * albedo, 0.05, None) / (1 + depth / IR_DEPTH_MM)
    ambient, gain = rng.uniform(0.05, 0.2), rng.normal(1.0, 0.04)
    volts = ambient + 4.6 * gain * _lookup(level, x / MACRO_DX_MM) + rng.normal(0.0, 0.002, x.size)
    return _quantise(np.clip(volts, 0.0, 5.0), DAQ_LSB_V)


def finger_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 finger slide: ``v_fs``, ``a_fs``, ``r_fs`` (SPEC 4 step 2)."""
    speed, start = operator.finger_speed_mm_s, operator.finger_slide_start_s
    v, a, r = _slide(material, rng, operator, FINGER, speed, start)
    return {"v_fs": v, "a_fs": a, "r_fs": r}


def tool_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 tool slide: ``v_ts``, ``a_ts``, ``r_ts`` (SPEC 4 step 4)."""
    v, a, r = _slide(material, rng, operator, TOOL, operator.tool_speed_mm_s, operator.tool_slide_start_s)
    return {"v_ts": v, "a_ts": a, "r_ts": r}


# --------------------------------------------------------------------------------------------------
# TU2: static touch and thermal
# --------------------------------------------------------------------------------------------------

def static_touch(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 static touch, 1 s: metal electrodes ``m`` and magnetometer ``dB`` (SPEC 4 step 5).

    ``m``: +1 where a conductive sample pulls the electrode below 2.5 V, else -1; the electrodes bounce
    for a few ms as they settle. ``dB``: the field change settles as the unit is placed; the sign follows
    ``magnet_response_ut`` (interpretation: ferro- and paramagnetic samples raise the field magnitude at
    the MAG3110, diamagnetic ones lower it slightly; the paper's Fig. 7 caption uses the opposite sign for
    diamagnets, with no diamagnet in its database). Noise 0.1 uT, quantised to 0.1 uT.
    """
    t = _times(STATIC_S, FS_DAQ)
    m = -np.ones(t.size)
    if material.conductive:
        contact = rng.uniform(0.0, 0.05)
        settled = contact + rng.uniform(0.005, 0.03)
        bouncing = (t >= contact) & (t < settled)
        m[t >= contact] = 1.0
        m[bouncing] = np.where(rng.random(int(bouncing.sum())) < 0.4, -1.0, 1.0)
    tb = _times(STATIC_S, FS_MAGNET)
    spread = 0.15 if material.magnetic == "ferro" else 0.1
    level = material.magnet_response_ut * rng.uniform(1 - spread, 1 + spread)
    placed = _smoothstep((tb - rng.uniform(0.0, 0.05)) / rng.uniform(0.05, 0.2))
    db = level * placed + rng.normal(0.0, 0.1, tb.size)
    return {"m": m, "dB": _quantise(db, 0.1)}


def thermal(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 thermal: ``t_cool``, 10 s at 20 Hz after heating the Peltier element for 3 s (SPEC 4 step 5).

    The heated spot cools as ``t_amb + dT exp(-r t)`` (paper eq. 26); ``dT`` is the library's heat rise,
    corrected for how long the operator takes to move the MLX90614 over the spot (``heat_delay_s`` against
    the nominal 1 s) and for the contact while heating. The sensor reaches the spot within the first
    0.15-0.5 s, so the maximum is not the first sample. Metals barely heat and cool fast; foams heat most.
    """
    heat = material.thermal
    t = _times(COOL_S, FS_THERMAL)
    rise = heat.heat_rise_k * np.exp(-heat.cooling_rate_per_s * (operator.heat_delay_s - 1.0))
    rise *= rng.uniform(0.85, 1.15)
    arrive = _smoothstep(t / rng.uniform(0.15, 0.5))
    surface = operator.t_amb + rng.normal(0.0, 0.05)
    return {"t_cool": _mlx90614(surface + arrive * rise * np.exp(-heat.cooling_rate_per_s * t), rng)}


# --------------------------------------------------------------------------------------------------
# TU2: friction, press, fold
# --------------------------------------------------------------------------------------------------

FINGER_CONTACT = Tip("finger-fsr", radius_mm=6.0, min_contact_mm=1.0, frequency_hz=180.0, damping=0.25,
                     gain=0.0, tap_g=0.0, audio_gain=0.0)
"""The TU2 friction contact (finger on the FSR with a PLA hemisphere): only its geometry matters."""


def _envelope(t: np.ndarray, on: float, rise: float, off: float, fall: float) -> np.ndarray:
    return _smoothstep((t - on) / rise) * (1.0 - _smoothstep((t - off) / fall))


def friction_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 friction slide: normal ``f_frn`` and tangential ``f_frt`` in N (SPEC 4 step 6, paper Fig. 11).

    The unit rests, the operator presses (normal force rising to ``friction_normal_n``), then pushes: the
    tangential force follows the push until it reaches ``mu_s f_n`` (stiction), drops to ``mu_k f_n`` within
    ~20 ms and slides with fluctuations from the macro profile (the slope under the finger) and micro
    stick-slip, until both forces are released well before the end. The operator's finger adds a constant
    offset on the tangential FSR (removed by SPEC 6's friction offset).
    """
    fric, t = _finger_friction(material.friction, operator), _times(STEP_S, FS_DAQ)
    on, off, press_time = operator.friction_start_s, rng.uniform(3.6, 4.3), rng.uniform(0.25, 0.5)
    normal = operator.friction_normal_n * _envelope(t, on, press_time, off, rng.uniform(0.15, 0.3))
    normal *= 1 + 0.03 * _band_noise(rng, t.size, FS_DAQ, 0.5, 6.0)
    push_at = on + press_time * rng.uniform(0.6, 1.0)
    push_time = rng.uniform(0.15, 0.35)
    push = fric.static * operator.friction_normal_n * 1.3 * _smoothstep((t - push_at) / push_time)
    slipping = np.cumsum((push >= fric.static * normal) & (t > push_at)) > 0
    if not slipping.any():
        slipping[int(off * FS_DAQ)] = True
        slipping = np.cumsum(slipping) > 0
    slip_at = int(np.argmax(slipping))
    kinetic = fric.kinetic * normal * (1 + _sliding_fluctuation(material, rng, operator, t, slip_at))
    since = np.maximum(t - t[slip_at], 0.0)
    drop = np.exp(-since / 0.02)
    tangential = np.where(slipping, kinetic + (fric.static - fric.kinetic) * normal * drop, push)
    offset = rng.uniform(0.05, 0.3)
    return {"f_frn": _fsr(normal, rng), "f_frt": _fsr(np.maximum(tangential, 0.0) + offset, rng)}


def _finger_friction(friction: Friction, operator: OperatorDraw) -> Friction:
    return Friction(friction.static * operator.friction_factor, friction.kinetic * operator.friction_factor)


def _sliding_fluctuation(material: Material, rng: Rng, operator: OperatorDraw,
                         t: np.ndarray, slip_at: int) -> np.ndarray:
    """Relative tangential-force fluctuation while sliding: macro slope under the finger plus stick-slip."""
    speed = operator.friction_speed_mm_s * (t >= t[slip_at])
    x = np.concatenate(([0.0], np.cumsum(speed[1:]) / FS_DAQ))
    macro = _macro_profile(material.roughness, rng, int(x[-1] / MACRO_DX_MM) + 8, MACRO_DX_MM)
    ridge = np.gradient(_tip_path(macro, MACRO_DX_MM, FINGER_CONTACT.radius_mm), MACRO_DX_MM)
    stick_slip = min(0.15, 0.03 * np.sqrt(1 + material.roughness.micro_um / 10)) * _band_noise(
        rng, t.size, FS_DAQ, 5.0, 150.0)
    relative = np.clip(0.8 * _lookup(ridge, x / MACRO_DX_MM) + stick_slip, -0.9, 2.0)
    return np.where(t >= t[slip_at], relative, 0.0)


def press(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 press: ``f_press`` in N with the indentation fixed at 4.0 mm by the casing (SPEC 4 step 7).

    A deformable sample reaches the stop and reads ``k * 4.0 mm``, then relaxes by ``relaxation`` with time
    constant ``relaxation_time_s`` while held to the end. A sample stiffer than the operator's force can
    indent 4 mm reads the operator's force (slow tremor, no relaxation).
    """
    comp, t = material.compliance, _times(STEP_S, FS_DAQ)
    reach = comp.stiffness_n_per_mm * INDENTATION_MM
    rise = rng.uniform(0.3, 0.6)
    peak_at = operator.press_start_s + rise
    if reach < operator.press_force_n:
        held = np.maximum(t - peak_at, 0.0)
        relax = 1.0 - comp.relaxation * (1.0 - np.exp(-held / comp.relaxation_time_s))
        force = reach * _smoothstep((t - operator.press_start_s) / rise) * relax
    else:
        tremor = 1 + 0.03 * _band_noise(rng, t.size, FS_DAQ, 0.5, 6.0)
        force = operator.press_force_n * _smoothstep((t - operator.press_start_s) / rise) * tremor
    return {"f_press": _fsr(force, rng)}


def fold(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 fold: ``f_fold`` in N and ``alpha_f`` in deg (SPEC 4 step 8, paper Fig. 13).

    Foldable: one or two folds of ``fold_angle_deg * fold_extent``, each smooth over 0.4-1.0 s, held, then
    released (a sample that stays deformed, yielding > 0, springs back only partly); the force is the grip
    plus ``k_b alpha + c dalpha/dt``. Rigid: the operator grips and tries, the flex sensor reads only noise
    (std well below 1 deg) — or the step is skipped (returns no arrays) when ``skips_rigid_fold``.
    """
    comp, t = material.compliance, _times(STEP_S, FS_DAQ)
    if not comp.foldable and operator.skips_rigid_fold:
        return {}
    start = rng.uniform(0.3, 0.8)
    grip = operator.fold_force_n * _envelope(t, start, 0.3, 4.4, 0.3)
    if comp.foldable:
        angle = _fold_angle(material, rng, operator, t, start + 0.2)
        force = grip + comp.fold_stiffness_n_per_deg * angle + comp.fold_damping_n_s_per_deg * np.gradient(
            angle, 1 / FS_DAQ)
    else:
        angle = rng.uniform(0.0, 0.4) * _envelope(t, start + 0.2, 0.5, 4.0, 0.5)
        force = grip * rng.uniform(2.0, 3.0)
    flex = angle + 0.15 * rng.standard_normal(t.size)
    return {"f_fold": _fsr(np.maximum(force, 0.0), rng),
            "alpha_f": _quantise(flex * FLEX_V_PER_DEG, DAQ_LSB_V) / FLEX_V_PER_DEG}


def _fold_angle(material: Material, rng: Rng, operator: OperatorDraw, t: np.ndarray,
                first: float) -> np.ndarray:
    """Flex angle (deg) of one or two folds; a yielding sample keeps part of the fold."""
    amplitude = material.compliance.fold_angle_deg * operator.fold_extent
    kept = 0.5 * material.yielding
    count = int(rng.integers(1, 3))
    span = (4.2 - first) / count
    angle = np.zeros(t.size)
    for k in range(count):
        on = first + k * span
        bend = rng.uniform(0.4, 1.0)
        hold = rng.uniform(0.2, max(0.25, span - 2 * bend - 0.3))
        rise = _smoothstep((t - on) / bend)
        back = _smoothstep((t - on - bend - hold) / bend)
        angle = np.maximum(angle, amplitude * (rise - (1 - kept) * back))
    return angle


# --------------------------------------------------------------------------------------------------
# TU3: photos
# --------------------------------------------------------------------------------------------------

PHOTO_FOV_MM = {"I_disp": 60.0, "I_macro": 15.0, "I_illu": 60.0}
"""Field of view across the image width: the 4x lens shows a quarter of the normal view."""


def _noise(rng: Rng, shape: tuple[int, int], scale_px: float, stretch: float = 1.0) -> np.ndarray:
    """Unit-variance smooth noise with correlation length ``scale_px`` (rows) and ``scale_px*stretch`` (cols).

    Features finer than a pixel average out: the amplitude falls with the scale below one pixel.
    """
    rows = max(2, int(np.ceil(shape[0] / max(scale_px, 1.0))) + 1)
    cols = max(2, int(np.ceil(shape[1] / max(scale_px * stretch, 1.0))) + 1)
    coarse = rng.standard_normal((rows, cols)).astype(np.float32)
    field = cv2.resize(coarse, (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
    field = (field - field.mean()) / max(float(field.std()), 1e-6)
    return field * min(1.0, scale_px)


def _ramp(colors: tuple[tuple[float, float, float], ...], field: np.ndarray) -> np.ndarray:
    """Map a field in [0, 1] piecewise linearly through the colours (0 = dominant colour) to RGB in [0, 1]."""
    palette = np.asarray(colors, dtype=np.float32) / 255.0
    position = np.clip(field, 0.0, 1.0).astype(np.float32) * (len(palette) - 1)
    rgb = np.broadcast_to(palette[0], (*field.shape, 3)).copy()
    for index, step in enumerate(np.diff(palette, axis=0)):
        rgb += np.clip(position - index, 0.0, 1.0)[..., None] * step
    return rgb


def _grid(size: int) -> tuple[np.ndarray, np.ndarray]:
    """Column and row coordinates (px) of a square canvas."""
    axis = np.arange(size, dtype=np.float32)
    return np.meshgrid(axis, axis)


def _texture_smooth(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    clouds = 0.5 + 0.25 * _noise(rng, (size, size), ppm / look.frequency_per_mm)
    return look.contrast * clouds, np.zeros((size, size), np.float32)


def _texture_grain(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Growth rings along the columns, warped by slow noise; late wood is the ``duty`` share of each ring."""
    _, rows = _grid(size)
    period = ppm / look.frequency_per_mm
    warp = 0.6 * period * _noise(rng, (size, size), 4 * period, stretch=4.0)
    theta = 2 * np.pi * (rows + warp) / period + rng.uniform(0, 2 * np.pi)
    c0 = np.cos(np.pi * look.duty)
    late = np.clip((np.cos(theta) - c0) / (1 - c0), 0, 1)
    pores = _noise(rng, (size, size), 0.15 * ppm, stretch=12.0)
    return look.contrast * np.clip(late + 0.15 * pores, 0, 1), -late


def _texture_speckle(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Mineral grains: a dark phase (``0.4 duty`` of the area), a second phase (``duty``), the rest first."""
    grain = ppm / look.frequency_per_mm
    dark = _noise(rng, (size, size), 0.7 * grain)
    second = _noise(rng, (size, size), grain)
    cut_dark, cut_second = np.quantile(dark, 1 - 0.4 * look.duty), np.quantile(second, 1 - look.duty)
    field = 0.5 * special.expit((second - cut_second) / 0.08) + special.expit((dark - cut_dark) / 0.08)
    field = np.clip(field, 0, 1) + 0.12 * _noise(rng, (size, size), 0.15 * grain)
    return look.contrast * field, _noise(rng, (size, size), 0.5 * grain)


def _texture_granular(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    grains = _noise(rng, (size, size), 0.5 * ppm / look.frequency_per_mm)
    field = 1 / (1 + np.exp(-2 * grains))
    return look.contrast * field, grains


def _texture_cellular(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Foam-like cells around random seeds: walls along the cell boundaries, cavities (``duty``) inside."""
    cell = ppm / look.frequency_per_mm
    count = int(size * size / max(cell, 1.0) ** 2)
    seeds = np.full((size, size), 255, np.uint8)
    seeds[rng.integers(0, size, count), rng.integers(0, size, count)] = 0
    _, owner = cv2.distanceTransformWithLabels(seeds, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    walls = np.zeros((size, size), bool)
    walls[:, 1:] |= owner[:, 1:] != owner[:, :-1]
    walls[1:, :] |= owner[1:, :] != owner[:-1, :]
    inside = cv2.distanceTransform(np.where(walls, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
    wall_half = (1 - look.duty) * cell / 4
    cavity = np.clip((inside - wall_half) / max(cell / 4, 0.5), 0, 1) * min(1.0, cell / 2)
    return look.contrast * cavity, -cavity


def _texture_fibrous(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    scale = 0.3 * ppm / look.frequency_per_mm
    fibres = _noise(rng, (size, size), scale, stretch=10.0) + 0.5 * _noise(rng, (size, size), scale)
    field = 1 / (1 + np.exp(-1.5 * fibres))
    return look.contrast * field, fibres


def _texture_brushed(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    streaks = _noise(rng, (size, size), 0.5 * ppm / look.frequency_per_mm, stretch=40.0)
    return look.contrast * (0.5 + 0.25 * streaks), 0.3 * streaks


def _texture_veined(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Marble: thin veins along the level lines of a turbulent field."""
    cols, rows = _grid(size)
    period = ppm / look.frequency_per_mm
    turbulence = _noise(rng, (size, size), period) + 0.3 * _noise(rng, (size, size), 0.25 * period)
    wave = np.sin(2 * np.pi * (cols + 0.3 * rows) / period + 2.0 * turbulence)
    veins = np.exp(-(wave / max(look.duty, 0.02)) ** 2)
    cloud = 0.15 * _noise(rng, (size, size), 0.3 * period)
    return look.contrast * np.clip(veins + cloud, 0, 1), np.zeros((size, size), np.float32)


def _texture_weave(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """Plain weave: threads ``duty`` of the pitch wide, alternating over and under."""
    cols, rows = _grid(size)
    pitch = ppm / look.frequency_per_mm
    shift = rng.uniform(0, pitch, 2)
    u, v = (cols + shift[0]) / pitch, (rows + shift[1]) / pitch
    warp_over = (np.floor(u) + np.floor(v)) % 2 == 0
    across = np.where(warp_over, u % 1.0, v % 1.0)
    gap = (1 - look.duty) / 2
    inside = np.clip((across - gap) / max(look.duty, 1e-3), 0, 1)
    thread = np.sqrt(np.sin(np.pi * inside)) * ((across > gap) & (across < 1 - gap))
    fibres = 0.1 * np.where(warp_over, _noise(rng, (size, size), 0.05 * pitch, stretch=0.1),
                            _noise(rng, (size, size), 0.05 * pitch, stretch=10.0))
    return look.contrast * np.clip(1 - thread + fibres, 0, 1), thread


def _texture_perforated(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    """A square grid of round holes, diameter ``duty`` of the pitch, with sharp edges."""
    cols, rows = _grid(size)
    pitch = ppm / look.frequency_per_mm
    shift = rng.uniform(0, pitch, 2)
    du = ((cols + shift[0]) / pitch) % 1.0 - 0.5
    dv = ((rows + shift[1]) / pitch) % 1.0 - 0.5
    distance = np.hypot(du, dv) * pitch
    hole = 1 / (1 + np.exp(-(look.duty * pitch / 2 - distance) / max(0.05 * ppm, 0.4)))
    sheen = 0.05 * _noise(rng, (size, size), 0.2 * ppm, stretch=20.0)
    return look.contrast * np.clip(hole + sheen, 0, 1), -hole


def _texture_ribbed(look: Appearance, rng: Rng, size: int, ppm: float) -> Layers:
    _, rows = _grid(size)
    ridge = 0.5 + 0.5 * np.cos(2 * np.pi * rows / (ppm / look.frequency_per_mm) + rng.uniform(0, 2 * np.pi))
    fibres = 0.3 * _noise(rng, (size, size), 0.05 * ppm, stretch=6.0)
    return look.contrast * np.clip(0.7 * ridge + fibres, 0, 1), ridge


TEXTURE_FUNCTIONS: Mapping[str, Callable[[Appearance, Rng, int, float], Layers]] = {
    "smooth": _texture_smooth, "grain": _texture_grain, "speckle": _texture_speckle,
    "granular": _texture_granular, "cellular": _texture_cellular, "fibrous": _texture_fibrous,
    "brushed": _texture_brushed, "veined": _texture_veined, "weave": _texture_weave,
    "perforated": _texture_perforated, "ribbed": _texture_ribbed,
}
"""Procedural texture generators: (appearance, rng, canvas size px, px per mm) -> (colour field, height)."""


def _place(image: np.ndarray, angle_deg: float, shift: np.ndarray, out: tuple[int, int]) -> np.ndarray:
    """Rotate the square material-frame canvas about its centre, shift it, and cut out an (h, w) view."""
    size = image.shape[0]
    h, w = out
    matrix = cv2.getRotationMatrix2D((size / 2, size / 2), angle_deg, 1.0)
    matrix[:, 2] += np.array([w / 2 - size / 2, h / 2 - size / 2]) + shift
    return cv2.warpAffine(image, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)


def _photo(material: Material, rng: Rng, operator: OperatorDraw, kind: str,
           size: tuple[int, int]) -> np.ndarray:
    """One RGB uint8 photo: texture, rotation, zoom and position, relief shading, lighting, white balance,
    vignetting, focus, exposure control, tone curve, sensor noise."""
    look = material.appearance
    h, w = size
    ppm = w / PHOTO_FOV_MM[kind] * operator.camera_zoom
    canvas = int(np.ceil(np.hypot(h, w))) + 8
    field, height = TEXTURE_FUNCTIONS[look.texture](look, rng, canvas, ppm)
    layers = np.dstack([field, height]).astype(np.float32)
    angle = look.orientation_deg + operator.photo_rotation_deg + rng.normal(0.0, 1.0)
    placed = _place(layers, angle, rng.uniform(-0.05, 0.05, 2) * w, (h, w))
    rgb = _ramp(look.colors, placed[..., 0])
    flash = kind == "I_illu"
    relief = look.relief * (0.5 if flash else 1.0) * (1.5 if kind == "I_macro" else 1.0)
    rgb = rgb * _shading(placed[..., 1], relief, rng.uniform(-2.6, -2.0))[..., None]
    cols, rows = np.meshgrid(np.linspace(-1, 1, w, dtype=np.float32), np.linspace(-1, 1, h, dtype=np.float32))
    radius = np.hypot(cols, rows) / np.sqrt(2)
    vignetting = 1 - (0.45 if kind == "I_macro" else 0.3) * radius**3
    light = operator.light_gain * rng.normal(1.0, 0.02) * vignetting
    side = rng.uniform(0, 2 * np.pi)
    light = light * (1 + 0.06 * (cols * np.cos(side) + rows * np.sin(side)))
    rgb = rgb * light[..., None] * np.asarray(operator.white_balance, np.float32)
    if flash:
        rgb = rgb * 1.3 + _highlight(look.gloss, rng, cols, rows)[..., None]
    focus = rng.uniform(0.6, 1.4) if kind == "I_macro" else rng.uniform(0.0, 0.8)
    if focus * w / 512 > 0.1:
        rgb = cv2.GaussianBlur(rgb, (0, 0), focus * w / 512)
    counts = _tone(_auto_exposure(rgb)) * 255 + rng.normal(0.0, 2.0, rgb.shape).astype(np.float32)
    return np.clip(np.round(counts), 0, 255).astype(np.uint8)


def _auto_exposure(rgb: np.ndarray, target: float = 0.72) -> np.ndarray:
    """The phone's exposure control: a frame brighter than ``target`` on average is darkened halfway (in
    log terms) toward it, so white surfaces and flash shots stay below white but remain brighter."""
    mean = float(rgb.mean())
    return rgb * np.float32(np.sqrt(target / mean)) if mean > target else rgb


def _tone(rgb: np.ndarray, knee: float = 0.8) -> np.ndarray:
    """The phone's tone curve: linear up to ``knee``, then a soft shoulder that never quite reaches white,
    so a bright or flash-lit surface keeps some texture instead of clipping flat."""
    shoulder = knee + (1 - knee) * np.tanh((rgb - knee) / (1 - knee))
    return np.where(rgb < knee, rgb, shoulder)


def _shading(height: np.ndarray, relief: float, light_angle: float) -> np.ndarray:
    """Lambert-like shading from the height gradient along the light direction, strength ``relief``."""
    if relief == 0.0 or not np.any(height):
        return np.ones_like(height)
    gy, gx = np.gradient(cv2.GaussianBlur(height, (0, 0), 1.0))
    slope = gx * np.cos(light_angle) + gy * np.sin(light_angle)
    spread = max(float(slope.std()), 1e-6)
    return np.clip(1 + 0.35 * relief * slope / spread, 0.3, 1.7)


def _highlight(gloss: float, rng: Rng, cols: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """The flash's specular spot near the image centre, as strong as the surface is glossy."""
    centre = rng.normal(0.0, 0.08, 2)
    return 0.45 * gloss * np.exp(-((cols - centre[0]) ** 2 + (rows - centre[1]) ** 2) / (2 * 0.15**2))


def photos(material: Material, rng: Rng, operator: OperatorDraw,
           image_size: tuple[int, int] = (512, 512)) -> dict[str, np.ndarray]:
    """TU3 photos ``I_disp``, ``I_macro`` (4x lens: a quarter of the field, coarser texture, softer) and
    ``I_illu`` (flash: brighter, specular highlight, flatter relief), RGB uint8 of ``image_size`` (h, w)."""
    return {kind: _photo(material, rng, operator, kind, image_size) for kind in PHOTO_FOV_MM}


# --------------------------------------------------------------------------------------------------
# TU4: mass, volume, judged values
# --------------------------------------------------------------------------------------------------

def tu4(material: Material, rng: Rng, operator: OperatorDraw) -> dict[str, float]:
    """TU4: mass (scale: 0.1 g steps) and volume (displacement: read within +-3 %, 0.5 cm^3 steps), and
    the operator's judged adhesive tack and yielding (the material's typical value, off by the operator's
    occasional +-0.25, kept on the five-step scale)."""
    volume = material.sample_volume_cm3
    mass = material.density_g_cm3 * volume
    return {
        "mass_g": max(0.1, _quantise(mass + rng.normal(0.0, 0.05), 0.1)),
        "volume_cm3": max(0.5, _quantise(volume * rng.uniform(0.97, 1.03), 0.5)),
        "atk": float(np.clip(material.adhesive_tack + operator.atk_offset, 0.0, 1.0)),
        "cyd": float(np.clip(material.yielding + operator.cyd_offset, 0.0, 1.0)),
    }


STEP_FUNCTIONS: Mapping[str, Callable[[Material, np.random.Generator, OperatorDraw], dict[str, Any]]] = {
    "finger_tap": finger_tap, "finger_slide": finger_slide, "tool_tap": tool_tap, "tool_slide": tool_slide,
    "static": static_touch, "thermal": thermal, "friction": friction_slide, "press": press, "fold": fold,
    "photos": photos, "tu4": tu4,
}


# --------------------------------------------------------------------------------------------------
# Whole scans
# --------------------------------------------------------------------------------------------------

SIMULATOR = "texplorer-sim"
_EPOCH = datetime.fromisoformat("2024-03-04T09:00:00+00:00")


def _check_image_size(image_size: tuple[int, int]) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in image_size)
    except (TypeError, ValueError):
        raise ValueError(f"image_size must be (height, width), got {image_size!r}") from None
    if h < 16 or w < 16 or (h, w) != tuple(image_size):
        raise ValueError(f"image_size must be two integers >= 16, got {image_size!r}")
    return h, w


def synthetic_scan(material: Material | str, *, seed: int, scan_index: int = 1, sample_id: str | None = None,
                   session_id: str = "sim", operator: str = "sim", image_size: tuple[int, int] = (512, 512),
                   started: str | None = None, t_amb: float | None = None,
                   fold_skip_probability: float = 0.5) -> Scan:
    """One simulated scan of ``material`` (a :class:`Material` or a slug of the default library).

    Every channel of SPEC 3 at its true rate and shape, the three photos at ``image_size`` (h, w) and the
    meta data. Bit-identical for the same arguments: the seed feeds an ``np.random.SeedSequence`` whose
    children drive the operator draw and each procedure step. A rigid sample's fold step is skipped
    (``meta.rigid``, no fold channels) with ``fold_skip_probability``.
    """
    material = _resolve(material)
    size = _check_image_size(image_size)
    sample_id = sample_id or f"{material.slug}-01"
    sample = sample_of(material, sample_id)
    children = np.random.SeedSequence(seed).spawn(1 + len(STEPS))
    draw = draw_operator(np.random.default_rng(children[0]), t_amb=t_amb,
                         fold_skip_probability=fold_skip_probability)
    results: dict[str, dict[str, Any]] = {}
    for step, child in zip(STEPS, children[1:], strict=True):
        rng = np.random.default_rng(child)
        results[step] = (photos(sample, rng, draw, size) if step == "photos"
                         else STEP_FUNCTIONS[step](sample, rng, draw))
    traces = {name: Trace(data, CHANNELS[name].fs, CHANNELS[name].unit)
              for step in STEPS if step not in ("photos", "tu4") for name, data in results[step].items()}
    meta = ScanMeta(
        label=material.label, operator=operator, sample_id=sample_id, scan_index=scan_index,
        session_id=session_id, started=started or _default_start(scan_index),
        t_amb=draw.t_amb, rigid=not material.compliance.foldable and draw.skips_rigid_fold,
        device={"simulator": SIMULATOR, "material": material.slug, "seed": str(seed),
                "daq": "NI USB-6002 (simulated)", "sensor_board": "TEXPLORER-SB (simulated)",
                "camera": "procedural"},
        software_version=scanner.__version__, notes=_notes(draw), **results["tu4"])
    return Scan(meta, traces, results["photos"])


def _default_start(scan_index: int) -> str:
    """A fixed, plausible start time (scans 15 min apart), so equal arguments give equal scans."""
    return (_EPOCH + timedelta(minutes=15 * (scan_index - 1))).isoformat()


def _notes(draw: OperatorDraw) -> str:
    return (f"simulated operator: finger slide {draw.finger_speed_mm_s:.0f} mm/s, tool slide "
            f"{draw.tool_speed_mm_s:.0f} mm/s, friction slide {draw.friction_speed_mm_s:.0f} mm/s")


def scan_seed(seed: int, slug: str, scan_index: int, sample: int = 1) -> int:
    """The seed of scan ``scan_index`` of sample number ``sample`` of ``slug`` in a simulated database built
    with ``seed``.

    Derived with ``np.random.SeedSequence`` from (seed, slug, scan index[, sample number]), so a single scan
    can be regenerated without the others and does not depend on which other materials were simulated. The
    first sample's key has no sample number: databases simulated before samples were numbered stay valid.
    """
    key = (zlib.crc32(slug.encode()), scan_index) + ((sample,) if sample != 1 else ())
    sequence = np.random.SeedSequence(seed, spawn_key=key)
    return int(sequence.generate_state(1, np.uint64)[0])


def sample_id_of(slug: str, sample: int) -> str:
    """Sample id of sample number ``sample`` of a simulated material: ``<slug>-01``, ``<slug>-02``, ..."""
    return f"{slug}-{sample:02d}"


@dataclass(frozen=True)
class _Job:
    """One simulated scan of a database: material, sample number, scan index and the settings."""

    slug: str
    sample: int
    index: int
    seed: int
    image_size: tuple[int, int]
    fold_skip_probability: float

    @property
    def scan_id(self) -> str:
        return f"{sample_id_of(self.slug, self.sample)}-{self.index:03d}"


def _jobs(materials: Iterable[str] | None, samples_per_material: int, scans_per_sample: int, seed: int,
          image_size: tuple[int, int], fold_skip_probability: float) -> list[_Job]:
    slugs = list(_default_library()) if materials is None else _known(materials)
    for name, value in (("samples_per_material", samples_per_material), ("scans_per_material", scans_per_sample)):
        if not (isinstance(value, int) and value >= 1):
            raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    _check_image_size(image_size)
    return [_Job(slug, sample, index, seed, image_size, fold_skip_probability) for slug in slugs
            for sample in range(1, samples_per_material + 1) for index in range(1, scans_per_sample + 1)]


def _simulate_one(job: _Job) -> Scan:
    return synthetic_scan(_default_library()[job.slug], seed=scan_seed(job.seed, job.slug, job.index, job.sample),
                          scan_index=job.index, sample_id=sample_id_of(job.slug, job.sample),
                          image_size=job.image_size, fold_skip_probability=job.fold_skip_probability)


def synthetic_scans(materials: Iterable[str] | None = None, scans_per_material: int = 5, seed: int = 0,
                    image_size: tuple[int, int] = (512, 512), fold_skip_probability: float = 0.5,
                    samples_per_material: int = 1) -> Iterator[Scan]:
    """Scans 1..n of each of ``samples_per_material`` samples (pieces) per material (sample ids
    ``<slug>-01``, ``<slug>-02``, ...), material by material; ``scans_per_material`` is n, the scans of
    each sample.

    ``materials``: slugs of the default library, or None for all of it. Scan k of sample j of material m
    is ``synthetic_scan(m, seed=scan_seed(seed, m, k, j), scan_index=k, sample_id=sample_id_of(m, j), ...)``.
    """
    return map(_simulate_one, _jobs(materials, samples_per_material, scans_per_material, seed, image_size,
                                    fold_skip_probability))


def synthetic_database(root: str | Path, materials: Iterable[str] | None = None, scans_per_material: int = 5,
                       seed: int = 0, image_size: tuple[int, int] = (512, 512), progress: bool = True,
                       fold_skip_probability: float = 0.5, workers: int | None = None,
                       samples_per_material: int = 1) -> Database:
    """Simulate scans (see :func:`synthetic_scans`) into ``scanner.database.Database(root)``; returns it.

    Scans are simulated in ``workers`` processes (default: the number of cores) and added by this process
    in a fixed order. Scans whose id is already in the database are kept, not simulated again, so an
    interrupted demo resumes where it stopped (delete the folder to start over with another seed).
    """
    all_jobs = _jobs(materials, samples_per_material, scans_per_material, seed, image_size, fold_skip_probability)
    database = Database(root)
    stored = {record.scan_id for record in database.records()}
    jobs = [job for job in all_jobs if job.scan_id not in stored]
    bar = tqdm(total=len(jobs), desc="simulating scans", unit="scan", file=sys.stderr,
               disable=None if progress else True, leave=False)
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1))
    if workers == 1:
        scans: Iterable[Scan] = map(_simulate_one, jobs)
        for scan in scans:
            database.add(scan)
            bar.update(1)
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
            for scan in pool.map(_simulate_one, jobs):
                database.add(scan)
                bar.update(1)
    bar.close()
    return database
