"""The feature families and the one registry everything about them is derived from.

A family is named columns computed from a scan by one function: TacTUM, image, audio and other are the
paper's (:mod:`features.families` registers them). Registering a family is the only step that adds
features: extraction (:func:`features.extract`, ``extract_many``) computes every registered family in
order, the feature space knows its modality, the evaluation grid gets a feature set for it, the web
application a group of values, and the feature cache's code version covers the source of its module and
of every project module that module imports, so a change to the code never serves stale cached values.

The registry holds the families' order; the column names of all of them, in that order, are the rows'
order everywhere (CSV, ``.mat``, cache).

Other labs' recordings have channel roles instead of the scanner's channels, and a scan read as a recording
has them too (:func:`features.recordings.scan_recording`): the families computed on one role of a recording
(:class:`RoleFamily`, registered by :mod:`features.recordings`) are in the same registry, shown by
``REGISTRY.roles``; from there come that module's columns, the families that apply to a recording and the roles
they need, in the same way.
"""

from __future__ import annotations

import dis
import hashlib
import importlib.util
import threading
import types
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import numpy as np

from features.prepared import PreparedScan
from taxonomy.errors import ParameterError

PROJECT_PACKAGES = ("scanner", "features", "taxonomy", "gui")
"""Packages whose modules count towards the code version when a family's module imports them."""

Compute = Callable[[PreparedScan], Mapping[str, float]]
"""A family's function: the prepared scan -> its values by column name, in the family's column order."""


class _Code:
    """What a family's values depend on: the module that defines its function, and its parameters."""

    compute: Callable[..., object]
    params: Mapping[str, object]
    opt_in: bool

    @property
    def module(self) -> str:
        """The module that defines the family's function."""
        return self.compute.__module__


@dataclass(frozen=True)
class Family(_Code):
    """One feature family.

    ``name`` is the modality: the first part of every column name (``tactum.matx``). ``groups`` are the
    web application's groups of values, ``(column prefix, title)``, by default the whole family under its
    ``title``. ``solver_rtol`` gives the relative tolerance of columns computed by an iterative fit (the
    regression comparison uses it; closed-form columns have none). ``params`` are the values the family's
    function reads besides the scan (a length rule, a filter bank's octaves): they count towards the code
    version, so a cached value is never served for other parameters. An ``opt_in`` family is computed
    only when asked for by name (:meth:`Registry.chosen`); iterating the registry, its ``names``,
    ``modalities``, ``groups`` and code version are those of the default families only.
    """

    name: str
    title: str
    columns: tuple[str, ...]
    compute: Compute
    groups: tuple[tuple[str, str], ...] = ()
    solver_rtol: Mapping[str, float] = field(default_factory=dict)
    params: Mapping[str, object] = field(default_factory=dict)
    opt_in: bool = False
    units: Mapping[str, str] = field(default_factory=dict)
    """Physical unit of each column that has one (``"Hz"``, ``"N/mm"``); dimensionless columns are absent.
    Descriptive only (export metadata, docs/features.md): it does not count towards the code version."""
    steps: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    """The steps of the scanning procedure (docs/operator.md#procedure: ``tool_slide``, ``photos``, ``tu4``, ...)
    whose recordings each column needs, by column name or column prefix (the longest prefix wins): a column is
    defined once all of its steps are recorded. A column not covered needs the whole scan. Descriptive as
    ``units``; the quick scan reads it (:meth:`ScanRegistry.column_steps`)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "columns", tuple(self.columns))
        object.__setattr__(self, "steps", {key: tuple(value) for key, value in self.steps.items()})
        if not self.groups:
            object.__setattr__(self, "groups", ((self.name, self.title),))
        if not self.name or "." in self.name:
            raise ParameterError(f"family name must be a non-empty word without dots, got {self.name!r}")
        prefix = self.name + "."
        _check_columns(self, [c for c in self.columns if not c.startswith(prefix)], f"start with '{prefix}'")
        strays = sorted(set(self.units) - set(self.columns))
        if strays:
            raise ParameterError(f"family {self.name}: units given for columns it does not have: {', '.join(strays)}")
        strays = sorted(key for key in self.steps if not any(c == key or c.startswith(key + ".") for c in self.columns))
        if strays:
            raise ParameterError(f"family {self.name}: steps given for columns it does not have: {', '.join(strays)}")
        empty = sorted(key for key, steps in self.steps.items() if not steps or not all(steps))
        if empty:
            raise ParameterError(f"family {self.name}: no step named for {', '.join(empty)}")


@dataclass(frozen=True)
class RoleFamily(_Code):
    """One feature family of a generic recording, computed on the channel role ``role`` (or its photo).

    ``name`` names the family (``audio.vibration``: the audio features of the vibration); every column is
    ``<modality>.<role>.<feature>``, the modality a scan family's, so ``FeatureSpace.modality`` finds it.
    A sampled role: ``applies(fs)`` says whether a channel sampled at ``fs`` Hz can carry the family,
    ``prepare(data, fs)`` (optional) runs once on the whole recording before it is cut into windows (a
    band limit), and ``compute(window, fs)`` gives the values of one window of the prepared data, in
    column order. An image role (``photo``): ``compute(image, border)``, the border cropped in pixels.
    ``params`` and ``opt_in`` as for :class:`Family`.
    """

    name: str
    role: str
    columns: tuple[str, ...]
    compute: Callable[[np.ndarray, Any], Sequence[float]]
    applies: Callable[[float], bool] = field(default=lambda fs: True)  # any rate
    prepare: Callable[[np.ndarray, float], np.ndarray] | None = None
    params: Mapping[str, object] = field(default_factory=dict)
    opt_in: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "columns", tuple(self.columns))
        role = f".{self.role}."
        _check_columns(self, [c for c in self.columns if c.count(".") != 2 or role not in c],
                       f"be '<modality>.{self.role}.<feature>'")


def _check_columns(family: Family | RoleFamily, strays: Sequence[str], rule: str) -> None:
    """Every column of ``family`` follows ``rule`` (``strays`` are those that do not), none repeats."""
    if strays or not family.columns:
        raise ParameterError(f"family {family.name!r}: every column must {rule} "
                             f"(got {', '.join(strays[:3]) or 'no columns'})")
    if len(set(family.columns)) != len(family.columns):
        raise ParameterError(f"family {family.name!r}: column names repeat")


F = TypeVar("F", Family, RoleFamily)


class _Store:
    """The families of every kind in registration order, and every column they name: one namespace."""

    def __init__(self) -> None:
        self.families: dict[str, Family | RoleFamily] = {}
        self.columns: set[str] = set()


class Registry(Generic[F]):
    """Registered families, in extraction (column) order.

    Iteration, :attr:`names`, :attr:`modalities` and :meth:`code_version` cover the default families;
    :meth:`chosen` gives any families by name, the opt-in ones too, and :attr:`every` all of them.

    A registry of one ``kind`` (:class:`Family` or :class:`RoleFamily`) shows the families of that kind of a
    ``store`` it may share with a registry of the other kind: :data:`REGISTRY` holds the scan families, its
    :attr:`ScanRegistry.roles` the role families of the same store, so a family's name and columns are unique
    over both and either is registered the same way. Without a ``kind`` it shows every family of its store.
    """

    def __init__(self, kind: type[F] | None = None, store: _Store | None = None) -> None:
        self._kind = kind
        self._store = _Store() if store is None else store

    @property
    def _families(self) -> dict[str, F]:
        """The families of the store of this registry's kind, in order."""
        return {name: family for name, family in self._store.families.items()
                if self._kind is None or isinstance(family, self._kind)}

    def register(self, family: F) -> F:
        """Add ``family`` after the others; returns it.

        Its module's source (and that of every project module it imports) is read now, for the code version
        (:func:`fix_code_version`).

        Parameters
        ----------
        family : Family or RoleFamily
            The family to add; its name and columns must be new to this registry.

        Returns
        -------
        Family or RoleFamily
            ``family``, so that a module can keep it: ``TOY = REGISTRY.register(Family(...))``.

        Raises
        ------
        ParameterError
            If a family of that name or one of its columns is already registered.

        Examples
        --------
        >>> from features.registry import Family, Registry
        >>> registry = Registry()
        >>> size = registry.register(Family("toy", "Toy", ("toy.size", "toy.mass"), lambda prepared: {}))
        >>> registry.names, registry.modalities
        (('toy.size', 'toy.mass'), ('toy',))
        >>> registry.register(Family("toy", "Toy", ("toy.colour",), lambda prepared: {}))
        Traceback (most recent call last):
        ...
        taxonomy.errors.ParameterError: a feature family 'toy' is already registered
        """
        if self._kind is not None and not isinstance(family, self._kind):
            raise ParameterError(f"family {family.name!r} is a {type(family).__name__}; this registry holds "
                                 f"{self._kind.__name__} families")
        if family.name in self._store.families:
            raise ParameterError(f"a feature family {family.name!r} is already registered")
        taken = sorted(self._store.columns.intersection(family.columns))
        if taken:
            raise ParameterError(f"family {family.name!r}: column(s) already registered: {', '.join(taken[:3])}")
        fix_code_version(family.module)
        self._store.families[family.name] = family
        self._store.columns.update(family.columns)
        return family

    def unregister(self, name: str) -> F:
        """Remove the family ``name`` (a plug-in or a test undoing its registration); returns it.

        Parameters
        ----------
        name : str
            The name of a registered family.

        Returns
        -------
        Family or RoleFamily
            The family removed; its column names are free again.

        Raises
        ------
        ParameterError
            If no family of that name is registered.

        Examples
        --------
        >>> from features.registry import Family, Registry
        >>> registry = Registry()
        >>> toy = registry.register(Family("toy", "Toy", ("toy.size",), lambda prepared: {}))
        >>> registry.unregister("toy") is toy, "toy" in registry, registry.names
        (True, False, ())
        """
        if name not in self._families:
            raise ParameterError(f"no feature family {name!r} (registered: {', '.join(self._families)})")
        family = self._store.families.pop(name)
        self._store.columns.difference_update(family.columns)
        return family

    def __iter__(self) -> Iterator[F]:
        return iter(tuple(f for f in self._families.values() if not f.opt_in))

    def __len__(self) -> int:
        return len(tuple(iter(self)))

    def __contains__(self, name: object) -> bool:
        return name in self._families

    @property
    def every(self) -> tuple[F, ...]:
        """Every registered family, the opt-in ones too, in order."""
        return tuple(self._families.values())

    @property
    def opt_in(self) -> tuple[str, ...]:
        """The names of the opt-in families, in order."""
        return tuple(f.name for f in self._families.values() if f.opt_in)

    def chosen(self, names: Sequence[str] | None = None) -> tuple[F, ...]:
        """The families ``names`` in registry order (None: the default ones).

        Parameters
        ----------
        names : sequence of str, optional
            Names of registered families, opt-in ones too, in any order.

        Returns
        -------
        tuple of Family or RoleFamily
            The families named (or every default one), in the order they were registered.

        Raises
        ------
        ParameterError
            If a name is not a registered family.

        Examples
        --------
        >>> from features import REGISTRY
        >>> [family.name for family in REGISTRY.chosen()]
        ['tactum', 'image', 'audio', 'other']
        >>> [family.name for family in REGISTRY.chosen(["catch22", "other", "tactum"])]
        ['tactum', 'other', 'catch22']
        """
        if names is None:
            return tuple(self)
        unknown = [n for n in names if n not in self._families]
        if unknown:
            raise ParameterError(f"no feature family {unknown[0]!r} (registered: {', '.join(self._families)})")
        return tuple(f for f in self._families.values() if f.name in names)

    def columns_of(self, names: Sequence[str] | None = None) -> tuple[str, ...]:
        """Every column of the families ``names`` (None: the default ones), in order.

        Parameters
        ----------
        names : sequence of str, optional
            Names of registered families, opt-in ones too (:meth:`chosen`).

        Returns
        -------
        tuple of str
            The column names of those families, family after family in registry order.

        Raises
        ------
        ParameterError
            If a name is not a registered family.

        Examples
        --------
        >>> from features import REGISTRY
        >>> len(REGISTRY.columns_of()), REGISTRY.columns_of(["other", "tactum"])[:2]
        (193, ('tactum.matx', 'tactum.maco'))
        """
        return tuple(column for family in self.chosen(names) for column in family.columns)

    def __getitem__(self, name: str) -> F:
        return self._families[name]

    @property
    def names(self) -> tuple[str, ...]:
        """Every column of every family, in order."""
        return tuple(column for family in self for column in family.columns)

    @property
    def modalities(self) -> tuple[str, ...]:
        """The default families' names, in order."""
        return tuple(family.name for family in self)

    def code_modules(self, *extra: str, families: Sequence[str] | None = None) -> tuple[str, ...]:
        """The modules whose source the values depend on: each family's module (of ``families``, default
        the default ones), ``extra`` modules (the extraction's own), and every project module they import,
        directly or not.

        Parameters
        ----------
        *extra : str
            Further modules whose source counts (dotted names).
        families : sequence of str, optional
            Names of registered families (:meth:`chosen`); default the default ones.

        Returns
        -------
        tuple of str
            The dotted module names, sorted, each once; only modules of :data:`PROJECT_PACKAGES` besides the
            families' own and ``extra``.

        Examples
        --------
        A family defined in this module depends on it and on what it imports (:mod:`features.prepared`, ...):

        >>> from features.registry import Family, Registry
        >>> registry = Registry()
        >>> toy = registry.register(Family("toy", "Toy", ("toy.size",), lambda prepared: {}))
        >>> modules = registry.code_modules()
        >>> toy.module in modules, "features.prepared" in modules, "features.selection" in modules
        (True, True, False)
        >>> "features.selection" in registry.code_modules("features.selection")
        True
        """
        return _closure(tuple(sorted({family.module for family in self.chosen(families)} | set(extra))))

    def code_version(self, *extra: str, families: Sequence[str] | None = None) -> str:
        """Hash of the source of :meth:`code_modules` as each module's file was when it was fixed
        (:func:`fix_code_version`, at registration; a process computes with the code it imported, not with
        what is on disk later), and of the chosen families' names and ``params`` when ``families`` are
        given: a cached feature vector is reused only with the code and parameters that computed it. The
        default families' version is that of their source alone.

        Parameters
        ----------
        *extra : str
            Further modules whose source counts (:meth:`code_modules`).
        families : sequence of str, optional
            Names of registered families whose names and ``params`` count too; default the default families,
            by their source alone.

        Returns
        -------
        str
            20 hexadecimal digits of a SHA-256 hash.

        Examples
        --------
        The same family's code with other parameters: the same source version, another version of the
        families chosen by name:

        >>> from features.registry import Family, Registry
        >>> def size(prepared):
        ...     return {"toy.size": 1.0}
        >>> octaves_4, octaves_2 = Registry(), Registry()
        >>> _ = octaves_4.register(Family("toy", "Toy", ("toy.size",), size, params={"octaves": 4}))
        >>> _ = octaves_2.register(Family("toy", "Toy", ("toy.size",), size, params={"octaves": 2}))
        >>> octaves_4.code_version() == octaves_2.code_version(), len(octaves_4.code_version())
        (True, 20)
        >>> octaves_4.code_version(families=["toy"]) == octaves_2.code_version(families=["toy"])
        False
        """
        source = _digest(self.code_modules(*extra, families=families))
        if families is None:
            return source
        described = repr([(f.name, sorted((k, repr(v)) for k, v in f.params.items()))
                          for f in self.chosen(families)])
        return hashlib.sha256(f"{source}\0{described}".encode()).hexdigest()[:20]


class ScanRegistry(Registry[Family]):
    """The scan families, with what only they carry: the web application's groups and solver tolerances, and
    the role families of the same store (:attr:`roles`)."""

    def __init__(self, kind: type[Family] = Family, store: _Store | None = None) -> None:
        super().__init__(kind, store)
        self.roles: Registry[RoleFamily] = Registry(RoleFamily, self._store)
        """The role families (:class:`RoleFamily`) registered beside the scan families: one store, so a name or
        column of either kind is unique over both."""

    @property
    def groups(self) -> tuple[tuple[str, str], ...]:
        """The web application's groups of values, ``(column prefix, title)``, in order."""
        return tuple(group for family in self for group in family.groups)

    @property
    def solver_rtol(self) -> dict[str, float]:
        """Relative tolerance of every column computed by an iterative fit."""
        return {column: rtol for family in self for column, rtol in family.solver_rtol.items()}

    @property
    def units(self) -> dict[str, str]:
        """The unit of every column that has one (:attr:`Family.units`)."""
        return {column: unit for family in self for column, unit in family.units.items()}

    def column_steps(self, columns: Sequence[str] | None = None) -> dict[str, frozenset[str]]:
        """The steps each column needs (:attr:`Family.steps`; the longest declared prefix wins), for ``columns``
        (default: every default column); an empty set where the family does not say, read as "the whole scan".

        Parameters
        ----------
        columns : sequence of str, optional
            Column names (of any registered family or none); default :attr:`names`.

        Returns
        -------
        dict of str to frozenset of str
            Each column's steps, in the order of ``columns``.

        Examples
        --------
        >>> import features
        >>> sorted(REGISTRY.column_steps(["tactum.matx"])["tactum.matx"])
        ['friction', 'tool_slide']
        """
        declared = {key: frozenset(steps) for family in self.every for key, steps in family.steps.items()}
        needed = {}
        for column in (self.names if columns is None else columns):
            parts = column.split(".")
            keys = [".".join(parts[:k]) for k in range(len(parts), 0, -1)]
            needed[column] = next((declared[key] for key in keys if key in declared), frozenset())
        return needed

    def column_groups(self, columns: Sequence[str]) -> list[tuple[str, tuple[int, ...]]]:
        """``columns`` by the sensing step that measured them: ``[(title, column indices), ...]`` in order of
        first appearance.

        A column under one of :attr:`groups`' prefixes takes its title (the longest prefix wins: ``image.disp``
        is "image: photo"); a recording's column ``<modality>.<role>.<feature>`` is grouped by modality and
        role ("generic: vibration"); any other column by its first name part.

        Parameters
        ----------
        columns : sequence of str
            Column names, in the order of a feature space's columns.

        Returns
        -------
        list of (str, tuple of int)
            Each group's title and the indices of its columns in ``columns``.

        Examples
        --------
        >>> from features import REGISTRY
        >>> REGISTRY.column_groups(["tactum.matx", "image.disp.color", "audio.tool.f0", "image.macro.color",
        ...                         "generic.vibration.mean", "tactum.fst"])  # doctest: +NORMALIZE_WHITESPACE
        [('TacTUM', (0, 5)), ('image: photo', (1,)), ('audio: tool slide', (2,)), ('image: macro lens', (3,)),
         ('generic: vibration', (4,))]
        """
        titles = {prefix: title.split(" (", 1)[0] for prefix, title in self.groups}
        grouped: dict[str, list[int]] = {}
        for index, column in enumerate(columns):
            parts = column.split(".")
            prefixes = [".".join(parts[:k]) for k in range(len(parts) - 1, 0, -1)]
            title = next((titles[p] for p in prefixes if p in titles), None)
            if title is None:
                title = f"{parts[0]}: {parts[1]}" if len(parts) == 3 else parts[0]
            grouped.setdefault(title, []).append(index)
        return [(title, tuple(indices)) for title, indices in grouped.items()]


REGISTRY = ScanRegistry(Family)
"""Every feature family: the scan families, which every extraction of a scan computes (the paper's four,
registered by :mod:`features.families`; the opt-in modern ones by :mod:`features.modern`), and in
:attr:`REGISTRY.roles <ScanRegistry.roles>` the families computed by channel role on recordings and on scans read
as recordings (the project's five, registered by :mod:`features.recordings`; the modern ones per role)."""


# -- the code a family depends on ---------------------------------------------------------------------
#
# Read once per process and module, under one lock: the web app's request threads asked for the version at
# once, and ``functools.cache`` does not serialise first calls.

_lock = threading.RLock()
_closures: dict[tuple[str, ...], tuple[str, ...]] = {}
_sources: dict[str, bytes] = {}
"""Each module's source as this process read it, when the module (or a family importing it) was fixed."""
_digests: dict[tuple[str, ...], str] = {}
"""The hash of each set of modules' sources (:func:`_digest`)."""
_imports: dict[str, frozenset[str]] = {}
"""The project modules each module imports, from its top-level code (:func:`_imports_in`)."""


def fix_code_version(*modules: str) -> None:
    """Read now the source of ``modules`` and of every project module they import, for the code version.

    Called when a family is registered, that is when its module is imported (and :mod:`features.extraction`
    for itself): the version is that of the files the process imported, so a long-running process (a web
    server) whose files are updated on disk keeps storing its values under the version of its own code.

    Parameters
    ----------
    *modules : str
        Dotted names of importable modules.

    Raises
    ------
    ParameterError
        If a module's source cannot be found.

    Examples
    --------
    A module outside the project is hashed as its name, a zero byte and its source; a change to its file
    after it was fixed does not change the version:

    >>> import hashlib, sys, tempfile
    >>> from pathlib import Path
    >>> from features.registry import Registry
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     source = Path(folder) / "texplorer_docs_toy.py"
    ...     _ = source.write_text("SCALE = 1")
    ...     sys.path.insert(0, folder)
    ...     fix_code_version("texplorer_docs_toy")
    ...     _ = source.write_text("SCALE = 2")
    ...     version = Registry().code_version("texplorer_docs_toy")
    ...     sys.path.remove(folder)
    >>> version == hashlib.sha256(b"texplorer_docs_toy" + bytes(1) + b"SCALE = 1").hexdigest()[:20]
    True
    """
    for module in _closure(tuple(sorted(modules))):
        _source_bytes(module)


def _closure(start: tuple[str, ...]) -> tuple[str, ...]:
    with _lock:
        if start not in _closures:
            seen: set[str] = set()
            todo = list(start)
            while todo:
                module = todo.pop()
                if module not in seen:
                    seen.add(module)
                    todo.extend(_imported(module))
            _closures[start] = tuple(sorted(seen))
        return _closures[start]


def _source(module: str) -> Path:
    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        raise ParameterError(f"cannot find the source of module {module!r}")
    return Path(spec.origin)


def _source_bytes(module: str) -> bytes:
    with _lock:
        if module not in _sources:
            _sources[module] = _source(module).read_bytes()
        return _sources[module]


def _imported(module: str) -> frozenset[str]:
    """Project modules that ``module`` imports (modules only import at their top, see docs/extending.md),
    found once per process: a module is in the closure of many families."""
    with _lock:
        if module not in _imports:
            _imports[module] = _imports_in(_code(module))
        return _imports[module]


def _code(module: str) -> types.CodeType:
    """The top-level code of ``module`` as the import system has it: from its bytecode cache when that is
    current (Python checks it against the source file), else compiled from the source (a loader without
    ``get_code``, such as pytest's for test modules)."""
    spec = importlib.util.find_spec(module)
    get_code = getattr(spec.loader, "get_code", None) if spec is not None else None
    code = get_code(module) if get_code is not None else None
    return code if code is not None else compile(_source_bytes(module), str(_source(module)), "exec",
                                                 dont_inherit=True)


def _imports_in(code: types.CodeType) -> frozenset[str]:
    """The project modules named by the import statements of a module's top level, those inside its
    ``if`` (``TYPE_CHECKING``), ``try`` and ``with`` blocks included: the ``IMPORT_NAME`` and ``IMPORT_FROM``
    instructions of the module's own code object (function and class bodies are code objects of their own).
    Relative imports name no top-level package of the project and so are left out. Reading the bytecode
    rather than parsing the source keeps this walk, which runs at each start, to a few milliseconds."""
    found = set()
    module = None
    for op, arg in _instructions(code.co_code):
        if op == _IMPORT_NAME:
            module = code.co_names[arg]
            found.add(module)
        elif op == _IMPORT_FROM and module is not None:
            found.add(f"{module}.{code.co_names[arg]}")
    return frozenset(name for name in found if name.split(".")[0] in PROJECT_PACKAGES and _is_module(name))


_IMPORT_NAME, _IMPORT_FROM, _EXTENDED_ARG = (dis.opmap[name] for name in ("IMPORT_NAME", "IMPORT_FROM", "EXTENDED_ARG"))


def _instructions(raw: bytes) -> Iterator[tuple[int, int]]:
    """``(opcode, argument)`` of every two-byte code unit of a code object's bytecode, ``EXTENDED_ARG``
    prefixes folded into the argument that follows (inline cache units come out as opcode 0)."""
    extended = 0
    for index in range(0, len(raw), 2):
        op, arg = raw[index], raw[index + 1] | extended
        extended = arg << 8 if op == _EXTENDED_ARG else 0
        yield op, arg


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # "package.attribute": its parent is a module, the name is not
        return False


def _digest(modules: tuple[str, ...]) -> str:
    """The hash of ``modules``' sources as this process read them: computed once per set (an extraction
    checks it for every scan it hands a worker)."""
    with _lock:
        if modules not in _digests:
            _digests[modules] = _hashed(modules)
        return _digests[modules]


def _hashed(modules: tuple[str, ...]) -> str:
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for module in modules:
        path = _source(module).resolve()
        shown = path.relative_to(root).as_posix() if path.is_relative_to(root) else module
        digest.update(shown.encode() + b"\0" + _source_bytes(module))
    return digest.hexdigest()[:20]
