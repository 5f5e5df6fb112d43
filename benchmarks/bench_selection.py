"""Feature-quality and evaluation-grid benchmark on a paper-sized synthetic feature space.

1. ``feature_quality`` on 920 rows (184 materials x 5 scans) x 193 features: 16,836 class pairs per
   feature. References in the same process: ``scipy.stats.rankdata`` of the same matrix (the floor: FQ ranks
   every column twice, once for the lower and once for the upper end of each tie run) and the projected
   time of calling ``scipy.stats.studentized_range.sf`` once per pair and feature. Target <= 5 s.
2. The evaluation grid: 6 classifiers x 3 levels x 2 set sizes (X3, X10) x 5 folds on all 193 columns,
   nested protocol, 2 worker processes. Target <= 60 s on 2 cores.

Ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.stats
from timing import median_time

from features.selection import feature_quality
from features.space import FeatureSpace
from taxonomy.learning.evaluation import evaluate_grid

MATERIALS = 184
SCANS = 5
FEATURES = 193
FQ_TARGET_S = 5.0
GRID_TARGET_S = 60.0


def synthetic_space(seed: int = 0) -> FeatureSpace:
    """184 materials C1..C8 / S1..S3 / M1..M8, five scans each; every feature shifts per material by a
    feature-specific amount, so FQ ranges from noise to near-perfect separation."""
    rng = np.random.default_rng(seed)
    labels = [f"C{i % 8 + 1}S{i // 8 % 3 + 1}M{i // 24 + 1}P1X1" for i in range(MATERIALS)]
    modalities = ("tactum", 15), ("image", 93), ("audio", 70), ("other", 15)
    columns = tuple(f"{name}.f{j:02d}" for name, count in modalities for j in range(count))
    centres = rng.standard_normal((MATERIALS, FEATURES)) * rng.uniform(0.0, 2.0, FEATURES)
    material = np.repeat(np.arange(MATERIALS), SCANS)
    X = centres[material] + rng.standard_normal((material.size, FEATURES))
    X[:, ::7] = np.round(X[:, ::7])  # some tied columns, as judged and counted features have
    return FeatureSpace(X, columns, tuple(f"scan-{i}" for i in range(material.size)),
                        tuple(labels[m] for m in material), tuple(f"sample-{m}" for m in material))


def bench_feature_quality(space: FeatureSpace) -> None:
    y = space.y("fine")
    start = time.perf_counter()
    feature_quality(space.X, y)
    cold = time.perf_counter() - start
    warm = median_time(lambda: feature_quality(space.X, y), repeat=5)
    ranks = median_time(lambda: scipy.stats.rankdata(space.X, axis=0), repeat=5)
    probe = np.linspace(0.5, 8.0, 200)
    per_value = median_time(lambda: scipy.stats.studentized_range.sf(probe, MATERIALS, np.inf), 3)
    per_value /= probe.size
    pairs = MATERIALS * (MATERIALS - 1) // 2 * FEATURES
    verdict = "ok" if cold <= FQ_TARGET_S else f"SLOWER than the {FQ_TARGET_S:.0f} s target"
    print(f"feature_quality on {space.X.shape[0]} rows x {FEATURES} features, {MATERIALS} classes "
          f"({pairs:,} pair p-values)")
    print(f"  first call (builds the p-value table) {cold:6.2f} s ({verdict})")
    print(f"  later calls (median of 5)             {warm:6.2f} s")
    print(f"  scipy.stats.rankdata, same matrix     {ranks:6.3f} s   ratio {warm / ranks:6.1f}x")
    print(f"  studentized_range.sf once per pair    {per_value * pairs:6.0f} s (projected from "
          f"{per_value * 1e6:.0f} us per value)   ratio {warm / (per_value * pairs):8.4f}x")


def bench_grid(space: FeatureSpace) -> None:
    start = time.perf_counter()
    reports = evaluate_grid(space, feature_sets={"all": None}, set_sizes=(3, 10), workers=2)
    elapsed = time.perf_counter() - start
    verdict = "ok" if elapsed <= GRID_TARGET_S else f"SLOWER than the {GRID_TARGET_S:.0f} s target"
    print(f"evaluation grid: {len(reports)} cells (6 classifiers x 3 levels x 2 sizes) x 5 folds, "
          f"2 workers: {elapsed:.1f} s ({verdict})")
    for report in reports:
        if report.n_features == 10 and report.level == "fine":
            print(f"  {report.summary()}")


def main() -> None:
    space = synthetic_space()
    bench_feature_quality(space)
    bench_grid(space)


if __name__ == "__main__":
    main()
