"""A simulated database: many synthetic scans stored through :class:`scanner.storage.database.Database` (``texplorer
demo``). Kept apart from the simulator's physics so that the simulated devices do not depend on storage."""

from __future__ import annotations

import concurrent.futures
import functools
import os
import sys
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import cv2
from tqdm import tqdm

from scanner.runtime.processes import end_with_parent
from scanner.scan import Scan, ScanMeta
from scanner.simulation.scans import _Job, scan_jobs, simulate_one
from scanner.storage.database import STAGING_PREFIX, Database, file_roles
from scanner.storage.files import owned_folder, temp_path_for
from scanner.storage.matfile import save_scan

Staged = tuple[ScanMeta, dict[str, Path], Any]
"""A written scan: its meta, its files by role, and what ``analyse`` made of it (None without)."""
BATCH = 8
"""Scans catalogued per transaction: an interrupted demo loses at most this many finished scans."""


def synthetic_database(root: str | Path, materials: Iterable[str] | None = None, scans_per_material: int = 5,
                       seed: int = 0, image_size: tuple[int, int] = (512, 512), progress: bool = True,
                       fold_skip_probability: float = 0.5, workers: int | None = None,
                       samples_per_material: int = 1, analyse: Callable[[Scan], Any] | None = None,
                       on_stored: Callable[[Database, str, Any], None] | None = None,
                       worker_start: Callable[[], object] | None = None) -> Database:
    """Simulate scans (see :func:`synthetic_scans`) into ``scanner.storage.database.Database(root)``.

    Scans are simulated and written (``.mat`` and photos, the costly encoding) in ``workers`` processes
    (default: the number of cores) into a staging folder on the database's file system, then catalogued by
    this process in a fixed order, :data:`BATCH` at a time (:meth:`~scanner.storage.database.Database.add_written`),
    so the files and the catalog are exactly those :meth:`~scanner.storage.database.Database.add` writes.
    Scans whose id is already in the database are kept, not simulated again, so an interrupted demo resumes
    where it stopped (delete the folder to start over with another seed).

    Parameters
    ----------
    root : str or pathlib.Path
        The database folder (created if missing).
    materials : iterable of str, optional
        Material slugs of ``scanner/data/materials.toml``; default the whole library.
    scans_per_material : int
        Scans of each sample.
    seed : int
        Seed of the whole database: the same arguments give the same scans.
    image_size : (int, int)
        Photo height and width in pixels.
    progress : bool
        Show a progress bar.
    fold_skip_probability : float
        How often the simulated operator skips the fold of a rigid sample.
    workers : int, optional
        Processes (default: the number of cores).
    samples_per_material : int
        Pieces per material (sample ids ``<slug>-01``, ``<slug>-02``, ...).
    analyse : callable, optional
        Run on each simulated scan in the process that simulated it, while the scan is in memory (a
        module-level function: it is pickled to the workers), e.g. feature extraction, which then reads no
        file back (:func:`scanner.workflows.demo.simulated_database`).
    on_stored : callable, optional
        ``on_stored(database, scan_id, analysed)`` in this process once the scan is catalogued, with what
        ``analyse`` returned (None without ``analyse``).
    worker_start : callable, optional
        Run once in each worker process before its first scan (a module-level function), e.g. telling the
        allocator to keep the memory a scan frees for the next one (:func:`scanner.workflows.demo.simulated_database`).

    Returns
    -------
    Database
    """
    all_jobs = scan_jobs(materials, samples_per_material, scans_per_material, seed, image_size, fold_skip_probability)
    database = Database(root)
    stored = {record.scan_id for record in database.records()}
    jobs = [job for job in all_jobs if job.scan_id not in stored]
    bar = tqdm(total=len(jobs), desc="simulating scans", unit="scan", file=sys.stderr,
               disable=None if progress else True, leave=False)
    workers = max(1, min(workers or os.cpu_count() or 1, len(jobs) or 1))
    with owned_folder(temp_path_for(database.root / STAGING_PREFIX.lstrip("."))) as staging:
        batch: list[Staged] = []
        for staged in _staged_scans(jobs, staging, workers, analyse, worker_start):
            batch.append(staged)
            bar.update(1)
            if len(batch) == BATCH:
                _catalogue(database, batch, on_stored)
                batch = []
        if batch:
            _catalogue(database, batch, on_stored)
    bar.close()
    return database


def _catalogue(database: Database, batch: list[Staged], on_stored: Callable[[Database, str, Any], None] | None) -> None:
    """Catalogue a batch of written scans in one transaction, then hand each one's analysis to ``on_stored``."""
    scan_ids = database.add_written([(meta, files) for meta, files, _ in batch])
    if on_stored is not None:
        for scan_id, (_, _, analysed) in zip(scan_ids, batch, strict=True):
            on_stored(database, scan_id, analysed)


def _staged_scans(jobs: list[_Job], staging: Path, workers: int, analyse: Callable[[Scan], Any] | None = None,
                  worker_start: Callable[[], object] | None = None) -> Iterator[Staged]:
    """Each job's scan written into ``staging`` (and analysed), in job order; ``worker_start`` runs first in
    each worker process (not in this process when ``workers`` is 1: it would outlive the call)."""
    work = functools.partial(simulate_into, folder=staging, analyse=analyse)
    if workers == 1:
        yield from map(work, jobs)
        return
    # The workers already use every core: OpenCV's threads in each would only wait for each other. Set in
    # this process before forking (changing OpenCV's pool in a forked child can deadlock), restored after.
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        with concurrent.futures.ProcessPoolExecutor(max_workers=workers, initializer=_start_worker,
                                                    initargs=(os.getpid(), worker_start)) as pool:
            yield from pool.map(work, jobs)
    finally:
        cv2.setNumThreads(threads)


def _start_worker(parent: int, worker_start: Callable[[], object] | None) -> None:
    """A simulation worker's first step: end with ``parent``, then ``worker_start()``."""
    end_with_parent(parent)
    if worker_start is not None:
        worker_start()


def simulate_into(job: _Job, folder: Path, analyse: Callable[[Scan], Any] | None = None) -> Staged:
    """Simulate one job's scan and write its files into ``folder``: its meta, its files by role, and
    ``analyse(scan)`` (None without)."""
    scan = simulate_one(job)
    mat_path = folder / f"{scan.scan_id}.mat"
    save_scan(scan, mat_path)
    return (scan.meta, {role: path for path, role in file_roles(mat_path, scan)},
            None if analyse is None else analyse(scan))
