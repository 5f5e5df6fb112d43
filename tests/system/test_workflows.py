"""The shared workflows (scanner.workflows): a database's features through its cache, named predictions: the
system tests (simulated databases)."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from features import code_version, extract, extraction
from scanner.runtime import memory
from scanner.simulation.database import synthetic_database
from scanner.storage.database import Database, DatabaseError
from scanner.workflows import demo as demo_workflow
from scanner.workflows.database import database_sources, extract_database, stored_features
from scanner.workflows.demo import simulated_database

SMALL = (64, 64)


def small_database(root) -> Database:
    return synthetic_database(root, ["granite-polished", "oak-planed"], scans_per_material=1, image_size=SMALL,
                              progress=False, workers=1)


@pytest.fixture(scope="module")
def db(tmp_path_factory) -> Database:
    return small_database(tmp_path_factory.mktemp("workflows") / "db")


def test_sources_are_the_catalog_rows_keyed_by_content(db):
    records = db.records()
    sources = database_sources(db, records)
    assert [s.scan_id for s in sources] == [r.scan_id for r in records]
    assert [s.cache_key for s in sources] == [r.content_hash for r in records]
    assert sources[0].load().scan_id == records[0].scan_id


def test_a_database_is_extracted_once_then_read_from_its_cache(tmp_path, monkeypatch):
    db = small_database(tmp_path / "db")  # its own: no other test has filled its cache
    ids = [r.scan_id for r in db.records()]
    with pytest.warns(Warning):  # the 64 px photos are too small for image features
        expected = [extract(db.get(scan_id)) for scan_id in ids]
    extracted = []

    def counted(scan, families=None):
        extracted.append(scan.scan_id)
        return extract(scan, families)

    monkeypatch.setattr(extraction, "extract", counted)  # workers=1: extracted in this process
    space = extract_database(db, workers=1, progress=False)
    assert extracted == ids
    assert space.scan_ids == tuple(ids)
    for row, values in zip(space.X, expected, strict=True):
        np.testing.assert_array_equal(row, np.array(list(values.values())))
    for record in db.records():
        cached = db.cached_features(record.content_hash, code_version())
        assert cached is not None and list(cached) == list(space.columns)
    again = extract_database(db, workers=1, progress=False)
    assert extracted == ids  # the second time, every row came from the cache
    np.testing.assert_array_equal(again.X, space.X)


def test_a_simulated_database_caches_the_features_its_stored_files_give(tmp_path, monkeypatch):
    # The demo's features are extracted by the simulating workers from the scans in memory; the cache then
    # holds exactly what an extraction from the stored .mat and PNG files gives, and the features stage
    # extracts nothing.
    db = simulated_database(tmp_path / "db", materials=["granite-polished", "oak-planed"], scans_per_material=2,
                            image_size=SMALL, progress=False, workers=2)
    records = db.records()
    assert len(records) == 4
    for record in records:
        cached = db.cached_features(record.content_hash, code_version())
        with pytest.warns(Warning):  # the 64 px photos are too small for image features
            fresh = extract(db.get(record.scan_id))
        assert cached is not None and list(cached) == list(fresh)
        np.testing.assert_array_equal(np.array(list(cached.values())), np.array(list(fresh.values())))
    extracted = []
    monkeypatch.setattr(extraction, "extract", lambda scan, families=None: extracted.append(scan.scan_id))
    space = extract_database(db, workers=1, progress=False)
    assert extracted == [] and len(space.scan_ids) == 4 and not space.failed


def _memory_kept(scan) -> tuple[int, bool]:
    """An ``analyse`` step reporting its process and whether it keeps the memory it frees."""
    return os.getpid(), memory._state["for_good"]


def test_the_simulating_workers_keep_the_memory_a_scan_frees(tmp_path, monkeypatch):
    # simulated_database starts each worker with keep_freed_memory (the next scan reuses the last one's
    # temporaries); with worker_start, every scan is simulated in a worker with that setting, none in this
    # process, and without it in workers without.
    asked = {}
    monkeypatch.setattr(demo_workflow, "synthetic_database", lambda root, **options: asked.update(options))
    simulated_database(tmp_path / "spy", workers=2)
    assert asked["worker_start"] is memory.keep_freed_memory and asked["workers"] == 2
    monkeypatch.undo()
    seen = []
    synthetic_database(tmp_path / "db", materials=["granite-polished", "oak-planed"], scans_per_material=2,
                       image_size=SMALL, progress=False, workers=2, analyse=_memory_kept,
                       on_stored=lambda db, scan_id, analysed: seen.append(analysed),
                       worker_start=memory.keep_freed_memory)
    assert len(seen) == 4 and all(kept for _, kept in seen)
    assert os.getpid() not in {pid for pid, _ in seen} and not memory._state["for_good"]
    seen.clear()
    synthetic_database(tmp_path / "plain", materials=["granite-polished"], scans_per_material=2, image_size=SMALL,
                       progress=False, workers=2, analyse=_memory_kept,
                       on_stored=lambda db, scan_id, analysed: seen.append(analysed))
    assert len(seen) == 2 and not any(kept for _, kept in seen)


def test_label_filter_and_an_empty_selection(db):
    assert extract_database(db, label="C6", workers=1, progress=False).scan_ids == ("granite-polished-01-001",)
    with pytest.raises(DatabaseError, match="no scans with label C5 to extract"):
        extract_database(db, label="C5", workers=1, progress=False)


def test_one_stored_scan(db):
    record = db.records()[0]
    values, failure = stored_features(db, record)
    assert failure is None
    expected = extract_database(db, records=[record], workers=1, progress=False)
    assert list(values) == list(expected.columns)
    assert all(math.isnan(a) and math.isnan(b) or a == b for a, b in zip(values.values(), expected.X[0], strict=True))
