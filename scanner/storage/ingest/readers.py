"""File readers of an import: CSV/TSV tables, WAV, NPY, NPZ, MATLAB v5 ``.mat`` and images, each
turned into timestamped streams and notes of what was done to the data.
"""

from __future__ import annotations

import csv
import itertools
import math
import warnings
import zipfile
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, TextIO

import numpy as np

from scanner.lazy import library
from scanner.photo import PhotoError, check_pixels, image_size, max_file_bytes
from scanner.scan import ScanError, Trace, handed_over
from scanner.storage.ingest.clock import Clock, on_slots, regular_clock
from scanner.storage.ingest.mapping import FORMATS, TIME_UNITS, ChannelMap, FileMap, IngestError, format_of
from scanner.storage.mat5 import MatFileError, read_mat

cv2 = library("cv2")
wavfile = library("scipy.io.wavfile")  # both load when a photo or a WAV file is read

NAN_TOKENS = ("nan", "-nan", "+nan", "", "na", "n/a", "null", "none")
"""Tokens read as a missing sample (case-insensitive, surrounding spaces ignored)."""
MAX_ARRAY_BYTES = 1 << 30
"""The samples of one file may take at most this many bytes as they are held after reading: float64, 8
bytes a value, whatever the file's own type (an int8 NPY of 40 MB is 320 MB). Checked from the headers
before an NPY, NPZ or WAV file's data is read, while a CSV/TSV file is read, and on a MAT file's variables
before they are converted (which inflate to at most this many bytes), so that a small file cannot make an
import take unbounded memory."""
HELD_ITEMSIZE = 8
"""Bytes of one sample as an import holds it (float64)."""
RATE_TOLERANCE = 0.05
"""Time steps may vary by this fraction of their median before the import notes it."""


def _number(token: str) -> float:
    """A table cell's value: a number (spaces around it allowed) or a token of :data:`NAN_TOKENS`."""
    try:
        return float(token)  # the common case: a number, or nan
    except ValueError:
        if token.strip().lower() in NAN_TOKENS:
            return math.nan
        raise


def _split_lines(lines: Iterable[str], delimiter: str | None,
                 comment: str | None) -> Iterator[tuple[int, list[str]]]:
    """The non-empty, non-comment rows of ``lines`` with their line numbers, one at a time."""
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
        yield number, row


MAX_LINE_CHARS = 1 << 22
"""The longest line of a CSV/TSV file (4,194,304 characters: 200,000 columns of 20 characters), read at most
this far before it is refused: a 1 GB line of 537 million fields, split into Python strings, took 6.4 GB."""


def _bounded_lines(handle: TextIO, path: Path) -> Iterator[str]:
    """The lines of a text file without their line ends, each read at most :data:`MAX_LINE_CHARS` + 1
    characters far; a longer line is refused naming it, before it is held whole."""
    number = 0
    while True:
        line = handle.readline(MAX_LINE_CHARS + 1)
        if not line:
            return
        number += 1
        if len(line) > MAX_LINE_CHARS and not line.endswith("\n"):
            raise IngestError(f"{path}: line {number} is longer than {MAX_LINE_CHARS:,} characters (the most "
                              "one line may hold)")
        yield line.rstrip("\r\n")


TABLE_BLOCK_ROWS = 4096
"""Rows parsed into one float64 block while a table is read: its text is never held whole."""


def read_table(path: Path, delimiter: str | None, header: bool, comment: str | None = "#",
               skip_rows: int = 0,
               needed: Callable[[list[str]], Collection[int]] | None = None,
               ignored: dict[str, str] | None = None) -> tuple[list[str], np.ndarray]:
    """Column names and values (rows, columns, NaN for missing tokens) of a CSV/TSV file.

    Trailing delimiters (an empty last field on every line) are dropped; a row with a different number of
    fields than the header is an error naming the line. ``needed`` (the column names -> the indices to
    read) leaves every other column unread, NaN: a text column the mapping does not use is no error, and
    is put in ``ignored`` (its name -> its first value) for a note. The file is read line by line into
    blocks of float64 values, refused as soon as the table would exceed :data:`MAX_ARRAY_BYTES` (a 90 MB
    CSV held as text and Python lists took 3.96 GB).
    """
    try:
        with open(path, encoding="utf-8-sig", newline="") as handle:
            lines = _bounded_lines(handle, path)
            rows = itertools.islice(_split_lines(lines, delimiter, comment), skip_rows, None)
            return _parse_table(path, rows, header, needed, ignored)
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read ({exc})") from None


def _parse_table(path: Path, rows: Iterator[tuple[int, list[str]]], header: bool,
                 needed: Callable[[list[str]], Collection[int]] | None,
                 ignored: dict[str, str] | None) -> tuple[list[str], np.ndarray]:
    first = next(rows, None)
    if first is None:
        raise IngestError(f"{path}: no data")
    names: list[str]
    if header:
        names = [cell.strip() for cell in first[1]]
        while names and not names[-1]:
            names.pop()
    else:
        # Without a header an empty last field can only be read as a trailing delimiter.
        names = [str(k) for k in range(len(_trimmed(first[1], 0)))]
        rows = itertools.chain([first], rows)
    read = sorted(set(range(len(names)) if needed is None else needed(names)))
    most_rows = MAX_ARRAY_BYTES // (HELD_ITEMSIZE * max(1, len(names)))
    blocks: list[np.ndarray] = []
    block: list[list[float]] = []
    count, first_row = 0, None
    for line, cells in rows:
        cells = _trimmed(cells, len(names))
        if len(cells) != len(names):
            raise IngestError(f"{path}: line {line}: {len(cells)} fields, expected {len(names)}")
        first_row = cells if first_row is None else first_row
        try:
            block.append([_number(cells[c]) for c in read])
        except ValueError:
            c = next(c for c in read if not _is_number(cells[c]))
            raise IngestError(f"{path}: line {line}, column {names[c]}: {cells[c]!r} is not a number") from None
        count += 1
        if count > most_rows:
            raise IngestError(f"{path}: more than {most_rows:,} rows of {len(names)} values, more than the "
                              f"{MAX_ARRAY_BYTES / 1e6:.0f} MB one file may hold")
        if len(block) == TABLE_BLOCK_ROWS:
            blocks.append(np.array(block, dtype=np.float64).reshape(len(block), len(read)))
            block = []
    if block:
        blocks.append(np.array(block, dtype=np.float64).reshape(len(block), len(read)))
    if first_row is None:
        raise IngestError(f"{path}: a header but no data rows")
    values = np.full((count, len(names)), np.nan)
    values[:, read] = np.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    if ignored is not None and header:
        ignored.update({names[c]: cell.strip() for c, cell in enumerate(first_row)
                        if c not in read and c < len(names) and not _is_number(cell)})
    return names, values


def _is_number(token: str) -> bool:
    try:
        _number(token)
    except ValueError:
        return False
    return True


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
              "gap": "gaps in the timestamps bridged", "aligned": "streams cut to their common time span",
              "clock": "jittered timestamps of a regular clock kept as regular streams",
              "text": "text columns not in the mapping ignored",
              "roles": "recordings lacking a role the others have",
              "role": "channels without a role read as the generic role signal",
              "excluded": "classes left out as asked",
              "class_roles": "classes lacking every recording of a role the other classes have",
              "repeats": "recordings beginning with an earlier recording's samples, kept in its fold group"}


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
    in seconds), images, notes, and the regular clock found under its timestamps."""

    arrays: dict[str, tuple[np.ndarray, float, ChannelMap, np.ndarray | None]] = field(default_factory=dict)
    images: dict[str, np.ndarray] = field(default_factory=dict)
    notes: list[Note] = field(default_factory=list)
    clock: dict[str, Any] | None = None


NOMINAL_RATE = 0.01
"""A mapping's ``rate`` is the nominal rate of a regular clock found under the timestamps when the two
agree to this fraction; otherwise the stream is resampled to it."""


def _table_file(path: Path, spec: FileMap, fmt: str) -> _Read:
    delimiter = spec.delimiter or ("\t" if fmt == "tsv" else ",")

    def needed(names: list[str]) -> list[int]:
        time = [] if spec.time_column is None else _select(names, [spec.time_column], path, "time")
        return time + [k for channel in spec.channels for k in _select(names, channel.columns, path, channel.name)]

    ignored: dict[str, str] = {}
    names, values = read_table(path, delimiter, spec.header, spec.comment, spec.skip_rows, needed, ignored)
    read = _Read()
    if ignored:
        shown = ", ".join(f"{name} ({value!r})" for name, value in list(ignored.items())[:3])
        read.notes.append(Note("text", path.name, len(ignored), f"{path.name}: text column(s) not in the "
                               f"mapping ignored: {shown}{' ...' if len(ignored) > 3 else ''}"))
    times = None
    if spec.time_column is not None:
        times = seconds_of(values[:, _select(names, [spec.time_column], path, "time")[0]], spec.time_unit, path)
        rate = spec.rate or 1.0 / float(np.median(np.diff(times)))
        clock = regular_clock(times)
        if clock is not None:
            values, times, rate = _regular(values, clock, spec.rate)
            read.clock = _clock_info(clock, rate)
            if clock.dropped or clock.duplicated or clock.jitter_max > 1e-3 * clock.period:
                read.notes.append(Note("clock", path.name, clock.jitter_rms / clock.period,
                                       f"{path.name}: timestamps are {clock.describe()}: kept as a regular "
                                       f"stream at {rate:.6g} Hz"))
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


def _regular(values: np.ndarray, clock: Clock, given: float | None) -> tuple[np.ndarray, np.ndarray, float]:
    """Rows in their clock slots, the slots' times and the rate: the mapping's where it is the clock's
    nominal rate (:data:`NOMINAL_RATE`), else the fitted one; a differing given rate keeps the fitted times,
    so the stream is then resampled to it."""
    rows = on_slots(values, clock)
    if given is not None and abs(given * clock.period - 1.0) <= NOMINAL_RATE:
        return rows, clock.start + np.arange(clock.length) / given, given
    return rows, clock.times, given or 1.0 / clock.period


def _clock_info(clock: Clock, rate: float) -> dict[str, Any]:
    return {"rate_hz": rate, "fitted_rate_hz": 1.0 / clock.period, "jitter_rms_s": clock.jitter_rms,
            "jitter_max_s": clock.jitter_max, "dropped": clock.dropped, "duplicated": clock.duplicated}


def _wav_file(path: Path, spec: FileMap) -> _Read:
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always", wavfile.WavFileWarning)
            rate, data = wavfile.read(path, mmap=True)  # the samples stay on disk until checked
    except (OSError, ValueError) as exc:
        if "mmap length is greater than file size" in str(exc):
            raise IngestError(f"{path}: the WAV file is truncated (its header announces more samples than it "
                              "holds)") from None
        raise IngestError(f"{path}: not a readable WAV file ({exc})") from None
    _check_held(path, data.size)
    if data.ndim not in (1, 2) or data.size == 0 or not rate > 0:
        raise IngestError(f"{path}: not a readable WAV file (no samples, or no sample rate)")
    short = [str(w.message) for w in warned if "EOF" in str(w.message) or "truncat" in str(w.message).lower()]
    if short:
        raise IngestError(f"{path}: the WAV file is truncated ({short[0]})")
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


def _npy_values(handle: BinaryIO) -> int:
    """The number of values an NPY stream's header announces."""
    version = np.lib.format.read_magic(handle)
    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    shape, _, _ = read(handle)
    return math.prod(shape)


def _check_held(path: Path, values: int) -> None:
    """Refuse a file whose ``values`` samples would take more than :data:`MAX_ARRAY_BYTES` as held."""
    if values * HELD_ITEMSIZE > MAX_ARRAY_BYTES:
        raise IngestError(f"{path}: its arrays take {values * HELD_ITEMSIZE / 1e6:.0f} MB, more than the "
                          f"{MAX_ARRAY_BYTES / 1e6:.0f} MB one file may hold")


def _check_sizes(path: Path, fmt: str) -> None:
    """Refuse, from headers alone, an array file whose values would take more than :data:`MAX_ARRAY_BYTES`
    as held (float64), whatever their type in the file.

    A few bytes of NPY header or a zip directory can announce terabytes; numpy would allocate them first.
    """
    if fmt == "npy":
        with open(path, "rb") as handle:
            values = _npy_values(handle)
    else:
        values = 0
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                with archive.open(info) as member:
                    values += _npy_values(member) if info.filename.endswith(".npy") else info.file_size
    _check_held(path, values)


def _variables(path: Path, fmt: str) -> dict[str, np.ndarray]:
    try:
        if fmt == "mat":
            variables = read_mat(path, MAX_ARRAY_BYTES, squeeze_me=False)
            variables = {k: v for k, v in variables.items() if not k.startswith("__")}
            _check_held(path, sum(np.size(v) for v in variables.values()))
            return variables
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
    clock: dict[str, Any] | None = None


def read_streams(path: Path, spec: FileMap,
                 missing: str = "interpolate") -> tuple[dict[str, Stream], dict[str, np.ndarray], list[Note]]:
    """The channels and images of one file, and notes on what was done to them."""
    fmt = file_format(path, spec)
    readers: dict[str, Callable[[], _Read]] = {
        "csv": lambda: _table_file(path, spec, fmt), "tsv": lambda: _table_file(path, spec, fmt),
        "wav": lambda: _wav_file(path, spec), "image": lambda: _image_file(path, spec)}
    read = readers.get(fmt, lambda: _array_file(path, spec, fmt))()
    streams, notes = {}, list(read.notes)
    for name, (data, rate, channel, times) in read.arrays.items():
        data = np.asarray(data, dtype=np.float64)
        if channel.scale != 1 and data.flags.writeable:
            data *= channel.scale  # in place: each channel's array is its own (a copy would double a large file)
        elif channel.scale != 1:
            data = data * channel.scale
        data, filled = _fill(data, missing, f"{path}: channel {name}")
        if filled:
            notes.append(Note("missing", path.name, filled, f"{path.name}: channel {name}: {filled} missing "
                              "sample(s) interpolated"))
        streams[name] = Stream(handed_over(data), rate, channel.unit, times, read.clock)
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

