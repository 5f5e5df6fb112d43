"""The database browser (docs/operator.md): materials, samples, scans, one scan's traces, photos and feature values,
the export of the feature table, and export bundles built in the background (:mod:`gui.exports`).

Pages read the catalog (``scanner.storage.database.Database``); a scan page loads the scan's ``.mat`` file. The
trace figure is ``taxonomy.reports.plots.plot_scan``, drawn once per scan content and kept in the app's cache
folder. Feature values come from ``features.extract_many`` with the database as cache, so a scan is only
extracted the first time it is shown (or never, after ``texplorer features``).
"""

from __future__ import annotations

import io
import math
import os
import tempfile
from collections import defaultdict
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from flask import Blueprint, abort, flash, jsonify, redirect, render_template, request, send_file, url_for
from werkzeug.wrappers import Response

from features import REGISTRY
from gui import figures
from gui.context import context
from gui.exports import ExportBusy, ExportError, ExportJob
from scanner.scan import CHANNELS, IMAGES
from scanner.storage.database import DatabaseError, ScanRecord
from scanner.storage.files import temp_path_for
from scanner.storage.metadata import MetadataError, checked_creator, license_url
from scanner.storage.settings import read_settings
from scanner.workflows.database import extract_database, stored_features
from taxonomy.labels import Label, LabelError
from taxonomy.learning.versions import VersionError, current_version, use_version, versions
from taxonomy.reports.plots import plot_scan
from taxonomy.table import Taxonomy, material_code, select_labels

blueprint = Blueprint("database", __name__)

SESSION_CHOICES = 200
"""Sessions offered in the export form's list (newest first); any other can still be typed."""


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
def overview() -> tuple[str, int]:
    try:
        settings = read_settings(context().db.root)
    except MetadataError as exc:
        flash(f"{exc}.", "bad")
        settings = {}
    return render_overview({"label": request.args.get("label", "")[:64],
                            "session": request.args.get("session", "")[:64],
                            "license": settings.get("license", ""), "creator": settings.get("creator", "")}, {})


@blueprint.get("/material/<label>")
def material(label: str) -> str:
    try:
        code = Label.parse(label[:64]).format()
    except LabelError as exc:
        abort(404, description=f"{exc}; the database page lists the materials it holds")
    records = [r for r in context().db.records(label=code) if r.label == code]
    if not records:
        abort(404, description=f"no scans of material {code} in the database")
    by_sample: dict[str, list[ScanRecord]] = defaultdict(list)
    for record in records:
        by_sample[record.sample_id].append(record)
    description = describe(context().db.taxonomy(), code)
    return render_template("db_material.html", label=code, description=description, samples=by_sample)


LabelMatch = Callable[[str], bool]


def label_filter(text: str, taxonomy: Taxonomy) -> tuple[str | None, LabelMatch | None]:
    """What the scans page's label field selects: ``(code prefix, None)`` for a label or class prefix
    (``C6`` = every stone, as ``texplorer export --label``), ``(None, match)`` for part of a material, sub-class
    or class name (``granite``, ``Oak``, ``stone``: the taxonomy picker's search), ``(None, None)`` when empty
    (``taxonomy.table.select_labels``, which the command line's ``--label`` reads too).

    Raises
    ------
    LabelError
        One line: the text is neither a prefix nor part of any name in the taxonomy.
    """
    prefix, materials = select_labels(text, lambda: taxonomy)
    return prefix, None if materials is None else (lambda label: material_code(label) in materials)


def starts_like(value: str, typed: str) -> bool:
    """Whether ``value`` begins with ``typed``, ignoring case (``granite`` finds granite-01, ``ann`` Ann)."""
    return value.casefold().startswith(typed.casefold())


def scan_rows(records: Iterable[ScanRecord], match: LabelMatch | None, sample: str,
              operator: str) -> list[ScanRecord]:
    """The records a person's search selects: a material name, sample and operator prefixes, any case."""
    return [record for record in records
            if (match is None or match(record.label)) and starts_like(record.sample_id, sample)
            and starts_like(record.operator, operator)]


@blueprint.get("/scans")
def scans() -> tuple[str, int]:
    filters = {key: request.args.get(key, "").strip()[:64] for key in ("label", "sample", "operator")}
    db = context().db
    try:
        prefix, match = label_filter(filters["label"], db.taxonomy())
    except ValueError as exc:
        return render_template("db_scans.html", records=[], filters=filters,
                               errors={"label": str(exc)}), 422
    records = scan_rows(db.records(label=prefix), match, filters["sample"], filters["operator"])
    return render_template("db_scans.html", records=records, filters=filters, errors={}), 200


def feature_values(record: ScanRecord) -> tuple[dict[str, float], str | None]:
    """The features of a stored scan from the database's cache (extracted and cached if missing)."""
    return stored_features(context().db, record)


def group_features(values: dict[str, float]) -> list[tuple[str, list[tuple[str, str]]]]:
    """Feature values by modality for display: ``[(title, [(short name, formatted value), ...]), ...]``."""
    groups = []
    for prefix, title in REGISTRY.groups:
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
                           figures=figures.step_figures(stored.traces, stored.meta.rigid),
                           channels=CHANNELS, missing=stored.missing_channels(), files=db.files(scan_id),
                           photos=photos, features=group_features(values), failure=failure,
                           description=describe(db.taxonomy(), record.label))


def plot_file(record: ScanRecord) -> Path:
    """The cached trace figure of a scan, drawn by ``plot_scan`` on first request (atomic rename)."""
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


@blueprint.get("/scan/<scan_id>/traces/<step>.png")
def step_png(scan_id: str, step: str) -> Response:
    """One step's figure (``gui.figures``): kept at save for the web app's scans, else drawn once."""
    record = _record(scan_id)
    if step not in figures.RECORDED:
        abort(404, description=f"there is no recording step {step[:40]!r}")
    path = figures.cached_path(context().plot_dir, record.content_hash, step)
    kept = context().figures.pending(path)
    if kept is not None:  # kept by the save, still being written
        return send_file(io.BytesIO(kept), mimetype="image/png", max_age=3600)
    if not path.is_file():
        path = figures.stored_figure(context().plot_dir, record.content_hash, context().db.get(scan_id), step)
    return send_file(path, mimetype="image/png", max_age=3600)


@blueprint.get("/scan/<scan_id>/photo/<variable>")
def photo(scan_id: str, variable: str) -> Response:
    record = _record(scan_id)
    entry = next((e for e in context().db.files(record.scan_id) if e.role == variable), None)
    if entry is None:
        abort(404, description=f"scan {scan_id} has no photo {variable!r}")
    return send_file(context().db.root / entry.path, mimetype="image/png", max_age=3600)


@blueprint.get("/export/features.csv")
def export_features() -> Response:
    """The feature space of every scan (docs/evaluation.md) as CSV, from the database's feature cache."""
    ctx = context()
    try:
        space = extract_database(ctx.db, workers=ctx.settings.workers, partial=False)
    except DatabaseError as exc:
        abort(404, description=str(exc))
    with tempfile.TemporaryDirectory(prefix="texplorer-features-") as scratch:  # nothing kept on the server
        data = space.to_csv(Path(scratch) / "features.csv").read_bytes()
    return send_file(io.BytesIO(data), mimetype="text/csv", as_attachment=True, download_name="features.csv",
                     max_age=0)


LICENSE_CHARS = 500
"""Longest license URL or creator the export form takes."""


def license_errors(license: str, creator: str) -> dict[str, str]:
    """The export form's license and creator errors by field (``texplorer export --license/--creator``)."""
    errors = {}
    if not license:
        errors["license"] = "give the bundle a license: an SPDX identifier (CC-BY-4.0, CC0-1.0), a URL, or none"
    else:
        try:
            license_url(license)
        except MetadataError as exc:
            errors["license"] = str(exc).replace("--license none", "none")
    try:
        checked_creator(creator)
    except MetadataError as exc:
        errors["creator"] = str(exc)
    return errors


def export_form(records: Iterable[ScanRecord]) -> dict[str, Any]:
    """What the export form offers: the sessions of the database, newest first, for the session field."""
    sessions: dict[str, ScanRecord] = {}
    for record in sorted(records, key=lambda r: r.started, reverse=True):
        sessions.setdefault(record.session_id, record)
    return {"sessions": [(sid, f"{r.label} {r.sample_id}, {r.started[:16].replace('T', ' ')}")
                         for sid, r in list(sessions.items())[:SESSION_CHOICES]]}


def render_overview(form: dict[str, str], errors: dict[str, str], status: int = 200) -> tuple[str, int]:
    db = context().db
    records = db.records()
    return render_template("db_overview.html", summary=db.summary(),
                           materials=material_rows(records, db.taxonomy()), form=form, errors=errors,
                           job=context().exports.job, **export_form(records)), status


@blueprint.post("/export")
def start_export() -> tuple[str, int] | Response:
    """Start a background export of the scans matching the form's label and session (``texplorer export``)."""
    form = {key: request.form.get(key, "").strip()[:64] for key in ("label", "session")}
    form |= {key: request.form.get(key, "").strip()[:LICENSE_CHARS] for key in ("license", "creator")}
    try:  # a label or class prefix (spelled canonically: c6 -> C6) or part of a name, as texplorer export --label
        prefix, _ = select_labels(form["label"], context().db.taxonomy)
    except ValueError as exc:
        return render_overview(form, {"label": str(exc)}, 422)
    errors = license_errors(form["license"], form["creator"])
    if errors:
        return render_overview(form, errors, 422)
    label = prefix or form["label"] or None
    try:
        job = context().exports.start(label=label, session=form["session"] or None, license=form["license"],
                                      creator=form["creator"] or None)
    except ExportBusy as exc:
        flash(f"{exc}.", "bad")
        return redirect(url_for("database.export_job", job_id=exc.job.id))
    except ExportError as exc:
        return render_overview(form, {"export": str(exc)}, 409)
    return redirect(url_for("database.export_job", job_id=job.id))


def _job(job_id: str) -> ExportJob:
    job = context().exports.get(job_id[:64])
    if job is None:
        abort(404, description="there is no such export (it was replaced by a newer one, or the server was "
                               "restarted); start the export again")
    job.touch()
    return job


def render_job(job: ExportJob, refused: str = "", status: int = 200) -> tuple[str, int]:
    """The job's page: its progress, its bundle to download, or (taken, cancelled, failed) a new export."""
    return render_template("db_export.html", job=job, status=job.status(), refused=refused,
                           config_abandon=context().settings.export_abandon_s), status


@blueprint.get("/export/<job_id>")
def export_job(job_id: str) -> tuple[str, int]:
    return render_job(_job(job_id))


@blueprint.get("/export/<job_id>/status")
def export_status(job_id: str) -> Response:
    """The job's progress for the page's poll (which also keeps the job from counting as abandoned)."""
    job = _job(job_id)
    answer = job.status()
    if answer["ready"]:
        answer["download"] = url_for("database.export_download", job_id=job.id)
    return jsonify(answer)


@blueprint.get("/export/<job_id>/bundle.zip")
def export_download(job_id: str) -> tuple[str, int] | Response:
    """Stream the finished bundle; it is deleted here as the download starts (it can be taken once).

    Without a bundle to take (taken already: the page's automatic download, then a tap on its link, which a
    page without script still shows; not built yet; deleted) the answer is 409 with the job's page: why,
    and once the job has ended a new export instead of the dead link.
    """
    job = _job(job_id)
    try:
        handle, name, size = context().exports.take(job)
    except ExportError as exc:
        return render_job(job, refused=str(exc), status=409)
    response = send_file(handle, mimetype="application/zip", as_attachment=True, download_name=name, max_age=0)
    response.content_length = size
    return response


@blueprint.post("/export/<job_id>/cancel")
def export_cancel(job_id: str) -> Response:
    job = _job(job_id)
    context().exports.cancel(job)
    flash(f"The export of {job.filters} was cancelled; nothing was kept.", "good")
    return redirect(url_for("database.overview"))


# -- model versions -----------------------------------------------------------------------------------


@blueprint.get("/models")
def models() -> tuple[str, int]:
    """The database's model versions (as ``texplorer models``), the background training and its queue."""
    ctx = context()
    try:
        found, current = versions(ctx.db.root), current_version(ctx.db.root)
    except VersionError as exc:
        flash(f"{exc}.", "bad")
        found, current = [], None
    fixed = ctx.settings.model  # serve --model: that file, whatever the database's current version
    return render_template("db_models.html", versions=list(reversed(found)), current=current, fixed=fixed,
                           job=ctx.trainings.job, queued=ctx.trainings.queued), 200


@blueprint.post("/models/train")
def train_model() -> Response:
    """Train a new model version on every scan now, in the background (:mod:`gui.training`)."""
    ctx = context()
    if not ctx.db.records():
        flash("There are no scans to train a model on.", "bad")
    else:
        started = ctx.trainings.start("asked for on the models page")
        flash("A new model version is being trained in the background" + ("" if started else
              ", after the one running now") + ".", "good")
    return redirect(url_for("database.models"))


@blueprint.post("/models/use")
def use_model() -> Response:
    """Make an older (or newer) model version current again: the next prediction uses it."""
    wanted = request.form.get("version", "")[:12]
    try:
        chosen = use_version(context().db.root, wanted)
    except VersionError as exc:
        flash(f"No version was made current: {exc}.", "bad")
    else:
        flash(f"Version {chosen.version} is current: the next prediction uses it.", "good")
    return redirect(url_for("database.models"))
