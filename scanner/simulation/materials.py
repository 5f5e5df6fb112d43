"""The material library of the simulated scanner: one table per material in ``scanner/data/materials.toml``
(physical properties, not code), read and validated into :class:`Material` records."""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, fields
from functools import lru_cache
from pathlib import Path
from typing import Any

from scanner.scan import JUDGED_SCALE
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label, LabelError

DEFAULT_LIBRARY = Path(__file__).parents[1] / "data" / "materials.toml"
TEXTURES = ("smooth", "grain", "speckle", "granular", "cellular", "fibrous", "brushed", "veined", "weave",
            "perforated", "ribbed")
MAGNETIC_TYPES = ("ferro", "para", "none", "dia")
class SimulationError(TexplorerError, ValueError):
    """Arguments the simulator cannot use; the message says which."""


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
    """One material of the library (docs/devices.md): every property the simulated scanner draws on."""

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
    stock_thickness_mm: float | None = None
    """Thickness of the stock a piece is cut from (:func:`~scanner.simulation.variability.sample_of`); None
    for the library's typical sample, whose face is 100 cm^2."""
    derived: bool = False
    """True for a material derived from its taxonomy codes (:mod:`~scanner.simulation.derived`), False for
    one set by hand in the library."""


_LABEL_FORM = "C<c>S<s>M<m>P<p>X<x>"


class _Where:
    """Names the place of a value in the library for one-line error messages."""

    def __init__(self, path: Path, slug: str, section: str = "") -> None:
        self.path, self.slug, self.section = path, slug, section

    def fail(self, key: str, problem: str) -> SimulationError:
        field_name = f"{self.section}.{key}" if self.section else key
        return SimulationError(f"{self.path.name}: material {self.slug!r}: {field_name} {problem}")


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
        raise SimulationError(f"{path.name}: material {slug!r} must be a table")
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
    """A full label written canonically (the library's labels are compared as text)."""
    try:
        return str(Label.parse(text)) == text
    except LabelError:
        return False


def load_materials(path: str | Path | None = None) -> dict[str, Material]:
    """Read and validate a material library (default: the shipped ``scanner/data/materials.toml``).

    Returns materials keyed by slug, in file order. Any problem raises :class:`SimulationError` with
    one line naming the file, the material and the field (missing, wrong type, out of range, unknown
    magnetic type or texture, malformed label, unknown field).
    """
    if path is None:
        return dict(default_library())
    return _read_library(Path(path))


@lru_cache(maxsize=1)
def default_library() -> Mapping[str, Material]:
    return _read_library(DEFAULT_LIBRARY)


def _read_library(path: Path) -> dict[str, Material]:
    try:
        with path.open("rb") as handle:
            document = tomllib.load(handle)
    except FileNotFoundError:
        raise SimulationError(f"{path}: material library not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise SimulationError(f"{path.name}: not valid TOML ({exc})") from None
    if not document:
        raise SimulationError(f"{path.name}: the library has no materials")
    return {slug: _material(slug, table, path) for slug, table in document.items()}


class UnknownMaterialError(TexplorerError, KeyError):
    """A name that is neither a slug of the default material library nor a taxonomy label."""

    def __str__(self) -> str:
        return str(self.args[0])

