"""What every request of the web application needs: the settings of ``texplorer serve`` and the
:class:`Context` built from them (database, device configuration, staged photos, the running scan, the
export job, the model), reached from a page through :func:`context`."""

from __future__ import annotations

import contextlib
import secrets
import threading
from dataclasses import dataclass, field
from pathlib import Path

from flask import current_app

from features import code_version
from gui.exports import Exports
from gui.figures import Keeper
from gui.live_session import Operations
from gui.photos import DEFAULT_MAX_BYTES, DEFAULT_MAX_PIXELS, PhotoStore
from gui.training import Trainings
from scanner.acquisition.config import Config
from scanner.storage.database import Database
from scanner.workflows.models import default_model
from scanner.workflows.quick import QuickIdentifier
from taxonomy.learning.models import TrainedModel, load_model

LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")

@dataclass(frozen=True)
class Settings:
    """What ``texplorer serve`` configures.

    ``upload_limit`` is per photo in bytes; a request may carry three photos plus the form fields.
    ``heartbeat_timeout_s``: a recording browser that has not polled for this long counts as
    disconnected (the Peltier is switched off). ``device_config`` is the scanner configuration
    (``scanner.acquisition.config.load_config``; tests pass short step durations). ``trusted_hosts`` guards against
    DNS rebinding when bound to the loopback interface; None accepts any Host header. ``export_dir`` is
    where export bundles are built before they are streamed (default: the system's temporary folder,
    ``$TMPDIR``); an export nobody has asked about for ``export_abandon_s`` is cancelled and its file
    deleted. ``prediction_timeout_s`` bounds the summary's wait for the model (loading it and predicting):
    past it the summary says so in one line and the scan can be saved without a prediction. ``workers``
    (processes on this machine) or ``scheduler`` (a Dask cluster, ``tcp://HOST:PORT`` or ``local:N``; default
    Dask's configuration, else processes here) choose where extraction and training run, ``ship_data`` sends
    the scans' files to the cluster's workers (:func:`scanner.runtime.executors.chosen`). Paths are made
    absolute when the settings are made.
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
    scheduler: str | None = None
    ship_data: bool = False
    export_dir: Path | None = None
    export_abandon_s: float = 120.0
    prediction_timeout_s: float = 30.0

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
    the export job, the background trainings, the model."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.db = Database(settings.db)
        self.device_config = settings.device_config
        self.photos = PhotoStore(settings.work_dir / "uploads")
        self.plot_dir = settings.work_dir / "plots"
        self.figures = Keeper()
        self.operations = Operations(self.photos, settings.heartbeat_timeout_s)
        self.exports = Exports(self.db, settings.export_dir, workers=settings.workers,
                               abandon_after_s=settings.export_abandon_s)
        self.trainings = Trainings(self.db, workers=settings.workers)
        self._model: tuple[tuple[Path, int], TrainedModel] | None = None
        self._model_lock = threading.Lock()
        self._quick: tuple[tuple[int, str], QuickIdentifier] | None = None
        self._quick_lock = threading.Lock()

    def quick_identifier(self) -> QuickIdentifier:
        """The quick identification learned from the database's scans (``scanner.workflows.quick.QuickIdentifier``):
        learned on first use (seconds: features from the cache), again once the scans or the feature code
        changed."""
        key = (len(self.db), code_version())
        with self._quick_lock:
            if self._quick is None or self._quick[0] != key:
                self._quick = (key, QuickIdentifier.from_database(self.db, self.device_config,
                                                                  workers=self.settings.workers))
            return self._quick[1]

    @property
    def model_path(self) -> Path | None:
        """``--model``, else the database's current model version (``texplorer models``) if any, else None."""
        if self.settings.model is not None:
            return Path(self.settings.model)
        return default_model(self.settings.db)

    @property
    def model(self) -> TrainedModel | None:
        """The trained model, or None: loaded on first use, and again when the current version changed
        (a training of this app or of ``texplorer train``, ``texplorer models --use``) or its file did."""
        path = self.model_path
        if path is None:
            return None
        try:
            key = (path, path.stat().st_mtime_ns)
        except OSError:
            key = (path, -1)  # load_model says why it cannot be read
        with self._model_lock:  # one load at a time; a request during it gets the same model
            if self._model is None or self._model[0] != key:
                self._model = (key, load_model(path))
            return self._model[1]

    def warm_up(self) -> None:
        """Load the model while the operator scans, so the summary page does not wait for it (seconds, the
        first time: scikit-learn and the model file). A model that cannot be loaded is reported there."""
        with contextlib.suppress(Exception):
            _ = self.model

    def shutdown(self) -> None:
        """Abort a running scan (Peltier off, devices released); cancel an export and delete its file; finish
        writing the figures a save kept."""
        self.operations.shutdown()
        self.exports.shutdown()
        self.figures.wait(10)


def context() -> Context:
    """The running app's :class:`Context`."""
    return current_app.extensions["texplorer"]
