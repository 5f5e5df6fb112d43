"""``texplorer select``, ``evaluate``, ``train``: feature selection, cross-validated evaluation and trained
models, of the database's scans or of a recording set (its feature table: :mod:`scanner.cli.features`)."""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path

from features import FeatureSpace, feature_sets
from features.selection import select_features
from scanner.acquisition.config import load_config
from scanner.cli.base import EXIT_ERROR, UsageError, open_db
from scanner.cli.common import (
    ALL,
    add_feature_set_option,
    add_space_options,
    choices,
    runtime_of,
    set_sizes,
    space_for,
)
from scanner.cli.features import add_set_options, set_space, stored_set_table
from scanner.storage.ingest import set_folder
from scanner.workflows.models import ModelChange, cross_validated, save_model_version
from scanner.workflows.quick import quick_evaluation
from taxonomy.labels import LEVELS
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
    running_vote,
    vote,
    with_values,
)
from taxonomy.learning.models import save_model, train_model
from taxonomy.learning.versions import current_version, version_file
from taxonomy.reports.report import format_open_set, format_protocols, format_quick, format_table, write_report
from taxonomy.table import load_taxonomy

CLASSIFIER_NAMES = tuple(CLASSIFIERS)
"""The classifiers ``--classifier`` offers (:func:`taxonomy.learning.evaluation.classifier_estimators`)."""


def windows_before(value: str) -> int:
    """An argparse type: ``--history``'s number of windows before each one, a whole number >= 0."""
    try:
        count = int(value)
    except ValueError:
        count = -1
    if count < 0:
        raise argparse.ArgumentTypeError(f"the history is a whole number of windows >= 0, got {value!r}")
    return count


def add_evaluation_options(parser: argparse.ArgumentParser, report_default: str | None, seed: bool = True) -> None:
    parser.add_argument("--classifier", nargs="+", choices=(*CLASSIFIER_NAMES, ALL), default=[ALL],
                        help="classifiers (default all)")
    parser.add_argument("--level", nargs="+", default=[ALL], help="levels: coarse, medium, fine, or a set's "
                        "own levels (default all)")
    parser.add_argument("--n", nargs="+", metavar="N", help="selected set sizes, and 'all' for every feature "
                        "without selection (default 3 10; for a set 3 10 all)")
    add_feature_set_option(parser, many=True)
    parser.add_argument("--protocol", choices=("nested", "paper"), default="nested",
                        help="nested (default): scaling and selection inside the folds; paper: on all data first")
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds (default 5)")
    if seed:
        parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    default = f" (default {report_default})" if report_default else ""
    parser.add_argument("--report", type=Path, default=None, help=f"write the HTML report into this folder{default}")


def cmd_select(args: argparse.Namespace) -> int:
    with runtime_of(args):
        space = space_for(args)
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


def run_evaluation(space, args: argparse.Namespace) -> list:
    """Evaluate the grid asked for on the command line (where the current runtime runs the work); print
    the table; write the HTML report if asked."""
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
    history = getattr(args, "history", None)
    if history is not None and (getattr(args, "quick", False) or getattr(args, "open_set", False)):
        raise UsageError("--history votes over the windows of a closed-set evaluation; not with --quick or "
                         "--open-set")
    if history is not None and group_by == "none":
        raise UsageError("--history answers a window with those before it in its recording, which --group-by "
                         "none puts in other folds (their models were trained on this window); group by recording")
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
                            single_group=getattr(args, "single_group", "train"),
                            calibrate=calibrate, group_by=group_by, pairs=getattr(args, "pairs", None))
    voting = "--vote" if getattr(args, "vote", False) else f"--history {history}" if history else None
    recordings = [recording_of(s) for s in space.scan_ids]
    if voting and len(set(recordings)) == len(recordings):
        print(f"texplorer: warning: {voting}: every recording is one row (no windows), so the vote changes "
              "nothing", file=sys.stderr)
    elif history == 1 and not calibrate:
        print("texplorer: warning: --history 1 --no-calibration: without probabilities two windows' answers "
              "agree or tie, and a tie goes to the latest, so the history changes nothing; give 2 or more",
              file=sys.stderr)
    if getattr(args, "vote", False):
        reports = [vote(r, recordings) for r in reports]
    if history:
        reports = [running_vote(r, space.scan_ids, history) for r in reports]
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
    with runtime_of(args):
        space = space_for(args)
        run_evaluation(regroup_scans(space, args), args)
    return 0


def cmd_set_evaluate(args: argparse.Namespace) -> int:
    if args.features:
        raise UsageError("give either a set (set:NAME) or --features CSV, not both")
    if getattr(args, "leakage", False) and (args.vote or args.history is not None):
        raise UsageError(f"{'--vote' if args.vote else '--history'} answers with several windows of a recording, "
                         "which --leakage's second evaluation puts in different folds; run them separately")
    table, which = stored_set_table(args, set_folder(args.db, args.dataset[4:]))
    print(f"{args.dataset}: {which}")
    with runtime_of(args):
        space = FeatureSpace.from_csv(table) if table else set_space(args)
        reports = run_evaluation(space, args)
        if reports and getattr(args, "leakage", False):
            print()
            print("the same evaluation with --group-by none: every row its own group, so the windows of one "
                  "recording fall in training and test (the published protocol)")
            ungrouped = run_evaluation(dataclasses.replace(space, groups=space.scan_ids),
                                       argparse.Namespace(**{**vars(args), "group_by": "none", "report": None}))
            print()
            print(format_protocols(reports, ungrouped))
    return 0 if reports else EXIT_ERROR


def cmd_train(args: argparse.Namespace) -> int:
    if args.out is not None and args.out.exists():  # said before the training, not after
        raise UsageError(f"{args.out} exists: a trained model is never overwritten; give a new name, or leave "
                         "out --out to keep it as the database's next model version")
    with runtime_of(args):
        space = space_for(args)
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
    add_set_options(evaluate)
    evaluate.add_argument("--leakage", action="store_true", help="sets: evaluate again with every row its own "
                        "group (--group-by none: windows of one recording in training and test, as published "
                        "window-level results do) and print both figures side by side")
    add_evaluation_options(evaluate, report_default=None)
    evaluate.add_argument("--ignore-split", action="store_true", help="sets: cross-validate over every "
                          "recording even if the set has its own train/test split")
    evaluate.add_argument("--single-group", choices=("train", "drop"), default="train",
                          help="a class with a single sample (group) cannot be tested in grouped folds: keep it "
                          "in training only (default) or leave it out; the other classes' folds stay grouped")
    voting = evaluate.add_mutually_exclusive_group()
    voting.add_argument("--vote", action="store_true", help="score each recording once, by the mean "
                        "calibrated probability of its windows (sets with --combine rows)")
    voting.add_argument("--history", type=windows_before, metavar="K", help="answer each window by the class of "
                        "highest mean calibrated probability over it and the K windows before it in its recording "
                        "(only past windows, as a robot driving on knows them; without calibration the most "
                        "frequent answer, a tie to the latest; sets with --combine rows, folds grouped by recording)")
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
