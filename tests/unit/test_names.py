"""One name, one meaning: no two classes of the project share a name."""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("scanner", "features", "taxonomy", "gui")


def class_names(root: Path = ROOT, packages: tuple[str, ...] = PACKAGES) -> dict[str, list[str]]:
    """Every top-level class name of the packages, with the modules that define it."""
    found: dict[str, list[str]] = defaultdict(list)
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            for node in ast.parse(path.read_text(encoding="utf-8")).body:
                if isinstance(node, ast.ClassDef):
                    found[node.name].append(path.relative_to(root).as_posix())
    return found


def test_no_class_name_is_used_twice():
    names = class_names()
    assert len(names) > 100  # the walk found the project's classes
    assert {name: where for name, where in names.items() if len(where) > 1} == {}


def test_the_check_sees_a_shared_name(tmp_path):
    for module in ("a", "b"):
        (tmp_path / "pkg").mkdir(exist_ok=True)
        (tmp_path / "pkg" / f"{module}.py").write_text("class Result:\n    pass\n")
    assert class_names(tmp_path, ("pkg",)) == {"Result": ["pkg/a.py", "pkg/b.py"]}
