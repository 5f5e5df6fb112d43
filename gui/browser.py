"""The database browser (SPEC 10): materials, samples, scans, one scan's traces, photos and feature values,
and the export of the feature table.

Pages read the catalog (``scanner.database.Database``); a scan page loads the scan's ``.mat`` file. The
trace figure is ``taxonomy.plots.plot_scan``, drawn once per scan content and kept in the app's cache
folder. Feature values come from ``features.extract_many`` with the database as cache, so a scan is only
extracted the first time it is shown (or never, after ``texplorer features``).
"""

from __future__ import annotations

import functools
import math
import os
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from flask import Blueprint, abort, render_template, request, send_file
from werkzeug.wrappers import Response

from gui.app import context
from scanner.database import DatabaseError, ScanRecord
from scanner.files import temp_path_for
from scanner.scan import CHANNELS, IMAGES
from taxonomy.table import Taxonomy

blueprint = Blueprint("database", __name__)

FEATURE_GROUPS = (("tactum", "TacTUM (paper section IV-A)"), ("image.disp", "image: photo"),
                  ("image.macro", "image: macro lens"), ("image.illu", "image: flash"),
                  ("audio.finger", "audio: finger slide"), ("audio.tool", "audio: tool slide"),
                  ("other", "other"))


@dataclass(frozen=True)
class MaterialRow:
    """One material of the overview: its label, the taxonomy's words for it, its samples and scans."""

    label: str
    description: str
    samples: tuple[str, ...]
    scans: int


def describe(taxonomy: Taxonomy, label: str) -> str:
    """The taxonomy's text for a label, or a note if the table does not know it."""
    try:
        return taxonomy.describe(label)
    except ValueError:
        return "(not in the taxonomy table)"


def material_rows(records: Iterable[ScanRecord], taxonomy: Taxonomy) -> list[MaterialRow]:
    """Materials in label order with their samples and scan counts."""
    samples: dict[str, set[str]] = defaultdict(set)
    scans: dict[str, int] = defaultdict(int)
    for record in records:
        samples[record.label].add(record.sample_id)
        scans[record.label] += 1
    return [MaterialRow(label, describe(taxonomy, label), tuple(sorted(samples[label])), scans[label])
            for label in sorted(samples)]


def _record(scan_id: str) -> ScanRecord:
    try:
        return context().db.record(scan_id)
    except DatabaseError:
        abort(404, description=f"there is no scan {scan_id!r} in the database")


@blueprint.get("/")
def overview() -> str:
    db = context().db
    return render_template("db_overview.html", summary=db.summary(),
                           materials=material_rows(db.records(), db.taxonomy()))


@blueprint.get("/material/<label>")
def material(label: str) -> str:
    records = [r for r in context().db.records(label=label) if r.label == label]
    if not records:
        abort(404, description=f"no scans of material {label!r} in the database")
    by_sample: dict[str, list[ScanRecord]] = defaultdict(list)
    for record in records:
        by_sample[record.sample_id].append(record)
    description = describe(context().db.taxonomy(), label)
    return render_template("db_material.html", label=label, description=description, samples=by_sample)


@blueprint.get("/scans")
def scans() -> str:
    filters = {key: request.args.get(key, "").strip()[:64] for key in ("label", "sample", "operator")}
    records = context().db.records(**{k: v or None for k, v in filters.items()})
    return render_template("db_scans.html", records=records, filters=filters)


def feature_values(record: ScanRecord) -> tuple[dict[str, float], str | None]:
    """The 193 features of a stored scan from the database's cache (extracted and cached if missing)."""
    from features import ScanSource, extract_many
    from scanner.matfile import load_scan

    db = context().db
    source = ScanSource(record.scan_id, record.label, record.sample_id,
                        functools.partial(load_scan, db.root / record.path), cache_key=record.content_hash)
    space = extract_many([source], workers=1, cache=db, progress=False)
    if space.failed:
        return {}, space.failed[0][1]
    return dict(zip(space.columns, space.X[0].tolist(), strict=True)), None


def group_features(values: dict[str, float]) -> list[tuple[str, list[tuple[str, str]]]]:
    """Feature values by modality for display: ``[(title, [(short name, formatted value), ...]), ...]``."""
    groups = []
    for prefix, title in FEATURE_GROUPS:
        rows = [(name[len(prefix) + 1:], _format(value)) for name, value in values.items()
                if name.startswith(prefix + ".")]
        if rows:
            groups.append((title, rows))
    return groups


def _format(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.6g}"


@blueprint.get("/scan/<scan_id>")
def scan(scan_id: str) -> str:
    record = _record(scan_id)
    db = context().db
    stored = db.get(scan_id, images=False)
    values, failure = feature_values(record)
    photos = [(variable, IMAGES[variable]) for variable in IMAGES
              if any(entry.role == variable for entry in db.files(scan_id))]
    return render_template("db_scan.html", record=record, meta=stored.meta, traces=stored.traces,
                           channels=CHANNELS, missing=stored.missing_channels(), files=db.files(scan_id),
                           photos=photos, features=group_features(values), failure=failure,
                           description=describe(db.taxonomy(), record.label))


def plot_file(record: ScanRecord) -> Path:
    """The cached trace figure of a scan, drawn by ``plot_scan`` on first request (atomic rename)."""
    from taxonomy.plots import plot_scan

    ctx = context()
    path = ctx.plot_dir / f"{record.content_hash}.png"
    if not path.is_file():
        ctx.plot_dir.mkdir(parents=True, exist_ok=True)
        scratch = temp_path_for(path).with_suffix(".png")
        plot_scan(ctx.db.get(record.scan_id), scratch, title=f"{record.label}  {record.scan_id}")
        os.replace(scratch, path)
    return path


@blueprint.get("/scan/<scan_id>/traces.png")
def traces_png(scan_id: str) -> Response:
    return send_file(plot_file(_record(scan_id)), mimetype="image/png", max_age=3600)


@blueprint.get("/scan/<scan_id>/photo/<variable>")
def photo(scan_id: str, variable: str) -> Response:
    record = _record(scan_id)
    entry = next((e for e in context().db.files(record.scan_id) if e.role == variable), None)
    if entry is None:
        abort(404, description=f"scan {scan_id} has no photo {variable!r}")
    return send_file(context().db.root / entry.path, mimetype="image/png", max_age=3600)


@blueprint.get("/export/features.csv")
def export_features() -> Response:
    """The feature space of every scan (SPEC 8) as CSV, from the database's feature cache."""
    from scanner.cli import feature_space

    ctx = context()
    try:
        space = feature_space(ctx.db, ctx.settings.workers)
    except DatabaseError as exc:
        abort(404, description=str(exc))
    export_dir = ctx.settings.work_dir / "exports"
    export_dir.mkdir(parents=True, exist_ok=True)
    path = space.to_csv(export_dir / "features.csv")
    return send_file(path, mimetype="text/csv", as_attachment=True, download_name="features.csv", max_age=0)


@blueprint.get("/export/bundle.zip")
def export_bundle() -> Response:
    """The export bundle of SPEC 11 (``scanner.bundle.export_bundle``) of every scan, as one ZIP file."""
    from datetime import UTC, datetime

    from scanner.bundle import BundleError
    from scanner.bundle import export_bundle as write_bundle

    ctx = context()
    export_dir = ctx.settings.work_dir / "exports"
    for old in export_dir.glob("texplorer-export-*.zip"):
        old.unlink(missing_ok=True)
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%S")
    try:
        report = write_bundle(ctx.db, export_dir / f"texplorer-export-{stamp}.zip",
                              workers=ctx.settings.workers)
    except BundleError as exc:
        abort(409, description=str(exc))
    return send_file(report.path, mimetype="application/zip", as_attachment=True,
                     download_name=report.path.name, max_age=0)
