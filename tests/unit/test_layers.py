"""The layer order of docs/extending.md holds: import-linter's contracts (pyproject.toml) are kept, every
module sits in a layer, no module imports itself through others, and no project import hides in a function."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import grimp
import pytest

ROOT = Path(__file__).resolve().parents[2]
CONFIG = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
PACKAGES = tuple(CONFIG["root_packages"])


@pytest.fixture(scope="module")
def graph() -> grimp.ImportGraph:
    return grimp.build_graph(*PACKAGES, cache_dir=None)


def _layer_modules() -> set[str]:
    names = set()
    for contract in CONFIG["contracts"]:
        if contract["type"] == "layers":
            prefixes = [f"{container}." for container in contract.get("containers", [])] or [""]
            for layer in contract["layers"]:
                names.update(prefix + part.strip() for prefix in prefixes
                             for part in layer.replace("|", ":").split(":"))
    return names


def _inside(module: str, layers: set[str]) -> bool:
    return any(module == layer or module.startswith(layer + ".") for layer in layers)


def test_every_module_sits_in_a_layer(graph):
    layers = _layer_modules()
    outside = sorted(module for module in graph.modules if module not in PACKAGES and not _inside(module, layers))
    assert outside == []


def test_every_module_of_a_container_sits_in_one_of_its_layers(graph):
    # A package named as one layer elsewhere (scanner.storage) would let any new module inside it pass
    # the test above; its own contract must name it.
    outside = []
    for contract in CONFIG["contracts"]:
        for container in contract.get("containers", []):
            layers = {f"{container}.{part.strip()}" for layer in contract["layers"]
                      for part in layer.replace("|", ":").split(":")}
            outside += [module for module in graph.modules
                        if module.startswith(container + ".") and not _inside(module, layers)]
    assert outside == []


def test_no_module_imports_itself_through_others(graph):
    cycles = []
    for importer in sorted(graph.modules):
        for imported in sorted(graph.find_modules_directly_imported_by(importer)):
            chain = graph.find_shortest_chain(importer=imported, imported=importer)
            if chain is not None:
                cycles.append(" -> ".join((importer, *chain)))
    assert cycles == []


OPTIONAL_LIBRARY_MODULES = {"scanner.acquisition.emulators.daq_grpc"}
"""Project modules built on an optional library at their top (gRPC and the nidaqmx stubs): imported where they
are used, like the library itself, so that no other command loads it."""


def _imports_in_functions(path: Path, root: Path = ROOT, libraries: bool = False) -> list[str]:
    """Project imports inside a function (any import there, with ``libraries``), and project modules imported
    by name at run time anywhere (``importlib.import_module("scanner.x")``, ``__import__``): the contracts see
    neither."""
    found = []
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for inner in ast.walk(node):
                names = ([inner.module or ""] if isinstance(inner, ast.ImportFrom)
                         else [alias.name for alias in inner.names] if isinstance(inner, ast.Import) else [])
                found += [f"{path.relative_to(root)}:{inner.lineno} {name}" for name in names
                          if (libraries or _project(name)) and name not in OPTIONAL_LIBRARY_MODULES]
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and _imports_by_name(node.func) and node.args:
            name = node.args[0].value if isinstance(node.args[0], ast.Constant) else ""
            if isinstance(name, str) and _project(name):
                found.append(f"{path.relative_to(root)}:{node.lineno} {name}")
    return found


def _project(name: str) -> bool:
    return name.split(".")[0] in PACKAGES


def _imports_by_name(func: ast.expr) -> bool:
    called = func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""
    return called in ("import_module", "__import__")


def test_every_package_is_checked():
    """A new top-level package is added to the contracts' ``root_packages`` and so to every check here."""
    found = {path.parent.name for path in ROOT.glob("*/__init__.py")} - {"tests", "benchmarks"}
    assert found == set(PACKAGES)


def test_no_project_import_hides_in_a_function():
    files = sorted(path for package in PACKAGES for path in (ROOT / package).rglob("*.py"))
    assert len(files) > 60
    hidden = [line for path in files for line in _imports_in_functions(path)]
    assert hidden == []


DEFERRING = "scanner/lazy.py"
"""The one module that imports inside its functions: the stand-ins of deferred libraries and numba's loading."""


def test_no_library_import_hides_in_a_function():
    # One way to defer an import (docs/extending.md): scanner.lazy's library() at a module's top, optional()
    # where an optional library is used, jit() for numba; the stdlib and numpy are imported at the top.
    files = sorted(path for package in PACKAGES for path in (ROOT / package).rglob("*.py")
                   if path.relative_to(ROOT).as_posix() != DEFERRING)
    hidden = [line for path in files for line in _imports_in_functions(path, libraries=True)]
    assert hidden == []


def test_the_check_sees_an_import_in_a_function(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import numpy\n\n\ndef f():\n    from scanner.scan import Scan\n    return Scan\n")
    assert _imports_in_functions(sample, tmp_path) == ["sample.py:5 scanner.scan"]


def test_the_check_sees_an_import_by_name(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import importlib\n\nscan = importlib.import_module('scanner.scan')\nnp = __import__('numpy')\n")
    assert _imports_in_functions(sample, tmp_path) == ["sample.py:3 scanner.scan"]


def test_the_library_check_sees_a_library_import_in_a_function(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("def f():\n    import sounddevice\n    return sounddevice\n")
    assert _imports_in_functions(sample, tmp_path) == []
    assert _imports_in_functions(sample, tmp_path, libraries=True) == ["sample.py:2 sounddevice"]
