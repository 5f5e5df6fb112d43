"""The feature and learning code documents every public function as numpydoc does (CONTRIBUTING.md): a
Parameters section naming each argument, Returns (or Yields) where it gives something, and Examples that run.

ruff's docstring rules (numpy convention) check the form of what is written; they cannot ask for sections
that are missing. This test does, module by module, and runs each module's examples as doctests."""

from __future__ import annotations

import ast
import doctest
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PATTERNS = ("features/*.py", "taxonomy/learning/*.py", "taxonomy/related/*_features.py", "taxonomy/related/inputs.py",
            "taxonomy/related/sets.py")
"""The feature and learning code: the features of scans and recordings, the learning, and the related papers'
features (each beside its method in ``taxonomy/related``)."""
MODULES = sorted(path for pattern in PATTERNS for path in ROOT.glob(pattern) if path.name != "__init__.py")


def _module_name(path: Path) -> str:
    return ".".join(path.relative_to(ROOT).with_suffix("").parts)


def _public_functions(tree: ast.Module) -> list[tuple[str, ast.FunctionDef]]:
    """Module-level functions and the methods of module-level classes, neither private nor dunder; a
    property documents itself in its summary."""
    found = []
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            found.append((node.name, node))
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                if (isinstance(item, ast.FunctionDef) and not item.name.startswith("_")
                        and not any(_named(d).rpartition(".")[2] in ("property", "cached_property", "overload",
                                                                      "setter") for d in item.decorator_list)):
                    found.append((f"{node.name}.{item.name}", item))
    return found


def _named(decorator: ast.expr) -> str:
    return ast.unparse(decorator.func if isinstance(decorator, ast.Call) else decorator)


def _arguments(function: ast.FunctionDef) -> list[str]:
    args = function.args
    names = [a.arg for a in (*args.posonlyargs, *args.args, *args.kwonlyargs)]
    names += [f"*{args.vararg.arg}"] if args.vararg else []
    names += [f"**{args.kwarg.arg}"] if args.kwarg else []
    return [n for n in names if n not in ("self", "cls")]


def _gives_something(function: ast.FunctionDef) -> bool:
    returns = function.returns
    if returns is not None:
        return ast.unparse(returns) not in ("None", "NoReturn")
    return any(isinstance(n, (ast.Return, ast.Yield, ast.YieldFrom)) and getattr(n, "value", None) is not None
               for n in ast.walk(function))


def missing_sections(path: Path) -> list[str]:
    """``name: what is missing`` for each public function of the module at ``path``."""
    problems = []
    for name, function in _public_functions(ast.parse(path.read_text())):
        doc = ast.get_docstring(function) or ""
        sections = {line.strip() for line in doc.splitlines()}
        lacking = []
        arguments = _arguments(function)
        if arguments and "Parameters" not in sections:
            lacking.append("Parameters")
        elif arguments:
            described = doc.split("Parameters", 1)[1]
            absent = [a for a in arguments if not any(part.strip().lstrip("*") == a.lstrip("*")
                      for line in described.splitlines() for part in line.split(":", 1)[0].split(","))]
            lacking += [f"parameter {a}" for a in absent]
        if _gives_something(function) and not sections & {"Returns", "Yields"}:
            lacking.append("Returns")
        if "Examples" not in sections:
            lacking.append("Examples")
        if lacking:
            problems.append(f"{name}: {', '.join(lacking)}")
    return problems


@pytest.mark.parametrize("path", MODULES, ids=_module_name)
def test_every_public_function_has_numpydoc_sections(path):
    problems = missing_sections(path)
    assert not problems, f"{_module_name(path)}: " + "; ".join(problems)


@pytest.mark.parametrize("path", MODULES, ids=_module_name)
def test_the_examples_run(path):
    found = doctest.testmod(importlib.import_module(_module_name(path)), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert found.failed == 0, f"{found.failed} of {found.attempted} examples of {_module_name(path)} fail"
