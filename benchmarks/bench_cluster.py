"""Dask cluster benchmark (docs/clusters.md): one 24-scan database extracted serially, with
the local process pool and on a LocalCluster of 2 worker processes (reading the database, and with the
files shipped by the client), every result checked bit for bit against the serial one.

Printed: speed-ups against the serial run; the per-scan scheduling overhead of the cluster -- the time
its workers sit idle between two scans (Dask's task stream: start and end of every task on every worker),
per scan -- relative to one scan's extraction time on the same workers in the same run, and to a 12 MP
scan's (goal: under 5 %); the fixed latency of a run (probe, first and last task); the client's serial
cost per task (tasks that do no work, through the same path); and from these measured numbers the
modelled time of the paper's 1,840 scans (184 materials x 10) at 12 MP on 1, 8 and 64 workers.

The machine may be shared: every configuration runs once per round, rounds alternate, the best round
counts, and the load average is printed. On a machine with as many cores as workers, the client and the
scheduler take cores from the workers, so the speed-ups there understate a real cluster's; the idle time
between tasks does not depend on that. The 12 MP scan is a simulated 512 px scan whose photos are
enlarged to 3024 x 4032 (simulating one at that size takes minutes); extraction time depends on the
number of pixels, not on their content.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from distributed import Client, LocalCluster, get_task_stream

from features import FeatureSpace, ScanSource, extract, extract_many
from scanner.runtime import cluster
from scanner.runtime.executors import DaskRuntime, using
from scanner.scan import Scan
from scanner.simulation.database import synthetic_database

MATERIALS = ["polyurethane-foam", "mild-steel-brushed", "granite-polished", "oak-planed", "sandpaper-p80",
             "float-glass"]
SCANS_PER_MATERIAL = 4
SIZE = (512, 512)
WORKERS = 2
ROUNDS = 3
PAPER_SCANS = 184 * 10
PAPER_PHOTO = (3024, 4032)
MODELLED_WORKERS = (1, 8, 64)
OVERHEAD_GOAL = 0.05


@dataclasses.dataclass(frozen=True)
class Run:
    """One timed extraction; on a cluster also the workers' compute and idle time from the task stream."""

    seconds: float
    space: FeatureSpace
    compute: float = math.nan
    """Seconds the workers spent in the tasks, summed."""
    idle: float = math.nan
    """Seconds the workers sat idle between their first and their last task, summed."""
    latency: float = math.nan
    """Seconds of the run before the first task started and after the last one ended."""


def timed(run: Callable[[], FeatureSpace]) -> Run:
    start = time.perf_counter()
    space = run()
    return Run(time.perf_counter() - start, space)


def timed_on(client: Client, run: Callable[[], FeatureSpace]) -> Run:
    with get_task_stream(client=client) as stream:
        start = time.time()
        space = run()
        seconds = time.time() - start
    per_worker: dict[str, list[tuple[float, float]]] = {}
    for task in stream.data:
        for interval in task["startstops"]:
            if interval["action"] == "compute" and str(task["key"]).startswith("texplorer-extract"):
                per_worker.setdefault(task["worker"], []).append((interval["start"], interval["stop"]))
    compute = sum(stop - begin for intervals in per_worker.values() for begin, stop in intervals)
    idle = sum(_gaps(sorted(intervals)) for intervals in per_worker.values())
    first = min(begin for intervals in per_worker.values() for begin, _ in intervals)
    last = max(stop for intervals in per_worker.values() for _, stop in intervals)
    return Run(seconds, space, compute, idle, seconds - (last - first))


def _gaps(intervals: list[tuple[float, float]]) -> float:
    return sum(max(0.0, nxt[0] - prev[1]) for prev, nxt in zip(intervals, intervals[1:], strict=False))


def best_of(runs: dict[str, Callable[[], Run]], rounds: int) -> dict[str, Run]:
    """The fastest run of each configuration over ``rounds`` alternating rounds."""
    best: dict[str, Run] = {}
    for _ in range(rounds):
        for name, run in runs.items():
            result = run()
            if name not in best or result.seconds < best[name].seconds:
                best[name] = result
    return best


def _no_work(source: ScanSource) -> tuple[None, str]:
    return None, "not extracted"


def on(client: Client, sources: list[ScanSource], ship_data: bool = False) -> FeatureSpace:
    """The features of ``sources`` with the cluster of ``client`` as the current runtime."""
    with using(DaskRuntime(client, ship_data=ship_data)):
        return extract_many(sources, progress=False)


def client_cost_per_task(client: Client, sources: list[ScanSource]) -> float:
    """Seconds per task of tasks that do nothing, through the path extraction takes (best of 3)."""
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        for _ in cluster.extract(client, _no_work, sources, range(len(sources)), lambda _: None,
                                 version=lambda: "x", ship_data=False):
            pass
        best = min(best, time.perf_counter() - start)
    return best / len(sources)


def enlarged(scan: Scan, size: tuple[int, int]) -> Scan:
    """``scan`` with its photos resized to ``size`` (height, width)."""
    images = {name: cv2.resize(photo, (size[1], size[0]), interpolation=cv2.INTER_LINEAR)
              for name, photo in scan.images.items()}
    return dataclasses.replace(scan, images=images)


def paper_scan_seconds(scan: Scan) -> float:
    big = enlarged(scan, PAPER_PHOTO)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        extract(big)
        start = time.perf_counter()
        extract(big)
        return time.perf_counter() - start


def modelled_seconds(workers: int, per_scan: float, overhead: float, latency: float, client_cost: float) -> float:
    """1,840 scans on ``workers``: the run's latency plus rounds of one scan per worker, each followed by
    the idle time between tasks, unless the client's serial handling of the results is slower."""
    return latency + max(math.ceil(PAPER_SCANS / workers) * (per_scan + overhead), PAPER_SCANS * client_cost)


def duration(seconds: float) -> str:
    return f"{seconds / 3600:5.2f} h" if seconds >= 3600 else f"{seconds / 60:5.1f} min"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        db = synthetic_database(Path(tmp) / "db", MATERIALS, scans_per_material=SCANS_PER_MATERIAL,
                                image_size=SIZE, progress=False)
        records = db.records()
        sources = [ScanSource(r.scan_id, r.label, r.sample_id, stored, cache_key=r.content_hash)
                   for r, stored in zip(records, db.stored_scans(records), strict=True)]
        n = len(sources)
        shipped_mb = sum(s.load.shipped().nbytes for s in sources) / n / 1e6
        start = time.perf_counter()
        with LocalCluster(n_workers=WORKERS, threads_per_worker=1, processes=True, dashboard_address=None,
                          host="127.0.0.1") as local, Client(local) as client:
            client.wait_for_workers(WORKERS)
            started = time.perf_counter() - start
            print(f"{n} scans ({SIZE[0]}x{SIZE[1]} photos), {os.cpu_count()} cores, load average "
                  f"{os.getloadavg()[0]:.1f} at the start; LocalCluster of {WORKERS} worker processes started "
                  f"in {started:.1f} s (not counted)")
            cluster_name = f"LocalCluster ({WORKERS} workers)"
            runs = best_of({
                "serial (1 process)": lambda: timed(lambda: extract_many(sources, workers=1, progress=False)),
                f"local pool ({WORKERS} processes, kept)": lambda: timed(
                    lambda: extract_many(sources, workers=WORKERS, progress=False)),
                cluster_name: lambda: timed_on(client, lambda: on(client, sources)),
                "  same, files shipped": lambda: timed_on(client, lambda: on(client, sources, ship_data=True)),
            }, ROUNDS)
            client_cost = client_cost_per_task(client, sources)
        serial = next(iter(runs.values()))
        for name, run in runs.items():
            if run.space.X.tobytes() != serial.space.X.tobytes() or run.space.scan_ids != serial.space.scan_ids:
                raise SystemExit(f"{name}: features differ from the serial run")
        print(f"best of {ROUNDS} rounds, every result equal to the serial one bit for bit "
              f"(load average {os.getloadavg()[0]:.1f} now):")
        for name, run in runs.items():
            print(f"  {name:28s} {run.seconds:6.2f} s   speed-up {serial.seconds / run.seconds:4.2f}x")
        big = paper_scan_seconds(db.get(records[0].scan_id))
        print(f"\none scan: {serial.seconds / n * 1e3:.0f} ms at {SIZE[0]}x{SIZE[1]} (serial run), {big:.2f} s with "
              f"{PAPER_PHOTO[0]}x{PAPER_PHOTO[1]} photos")
        on_cluster = runs[cluster_name]
        overhead, per_scan = on_cluster.idle / n, on_cluster.compute / n
        verdict = "met" if overhead / per_scan < OVERHEAD_GOAL else "NOT met"
        print(f"scheduling overhead per scan on the cluster: workers idle between tasks {overhead * 1e3:.1f} ms per "
              f"scan = {overhead / per_scan:.1%} of a scan's extraction on the same workers "
              f"({per_scan * 1e3:.0f} ms; goal < {OVERHEAD_GOAL:.0%}: {verdict}), {overhead / big:.2%} of a 12 MP "
              f"scan's")
        print(f"fixed latency of a cluster run (probe, first task, last result): {on_cluster.latency:.2f} s")
        print(f"client's serial cost per task (tasks doing nothing): {client_cost * 1e3:.1f} ms, at most "
              f"{1 / client_cost:.0f} scans/s whatever the cluster's size")
        print(f"files shipped per scan: {shipped_mb:.2f} MB at {SIZE[0]} px, about "
              f"{shipped_mb * np.prod(PAPER_PHOTO) / np.prod(SIZE):.0f} MB at 12 MP (scaled by pixels): at "
              f"125 MB/s (1 Gbit/s) the client's link alone allows "
              f"{125 / (shipped_mb * np.prod(PAPER_PHOTO) / np.prod(SIZE)):.1f} scans/s")
        print(f"\nmodelled: {PAPER_SCANS} scans at 12 MP, workers reading shared storage")
        for workers in MODELLED_WORKERS:
            seconds = modelled_seconds(workers, big, overhead, on_cluster.latency, client_cost)
            print(f"  {workers:3d} worker(s)  {duration(seconds)}   ({on_cluster.latency:.1f} s + "
                  f"{math.ceil(PAPER_SCANS / workers)} x ({big:.2f} s + {overhead * 1e3:.1f} ms))")


if __name__ == "__main__":
    main()
