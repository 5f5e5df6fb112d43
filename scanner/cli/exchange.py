"""``texplorer export``, ``import``, ``replay``: bundles for other labs and replaying stored scans."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from features import REGISTRY, SOLVER_RTOL, FeatureSpace
from scanner.cli.base import EXIT_ERROR, EXIT_PROBLEMS, UsageError, add_db_option, created_db, open_db, progress
from scanner.cli.common import add_cluster_options, runtime_of
from scanner.cli.features import current_set_table
from scanner.replay import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    ReplayError,
    check_unique,
    compare,
    format_comparison,
    paced_steps,
    predictions,
    replay,
    scan_paths,
)
from scanner.storage.bundle import BundleError, import_bundle
from scanner.storage.ingest import set_folder
from scanner.storage.matfile import load_scan
from scanner.storage.set_bundle import KIND, bundle_kind, export_set, import_set_bundle
from scanner.storage.settings import read_settings
from scanner.workflows.exchange import export_database
from taxonomy.labels import Label
from taxonomy.learning.models import load_model

EXIT_MISMATCH = 4
"""``replay --expect`` found feature values outside the tolerance, or missing scans or features."""


def cmd_export(args: argparse.Namespace) -> int:
    if args.set:
        return _export_set(args)
    report = export_database(open_db(args), args.out, label=args.label, session=args.session,
                             license=args.license, creator=args.creator, workers=args.workers,
                             progress=progress("exporting"))
    for scan_id, reason in report.feature_failures:
        print(f"texplorer: warning: no feature row for {scan_id}: {reason}", file=sys.stderr)
    print(f"exported {report.scans} scan(s), {report.files} files, {report.bytes / 1e6:.1f} MB "
          f"to {report.path} in {report.seconds:.1f} s")
    return 0


def _export_set(args: argparse.Namespace) -> int:
    if args.label or args.session:
        raise UsageError("--label and --session choose scans; --set exports a whole recording set")
    name = args.set.removeprefix("set:")
    folder = set_folder(args.db, name)
    if not folder.is_dir():
        raise UsageError(f"{args.db}: no recording set {name!r} to export (see 'texplorer ingest')")
    table, why = current_set_table(folder)
    if table is None:
        print(f"texplorer: warning: no features.csv in the bundle: {why}", file=sys.stderr)
    settings = read_settings(args.db)
    report = export_set(args.db, name, args.out, license=args.license or settings.get("license"),
                        creator=args.creator or settings.get("creator"), features=table,
                        progress=progress("exporting", unit="recording"))
    print(f"exported set {name}: {report.recordings} recording(s), {report.files} files, "
          f"{report.bytes / 1e6:.1f} MB to {report.path} in {report.seconds:.1f} s"
          + ("" if report.mapping else " (the set kept no mapping file: ingested before sets kept it)"))
    return 0


def _listing_problems(error: BundleError) -> BundleError:
    for problem in error.problems:
        print(f"problem  {problem}", file=sys.stderr)
    return error


def _import_set(args: argparse.Namespace) -> int:
    try:
        report = import_set_bundle(args.db, args.bundle, name=args.name, replace=args.replace,
                                   progress=progress("verifying", unit="recording"))
    except BundleError as exc:
        raise _listing_problems(exc) from None
    print(f"imported {report.bundle}: set {report.name}, {report.recordings} recording(s) -> {report.folder}, "
          f"{report.bytes / 1e6:.1f} MB verified in {report.seconds:.1f} s")
    return 0


def cmd_import(args: argparse.Namespace) -> int:
    if bundle_kind(args.bundle) == KIND:
        return _import_set(args)
    if args.name or args.replace:
        raise UsageError("--name and --replace apply to a recording-set bundle; this bundle holds scans")
    with created_db(args) as db:
        try:
            report = import_bundle(db, args.bundle, progress=progress("verifying"))
        except BundleError as exc:
            raise _listing_problems(exc) from None
    for line in report.conflicts:
        print(f"conflict {line}")
    for label in report.unknown_labels:
        print(f"texplorer: warning: label {label} is in neither taxonomy; "
              f"add its codes to {db.taxonomy_path}", file=sys.stderr)
    print(f"imported {report.bundle}: {len(report.added)} added, {len(report.identical)} identical "
          f"(skipped), {len(report.conflicts)} conflict(s), {report.bytes / 1e6:.1f} MB verified "
          f"in {report.seconds:.1f} s")
    if report.taxonomy_added:
        print(f"taxonomy codes added to {db.taxonomy_path}: {', '.join(report.taxonomy_added)}")
    return EXIT_PROBLEMS if report.conflicts else 0


def _print_replay(space, predicted: list | None, level: str | None) -> None:

    header = f"{'scan':<28} {'label':<14} {'NaN':>4}"
    print(header + ("  prediction" if predicted else ""))
    for i, scan_id in enumerate(space.scan_ids):
        line = f"{scan_id:<28} {space.label_text[i]:<14} {int(np.isnan(space.X[i]).sum()):>4}"
        if predicted and isinstance(predicted[i], str):
            line += f"  ({predicted[i]})"
        elif predicted:
            label, probability = predicted[i][0]
            verdict = "right" if Label.parse(space.label_text[i]).at(level) == label else "WRONG"
            line += f"  {label} {100 * probability:5.1f} % {verdict}"
        print(line)


def _play(paths: Sequence[Path], speed: float) -> None:

    for path in paths:
        scan = load_scan(path)
        print(f"playing {scan.scan_id} at {speed:g}x")
        for step, arrays in paced_steps(scan, speed):
            levels = ", ".join(f"{name} {np.sqrt(np.mean(np.square(a, dtype=np.float64))):.3g}"
                               for name, a in arrays.items())
            print(f"  {step:<13} rms {levels}", flush=True)


def cmd_replay(args: argparse.Namespace) -> int:
    paths = scan_paths(args.paths)
    if args.pace:
        _play(paths, args.pace)
    model = None
    if args.model:
        model = load_model(args.model)
    expected = FeatureSpace.from_csv(args.expect) if args.expect else None
    started = time.perf_counter()
    with runtime_of(args):
        space = replay(paths, workers=args.workers)
    seconds = time.perf_counter() - started
    _print_replay(space, predictions(space, model, args.k) if model else None, model.level if model else None)
    for path, reason in space.failed:
        print(f"failed   {path}: {reason}")
    print(f"{len(space)} scan(s) replayed in {seconds:.1f} s ({len(paths) / seconds:.2f} scans/s), "
          f"{len(space.failed)} failed")
    status = EXIT_ERROR if space.failed else 0
    if args.write_expected:
        if space.failed:
            raise ReplayError(f"expected values not written: {len(space.failed)} scan(s) failed")
        check_unique(space)
        print(f"wrote {space.to_csv(args.write_expected)}")
    if expected is not None:
        comparison = compare(space, expected, args.rtol, args.atol, SOLVER_RTOL, scans=space.scan_ids)
        print(format_comparison(comparison, args.max_rows))
        status = status if comparison.ok else EXIT_MISMATCH
    return status


def register(commands: argparse._SubParsersAction) -> None:
    count = len(REGISTRY.names)
    export = commands.add_parser(
        "export", help="write scans, features, taxonomy and a checksummed manifest as a bundle for a lab",
        description="Export scans with their photos, features.csv/.mat, taxonomy.csv, scans.csv, manifest.json "
        "(SHA-256 of every file), MATLAB/Python loaders and standard metadata (RO-Crate, Croissant, Frictionless "
        "table schemas, BIDS-style channel tables), as a folder or a .zip that appears only when complete.")
    add_db_option(export)
    export.add_argument("out", type=Path, metavar="OUT", help="new bundle folder, or a file ending in .zip")
    export.add_argument("--set", metavar="NAME", help="export the recording set NAME (set:NAME; 'texplorer "
                        "ingest') with its mapping, channel roles and feature table, instead of scans")
    export.add_argument("--label", help="only this label, class prefix (C6 = every stone) or part of a material "
                        "name (granite)")
    export.add_argument("--session", help="only this session id")
    export.add_argument("--license", help="the bundle's license: SPDX identifier (CC-BY-4.0, CC0-1.0) or URL; "
                        "'none' exports without one (default: 'texplorer db settings'; refused if neither)")
    export.add_argument("--creator", help="who made the data: a person's or lab's name, or an ORCID URL "
                        "(default: 'texplorer db settings')")
    export.add_argument("--workers", type=int, help="processes for uncached features (default: cores)")
    export.set_defaults(handler=cmd_export)

    importing = commands.add_parser(
        "import", help="verify a bundle completely, then merge its scans into the database",
        description="Verify every checksum, the manifest and every scan first (a damaged bundle is refused "
        "with its problems and nothing changes), then add the new scans in one transaction. Identical scans "
        "are skipped; a scan id or sample stored with other content or label is a conflict and is never "
        "overwritten (exit 3); new material codes go to <db>/taxonomy.csv.")
    add_db_option(importing)
    importing.add_argument("bundle", type=Path, metavar="BUNDLE", help="folder or .zip of 'texplorer export'")
    importing.add_argument("--name", help="a recording-set bundle: store the set under this name (default: its own)")
    importing.add_argument("--replace", action="store_true", help="a recording-set bundle: replace a set of the "
                           "same name")
    importing.set_defaults(handler=cmd_import)

    replaying = commands.add_parser(
        "replay", help="run stored scans through preprocessing, features and a model; check expected values",
        description=f"Replay stored .mat scans through preprocessing and the {count} features (and a model). "
        "With --expect, compare with a feature table: |actual - expected| <= atol + rtol * |expected|, NaN "
        f"matches only NaN; exit {EXIT_MISMATCH} on any difference.")
    replaying.add_argument("paths", nargs="+", type=Path, metavar="PATH", help=".mat files or their folders")
    replaying.add_argument("--model", type=Path, help="model file written by 'texplorer train'")
    replaying.add_argument("--k", type=int, default=1, help="predictions per scan with --model (default 1)")
    replaying.add_argument("--expect", type=Path, metavar="CSV", help="expected features (as features.csv)")
    replaying.add_argument("--rtol", type=float, default=DEFAULT_RTOL,
                           help=f"relative tolerance (default {DEFAULT_RTOL:g})")
    replaying.add_argument("--atol", type=float, default=DEFAULT_ATOL,
                           help=f"absolute tolerance (default {DEFAULT_ATOL:g})")
    replaying.add_argument("--write-expected", type=Path, metavar="CSV",
                           help="write the replayed features as the new expected table")
    replaying.add_argument("--max-rows", type=int, default=50, help="differences to list (default 50)")
    replaying.add_argument("--pace", type=float, metavar="SPEED", help="first play each scan step by step in "
                           "real time at this speed (1 = as recorded), printing each step's levels")
    replaying.add_argument("--workers", type=int, help="processes (default: number of cores)")
    add_cluster_options(replaying)
    replaying.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
    replaying.set_defaults(handler=cmd_replay)
