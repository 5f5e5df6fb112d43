"""Accuracy of every modern family beside the paper's features, on the same folds (docs/modern-features.md).

    python benchmarks/modern_accuracy.py [--db DEMO_DB] [--per-class 30] [--workers 2] [--snr-db 0 -6]

Sets: the simulated database of ``texplorer demo`` (if ``--db`` is given; scans), and the two contrast sets
of :mod:`scanner.simulation.contrasts` (spectral shape only; transient timing only; recordings with a
``vibration`` role). Every feature set is evaluated by the project's evaluation (nested protocol, 5 folds,
seed 0, the same folds for every set, random kernels fitted inside the folds) with the random forest and
the ridge classifier, on the 10 features FQ + Spearman selects and on every feature. Prints one table per
set and the time each feature set took. Run once; it takes minutes on two cores.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from features import feature_sets
from features.recordings import feature_space
from scanner.simulation.contrasts import contrast_recordings
from scanner.storage.database import Database
from scanner.workflows.database import extract_database
from taxonomy.learning.evaluation import evaluate_grid
from taxonomy.reports.report import format_table

SETS = ("paper", "catch22", "scattering", "minirocket", "multirocket", "fusion")
CLASSIFIERS = ("rf", "ridge")
SIZES = (10, None)


def evaluate_sets(space, levels, workers: int, sets: tuple[str, ...] = SETS,
                  classifiers: tuple[str, ...] = CLASSIFIERS) -> None:
    """One table per feature set. Calibration is off: it changes no prediction, so no accuracy, and it
    would fit every pipeline (random kernels included) three more times per fold."""
    reports = []
    for name in sets:
        started = time.perf_counter()
        found = evaluate_grid(space, classifiers, levels, SIZES, {name: name}, workers=workers, calibrate=False)
        reports += found
        print(f"  {name:<12} {time.perf_counter() - started:7.1f} s", flush=True)
        print(format_table(found), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--db", type=Path)
    parser.add_argument("--per-class", type=int, default=30)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--sets", nargs="+", default=list(SETS), help="feature sets (default: all six)")
    parser.add_argument("--levels", nargs="+", help="levels of the database (default: all)")
    parser.add_argument("--classifiers", nargs="+", default=list(CLASSIFIERS), help="default: rf ridge")
    parser.add_argument("--no-contrasts", action="store_true", help="only the database")
    parser.add_argument("--contrasts", nargs="*", default=["spectral", "timing"], help="contrast sets")
    parser.add_argument("--snr-db", type=float, nargs="*", default=[],
                        help="also each contrast set buried in white noise at these signal-to-noise ratios")
    args = parser.parse_args()
    contrasts = [(which, snr) for which in args.contrasts for snr in [None, *args.snr_db]]
    for which, snr in () if args.no_contrasts else contrasts:
        recordings = contrast_recordings(which, per_class=args.per_class, snr_db=snr)
        started = time.perf_counter()
        space, _ = feature_space(recordings, chosen=feature_sets.role_families_for(SETS), workers=args.workers)
        where = "" if snr is None else f" at {snr:g} dB SNR"
        print(f"== {which}{where}: {len(space)} recordings, {len(set(space.label_text))} classes, "
              f"{len(space.columns)} columns in {time.perf_counter() - started:.1f} s", flush=True)
        evaluate_sets(space, None, args.workers, tuple(args.sets), tuple(args.classifiers))
    if args.db:
        started = time.perf_counter()
        space = extract_database(Database(args.db, create=False), workers=args.workers, progress=False,
                                 families=feature_sets.families_for(args.sets))
        print(f"== simulated database {args.db}: {len(space)} scans, {len(space.columns)} columns in "
              f"{time.perf_counter() - started:.1f} s", flush=True)
        evaluate_sets(space, args.levels, args.workers, tuple(args.sets), tuple(args.classifiers))


if __name__ == "__main__":
    main()
