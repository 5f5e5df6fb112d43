"""``texplorer features``, ``select``, ``evaluate``, ``train``, ``classify``: the feature space, feature
selection, cross-validated evaluation and trained models, of the database's scans or of a recording set."""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from features import REGISTRY, FeatureSpace, code_version, feature_sets
from features.recordings import Windowing, describe_families, feature_space
from features.selection import select_features
from scanner.acquisition.config import load_config
from scanner.cli.base import EXIT_ERROR, UsageError, add_db_option, open_db
from scanner.cli.common import (
    ALL,
    CLASSIFIER_NAMES,
    add_cluster_options,
    add_evaluation_options,
    add_feature_set_option,
    add_space_options,
    choices,
    cluster,
    set_sizes,
    space_for,
)
from scanner.storage.files import atomic_write_bytes, sha256_file
from scanner.storage.ingest import load_recordings, set_folder
from scanner.workflows.database import extract_database
from scanner.workflows.models import ModelChange, cross_validated, save_model_version
from scanner.workflows.quick import quick_evaluation
from taxonomy.labels import LEVELS, parse_prefix
from taxonomy.learning.evaluation import (
    CLASSIFIERS,
    MLP_MAX_ITER,
    classifier_estimators,
    default_feature_sets,
    evaluate_grid,
    evaluate_open_set,
    iteration_limit_stops,
    present_feature_sets,
    recording_of,
    vote,
    with_values,
)
from taxonomy.learning.models import save_model, train_model
from taxonomy.learning.results import one_line
from taxonomy.learning.versions import current_version, version_file
from taxonomy.reports.report import format_open_set, format_protocols, format_quick, format_table, write_report
from taxonomy.table import load_taxonomy


def report_space(space, seconds: float) -> None:
    import numpy as np

    nan_columns = int(np.isnan(space.X).any(axis=0).sum()) if len(space) else 0
    print(f"{len(space)} scans x {len(space.columns)} features in {seconds:.1f} s "
          f"({nan_columns} column(s) with NaN, {len(space.failed)} scan(s) failed)")
    for scan_id, reason in space.failed:
        print(f"failed   {scan_id}: {reason}")


def table_name(label: str | None) -> str:
    """The default file of ``texplorer features``: ``features.csv`` for every scan, ``features-C6.csv`` for the
    scans of a label or class prefix, so a filtered run never replaces the table of every scan."""
    return f"features-{parse_prefix(label)}.csv" if label else "features.csv"


def cmd_features(args: argparse.Namespace) -> int:
    if args.dataset:
        return cmd_set_features(args)
    db = open_db(args)
    started = time.perf_counter()
    with cluster(args) as client:
        space = extract_database(db, label=args.label, workers=args.workers, client=client, ship_data=args.ship_data,
                                 families=feature_sets.families_for(args.feature_set), partial=False)
    report_space(space, time.perf_counter() - started)
    out = args.out or db.root / table_name(args.label)
    space.to_csv(out)
    kept = "" if args.out or not args.label else (f" (the scans of {parse_prefix(args.label)}; "
                                                  f"{db.root / table_name(None)} is left as it was)")
    print(f"wrote {out}{kept}")
    if args.mat:
        space.to_mat(args.mat)
        print(f"wrote {args.mat}")
    return EXIT_ERROR if space.failed else 0


def cmd_select(args: argparse.Namespace) -> int:
    with cluster(args) as client:
        space = space_for(args, client)
    print(select_features(space, args.level, args.n, args.max_corr).format(args.top))
    return 0


SCAN_GROUPINGS = ("sample", "session", "operator", "recording")
"""What ``--group-by`` keeps in one fold for the database's scans (a scan is its own recording)."""


def scan_grouping(args: argparse.Namespace) -> str:
    """The ``--group-by`` of a command on the database's scans: ``sample`` by default."""
    group_by = getattr(args, "group_by", "auto")
    group_by = "sample" if group_by in (None, "auto") else group_by
    if group_by not in SCAN_GROUPINGS:
        raise UsageError(f"--group-by {group_by!r}: the database's scans group by "
                         f"{', '.join(SCAN_GROUPINGS)}")
    return group_by


def regroup_scans(space, args: argparse.Namespace):
    """The space with ``groups`` replaced by each scan's session, operator or scan id (``--group-by``), read
    from the database's catalog; the space itself for ``sample``."""
    group_by = scan_grouping(args)
    if group_by == "sample":
        return space
    if group_by == "recording":
        return dataclasses.replace(space, groups=space.scan_ids)
    records = {r.scan_id: r for r in open_db(args).records()}
    missing = [s for s in space.scan_ids if s not in records]
    if missing:
        raise UsageError(f"--group-by {group_by}: {len(missing)} scan(s) of the feature table are not in the "
                         f"database {args.db}, e.g. {missing[0]}")
    field = "session_id" if group_by == "session" else "operator"
    return dataclasses.replace(space, groups=tuple(getattr(records[s], field) for s in space.scan_ids))


def set_grouping(args: argparse.Namespace) -> str:
    """The ``--group-by`` of a set, as the report names it (``recording`` for each recording alone)."""
    group_by = getattr(args, "group_by", "auto")
    return {"auto": "the set's groups"}.get(group_by, group_by)


def run_evaluation(space, args: argparse.Namespace, client=None) -> list:
    """Evaluate the grid asked for on the command line (on the Dask cluster of ``client`` if given);
    print the table; write the HTML report if asked."""
    classifiers = choices(args.classifier, list(CLASSIFIERS))
    levels = choices(args.level, space.level_names)
    defaults = default_feature_sets()
    named = {name: defaults.get(name, name) for name in args.feature_set if name != ALL}
    if not named:
        sets = None
    else:
        # "all" beside a modern set is the paper's columns, not every column (the signals are no features).
        present = {name: feature_sets.PAPER if name == ALL else fs for name, fs in present_feature_sets(space).items()}
        sets = {**present, **named} if ALL in args.feature_set else named
    use_split = not getattr(args, "ignore_split", False)
    sizes = set_sizes(args.n, ("3", "10", ALL) if space.label_level is not None else ("3", "10"))
    group_by = set_grouping(args) if space.label_level is not None else scan_grouping(args)
    if getattr(args, "quick", False):
        return run_quick(space, args, ["fine"] if args.level == [ALL] else levels)
    if getattr(args, "open_set", False):
        return run_open_set(space, args, classifiers, levels, sizes, sets, group_by)
    sets, left_out = with_values(space, sets if sets is not None else present_feature_sets(space))
    for line in left_out:
        print(f"texplorer: note: {line}", file=sys.stderr)
    started = time.perf_counter()
    calibrate = not getattr(args, "no_calibration", False)
    if calibrate and getattr(args, "calibrate_diagram_only", False):
        calibrate = diagram_cells(levels, sizes, list(sets or present_feature_sets(space)), space.level_names)
    reports = evaluate_grid(space, classifiers, levels, sizes, sets, folds=args.folds, seed=args.seed,
                            protocol=args.protocol, workers=args.workers, progress=True, use_split=use_split,
                            client=client, single_group=getattr(args, "single_group", "train"),
                            calibrate=calibrate, group_by=group_by, pairs=getattr(args, "pairs", None))
    if getattr(args, "vote", False):
        recordings = [recording_of(s) for s in space.scan_ids]
        if len(set(recordings)) == len(recordings):
            print("texplorer: warning: --vote: every recording is one row (no windows), so the vote changes "
                  "nothing", file=sys.stderr)
        reports = [vote(r, recordings) for r in reports]
    print(format_table(reports))
    splitting = reports[0].splitting if reports else f"{args.folds} folds"
    print(f"{len(reports)} evaluations ({args.protocol} protocol, {splitting}) "
          f"in {time.perf_counter() - started:.1f} s")
    for warning in sorted({w for report in reports for w in report.notes if w.strip()}):
        print(f"texplorer: warning: {warning}", file=sys.stderr)
    if args.report:
        print(f"report: {write_report(args.report, space, reports, workers=getattr(args, 'workers', None))}")
    return reports


def diagram_cells(levels: Sequence[str], sizes: Sequence[int | None], set_names: Sequence[str],
                  level_names: Sequence[str]) -> set[tuple[str, str, int | None]]:
    """The (level, feature set, set size) cells whose calibrated results the report's reliability diagram
    shows (:mod:`taxonomy.reports.report`): the finest level, every feature ("all", else each set) and the
    largest set size (``all`` above any number)."""
    finest = max(levels, key=list(level_names).index)
    largest = max(sizes, key=lambda n: math.inf if n is None else n)
    names = [ALL] if ALL in set_names else list(set_names)
    return {(finest, name, largest) for name in names}


def run_open_set(space, args: argparse.Namespace, classifiers, levels, sizes, sets, group_by: str) -> list:
    """``evaluate --open-set``: every classifier x level x set size x feature set with whole classes held
    out per fold (:func:`taxonomy.learning.evaluation.evaluate_open_set`); the table of AUROC and accuracies."""
    started = time.perf_counter()
    named_sets = sets if sets is not None else {"all": None}
    reports = [evaluate_open_set(space, classifier, level, size, args.folds, args.seed, feature_set,
                                 group_by=group_by, calibrate=not getattr(args, "no_calibration", False))
               for classifier in classifiers for level in levels for size in sizes
               for feature_set in named_sets.values()]
    print(format_open_set(reports))
    print(f"{len(reports)} open-set evaluations in {time.perf_counter() - started:.1f} s")
    if args.report:
        print(f"report: {write_report(args.report, space, reports, workers=getattr(args, 'workers', None))}")
    return reports


def run_quick(space, args: argparse.Namespace, levels: Sequence[str]) -> list:
    """``evaluate --quick``: the database's full scans walked step by step as quick scans in grouped folds
    (:func:`scanner.workflows.quick.quick_evaluation`), step times from ``--config``; the tables and the one line,
    at the fine level unless ``--level`` names others."""
    if space.label_level is not None:
        raise UsageError("--quick walks the scanner's procedure step by step; a recording set has no steps")
    started = time.perf_counter()
    config = load_config(args.config) if getattr(args, "config", None) else None
    results = [quick_evaluation(space, config, level, args.folds, args.seed, getattr(args, "workers", None),
                                open_set=getattr(args, "open_set", False)) for level in levels]
    for result in results:
        print(format_quick(result))
    print(f"{len(results)} quick-scan evaluation(s) in {time.perf_counter() - started:.1f} s")
    return results


def cmd_evaluate(args: argparse.Namespace) -> int:
    if args.dataset:
        return cmd_set_evaluate(args)
    with cluster(args) as client:
        space = space_for(args, client)
        run_evaluation(regroup_scans(space, args), args, client)
    return 0


def set_recordings(spec: str, db: Path) -> tuple[str, list]:
    """The set name and recordings a ``set:NAME`` argument names."""
    if not spec.startswith("set:"):
        raise UsageError(f"{spec!r} is not a recording set; name one as set:NAME (see 'texplorer ingest')")
    return spec[4:], load_recordings(set_folder(db, spec[4:]))


def set_space(args: argparse.Namespace, client=None):
    """The feature space of ``set:NAME`` with the windowing, crop and grouping asked for (on the Dask cluster
    of ``client`` if given); prints a summary line and the extraction warnings (a count, all with
    --verbose)."""
    name, recordings = set_recordings(args.dataset, args.db)
    windowing = Windowing(args.window, args.combine)
    started = time.perf_counter()
    wanted = args.feature_set if isinstance(args.feature_set, list) else [args.feature_set]
    space, notes = feature_space(recordings, windowing, args.border, args.group_by, workers=args.workers,
                                 progress=True, client=client, chosen=feature_sets.role_families_for(wanted))
    for note in notes if args.verbose else notes[:3]:
        print(f"texplorer: warning: {one_line(note)}", file=sys.stderr)
    if len(notes) > 3 and not args.verbose:
        print(f"texplorer: warning: {len(notes) - 3} more warning(s); --verbose lists them", file=sys.stderr)
    levels = ", ".join(f"{level} ({len(set(space.y(level)))} classes)" for level in reversed(space.level_names))
    split = (f"; split {space.split.count('train')} train / {space.split.count('test')} test"
             if space.split else "")
    print(f"set:{name}: {len(recordings)} recordings -> {len(space)} rows ({windowing.describe()}), "
          f"{len(set(space.groups))} groups; levels {levels}{split}")
    print(f"features: {describe_families(space.columns)} in {time.perf_counter() - started:.1f} s")
    return space


SET_TABLE = "features.csv"
SET_TABLE_OPTIONS = "features.json"
"""Beside a set's feature table, the options it was written with (windowing, crop, grouping), the feature
code version and the recordings it read, so ``evaluate set:NAME`` can tell whether the table fits."""


def recordings_fingerprint(folder: Path) -> str:
    """A hash of the set's recording files' stat records: name, size, modification time, inode and inode
    change time. The change time is the kernel's: an edit of the same size whose modification time is put
    back (``cp -p``, ``rsync -t``, ``touch -r``, a backup restored) still changes it."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.mat")):
        stat = path.stat()
        digest.update(f"{path.name}\0{stat.st_size}\0{stat.st_mtime_ns}\0{stat.st_ino}\0{stat.st_ctime_ns}\n"
                      .encode())
    return digest.hexdigest()


def recordings_content(folder: Path) -> str:
    """A hash of the set's recording files' names and contents: what a feature table was computed from.
    Asked only when the stat records differ (a set copied, restored or touched), so an unchanged set is not
    read in full."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.mat")):
        digest.update(f"{path.name}\0{sha256_file(path)}\n".encode())
    return digest.hexdigest()


def set_table_options(args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """What a set's feature table depends on, as ``features.json`` records it."""
    wanted = args.feature_set if isinstance(args.feature_set, list) else [args.feature_set]
    families = feature_sets.role_families_for(wanted)
    return {"window": args.window, "combine": args.combine, "border": args.border, "group_by": args.group_by,
            "families": list(families or ()), "code_version": code_version(),
            "recordings": recordings_fingerprint(folder)}


OPTION_WORDS = {"window": "--window", "combine": "--combine", "border": "--border", "group_by": "--group-by",
                "families": "--feature-set",
                "code_version": "the feature code", "recordings": "the recordings"}


def _table_options(folder: Path) -> tuple[Path, dict[str, Any] | None, str]:
    """A set's feature table, the options its ``features.json`` records (None if there are none), and why not."""
    table, written = folder / SET_TABLE, folder / SET_TABLE_OPTIONS
    if not table.is_file() or not written.is_file():
        return table, None, f"no table written by 'texplorer features set:{folder.name}'"
    try:
        stored = json.loads(written.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return table, None, f"{written} cannot be read"
    return (table, stored, "") if isinstance(stored, dict) else (table, None, f"{written} holds no table options")


def stored_set_table(args: argparse.Namespace, folder: Path) -> tuple[Path | None, str]:
    """The set's feature table if it was written with the options of ``args`` (and the same recordings and
    feature code), else None; and one line saying which table ``evaluate`` uses and why."""
    table, stored, why = _table_options(folder)
    if stored is None:
        return None, f"extracting the features ({why})"
    wanted = set_table_options(args, folder)
    differ = [OPTION_WORDS[key] for key in wanted if stored.get(key) != wanted[key]]
    if differ == [OPTION_WORDS["recordings"]] and stored.get("content") == recordings_content(folder):
        differ = []  # the files were copied or touched, not changed: their contents prove it
    if differ:
        return None, f"extracting the features ({table} was written with other {', '.join(differ)})"
    return table, f"using {table} (written by 'texplorer features {args.dataset}' with the same options)"


def current_set_table(folder: Path) -> tuple[Path | None, str]:
    """The set's feature table if the current feature code computed it from the recordings the set holds now
    (whatever its options, which its ``features.json`` records), else None; and why not."""
    table, stored, why = _table_options(folder)
    if stored is None:
        return None, why
    if stored.get("code_version") != code_version():
        return None, f"{table} was written by other feature code"
    if stored.get("recordings") != recordings_fingerprint(folder) and stored.get("content") != \
            recordings_content(folder):
        return None, f"{table} was written from other recordings"
    return table, ""


def cmd_set_features(args: argparse.Namespace) -> int:
    folder = set_folder(args.db, args.dataset[4:])
    with cluster(args) as client:
        space = set_space(args, client)
    out = args.out or folder / SET_TABLE
    print(f"wrote {space.to_csv(out)}")
    if args.out is None:
        atomic_write_bytes(folder / SET_TABLE_OPTIONS, json.dumps(
            {**set_table_options(args, folder), "content": recordings_content(folder)}).encode())
    if args.mat:
        print(f"wrote {space.to_mat(args.mat)}")
    return 0


def cmd_set_evaluate(args: argparse.Namespace) -> int:
    if args.features:
        raise UsageError("give either a set (set:NAME) or --features CSV, not both")
    table, which = stored_set_table(args, set_folder(args.db, args.dataset[4:]))
    print(f"{args.dataset}: {which}")
    with cluster(args) as client:
        space = FeatureSpace.from_csv(table) if table else set_space(args, client)
        reports = run_evaluation(space, args, client)
        if reports and getattr(args, "leakage", False):
            print()
            print("the same evaluation with --group-by none: every row its own group, so the windows of one "
                  "recording fall in training and test (the published protocol)")
            ungrouped = run_evaluation(dataclasses.replace(space, groups=space.scan_ids),
                                       argparse.Namespace(**{**vars(args), "group_by": "none", "report": None}),
                                       client)
            print()
            print(format_protocols(reports, ungrouped))
    return 0 if reports else EXIT_ERROR


def _add_set_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", nargs="?", metavar="set:NAME", help="a recording set imported with "
                        "'texplorer ingest' (default: the scans of the database)")
    parser.add_argument("--window", type=float, metavar="SECONDS", help="sets: cut each recording into "
                        "windows of this length (default: the whole recording)")
    parser.add_argument("--combine", choices=("mean", "median", "rows"), default="mean", help="sets: combine "
                        "the windows' features by their mean (default) or median, or make each window a row "
                        "(in its recording's group)")
    parser.add_argument("--border", type=int, default=0, metavar="PX", help="sets: pixels cropped from every "
                        "side of a photo before its features (default 0; the scanner's photos use 100)")
    parser.add_argument("--group-by", default="auto", metavar="GROUP", help="what folds keep together: for "
                        "the database's scans sample (default), session, operator or recording (each scan); "
                        "for sets a group of the mapping's pattern, recording (each recording with its "
                        "windows; also 'none'), or auto (default: object, else the photo a patch was cut "
                        "from, else the recording)")
    parser.add_argument("--verbose", action="store_true", help="sets: print every extraction warning")


def cmd_train(args: argparse.Namespace) -> int:
    if args.out is not None and args.out.exists():  # said before the training, not after
        raise UsageError(f"{args.out} exists: a trained model is never overwritten; give a new name, or leave "
                         "out --out to keep it as the database's next model version")
    with cluster(args) as client:
        space = space_for(args, client)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = train_model(space, args.level, args.n, args.classifier, args.seed,
                            None if args.feature_set == ALL else args.feature_set)
    stops, others = iteration_limit_stops(classifier_estimators(args.seed)[args.classifier], caught)
    for warning in others:  # as they would have been shown
        warnings.showwarning(warning.message, warning.category, warning.filename, warning.lineno)
    if stops:
        print(f"texplorer: note: the MLP stopped at the paper's {MLP_MAX_ITER} L-BFGS iterations before "
              f"converging in {stops} of its fits, as the paper's setting does (not a fault; the features are "
              "scaled)", file=sys.stderr)
    print(model.describe())
    if args.out is not None:
        save_model(model, args.out)
        print(f"wrote {args.out}")
        return 0
    figures = {}
    if not args.no_cv:
        figures, line = cross_validated(space, args.level, args.n, args.classifier, args.seed,
                                        None if args.feature_set == ALL else args.feature_set)
        print(line if figures else f"texplorer: note: {line}", file=sys.stdout if figures else sys.stderr)
    before = current_version(args.db)
    version = save_model_version(open_db(args), model, space, figures, note="texplorer train",
                                 make_current=not args.keep_current)
    now = current_version(args.db)
    print(ModelChange(version, before, now).describe(load_taxonomy()))
    print(f"wrote {version_file(args.db, version)}; the web application (at its next prediction) and classify use "
          f"version {now.version if now else '-'}")
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    count = len(REGISTRY.names)
    features = commands.add_parser("features", help="extract the features of every scan into a feature table",
                                   description=f"Extract the {count} features of every scan (cached in the database "
                                   "by scan content and feature-code version) and write features.csv.")
    add_db_option(features)
    _add_set_options(features)
    add_feature_set_option(features, many=True)
    features.add_argument("--workers", type=int, help="processes (default: number of cores)")
    features.add_argument("--out", type=Path, help="CSV file (default: <db>/features.csv, with --label "
                          "<db>/features-<LABEL>.csv; for a set <db>/recordings/<set>/features.csv, which "
                          "'evaluate set:NAME' then uses when given the same options)")
    features.add_argument("--mat", type=Path, help="also write the feature space as a .mat file")
    features.add_argument("--label", help="only scans with this label, class prefix (C6 = every stone) or part "
                          "of a material name (granite)")
    add_cluster_options(features)
    features.set_defaults(handler=cmd_features)

    select = commands.add_parser("select", help="print the FQ ranking and the selected feature set",
                                 description="Feature quality (Kruskal-Wallis + Tukey-Kramer) ranking and the "
                                 "FQ + Spearman selection on all scans.")
    add_space_options(select)
    select.add_argument("--level", choices=LEVELS, default="fine", help="classification level (default fine)")
    select.add_argument("--n", type=int, default=10, help="features to select (default 10)")
    select.add_argument("--max-corr", type=float, default=0.5, help="Spearman limit (default 0.5)")
    select.add_argument("--top", type=int, default=20, help="rows of the FQ ranking to print (default 20)")
    select.set_defaults(handler=cmd_select)

    evaluate = commands.add_parser("evaluate", help="cross-validate classifiers x feature sets x levels; "
                                   "table and HTML report", description="Cross-validated accuracy, macro F1 and "
                                   "r_C of classifiers x feature sets x levels x set sizes. For a recording set "
                                   "(set:NAME): its own class names and levels, folds grouped by its groups, or "
                                   "its own train/test split when it has one.")
    add_space_options(evaluate)
    _add_set_options(evaluate)
    evaluate.add_argument("--leakage", action="store_true", help="sets: evaluate again with every row its own "
                        "group (--group-by none: windows of one recording in training and test, as published "
                        "window-level results do) and print both figures side by side")
    add_evaluation_options(evaluate, report_default=None)
    evaluate.add_argument("--ignore-split", action="store_true", help="sets: cross-validate over every "
                          "recording even if the set has its own train/test split")
    evaluate.add_argument("--single-group", choices=("train", "drop"), default="train",
                          help="a class with a single sample (group) cannot be tested in grouped folds: keep it "
                          "in training only (default) or leave it out; the other classes' folds stay grouped")
    evaluate.add_argument("--vote", action="store_true", help="score each recording once, by the mean "
                          "calibrated probability of its windows (sets with --combine rows)")
    evaluate.add_argument("--open-set", action="store_true", help="hold out whole classes per fold: AUROC of "
                          "the rejection score, known-class accuracy at the learned threshold and the share "
                          "of unknown scans rejected (docs/trust.md)")
    evaluate.add_argument("--quick", action="store_true", help="walk every full scan step by step as a quick "
                          "scan (the next step chosen by information per second, stopping at a calibrated 0.95): "
                          "share decided and accuracy after each step and second, adaptive and in the paper's "
                          "order, at the fine level unless --level says otherwise; with --open-set also how "
                          "often it stops on a material it never saw (docs/quick.md)")
    evaluate.add_argument("--config", type=Path, help="--quick: device configuration TOML whose [steps] and "
                          "[handling] give each step's time (default: the built-in times)")
    evaluate.add_argument("--no-calibration", action="store_true", help="skip the temperature scaling inside "
                          "every fold (about 4x less fitting; no reliability diagram or ECE)")
    evaluate.set_defaults(handler=cmd_evaluate)

    train = commands.add_parser("train", help="train a classifier on all scans and save it (skops)",
                                description="Fit scaler -> FQ selector -> classifier on every scan and save "
                                "the model in a format that cannot execute code when loaded.")
    add_space_options(train)
    train.add_argument("--out", type=Path, help="write the model to this new file (.skops) instead of keeping it as "
                       "the database's next model version ('texplorer models')")
    train.add_argument("--keep-current", action="store_true", help="keep the current model version current (the "
                       "new version is kept, and 'texplorer models --use N' makes it current later)")
    train.add_argument("--no-cv", action="store_true", help="skip the cross-validated accuracy the version records")
    train.add_argument("--level", choices=LEVELS, default="fine", help="classification level (default fine)")
    train.add_argument("--n", type=int, default=10, help="selected features (default 10)")
    train.add_argument("--classifier", choices=CLASSIFIER_NAMES, default="rf", help="classifier (default rf)")
    train.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_feature_set_option(train, many=False)
    train.set_defaults(handler=cmd_train)
