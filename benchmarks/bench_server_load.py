"""A busy web app: 200 requests over 20 threads against ``texplorer serve`` with an empty feature cache.

The requests are a lab's mix (database overview, scan list, material pages, scan pages, which show the scan's
features, and the features export, which extracts every uncached scan). The reference, run in the same
process, is the same 200 requests one after another against a server of its own with an empty cache.

A request's bound is twice the serial time of the requests it was queued with: the reference's time of
every request in flight at some moment of its life, itself included ("the serial time per request times
the queue depth it saw", with each request's own serial time rather than the mean, so that pages waiting on
the one export that extracts are measured against that export's work). Also printed: the mean-based form,
and the peak number of processes beside the server (the worker server, multiprocessing's resource tracker
and the workers), sampled every 20 ms, which one bounded set of workers keeps at workers + 2.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import re
import shutil
import sqlite3
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import psutil

from scanner.simulation.database import synthetic_database

MATERIALS = ("oak-planed", "granite-polished", "cork-board", "aluminium-sheet")
THREADS = 20
REQUESTS = 200
WORKERS = 2


@contextlib.contextmanager
def served(db: Path) -> Iterator[tuple[str, psutil.Process]]:
    """``texplorer serve`` on ``db`` at a free port: its base URL and process."""
    command = [str(Path(sys.executable).with_name("texplorer")), "serve", "--db", str(db), "--port", "0",
               "--workers", str(WORKERS)]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
    try:
        for line in process.stderr:
            if found := re.search(r"at (http://\S+)", line):
                break
        else:
            raise RuntimeError(f"the server did not start: {process.wait()}")
        threading.Thread(target=process.stderr.read, daemon=True).start()  # keep its pipe drained
        yield found.group(1).rstrip("/"), psutil.Process(process.pid)
    finally:
        process.terminate()
        process.wait(30)


def requests(db: Path) -> list[str]:
    """The 200 paths, in a fixed order: 10 exports spread among pages."""
    conn = sqlite3.connect(db / "catalog.sqlite")
    ids = [row[0] for row in conn.execute("SELECT scan_id FROM scans ORDER BY scan_id")]
    labels = sorted({row[0] for row in conn.execute("SELECT label FROM scans")})
    conn.close()
    pages = ["/db/", "/db/scans"] + [f"/db/material/{label}" for label in labels] + [f"/db/scan/{i}" for i in ids]
    paths = []
    for n in range(REQUESTS):
        paths.append("/db/export/features.csv" if n % 20 == 0 else pages[n % len(pages)])
    return paths


def empty_cache(db: Path) -> None:
    conn = sqlite3.connect(db / "catalog.sqlite")
    with conn:
        conn.execute("DELETE FROM feature_cache")
    conn.close()


def fetch(url: str) -> None:
    with urllib.request.urlopen(url, timeout=600) as answer:
        answer.read()
        assert answer.status == 200, (url, answer.status)


def peak_processes(process: psutil.Process, stop: threading.Event, peak: list[int]) -> None:
    while not stop.wait(0.02):
        with contextlib.suppress(psutil.Error):
            peak[0] = max(peak[0], 1 + len(process.children(recursive=True)))


def run(db: Path, paths: list[str], threads: int) -> tuple[np.ndarray, np.ndarray, float, int]:
    """Each request's (start, end) in seconds, the wall time and the peak number of processes beside the server."""
    empty_cache(db)
    with served(db) as (base, process):
        fetch(base + "/db/")  # the server is up and has imported its pages
        stop, peak = threading.Event(), [0]
        watcher = threading.Thread(target=peak_processes, args=(process, stop, peak), daemon=True)
        watcher.start()
        spans = np.zeros((len(paths), 2))
        origin = time.perf_counter()

        def one(index: int) -> None:
            spans[index, 0] = time.perf_counter() - origin
            fetch(base + paths[index])
            spans[index, 1] = time.perf_counter() - origin

        with concurrent.futures.ThreadPoolExecutor(threads) as pool:
            list(pool.map(one, range(len(paths))))
        wall = time.perf_counter() - origin
        stop.set()
        watcher.join()
    return spans, wall, peak[0]


def bounds(spans: np.ndarray, serial: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per request: the requests in flight during its life (itself included) and their summed serial time."""
    overlap = (spans[:, None, 0] < spans[None, :, 1]) & (spans[None, :, 0] < spans[:, None, 1])
    return overlap.sum(axis=1), overlap @ serial


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "db"
        synthetic_database(db, materials=MATERIALS, samples_per_material=1, scans_per_material=3,
                           image_size=(512, 512), progress=False).close()
        paths = requests(db)
        serial_spans, serial_wall, serial_peak = run(db, paths, 1)
        spans, wall, peak = run(db, paths, THREADS)
        shutil.rmtree(db)
    serial = serial_spans[:, 1] - serial_spans[:, 0]
    latency = spans[:, 1] - spans[:, 0]
    depth, queued = bounds(spans, serial)
    per_request = serial_wall / len(paths)
    print(f"{len(paths)} requests ({paths.count('/db/export/features.csv')} features exports) against a server "
          f"of {WORKERS} workers, 12 scans of 512 px, empty feature cache")
    print(f"reference, one at a time: {serial_wall:.1f} s, {per_request * 1000:.0f} ms per request (p50 "
          f"{np.percentile(serial, 50) * 1000:.0f} ms, max {serial.max():.2f} s), peak {serial_peak - 1} processes "
          "beside the server")
    print(f"{THREADS} threads: {wall:.1f} s; latency p50 {np.percentile(latency, 50):.2f} s, "
          f"p95 {np.percentile(latency, 95):.2f} s; requests in flight during a request p50 "
          f"{np.percentile(depth, 50):.0f}")
    within = np.mean(latency <= 2 * queued) * 100
    print(f"p95 of latency / serial time of the requests it was queued with: "
          f"{np.percentile(latency / queued, 95):.2f} (goal <= 2); within 2x for {within:.0f} %")
    print(f"p95 of latency / (mean serial time per request x requests in flight): "
          f"{np.percentile(latency / (per_request * depth), 95):.2f}")
    print(f"peak processes beside the server {peak - 1} (goal <= workers + 2 = {WORKERS + 2})")
    print(f"wall time, {THREADS} threads / one at a time: {wall / serial_wall:.2f}")


if __name__ == "__main__":
    main()
