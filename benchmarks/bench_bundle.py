"""Export, import and replay benchmark (docs/export.md).

- export of a 120-scan simulated database (24 materials x 5 scans, 256 x 256 photos to keep generation
  short) as a folder and as a zip, in MB/s of bundle, against a plain copy of the same ``scans/`` folder
  (``shutil.copytree``) and a plain zip of it (``shutil.make_archive``) in the same run; features come from
  the warm feature cache (the cold extraction is reported once); and the share of the standard metadata
  (RO-Crate, Croissant, Frictionless schemas, channel tables): the export's time against its time without
  them, measured inside the same export (``ExportReport.metadata_seconds``);
- import of both bundles into empty databases (verify everything, then merge) against ``copytree`` and
  ``zipfile.extractall`` of the same data;
- replay throughput in scans per second on one and two workers, against loading the same scans alone.

Our side fsyncs every file it writes (crash safety); the references do not.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import shutil  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import zipfile  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

from scanner.replay import replay, scan_paths  # noqa: E402
from scanner.simulation import load_materials  # noqa: E402
from scanner.simulation.database import synthetic_database  # noqa: E402
from scanner.storage.bundle import import_bundle  # noqa: E402
from scanner.storage.database import Database  # noqa: E402
from scanner.storage.matfile import load_scan  # noqa: E402
from scanner.workflows.exchange import export_database  # noqa: E402

MATERIALS = 24
SCANS_PER_MATERIAL = 5
IMAGE_SIZE = (256, 256)
REPLAYED = 24


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def folder_bytes(folder: Path) -> int:
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def line(what: str, megabytes: float, seconds: float, reference: str, ref_seconds: float) -> None:
    print(f"  {what:<16} {seconds:6.2f} s {megabytes / seconds:7.1f} MB/s   {reference:<20} "
          f"{ref_seconds:6.2f} s {megabytes / ref_seconds:7.1f} MB/s   ratio {seconds / ref_seconds:5.2f}x")


def bench_export_import(tmp: Path) -> Database:
    slugs = list(load_materials())[:MATERIALS]
    seconds, db = timed(lambda: synthetic_database(tmp / "db", materials=slugs,
                                                   scans_per_material=SCANS_PER_MATERIAL,
                                                   image_size=IMAGE_SIZE, progress=False))
    scans_mb = folder_bytes(tmp / "db" / "scans") / 1e6
    print(f"database: {len(db)} scans, {scans_mb:.1f} MB of .mat and photos, simulated in {seconds:.1f} s")

    cold, _ = timed(lambda: export_database(db, tmp / "cold", license="CC0-1.0", workers=2))
    print(f"  first export, features extracted on 2 workers: {cold:.1f} s")
    t_folder, folder = timed(lambda: export_database(db, tmp / "bundle", license="CC0-1.0", workers=2))
    t_zip, archive = timed(lambda: export_database(db, tmp / "bundle.zip", license="CC0-1.0", workers=2))
    t_copy, _ = timed(lambda: shutil.copytree(tmp / "db" / "scans", tmp / "copy" / "scans"))
    t_make, _ = timed(lambda: shutil.make_archive(str(tmp / "plain"), "zip", tmp / "db", "scans"))
    bundle_mb = folder.bytes / 1e6
    print(f"export ({bundle_mb:.1f} MB bundle; zip {archive.path.stat().st_size / 1e6:.1f} MB, "
          f"plain zip {(tmp / 'plain.zip').stat().st_size / 1e6:.1f} MB), features from the cache:")
    line("export folder", bundle_mb, t_folder, "shutil.copytree", t_copy)
    line("export zip", bundle_mb, t_zip, "shutil.make_archive", t_make)
    print("standard metadata (RO-Crate, Croissant, Frictionless schemas, channel tables), inside the export:")
    for what, report in (("export folder", folder), ("export zip", archive)):
        without = report.seconds - report.metadata_seconds
        print(f"  {what:<16} {report.seconds:6.2f} s with, {without:6.2f} s without ({report.metadata_seconds:.3f} s "
              f"of metadata)   ratio {report.seconds / without:5.2f}x")

    t_import_folder, report = timed(lambda: import_bundle(Database(tmp / "from-folder"), folder.path))
    t_import_zip, _ = timed(lambda: import_bundle(Database(tmp / "from-zip"), archive.path))
    t_copy_back, _ = timed(lambda: shutil.copytree(folder.path, tmp / "copy-back"))

    def unzip() -> None:
        with zipfile.ZipFile(tmp / "plain.zip") as plain:
            plain.extractall(tmp / "unzipped")

    t_unzip, _ = timed(unzip)
    print(f"import into an empty database ({len(report.added)} scans added, verified before merging):")
    line("import folder", bundle_mb, t_import_folder, "shutil.copytree", t_copy_back)
    line("import zip", bundle_mb, t_import_zip, "zipfile.extractall", t_unzip)
    return db


def bench_replay(db: Database) -> None:
    paths = scan_paths([db.root / record.path for record in db.records()[:REPLAYED]])
    t_load, _ = timed(lambda: [load_scan(path) for path in paths])
    print(f"replay of {len(paths)} stored scans (load, preprocess, 193 features):")
    for workers in (1, 2):
        seconds, space = timed(lambda workers=workers: replay(paths, workers=workers, progress=False))
        assert not space.failed
        print(f"  {workers} worker(s)  {len(paths) / seconds:6.2f} scans/s   "
              f"load_scan alone {len(paths) / t_load:6.1f} scans/s   ratio {seconds / t_load:5.1f}x")


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="bench-bundle-") as tmp:
        db = bench_export_import(Path(tmp))
        bench_replay(db)


if __name__ == "__main__":
    main()
