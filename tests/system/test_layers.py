"""The layer order of docs/extending.md holds: import-linter's contracts (pyproject.toml) are kept, every module
sits in a layer, no module imports itself through others, and no project import hides in a function: the
system tests (import-linter in a subprocess). The rest of ``make lint`` too: ruff finds nothing, so a
change that only the linter would have caught fails the suite that CI runs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from unit.test_layers import CONFIG, ROOT


def test_import_linter_contracts_are_kept():
    linter = Path(sys.executable).with_name("lint-imports")
    run = subprocess.run([str(linter), "--no-cache", "--no-logo"], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert f"Contracts: {len(CONFIG['contracts'])} kept, 0 broken." in run.stdout




def test_ruff_finds_nothing():
    ruff = Path(sys.executable).with_name("ruff")
    run = subprocess.run([str(ruff), "check", "--no-cache", "."], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
