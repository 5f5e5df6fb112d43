"""The operator's pages (docs/operator.md): start a scan, the guided steps, the operator form, the summary.

Every page is a view of the running :class:`scanner.acquisition.session.Session` (through
:mod:`gui.live_session`); every action is one session call: ``Session.open``, ``start_step``, ``cancel_step``,
``redo``, ``skip``, ``set_photo``, ``capture_photo``, ``set_values``, ``t_amb``, ``save`` and ``abort``. Input
is validated by :mod:`gui.forms` first so that each reason appears beside its field; the session checks again
and its refusals are shown too. The database is written once, by ``Session.save``; an abort or an error before
it leaves the database as it was.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import threading
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from flask import Blueprint, abort, flash, jsonify, redirect, render_template, request, send_file, url_for
from flask import session as browser_session
from werkzeug.wrappers import Response

from features import extract, feature_sets
from features.extraction import code_version
from features.space import FeatureSpaceError
from gui import figures
from gui.context import context
from gui.forms import (
    TACK_CHOICES,
    VOLUME_METHOD_WORDS,
    YIELDING_CHOICES,
    FormErrors,
    parse_ambient,
    validate_operator,
    validate_start,
)
from gui.live_session import Operation, SessionBusy
from gui.photos import UploadError, check_size, check_upload, file_size
from scanner.acquisition.config import ConfigError
from scanner.acquisition.devices.protocols import DeviceError
from scanner.acquisition.session import VOLUME_METHODS, Session, SessionError, StepInfo, StepState
from scanner.scan import CHANNELS, IMAGES
from scanner.simulation import is_hand_set
from scanner.storage.database import DatabaseError, ScanRecord
from scanner.workflows.predictions import LabelCheck, check_label, predict_values
from scanner.workflows.quick import QuickIdentifier
from taxonomy.learning.evaluation import EvaluationError
from taxonomy.learning.models import ModelError, TrainedModel
from taxonomy.learning.quick import STOP_AT
from taxonomy.reports.plots import plot_scan

blueprint = Blueprint("operate", __name__)

PICKER_LIMIT = 40
"""Materials listed for one picker query; the operator narrows the search rather than scrolls."""

PHOTO_TITLES = {"I_disp": "Display photo", "I_macro": "Macro photo (4x lens)",
                "I_illu": "Illuminated photo (flash)"}
FORM_FIELDS = ("atk", "cyd", "mass_g", "volume_cm3", "volume_method", "notes")
TACTUM_TITLES = {
    "tactum.matx": "macrotexture MaTX", "tactum.maco": "macrotexture coarseness MaCO",
    "tactum.marg": "macrotexture regularity MaRG", "tactum.miro": "microtexture roughness MiRO",
    "tactum.mico": "microtexture coarseness MiCO (Hz)", "tactum.fst": "tactile stiction FST",
    "tactum.frs": "sliding resistance FRS", "tactum.atk": "adhesive tack ATK",
    "tactum.ccp": "tactile compliance CCP (N/mm)", "tactum.cdf": "local deformation CDF (deg)",
    "tactum.cdp": "damping CDP", "tactum.crx": "relaxation CRX (N)", "tactum.cyd": "yielding CYD",
    "tactum.tco": "thermal cooling TCO (K)", "tactum.tpr": "thermal persistence TPR (K)",
}
"""The 15 TacTUM features with the paper's names (Strese et al. 2020, section IV-A)."""

PHASE_TEXT = {
    "starting": "Starting the devices…",
    "recording": "Recording: carry on with the step",
    "heating": "Peltier heating: keep TU2 pressed on the surface",
    "cooling": "Cooling: hold the temperature sensor over the heated spot",
}
"""What the operator should be doing in each phase of a recording (``scanner.acquisition.recorder.Level.phase``)."""


# -- helpers -------------------------------------------------------------------------------------------


def operation() -> Operation:
    """The running operation, or a redirect to the start page when there is none."""
    active = context().operations.active
    if active is None:
        abort(redirect(url_for("operate.start")))
    return active


def sample_owner(sample_id: str) -> str | None:
    """The label the database stores for ``sample_id``, or None for a new sample."""
    records = context().db.records(sample=sample_id)
    return records[0].label if records else None


def step_url(step: StepInfo) -> str:
    if step.kind == "record":
        return url_for("operate.step", step_id=step.id)
    return url_for("operate.operator_form")


def next_url(session: Session) -> str:
    """The first step still to do, in procedure order; the summary when everything is done. In a quick
    identification (until the operator goes on to the full scan): its page, with the prediction and the step
    proposed next."""
    op = context().operations.active
    if op is not None and op.session is session and op.quick is not None and not op.quick_full:
        return url_for("operate.quick")
    for step in session.steps:
        if session.status(step.id).state not in (StepState.RECORDED, StepState.SKIPPED):
            return step_url(step)
    return url_for("operate.summary")


def step_chips(session: Session, current: str | None) -> list[dict[str, Any]]:
    """The progress strip: every step with its state and link."""
    return [{"title": f"{step.number}. {step.title}", "state": session.status(step.id).state.value,
             "current": step.id == current, "url": step_url(step)} for step in session.steps]


def render_page(template: str, http_status: int = 200, **values: Any) -> tuple[str, int]:
    op = context().operations.active
    chips = step_chips(op.session, values.get("current")) if op is not None else []
    return render_template(template, operation=op, chips=chips, **values), http_status


def session_error(exc: Exception) -> str:
    """A session or device refusal as one line for the page."""
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]


# -- start ---------------------------------------------------------------------------------------------


def render_start(form: dict[str, str], errors: dict[str, str], status: int = 200) -> tuple[str, int]:
    ctx = context()
    taxonomy = ctx.db.taxonomy()
    description = None
    if form.get("label") and "label" not in errors:
        try:
            description = taxonomy.describe(form["label"])
        except ValueError:
            description = None
    config = ctx.device_config
    return render_page("start.html", status, form=form, errors=errors, description=description,
                       processing=taxonomy.entries("P"), extras=taxonomy.entries("X"),
                       config_source=config.source, devices=dict(config.devices))


START_FIELDS = ("operator", "label", "sample_id")

KEPT_FORM = "start_form"
"""The browser session's key for the start form to show again: all of it after an abort (the same sample is
scanned again), the operator after a save (the next sample is another)."""


def provisional_label(identifier: QuickIdentifier | None, sample_id: str) -> str:
    """The label a quick identification without one starts under: the sample's, if the database has it (a sample
    cannot change its material), else the first trained material; the prediction replaces it before a save."""
    try:
        owner = sample_owner(sample_id.strip())
    except (ValueError, DatabaseError):
        owner = None
    return owner or str(identifier.model.classes[0])


def keep_start_form(session: Session, fields: tuple[str, ...]) -> None:
    """Fill the start form with ``fields`` of ``session`` the next time it is shown."""
    values = {"operator": session.operator, "label": session.label, "sample_id": session.sample_id}
    browser_session[KEPT_FORM] = {name: values[name] if name in fields else "" for name in START_FIELDS}


@blueprint.get("/")
def start() -> tuple[str, int]:
    kept = browser_session.get(KEPT_FORM)
    form = {name: str(kept.get(name, ""))[:200] if isinstance(kept, dict) else "" for name in START_FIELDS}
    return render_start(form, {})


@blueprint.post("/")
def begin() -> tuple[str, int] | Response:
    ctx = context()
    form = {key: request.form.get(key, "")[:200] for key in START_FIELDS}
    quick = request.form.get("quick") == "on"
    form["quick"] = "on" if quick else ""
    identifier = None
    if quick:
        try:
            identifier = ctx.quick_identifier()
        except (EvaluationError, FeatureSpaceError, DatabaseError) as exc:
            return render_start(form, {"quick": session_error(exc)}, 422)
    unlabelled = quick and not form["label"].strip()
    checked = dict(form, label=provisional_label(identifier, form["sample_id"]) if unlabelled else form["label"])
    try:
        values = validate_start(checked, ctx.db.taxonomy(), sample_owner)
    except FormErrors as exc:
        return render_start(form, exc.errors, 422)

    def open_session() -> Session:
        return Session.open(ctx.device_config, label=values.label, sample_id=values.sample_id,
                            operator=values.operator, db=ctx.db)

    try:
        op = ctx.operations.begin(open_session)
        op.quick, op.unlabelled = identifier, unlabelled
    except SessionBusy as exc:
        return render_start(form, {"form": str(exc)}, 409)
    except ConfigError as exc:
        # A label the simulated scanner cannot simulate (a class a lab added), or a bad simulated.material.
        return render_start(form, {"label": session_error(exc)}, 422)
    except (SessionError, DeviceError) as exc:
        return render_start(form, {"form": f"the scanner could not start: {session_error(exc)}"}, 422)
    browser_session.pop(KEPT_FORM, None)
    threading.Thread(target=ctx.warm_up, name="warm-up", daemon=True).start()
    return redirect(url_for("operate.overview"))


@blueprint.get("/api/taxonomy")
def api_taxonomy() -> Response:
    """Materials matching ``q`` (name or code prefix) for the picker: code, name, sub-class, major class,
    and with a simulated device whether the simulator's parameters are ``hand-set`` or ``derived``."""
    query = request.args.get("q", "")[:40]
    ctx = context()
    found = ctx.db.taxonomy().search(query)
    materials = [{"code": m.code, "name": m.name, "subclass": m.subclass, "major": m.major}
                 for m in found[:PICKER_LIMIT]]
    if "simulated" in ctx.device_config.devices.values():
        # Which of them the simulated scanner knows by hand-set parameters, and which it derives.
        for m in materials:
            m["simulation"] = "hand-set" if is_hand_set(m["code"]) else "derived"
    return jsonify(total=len(found), materials=materials)


@blueprint.get("/api/label")
def api_label() -> Response:
    """Whether ``label`` is a known label, with its description or the reason it is not."""
    label = request.args.get("label", "")[:40]
    taxonomy = context().db.taxonomy()
    try:
        return jsonify(ok=True, label=taxonomy.check(label).format(), description=taxonomy.describe(label))
    except ValueError as exc:
        return jsonify(ok=False, error=str(exc))


# -- the session's overview and ambient temperature ------------------------------------------------------


def render_overview(ambient: str, errors: dict[str, str], status: int = 200) -> tuple[str, int]:
    op = operation()
    description = context().db.taxonomy().describe(op.session.label)
    return render_page("session.html", status, session=op.session, ambient=ambient, errors=errors,
                       description=description, next=next_url(op.session))


def _ambient_text(value: float) -> str:
    return "" if math.isnan(value) else f"{value:.1f}"


@blueprint.get("/session")
def overview() -> tuple[str, int]:
    return render_overview(_ambient_text(operation().session.t_amb), {})


@blueprint.post("/session/ambient")
def set_ambient() -> tuple[str, int] | Response:
    op = operation()
    text = request.form.get("t_amb", "")[:40]
    try:
        op.session.t_amb = parse_ambient(text)
    except (ValueError, SessionError) as exc:
        return render_overview(text, {"t_amb": session_error(exc)}, 422)
    op.changed()
    flash(f"Ambient temperature set to {op.session.t_amb:g} °C.", "good")
    return redirect(url_for("operate.overview"))


ABORT_CONFIRMATION = "discard"
"""The value of the confirmation page's ``confirm`` field; an abort without it only asks."""


@blueprint.get("/session/abort")
def confirm_abort() -> tuple[str, int]:
    """Ask before discarding the scan, naming what would be lost (one mis-tap must not cost a scan)."""
    op = operation()
    return render_page("abort.html", session=op.session, work=op.session.work(), back=request_back())


def request_back() -> str:
    """Where "Keep scanning" returns to: the page the operator came from, if it is one of this app's."""
    back = request.values.get("back", "")[:200]
    return back if back.startswith("/session") and "//" not in back else url_for("operate.overview")


@blueprint.post("/session/abort")
def abort_session() -> tuple[str, int] | Response:
    ctx = context()
    op = ctx.operations.active
    if op is not None and request.form.get("confirm") != ABORT_CONFIRMATION:
        return confirm_abort()
    if op is not None:
        keep_start_form(op.session, START_FIELDS)
        ctx.operations.end(op)
    flash("The scan was aborted; nothing was saved. Operator, sample and label are filled in to start again.",
          "good")
    return redirect(url_for("operate.start"))


# -- recorded steps ----------------------------------------------------------------------------------------


def _record_step(session: Session, step_id: str) -> StepInfo:
    try:
        step = session.step(step_id)
    except SessionError:
        abort(404, description=f"there is no step {step_id!r}")
    if step.kind != "record":
        abort(redirect(url_for("operate.operator_form")))
    return step


@blueprint.get("/session/step/<step_id>")
def step(step_id: str) -> tuple[str, int]:
    op = operation()
    info = _record_step(op.session, step_id)
    op.touch()
    status = op.session.status(step_id)
    return render_page("step.html", step=info, status=status, current=step_id, next=next_url(op.session),
                       channels=CHANNELS,
                       watchdog=op.cancelled_by_watchdog if status.state is StepState.FAILED else "")


def _step_action(step_id: str, action: str) -> Response:
    op = operation()
    info = _record_step(op.session, step_id)
    session = op.session
    try:
        if action == "record":
            op.cancelled_by_watchdog = ""
            op.touch()
            session.start_step(step_id)
        elif action == "stop":
            session.cancel_step()
        elif action == "redo":
            session.redo(step_id)
        elif action == "skip":
            session.skip(step_id)
            op.changed()
            return redirect(next_url(session))
    except SessionError as exc:
        flash(session_error(exc), "bad")
    op.changed()
    return redirect(url_for("operate.step", step_id=info.id))


@blueprint.post("/session/step/<step_id>/<action>")
def step_action(step_id: str, action: str) -> Response:
    if action not in ("record", "stop", "redo", "skip"):
        abort(404, description=f"there is no step action {action!r}")
    return _step_action(step_id, action)


@blueprint.get("/session/status")
def status() -> Response:
    """The live state of the recording step for the page's poll (also the browser's heartbeat)."""
    op = context().operations.active
    if op is None:
        return jsonify(recording=False, next=url_for("operate.start"))
    op.touch()
    session = op.session
    level = session.level
    recording = session.running
    answer: dict[str, Any] = {"recording": recording, "next": None}
    if not recording:
        return jsonify(answer)
    if level is None:
        answer.update(phase="starting", level=0.0, level_text="", progress_text="", heating=False)
    else:
        answer.update(phase=level.phase, level=max(0.0, min(1.0, level.fraction)),
                      heating=level.phase == "heating",
                      level_text=f"{level.signal}: {level.value:.3g} {level.unit}",
                      progress_text=f"{level.elapsed_s:.1f} s of {level.duration_s:.1f} s")
    answer["phase_text"] = PHASE_TEXT.get(answer["phase"], answer["phase"])
    return jsonify(answer)


# -- photos and the TU4 form -------------------------------------------------------------------------------


def render_form(errors: dict[str, str], status: int = 200) -> tuple[str, int]:
    op = operation()
    values = op.session.values
    form = {name: op.draft.get(name, _value_text(values.get(name))) for name in FORM_FIELDS}
    settings = context().settings
    numbers = [step.number for step in op.session.steps if step.kind in ("photos", "form")]
    return render_page("form.html", status, form=form, errors=errors, current="photos", numbers=numbers,
                       tack=TACK_CHOICES, yielding=YIELDING_CHOICES,
                       methods=[(m, VOLUME_METHOD_WORDS.get(m, m)) for m in VOLUME_METHODS],
                       photos=[(name, PHOTO_TITLES[name], op.photos.get(name), op.photo_sources.get(name))
                               for name in IMAGES],
                       upload_limit=file_size(settings.upload_limit))


def _value_text(value: Any) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:g}"
    return value or ""


@blueprint.get("/session/form")
def operator_form() -> tuple[str, int]:
    return render_form({})


def _keep_photo(op: Operation, name: str, source: str) -> None:
    """Stage the photo the session now holds as ``name`` for the preview."""
    store = context().photos
    old = op.photos.get(name)
    op.photos[name] = store.put(op.session.photos[name])
    op.photo_sources[name] = source
    if old:
        store.discard([old])
    op.changed()


def _upload_photos(op: Operation) -> dict[str, str]:
    """Give every uploaded file to the session; the reasons for the refused ones by field."""
    settings = context().settings
    errors = {}
    for name in IMAGES:
        upload = request.files.get(name)
        if upload is None or not upload.filename:
            continue
        try:
            check_size(upload.stream.seek(0, os.SEEK_END), settings.upload_limit)
            upload.stream.seek(0)
            data = upload.stream.read()
            check_upload(data, max_bytes=settings.upload_limit, max_pixels=settings.max_photo_pixels)
            op.session.set_photo(name, data)
        except (UploadError, SessionError) as exc:
            errors[name] = session_error(exc).removeprefix(f"{name}: ")
            continue
        _keep_photo(op, name, "upload")
    return errors


@blueprint.post("/session/form")
def submit_form() -> tuple[str, int] | Response:
    op = operation()
    op.draft = {name: request.form.get(name, "")[:4000] for name in FORM_FIELDS}
    errors = _upload_photos(op)
    capture = request.form.get("capture", "")
    if capture:
        if capture not in IMAGES:
            abort(400, description=f"{capture[:20]!r} is not a photo")
        try:
            op.session.capture_photo(capture)
            _keep_photo(op, capture, "camera")
        except (SessionError, DeviceError) as exc:
            errors[capture] = session_error(exc)
        return render_form(errors, 422 if errors else 200)
    try:
        values = validate_operator(op.draft)
    except FormErrors as exc:
        errors.update(exc.errors)
    missing = [name for name in IMAGES if name not in op.session.photos and name not in errors]
    errors.update(dict.fromkeys(missing, "upload a PNG or JPEG photo or take it with the scanner's camera"))
    if errors:
        return render_form(errors, 422)
    try:
        op.session.set_values(**vars(values))
    except SessionError as exc:
        field, _, reason = session_error(exc).partition(": ")
        return render_form({field if field in FORM_FIELDS else "form": reason or field}, 422)
    op.changed()
    return redirect(next_url(op.session))


@blueprint.get("/session/photo/<variable>")
def staged_photo(variable: str) -> Response:
    op = operation()
    name = op.photos.get(variable)
    if name is None:
        abort(404, description=f"no {variable!r} photo yet")
    return send_file(context().photos.path(name), mimetype="image/png", max_age=0)


# -- summary and save -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Summary:
    """What the summary page shows of the scan about to be saved."""

    tactum: list[tuple[str, str]]
    predictions: list[tuple[str, float, str]] | None
    prediction_note: str
    notes: list[str]
    unknown: str = ""
    label_check: LabelCheck | None = None


def _format(value: float) -> str:
    return "NaN" if math.isnan(value) else f"{value:.4g}"


def summarise(op: Operation) -> Summary:
    """TacTUM values and the model's top three of the scan as it would be saved (cached per change)."""
    cached = op.summary_cache.get("summary")
    if cached is not None:
        return cached
    ctx = context()
    scan = op.session.scan(ctx.db.next_scan_index(op.session.sample_id))
    model, problem = _loaded_model()
    # the families the model's inputs need beside the paper's (a model of modern features)
    families = None if model is None else feature_sets.families_of(model.feature_names)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = extract(scan, families)
    notes = sorted({str(w.message) for w in caught})
    tactum = [(TACTUM_TITLES[name], _format(values[name])) for name in TACTUM_TITLES]
    predictions, note, unknown, check = (None, problem, "", None) if model is None else \
        _predict(model, values, op.session.label)
    summary = Summary(tactum, predictions, note, notes, unknown, check)
    op.summary_cache["summary"] = summary
    op.summary_cache["scan"] = scan
    op.summary_cache["values"] = values
    return summary


def within(seconds: float, fn: Callable[[], Any]) -> Any:
    """``fn()``, waited for at most ``seconds``: run in a thread of its own, so that a model that is slow to
    load or to predict (or never returns) cannot hold the summary page; raises :class:`ModelError` then
    (the thread is left to finish, as a daemon). Exceptions of ``fn`` are raised here."""
    outcome: dict[str, Any] = {}

    def run() -> None:
        try:
            outcome["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - handed to the waiting request below
            outcome["error"] = exc

    thread = threading.Thread(target=run, name="prediction", daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        raise ModelError(f"the model did not answer within {seconds:g} s; the scan can be saved without a "
                         "prediction")
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def _loaded_model() -> tuple[TrainedModel | None, str]:
    """The model (loaded once per server, waited for at most ``prediction_timeout_s``), or None and why."""
    ctx = context()
    try:
        model = within(ctx.settings.prediction_timeout_s, lambda: ctx.model)
    except ModelError as exc:
        return None, f"the model cannot be used: {session_error(exc)}"
    if model is None:
        return None, "no trained model: run 'texplorer train' (or 'texplorer demo') to see predictions here"
    return model, ""


Predicted = tuple[list[tuple[str, float, str]] | None, str, str, LabelCheck | None]


def _predict(model: TrainedModel, values: dict[str, float], label: str) -> Predicted:
    """The top three, a note on the model, "unknown material (closest: ...): why" when its rule rejects, and where
    the operator's ``label`` disagrees with the model (:func:`scanner.workflows.predictions.check_label`).
    A model that fails or takes longer than ``prediction_timeout_s`` gives no prediction and a one-line note
    instead; the scan stays ready to save."""
    ctx = context()
    taxonomy = ctx.db.taxonomy()  # read here: the database's connection belongs to this thread
    try:
        prediction = within(ctx.settings.prediction_timeout_s, lambda: predict_values(model, values, 3, taxonomy))
    except ModelError as exc:
        return None, f"no prediction: {session_error(exc)}", "", None
    except Exception as exc:  # noqa: BLE001 - a model from elsewhere may fail in any way; the scan must stay
        return None, f"no prediction: the model failed ({type(exc).__name__}: {session_error(exc)})", "", None
    named = [(p.label, p.probability, p.names) for p in prediction.predictions]
    unknown = prediction.headline() if prediction.unknown else ""
    note = f"{model.classifier} at level {model.level}, trained on {model.n_rows} scans"
    return named, note, unknown, check_label(label, prediction, model, taxonomy)


def session_figures(session: Session) -> list[figures.StepFigure]:
    """The summary's figures: every recorded step's, the note for a skipped fold."""
    shown = []
    for step in figures.RECORDED:
        info, state = session.step(step), session.status(step).state
        note = "skipped: rigid sample" if state is StepState.SKIPPED else ""
        shown.append(figures.StepFigure(step, info.number, info.title, state is StepState.RECORDED, note))
    return shown


@blueprint.get("/session/summary")
def summary() -> tuple[str, int] | Response:
    op = operation()
    missing = op.session.missing()
    if missing:
        return render_page("summary.html", 409, current=None, missing=missing, next=next_url(op.session))
    result = summarise(op)
    session = op.session
    return render_page("summary.html", current=None, missing=[], result=result, session=session,
                       values=session.values, rigid=session.rigid, figures=session_figures(session),
                       photos=[(name, PHOTO_TITLES[name], op.photos.get(name)) for name in IMAGES],
                       description=context().db.taxonomy().describe(session.label),
                       label_check=None if op.summary_cache.get("label_kept") else result.label_check)


def _png(draw: Callable[[io.BytesIO], None]) -> bytes:
    buffer = io.BytesIO()
    draw(buffer)
    return buffer.getvalue()


def _send_png(data: bytes) -> Response:
    return send_file(io.BytesIO(data), mimetype="image/png", max_age=0)


def _figure_inputs(session: Session, step_id: str) -> str:
    """What a step's figure shows besides its recording: the ambient temperature line of the cooling."""
    return f"{session.t_amb!r}" if step_id == "thermal" else ""


def current_figures(op: Operation) -> dict[str, bytes]:
    """The step figures already drawn that still show the session's recordings."""
    session = op.session
    return {step: png for step, (result, inputs, png) in list(op.step_figures.items())
            if result is session.result(step) and inputs == _figure_inputs(session, step)}


def step_figure(op: Operation, step_id: str) -> bytes:
    """The figure of a recorded step (``gui.figures``), drawn on its first view and reused by the summary
    and the saved scan's page."""
    session = op.session
    kept = current_figures(op).get(step_id)
    if kept is not None:
        return kept
    result = session.result(step_id)
    png = figures.draw(result.traces, step_id, session.label, session.sample_id, t_amb=session.t_amb,
                       rigid=session.rigid)
    op.step_figures[step_id] = (result, _figure_inputs(session, step_id), png)
    return png


@blueprint.get("/session/step/<step_id>/traces.png")
def step_traces(step_id: str) -> Response:
    """The traces of a recorded step, drawn by ``taxonomy.reports.plots.plot_step`` (once per recording)."""
    op = operation()
    info = _record_step(op.session, step_id)
    if op.session.result(step_id) is None or op.session.status(step_id).state is not StepState.RECORDED:
        abort(404, description=f"step {info.number} has no recording yet")
    return _send_png(step_figure(op, step_id))


@blueprint.get("/session/summary/traces.png")
def summary_traces() -> Response:
    """Every channel on one page (``taxonomy.reports.plots.plot_scan``), for a large screen; drawn only when asked."""
    op = operation()
    if op.session.missing():
        abort(409, description="the scan is not complete yet")
    summarise(op)
    if "plot" not in op.summary_cache:
        scan = op.summary_cache["scan"]
        title = f"{scan.meta.label}  {scan.scan_id} (not saved yet)"
        op.summary_cache["plot"] = _png(lambda out: plot_scan(scan, out, title=title))
    return _send_png(op.summary_cache["plot"])


def keep_for_the_scan_page(op: Operation, record: ScanRecord) -> None:
    """Keep what the session already computed for the page the save leads to: the step figures (plot
    cache) and the summary's feature values (the database's feature cache; the ``.mat`` round trip is exact,
    so they are the values ``texplorer features`` would compute for the stored file)."""
    ctx = context()
    ctx.figures.keep(ctx.plot_dir, record.content_hash, current_figures(op))
    scan, values = op.summary_cache.get("scan"), op.summary_cache.get("values")
    if scan is not None and values is not None and scan.scan_id == record.scan_id:
        with contextlib.suppress(DatabaseError):
            ctx.db.store_features(record.content_hash, code_version(), values)


@blueprint.post("/session/label")
def relabel() -> tuple[str, int] | Response:
    """The summary's answer to a label check: keep the operator's label, take the predicted one, or another
    (checked as on the start page: known to the taxonomy, and the sample's own material)."""
    op = operation()
    choice = request.form.get("choice", "")[:16]
    text = {"mine": op.session.label, "predicted": request.form.get("predicted", ""),
            "other": request.form.get("label", "")}.get(choice)
    if text is None:
        abort(400, description=f"choice must be mine, predicted or other, got {choice!r}")
    refused = _relabel(op, text[:200])
    if refused:
        flash(f"The label was not changed: {refused}", "bad")
        return redirect(url_for("operate.summary"))
    op.summary_cache["label_kept"] = choice == "mine"
    if choice != "mine":
        op.changed()
        flash(f"The scan will be saved as {op.session.label}.", "good")
    return redirect(url_for("operate.summary"))


def _relabel(op: Operation, text: str) -> str:
    """Give the session's scan the label ``text``, checked as on the start page (known to the taxonomy, and
    the sample's own material); "" when done, else why not (one line)."""
    form = {"operator": op.session.operator, "label": text, "sample_id": op.session.sample_id}
    try:
        op.session.relabel(validate_start(form, context().db.taxonomy(), sample_owner).label)
    except FormErrors as exc:
        return str(next(iter(exc.errors.values())))
    except SessionError as exc:
        return session_error(exc)
    return ""


@blueprint.post("/session/save")
def save() -> tuple[str, int] | Response:
    op = operation()
    scan_id = _save(op)
    if scan_id is None:
        return redirect(url_for("operate.summary"))
    flash(f"Scan {scan_id} was saved.", "good")
    return redirect(url_for("database.scan", scan_id=scan_id))


def _save(op: Operation, partial: bool = False) -> str | None:
    """Save the session's scan (``partial``: a quick scan of the steps done so far) and end the session; None
    (and a message) when the save was refused."""
    ctx = context()
    try:
        scan_id = op.session.save(ctx.db, partial=partial)
    except (SessionError, DatabaseError, ValueError) as exc:
        flash(f"The scan was not saved: {session_error(exc)}", "bad")
        return None
    keep_for_the_scan_page(op, ctx.db.record(scan_id))
    keep_start_form(op.session, ("operator",))
    ctx.operations.end(op)
    return scan_id


@blueprint.post("/session/enrol")
def enrol() -> tuple[str, int] | Response:
    """Enrolment from the summary: save the scan under the label given (a new material's, or the corrected
    one; checked as on the start page) and train a new model version with it in the background
    (:mod:`gui.training`); scanning goes on meanwhile."""
    ctx = context()
    op = operation()
    text = request.form.get("label", "").strip()[:200] or op.session.label
    if text != op.session.label:
        refused = _relabel(op, text)
        if refused:
            flash(f"Nothing was saved: {refused}", "bad")
            return redirect(url_for("operate.summary"))
        op.changed()
    label = op.session.label
    scan_id = _save(op)
    if scan_id is None:
        return redirect(url_for("operate.summary"))
    started = ctx.trainings.start(f"{scan_id} enrolled as {label}")
    flash(f"Scan {scan_id} was saved as {label}. A new model version with it is being trained in the background"
          + ("" if started else ", after the one running now") + "; every page says when it is ready.", "good")
    return redirect(url_for("database.scan", scan_id=scan_id))


# -- quick identification (docs/quick.md) -----------------------------------------------------------------


def _quick_operation() -> Operation:
    op = operation()
    if op.quick is None:
        abort(redirect(next_url(op.session)))
    return op


@blueprint.get("/session/quick")
def quick() -> tuple[str, int]:
    """The quick identification after the steps done so far: the three most probable materials, the stop or
    the step proposed next and why, the other steps still open."""
    op = _quick_operation()
    state = op.quick_state()
    session = op.session
    proposed = session.step(state.next_step) if state.next_step else None
    recorded = [step.title for step in session.steps if step.id in state.recorded]
    others = [(step, step_url(step)) for step in session.steps
              if step.id not in state.recorded and (proposed is None or step.id != proposed.id)]
    return render_page("quick.html", state=state, proposed=proposed, proposed_url=step_url(proposed) if proposed
                       else None, recorded=recorded, others=others, stop_at=100 * STOP_AT)


@blueprint.post("/session/quick/stop")
def quick_stop() -> Response:
    """End a quick identification here: nothing is saved; the start page says what it found."""
    op = _quick_operation()
    state = op.quick_state()
    top = state.predictions[0]
    why = state.why_stopped() if state.decided or state.next_step is None else "the operator stopped it"
    flash(f"Quick identification: {top.names} ({top.label}) at {100 * top.probability:.1f} % after "
          f"{len(state.recorded)} of {len(op.session.steps)} steps ({state.seconds:.0f} s); {why}. "
          "Nothing was saved.", "good" if state.decided else "")
    keep_start_form(op.session, ("operator",))
    context().operations.end(op)
    return redirect(url_for("operate.start"))


@blueprint.post("/session/quick/full")
def quick_full() -> Response:
    """Go on from the quick identification to the full scan (saved as any scan); a scan started without a
    label takes the quick prediction's, which the summary lets the operator change."""
    op = _quick_operation()
    state = op.quick_state()
    op.quick_full = True
    if op.unlabelled:
        top = state.predictions[0]
        with contextlib.suppress(SessionError):
            op.session.relabel(top.label)
        flash(f"The scan will be saved as {top.names} ({top.label}), the quick prediction; the summary lets you "
              "change it.", "")
    op.changed()
    return redirect(next_url(op.session))


@blueprint.post("/session/quick/save")
def quick_save() -> Response:
    """Keep the quick scan as it is (``meta.steps`` names the steps it holds): a sample started without a label
    under the quick prediction's."""
    op = _quick_operation()
    state = op.quick_state()
    if op.unlabelled:
        with contextlib.suppress(SessionError):
            op.session.relabel(state.predictions[0].label)
    scan_id = _save(op, partial=True)
    if scan_id is None:
        return redirect(url_for("operate.quick"))
    flash(f"Quick scan {scan_id} was saved with {len(state.recorded)} of {len(op.session.steps)} steps.", "good")
    return redirect(url_for("database.scan", scan_id=scan_id))
