"""The documentation: the code cites the papers and the project's own pages, not a document it does not ship."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
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
