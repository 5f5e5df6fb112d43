"""The texplorer command line: db list/show/check/rebuild, one-line errors, --debug tracebacks."""

from __future__ import annotations

import argparse
import re

import numpy as np
import pytest
from conftest import make_scan

from features.space import FeatureSpace
from scanner.cli import COMMANDS, ENTRY_POINTS, EXIT_PROBLEMS, build_parser, main, plugin_summary
from scanner.storage.database import Database


def test_db_list_filters(db_path, capsys):
    assert main(["db", "list", "--db", str(db_path)]) == 0
    out = capsys.readouterr().out
    assert "granite-01-001" in out and "steel-01-001" in out and out.rstrip().endswith("2 scan(s)")
    assert main(["db", "list", "--db", str(db_path), "--label", "C7"]) == 0
    out = capsys.readouterr().out
    assert "steel-01-001" in out and "granite-01-001" not in out
    assert main(["db", "list", "--db", str(db_path), "--operator", "nobody"]) == 0
    assert capsys.readouterr().out.rstrip().endswith("0 scan(s)")


def test_db_show(db_path, capsys):
    assert main(["db", "show", "granite-01-001", "--db", str(db_path)]) == 0
    out = capsys.readouterr().out
    assert "label       C6S1M1P2X1" in out and "v_ts" in out and "44100 Hz" in out and "I_disp" in out
    # make_scan records 0.2 s per step: the slides and the audio are too short for their features.
    assert ("too short:  v_fs (600 of the 3000 samples its features need; they are NaN), v_ts (600 of the 3000 "
            "samples") in out
    assert main(["db", "show", "steel-01-001", "--db", str(db_path)]) == 0
    assert "rigid 1" in capsys.readouterr().out


def test_db_check_exit_codes(db_path, capsys):
    assert main(["db", "check", "--db", str(db_path)]) == 0
    assert "0 missing, 0 changed, 0 unknown" in capsys.readouterr().out
    next(db_path.glob("scans/C7*/steel-01/*_illu.png")).unlink()
    assert main(["db", "check", "--db", str(db_path)]) == EXIT_PROBLEMS
    out = capsys.readouterr().out
    assert "missing  scans/C7S1M1P8X1/steel-01/steel-01-001_illu.png" in out


def test_db_rebuild(db_path, capsys):
    (db_path / "catalog.sqlite").unlink()
    for extra in db_path.glob("catalog.sqlite-*"):
        extra.unlink()
    assert main(["db", "rebuild", "--db", str(db_path)]) == 0
    assert "catalog rebuilt: 2 scan(s), 0 file(s) skipped" in capsys.readouterr().out


@pytest.mark.parametrize("command", [["db", "list"], ["db", "show", "x"], ["db", "check"], ["db", "rebuild"],
                                     ["features"], ["select"], ["evaluate"], ["train", "--out", "m.skops"],
                                     ["export", "out.zip"]])
def test_commands_that_only_read_refuse_a_folder_that_is_not_a_database(command, tmp_path, capsys):
    # `texplorer db list --db /etc` must not create /etc/catalog.sqlite and /etc/scans/.
    folder = tmp_path / "etc"
    folder.mkdir()
    (folder / "passwd").write_text("root:x:0:0")
    assert main([*command, "--db", str(folder)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "no texplorer database here" in err and "create one with 'texplorer demo'" in err
    assert sorted(p.name for p in folder.iterdir()) == ["passwd"]


def test_db_list_keeps_columns_aligned_for_long_ids(tmp_path, capsys):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="polyurethane-foam-open-cell-01", scan_index=1, images=False))
    db.add(make_scan(1, sample_id="oak-01", scan_index=1, images=False, label="C5S1M1P1X1"))
    assert main(["db", "list", "--db", str(tmp_path / "db")]) == 0
    header, *rows, total = capsys.readouterr().out.splitlines()
    assert len(rows) == 2 and total == "2 scan(s)"
    for column in ("label", "sample", "session", "operator", "started"):
        assert {row[header.index(column) - 1] for row in rows} == {" "}  # every column starts after a blank
        assert all(row[header.index(column)] != " " for row in rows)


def test_label_filters_are_case_normalised_and_malformed_codes_refused(db_path, capsys):
    assert main(["db", "list", "--db", str(db_path), "--label", "c7"]) == 0
    out = capsys.readouterr().out
    assert "steel-01-001" in out and out.rstrip().endswith("1 scan(s)")
    for bad in ("Z9", "C06", "C7S", "C7S1M1P8X1Y1"):
        assert main(["db", "list", "--db", str(db_path), "--label", bad]) == 1
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and f"'{bad}' is not a label or class prefix" in err
        assert "e.g. C6, C6S1 or C6S1M1P2X1" in err


def test_label_options_take_names_as_the_web_search_does(db_path, capsys):
    for name in ("steel", "Steel", "metal"):  # a material, in any case, and a major class's name
        assert main(["db", "list", "--db", str(db_path), "--label", name]) == 0
        out = capsys.readouterr().out
        assert "steel-01-001" in out and "granite" not in out, name
    assert main(["db", "list", "--db", str(db_path), "--label", "unobtainium"]) == 1
    err = capsys.readouterr().err.strip()
    assert err == ("texplorer: error: 'unobtainium' is not a label or class prefix: unexpected 'u' at character 1 "
                   "where C<number> was expected (expected C<n>, C<n>S<n>, ... up to a full label, e.g. C6, C6S1 or "
                   "C6S1M1P2X1); or part of a material name, e.g. granite")


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                yield sub
                yield from _subparsers(sub)


def test_help_texts_name_the_paper_not_internal_documents():
    parsers = [build_parser(), *_subparsers(build_parser())]
    assert len(parsers) > 20
    for parser in parsers:
        text = parser.format_help()
        assert not re.search(r"seed \d{3}|seed paper", text), parser.prog


def _listed(parser: argparse.ArgumentParser) -> dict[str, str]:
    """Each command of ``texplorer --help`` with its one-line help."""
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return {action.dest: action.help for action in commands._choices_actions}


def test_the_commands_listed_without_their_groups_are_those_the_groups_register():
    from importlib.metadata import entry_points

    registered, listed = _listed(build_parser()), _listed(build_parser([]))
    plugins = {entry.name: entry for entry in entry_points(group=ENTRY_POINTS)}
    assert "serve" in plugins and set(registered) == set(COMMANDS) | set(plugins)
    assert registered == listed
    assert listed == {**{name: summary for name, (_, summary) in COMMANDS.items()},
                      **{name: plugin_summary(entry) for name, entry in plugins.items()}}


def test_a_command_line_builds_only_its_own_group():
    parser = build_parser(["db"])
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    assert commands.choices["db"].format_help().count("rebuild") >= 1
    assert "--db" not in commands.choices["features"].format_help()  # listed, its options not loaded


@pytest.mark.parametrize("argv", [["--help"], ["db", "--help"], ["db", "check", "--help"], ["demo", "--help"],
                                  ["features", "--help"]])
def test_help_everywhere(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 0 and "usage: texplorer" in capsys.readouterr().out


def test_classify_without_a_model_says_where_it_looked(db_path, capsys):
    assert main(["classify", "granite-01-001", "--db", str(db_path)]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "no --model given" in err and "holds no model" in err
    assert "texplorer demo" in err


def test_a_refused_import_leaves_no_database_folder(tmp_path, capsys):
    damaged = tmp_path / "bundle.zip"
    damaged.write_bytes(b"PK\x03\x04 not a bundle")
    target = tmp_path / "new" / "db"
    assert main(["import", "--db", str(target), str(damaged)]) == 1
    assert "bundle.zip" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()
    existing = tmp_path / "lab"
    Database(existing).close()
    before = sorted(p.relative_to(existing) for p in existing.rglob("*"))
    assert main(["import", "--db", str(existing), str(damaged)]) == 1
    assert sorted(p.relative_to(existing) for p in existing.rglob("*")) == before


def test_progress_bars_count_what_they_go_through(monkeypatch):
    import tqdm

    from scanner.cli import base

    made = {}
    monkeypatch.setattr(tqdm, "tqdm", lambda items, **options: made.update(options) or items)
    assert list(base.progress("comparing", unit="method")(["a"])) == ["a"]
    assert made["unit"] == "method" and made["desc"] == "comparing"


def test_features_of_a_label_leave_the_full_table_alone(tmp_path, capsys):
    from features import FeatureSpace

    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", image_shape=(64, 64)))
    db.add(make_scan(1, label="C7S1M1P8X1", sample_id="steel-01", image_shape=(64, 64)))
    db.close()
    assert main(["features", "--db", str(tmp_path / "db"), "--workers", "1"]) == 0
    full = (tmp_path / "db" / "features.csv").read_bytes()
    capsys.readouterr()
    assert main(["features", "--db", str(tmp_path / "db"), "--label", "c6", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert f"wrote {tmp_path / 'db' / 'features-C6.csv'} (the scans of C6; {tmp_path / 'db' / 'features.csv'} " \
           "is left as it was)" in out
    assert (tmp_path / "db" / "features.csv").read_bytes() == full
    assert list(FeatureSpace.from_csv(tmp_path / "db" / "features-C6.csv").scan_ids) == ["granite-01-001"]


def test_the_demo_calibrates_the_cells_of_the_reliability_diagram():
    from scanner.cli.analysis import diagram_cells

    levels = ("coarse", "medium", "fine")
    assert diagram_cells(["coarse", "fine"], [3, 10], ["tactum", "all"], levels) == {("fine", "all", 10)}
    assert diagram_cells(["medium"], [10, None], ["audio", "image"], levels) == {("medium", "audio", None),
                                                                                 ("medium", "image", None)}


@pytest.mark.parametrize(("argv", "usage", "error"), [
    (["db", "list", "--lable", "C6"], "usage: texplorer db list ",
     "texplorer db list: error: unrecognized arguments: --lable C6 (did you mean --label?)"),
    (["demo", "--image-sise=300"], "usage: texplorer demo ",
     "texplorer demo: error: unrecognized arguments: --image-sise=300 (did you mean --image-size?)"),
    (["db", "list", "--zzz"], "usage: texplorer db list ", "texplorer db list: error: unrecognized arguments: --zzz"),
])
def test_a_misspelled_option_gets_the_commands_usage_and_the_closest_option(argv, usage, error, capsys):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(usage) and err.strip().splitlines()[-1] == error


def test_train_states_the_paper_mlps_iteration_stops_once_instead_of_warning(tmp_path, capsys):
    # random features of three classes: L-BFGS is still improving the fit at the paper's 200 iterations
    rng = np.random.default_rng(0)
    labels = [f"C{1 + i % 3}S1M1P1X1" for i in range(60)]
    space = FeatureSpace(X=rng.standard_normal((60, 12)), columns=tuple(f"other.f{i}" for i in range(12)),
                         scan_ids=[f"s{i}" for i in range(60)], label_text=labels,
                         groups=[f"g{i}" for i in range(60)])
    table = space.to_csv(tmp_path / "space.csv")
    assert main(["train", "--features", str(table), "--classifier", "mlp", "--out", str(tmp_path / "m.skops"),
                 "--db", str(tmp_path / "db")]) == 0
    err = capsys.readouterr().err
    assert "ConvergenceWarning" not in err
    (note,) = [line for line in err.splitlines() if "L-BFGS" in line]
    assert note.startswith("texplorer: note: the MLP stopped at the paper's 200 L-BFGS iterations before converging")
