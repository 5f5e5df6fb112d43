"""CLI start-up benchmark: CPU time of ``texplorer --help``, ``--version``, ``db list`` and ``import features``,
and of two commands that do a little work: ``classify`` of a stored scan and a fully cached ``features``.

Each command runs in a fresh interpreter; its CPU time (user + system, from ``os.wait4``) is compared with the
CPU time of ``python -c "import numpy"`` measured in the same run, interleaved with the commands so that all
see the same load. Medians over several repeats. Target: each CLI command at most 3x the reference; a command
that loads scikit-learn, Flask, numba or OpenCV up front is 10-25x. ``classify`` is compared with
``python -c "import sklearn.ensemble, scipy.stats"`` (what its model needs; goal 1.3x) and the cached
``features`` with ``texplorer --help`` (goal 2x), both measured in the same run.

``db list`` reads the database given as ``--db PATH``, else ``make demo``'s (``$TEXPLORER_DB``, else
``./texplorer-data``) if there is one, else one with the demo's catalog (every material of the library, as many
samples and scans as ``texplorer demo``; 64 px photos, which ``db list`` does not read) built into a temporary
folder first. ``classify`` and ``features`` use that database when it has a model, else a small simulated one
with a model (:data:`SMALL`), built first; their runs before the timed ones fill the feature cache and the
files' stat records.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPEATS = 7
TARGET = 3.0
REFERENCE = "reference: python -c 'import numpy'"
LEARNING = "reference: python -c 'import sklearn.ensemble, scipy.stats'"
HELP = "texplorer --help"
SMALL = ("granite-polished", "marble-polished", "oak-planed", "pine-planed", "cotton-woven", "cork-board")
"""The materials of the small database built when none with a model is given: 2 samples x 2 scans each."""


def cpu_seconds(argv: list[str], env: dict[str, str]) -> float:
    """User + system CPU time of one run of ``argv`` (its whole process tree that it waited for)."""
    process = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    stderr = process.stderr.read().decode() if process.stderr else ""
    process.stderr.close()
    if process.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} exited {process.returncode}: {stderr.strip()}")
    return usage.ru_utime + usage.ru_stime


def texplorer(*args: str) -> list[str]:
    return [sys.executable, "-c", "import sys; from scanner.cli import main; sys.exit(main())", *args]


def demo_database() -> Path | None:
    """``make demo``'s database, if there is one."""
    from scanner.cli.base import default_db
    from scanner.storage.database import is_database

    root = default_db()
    return root if is_database(root) else None


def build_database(root: Path) -> None:
    from scanner.cli.demo import DEMO_SAMPLES, DEMO_SCANS
    from scanner.simulation.database import synthetic_database

    synthetic_database(root, samples_per_material=DEMO_SAMPLES, scans_per_material=DEMO_SCANS, image_size=(64, 64),
                       progress=False)


def model_database(given: Path | None, folder: Path) -> Path:
    """``given`` if it has a current model, else a small simulated database with one, built in ``folder``."""
    from scanner.workflows.models import default_model

    if given is not None and default_model(given) is not None:
        return given
    from scanner.workflows.database import extract_database
    from scanner.workflows.demo import simulated_database
    from scanner.workflows.models import save_model_version, train_default_model

    db = simulated_database(folder, materials=list(SMALL), samples_per_material=2, scans_per_material=2,
                            image_size=(256, 256), progress=False)
    space = extract_database(db, progress=False)
    save_model_version(db, train_default_model(space, seed=0), space)
    db.close()
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", type=Path, help="database for 'db list' (default: make demo's, else a simulated "
                        "one, built first)")
    parser.add_argument("--repeats", type=int, default=REPEATS, help=f"runs of each command (default {REPEATS})")
    options = parser.parse_args()
    given, repeats = options.db or demo_database(), options.repeats
    with tempfile.TemporaryDirectory() as tmp:
        # Bytecode caches as a user's installation has them (in a folder of their own, so the tree stays as it
        # is), written by the warm-up runs even where the environment asks Python not to write them.
        env = {**os.environ, "PYTHONPYCACHEPREFIX": str(Path(tmp) / "pycache"),
               "PYTHONPATH": os.pathsep.join(filter(None, [str(Path(__file__).resolve().parents[1]),
                                                          os.environ.get("PYTHONPATH")]))}
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        db = given or Path(tmp) / "db"
        if given is None:
            build_database(db)
        modelled = model_database(given, Path(tmp) / "modelled")
        from scanner.storage.database import Database
        from scanner.storage.stored import RACY_SECONDS

        with Database(modelled, create=False) as db_modelled:
            scan = db_modelled.records()[0].scan_id
        commands = {
            REFERENCE: [sys.executable, "-c", "import numpy"],
            LEARNING: [sys.executable, "-c", "import sklearn.ensemble, scipy.stats"],
            HELP: texplorer("--help"),
            "texplorer --version": texplorer("--version"),
            "texplorer db list": texplorer("db", "list", "--db", str(db)),
            "python -c 'import features'": [sys.executable, "-c", "import features"],
            "python -c 'import scanner'": [sys.executable, "-c", "import scanner"],
            "texplorer classify SCAN": texplorer("classify", scan, "--db", str(modelled)),
            "texplorer features (cached)": texplorer("features", "--db", str(modelled), "--out",
                                                     str(Path(tmp) / "features.csv")),
        }
        for argv in commands.values():  # warm the page cache and the bytecode caches, fill the feature cache
            cpu_seconds(argv, env)
        time.sleep(RACY_SECONDS)  # the files settle: the next run keeps their stat records
        cpu_seconds(commands["texplorer features (cached)"], env)
        times: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(repeats):
            for name, argv in commands.items():
                times[name].append(cpu_seconds(argv, env))
    medians = {name: statistics.median(values) for name, values in times.items()}
    reference = medians[REFERENCE]
    print(f"CPU time of a fresh process, median of {repeats} (target: texplorer commands <= {TARGET:g}x the "
          "reference)")
    for name, median in medians.items():
        print(f"  {name:<60} {median * 1e3:7.0f} ms  {median / reference:5.2f}x")
    classify, cached = medians["texplorer classify SCAN"], medians["texplorer features (cached)"]
    print(f"  classify: {classify / medians[LEARNING]:.2f}x the learning reference (goal 1.3x); cached features: "
          f"{cached / medians[HELP]:.2f}x texplorer --help (goal 2x)")


if __name__ == "__main__":
    main()
