"""``texplorer demo``: simulated scanner -> database -> features -> evaluation -> a trained model."""

from __future__ import annotations

import argparse
import sys
import time

from features import REGISTRY
from scanner.cli.analysis import add_evaluation_options, run_evaluation
from scanner.cli.base import UsageError, add_db_option
from scanner.cli.common import ALL, add_cluster_options, runtime_of
from scanner.cli.features import report_space
from scanner.preprocess import small_photo_note
from scanner.workflows.database import extract_database
from scanner.workflows.demo import simulated_database
from scanner.workflows.models import DEFAULT_MODEL_SETTINGS, save_model_version, train_default_model
from taxonomy.learning.versions import version_file

DEMO_SAMPLES = 2


DEMO_SCANS = 3


DEMO_IMAGE_SIZE = 384
"""Photo size of the demo's simulated camera, in pixels. The image features crop 100 px from each edge
(184 px squares left at 384 px), and the demo's image and fused accuracies at 384 px equal those at 512 px
within their intervals (docs/simulator.md), for 0.56x the pixels to simulate, encode and extract."""


PAPER_FIGURES = (("coarse", 10), ("fine", 10))
"""The (level, set size) pairs the demo evaluates unless asked for more: the paper's Figs. 16 (coarse, X10)
and 17 (fine, X10, the paper's headline). Its Fig. 18 (fine, X3) would cost as much again as Fig. 17
(docs/performance.md); ``--full-grid`` (or ``--level`` / ``--n``)
evaluates it with every other level and set size, as ``texplorer evaluate`` does."""


def fitting_folds(folds: int, samples: int, scans: int) -> int:
    """The cross-validation folds the demo's database allows: each material has ``samples * scans`` scans,
    and stratified folds need a class with at least as many rows as folds (``taxonomy.evaluation.cv_splits``).

    Raises
    ------
    UsageError
        Fewer than two scans per material: nothing can be cross-validated.
    """
    per_material = samples * scans
    if per_material < 2:
        raise UsageError(f"--samples {samples} --scans {scans} make one scan per material; cross-validation "
                         "needs two or more: use --samples 2 or --scans 2, or --no-evaluation")
    return min(folds, per_material)


def cmd_demo(args: argparse.Namespace) -> int:
    if args.samples < 1 or args.scans < 1:
        raise UsageError(f"--samples and --scans must be at least 1, got {args.samples} and {args.scans}")
    if not args.no_evaluation:
        folds = fitting_folds(args.folds, args.samples, args.scans)
        if folds < args.folds:
            print(f"texplorer: note: {folds} folds instead of {args.folds}: each material has {args.samples} x "
                  f"{args.scans} = {args.samples * args.scans} scans (more with --samples or --scans)",
                  file=sys.stderr)
            args.folds = folds
    if (note := small_photo_note(args.image_size, args.image_size)) is not None:
        print(f"texplorer: note: {note}", file=sys.stderr)
    started = time.perf_counter()
    db = simulated_database(args.db, materials=args.materials, scans_per_material=args.scans, seed=args.seed,
                            image_size=(args.image_size, args.image_size), progress=True,
                            samples_per_material=args.samples, workers=args.workers)
    summary = db.summary()
    print(f"database {args.db}: {summary['scans']} scans of {summary['materials']} materials "
          f"({summary['samples']} samples, {summary['files']} files) in {time.perf_counter() - started:.1f} s")
    by_class: dict[str, int] = {}
    for record in db.records():
        by_class[record.label[:2]] = by_class.get(record.label[:2], 0) + 1
    print("scans per major class: " + ", ".join(f"{c} {n}" for c, n in sorted(by_class.items())))
    with runtime_of(args) as runtime:
        started = time.perf_counter()
        space = extract_database(db, workers=args.workers)
        report_space(space, time.perf_counter() - started)
        print(f"wrote {space.to_csv(db.root / 'features.csv')}")
        if args.no_evaluation:
            return 0
        # The model needs only the features: trained beside the evaluation (in a process of its own, or as
        # one task on the cluster).
        model = runtime.submit(train_default_model, space, args.seed)
        args.report = args.report or db.root / "report"
        # Temperature scaling refits each classifier on three inner splits per fold; the report shows its
        # result in one reliability diagram per classifier, so the demo calibrates those cells only (the
        # report says so; texplorer evaluate calibrates every cell).
        args.calibrate_diagram_only = True
        if not args.full_grid and args.level == [ALL] and args.n is None:
            args.pairs = PAPER_FIGURES
        reports = run_evaluation(space, args)
        trained = model.result()
    level, n_features, classifier = DEFAULT_MODEL_SETTINGS
    same = [r for r in reports if (r.level, r.n_features, r.classifier, r.feature_set) ==
            (level, n_features, classifier, "all")]
    figures = {"cv_accuracy": float(same[0].accuracy_pooled)} if same else {}
    version = save_model_version(db, trained, space, figures, note="texplorer demo")
    print(f"model: version {version.version}, {version_file(db.root, version)} ({trained.describe()}); "
          f"the web application and classify use version {version.version} ('texplorer models' lists them all)")
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    count = len(REGISTRY.names)
    demo = commands.add_parser("demo", help="build a synthetic database from the simulated scanner and summarise it",
                               description=f"Simulated scanner -> database -> {count} features -> "
                               "cross-validated evaluation (table + HTML report) -> a trained random forest.")
    add_db_option(demo)
    demo.add_argument("--materials", nargs="+", metavar="SLUG", help="material slugs (default: whole library)")
    demo.add_argument("--samples", type=int, default=DEMO_SAMPLES, help="samples (pieces) per material "
                      f"(default {DEMO_SAMPLES}: two or more let cross-validation keep each piece in one fold)")
    demo.add_argument("--scans", type=int, default=DEMO_SCANS, help=f"scans per sample (default {DEMO_SCANS})")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    demo.add_argument("--image-size", type=int, default=DEMO_IMAGE_SIZE,
                      help=f"photo size in pixels (default {DEMO_IMAGE_SIZE})")
    demo.add_argument("--workers", type=int, help="processes for simulation, features and evaluation "
                      "(default: number of cores)")
    demo.add_argument("--no-evaluation", action="store_true", help="stop after the feature table")
    demo.add_argument("--full-grid", action="store_true", help="evaluate every level (coarse, medium, fine) "
                      "and set size (3, 10), as texplorer evaluate does; default: the paper's Figs. 16 and "
                      "17 (coarse X10, fine X10)")
    add_cluster_options(demo)
    add_evaluation_options(demo, report_default="<db>/report", seed=False)
    demo.set_defaults(handler=cmd_demo)
