"""Mapping files of an import: which files form a recording, how to read them and which column
or variable plays which channel role (the format is in ``docs/ingest.md``).
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
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


def _fail(where: str, reason: str) -> IngestError:
    return IngestError(f"{where}: {reason}")


def _get(table: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str,
         default: Any = None) -> Any:
    value = table.get(key, default)
    if value is not None and not isinstance(value, kind):
        names = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise _fail(where, f"{key} must be a {names}, got {value!r}")
    return value


def _is_column(value: Any) -> bool:
    return isinstance(value, str | int) and not isinstance(value, bool)


def _columns(value: Any, where: str) -> tuple[str | int, ...]:
    if value is None:
        return ()
    if _is_column(value):
        return (value,)
    if isinstance(value, list) and value and all(_is_column(v) for v in value):
        return tuple(value)
    raise _fail(where, f"columns must be a name, an index, a 'first:last' range or a list of them, "
                       f"got {value!r}")


def _channel(table: Mapping[str, Any], where: str) -> ChannelMap:
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    name = _get(table, "name", str, where)
    if not name or not _NAME.match(name):
        raise _fail(where, f"name {name!r} must be a MATLAB-style identifier "
                           "(a letter, then letters, digits, _)")
    role = _get(table, "role", str, where)
    if role is not None and role not in ROLES:
        raise _fail(where, f"unknown role {role!r} (known: {', '.join(sorted(ROLES))})")
    unknown = set(table) - {"name", "role", "columns", "variable", "spread", "unit", "scale"}
    if unknown:
        raise _fail(where, f"unknown key(s) {', '.join(sorted(unknown))}")
    scale = float(_get(table, "scale", (int, float), where, 1.0))
    return ChannelMap(name, role, _columns(table.get("columns"), where), _get(table, "variable", str, where),
                      bool(_get(table, "spread", bool, where, False)), _get(table, "unit", str, where, "-"),
                      scale)


_FILE_KEYS = {"glob", "suffix", "format", "channels", "delimiter", "header", "comment", "skip_rows", "rate",
              "time_column", "time_unit", "rate_variable", "grid", "stem_pattern"}

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
        value = [int(p) for p in parts] if len(parts) == 2 and all(p.isdigit() for p in parts) else value
    if not (isinstance(value, list | tuple) and len(value) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 64 for v in value)):
        raise _fail(where, f"grid must be [rows, columns] (or 'RxC') of 1-64 each, got {value!r}")
    return int(value[0]), int(value[1])


def _file(table: Mapping[str, Any], where: str) -> FileMap:
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    unknown = set(table) - _FILE_KEYS
    if unknown:
        raise _fail(where, f"unknown key(s) {', '.join(sorted(unknown))}")
    glob = _get(table, "glob", str, where)
    if not glob:
        raise _fail(where, "glob (which files, e.g. '**/*.csv') is required")
    fmt = _get(table, "format", str, where)
    if fmt is not None and fmt not in FORMATS:
        raise _fail(where, f"unknown format {fmt!r} (known: {', '.join(FORMATS)})")
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
    rate = _get(table, "rate", (int, float), where)
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise _fail(where, f"rate must be positive, got {rate!r}")
    time_unit = _get(table, "time_unit", str, where, "s")
    if time_unit not in TIME_UNITS:
        raise _fail(where, f"time_unit must be one of {', '.join(TIME_UNITS)}, got {time_unit!r}")
    skip = _get(table, "skip_rows", int, where, 0)
    if skip < 0:
        raise _fail(where, f"skip_rows must be >= 0, got {skip}")
    stem_pattern = _stem_pattern(_get(table, "stem_pattern", str, where), where)
    if stem_pattern is not None and table.get("suffix") is not None:
        raise _fail(where, "give suffix or stem_pattern, not both")
    return FileMap(glob, _get(table, "suffix", str, where), fmt, maps,
                   _get(table, "delimiter", str, where), bool(_get(table, "header", bool, where, True)),
                   _get(table, "comment", str, where, "#") or None, skip,
                   None if rate is None else float(rate), _get(table, "time_column", (str, int), where),
                   time_unit, _get(table, "rate_variable", str, where), grid, stem_pattern)


def _stem_pattern(text: str | None, where: str) -> re.Pattern[str] | None:
    """``stem_pattern``: a regular expression searched in the file name whose group ``stem`` is the stem."""
    if text is None:
        return None
    try:
        pattern = re.compile(text)
    except re.error as exc:
        raise _fail(where, f"stem_pattern is not a regular expression ({exc})") from None
    if "stem" not in pattern.groupindex:
        raise _fail(where, f"stem_pattern {text!r} needs a (?P<stem>...) group: the part files of one "
                           "recording share")
    return pattern


def _labels(table: Any, where: str) -> dict[str, Any]:
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    source = _get(table, "from", str, where, "folder")
    if source not in ("folder", "csv", "pattern"):
        raise _fail(where, f"from must be 'folder', 'csv' or 'pattern', got {source!r}")
    depth = _get(table, "depth", int, where, 1)
    if depth < 1:
        raise _fail(where, f"depth must be >= 1 (1 = the folder holding the file), got {depth}")
    csv_file = _get(table, "csv", str, where)
    if source == "csv" and not csv_file:
        raise _fail(where, "from = 'csv' needs csv = '<file>'")
    levels = table.get("levels", [])
    if not isinstance(levels, list) or not all(isinstance(level, str) for level in levels):
        raise _fail(where, f"levels must be a list of column names, got {levels!r}")
    return {"label_from": source, "label_depth": depth, "label_csv": csv_file,
            "label_key": _get(table, "key", str, where, "recording"),
            "label_column": _get(table, "column", str, where, "label"), "label_levels": tuple(levels)}


def _split(table: Any, where: str) -> dict[str, Any]:
    """``[split]``: where a dataset's own train/test split comes from and the names that mean each part."""
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise _fail(where, "must be a table")
    unknown = set(table) - {"from", "train", "test"}
    if unknown:
        raise _fail(where, f"unknown key(s) {', '.join(sorted(unknown))}")
    source = _get(table, "from", str, where, "folder")
    if source not in ("folder", "pattern", "none"):
        raise _fail(where, f"from must be 'folder', 'pattern' or 'none', got {source!r}")
    names = {}
    for part in ("train", "test"):
        value = table.get(part, list(SPLIT_NAMES[part]))
        value = [value] if isinstance(value, str) else value
        if not isinstance(value, list) or not value or not all(isinstance(v, str) and v for v in value):
            raise _fail(where, f"{part} must be a name or a list of names, got {value!r}")
        names[part] = tuple(v.lower() for v in value)
    if set(names["train"]) & set(names["test"]):
        raise _fail(where, f"{', '.join(sorted(set(names['train']) & set(names['test'])))} names both parts")
    return {"split_from": source, "split_names": names}


def parse_mapping(text: str, name: str, where: str = "mapping") -> IngestMapping:
    """A mapping from TOML text; ``name`` is the default set name. Errors name the file and the key."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise _fail(where, f"not valid TOML ({exc})") from None
    unknown = set(data) - {"name", "label_level", "missing", "labels", "groups", "files", "meta", "split"}
    if unknown:
        raise _fail(where, f"unknown key(s) {', '.join(sorted(unknown))}")
    set_name = _get(data, "name", str, where, name)
    if not _SET.match(set_name):
        raise _fail(where, f"name {set_name!r} must be 1-64 letters, digits, '.', '_' or '-'")
    files = data.get("files")
    if not isinstance(files, list) or not files:
        raise _fail(where, "needs at least one [[files]] table")
    missing = _get(data, "missing", str, where, "interpolate")
    if missing not in MISSING:
        raise _fail(where, f"missing must be one of {', '.join(MISSING)}, got {missing!r}")
    groups = data.get("groups", {})
    pattern_text = _get(groups, "pattern", str, f"{where}: groups") if isinstance(groups, Mapping) else None
    try:
        pattern = re.compile(pattern_text) if pattern_text else None
    except re.error as exc:
        raise _fail(f"{where}: groups", f"pattern is not a regular expression ({exc})") from None
    labels = _labels(data.get("labels"), f"{where}: labels")
    if labels.get("label_from") == "pattern" and (pattern is None or "label" not in pattern.groupindex):
        raise _fail(f"{where}: labels", "from = 'pattern' needs a (?P<label>...) group in groups.pattern")
    split = _split(data.get("split"), f"{where}: split")
    if split.get("split_from") == "pattern" and (pattern is None or "split" not in pattern.groupindex):
        raise _fail(f"{where}: split", "from = 'pattern' needs a (?P<split>...) group in groups.pattern")
    meta = data.get("meta", {})
    if not isinstance(meta, Mapping):
        raise _fail(where, "meta must be a table")
    return IngestMapping(set_name, tuple(_file(f, f"{where}: files[{k}]") for k, f in enumerate(files)),
                         label_level=_get(data, "label_level", str, where, "label"), pattern=pattern,
                         missing=missing, meta=dict(meta), **labels, **split)


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
    try:
        pattern = re.compile(text)
    except re.error as exc:
        raise _fail("--label-pattern", f"not a regular expression ({exc})") from None
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

