"""The ``texplorer`` command line (docs/extending.md).

Every subcommand that uses a database takes ``--db PATH`` (default ``$TEXPLORER_DB``, else
``./texplorer-data``). Errors are one line on stderr and a non-zero exit; ``--debug`` shows the traceback.

Each group of subcommands is a module that registers itself (``register(commands)``): ``demo``,
``analysis``, ``db``, ``exchange``, ``acquisition``, ``recordings``; packages above the CLI add their own
groups through the ``texplorer.commands`` entry point (the web application's ``serve``).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from importlib.metadata import entry_points

from scanner.cli import acquisition, analysis, db, demo, exchange, recordings
from scanner.cli.common import EXIT_ERROR, EXIT_PROBLEMS, UsageError
from scanner.cli.exchange import EXIT_MISMATCH
from scanner.cli.recordings import COMPARE_METHODS
from scanner.version import __version__
from taxonomy.errors import TexplorerError

__all__ = ["COMPARE_METHODS", "EXIT_ERROR", "EXIT_MISMATCH", "EXIT_PIPE", "EXIT_PROBLEMS", "GROUPS", "UsageError",
           "build_parser", "main"]

GROUPS = (demo, analysis, db, exchange, acquisition, recordings)
"""The CLI's own command groups, in the order of ``texplorer --help``."""

ENTRY_POINTS = "texplorer.commands"
"""Entry-point group through which a package above the CLI adds a command group (``register(commands)``)."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="texplorer", description="Multimodal material scanner: acquisition, "
                                     "database, features and classification.")
    parser.add_argument("--version", action="version", version=f"texplorer {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for group in GROUPS:
        group.register(commands)
    for entry in sorted(entry_points(group=ENTRY_POINTS), key=lambda e: e.name):
        entry.load()(commands)
    return parser

def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.debug = getattr(args, "debug", False)
    try:
        status = args.handler(args)
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's flush at exit
        return status
    except BrokenPipeError:
        return _reader_gone()
    except KeyboardInterrupt:
        print("texplorer: interrupted", file=sys.stderr)
        return 130
    except (TexplorerError, OSError) as exc:
        if args.debug:
            raise
        print(f"texplorer: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except Exception as exc:
        if args.debug:
            raise
        print(f"texplorer: error: {type(exc).__name__}: {exc} (run with --debug for the traceback)",
              file=sys.stderr)
        return EXIT_ERROR


EXIT_PIPE = 128 + 13
"""The reader of the output went away (``texplorer db list | head``): the status of a process ended by
SIGPIPE, as ``cat`` gives."""


def _reader_gone() -> int:
    """End quietly when standard output is a closed pipe: no error line, no traceback at exit."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())  # the interpreter's last flush of stdout must not fail again
    os.close(devnull)
    return EXIT_PIPE

