"""The guided session the web application is running, and the watchdog that keeps the Peltier safe.

The scanner is one device, so the app runs at most one :class:`scanner.acquisition.session.Session` at a time. An
:class:`Operation` wraps it with what only the web pages need: the staged photo files shown as previews,
the operator form as typed, a change counter that keys the summary's cached plot and prediction, and the
time the browser last asked for the recording's status.

Peltier safety (docs/devices.md: the Peltier is switched off if the browser disconnects during heating):
while a step records, the page polls its status several times a second. :class:`Operations` runs a
watchdog thread that cancels the recording (``Session.cancel_step``: the recorder switches the Peltier off
on that exit path) when the step is heating and the browser has been silent for ``heartbeat_timeout_s``:
a closed tab, a crashed browser, a dropped network or a laptop gone to sleep. Heating itself is bounded
to 5 s by the session; the watchdog ends it sooner when nobody is watching.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from gui.photos import PhotoStore
from scanner.acquisition.session import Session, SessionState
from taxonomy.errors import TexplorerError

WATCHDOG_PERIOD_S = 0.25


@dataclass
class Operation:
    """One running session and the web pages' state beside it."""

    session: Session
    photos: dict[str, str] = field(default_factory=dict)
    """Photo variable -> staged PNG name (the preview of what the session holds)."""
    photo_sources: dict[str, str] = field(default_factory=dict)
    """Photo variable -> "upload" or "camera"."""
    draft: dict[str, str] = field(default_factory=dict)
    """The operator form's fields as last typed, valid or not, to refill the form."""
    version: int = 0
    """Increases with every change of the scan to be saved."""
    last_seen: float = field(default_factory=time.monotonic)
    cancelled_by_watchdog: str = ""
    summary_cache: dict[str, Any] = field(default_factory=dict)
    step_figures: dict[str, tuple[Any, str, bytes]] = field(default_factory=dict)
    """Step -> (the recording it shows, what else it depends on, PNG): drawn once, kept across changes
    (``gui.figures``)."""
    quick: Any = None
    """A quick identification's :class:`scanner.workflows.quick.QuickIdentifier` (docs/quick.md), else None."""
    quick_full: bool = False
    """The operator went on from the quick identification to the full scan."""
    unlabelled: bool = False
    """The scan started without a label: the quick prediction names it."""
    quick_cache: tuple[int, Any] | None = None

    def quick_state(self) -> Any:
        """The quick identification after the steps done so far (:meth:`QuickIdentifier.assess`), kept until
        the scan changes."""
        if self.quick_cache is None or self.quick_cache[0] != self.version:
            session = self.session
            self.quick_cache = (self.version, self.quick.assess(session.scan(partial=True), session.recorded_steps()))
        return self.quick_cache[1]

    def touch(self) -> None:
        """The browser is still there."""
        self.last_seen = time.monotonic()

    def changed(self) -> None:
        self.version += 1
        self.summary_cache.clear()

    @property
    def heating(self) -> bool:
        level = self.session.level
        return self.session.running and level is not None and level.phase == "heating"


class SessionBusy(TexplorerError, RuntimeError):
    """A session is already running; the scanner has one set of devices."""


class Operations:
    """The app's one running :class:`Operation` (or none) and its Peltier watchdog thread."""

    def __init__(self, photos: PhotoStore, heartbeat_timeout_s: float) -> None:
        self.photos = photos
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.active: Operation | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._watchdog: threading.Thread | None = None

    def begin(self, open_session: Callable[[], Session]) -> Operation:
        """Open a session with ``open_session()`` unless one is running; start the watchdog."""
        with self._lock:
            if self.active is not None and self.active.session.state is SessionState.OPEN:
                raise SessionBusy("a scan is already in progress; continue it or abort it first")
            self.active = Operation(open_session())
            if self._watchdog is None:
                self._watchdog = threading.Thread(target=self._watch, name="peltier-watchdog", daemon=True)
                self._watchdog.start()
            return self.active

    def end(self, operation: Operation) -> None:
        """Forget a saved or aborted operation and delete its staged photos."""
        with self._lock:
            if operation.session.state is SessionState.OPEN:
                operation.session.abort()
            self.photos.discard(operation.photos.values())
            if self.active is operation:
                self.active = None

    def check_heartbeat(self, now: float | None = None) -> bool:
        """Cancel a heating step whose browser went silent; True if it did."""
        operation = self.active
        if operation is None or not operation.heating:
            return False
        silent = (time.monotonic() if now is None else now) - operation.last_seen
        if silent <= self.heartbeat_timeout_s:
            return False
        operation.cancelled_by_watchdog = (f"the browser stopped responding for {silent:.1f} s while the "
                                           "Peltier was heating, so heating was stopped; redo this step")
        operation.session.cancel_step()
        operation.changed()
        return True

    def _watch(self) -> None:
        while not self._stop.wait(WATCHDOG_PERIOD_S):
            self.check_heartbeat()

    def shutdown(self) -> None:
        """Abort a running session (Peltier off, devices released) and stop the watchdog."""
        self._stop.set()
        if self.active is not None:
            self.end(self.active)
