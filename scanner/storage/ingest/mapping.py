"""Mapping files of an import: which files form a recording, how to read them and which column
or variable plays which channel role (the format is in ``docs/ingest.md``).
"""

from __future__ import annotations

import math
import os
import re
import reprlib
import tomllib
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import Any

from scanner.scan import ROLES
from taxonomy.errors import TexplorerError

FORMATS = ("csv", "tsv", "wav", "npy", "npz", "mat", "image")
IMAGE_EXTENSIONS = ("png", "jpg", "jpeg", "bmp", "tif", "tiff")
"""Extensions read as ``format = "image"`` (an RGB photo, OpenCV's decoders)."""
TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
MISSING = ("interpolate", "error")
SPLIT_NAMES = {"train": ("train", "training"), "test": ("test", "testing")}
"""Folder names (or pattern values) of a dataset's own train/test split, compared case-insensitively."""
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")
_SET = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
MAX_INDEX = 2**31 - 1
"""The largest column index, ``skip_rows`` or label ``depth`` a mapping may give."""
META_DEPTH = 8
"""How deep ``[meta]`` may nest tables and lists (the TOML reader itself stops far deeper)."""
RESERVED_META = ("label_level", "levels", "source", "split", "time_base", "patch", "grid")
"""``meta`` keys the import sets itself; a mapping's ``[meta]`` may not give them."""
_SHOWN = reprlib.Repr()
_SHOWN.maxstring, _SHOWN.maxother, _SHOWN.maxlong, _SHOWN.maxlist, _SHOWN.maxdict, _SHOWN.maxlevel = (
    40, 40, 24, 4, 4, 2)


class IngestError(TexplorerError, ValueError):
    """A mapping file or a data file that cannot be used; the message names it and the reason."""

@dataclass(frozen=True)
class ChannelMap:
    """One channel: where its samples are (``columns`` of a table, ``variable`` of an npz/mat file, audio
    channel indices of a WAV), its role, unit and scale, and whether its columns are consecutive samples."""

    name: str
    role: str | None
    columns: tuple[str | int, ...] = ()
    variable: str | None = None
    spread: bool = False
    unit: str = "-"
    scale: float = 1.0


@dataclass(frozen=True)
class FileMap:
    """A kind of file: which files (``glob``), the part of the name after the recording stem (``suffix``)
    or a pattern whose ``stem`` group is the stem (``stem_pattern``), how to read them and the channels they
    hold."""

    glob: str
    suffix: str | None
    format: str | None
    channels: tuple[ChannelMap, ...]
    delimiter: str | None = None
    header: bool = True
    comment: str | None = "#"
    skip_rows: int = 0
    rate: float | None = None
    time_column: str | int | None = None
    time_unit: str = "s"
    rate_variable: str | None = None
    grid: tuple[int, int] | None = None
    stem_pattern: re.Pattern[str] | None = None
    required: bool = False
    """Every recording needs a file of this entry: one without it is not made, its files reported by name."""


@dataclass(frozen=True)
class IngestMapping:
    """A parsed mapping file (see ``docs/ingest.md``)."""

    name: str
    files: tuple[FileMap, ...]
    label_from: str = "folder"
    label_depth: int = 1
    label_csv: str | None = None
    label_key: str = "recording"
    label_column: str = "label"
    label_levels: tuple[str, ...] = ()
    label_level: str = "label"
    pattern: re.Pattern[str] | None = None
    missing: str = "interpolate"
    meta: Mapping[str, Any] = field(default_factory=dict)
    split_from: str = "auto"
    split_names: Mapping[str, tuple[str, ...]] = field(default_factory=lambda: dict(SPLIT_NAMES))
    exclude: tuple[str, ...] = ()
    """Labels (classes, label folders) left out of the import: their files are not read, and a note counts them."""


def _fail(where: str, reason: str) -> IngestError:
    return IngestError(f"{where}: {reason}")


def nfc(text: str) -> str:
    """``text`` in Unicode normal form C, so a name in NFD (as macOS file systems store it) is the same name."""
    return unicodedata.normalize("NFC", text)


def shown(value: Any) -> str:
    """``repr(value)`` cut short (long text, big numbers, deep lists): error messages stay one short line."""
    return _SHOWN.repr(value)


_KIND_NAMES = {str: "text", int: "a whole number", float: "a number", bool: "true or false", list: "a list"}


def _get(table: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str,
         default: Any = None) -> Any:
    value = table.get(key, default)
    kinds = (kind,) if isinstance(kind, type) else kind
    if value is not None and (not isinstance(value, kinds) or (isinstance(value, bool) and bool not in kinds)):
        names = " or ".join(_KIND_NAMES[k] for k in kinds if k is not int or float not in kinds)
        raise _fail(where, f"{key} must be {names}, got {shown(value)}")
    if isinstance(value, int) and not isinstance(value, bool) and float not in kinds and abs(value) > MAX_INDEX:
        raise _fail(where, f"{key} must be at most {MAX_INDEX} in size, got {shown(value)}")
    return value


def _finite(table: Mapping[str, Any], key: str, where: str, default: float | None = None) -> float | None:
    """A finite number at ``key`` (None if absent and no default)."""
    value = _get(table, key, (int, float), where, default)
    if value is None:
        return None
    try:
        number = float(value)
    except OverflowError:  # an integer beyond float64 (10**400)
        number = math.inf
    if not math.isfinite(number):
        raise _fail(where, f"{key} must be a finite number, got {shown(value)}")
    return number


def _unknown(table: Mapping[str, Any], known: set[str] | tuple[str, ...], where: str) -> None:
    unknown = set(table) - set(known)
    if unknown:
        raise _fail(where, f"unknown key(s) {shown(', '.join(sorted(unknown)))[1:-1]}")


def _compiled(text: str, key: str, where: str) -> re.Pattern[str]:
    """``text`` (in NFC, as the names it is searched in) compiled as a regular expression."""
    try:
        return re.compile(nfc(text))
    except (re.error, RecursionError, OverflowError) as exc:
        reason = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)
        raise _fail(where, f"{key} is not a regular expression ({reason})") from None


def _inside(text: str, key: str, where: str) -> str:
    """``text``, a path or glob relative to the ingested folder that does not climb out of it (no leading
    ``/`` or drive, no ``..``): a mapping reads only files inside the folder it is applied to."""
    if (text.startswith(("/", "\\")) or PureWindowsPath(text).drive or ".." in PurePosixPath(text).parts
            or ".." in PureWindowsPath(text).parts):
        raise _fail(where, f"{key} {shown(text)} must name files inside the ingested folder (relative to it, "
                           "without '..')")
    return text


def _is_column(value: Any) -> bool:
    return isinstance(value, str | int) and not isinstance(value, bool)


def _columns(value: Any, where: str) -> tuple[str | int, ...]:
    values = [value] if _is_column(value) else value
    if value is None:
        return ()
    if (isinstance(values, list) and values and all(_is_column(v) for v in values)
            and all(0 <= v <= MAX_INDEX for v in values if isinstance(v, int))):
        return tuple(values)
    raise _fail(where, f"columns must be a name, an index (0 to {MAX_INDEX}), a 'first:last' range or a list "
                       f"of them, got {shown(value)}")


def _channel(table: Mapping[str, Any], where: str) -> ChannelMap:
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    name = _get(table, "name", str, where)
    if not name or not _NAME.match(name):
        raise _fail(where, f"name {shown(name)} must be a MATLAB-style identifier "
                           "(a letter, then letters, digits, _)")
    role = _get(table, "role", str, where)
    if role is not None and role not in ROLES:
        raise _fail(where, f"unknown role {shown(role)} (known: {', '.join(sorted(ROLES))})")
    _unknown(table, ("name", "role", "columns", "variable", "spread", "unit", "scale"), where)
    scale = _finite(table, "scale", where, 1.0)
    if scale == 0:
        raise _fail(where, "scale must not be 0 (it would erase the channel)")
    return ChannelMap(name, role, _columns(table.get("columns"), where), _get(table, "variable", str, where),
                      bool(_get(table, "spread", bool, where, False)), _get(table, "unit", str, where, "-"),
                      scale)


_FILE_KEYS = {"glob", "suffix", "format", "channels", "delimiter", "header", "comment", "skip_rows", "rate",
              "time_column", "time_unit", "rate_variable", "grid", "stem_pattern", "required"}

DEFAULT_CHANNELS = {"wav": ChannelMap("audio", "audio", unit="FS"), "image": ChannelMap("photo", "photo")}
"""The channel of a WAV or image file whose mapping lists none."""


def format_of(name: str) -> str | None:
    """The format a file name's extension implies (``.png`` -> ``image``), or None."""
    extension = name.rsplit(".", 1)[-1].lower() if "." in name else ""
    if extension in IMAGE_EXTENSIONS:
        return "image"
    return extension if extension in FORMATS else None


def parse_grid(value: Any, where: str) -> tuple[int, int]:
    """``[rows, columns]`` (or ``"RxC"`` text) of a patch grid, each 1..64."""
    if isinstance(value, str):
        parts = value.lower().split("x")
        value = ([int(p) for p in parts] if len(parts) == 2 and all(p.isdigit() and len(p) < 4 for p in parts)
                 else value)
    if not (isinstance(value, list | tuple) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 64 for v in value)):
        raise _fail(where, f"grid must be [rows, columns] (or 'RxC') of 1-64 each, got {shown(value)}")
    return int(value[0]), int(value[1])


def _file(table: Mapping[str, Any], where: str) -> FileMap:
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    _unknown(table, _FILE_KEYS, where)
    glob = _get(table, "glob", str, where)
    if not glob or "\0" in glob:
        raise _fail(where, "glob (which files, e.g. '**/*.csv') is required")
    _inside(glob, "glob", where)
    fmt = _get(table, "format", str, where)
    if fmt is not None and fmt not in FORMATS:
        raise _fail(where, f"unknown format {shown(fmt)} (known: {', '.join(FORMATS)})")
    kind = fmt or format_of(glob)
    channels = table.get("channels")
    if channels is None and kind in DEFAULT_CHANNELS:
        maps = (DEFAULT_CHANNELS[kind],)
    elif not isinstance(channels, list) or not channels:
        raise _fail(where, "needs at least one [[files.channels]] table")
    else:
        maps = tuple(_channel(c, f"{where}.channels[{k}]") for k, c in enumerate(channels))
    if kind == "image" and (len(maps) != 1 or maps[0].role not in (None, "photo")):
        raise _fail(where, "an image file is one channel, of role photo")
    grid = table.get("grid")
    if grid is not None:
        if kind != "image":
            raise _fail(where, "grid (patches) applies to image files only")
        grid = parse_grid(grid, where)
    rate = _finite(table, "rate", where)
    if rate is not None and not rate > 0:
        raise _fail(where, f"rate must be positive, got {shown(table['rate'])}")
    time_unit = _get(table, "time_unit", str, where, "s")
    if time_unit not in TIME_UNITS:
        raise _fail(where, f"time_unit must be one of {', '.join(TIME_UNITS)}, got {shown(time_unit)}")
    skip = _get(table, "skip_rows", int, where, 0)
    if skip < 0:
        raise _fail(where, f"skip_rows must be >= 0, got {skip}")
    stem_pattern = _stem_pattern(_get(table, "stem_pattern", str, where), where)
    if stem_pattern is not None and table.get("suffix") is not None:
        raise _fail(where, "give suffix or stem_pattern, not both")
    delimiter = _get(table, "delimiter", str, where)
    if delimiter is not None and delimiter != "whitespace" and (len(delimiter) != 1 or delimiter in "\"\r\n"):
        raise _fail(where, f"delimiter must be one character (not a quote or line end) or 'whitespace', got "
                           f"{shown(delimiter)}")
    time_column = _get(table, "time_column", (str, int), where)
    if isinstance(time_column, int) and time_column < 0:
        raise _fail(where, f"time_column must be a name or an index >= 0, got {time_column}")
    return FileMap(glob, _get(table, "suffix", str, where), fmt, maps, delimiter,
                   bool(_get(table, "header", bool, where, True)), _get(table, "comment", str, where, "#") or None,
                   skip, rate, time_column, time_unit, _get(table, "rate_variable", str, where), grid, stem_pattern,
                   bool(_get(table, "required", bool, where, False)))


def _stem_pattern(text: str | None, where: str) -> re.Pattern[str] | None:
    """``stem_pattern``: a regular expression searched in the file name whose group ``stem`` is the stem."""
    if text is None:
        return None
    pattern = _compiled(text, "stem_pattern", where)
    if "stem" not in pattern.groupindex:
        raise _fail(where, f"stem_pattern {shown(text)} needs a (?P<stem>...) group: the part files of one "
                           "recording share")
    return pattern


def _labels(table: Any, where: str) -> dict[str, Any]:
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    _unknown(table, ("from", "depth", "csv", "key", "column", "levels", "exclude"), where)
    source = _get(table, "from", str, where, "folder")
    if source not in ("folder", "csv", "pattern"):
        raise _fail(where, f"from must be 'folder', 'csv' or 'pattern', got {shown(source)}")
    depth = _get(table, "depth", int, where, 1)
    if depth < 1:
        raise _fail(where, f"depth must be >= 1 (1 = the folder holding the file), got {depth}")
    csv_file = _get(table, "csv", str, where)
    if source == "csv" and not csv_file:
        raise _fail(where, "from = 'csv' needs csv = '<file>'")
    if csv_file:
        _inside(csv_file, "csv", where)
    levels = table.get("levels", [])
    if not isinstance(levels, list) or not all(isinstance(level, str) for level in levels):
        raise _fail(where, f"levels must be a list of column names, got {shown(levels)}")
    return {"label_from": source, "label_depth": depth, "label_csv": csv_file,
            "exclude": label_list(table.get("exclude", []), "exclude", where),
            "label_key": nfc(_get(table, "key", str, where, "recording")),
            "label_column": nfc(_get(table, "column", str, where, "label")),
            "label_levels": tuple(map(nfc, levels))}


def label_list(value: Any, key: str, where: str) -> tuple[str, ...]:
    """A list of class names (or one name) in NFC: ``[labels] exclude`` or ``--exclude-label``."""
    value = [value] if isinstance(value, str) else value
    if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
        raise _fail(where, f"{key} must be a class name or a list of class names, got {shown(value)}")
    return tuple(dict.fromkeys(nfc(v.strip()) for v in value))


def with_excluded(mapping: IngestMapping, labels: list[str]) -> IngestMapping:
    """The mapping leaving out the classes ``labels`` too (``texplorer ingest --exclude-label``)."""
    return replace(mapping, exclude=tuple(dict.fromkeys((*mapping.exclude,
                                                         *label_list(labels, "--exclude-label", "--exclude-label")))))


def _split(table: Any, where: str) -> dict[str, Any]:
    """``[split]``: where a dataset's own train/test split comes from and the names that mean each part."""
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    _unknown(table, ("from", "train", "test"), where)
    source = _get(table, "from", str, where, "folder")
    if source not in ("folder", "pattern", "none"):
        raise _fail(where, f"from must be 'folder', 'pattern' or 'none', got {shown(source)}")
    names = {}
    for part in ("train", "test"):
        value = table.get(part, list(SPLIT_NAMES[part]))
        value = [value] if isinstance(value, str) else value
        if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
            raise _fail(where, f"{part} must be a name or a list of names, got {shown(value)}")
        names[part] = tuple(nfc(v).lower() for v in value)
    if set(names["train"]) & set(names["test"]):
        both = ", ".join(sorted(set(names["train"]) & set(names["test"])))
        raise _fail(where, f"{shown(both)[1:-1]} names both parts")
    return {"split_from": source, "split_names": names}


def parse_mapping(text: str, name: str, where: str = "mapping") -> IngestMapping:
    """A mapping from TOML text; ``name`` is the default set name. Errors name the file and the key."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise _fail(where, f"not valid TOML ({shown(str(exc))[1:-1]})") from None
    except RecursionError:  # tomllib recurses per level of [[...]] or {a = {...}}
        raise _fail(where, "not valid TOML (nested more than the TOML reader can follow)") from None
    _unknown(data, ("name", "label_level", "missing", "labels", "groups", "files", "meta", "split"), where)
    set_name = _get(data, "name", str, where, name)
    if not _SET.match(set_name):
        raise _fail(where, f"name {shown(set_name)} must be 1-64 letters, digits, '.', '_' or '-'")
    files = data.get("files")
    if not isinstance(files, list) or not files:
        raise _fail(where, "needs at least one [[files]] table")
    missing = _get(data, "missing", str, where, "interpolate")
    if missing not in MISSING:
        raise _fail(where, f"missing must be one of {', '.join(MISSING)}, got {shown(missing)}")
    groups = data.get("groups", {})
    if not isinstance(groups, Mapping):
        raise _fail(where, f"groups must be a table, got {shown(groups)}")
    _unknown(groups, ("pattern",), f"{where}: groups")
    pattern_text = _get(groups, "pattern", str, f"{where}: groups")
    pattern = _compiled(pattern_text, "pattern", f"{where}: groups") if pattern_text else None
    labels = _labels(data.get("labels"), f"{where}: labels")
    if labels.get("label_from") == "pattern" and (pattern is None or "label" not in pattern.groupindex):
        raise _fail(f"{where}: labels", "from = 'pattern' needs a (?P<label>...) group in groups.pattern")
    split = _split(data.get("split"), f"{where}: split")
    if split.get("split_from") == "pattern" and (pattern is None or "split" not in pattern.groupindex):
        raise _fail(f"{where}: split", "from = 'pattern' needs a (?P<split>...) group in groups.pattern")
    meta = data.get("meta", {})
    if not isinstance(meta, Mapping):
        raise _fail(where, f"meta must be a table, got {shown(meta)}")
    reserved = sorted(set(meta) & set(RESERVED_META))
    if reserved:
        raise _fail(f"{where}: meta", f"{', '.join(reserved)} is set by the import, not the mapping")
    _check_meta(meta, f"{where}: meta")
    return IngestMapping(set_name, tuple(_file(f, f"{where}: files[{k}]") for k, f in enumerate(files)),
                         label_level=nfc(_get(data, "label_level", str, where, "label")), pattern=pattern,
                         missing=missing, meta=dict(meta), **labels, **split)


def _check_meta(value: Any, where: str, depth: int = 0) -> None:
    """``[meta]`` is stored as JSON with every recording: tables and lists at most :data:`META_DEPTH` deep
    of text, booleans, 64-bit integers, finite numbers and dates."""
    if depth > META_DEPTH:
        raise _fail(where, f"nested more than {META_DEPTH} levels")
    if isinstance(value, Mapping):
        for key, item in value.items():
            _check_meta(item, f"{where}.{shown(key)[1:-1]}", depth + 1)
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _check_meta(item, f"{where}[{k}]", depth + 1)
    elif isinstance(value, int) and not isinstance(value, bool) and not -2**63 <= value < 2**63:
        raise _fail(where, f"{shown(value)} does not fit 64 bits")
    elif isinstance(value, float) and not math.isfinite(value):
        raise _fail(where, f"{value} is not a finite number")


def default_mapping(name: str) -> IngestMapping:
    """The mapping of a plain folder of recordings: every WAV file as ``audio``, every image as ``photo``,
    labelled by the folder holding it; a ``train``/``test`` folder level is kept as the split."""
    def any_case(extension: str) -> str:  # PHOTO.JPG from cameras too
        return "**/*." + "".join(f"[{c}{c.upper()}]" for c in extension)

    return IngestMapping(name, tuple(FileMap(any_case(extension), None, kind, (DEFAULT_CHANNELS[kind],))
                                     for extension, kind in (("wav", "wav"),
                                                             *((e, "image") for e in IMAGE_EXTENSIONS))))


def with_grid(mapping: IngestMapping, grid: tuple[int, int]) -> IngestMapping:
    """The mapping with every image entry cut into a ``grid`` of patches."""
    files = tuple(replace(f, grid=grid) if (f.format or format_of(f.glob)) == "image" else f for f in mapping.files)
    return replace(mapping, files=files)


def with_label_pattern(mapping: IngestMapping, text: str) -> IngestMapping:
    """The mapping with labels from the ``label`` group of ``text`` searched in each recording's stem (its
    other named groups become group ids), for a flat folder whose file names carry the class."""
    if mapping.pattern is not None:
        raise _fail("--label-pattern", "the mapping has a groups.pattern; put the (?P<label>...) group there "
                                       "and set labels.from = 'pattern'")
    pattern = _compiled(text, "the pattern", "--label-pattern")
    if "label" not in pattern.groupindex:
        raise _fail("--label-pattern", f"{text!r} needs a (?P<label>...) group, e.g. '^(?P<label>[a-z]+)_'")
    return replace(mapping, pattern=pattern, label_from="pattern")


def load_mapping(path: str | os.PathLike[str]) -> IngestMapping:
    """Read a TOML mapping file; the set name defaults to the file's stem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read the mapping ({exc})") from None
    return parse_mapping(text, path.stem, str(path))

