"""``texplorer db``: inspect and repair the database (list, show, check, rebuild) and set its settings."""

from __future__ import annotations

import argparse
from pathlib import Path

from scanner.cli.base import EXIT_PROBLEMS, add_db_option, open_db, progress, table_lines
from scanner.storage.database import CATALOG, RECORDINGS, SCANS, recording_leftovers, repair_recordings
from scanner.storage.settings import KEYS, read_settings, write_settings


def cmd_db_list(args: argparse.Namespace) -> int:
    db = open_db(args)
    records = db.records(label=args.label, sample=args.sample, session=args.session, operator=args.operator)
    rows = [(r.scan_id, r.label, r.sample_id, r.session_id, r.operator, r.started, _steps(r.steps))
            for r in records]
    for line in table_lines(("scan", "label", "sample", "session", "operator", "started", "steps"), rows):
        print(line)
    quick = sum(r.partial for r in records)
    print(f"{len(records)} scan(s)" + (f", {quick} of them quick scans holding only some steps" if quick else ""))
    return 0


def _steps(steps: str) -> str:
    """A catalog row's steps: ``all`` for a full scan, ``quick: tool_slide, photos`` for a partial one."""
    return f"quick: {steps.replace(',', ', ')}" if steps else "all"


def cmd_db_show(args: argparse.Namespace) -> int:
    db = open_db(args)
    record = db.record(args.scan_id)
    scan = db.get(args.scan_id, images=False)
    meta = scan.meta
    print(f"scan        {record.scan_id}\nlabel       {meta.label}\nsample      {meta.sample_id} "
          f"(scan {meta.scan_index})\nsession     {meta.session_id}, operator {meta.operator}, "
          f"started {meta.started}")
    print(f"t_amb       {meta.t_amb:g} degC   mass {meta.mass_g:g} g   volume {meta.volume_cm3:g} cm^3   "
          f"atk {meta.atk:g}   cyd {meta.cyd:g}   rigid {int(meta.rigid)}")
    print(f"steps       {_steps(meta.steps)}")
    print(f"file        {record.path}\ncontent     {record.content_hash}")
    print("channels:")
    for name, trace in scan.traces.items():
        shape = "x".join(str(n) for n in trace.data.shape)
        print(f"  {name:<8} {shape:>10}  {trace.fs:>7g} Hz  {trace.duration:6.2f} s  {trace.unit:<5} "
              f"min {trace.data.min():10.4g}  max {trace.data.max():10.4g}")
    missing = scan.missing_channels()
    if missing:
        print(f"missing:    {', '.join(missing)}")
    short = scan.short_channels()
    if short:
        print("too short:  " + ", ".join(f"{name} ({scan[name].n} of the {need} samples its features need; "
                                         "they are NaN)" for name, need in short.items()))
    for entry in db.files(args.scan_id):
        print(f"  {entry.role:<8} {entry.path}  {entry.size} bytes  sha256 {entry.sha256[:16]}...")
    return 0


def cmd_db_check(args: argparse.Namespace) -> int:
    root = Path(args.db)
    if (root / RECORDINGS).is_dir() and not (root / CATALOG).is_file() and not (root / SCANS).is_dir():
        return _check_recordings_only(root, args.repair)
    db = open_db(args)
    if args.repair:
        for path in db.repair():
            print(f"removed  {path}")
    report = db.check(progress=progress("checking", unit="file"))
    for label, paths in (("missing", report.missing), ("changed", report.changed), ("unknown", report.unknown),
                         ("leftover", report.leftovers)):
        for path in paths:
            print(f"{label:<8} {path}")
    print(f"{report.checked} file(s) checked: {len(report.missing)} missing, {len(report.changed)} changed, "
          f"{len(report.unknown)} unknown" + (f"; {len(report.leftovers)} crash leftover(s), which "
                                              "'texplorer db check --repair' removes" if report.leftovers else ""))
    return 0 if report.ok else EXIT_PROBLEMS


def _check_recordings_only(root: Path, repair: bool) -> int:
    """``db check`` of a folder that holds recording sets and no scans: the leftovers of killed ingests and
    trainings, removed with ``--repair``."""
    if repair:
        for line in repair_recordings(root):
            print(f"removed  {line}")
    leftovers = recording_leftovers(root)
    for path in leftovers:
        print(f"leftover {path}")
    sets = sorted(p.name for p in (root / RECORDINGS).iterdir() if p.is_dir() and not p.name.startswith("."))
    print(f"{root}: recording sets only ({len(sets)}: {', '.join(sets[:5]) or 'none'}), no scans to check"
          + (f"; {len(leftovers)} crash leftover(s), which 'texplorer db check --repair' removes" if leftovers
             else ""))
    return 0  # leftovers are not damage (as for a scan database): listed, and removed with --repair


def cmd_db_rebuild(args: argparse.Namespace) -> int:
    db = open_db(args)
    report = db.rebuild(progress=progress("rebuilding"))
    for path in report.removed:
        print(f"removed  {path} (crash leftover)")
    for line in report.skipped:
        print(f"skipped  {line}")
    print(f"catalog rebuilt: {report.scans} scan(s), {len(report.skipped)} file(s) skipped"
          + (f" and moved with their photos to {report.quarantine}" if report.quarantine else ""))
    return EXIT_PROBLEMS if report.skipped else 0


def cmd_db_settings(args: argparse.Namespace) -> int:
    root = Path(args.db)
    if not (root / CATALOG).is_file() and not (root / RECORDINGS).is_dir():
        open_db(args)  # its one-line error: no database here
    changes = {key: value for key, value in (("license", args.license), ("creator", args.creator))
               if value is not None}
    changes.update(dict.fromkeys(args.unset or (), None))
    settings = write_settings(root, **changes) if changes else read_settings(root)
    for key in KEYS:
        print(f"{key:<8} {settings.get(key, '(not set)')}")
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    db = commands.add_parser("db", help="inspect and repair the database", description="Inspect and repair the "
                             "scan database (catalog.sqlite + .mat files).")
    db_commands = db.add_subparsers(dest="db_command", metavar="ACTION", required=True)
    listing = db_commands.add_parser("list", help="list scans, optionally filtered")
    add_db_option(listing)
    listing.add_argument("--label", help="label, class prefix (C6 = every stone) or part of a material name (granite)")
    listing.add_argument("--sample", help="sample id")
    listing.add_argument("--session", help="session id")
    listing.add_argument("--operator", help="operator")
    listing.set_defaults(handler=cmd_db_list)
    show = db_commands.add_parser("show", help="show one scan's metadata, channels and files")
    add_db_option(show)
    show.add_argument("scan_id")
    show.set_defaults(handler=cmd_db_show)
    check = db_commands.add_parser("check", help="verify the SHA-256 of every file; report missing, changed, "
                                   "unknown files (exit 3 if any) and crash leftovers")
    add_db_option(check)
    check.add_argument("--repair", action="store_true", help="first remove crash leftovers (temp files, files of "
                       "writes that never committed, photos without their .mat, staging of a killed import)")
    check.set_defaults(handler=cmd_db_check)
    rebuild = db_commands.add_parser("rebuild", help="recreate the catalog from the .mat files alone; files "
                                     "that cannot be catalogued go to <db>/quarantine/ (exit 3)")
    add_db_option(rebuild)
    rebuild.set_defaults(handler=cmd_db_rebuild)
    settings = db_commands.add_parser("settings", help="show or set the database's export license and creator",
                                      description="Show the database's settings, or set them: the license and "
                                      "creator that 'texplorer export' and the web application's export write "
                                      "into a bundle's metadata when not given (kept in <db>/settings.json).")
    add_db_option(settings)
    settings.add_argument("--license", help="SPDX identifier (CC-BY-4.0, CC0-1.0), a license URL, or none")
    settings.add_argument("--creator", help="a person's or lab's name, or an ORCID URL")
    settings.add_argument("--unset", action="append", choices=KEYS, help="remove a setting (repeatable)")
    settings.set_defaults(handler=cmd_db_settings)

