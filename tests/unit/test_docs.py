"""The documentation: the code cites the papers and the project's own pages, not a document it does not ship."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CITED_TREES = ("scanner", "features", "taxonomy", "gui", "tests", "benchmarks", "docs", ".ci")
CITED_FILES = ("README.md", "Makefile", "pyproject.toml", "mkdocs.yml")
TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".html", ".js", ".css", ".yml", ".yaml", ".m", ".csv", ".sh", ""}
# The name of the product specification the project was first written from, which is not in the repository:
# a citation of it points a reader at nothing. Spelled with a class so that this file does not match itself.
UNSHIPPED_DOCUMENT = re.compile(r"(?<![A-Za-z])SP[E]C(?![a-z])")


def _cited_files() -> list[Path]:
    files = [ROOT / name for name in CITED_FILES if (ROOT / name).is_file()]
    for tree in CITED_TREES:
        files += [p for p in sorted((ROOT / tree).rglob("*"))
                  if p.is_file() and p.suffix in TEXT_SUFFIXES and "__pycache__" not in p.parts]
    return files


def test_no_file_cites_a_document_the_repository_does_not_ship():
    found = []
    for path in _cited_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if UNSHIPPED_DOCUMENT.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()[:100]}")
    assert not found, "cite the paper or a page under docs/ instead:\n" + "\n".join(found)


def test_the_check_finds_a_citation_and_ignores_ordinary_words():
    assert UNSHIPPED_DOCUMENT.search("(" + "SP" + "EC 7.1)")
    assert UNSHIPPED_DOCUMENT.search("SP" + "EC_NAMES = [")
    assert not UNSHIPPED_DOCUMENT.search("INSPECTION of the spectrum, Spectral centroid")


# -- the examples of README.md and docs/ run as written ------------------------------------------------------

FENCE = re.compile(r"^(?:<!-- (?P<directive>not run|file): (?P<argument>[^>]*) -->\n)?"
                   r"```(?P<lang>[\w-]*)[^\n]*\n(?P<body>.*?)^```$", re.S | re.M)
PYTHON, SHELL = {"python", "py"}, {"sh", "bash", "shell"}
FILE_HEADER = re.compile(r"#\s*(?P<name>[\w.-]+\.(?:toml|csv|txt))\s*\n")
"""The small demo database the examples run on: the command getting-started.md shows."""


@dataclasses.dataclass(frozen=True)
class Block:
    """A fenced code block of a page: ``skip`` is the reason it does not run, ``file`` the file it is written
    to (``<!-- file: NAME -->`` before the block, or a first line ``# NAME.toml``)."""

    page: str
    line: int
    lang: str
    body: str
    skip: str | None = None
    file: str | None = None

    def __str__(self) -> str:
        return f"{self.page}:{self.line} ({self.lang or 'text'})"


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def blocks(path: Path) -> list[Block]:
    """The fenced code blocks of a Markdown page, with the reason given in a ``<!-- not run: ... -->`` comment
    on the line before a block that must not run (hardware, a cluster, a server that runs until stopped)."""
    text = path.read_text(encoding="utf-8")
    page = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else path.name
    found = []
    for m in FENCE.finditer(text):
        header = FILE_HEADER.match(m["body"]) if m["lang"] not in PYTHON | SHELL else None
        found.append(Block(page, text.count("\n", 0, m.start("body")), m["lang"].lower(), m["body"],
                           skip=m["argument"] if m["directive"] == "not run" else None,
                           file=m["argument"] if m["directive"] == "file" else header and header["name"]))
    return found


def runnable(block: Block) -> bool:
    return block.skip is None and (block.lang in PYTHON | SHELL or block.file is not None)


def test_blocks_are_found_with_their_languages_and_reasons(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("text\n\n```python\nx = 1\n```\n\n<!-- not run: needs a DAQ -->\n```sh\ntexplorer scan\n```\n"
                    "\n```toml\n# lab.toml\n[steps]\n```\n\n```\n$ transcript\n```\n"
                    "<!-- file: lab.csv -->\n```\nkind,code\n```\n")
    found = blocks(page)
    assert [(b.lang, b.skip, b.file, b.line) for b in found] == [
        ("python", None, None, 3), ("sh", "needs a DAQ", None, 8), ("toml", None, "lab.toml", 12),
        ("", None, None, 17), ("", None, "lab.csv", 21)]
    assert [runnable(b) for b in found] == [True, False, True, False, True]


def test_every_skipped_example_says_why():
    for path in _pages():
        for block in blocks(path):
            assert block.skip is None or block.skip.strip(), f"{block}: say why the example does not run"


















# -- the site --------------------------------------------------------------------------------------------------



# -- the API reference and its examples ------------------------------------------------------------------------

API_ENTRY = re.compile(r"^::: (?P<name>[\w.]+)", re.M)


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # a name inside a module that is not a package
        return False


def _documented_modules() -> list[str]:
    """The modules whose objects docs/api/*.md lists (``::: package.module.name``)."""
    modules = set()
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        for m in API_ENTRY.finditer(page.read_text()):
            parts = m["name"].split(".")
            while parts and not _is_module(".".join(parts)):
                parts.pop()
            assert parts, f"{page.name}: {m['name']} names no module"
            modules.add(".".join(parts))
    return sorted(modules)


def test_every_object_of_the_api_reference_exists():
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        for m in API_ENTRY.finditer(page.read_text()):
            module_name, _, attribute = m["name"].rpartition(".")
            if _is_module(m["name"]):
                continue
            assert hasattr(importlib.import_module(module_name), attribute), f"{page.name}: no {m['name']}"


@pytest.mark.parametrize("module", _documented_modules())
def test_the_docstring_examples_of_the_api_reference_run(module):
    import doctest

    found = doctest.testmod(importlib.import_module(module), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert found.failed == 0, f"{found.failed} of {found.attempted} examples of {module} fail"
