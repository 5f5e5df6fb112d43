"""What killed ingests and trainings leave behind: listed by ``db check``, removed by ``--repair`` or by the
next run, also in a database folder that holds only recording sets; and the worker server of a long-running
process, whose socket a ``/tmp`` cleaner deleted, started again."""

from __future__ import annotations

import os
import sqlite3
import time
from pathlib import Path

import numpy as np

from scanner.cli import main
from scanner.scan import Recording, Trace
from scanner.storage import ingest
from scanner.storage.database import Database
from scanner.storage.files import STALE_TEMP_S


def _aged(path: Path, seconds: float) -> Path:
    then = time.time() - seconds
    os.utime(path, (then, then))
    return path


def _killed_write(folder: Path, target: str, seconds: float, token: str = "0123456789ab") -> Path:
    """The temporary file an atomic write of ``target`` leaves when killed before its rename."""
    folder.mkdir(parents=True, exist_ok=True)
    temp = folder / f".{target}.tmp-{token}"
    temp.write_bytes(b"PK\x03\x04 half a model")
    return _aged(temp, seconds)


def _killed_ingest(db: Path, name: str) -> Path:
    """The staging folder of an ingest killed part way: its owner lock no longer held."""
    staging = db / "recordings" / f".{name}.tmp-89abcdef"
    staging.mkdir(parents=True)
    sqlite3.connect(staging / "owner.lock").close()
    (staging / "content").mkdir()
    return staging


def test_a_killed_trainings_temporary_model_is_removed_by_the_next_save(tmp_path):
    from taxonomy.learning.models import save_model, train_model
    from tests.unit.test_models import separated_space

    models = tmp_path / "models"
    stale = _killed_write(models, "m.skops", 2 * STALE_TEMP_S)
    writing = _killed_write(models, "m.skops", 1.0, token="fedcba987654")  # another train, writing now
    other = _killed_write(models, "other.skops", 2 * STALE_TEMP_S, token="aaaaaaaaaaaa")
    save_model(train_model(separated_space(), level="fine", n_features=2, classifier="lda"), models / "m.skops")
    assert not stale.exists() and writing.exists() and other.exists()
    assert (models / "m.skops").is_file()


def test_db_check_lists_and_repair_removes_model_leftovers_of_a_scan_database(tmp_path, capsys):
    db = tmp_path / "db"
    Database(db).close()
    stale = _killed_write(db / "models", "rf-fine-X10.skops", 2 * STALE_TEMP_S)
    assert main(["db", "check", "--db", str(db)]) == 0  # leftovers are listed, not damage
    assert f"leftover models/{stale.name}" in capsys.readouterr().out
    assert main(["db", "check", "--repair", "--db", str(db)]) == 0
    assert f"removed  models/{stale.name}" in capsys.readouterr().out and not stale.exists()


def test_db_check_works_on_a_folder_of_recording_sets_only(tmp_path, capsys):
    db = tmp_path / "lab"
    kept = [Recording("r1", {"v": Trace(np.ones(64), 100.0, "V")}, {"vibration": "v"}, "cork")]
    ingest.store_recordings(db, "slides", kept)
    staging = _killed_ingest(db, "terrain")
    model = _killed_write(db / "models", "terrain.skops", 2 * STALE_TEMP_S)
    assert not (db / "catalog.sqlite").exists()
    assert main(["db", "check", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"leftover recordings/{staging.name}/" in out and f"leftover models/{model.name}" in out
    assert "recording sets only (1: slides), no scans to check; 2 crash leftover(s)" in out
    assert main(["db", "check", "--repair", "--db", str(db)]) == 0
    out = capsys.readouterr().out
    assert f"removed  recordings/{staging.name}/ removed" in out and f"removed  models/{model.name}" in out
    assert not staging.exists() and not model.exists()
    assert [r.name for r in ingest.load_recordings(ingest.set_folder(db, "slides"))] == ["r1"]


def test_the_next_ingest_of_any_set_removes_what_a_killed_one_left(tmp_path):
    db = tmp_path / "lab"
    staging = _killed_ingest(db, "terrain")
    ingest.store_recordings(db, "slides", [Recording("r1", {"v": Trace(np.ones(64), 100.0, "V")},
                                                     {"vibration": "v"}, "cork")])
    assert not staging.exists()
    assert sorted(p.name for p in (db / "recordings").iterdir() if not p.name.startswith(".swap")) == ["slides"]


WORKER_SERVER_SCRIPT = """
import os, sys
from multiprocessing import forkserver
from scanner.runtime import local

local.start_workers_from_a_server()
first = sorted(v for _, v in local.worker_map(abs, [-1, -2, -3, -4], workers=2))
local.release_workers()
address = forkserver._forkserver._forkserver_address
os.unlink(address)  # what a /tmp cleaner does to a socket it has not seen used for days
second = sorted(v for _, v in local.worker_map(abs, [-5, -6, -7, -8], workers=2))
print(first, second, forkserver._forkserver._forkserver_address != address,
      os.path.exists(forkserver._forkserver._forkserver_address))
"""


def test_the_worker_server_comes_back_after_its_socket_was_deleted():
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-c", WORKER_SERVER_SCRIPT], cwd=root, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.split("\n")[0] == "[1, 2, 3, 4] [5, 6, 7, 8] True True", run.stdout
