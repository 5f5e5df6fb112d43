"""The scan database (docs/database.md): catalog + files, check, rebuild, concurrency and crash safety."""

from __future__ import annotations

import dataclasses
import os
import re
import sqlite3
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import make_scan, png_bomb

from scanner.cli import EXIT_PROBLEMS, main
from scanner.storage import stored
from scanner.storage.database import Database, DatabaseError
from scanner.storage.matfile import encode_mat, save_scan, scan_to_variables
from scanner.storage.stored import ChangedSinceStored
from taxonomy.labels import LabelError


def _fill(db: Database) -> None:
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, session_id="s-1", operator="ab"))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2", operator="cd"))
    db.add(make_scan(2, label="C6S1M1P3X1", sample_id="granite-02", scan_index=1, session_id="s-2", operator="cd"))
    db.add(make_scan(3, label="C7S1M1P8X1", sample_id="steel-01", scan_index=1, session_id="s-3", operator="ab",
                     rigid=True, drop=("f_fold", "alpha_f")))


def test_add_get_and_list_with_filters(tmp_path):
    db = Database(tmp_path / "db")
    _fill(db)
    assert len(db) == 4
    assert db.summary() == {"materials": 3, "samples": 3, "sessions": 3, "scans": 4, "files": 16}
    assert [r.scan_id for r in db.records(label="C6")] == ["granite-01-001", "granite-01-002", "granite-02-001"]
    assert [r.scan_id for r in db.records(label="C6S1M1P3X1")] == ["granite-02-001"]
    assert [r.scan_id for r in db.records(sample="granite-01")] == ["granite-01-001", "granite-01-002"]
    assert [r.scan_id for r in db.records(session="s-2")] == ["granite-01-002", "granite-02-001"]
    assert [r.scan_id for r in db.records(operator="ab")] == ["granite-01-001", "steel-01-001"]
    with pytest.raises(LabelError, match="not a label or class prefix"):  # LIKE wildcards are no codes
        db.records(label="C6_")
    assert db.record("steel-01-001").rigid
    assert db.get("granite-01-002") == make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2",
                                                  operator="cd")
    assert (tmp_path / "db/scans/C6S1M1P2X1/granite-01/granite-01-002.mat").is_file()
    assert db.next_scan_index("granite-01") == 3 and db.next_scan_index("new-sample") == 1
    with pytest.raises(DatabaseError, match="no scan 'nope'"):
        db.record("nope")


def test_add_refuses_duplicates_and_relabelled_samples_without_touching_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    path = tmp_path / "scans/C6S1M1P2X1/granite-01/granite-01-001.mat"
    before = path.read_bytes()
    with pytest.raises(DatabaseError, match="granite-01-001 is already in the database"):
        db.add(make_scan(9, sample_id="granite-01", scan_index=1))
    assert path.read_bytes() == before
    with pytest.raises(DatabaseError, match="sample granite-01 is C6S1M1P2X1 in the database, not C5S1M1P2X1"):
        db.add(make_scan(9, label="C5S1M1P2X1", sample_id="granite-01", scan_index=3))
    assert db.check().ok


def test_check_reports_missing_changed_and_unknown_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    report = db.check()
    assert report.ok and report.checked == 16
    scans = tmp_path / "scans"
    (scans / "C6S1M1P2X1/granite-01/granite-01-001_macro.png").unlink()
    mat = scans / "C6S1M1P3X1/granite-02/granite-02-001.mat"
    data = bytearray(mat.read_bytes())
    data[-1] ^= 0xFF
    mat.write_bytes(bytes(data))
    (scans / "stray.txt").write_text("?")
    report = db.check()
    assert report.missing == ["scans/C6S1M1P2X1/granite-01/granite-01-001_macro.png"]
    assert report.changed == ["scans/C6S1M1P3X1/granite-02/granite-02-001.mat"]
    assert report.unknown == ["scans/stray.txt"] and not report.ok


def test_rebuild_recreates_the_catalog_from_files_alone(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    db.store_features("abc", "1", {"x": 1.0})
    before = [dataclasses.replace(r, added="") for r in db.records()]
    db.close()
    for name in ("catalog.sqlite", "catalog.sqlite-wal", "catalog.sqlite-shm"):
        (tmp_path / name).unlink(missing_ok=True)
    fresh = Database(tmp_path)
    assert len(fresh) == 0
    report = fresh.rebuild()
    assert report.scans == 4 and report.skipped == []
    assert [dataclasses.replace(r, added="") for r in fresh.records()] == before
    assert fresh.check().ok


def test_rebuild_replaces_a_corrupt_catalog_and_skips_bad_files(tmp_path):
    db = Database(tmp_path)
    _fill(db)
    db.close()
    (tmp_path / "catalog.sqlite").write_bytes(b"not sqlite at all " * 500)
    for name in ("catalog.sqlite-wal", "catalog.sqlite-shm"):
        (tmp_path / name).unlink(missing_ok=True)
    (tmp_path / "scans/C9S1M1P1X1/x/x-001.mat").parent.mkdir(parents=True)
    (tmp_path / "scans/C9S1M1P1X1/x/x-001.mat").write_bytes(b"MATLAB 5.0 truncated")
    broken = Database(tmp_path)
    with pytest.raises(DatabaseError, match="catalog is unreadable.*texplorer db rebuild"):
        broken.records()
    report = broken.rebuild()
    assert report.scans == 4
    assert len(report.skipped) == 1 and report.skipped[0].startswith("scans/C9S1M1P1X1/x/x-001.mat: not a readable")
    assert any(p.name.startswith("catalog.sqlite.broken-") for p in tmp_path.iterdir())
    assert len(broken) == 4
    assert (report.quarantine / "scans/C9S1M1P1X1/x/x-001.mat").read_bytes() == b"MATLAB 5.0 truncated"
    assert broken.check().ok and not (tmp_path / "scans/C9S1M1P1X1").exists()


def _forged(path: Path, scan, **meta) -> Path:
    """Write ``scan`` to ``path`` with ``meta`` fields the data model would refuse (a foreign writer)."""
    save_scan(scan, path)
    variables = scan_to_variables(scan, path)
    variables["meta"].update(meta)
    path.write_bytes(encode_mat(variables))
    return path


def test_rebuild_catalogues_every_good_file_and_quarantines_each_bad_one_with_its_reason(tmp_path, capsys):
    db = Database(tmp_path)
    _fill(db)
    good = {r.scan_id: db.get(r.scan_id) for r in db.records()}
    folder = tmp_path / "scans/C6S1M1P2X1/granite-01"
    overflow = _forged(folder / "granite-01-9223372036854775808.mat", make_scan(5), scan_index=2.0**63)
    empty_raw = _forged(folder / "granite-01-007.mat", make_scan(6, scan_index=7), raw_volts=np.zeros((0, 0)))
    bomb = folder / "granite-01-008.mat"
    save_scan(make_scan(7, scan_index=8, image_shape=(8, 8)), bomb)
    (folder / "granite-01-008_disp.png").write_bytes(png_bomb(20_000, 20_000))
    copy = tmp_path / "scans/C6S1M1P2X1/elsewhere/granite-01-001.mat"
    save_scan(good["granite-01-001"], copy)  # a second copy of a stored scan, not at its own path
    (tmp_path / "scans/notes.txt").write_text("the operator's notes: not a scan file, never moved")
    db.close()
    (tmp_path / "catalog.sqlite").write_bytes(b"\x00" * 4096)  # and the catalog is gone too

    assert main(["db", "rebuild", "--db", str(tmp_path)]) == EXIT_PROBLEMS
    out = capsys.readouterr().out
    db = Database(tmp_path)
    assert {r.scan_id for r in db.records()} == set(good)
    assert all(db.get(scan_id) == scan for scan_id, scan in good.items())
    reasons = {line.split(": ", 1)[0].removeprefix("skipped  "): line for line in out.splitlines()
               if line.startswith("skipped  ")}
    assert sorted(reasons) == sorted(db._relative(p) for p in (overflow, empty_raw, bomb, copy))
    assert "meta.scan_index: must be a whole number 1..9999, got 9.22337e+18" in reasons[db._relative(overflow)]
    assert "meta.raw_volts: must be 0 or 1, got a float64 array of shape (0, 0)" in reasons[db._relative(empty_raw)]
    assert "I_disp: photo granite-01-008_disp.png: the image has 400,000,000 pixels" in reasons[db._relative(bomb)]
    assert "scan id granite-01-001 is already in scans/C6S1M1P2X1/granite-01/granite-01-001.mat" in reasons[
        db._relative(copy)]
    quarantine = next((tmp_path / "quarantine").iterdir())
    assert f"4 file(s) skipped and moved with their photos to {quarantine}" in out
    moved = sorted(p.relative_to(quarantine).as_posix() for p in quarantine.rglob("*") if p.is_file())
    assert moved == sorted([db._relative(overflow), *(db._relative(p).replace(".mat", f"_{s}.png")
                                                      for p in (overflow, empty_raw, bomb, copy)
                                                      for s in ("disp", "macro", "illu")),
                            db._relative(empty_raw), db._relative(bomb), db._relative(copy)])
    report = db.check()
    assert report.ok is False and report.unknown == ["scans/notes.txt"] and not report.missing + report.changed
    assert main(["db", "rebuild", "--db", str(tmp_path)]) == 0  # nothing bad is left in scans/
    assert "catalog rebuilt: 4 scan(s), 0 file(s) skipped" in capsys.readouterr().out
    assert (tmp_path / "scans/notes.txt").is_file()


@pytest.mark.parametrize("catalog", ["readable", "corrupt"])
def test_rebuild_keeps_the_photos_of_a_scan_whose_mat_is_gone(tmp_path, catalog):
    db = Database(tmp_path)
    _fill(db)
    (tmp_path / "scans/C6S1M1P2X1/granite-01/granite-01-002.mat").unlink()
    db.close()
    if catalog == "corrupt":
        _corrupt(tmp_path, "random bytes")
    report = Database(tmp_path).rebuild()
    photos = [f"scans/C6S1M1P2X1/granite-01/granite-01-002_{short}.png" for short in ("disp", "illu", "macro")]
    reason = "a photo whose scan's .mat is missing" if catalog == "readable" else "a photo without its .mat"
    assert report.scans == 3 and report.skipped == [f"{photo}: {reason}" for photo in photos]
    assert all((report.quarantine / photo).is_file() for photo in photos)  # moved aside, never deleted
    assert Database(tmp_path).check().ok


def test_a_scan_the_catalog_refuses_is_quarantined_and_the_others_are_catalogued(tmp_path, monkeypatch):
    db = Database(tmp_path)
    _fill(db)
    real_insert = Database._insert

    def refuse_one(self, conn, meta, entries):
        if meta.scan_id == "granite-01-002":
            raise OverflowError("Python int too large to convert to SQLite INTEGER")
        real_insert(self, conn, meta, entries)

    monkeypatch.setattr(Database, "_insert", refuse_one)
    report = db.rebuild()  # the readable-catalog path: one transaction, a savepoint per scan
    assert report.scans == 3 and len(db) == 3
    assert report.skipped == ["scans/C6S1M1P2X1/granite-01/granite-01-002.mat: the catalog refused it "
                              "(Python int too large to convert to SQLite INTEGER)"]
    assert (report.quarantine / "scans/C6S1M1P2X1/granite-01/granite-01-002_disp.png").is_file()
    assert db.check().ok


def _corrupt(root: Path, how: str) -> None:
    for name in ("catalog.sqlite-wal", "catalog.sqlite-shm"):
        (root / name).unlink(missing_ok=True)
    catalog = root / "catalog.sqlite"
    data = bytearray(catalog.read_bytes())
    if how == "zero-length":
        data = bytearray()
    else:  # random bytes over every page but the first: the header still says SQLite
        rng = np.random.default_rng(3)
        data[4096:] = rng.integers(0, 256, len(data) - 4096, dtype=np.uint8).tobytes()
    catalog.write_bytes(bytes(data))


@pytest.mark.parametrize(("how", "reason"), [("zero-length", "catalog is empty (0 bytes) although scans/ holds "
                                                             "scans"),
                                             ("random bytes", "catalog is unreadable (database disk image is "
                                                              "malformed)")])
def test_a_corrupt_catalog_is_never_read_as_a_database_and_names_the_rebuild(tmp_path, capsys, how, reason):
    db = Database(tmp_path)
    _fill(db)
    db.close()
    _corrupt(tmp_path, how)
    broken = Database(tmp_path)
    for call in (broken.records, broken.__len__, broken.summary, broken.check, broken.repair,
                 lambda: broken.add(make_scan(9, sample_id="new-01"))):
        with pytest.raises(DatabaseError, match=re.escape(reason) + ".*run 'texplorer db rebuild'"):
            call()
    assert main(["db", "list", "--db", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("texplorer: error: ") and reason in err and "texplorer db rebuild" in err
    assert len(err.strip().splitlines()) == 1
    assert broken.rebuild().scans == 4 and len(broken) == 4 and broken.check().ok


def test_a_zero_length_catalog_of_a_database_without_scans_is_an_empty_database(tmp_path):
    Database(tmp_path).close()
    for name in ("catalog.sqlite", "catalog.sqlite-wal", "catalog.sqlite-shm"):
        (tmp_path / name).unlink(missing_ok=True)
    (tmp_path / "catalog.sqlite").write_bytes(b"")
    assert len(Database(tmp_path)) == 0


def test_an_add_that_fails_removes_the_files_it_wrote(tmp_path, monkeypatch):
    db = Database(tmp_path)
    _fill(db)
    before = db.stored_files()

    def full_disk(*args, **kwargs):
        raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(Database, "_insert", full_disk)
    with pytest.raises(DatabaseError, match="database or disk is full"):
        db.add(make_scan(5, sample_id="granite-05"))
    assert db.stored_files() == before and not any((tmp_path / ".pending").iterdir())
    assert db.check().ok and db.check().leftovers == []


def test_feature_cache_round_trips_nan(tmp_path):
    db = Database(tmp_path)
    assert db.cached_features("h", "1") is None
    db.store_features("h", "1", {"a": 1.5, "b": float("nan")})
    values = db.cached_features("h", "1")
    assert values["a"] == 1.5 and values["b"] != values["b"]
    assert db.cached_features("h", "2") is None


def test_opening_a_missing_database_without_create_is_a_clear_error(tmp_path):
    with pytest.raises(DatabaseError, match="nothing: no texplorer database here"):
        Database(tmp_path / "nothing", create=False)
    # A folder that is not a database is refused and left as it was; one with scans/ is a database
    # whose catalog can be rebuilt.
    (tmp_path / "other").mkdir()
    with pytest.raises(DatabaseError, match="other: no texplorer database here"):
        Database(tmp_path / "other", create=False)
    assert list((tmp_path / "other").iterdir()) == []
    (tmp_path / "other" / "scans").mkdir()
    assert len(Database(tmp_path / "other", create=False)) == 0


def test_readers_work_while_a_writer_adds(tmp_path):
    db = Database(tmp_path)
    db.add(make_scan(0, sample_id="s-00", images=False))
    errors: list[BaseException] = []
    counts: list[list[int]] = [[], []]
    stop = threading.Event()

    def read(seen: list[int]) -> None:
        reader = Database(tmp_path)
        try:
            while not stop.is_set():
                records = reader.records()
                seen.append(len(records))
                for record in records[-2:]:
                    reader.get(record.scan_id, images=False)
        except BaseException as exc:  # reported to the main thread
            errors.append(exc)
        finally:
            reader.close()

    threads = [threading.Thread(target=read, args=(seen,)) for seen in counts]
    for thread in threads:
        thread.start()
    for i in range(1, 15):
        db.add(make_scan(i, sample_id=f"s-{i:02d}", images=False))
        # Each reader reads at least once between two adds, so reads and writes really interleave,
        # however loaded the machine is: two reads end after the add, so one started after it.
        before = [len(seen) for seen in counts]
        deadline = time.monotonic() + 30
        while any(len(seen) <= n + 1 for seen, n in zip(counts, before, strict=True)) and not errors:
            assert time.monotonic() < deadline, "a reader made no progress while the writer was adding"
            time.sleep(0.001)
    stop.set()
    for thread in threads:
        thread.join()
    assert not errors, errors
    for seen in counts:  # each reader saw the catalog grow, never shrink or break
        assert len(seen) >= 14 and seen == sorted(seen) and seen[0] >= 1 and seen[-1] == 15
    assert len(db) == 15


def test_label_prefix_stops_at_the_class_boundary(tmp_path):
    db = Database(tmp_path)
    db.add(make_scan(0, label="C6S1M1P2X1", sample_id="a", images=False))
    db.add(make_scan(1, label="C60S1M1P2X1", sample_id="b", images=False))
    db.add(make_scan(2, label="C6S12M1P2X1", sample_id="c", images=False))
    assert sorted(r.sample_id for r in db.records(label="C6")) == ["a", "c"]
    assert [r.sample_id for r in db.records(label="C6S1")] == ["a"]
    assert [r.sample_id for r in db.records(label="C6S1M1P2X1")] == ["a"]
    assert [r.sample_id for r in db.records(label="C60")] == ["b"]


class _InterruptedAfterBegin:
    """A catalog connection where Ctrl-C arrives the moment a transaction has begun."""

    def __init__(self, conn: sqlite3.Connection):
        self.conn = conn

    def execute(self, sql: str, *args):
        cursor = self.conn.execute(sql, *args)
        if sql.startswith("BEGIN"):
            raise KeyboardInterrupt
        return cursor

    @property
    def in_transaction(self) -> bool:
        return self.conn.in_transaction


def test_ctrl_c_just_after_a_transaction_begins_leaves_the_catalog_writable(tmp_path):
    # The interrupt lands between BEGIN and the body: the transaction must be rolled back, or every later
    # write on the connection fails with "cannot start a transaction within a transaction".
    db = Database(tmp_path / "db")
    conn = db._conn
    db._local.conn = _InterruptedAfterBegin(conn)
    with pytest.raises(KeyboardInterrupt):
        db.store_features("a" * 64, "v1", {"x": 1.0})
    db._local.conn = conn
    assert not conn.in_transaction
    db.store_features("a" * 64, "v1", {"x": 2.0})
    assert db.cached_features("a" * 64, "v1") == {"x": 2.0}


# -- stat records: cached features served without hashing unchanged files --------------------------------

SETTLE = 0.05
"""Seconds that put a file's next change on a later tick of the file-system clock (ticks are 1-10 ms)."""


@pytest.fixture
def hashed(tmp_path, monkeypatch):
    """A database with one scan whose files count as settled after :data:`SETTLE` seconds, and a list that
    every SHA-256 the verification computes is appended to."""
    monkeypatch.setattr(stored, "RACY_SECONDS", 0.0)
    calls: list[Path] = []
    hash_file = stored.sha256_file
    monkeypatch.setattr(stored, "sha256_file", lambda path: calls.append(path) or hash_file(path))
    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1))
    time.sleep(SETTLE)
    yield db, calls
    db.close()


def _verify(db: Database) -> None:
    (loader,) = db.stored_scans(db.records())
    loader.verify()


def _stat_rows(db: Database) -> int:
    with sqlite3.connect(db.catalog_path) as conn:
        return conn.execute("SELECT COUNT(*) FROM file_stats").fetchone()[0]


def test_a_verified_file_is_hashed_again_only_when_its_stat_record_changes(hashed):
    db, calls = hashed
    files = len(db.stored_scans(db.records())[0].catalogued)
    _verify(db)
    assert len(calls) == files and _stat_rows(db) == files
    _verify(db)
    assert len(calls) == files  # every record matched: nothing hashed
    mat = db.root / db.records()[0].path
    time.sleep(SETTLE)
    mat.touch()
    _verify(db)
    assert calls[files:] == [mat]  # the touched file alone, still the catalogued bytes


def test_bytes_changed_in_place_with_their_old_times_put_back_are_caught(hashed):
    db, _ = hashed
    _verify(db)
    mat = db.root / db.records()[0].path
    before = mat.stat()
    data = bytearray(mat.read_bytes())
    data[len(data) // 2] ^= 0xFF
    time.sleep(SETTLE)
    mat.write_bytes(bytes(data))
    os.utime(mat, ns=(before.st_atime_ns, before.st_mtime_ns))  # what cp -p and touch -r do
    after = mat.stat()
    assert (after.st_size, after.st_mtime_ns, after.st_ino) == (before.st_size, before.st_mtime_ns, before.st_ino)
    with pytest.raises(ChangedSinceStored, match="SHA-256 differs"):
        _verify(db)


def test_a_file_changed_within_the_racy_window_gets_no_stat_record(hashed, monkeypatch):
    db, calls = hashed
    monkeypatch.setattr(stored, "RACY_SECONDS", 3600.0)
    _verify(db)
    _verify(db)
    assert _stat_rows(db) == 0 and len(calls) == 2 * len(db.stored_scans(db.records())[0].catalogued)


def test_a_stat_record_confirms_only_the_digest_it_was_checked_against(hashed):
    db, calls = hashed
    _verify(db)
    with sqlite3.connect(db.catalog_path) as conn:
        conn.execute("UPDATE file_stats SET stat = substr(stat, 1, length(stat) - 64) || ?", ("0" * 64,))
    _verify(db)
    assert len(calls) == 2 * len(db.stored_scans(db.records())[0].catalogued)
