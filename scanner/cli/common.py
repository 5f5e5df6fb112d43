"""What the analysis command groups share: the feature space of ``--features`` or the database, the feature
sets and the cluster options (what every group shares, :mod:`scanner.cli.base`, loads nothing heavy; the
evaluation's options, which need the classifiers, are :mod:`scanner.cli.analysis`'s)."""

from __future__ import annotations

import argparse
import contextlib
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path

from features import REGISTRY, FeatureSpace, feature_sets
from scanner.cli.base import UsageError, add_db_option, open_db
from scanner.runtime.executors import LOCAL, Runtime, chosen
from scanner.workflows.database import extract_database

ALL = "all"


def space_for(args: argparse.Namespace):
    """The feature space of ``--features CSV`` if given, else of the database (from its feature cache)."""
    if args.features:
        return FeatureSpace.from_csv(args.features)
    wanted = args.feature_set if isinstance(getattr(args, "feature_set", None), list) else [
        getattr(args, "feature_set", ALL)]
    space = extract_database(open_db(args), workers=args.workers, families=feature_sets.families_for(wanted),
                             partial=False)
    for scan_id, reason in space.failed:
        print(f"texplorer: warning: {scan_id} left out: {reason}", file=sys.stderr)
    return space


def choices(values: list[str], every: Sequence[str]) -> list[str]:
    return list(every) if ALL in values else values


def set_sizes(values: Sequence[str] | None, default: Sequence[str]) -> list[int | None]:
    """``--n`` values: positive integers, and ``all`` (every feature, no selection) as None."""
    sizes: list[int | None] = []
    for value in values or default:
        if value == ALL:
            sizes.append(None)
        elif value.isdigit() and int(value) > 0:
            sizes.append(int(value))
        else:
            raise UsageError(f"--n: {value!r} is neither a positive number of features nor 'all'")
    return list(dict.fromkeys(sizes))


def add_space_options(parser: argparse.ArgumentParser) -> None:
    add_db_option(parser)
    parser.add_argument("--features", type=Path, help="feature table CSV (default: extract from the database, "
                        "using its feature cache)")
    parser.add_argument("--workers", type=int, help="processes (default: number of cores)")
    add_cluster_options(parser)


def feature_set_name(value: str) -> str:
    """An argparse type: a modality, ``all``, or a modern or fused set (:mod:`features.feature_sets`)."""
    try:
        return feature_sets.check_names([value])[0]
    except feature_sets.FeatureSetError as problem:
        raise argparse.ArgumentTypeError(str(problem)) from None


def add_feature_set_option(parser: argparse.ArgumentParser, many: bool) -> None:
    modern = ", ".join(feature_sets.MODERN_SETS)
    parser.add_argument("--feature-set", nargs="+" if many else None, type=feature_set_name,
                        default=[ALL] if many else ALL, metavar="SET",
                        help=f"feature sets: {', '.join(REGISTRY.modalities)}, {ALL} = every modality and all "
                        f"{len(REGISTRY.names)} (default); opt-in: {modern} (docs/modern-features.md), "
                        f"paper, {feature_sets.FUSION} (paper+catch22+scattering+minirocket), or parts joined "
                        "by '+' (paper+minirocket)")


@contextlib.contextmanager
def runtime_of(args: argparse.Namespace) -> Iterator[Runtime]:
    """Where the command's work runs, current until the block ends (:mod:`scanner.runtime.executors`): the
    Dask cluster of ``--scheduler``, else of Dask's configuration (``DASK_SCHEDULER_ADDRESS``), else
    processes on this machine; an explicit ``--workers`` means processes on this machine. ``--ship-data``
    sends the scans' files to a cluster's workers."""
    with chosen(args.scheduler, workers=getattr(args, "workers", None),
                ship_data=getattr(args, "ship_data", False)) as runtime:
        if runtime is LOCAL:
            yield runtime
            return
        print(runtime.describe(), file=sys.stderr)
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            yield runtime


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"texplorer: warning: {message}", file=sys.stderr)


def add_cluster_options(parser: argparse.ArgumentParser, ship: bool = True) -> None:
    parser.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster: tcp://HOST:PORT of its "
                        "scheduler, or local:N for N worker processes here with Dask's dashboard (default: "
                        "Dask's scheduler-address, e.g. $DASK_SCHEDULER_ADDRESS, else processes on this machine)")
    if ship:
        parser.add_argument("--ship-data", action="store_true", help="send each scan's files from this machine "
                            "to the Dask workers (automatic for workers that do not see them at the same path)")
