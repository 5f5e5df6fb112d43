"""Storage benchmark: .mat save/load against numpy.save/load of the same arrays, the .mat file's compression
(ISA-L) against the standard library's zlib at the same level, the photos' PNG encoding against OpenCV's
default and against our options without the fixed row filter, catalog queries at 10,000 scans, and cached
features served with the files' stat records against hashing every file (the files verified either way).

Ratios are against references run in the same process, so they compare across machines.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
import zlib
from pathlib import Path
from unittest import mock

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import make_meta, make_scan  # noqa: E402
from timing import best_time  # noqa: E402

from scanner.photo import encode_png  # noqa: E402
from scanner.simulation import synthetic_scan  # noqa: E402
from scanner.storage import matfile, stored  # noqa: E402
from scanner.storage.database import Database, FileEntry  # noqa: E402
from scanner.storage.matfile import encode_mat, load_scan, save_scan, scan_to_variables  # noqa: E402
from scanner.workflows.database import extract_database  # noqa: E402


def bench_mat(folder: Path) -> None:
    scan = make_scan(seconds=5.0, images=False)  # full-length traces: 5 s at the scanner's rates, no photos
    arrays = {name: trace.data for name, trace in scan.traces.items()}
    megabytes = sum(a.nbytes for a in arrays.values()) / 1e6

    def np_save() -> None:
        with open(folder / "ref.npz", "wb") as handle:
            np.savez(handle, **arrays)

    def np_load() -> None:
        with np.load(folder / "ref.npz") as data:
            for name in data.files:
                data[name]

    t_save = best_time(lambda: save_scan(scan, folder / "s.mat"))
    t_load = best_time(lambda: load_scan(folder / "s.mat", images=False))
    t_np_save, t_np_load = best_time(np_save), best_time(np_load)

    def np_save_compressed() -> None:
        with open(folder / "ref.npz", "wb") as handle:
            np.savez_compressed(handle, **arrays)

    t_np_compressed = best_time(np_save_compressed)
    size = (folder / "s.mat").stat().st_size / 1e6
    print(f".mat scan with {len(arrays)} channels, {megabytes:.1f} MB of samples, {size:.1f} MB on disk (compressed)")
    print(f"  save  {t_save * 1e3:7.1f} ms  {megabytes / t_save:6.1f} MB/s   numpy.savez {t_np_save * 1e3:6.1f} ms"
          f"   ratio {t_save / t_np_save:5.1f}x;  numpy.savez_compressed {t_np_compressed * 1e3:6.1f} ms"
          f"   ratio {t_save / t_np_compressed:5.1f}x  (save includes fsync)")
    print(f"  load  {t_load * 1e3:7.1f} ms  {megabytes / t_load:6.1f} MB/s   numpy.load  {t_np_load * 1e3:6.1f} ms"
          f"   ratio {t_load / t_np_load:5.1f}x  (includes validation)")


def bench_compression() -> None:
    """A simulated scan's variables encoded as save_scan does (zlib streams written by ISA-L) against the
    same encoding with the standard library's zlib at the same level."""
    scan = synthetic_scan("granite-polished", seed=0, image_size=(64, 64))
    variables = scan_to_variables(scan, Path("scan.mat"))
    isal = encode_mat(variables)
    t_isal = best_time(lambda: encode_mat(variables))
    with mock.patch.object(matfile, "isal_zlib", zlib):
        standard = encode_mat(variables)
        t_zlib = best_time(lambda: encode_mat(variables))
    print(f".mat encoding of a simulated scan (level {matfile.COMPRESSION_LEVEL}): ISA-L {t_isal * 1e3:6.1f} ms "
          f"{len(isal) / 1e6:5.2f} MB;  zlib {t_zlib * 1e3:6.1f} ms {len(standard) / 1e6:5.2f} MB;  "
          f"time ratio {t_isal / t_zlib:4.2f}x, size ratio {len(isal) / len(standard):4.2f}x")


def bench_png() -> None:
    """encode_png (zlib 1, Z_RLE, the "average" row filter) against OpenCV's default PNG options and against
    the same options with libpng's adaptive filter, on simulated 512 px photos and on a 2048 px camera-like
    photo (scikit-image's coffee, scaled up, with 2 counts of sensor noise)."""
    from skimage import data, transform  # noqa: PLC0415 (scikit-image loads only for this benchmark)

    simulated = list(synthetic_scan("oak-planed", seed=0, image_size=(512, 512)).images.values())
    coffee = transform.resize(data.coffee(), (2048, 3072), order=1) * 255
    noisy = np.clip(coffee + np.random.default_rng(0).normal(0.0, 2.0, coffee.shape), 0, 255).astype(np.uint8)
    adaptive = [cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]

    def opencv(rgb: np.ndarray, options: list[int]) -> bytes:
        return cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), options)[1].tobytes()

    for name, images in (("simulated 512 px photo", simulated), ("2048 x 3072 camera-like photo", [noisy])):
        ours = best_time(lambda images=images: [encode_png(i) for i in images]) / len(images)
        size = np.mean([len(encode_png(i)) for i in images]) / 1e6
        line = f"PNG of a {name}: encode_png {ours * 1e3:6.1f} ms {size:5.2f} MB"
        for label, options in (("OpenCV default", []), ("adaptive filter", adaptive)):
            t = best_time(lambda images=images, options=options: [opencv(i, options) for i in images]) / len(images)
            other = np.mean([len(opencv(i, options)) for i in images]) / 1e6
            line += f";  {label} {t * 1e3:6.1f} ms {other:5.2f} MB (time {ours / t:4.2f}x, size {size / other:4.2f}x)"
        print(line)


def fill_catalog(db: Database, n: int) -> None:
    template = make_meta()
    labels = [f"C{c}S{s}M1P{p}X1" for c in range(1, 9) for s in range(1, 4) for p in range(1, 3)]
    conn = db._conn  # rows only: the benchmark is about queries, not about writing 10,000 files
    conn.execute("BEGIN IMMEDIATE")
    for i in range(n):
        label = labels[i % len(labels)]
        meta = dataclasses.replace(template, label=label, sample_id=f"sample-{i // 5:05d}", scan_index=i % 5 + 1,
                                   session_id=f"session-{i // 50:04d}", operator=f"op{i % 7}")
        path = f"scans/{label}/{meta.sample_id}/{meta.scan_id}.mat"
        db._insert(conn, meta, [FileEntry(path, "mat", "0" * 64, 1)])
    conn.execute("COMMIT")


def bench_catalog(folder: Path, n: int = 10_000) -> None:
    db = Database(folder / "db")
    start = time.perf_counter()
    fill_catalog(db, n)
    print(f"catalog of {n} scans filled in {time.perf_counter() - start:.1f} s")
    raw = db._conn
    queries = {
        "record(scan_id)": (lambda i: db.record(f"sample-{i % (n // 5):05d}-001"),
                           lambda i: raw.execute("SELECT * FROM scans WHERE scan_id = ?",
                                                 (f"sample-{i % (n // 5):05d}-001",)).fetchone()),
        "records(sample=...)": (lambda i: db.records(sample=f"sample-{i % (n // 5):05d}"),
                                lambda i: raw.execute("SELECT * FROM scans WHERE sample_id = ?",
                                                      (f"sample-{i % (n // 5):05d}",)).fetchall()),
        "records(label='C6S2')": (lambda i: db.records(label="C6S2"),
                                  lambda i: raw.execute("SELECT * FROM scans WHERE label LIKE 'C6S2M%'").fetchall()),
        "records(operator=...)": (lambda i: db.records(operator=f"op{i % 7}"),
                                  lambda i: raw.execute("SELECT * FROM scans WHERE operator = ?",
                                                        (f"op{i % 7}",)).fetchall()),
    }
    for name, (ours, reference) in queries.items():
        count = 200 if "label" in name or "operator" in name else 5000
        t_ours = best_time(lambda ours=ours, count=count: [ours(i) for i in range(count)], 3) / count
        t_ref = best_time(lambda reference=reference, count=count: [reference(i) for i in range(count)], 3) / count
        print(f"  {name:<24} {1 / t_ours:9.0f} queries/s   raw sqlite3 {1 / t_ref:9.0f}/s   "
              f"ratio {t_ours / t_ref:4.1f}x")
    db.close()


CACHED_MATERIALS = ("granite-polished", "oak-planed", "cotton-woven", "mild-steel-brushed")


def bench_cached_features(folder: Path, scans: int = 12, size: int = 512) -> None:
    """Serve the cached features of ``scans`` stored scans with ``size`` px photos, as a web page does: with the
    files' stat records, and (reference) with every file hashed, the records taken away."""
    db = Database(folder / "cached")
    for i in range(scans):
        material, index = CACHED_MATERIALS[i % len(CACHED_MATERIALS)], i // len(CACHED_MATERIALS) + 1
        db.add(synthetic_scan(material, seed=i, scan_index=index, image_size=(size, size)))
    records = db.records()
    extract_database(db, records=records, workers=1, progress=False)  # fills the feature cache
    time.sleep(stored.RACY_SECONDS + 0.1)  # the files settle: their stat records can be kept
    extract_database(db, records=records, workers=1, progress=False)  # checks the hashes once, keeps the records

    def serve() -> None:
        space = extract_database(db, records=records, workers=1, progress=False)
        assert len(space) == scans and not space.failed

    t_stat = best_time(serve, 5)
    with mock.patch.object(stored, "RACY_SECONDS", float("inf")):
        with db._transaction() as conn:
            conn.execute("DELETE FROM file_stats")
        t_hash = best_time(serve, 5)
    megabytes = sum(p.stat().st_size for p in (folder / "cached").rglob("*") if p.is_file()) / 1e6
    print(f"cached features of {scans} scans ({size} px photos, {megabytes:.0f} MB of files): stat records "
          f"{t_stat * 1e3:6.1f} ms, every file hashed (reference) {t_hash * 1e3:6.1f} ms, "
          f"ratio {t_stat / t_hash:5.3f}x")
    db.close()


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        bench_mat(Path(tmp))
        bench_compression()
        bench_png()
        bench_catalog(Path(tmp))
        bench_cached_features(Path(tmp))


if __name__ == "__main__":
    main()
