"""The trace figures of the summary and scan pages: one per recorded step, each drawn once.

A figure of the whole scan (``taxonomy.reports.plots.plot_scan``, 16 panels) takes about ten seconds to draw on a
busy two-core machine and its text shrinks to about 5 px on a tablet. A step's figure
(``taxonomy.reports.plots.plot_step``, 800 px wide, one panel per row) is drawn when the operator checks the step's
recording; the summary shows those same figures again, and saving the scan keeps them in the app's plot
cache under the saved file's content hash, so the saved scan's page shows them without drawing anything.
Scans stored otherwise (``texplorer demo``, ``import``) have theirs drawn on first view, once.
"""

from __future__ import annotations

import io
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


def keep(plot_dir: Path, content_hash: str, figures: Mapping[str, bytes]) -> None:
    """Store a scan's step figures under its content hash (atomic writes; the figures drawn in the session
    are those of the saved file: same traces, same title)."""
    for step, png in figures.items():
        atomic_write_bytes(cached_path(plot_dir, content_hash, step), png)


def stored_figure(plot_dir: Path, content_hash: str, scan: Scan, step: str) -> Path:
    """The cached figure of one step of a stored scan, drawn on first request."""
    path = cached_path(plot_dir, content_hash, step)
    if not path.is_file():
        meta = scan.meta
        atomic_write_bytes(path, draw(scan.traces, step, meta.label, meta.sample_id, t_amb=meta.t_amb,
                                      rigid=meta.rigid))
    return path
