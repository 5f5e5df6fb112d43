"""Physical parameters for every taxonomy material: hand-set where the library has them, derived otherwise.

The library (``scanner/data/materials.toml``) sets 32 materials by hand. Any other full label
``C<c>S<s>M<m>P<p>X<x>`` of the taxonomy is derived from its codes, in this order, from
``scanner/data/material_classes.toml``:

1. **Material.** A hand-set material of the same C, S and M (another finish of it) is the base as it is.
   Otherwise the sub-class's prototype (a hand-set material of that sub-class, or the closest one, with the
   sub-class's own values) is the base, with the material's known constants (``[M.<code>]``: density,
   modulus, magnetism), the density its taxonomy description gives ("density about 0.69 g/cm3") and the
   magnetism it names ("ferromagnetic", "paramagnetic", "diamagnetic", "barely magnetic").
2. **Per-material variation**, only for a prototype base: seeded by the material code (so the same material
   gets the same values everywhere), lognormal factors of typical spreads within a sub-class: density
   ``sigma = 0.15`` (unless the description or the constants give it), Young's modulus 0.3, loss factor 0.3,
   friction 0.08, micro-roughness rms 0.3 and its cut-off 0.2, the heat rise and the cooling rate 0.1, the
   pattern frequency 0.2; the IR reflectance level +-0.05 and the colours +-12 % per channel. Two derived
   materials of one sub-class therefore differ the way two woods or two rubbers do, by amounts of the
   order that handbooks (e.g. Ashby, *Materials Selection in Mechanical Design*, 2011) give within a class.
3. **Processing shape and extra attribute** (``[P<p>]``, ``[X<x>]``): the surface they leave (polished,
   pointed, perforated, woven, varnished, coarse grain, ...), setting or scaling roughness, friction,
   appearance and, for foamed, painted, anodised or moist, the bulk or the electrodes' contact.

Every derived table passes the library's own validation, with values first kept inside its ranges.
"""

from __future__ import annotations

import copy
import re
import tomllib
import zlib
from collections.abc import Mapping
from dataclasses import replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from scanner.simulation.materials import (
    DEFAULT_LIBRARY,
    Material,
    SimulationError,
    UnknownMaterialError,
    _material,
    default_library,
)
from taxonomy.labels import Label, LabelError
from taxonomy.table import Taxonomy, load_taxonomy

CLASSES_FILE = Path(__file__).parents[1] / "data" / "material_classes.toml"
_COMPLIANCE_KEYS = ("elastic_modulus_mpa", "loss_factor")
_LIMITS = {
    "density_g_cm3": (0.005, 25.0), "micro_um": (0.0, 500.0), "cutoff_per_mm": (0.05, 50.0),
    "macro_height_um": (-5000.0, 5000.0), "macro_spacing_mm": (0.2, 50.0), "static": (0.05, 3.0),
    "kinetic": (0.05, 3.0), "elastic_modulus_mpa": (0.001, 1e6), "loss_factor": (0.0, 1.0),
    "stiffness_n_per_mm": (0.01, 1000.0), "heat_rise_k": (0.0, 30.0), "cooling_rate_per_s": (0.005, 10.0),
    "level": (0.0, 1.0), "variation": (0.0, 1.0), "frequency_per_mm": (0.01, 50.0), "contrast": (0.0, 1.0),
    "duty": (0.0, 1.0), "relief": (0.0, 1.0), "gloss": (0.0, 1.0),
}
"""The library's ranges (:mod:`~scanner.simulation.materials`) of the values derivation changes."""


@lru_cache(maxsize=1)
def _classes() -> Mapping[str, Any]:
    with CLASSES_FILE.open("rb") as handle:
        return tomllib.load(handle)


@lru_cache(maxsize=1)
def _library_tables() -> Mapping[str, Any]:
    with DEFAULT_LIBRARY.open("rb") as handle:
        return tomllib.load(handle)


@lru_cache(maxsize=1)
def _taxonomy() -> Taxonomy:
    return load_taxonomy()


@lru_cache(maxsize=1)
def _descriptions() -> Mapping[str, str]:
    return {m.code: m.description for m in _taxonomy().materials()}


def hand_set(label: str | Label) -> Material | None:
    """The hand-set library material with exactly this label, or None."""
    text = str(Label.parse(label))
    return next((m for m in default_library().values() if m.label == text), None)


def is_hand_set(code: str) -> bool:
    """Whether the library sets some finish of the material ``C<c>S<s>M<m>`` (or the full label) by hand."""
    return any(m.label == code or m.label.startswith(f"{code}P") for m in default_library().values())


def material_for_label(label: str | Label) -> Material:
    """The material the simulated scanner uses for ``label``: hand-set if the library has it, else derived.

    Raises
    ------
    SimulationError
        The label is malformed, or its major class and sub-class have no prototype (a class a lab added
        to its taxonomy); the message says what to do instead.
    """
    try:
        parsed = Label.parse(label)
    except LabelError as exc:
        raise SimulationError(f"{exc}; pick the material with the search to get a valid label") from None
    return hand_set(parsed) or derived_material(parsed)


def material_named(name: Material | str) -> Material:
    """A material given as itself, as a library slug (``oak-planed``) or as a full label (``C1S1M4P1X1``).

    Raises
    ------
    UnknownMaterialError
        ``name`` is neither; the message says both forms.
    SimulationError
        A label the simulator cannot simulate (:func:`material_for_label`).
    """
    if isinstance(name, Material):
        return name
    library = default_library()
    if name in library:
        return library[name]
    if re.fullmatch(r"[Cc]\d+[Ss]\d+[Mm]\d+[Pp]\d+[Xx]\d+", name.strip()):
        return material_for_label(name.strip().upper())
    raise UnknownMaterialError(
        f"unknown material {name!r}: give a full taxonomy label such as C1S1M4P1X1 (any material of the "
        f"taxonomy) or a hand-set material: {', '.join(library)}")


@lru_cache(maxsize=512)
def derived_material(label: Label) -> Material:
    """The derived material of ``label`` (module docstring), validated like a library material."""
    c, csub, cm, p, x = label.codes()
    classes = _classes()
    if csub not in classes:
        raise SimulationError(
          f"the simulated scanner has no physics for {csub} ({_name(csub)}), so it cannot simulate {label}: "
          "choose a material of the classes C1-C8 of the shipped taxonomy, or connect the real scanner")
    table = _base_table(cm, classes[csub])
    for code in (p, x):
        _apply(table, classes.get(code, {}))
    table["label"] = str(label)
    table["name"] = _describe(label)
    _keep_in_range(table)
    return replace(_material(_slug(label), table, CLASSES_FILE), derived=True)


def _base_table(code: str, prototype: Mapping[str, Any]) -> dict[str, Any]:
    """The base table of material ``code``: a hand-set finish of it, else the varied sub-class prototype."""
    tables = _library_tables()
    same = next((slug for slug, m in default_library().items() if m.label.startswith(f"{code}P")), None)
    if same is not None:
        return copy.deepcopy(tables[same])
    table = copy.deepcopy(tables[prototype["base"]])
    _apply(table, {"set": {k: v for k, v in prototype.items() if not isinstance(v, (dict, str))}})
    _apply(table, {"set": {k: v for k, v in prototype.items() if k in ("magnetic",)}})
    _apply(table, prototype)
    known = dict(_classes().get("M", {}).get(code, {}))
    known.update(_described(code))
    _vary(table, np.random.default_rng(zlib.crc32(code.encode())), fixed_density="density_g_cm3" in known)
    for key, value in known.items():
        if key in _COMPLIANCE_KEYS:
            table["compliance"][key] = value
        else:
            table[key] = value
    return table


def _described(code: str) -> dict[str, Any]:
    """Density and magnetism the taxonomy's description of ``code`` states."""
    text = _descriptions().get(code, "")
    found: dict[str, Any] = {}
    density = re.search(r"density about ([0-9.]+) g/cm3", text)
    if density:
        found["density_g_cm3"] = float(density.group(1))
    lowered = text.lower()
    if "barely magnetic" in lowered or "paramagnetic" in lowered:
        found.update(magnetic="para", magnet_response_ut=1.0)
    elif "ferromagnetic" in lowered:
        found.update(magnetic="ferro", magnet_response_ut=80.0)
    elif "diamagnetic" in lowered:
        found.update(magnetic="dia", magnet_response_ut=-0.05)
    return found


def _vary(table: dict[str, Any], rng: np.random.Generator, *, fixed_density: bool) -> None:
    """The seeded per-material variation (module docstring, step 2)."""
    factor = dict(zip(("density", "modulus", "loss", "friction", "micro", "cutoff", "heat", "cooling", "frequency"),
                      rng.lognormal(0.0, [0.15, 0.3, 0.3, 0.08, 0.3, 0.2, 0.1, 0.1, 0.2]), strict=True))
    if not fixed_density:
        table["density_g_cm3"] *= factor["density"]
    comp = table["compliance"]
    comp["elastic_modulus_mpa"] *= factor["modulus"]
    if comp["stiffness_n_per_mm"] != "rigid":
        comp["stiffness_n_per_mm"] *= factor["modulus"]
    comp["loss_factor"] *= factor["loss"]
    for key in ("static", "kinetic"):
        table["friction"][key] *= factor["friction"]
    table["roughness"]["micro_um"] *= factor["micro"]
    table["roughness"]["cutoff_per_mm"] *= factor["cutoff"]
    table["thermal"]["heat_rise_k"] *= factor["heat"]
    table["thermal"]["cooling_rate_per_s"] *= factor["cooling"]
    table["appearance"]["frequency_per_mm"] *= factor["frequency"]
    table["reflectance"]["level"] += float(rng.uniform(-0.05, 0.05))
    tint = rng.uniform(0.88, 1.12, 3)
    table["appearance"]["colors"] = [[int(min(255, round(v * t))) for v, t in zip(color, tint, strict=True)]
                                     for color in table["appearance"]["colors"]]


def _apply(table: dict[str, Any], change: Mapping[str, Any]) -> None:
    """Apply a ``set`` and a ``scale`` table: scalars at the top level, sub-tables per section."""
    for key, value in change.get("set", {}).items():
        if isinstance(value, dict):
            table[key].update(copy.deepcopy(value))
        else:
            table[key] = value
    for key, value in change.get("scale", {}).items():
        if isinstance(value, dict):
            for field, by in value.items():
                if table[key][field] != "rigid":
                    table[key][field] *= by
        else:
            table[key] *= value


def _keep_in_range(table: dict[str, Any]) -> None:
    """Clip every value derivation changed into the library's range; kinetic friction stays <= static."""
    for section in (table, *[v for v in table.values() if isinstance(v, dict)]):
        for key, (lo, hi) in _LIMITS.items():
            if key in section and not isinstance(section[key], str):
                section[key] = float(np.clip(section[key], lo, hi))
    friction = table["friction"]
    friction["kinetic"] = min(friction["kinetic"], friction["static"])


def _slug(label: Label) -> str:
    return str(label).lower()


def _name(code: str) -> str:
    try:
        return _taxonomy().name(code)
    except (KeyError, ValueError):
        return "a class the shipped taxonomy does not know"


def _describe(label: Label) -> str:
    try:
        return _taxonomy().describe(label)
    except ValueError:
        return str(label)
