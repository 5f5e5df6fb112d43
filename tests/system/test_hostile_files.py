"""Hostile and damaged scan files: refused with a ScanFormatError, within bounded memory and time (docs/database.md).

The corpus (``tests/hostile_scans.py``) is made from a regression scan: byte flips, truncations, removed
and renamed variables, wrong types, shapes and dtypes, NaN/Inf, dimensions that announce gigabytes, a
compressed variable that inflates beyond the limit, and hostile photos. It runs in a subprocess whose address
space is limited, so a case that allocated without bound would fail there as MemoryError (or be killed)
instead of passing by luck on a large machine.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

TESTS = Path(__file__).parents[1]
linux_only = pytest.mark.skipif(not Path("/proc/self/status").is_file() or os.name != "posix",
                                reason="the address-space limit needs Linux's /proc and setrlimit")
MUST_REFUSE = ("photo: pixel bomb 20000 x 20000", "photo: header 100000 x 100000", "photo: header 16385 x 16",
               "inflation bomb", "oversized file", "v_ts announces (100000, 100000)", "meta announces (10000, 10000)",
               "meta nested 20 deep", "meta.scan_index = 2^63", "meta.scan_index = huge", "meta.raw_volts = empty",
               "v_ts one sample too long", "a_ts one sample too long", "photo: tiff", "photo: bmp",
               "photo: jpeg announcing 65000 x 65000", "meta.sample_id = long text", "meta.notes = long text")


def _run(args: list[str], env: dict[str, str] | None = None, timeout: float = 240) -> subprocess.CompletedProcess:
    environment = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", **(env or {})}
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, timeout=timeout,
                          env=environment, cwd=TESTS)


@linux_only
def test_no_exception_but_scan_format_error_leaves_load_scan_for_a_seeded_corpus_of_hostile_files():
    run = _run(["hostile_scans.py", "14", "1500"])  # 1.5 GB over what the process holds after start-up
    assert run.returncode == 0, run.stderr[-3000:]
    results = [json.loads(line) for line in run.stdout.splitlines()]
    assert len(results) >= 300
    escaped = [r for r in results if r["outcome"] not in ("loaded", "refused")]
    assert escaped == [], escaped[:10]
    outcome = {r["case"]: r["outcome"] for r in results}
    assert [name for name in MUST_REFUSE if outcome[name] != "refused"] == []
    assert all(outcome[f"flip-{i}"] == "refused" for i in range(1, 60, 3)), "a flipped byte went unnoticed"
    slow = [r for r in results if r["seconds"] > 5.0]
    assert slow == [], slow


MEMORY = textwrap.dedent("""
    import os, resource, sys, warnings
    from pathlib import Path
    import cv2, numpy as np
    import features
    from conftest import png_bomb
    from scanner.storage.matfile import ScanFormatError, load_scan, save_scan

    warnings.simplefilter("ignore")
    regression, work, side = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
    scan = load_scan(regression / "granite-polished-01-001.mat")
    photo = {name: cv2.resize(image, (side, side)) for name, image in scan.images.items()}
    at_limit = save_scan(type(scan)(scan.meta, scan.traces, photo, scan.raw), work / "limit" / "s.mat")[-1]
    bomb = save_scan(scan, work / "bomb" / "s.mat")[-1]
    (work / "bomb" / "s_disp.png").write_bytes(png_bomb(20000, 20000))
    full_size = sum(np.isfinite(v) for v in features.extract(scan).values())  # lazy imports done before the limit
    with open("/proc/self/status") as status:
        used = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
    resource.setrlimit(resource.RLIMIT_AS, (used + (1 << 30), resource.RLIM_INFINITY))
    try:
        load_scan(bomb)
        print("bomb loaded")
    except ScanFormatError as exc:
        print("bomb refused:", str(exc).split(": ", 2)[-1])
    values = features.extract(load_scan(at_limit))
    print("at the limit:", sum(np.isfinite(v) for v in values.values()) - full_size, "finite features fewer")
    print("peak MB:", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
""")


@linux_only
def test_load_and_extract_stay_within_a_memory_limit_on_a_pixel_bomb_and_at_the_photo_limit(tmp_path):
    # A 2.25 MP limit for the test (the default is 25 MP): three photos exactly at the limit are extracted, the
    # 20000 x 20000 bomb (1.2 GB decoded, 15 GB during extraction) is refused from its header, all in 1 GB.
    run = _run(["-c", MEMORY, str(TESTS / "regression" / "scans"), str(tmp_path), "1500"],
               env={"TEXPLORER_MAX_PHOTO_PIXELS": "2250000"}, timeout=180)
    assert run.returncode == 0, run.stderr[-3000:]
    lines = run.stdout.splitlines()
    assert lines[0] == ("bomb refused: photo s_disp.png: the image has 400,000,000 pixels (20000 x 20000); "
                        "at most 2,250,000 are accepted ($TEXPLORER_MAX_PHOTO_PIXELS)")
    assert lines[1] == "at the limit: 0 finite features fewer", lines
