"""The operator's web application: guided scans, operator form, database browser.

``texplorer serve``, a command group the web application adds to the CLI (through the ``texplorer.commands``
entry point: the CLI, a layer below, does not import it). The first paragraph above is the command's line in
``texplorer --help``, read without importing this module or Flask."""

from __future__ import annotations

import argparse
from pathlib import Path

from gui.app import Settings, serve
from scanner.acquisition.config import load_config
from scanner.cli.base import UsageError, add_db_option
from scanner.cli.common import add_cluster_options
from scanner.photo import max_pixels
from scanner.workflows.models import model_file

MAX_PORT = 65535
"""The largest TCP port: a larger number would be taken modulo 65536 by the system (70000 listens on 4464)."""


def cmd_serve(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if not args.upload_limit_mb > 0:
        raise UsageError(f"--upload-limit-mb must be positive, got {args.upload_limit_mb:g}")
    if not 0 <= args.port <= MAX_PORT:
        raise UsageError(f"--port must be 1-{MAX_PORT} (or 0 for any free port), got {args.port}")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be at least 1, got {args.workers}")
    limit = int(args.upload_limit_mb * 1024 * 1024)
    model = model_file(args.db, args.model) if args.model is not None else None  # None: the current version
    settings = Settings(db=args.db, model=model, device_config=config, upload_limit=limit,
                        max_photo_pixels=max_pixels(), workers=args.workers, scheduler=args.scheduler,
                        ship_data=args.ship_data)
    serve(settings, args.host, args.port)
    return 0


def register(commands: argparse._SubParsersAction) -> None:
    serving = commands.add_parser(
        "serve", help="the operator's web application: guided scans, operator form, database browser",
        description="Serve the operator's web application for the database: start a scan, the guided steps "
        "with live levels, the operator form with photo uploads, the summary with the prediction, and the "
        "database browser with export. Listens on 127.0.0.1 only, unless --host says otherwise.")
    add_db_option(serving)
    serving.add_argument("--host", default="127.0.0.1", help="interface to listen on (default 127.0.0.1; "
                         "anything else makes the scanner reachable from the network, with a warning)")
    serving.add_argument("--port", type=int, default=8080, help="port (default 8080; 0 = any free port)")
    serving.add_argument("--config", type=Path, help="device configuration TOML (default: the simulated "
                         "scanner; see docs/texplorer.example.toml)")
    serving.add_argument("--model", help="model for the prediction on the summary page: a model version of the "
                         "database (3 or v3, 'texplorer models') or a file (default: the current version, if any)")
    serving.add_argument("--upload-limit-mb", type=float, default=20.0, help="largest photo upload in MB "
                         "(default 20)")
    serving.add_argument("--workers", type=int, help="worker processes every request and export shares for "
                         "feature extraction (default: number of cores); concurrent requests queue for them")
    add_cluster_options(serving)
    serving.set_defaults(handler=cmd_serve)
