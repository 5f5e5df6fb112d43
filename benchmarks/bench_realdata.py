"""Real recordings end to end: the BorealTC terrain runs (``../shared/realdata/borealtc``) ingested,
their features extracted and evaluated, beside the ingest of the same files, in one process.

The mapping is the one docs/ingest.md shows (68 runs of an IMU at 100 Hz and wheel service data at 6.5 Hz).
Timed: ``ingest`` into a fresh database; the features of 5 s windows (every window a row, two worker
processes); the random forest and the balanced forest on every feature, 5 folds grouped by run, once with
the set's groups and once with every window alone (``evaluate --leakage --classifier rf brf``). The ratio
of the whole run to the ingest alone compares across machines; the goal is the whole run within 5 minutes
on two cores. Skips with a line where the recordings are not there.
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BOREALTC = ROOT.parent / "shared" / "realdata" / "borealtc"


def docs_mapping() -> str:
    sys.path.insert(0, str(ROOT))
    from tests.unit.test_docs import blocks

    (block,) = [b for b in blocks(ROOT / "docs" / "ingest.md") if b.file == "borealtc.toml"]
    return block.body


def main() -> None:
    if not BOREALTC.is_dir():
        print(f"skipped: the real recordings are not at {BOREALTC}")
        return
    import warnings

    from features.recordings import Windowing, feature_space
    from scanner.storage import ingest
    from taxonomy.learning.evaluation import evaluate_grid

    mapping = ingest.parse_mapping(docs_mapping(), "borealtc")
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        with ingest.SetWriter(folder, "borealtc") as writer:
            report = ingest.ingest(BOREALTC, mapping, sink=writer)
            writer.commit()
        ingested = time.perf_counter() - started
        recordings = ingest.load_recordings(ingest.set_folder(folder, "borealtc"))
        started = time.perf_counter()
        space, _ = feature_space(recordings, Windowing(5.0, "rows"), workers=2)
        extracted = time.perf_counter() - started
        cells = {"classifiers": ["rf", "brf"], "set_sizes": [None], "feature_sets": {"all": None}, "workers": 2}
        started = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            grouped = evaluate_grid(space, group_by="recording", **cells)
            alone = evaluate_grid(dataclasses.replace(space, groups=space.scan_ids), group_by="none", **cells)
        evaluated = time.perf_counter() - started
    total = ingested + extracted + evaluated
    print(f"BorealTC: {len(report.made)} runs ({report.files} files, {len(report.skipped)} named and not read) "
          f"-> {len(space)} windows x {space.X.shape[1]} features")
    print(f"  ingest                        {ingested:6.1f} s  (reference: 1.00x)")
    print(f"  features, 5 s windows         {extracted:6.1f} s  ({extracted / ingested:.2f}x the ingest)")
    print(f"  rf + brf, grouped and not     {evaluated:6.1f} s  ({evaluated / ingested:.2f}x the ingest)")
    print(f"  ingest + features + evaluation {total:5.1f} s  ({total / ingested:.2f}x the ingest; goal <= 300 s "
          "on two cores)")
    for by_run, each_alone in zip(grouped, alone, strict=True):
        print(f"  accuracy, {by_run.classifier:3s}: {100 * by_run.accuracy_pooled:.1f} % grouped by run, "
              f"{100 * each_alone.accuracy_pooled:.1f} % not grouped")


if __name__ == "__main__":
    main()
