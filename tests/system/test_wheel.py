"""The release: the wheel holds every package and data file, and runs from a fresh virtual environment.

The wheel is built from this source tree (``pip wheel --no-build-isolation``: the build backend of the dev
environment, no download) and installed without its dependencies into a new virtual environment; the
dependencies come from this test's own environment through a path file (no network, the locked set). The
commands then run from an unrelated folder, so nothing can be imported from the source tree.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

# One xdist worker builds the wheel for every test here: two builds at once share the tree's build/ folder.
pytestmark = pytest.mark.xdist_group("wheel")

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("scanner", "features", "taxonomy", "gui", "texplorer")


def _run(argv: list[str | Path], cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {key: value for key, value in os.environ.items() if key not in ("PYTHONPATH", "TEXPLORER_DB")}
    run = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True, text=True,
                         timeout=timeout)
    assert run.returncode == 0, f"{argv}: exit {run.returncode}\n{run.stdout}\n{run.stderr}"
    return run


def _source_files() -> set[str]:
    """Every file of the four packages that a user needs: modules, templates, static files, data."""
    found = set()
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*"):
            if path.is_file() and "__pycache__" not in path.parts and path.suffix != ".pyc":
                found.add(path.relative_to(ROOT).as_posix())
    return found


def _clean_source(target: Path) -> Path:
    """The files a release is built from, copied without build leftovers: setuptools reuses ``build/``, so
    a module moved or deleted since the last build in the tree itself would still land in the wheel."""
    for name in ("pyproject.toml", "README.md"):
        (target / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, target / name)
    for package in PACKAGES:
        shutil.copytree(ROOT / package, target / package, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return target


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    source = _clean_source(tmp_path_factory.mktemp("source"))
    run = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", out, source],
               cwd=out)
    assert "warning" not in (run.stdout + run.stderr).lower().replace("warnings", "")
    (path,) = out.glob("texplorer-*.whl")
    return path


@pytest.mark.slow
def test_the_wheel_holds_every_module_template_static_and_data_file(wheel):
    with zipfile.ZipFile(wheel) as archive:
        names = {name for name in archive.namelist() if not name.startswith("texplorer-")}
    assert names == _source_files()
    for expected in ("scanner/acquisition/devices/daq.py", "scanner/acquisition/emulators/board.py",
                     "scanner/storage/bundle.py", "gui/templates/step.html", "gui/static/app.js",
                     "scanner/data/materials.toml", "taxonomy/data/taxonomy.csv"):
        assert expected in names


@pytest.mark.slow
def test_the_installed_wheel_runs_without_the_source_tree(wheel, tmp_path):
    env_dir = tmp_path / "fresh"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    _run([python, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", wheel], cwd=tmp_path)
    purelib = Path(_run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                        cwd=tmp_path).stdout.strip())
    # The dependencies of this environment, as plain path entries: their .pth files (among them this
    # environment's editable install of texplorer) are not processed, so the source tree stays unseen.
    (purelib / "texplorer-test-deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    work = tmp_path / "elsewhere"
    work.mkdir()

    where = _run([python, "-c", "import scanner, features, taxonomy, gui, scanner.acquisition.devices.daq, "
                  "scanner.acquisition.emulators.board; print(scanner.__file__, gui.__file__)"], cwd=work).stdout
    assert str(ROOT) not in where and str(purelib) in where

    texplorer = env_dir / "bin" / "texplorer"
    for argv in (["--help"], ["emulate", "board", "--help"], ["serve", "--help"]):
        assert "usage: texplorer" in _run([texplorer, *argv], cwd=work).stdout
    assert _run([python, "-m", "texplorer", "--version"], cwd=work).stdout.startswith("texplorer ")
    out = _run([texplorer, "demo", "--db", "db", "--materials", "float-glass", "oak-planed", "--samples", "1",
                "--scans", "2", "--image-size", "320", "--no-evaluation", "--workers", "1"], cwd=work).stdout
    assert "database db: 4 scans of 2 materials" in out and (work / "db" / "features.csv").is_file()
    # The web app finds its templates and static files inside the installed package.
    page = _run([python, "-c", "from pathlib import Path; from gui.app import Settings, create_app; "
                 "client = create_app(Settings(db=Path('db').resolve(), trusted_hosts=None)).test_client(); "
                 "print(client.get('/').status_code, client.get('/static/style.css').status_code)"],
                cwd=work).stdout
    assert page.split() == ["200", "200"]
