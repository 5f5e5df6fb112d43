"""What starting the CLI or importing the packages loads: the heavy libraries only where a command computes with
them (benchmarks/bench_cli.py measures the time). Each check runs in a fresh interpreter, whose ``sys.modules``
holds only what it imported itself."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import make_scan
from unit.test_models import separated_space

from scanner.runtime.cluster import dask_configuration_exists
from scanner.storage.database import Database
from scanner.workflows.database import extract_database
from taxonomy.learning.models import save_model, train_model

TESTS = Path(__file__).resolve().parents[1]

HEAVY = ("numba", "sklearn", "flask", "cv2", "scipy.signal", "scipy.stats", "scipy.io", "matplotlib", "skops",
         "pywt", "distributed", "dask")
"""Libraries that cost more CPU to import than numpy itself, or about as much."""


def _loaded_after(code: str, env: dict[str, str] | None = None) -> list[str]:
    """The :data:`HEAVY` libraries loaded in a fresh interpreter after running ``code``."""
    probe = (f"import json, sys\nsys.path.insert(0, {str(TESTS)!r})\n{code}\n"
             f"print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))")
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, env=env)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.splitlines()[-1])


def _cli(*argv: str) -> str:
    return f"from scanner.cli import main\ntry:\n    main({list(argv)!r})\nexcept SystemExit:\n    pass"


@pytest.mark.parametrize("package", ["scanner", "features", "taxonomy"])
def test_importing_a_package_loads_no_heavy_library(package):
    assert _loaded_after(f"import {package}") == []


def test_help_and_version_load_no_heavy_library_nor_any_command_group():
    code = _cli("--help") + "\n" + _cli("--version") + "\nimport sys\nprint(sorted(m for m in sys.modules if " \
        "m.startswith(('scanner.cli.', 'features', 'gui.', 'taxonomy.learning'))))"
    run = subprocess.run([sys.executable, "-c", code + f"\nprint(sorted(m for m in {HEAVY!r} if m in sys.modules))"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    *_, groups, heavy = run.stdout.splitlines()
    assert groups == "['scanner.cli.base']" and heavy == "[]"


def test_the_package_and_help_load_no_worker_machinery():
    # Storage raises NotOnThisMachine from the ground layer, so opening the package (and a database) loads
    # neither the runtime's pools and cluster code nor the stdlib they need.
    code = _cli("--help") + "\nimport sys\nprint(sorted(m for m in ('scanner.runtime', 'concurrent.futures', " \
        "'multiprocessing', 'logging') if m in sys.modules))"
    run = subprocess.run([sys.executable, "-c", "import scanner\n" + code], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines()[-1] == "[]"


def test_db_list_loads_no_heavy_library(tmp_path):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1))
    db.close()
    assert _loaded_after(_cli("db", "list", "--db", str(tmp_path / "db"))) == []


def test_features_load_the_libraries_they_compute_with():
    # the other side of the checks above: a command that computes loads what it needs, when it needs it
    loaded = _loaded_after("from conftest import make_scan\nfrom features import extract\nextract(make_scan(0))")
    assert {"numba", "cv2", "scipy.signal"} <= set(loaded) and "sklearn" not in loaded


def test_a_model_loads_without_importing_the_rest_of_scikit_learn(tmp_path):
    # skops lists every scikit-learn estimator when imported (a second of CPU); loading hands it the model's own
    space = separated_space()
    path = save_model(train_model(space, level="fine", n_features=2, classifier="rf"), tmp_path / "rf.skops")
    crawled = ("sklearn.gaussian_process", "sklearn.kernel_ridge", "sklearn.semi_supervised")
    code = (f"from taxonomy.learning.models import load_model\nmodel = load_model({str(path)!r})\n"
            f"import sys\nprint(sorted(m for m in {crawled!r} if m in sys.modules), model.classifier)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split("\n")[-2] == "[] rf"


def test_skops_trusts_the_same_names_imported_with_the_module_index():
    # The model code imports skops with its search for an object's module answered from one index of the loaded
    # modules: every name skops derives at its import (the ufuncs of numpy and scipy.special among them) is the one
    # its own search gives, in a process that has loaded what classify loads.
    lists = ("import json, sys\nimport skops.io._trusted_types as t\n"
             "print(json.dumps({k: v for k, v in vars(t).items() if k.endswith('_NAMES')}, sort_keys=True))")
    setup = "import sklearn.ensemble, scipy.stats, features, scanner.cli.models\nfrom taxonomy.learning import models\n"
    ours = setup + "models._skops()\nimport skops, skops.io\nassert skops.io is sys.modules['skops.io']\n"
    theirs = setup + "with models._estimators(models.SKLEARN_PARTS):\n    import skops.io\n"
    found = []
    for code in (ours, theirs):
        run = subprocess.run([sys.executable, "-c", "import sys\n" + code + lists], capture_output=True, text=True,
                             timeout=300)
        assert run.returncode == 0, run.stderr
        found.append(json.loads(run.stdout.splitlines()[-1]))
    assert found[0] == found[1]
    assert len(found[0]["SCIPY_UFUNC_TYPE_NAMES"]) > 100 and len(found[0]["NUMPY_UFUNC_TYPE_NAMES"]) > 50


def test_classify_s_group_loads_neither_the_devices_nor_the_simulator():
    code = ("import scanner.cli.models, sys\nprint(sorted(m for m in sys.modules if m.startswith(("
            "'scanner.simulation', 'scanner.acquisition', 'cv2', 'scipy.signal', 'numba'))))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines()[-1] == "[]"


def test_a_cached_feature_table_loads_neither_scikit_learn_nor_scipy_stats(tmp_path):
    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1))
    extract_database(db, workers=1, progress=False)  # the feature cache holds the scan now
    db.close()
    loaded = _loaded_after(_cli("features", "--db", str(tmp_path / "db"), "--workers", "1", "--out",
                                str(tmp_path / "features.csv")))
    assert (tmp_path / "features.csv").is_file()
    assert not {"sklearn", "scipy.stats", "numba", "cv2", "skops"} & set(loaded), loaded
    # Without --workers the command asks where to run: with no Dask configuration anywhere, Dask is not imported
    # to say so, and reading a stored recording set's files (scipy.io) waits for a set.
    home = tmp_path / "home"
    home.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("DASK_")} | {"HOME": str(home)}
    loaded = _loaded_after(_cli("features", "--db", str(tmp_path / "db"), "--out", str(tmp_path / "again.csv")),
                           env)
    assert (tmp_path / "again.csv").read_bytes() == (tmp_path / "features.csv").read_bytes()
    if not dask_configuration_exists(env):  # a machine with /etc/dask or a site's Dask YAML asks Dask
        assert not {"dask", "distributed", "scipy.io", "sklearn"} & set(loaded), loaded


def test_python_dash_m_texplorer_is_the_texplorer_command():
    run = subprocess.run([sys.executable, "-m", "texplorer", "--version"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("texplorer ") and run.stdout.split()[1][0].isdigit()
