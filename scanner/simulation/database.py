"""A simulated database: many synthetic scans stored through :class:`scanner.storage.database.Database` (``texplorer
demo``). Kept apart from the simulator's physics so that the simulated devices do not depend on storage."""

from __future__ import annotations

import concurrent.futures
import os
import sys
from collections.abc import Iterable
from pathlib import Path

from tqdm import tqdm

from scanner.scan import Scan
from scanner.simulation.scans import scan_jobs, simulate_one
from scanner.storage.database import Database


def synthetic_database(root: str | Path, materials: Iterable[str] | None = None, scans_per_material: int = 5,
                       seed: int = 0, image_size: tuple[int, int] = (512, 512), progress: bool = True,
                       fold_skip_probability: float = 0.5, workers: int | None = None,
                       samples_per_material: int = 1) -> Database:
    """Simulate scans (see :func:`synthetic_scans`) into ``scanner.storage.database.Database(root)``; returns it.

    Scans are simulated in ``workers`` processes (default: the number of cores) and added by this process
    in a fixed order. Scans whose id is already in the database are kept, not simulated again, so an
    interrupted demo resumes where it stopped (delete the folder to start over with another seed).
    """
    all_jobs = scan_jobs(materials, samples_per_material, scans_per_material, seed, image_size, fold_skip_probability)
    database = Database(root)
    stored = {record.scan_id for record in database.records()}
    jobs = [job for job in all_jobs if job.scan_id not in stored]
    bar = tqdm(total=len(jobs), desc="simulating scans", unit="scan", file=sys.stderr,
               disable=None if progress else True, leave=False)
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1))
    if workers == 1:
        scans: Iterable[Scan] = map(simulate_one, jobs)
        for scan in scans:
            database.add(scan)
            bar.update(1)
    else:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
            for scan in pool.map(simulate_one, jobs):
                database.add(scan)
                bar.update(1)
    bar.close()
    return database
