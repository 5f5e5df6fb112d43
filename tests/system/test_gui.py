"""The web application at server level: form validation, uploads, CSRF, the database browser, and the guided
session driven through Flask's test client with simulated devices: the system tests (texplorer serve in a
subprocess, exports and whole sessions)."""

from __future__ import annotations

import contextlib
import re
import struct

import numpy as np
import pytest
from unit.test_gui import (
    RECORDED_STEPS,
    active,
    database,
    density_model,
    fast_config,  # noqa: E402
    field_error,
    get,
    make_app,
    noise_photo,
    png_upload,
    post,
    record_all,
    start_session,
)


def test_full_session_through_the_server(client, app):
    assert start_session(client, operator="Ann", sample_id="granite-07").headers["Location"] == "/session"
    overview = get(client, "/session").text
    assert "granite (igneous stone, stone), polished, plain" in overview
    sensor = active(app).session.t_amb
    assert f'value="{sensor:.1f}"' in overview  # pre-filled from the (simulated) MLX90614
    assert field_error(post(client, "/session/ambient", {"t_amb": "90"}).text, "t_amb") \
        == "90 degC is outside the sensor's range -40 to 85 degC"
    assert post(client, "/session/ambient", {"t_amb": "22,5"}).status_code == 302
    assert get(client, "/session/step/finger_tap/traces.png").status_code == 404  # nothing recorded yet
    record_all(client, app)
    numbers = []
    for step in RECORDED_STEPS:
        step_page = get(client, f"/session/step/{step}").text
        assert "Quality check" in step_page and "Redo this step" in step_page
        numbers.append(int(step_page.split("<h1>Step ", 1)[1].split(":", 1)[0]))
        # the step's traces between the quality result and the keep/redo buttons
        image = f'<img src="/session/step/{step}/traces.png?v={active(app).version}"'
        assert step_page.index("Quality check") < step_page.index(image) < step_page.index("Redo this step")
        png = get(client, f"/session/step/{step}/traces.png")
        assert png.mimetype == "image/png" and png_size(png.data)[0] == 800
    assert numbers == list(range(1, len(RECORDED_STEPS) + 1))
    chips = re.findall(r'<a href="/session/[^"]*"[^>]*>(\d+)\. ', step_page)
    assert chips == [str(n) for n in range(1, 12)]  # the progress strip too, photos and TU4 included

    photo = noise_photo(1)
    upload = {"I_disp": png_upload(photo), "atk": "0.25", "cyd": "0", "mass_g": "512,5 g",
              "volume_cm3": "190", "volume_method": "micro-pearls", "notes": "left corner chipped"}
    page = post(client, "/session/form", upload, content_type="multipart/form-data")
    assert page.status_code == 422  # two photos still missing; the upload and the values are kept
    assert field_error(page.text, "I_macro").startswith("upload a PNG or JPEG photo")
    assert field_error(page.text, "I_disp") is None and 'value="512,5 g"' in page.text
    for name in ("I_macro", "I_illu"):
        assert post(client, "/session/form", {"capture": name}).status_code == 200
    done = post(client, "/session/form", {"atk": "0.25", "cyd": "0", "mass_g": "512,5 g", "volume_cm3": "190",
                                         "volume_method": "micro-pearls", "notes": "left corner chipped"})
    assert done.headers["Location"] == "/session/summary"
    summary = get(client, "/session/summary")
    assert summary.status_code == 200
    assert "thermal cooling TCO (K)" in summary.text and "no trained model" in summary.text
    traces = get(client, "/session/summary/traces.png")
    assert traces.data.startswith(b"\x89PNG")
    assert len(database(app)) == 0  # nothing stored before save

    saved = post(client, "/session/save")
    assert saved.headers["Location"] == "/db/scan/granite-07-001"
    assert active(app) is None
    scan = database(app).get("granite-07-001")
    meta = scan.meta
    assert (meta.label, meta.operator, meta.sample_id, meta.scan_index) \
        == ("C6S1M1P2X1", "Ann", "granite-07", 1)
    assert (meta.t_amb, meta.atk, meta.cyd, meta.mass_g, meta.volume_cm3) == (22.5, 0.25, 0.0, 512.5, 190.0)
    assert "left corner chipped" in meta.notes and meta.volume_method == "micro-pearls" and not meta.rigid
    assert np.array_equal(scan.images["I_disp"], photo)  # the uploaded pixels, losslessly
    assert set(scan.traces) == set(scanner_channels())
    assert not any((app.extensions["texplorer"].photos.folder).iterdir())  # staged previews removed
    # Only the step figures drawn during the scan are kept, as the saved scan's cached figures (gui.figures)
    work = app.extensions["texplorer"].settings.work_dir
    app.extensions["texplorer"].figures.wait(30)  # written after the save's answer
    record = database(app).record("granite-07-001")
    kept = sorted(p.relative_to(work).as_posix() for p in work.rglob("*") if p.is_file())
    assert kept and all(re.fullmatch(rf"plots/{record.content_hash}-[a-z_]+\.png", name) for name in kept)
    listing = get(client, "/db/scans").text
    assert "granite-07-001" in listing


def png_size(data: bytes) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk."""
    assert data.startswith(b"\x89PNG\r\n\x1a\n")
    return struct.unpack(">II", data[16:24])


def scanner_channels():
    from scanner.scan import CHANNELS

    return CHANNELS


def test_summary_shows_the_models_top_predictions(tmp_path):
    density_model(tmp_path / "db" / "models" / "rf-fine-X10.skops")  # where 'texplorer demo' puts it
    app = make_app(tmp_path / "db")
    client = app.test_client()
    try:
        page = summary_after_a_full_scan(client, app)  # 2.697 g/cm^3: inside the granite range
        ranking = page.split('<ol class="predictions">', 1)[1].split("</ol>", 1)[0]
        assert ranking.index("C6S1M1P2X1") < ranking.index("C1S1M1P4X1")
        # every tree splits between 0.8 and 2.6, so all of them vote granite
        assert ranking.index("100.0 %") < ranking.index("0.0 %")
        assert "granite (igneous stone, stone), polished, plain" in ranking
        assert "oak (hardwood, wood), planed, plain" in ranking
        assert "rf at level fine, trained on 12 scans" in page
    finally:
        app.extensions["texplorer"].shutdown()


def test_summary_says_unknown_material_for_a_scan_unlike_every_trained_one(tmp_path):
    """Three materials by density, two pieces each; a scan of 8.0 g/cm^3 (steel) is far from all of them."""
    from features.space import FeatureSpace
    from taxonomy.learning.models import save_model, train_model

    rng = np.random.default_rng(0)
    centres = {"C6S1M1P2X1": 2.7, "C1S1M1P4X1": 0.7, "C3S4M2P1X1": 1.2}
    labels = [label for label in centres for _ in range(8)]
    density = np.array([centres[label] for label in labels]) + 0.05 * rng.standard_normal(len(labels))
    space = FeatureSpace(X=density[:, None], columns=("other.density",),
                         scan_ids=[f"s-{i}" for i in range(len(labels))], label_text=labels,
                         groups=[f"{label}-{i % 2}" for i, label in enumerate(labels)])
    save_model(train_model(space, "fine", 1, "rf"), tmp_path / "db" / "models" / "rf-fine-X10.skops")
    app = make_app(tmp_path / "db")
    client = app.test_client()
    try:
        page = summary_after_a_full_scan(client, app, mass_g="1520")
        assert 'id="unknown-material"' in page
        assert "unknown material (closest: granite (igneous stone, stone), polished, plain (C6S1M1P2X1)" in page
    finally:
        app.extensions["texplorer"].shutdown()


def test_browser_scan_page_traces_photos_features(stocked):
    page = get(stocked, "/db/scan/granite-01-001").text
    assert "Scan granite-01-001" in page and "21.50 °C" in page and "512 g" in page
    assert "<code>v_ts</code>" in page and "44100 Hz" in page
    assert "TacTUM (paper section IV-A)" in page
    assert '<th scope="row">atk</th><td class="num">0</td>' in page
    assert get(stocked, "/db/scan/granite-01-001/traces.png").data.startswith(b"\x89PNG")
    photo = get(stocked, "/db/scan/granite-01-001/photo/I_disp")
    assert photo.mimetype == "image/png" and photo.data.startswith(b"\x89PNG")
    assert get(stocked, "/db/scan/steel-01-001/photo/I_disp").status_code == 404
    assert "This scan has no photos" in get(stocked, "/db/scan/steel-01-001").text


def test_feature_table_export(stocked):
    answer = get(stocked, "/db/export/features.csv")
    assert answer.status_code == 200 and "attachment" in answer.headers["Content-Disposition"]
    lines = answer.data.decode().splitlines()
    header = lines[0].split(",")
    assert "tactum.matx" in header and "other.tap_decay" in header and len(header) == 3 + 5 + 193
    scan_ids = sorted(line.split(",")[0] for line in lines[1:])
    assert scan_ids == ["granite-01-001", "granite-01-002", "steel-01-001"]


def export_in_browser_session(client, form, timeout=60.0):
    """Start an export from the database page, poll it as the page does, download the bundle."""
    import time

    answer = post(client, "/db/export", {"license": "CC-BY-4.0", **form})
    assert answer.status_code == 302, answer.text
    job_url = answer.headers["Location"]
    assert get(client, job_url).status_code == 200
    deadline = time.monotonic() + timeout
    while (status := get(client, job_url + "/status").json)["running"]:
        assert time.monotonic() < deadline, status
        time.sleep(0.05)
    assert status["ready"], status
    return get(client, status["download"])


def bundle_manifest(data: bytes) -> dict:
    import io
    import json
    import zipfile

    with zipfile.ZipFile(io.BytesIO(data)) as bundle:
        assert bundle.testzip() is None
        return json.loads(bundle.read("manifest.json"))


def files_under(folder):
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


@pytest.fixture
def exporter(tmp_path):
    """The stocked database's app with its own temporary folder for bundles, to see what is left there."""
    from conftest import make_scan

    from scanner.storage.database import Database

    db = Database(tmp_path / "db")
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, session_id="s-1", image_shape=(300, 300)))
    db.add(make_scan(1, sample_id="granite-01", scan_index=2, session_id="s-2", image_shape=(300, 300)))
    db.add(make_scan(2, label="C7S1M1P8X1", sample_id="steel-01", scan_index=1, session_id="s-2", rigid=True,
                     drop=("f_fold", "alpha_f"), images=False))
    db.close()
    (tmp_path / "tmp").mkdir()
    app = make_app(tmp_path / "db", export_dir=tmp_path / "tmp")
    yield app
    app.extensions["texplorer"].shutdown()


def test_export_job_streams_the_whole_database_and_keeps_nothing(exporter, tmp_path):
    answer = export_in_browser_session(exporter.test_client(), {})
    assert answer.status_code == 200 and answer.mimetype == "application/zip"
    assert answer.headers["Content-Length"] == str(len(answer.data))
    manifest = bundle_manifest(answer.data)
    assert [scan["scan_id"] for scan in manifest["scans"]] == ["granite-01-001", "granite-01-002", "steel-01-001"]
    assert manifest["filters"] == {"label": None, "session": None}
    assert files_under(tmp_path / "tmp") == [] and not list((tmp_path / "tmp").iterdir())
    assert files_under(tmp_path / "db" / ".gui") == []


@pytest.mark.parametrize(("form", "filters", "scans"), [
    ({"label": " c7 "}, {"label": "C7", "session": None}, ["steel-01-001"]),
    ({"session": "s-2"}, {"label": None, "session": "s-2"}, ["granite-01-002", "steel-01-001"]),
    ({"label": "C6S1M1P2X1", "session": "s-2"}, {"label": "C6S1M1P2X1", "session": "s-2"}, ["granite-01-002"])])
def test_export_job_filters_like_the_cli(exporter, form, filters, scans):
    answer = export_in_browser_session(exporter.test_client(), form)
    manifest = bundle_manifest(answer.data)
    assert [scan["scan_id"] for scan in manifest["scans"]] == scans and manifest["filters"] == filters


def test_export_job_refusals(exporter, tmp_path):
    client = exporter.test_client()
    answer = post(client, "/db/export", {"label": "Z9", "license": "CC0-1.0"})
    assert answer.status_code == 422
    assert field_error(answer.text, "label").startswith("'Z9' is not a label or class prefix")
    answer = post(client, "/db/export", {"label": "C7"})
    assert answer.status_code == 422 and field_error(answer.text, "license").startswith("give the bundle a license")
    answer = post(client, "/db/export", {"label": "C7", "license": "CC BY", "creator": "lab\nx"})
    assert answer.status_code == 422 and "neither an SPDX identifier" in field_error(answer.text, "license")
    assert field_error(answer.text, "creator") == "creator must be one line of at most 200 printable characters"
    answer = post(client, "/db/export", {"label": "C1", "license": "CC0-1.0"})
    assert answer.status_code == 409 and "no scans with label C1 to export" in answer.text
    assert exporter.extensions["texplorer"].exports.job is None and not list((tmp_path / "tmp").iterdir())


def test_export_bundle_is_taken_once_then_gone(exporter, tmp_path):
    client = exporter.test_client()
    first = export_in_browser_session(client, {"label": "C7"})
    assert first.status_code == 200
    job = exporter.extensions["texplorer"].exports.job
    again = get(client, f"/db/export/{job.id}/bundle.zip")
    assert again.status_code == 409 and "no bundle to download (downloaded, and no longer kept here)" in again.text
    assert get(client, f"/db/export/{job.id}/status").json["phase"] == "downloaded"
    assert get(client, "/db/export/not-a-job/status").status_code == 404
    assert get(client, "/db/export/%C3%A9t%C3%A9/status").status_code == 404
    job.thread.join(5)
    assert not list((tmp_path / "tmp").iterdir())


def test_second_export_while_one_runs_is_refused_and_cancel_deletes(exporter, tmp_path):
    import threading

    from gui import exports

    exports_ = exporter.extensions["texplorer"].exports
    gate = threading.Event()
    original = exports.extract_database

    def held(*args, **kwargs):  # the first chunk waits until the test has looked
        gate.wait(10)
        return original(*args, **kwargs)

    exports.extract_database = held
    try:
        client = exporter.test_client()
        first = post(client, "/db/export", {"license": "none"})
        job = exports_.job
        assert job.running and len(list((tmp_path / "tmp").iterdir())) == 1
        second = post(client, "/db/export", {"label": "C7", "license": "none"})
        assert second.status_code == 302 and second.headers["Location"].endswith(f"/db/export/{job.id}")
        assert "an export of every scan is running" in get(client, second.headers["Location"]).text
        assert exports_.job is job
        gate.set()
        assert post(client, f"/db/export/{job.id}/cancel").status_code == 302
        assert first.status_code == 302 and job.phase in ("cancelled", "done") and not job.thread.is_alive()
    finally:
        exports.extract_database = original
    assert job.phase == "cancelled" and not list((tmp_path / "tmp").iterdir())


def test_abandoned_export_and_server_stop_delete_the_bundle(tmp_path, exporter):
    import time

    from gui.exports import Exports

    db = exporter.extensions["texplorer"].db
    exports = Exports(db, tmp_path / "tmp", abandon_after_s=0.3)
    job = exports.start(license="CC0-1.0")
    job.thread.join(60)
    assert job.phase == "cancelled" and job.path is None  # built, then nobody came for it
    assert not list((tmp_path / "tmp").iterdir())
    job = exports.start(label="C7", license="CC0-1.0")
    deadline = time.monotonic() + 30
    while job.phase != "done":
        job.touch()
        assert time.monotonic() < deadline and job.phase != "failed", job.status()
        time.sleep(0.02)
    assert len(list((tmp_path / "tmp").rglob("*.zip"))) == 1
    exports.shutdown()
    assert job.phase == "cancelled" and not list((tmp_path / "tmp").iterdir())


def test_export_chunks_share_one_set_of_worker_processes(tmp_path, monkeypatch):
    """The export extracts its uncached scans chunk by chunk (progress and cancellation between); the chunks
    use the same two worker processes, forked once, not a pool each."""
    import time

    from conftest import make_scan

    from features import code_version
    from gui import exports
    from gui.exports import Exports
    from scanner.storage.database import Database

    db = Database(tmp_path / "db")
    for index in range(1, 5):
        db.add(make_scan(index, sample_id="granite-01", scan_index=index, image_shape=(64, 64)))
    original, workers_seen = exports.extract_database, []

    def extract_noting_the_workers(db, *, records, pool, **kwargs):
        space = original(db, records=records, pool=pool, **kwargs)
        workers_seen.append((pool, frozenset(pool._executor._processes)))
        return space

    monkeypatch.setattr(exports, "FEATURE_CHUNK", 2)
    monkeypatch.setattr(exports, "extract_database", extract_noting_the_workers)
    (tmp_path / "tmp").mkdir()
    jobs = Exports(db, tmp_path / "tmp", workers=2)
    try:
        job = jobs.start(license="CC0-1.0")
        deadline = time.monotonic() + 120
        while job.phase in exports.RUNNING and time.monotonic() < deadline:
            job.touch()
            time.sleep(0.02)
        assert job.phase == "done", job.status()
    finally:
        jobs.shutdown()
    (pool, first), (same_pool, second) = workers_seen
    assert pool is same_pool and first == second and len(first) == 2
    assert pool._executor is None  # closed with the job
    assert len(db.records()) == 4 and all(db.cached_features(r.content_hash, code_version()) for r in db.records())


def test_export_needs_free_space(exporter, tmp_path, monkeypatch):
    import shutil
    from collections import namedtuple

    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10 << 20, 9 << 20, 1 << 20))
    answer = post(exporter.test_client(), "/db/export", {"license": "CC0-1.0"})
    assert answer.status_code == 409 and "not enough free space in" in answer.text
    assert "1 MB free" in answer.text and not list((tmp_path / "tmp").iterdir())


def test_relative_database_path_serves_files(tmp_path, monkeypatch):
    """'texplorer serve --db texplorer-data': photos, traces, the feature table and the bundle are found
    although Flask reads relative paths against its package folder (they were all HTTP 500)."""
    from conftest import make_scan

    from scanner.storage.database import Database

    monkeypatch.chdir(tmp_path)
    Database("texplorer-data").add(make_scan(0, image_shape=(300, 300)))
    app = make_app("texplorer-data")
    try:
        client = app.test_client()
        for url in ("/db/scan/granite-01-001/photo/I_disp", "/db/scan/granite-01-001/traces.png",
                    "/db/export/features.csv"):
            assert get(client, url).status_code == 200, url
        assert export_in_browser_session(client, {}).status_code == 200
        assert app.extensions["texplorer"].settings.db == tmp_path / "texplorer-data"
    finally:
        app.extensions["texplorer"].shutdown()


def serve_process(tmp_path, *options):
    import subprocess
    import sys

    command = [sys.executable, "-m", "scanner.cli", "serve", "--db", str(tmp_path / "db"), "--port", "0",
               *options]
    return subprocess.Popen(command, stderr=subprocess.PIPE, text=True)


def served_url(process) -> tuple[str, list[str]]:
    """The URL the server prints, and the lines it printed before."""
    lines = []
    for line in process.stderr:
        lines.append(line.strip())
        if " at http://" in line:
            return line.split(" at ", 1)[1].split("/ ", 1)[0], lines
    raise AssertionError(f"the server printed no address: {lines}")


def test_texplorer_serve_binds_loopback_and_stops_on_ctrl_c(tmp_path):
    import signal
    import urllib.request

    process = serve_process(tmp_path)
    try:
        url, lines = served_url(process)
        assert url.startswith("http://127.0.0.1:") and not any("warning" in line for line in lines)
        with urllib.request.urlopen(url + "/") as answer:
            assert answer.status == 200 and b"Start a scan" in answer.read()
        process.send_signal(signal.SIGINT)
        assert process.wait(10) == 0
        assert "texplorer: stopped" in process.stderr.read()
    finally:
        process.kill()


def test_texplorer_serve_warns_when_listening_on_the_network(tmp_path):
    process = serve_process(tmp_path, "--host", "0.0.0.0")
    try:
        _, lines = served_url(process)
        assert any(line.startswith("texplorer: warning: listening on 0.0.0.0:") for line in lines)
    finally:
        process.kill()


def test_texplorer_serve_on_ipv6_loopback_answers_a_browser(tmp_path):
    import socket
    import urllib.request

    try:
        with socket.socket(socket.AF_INET6) as probe:
            probe.bind(("::1", 0))
    except OSError:
        pytest.skip("no IPv6 loopback on this machine")
    process = serve_process(tmp_path, "--host", "::1")
    try:
        url, lines = served_url(process)
        assert url.startswith("http://[::1]:") and not any("warning" in line for line in lines)
        with urllib.request.urlopen(url + "/") as answer:  # sends Host: [::1]:PORT, as a browser does
            assert answer.status == 200 and b"Start a scan" in answer.read()
    finally:
        process.kill()


def test_texplorer_serve_warns_about_a_missing_model(tmp_path):
    process = serve_process(tmp_path, "--model", str(tmp_path / "no-such.skops"))
    try:
        _, lines = served_url(process)
        assert f"texplorer: warning: --model {tmp_path / 'no-such.skops'} does not exist: the summary page " \
               "shows no prediction until a model file is there ('texplorer train --out FILE' makes one)" in lines
    finally:
        process.kill()
        process.wait(10)


def test_peltier_off_when_the_browser_goes_silent_while_heating(tmp_path):
    import time

    app = make_app(tmp_path / "db", fast_config(realtime=True, heat=3.0), heartbeat_timeout_s=0.3)
    client = app.test_client()
    try:
        start_session(client)
        post(client, "/session/step/thermal/record")  # ... and the browser never polls again
        session = active(app).session
        assert session.wait(5)
        status = session.status("thermal")
        assert status.state == "failed"
        heat_log = session.devices.board.heat_log
        (on_time, on_ms), (off_time, off_ms) = heat_log[0], heat_log[-1]
        assert on_ms == 3000 and off_ms == 0
        assert off_time - on_time < 1.5  # switched off long before the 3 s were up
        page = get(client, "/session/step/thermal").text
        assert "the browser stopped responding" in page and "Start recording" in page
        started = time.monotonic()
        post(client, "/session/step/thermal/record")
        while session.running:  # a browser that polls keeps the step alive
            get(client, "/session/status")
            time.sleep(0.1)
        assert session.status("thermal").state == "recorded" and time.monotonic() - started > 3.0
    finally:
        app.extensions["texplorer"].shutdown()


def summary_after_a_full_scan(client, app, mass_g="512.5", label="C6S1M1P2X1"):
    """Record every step and fill the form; the summary page's text (with 190 cm^3: 512.5 g is 2.697 g/cm^3,
    granite by density)."""
    start_session(client, label=label)
    record_all(client, app)
    for name in ("I_disp", "I_macro", "I_illu"):
        post(client, "/session/form", {"capture": name})
    post(client, "/session/form", {"atk": "0", "cyd": "0", "mass_g": mass_g, "volume_cm3": "190",
                                   "volume_method": "water"})
    return get(client, "/session/summary").text


@pytest.mark.parametrize("failure", ["slow", "raises"])
def test_a_slow_or_failing_prediction_answers_the_summary_and_the_scan_can_be_saved(tmp_path, monkeypatch,
                                                                                      failure):
    import threading
    import time

    import gui.operate

    density_model(tmp_path / "db" / "models" / "rf-fine-X10.skops")
    release = threading.Event()

    def broken(*args, **kwargs):
        if failure == "slow":
            release.wait(60)  # a model that never answers (released at the end, not to outlive the test)
        raise IndexError()

    monkeypatch.setattr(gui.operate, "predict_values", broken)
    app = make_app(tmp_path / "db", prediction_timeout_s=1.0)
    client = app.test_client()
    try:
        started = time.monotonic()
        page = summary_after_a_full_scan(client, app)
        if failure == "slow":
            assert '<p class="notice">no prediction: the model did not answer within 1 s; the scan can be saved ' \
                   'without a prediction.</p>' in page
        else:
            assert '<p class="notice">no prediction: the model failed (IndexError: IndexError).</p>' in page
        assert time.monotonic() - started < 60
        answer = post(client, "/session/save")
        assert answer.status_code == 302
        assert [r.sample_id for r in app.extensions["texplorer"].db.records()] == ["granite-01"]
    finally:
        release.set()
        app.extensions["texplorer"].shutdown()


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--port", "70000", "--port must be 1-65535 (or 0 for any free port), got 70000"),
    ("--port", "-1", "--port must be 1-65535 (or 0 for any free port), got -1"),
    ("--workers", "0", "--workers must be at least 1, got 0"),
])
def test_texplorer_serve_refuses_a_port_or_worker_count_out_of_range(tmp_path, option, value, message):
    import subprocess
    import sys

    answer = subprocess.run([sys.executable, "-m", "scanner.cli", "serve", "--db", str(tmp_path / "db"), option,
                             value], capture_output=True, text=True, timeout=120)
    assert answer.returncode == 1  # the usage errors the command itself finds (argparse's own exit 2)
    assert answer.stderr.strip().splitlines()[-1] == f"texplorer: error: {message}"


def test_concurrent_requests_share_one_bounded_set_of_workers(tmp_path):
    """A real server with 2 workers and 12 uncached scans: the features export and the scan pages asked by
    12 threads at once are answered from one queue, never more than 2 workers (+ the worker server and the
    resource tracker) beside the server, and every export holds every scan's features."""
    import concurrent.futures
    import csv
    import io
    import threading
    import urllib.request

    import psutil

    from scanner.simulation.database import synthetic_database
    from scanner.storage.database import Database

    synthetic_database(tmp_path / "db", materials=["oak-planed", "cork-board", "granite-polished", "pvc-sheet"],
                       scans_per_material=3, image_size=(200, 200), progress=False).close()
    ids = [r.scan_id for r in Database(tmp_path / "db").records()]
    process = serve_process(tmp_path, "--workers", "2")
    try:
        url, _ = served_url(process)
        threading.Thread(target=process.stderr.read, daemon=True).start()
        server = psutil.Process(process.pid)
        stop, peak = threading.Event(), [0]

        def watch():
            while not stop.wait(0.02):
                with contextlib.suppress(psutil.Error):
                    peak[0] = max(peak[0], len(server.children(recursive=True)))

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()

        def fetch(path):
            with urllib.request.urlopen(url + path, timeout=300) as answer:
                return answer.status, answer.read()

        paths = [f"/db/scan/{scan_id}" for scan_id in ids] + ["/db/export/features.csv"] * 6
        with concurrent.futures.ThreadPoolExecutor(12) as pool:
            answers = list(pool.map(fetch, paths))
        stop.set()
        watcher.join()
        assert [status for status, _ in answers] == [200] * len(paths)
        for _, body in answers[len(ids):]:
            rows = list(csv.DictReader(io.StringIO(body.decode())))
            assert sorted(row["scan_id"] for row in rows) == sorted(ids)
        assert 3 <= peak[0] <= 2 + 2, peak[0]
    finally:
        process.terminate()
        process.wait(30)


def test_the_summary_checks_the_label_against_the_model_and_takes_the_predicted_one(tmp_path):
    density_model(tmp_path / "db" / "models" / "rf-fine-X10.skops")  # granite polished vs oak, by density
    app = make_app(tmp_path / "db")
    client = app.test_client()
    try:
        # oak by its label, granite by its density (2.697 g/cm^3)
        page = summary_after_a_full_scan(client, app, label="C1S1M1P4X1")
        assert ("Check the label: your label oak (hardwood, wood), planed, plain (C1S1M1P4X1) differs from the "
                "prediction at level fine: the model predicts granite (igneous stone, stone), polished, plain "
                "(C6S1M1P2X1) at 100.0 %.") in page
        assert '<button type="submit" name="choice" value="predicted">Save as <code>C6S1M1P2X1</code>' in page
        answer = post(client, "/session/label", {"choice": "predicted", "predicted": "C6S1M1P2X1"})
        assert answer.status_code == 302
        page = get(client, "/session/summary").text
        assert "Check the label" not in page and "The scan will be saved as C6S1M1P2X1." in page
        post(client, "/session/save")
        assert [r.label for r in app.extensions["texplorer"].db.records()] == ["C6S1M1P2X1"]
    finally:
        app.extensions["texplorer"].shutdown()


def test_a_label_the_model_never_saw_is_named_and_can_be_kept_or_replaced(tmp_path):
    density_model(tmp_path / "db" / "models" / "rf-fine-X10.skops")
    app = make_app(tmp_path / "db")
    client = app.test_client()
    try:
        page = summary_after_a_full_scan(client, app, label="C6S1M1P1X1")  # granite, natural: not trained
        assert ("your label granite (igneous stone, stone), natural, plain (C6S1M1P1X1) names a class the model "
                "was never trained on (C6S1M1P1X1 at level fine)") in page
        answer = post(client, "/session/label", {"choice": "other", "label": "C99"})
        assert answer.status_code == 302
        page = get(client, "/session/summary").text
        assert "The label was not changed: " in page and "Check the label" in page
        post(client, "/session/label", {"choice": "mine"})
        page = get(client, "/session/summary").text
        assert "Check the label" not in page
        post(client, "/session/save")
        assert [r.label for r in app.extensions["texplorer"].db.records()] == ["C6S1M1P1X1"]
    finally:
        app.extensions["texplorer"].shutdown()


def test_an_unknown_material_is_enrolled_from_the_summary_into_a_new_model_version(tmp_path):
    """A database of three materials and its model (version 1); a scan of granite, which the model never
    saw, is saved from the summary as granite and trained into version 2 in the background."""
    from scanner.workflows.demo import simulated_database
    from scanner.workflows.models import retrain
    from taxonomy.learning.versions import current_version, versions

    db = simulated_database(tmp_path / "db", materials=["oak-planed", "mild-steel-brushed", "cork-board"],
                            scans_per_material=2, samples_per_material=2, image_size=(300, 300), progress=False,
                            workers=2)
    first = retrain(db, note="the first model")
    assert first.after.version == 1 and "C6S1M1P2X1" not in first.after.classes
    app = make_app(tmp_path / "db", long_enough_config())
    client = app.test_client()
    ctx = app.extensions["texplorer"]
    try:
        page = summary_after_a_full_scan(client, app)
        assert 'id="enrol"' in page and "never trained on" in page
        # an unknown material: no offer to save it as the trained material the forest would name
        assert 'id="unknown-material"' in page and 'value="predicted">Save as' not in page
        assert post(client, "/session/enrol", {"label": "C7S1M1P1X1x"}).headers["Location"] == "/session/summary"
        assert "Nothing was saved" in get(client, "/session/summary").text and len(database(app)) == 12
        answer = post(client, "/session/enrol", {"label": "C6S1M1P2X1"})
        assert answer.headers["Location"] == "/db/scan/granite-01-001"
        assert "is being trained in the background" in get(client, answer.headers["Location"]).text
        assert ctx.trainings.wait(600)
        job = ctx.trainings.job
        assert job.phase == "done", job.outcome
        assert job.change.added == ("C6S1M1P2X1",) and job.change.before.version == 1
        assert current_version(db.root).version == 2 and [v.version for v in versions(db.root)] == [1, 2]
        assert "C6S1M1P2X1" in ctx.model.classes and ctx.model.n_rows == 13
        notice = get(client, "/").text.split('id="training"', 1)[1].split("</p>", 1)[0]
        assert "model version 2" in notice and "1 class added: granite" in notice
        listing = get(client, "/db/models").text
        assert "v2 (current)" in listing and "granite-01-001 enrolled as C6S1M1P2X1" in listing
        # an older version can be made current again, and the next prediction uses it
        post(client, "/db/models/use", {"version": "1"})
        assert current_version(db.root).version == 1 and "C6S1M1P2X1" not in ctx.model.classes
    finally:
        ctx.shutdown()


def long_enough_config():
    """Simulated devices with slides long enough for every feature (a second of sound and vibration after the
    slide starts)."""
    from dataclasses import replace

    config = fast_config()
    return replace(config, steps=replace(config.steps, finger_slide=2.5, tool_slide=2.5))
