"""The ``.mat`` scan format (docs/database.md): one MATLAB v5 file per scan, photos as PNG beside it.

Layout of ``<scan>.mat`` (``scipy.io.savemat``, ``long_field_names=True``, every variable zlib-compressed):

- one float64 variable per channel of :data:`scanner.scan.CHANNELS` that the scan has; 1-D channels are
  column vectors (n x 1), accelerations n x 3; raw DAQ volts as ``<channel>_raw``;
- ``I_disp``, ``I_macro``, ``I_illu``: file names of the photos, PNG files in the same folder;
- ``meta``: a struct with ``label``, ``operator``, ``sample_id``, ``scan_index``, ``session_id``,
  ``started``, ``t_amb``, ``mass_g``, ``volume_cm3``, ``volume_method`` (water, micro-pearls, known or
  empty), ``atk``, ``cyd``, ``rigid``, ``fs`` (struct: channel -> Hz), ``units`` (struct: channel -> unit),
  ``raw_volts`` (0/1), ``device`` (struct of strings), ``calibration`` (struct of numbers),
  ``software_version``, ``schema_version``, ``notes``, ``steps`` (only in a partial, quick scan: the steps
  it holds, comma-separated, ``tool_slide,photos``; a file without it is a full scan).
  Unknown numbers (not weighed, not judged) are NaN.

In MATLAB or Octave: ``s = load('granite-01-001.mat'); plot(s.v_ts); s.meta.fs.v_ts``.
In Python: ``scipy.io.loadmat(path, simplify_cells=True)``.

Reading is bounded whatever the bytes: the file and its inflated variables at most :data:`MAX_SCAN_BYTES`
(:mod:`scanner.storage.mat5` checks sizes before scipy allocates), a channel at most
``scanner.scan.MAX_CHANNEL_SECONDS`` (checked before its float64 copy), a photo within the pixel limit of
:mod:`scanner.photo` (checked from its header before decoding). Every meta field has a range
(``scanner.scan.ScanMeta``: ``scan_index`` 1..9999, ``t_amb`` in the MLX90614's -40..85 degC, mass and
volume up to 1e6, ``rigid`` and ``raw_volts`` 0 or 1, ids and texts of bounded length; the full table is
``docs/database.md``); anything outside is a :class:`ScanFormatError` naming the file and the field.
"""

from __future__ import annotations

import io
import math
import os
import struct
import warnings
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import scipy  # scipy.io loads at its first use (scipy's submodules load when first read)
from isal import isal_zlib

from scanner import photo
from scanner.photo import PhotoError, encode_png, read_photo
from scanner.scan import (
    CHANNELS,
    IMAGES,
    MAX_CHANNEL_SECONDS,
    SCHEMA_VERSION,
    ChannelSpec,
    Scan,
    ScanError,
    ScanMeta,
    Trace,
)
from scanner.storage import mat5
from scanner.storage.files import atomic_write_bytes, atomic_writer
from scanner.storage.mat5 import MatFileError, read_mat
from taxonomy.errors import TexplorerError

REQUIRED_META = ("label", "operator", "sample_id", "scan_index", "session_id", "started",
                 "fs", "units", "schema_version")
_OPTIONAL_NUMBERS = ("t_amb", "mass_g", "volume_cm3", "atk", "cyd")
MAX_SCAN_BYTES = 256 << 20
"""A ``.mat`` scan file, and its variables once inflated, may have at most this many bytes: every channel
at its longest (``scanner.scan.MAX_CHANNEL_SECONDS``) with its raw volts takes about 200 MB."""


class ScanFormatError(TexplorerError, ValueError):
    """A ``.mat`` scan file cannot be read as a valid scan; the message names the file and the field."""

    def __init__(self, path: str | os.PathLike[str], field: str | None, reason: str) -> None:
        self.path = Path(path)
        self.field = field
        self.reason = reason
        where = f"{self.path}: {field}" if field else str(self.path)
        super().__init__(f"{where}: {reason}")


class ScanFormatWarning(UserWarning):
    """A scan file loads, but something in it is inconsistent and was resolved as docs/database.md says."""


def photo_file_name(mat_path: Path, variable: str) -> str:
    """``<stem>_<disp|macro|illu>.png`` beside the ``.mat`` file."""
    return f"{mat_path.stem}_{IMAGES[variable]}.png"


def scan_files(path: str | os.PathLike[str], scan: Scan) -> list[Path]:
    """Every file :func:`save_scan` writes for ``scan`` at ``path`` (photos first, the ``.mat`` last)."""
    mat_path = Path(path)
    return [mat_path.with_name(photo_file_name(mat_path, v)) for v in IMAGES if v in scan.images] + [mat_path]


def _meta_struct(scan: Scan) -> dict[str, Any]:
    meta = scan.meta
    return {
        "label": meta.label,
        "operator": meta.operator,
        "sample_id": meta.sample_id,
        "scan_index": float(meta.scan_index),
        "session_id": meta.session_id,
        "started": meta.started,
        "t_amb": meta.t_amb,
        "mass_g": meta.mass_g,
        "volume_cm3": meta.volume_cm3,
        "volume_method": meta.volume_method,
        "atk": meta.atk,
        "cyd": meta.cyd,
        "rigid": float(meta.rigid),
        "fs": {name: trace.fs for name, trace in (*scan.raw.items(), *scan.traces.items())},
        "units": {name: trace.unit for name, trace in scan.traces.items()},
        "raw_volts": float(bool(scan.raw)),
        "device": dict(meta.device),
        "calibration": dict(meta.calibration),
        "software_version": meta.software_version,
        "schema_version": float(meta.schema_version),
        "notes": meta.notes,
        **({"steps": meta.steps} if meta.steps else {}),  # a full scan's file stays as it was before
    }


def scan_to_variables(scan: Scan, mat_path: Path) -> dict[str, Any]:
    """The MATLAB variables of a scan, as passed to ``scipy.io.savemat``."""
    variables: dict[str, Any] = {name: trace.data for name, trace in scan.traces.items()}
    variables.update({f"{name}_raw": trace.data for name, trace in scan.raw.items()})
    variables.update({var: photo_file_name(mat_path, var) for var in IMAGES if var in scan.images})
    variables["meta"] = _meta_struct(scan)
    return variables


_HEADER_TEXT_BYTES = 116
_HEADER = f"MATLAB 5.0 MAT-file, texplorer scan, schema {SCHEMA_VERSION}".encode("ascii")


_MI_COMPRESSED = 15
"""The v5 data type of a zlib-compressed element."""
COMPRESSION_LEVEL = 1
"""Compression level of every variable's zlib stream, written by ISA-L (``isal.isal_zlib``, Intel's
deflate, levels 0-3). On a scan's float64 traces its level 1 takes about a quarter of the CPU of zlib's
level 1 for files of the same size, which are about a quarter larger than at zlib's default 6
(``scipy.io.savemat``'s, five times zlib 1's CPU; docs/performance.md). The streams are ordinary zlib
streams: MATLAB, scipy and zlib read them."""


def encode_mat(variables: dict[str, Any]) -> bytes:
    """MATLAB v5 bytes; the header's free text is fixed so the same scan always gives the same bytes.

    ``savemat`` writes its creation time into the 116-byte descriptive header, which MATLAB only
    displays; replacing it makes files content-addressable (same scan -> same SHA-256). Each top-level
    variable is then compressed as ``savemat(do_compression=True)`` does (one ``miCOMPRESSED`` element
    holding the zlib stream of the variable's element), by ISA-L at :data:`COMPRESSION_LEVEL`.
    """
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, variables, long_field_names=True, do_compression=False, oned_as="column")
    data = buffer.getvalue()
    order = "<" if data[126:128] == b"IM" else ">"
    out = bytearray(_HEADER.ljust(_HEADER_TEXT_BYTES, b" ") + data[_HEADER_TEXT_BYTES:128])
    position = 128
    while position < len(data):
        _, size = struct.unpack_from(order + "II", data, position)
        packed = isal_zlib.compress(data[position:position + 8 + size], COMPRESSION_LEVEL)
        out += struct.pack(order + "II", _MI_COMPRESSED, len(packed)) + packed
        position += 8 + size
    return bytes(out)


def save_scan(scan: Scan, path: str | os.PathLike[str]) -> list[Path]:
    """Write ``scan`` to ``path`` (a ``.mat`` file) and its photos beside it, each atomically.

    Photos are written first, so a ``.mat`` file never names a photo that is not there.

    Parameters
    ----------
    scan : Scan
        The scan to store.
    path : str or os.PathLike
        The ``.mat`` file; the photos become ``<stem>_disp.png``, ``_macro.png``, ``_illu.png`` beside it.

    Returns
    -------
    list of pathlib.Path
        The written paths, the ``.mat`` last.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from scanner import load_scan, save_scan
    >>> from scanner.simulation import synthetic_scan
    >>> scan = synthetic_scan("granite-polished", seed=0, image_size=(256, 256))
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "granite.mat"
    >>> written = save_scan(scan, path)
    >>> load_scan(path) == scan
    True
    """
    mat_path = Path(path)
    if mat_path.suffix != ".mat":
        raise ScanFormatError(f"{mat_path}: a scan file must end in .mat")
    mat_path.parent.mkdir(parents=True, exist_ok=True)
    for variable in IMAGES:
        if variable in scan.images:
            atomic_write_bytes(mat_path.with_name(photo_file_name(mat_path, variable)),
                               encode_png(scan.images[variable]))
    with atomic_writer(mat_path) as handle:
        handle.write(encode_mat(scan_to_variables(scan, mat_path)))
    return scan_files(mat_path, scan)


def _to_python(value: Any) -> Any:
    """MATLAB values from ``loadmat(squeeze_me=False, struct_as_record=False)`` as plain Python."""
    if isinstance(value, scipy.io.matlab.mat_struct):
        return {name: _to_python(getattr(value, name)) for name in value._fieldnames}
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "U":
            return "".join(value.ravel().tolist())
        if value.dtype == object:
            return _to_python(value.ravel()[0]) if value.size == 1 else [_to_python(v) for v in value.ravel()]
        if value.size == 1 and value.dtype.kind in "fiub":
            return float(value.ravel()[0])
    if isinstance(value, str):
        return value
    return value


class FileView(Protocol):
    """Where :func:`load_scan` finds a scan's files other than this machine's file system (a cluster worker
    loading what the client sent, see :mod:`scanner.storage.stored`). Each method answers for a path as
    ``Path.is_file``, ``os.stat(path).st_size`` and ``Path.read_bytes`` do, raising the same ``OSError``s,
    so every problem is reported as a local load reports it; a size beyond a limit is refused unread."""

    def is_file(self, path: Path) -> bool: ...

    def size(self, path: Path) -> int: ...

    def read(self, path: Path) -> bytes: ...


_MAT_OPTIONS = dict(squeeze_me=False, struct_as_record=False, chars_as_strings=True)


def _read_variables(path: Path, files: FileView | None = None) -> dict[str, Any]:
    if not (path.is_file() if files is None else files.is_file(path)):
        raise ScanFormatError(path, None, "file not found")
    try:
        if files is None:
            return read_mat(path, MAX_SCAN_BYTES, **_MAT_OPTIONS)
        mat5.check_file_size(files.size(path), MAX_SCAN_BYTES)
        return mat5.read_mat_bytes(files.read(path), MAX_SCAN_BYTES, **_MAT_OPTIONS)
    except MatFileError as exc:
        raise ScanFormatError(path, None, f"not a readable MATLAB v5 .mat file ({exc})") from None
    except OSError as exc:
        raise ScanFormatError(path, None, f"cannot be read ({exc.strerror or exc})") from None


def _meta_number(path: Path, meta: dict[str, Any], name: str, default: float = math.nan) -> float:
    value = meta.get(name, default)
    if isinstance(value, np.ndarray) and value.size == 0:
        return default
    if not isinstance(value, float):
        raise ScanFormatError(path, f"meta.{name}", f"must be a number, got {_kind(value)}")
    return value


def _meta_flag(path: Path, meta: dict[str, Any], name: str) -> bool:
    """A 0/1 field (``rigid``, ``raw_volts``); absent means 0."""
    value = meta.get(name, 0.0)
    if not isinstance(value, float) or value not in (0.0, 1.0):
        shown = f"{value:g}" if isinstance(value, float) else _kind(value)
        raise ScanFormatError(path, f"meta.{name}", f"must be 0 or 1, got {shown}")
    return value == 1.0


def _kind(value: Any) -> str:
    """What a MATLAB value is, in MATLAB's words, for messages."""
    if isinstance(value, np.ndarray):
        return f"a {value.dtype} array of shape {value.shape}"
    kinds = {dict: "a struct", list: "a cell array", float: "a number", str: "text"}
    return kinds.get(type(value), type(value).__name__)


def _meta_text(path: Path, meta: dict[str, Any], name: str, default: str | None = None) -> str:
    value = meta.get(name, default)
    if isinstance(value, np.ndarray) and value.size == 0:
        value = ""
    if value is None:
        raise ScanFormatError(path, f"meta.{name}", "required field is missing")
    if not isinstance(value, str):
        raise ScanFormatError(path, f"meta.{name}", f"must be text, got {_kind(value)}")
    return value


def _meta_struct_field(path: Path, meta: dict[str, Any], name: str) -> dict[str, Any]:
    value = meta.get(name, {})
    if isinstance(value, np.ndarray) and value.size == 0:
        return {}
    if not isinstance(value, dict):
        raise ScanFormatError(path, f"meta.{name}", "must be a struct")
    return value


def _parse_meta(path: Path, variables: dict[str, Any]) -> tuple[dict[str, Any], ScanMeta]:
    if "meta" not in variables:
        raise ScanFormatError(path, "meta", "required variable is missing")
    meta = _to_python(variables["meta"])
    if not isinstance(meta, dict):
        raise ScanFormatError(path, "meta", "must be a struct")
    for name in REQUIRED_META:
        if name not in meta:
            raise ScanFormatError(path, f"meta.{name}", "required field is missing")
    schema = _meta_number(path, meta, "schema_version")
    if schema != SCHEMA_VERSION:
        raise ScanFormatError(path, "meta.schema_version",
                              f"unknown schema version {schema:g} (this software reads {SCHEMA_VERSION})")
    try:
        scan_meta = ScanMeta(
            label=_meta_text(path, meta, "label"),
            operator=_meta_text(path, meta, "operator"),
            sample_id=_meta_text(path, meta, "sample_id"),
            scan_index=_meta_number(path, meta, "scan_index"),
            session_id=_meta_text(path, meta, "session_id"),
            started=_meta_text(path, meta, "started"),
            rigid=_meta_flag(path, meta, "rigid"),
            device={k: str(v) for k, v in _meta_struct_field(path, meta, "device").items()},
            calibration=_meta_struct_field(path, meta, "calibration"),
            software_version=_meta_text(path, meta, "software_version", ""),
            schema_version=int(schema),
            notes=_meta_text(path, meta, "notes", ""),
            volume_method=_meta_text(path, meta, "volume_method", ""),
            steps=_meta_text(path, meta, "steps", ""),
            **{name: _meta_number(path, meta, name) for name in _OPTIONAL_NUMBERS},
        )
    except ScanError as exc:
        raise ScanFormatError(path, exc.field or "meta", exc.reason) from None
    return meta, scan_meta


def _channel_array(path: Path, name: str, value: Any, spec: ChannelSpec) -> np.ndarray:
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiu":
        raise ScanFormatError(path, name, f"must be a real numeric array, got {_kind(value)}")
    axes = spec.axes
    if axes == 0 and value.ndim == 2 and 1 in value.shape:
        value = value.ravel()  # MATLAB users save row or column vectors; both are a 1-D channel
    expected = f"(n, {axes})" if axes else "(n,) column or row vector"
    if (axes and (value.ndim != 2 or value.shape[1] != axes)) or (not axes and value.ndim != 1):
        raise ScanFormatError(path, name, f"wrong shape {value.shape}, expected {expected}")
    if value.shape[0] == 0:
        raise ScanFormatError(path, name, "is empty")
    if value.shape[0] > spec.max_n:  # checked before the float64 copy, which may be 8 times the stored bytes
        raise ScanFormatError(path, name, f"{value.shape[0]} samples, more than the {spec.max_n} "
                                          f"({MAX_CHANNEL_SECONDS:g} s at {spec.fs:g} Hz) a channel may hold")
    bad = ~np.isfinite(value)
    if bad.any():
        raise ScanFormatError(path, name, f"{int(bad.sum())} non-finite samples "
                                          f"(first at sample {int(np.argwhere(bad)[0][0])})")
    return value.astype(np.float64, copy=False)


def _read_traces(path: Path, variables: dict[str, Any], meta: dict[str, Any],
                 suffix: str = "") -> dict[str, Trace]:
    rates = _meta_struct_field(path, meta, "fs")
    units = _meta_struct_field(path, meta, "units")
    traces = {}
    for name, spec in CHANNELS.items():
        if name + suffix not in variables:
            continue
        data = _channel_array(path, name + suffix, variables[name + suffix], spec)
        rate = rates.get(name)
        if not isinstance(rate, float):
            raise ScanFormatError(path, f"meta.fs.{name}", "sample rate is missing")
        if rate != spec.fs:
            raise ScanFormatError(path, f"meta.fs.{name}", f"sample rate {rate:g} Hz, expected {spec.fs:g} Hz")
        unit = "V" if suffix else units.get(name)
        if not suffix and (not isinstance(unit, str) or unit != spec.unit):
            shown = repr(unit[:20]) if isinstance(unit, str) else _kind(unit)
            raise ScanFormatError(path, f"meta.units.{name}", f"unit {shown}, expected {spec.unit!r}")
        traces[name] = Trace(data, rate, unit)
    return traces


def _photo_name(path: Path, variable: str, value: Any) -> str:
    name = _to_python(value)
    plain = (isinstance(name, str) and 0 < len(name) <= 255 and name not in (".", "..")
             and not any(ch in name for ch in "/\\\x00"))
    if not plain:
        raise ScanFormatError(path, variable, f"must be a plain file name, got {_kind(name)}"
                              if not isinstance(name, str) else f"must be a plain file name, got {name[:60]!r}")
    return name


def photo_names(data: bytes) -> list[str]:
    """The photo file names a ``.mat`` file's bytes name (plain names only), its traces left unread; [] if
    the bytes are not a readable scan file."""
    try:
        variables = mat5.read_mat_bytes(data, MAX_SCAN_BYTES, variable_names=list(IMAGES), **_MAT_OPTIONS)
        return [_photo_name(Path(), variable, variables[variable]) for variable in IMAGES if variable in variables]
    except (MatFileError, ScanFormatError):  # the load that follows reports the problem, naming the file
        return []


def _read_images(path: Path, variables: dict[str, Any], files: FileView | None = None) -> dict[str, np.ndarray]:
    """The photos, each refused from its header if beyond the pixel limit (:mod:`scanner.photo`)."""
    images = {}
    for variable in IMAGES:
        if variable not in variables:
            continue
        name = _photo_name(path, variable, variables[variable])
        try:
            if files is None:
                images[variable] = read_photo(path.with_name(name), f"photo {name}")
            else:
                photo.check_file_size(files.size(path.with_name(name)), f"photo {name}")
                images[variable] = photo.decode(files.read(path.with_name(name)), f"photo {name}")
        except PhotoError as exc:
            raise ScanFormatError(path, variable, str(exc)) from None
        except OSError as exc:
            raise ScanFormatError(path, variable, f"photo {name} cannot be read ({exc.strerror or exc})") from None
    return images


def load_scan(path: str | os.PathLike[str], *, images: bool = True, files: FileView | None = None) -> Scan:
    """Read and validate a scan written by :func:`save_scan` (or by MATLAB in the same layout).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mat`` file.
    images : bool
        Read the photos too (False skips them).
    files : FileView, optional
        Read the ``.mat`` and its photos from elsewhere than this machine's file system; errors still
        name ``path``.

    Returns
    -------
    Scan
        Missing optional channels are fine: the features that need them are NaN.

    Raises
    ------
    ScanFormatError
        Naming the file and field, for a truncated, foreign or oversized file (:data:`MAX_SCAN_BYTES`), a
        wrong shape, non-finite samples, a channel longer than ``scanner.scan.MAX_CHANNEL_SECONDS``, a
        missing required field, a meta value out of its range, a wrong or missing rate, an unknown schema
        version, or a photo that is unreadable or beyond the pixel limit (checked from its header before
        decoding). No other exception comes out of it for any content of the files.

    Warns
    -----
    ScanFormatWarning
        A file with ``meta.rigid`` = 1 that stores the fold: the stored fold wins (Strese et al. 2020,
        eq. 21; docs/features.md#cdf).
    """
    mat_path = Path(path)
    variables = _read_variables(mat_path, files)
    meta, scan_meta = _parse_meta(mat_path, variables)
    traces = _read_traces(mat_path, variables, meta)
    raw = _read_traces(mat_path, variables, meta, suffix="_raw") if _meta_flag(mat_path, meta, "raw_volts") else {}
    photos = _read_images(mat_path, variables, files) if images else {}
    try:
        scan = Scan(scan_meta, traces, photos, raw)
    except ScanError as exc:
        raise ScanFormatError(mat_path, exc.field, exc.reason) from None
    if scan.fold_despite_rigid:
        stored = ", ".join(name for name in ("f_fold", "alpha_f") if name in scan.traces)
        warnings.warn(f"{mat_path}: meta.rigid is 1 but the fold is stored ({stored}); the stored fold is used",
                      ScanFormatWarning, stacklevel=2)
    return scan
