"""The quick scan's model (docs/quick.md) on a demo-sized synthetic feature space with the paper's 193 columns.

1. Learning: ``fit_step_model`` (twelve extra-trees experts on all rows and on four grouped inner splits)
   and ``calibrate_walks`` (every training row walked in the adaptive and the paper's order), against a
   reference in the same process: one random forest of the product (100 trees) on every column, the
   cost unit of the paper's training.
2. One decision after a step: the experts' ratios and novelty of one scan, the posterior, the open-set
   check and the next step's expected information gain, against one ``predict_proba`` of that forest.

Ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

import numpy as np
from sklearn.ensemble import RandomForestClassifier
from timing import best_time

import features  # noqa: F401 - registers the paper's families, whose columns name their steps
from features.registry import REGISTRY
from taxonomy.learning.quick import STOP_AT, calibrate_walks, experts_of, fit_step_model, next_step

MATERIALS = 32
SAMPLES = 2
SCANS = 3
SECONDS = {"finger_tap": 10.0, "finger_slide": 10.0, "tool_tap": 20.0, "tool_slide": 10.0, "static": 11.0,
           "thermal": 18.0, "friction": 10.0, "press": 10.0, "fold": 15.0, "photos": 60.0, "tu4": 120.0}
"""The default protocol's step times (recording and handling, ``scanner.acquisition.session.step_seconds``)."""


def synthetic_scans(seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The demo database's shape: 32 materials x 2 samples x 3 scans; each column shifts per material by a
    column-specific amount and per sample by a tenth of it."""
    rng = np.random.default_rng(seed)
    columns = len(REGISTRY.names)
    centres = rng.standard_normal((MATERIALS, columns)) * rng.uniform(0.0, 2.0, columns)
    material = np.repeat(np.arange(MATERIALS), SAMPLES * SCANS)
    sample = material * SAMPLES + np.tile(np.repeat(np.arange(SAMPLES), SCANS), MATERIALS)
    offsets = 0.1 * rng.standard_normal((MATERIALS * SAMPLES, columns))
    X = centres[material] + offsets[sample] + rng.standard_normal((material.size, columns))
    return X, np.array([f"C1S1M{m + 1}P1X1" for m in material]), sample.astype(str)


def main() -> None:
    X, y, groups = synthetic_scans()
    experts = experts_of(REGISTRY.names, REGISTRY.column_steps())
    order = tuple(SECONDS)
    forest = RandomForestClassifier(n_estimators=100, random_state=0, n_jobs=1)
    reference_fit = best_time(lambda: forest.fit(X, y), repeat=3)
    model = None

    def learn() -> None:
        nonlocal model
        model = calibrate_walks(fit_step_model(X, y, groups, experts), SECONDS, (None, order))

    fit = best_time(learn, repeat=1)
    print(f"learning the quick model: {len(experts)} experts on {len(y)} scans x {X.shape[1]} columns, "
          f"{fit:.2f} s = {fit / reference_fit:.1f}x one random forest of 100 trees ({reference_fit:.2f} s)")

    x = X[:1]
    recorded = frozenset({"tool_slide"})

    def decide() -> None:
        ratios, novelty = model.ratios(x[0]), model.novelty(x[0])
        p = model.predict(ratios, recorded)
        _ = p.max() >= STOP_AT and model.accepts(novelty, recorded, int(np.argmax(p)))
        next_step(model, ratios, recorded, SECONDS)  # what a scan not yet sure does next

    reference_predict = best_time(lambda: forest.predict_proba(x), repeat=20)
    decision = best_time(decide, repeat=10)
    print(f"one decision after a step (posterior, open-set check, next step): {1000 * decision:.0f} ms = "
          f"{decision / reference_predict:.1f}x one predict_proba of that forest ({1000 * reference_predict:.1f} ms)")


if __name__ == "__main__":
    main()
