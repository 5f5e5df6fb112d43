"""A seeded corpus of damaged and hostile scan files made from a regression scan, and its runner.

Run as a script (``python hostile_scans.py SEED BUDGET_MB``) it lowers its own address-space limit to what it
uses after start-up plus ``BUDGET_MB``, writes every case into a scratch folder one at a time, loads it with
``scanner.load_scan`` (and extracts the features of a sample of those that load) and prints one JSON line per
case: ``{"case": name, "outcome": "loaded" | "refused" | "<ExceptionType>: message", "seconds": ...}``.
The test asserts on those lines; a case that exhausts the memory limit shows up as ``MemoryError`` there
instead of taking the machine down.
"""

from __future__ import annotations

import io
import json
import os
import random
import shutil
import struct
import sys
import tempfile
import time
import warnings
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import scipy.io
from conftest import png_bomb

import features
from scanner.scan import CHANNELS
from scanner.storage.matfile import MAX_SCAN_BYTES, ScanFormatError, encode_mat, load_scan, scan_to_variables

REGRESSION = Path(__file__).parent / "regression" / "scans"
BASE = "granite-polished-01-001"
PHOTOS = {"I_disp": "disp", "I_macro": "macro", "I_illu": "illu"}
META_FIELDS = ("label", "operator", "sample_id", "scan_index", "session_id", "started", "t_amb", "mass_g",
               "volume_cm3", "volume_method", "atk", "cyd", "rigid", "fs", "units", "raw_volts", "device",
               "calibration", "software_version", "schema_version", "notes")
WRONG_VALUES: dict[str, Any] = {
    "text": "x", "array": np.array([1.0, 2.0, 3.0]), "empty": np.zeros((0, 0)), "struct": {"a": 1.0},
    "cell": np.array([[1.0], "two"], dtype=object), "nan": float("nan"), "inf": float("inf"), "negative": -1.0,
    "huge": 1e300, "2^63": 2.0**63, "long text": "z" * 5000,
}
CHANNEL_VALUES: dict[str, Callable[[np.ndarray], Any]] = {
    "int8": lambda a: np.clip(a * 40, -128, 127).astype(np.int8),
    "uint16": lambda a: np.abs(a * 1000).astype(np.uint16),
    "complex": lambda a: a.astype(np.complex128) * 1j,
    "bool": lambda a: a > 0,
    "text": lambda a: "not samples",
    "cell": lambda a: np.array([[a[:2]], [a[2:4]]], dtype=object),
    "struct": lambda a: {"samples": a},
    "one sample": lambda a: a[:1],
    "empty": lambda a: a[:0],
    "transposed": lambda a: a.T,
    "3-D": lambda a: np.stack([a, a], axis=-1),
    "two columns": lambda a: np.column_stack([a.reshape(len(a), -1)[:, 0]] * 2),
    "nan": lambda a: np.where(np.arange(a.size).reshape(a.shape) == 7, np.nan, a),
    "inf": lambda a: np.where(np.arange(a.size).reshape(a.shape) == 0, -np.inf, a),
}
mi_MATRIX = 14


class Case:
    """A name and a function writing the case into a folder that holds the base scan's photos."""

    def __init__(self, name: str, write: Callable[[Path], Path]) -> None:
        self.name, self.write = name, write


def _base_variables() -> dict[str, Any]:
    """The regression scan's variables, channels cut to 1.2 s (the corpus stays fast to write and read)."""
    scan = load_scan(REGRESSION / f"{BASE}.mat")
    variables = scan_to_variables(scan, REGRESSION / f"{BASE}.mat")
    for name in scan.traces:
        variables[name] = variables[name][:max(4, int(1.2 * scan[name].fs))]
    return variables


def _written(variables: dict[str, Any], name: str, *, compress: bool = False) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / f"{name}.mat"
        if compress:
            path.write_bytes(encode_mat(variables))
        else:
            scipy.io.savemat(path, variables, long_field_names=True, do_compression=False, oned_as="column")
        return path
    return write


def _bytes_case(data: bytes, name: str) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        path = folder / f"{name}.mat"
        path.write_bytes(data)
        return path
    return write


def _flipped(original: bytes, flips: list[tuple[int, int]], name: str) -> Callable[[Path], Path]:
    def write(folder: Path) -> Path:
        data = bytearray(original)
        for position, bit in flips:
            data[position] ^= 1 << bit
        return _bytes_case(bytes(data), name)(folder)
    return write


def _sparse(size: int, name: str) -> Callable[[Path], Path]:
    """A file of ``size`` bytes that takes no memory to write (a sparse file on most file systems)."""
    def write(folder: Path) -> Path:
        path = folder / f"{name}.mat"
        with open(path, "wb") as handle:
            handle.write(b"MATLAB 5.0")
            handle.truncate(size)
        return path
    return write


def _changed(base: dict[str, Any], change: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    variables = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    variables["meta"] = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base["meta"].items()}
    change(variables)
    return variables


def _patched_dims(base: dict[str, Any], variable: str, dims: tuple[int, ...]) -> bytes:
    """An uncompressed file whose ``variable`` announces ``dims`` while holding its original data."""
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {variable: base[variable]}, long_field_names=True, do_compression=False)
    data = bytearray(buffer.getvalue())
    at = 128 + 8 + 16  # top-level tag, then the array flags sub-element: the dimensions follow
    count = struct.unpack_from("<I", data, at + 4)[0] // 4
    new = struct.pack(f"<II{len(dims)}i", 5, 4 * len(dims), *dims)
    new += bytes(-len(new) % 8)
    data[at:at + 8 + 4 * count + (-4 * count % 8)] = new
    total = len(data) - 128 - 8
    struct.pack_into("<I", data, 128 + 4, total)
    return bytes(data)


def inflation_bomb(inflated: int) -> bytes:
    """A MAT file whose one compressed variable ``v_ts`` inflates to ``inflated`` bytes of zeros."""
    rows = inflated // 24
    header = bytearray(b"MATLAB 5.0 MAT-file, hostile".ljust(116, b" ") + bytes(8) + b"\x00\x01IM")
    name = b"v_ts"
    body = (struct.pack("<IIII", 6, 8, 6, 0) + struct.pack("<IIii", 5, 8, rows, 3)
            + struct.pack("<HH", 1, len(name)) + name + struct.pack("<II", 9, rows * 24))
    deflate = zlib.compressobj(1)
    parts = [deflate.compress(struct.pack("<II", mi_MATRIX, len(body) + rows * 24) + body)]
    zeros = bytes(1 << 22)
    for _ in range(rows * 24 // len(zeros)):
        parts.append(deflate.compress(zeros))
    parts.append(deflate.compress(bytes(rows * 24 % len(zeros))) + deflate.flush())
    stream = b"".join(parts)
    return bytes(header) + struct.pack("<II", 15, len(stream)) + stream


def _png_header(width: int, height: int, tail: bytes = b"") -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + ihdr
            + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)) + tail)


def _jpeg_sof(width: int, height: int) -> bytes:
    return (b"\xff\xd8\xff\xe0" + struct.pack(">H", 16) + b"JFIF\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00"
            + b"\xff\xc0" + struct.pack(">HBHHB", 17, 8, height, width, 3) + bytes(9) + b"\xff\xd9")


def _photo_case(base: dict[str, Any], name: str, content: bytes | None, *,
                file_name: str | None = None) -> Callable[[Path], Path]:
    """The base scan with its ``I_disp`` photo replaced by ``content`` (None: a folder of that name)."""
    def write(folder: Path) -> Path:
        photo = f"{name}_disp.png" if file_name is None else file_name
        variables = _changed(base, lambda v: v.update(I_disp=photo))
        path = _written(variables, name)(folder)
        if file_name is None:
            if content is None:
                (folder / photo).mkdir()
            else:
                (folder / photo).write_bytes(content)
        return path
    return write


def cases(seed: int) -> Iterator[Case]:
    """A few hundred cases, the same for the same seed."""
    rng = random.Random(seed)
    original = (REGRESSION / f"{BASE}.mat").read_bytes()
    base = _base_variables()

    for i in range(60):  # byte flips anywhere, a third of them where the header and meta are
        span = 2048 if i % 3 == 0 else len(original)
        flips = [(rng.randrange(span), rng.randrange(8)) for _ in range(rng.choice((1, 3, 16)))]
        yield Case(f"flip-{i}", _flipped(original, flips, f"flip-{i}"))
    for i, keep in enumerate([0, 1, 4, 116, 127, 128, 129, 135, 136, 200] + [rng.randrange(len(original))
                                                                               for _ in range(20)]):
        yield Case(f"truncated-{keep}", _flipped(original[:keep], [], f"truncated-{i}"))

    for variable in [name for name in base if name != "meta"]:
        yield Case(f"removed {variable}", _written(_changed(base, lambda v, n=variable: v.pop(n)), "removed"))
    for old, new in (("v_ts", "V_ts"), ("meta", "Meta"), ("I_disp", "I_dsp"), ("a_ts", "a_ts_raw"),
                     ("t_cool", "t_cool_raw")):
        yield Case(f"renamed {old} to {new}",
                   _written(_changed(base, lambda v, o=old, n=new: v.__setitem__(n, v.pop(o))), "renamed"))
    yield Case("meta removed", _written(_changed(base, lambda v: v.pop("meta")), "no-meta"))
    for field in META_FIELDS:
        yield Case(f"meta.{field} removed", _written(_changed(base, lambda v, f=field: v["meta"].pop(f)), "field"))
        for kind, value in WRONG_VALUES.items():
            yield Case(f"meta.{field} = {kind}",
                       _written(_changed(base, lambda v, f=field, x=value: v["meta"].__setitem__(f, x)), "field"))
    for field in ("fs", "units"):
        for kind, value in (("text", "3000"), ("array", np.ones(3)), ("nan", float("nan"))):
            yield Case(f"meta.{field}.v_ts = {kind}",
                       _written(_changed(base, lambda v, f=field, x=value: v["meta"][f].__setitem__("v_ts", x)),
                                "sub"))
    for channel in ("v_ts", "a_ts", "t_cool", "dB"):
        for kind, make in CHANNEL_VALUES.items():
            yield Case(f"{channel} as {kind}",
                       _written(_changed(base, lambda v, c=channel, m=make: v.__setitem__(c, m(v[c]))), "channel"))
        too_long = (CHANNELS[channel].max_n + 1,) + ((3,) if CHANNELS[channel].axes else ())
        yield Case(f"{channel} one sample too long", _written(_changed(
            base, lambda v, c=channel, shape=too_long: v.__setitem__(c, np.zeros(shape, dtype=np.int8))), "long"))
    yield Case("raw volts claimed, none stored", _written(_changed(base, lambda v: v["meta"].update(raw_volts=1.0)),
                                                          "raw"))
    yield Case("raw volts with NaN", _written(_changed(base, lambda v: (
        v["meta"].update(raw_volts=1.0), v.__setitem__("v_ts_raw", np.full((10, 3), np.nan)))), "raw"))

    for variable, dims in (("v_ts", (100_000, 100_000)), ("v_ts", (-1, 3)), ("v_ts", (3,)), ("v_ts", (1,) * 40),
                           ("I_disp", (100_000, 100_000)), ("meta", (10_000, 10_000)), ("meta", (4097, 1)),
                           ("meta", (0, 0))):
        yield Case(f"{variable} announces {dims[:4]}", _bytes_case(_patched_dims(base, variable, dims), "dims"))
    cell = np.empty((1, 1), dtype=object)
    cell[0, 0] = np.ones((2, 2))
    buffer = io.BytesIO()
    scipy.io.savemat(buffer, {"meta": cell}, do_compression=False)
    nested: dict[str, Any] = {"x": 1.0}
    for _ in range(20):
        nested = {"x": nested}
    yield Case("meta nested 20 deep", _written(_changed(base, lambda v: v["meta"].update(device=nested)), "deep"))
    yield Case("inflation bomb", _bytes_case(inflation_bomb(MAX_SCAN_BYTES + (64 << 20)), "inflation"))
    yield Case("oversized file", _sparse(MAX_SCAN_BYTES + 10, "oversized"))
    yield Case("MATLAB v7.3 header", _bytes_case(original[:124] + b"\x00\x02IM" + original[128:4096], "v73"))
    yield Case("MATLAB v4 file", _bytes_case(bytes(20) + original[128:1024], "v4"))

    real_png = (REGRESSION / f"{BASE}_disp.png").read_bytes()
    image = cv2.imdecode(np.frombuffer(real_png, np.uint8), cv2.IMREAD_COLOR)
    broken_crc = bytearray(real_png)
    broken_crc[len(broken_crc) // 2] ^= 0xFF
    photos = {
        "pixel bomb 20000 x 20000": png_bomb(20_000, 20_000),
        "header 100000 x 100000": _png_header(100_000, 100_000, bytes(64)),
        "header 16385 x 16": _png_header(16_385, 16, bytes(64)),
        "header 0 x 10": _png_header(0, 10),
        "truncated png": real_png[:len(real_png) // 3],
        "png with a damaged byte": bytes(broken_crc),
        "png signature only": real_png[:8],
        "random bytes": bytes(rng.randrange(256) for _ in range(4096)),
        "empty photo": b"",
        "bmp": cv2.imencode(".bmp", image)[1].tobytes(),
        "tiff": cv2.imencode(".tiff", image)[1].tobytes(),
        "jpeg announcing 65000 x 65000": _jpeg_sof(65_000, 65_000),
        "truncated jpeg": cv2.imencode(".jpg", image)[1].tobytes()[:500],
        "16-bit png": cv2.imencode(".png", image.astype(np.uint16) * 257)[1].tobytes(),
        "gray png": cv2.imencode(".png", image[..., 0])[1].tobytes(),
    }
    for name, content in photos.items():
        yield Case(f"photo: {name}", _photo_case(base, "photo", content))
    yield Case("photo: a folder", _photo_case(base, "photo", None))
    for name in ("..", "a/b.png", "nul\x00.png", "", "x" * 300):
        yield Case(f"photo name {name[:12]!r}", _photo_case(base, "photo-name", b"", file_name=name))


def _limit_memory(budget: int) -> None:
    import resource

    with open("/proc/self/status") as status:
        used = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
    resource.setrlimit(resource.RLIMIT_AS, (used + budget, resource.RLIM_INFINITY))


def run(seed: int, budget: int) -> None:
    warnings.simplefilter("ignore")
    features.extract(load_scan(REGRESSION / f"{BASE}.mat"))  # warm up: every lazy import done before the limit
    corpus = list(cases(seed))
    _limit_memory(budget)
    folder = Path(tempfile.mkdtemp(prefix="hostile-"))
    photos = folder / "photos"
    photos.mkdir()
    for short in PHOTOS.values():
        shutil.copy(REGRESSION / f"{BASE}_{short}.png", photos)
    loaded = 0
    try:
        for n, case in enumerate(corpus):
            work = folder / str(n)
            work.mkdir()
            for photo in photos.iterdir():
                os.link(photo, work / photo.name)
            started = time.perf_counter()
            try:
                scan = load_scan(case.write(work))
                outcome = "loaded"
                loaded += 1
                if loaded % 4 == 1:  # features of every fourth scan that loads: odd but valid input
                    features.extract(scan)
            except ScanFormatError as exc:
                outcome = "refused" if "\n" not in str(exc) and str(exc).startswith(str(work)) else f"bad: {exc!r}"
            except BaseException as exc:  # what the test is looking for
                outcome = f"{type(exc).__name__}: {str(exc)[:200]}"
            seconds = time.perf_counter() - started
            print(json.dumps({"case": case.name, "outcome": outcome, "seconds": round(seconds, 3)}), flush=True)
            shutil.rmtree(work, ignore_errors=True)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    run(int(sys.argv[1]), int(sys.argv[2]) << 20)
