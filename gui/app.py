"""The operator's web application (SPEC 10): a small server-rendered Flask app, no front-end build step.

Flask because it is small, well kept and ships what this needs and nothing more: Jinja2 templates with
auto-escaping, Werkzeug's multipart parser with request size limits, a signed session cookie
(``itsdangerous``) for the CSRF token, trusted-host checking, and a test client.

The app holds no business logic. Pages call ``scanner`` (database, guided session, devices),
``features`` (extraction with the database's cache) and ``taxonomy`` (table, model, plots).

:func:`serve` runs it on Werkzeug's threaded WSGI server, bound to 127.0.0.1 unless another host is given.
"""

from __future__ import annotations

import math
import secrets
import sys
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

from flask import Flask, Response, current_app, render_template
from flask.globals import request_ctx
from werkzeug.exceptions import HTTPException, RequestEntityTooLarge

from gui import security
from gui.exports import Exports
from gui.operation import Operations
from gui.photos import DEFAULT_MAX_BYTES, DEFAULT_MAX_PIXELS, PhotoStore
from scanner.config import Config
from scanner.database import Database

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")
DEMO_MODEL = Path("models") / "rf-fine-X10.skops"
"""Where ``texplorer demo`` saves its model; used when no ``--model`` is given and the file exists."""

MULTIPART_OVERHEAD = 1024 * 1024
"""Room for the form fields next to three photos in one request."""


@dataclass(frozen=True)
class Settings:
    """What ``texplorer serve`` configures.

    ``upload_limit`` is per photo in bytes; a request may carry three photos plus the form fields.
    ``heartbeat_timeout_s``: a recording browser that has not polled for this long counts as
    disconnected (the Peltier is switched off). ``device_config`` is the scanner configuration
    (``scanner.config.load_config``; tests pass short step durations). ``trusted_hosts`` guards against
    DNS rebinding when bound to the loopback interface; None accepts any Host header. ``export_dir`` is
    where export bundles are built before they are streamed (default: the system's temporary folder,
    ``$TMPDIR``); an export nobody has asked about for ``export_abandon_s`` is cancelled and its file
    deleted. Paths are made absolute when the settings are made.
    """

    db: Path
    model: Path | None = None
    device_config: Config = field(default_factory=Config)
    upload_limit: int = DEFAULT_MAX_BYTES
    max_photo_pixels: int = DEFAULT_MAX_PIXELS
    heartbeat_timeout_s: float = 5.0
    secret_key: bytes = field(default_factory=lambda: secrets.token_bytes(32), repr=False)
    trusted_hosts: tuple[str, ...] | None = LOOPBACK_HOSTS
    workers: int | None = None
    export_dir: Path | None = None
    export_abandon_s: float = 120.0

    def __post_init__(self) -> None:
        # Resolved once here: Flask's send_file reads a relative path against the package folder, not the
        # folder 'texplorer serve' was started in, and the server must not depend on its working directory.
        for name in ("db", "model", "export_dir"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, Path(value).expanduser().resolve())

    @property
    def work_dir(self) -> Path:
        """The app's own files (staged uploads, plot cache), beside but outside the database's scans."""
        return Path(self.db) / ".gui"


class Context:
    """What every request needs: settings, database, device configuration, staged photos, the running scan,
    the export job, the model."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.db = Database(settings.db)
        self.device_config = settings.device_config
        self.photos = PhotoStore(settings.work_dir / "uploads")
        self.plot_dir = settings.work_dir / "plots"
        self.operations = Operations(self.photos, settings.heartbeat_timeout_s)
        self.exports = Exports(self.db, settings.export_dir, workers=settings.workers,
                               abandon_after_s=settings.export_abandon_s)

    @property
    def model_path(self) -> Path | None:
        """``--model``, else the demo's model in the database folder if it exists, else None."""
        if self.settings.model is not None:
            return Path(self.settings.model)
        demo = Path(self.settings.db) / DEMO_MODEL
        return demo if demo.is_file() else None

    @cached_property
    def model(self) -> Any:
        """The trained model (loaded on first use: scikit-learn takes seconds to import), or None."""
        from taxonomy.models import load_model

        path = self.model_path
        return None if path is None else load_model(path)

    def shutdown(self) -> None:
        """Abort a running scan (Peltier off, devices released); cancel an export and delete its file."""
        self.operations.shutdown()
        self.exports.shutdown()


def context() -> Context:
    """The running app's :class:`Context`."""
    return current_app.extensions["texplorer"]


def quantity(value: float, spec: str = "%g", unit: str = "") -> str:
    """Template filter: a number with its unit, or "not measured" for NaN (the data model's "unknown")."""
    if math.isnan(value):
        return "not measured"
    return f"{spec % value} {unit}".rstrip()


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
    """The web application for the database at ``settings.db``."""
    app = Flask(__name__)
    app.config.update(
        SECRET_KEY=settings.secret_key,
        MAX_CONTENT_LENGTH=3 * settings.upload_limit + MULTIPART_OVERHEAD,
    )
    app.extensions["texplorer"] = Context(settings)
    app.jinja_env.filters["quantity"] = quantity
    security.install(app, settings.trusted_hosts)
    app.register_error_handler(RequestEntityTooLarge, _too_large)
    app.register_error_handler(HTTPException, _error_page)

    from gui import browser, operate

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


def serve(settings: Settings, host: str = "127.0.0.1", port: int = 8080) -> None:
    """Run the app until Ctrl-C; warns on stderr when it listens beyond this computer."""
    from werkzeug.serving import make_server

    if not is_loopback(host):
        print(f"texplorer: warning: listening on {host}:{port}: anyone who can reach this computer on the "
              "network can use the scanner and the database", file=sys.stderr)
        settings = replace(settings, trusted_hosts=None)
    app = create_app(settings)
    server = make_server(host, port, app, threaded=True)
    print(f"texplorer: serving {settings.db} at {url_of(host, server.server_port)} (Ctrl-C stops)", file=sys.stderr)
    try:
        server.serve_forever()  # returns on Ctrl-C (Werkzeug handles the KeyboardInterrupt)
    finally:
        server.server_close()
        app.extensions["texplorer"].shutdown()
    print("texplorer: stopped", file=sys.stderr)

