"""``texplorer models`` and ``classify``: the database's model versions, and the most probable materials of a
stored scan by one of them. A group of its own so that ``classify`` starts without what the other analysis
commands need (the feature families of recordings, the evaluation's reports, the devices)."""

from __future__ import annotations

import argparse
from pathlib import Path

from scanner.cli.base import UsageError, add_db_option, open_db, table_lines
from scanner.storage.matfile import load_scan
from scanner.workflows.database import stored_features
from scanner.workflows.models import model_file
from scanner.workflows.predictions import format_predictions, predict_scan, predict_values
from taxonomy.learning.models import load_model
from taxonomy.learning.versions import current_version, use_version, versions
from taxonomy.table import load_taxonomy


def cmd_models(args: argparse.Namespace) -> int:
    if args.use is not None:
        chosen = use_version(args.db, args.use)
        print(f"version {chosen.version} is current: the web application (when it next loads the model) and "
              "classify use it")
    found = versions(args.db)
    if not found:
        print(f"no models in {args.db / 'models'}: 'texplorer train' or 'texplorer demo' makes one")
        return 0
    current = current_version(args.db)
    rows = [(("* " if current and v.version == current.version else "  ") + f"v{v.version}", v.created[:16],
             v.protocol(), str(len(v.classes) or "?"), str(v.rows or "?"), v.fingerprint[:12] or "-",
             v.feature_code_version[:8] or "-", v.figures_text(), v.file) for v in found]
    for line in table_lines(("version", "created", "protocol", "classes", "scans", "training data",
                             "features", "figures", "file"), rows):
        print(line)
    print("* current: the model serve, classify and scan use when not given --model; 'texplorer models --use N' "
          "makes another current")
    return 0


def cmd_classify(args: argparse.Namespace) -> int:
    model = load_model(model_path(args))
    if _is_scan_file(args.scan):
        scan = load_scan(args.scan)
        print(f"{scan.scan_id} ({scan.meta.label} recorded) with {model.describe()}")
        print(format_predictions(predict_scan(model, scan, args.k, load_taxonomy())))
        return 0
    db = open_db(args)
    record = db.record(args.scan)
    values, failure = stored_features(db, record)  # from the feature cache when the scan was extracted before
    if failure:
        raise UsageError(f"{record.scan_id}: its features cannot be extracted: {failure}")
    print(f"{record.scan_id} ({record.label} recorded) with {model.describe()}")
    print(format_predictions(predict_values(model, values, args.k, db.taxonomy())))
    return 0


def _is_scan_file(scan: str) -> bool:
    """Whether ``classify``'s SCAN names a ``.mat`` file rather than a scan of the database (whose ids
    ``db list`` shows)."""
    return Path(scan).suffix.lower() == ".mat" or Path(scan).is_file()


def model_path(args: argparse.Namespace) -> Path:
    """``--model``, else the database's default model (:func:`scanner.workflows.models.default_model`), as
    ``serve`` uses it.

    Raises
    ------
    UsageError
        No ``--model`` given and the database has no default model.
    """
    found = model_file(args.db, args.model)
    if found is None:
        raise UsageError(f"no --model given and {args.db / 'models'} holds no model: train one with "
                         "'texplorer train' or run 'texplorer demo'")
    return found


def register(commands: argparse._SubParsersAction) -> None:
    models = commands.add_parser("models", help="list the database's model versions; make one current",
                                 description="List every model 'texplorer train' and 'texplorer demo' kept, with "
                                 "its date, protocol, classes, training-data fingerprint (scans and feature code) "
                                 "and headline figures; --use N makes version N the current one.")
    add_db_option(models)
    models.add_argument("--use", metavar="N", help="make version N current (3 or v3)")
    models.set_defaults(handler=cmd_models)

    classify = commands.add_parser("classify", help="predict the material of a stored scan (its id in the "
                                   "database, or a .mat file)", description="Extract the features of a scan "
                                   "(a scan id as 'texplorer db list' shows it, its features read from the "
                                   "database's cache, or a .mat file) and print the most probable labels with a "
                                   "trained model.")
    classify.add_argument("scan", help="scan id in the database, or a scan file (.mat)")
    add_db_option(classify)
    classify.add_argument("--model", help="a model version of the database (3 or v3, as 'texplorer models' lists "
                          "them) or a model file (default: the current version)")
    classify.add_argument("--k", type=int, default=3, help="how many labels to print (default 3)")
    classify.set_defaults(handler=cmd_classify)
