"""``texplorer features``: the feature table of the database's scans (from the feature cache where the scans
and the feature code are unchanged) or of a recording set, with what ``evaluate set:NAME`` reads back of it (the
options a set's table was written with). A group of its own: a fully cached run imports neither scikit-learn nor
scipy.stats."""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from features import REGISTRY, code_version, feature_sets
from features.recordings import Windowing, describe_families, feature_space
from scanner.cli.base import EXIT_ERROR, UsageError, add_db_option, open_db
from scanner.cli.common import add_cluster_options, add_feature_set_option, runtime_of
from scanner.storage.files import atomic_write_bytes, sha256_file
from scanner.storage.ingest import load_recordings, set_folder
from scanner.storage.stored import stat_record
from scanner.workflows.database import extract_database
from taxonomy.labels import parse_prefix
from taxonomy.learning.results import one_line


def report_space(space, seconds: float) -> None:
    nan_columns = int(np.isnan(space.X).any(axis=0).sum()) if len(space) else 0
    print(f"{len(space)} scans x {len(space.columns)} features in {seconds:.1f} s "
          f"({nan_columns} column(s) with NaN, {len(space.failed)} scan(s) failed)")
    for scan_id, reason in space.failed:
        print(f"failed   {scan_id}: {reason}")


def table_name(label: str | None) -> str:
    """The default file of ``texplorer features``: ``features.csv`` for every scan, ``features-C6.csv`` for the
    scans of a label or class prefix, so a filtered run never replaces the table of every scan."""
    return f"features-{parse_prefix(label)}.csv" if label else "features.csv"


def cmd_features(args: argparse.Namespace) -> int:
    if args.dataset:
        return cmd_set_features(args)
    db = open_db(args)
    started = time.perf_counter()
    with runtime_of(args):
        space = extract_database(db, label=args.label, workers=args.workers,
                                 families=feature_sets.families_for(args.feature_set), partial=False)
    report_space(space, time.perf_counter() - started)
    out = args.out or db.root / table_name(args.label)
    space.to_csv(out)
    kept = "" if args.out or not args.label else (f" (the scans of {parse_prefix(args.label)}; "
                                                  f"{db.root / table_name(None)} is left as it was)")
    print(f"wrote {out}{kept}")
    if args.mat:
        space.to_mat(args.mat)
        print(f"wrote {args.mat}")
    return EXIT_ERROR if space.failed else 0


def set_recordings(spec: str, db: Path) -> tuple[str, list]:
    """The set name and recordings a ``set:NAME`` argument names."""
    if not spec.startswith("set:"):
        raise UsageError(f"{spec!r} is not a recording set; name one as set:NAME (see 'texplorer ingest')")
    return spec[4:], load_recordings(set_folder(db, spec[4:]))


def set_space(args: argparse.Namespace):
    """The feature space of ``set:NAME`` with the windowing, crop and grouping asked for (where the current
    runtime runs the work); prints a summary line and the extraction warnings (a count, all with
    --verbose)."""
    name, recordings = set_recordings(args.dataset, args.db)
    windowing = Windowing(args.window, args.combine)
    started = time.perf_counter()
    wanted = args.feature_set if isinstance(args.feature_set, list) else [args.feature_set]
    space, notes = feature_space(recordings, windowing, args.border, args.group_by, workers=args.workers,
                                 progress=True, chosen=feature_sets.role_families_for(wanted))
    for note in notes if args.verbose else notes[:3]:
        print(f"texplorer: warning: {one_line(note)}", file=sys.stderr)
    if len(notes) > 3 and not args.verbose:
        print(f"texplorer: warning: {len(notes) - 3} more warning(s); --verbose lists them", file=sys.stderr)
    levels = ", ".join(f"{level} ({len(set(space.y(level)))} classes)" for level in reversed(space.level_names))
    split = (f"; split {space.split.count('train')} train / {space.split.count('test')} test"
             if space.split else "")
    print(f"set:{name}: {len(recordings)} recordings -> {len(space)} rows ({windowing.describe()}), "
          f"{len(set(space.groups))} groups; levels {levels}{split}")
    print(f"features: {describe_families(space.columns)} in {time.perf_counter() - started:.1f} s")
    return space


SET_TABLE = "features.csv"
SET_TABLE_OPTIONS = "features.json"
"""Beside a set's feature table, the options it was written with (windowing, crop, grouping), the feature
code version and the recordings it read, so ``evaluate set:NAME`` can tell whether the table fits."""


def recordings_fingerprint(folder: Path) -> str:
    """A hash of the set's recording files' stat records (:func:`scanner.storage.stored.stat_record`: size,
    modification time, inode change time, inode and device). The change time is the kernel's: an edit of the
    same size whose modification time is put back (``cp -p``, ``rsync -t``, ``touch -r``, a backup restored)
    still changes it."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.mat")):
        digest.update(f"{path.name}\0{stat_record(path.stat())}\n".encode())
    return digest.hexdigest()


def recordings_content(folder: Path) -> str:
    """A hash of the set's recording files' names and contents: what a feature table was computed from.
    Asked only when the stat records differ (a set copied, restored or touched), so an unchanged set is not
    read in full."""
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.mat")):
        digest.update(f"{path.name}\0{sha256_file(path)}\n".encode())
    return digest.hexdigest()


def set_table_options(args: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """What a set's feature table depends on, as ``features.json`` records it."""
    wanted = args.feature_set if isinstance(args.feature_set, list) else [args.feature_set]
    families = feature_sets.role_families_for(wanted)
    return {"window": args.window, "combine": args.combine, "border": args.border, "group_by": args.group_by,
            "families": list(families or ()), "code_version": code_version(),
            "recordings": recordings_fingerprint(folder)}


OPTION_WORDS = {"window": "--window", "combine": "--combine", "border": "--border", "group_by": "--group-by",
                "families": "--feature-set",
                "code_version": "the feature code", "recordings": "the recordings"}


def _table_options(folder: Path) -> tuple[Path, dict[str, Any] | None, str]:
    """A set's feature table, the options its ``features.json`` records (None if there are none), and why not."""
    table, written = folder / SET_TABLE, folder / SET_TABLE_OPTIONS
    if not table.is_file() or not written.is_file():
        return table, None, f"no table written by 'texplorer features set:{folder.name}'"
    try:
        stored = json.loads(written.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return table, None, f"{written} cannot be read"
    return (table, stored, "") if isinstance(stored, dict) else (table, None, f"{written} holds no table options")


def stored_set_table(args: argparse.Namespace, folder: Path) -> tuple[Path | None, str]:
    """The set's feature table if it was written with the options of ``args`` (and the same recordings and
    feature code), else None; and one line saying which table ``evaluate`` uses and why."""
    table, stored, why = _table_options(folder)
    if stored is None:
        return None, f"extracting the features ({why})"
    wanted = set_table_options(args, folder)
    differ = [OPTION_WORDS[key] for key in wanted if stored.get(key) != wanted[key]]
    if differ == [OPTION_WORDS["recordings"]] and stored.get("content") == recordings_content(folder):
        differ = []  # the files were copied or touched, not changed: their contents prove it
    if differ:
        return None, f"extracting the features ({table} was written with other {', '.join(differ)})"
    return table, f"using {table} (written by 'texplorer features {args.dataset}' with the same options)"


def current_set_table(folder: Path) -> tuple[Path | None, str]:
    """The set's feature table if the current feature code computed it from the recordings the set holds now
    (whatever its options, which its ``features.json`` records), else None; and why not."""
    table, stored, why = _table_options(folder)
    if stored is None:
        return None, why
    if stored.get("code_version") != code_version():
        return None, f"{table} was written by other feature code"
    if stored.get("recordings") != recordings_fingerprint(folder) and stored.get("content") != \
            recordings_content(folder):
        return None, f"{table} was written from other recordings"
    return table, ""


def cmd_set_features(args: argparse.Namespace) -> int:
    folder = set_folder(args.db, args.dataset[4:])
    with runtime_of(args):
        space = set_space(args)
    out = args.out or folder / SET_TABLE
    if args.out is None:  # the options of the table it replaces no longer describe it
        (folder / SET_TABLE_OPTIONS).unlink(missing_ok=True)
    print(f"wrote {space.to_csv(out)}")
    if args.out is None and not space.failed:  # a table without some recordings is not reused by evaluate
        atomic_write_bytes(folder / SET_TABLE_OPTIONS, json.dumps(
            {**set_table_options(args, folder), "content": recordings_content(folder)}).encode())
    if args.mat:
        print(f"wrote {space.to_mat(args.mat)}")
    return EXIT_ERROR if space.failed else 0


def add_set_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", nargs="?", metavar="set:NAME", help="a recording set imported with "
                        "'texplorer ingest' (default: the scans of the database)")
    parser.add_argument("--window", type=float, metavar="SECONDS", help="sets: cut each recording into "
                        "windows of this length (default: the whole recording)")
    parser.add_argument("--combine", choices=("mean", "median", "rows"), default="mean", help="sets: combine "
                        "the windows' features by their mean (default) or median, or make each window a row "
                        "(in its recording's group)")
    parser.add_argument("--border", type=int, default=0, metavar="PX", help="sets: pixels cropped from every "
                        "side of a photo before its features (default 0; the scanner's photos use 100)")
    parser.add_argument("--group-by", default="auto", metavar="GROUP", help="what folds keep together: for "
                        "the database's scans sample (default), session, operator or recording (each scan); "
                        "for sets a group of the mapping's pattern, recording (each recording with its "
                        "windows; also 'none'), or auto (default: object, else the photo a patch was cut "
                        "from, else the recording)")
    parser.add_argument("--verbose", action="store_true", help="sets: print every extraction warning")


def register(commands: argparse._SubParsersAction) -> None:
    count = len(REGISTRY.names)
    features = commands.add_parser("features", help="extract the features of every scan into a feature table",
                                   description=f"Extract the {count} features of every scan (cached in the database "
                                   "by scan content and feature-code version) and write features.csv.")
    add_db_option(features)
    add_set_options(features)
    add_feature_set_option(features, many=True)
    features.add_argument("--workers", type=int, help="processes (default: number of cores)")
    features.add_argument("--out", type=Path, help="CSV file (default: <db>/features.csv, with --label "
                          "<db>/features-<LABEL>.csv; for a set <db>/recordings/<set>/features.csv, which "
                          "'evaluate set:NAME' then uses when given the same options)")
    features.add_argument("--mat", type=Path, help="also write the feature space as a .mat file")
    features.add_argument("--label", help="only scans with this label, class prefix (C6 = every stone) or part "
                          "of a material name (granite)")
    add_cluster_options(features)
    features.set_defaults(handler=cmd_features)
