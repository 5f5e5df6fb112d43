"""One base error: every exception class the project defines derives from ``TexplorerError``."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

import scanner
from scanner import cli
from taxonomy import TexplorerError

PACKAGES = ("scanner", "features", "taxonomy", "gui")


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

