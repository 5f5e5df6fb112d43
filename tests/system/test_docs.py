"""The documentation: the code cites the papers and the project's own pages, not a document it does not ship: the
system tests (the site built and the pages' examples run in subprocesses)."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.io.wavfile
from unit.test_docs import PYTHON, ROOT, Block, _pages, blocks, runnable

SNIPPET = re.compile(r'^--8<-- "(?P<path>[^"]+)"$')


DEMO = ["demo", "--materials", "granite-polished", "oak-planed", "mild-steel-brushed", "polyurethane-foam",
        "--image-size", "256", "--classifier", "rf", "lda"]


"""The small demo database the examples run on: the command getting-started.md shows."""


def _pages_with_examples() -> list[str]:
    return [str(p.relative_to(ROOT)) for p in _pages() if any(runnable(b) for b in blocks(p))]


def _wav(path: Path, frequency: float, seed: int) -> None:
    """One second of a noisy tone as 16-bit PCM, a tool slide's sound for the walk-through of ingest.md."""
    rng = np.random.default_rng(seed)
    t = np.arange(44100) / 44100
    x = 0.3 * np.sin(2 * np.pi * frequency * t) + 0.05 * rng.standard_normal(t.size)
    path.parent.mkdir(parents=True, exist_ok=True)
    scipy.io.wavfile.write(path, 44100, (x * 32767).astype(np.int16))


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory) -> Path:
    """A working folder holding the small demo database (``texplorer-data``) and the tool-slide sounds of
    ingest.md's walk-through (``slides/<material>/<object>_<trial>.wav``)."""
    folder = tmp_path_factory.mktemp("examples")
    done = subprocess.run([_texplorer(), *DEMO, "--db", str(folder / "texplorer-data")], env=_environment(),
                          cwd=folder, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, f"texplorer {' '.join(DEMO)} exits {done.returncode}: {done.stderr[-2000:]}"
    for k, (material, frequency) in enumerate((("cardboard", 180.0), ("cork", 420.0), ("steel", 900.0))):
        for piece in (1, 2, 3, 4):
            for trial in (1, 2):
                _wav(folder / "slides" / material / f"{material}-{piece}_{trial:02d}.wav",
                     frequency * (1 + 0.02 * piece), seed=100 * k + 10 * piece + trial)
    return folder


def _texplorer() -> str:
    return str(Path(sys.executable).with_name("texplorer"))


def _environment() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "TEXPLORER_DB"}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    return env


def _run(block: Block, command: list[str], cwd: Path) -> None:
    done = subprocess.run(command, cwd=cwd, env=_environment(), capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{block} exits {done.returncode}:\n{block.body}\n{done.stdout}\n{done.stderr}"


@pytest.mark.slow
@pytest.mark.parametrize("page", _pages_with_examples())
def test_the_examples_of_a_page_run_as_written(page, demo_folder, tmp_path):
    """Every Python and shell block of the page, in order, in one folder
    holding a copy of the small demo database (a shell block, or a run of consecutive Python blocks, in a
    process of its own); the files the page shows (``# slides.toml``) are written
    there first, and the repository's docs/, tests/ and benchmarks/ are reachable by the relative paths the
    examples use."""
    work = tmp_path / "work"
    shutil.copytree(demo_folder, work, symlinks=True)
    for name in ("docs", "tests", "benchmarks"):
        (work / name).symlink_to(ROOT / name)
    python: list[Block] = []  # consecutive Python blocks run in one process, as a notebook's cells
    for block in [*filter(runnable, blocks(ROOT / page)), None]:
        if block is not None and block.lang in PYTHON:
            python.append(block)
            continue
        if python:
            code = "\n".join(_python_source(b) for b in python)
            _run(python[0], [sys.executable, "-c", code], work)
            python = []
        if block is None:
            break
        if block.file is not None:
            (work / block.file).write_text(block.body)
        else:
            _run(block, ["bash", "-euo", "pipefail", "-c", block.body], work)


def _python_source(block: Block) -> str:
    snippet = SNIPPET.match(block.body.strip())
    return (ROOT / "docs" / snippet["path"]).read_text() if snippet else block.body


@pytest.mark.slow
def test_the_site_builds_with_warnings_as_errors(tmp_path):
    """``make docs``: every page, link, anchor, image and API entry resolves (mkdocs build --strict), with no
    network (the theme's web fonts are off)."""
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None:
        pytest.skip("mkdocs and mkdocstrings are not installed (pip install 'texplorer[docs]'; make install does)")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                          cwd=ROOT, env={**_environment(), "NO_MKDOCS_2_WARNING": "1"}, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    assert (tmp_path / "site" / "features" / "index.html").is_file()
    assert "tactum.matx" in (tmp_path / "site" / "api" / "features" / "index.html").read_text()
