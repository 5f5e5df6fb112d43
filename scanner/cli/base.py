"""What every command group shares and that loads nothing heavy: the database option, exit codes, usage
errors, tables and progress bars. ``texplorer db`` needs only these, so it starts without the feature code
and the classifiers (:mod:`scanner.cli.common` holds the options that need them)."""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

from scanner.lazy import library
from scanner.storage.database import Database
from taxonomy.errors import TexplorerError

tqdm = library("tqdm")  # loaded by the commands that show progress, not by every start

DEFAULT_DB = "texplorer-data"


EXIT_ERROR = 1


EXIT_PROBLEMS = 3
"""``db check`` found missing, changed or unknown files; ``db rebuild`` quarantined files; ``import`` had
conflicts."""


Handler = Callable[[argparse.Namespace], int]


class UsageError(TexplorerError, ValueError):
    """Options that do not fit together or a value out of range; the message names the option."""


def default_db() -> Path:
    return Path(os.environ.get("TEXPLORER_DB") or DEFAULT_DB)


def progress(description: str, unit: str = "scan") -> Callable[[Iterable], Iterable]:
    """A tqdm progress bar on stderr counting ``unit`` (hidden when stderr is not a terminal)."""
    return lambda items: tqdm.tqdm(items, desc=description, unit=unit, file=sys.stderr, disable=None,
                                   leave=False)


def open_db(args: argparse.Namespace, *, create: bool = False) -> Database:
    return Database(args.db, create=create)


def first_missing(path: Path) -> Path | None:
    """The outermost folder of ``path`` that does not exist yet (``path`` itself, or one of its parents), or
    None when ``path`` exists."""
    path = Path(path).absolute()
    missing = None
    for folder in (path, *path.parents):
        if folder.exists():
            break
        missing = folder
    return missing


@contextlib.contextmanager
def created_db(args: argparse.Namespace) -> Iterator[Database]:
    """The database of ``--db``, made if missing; made and the command then refused, it is removed again, so
    a refused command leaves no empty database folder behind."""
    made = first_missing(args.db)
    db = open_db(args, create=True)
    try:
        yield db
    except BaseException:
        db.close()
        if made is not None:
            shutil.rmtree(made, ignore_errors=True)
        raise


def table_lines(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Left-aligned columns as wide as their longest entry (the last column is not padded)."""
    widths = [max(len(str(cell)) for cell in column) for column in zip(header, *rows, strict=True)]
    return [" ".join(f"{cell!s:<{width}}" for cell, width in zip(row, widths, strict=True)).rstrip()
            for row in (header, *rows)]


def add_db_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, default=default_db(),
                        help="database folder (default: $TEXPLORER_DB, else ./texplorer-data)")
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks on errors")
