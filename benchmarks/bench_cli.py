"""CLI start-up benchmark: CPU time of ``texplorer --help``, ``--version``, ``db list`` and ``import features``.

Each command runs in a fresh interpreter; its CPU time (user + system, from ``os.wait4``) is compared with the
CPU time of ``python -c "import numpy"`` measured in the same run, interleaved with the commands so that all
see the same load. Medians over several repeats. Target: each CLI command at most 3x the reference; a command
that loads scikit-learn, Flask, numba or OpenCV up front is 10-25x.

``db list`` reads the database given as ``--db PATH``, else ``make demo``'s (``$TEXPLORER_DB``, else
``./texplorer-data``) if there is one, else one with the demo's catalog (every material of the library, as many
samples and scans as ``texplorer demo``; 64 px photos, which ``db list`` does not read) built into a temporary
folder first.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPEATS = 7
TARGET = 3.0
REFERENCE = "reference: python -c 'import numpy'"


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
        commands = {
            REFERENCE: [sys.executable, "-c", "import numpy"],
            "texplorer --help": texplorer("--help"),
            "texplorer --version": texplorer("--version"),
            "texplorer db list": texplorer("db", "list", "--db", str(db)),
            "python -c 'import features'": [sys.executable, "-c", "import features"],
            "python -c 'import scanner'": [sys.executable, "-c", "import scanner"],
        }
        for argv in commands.values():  # warm the page cache and the bytecode caches
            cpu_seconds(argv, env)
        times: dict[str, list[float]] = {name: [] for name in commands}
        for _ in range(repeats):
            for name, argv in commands.items():
                times[name].append(cpu_seconds(argv, env))
    reference = statistics.median(times[REFERENCE])
    print(f"CPU time of a fresh process, median of {repeats} (target: texplorer commands <= {TARGET:g}x the "
          "reference)")
    for name, values in times.items():
        median = statistics.median(values)
        print(f"  {name:<40} {median * 1e3:7.0f} ms  {median / reference:5.2f}x")


if __name__ == "__main__":
    main()
