"""Where the work runs: this machine's kept workers (``scanner.runtime.local``) against loky's reusable executor.

loky (``joblib.externals.loky.get_reusable_executor``, the executor joblib runs on) keeps its workers between
calls too, but starts them as fresh interpreters that import the feature code themselves; the kept workers
are forked from this process with everything it imported. Both run the same task, ``extract_many``'s
(one scan's 193 features, checked against this process's code version), on 12 simulated scans with
512 x 512 photos, 2 workers, and the results are checked equal bit for bit:

- a process's first call (loky starts its interpreters, the kept workers are forked) and a later call (both
  find their workers kept), each as a ratio against the serial run of the same scans in this process;
- the folds of an evaluation grid (random forest, 2 folds, 2 levels) through ``Runtime.map_unordered``
  against the same folds on loky's workers.

Every timing is the best of several rounds (the machine may be shared); the load average is printed.

    python benchmarks/bench_runtime.py
"""

from __future__ import annotations

import functools
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from joblib.externals.loky import get_reusable_executor

from features import code_version
from features.extraction import extract_source, with_code
from scanner.runtime import LOCAL
from scanner.runtime.local import release_workers
from scanner.simulation.database import synthetic_database
from scanner.workflows.database import database_sources, extract_database
from taxonomy.learning import evaluation

WORKERS = 2
ROUNDS = 3
MATERIALS = ["polyurethane-foam", "mild-steel-brushed", "granite-polished", "oak-planed", "sandpaper-p80",
             "float-glass"]


def timed(fn: Callable[[], object]) -> tuple[float, object]:
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def kept(task: Callable, items: list) -> list:
    """The kept workers, as extract_many and the evaluation use them (results in item order)."""
    results = [None] * len(items)
    for i, result in LOCAL.map_unordered(task, [(item,) for item in items], workers=WORKERS):
        results[i] = result
    return results


def on_loky(task: Callable, items: list) -> list:
    """loky's reusable executor of the same size (started on its first use, kept after)."""
    return list(get_reusable_executor(max_workers=WORKERS).map(task, items))


def serial(task: Callable, items: list) -> list:
    return [task(item) for item in items]


def first_and_later(task: Callable, items: list, expected: list) -> dict[str, float]:
    """Best first-call and later-call times of both executors; each first call finds no worker."""
    best: dict[str, float] = {}
    for _ in range(ROUNDS):
        for name, run, end in (("kept workers", kept, release_workers),
                               ("loky reusable executor", on_loky, _end_loky)):
            end()
            first, got = timed(lambda run=run: run(task, items))
            later, again = timed(lambda run=run: run(task, items))
            assert got == expected and again == expected, f"{name}: other results than the serial run"
            best[f"{name}, first call"] = min(best.get(f"{name}, first call", float("inf")), first)
            best[f"{name}, later call"] = min(best.get(f"{name}, later call", float("inf")), later)
    release_workers()
    _end_loky()
    return best


def _end_loky() -> None:
    get_reusable_executor(max_workers=WORKERS).shutdown(wait=True, kill_workers=True)


def extraction(folder: Path) -> None:
    db = synthetic_database(folder / "db", MATERIALS, scans_per_material=2, seed=0, image_size=(512, 512),
                            progress=False, workers=WORKERS)
    sources = database_sources(db, db.records())
    task = functools.partial(with_code, code_version(), code_version, extract_source)
    reference = min((timed(lambda: serial(task, sources)) for _ in range(ROUNDS)), key=lambda t: t[0])
    expected = reference[1]
    print(f"features of {len(sources)} scans (512x512), {WORKERS} workers, serial {reference[0]:.2f} s "
          f"(the reference); load average {os.getloadavg()[0]:.1f}")
    for name, seconds in first_and_later(task, sources, expected).items():
        print(f"  {name:36s} {seconds:6.2f} s = {seconds / reference[0]:5.2f} x serial")
    space = extract_database(db, workers=1, progress=False)
    folds(space)


def folds(space) -> None:
    """The folds of a small grid: prepared once, each fold one task."""
    cells = [evaluation._Cell(level, "all", None, 10) for level in ("coarse", "fine")]
    prepared = [evaluation._prepare(space, cell, ["rf"], 2, 0, "nested", True, "train", False, "sample")
                for cell in cells]
    jobs = [(prepared[c], f, "nested") for c in range(len(cells)) for f in range(len(prepared[c].splits))]
    task = functools.partial(_fold_of, jobs)
    indices = list(range(len(jobs)))
    reference = min((timed(lambda: serial(task, indices)) for _ in range(ROUNDS)), key=lambda t: t[0])
    print(f"{len(jobs)} evaluation folds (random forest, 2 levels), serial {reference[0]:.2f} s (the reference)")
    for name, seconds in first_and_later(task, indices, reference[1]).items():
        print(f"  {name:36s} {seconds:6.2f} s = {seconds / reference[0]:5.2f} x serial")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


def _fold_of(jobs: list, i: int) -> list:
    outcome = evaluation._fold(*jobs[i])
    return _comparable(outcome)


def _comparable(outcome: object) -> object:
    """A fold's predictions, without its timings (which differ from run to run)."""
    if isinstance(outcome, list):
        return [_comparable(o) for o in outcome]
    return [p.tolist() for p in outcome.predictions]


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        extraction(Path(tmp))


if __name__ == "__main__":
    main()
