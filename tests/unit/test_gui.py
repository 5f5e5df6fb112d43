"""The web application at server level: form validation, uploads, CSRF, the database browser, and the guided
session driven through Flask's test client with simulated devices."""

from __future__ import annotations

import math
import re
import struct
import zlib

import cv2
import numpy as np
import pytest

from features.space import FeatureSpace
from gui.exports import ExportJob
from gui.forms import (
    TACK_CHOICES,
    YIELDING_CHOICES,
    FormErrors,
    OperatorValues,
    parse_ambient,
    parse_judged,
    parse_quantity,
    validate_operator,
    validate_start,
)
from gui.photos import PhotoStore, UploadError, check_upload
from scanner.acquisition.devices.camera import PhotoError, decode_photo
from scanner.photo import image_size
from scanner.storage.matfile import encode_png
from taxonomy.learning.models import save_model, train_model
from taxonomy.table import load_taxonomy

# -- forms --------------------------------------------------------------------------------------------


def test_judged_choices_use_the_papers_words():
    # Strese et al. 2020, eq. 18 (ATK) and eq. 24 (CYD).
    assert TACK_CHOICES == ((0.0, "not adhesive"), (0.25, "slightly adhesive"), (0.5, "uncertain"),
                            (0.75, "adhesive"), (1.0, "strongly adhesive"))
    assert YIELDING_CHOICES == ((0.0, "material recovers shape"), (0.25, "material likely recovers shape"),
                                (0.5, "uncertain"), (0.75, "material unlikely recovers shape"),
                                (1.0, "material stays deformed"))


@pytest.mark.parametrize(("text", "value"), [("12.5", 12.5), ("12,5 g", 12.5), (" 3g ", 3.0), (".5", 0.5),
                                             ("2e3", 2000.0), ("7.", 7.0)])
def test_quantity_accepts_numbers_with_the_unit(text, value):
    assert parse_quantity(text, ("g",), what="mass") == value


@pytest.mark.parametrize(("text", "reason"), [
    ("", "enter the mass in g"), ("   ", "enter the mass in g"),
    ("-3", r"the mass must be positive \(in g\), got -3"),
    ("0", "must be positive"), ("0,0 g", "must be positive"), ("nan", "is not a number"),
    ("inf", "is not a number"), ("1e400", "must be positive"), ("5 kg", "is not a number in g"),
    ("5 g g", "is not a number in g"), ("1.2.3", "is not a number in g"),
])
def test_quantity_refuses_with_a_reason(text, reason):
    with pytest.raises(ValueError, match=reason):
        parse_quantity(text, ("g",), what="mass")


def test_volume_units():
    form = _operator_form(volume_cm3="120 cm^3")
    assert validate_operator(form).volume_cm3 == 120.0
    assert validate_operator(_operator_form(volume_cm3="7,5 ml")).volume_cm3 == 7.5
    with pytest.raises(FormErrors) as caught:
        validate_operator(_operator_form(volume_cm3="3 l"))
    assert set(caught.value.errors) == {"volume_cm3"}


@pytest.mark.parametrize(("text", "reason"), [
    ("", "choose the adhesive tack"), ("0.3", "not on the five-step scale"),
    ("1.25", "not on the five-step scale"), ("x", "is not one of the five"),
    ("nan", "not on the five-step scale")])
def test_judged_value_off_the_scale(text, reason):
    with pytest.raises(ValueError, match=reason):
        parse_judged(text, TACK_CHOICES, what="adhesive tack")


def test_judged_values_on_the_scale():
    assert [parse_judged(t, YIELDING_CHOICES, what="yielding") for t in ("0", "0.25", "0.5", "0.75", "1")] \
        == [0.0, 0.25, 0.5, 0.75, 1.0]


def _start_form(**changes):
    return {"operator": "ab", "label": "C6S1M1P2X1", "sample_id": "granite-01", **changes}


def _operator_form(**changes):
    return {"atk": "0", "cyd": "0.25", "mass_g": "512", "volume_cm3": "190", "volume_method": "water",
            "notes": "", **changes}


def test_start_form_valid():
    form = _start_form(label=" c6s1m1p2x1 ", operator=" Ann ")
    values = validate_start(form, load_taxonomy(), lambda s: None)
    assert (values.operator, values.label, values.sample_id) == ("Ann", "C6S1M1P2X1", "granite-01")


def test_start_form_reports_every_bad_field_at_once():
    form = _start_form(operator="a/b", label="C6S1", sample_id="../etc")
    with pytest.raises(FormErrors) as caught:
        validate_start(form, load_taxonomy(), lambda s: None)
    errors = caught.value.errors
    assert set(errors) == {"operator", "label", "sample_id"}
    assert "missing M<number>" in errors["label"]
    assert "must be 1-64 letters" in errors["sample_id"]


@pytest.mark.parametrize(("text", "value"), [("21.5", 21.5), ("21,5 °C", 21.5), ("-40", -40.0),
                                             ("85 degC", 85.0)])
def test_ambient_temperature(text, value):
    assert parse_ambient(text) == value


@pytest.mark.parametrize(("text", "reason"), [
    ("", "enter the ambient temperature in degC"),
    ("85.5", "85.5 degC is outside the sensor's range -40 to 85 degC"),
    ("-41", "outside the sensor's range"), ("warm", "is not a temperature")])
def test_ambient_temperature_refused(text, reason):
    with pytest.raises(ValueError, match=reason):
        parse_ambient(text)


def test_start_form_unknown_code_and_sample_of_another_material():
    with pytest.raises(FormErrors) as caught:
        validate_start(_start_form(label="C6S9M1P2X1"), load_taxonomy(), lambda s: None)
    assert caught.value.errors == {"label": "C6S9M1P2X1: stone has no sub-class S9"}
    with pytest.raises(FormErrors) as caught:
        validate_start(_start_form(), load_taxonomy(), lambda s: "C7S1M1P8X1")
    assert caught.value.errors == {
        "sample_id": "sample granite-01 is C7S1M1P8X1 in the database, not C6S1M1P2X1"}


def test_start_form_required_fields():
    with pytest.raises(FormErrors) as caught:
        validate_start({}, load_taxonomy(), lambda s: None)
    assert set(caught.value.errors) == {"operator", "label", "sample_id"}


def test_operator_form_valid_and_notes():
    form = _operator_form(atk="0.75", cyd="1", mass_g="12,5 g", notes="  chipped edge\r\n")
    values = validate_operator(form)
    assert values == OperatorValues(0.75, 1.0, 12.5, 190.0, "water", "chipped edge")
    assert validate_operator(_operator_form(volume_method="micro-pearls")).volume_method == "micro-pearls"


def test_operator_form_reports_every_bad_field():
    form = _operator_form(atk="2", cyd="", mass_g="-1", volume_cm3="abc", volume_method="guess",
                          notes="x" * 2001)
    with pytest.raises(FormErrors) as caught:
        validate_operator(form)
    assert set(caught.value.errors) == {"atk", "cyd", "mass_g", "volume_cm3", "volume_method", "notes"}
    assert caught.value.errors["notes"] == "notes are 2001 characters long; at most 2000 are kept"
    with pytest.raises(FormErrors) as caught:
        validate_operator(_operator_form(notes="bell\x07"))
    assert set(caught.value.errors) == {"notes"}


# -- photos -------------------------------------------------------------------------------------------


def _rgb(h=5, w=7):
    image = np.zeros((h, w, 3), dtype=np.uint8)
    image[..., 0] = np.arange(w, dtype=np.uint8) * 30
    image[..., 1] = np.arange(h, dtype=np.uint8)[:, None] * 50
    image[..., 2] = 200
    return image


def _jpeg(rgb):
    ok, buffer = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    assert ok
    return buffer.tobytes()


def _png_header(width, height):
    """A PNG signature and IHDR chunk claiming ``width`` x ``height`` pixels, and no image data."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = struct.pack(">I", len(ihdr)) + b"IHDR" + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr))
    return b"\x89PNG\r\n\x1a\n" + chunk


def test_image_size_from_headers():
    assert image_size(encode_png(_rgb(5, 7))) == ("PNG", 7, 5)
    assert image_size(_jpeg(_rgb(5, 7))) == ("JPEG", 7, 5)
    assert image_size(_png_header(100_000, 30_000)) == ("PNG", 100_000, 30_000)
    assert image_size(b"GIF89a" + bytes(20)) is None


def test_decoding_outside_the_web_app_refuses_a_decompression_bomb():
    with pytest.raises(PhotoError, match=r"upload: the image has 3,000,000,000 pixels"):
        decode_photo(_png_header(100_000, 30_000) + bytes(100))


@pytest.mark.parametrize(("data", "reason"), [
    (b"", "the file is empty"),
    (b"\xff\xd8\xff\xe0" + bytes(10), "JPEG file is damaged"),
    (b"\x89PNG\r\n\x1a\n" + bytes(4), "PNG file is damaged"),
    (_png_header(100_000, 30_000), r"the image has 3,000,000,000 pixels \(100000 x 30000\); at most 25,000,000 are"),
    (_png_header(0, 10), "empty image"),
])
def test_check_upload_refuses(data, reason):
    with pytest.raises(UploadError, match=reason):
        check_upload(data)


def test_check_upload_passes_what_decoding_must_judge():
    check_upload(_png_header(10, 10))  # header only: the decoder refuses it later
    check_upload(b"%PDF-1.7")
    check_upload(_png_header(5000, 10_000), max_pixels=50_000_000)
    with pytest.raises(UploadError, match=r"the image has 50,010,000 pixels \(5001 x 10000\)"):
        check_upload(_png_header(5001, 10_000), max_pixels=50_000_000)


def test_check_upload_size_limit():
    data = encode_png(_rgb())
    check_upload(data, max_bytes=len(data))
    with pytest.raises(UploadError, match="photos may be at most"):
        check_upload(data, max_bytes=len(data) - 1)
    big = bytes(3 * 1024 * 1024)
    with pytest.raises(UploadError, match=r"the file is 3.0 MB; photos may be at most 2.0 MB"):
        check_upload(big, max_bytes=2 * 1024 * 1024)


def test_photo_store_generated_names(tmp_path):
    store = PhotoStore(tmp_path / "uploads")
    name = store.put(_rgb())
    assert len(name) == 36 and name.endswith(".png") and int(name[:32], 16) >= 0
    assert np.array_equal(store.load(name), _rgb())
    assert [p.name for p in (tmp_path / "uploads").iterdir()] == [name]
    for bad in ("../x.png", "a" * 32 + ".png.exe", "/etc/passwd", ""):
        with pytest.raises(UploadError, match="not a staged photo name"):
            store.path(bad)
    store.discard([name])
    assert not any((tmp_path / "uploads").iterdir())


# -- the app ------------------------------------------------------------------------------------------

BASE = "http://127.0.0.1"
RECORDED_STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction",
                  "press", "fold")


def fast_config(realtime=False, heat=0.2):
    """Simulated devices with short steps; not paced in real time unless asked."""
    from scanner.acquisition.config import Config, SimulatedConfig, StepDurations

    return Config(steps=StepDurations(finger_tap=0.3, finger_slide=0.6, tool_tap=0.3, tool_slide=0.6,
                                      static=0.2, heat=heat, thermal=0.4, friction=0.3, press=0.3, fold=0.3),
                  simulated=SimulatedConfig(realtime=realtime, image_size=(300, 300)))


def make_app(root, config=None, **settings):
    from gui.app import Settings, create_app

    app = create_app(Settings(db=root, device_config=config or fast_config(), **settings))
    app.config["TESTING"] = True
    return app


def csrf(client):
    """The CSRF token of the client's browser session, as the pages embed it."""
    page = client.get("/", base_url=BASE).text
    return page.split('name="csrf_token" value="', 1)[1].split('"', 1)[0]


def post(client, url, data=None, **kwargs):
    return client.post(url, data={"csrf_token": csrf(client), **(data or {})}, base_url=BASE, **kwargs)


def get(client, url):
    return client.get(url, base_url=BASE)


def field_error(page, name):
    """The text of the error shown beside field ``name``, or None."""
    marker = f'<p class="error" id="{name}-error"><span class="sr">Error: </span>'
    if marker not in page:
        return None
    import html

    return html.unescape(page.split(marker, 1)[1].split("</p>", 1)[0])


def active(app):
    return app.extensions["texplorer"].operations.active


def database(app):
    return app.extensions["texplorer"].db


def start_session(client, **changes):
    form = {"operator": "ab", "label": "C6S1M1P2X1", "sample_id": "granite-01", **changes}
    return post(client, "/", form)


def record_all(client, app, skip_fold=False):
    for step in RECORDED_STEPS:
        if step == "fold" and skip_fold:
            assert post(client, "/session/step/fold/skip").status_code == 302
            continue
        assert post(client, f"/session/step/{step}/record").status_code == 302
        assert active(app).session.wait(30)
        assert active(app).session.status(step).state == "recorded", active(app).session.status(step)


def png_upload(rgb, name="photo.png"):
    import io

    return (io.BytesIO(encode_png(rgb)), name)


def noise_photo(seed, size=300):
    return np.random.default_rng(seed).integers(0, 256, (size, size, 3), dtype=np.uint8)


def test_start_form_shows_each_reason_beside_its_field(client, app):
    page = start_session(client, operator="a<b", label="C6S1M1P2", sample_id="no/slash")
    assert page.status_code == 422
    text = page.text
    assert field_error(text, "operator") \
        == "1-64 printable characters without quotes, slashes or angle brackets"
    assert field_error(text, "label").startswith("'C6S1M1P2' is not a label: missing X<number>")
    assert "must be 1-64 letters, digits" in field_error(text, "sample_id")
    assert 'aria-invalid="true" aria-describedby="label-error' in text
    assert active(app) is None and len(database(app)) == 0


def test_start_refuses_unknown_code_and_simulates_every_taxonomy_label(client, app):
    page = start_session(client, label="C6S9M1P2X1").text
    assert field_error(page, "label") == "C6S9M1P2X1: stone has no sub-class S9"
    assert active(app) is None
    page = start_session(client, label="C6S1M1P5X1")  # no hand-set material: derived from its codes
    assert page.status_code == 302 and active(app) is not None


def test_csrf_token_required_on_every_state_change(client, app):
    form = {"operator": "ab", "label": "C6S1M1P2X1", "sample_id": "granite-01"}
    for data in (form, {**form, "csrf_token": "forged"}, {**form, "csrf_token": ""}):
        answer = client.post("/", data=data, base_url=BASE)
        assert answer.status_code == 400
        assert "security token is missing or out of date" in answer.text
    assert active(app) is None
    assert start_session(client).status_code == 302
    for url in ("/session/abort", "/session/step/finger_tap/record", "/session/save", "/session/form"):
        assert client.post(url, base_url=BASE).status_code == 400
    other = app.test_client()  # another browser: its own token does not work with this one's cookie
    token = csrf(other)
    assert client.post("/session/abort", data={"csrf_token": token}, base_url=BASE).status_code == 400
    assert active(app) is not None and active(app).session.status("finger_tap").state == "pending"
    header = client.post("/session/abort", data={"confirm": "discard"}, headers={"X-CSRF-Token": csrf(client)},
                         base_url=BASE)
    assert header.status_code == 302 and active(app) is None


def test_hosts_and_headers(client):
    assert client.get("/", base_url="http://evil.example").status_code == 400
    assert client.get("/", base_url="http://localhost:8080").status_code == 200
    page = get(client, "/")
    assert "script-src 'self'" in page.headers["Content-Security-Policy"]
    assert page.headers["X-Frame-Options"] == "DENY" and page.headers["X-Content-Type-Options"] == "nosniff"
    cookie = page.headers["Set-Cookie"]
    assert "HttpOnly" in cookie and "SameSite=Strict" in cookie


def test_any_host_when_listening_on_the_network(tmp_path):
    app = make_app(tmp_path / "db", trusted_hosts=None)
    assert app.test_client().get("/", base_url="http://scanner-laptop.lab:8080").status_code == 200


def test_taxonomy_picker_api(client):
    found = get(client, "/api/taxonomy?q=granite").json
    granite = {"code": "C6S1M1", "name": "granite", "subclass": "igneous stone", "major": "stone",
               "simulation": "hand-set"}
    assert granite in found["materials"]
    by_code = get(client, "/api/taxonomy?q=c6s1").json["materials"]
    assert by_code and all(m["code"].startswith("C6S1M") for m in by_code)
    # The default (simulated) scanner tells which materials it derives: basalt has no hand-set table.
    assert {m["code"]: m["simulation"] for m in by_code}["C6S1M2"] == "derived"
    assert get(client, "/api/label?label=C6S1M1P2X1").json == {
        "ok": True, "label": "C6S1M1P2X1", "description": "granite (igneous stone, stone), polished, plain"}
    answer = get(client, "/api/label?label=C6S1").json
    assert answer["ok"] is False and "missing M<number>" in answer["error"]


def test_operator_form_errors_save_nothing(client, app):
    start_session(client)
    record_all(client, app, skip_fold=True)
    assert active(app).session.rigid
    big = noise_photo(0, size=400)
    size = len(encode_png(big))
    assert size > 400_000
    form = {"I_disp": (png_upload(noise_photo(2))[0], "../../etc/passwd"),
            "I_macro": png_upload(big, "huge.png"),
            "I_illu": (__import__("io").BytesIO(b"%PDF-1.4 not a photo"), "photo.jpg"),
            "atk": "0.3", "cyd": "", "mass_g": "-12", "volume_cm3": "0", "volume_method": "bucket",
            "notes": "x" * 2001}
    page = post(client, "/session/form", form, content_type="multipart/form-data")
    assert page.status_code == 422
    text = page.text
    assert field_error(text, "I_macro") \
        == f"the file is {round(size / 1024)} KB; photos may be at most 391 KB"
    assert field_error(text, "I_illu") == "not a PNG or JPEG file"
    assert "not on the five-step scale" in field_error(text, "atk")
    assert field_error(text, "cyd").startswith('choose the yielding: one of "material recovers shape"')
    assert field_error(text, "mass_g") == "the mass must be positive (in g), got -12"
    assert field_error(text, "volume_cm3") == "the volume must be positive (in cm^3), got 0"
    assert field_error(text, "volume_method").startswith("choose how the volume was measured")
    assert field_error(text, "notes") == "notes are 2001 characters long; at most 2000 are kept"
    session = active(app).session
    assert set(session.photos) == {"I_disp"}  # the one good upload, under a generated name
    staged = active(app).photos["I_disp"]
    assert "passwd" not in staged and staged.endswith(".png")
    assert all(math.isnan(session.values[k]) for k in ("atk", "cyd", "mass_g", "volume_cm3"))
    assert get(client, "/session/summary").status_code == 409
    assert post(client, "/session/save").headers["Location"] == "/session/summary"
    assert len(database(app)) == 0 and not any((database(app).root / "scans").iterdir())


def test_request_too_large_for_three_photos(client, app):
    start_session(client)
    huge = __import__("io").BytesIO(bytes(3 * 400_000 + 2 * 1024 * 1024))
    page = post(client, "/session/form", {"I_disp": (huge, "a.png")}, content_type="multipart/form-data")
    assert page.status_code == 413 and "nothing was saved" in page.text
    assert active(app) is not None and not active(app).session.photos


def test_abort_saves_nothing_and_releases_the_devices(client, app):
    start_session(client)
    post(client, "/session/step/finger_tap/record")
    active(app).session.wait(30)
    post(client, "/session/form", {"capture": "I_disp"})
    op = active(app)
    staged = app.extensions["texplorer"].photos.path(op.photos["I_disp"])
    assert staged.is_file()
    answer = post(client, "/session/abort", {"confirm": "discard"})
    assert answer.headers["Location"] == "/"
    assert "The scan was aborted; nothing was saved." in get(client, "/").text
    assert active(app) is None and op.session.state == "aborted" and op.session.devices is None
    assert not staged.exists() and len(database(app)) == 0
    assert get(client, "/session").headers["Location"] == "/"


def test_redo_skip_and_refusals(client, app):
    start_session(client)
    assert post(client, "/session/step/tool_tap/skip").status_code == 302
    page = get(client, "/session/step/tool_tap").text
    assert "tool_tap cannot be skipped (only the fold, for a rigid sample)" in page
    post(client, "/session/step/fold/skip")
    assert active(app).session.status("fold").state == "skipped"
    post(client, "/session/step/fold/redo")
    assert active(app).session.status("fold").state == "pending"
    post(client, "/session/step/press/record")
    active(app).session.wait(30)
    post(client, "/session/step/press/redo")
    assert active(app).session.status("press").state == "pending"
    assert get(client, "/session/step/nonsense").status_code == 404
    assert post(client, "/session/step/press/explode").status_code == 404
    assert start_session(client, sample_id="other-01").status_code == 409  # one scanner, one session


def test_status_while_recording(tmp_path):
    app = make_app(tmp_path / "db", fast_config(realtime=True, heat=1.0))
    client = app.test_client()
    try:
        start_session(client)
        post(client, "/session/step/thermal/record")
        seen = []
        while active(app).session.running:
            answer = get(client, "/session/status").json
            if answer["recording"]:
                seen.append(answer)
        assert any(a["heating"] and a["phase"] == "heating" for a in seen)
        assert any(a["phase"] == "cooling" for a in seen)
        assert all(0.0 <= a["level"] <= 1.0 for a in seen)
        assert get(client, "/session/status").json == {"recording": False, "next": None}
        assert active(app).session.status("thermal").state == "recorded"
    finally:
        app.extensions["texplorer"].shutdown()


# -- database browser ------------------------------------------------------------------------------------


def test_browser_overview_material_and_scans(stocked):
    page = get(stocked, "/db/").text
    assert "3 scans of 2 materials (2 samples" in page
    assert "granite (igneous stone, stone), polished, plain" in page
    material = get(stocked, "/db/material/C6S1M1P2X1").text
    assert "Sample granite-01" in material and "granite-01-002" in material and "steel-01" not in material
    listing = get(stocked, "/db/scans?label=C7").text
    assert "steel-01-001" in listing and "granite-01-001" not in listing and "skipped (rigid)" in listing
    assert "1 scan(s)" in get(stocked, "/db/scans?operator=cd").text
    assert get(stocked, "/db/material/C1S1M1P1X1").status_code == 404
    assert get(stocked, "/db/scan/nope-001").status_code == 404


def test_empty_database_pages(client):
    assert "The database is empty" in get(client, "/db/").text
    assert get(client, "/db/export/features.csv").status_code == 404
    assert post(client, "/db/export", {"license": "CC0-1.0"}).status_code == 409


def export_links(page: str) -> dict[str, tuple[str, bool]]:
    """The export page's download and export-again links: their address and whether they are shown."""
    links = re.findall(r'<a class="button big" id="export-(download|again)" href="([^"]*)"( hidden)?>', page)
    return {name: (href, not hidden) for name, href, hidden in links}


@pytest.mark.parametrize(("phase", "offered"), [("done", "download"), ("downloaded", "again"),
                                                ("cancelled", "again"), ("failed", "again")])
def test_export_page_offers_the_bundle_or_a_new_export(app, tmp_path, phase, offered):
    exports = app.extensions["texplorer"].exports
    exports.job = ExportJob("job-1", database(app), [], "C6", None, tmp_path / "gone", phase=phase,
                            name="texplorer-export-x.zip", size=2**20)
    page = get(app.test_client(), "/db/export/job-1").text
    assert export_links(page) == {"download": ("/db/export/job-1/bundle.zip", offered == "download"),
                                  "again": ("/db/?label=C6#export-form", offered == "again")}


def test_a_taken_bundle_answers_with_its_page_offering_a_new_export(app, tmp_path):
    """The bundle's link tapped after its download (a page without script still shows it): 409 with the job's
    page, which says why and offers the export form with the same filters, not a bare refusal."""
    exports = app.extensions["texplorer"].exports
    exports.job = ExportJob("job-1", database(app), [], "C6", "s-2", tmp_path / "gone", phase="downloaded",
                            name="texplorer-export-x.zip", size=2**20)
    answer = get(app.test_client(), "/db/export/job-1/bundle.zip")
    assert answer.status_code == 409 and answer.mimetype == "text/html"
    assert "This export has no bundle to download (downloaded, and no longer kept here)." in answer.text
    assert export_links(answer.text) == {"download": ("/db/export/job-1/bundle.zip", False),
                                         "again": ("/db/?label=C6&amp;session=s-2#export-form", True)}


# -- texplorer serve ----------------------------------------------------------------------------------


def test_ipv6_loopback_hosts_are_trusted_and_printed_in_brackets(tmp_path):
    from gui.app import url_of

    client = make_app(tmp_path / "db").test_client()
    assert client.get("/", base_url="http://[::1]:8080").status_code == 200
    assert client.get("/", base_url="http://[::1]").status_code == 200
    assert client.get("/", base_url="http://[::2]:8080").status_code == 400
    assert client.get("/", base_url="http://127.0.0.2:8080").status_code == 400
    assert url_of("::1", 8080) == "http://[::1]:8080/" and url_of("127.0.0.1", 80) == "http://127.0.0.1:80/"
    assert url_of("0.0.0.0", 5) == "http://127.0.0.1:5/" and url_of("fe80::1", 5) == "http://[fe80::1]:5/"


def test_texplorer_serve_refuses_bad_options(tmp_path, capsys):
    from scanner.cli import main

    assert main(["serve", "--db", str(tmp_path / "db"), "--upload-limit-mb", "0"]) == 1
    assert capsys.readouterr().err.strip() == "texplorer: error: --upload-limit-mb must be positive, got 0"
    (tmp_path / "bad.toml").write_text("[devices]\ndaq = 'teleport'\n")
    assert main(["serve", "--db", str(tmp_path / "db"), "--config", str(tmp_path / "bad.toml")]) == 1
    assert "devices.daq: 'teleport' is not one of" in capsys.readouterr().err


def test_unmeasured_values_read_not_measured(tmp_path):
    from conftest import make_scan

    from scanner.storage.database import Database

    Database(tmp_path / "db").add(make_scan(0, mass_g=math.nan, t_amb=math.nan, atk=math.nan))
    app = make_app(tmp_path / "db")
    page = get(app.test_client(), "/db/scan/granite-01-001").text
    for name in ("Ambient temperature", "Mass", "Adhesive tack"):
        assert f"<dt>{name}</dt><dd>not measured</dd>" in page
    assert "<dt>Volume</dt><dd>190 cm³</dd>" in page and "<dd>nan" not in page


def test_export_folder_missing_is_one_line(tmp_path):
    from conftest import make_scan

    from scanner.storage.database import Database

    Database(tmp_path / "db").add(make_scan(0))
    app = make_app(tmp_path / "db", export_dir=tmp_path / "no-such-folder")
    try:
        answer = post(app.test_client(), "/db/export", {"license": "CC0-1.0"})
        assert answer.status_code == 409
        assert f"cannot build the bundle in {tmp_path / 'no-such-folder'}: No such file or directory" in answer.text
    finally:
        app.extensions["texplorer"].shutdown()


def density_model(path):
    """A random forest on density alone: granite (2.6-2.8 g/cm^3) against oak (0.6-0.8 g/cm^3)."""
    density = np.concatenate([np.linspace(2.6, 2.8, 6), np.linspace(0.6, 0.8, 6)])
    labels = ["C6S1M1P2X1"] * 6 + ["C1S1M1P4X1"] * 6
    space = FeatureSpace(X=density[:, None], columns=("other.density",),
                         scan_ids=[f"s-{i}" for i in range(12)], label_text=labels,
                         groups=[f"g-{i}" for i in range(12)])
    return save_model(train_model(space, "fine", 1, "rf"), path)


def test_export_form_offers_the_database_license_and_creator(stocked, tmp_path):
    from scanner.storage.settings import write_settings

    page = get(stocked, "/db/").text
    assert 'id="export-license" name="license" value=""' in page and "required" in page
    write_settings(tmp_path / "db", license="CC-BY-4.0", creator="Haptics <Lab>")
    page = get(stocked, "/db/").text
    assert 'id="export-license" name="license" value="CC-BY-4.0"' in page
    assert 'id="export-creator" name="creator" value="Haptics &lt;Lab&gt;"' in page  # escaped, as typed
    (tmp_path / "db" / "settings.json").write_text("{broken")
    page = get(stocked, "/db/").text
    assert "settings.json: not valid JSON" in page and 'name="license" value=""' in page


def test_the_models_page_refuses_hostile_or_empty_requests_in_one_line(client, app):
    page = get(client, "/db/models")
    assert page.status_code == 200 and "No model yet" in page.text
    for url in ("/db/models/train", "/db/models/use", "/session/enrol"):
        assert client.post(url, data={"version": "1"}, base_url=BASE).status_code == 400  # no CSRF token
    assert "There are no scans to train a model on" in get(client, post(client, "/db/models/train").location).text
    assert app.extensions["texplorer"].trainings.job is None
    for version in ("7", "v1x", "../../etc/passwd", "1" * 5000, "\x00"):
        answer = post(client, "/db/models/use", {"version": version})
        text = get(client, answer.location).text
        assert answer.status_code == 302 and "No version was made current" in text, version
    assert not (app.extensions["texplorer"].settings.db / "models").exists()  # nothing written
    # no scan running: the start page, nothing saved, nothing trained
    assert post(client, "/session/enrol", {"label": "C6S1M1P2X1"}).location == "/"
    assert len(database(app)) == 0 and app.extensions["texplorer"].trainings.job is None


def test_a_training_that_fails_says_why_and_leaves_the_versions_alone(tmp_path):
    from gui.training import Trainings
    from scanner.storage.database import Database

    db = Database(tmp_path / "db")
    trainings = Trainings(db, workers=1)
    job = trainings.start("asked for by a test")
    assert job is not None and trainings.wait(60)
    assert job.phase == "failed" and job.change is None and job.finished is not None
    assert job.notice().startswith("The model training failed: DatabaseError: ") and "no scans" in job.notice()
    assert trainings.recent() is job and not (db.root / "models").exists()
