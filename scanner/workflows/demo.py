"""The simulated side: a simulated database whose features are extracted while each scan is in memory, and
the compilation of every feature kernel once (``make install``)."""

from __future__ import annotations

import os
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

from features import code_version, extract
from scanner.runtime.memory import keep_freed_memory
from scanner.scan import Scan
from scanner.simulation.database import synthetic_database
from scanner.simulation.scans import synthetic_scan
from scanner.storage.database import Database
from scanner.storage.matfile import load_scan, save_scan


def simulated_database(root: str | os.PathLike[str], **options: Any) -> Database:
    """:func:`scanner.simulation.database.synthetic_database` (``options`` are its own) with each scan's
    features extracted by the process that simulated it, from the scan in memory, and stored in the
    feature cache once the scan is catalogued: the features stage that follows (:func:`extract_database`)
    then reads no file back, only verifies the files' hashes. The workers keep the memory a scan frees for
    the next (:func:`scanner.runtime.memory.keep_freed_memory`; docs/performance.md). The values are those an
    extraction from the stored files gives (the ``.mat`` and PNG files are lossless), and a scan whose
    extraction fails here is simply left to that stage, which reports it."""
    version = code_version()

    def cache(db: Database, scan_id: str, values: dict[str, float] | None) -> None:
        if values is not None:
            db.store_features(db.record(scan_id).content_hash, version, values)

    return synthetic_database(root, analyse=_features_or_none, on_stored=cache, worker_start=keep_freed_memory,
                              **options)


def _features_or_none(scan: Scan) -> dict[str, float] | None:
    """The default features of ``scan`` (missing-channel warnings are the features stage's to report), or
    None if the extraction fails."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return extract(scan)
    except Exception:  # noqa: BLE001 - the features stage extracts the scan again and names the failure
        return None

# -- compile the feature kernels once ---------------------------------------------------------------

KERNEL_SCANS = (("cotton-woven", 0.0), ("granite-polished", 1.0))
"""The simulated scans :func:`compile_kernels` extracts: (material, probability that the fold step is
skipped), a folded textile and a rigid stone whose fold step is skipped, between them every step's kernels."""


def compile_kernels(image_size: int = 384) -> float:
    """Extract the features of the :data:`KERNEL_SCANS`, each in memory and read back from its stored files,
    so that numba compiles every kernel the features use (for the array layouts of both paths) and writes it
    into its cache (``__pycache__`` beside the code); returns the seconds it took.

    ``make install`` runs this, so that the first ``make demo`` does not compile in each of its worker
    processes at once (docs/performance.md); a later process loads the cached machine code."""
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for index, (material, skip) in enumerate(KERNEL_SCANS):
            scan = synthetic_scan(material, seed=index, image_size=(image_size, image_size),
                                  fold_skip_probability=skip)
            path = Path(folder) / f"{material}.mat"
            save_scan(scan, path)
            extract(scan)
            extract(load_scan(path))
    return time.perf_counter() - started
