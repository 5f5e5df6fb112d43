"""``texplorer ingest`` and ``compare``: other labs' recordings and the related papers' methods on them."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from scanner.cli.base import EXIT_PROBLEMS, UsageError, add_db_option, progress
from scanner.cli.common import add_cluster_options, runtime_of
from scanner.simulation.recordings import simulate_recordings
from scanner.storage.database import Database, DatabaseError
from scanner.storage.ingest import (
    MAPPING,
    IngestError,
    SetWriter,
    default_mapping,
    ingest,
    load_mapping,
    load_recordings,
    parse_grid,
    safe_name,
    set_folder,
    summarise_notes,
    with_excluded,
    with_grid,
    with_label_pattern,
)
from taxonomy.learning.results import format_comparison
from taxonomy.related import METHODS, Dataset, MethodError, compare_methods
from taxonomy.reports.report import write_comparison


def ingest_mapping(args: argparse.Namespace):
    """The mapping file's mapping, or for a plain folder the default one (WAV as audio, images as photo,
    labels from folders); ``--grid`` cuts every image into patches, ``--label-pattern`` takes the labels
    from the file names."""
    if args.mapping is None:
        mapping = default_mapping(args.name or safe_name(args.path.resolve().name))
    else:
        mapping = load_mapping(args.mapping)
    if args.label_pattern:
        mapping = with_label_pattern(mapping, args.label_pattern)
    if args.exclude_label:
        mapping = with_excluded(mapping, args.exclude_label)
    return with_grid(mapping, parse_grid(args.grid, "--grid")) if args.grid else mapping


def cmd_ingest(args: argparse.Namespace) -> int:
    mapping = ingest_mapping(args)
    # Each recording is written as it is read (the set swapped in at the end): memory does not grow with
    # the number of files, and an interrupted import leaves the database as it was.
    with SetWriter(args.db, args.name or mapping.name, replace=args.replace) as writer:
        if args.mapping is not None:  # kept with the set: an export sends it along (docs/export.md)
            writer.keep(MAPPING, args.mapping.read_bytes())
        report = ingest(args.path, mapping, progress=progress("reading", unit="recording"), sink=writer)
        for line in report.skipped:
            print(f"skipped  {line}")
        notes = [str(note) for note in report.notes] if args.verbose else summarise_notes(report.notes)
        for note in notes:
            print(f"note     {note}")
        if report.notes and not args.verbose:
            print(f"note     {len(report.notes)} note(s) in all; --verbose lists every one")
        if not report.made:
            raise IngestError(f"{args.path}: no recording could be imported from {report.files} matching file(s)")
        folder = writer.commit()
    roles = sorted({role for made in report.made for role in made.roles})
    splits = [made.split for made in report.made]
    split = (f"; split {splits.count('train')} train / {splits.count('test')} test" if any(splits) else "")
    print(f"{len(report.made)} recording(s) from {report.files} file(s) -> {folder}; roles "
          f"{', '.join(roles) or 'none'}{split}; {len(report.skipped)} problem line(s)")
    return EXIT_PROBLEMS if report.skipped else 0


COMPARE_METHODS = tuple(METHODS)
"""``taxonomy.related.METHODS``, named here so the parser does not import scikit-learn."""


COMPARE_REPEATS = 10


DATASET_HELP = ("sim:biotac, sim:array or sim:soft3axis (simulated sensors), set:NAME (recordings imported "
                "into --db with 'texplorer ingest'), scans (the scans of --db), or a folder: a database or "
                "a recording set")


def comparison_dataset(spec: str, db: Path, seed: int):
    """The dataset a ``compare`` argument names (see :data:`DATASET_HELP`)."""
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


def repeats_note(results, repeats: int) -> str:
    """What ``--repeats`` did: the methods whose protocol it repeats, and those with a fixed protocol."""
    repeated = sorted({r.method for r in results if " x " in r.splitting})
    fixed = sorted({f"{r.method} ({r.splitting})" for r in results if " x " not in r.splitting})
    parts = [f"--repeats {repeats}: {', '.join(repeated)} repeated {repeats} times" if repeated else
             f"--repeats {repeats}: no method here has a repeated protocol"]
    if fixed:
        parts.append(f"{', '.join(fixed)} keep their published protocol")
    return "; ".join(parts)


def cmd_compare(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    dataset = comparison_dataset(args.dataset, args.db, args.seed)
    print(dataset.summary())
    with runtime_of(args):
        comparison = compare_methods(dataset, args.methods, seed=args.seed, repeats=args.repeats,
                                     progress=progress("comparing", unit="method"))
    print(comparison.format_outcome())
    results = comparison.results
    if not results:
        own = (f"; the project's own features: texplorer evaluate {args.dataset}"
               if args.dataset.startswith("set:") else "")
        raise MethodError(f"no method could run on {args.dataset} (see above){own}")
    print(format_comparison(results))
    print(repeats_note(results, args.repeats))
    slug = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in args.dataset).strip("-") or "dataset"
    folder = args.report or (args.db / "reports" if args.db.is_dir() else Path(".")) / f"compare-{slug}"
    print(f"{len(results)} result(s) in {time.perf_counter() - started:.1f} s; report: "
          f"{write_comparison(folder, results, dataset.summary(), comparison.outcome)}")
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    ingesting = commands.add_parser(
        "ingest", help="import recordings or photos (CSV/TSV, WAV, NPY/NPZ, .mat, PNG/JPG/BMP/TIFF) as a set",
        description="Read the files under PATH as the TOML mapping file describes them (docs/ingest.md) "
        "and store the recordings in <db>/recordings/<set>/. Without --mapping, every WAV file is an audio "
        "recording and every image a photo, labelled by its folder. Bad files are reported by name and "
        "skipped; the exit status is 3 if there were any.")
    add_db_option(ingesting)
    ingesting.add_argument("path", type=Path, help="folder with the files")
    ingesting.add_argument("--mapping", type=Path, help="TOML mapping file (docs/ingest.md); default: WAV "
                           "files as audio, images as photos, the label from the folder holding each file")
    ingesting.add_argument("--name", help="set name (default: the mapping's name, else its file name; "
                           "without a mapping, the folder's name)")
    ingesting.add_argument("--grid", metavar="RxC", help="cut every image into R x C patches (one recording "
                           "each, sharing the group 'photo', so folds keep a photo's patches together; each "
                           "patch's 'row' and 'column' are groups too, for evaluate --group-by row)")
    ingesting.add_argument("--label-pattern", metavar="REGEX",
                           help="labels from the file names: the (?P<label>...) group of REGEX searched in each "
                           "file's stem, e.g. '^(?P<label>[a-z]+)_' for cork_01.png (other named groups become "
                           "group ids); for a flat folder of files")
    ingesting.add_argument("--exclude-label", metavar="CLASS", action="append", default=[],
                           help="leave out the recordings of this class (a label folder such as MIXED); "
                           "repeat for more; adds to the mapping's [labels] exclude")
    ingesting.add_argument("--verbose", action="store_true", help="print every note, not a summary per kind")
    ingesting.add_argument("--replace", action="store_true", help="replace an existing set of that name")
    ingesting.set_defaults(handler=cmd_ingest)

    comparing = commands.add_parser(
        "compare", help="run the related papers' methods on one dataset: table and HTML report",
        description="Run every related method that applies to DATASET with its published features, "
        "classifiers and protocol; print accuracy, macro F1 and time per classification, and write the HTML "
        "report.")
    add_db_option(comparing)
    comparing.add_argument("dataset", metavar="DATASET", help=DATASET_HELP)
    comparing.add_argument("--methods", nargs="+", choices=COMPARE_METHODS,
                           help="methods to run (default: every one that applies)")
    comparing.add_argument("--repeats", type=int, default=COMPARE_REPEATS, help="repetitions of the repeated "
                           f"protocols (default {COMPARE_REPEATS}; Hoelscher et al. 2015 used 100)")
    comparing.add_argument("--seed", type=int, default=0, help="random seed of simulation, splits and "
                           "classifiers (default 0)")
    comparing.add_argument("--report", type=Path, help="HTML report folder (default <db>/reports/compare-"
                           "<dataset>, or ./compare-<dataset> without a database folder)")
    add_cluster_options(comparing, ship=False)
    comparing.set_defaults(handler=cmd_compare)
