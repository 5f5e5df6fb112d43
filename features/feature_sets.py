"""Named feature sets over the paper's features and the modern families, alone and fused.

A set name is one of

- ``paper``: the default families' columns (the paper's 193 on scans; the project's role families on
  imported recordings), the same columns as ``all`` of a default feature space;
- a default modality (``tactum``, ``image``, ``audio``, ``other``);
- a modern family: ``catch22``, ``scattering`` (computed at extraction), ``minirocket``, ``multirocket``
  (the ``signal`` columns, transformed by a random-kernel step fitted inside the folds:
  :mod:`features.random_kernels`);
- several of these joined by ``+`` (``paper+minirocket``), fused through the pipeline's FQ + Spearman
  selection; at most one random-kernel transform per set;
- ``fusion``: ``paper+catch22+scattering+minirocket``.

:func:`families_for` says which families an extraction must compute for the sets asked for, so the default
extraction (the paper's 193) is unchanged unless a modern set is named.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from features.modern import FITTED_KINDS, SIGNAL_PREFIX, role_families
from features.modern import KINDS as EXTRACTED_KINDS
from features.registry import REGISTRY, ROLE_REGISTRY
from taxonomy.errors import TexplorerError

PAPER = "paper"
FUSION = "fusion"
FUSION_PARTS = (PAPER, "catch22", "scattering", "minirocket")
"""What ``fusion`` joins."""

MODERN_SETS = ("catch22", "scattering", *FITTED_KINDS)
"""The modern families as feature sets."""

OWN_PREFIXES = (*REGISTRY.modalities, "generic")
"""The column prefixes of ``paper``: the paper's modalities and, on imported recordings, the generic
family of any sensor channel (``generic.signal_gyro.std``, slow channels and their ratios too)."""


class FeatureSetError(TexplorerError, ValueError):
    """A feature set name that names nothing, or two random-kernel transforms in one set."""


def known_parts() -> tuple[str, ...]:
    """Every name a set may join: ``paper``, the default modalities and the modern families."""
    return (PAPER, *REGISTRY.modalities, *MODERN_SETS)


def parts(name: str) -> tuple[str, ...]:
    """The parts of a set name (``fusion`` expanded), checked.

    Raises
    ------
    FeatureSetError
        If a part is unknown, or two random-kernel transforms are joined.
    """
    pieces = FUSION_PARTS if name == FUSION else tuple(name.split("+"))
    unknown = [p for p in pieces if p not in known_parts()]
    if unknown or not pieces:
        raise FeatureSetError(f"unknown feature set {unknown[0] if unknown else name!r} (known: "
                              f"{', '.join(known_parts())}, {FUSION}, or several joined by '+')")
    if sum(p in FITTED_KINDS for p in pieces) > 1:
        raise FeatureSetError(f"feature set {name!r}: one random-kernel transform per set "
                              f"({' or '.join(FITTED_KINDS)})")
    return tuple(dict.fromkeys(pieces))


def is_named_set(name: object) -> bool:
    """Whether ``name`` is a set of this module (not a plain modality, ``all``, or a column list)."""
    if not isinstance(name, str) or name == "all" or name in REGISTRY.modalities:
        return False
    return name in (PAPER, FUSION, *MODERN_SETS) or "+" in name


def kernels_of(name: str) -> str | None:
    """The random-kernel transform a set needs (``minirocket``, ``multirocket``), or None."""
    return next((p for p in parts(name) if p in FITTED_KINDS), None)


def columns_of(columns: Sequence[str], name: str) -> list[str]:
    """The columns of ``columns`` that the set ``name`` reads, in their order.

    Raises
    ------
    FeatureSetError
        If a part of the set has no column (its family was not extracted).
    """
    prefixes: dict[str, tuple[str, ...]] = {}
    for part in parts(name):
        if part == PAPER:
            prefixes[part] = OWN_PREFIXES
        elif part in FITTED_KINDS:
            prefixes[part] = (SIGNAL_PREFIX,)
        else:
            prefixes[part] = (part,)
    for part, wanted in prefixes.items():
        if not any(c.split(".", 1)[0] in wanted for c in columns):
            raise FeatureSetError(f"feature set {name!r}: no {part} columns in the feature space (extract "
                                  f"with --feature-set {name}, which computes them)")
    every = {p for wanted in prefixes.values() for p in wanted}
    return [c for c in columns if c.split(".", 1)[0] in every]


def column_parts(columns: Sequence[str], kernels: bool = False) -> tuple[int, ...] | None:
    """The part of each column for a fused set's per-part selection (:class:`features.selection.PartwiseFQSelector`):
    the paper's features (every default modality) are one part, each modern family another; a random-kernel
    step's ``signal`` columns are not listed (the step replaces them by its features, which follow the
    columns it passes through and form the last part). None when there is one part only: a set of one
    family is selected as a whole, as the paper's is.

    ``kernels``: whether a random-kernel step transforms the ``signal`` columns."""
    passed = [c for c in columns if not (kernels and c.split(".", 1)[0] == SIGNAL_PREFIX)]
    names = [PAPER if c.split(".", 1)[0] in OWN_PREFIXES else c.split(".", 1)[0] for c in passed]
    index = {name: k for k, name in enumerate(dict.fromkeys(names))}
    if len(index) + kernels < 2:
        return None
    return tuple(index[name] for name in names)


def extracted_kinds(names: Iterable[str | None]) -> tuple[str, ...]:
    """The modern extraction families (``signal``, ``catch22``, ``scattering``) the sets ``names`` need."""
    needed: set[str] = set()
    for name in names:
        if isinstance(name, str) and is_named_set(name):
            for part in parts(name):
                needed.add(SIGNAL_PREFIX if part in FITTED_KINDS else part)
    return tuple(k for k in EXTRACTED_KINDS if k in needed)


def families_for(names: Iterable[str | None]) -> tuple[str, ...] | None:
    """The scan families to extract for the sets ``names``: None (the default ones) unless a modern set is
    named, else the default ones and the modern ones needed."""
    kinds = extracted_kinds(names)
    return None if not kinds else (*REGISTRY.modalities, *kinds)


def role_families_for(names: Iterable[str | None]) -> tuple[str, ...] | None:
    """The role families to extract from imported recordings for the sets ``names``, as
    :func:`families_for` (``catch22`` -> ``catch22.audio``, ``catch22.vibration``, ...)."""
    kinds = extracted_kinds(names)
    return None if not kinds else (*ROLE_REGISTRY.modalities, *role_families(kinds))


def families_of(columns: Iterable[str]) -> tuple[str, ...] | None:
    """The scan families that compute ``columns`` (a trained model's inputs): None when the default ones do."""
    prefixes = {c.split(".", 1)[0] for c in columns}
    if prefixes <= set(REGISTRY.modalities):
        return None
    return tuple(f.name for f in REGISTRY.every if f.name in prefixes or not f.opt_in)


def check_names(names: Iterable[str]) -> list[str]:
    """``names`` with every one a default modality, ``all`` or a set of this module; an error otherwise."""
    names = list(names)
    for name in names:
        if name != "all" and name not in REGISTRY.modalities:
            parts(name)
    return names
