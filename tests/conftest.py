"""Shared test fixtures: hand-built scans with every channel, independent of the simulator."""

from __future__ import annotations

import functools
import signal
import struct
import sys
import zlib

import numpy as np
import pytest

from scanner.scan import CHANNELS, Scan, ScanMeta, Trace
from scanner.storage.database import Database


def make_meta(**overrides) -> ScanMeta:
    values = dict(label="C6S1M1P2X1", operator="ab", sample_id="granite-01", scan_index=1, session_id="s-1",
                  started="2026-11-21T08:00:00+00:00", t_amb=21.5, mass_g=512.0, volume_cm3=190.0,
                  volume_method="water", atk=0.0, cyd=0.25,
                  device={"daq": "USB-6002 1F2A3B4", "board": "TEXPLORER-SB 1.2"},
                  calibration={"accel_zero_V": 1.65, "accel_V_per_g": 0.33}, software_version="0.1.0")
    values.update(overrides)
    return ScanMeta(**values)


def make_scan(seed: int = 0, *, seconds: float = 0.2, images: bool = True, drop: tuple[str, ...] = (),
              raw: bool = False, image_shape: tuple[int, int] = (240, 320), **meta) -> Scan:
    """A scan with random but valid data on every channel of docs/database.md (short, so tests stay fast)."""
    rng = np.random.default_rng(seed)
    traces = {}
    for name, spec in CHANNELS.items():
        if name in drop:
            continue
        n = max(2, int(round(seconds * spec.fs)))
        shape = (n, spec.axes) if spec.axes else (n,)
        traces[name] = Trace(rng.standard_normal(shape), spec.fs, spec.unit)
    photos = {}
    if images:
        h, w = image_shape
        photos = {v: rng.integers(0, 256, (h, w, 3), dtype=np.uint8) for v in ("I_disp", "I_macro", "I_illu")}
    raw_volts = {"v_ts": Trace(rng.uniform(0, 3.3, traces["v_ts"].data.shape), 3000.0, "V")} if raw else {}
    return Scan(make_meta(**meta), traces, photos, raw_volts)


def pytest_configure(config):
    """Ctrl-C handled as Python's default, in this process and every program it starts: a shell that starts
    the suite in the background (``make test &`` without job control) starts it with SIGINT ignored, which
    the children inherit, and then the tests of Ctrl-C (the recorder switching off, ``serve`` and the
    emulators stopping, a cluster run cancelled) could not send it. A handler, unlike ``SIG_IGN``, is reset
    to the default by ``exec``."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_collection_modifyitems(config, items):
    """Every test under ``tests/system`` carries the ``system`` marker, so ``-m "not system"`` selects the
    unit tests wherever they are named (``make test-fast`` runs ``tests/unit``; CONTRIBUTING.md)."""
    for item in items:
        if item.path.parent.name == "system":
            item.add_marker(pytest.mark.system)


@pytest.fixture(autouse=True)
def _no_workers_kept_between_tests():
    """``extract_many`` keeps its workers for its next call: a test must not extract with workers forked by
    another, which run that test's code and patches (not imported here if no test has)."""
    yield
    local = sys.modules.get("scanner.runtime.local")
    if local is not None:
        local.release_workers()


@pytest.fixture
def scan() -> Scan:
    return make_scan()


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


@functools.cache
def png_bomb(width: int, height: int) -> bytes:
    """A valid PNG of ``width`` x ``height`` black RGB pixels in about a thousandth of their bytes.

    Each block of 16 rows is deflated after a full flush, which resets the compressor, so one block's bytes
    repeat for the whole image without compressing gigabytes; 20000 x 20000 px (1.2 GB decoded) is 1.2 MB.
    """
    assert height >= 16, "a bomb has at least one block of 16 rows"
    rows = (b"\x00" + bytes(3 * width)) * 16
    deflate = zlib.compressobj(9)
    first = deflate.compress(rows) + deflate.flush(zlib.Z_FULL_FLUSH)
    block = deflate.compress(rows) + deflate.flush(zlib.Z_FULL_FLUSH)
    blocks, rest = divmod(height, 16)
    adler = 1
    for _ in range(blocks):
        adler = zlib.adler32(rows, adler)
    tail = zlib.compressobj(9)
    last = b""
    if rest:
        part = (b"\x00" + bytes(3 * width)) * rest
        adler = zlib.adler32(part, adler)
        last = tail.compress(part) + tail.flush(zlib.Z_FULL_FLUSH)
        last = last[2:]  # a raw continuation: no second zlib header
    stream = first + block * (blocks - 1) + last + b"\x03\x00" + struct.pack(">I", adler)
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + _png_chunk(b"IDAT", stream) + _png_chunk(b"IEND", b"")


@pytest.fixture
def db_path(tmp_path):
    """A database of two scans (granite, and a rigid steel without its fold channels) for the CLI tests."""
    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1))
    db.add(make_scan(1, label="C7S1M1P8X1", sample_id="steel-01", scan_index=1, operator="cd",
                     rigid=True, drop=("f_fold", "alpha_f")))
    db.close()
    return tmp_path / "db"


# -- the web app, for the unit and the system tests of gui/ -----------------------------------------------

@pytest.fixture
def app(tmp_path):
    """The web app on an empty database in ``tmp_path`` (uploads up to 400 kB), shut down after the test."""
    from unit.test_gui import make_app

    app = make_app(tmp_path / "db", upload_limit=400_000)
    yield app
    app.extensions["texplorer"].shutdown()


@pytest.fixture
def client(app):
    return app.test_client()


@pytest.fixture
def stocked(tmp_path):
    """A test client of the web app on three scans: granite-01 twice (300 px photos), a rigid steel scan."""
    from unit.test_gui import make_app

    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, image_shape=(300, 300)))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, image_shape=(300, 300)))
    db.add(make_scan(2, label="C7S1M1P8X1", sample_id="steel-01", scan_index=1, operator="cd", rigid=True,
                     drop=("f_fold", "alpha_f"), images=False))
    db.close()
    app = make_app(tmp_path / "db")
    yield app.test_client()
    app.extensions["texplorer"].shutdown()
