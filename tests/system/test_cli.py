"""The texplorer command line: db list/show/check/rebuild, one-line errors, --debug tracebacks: the system tests
(the CLI in subprocesses and texplorer demo)."""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from features.space import FeatureSpace
from scanner.cli import EXIT_PIPE, main
from scanner.cli.base import UsageError
from scanner.storage.database import Database


def test_errors_are_one_line_without_traceback(tmp_path, db_path):
    run = subprocess.run([sys.executable, "-m", "scanner.cli", "db", "show", "nope", "--db", str(db_path)],
                         capture_output=True, text=True)
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr.strip().splitlines() == [f"texplorer: error: no scan 'nope' in {db_path}"]
    run = subprocess.run([sys.executable, "-m", "scanner.cli", "db", "list", "--db", str(tmp_path / "none")],
                         capture_output=True, text=True)
    assert run.returncode == 1 and len(run.stderr.strip().splitlines()) == 1
    assert "no texplorer database here" in run.stderr and not (tmp_path / "none").exists()
    run = subprocess.run([sys.executable, "-m", "scanner.cli", "db", "show", "nope", "--db", str(db_path),
                          "--debug"], capture_output=True, text=True)
    assert run.returncode == 1 and "Traceback" in run.stderr


def test_db_list_into_a_closed_pipe_ends_quietly(db_path):
    # `texplorer db list | head`: the reader is gone before the table is written.
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        run = subprocess.run([sys.executable, "-m", "scanner.cli", "db", "list", "--db", str(db_path)],
                             stdout=write_end, stderr=subprocess.PIPE, text=True)
    finally:
        os.close(write_end)
    assert run.stderr == "" and run.returncode == EXIT_PIPE


@pytest.fixture(scope="module")
def demo_db(tmp_path_factory):
    """A small synthetic database with features, evaluation and a model, built by 'texplorer demo'."""
    root = tmp_path_factory.mktemp("demo") / "db"
    code = main(["demo", "--db", str(root), "--samples", "2", "--scans", "2", "--image-size", "320", "--materials",
                 "polyurethane-foam", "mild-steel-brushed", "float-glass", "--classifier", "rf", "nb",
                 "--level", "coarse", "fine", "--feature-set", "tactum", "--folds", "3", "--workers", "2"])
    assert code == 0
    return root


def test_demo_runs_the_whole_chain(demo_db):
    # Two samples per material: the evaluation keeps each sample in one fold and its table says so.
    database = Database(demo_db, create=False)
    assert len(database) == 12 and len({r.sample_id for r in database.records()}) == 6
    assert (demo_db / "features.csv").is_file()
    assert (demo_db / "report" / "index.html").is_file() and (demo_db / "report" / "fq_ranking.png").is_file()
    assert (demo_db / "models" / "v001-rf-fine-X10.skops").is_file()  # the demo's model is the first version
    assert json.loads((demo_db / "models" / "versions.json").read_text())["current"] == 1


def test_select_evaluate_train_classify(demo_db, tmp_path, capsys):
    capsys.readouterr()
    assert main(["select", "--db", str(demo_db), "--n", "3", "--top", "5"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("feature quality at level fine (193 features, top 5):")
    assert "selected (|Spearman rho| < 0.5, n = 3): " in out
    assert main(["evaluate", "--db", str(demo_db), "--features", str(demo_db / "features.csv"),
                 "--classifier", "lda", "--level", "coarse", "--n", "3", "--feature-set", "other",
                 "--folds", "3", "--report", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "lda" in out and "other" in out and (tmp_path / "r" / "index.html").is_file()
    assert "X3, nested protocol, 3 folds grouped by sample, seed 0" in out
    model = tmp_path / "m.skops"
    assert main(["train", "--db", str(demo_db), "--out", str(model), "--level", "coarse", "--n", "3"]) == 0
    scan = next(demo_db.glob("scans/C3*/*/*-001.mat"))
    capsys.readouterr()
    assert main(["classify", str(scan), "--model", str(model), "--k", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[1].split()[:2] == ["1.", "C3"]


def test_train_keeps_every_model_version_and_models_lists_and_switches_them(demo_db, tmp_path, capsys):
    db = tmp_path / "db"
    shutil.copytree(demo_db, db)
    demo_model = (db / "models" / "v001-rf-fine-X10.skops").read_bytes()
    scan = next(db.glob("scans/C3*/*/*-001.mat"))
    capsys.readouterr()
    assert main(["train", "--db", str(db), "--level", "coarse", "--n", "3"]) == 0
    captured = capsys.readouterr()
    # Four scans per major class cannot fill five folds: said, and the model is kept all the same.
    assert "no cross-validated accuracy for this version: 5 folds need a class with at least 5 rows" in captured.err
    # What changed against the version before: the coarse classes added, the fine ones of the demo removed.
    assert "model version 2 (rf, coarse level, 3 features; " in captured.out and ") is current; " in captured.out
    assert re.search(r"\d+ classes added: [^;]*\(C\d\)", captured.out) and "classes removed: " in captured.out
    assert "use version 2" in captured.out
    assert main(["train", "--db", str(db), "--level", "coarse", "--n", "3", "--no-cv", "--keep-current"]) == 0
    out = capsys.readouterr().out
    assert "model version 3 (" in out and "is kept; version 2 stays current; the same " in out
    assert (db / "models" / "v001-rf-fine-X10.skops").read_bytes() == demo_model  # a second train keeps the first
    assert sorted(p.name for p in (db / "models").glob("*.skops")) == [
        "v001-rf-fine-X10.skops", "v002-rf-coarse-X3.skops", "v003-rf-coarse-X3.skops"]

    assert main(["models", "--db", str(db)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[:3] == ["version", "created", "protocol"]
    rows = {line.split()[0 if line.startswith(" ") else 1]: line for line in lines[1:4]}
    assert rows["v2"].startswith("* v2") and "rf, coarse level, 3 features" in rows["v2"]
    assert "rejection AUROC" in rows["v2"] and "CV accuracy" not in rows["v2"]
    fingerprints = {v: re.findall(r" ([0-9a-f]{12}) ", rows[v]) for v in ("v1", "v2", "v3")}
    assert fingerprints["v2"] == fingerprints["v3"] == fingerprints["v1"]  # the same scans and feature code

    assert main(["classify", str(scan), "--db", str(db)]) == 0  # the current version: coarse
    assert "rf at level coarse" in capsys.readouterr().out
    assert main(["classify", str(scan), "--db", str(db), "--model", "v1"]) == 0
    assert "rf at level fine" in capsys.readouterr().out
    assert main(["models", "--db", str(db), "--use", "1"]) == 0
    assert "version 1 is current" in capsys.readouterr().out
    assert main(["classify", str(scan), "--db", str(db)]) == 0
    assert "rf at level fine" in capsys.readouterr().out
    assert main(["models", "--db", str(db), "--use", "9"]) == 1
    assert "no model version 9 (versions: v1, v2, v3)" in capsys.readouterr().err
    assert main(["train", "--db", str(db), "--out", str(db / "models" / "v001-rf-fine-X10.skops")]) == 1
    assert "exists: a trained model is never overwritten" in capsys.readouterr().err
    assert (db / "models" / "v001-rf-fine-X10.skops").read_bytes() == demo_model


def test_a_feature_set_without_any_value_is_left_out_and_the_rest_evaluated(demo_db, tmp_path, capsys):
    # photos below the border crop leave the whole image family NaN; that set is named and left out
    space = FeatureSpace.from_csv(demo_db / "features.csv")
    image = np.array([c.startswith("image.") for c in space.columns])
    X = space.X.copy()
    X[:, image] = np.nan
    table = dataclasses.replace(space, X=X).to_csv(tmp_path / "no-photos.csv")
    capsys.readouterr()
    assert main(["evaluate", "--db", str(demo_db), "--features", str(table), "--classifier", "rf", "--level",
                 "coarse", "--n", "3", "--folds", "3", "--report", str(tmp_path / "r")]) == 0
    captured = capsys.readouterr()
    assert (f"texplorer: note: feature set image left out: none of its {image.sum()} columns has a value in any "
            f"of the {len(X)} rows") in captured.err
    table_lines = captured.out.splitlines()
    assert any(line.startswith("rf") and "all" in line for line in table_lines)
    assert not any(" image " in f" {line} " for line in table_lines if line.startswith("rf"))
    assert (tmp_path / "r" / "index.html").is_file()


def test_the_demo_notes_photos_too_small_for_the_image_features(tmp_path, capsys):
    assert main(["demo", "--db", str(tmp_path / "db"), "--materials", "oak-planed", "--samples", "1", "--scans",
                 "1", "--image-size", "200", "--no-evaluation", "--workers", "1"]) == 0
    assert ("texplorer: note: photos of 200 x 200 px leave nothing for the image features after the 100 px border "
            "crop: they need at least 202 x 202 px") in capsys.readouterr().err


def test_classify_refuses_a_foreign_model(demo_db, tmp_path, capsys):
    (tmp_path / "evil.skops").write_bytes(b"PK\x03\x04 not really a model")
    scan = next(demo_db.glob("scans/C3*/*/*-001.mat"))
    assert main(["classify", str(scan), "--model", str(tmp_path / "evil.skops")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("texplorer: error: ") and "evil.skops" in err and len(err.strip().splitlines()) == 1


def test_classify_a_scan_id_with_the_databases_default_model(demo_db, capsys):
    record = Database(demo_db, create=False).records(label="C3")[0]
    capsys.readouterr()
    assert main(["classify", record.scan_id, "--db", str(demo_db), "--k", "2"]) == 0
    by_id = capsys.readouterr().out.splitlines()
    assert by_id[0] == f"{record.scan_id} ({record.label} recorded) with " + by_id[0].split(" with ", 1)[1]
    assert len(by_id) == 3 and by_id[1].startswith("1. ")
    # the same scan as a file, the same default model: the same predictions
    assert main(["classify", str(demo_db / record.path), "--db", str(demo_db), "--k", "2"]) == 0
    assert capsys.readouterr().out.splitlines() == by_id


def test_classify_an_unknown_scan_id_is_one_line(demo_db, capsys):
    assert main(["classify", "no-such-scan", "--db", str(demo_db)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "no scan 'no-such-scan'" in err


def test_demo_evaluates_the_papers_figures_unless_asked_for_the_full_grid(tmp_path, capsys):
    # Figs. 16 and 17 of the paper: coarse and fine with X10; --full-grid adds medium and X3 at every level.
    common = ["--samples", "2", "--scans", "2", "--image-size", "64", "--materials", "polyurethane-foam",
              "float-glass", "--classifier", "nb", "--feature-set", "tactum", "--workers", "1", "--folds", "2"]
    assert main(["demo", "--db", str(tmp_path / "db"), *common]) == 0
    out = capsys.readouterr().out
    assert out.split("X10, nested protocol")[1].splitlines()[1].split()[3:] == ["coarse", "fine"]
    assert "X3, nested protocol" not in out and "2 evaluations" in out
    assert main(["demo", "--db", str(tmp_path / "db"), *common, "--full-grid"]) == 0
    out = capsys.readouterr().out
    assert out.split("X3, nested protocol")[1].splitlines()[1].split()[3:] == ["coarse", "medium", "fine"]
    assert "6 evaluations" in out


def test_demo_chooses_folds_that_fit_its_scans(tmp_path, capsys):
    from scanner.cli.demo import fitting_folds

    assert fitting_folds(5, 2, 2) == 4 and fitting_folds(5, 2, 3) == 5 and fitting_folds(3, 1, 2) == 2
    with pytest.raises(UsageError, match="one scan per material; cross-validation needs two or more"):
        fitting_folds(5, 1, 1)
    root = tmp_path / "db"
    assert main(["demo", "--db", str(root), "--samples", "1", "--scans", "1"]) == 1
    assert "--samples 2 or --scans 2, or --no-evaluation" in capsys.readouterr().err and not root.exists()
    code = main(["demo", "--db", str(root), "--samples", "2", "--scans", "2", "--image-size", "64", "--materials",
                 "polyurethane-foam", "float-glass", "--classifier", "nb", "--level", "fine", "--n", "3",
                 "--feature-set", "tactum", "--workers", "1"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert "texplorer: note: 4 folds instead of 5: each material has 2 x 2 = 4 scans" in captured.err
    assert "4 folds" in captured.out
