"""The ``texplorer`` command line (SPEC section 2).

Every subcommand that uses a database takes ``--db PATH`` (default ``$TEXPLORER_DB``, else
``./texplorer-data``). Errors are one line on stderr and a non-zero exit; ``--debug`` shows the traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import textwrap
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path

from tqdm import tqdm

from features import REGISTRY
from scanner.database import Database, DatabaseError, is_database
from scanner.devices.protocols import DeviceError
from scanner.photo import max_pixels
from scanner.scan import IMAGES, JUDGED_SCALE
from scanner.version import __version__
from scanner.workflows import export_database, extract_database, format_predictions, predict_scan
from taxonomy.errors import TexplorerError

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


def progress(description: str) -> Callable[[Iterable], Iterable]:
    """A tqdm progress bar on stderr (hidden when stderr is not a terminal)."""
    return lambda items: tqdm(items, desc=description, unit="scan", file=sys.stderr, disable=None,
                              leave=False)


def _open_db(args: argparse.Namespace, *, create: bool = False) -> Database:
    return Database(args.db, create=create)


@contextlib.contextmanager
def _cluster(args: argparse.Namespace) -> Iterator:
    """The Dask client of ``--scheduler``, else of Dask's configuration (``DASK_SCHEDULER_ADDRESS``), or
    None for processes on this machine; an explicit ``--workers`` means processes on this machine."""
    from features.cluster import ClusterError, connect, describe

    workers = getattr(args, "workers", None)
    if args.scheduler and workers:
        raise ClusterError("--workers sets processes on this machine, --scheduler a Dask cluster: give one")
    if workers:
        yield None
        return
    with connect(args.scheduler) as client:
        if client is None:
            yield None
            return
        print(f"dask: {describe(client)}", file=sys.stderr)
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            yield client


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"texplorer: warning: {message}", file=sys.stderr)


# -- db ----------------------------------------------------------------------------------------------

def cmd_db_list(args: argparse.Namespace) -> int:
    db = _open_db(args)
    records = db.records(label=args.label, sample=args.sample, session=args.session, operator=args.operator)
    rows = [(r.scan_id, r.label, r.sample_id, r.session_id, r.operator, r.started) for r in records]
    for line in table_lines(("scan", "label", "sample", "session", "operator", "started"), rows):
        print(line)
    print(f"{len(records)} scan(s)")
    return 0


def table_lines(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Left-aligned columns as wide as their longest entry (the last column is not padded)."""
    widths = [max(len(str(cell)) for cell in column) for column in zip(header, *rows, strict=True)]
    return [" ".join(f"{cell!s:<{width}}" for cell, width in zip(row, widths, strict=True)).rstrip()
            for row in (header, *rows)]


def cmd_db_show(args: argparse.Namespace) -> int:
    db = _open_db(args)
    record = db.record(args.scan_id)
    scan = db.get(args.scan_id, images=False)
    meta = scan.meta
    print(f"scan        {record.scan_id}\nlabel       {meta.label}\nsample      {meta.sample_id} "
          f"(scan {meta.scan_index})\nsession     {meta.session_id}, operator {meta.operator}, "
          f"started {meta.started}")
    print(f"t_amb       {meta.t_amb:g} degC   mass {meta.mass_g:g} g   volume {meta.volume_cm3:g} cm^3   "
          f"atk {meta.atk:g}   cyd {meta.cyd:g}   rigid {int(meta.rigid)}")
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
    db = _open_db(args)
    if args.repair:
        for path in db.repair():
            print(f"removed  {path}")
    report = db.check(progress=progress("checking"))
    for label, paths in (("missing", report.missing), ("changed", report.changed), ("unknown", report.unknown),
                         ("leftover", report.leftovers)):
        for path in paths:
            print(f"{label:<8} {path}")
    print(f"{report.checked} file(s) checked: {len(report.missing)} missing, {len(report.changed)} changed, "
          f"{len(report.unknown)} unknown" + (f"; {len(report.leftovers)} crash leftover(s), which "
                                              "'texplorer db check --repair' removes" if report.leftovers else ""))
    return 0 if report.ok else EXIT_PROBLEMS


def cmd_db_rebuild(args: argparse.Namespace) -> int:
    db = _open_db(args)
    report = db.rebuild(progress=progress("rebuilding"))
    for path in report.removed:
        print(f"removed  {path} (crash leftover)")
    for line in report.skipped:
        print(f"skipped  {line}")
    print(f"catalog rebuilt: {report.scans} scan(s), {len(report.skipped)} file(s) skipped"
          + (f" and moved with their photos to {report.quarantine}" if report.quarantine else ""))
    return EXIT_PROBLEMS if report.skipped else 0


# -- features ----------------------------------------------------------------------------------------

def _report_space(space, seconds: float) -> None:
    import numpy as np

    nan_columns = int(np.isnan(space.X).any(axis=0).sum()) if len(space) else 0
    print(f"{len(space)} scans x {len(space.columns)} features in {seconds:.1f} s "
          f"({nan_columns} column(s) with NaN, {len(space.failed)} scan(s) failed)")
    for scan_id, reason in space.failed:
        print(f"failed   {scan_id}: {reason}")


def cmd_features(args: argparse.Namespace) -> int:
    if args.dataset:
        return cmd_set_features(args)
    db = _open_db(args)
    started = time.perf_counter()
    with _cluster(args) as client:
        space = extract_database(db, label=args.label, workers=args.workers, client=client, ship_data=args.ship_data)
    _report_space(space, time.perf_counter() - started)
    out = args.out or db.root / "features.csv"
    space.to_csv(out)
    print(f"wrote {out}")
    if args.mat:
        space.to_mat(args.mat)
        print(f"wrote {args.mat}")
    return EXIT_ERROR if space.failed else 0


# -- export, import, replay --------------------------------------------------------------------------

EXIT_MISMATCH = 4
"""``replay --expect`` found feature values outside the tolerance, or missing scans or features."""


def cmd_export(args: argparse.Namespace) -> int:
    report = export_database(_open_db(args), args.out, label=args.label, session=args.session,
                             workers=args.workers, progress=progress("exporting"))
    for scan_id, reason in report.feature_failures:
        print(f"texplorer: warning: no feature row for {scan_id}: {reason}", file=sys.stderr)
    print(f"exported {report.scans} scan(s), {report.files} files, {report.bytes / 1e6:.1f} MB "
          f"to {report.path} in {report.seconds:.1f} s")
    return 0


def cmd_import(args: argparse.Namespace) -> int:
    from scanner.bundle import BundleError, import_bundle

    db = _open_db(args, create=True)
    try:
        report = import_bundle(db, args.bundle, progress=progress("verifying"))
    except BundleError as exc:
        for problem in exc.problems:
            print(f"problem  {problem}", file=sys.stderr)
        raise
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
    import numpy as np

    from taxonomy.labels import Label

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
    import numpy as np

    from scanner.matfile import load_scan
    from scanner.replay import paced_steps

    for path in paths:
        scan = load_scan(path)
        print(f"playing {scan.scan_id} at {speed:g}x")
        for step, arrays in paced_steps(scan, speed):
            levels = ", ".join(f"{name} {np.sqrt(np.mean(np.square(a, dtype=np.float64))):.3g}"
                               for name, a in arrays.items())
            print(f"  {step:<13} rms {levels}", flush=True)


def cmd_replay(args: argparse.Namespace) -> int:
    from features import SOLVER_RTOL, FeatureSpace
    from scanner.replay import (
        ReplayError,
        check_unique,
        compare,
        format_comparison,
        predictions,
        replay,
        scan_paths,
    )

    paths = scan_paths(args.paths)
    if args.pace:
        _play(paths, args.pace)
    model = None
    if args.model:
        from taxonomy.models import load_model

        model = load_model(args.model)
    expected = FeatureSpace.from_csv(args.expect) if args.expect else None
    started = time.perf_counter()
    with _cluster(args) as client:
        space = replay(paths, workers=args.workers, client=client, ship_data=args.ship_data)
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


# -- scan, emulate -----------------------------------------------------------------------------------

ABORT = "a"


class _Aborted(TexplorerError):
    """The operator chose to abort the scan (or the input ended)."""


def _ask(prompt: str) -> str:
    """One answer from the operator; 'a' or the end of the input aborts."""
    try:
        answer = input(prompt).strip()
    except EOFError:
        print()
        raise _Aborted("input ended") from None
    if answer.lower() == ABORT:
        raise _Aborted("aborted by the operator")
    return answer


def _ask_value(session, prompt: str, name: str, convert: Callable[[str], object] = float,
               optional: bool = False) -> None:
    """Ask until the session accepts the value of ``name`` (its error is shown before asking again)."""
    from scanner.session import SessionError

    while True:
        answer = _ask(prompt)
        if not answer and optional:
            return
        try:
            session.set_values(**{name: convert(answer)})
            return
        except (SessionError, ValueError) as exc:
            print(f"  {exc}")


def _meter(reading) -> None:
    """The live level on stderr (only on a terminal): bar, signal value, elapsed time."""
    if not sys.stderr.isatty():
        return
    bar = "#" * int(round(20 * reading.fraction))
    print(f"\r  {reading.phase:<9} [{bar:<20}] {reading.signal} {reading.value:8.3f} {reading.unit:<4} "
          f"{reading.elapsed_s:5.1f}/{reading.duration_s:g} s", end="", file=sys.stderr, flush=True)


def _record_step(session, step) -> None:
    """Record (or skip) one step until the operator keeps it."""
    from scanner.session import StepState

    while True:
        options = "[Enter] record" + (", s skip (rigid sample)" if step.skippable else "") + ", a abort: "
        if _ask(f"  {options}").lower() == "s" and step.skippable:
            session.skip(step.id)
            print("  skipped: the sample is recorded as rigid")
            return
        status = session.record(step.id, level=_meter)
        if sys.stderr.isatty():
            print(file=sys.stderr)
        if status.state is StepState.FAILED:
            print(f"  failed: {status.error}")
            session.redo(step.id)
            continue
        for problem in status.problems:
            print(f"  quality: {problem}")
        verdict = "check the problems above" if status.problems else "quality ok"
        if _ask(f"  {verdict}. [Enter] keep, r redo, a abort: ").lower() != "r":
            return
        session.redo(step.id)


def _take_photos(session) -> None:
    from scanner.session import SessionError

    for name in IMAGES:
        while True:
            answer = _ask(f"  {name}: [Enter] capture with the camera, or a PNG/JPEG file, a abort: ")
            try:
                if answer:
                    session.set_photo(name, Path(answer).expanduser().read_bytes())
                else:
                    session.capture_photo(name)
                break
            except (SessionError, OSError, DeviceError) as exc:
                print(f"  {exc}")


def _tu4(session) -> None:
    from scanner.session import VOLUME_METHODS

    _ask_value(session, "  mass (g): ", "mass_g")
    _ask_value(session, "  volume (cm^3): ", "volume_cm3")
    _ask_value(session, f"  volume measured by ({'/'.join(VOLUME_METHODS)}): ", "volume_method", str)
    scale = "/".join(f"{v:g}" for v in JUDGED_SCALE)
    _ask_value(session, f"  adhesive tack ({scale}): ", "atk")
    _ask_value(session, f"  yielding ({scale}): ", "cyd")
    _ask_value(session, "  notes (optional): ", "notes", str, optional=True)


def _guide(session, args: argparse.Namespace) -> str | None:
    """Walk the operator through every step; the saved scan id, or None if not saved."""
    answer = _ask(f"ambient temperature {session.t_amb:.2f} degC: [Enter] keep, or type degC: ")
    while answer:
        try:
            session.t_amb = float(answer)
            break
        except ValueError as exc:
            answer = _ask(f"  {exc}; degC: ")
    total = len(session.steps)
    for index, step in enumerate(session.steps, 1):
        duration = f" ({step.duration_s:g} s)" if step.duration_s else ""
        print(f"\nstep {index}/{total}: {step.title}{duration}")
        print(textwrap.fill(step.instruction, 100, initial_indent="  ", subsequent_indent="  "))
        if step.kind == "record":
            _record_step(session, step)
        elif step.kind == "photos":
            _take_photos(session)
        else:
            _tu4(session)
    if _ask("\nsave the scan? [Y/n] ").lower() in ("n", "no"):
        return None
    while True:
        try:
            return session.save(_open_db(args, create=True))
        except (DatabaseError, OSError) as exc:
            # The recording is still in the session: let the operator fix the disk or path and retry.
            _ask(f"  not saved: {exc}\n  [Enter] retry, a abort: ")


def cmd_scan(args: argparse.Namespace) -> int:
    from scanner.config import load_config
    from scanner.session import Session

    config = load_config(args.config)
    model = None
    if args.model:
        from taxonomy.models import load_model

        model = load_model(args.model)
    if args.daq:
        config = config.with_daq_server(args.daq)
    if args.board:
        config = config.with_board_port(args.board)
    # An aborted scan leaves no trace: an existing database is only read, a new one is made when saving.
    db = _open_db(args) if is_database(args.db) else None
    session = Session.open(config, label=args.label, sample_id=args.sample, operator=args.operator, db=db)
    try:
        print(f"scan of {session.label}, sample {session.sample_id}, operator {session.operator} "
              f"(session {session.session_id}); 'a' aborts at any prompt")
        for name, description in session.devices.describe().items():
            print(f"  {name:<13} {description}")
        for warning in session.warnings:
            print(f"texplorer: warning: {warning}", file=sys.stderr)
        scan_id = _guide(session, args)
    except _Aborted as reason:
        print(f"scan aborted ({reason}): nothing was saved")
        return EXIT_ERROR
    finally:
        session.abort()
    if scan_id is None:
        print("not saved")
        return EXIT_ERROR
    print(f"saved {scan_id} in {args.db}")
    if model is not None:
        db = _open_db(args)
        print(format_predictions(predict_scan(model, db.get(scan_id), 3, db.taxonomy())))
    return 0


def cmd_emulate_board(args: argparse.Namespace) -> int:
    try:
        from scanner.emulators.board import BoardEmulator, FaultPlan
    except ImportError as exc:
        raise OSError(f"the board emulator needs pseudo-terminals (Linux, macOS): {exc}") from None
    from scanner.devices.sources import SimulatedSample

    faults = FaultPlan(args.bad_checksum_every, args.garbage_every, args.gap_every)
    sample = SimulatedSample(args.material, seed=args.seed)
    try:
        with BoardEmulator(sample, link=args.link, faults=faults) as emulator:
            print(f"serial sensor board emulator: {sample.describe()}; Ctrl-C stops it", file=sys.stderr)
            print(emulator.path, flush=True)
            _serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


def cmd_emulate_daq(args: argparse.Namespace) -> int:
    from scanner.devices.sources import SimulatedSample
    from scanner.emulators.daq_grpc import DaqEmulator, DaqServicer

    sample = SimulatedSample(args.material, seed=args.seed)
    try:
        with DaqEmulator(DaqServicer(sample), host=args.host, port=args.port) as emulator:
            print(f"NI-DAQmx gRPC emulator: {sample.describe()}; Ctrl-C stops it", file=sys.stderr)
            print(f"grpc://{emulator.address}", flush=True)
            _serve_forever()
    except KeyboardInterrupt:
        pass
    return 0


def _serve_forever() -> None:
    """The emulators work in their own threads; this one waits for Ctrl-C."""
    while True:
        time.sleep(3600)


# -- serve -------------------------------------------------------------------------------------------

def cmd_serve(args: argparse.Namespace) -> int:
    from gui.app import Settings, serve
    from scanner.config import load_config

    config = load_config(args.config)
    if not args.upload_limit_mb > 0:
        raise UsageError(f"--upload-limit-mb must be positive, got {args.upload_limit_mb:g}")
    limit = int(args.upload_limit_mb * 1024 * 1024)
    settings = Settings(db=args.db, model=args.model, device_config=config, upload_limit=limit,
                        max_photo_pixels=max_pixels())
    serve(settings, args.host, args.port)
    return 0


# -- ingest, compare ---------------------------------------------------------------------------------

def ingest_mapping(args: argparse.Namespace):
    """The mapping file's mapping, or for a plain folder the default one (WAV as audio, images as photo,
    labels from folders); ``--grid`` cuts every image into patches."""
    from scanner.ingest import default_mapping, load_mapping, parse_grid, safe_name, with_grid

    if args.mapping is None:
        mapping = default_mapping(args.name or safe_name(args.path.resolve().name))
    else:
        mapping = load_mapping(args.mapping)
    return with_grid(mapping, parse_grid(args.grid, "--grid")) if args.grid else mapping


def cmd_ingest(args: argparse.Namespace) -> int:
    from scanner.ingest import IngestError, ingest, store_recordings, summarise_notes

    mapping = ingest_mapping(args)
    report = ingest(args.path, mapping, progress=progress("reading"))
    for line in report.skipped:
        print(f"skipped  {line}")
    notes = [str(note) for note in report.notes] if args.verbose else summarise_notes(report.notes)
    for note in notes:
        print(f"note     {note}")
    if report.notes and not args.verbose:
        print(f"note     {len(report.notes)} note(s) in all; --verbose lists every one")
    if not report.recordings:
        raise IngestError(f"{args.path}: no recording could be imported from {report.files} matching file(s)")
    folder = store_recordings(args.db, args.name or mapping.name, report.recordings, replace=args.replace)
    roles = sorted({role for r in report.recordings for role in r.roles})
    splits = [r.meta.get("split") for r in report.recordings]
    split = (f"; split {splits.count('train')} train / {splits.count('test')} test" if any(splits) else "")
    print(f"{len(report.recordings)} recording(s) from {report.files} file(s) -> {folder}; roles "
          f"{', '.join(roles) or 'none'}{split}; {len(report.skipped)} problem line(s)")
    return EXIT_PROBLEMS if report.skipped else 0


COMPARE_METHODS = ("fishel", "xie", "huang", "chathuranga", "hoelscher")
"""``taxonomy.methods.METHODS``, named here so the parser does not import scikit-learn."""
COMPARE_REPEATS = 10

DATASET_HELP = ("sim:biotac, sim:array or sim:soft3axis (simulated sensors), set:NAME (recordings imported "
                "into --db with 'texplorer ingest'), scans (the scans of --db), or a folder: a database or "
                "a recording set")


def comparison_dataset(spec: str, db: Path, seed: int):
    """The dataset a ``compare`` argument names (see :data:`DATASET_HELP`)."""
    from scanner.ingest import load_recordings, set_folder
    from scanner.simulation.recordings import simulate_recordings
    from taxonomy.methods import Dataset

    if spec.startswith("sim:"):
        return Dataset.from_recordings(spec, simulate_recordings(spec[4:], seed))
    if spec.startswith("set:"):
        return Dataset.from_recordings(spec, load_recordings(set_folder(db, spec[4:])))
    folder = db if spec == "scans" else Path(spec)
    if spec == "scans" or (folder / "catalog.sqlite").is_file():
        database = Database(folder, create=False)
        scans = list(progress("loading")(database.scans(images=False)))
        if not scans:
            raise DatabaseError(f"{folder}: the database holds no scans")
        return Dataset.from_scans(str(folder), scans)
    if folder.is_dir():
        return Dataset.from_recordings(str(folder), load_recordings(folder))
    raise UsageError(f"dataset {spec!r} is none of: {DATASET_HELP}")


def cmd_compare(args: argparse.Namespace) -> int:
    from taxonomy.methods import MethodError, compare_methods, format_comparison
    from taxonomy.report import write_comparison

    started = time.perf_counter()
    dataset = comparison_dataset(args.dataset, args.db, args.seed)
    print(dataset.summary())
    with _cluster(args) as client:
        comparison = compare_methods(dataset, args.methods, seed=args.seed, repeats=args.repeats,
                                     progress=progress("comparing"), client=client)
    print(comparison.format_outcome())
    results = comparison.results
    if not results:
        own = (f"; the project's own features: texplorer evaluate {args.dataset}"
               if args.dataset.startswith("set:") else "")
        raise MethodError(f"no method could run on {args.dataset} (see above){own}")
    print(format_comparison(results))
    slug = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in args.dataset).strip("-") or "dataset"
    folder = args.report or (args.db / "reports" if args.db.is_dir() else Path(".")) / f"compare-{slug}"
    print(f"{len(results)} result(s) in {time.perf_counter() - started:.1f} s; report: "
          f"{write_comparison(folder, results, dataset.summary(), comparison.outcome)}")
    return 0


# -- selection, evaluation, models -------------------------------------------------------------------

ALL = "all"


def _space_for(args: argparse.Namespace, client=None):
    """The feature space of ``--features CSV`` if given, else of the database (from its feature cache)."""
    from features import FeatureSpace

    if args.features:
        return FeatureSpace.from_csv(args.features)
    space = extract_database(_open_db(args), workers=args.workers, client=client, ship_data=args.ship_data)
    for scan_id, reason in space.failed:
        print(f"texplorer: warning: {scan_id} left out: {reason}", file=sys.stderr)
    return space


def _choices(values: list[str], every: Sequence[str]) -> list[str]:
    return list(every) if ALL in values else values


def cmd_select(args: argparse.Namespace) -> int:
    from features.selection import select_features

    with _cluster(args) as client:
        space = _space_for(args, client)
    print(select_features(space, args.level, args.n, args.max_corr).format(args.top))
    return 0


def one_line(message: str) -> str:
    """A warning's text on one line, whole: its lines joined, runs of white space made one space."""
    return " ".join(str(message).split())


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


def run_evaluation(space, args: argparse.Namespace, client=None) -> list:
    """Evaluate the grid asked for on the command line (on the Dask cluster of ``client`` if given);
    print the table; write the HTML report if asked."""
    from taxonomy.evaluation import CLASSIFIERS, default_feature_sets, evaluate_grid
    from taxonomy.report import format_table, write_report

    classifiers = _choices(args.classifier, list(CLASSIFIERS))
    levels = _choices(args.level, space.level_names)
    sets = None if ALL in args.feature_set else {name: default_feature_sets()[name] for name in args.feature_set}
    use_split = not getattr(args, "ignore_split", False)
    sizes = set_sizes(args.n, ("3", "10", ALL) if space.label_level is not None else ("3", "10"))
    started = time.perf_counter()
    reports = evaluate_grid(space, classifiers, levels, sizes, sets, folds=args.folds, seed=args.seed,
                            protocol=args.protocol, workers=args.workers, progress=True, use_split=use_split,
                            client=client)
    print(format_table(reports))
    splitting = reports[0].splitting if reports else f"{args.folds} folds"
    print(f"{len(reports)} evaluations ({args.protocol} protocol, {splitting}) "
          f"in {time.perf_counter() - started:.1f} s")
    for warning in sorted({w for report in reports for w in report.warnings if w.strip()}):
        print(f"texplorer: warning: {warning}", file=sys.stderr)
    if args.report:
        print(f"report: {write_report(args.report, space, reports)}")
    return reports


def cmd_evaluate(args: argparse.Namespace) -> int:
    if args.dataset:
        return cmd_set_evaluate(args)
    with _cluster(args) as client:
        run_evaluation(_space_for(args, client), args, client)
    return 0


# -- recording sets: the project's own features and evaluation ---------------------------------------

def set_recordings(spec: str, db: Path) -> tuple[str, list]:
    """The set name and recordings a ``set:NAME`` argument names."""
    from scanner.ingest import load_recordings, set_folder

    if not spec.startswith("set:"):
        raise UsageError(f"{spec!r} is not a recording set; name one as set:NAME (see 'texplorer ingest')")
    return spec[4:], load_recordings(set_folder(db, spec[4:]))


def set_space(args: argparse.Namespace, client=None):
    """The feature space of ``set:NAME`` with the windowing, crop and grouping asked for (on the Dask cluster
    of ``client`` if given); prints a summary line and the extraction warnings (a count, all with
    --verbose)."""
    from features.recordings import Windowing, describe_families, feature_space

    name, recordings = set_recordings(args.dataset, args.db)
    windowing = Windowing(args.window, args.combine)
    started = time.perf_counter()
    space, notes = feature_space(recordings, windowing, args.border, args.group_by, workers=args.workers,
                                 progress=True, client=client)
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


def cmd_set_features(args: argparse.Namespace) -> int:
    from scanner.ingest import set_folder

    with _cluster(args) as client:
        space = set_space(args, client)
    out = args.out or set_folder(args.db, args.dataset[4:]) / "features.csv"
    print(f"wrote {space.to_csv(out)}")
    if args.mat:
        print(f"wrote {space.to_mat(args.mat)}")
    return 0


def cmd_set_evaluate(args: argparse.Namespace) -> int:
    if args.features:
        raise UsageError("give either a set (set:NAME) or --features CSV, not both")
    with _cluster(args) as client:
        space = set_space(args, client)
        reports = run_evaluation(space, args, client)
    return 0 if reports else EXIT_ERROR


def _add_set_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("dataset", nargs="?", metavar="set:NAME", help="a recording set imported with "
                        "'texplorer ingest' (default: the scans of the database)")
    parser.add_argument("--window", type=float, metavar="SECONDS", help="sets: cut each recording into "
                        "windows of this length (default: the whole recording)")
    parser.add_argument("--combine", choices=("mean", "median", "rows"), default="mean", help="sets: combine "
                        "the windows' features by their mean (default) or median, or make each window a row "
                        "(in its recording's group)")
    parser.add_argument("--border", type=int, default=0, metavar="PX", help="sets: pixels cropped from every "
                        "side of a photo before its features (default 0; the scanner's photos use 100)")
    parser.add_argument("--group-by", default="auto", metavar="GROUP", help="sets: the group folds keep "
                        "together: a group of the mapping's pattern, 'none', or auto (default: object, else "
                        "the photo a patch was cut from, else the recording)")
    parser.add_argument("--verbose", action="store_true", help="sets: print every extraction warning")


def cmd_train(args: argparse.Namespace) -> int:
    from taxonomy.models import save_model, train_model

    with _cluster(args) as client:
        space = _space_for(args, client)
    model = train_model(space, args.level, args.n, args.classifier, args.seed)
    save_model(model, args.out)
    print(model.describe())
    print(f"wrote {args.out}")
    return 0


def cmd_classify(args: argparse.Namespace) -> int:
    from scanner.matfile import load_scan
    from taxonomy.models import load_model
    from taxonomy.table import load_taxonomy

    model = load_model(args.model)
    scan = load_scan(args.scan)
    print(f"{scan.scan_id} ({scan.meta.label} recorded) with {model.describe()}")
    print(format_predictions(predict_scan(model, scan, args.k, load_taxonomy())))
    return 0


# -- demo --------------------------------------------------------------------------------------------

DEMO_SAMPLES = 2
DEMO_SCANS = 3

def cmd_demo(args: argparse.Namespace) -> int:
    from scanner.simulation.database import synthetic_database

    started = time.perf_counter()
    db = synthetic_database(args.db, materials=args.materials, scans_per_material=args.scans, seed=args.seed,
                            image_size=(args.image_size, args.image_size), progress=True,
                            samples_per_material=args.samples)
    summary = db.summary()
    print(f"database {args.db}: {summary['scans']} scans of {summary['materials']} materials "
          f"({summary['samples']} samples, {summary['files']} files) in {time.perf_counter() - started:.1f} s")
    by_class: dict[str, int] = {}
    for record in db.records():
        by_class[record.label[:2]] = by_class.get(record.label[:2], 0) + 1
    print("scans per major class: " + ", ".join(f"{c} {n}" for c, n in sorted(by_class.items())))
    with _cluster(args) as client:
        started = time.perf_counter()
        space = extract_database(db, workers=args.workers, client=client, ship_data=args.ship_data)
        _report_space(space, time.perf_counter() - started)
        print(f"wrote {space.to_csv(db.root / 'features.csv')}")
        if args.no_evaluation:
            return 0
        args.report = args.report or db.root / "report"
        run_evaluation(space, args, client)
    from taxonomy.models import save_model, train_model

    model = train_model(space, "fine", 10, "rf", args.seed)
    path = save_model(model, db.root / "models" / "rf-fine-X10.skops")
    print(f"model: {path} ({model.describe()})")
    return 0


# -- parser ------------------------------------------------------------------------------------------

def _add_db_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--db", type=Path, default=default_db(),
                        help="database folder (default: $TEXPLORER_DB, else ./texplorer-data)")
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="show tracebacks on errors")


LEVELS = ("coarse", "medium", "fine")
CLASSIFIER_NAMES = ("svm", "lda", "knn", "mlp", "rf", "nb")


def _add_cluster_options(parser: argparse.ArgumentParser, ship: bool = True) -> None:
    parser.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster: tcp://HOST:PORT of its "
                        "scheduler, or local:N for N worker processes here with Dask's dashboard (default: "
                        "Dask's scheduler-address, e.g. $DASK_SCHEDULER_ADDRESS, else processes on this machine)")
    if ship:
        parser.add_argument("--ship-data", action="store_true", help="send each scan's files from this machine "
                            "to the Dask workers (automatic for workers that do not see them at the same path)")


def _add_space_options(parser: argparse.ArgumentParser) -> None:
    _add_db_option(parser)
    parser.add_argument("--features", type=Path, help="feature table CSV (default: extract from the database, "
                        "using its feature cache)")
    parser.add_argument("--workers", type=int, help="processes (default: number of cores)")
    _add_cluster_options(parser)


def _add_evaluation_options(parser: argparse.ArgumentParser, report_default: str | None, seed: bool = True) -> None:
    parser.add_argument("--classifier", nargs="+", choices=(*CLASSIFIER_NAMES, ALL), default=[ALL],
                        help="classifiers (default all)")
    parser.add_argument("--level", nargs="+", default=[ALL], help="levels: coarse, medium, fine, or a set's "
                        "own levels (default all)")
    parser.add_argument("--n", nargs="+", metavar="N", help="selected set sizes, and 'all' for every feature "
                        "without selection (default 3 10; for a set 3 10 all)")
    parser.add_argument("--feature-set", nargs="+", choices=(*REGISTRY.modalities, ALL), default=[ALL],
                        help=f"feature sets: one modality each, or all = every modality and all "
                        f"{len(REGISTRY.names)} (default)")
    parser.add_argument("--protocol", choices=("nested", "paper"), default="nested",
                        help="nested (default): scaling and selection inside the folds; paper: on all data first")
    parser.add_argument("--folds", type=int, default=5, help="cross-validation folds (default 5)")
    if seed:
        parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    default = f" (default {report_default})" if report_default else ""
    parser.add_argument("--report", type=Path, default=None, help=f"write the HTML report into this folder{default}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="texplorer", description="Multimodal material scanner: acquisition, "
                                     "database, features and classification.")
    parser.add_argument("--version", action="version", version=f"texplorer {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    count = len(REGISTRY.names)
    demo = commands.add_parser("demo", help="build a synthetic database from the simulated scanner and summarise it",
                               description=f"Simulated scanner -> database -> {count} features -> "
                               "cross-validated evaluation (table + HTML report) -> a trained random forest.")
    _add_db_option(demo)
    demo.add_argument("--materials", nargs="+", metavar="SLUG", help="material slugs (default: whole library)")
    demo.add_argument("--samples", type=int, default=DEMO_SAMPLES, help="samples (pieces) per material "
                      f"(default {DEMO_SAMPLES}: two or more let cross-validation keep each piece in one fold)")
    demo.add_argument("--scans", type=int, default=DEMO_SCANS, help=f"scans per sample (default {DEMO_SCANS})")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    demo.add_argument("--image-size", type=int, default=512, help="photo size in pixels (default 512)")
    demo.add_argument("--workers", type=int, help="processes for simulation, features and evaluation "
                      "(default: number of cores)")
    demo.add_argument("--no-evaluation", action="store_true", help="stop after the feature table")
    _add_cluster_options(demo)
    _add_evaluation_options(demo, report_default="<db>/report", seed=False)
    demo.set_defaults(handler=cmd_demo)

    features = commands.add_parser("features", help=f"extract the {count} features of every scan into a feature table",
                                   description=f"Extract the {count} features of every scan (cached in the database "
                                   "by scan content and feature-code version) and write features.csv.")
    _add_db_option(features)
    _add_set_options(features)
    features.add_argument("--workers", type=int, help="processes (default: number of cores)")
    features.add_argument("--out", type=Path, help="CSV file (default: <db>/features.csv; for a set "
                          "<db>/recordings/<set>/features.csv)")
    features.add_argument("--mat", type=Path, help="also write the feature space as a .mat file")
    features.add_argument("--label", help="only scans with this label or class prefix")
    _add_cluster_options(features)
    features.set_defaults(handler=cmd_features)

    select = commands.add_parser("select", help="print the FQ ranking and the selected feature set",
                                 description="Feature quality (Kruskal-Wallis + Tukey-Kramer) ranking and the "
                                 "FQ + Spearman selection on all scans.")
    _add_space_options(select)
    select.add_argument("--level", choices=LEVELS, default="fine", help="classification level (default fine)")
    select.add_argument("--n", type=int, default=10, help="features to select (default 10)")
    select.add_argument("--max-corr", type=float, default=0.5, help="Spearman limit (default 0.5)")
    select.add_argument("--top", type=int, default=20, help="rows of the FQ ranking to print (default 20)")
    select.set_defaults(handler=cmd_select)

    evaluate = commands.add_parser("evaluate", help="cross-validate classifiers x feature sets x levels; "
                                   "table and HTML report", description="Cross-validated accuracy, macro F1 and "
                                   "r_C of classifiers x feature sets x levels x set sizes. For a recording set "
                                   "(set:NAME): its own class names and levels, folds grouped by its groups, or "
                                   "its own train/test split when it has one.")
    _add_space_options(evaluate)
    _add_set_options(evaluate)
    _add_evaluation_options(evaluate, report_default=None)
    evaluate.add_argument("--ignore-split", action="store_true", help="sets: cross-validate over every "
                          "recording even if the set has its own train/test split")
    evaluate.set_defaults(handler=cmd_evaluate)

    train = commands.add_parser("train", help="train a classifier on all scans and save it (skops)",
                                description="Fit scaler -> FQ selector -> classifier on every scan and save "
                                "the model in a format that cannot execute code when loaded.")
    _add_space_options(train)
    train.add_argument("--out", type=Path, required=True, help="model file (.skops)")
    train.add_argument("--level", choices=LEVELS, default="fine", help="classification level (default fine)")
    train.add_argument("--n", type=int, default=10, help="selected features (default 10)")
    train.add_argument("--classifier", choices=CLASSIFIER_NAMES, default="rf", help="classifier (default rf)")
    train.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    train.set_defaults(handler=cmd_train)

    classify = commands.add_parser("classify", help="predict the material of a stored scan (.mat)",
                                   description="Extract the features of SCAN.mat and print the most probable "
                                   "labels with a trained model.")
    classify.add_argument("scan", type=Path, help="scan file (.mat)")
    classify.add_argument("--model", type=Path, required=True, help="model file written by 'texplorer train'")
    classify.add_argument("--k", type=int, default=3, help="how many labels to print (default 3)")
    classify.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
    classify.set_defaults(handler=cmd_classify)

    db = commands.add_parser("db", help="inspect and repair the database", description="Inspect and repair the "
                             "scan database (catalog.sqlite + .mat files).")
    db_commands = db.add_subparsers(dest="db_command", metavar="ACTION", required=True)
    listing = db_commands.add_parser("list", help="list scans, optionally filtered")
    _add_db_option(listing)
    listing.add_argument("--label", help="label or label prefix, e.g. C6 for every stone")
    listing.add_argument("--sample", help="sample id")
    listing.add_argument("--session", help="session id")
    listing.add_argument("--operator", help="operator")
    listing.set_defaults(handler=cmd_db_list)
    show = db_commands.add_parser("show", help="show one scan's metadata, channels and files")
    _add_db_option(show)
    show.add_argument("scan_id")
    show.set_defaults(handler=cmd_db_show)
    check = db_commands.add_parser("check", help="verify the SHA-256 of every file; report missing, changed, "
                                   "unknown files (exit 3 if any) and crash leftovers")
    _add_db_option(check)
    check.add_argument("--repair", action="store_true", help="first remove crash leftovers (temp files, files of "
                       "writes that never committed, photos without their .mat, staging of a killed import)")
    check.set_defaults(handler=cmd_db_check)
    rebuild = db_commands.add_parser("rebuild", help="recreate the catalog from the .mat files alone; files "
                                     "that cannot be catalogued go to <db>/quarantine/ (exit 3)")
    _add_db_option(rebuild)
    rebuild.set_defaults(handler=cmd_db_rebuild)

    from scanner.replay import DEFAULT_ATOL, DEFAULT_RTOL

    export = commands.add_parser(
        "export", help="write scans, features, taxonomy and a checksummed manifest as a bundle for a lab",
        description="Export scans with their photos, features.csv/.mat, taxonomy.csv, manifest.json (SHA-256 "
        "of every file) and MATLAB/Python loaders, as a folder or a .zip that appears only when complete.")
    _add_db_option(export)
    export.add_argument("out", type=Path, metavar="OUT", help="new bundle folder, or a file ending in .zip")
    export.add_argument("--label", help="only this label or class prefix (C6 = every stone)")
    export.add_argument("--session", help="only this session id")
    export.add_argument("--workers", type=int, help="processes for uncached features (default: cores)")
    export.set_defaults(handler=cmd_export)

    importing = commands.add_parser(
        "import", help="verify a bundle completely, then merge its scans into the database",
        description="Verify every checksum, the manifest and every scan first (a damaged bundle is refused "
        "with its problems and nothing changes), then add the new scans in one transaction. Identical scans "
        "are skipped; a scan id or sample stored with other content or label is a conflict and is never "
        "overwritten (exit 3); new material codes go to <db>/taxonomy.csv.")
    _add_db_option(importing)
    importing.add_argument("bundle", type=Path, metavar="BUNDLE", help="folder or .zip of 'texplorer export'")
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
    _add_cluster_options(replaying)
    replaying.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks")
    replaying.set_defaults(handler=cmd_replay)
    scanning = commands.add_parser(
        "scan", help="guided scanning session in the terminal (simulated devices unless configured)",
        description="Guide the operator through the steps of a scan (Strese et al. 2020, section III) with live "
        "levels, quality checks and redo, then save it. Devices come from --config (default: the simulated scanner).")
    _add_db_option(scanning)
    scanning.add_argument("--label", required=True, help="material label, e.g. C6S1M1P2X1")
    scanning.add_argument("--sample", required=True, help="sample id, e.g. granite-01")
    scanning.add_argument("--operator", required=True, help="operator name or initials")
    scanning.add_argument("--config", type=Path, help="device configuration TOML "
                          "(see docs/texplorer.example.toml)")
    scanning.add_argument("--daq", metavar="grpc://HOST:PORT", help="read the real DAQ through this NI gRPC "
                          "Device Server")
    scanning.add_argument("--board", metavar="PORT", help="use the real sensor board on this serial port "
                          "(COM3, /dev/ttyACM0)")
    scanning.add_argument("--model", type=Path, help="after saving, print the prediction of this model")
    scanning.set_defaults(handler=cmd_scan)

    emulate = commands.add_parser("emulate", help="run a device emulator to try the app without hardware",
                                  description="Emulated hardware playing a simulated material sample.")
    emulators = emulate.add_subparsers(dest="emulator", metavar="DEVICE", required=True)
    emulate_board = emulators.add_parser(
        "board", help="serial sensor board on a pseudo-terminal; prints its device path",
        description="The serial sensor board (its line protocol is described in scanner/devices/board.py) "
        "on a pseudo-terminal, until Ctrl-C. Use the "
        "printed path as board.port or with 'texplorer scan --board PATH'. POSIX only.")
    emulate_board.add_argument("--link", type=Path, help="path of the port's symbolic link "
                               "(default: in a new temporary folder)")
    emulate_board.add_argument("--bad-checksum-every", type=int, default=0, metavar="N",
                               help="corrupt the checksum of every N-th data line")
    emulate_board.add_argument("--garbage-every", type=int, default=0, metavar="N",
                               help="send garbage bytes before every N-th data line")
    emulate_board.add_argument("--gap-every", type=int, default=0, metavar="N",
                               help="leave out every N-th data line (a counter gap)")
    emulate_board.set_defaults(handler=cmd_emulate_board)
    emulate_daq = emulators.add_parser(
        "daq", help="NI-DAQmx gRPC server; prints its grpc:// address",
        description="An NI gRPC Device Server with an emulated USB-6002 (Dev1), until Ctrl-C. Use the "
        "printed address with 'texplorer scan --daq ADDRESS'.")
    emulate_daq.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1)")
    emulate_daq.add_argument("--port", type=int, default=0, help="port (default: any free port)")
    emulate_daq.set_defaults(handler=cmd_emulate_daq)
    for emulator in (emulate_board, emulate_daq):
        emulator.add_argument("--material", default="granite-polished", help="simulated material slug "
                              "(default granite-polished)")
        emulator.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
        emulator.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                              help="show tracebacks")

    serving = commands.add_parser(
        "serve", help="the operator's web application: guided scans, operator form, database browser",
        description="Serve the operator's web application for the database: start a scan, the guided steps "
        "with live levels, the operator form with photo uploads, the summary with the prediction, and the "
        "database browser with export. Listens on 127.0.0.1 only, unless --host says otherwise.")
    _add_db_option(serving)
    serving.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1; "
                         "anything else makes the scanner reachable from the network, with a warning)")
    serving.add_argument("--port", type=int, default=8080, help="port (default 8080; 0 = any free port)")
    serving.add_argument("--config", type=Path, help="device configuration TOML (default: the simulated "
                         "scanner; see docs/texplorer.example.toml)")
    serving.add_argument("--model", type=Path, help="model for the prediction on the summary page (default: "
                         "<db>/models/rf-fine-X10.skops if 'texplorer demo' made one)")
    serving.add_argument("--upload-limit-mb", type=float, default=20.0, help="largest photo upload in MB "
                         "(default 20)")
    serving.set_defaults(handler=cmd_serve)

    ingesting = commands.add_parser(
        "ingest", help="import recordings or photos (CSV/TSV, WAV, NPY/NPZ, .mat, PNG/JPG/BMP/TIFF) as a set",
        description="Read the files under PATH as the TOML mapping file describes them (docs/ingest.md) "
        "and store the recordings in <db>/recordings/<set>/. Without --mapping, every WAV file is an audio "
        "recording and every image a photo, labelled by its folder. Bad files are reported by name and "
        "skipped; the exit status is 3 if there were any.")
    _add_db_option(ingesting)
    ingesting.add_argument("path", type=Path, help="folder with the files")
    ingesting.add_argument("--mapping", type=Path, help="TOML mapping file (docs/ingest.md); default: WAV "
                           "files as audio, images as photos, the label from the folder holding each file")
    ingesting.add_argument("--name", help="set name (default: the mapping's name, else its file name; "
                           "without a mapping, the folder's name)")
    ingesting.add_argument("--grid", metavar="RxC", help="cut every image into R x C patches (one recording "
                           "each, sharing the group 'photo', so folds keep a photo's patches together)")
    ingesting.add_argument("--verbose", action="store_true", help="print every note, not a summary per kind")
    ingesting.add_argument("--replace", action="store_true", help="replace an existing set of that name")
    ingesting.set_defaults(handler=cmd_ingest)

    comparing = commands.add_parser(
        "compare", help="run the related papers' methods on one dataset: table and HTML report",
        description="Run every related method that applies to DATASET with its published features, "
        "classifiers and protocol; print accuracy, macro F1 and time per classification, and write the HTML "
        "report.")
    _add_db_option(comparing)
    comparing.add_argument("dataset", metavar="DATASET", help=DATASET_HELP)
    comparing.add_argument("--methods", nargs="+", choices=COMPARE_METHODS,
                           help="methods to run (default: every one that applies)")
    comparing.add_argument("--repeats", type=int, default=COMPARE_REPEATS, help="repetitions of the repeated "
                           f"protocols (default {COMPARE_REPEATS}; Hoelscher et al. 2015 used 100)")
    comparing.add_argument("--seed", type=int, default=0, help="random seed of simulation, splits and "
                           "classifiers (default 0)")
    comparing.add_argument("--report", type=Path, help="HTML report folder (default <db>/reports/compare-"
                           "<dataset>, or ./compare-<dataset> without a database folder)")
    _add_cluster_options(comparing, ship=False)
    comparing.set_defaults(handler=cmd_compare)
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


if __name__ == "__main__":
    sys.exit(main())
