"""The taxonomy table: names behind the C/S/M/P/X codes (docs/taxonomy.md; Strese et al. 2020, Tables I and VI).

The table is a UTF-8 CSV file with the header ``kind,code,name,description``. ``kind`` is one of C, S, M, P,
X; ``code`` is the hierarchical code of that kind (``C6``, ``C6S1``, ``C6S1M1``, ``P2``, ``X1``). The package
ships ``data/taxonomy.csv``; a lab adds its own materials in extension files of the same format, passed to
:func:`load_taxonomy` or named by the environment variable ``TEXPLORER_TAXONOMY``.

The paper's Tables I and VI did not survive in its text, so the shipped table is a reconstruction
(interpretation): every name the paper gives is kept with its code (C6 stone, C6 S1 igneous, C6 S1 M1
granite, P2 polished, P3 pointed, C3 S4 M2 epoxy, and the materials it names without codes), the rest is
filled in from common material science. The paper labels its regularly perforated epoxy plate
``C3 S4 M2 P2 X1`` although P2 is "polished"; here perforated is P5.
"""

from __future__ import annotations

import csv
import io
import os
import re
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import NamedTuple

from taxonomy.errors import ParameterError, TexplorerError
from taxonomy.labels import Label, LabelError, format_code, parse_code, parse_prefix

KINDS = ("C", "S", "M", "P", "X")
"""Row kinds: major class, sub-class, material, processing shape, extra attribute."""

KIND_NAMES = {"C": "major class", "S": "sub-class", "M": "material", "P": "processing shape",
              "X": "extra attribute"}
HEADER = ("kind", "code", "name", "description")
SHIPPED_TABLE = Path(__file__).resolve().parent / "data" / "taxonomy.csv"
ENV_VAR = "TEXPLORER_TAXONOMY"
"""Environment variable that may name one lab extension file."""

_LETTERS = {"C": "C", "S": "CS", "M": "CSM", "P": "P", "X": "X"}
_GROUP = {"C": 0, "S": 0, "M": 0, "P": 1, "X": 2}
_QUERY_CODE = re.compile(r"C[0-9]*|C[0-9]+S[0-9]*|C[0-9]+S[0-9]+M[0-9]*|C[0-9]+S[0-9]+M[0-9]+P[0-9]*"
                         r"|C[0-9]+S[0-9]+M[0-9]+P[0-9]+X[0-9]*")
"""The beginnings of a label a picker query may be: "C", "C6", "C6S", ..., "C6S1M1P2X1"."""


class TaxonomyError(TexplorerError, ValueError):
    """A taxonomy file or row is unusable; the message names the file, the line and the reason."""


class UnknownLabelError(TexplorerError, ValueError):
    """A well-formed label uses a code the taxonomy does not define; the message names the code."""


@dataclass(frozen=True)
class Entry:
    """One row of the table. ``source`` ("file line n") says where it came from and takes no part in ``==``.

    The code is validated against the kind and stored in canonical spelling (``c6s1`` becomes ``C6S1``).
    """

    kind: str
    code: str
    name: str
    description: str = ""
    source: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise TaxonomyError(f"kind {self.kind!r} is not one of {', '.join(KINDS)}")
        try:
            numbers = parse_code(self.code, _LETTERS[self.kind])
        except LabelError as error:
            raise TaxonomyError(f"kind {self.kind} needs a {KIND_NAMES[self.kind]} code: {error}") from None
        object.__setattr__(self, "code", format_code(_LETTERS[self.kind], numbers))
        if not isinstance(self.name, str) or not self.name.strip():
            raise TaxonomyError(f"{KIND_NAMES[self.kind]} {self.code} has no name")
        if not isinstance(self.description, str):
            raise TaxonomyError(f"{KIND_NAMES[self.kind]} {self.code}: description must be text")

    @property
    def numbers(self) -> tuple[int, ...]:
        """The integers of the code: ``(6, 1)`` for ``C6S1``."""
        return parse_code(self.code, _LETTERS[self.kind])

    @property
    def parent(self) -> str | None:
        """Code of the row this one belongs to: ``C6`` for ``C6S1``, ``C6S1`` for ``C6S1M1``, else None."""
        if self.kind in ("S", "M"):
            return format_code(_LETTERS[self.kind][:-1], self.numbers[:-1])
        return None


class LabelNames(NamedTuple):
    """The names behind the five codes of a label."""

    c: str
    s: str
    m: str
    p: str
    x: str


@dataclass(frozen=True)
class MaterialChoice:
    """A material (C, S, M) with the names of its sub-class and major class, as a picker shows it."""

    code: str
    name: str
    subclass: str
    major: str
    description: str = ""

    def label(self, p: int = 1, x: int = 1) -> Label:
        """The full label of this material with processing shape ``p`` and extra attribute ``x``."""
        return Label(*parse_code(self.code, "CSM"), p, x)

    def __str__(self) -> str:
        return f"{self.code} {self.name} ({self.subclass}, {self.major})"


def _same_name(a: str, b: str) -> bool:
    return " ".join(a.split()).casefold() == " ".join(b.split()).casefold()


def _sort_key(entry: Entry) -> tuple[int, tuple[int, ...]]:
    # (6,) < (6, 1) < (6, 1, 1) < (6, 2): every class is followed by its sub-classes and their materials.
    return (_GROUP[entry.kind], entry.numbers)


def _merge(entries: Iterable[Entry]) -> dict[str, Entry]:
    """Rows by code; a repeated code must repeat the name (the first description is kept)."""
    merged: dict[str, Entry] = {}
    for entry in entries:
        known = merged.setdefault(entry.code, entry)
        if not _same_name(known.name, entry.name):
            raise TaxonomyError(f"taxonomy code {entry.code} is {known.name!r} in {known.source or 'a row'} "
                                f"but {entry.name!r} in {entry.source or 'another row'}")
    for entry in merged.values():
        if entry.parent is not None and entry.parent not in merged:
            raise TaxonomyError(f"{entry.source or 'row'}: {KIND_NAMES[entry.kind]} {entry.code} "
                                f"({entry.name}) has no parent {entry.parent} in any taxonomy file")
    return merged


class Taxonomy:
    """The merged, read-only taxonomy table: code -> :class:`Entry`.

    Parameters
    ----------
    entries : iterable of Entry
        Rows in any order; repeated codes must repeat the name, and every S and M row needs its parent.

    Raises
    ------
    TaxonomyError
        A code is given two names, or a sub-class or material has no parent row.
    """

    def __init__(self, entries: Iterable[Entry]) -> None:
        merged = _merge(entries)
        self._entries = MappingProxyType({entry.code: entry for entry in sorted(merged.values(), key=_sort_key)})

    @classmethod
    def from_csv(cls, *paths: str | os.PathLike[str]) -> Taxonomy:
        """The table merged from the given CSV files only (no shipped table, no environment)."""
        return cls(entry for path in paths for entry in read_table(path))

    def __len__(self) -> int:
        return len(self._entries)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Taxonomy):
            return NotImplemented
        return self._entries == other._entries

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        counts = ", ".join(f"{len(self.entries(kind))} {kind}" for kind in KINDS)
        return f"Taxonomy({counts})"

    def __contains__(self, label: object) -> bool:
        """True if ``label`` (a :class:`Label` or its text) is well formed and every code is known."""
        try:
            self.check(label)
        except (LabelError, UnknownLabelError):
            return False
        return True

    def entries(self, kind: str | None = None) -> tuple[Entry, ...]:
        """All rows in table order (classes with their sub-classes and materials, then P, then X)."""
        if kind is not None and kind not in KINDS:
            raise ParameterError(f"kind {kind!r} is not one of {', '.join(KINDS)}")
        return tuple(entry for entry in self._entries.values() if kind is None or entry.kind == kind)

    def name(self, code: str) -> str:
        """Name of one code (``"C6S1"`` -> ``"igneous stone"``); a full label gets :meth:`describe`.

        Accepts every code :meth:`Label.at` returns, so class names can be shown at any level.
        """
        key = code.strip().upper() if isinstance(code, str) else code
        if key in self._entries:
            return self._entries[key].name
        for kind in KINDS:
            try:
                numbers = parse_code(code, _LETTERS[kind])
            except LabelError:
                continue
            raise UnknownLabelError(f"{code}: {self._why_unknown(kind, numbers)}")
        return self.describe(code)

    def check(self, label: Label | str) -> Label:
        """The parsed label if all five codes are known.

        Raises
        ------
        LabelError
            ``label`` is malformed.
        UnknownLabelError
            A code is unknown; the message names the first one and its parent, e.g.
            ``"C6S9M1P2X1: stone has no sub-class S9"``.
        """
        label = Label.parse(label)
        c, s, m, p, x = label.numbers()
        for kind, numbers in (("C", (c,)), ("S", (c, s)), ("M", (c, s, m)), ("P", (p,)), ("X", (x,))):
            if format_code(_LETTERS[kind], numbers) not in self._entries:
                raise UnknownLabelError(f"{label}: {self._why_unknown(kind, numbers)}")
        return label

    def _why_unknown(self, kind: str, numbers: tuple[int, ...]) -> str:
        own = f"{kind}{numbers[-1]}"
        if kind not in ("S", "M"):
            return f"there is no {KIND_NAMES[kind]} {own}"
        parent_kind = _LETTERS[kind][-2]
        parent = format_code(_LETTERS[parent_kind], numbers[:-1])
        if parent not in self._entries:
            return self._why_unknown(parent_kind, numbers[:-1])
        return f"{self._entries[parent].name} has no {KIND_NAMES[kind]} {own}"

    def names(self, label: Label | str) -> LabelNames:
        """Names of the C, S, M, P and X codes of a known label."""
        label = self.check(label)
        return LabelNames(*(self._entries[code].name for code in label.codes()))

    def describe(self, label: Label | str) -> str:
        """Short text for people: ``"granite (igneous stone, stone), polished, plain"``."""
        names = self.names(label)
        return f"{names.m} ({names.s}, {names.c}), {names.p}, {names.x}"

    def class_name(self, code: str) -> str:
        """Short name of a class at any level, for figures: ``"stone"`` (C6), ``"igneous stone"`` (C6S1),
        ``"granite, polished"`` (C6S1M1P2X1: material and processing shape, and the extra attribute unless
        it is X1, which the table defines as "no extra attribute").

        Raises
        ------
        ValueError
            The code is malformed or not in the table.
        """
        key = code.strip().upper()
        if key in self._entries:
            return self._entries[key].name
        names = self.names(key)
        label = Label.parse(key)
        return ", ".join([names.m, names.p] + ([names.x] if label.x != 1 else []))

    def materials(self) -> list[MaterialChoice]:
        """Every material (C, S, M) in table order, with its sub-class and major class names."""
        return [self._material(entry) for entry in self._entries.values() if entry.kind == "M"]

    def _material(self, entry: Entry) -> MaterialChoice:
        subclass = self._entries[entry.parent]
        major = self._entries[subclass.parent]
        return MaterialChoice(entry.code, entry.name, subclass.name, major.name, entry.description)

    def search(self, text: str) -> list[MaterialChoice]:
        """Materials for a picker: by code prefix (``"C6"``, ``"c6s1"``, a full label) or by name.

        A query that starts like a code matches materials below that code (``"C1"`` finds C1S1M1 but not
        C10S1M1); any other query matches a case-insensitive substring of the material, sub-class or
        major class name. An empty query lists all materials.
        """
        if not isinstance(text, str):
            raise TypeError(f"search text must be a string, got {type(text).__name__}")
        query = text.strip()
        prefix = _code_prefix(query)
        if prefix is not None:
            return [material for material in self.materials() if _below(material.code, prefix)]
        needle = query.casefold()
        return [material for material in self.materials()
                if any(needle in name.casefold() for name in (material.name, material.subclass, material.major))]

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the merged table in the shipped format, atomically (temporary file + ``os.replace``)."""
        path = Path(path)
        # The temporary file is private (0600); the table is meant to be shared, so keep the old mode.
        mode = path.stat().st_mode & 0o777 if path.exists() else 0o644
        handle = tempfile.NamedTemporaryFile("w", encoding="utf-8", newline="", dir=path.parent,
                                             prefix=f".{path.name}.", suffix=".tmp", delete=False)
        try:
            with handle:
                writer = csv.writer(handle, lineterminator="\n")
                writer.writerow(HEADER)
                writer.writerows((e.kind, e.code, e.name, e.description) for e in self._entries.values())
                handle.flush()
                os.fsync(handle.fileno())
            os.chmod(handle.name, mode)
            os.replace(handle.name, path)
        except BaseException:
            Path(handle.name).unlink(missing_ok=True)
            raise
        return path


def select_labels(text: str, taxonomy: Callable[[], Taxonomy]) -> tuple[str | None, frozenset[str] | None]:
    """What a ``--label`` option or the web app's label field selects: ``(code prefix, None)`` for a label or
    class prefix (``C6`` = every stone, not C60), ``(None, materials)`` for part of a material, sub-class or
    class name (``granite``, ``Oak``, ``stone``: the taxonomy picker's search; the C/S/M codes it finds), and
    ``(None, None)`` for empty text. ``taxonomy`` gives the table, read only for a name (not for a prefix).

    Raises
    ------
    LabelError
        One line: the text is neither a prefix nor part of any name in the taxonomy.
    """
    text = text.strip()
    if not text:
        return None, None
    try:
        return parse_prefix(text), None
    except LabelError as exc:
        reason = str(exc)
    codes = frozenset(material.code for material in taxonomy().search(text)) if _code_prefix(text) is None else None
    if not codes:  # a code typed wrong ("C7S") is refused as a code, not searched as a name
        raise LabelError(f"{reason}; or part of a material name, e.g. granite")
    return None, codes


def material_code(label: str) -> str:
    """The C/S/M code of a full label (``C6S1M1P2X1`` -> ``C6S1M1``); empty if it is not one."""
    try:
        return Label.parse(label).codes()[2]
    except LabelError:  # a row written by hand into a catalog; it matches no name
        return ""


def _code_prefix(query: str) -> str | None:
    """The C/S/M part of ``query`` if it reads as the start of a label (``"c6s1m1p2"`` -> ``"C6S1M1"``)."""
    upper = query.upper()
    if _QUERY_CODE.fullmatch(upper) is None:
        return None
    return upper.split("P")[0]


def _below(code: str, prefix: str) -> bool:
    if not code.startswith(prefix):
        return False
    # "C1" must not match C10S1M1: after a digit the code must go on with a letter, not another digit.
    rest = code[len(prefix):]
    return not (prefix[-1].isdigit() and rest[:1].isdigit())


def _rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """(first line number, fields) of every non-blank CSV record of ``path``."""
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise TaxonomyError(f"taxonomy file {path} does not exist") from None
    except UnicodeDecodeError as error:
        raise TaxonomyError(f"{path}: not UTF-8 text (byte {error.start})") from None
    except OSError as error:
        raise TaxonomyError(f"taxonomy file {path} cannot be read: {error.strerror}") from None
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    line = 1
    while True:
        try:
            fields = next(reader)
        except StopIteration:
            return
        except csv.Error as error:
            raise TaxonomyError(f"{path} line {line}: broken CSV ({error})") from None
        if any(value.strip() for value in fields):
            yield line, fields
        line = reader.line_num + 1


def read_table(path: str | os.PathLike[str]) -> tuple[Entry, ...]:
    """The rows of one taxonomy CSV file, each with its ``source`` ("file line n").

    Blank lines and rows of empty fields (as spreadsheets export them) are skipped; every other row needs
    exactly four fields. The file may start with a UTF-8 byte order mark.

    Raises
    ------
    TaxonomyError
        The file is missing, unreadable or not UTF-8, the header is wrong, or a row is bad; the message
        names the file and the line.
    """
    path = Path(path)
    rows = _rows(path)
    first = next(rows, None)
    if first is None:
        raise TaxonomyError(f"{path}: empty, expected the header {','.join(HEADER)}")
    line, header = first
    if tuple(value.strip().lower() for value in header) != HEADER:
        raise TaxonomyError(f"{path} line {line}: header must be {','.join(HEADER)}, found {','.join(header)}")
    return tuple(_entry(path, line, fields) for line, fields in rows)


def _entry(path: Path, line: int, fields: Sequence[str]) -> Entry:
    if len(fields) != len(HEADER):
        raise TaxonomyError(f"{path} line {line}: expected {len(HEADER)} fields ({','.join(HEADER)}), "
                            f"found {len(fields)}")
    kind, code, name, description = (value.strip() for value in fields)
    try:
        return Entry(kind.upper(), code, name, description, source=f"{path} line {line}")
    except TaxonomyError as error:
        raise TaxonomyError(f"{path} line {line}: {error}") from None


def _extension_paths(extra: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None) -> list[Path]:
    paths = []
    from_env = os.environ.get(ENV_VAR, "").strip()
    if from_env:
        if not Path(from_env).is_file():
            raise TaxonomyError(f"{ENV_VAR} names {from_env}, which is not a file")
        paths.append(Path(from_env))
    if extra is None:
        return paths
    if isinstance(extra, (str, os.PathLike)):
        extra = [extra]
    return paths + [Path(path) for path in extra]


def load_taxonomy(extra: str | os.PathLike[str] | Sequence[str | os.PathLike[str]] | None = None) -> Taxonomy:
    """The shipped table merged with the lab's extension files.

    Extensions are read in this order: the file named by ``$TEXPLORER_TAXONOMY`` (if set and not empty),
    then ``extra`` (one path or a list of paths). An extension may add codes and may repeat an existing
    code with the same name (compared ignoring case and repeated spaces); giving it another name is an error.

    Raises
    ------
    TaxonomyError
        A file is missing or broken, a code is given two names (both files are named), or a new sub-class
        or material has no parent.

    Examples
    --------
    >>> load_taxonomy().describe("C6S1M1P2X1")
    'granite (igneous stone, stone), polished, plain'
    """
    return Taxonomy.from_csv(SHIPPED_TABLE, *_extension_paths(extra))
