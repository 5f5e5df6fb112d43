"""``texplorer scan`` (the guided session in the terminal) and ``texplorer emulate`` (device emulators)."""

from __future__ import annotations

import argparse
import shlex
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path

from scanner.acquisition.config import load_config
from scanner.acquisition.devices.protocols import DeviceError
from scanner.acquisition.devices.sources import SimulatedSample
from scanner.acquisition.entries import (
    MASS_UNITS,
    TACK_CHOICES,
    VOLUME_UNITS,
    YIELDING_CHOICES,
    parse_ambient,
    parse_judged,
    parse_quantity,
    parse_volume_method,
)
from scanner.acquisition.session import STEP_TITLES, VOLUME_METHODS, Session, SessionError, StepState
from scanner.cli.base import EXIT_ERROR, UsageError, add_db_option, open_db
from scanner.scan import IMAGES
from scanner.storage.database import DatabaseError, is_database
from scanner.workflows.models import model_file
from scanner.workflows.predictions import check_label, format_predictions, predict_scan
from scanner.workflows.quick import QuickIdentifier, QuickState, step_words
from taxonomy.errors import TexplorerError
from taxonomy.labels import LabelError
from taxonomy.learning.models import TrainedModel, load_model
from taxonomy.learning.quick import STOP_AT
from taxonomy.table import UnknownLabelError, load_taxonomy

try:  # pseudo-terminals: POSIX only
    from scanner.acquisition.emulators.board import BoardEmulator, FaultPlan
except ImportError as missing:
    BoardEmulator = FaultPlan = None
    NO_PSEUDO_TERMINALS = str(missing)


ABORT = "a"
CONFIRM = "yes"


class _Aborted(TexplorerError):
    """The operator chose to abort the scan (or the input ended)."""


def _read(prompt: str) -> str:
    try:
        return input(prompt).strip()
    except EOFError:
        print()
        raise _Aborted("input ended") from None


def _confirm_discard(session: Session, doing: str) -> bool:
    """Ask before discarding the scan, naming what would be lost; True if the operator typed 'yes'."""
    work = session.work()
    print(f"  {doing} discards: {'; '.join(work)}" if work else f"  {doing}: nothing is recorded yet")
    return _read(f"  type '{CONFIRM}' to discard the scan, or Enter to go on: ").lower() == CONFIRM


def _ask(session: Session, prompt: str) -> str:
    """One answer from the operator; 'a' asks to confirm, then aborts; the end of the input aborts."""
    while True:
        answer = _read(prompt)
        if answer.lower() != ABORT:
            return answer
        if _confirm_discard(session, "aborting"):
            raise _Aborted("aborted by the operator")


def _ask_value(session: Session, prompt: str, name: str, parse: Callable[[str], object],
               optional: bool = False) -> None:
    """Ask until ``parse`` (the web form's parser) and the session accept the value of ``name``; the reason
    for a refusal is one line before asking again."""
    while True:
        answer = _ask(session, prompt)
        if not answer and optional:
            return
        try:
            session.set_values(**{name: parse(answer)})
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


def _record_step(session: Session, step) -> None:
    """Record (or skip) one step until the operator keeps it."""
    while True:
        options = "[Enter] record" + (", s skip (rigid sample)" if step.skippable else "") + ", a abort: "
        if _ask(session, f"  {options}").lower() == "s" and step.skippable:
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
        if _ask(session, f"  {verdict}. [Enter] keep, r redo, a abort: ").lower() != "r":
            return
        session.redo(step.id)


def _take_photos(session: Session) -> None:
    for name in IMAGES:
        while True:
            answer = _ask(session, f"  {name}: [Enter] capture with the camera, or a PNG/JPEG file, a abort: ")
            try:
                if answer:
                    session.set_photo(name, Path(answer).expanduser().read_bytes())
                else:
                    session.capture_photo(name)
                break
            except (SessionError, OSError, DeviceError) as exc:
                print(f"  {exc}")


def _scale(choices: tuple[tuple[float, str], ...]) -> str:
    return ", ".join(f"{value:g} {words}" for value, words in choices)


def _tu4(session: Session) -> None:
    _ask_value(session, "  mass (g): ", "mass_g", lambda text: parse_quantity(text, MASS_UNITS, what="mass"))
    _ask_value(session, "  volume (cm^3 or ml): ", "volume_cm3",
               lambda text: parse_quantity(text, VOLUME_UNITS, what="volume"))
    _ask_value(session, f"  volume measured by ({'/'.join(VOLUME_METHODS)}): ", "volume_method",
               parse_volume_method)
    print(f"  adhesive tack: {_scale(TACK_CHOICES)}")
    _ask_value(session, "  adhesive tack: ", "atk", lambda text: parse_judged(text, TACK_CHOICES, what="adhesive tack"))
    print(f"  yielding: {_scale(YIELDING_CHOICES)}")
    _ask_value(session, "  yielding: ", "cyd", lambda text: parse_judged(text, YIELDING_CHOICES, what="yielding"))
    _ask_value(session, "  notes (optional): ", "notes", str, optional=True)


def _check_label(session: Session, model: TrainedModel, args: argparse.Namespace) -> None:
    """Before saving: the model's prediction of the scan as it would be saved, and where the operator's label
    disagrees with it (:func:`scanner.workflows.predictions.check_label`), the choice of the predicted label, the
    operator's, or another."""
    db = open_db(args) if is_database(args.db) else None
    taxonomy = db.taxonomy() if db is not None else load_taxonomy()
    scan = session.scan(db.next_scan_index(session.sample_id) if db is not None else 1)
    prediction = predict_scan(model, scan, 3, taxonomy)
    print("\n" + format_predictions(prediction))
    if prediction.unknown:
        print("to teach the model this material: save the scan under its label, then 'texplorer train' makes a new "
              "model version with it ('texplorer models' lists the versions)")
    check = check_label(session.label, prediction, model, taxonomy)
    if check is None:
        return
    print(f"check the label: {check.message}")
    offer = f"[p] save as {check.predicted}, " if check.predicted else ""
    while answer := _ask(session, f"{offer}[Enter] keep {session.label}, or type another label: ").strip():
        label = check.predicted if answer.lower() == "p" and check.predicted else answer
        try:
            session.relabel(taxonomy.check(label).format())
        except (LabelError, UnknownLabelError, SessionError) as exc:
            print(f"  {exc}")
            continue
        print(f"the scan will be saved as {session.label}")
        return


def _ambient(session: Session) -> None:
    answer = _ask(session, f"ambient temperature {session.t_amb:.2f} degC: [Enter] keep, or type degC: ")
    while answer:
        try:
            session.t_amb = parse_ambient(answer)
            break
        except ValueError as exc:
            answer = _ask(session, f"  {exc}; degC: ")


def _do_step(session: Session, step) -> None:
    """Show one step's instruction and record it, take the photos or ask for the TU4 values."""
    duration = f" ({step.duration_s:g} s)" if step.duration_s else ""
    print(f"\nstep {step.number}/{len(session.steps)}: {step.title}{duration}")
    print(textwrap.fill(step.instruction, 100, initial_indent="  ", subsequent_indent="  "))
    if step.kind == "record":
        _record_step(session, step)
    elif step.kind == "photos":
        _take_photos(session)
    else:
        _tu4(session)


def _finish(session: Session, args: argparse.Namespace, model: TrainedModel | None) -> str | None:
    """Check the label against ``model`` if given, then save when the operator says so: the scan id, or None."""
    if model is not None:
        _check_label(session, model, args)
    while _ask(session, "\nsave the scan? [Y/n] ").lower() in ("n", "no"):
        if _confirm_discard(session, "not saving"):
            return None
    while True:
        try:
            return session.save(open_db(args, create=True))
        except (DatabaseError, OSError) as exc:
            # The recording is still in the session: let the operator fix the disk or path and retry.
            _ask(session, f"  not saved: {exc}\n  [Enter] retry, a abort: ")


def _guide(session, args: argparse.Namespace, model: TrainedModel | None = None) -> str | None:
    """Walk the operator through every step, check the label against ``model`` if given; the saved scan id,
    or None if not saved."""
    _ambient(session)
    for step in session.steps:
        _do_step(session, step)
    return _finish(session, args, model)


def _quick_lines(state: QuickState) -> str:
    steps = ", ".join(step_words(step) for step in sorted(state.recorded, key=list(STEP_TITLES).index))
    return f"after {steps} ({state.seconds:.0f} s):\n" + format_predictions(state.predictions)


def _guide_quick(session: Session, args: argparse.Namespace, identifier: QuickIdentifier,
                 model: TrainedModel | None = None) -> tuple[str | None, QuickState]:
    """The quick scan (docs/quick.md): after every step the prediction, then the step proposed next and why,
    until the prediction is sure; the operator may take another step, stop, or go on to the full scan (which
    is saved as any scan). Returns the saved scan id (None if not saved) and where the quick scan stopped."""
    _ambient(session)
    print("\nquick identification: each step is chosen to tell the likeliest materials apart fastest; the scan "
          f"stops at {100 * STOP_AT:.0f} %")
    while True:
        state = identifier.assess(session.scan(partial=True), session.recorded_steps())
        if state.recorded:
            print("\n" + _quick_lines(state))
        if state.decided or state.next_step is None:
            print(f"\nidentified: stopped because {state.why_stopped()}")
            answer = _ask(session, "[Enter] stop here, k keep this quick scan in the database, f go on to the "
                                   "full scan: ").lower()
            if answer == "k":
                return _keep_quick(session, args, state), state
            if answer != "f":
                return None, state
            break
        proposed = session.step(state.next_step)
        print(f"\nnext: {proposed.title} ({proposed.seconds:g} s): {state.reason}")
        answer = _ask(session, "  [Enter] take it, or a step number, f full scan, s stop: ").lower()
        if answer == "s":
            print(f"stopped by the operator after {len(state.recorded)} step(s)")
            return None, state
        if answer == "f":
            break
        chosen = _chosen_step(session, answer, proposed)
        if chosen is not None:
            _do_step(session, chosen)
    for step in session.steps:
        if step.id not in session.recorded_steps():
            _do_step(session, step)
    state = identifier.assess(session.scan(partial=True), session.recorded_steps())
    print("\n" + _quick_lines(state))
    if args.label is None:
        _label_from(session, state)
    return _finish(session, args, model), state


def _keep_quick(session: Session, args: argparse.Namespace, state: QuickState) -> str | None:
    """Save the quick scan as it is (``meta.steps`` names the steps it holds; docs/quick.md): under the
    quick prediction's label when it started without one."""
    if args.label is None:
        _label_from(session, state)
    while True:
        try:
            return session.save(open_db(args, create=True), partial=True)
        except (DatabaseError, OSError) as exc:
            _ask(session, f"  not saved: {exc}\n  [Enter] retry, a abort: ")


def _chosen_step(session: Session, answer: str, proposed):
    """The step the operator typed (its number), the proposed one on Enter; None (with why) for another."""
    if not answer:
        return proposed
    if answer.isdigit() and 1 <= int(answer) <= len(session.steps):
        step = session.steps[int(answer) - 1]
        if step.id not in session.recorded_steps():
            return step
        print(f"  step {answer} ({step.title}) is done already")
        return None
    print(f"  {answer!r}: type a step number 1-{len(session.steps)}, f or s")
    return None


def _label_from(session: Session, state: QuickState) -> None:
    """Before saving a quick scan started without a label: the quick prediction's label, or one typed."""
    offered = state.predictions[0].label
    session.relabel(offered)
    while answer := _ask(session, f"label: [Enter] {offered} ({state.predictions[0].names}), or type another: "):
        try:
            session.relabel(load_taxonomy().check(answer.strip()).format())
            return
        except (LabelError, UnknownLabelError, SessionError) as exc:
            print(f"  {exc}")


def again(args: argparse.Namespace, session: Session) -> str:
    """The command that starts this scan over, with the same database, label, sample and operator (a quick
    scan started without a label again without one)."""
    label = [] if getattr(args, "quick", False) and args.label is None else ["--label", session.label]
    words = ["texplorer", "scan", "--db", str(args.db), *label, "--sample", session.sample_id,
             "--operator", session.operator] + (["--quick"] if getattr(args, "quick", False) else [])
    for option in ("config", "daq", "board", "model"):
        if getattr(args, option, None):
            words += [f"--{option}", str(getattr(args, option))]
    return shlex.join(words)


def cmd_scan(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    model = None
    if args.model:
        model = load_model(model_file(args.db, args.model))
    if args.label is None and not args.quick:
        raise UsageError("--label is required (only a quick scan, --quick, may start without one)")
    if args.daq:
        config = config.with_daq_server(args.daq)
    if args.board:
        config = config.with_board_port(args.board)
    # An aborted scan leaves no trace: an existing database is only read, a new one is made when saving.
    db = open_db(args) if is_database(args.db) else None
    identifier = None
    if args.quick:
        if db is None:
            raise UsageError(f"--quick learns from the scans of a database; {args.db} is none")
        print(f"learning the quick scan from the {len(db)} scans of {args.db} ...", flush=True)
        identifier = QuickIdentifier.from_database(db, config)
    label = args.label or str(identifier.model.classes[0])  # a quick scan without label: the prediction's, later
    session = Session.open(config, label=label, sample_id=args.sample, operator=args.operator, db=db)
    state = None
    try:
        about = session.label if args.label else "an unlabelled sample"
        print(f"scan of {about}, sample {session.sample_id}, operator {session.operator} "
              f"(session {session.session_id}); 'a' aborts at any prompt")
        for name, description in session.devices.describe().items():
            print(f"  {name:<13} {description}")
        for warning in session.warnings:
            print(f"texplorer: warning: {warning}", file=sys.stderr)
        if identifier is not None:
            scan_id, state = _guide_quick(session, args, identifier, model)
        else:
            scan_id = _guide(session, args, model)
    except _Aborted as reason:
        print(f"scan aborted ({reason}): nothing was saved")
        print(f"to scan this sample again: {again(args, session)}")
        return EXIT_ERROR
    finally:
        session.abort()
    if state is not None:
        top = state.predictions[0]
        kept = (f"saved {scan_id} in {args.db}" if scan_id else
                "not saved (k keeps a quick scan, f records the full scan)")
        print(f"quick scan: {top.names} ({top.label}) at {100 * top.probability:.1f} % after "
              f"{len(state.recorded)} of {len(session.steps)} steps ({state.seconds:.0f} s); {kept}")
        return 0
    if scan_id is None:
        print("not saved")
        print(f"to scan this sample again: {again(args, session)}")
        return EXIT_ERROR
    print(f"saved {scan_id} in {args.db}")
    return 0


def cmd_emulate_board(args: argparse.Namespace) -> int:
    if BoardEmulator is None:
        raise OSError(f"the board emulator needs pseudo-terminals (Linux, macOS): {NO_PSEUDO_TERMINALS}")

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
    # The emulator is built on gRPC and the nidaqmx stubs, optional libraries no other command loads.
    from scanner.acquisition.emulators.daq_grpc import DaqEmulator, DaqServicer


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


def register(commands: argparse._SubParsersAction) -> None:
    scanning = commands.add_parser(
        "scan", help="guided scanning session in the terminal (simulated devices unless configured)",
        description="Guide the operator through the steps of a scan (Strese et al. 2020, section III) with live "
        "levels, quality checks and redo, then save it. Devices come from --config (default: the simulated scanner).")
    add_db_option(scanning)
    scanning.add_argument("--label", help="material label, e.g. C6S1M1P2X1 (required, except for --quick)")
    scanning.add_argument("--sample", required=True, help="sample id, e.g. granite-01")
    scanning.add_argument("--operator", required=True, help="operator name or initials")
    scanning.add_argument("--config", type=Path, help="device configuration TOML "
                          "(see docs/texplorer.example.toml)")
    scanning.add_argument("--daq", metavar="grpc://HOST:PORT", help="read the real DAQ through this NI gRPC "
                          "Device Server")
    scanning.add_argument("--board", metavar="PORT", help="use the real sensor board on this serial port "
                          "(COM3, /dev/ttyACM0)")
    scanning.add_argument("--model", help="before saving, print the prediction of this model (a version of the "
                          "database, 3 or v3, or a file) and "
                          "check the label against it")
    scanning.add_argument("--quick", action="store_true", help="quick identification: after every step the "
                          "prediction from the database's scans, the next step chosen by information per second, "
                          "a stop at a calibrated 0.95; go on to the full scan to save it (docs/quick.md)")
    scanning.set_defaults(handler=cmd_scan)

    emulate = commands.add_parser("emulate", help="run a device emulator to try the app without hardware",
                                  description="Emulated hardware playing a simulated material sample.")
    emulators = emulate.add_subparsers(dest="emulator", metavar="DEVICE", required=True)
    emulate_board = emulators.add_parser(
        "board", help="serial sensor board on a pseudo-terminal; prints its device path",
        description="The serial sensor board (its line protocol is described in scanner/acquisition/devices/board.py) "
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
