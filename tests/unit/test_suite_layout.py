"""The fast loop stays fast: nothing of a system test in tests/unit (CONTRIBUTING.md).

A system test starts something heavy: a process (the CLI, a worker pool, a writer killed with kill -9, a
wheel build), a Dask cluster, a browser, a device emulator on a socket or a pseudo-terminal, a simulated
database. This check times nothing: it lists the names such a test cannot do without and fails if a unit
test module names one, or carries a marker that only system tests need.
"""

from __future__ import annotations

import ast
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]

SYSTEM_NAMES = {
    "subprocess": "starts a process",
    "multiprocessing": "starts a process",
    "sys.executable": "starts a Python process",
    "signal.SIGKILL": "kills a process",
    "os.kill": "kills a process",
    "os.fork": "forks a process",
    "WorkerPool": "forks worker processes",
    "release_workers": "forks worker processes (extract_many's kept workers)",
    "distributed": "starts a Dask cluster",
    "dask": "starts a Dask cluster",
    "playwright": "drives a browser",
    "socket": "listens on a socket",
    "pty": "opens a pseudo-terminal",
    "DaqEmulator": "runs the DAQ's gRPC emulator",
    "BoardEmulator": "runs the sensor board's emulator on a pseudo-terminal",
    "synthetic_database": "simulates a whole database",
    "workers > 1": "forks worker processes (extract_many, evaluate_grid, exports)",
}
"""What a unit test module may not name, and why such a test is a system test."""

SYSTEM_MARKERS = {"slow", "timeout", "xdist_group"}
"""Markers only slow or process-starting tests need."""


def system_uses(path: Path) -> list[str]:
    """``name: why`` for every system name or marker a test module uses."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name.split(".")[0] for alias in node.names} | {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            found |= {node.module.split(".")[0]} | {alias.name for alias in node.names}
        elif isinstance(node, ast.Name):
            found.add(node.id)
        elif isinstance(node, ast.keyword) and node.arg == "workers" and isinstance(node.value, ast.Constant) \
                and isinstance(node.value.value, int) and node.value.value > 1:
            found.add("workers > 1")
        elif isinstance(node, ast.Attribute):
            found.add(ast.unparse(node))
            if ast.unparse(node.value) == "pytest.mark" and node.attr in SYSTEM_MARKERS:
                found.add(f"pytest.mark.{node.attr}")
    uses = [f"{name}: {why}" for name, why in SYSTEM_NAMES.items() if name in found]
    uses += [f"{marker}: a system marker" for marker in sorted(found) if marker.startswith("pytest.mark.")
             and marker.removeprefix("pytest.mark.") in SYSTEM_MARKERS]
    return uses


def test_no_unit_test_does_what_a_system_test_does():
    modules = sorted((TESTS / "unit").glob("test_*.py"))
    assert len(modules) > 20  # the walk found the unit tests
    found = {path.name: uses for path in modules if (uses := system_uses(path))}
    assert found == {}


SLOW_MODULES = {
    "test_tactum.py": "simulated scans at 256 px, about 3 s of CPU each",
    "test_methods.py": "the related methods end to end (6-20 s of CPU each) and scikit-learn's estimator checks",
    "test_own_recordings.py": "recording sets ingested, extracted and evaluated through the CLI (9-18 s of CPU each)",
    "test_corners.py": "Harris on a photo-sized image, bit for bit against OpenCV (11 s of CPU)",
    "test_image.py": "every image feature on photos of many sizes (2-9 s of CPU each)",
    "test_modern.py": "cross-validated random-kernel evaluations and a saved MiniRocket model (4-40 s of CPU each)",
    "test_simulation_physics.py": "a simulated set of 48 whole scans, each family cross-validated (about 60 s of CPU)",
    "test_selection.py": "the studentized-range table against SciPy's numerical integration (4-6 s of CPU each)",
    "test_metrics.py": "a cross-validated evaluation with a temperature fitted per fold (about 3 s of CPU)",
    "test_gui_operator.py": "about two thousand hostile requests through the web app (about 10 s of CPU)",
}
"""System test modules that start nothing heavy but take seconds of CPU per test."""


def test_the_system_tests_are_the_heavy_ones():
    modules = sorted((TESTS / "system").glob("test_*.py"))
    assert len(modules) > 5
    light = [path.name for path in modules if not system_uses(path) and path.name not in SLOW_MODULES]
    assert light == [], "a system test module that names nothing heavy belongs in tests/unit"


def test_the_check_sees_a_process_and_a_marker(tmp_path):
    sample = tmp_path / "test_sample.py"
    sample.write_text("import subprocess\nimport sys\n\nimport pytest\n\n\n@pytest.mark.slow\ndef test_x():\n"
                      "    subprocess.run([sys.executable, '-c', 'pass'], check=True)\n"
                      "    extract_many(s, workers=2)\n")
    assert system_uses(sample) == ["subprocess: starts a process", "sys.executable: starts a Python process",
                                   "workers > 1: forks worker processes (extract_many, evaluate_grid, exports)",
                                   "pytest.mark.slow: a system marker"]
