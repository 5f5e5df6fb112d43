"""Import of other labs' recordings (docs/ingest.md): files + a TOML mapping -> Recordings.

A small TOML mapping file says which files belong together, how to read them and which column or variable
plays which channel role; :func:`ingest` applies it to a folder and returns the :class:`scanner.Recording`
objects and a report of every file it could not use (a bad file is named and skipped, the import goes on).
The mapping format, with an example, is in ``docs/ingest.md``.

Formats: CSV/TSV (header or not, trailing delimiters, ``nan``/``-nan``/empty tokens, a timestamp column
from which the rate is derived or a given rate, comment lines), WAV, NPY, NPZ and MATLAB v5 ``.mat``. A
recording may span several files sharing a stem (one file per sensor topic at different rates); a channel
may be spread over several columns of one row as consecutive samples (22 vibration samples per 100 Hz row
-> one 2200 Hz channel). Labels come from folder names, a label CSV or the file-name pattern; group ids
(object, trial, motion, ...) from the named groups of a file-name pattern.

Imported recordings are stored in a database folder as ``recordings/<set>/<recording>.mat`` (MATLAB v5,
one variable per channel plus a ``meta`` struct), written to a temporary folder first and renamed into
place, so a set is either complete or absent; :func:`load_recordings` reads a set back.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import os
import re
import secrets
import shutil
import tomllib
import zipfile
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import scipy.io
from scipy.io import wavfile

from scanner.photo import PhotoError, check_pixels, image_size, max_file_bytes
from scanner.scan import ROLES, Recording, ScanError, Trace
from scanner.storage.files import atomic_write_bytes, fsync_dir
from scanner.storage.mat5 import MatFileError, read_mat
from taxonomy.errors import TexplorerError

RECORDINGS = "recordings"
"""Folder of imported recording sets inside a database."""

FORMATS = ("csv", "tsv", "wav", "npy", "npz", "mat", "image")
IMAGE_EXTENSIONS = ("png", "jpg", "jpeg", "bmp", "tif", "tiff")
"""Extensions read as ``format = "image"`` (an RGB photo, OpenCV's decoders)."""
NAN_TOKENS = ("nan", "-nan", "+nan", "", "na", "n/a", "null", "none")
"""Tokens read as a missing sample (case-insensitive, surrounding spaces ignored)."""

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
MISSING = ("interpolate", "error")
MAX_ARRAY_BYTES = 1 << 30
"""An NPY, NPZ or MAT file may hold at most this many bytes of arrays (once inflated): checked before
they are read, so a small file cannot make an import take unbounded memory."""
RATE_TOLERANCE = 0.05
"""Time steps may vary by this fraction of their median before the import notes it."""

GAP_STEPS = 1.5
"""A time step longer than this many sample periods is a gap: at least one sample is missing."""

SPLIT_NAMES = {"train": ("train", "training"), "test": ("test", "testing")}
"""Folder names (or pattern values) of a dataset's own train/test split, compared case-insensitively."""

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")
_SET = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")


class IngestError(TexplorerError, ValueError):
    """A mapping file or a data file that cannot be used; the message names it and the reason."""


# -- the mapping -------------------------------------------------------------------------------------

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
    """A kind of file: which files (``glob``), the part of the name after the recording stem (``suffix``),
    how to read them and the channels they hold."""

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
              "time_column", "time_unit", "rate_variable", "grid"}

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
    return FileMap(glob, _get(table, "suffix", str, where), fmt, maps,
                   _get(table, "delimiter", str, where), bool(_get(table, "header", bool, where, True)),
                   _get(table, "comment", str, where, "#") or None, skip,
                   None if rate is None else float(rate), _get(table, "time_column", (str, int), where),
                   time_unit, _get(table, "rate_variable", str, where), grid)


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


def load_mapping(path: str | os.PathLike[str]) -> IngestMapping:
    """Read a TOML mapping file; the set name defaults to the file's stem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read the mapping ({exc})") from None
    return parse_mapping(text, path.stem, str(path))


# -- reading files -----------------------------------------------------------------------------------

def _number(token: str, where: str) -> float:
    text = token.strip()
    if text.lower() in NAN_TOKENS:
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise IngestError(f"{where}: {token!r} is not a number") from None


def _split_lines(text: str, delimiter: str | None, comment: str | None) -> list[tuple[int, list[str]]]:
    rows = []
    lines = text.splitlines()
    reader: Iterable[list[str]]
    if delimiter == "whitespace":
        reader = (line.split() for line in lines)
    else:
        reader = csv.reader(lines, delimiter=delimiter or ",")
    for number, row in enumerate(reader, start=1):
        if not row or all(not cell.strip() for cell in row):
            continue
        if comment and row[0].lstrip().startswith(comment):
            continue
        rows.append((number, row))
    return rows


def read_table(path: Path, delimiter: str | None, header: bool, comment: str | None = "#",
               skip_rows: int = 0) -> tuple[list[str], np.ndarray]:
    """Column names and values (rows, columns, NaN for missing tokens) of a CSV/TSV file.

    Trailing delimiters (an empty last field on every line) are dropped; a row with a different number of
    fields than the header is an error naming the line.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read ({exc})") from None
    rows = _split_lines(text, delimiter, comment)[skip_rows:]
    if not rows:
        raise IngestError(f"{path}: no data")
    names: list[str]
    if header:
        names = [cell.strip() for cell in rows[0][1]]
        rows = rows[1:]
        while names and not names[-1]:
            names.pop()
    else:
        # Without a header an empty last field can only be read as a trailing delimiter.
        names = [str(k) for k in range(len(_trimmed(rows[0][1], 0)))]
    if not rows:
        raise IngestError(f"{path}: a header but no data rows")
    values = np.empty((len(rows), len(names)))
    for r, (line, cells) in enumerate(rows):
        cells = _trimmed(cells, len(names))
        if len(cells) != len(names):
            raise IngestError(f"{path}: line {line}: {len(cells)} fields, expected {len(names)}")
        values[r] = [_number(cell, f"{path}: line {line}, column {names[c]}") for c, cell in enumerate(cells)]
    return names, values


def _trimmed(cells: list[str], width: int) -> list[str]:
    """Drop empty fields left by trailing delimiters beyond ``width``."""
    while len(cells) > width and not cells[-1].strip():
        cells = cells[:-1]
    return cells


def _select(names: Sequence[str], spec: Sequence[str | int], path: Path, channel: str) -> list[int]:
    """Column indices of a channel: names, 0-based indices, or inclusive ``first:last`` ranges of names."""
    index = {name: k for k, name in enumerate(names)}
    picked: list[int] = []
    for item in spec:
        if isinstance(item, int):
            if not 0 <= item < len(names):
                raise IngestError(f"{path}: channel {channel}: column index {item} is outside "
                                  f"0..{len(names) - 1}")
            picked.append(item)
        elif ":" in item and item not in index:
            first, last = (part.strip() for part in item.split(":", 1))
            if first not in index or last not in index or index[first] > index[last]:
                raise IngestError(f"{path}: channel {channel}: column range {item!r} "
                                  "does not match the header")
            picked.extend(range(index[first], index[last] + 1))
        elif item in index:
            picked.append(index[item])
        else:
            shown = ", ".join(names[:12]) + (" ..." if len(names) > 12 else "")
            raise IngestError(f"{path}: channel {channel}: no column {item!r} (columns: {shown})")
    return picked


@dataclass(frozen=True)
class Note:
    """Something the import did to one file's data, kept so that many alike can be summarised.

    ``kind`` groups alike notes (``missing``, ``irregular``, ``gap``), ``amount`` ranks them (the worst
    first), ``text`` is the full line.
    """

    kind: str
    file: str
    amount: float
    text: str

    def __str__(self) -> str:
        return self.text


NOTE_KINDS = {"missing": "missing samples interpolated", "irregular": "irregular time steps resampled",
              "gap": "gaps in the timestamps bridged", "aligned": "streams cut to their common time span"}


def summarise_notes(notes: Sequence[Note], first: int = 3) -> list[str]:
    """One line per kind of note: how many files, the worst case and the first few names."""
    lines = []
    for kind in dict.fromkeys(note.kind for note in notes):
        alike = [note for note in notes if note.kind == kind]
        files = list(dict.fromkeys(note.file for note in alike))
        worst = max(alike, key=lambda note: note.amount)
        shown = ", ".join(files[:first]) + (f" and {len(files) - first} more" if len(files) > first else "")
        lines.append(f"{NOTE_KINDS.get(kind, kind)} in {len(files)} file(s) ({shown}); worst: {worst.text}")
    return lines


def seconds_of(times: np.ndarray, unit: str, path: Path) -> np.ndarray:
    """A timestamp column in seconds; IngestError unless it has two finite values and increases."""
    t = np.asarray(times, dtype=np.float64) * TIME_UNITS[unit]
    if t.size < 2 or not np.all(np.isfinite(t)):
        raise IngestError(f"{path}: the time column needs at least two finite timestamps")
    steps = np.diff(t)
    if np.any(steps <= 0):
        row = int(np.flatnonzero(steps <= 0)[0]) + 2
        raise IngestError(f"{path}: the time column does not increase at data row {row}")
    return t


def rate_from_times(times: np.ndarray, unit: str, path: Path) -> tuple[float, str | None]:
    """Sample rate from a timestamp column: 1 / median step, and a note if steps vary by > 5 %."""
    steps = np.diff(seconds_of(times, unit, path))
    step = float(np.median(steps))
    spread = float(np.max(np.abs(steps - step)) / step)
    note = f"{path.name}: time steps vary by up to {100 * spread:.0f} %" if spread > RATE_TOLERANCE else None
    return 1.0 / step, note


def _fill(values: np.ndarray, missing: str, where: str) -> tuple[np.ndarray, int]:
    """Missing samples filled by linear interpolation along the samples (the ends by the nearest value)."""
    bad = ~np.isfinite(values)
    count = int(bad.sum())
    if not count:
        return values, 0
    if missing == "error":
        raise IngestError(f"{where}: {count} missing sample(s)")
    flat = values.reshape(values.shape[0], -1).copy()
    samples = np.arange(flat.shape[0])
    for column in range(flat.shape[1]):
        good = np.isfinite(flat[:, column])
        if not good.any():
            raise IngestError(f"{where}: every sample of a column is missing")
        flat[:, column] = np.interp(samples, samples[good], flat[good, column])
    return flat.reshape(values.shape), count


@dataclass
class _Read:
    """What one file contributes: channels (raw arrays, rates and, from a time column, each sample's time
    in seconds) and images."""

    arrays: dict[str, tuple[np.ndarray, float, ChannelMap, np.ndarray | None]] = field(default_factory=dict)
    images: dict[str, np.ndarray] = field(default_factory=dict)


def _table_file(path: Path, spec: FileMap, fmt: str) -> _Read:
    delimiter = spec.delimiter or ("\t" if fmt == "tsv" else ",")
    names, values = read_table(path, delimiter, spec.header, spec.comment, spec.skip_rows)
    read = _Read()
    times = None
    if spec.time_column is not None:
        times = seconds_of(values[:, _select(names, [spec.time_column], path, "time")[0]], spec.time_unit, path)
        rate = spec.rate or 1.0 / float(np.median(np.diff(times)))
    elif spec.rate is not None:
        rate = spec.rate
    else:
        raise IngestError(f"{path}: give the file's rate or a time_column in the mapping")
    for channel in spec.channels:
        if not channel.columns:
            raise IngestError(f"{path}: channel {channel.name} needs columns")
        data = values[:, _select(names, channel.columns, path, channel.name)]
        if channel.spread:
            # The k-th of c samples in a row was taken k / (c rate) after the row's timestamp.
            spread = None if times is None else (times[:, None] + np.arange(data.shape[1]) / (rate * data.shape[1]))
            read.arrays[channel.name] = (data.reshape(-1), rate * data.shape[1], channel,
                                         None if spread is None else spread.reshape(-1))
        else:
            read.arrays[channel.name] = (data[:, 0] if data.shape[1] == 1 else data, rate, channel, times)
    return read


def _wav_file(path: Path, spec: FileMap) -> _Read:
    try:
        rate, data = wavfile.read(path)
    except (OSError, ValueError) as exc:
        raise IngestError(f"{path}: not a readable WAV file ({exc})") from None
    if data.dtype.kind in "iu":
        info = np.iinfo(data.dtype)
        data = (data.astype(np.float64) - (info.max + 1 + info.min) / 2) / ((info.max - info.min + 1) / 2)
    data = np.asarray(data, dtype=np.float64)
    data = data[:, None] if data.ndim == 1 else data
    read = _Read()
    for channel in spec.channels:
        picked = list(channel.columns) or list(range(data.shape[1]))
        if not all(isinstance(k, int) and 0 <= k < data.shape[1] for k in picked):
            raise IngestError(f"{path}: channel {channel.name}: audio channels {picked} are not in "
                              f"0..{data.shape[1] - 1}")
        part = data[:, picked]
        read.arrays[channel.name] = (part[:, 0] if part.shape[1] == 1 else part, float(rate), channel, None)
    return read


def _check_sizes(path: Path, fmt: str) -> None:
    """Refuse, from headers alone, an array file whose data would take more than :data:`MAX_ARRAY_BYTES`.

    A few bytes of NPY header or a zip directory can announce terabytes; numpy would allocate them first.
    """
    if fmt == "npy":
        with open(path, "rb") as handle:
            version = np.lib.format.read_magic(handle)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _, dtype = read(handle)
        size = math.prod(shape) * dtype.itemsize
    else:
        with zipfile.ZipFile(path) as archive:
            size = sum(info.file_size for info in archive.infolist())
    if size > MAX_ARRAY_BYTES:
        raise IngestError(f"{path}: its arrays take {size / 1e6:.0f} MB, more than the "
                          f"{MAX_ARRAY_BYTES / 1e6:.0f} MB one file may hold")


def _variables(path: Path, fmt: str) -> dict[str, np.ndarray]:
    try:
        if fmt == "mat":
            variables = read_mat(path, MAX_ARRAY_BYTES, squeeze_me=False)
            return {k: v for k, v in variables.items() if not k.startswith("__")}
        _check_sizes(path, fmt)
        if fmt == "npy":
            return {"": np.load(path, allow_pickle=False)}
        with np.load(path, allow_pickle=False) as archive:
            return {key: archive[key] for key in archive.files}
    except IngestError:
        raise
    except MatFileError as exc:
        if "7.3" in str(exc):
            raise IngestError(f"{path}: MATLAB v7.3 (HDF5) files are not read; save with -v7") from None
        raise IngestError(f"{path}: not a readable MAT file ({exc})") from None
    except Exception as exc:  # numpy raises many types for foreign or damaged files
        reason = f"{type(exc).__name__}: {exc}"
        raise IngestError(f"{path}: not a readable {fmt.upper()} file ({reason})") from None


def _array_file(path: Path, spec: FileMap, fmt: str) -> _Read:
    variables = _variables(path, fmt)
    rate = spec.rate
    if spec.rate_variable is not None:
        if spec.rate_variable not in variables or np.asarray(variables[spec.rate_variable]).size != 1:
            raise IngestError(f"{path}: no scalar rate variable {spec.rate_variable!r}")
        rate = float(np.asarray(variables[spec.rate_variable]).ravel()[0])
    if rate is None or not rate > 0:
        raise IngestError(f"{path}: give the rate or a rate_variable in the mapping")
    read = _Read()
    for channel in spec.channels:
        key = "" if fmt == "npy" else (channel.variable or channel.name)
        if key not in variables:
            raise IngestError(f"{path}: no variable {key!r} for channel {channel.name} "
                              f"(variables: {', '.join(sorted(variables)) or 'none'})")
        data = np.asarray(variables[key])
        if data.dtype.kind not in "fiub":
            raise IngestError(f"{path}: variable {key or 'array'} is {data.dtype}, not numeric")
        data = data.astype(np.float64)
        if fmt == "mat" and data.ndim == 2 and 1 in data.shape:
            data = data.reshape(-1)  # MATLAB stores vectors as n x 1 or 1 x n
        if channel.columns:
            columns = channel.columns
            if data.ndim != 2 or not all(isinstance(k, int) and 0 <= k < data.shape[1] for k in columns):
                raise IngestError(f"{path}: channel {channel.name}: columns {list(columns)} do not index "
                                  f"the columns of an array of shape {data.shape}")
            data = data[:, list(columns)]
        if channel.spread:
            read.arrays[channel.name] = (data.reshape(-1), rate * int(np.prod(data.shape[1:])), channel, None)
        else:
            read.arrays[channel.name] = (data, rate, channel, None)
    return read


def read_image(path: Path) -> np.ndarray:
    """An image file (PNG, JPEG, BMP, TIFF) as RGB uint8 (h, w, 3).

    Gray images are repeated into three channels, an alpha channel is dropped, 16-bit images are scaled to
    8 bits (``round(v / 257)``); a header announcing more pixels than the photo limit of
    :mod:`scanner.photo` is refused before decoding, and so is any other kind of file. A multi-page TIFF
    gives its first page (the one whose size its first directory gives).
    """
    try:
        if path.stat().st_size > max_file_bytes(bytes_per_pixel=8):
            raise PhotoError("the file is larger than an image within the pixel limit can be")
        data = path.read_bytes()
        if image_size(data) is None:
            raise PhotoError("not a PNG, JPEG, BMP or TIFF file")
        check_pixels(data, name=path.name)
    except (OSError, PhotoError) as exc:
        raise IngestError(f"{path}: cannot read the image ({exc})") from None
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None or image.size == 0:
        raise IngestError(f"{path}: not a readable image file")
    if image.dtype == np.uint16:
        image = np.rint(image / 257.0).astype(np.uint8)
    elif image.dtype != np.uint8:
        raise IngestError(f"{path}: {image.dtype} pixels are not read; save the image with 8 or 16 bits")
    if image.ndim == 2 or image.shape[2] == 1:
        return np.repeat(image.reshape(image.shape[0], image.shape[1], 1), 3, axis=2)
    return cv2.cvtColor(image, cv2.COLOR_BGRA2RGB if image.shape[2] == 4 else cv2.COLOR_BGR2RGB)


def _image_file(path: Path, spec: FileMap) -> _Read:
    read = _Read()
    read.images[spec.channels[0].name] = read_image(path)
    return read


def file_format(path: Path, spec: FileMap) -> str:
    """The file's format: the mapping's ``format``, else its extension."""
    fmt = spec.format or format_of(path.name)
    if fmt not in FORMATS:
        raise IngestError(f"{path}: unknown format {path.suffix.lstrip('.')!r}; "
                          f"give format = one of {', '.join(FORMATS)}")
    return fmt


@dataclass(frozen=True)
class Stream:
    """One channel as read: samples (scaled, missing ones filled), rate, unit and, from a time column,
    the time of every sample in seconds."""

    data: np.ndarray
    rate: float
    unit: str
    times: np.ndarray | None = None


def read_streams(path: Path, spec: FileMap,
                 missing: str = "interpolate") -> tuple[dict[str, Stream], dict[str, np.ndarray], list[Note]]:
    """The channels and images of one file, and notes on what was done to them."""
    fmt = file_format(path, spec)
    readers: dict[str, Callable[[], _Read]] = {
        "csv": lambda: _table_file(path, spec, fmt), "tsv": lambda: _table_file(path, spec, fmt),
        "wav": lambda: _wav_file(path, spec), "image": lambda: _image_file(path, spec)}
    read = readers.get(fmt, lambda: _array_file(path, spec, fmt))()
    streams, notes = {}, []
    for name, (data, rate, channel, times) in read.arrays.items():
        data, filled = _fill(data * channel.scale, missing, f"{path}: channel {name}")
        if filled:
            notes.append(Note("missing", path.name, filled, f"{path.name}: channel {name}: {filled} missing "
                              "sample(s) interpolated"))
        streams[name] = Stream(data, rate, channel.unit, times)
    return streams, read.images, notes


def read_file(path: Path, spec: FileMap, missing: str = "interpolate") -> tuple[dict[str, Trace], list[str]]:
    """The channels of one file as traces (scaled, missing samples filled, timestamps only setting the
    rate), and notes on what was done; :func:`align` puts timestamped streams on a common time base."""
    streams, _, notes = read_streams(path, spec, missing)
    traces = {}
    for name, stream in streams.items():
        try:
            traces[name] = Trace(stream.data, stream.rate, stream.unit)
        except ScanError as exc:
            raise IngestError(f"{path}: channel {name}: {exc}") from None
    return traces, [str(note) for note in notes]


# -- a common time base ------------------------------------------------------------------------------

def _on_grid(times: np.ndarray, grid: np.ndarray, step: float) -> int | None:
    """The index of the sample at ``grid[0]`` if the samples from there lie on the grid, else None."""
    first = int(np.searchsorted(times, grid[0] - 1e-6 * step))
    chosen = times[first:first + grid.size]
    if chosen.size == grid.size and np.all(np.abs(chosen - grid) <= 1e-6 * step):
        return first
    return None


def _interpolated(stream: Stream, grid: np.ndarray) -> np.ndarray:
    """The stream's values at the grid times, linear between samples (each column on its own)."""
    assert stream.times is not None
    flat = stream.data.reshape(stream.data.shape[0], -1)
    columns = [np.interp(grid, stream.times, flat[:, k]) for k in range(flat.shape[1])]
    return np.stack(columns, axis=1).reshape((grid.size, *stream.data.shape[1:]))


def gaps(times: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Start times and lengths (s) of the gaps in a timestamp column: steps longer than 1.5 periods."""
    steps = np.diff(times)
    where = np.flatnonzero(steps > GAP_STEPS * step)
    return times[where], steps[where]


@dataclass(frozen=True)
class Aligned:
    """Streams on a common time base: traces, notes and what was done (``meta["time_base"]``)."""

    traces: dict[str, Trace]
    notes: list[Note]
    info: dict[str, Any]


def align(streams: Mapping[str, Stream], files: Mapping[str, str], missing: str = "interpolate") -> Aligned:
    """Put the timestamped streams of one recording on a common time base.

    A sample stands for the period from its time to the next one, so a stream covers ``[first time, last
    time + 1 / rate)``. Every stream with timestamps is cut to the span all of them cover and sampled on
    its own grid ``t0 + k / rate`` from the common start ``t0``: sample
    k of every stream then means the same moment. A stream whose samples already lie on that grid (to
    1e-6 of a period) is taken as it is; otherwise it is resampled by linear interpolation, with a note.
    A step longer than 1.5 periods is a gap: the grid samples inside it are bridged by the interpolation
    and reported (``missing = "interpolate"``) or the recording is refused (``missing = "error"``), never
    filled silently. Streams without timestamps are taken as they are. ``files`` names each stream's file.
    """
    timed = {name: s for name, s in streams.items() if s.times is not None}
    traces: dict[str, Trace] = {}
    notes: list[Note] = []
    info: dict[str, Any] = {}
    if timed:
        start = max(float(s.times[0]) for s in timed.values())
        stop = min(float(s.times[-1]) + 1.0 / s.rate for s in timed.values())
        if stop <= start:
            spans = ", ".join(f"{n} {s.times[0]:.6g}-{s.times[-1]:.6g} s" for n, s in timed.items())
            raise IngestError(f"the timestamped streams do not overlap in time ({spans})")
        info = {"start_s": start, "seconds": stop - start, "channels": {}}
    for name, stream in streams.items():
        data = stream.data
        if stream.times is not None:
            data, channel_notes, channel_info = _on_common_grid(name, stream, start, stop, files[name], missing)
            notes += channel_notes
            info["channels"][name] = channel_info
        try:
            traces[name] = Trace(data, stream.rate, stream.unit)
        except ScanError as exc:
            raise IngestError(f"{files[name]}: channel {name}: {exc}") from None
    if len(timed) > 1:
        cut = [n for n, s in timed.items() if s.times[0] < start - 0.5 / s.rate or s.times[-1] > stop - 0.5 / s.rate]
        if cut:
            notes.append(Note("aligned", files[cut[0]], len(cut), f"{files[cut[0]]}: channel(s) {', '.join(cut)} "
                              f"cut to the span {start:.6g}-{stop:.6g} s that {', '.join(timed)} share"))
    return Aligned(traces, notes, info)


def _on_common_grid(name: str, stream: Stream, start: float, stop: float, file: str,
                    missing: str) -> tuple[np.ndarray, list[Note], dict[str, Any]]:
    assert stream.times is not None
    step = 1.0 / stream.rate
    count = max(1, int(math.floor((stop - start) * stream.rate + 1e-6)))
    grid = start + np.arange(count) * step
    notes = []
    gap_start, gap_length = gaps(stream.times, step)
    inside = (gap_start >= start - step) & (gap_start < stop)
    gap_start, gap_length = gap_start[inside], gap_length[inside]
    bridged = int(sum(np.count_nonzero((grid > t + 0.5 * step) & (grid < t + length - 0.5 * step))
                      for t, length in zip(gap_start, gap_length, strict=True)))
    if gap_start.size:
        longest = int(np.argmax(gap_length))
        text = (f"{file}: channel {name}: {gap_start.size} gap(s) in the timestamps, {bridged} sample(s) "
                f"missing; the longest {gap_length[longest]:.4g} s at t = {gap_start[longest]:.6g} s")
        if missing == "error":
            raise IngestError(text)
        notes.append(Note("gap", file, float(gap_length[longest]), text + " (bridged linearly)"))
    first = None if gap_start.size else _on_grid(stream.times, grid, step)
    if first is not None:
        data = stream.data[first:first + count]
    else:
        data = _interpolated(stream, grid)
        steps = np.diff(stream.times)
        regular = steps[steps <= GAP_STEPS * step]
        spread = float(np.max(np.abs(regular - step)) / step) if regular.size else 0.0
        if spread > RATE_TOLERANCE:
            notes.append(Note("irregular", file, spread, f"{file}: channel {name}: time steps vary by up to "
                              f"{100 * spread:.0f} %; resampled to {stream.rate:.6g} Hz"))
    info = {"resampled": first is None, "gaps": int(gap_start.size), "bridged_samples": bridged,
            "longest_gap_s": float(gap_length.max()) if gap_length.size else 0.0}
    return data, notes, info


# -- recordings --------------------------------------------------------------------------------------

@dataclass
class IngestReport:
    """The recordings made and the problems met: ``skipped`` holds one line per bad file or recording,
    ``notes`` what was done to usable data (:func:`summarise_notes` condenses them)."""

    recordings: list[Recording] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    notes: list[Note] = field(default_factory=list)
    files: int = 0


def stem_of(path: Path, spec: FileMap) -> str:
    """The recording stem of a file: its name without ``suffix`` (default: without the extension)."""
    if spec.suffix is not None:
        return path.name[:-len(spec.suffix)] if spec.suffix and path.name.endswith(spec.suffix) else path.name
    return path.stem


def _matched(root: Path, mapping: IngestMapping) -> dict[Path, list[tuple[Path, FileMap]]]:
    """Files of every [[files]] entry, grouped by recording key: the folder plus the stem."""
    groups: dict[Path, list[tuple[Path, FileMap]]] = {}
    for spec in mapping.files:
        for path in sorted(p for p in root.glob(spec.glob) if p.is_file()):
            if spec.suffix and not path.name.endswith(spec.suffix):
                continue
            groups.setdefault(path.parent / stem_of(path, spec), []).append((path, spec))
    return groups


def recording_names(keys: Sequence[Path], root: Path) -> dict[Path, str]:
    """A distinct, stable name for every recording key (folder + stem), derived from its path.

    The stem where no other recording has it; otherwise the folders below ``root`` and the stem joined by
    ``_`` (``train/cork/r01`` -> ``train_cork_r01``); a name still shared, or longer than 64 characters,
    ends in 8 hex digits of the SHA-256 of the relative path.
    """
    stems: dict[str, int] = {}
    for key in keys:
        stems[safe_name(key.name)] = stems.get(safe_name(key.name), 0) + 1
    names = {}
    for key in keys:
        relative = key.relative_to(root)
        long = re.sub(r"[^A-Za-z0-9._-]", "_", "_".join(relative.parts)).lstrip("._-") or "recording"
        names[key] = safe_name(key.name) if stems[safe_name(key.name)] == 1 else long
    shared: dict[str, int] = {}
    for name in names.values():
        shared[name] = shared.get(name, 0) + 1
    for key, name in names.items():
        if shared[name] > 1 or len(name) > 64:
            digest = hashlib.sha256(key.relative_to(root).as_posix().encode()).hexdigest()[:8]
            names[key] = f"{name[:55]}-{digest}"
    return names


def _label_table(root: Path, mapping: IngestMapping) -> dict[str, dict[str, str]]:
    if mapping.label_from != "csv" or mapping.label_csv is None:
        return {}
    path = Path(mapping.label_csv)
    path = path if path.is_absolute() else root / path
    try:
        rows = list(csv.DictReader(io.StringIO(path.read_text(encoding="utf-8-sig"))))
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read the label table ({exc})") from None
    needed = [mapping.label_key, mapping.label_column, *mapping.label_levels]
    missing = [c for c in needed if rows and c not in rows[0]]
    if not rows or missing:
        raise IngestError(f"{path}: the label table needs the column(s) {', '.join(missing or needed)}")
    return {row[mapping.label_key].strip(): {k: (v or "").strip() for k, v in row.items() if k}
            for row in rows}


def _label(key: Path, root: Path, mapping: IngestMapping, table: Mapping[str, Mapping[str, str]],
           groups: Mapping[str, str]) -> tuple[str, dict[str, str]]:
    """The label and coarser levels of a recording; an IngestError if there is none."""
    if mapping.label_from == "pattern":
        return groups["label"], {}
    if mapping.label_from == "csv":
        row = table.get(key.name)
        if row is None or not row.get(mapping.label_column):
            raise IngestError(f"no label for {key.name!r} in {mapping.label_csv}")
        return row[mapping.label_column], {level: row[level] for level in mapping.label_levels}
    relative = key.relative_to(root).parts[:-1]
    if len(relative) < mapping.label_depth:
        raise IngestError(f"{key.name}: no folder {mapping.label_depth} level(s) up to take the label from")
    return relative[-mapping.label_depth], {}


def _split_part(value: str, mapping: IngestMapping) -> str | None:
    lowered = value.lower()
    return next((part for part, names in mapping.split_names.items() if lowered in names), None)


def split_of(key: Path, root: Path, mapping: IngestMapping, groups: Mapping[str, str]) -> str | None:
    """``train`` or ``test`` from a folder of the recording's path or the pattern's ``split`` group; None
    if the mapping has no split (or, by default, no folder names one). IngestError if the mapping asks for a
    split the recording does not have."""
    if mapping.split_from == "none":
        return None
    if mapping.split_from == "pattern":
        value = groups.get("split", "")
        part = _split_part(value, mapping)
        if part is None:
            names = mapping.split_names
            raise IngestError(f"{key.name}: split {value!r} is neither train ({', '.join(names['train'])}) "
                              f"nor test ({', '.join(names['test'])})")
        return part
    parts = [p for p in (_split_part(folder, mapping) for folder in key.relative_to(root).parts[:-1]) if p]
    if len(set(parts)) > 1:
        raise IngestError(f"{key.relative_to(root)}: folders name both a training and a test part")
    if not parts and mapping.split_from == "folder":
        raise IngestError(f"{key.relative_to(root)}: no train or test folder in the path")
    return parts[0] if parts else None


def safe_name(text: str) -> str:
    """A recording name usable as a file name: other characters become '_' (1-64 characters)."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", text).lstrip("._-")[:64]
    return name or "recording"


def patches(image: np.ndarray, grid: tuple[int, int]) -> list[tuple[int, int, np.ndarray]]:
    """``(row, column, patch)`` of a rows x columns grid of equal patches, centred: the image's last
    ``h mod rows`` rows and ``w mod columns`` columns are split between the two sides and left out."""
    rows, columns = grid
    h, w = image.shape[:2]
    ph, pw = h // rows, w // columns
    if ph < 1 or pw < 1:
        raise IngestError(f"an image of {w}x{h} px cannot be cut into {rows}x{columns} patches")
    top, left = (h - rows * ph) // 2, (w - columns * pw) // 2
    return [(r, c, image[top + r * ph:top + (r + 1) * ph, left + c * pw:left + (c + 1) * pw])
            for r in range(rows) for c in range(columns)]


@dataclass(frozen=True)
class _Parts:
    """Everything read for one recording key."""

    streams: dict[str, Stream]
    images: dict[str, np.ndarray]
    roles: dict[str, str]
    files: dict[str, str]
    grid: tuple[int, int] | None


def _read_parts(key: Path, files: list[tuple[Path, FileMap]], root: Path, mapping: IngestMapping,
                report: IngestReport) -> _Parts | None:
    streams: dict[str, Stream] = {}
    images: dict[str, np.ndarray] = {}
    roles: dict[str, str] = {}
    origin: dict[str, str] = {}
    grid = None
    for path, spec in files:
        try:
            read, pictures, notes = read_streams(path, spec, mapping.missing)
        except IngestError as exc:
            report.skipped.append(str(exc))
            report.skipped.append(f"{key.relative_to(root)}: recording skipped, {path.name} is unusable")
            return None
        report.notes.extend(notes)
        streams.update(read)
        images.update(pictures)
        origin.update(dict.fromkeys([*read, *pictures], path.name))
        roles.update({c.role or ("photo" if c.name in pictures else ""): c.name for c in spec.channels
                      if c.role or c.name in pictures})
        grid = spec.grid or grid
    return _Parts(streams, images, roles, origin, grid)


def _recordings(key: Path, name: str, files: list[tuple[Path, FileMap]], root: Path, mapping: IngestMapping,
                table: Mapping[str, Mapping[str, str]], report: IngestReport) -> list[Recording]:
    """The recording of one key (one per patch when its image is cut into a grid)."""
    groups: dict[str, str] = {}
    if mapping.pattern is not None:
        match = mapping.pattern.search(key.name)
        if match is None:
            report.skipped.extend(f"{path}: name does not match groups.pattern" for path, _ in files)
            return []
        groups = {k: v for k, v in match.groupdict().items() if v is not None}
    parts = _read_parts(key, files, root, mapping, report)
    if parts is None:
        return []
    try:
        aligned = align(parts.streams, parts.files, mapping.missing)
        label, levels = _label(key, root, mapping, table, groups)
        split = split_of(key, root, mapping, groups)
        meta = {**mapping.meta, "label_level": mapping.label_level, "levels": levels,
                "source": [str(path.relative_to(root)) for path, _ in files]}
        if split is not None:
            meta["split"] = split
        if aligned.info:
            meta["time_base"] = aligned.info
        group = {k: v for k, v in groups.items() if k not in ("label", "split")}
        if parts.grid is None:
            recordings = [Recording(name, aligned.traces, parts.roles, label, group, meta, parts.images)]
        else:
            recordings = _patched(name, parts, aligned.traces, label, group, meta)
    except (IngestError, ScanError) as exc:
        report.skipped.append(f"{key.relative_to(root)}: recording skipped: {exc}")
        return []
    report.notes.extend(aligned.notes)
    return recordings


def _patched(name: str, parts: _Parts, traces: Mapping[str, Trace], label: str, group: Mapping[str, str],
             meta: Mapping[str, Any]) -> list[Recording]:
    """One recording per patch of the grid, sharing the group ``photo`` (and the sampled channels)."""
    assert parts.grid is not None
    (image_name, image), = parts.images.items()  # an image file is one channel
    return [Recording(f"{name}_r{r}c{c}", traces, parts.roles, label, {**group, "photo": name},
                      {**meta, "patch": [r, c], "grid": list(parts.grid)}, {image_name: patch})
            for r, c, patch in patches(image, parts.grid)]


def ingest(path: str | os.PathLike[str], mapping: IngestMapping,
           progress: Callable[[Iterable[Any]], Iterable[Any]] = iter) -> IngestReport:
    """Recordings from the files under ``path`` as ``mapping`` describes them.

    Files with the same stem in the same folder form one recording; its timestamped streams are put on a
    common time base (:func:`align`). A file that cannot be read as mapped (wrong format, missing column,
    bad token, no rate, ...) is reported in ``skipped`` with its name and reason, and its recording is
    skipped; the import goes on with the others. Names come from the paths (:func:`recording_names`);
    an image file with a ``grid`` gives one recording per patch. ``progress`` wraps the iteration over
    the recordings (e.g. a tqdm bar).

    Raises
    ------
    IngestError
        If ``path`` is not a folder or the label table cannot be read (nothing could be labelled).
    """
    root = Path(path)
    if not root.is_dir():
        raise IngestError(f"{root}: not a folder")
    table = _label_table(root, mapping)
    report = IngestReport()
    matched = _matched(root, mapping)
    names = recording_names(list(matched), root)
    for key, files in progress(list(matched.items())):
        report.files += len(files)
        report.recordings += _recordings(key, names[key], files, root, mapping, table, report)
    splits = {r.meta.get("split") for r in report.recordings}
    if mapping.split_from == "auto" and splits != {"train", "test"}:
        # Folders named train or test hold only some recordings, or one part: not a split of the set.
        report.recordings = [replace(r, meta={k: v for k, v in r.meta.items() if k != "split"})
                             for r in report.recordings]
    return report


# -- storage -----------------------------------------------------------------------------------------

def _struct(mapping: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in mapping.items() if _NAME.match(k)}


def recording_variables(recording: Recording) -> dict[str, Any]:
    """The MATLAB variables of a recording: one per channel and ``meta`` (name, label, label level, fs,
    units, roles, group, levels, ndim per channel, and all of ``Recording.meta`` as JSON text, which is what
    :func:`read_recording` restores it from)."""
    bad = [name for name in [*recording.channels, *recording.images] if not _NAME.match(name) or name == "meta"]
    if bad:
        raise IngestError(f"recording {recording.name}: channel name(s) {', '.join(bad)} "
                          "are not MATLAB names")
    meta = {
        "name": recording.name, "label": recording.label or "",
        "label_level": str(recording.meta.get("label_level", "label")),
        "fs": {n: t.fs for n, t in recording.channels.items()},
        "units": {n: t.unit for n, t in recording.channels.items()},
        "ndim": {n: float(t.data.ndim) for n, t in recording.channels.items()},
        "images": {n: np.array(image.shape, dtype=np.float64) for n, image in recording.images.items()},
        "roles": dict(recording.roles), "group": _struct(recording.group),
        "levels": _struct(recording.meta.get("levels", {})), "split": str(recording.meta.get("split", "")),
        "meta_json": json.dumps(dict(recording.meta), default=str),
    }
    return {**{n: t.data for n, t in recording.channels.items()}, **recording.images, "meta": meta}


def encode_recording(recording: Recording) -> bytes:
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, recording_variables(recording), long_field_names=True, do_compression=True,
                     oned_as="column")
    return buffer.getvalue()


def _plain(value: Any) -> Any:
    if isinstance(value, scipy.io.matlab.mat_struct):
        return {name: _plain(getattr(value, name)) for name in value._fieldnames}
    if isinstance(value, np.ndarray) and value.dtype.kind == "U":
        return "".join(value.ravel().tolist())
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "fiu":
        return float(value.ravel()[0])
    return value


def read_recording(path: str | os.PathLike[str]) -> Recording:
    """A recording written by :func:`store_recordings`."""
    path = Path(path)
    try:
        data = scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False)
        meta = {k: _plain(v) for k, v in _plain(data["meta"]).items()}
        channels = {}
        for name, fs in dict(meta.get("fs") or {}).items():
            array = np.asarray(data[name], dtype=np.float64)
            ndim = int(meta["ndim"][name])
            shape = array.shape if array.ndim == ndim else ((array.size,) if ndim == 1 else (array.size, 1))
            channels[name] = Trace(array.reshape(shape), float(fs), str(meta["units"][name]))
        images = {name: np.asarray(data[name], dtype=np.uint8).reshape(np.asarray(shape, dtype=int).tolist())
                  for name, shape in dict(meta.get("images") or {}).items()}
        group = meta.get("group") or {}
        roles = meta.get("roles") or {}
        extra = json.loads(meta.get("meta_json") or "{}")
        return Recording(str(meta["name"]), channels, dict(roles), str(meta["label"]) or None,
                         {k: str(v) for k, v in dict(group).items()}, extra, images)
    except IngestError:
        raise
    except Exception as exc:  # scipy and the data model raise many types for foreign files
        raise IngestError(f"{path}: not a readable recording file ({type(exc).__name__}: {exc})") from None


def set_folder(db_root: str | os.PathLike[str], name: str) -> Path:
    if not _SET.match(name):
        raise IngestError(f"set name {name!r} must be 1-64 letters, digits, '.', '_' or '-'")
    return Path(db_root) / RECORDINGS / name


def store_recordings(db_root: str | os.PathLike[str], name: str, recordings: Sequence[Recording],
                     replace: bool = False) -> Path:
    """Write a set of recordings to ``<db_root>/recordings/<name>/<recording>.mat``; returns the folder.

    The files go to a temporary folder first, which is renamed into place only when all are written, so a
    crash leaves the previous set (or none), never part of one. An existing set is refused unless
    ``replace``.
    """
    target = set_folder(db_root, name)
    if target.exists() and not replace:
        raise IngestError(f"{target}: the set {name!r} exists; choose another name or replace it")
    if not recordings:
        raise IngestError(f"set {name!r}: no recordings to store")
    temp = target.with_name(f".{name}.tmp-{secrets.token_hex(4)}")
    temp.mkdir(parents=True)
    try:
        for recording in recordings:
            atomic_write_bytes(temp / f"{recording.name}.mat", encode_recording(recording))
        old = target.with_name(f".{name}.old-{secrets.token_hex(4)}")
        if target.exists():
            os.replace(target, old)
        os.replace(temp, target)
        fsync_dir(target.parent)
    except BaseException:
        shutil.rmtree(temp, ignore_errors=True)
        raise
    shutil.rmtree(old, ignore_errors=True)
    return target


def load_recordings(folder: str | os.PathLike[str]) -> list[Recording]:
    """Every recording of a stored set (a folder of recording ``.mat`` files), in name order."""
    folder = Path(folder)
    files = sorted(folder.glob("*.mat")) if folder.is_dir() else []
    if not files:
        raise IngestError(f"{folder}: no recording files here")
    return [read_recording(path) for path in files]


def recording_sets(db_root: str | os.PathLike[str]) -> list[str]:
    """Names of the recording sets stored in a database."""
    folder = Path(db_root) / RECORDINGS
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")) \
        if folder.is_dir() else []
