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
from features.registry import REGISTRY
from features.space import FeatureSpace, drop_nan_columns
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


FeatureSet = str | Sequence[str] | None
"""Columns to learn from: None or ``"all"`` (every column), a set name, a modality name, or column names."""


class FeatureSetError(TexplorerError, ValueError):
    """A feature set name that names nothing, or two random-kernel transforms in one set."""


def known_parts() -> tuple[str, ...]:
    """Every name a set may join: ``paper``, the default modalities and the modern families.

    Returns
    -------
    tuple of str
        ``paper``, the modalities of :data:`features.REGISTRY`, then :data:`MODERN_SETS`.

    Examples
    --------
    >>> from features.feature_sets import known_parts
    >>> known_parts()
    ('paper', 'tactum', 'image', 'audio', 'other', 'catch22', 'scattering', 'minirocket', 'multirocket')
    """
    return (PAPER, *REGISTRY.modalities, *MODERN_SETS)


def parts(name: str) -> tuple[str, ...]:
    """The parts of a set name (``fusion`` expanded), checked.

    Parameters
    ----------
    name : str
        A set name: a part, ``fusion``, or parts joined by ``+``.

    Returns
    -------
    tuple of str
        The parts in the order named, each once.

    Raises
    ------
    FeatureSetError
        If a part is unknown, or two random-kernel transforms are joined.

    Examples
    --------
    >>> from features.feature_sets import parts
    >>> parts("fusion"), parts("paper+catch22+paper")
    (('paper', 'catch22', 'scattering', 'minirocket'), ('paper', 'catch22'))
    >>> parts("minirocket+multirocket")
    Traceback (most recent call last):
        ...
    features.feature_sets.FeatureSetError: feature set 'minirocket+multirocket': one random-kernel transform
    per set (minirocket or multirocket)
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
    """Whether ``name`` is a set of this module (not a plain modality, ``all``, or a column list).

    Parameters
    ----------
    name : object
        A feature selection as given: a name, ``all``, a list of columns, None, ...

    Returns
    -------
    bool
        True for ``paper``, ``fusion``, a modern family or a name with ``+`` (checked by :func:`parts`
        only when used).

    Examples
    --------
    >>> from features.feature_sets import is_named_set
    >>> [is_named_set(name) for name in ("paper+minirocket", "catch22", "tactum", "all", ["tactum.matx"])]
    [True, True, False, False, False]
    """
    if not isinstance(name, str) or name == "all" or name in REGISTRY.modalities:
        return False
    return name in (PAPER, FUSION, *MODERN_SETS) or "+" in name


def kernels_of(name: str) -> str | None:
    """The random-kernel transform a set needs (``minirocket``, ``multirocket``), or None.

    Parameters
    ----------
    name : str
        A set name (:func:`parts`).

    Returns
    -------
    str or None
        The name of its random-kernel part, None if it has none.

    Raises
    ------
    FeatureSetError
        If the name is not a valid set (:func:`parts`).

    Examples
    --------
    >>> from features.feature_sets import kernels_of
    >>> kernels_of("paper+multirocket"), kernels_of("fusion"), kernels_of("paper+catch22")
    ('multirocket', 'minirocket', None)
    """
    return next((p for p in parts(name) if p in FITTED_KINDS), None)


def columns_of(columns: Sequence[str], name: str) -> list[str]:
    """The columns of ``columns`` that the set ``name`` reads, in their order.

    Parameters
    ----------
    columns : sequence of str
        The columns of a feature space.
    name : str
        A set name (:func:`parts`).

    Returns
    -------
    list of str
        The columns whose prefix (the text before the first ``.``) belongs to a part of the set; a
        random-kernel part reads the ``signal`` columns.

    Raises
    ------
    FeatureSetError
        If a part of the set has no column (its family was not extracted).

    Examples
    --------
    >>> from features.feature_sets import columns_of
    >>> columns = ("tactum.matx", "image.disp.color", "catch22.v_ts.DN_HistogramMode_5", "signal.v_ts.00000")
    >>> columns_of(columns, "paper")
    ['tactum.matx', 'image.disp.color']
    >>> columns_of(columns, "catch22+minirocket")
    ['catch22.v_ts.DN_HistogramMode_5', 'signal.v_ts.00000']
    >>> columns_of(columns, "scattering")
    Traceback (most recent call last):
        ...
    features.feature_sets.FeatureSetError: feature set 'scattering': no scattering columns in the feature space
    (extract with --feature-set scattering, which computes them)
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

    ``kernels``: whether a random-kernel step transforms the ``signal`` columns.

    Parameters
    ----------
    columns : sequence of str
        The columns of a fused set (:func:`columns_of`).
    kernels : bool
        Whether a random-kernel step transforms the ``signal`` columns.

    Returns
    -------
    tuple of int or None
        For each column passed on, the number of its part (parts numbered in the order they first
        appear); None for a single part.

    Examples
    --------
    >>> from features.feature_sets import column_parts
    >>> columns = ("tactum.matx", "image.disp.color", "catch22.v_ts.DN_HistogramMode_5", "signal.v_ts.00000")
    >>> column_parts(columns), column_parts(columns, kernels=True)
    ((0, 0, 1, 2), (0, 0, 1))
    >>> column_parts(["tactum.matx", "audio.tool.f0"]) is None
    True
    """
    passed = [c for c in columns if not (kernels and c.split(".", 1)[0] == SIGNAL_PREFIX)]
    names = [PAPER if c.split(".", 1)[0] in OWN_PREFIXES else c.split(".", 1)[0] for c in passed]
    index = {name: k for k, name in enumerate(dict.fromkeys(names))}
    if len(index) + kernels < 2:
        return None
    return tuple(index[name] for name in names)


def extracted_kinds(names: Iterable[str | None]) -> tuple[str, ...]:
    """The modern extraction families (``signal``, ``catch22``, ``scattering``) the sets ``names`` need.

    Parameters
    ----------
    names : iterable of str or None
        Feature selections (set names, modalities, ``all``, None).

    Returns
    -------
    tuple of str
        The families needed, in the order of :data:`features.modern.KINDS`; a random-kernel set needs
        ``signal``.

    Examples
    --------
    >>> from features.feature_sets import extracted_kinds
    >>> extracted_kinds(["fusion"]), extracted_kinds(["paper+multirocket"]), extracted_kinds(["paper", "tactum", None])
    (('signal', 'catch22', 'scattering'), ('signal',), ())
    """
    needed: set[str] = set()
    for name in names:
        if isinstance(name, str) and is_named_set(name):
            for part in parts(name):
                needed.add(SIGNAL_PREFIX if part in FITTED_KINDS else part)
    return tuple(k for k in EXTRACTED_KINDS if k in needed)


def families_for(names: Iterable[str | None]) -> tuple[str, ...] | None:
    """The scan families to extract for the sets ``names``: None (the default ones) unless a modern set is
    named, else the default ones and the modern ones needed.

    Parameters
    ----------
    names : iterable of str or None
        Feature selections (set names, modalities, ``all``, None).

    Returns
    -------
    tuple of str or None
        Family names for :func:`features.extract`, or None for its default.

    Examples
    --------
    >>> from features.feature_sets import families_for
    >>> families_for(["paper+catch22"])
    ('tactum', 'image', 'audio', 'other', 'catch22')
    >>> families_for(["paper", "tactum"]) is None
    True
    """
    kinds = extracted_kinds(names)
    return None if not kinds else (*REGISTRY.modalities, *kinds)


def role_families_for(names: Iterable[str | None]) -> tuple[str, ...] | None:
    """The role families to extract from imported recordings for the sets ``names``, as
    :func:`families_for` (``catch22`` -> ``catch22.audio``, ``catch22.vibration``, ...).

    Parameters
    ----------
    names : iterable of str or None
        Feature selections (set names, modalities, ``all``, None).

    Returns
    -------
    tuple of str or None
        The default role families and the modern ones per role, or None for the default ones.

    Examples
    --------
    >>> from features.feature_sets import role_families_for
    >>> role_families_for(["paper+minirocket"])
    ('audio.audio', 'audio.vibration', 'image.photo', 'vibration', 'friction', 'signal.audio', 'signal.vibration',
     'signal.force_xyz', 'signal.pressure_dc', 'signal.temperature', 'signal.heat_flow')
    >>> role_families_for(["paper"]) is None
    True
    """
    kinds = extracted_kinds(names)
    return None if not kinds else (*REGISTRY.roles.modalities, *role_families(kinds))


def families_of(columns: Iterable[str]) -> tuple[str, ...] | None:
    """The scan families that compute ``columns`` (a trained model's inputs): None when the default ones do.

    Parameters
    ----------
    columns : iterable of str
        Feature columns.

    Returns
    -------
    tuple of str or None
        The default families and the opt-in ones whose name prefixes a column, in registration order;
        None if every column is a default modality's.

    Examples
    --------
    >>> from features.feature_sets import families_of
    >>> families_of(["tactum.matx", "other.density"]) is None
    True
    >>> families_of(["tactum.matx", "catch22.v_ts.DN_HistogramMode_5"])
    ('tactum', 'image', 'audio', 'other', 'catch22')
    """
    prefixes = {c.split(".", 1)[0] for c in columns}
    if prefixes <= set(REGISTRY.modalities):
        return None
    return tuple(f.name for f in REGISTRY.every if f.name in prefixes or not f.opt_in)


def check_names(names: Iterable[str]) -> list[str]:
    """``names`` with every one a default modality, ``all`` or a set of this module; an error otherwise.

    Parameters
    ----------
    names : iterable of str
        Feature selections.

    Returns
    -------
    list of str
        ``names``, unchanged.

    Raises
    ------
    FeatureSetError
        For the first name that is no valid set (:func:`parts`).

    Examples
    --------
    >>> from features.feature_sets import check_names
    >>> check_names(("tactum", "all", "paper+catch22"))
    ['tactum', 'all', 'paper+catch22']
    >>> check_names(["paper+rocket"])
    Traceback (most recent call last):
        ...
    features.feature_sets.FeatureSetError: unknown feature set 'rocket' (known: paper, tactum, image, audio,
    other, catch22, scattering, minirocket, multirocket, fusion, or several joined by '+')
    """
    names = list(names)
    for name in names:
        if name != "all" and name not in REGISTRY.modalities:
            parts(name)
    return names


def resolve_feature_set(space: FeatureSpace, feature_set: FeatureSet) -> tuple[FeatureSpace, str]:
    """The columns of ``feature_set`` and its display name ("all", the modality, or "<n> columns").

    Parameters
    ----------
    space : FeatureSpace
        The feature space.
    feature_set : FeatureSet
        None or ``"all"``, a named set (:mod:`features.feature_sets`), a modality, or column names.

    Returns
    -------
    subset : FeatureSpace
        ``space`` with the set's columns only.
    name : str
        The set's display name.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> space = FeatureSpace(np.array([[1.0, 2.0, 3.0]]), ("tactum.matx", "other.density", "other.metal"),
    ...                      ("scan1",), ("C1S1M1P1X1",), ("sample1",))
    >>> from features.feature_sets import resolve_feature_set
    >>> subset, name = resolve_feature_set(space, "other")
    >>> subset.columns, name
    (('other.density', 'other.metal'), 'other')
    >>> resolve_feature_set(space, ["tactum.matx", "other.metal"])[1], resolve_feature_set(space, None)[1]
    ('2 columns', 'all')
    """
    if feature_set is None or feature_set == "all":
        return space, "all"
    if isinstance(feature_set, str) and is_named_set(feature_set):
        return space.subset(columns_of(space.columns, feature_set)), feature_set
    if isinstance(feature_set, str):
        return space.modality(feature_set), feature_set
    columns = list(feature_set)
    return space.subset(columns), f"{len(columns)} columns"


def learning_subset(space: FeatureSpace, level: str, feature_set: FeatureSet) -> tuple[FeatureSpace, tuple[str, ...]]:
    """The rows and columns of ``space`` a classifier of ``level`` learns ``feature_set`` from: the set's columns
    (:func:`resolve_feature_set`), without the rows and columns that hold NaN, checked to be scalable
    (:func:`features.space.drop_nan_columns`).

    Parameters
    ----------
    space : FeatureSpace
        The feature space.
    level : str
        The class level (``coarse``, ``medium``, ``fine``, or a level of a set's free labels).
    feature_set : FeatureSet
        None or ``"all"``, a named set, a modality, or column names.

    Returns
    -------
    subset : FeatureSpace
        The rows and columns kept.
    dropped : tuple of str
        The set's columns left out for NaN.

    Raises
    ------
    FeatureSpaceError
        ``space`` has no level ``level``, a column is missing, every row holds only NaN, or the values kept cannot
        be scaled or are constant.
    FeatureSetError
        A set name that names nothing.

    Examples
    --------
    >>> import numpy as np
    >>> from features import FeatureSpace
    >>> from features.feature_sets import learning_subset
    >>> X = np.array([[1.0, 5.0, 3.0], [2.0, np.nan, 1.0], [3.0, 4.0, 2.0]])
    >>> space = FeatureSpace(X, ("tactum.matx", "other.metal", "other.density"), ("a", "b", "c"),
    ...                      ("C1S1M1P1X1", "C2S1M1P1X1", "C2S1M1P1X1"), ("a", "b", "c"))
    >>> subset, dropped = learning_subset(space, "fine", "other")
    >>> subset.columns, dropped
    (('other.density',), ('other.metal',))
    """
    space.check_level(level)
    subset, _ = resolve_feature_set(space, feature_set)
    return drop_nan_columns(subset)
