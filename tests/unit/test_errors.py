"""One base error: every exception class the project defines derives from ``TexplorerError``, and the
project raises its own errors, not bare built-in ones (bad arguments raise ``ParameterError``)."""

from __future__ import annotations

import ast
import builtins
import importlib
import inspect
import pkgutil
from pathlib import Path

import pytest

import scanner
from scanner import cli
from taxonomy import TexplorerError
from taxonomy.errors import ParameterError

PACKAGES = ("scanner", "features", "taxonomy", "gui")
ROOT = Path(__file__).resolve().parents[2]

BUILT_IN_ERRORS = frozenset(name for name, value in vars(builtins).items()
                            if inspect.isclass(value) and issubclass(value, BaseException))

BUILT_IN_RAISES = {
    ("scanner/scan.py", "Scan.__getitem__", "KeyError"):
        "the mapping protocol: scan[name] of a channel the scan lacks",
    ("scanner/storage/stored.py", "ShippedScan.read", "OSError"):
        "a file system of the files a client sent: its readers handle OSError as for files on disk",
    ("scanner/storage/stored.py", "ShippedScan._sent", "FileNotFoundError"):
        "a file system of the files a client sent: a name it did not send is a missing file",
    ("scanner/acquisition/emulators/daq_grpc.py", "DaqEmulator.__init__", "OSError"):
        "the operating system refused the port, as socket.bind would say",
    ("scanner/acquisition/emulators/daq_grpc.py", "", "ImportError"):
        "an optional library is missing: importing the module fails as an import does",
    ("scanner/cli/acquisition.py", "cmd_emulate_board", "OSError"):
        "the operating system has no pseudo-terminals",
    ("features/extraction.py", "extract", "RuntimeError"):
        "a programming error in a feature family (names out of order), not bad input",
    ("scanner/lazy.py", "_Library.__getattr__", "AttributeError"):
        "the module __getattr__ protocol: a name the module does not have",
    ("scanner/lazy.py", "_Kernel.__getattr__", "AttributeError"):
        "the __getattr__ protocol: a name the compiled function does not have",
    ("scanner/lazy.py", "optional", "ModuleNotFoundError"):
        "an optional library is missing: the import fails as an import does, naming the extra",
    ("scanner/lazy.py", "library", "ValueError"):
        "a programming error (a project module deferred), in the one module that imports nothing of the project",
    ("gui/app.py", "_stop", "KeyboardInterrupt"):
        "a signal handler: SIGTERM stops the server the way Ctrl-C does",
    ("taxonomy/table.py", "Taxonomy.search", "TypeError"):
        "an argument of the wrong type, as Python's own functions say",
}
"""Where a built-in exception is raised on purpose, and why; every other raise is of a project error."""


def project_modules() -> list[str]:
    names = []
    for package in PACKAGES:
        names.append(package)
        root = importlib.import_module(package)
        names += [info.name for info in pkgutil.walk_packages(root.__path__, f"{package}.")
                  if not info.name.endswith(".__main__")]  # running one is the program, not an import
    return names


def defined_exceptions() -> list[type[BaseException]]:
    found = []
    for name in project_modules():
        module = importlib.import_module(name)
        found += [value for value in vars(module).values() if inspect.isclass(value)
                  and issubclass(value, Exception) and not issubclass(value, Warning)
                  and value.__module__ == module.__name__]
    return found


def test_every_project_error_derives_from_texplorer_error():
    errors = defined_exceptions()
    assert len(errors) >= 35  # the walk found the packages' modules, not an empty list
    strays = [f"{error.__module__}.{error.__qualname__}" for error in errors if not issubclass(error, TexplorerError)]
    assert strays == []


def test_base_error_is_one_public_name():
    assert scanner.TexplorerError is TexplorerError


@pytest.mark.parametrize("error", [e for e in defined_exceptions() if not e.__name__.startswith("_")],
                         ids=lambda e: e.__qualname__)
def test_cli_shows_every_project_error_as_one_line(error, monkeypatch, capsys):
    def fail(args):
        raise error.__new__(error, "what went wrong")

    monkeypatch.setattr(cli.db, "cmd_db_list", fail)  # the parser binds the handler when main builds it
    assert cli.main(["db", "list"]) == cli.EXIT_ERROR
    assert capsys.readouterr().err.splitlines() == ["texplorer: error: what went wrong"]


def test_a_parameter_error_is_a_texplorer_error_and_a_value_error():
    assert issubclass(ParameterError, TexplorerError) and issubclass(ParameterError, ValueError)


def built_in_raises(path: Path, root: Path = ROOT) -> list[tuple[str, str, str]]:
    """``(file, enclosing function, exception)`` of every ``raise`` of a built-in exception in ``path``."""
    found = []

    def visit(node: ast.AST, scope: tuple[str, ...]) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                visit(child, (*scope, child.name))
                continue
            if isinstance(child, ast.Raise) and child.exc is not None:
                raised = child.exc.func if isinstance(child.exc, ast.Call) else child.exc
                name = (raised.id if isinstance(raised, ast.Name) else
                        raised.attr if isinstance(raised, ast.Attribute) and ast.unparse(raised.value) == "builtins"
                        else "")
                if name in BUILT_IN_ERRORS:
                    found.append((path.relative_to(root).as_posix(), ".".join(scope), name))
            visit(child, scope)

    visit(ast.parse(path.read_text(encoding="utf-8")), ())
    return found


def test_no_bare_built_in_error_is_raised():
    files = sorted(path for package in PACKAGES for path in (ROOT / package).rglob("*.py"))
    assert len(files) > 60
    raised = [found for path in files for found in built_in_raises(path)]
    assert sorted(set(raised) - set(BUILT_IN_RAISES)) == []
    assert sorted(set(BUILT_IN_RAISES) - set(raised)) == []  # the list names only raises that exist


def test_the_check_sees_a_bare_raise(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("import builtins\n\n\nclass A:\n    def f(self, x):\n        if x:\n"
                      "            raise ValueError(x)\n        raise builtins.TypeError\n\n\n"
                      "def g():\n    raise ParameterError('bad')\n")
    assert built_in_raises(sample, tmp_path) == [("sample.py", "A.f", "ValueError"), ("sample.py", "A.f", "TypeError")]


KEPT_BASES = ("TexplorerError", "ParameterError")
"""The two errors every caller may catch; any other project error is kept only where someone catches it by
name, as it tells them something those two do not."""


def caught_names(path: Path) -> set[str]:
    """The exception names ``path`` catches: in ``except`` clauses, ``pytest.raises`` and
    ``isinstance(..., X)`` checks (a plain name, the last part of a dotted one, or any of a tuple)."""
    found: set[str] = set()

    def names(node: ast.AST | None) -> None:
        if isinstance(node, ast.Tuple):
            for item in node.elts:
                names(item)
        elif isinstance(node, ast.Name):
            found.add(node.id)
        elif isinstance(node, ast.Attribute):
            found.add(node.attr)

    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ExceptHandler):
            names(node.type)
        elif isinstance(node, ast.Call) and node.args and ast.unparse(node.func) in ("pytest.raises", "raises"):
            names(node.args[0])
        elif isinstance(node, ast.Call) and ast.unparse(node.func) == "isinstance" and len(node.args) == 2:
            names(node.args[1])
    return found


def test_every_project_error_beyond_the_two_bases_is_caught_by_name_somewhere():
    files = sorted(path for folder in (*PACKAGES, "tests") for path in (ROOT / folder).rglob("*.py"))
    caught = set().union(*(caught_names(path) for path in files))
    uncaught = sorted({error.__qualname__ for error in defined_exceptions()} - caught - set(KEPT_BASES))
    assert uncaught == []


def test_the_catch_check_sees_except_raises_and_isinstance(tmp_path):
    sample = tmp_path / "sample.py"
    sample.write_text("try:\n    f()\nexcept (storage.BundleError, OSError):\n    pass\n"
                      "with pytest.raises(ModelError, match='x'):\n    g()\n"
                      "if isinstance(exc, (UsageError, errors.LabelError)):\n    pass\n")
    assert caught_names(sample) == {"BundleError", "OSError", "ModelError", "UsageError", "LabelError"}
