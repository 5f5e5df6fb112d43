"""Recall of a material enrolled from a few scans, and what enrolment costs the other materials
(docs/trust.md#enrolment).

    python benchmarks/enrolment_recall.py texplorer-data/features.csv [--every 2] [--scans 2 3 5]

For each material ``m`` of the feature table (every ``--every``-th, in label order) and each number ``k`` of
enrolled scans: the database's default model (:func:`scanner.workflows.models.train_default_model`: random forest,
fine level, 10 features, the rejection rule) is trained on every scan of the other materials and the first
``k`` scans of ``m`` (its first sample's scans first, as an operator scans one piece, then the next), and
classifies ``m``'s other scans. Recall counts a scan named ``m`` and accepted by the rule; "named" counts it
named ``m`` whatever the rule says. The other materials' accuracy is their pooled cross-validated accuracy
(5 folds grouped by sample, closed set) on the same folds without ``m`` (before) and with its ``k`` scans
added to every fold's training rows (after). Prints one table; minutes on two cores.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from features.space import FeatureSpace
from scanner.workflows.models import train_default_model
from taxonomy.learning.evaluation import SEED, cv_splits, fit_pipeline


def others_accuracy(space: FeatureSpace, others: np.ndarray, enrolled: np.ndarray) -> float:
    """Pooled accuracy over the rows ``others`` in 5 folds grouped by sample, each fold's model (random forest,
    fine level, 10 features) trained on its other folds' rows and the ``enrolled`` rows: the same folds with
    and without a material's scans, so the difference is the enrolment's alone."""
    y, groups = space.y("fine"), np.asarray(space.groups)
    splits, _ = cv_splits(y[others], groups[others], 5, SEED)
    right = 0
    for train, test in splits:
        rows = np.concatenate([others[train], enrolled])
        pipeline = fit_pipeline(space.X[rows], y[rows], groups[rows], "rf", 10, SEED, calibrate=False,
                                columns=space.columns)
        right += int(np.sum(pipeline.predict(space.X[others[test]]) == y[others[test]]))
    return right / len(others)


def enrolled_order(space: FeatureSpace, rows: np.ndarray) -> np.ndarray:
    """``rows`` of one material in the order an operator scans them: sample by sample, scan by scan."""
    return rows[np.lexsort((np.asarray(space.scan_ids)[rows], np.asarray(space.groups)[rows]))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n", 1)[0])
    parser.add_argument("features")
    parser.add_argument("--every", type=int, default=2, help="every n-th material (default 2)")
    parser.add_argument("--scans", type=int, nargs="+", default=[2, 3, 5], help="scans enrolled (default 2 3 5)")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    space = FeatureSpace.from_csv(args.features)
    y = space.y("fine")
    materials = sorted(set(y))[::args.every]
    started = time.perf_counter()
    recall = {k: [] for k in args.scans}
    named = {k: [] for k in args.scans}
    before_after = {k: [] for k in args.scans}
    for material in materials:
        own = enrolled_order(space, np.flatnonzero(y == material))
        others = np.flatnonzero(y != material)
        before = others_accuracy(space, others, own[:0])
        for k in args.scans:
            if k >= len(own):
                continue
            train = np.concatenate([others, own[:k]])
            model = train_default_model(space.rows(train), 0)
            test = space.rows(own[k:])
            columns = [list(space.columns).index(c) for c in model.feature_names]
            X = test.X[:, columns]
            predicted = model.pipeline.predict(X)
            rejected = model.rejection.score(model.pipeline, X) > model.rejection.threshold
            recall[k] += list((predicted == material) & ~rejected)
            named[k] += list(predicted == material)
            before_after[k].append((before, others_accuracy(space, others, own[:k])))
        print(f"{material}: done ({time.perf_counter() - started:.0f} s)", flush=True)
    print(f"\n{len(materials)} materials of {args.features}, default model (rf, fine, 10 features, rejection rule)")
    print("| scans enrolled | scans tested | recall % (named and accepted) | named % | "
          "others' CV accuracy % before -> after |")
    print("| --- | --- | --- | --- | --- |")
    for k in args.scans:
        if not recall[k]:
            continue
        pairs = np.array(before_after[k])
        print(f"| {k} | {len(recall[k])} | {100 * np.mean(recall[k]):.1f} | {100 * np.mean(named[k]):.1f} | "
              f"{100 * pairs[:, 0].mean():.1f} -> {100 * pairs[:, 1].mean():.1f} |")
    print(f"{time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
