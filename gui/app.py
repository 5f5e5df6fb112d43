"""The operator's web application (docs/operator.md): a small server-rendered Flask app, no front-end build step.

Flask because it is small, well kept and ships what this needs and nothing more: Jinja2 templates with
auto-escaping, Werkzeug's multipart parser with request size limits, a signed session cookie
(``itsdangerous``) for the CSRF token, trusted-host checking, and a test client.

The app holds no business logic. Pages call ``scanner`` (database, guided session, devices),
``features`` (extraction with the database's cache) and ``taxonomy`` (table, model, plots).

:func:`serve` runs it on Werkzeug's threaded WSGI server, bound to 127.0.0.1 unless another host is given.
Extraction for its requests runs in workers started by a fork server that :func:`serve` starts before any
request thread exists (:func:`scanner.runtime.local.start_workers_from_a_server`): a worker forked from the threaded
server would inherit locks other request threads held (SQLite's memory mutex: a request hung for good).
Every request and export job shares one bounded set of those workers (:func:`scanner.runtime.local.share_workers`,
``--workers``): a busy lab's concurrent requests queue for them rather than each starting its own.

Where the settings (``--scheduler``) or Dask's configuration (``DASK_SCHEDULER_ADDRESS``) name a Dask cluster,
the requests' extraction, the export jobs and the background trainings run on its workers instead
(:func:`scanner.runtime.executors.chosen`), and this process starts no workers of its own: the cluster's
workers are the bound then, and concurrent requests queue on its scheduler.
"""

from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
from collections.abc import Iterator
from dataclasses import replace

from flask import Flask, Response, render_template
from flask.globals import request_ctx
from werkzeug.exceptions import HTTPException, RequestEntityTooLarge
from werkzeug.serving import make_server

from features import WORKER_SERVER_PRELOAD
from gui import browser, operate, security
from gui.context import LOOPBACK_HOSTS, Context, Settings, context
from scanner.runtime.executors import LOCAL, Runtime, chosen
from scanner.runtime.local import end_shared_workers, share_workers, start_workers_from_a_server

MULTIPART_OVERHEAD = 1024 * 1024
"""Room for the form fields next to three photos in one request."""


def quantity(value: float, spec: str = "%g", unit: str = "") -> str:
    """Template filter: a number with its unit, or "not measured" for NaN (the data model's "unknown")."""
    if math.isnan(value):
        return "not measured"
    return f"{spec % value} {unit}".rstrip()


def when(started: str) -> str:
    """Template filter: an ISO 8601 time as a person reads it in a table, ``2026-03-02 14:05`` (to the minute;
    the full text stays in the page's ``<time datetime>``)."""
    date, _, clock = started.partition("T")
    return f"{date} {clock[:5]}".strip()


def _training_notice() -> dict[str, tuple[str, str] | None]:
    """Every page's line on the background training (:mod:`gui.training`): ``(css class, text)`` or None."""
    job = context().trainings.recent()
    if job is None:
        return {"training_notice": None}
    kind = "busy" if job.running else ("good" if job.change is not None else "bad")
    return {"training_notice": (kind, job.notice())}


def _error_page(error: HTTPException) -> tuple[str, int] | Response:
    if request_ctx.url_adapter is None:  # refused before routing (a malformed Host header): no page links
        text = f"{error.code} {error.name}: {error.description}\n"
        return Response(text, error.code or 500, mimetype="text/plain")
    return render_template("error.html", error=error), error.code or 500


def _too_large(error: RequestEntityTooLarge) -> tuple[str, int] | Response:
    limit = context().settings.upload_limit / (1024 * 1024)
    error.description = (f"the upload is larger than three photos of {limit:.1f} MB each; go back and choose "
                         "smaller photos (nothing was saved)")
    return _error_page(error)


def create_app(settings: Settings) -> Flask:
    """The operator's web application for the database at ``settings.db`` (docs/operator.md).

    Parameters
    ----------
    settings : Settings
        Database, device configuration, model, upload limit and export folder.

    Returns
    -------
    flask.Flask
        Serve it with :func:`serve`, or any WSGI server on the loopback interface.
    """
    app = Flask(__name__)
    app.config.update(
        SECRET_KEY=settings.secret_key,
        MAX_CONTENT_LENGTH=3 * settings.upload_limit + MULTIPART_OVERHEAD,
    )
    app.extensions["texplorer"] = Context(settings)
    app.jinja_env.filters["quantity"] = quantity
    app.jinja_env.filters["when"] = when
    security.install(app, settings.trusted_hosts)
    app.register_error_handler(RequestEntityTooLarge, _too_large)
    app.register_error_handler(HTTPException, _error_page)

    app.context_processor(_training_notice)
    app.register_blueprint(operate.blueprint)
    app.register_blueprint(browser.blueprint, url_prefix="/db")
    return app


def is_loopback(host: str) -> bool:
    return host in LOOPBACK_HOSTS


def url_of(host: str, port: int) -> str:
    """The address a browser opens: ``http://[::1]:8080/`` (IPv6 in brackets, RFC 3986), a wildcard bind
    shown as this computer."""
    shown = "127.0.0.1" if host in ("0.0.0.0", "::", "") else host
    return f"http://[{shown}]:{port}/" if ":" in shown else f"http://{shown}:{port}/"


def model_warning(settings: Settings) -> str | None:
    """Why the summary page will show no prediction with the ``--model`` given (a missing file), or None."""
    model = settings.model
    if model is None or model.is_file():
        return None
    reason = "is a folder" if model.is_dir() else "does not exist"
    return (f"--model {model} {reason}: the summary page shows no prediction until a model file is there "
            "('texplorer train --out FILE' makes one)")


def _stop(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


@contextlib.contextmanager
def _local_workers(settings: Settings, runtime: Runtime) -> Iterator[None]:
    """The server's one bounded set of workers, on this machine only (a cluster's workers bound the work)."""
    if runtime is not LOCAL:
        print(f"texplorer: extraction, exports and trainings run on {runtime.describe()}", file=sys.stderr)
        yield
        return
    start_workers_from_a_server(WORKER_SERVER_PRELOAD)  # before the first request thread
    share_workers(settings.workers)  # one bounded set of workers for every request and export job
    try:
        yield
    finally:
        end_shared_workers()


def serve(settings: Settings, host: str = "127.0.0.1", port: int = 8080) -> None:
    """Run the app until Ctrl-C; warns on stderr when it listens beyond this computer.

    Parameters
    ----------
    settings : Settings
    host : str
        Address to listen on; anything but a loopback address lets the lab network use the scanner.
    port : int
        TCP port; 0 picks a free one (printed).
    """
    if not is_loopback(host):
        print(f"texplorer: warning: listening on {host}:{port}: anyone who can reach this computer on the "
              "network can use the scanner and the database", file=sys.stderr)
        settings = replace(settings, trusted_hosts=None)
    warning = model_warning(settings)
    if warning:
        print(f"texplorer: warning: {warning}", file=sys.stderr)
    with chosen(settings.scheduler, workers=settings.workers, ship_data=settings.ship_data) as runtime:
        app = create_app(settings)
        with _local_workers(settings, runtime):
            _serve(app, settings, host, port)
    print("texplorer: stopped", file=sys.stderr)


def _serve(app: Flask, settings: Settings, host: str, port: int) -> None:
    """Serve ``app`` until Ctrl-C or SIGTERM, then end its running work."""
    signal.signal(signal.SIGTERM, _stop)  # as Ctrl-C: a running scan aborted, an export's bundle deleted
    threading.Thread(target=app.extensions["texplorer"].warm_up, name="warm-up", daemon=True).start()
    server = make_server(host, port, app, threaded=True)
    print(f"texplorer: serving {settings.db} at {url_of(host, server.server_port)} (Ctrl-C stops)", file=sys.stderr)
    try:
        server.serve_forever()  # returns on Ctrl-C (Werkzeug handles the KeyboardInterrupt)
    finally:
        server.server_close()
        app.extensions["texplorer"].shutdown()

