"""The ``texplorer`` command line (docs/extending.md).

Every subcommand that uses a database takes ``--db PATH`` (default ``$TEXPLORER_DB``, else
``./texplorer-data``). Errors are one line on stderr and a non-zero exit; ``--debug`` shows the traceback.

Each group of subcommands is a module that registers itself (``register(commands)``): ``demo``,
``analysis``, ``db``, ``exchange``, ``acquisition``, ``recordings``; packages above the CLI add their own
groups through the ``texplorer.commands`` entry point (the web application's ``serve``). A command line loads
only the group of its command (:data:`COMMANDS`), and ``texplorer --help`` none: a command starts without
the libraries only the others need.
"""

from __future__ import annotations

import argparse
import ast
import difflib
import importlib
import importlib.util
import os
import sys
from collections.abc import Iterable, Sequence
from importlib.metadata import EntryPoint, entry_points

from scanner.cli.base import EXIT_ERROR, EXIT_PROBLEMS, UsageError
from scanner.version import __version__
from taxonomy.errors import ParameterError, TexplorerError

__all__ = ["COMMANDS", "EXIT_ERROR", "EXIT_PIPE", "EXIT_PROBLEMS", "GROUPS", "UsageError", "build_parser", "main"]

COMMANDS = {
    "demo": ("demo", "build a synthetic database from the simulated scanner and summarise it"),
    "features": ("features", "extract the features of every scan into a feature table"),
    "select": ("analysis", "print the FQ ranking and the selected feature set"),
    "evaluate": ("analysis", "cross-validate classifiers x feature sets x levels; table and HTML report"),
    "train": ("analysis", "train a classifier on all scans and save it (skops)"),
    "models": ("models", "list the database's model versions; make one current"),
    "classify": ("models", "predict the material of a stored scan (its id in the database, or a .mat file)"),
    "db": ("db", "inspect and repair the database"),
    "export": ("exchange", "write scans, features, taxonomy and a checksummed manifest as a bundle for a lab"),
    "import": ("exchange", "verify a bundle completely, then merge its scans into the database"),
    "replay": ("exchange", "run stored scans through preprocessing, features and a model; check expected values"),
    "scan": ("acquisition", "guided scanning session in the terminal (simulated devices unless configured)"),
    "emulate": ("acquisition", "run a device emulator to try the app without hardware"),
    "ingest": ("recordings", "import recordings or photos (CSV/TSV, WAV, NPY/NPZ, .mat, PNG/JPG/BMP/TIFF) as a set"),
    "compare": ("recordings", "run the related papers' methods on one dataset: table and HTML report"),
}
"""Every command of the CLI's own groups, in the order of ``texplorer --help``: the group module of
``scanner.cli`` that registers it, and its one-line help (the group registers the same line; a test
holds them equal). ``texplorer --help`` and ``--version`` load no group; a command loads its own group only,
so that it starts without the libraries the others need (numba, scikit-learn, OpenCV, Flask)."""

GROUPS = tuple(dict.fromkeys(group for group, _ in COMMANDS.values()))
"""The CLI's own command groups: each a module of ``scanner.cli`` with ``register(commands)``. They are
imported by name when one of their commands runs (the one import by name of the project, within the CLI's
own layer, so that no arrow between layers is hidden from the contracts; docs/extending.md)."""

ENTRY_POINTS = "texplorer.commands"
"""Entry-point group through which a package above the CLI adds a command group (``register(commands)``):
the entry point's name is the command, the first paragraph of its module's docstring the one-line help."""


def build_parser(commands: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The ``texplorer`` parser, with the groups of ``commands`` loaded (default: every group).

    The other commands are listed with their one-line help, without their options: the parser of a command
    line needs only the group of its command.
    """
    wanted = None if commands is None else set(commands)
    parser = argparse.ArgumentParser(prog="texplorer", description="Multimodal material scanner: acquisition, "
                                     "database, features and classification.")
    parser.add_argument("--version", action="version", version=f"texplorer {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    # The installed packages' entry points are read (some 0.1 s) only to list every command or to run one of them
    listing = wanted is None or not wanted or not wanted <= set(COMMANDS)
    plugins = {entry.name: entry for entry in entry_points(group=ENTRY_POINTS)} if listing else {}
    groups = GROUPS if wanted is None else {COMMANDS[command][0] for command in wanted if command in COMMANDS}
    loaded: set[str] = set()
    for group in GROUPS:
        if group in groups:
            _group_module(group).register(subparsers)
            loaded.update(command for command, (owner, _) in COMMANDS.items() if owner == group)
    for name in sorted(plugins):
        if wanted is None or name in wanted:
            plugins[name].load()(subparsers)
            loaded.add(name)
    for command, (_, summary) in COMMANDS.items():
        if command not in loaded:
            subparsers.add_parser(command, help=summary)
    for name in sorted(set(plugins) - loaded):
        subparsers.add_parser(name, help=plugin_summary(plugins[name]))
    return parser


def _group_module(group: str):
    if group not in GROUPS:
        raise ParameterError(f"{group!r} is not a command group of the CLI")
    return importlib.import_module(f"{__name__}.{group}")


def plugin_summary(entry: EntryPoint) -> str:
    """The one-line help of a command group added through an entry point: the first paragraph of its module's
    docstring, read from the source without importing the module (nor the libraries it needs)."""
    spec = importlib.util.find_spec(entry.module)
    if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
        return f"(from {entry.module})"
    with open(spec.origin, encoding="utf-8") as source:
        docstring = ast.get_docstring(ast.parse(source.read())) or ""
    summary = " ".join(docstring.split("\n\n")[0].split()).rstrip(".")
    return summary[:1].lower() + summary[1:] if summary else f"(from {entry.module})"


def command_of(argv: Sequence[str]) -> str | None:
    """The command of a command line: its first word that is not an option (the top-level options take no
    value)."""
    return next((word for word in argv if not word.startswith("-")), None)


def parse_command_line(parser: argparse.ArgumentParser, argv: Sequence[str]) -> argparse.Namespace:
    """``parser.parse_args(argv)``, except that a word no option of the command knows is refused by the
    command's own parser (its usage, not the top level's) with the closest option it has: ``texplorer
    evaluate --clasifier rf`` -> "unrecognized arguments: --clasifier (did you mean --classifier?)"."""
    args, unknown = parser.parse_known_args(argv)
    if unknown:
        command = command_parser(parser, argv)
        command.error(f"unrecognized arguments: {' '.join(unknown)}{did_you_mean(unknown, command)}")
    return args


def command_parser(parser: argparse.ArgumentParser, argv: Sequence[str]) -> argparse.ArgumentParser:
    """The parser of the (sub-)command ``argv`` names: ``db list ...`` -> the parser of ``texplorer db list``."""
    for word in argv:
        subparsers = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
        if subparsers is None:
            break
        if not word.startswith("-") and word in subparsers.choices:
            parser = subparsers.choices[word]
    return parser


def did_you_mean(words: Sequence[str], parser: argparse.ArgumentParser) -> str:
    """`` (did you mean --classifier?)`` for the first option-like word close to an option of ``parser``."""
    options = [option for action in parser._actions for option in action.option_strings]
    for word in words:
        if word.startswith("-"):
            close = difflib.get_close_matches(word.split("=", 1)[0], options, n=1, cutoff=0.6)
            if close:
                return f" (did you mean {close[0]}?)"
    return ""


def main(argv: Sequence[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = command_of(argv)
    parser = build_parser([command] if command else [])
    args = parse_command_line(parser, argv)
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

