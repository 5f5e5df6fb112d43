"""The trace figures of the summary and scan pages: one per recorded step, each drawn once.

A figure of the whole scan (``taxonomy.reports.plots.plot_scan``, 16 panels) takes about ten seconds to draw on a
busy two-core machine and its text shrinks to about 5 px on a tablet. A step's figure
(``taxonomy.reports.plots.plot_step``, 800 px wide, one panel per row) is drawn when the operator checks the step's
recording; the summary shows those same figures again, and saving the scan keeps them in the app's plot
cache under the saved file's content hash, so the saved scan's page shows them without drawing anything.
Scans stored otherwise (``texplorer demo``, ``import``) have theirs drawn on first view, once.
"""

from __future__ import annotations

import contextlib
import io
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from scanner.acquisition.session import STEP_TITLES
from scanner.scan import CHANNELS, Scan, Trace
from scanner.storage.files import atomic_write_bytes
from taxonomy.reports.plots import plot_step

RECORDED = tuple(step for step in STEP_TITLES if any(spec.step == step for spec in CHANNELS.values()))
"""The steps that record channels, in the order of the procedure (the photos and TU4 record none)."""


@dataclass(frozen=True)
class StepFigure:
    """What one step shows on a page: its figure, or why there is none (skipped as rigid, not recorded)."""

    step: str
    number: int
    title: str
    drawn: bool
    note: str = ""


def title_of(step: str, label: str, sample_id: str) -> str:
    """The figure's title, the same before and after the scan is saved: ``Step 2: TU1 finger slide, ...``."""
    number, title = STEP_TITLES[step]
    return f"Step {number}: {title}, {label} {sample_id}"


def draw(traces: Mapping[str, Trace], step: str, label: str, sample_id: str, *, t_amb: float,
         rigid: bool) -> bytes:
    """The PNG of one step's channels (``taxonomy.reports.plots.plot_step``), drawn in memory."""
    buffer = io.BytesIO()
    plot_step(traces, step, buffer, title_of(step, label, sample_id), t_amb=t_amb, rigid=rigid)
    return buffer.getvalue()


def step_figures(traces: Mapping[str, Trace], rigid: bool) -> list[StepFigure]:
    """For every recording step: drawn if the scan has any of its channels, else the reason it has none."""
    figures = []
    for step in RECORDED:
        number, title = STEP_TITLES[step]
        recorded = any(spec.step == step and name in traces for name, spec in CHANNELS.items())
        note = "" if recorded else ("skipped: rigid sample" if step == "fold" and rigid else "not recorded")
        figures.append(StepFigure(step, number, title, recorded, note))
    return figures


def cached_path(plot_dir: Path, content_hash: str, step: str) -> Path:
    return plot_dir / f"{content_hash}-{step}.png"


class Keeper:
    """Writes the figures a save keeps into the plot cache in a thread of its own, so the save does not wait
    for the disk (an atomic write with fsync per figure); until a figure is written, :meth:`pending` has it."""

    def __init__(self) -> None:
        self._pending: dict[Path, bytes] = {}
        self._lock = threading.Lock()
        self._threads: list[threading.Thread] = []

    def keep(self, plot_dir: Path, content_hash: str, figures: Mapping[str, bytes]) -> threading.Thread:
        """Store a scan's step figures under its content hash (the figures drawn in the session are those of
        the saved file: same traces, same title); returns the writing thread."""
        paths = {cached_path(plot_dir, content_hash, step): png for step, png in figures.items()}
        with self._lock:
            self._pending.update(paths)
        thread = threading.Thread(target=self._write, args=(paths,), name="keep-figures", daemon=True)
        thread.start()
        self._threads = [t for t in self._threads if t.is_alive()] + [thread]
        return thread

    def wait(self, timeout: float | None = None) -> None:
        """Wait until the figures kept so far are written (the server's stop, tests)."""
        for thread in list(self._threads):
            thread.join(timeout)

    def _write(self, paths: Mapping[Path, bytes]) -> None:
        for path, png in paths.items():
            with contextlib.suppress(OSError):  # only a cache: the scan's page draws what is missing
                atomic_write_bytes(path, png)
            with self._lock:
                self._pending.pop(path, None)

    def pending(self, path: Path) -> bytes | None:
        with self._lock:
            return self._pending.get(path)


def stored_figure(plot_dir: Path, content_hash: str, scan: Scan, step: str) -> Path:
    """The cached figure of one step of a stored scan, drawn on first request."""
    path = cached_path(plot_dir, content_hash, step)
    if not path.is_file():
        meta = scan.meta
        atomic_write_bytes(path, draw(scan.traces, step, meta.label, meta.sample_id, t_amb=meta.t_amb,
                                      rigid=meta.rigid))
    return path
