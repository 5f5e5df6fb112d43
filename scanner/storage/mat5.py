"""Reading MATLAB v5 ``.mat`` files with bounded memory, whatever their bytes; writing large arrays without
copies of them (:func:`write_variables`).

``scipy.io.loadmat`` trusts the file: a compressed variable of a few kilobytes can inflate to gigabytes of
zeros, and a cell or struct array allocates one Python object per element its header announces before
reading any (a 200-byte file announcing a 10000 x 10000 cell takes 800 MB). :func:`read_mat` therefore
inflates every compressed variable itself, stopping at ``max_bytes`` in total, walks the element tree of the
result (MATLAB's "MAT-File Format", 2021, chapter 1: tags, array flags, dimensions, names, fields) and
checks every size against the bytes that hold it, and only then lets scipy read the uncompressed copy.
Numeric and character data are read by scipy from that bounded copy, so a dimension that lies about them
fails scipy's own reshape instead of allocating.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import scipy  # scipy.io loads at its first use (scipy's submodules load when first read)

from taxonomy.errors import TexplorerError

HEADER_BYTES = 128
MI_INT8, MI_INT32, MI_UINT32, MI_MATRIX, MI_COMPRESSED = 1, 5, 6, 14, 15
CELL, STRUCT, OBJECT, CHAR, SPARSE = 1, 2, 3, 4, 5
NUMERIC = frozenset(range(6, 16))
"""mxDOUBLE_CLASS .. mxUINT64_CLASS."""
MAX_ITEMS = 4096
"""Elements a cell or struct array may have (a scan's structs have one)."""
MAX_FIELDS = 1024
MAX_DEPTH = 8
"""Nesting of structs and cells (a scan's ``meta.fs.v_ts`` is three deep)."""
MAX_DIMS = 32


class MatFileError(TexplorerError, ValueError):
    """The bytes are not a MATLAB v5 file this reader accepts; the message is the reason, one line."""


def _padded(n: int) -> int:
    return n + (-n % 8)


class _Elements:
    """The uncompressed element stream of one variable, read with the file's byte order."""

    def __init__(self, data: bytes, order: str) -> None:
        self.data = memoryview(data)
        self.order = order

    def tag(self, position: int, end: int) -> tuple[int, int, int, int]:
        """``(type, bytes, data position, next position)`` of the element at ``position``."""
        if position + 8 > end:
            raise MatFileError("truncated data element")
        (first,) = struct.unpack_from(self.order + "I", self.data, position)
        if first >> 16:  # small data element: type and size in one word, data in the next four bytes
            kind, size = first & 0xFFFF, first >> 16
            if size > 4:
                raise MatFileError(f"small data element of {size} bytes")
            return kind, size, position + 4, position + 8
        (size,) = struct.unpack_from(self.order + "I", self.data, position + 4)
        stop = position + 8 + _padded(size)
        if position + 8 + size > end:
            raise MatFileError("data element longer than the variable holding it")
        return first, size, position + 8, min(stop, end)

    def expect(self, position: int, end: int, kind: int, what: str) -> tuple[int, int, int]:
        found, size, data, following = self.tag(position, end)
        if found != kind:
            raise MatFileError(f"{what}: data type {found}, expected {kind}")
        return size, data, following

    def int32s(self, data: int, size: int) -> tuple[int, ...]:
        return struct.unpack_from(f"{self.order}{size // 4}i", self.data, data)

    def matrix(self, position: int, end: int, depth: int) -> int:
        """Check the array element at ``position``; returns the position after it."""
        size, data, following = self.expect(position, end, MI_MATRIX, "array")
        stop = data + size
        if size == 0:
            return following
        flags_size, flags, p = self.expect(data, stop, MI_UINT32, "array flags")
        if flags_size != 8:
            raise MatFileError("array flags of the wrong size")
        kind = struct.unpack_from(self.order + "I", self.data, flags)[0] & 0xFF
        dims_size, dims_at, p = self.expect(p, stop, MI_INT32, "dimensions")
        dims = self.int32s(dims_at, dims_size)
        if not 2 <= len(dims) <= MAX_DIMS or min(dims) < 0:
            raise MatFileError(f"impossible dimensions {dims[:MAX_DIMS]}")
        _, _, p = self.expect(p, stop, MI_INT8, "array name")
        if kind in NUMERIC or kind in (CHAR, SPARSE):
            return following  # scipy reads the data from these bounded bytes
        if kind not in (CELL, STRUCT, OBJECT):
            raise MatFileError(f"unsupported MATLAB class {kind}")
        count = math.prod(dims)
        if count > MAX_ITEMS:
            raise MatFileError(f"a cell or struct array of {count} elements (at most {MAX_ITEMS})")
        if depth >= MAX_DEPTH:
            raise MatFileError(f"structs or cells nested more than {MAX_DEPTH} deep")
        items = count
        if kind in (STRUCT, OBJECT):
            if kind == OBJECT:
                _, _, p = self.expect(p, stop, MI_INT8, "class name")
            length_size, length_at, p = self.expect(p, stop, MI_INT32, "field name length")
            length = self.int32s(length_at, length_size)[0] if length_size == 4 else 0
            names_size, _, p = self.expect(p, stop, MI_INT8, "field names")
            if length < 1 or names_size % length or names_size // length > MAX_FIELDS:
                raise MatFileError("malformed struct field names")
            items = count * (names_size // length)
        if items * 8 > stop - p:
            raise MatFileError(f"{items} elements announced in {stop - p} bytes")
        for _ in range(items):
            p = self.matrix(p, stop, depth + 1)
        return following


def _header_order(header: bytes) -> str:
    if len(header) < HEADER_BYTES:
        raise MatFileError("shorter than a MATLAB v5 header")
    if 0 in header[:4]:
        raise MatFileError("no MATLAB v5 header (a MATLAB v4 file, or not a .mat file)")
    indicator = header[126:128]
    if indicator not in (b"IM", b"MI"):
        raise MatFileError("no MATLAB v5 byte-order mark")
    order = "<" if indicator == b"IM" else ">"
    (version,) = struct.unpack(order + "H", header[124:126])
    if version == 0x0200:
        raise MatFileError("a MATLAB 7.3 (HDF5) file; save it with -v7")
    if version != 0x0100:
        raise MatFileError(f"unknown MATLAB file version {version:#06x}")
    return order


def _inflate(data: bytes, budget: int) -> bytes:
    inflater = zlib.decompressobj()
    try:
        out = inflater.decompress(data, budget + 1)
    except zlib.error as exc:
        raise MatFileError(f"damaged compressed variable ({exc})") from None
    if len(out) > budget:
        raise MatFileError("its variables inflate beyond the size limit")
    return out


def uncompressed_copy(path: str | os.PathLike[str], max_bytes: int) -> io.BytesIO:
    """The file's header and variables, every one inflated and checked, as one uncompressed v5 stream.

    Raises
    ------
    MatFileError
        The file is larger than ``max_bytes``, its variables inflate to more, or its structure is not a
        well-formed MATLAB v5 file within the limits of this module.
    OSError
        The file cannot be read.
    """
    path = Path(path)
    check_file_size(path.stat().st_size, max_bytes)
    with open(path, "rb") as handle:
        return _uncompressed(handle, max_bytes)


def check_file_size(size: int, max_bytes: int) -> None:
    """Refuse a file of ``size`` bytes beyond ``max_bytes`` before reading it (MatFileError)."""
    if size > max_bytes:
        raise MatFileError(f"{size / 1e6:.0f} MB is larger than the {max_bytes / 1e6:.0f} MB a scan file may have")


def _uncompressed(handle: BinaryIO, max_bytes: int) -> io.BytesIO:
    """The checked elements written one by one into a growing stream, each let go after its write: peak memory
    about the stream plus one element. (Keeping the elements to join them once would hold every element and
    the joined copy at once, about 1.4 times the peak; docs/performance.md.)"""
    out = io.BytesIO()
    total = 0
    header = handle.read(HEADER_BYTES)
    order = _header_order(header)
    out.write(header)
    while tag := handle.read(8):
        if len(tag) < 8:
            raise MatFileError("truncated variable")
        kind, length = struct.unpack(order + "II", tag)
        body = handle.read(length)
        if len(body) < length:
            raise MatFileError("truncated variable")
        if kind == MI_COMPRESSED:
            element = _inflate(body, max_bytes - total)
        elif kind == MI_MATRIX:
            element = tag + body
        else:
            raise MatFileError(f"unexpected top-level data type {kind}")
        elements = _Elements(element, order)
        end = elements.matrix(0, len(element), 0)
        total += end
        if total > max_bytes:
            raise MatFileError("its variables inflate beyond the size limit")
        out.write(elements.data[:end])
    out.seek(0)
    return out


def read_mat(path: str | os.PathLike[str], max_bytes: int, **options: Any) -> dict[str, Any]:
    """``scipy.io.loadmat(path, **options)`` on the checked copy of :func:`uncompressed_copy`.

    Raises :class:`MatFileError` for anything wrong with the bytes, scipy's complaints included, and
    OSError when the file cannot be read.
    """
    return _loadmat(uncompressed_copy(path, max_bytes), options)


def read_mat_bytes(data: bytes, max_bytes: int, **options: Any) -> dict[str, Any]:
    """:func:`read_mat` of a file's bytes read elsewhere (a copy a cluster worker got from the client)."""
    check_file_size(len(data), max_bytes)
    return _loadmat(_uncompressed(io.BytesIO(data), max_bytes), options)


def _loadmat(stream: io.BytesIO, options: dict[str, Any]) -> dict[str, Any]:
    try:
        return scipy.io.loadmat(stream, **options)
    except Exception as exc:  # scipy raises many types for malformed content; the bytes are bounded here
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MatFileError(reason) from None


# -- writing, with bounded memory --------------------------------------------------------------------------------

MI_DOUBLE, MX_DOUBLE = 9, 6
STREAMED_BYTES = 1 << 20
"""A real float64 variable of at least this many bytes is written by :func:`write_variables` itself, its
column-major data compressed in blocks of this size; smaller ones and every other kind by ``savemat``."""


def _element(kind: int, payload: bytes, order: str) -> bytes:
    """A (normal, not small) data element: tag, payload, padding to 8 bytes."""
    return struct.pack(order + "II", kind, len(payload)) + payload + b"\0" * (-len(payload) % 8)


def _double_matrix_head(name: str, shape: tuple[int, ...], order: str) -> bytes:
    """The ``miMATRIX`` element of a real double array up to its data's tag ("MAT-File Format", 2021, table
    1-5): array flags (class ``mxDOUBLE_CLASS``), dimensions, name; the column-major data follows."""
    data_bytes = 8 * math.prod(shape)
    flags = _element(MI_UINT32, struct.pack(order + "II", MX_DOUBLE, 0), order)
    dims = _element(MI_INT32, struct.pack(order + f"{len(shape)}i", *shape), order)
    label = _element(MI_INT8, name.encode("ascii"), order)
    size = len(flags) + len(dims) + len(label) + 8 + data_bytes
    if size >= 1 << 32:
        raise MatFileError(f"variable {name}: {data_bytes} bytes do not fit a MATLAB v5 element (4 GiB)")
    return (struct.pack(order + "II", MI_MATRIX, size) + flags + dims + label
            + struct.pack(order + "II", MI_DOUBLE, data_bytes))


def _column_major_blocks(array: np.ndarray, block: int, order: str) -> Iterator[bytes]:
    """The bytes of a 1-D or 2-D float64 array in MATLAB's (column-major) order and the file's byte order,
    ``block`` bytes or fewer at a time: never a copy of the whole array."""
    columns = array.reshape(len(array), -1)
    rows = max(1, block // 8)
    for column in range(columns.shape[1]):
        for start in range(0, columns.shape[0], rows):
            yield np.ascontiguousarray(columns[start:start + rows, column], dtype=order + "f8").tobytes()


def _streamed(value: Any) -> bool:
    return (getattr(value, "dtype", None) is not None and value.dtype.kind == "f" and value.dtype.itemsize == 8
            and value.ndim in (1, 2) and value.nbytes >= STREAMED_BYTES)


def write_variables(handle: BinaryIO, variables: dict[str, Any], compress: Any, level: int) -> None:
    """``variables`` as a MATLAB v5 file (each variable one compressed element, vectors as columns, long field
    names) written to ``handle``, holding no more than a block of a large array at a time: ``savemat`` builds
    each variable's whole element in memory, and then its compressed copy (a 320 MB trace peaked at three times
    its size). Large real float64 arrays (:data:`STREAMED_BYTES`) are written here, their data compressed as it
    is read; everything else by ``savemat``, one variable at a time. ``compress`` is a zlib-compatible module
    (``zlib``, ``isal.isal_zlib``) and ``level`` its level. ``handle`` must be seekable (the compressed size is
    written once known)."""
    small = io.BytesIO()
    scipy.io.savemat(small, {}, long_field_names=True, oned_as="column")
    header = small.getvalue()[:HEADER_BYTES]
    order = "<" if header[126:128] == b"IM" else ">"
    handle.write(header)
    for name, value in variables.items():
        if not _streamed(value):
            one = io.BytesIO()
            scipy.io.savemat(one, {name: value}, long_field_names=True, do_compression=False, oned_as="column")
            element = one.getbuffer()[HEADER_BYTES:]
            packed = compress.compress(element, level)
            handle.write(struct.pack(order + "II", MI_COMPRESSED, len(packed)) + packed)
            continue
        shape = tuple(value.shape) if value.ndim == 2 else (len(value), 1)
        tag_at = handle.tell()
        handle.write(b"\0" * 8)
        packer = compress.compressobj(level)
        size = 0
        head = _double_matrix_head(name, shape, order)
        for chunk in itertools.chain([head], _column_major_blocks(value, STREAMED_BYTES, order)):
            packed = packer.compress(chunk)
            size += len(packed)
            handle.write(packed)
        packed = packer.flush()
        size += len(packed)
        handle.write(packed)
        end = handle.tell()
        handle.seek(tag_at)
        handle.write(struct.pack(order + "II", MI_COMPRESSED, size))
        handle.seek(end)
