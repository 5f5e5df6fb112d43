"""The web application in a real headless Chromium (Debian's ``chromium`` driven by Playwright).

A whole scan through the browser with simulated devices paced in real time (short steps): the taxonomy
picker, every step with its live level, the operator form with a photo upload, the summary, save; then the
database contents and the database browser. Then each validation error for bad input with nothing saved,
CSRF rejection, keyboard use, and the layout on a laptop and a tablet screen.

Screenshots of every page are written when ``$TEXPLORER_SCREENSHOTS`` names a folder (keep it outside the
repository), to look at the pages: a full-page screenshot of a page that redraws its live level five times
a second can take longer than the step itself on a busy machine, so the suite does not take them otherwise.
"""

from __future__ import annotations

import json
import logging
import os
import re
import shutil
import threading
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

playwright = pytest.importorskip("playwright.sync_api", reason="Playwright for Python is not installed")

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
if not Path(CHROMIUM).is_file():
    pytest.skip("Debian's chromium is not installed (apt-get install chromium)", allow_module_level=True)

from unit.test_gui import make_app  # noqa: E402

from scanner.acquisition.config import Config, SimulatedConfig, StepDurations  # noqa: E402
from scanner.storage.matfile import encode_png  # noqa: E402

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
SCREENSHOTS = Path(os.environ["TEXPLORER_SCREENSHOTS"]) if os.environ.get("TEXPLORER_SCREENSHOTS") else None
LAPTOP = {"width": 1366, "height": 800}
TABLET = {"width": 768, "height": 1024}
UPLOAD_LIMIT = 400_000


def realtime_config() -> Config:
    """Simulated devices in real time, with steps short enough for a test but long enough to watch."""
    return Config(steps=StepDurations(finger_tap=0.6, finger_slide=1.0, tool_tap=0.6, tool_slide=2.4,
                                      static=0.4, heat=0.8, thermal=0.8, friction=0.6, press=0.6, fold=0.6),
                  simulated=SimulatedConfig(realtime=True, image_size=(320, 320)))


@pytest.fixture(scope="module")
def browser():
    if SCREENSHOTS is not None:
        SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    with playwright.sync_playwright() as driver:
        chromium = driver.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield chromium
        chromium.close()


@pytest.fixture
def server(tmp_path):
    """The app on a free port of 127.0.0.1 in a thread; yields (base url, app)."""
    from werkzeug.serving import make_server

    logging.getLogger("werkzeug").setLevel(logging.WARNING)  # no line per request in the test output
    (tmp_path / "exports").mkdir()
    app = make_app(tmp_path / "db", realtime_config(), upload_limit=UPLOAD_LIMIT, export_dir=tmp_path / "exports")
    http = make_server("127.0.0.1", 0, app, threaded=True)
    thread = threading.Thread(target=http.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{http.server_port}", app
    http.shutdown()
    thread.join(10)
    app.extensions["texplorer"].shutdown()


@pytest.fixture
def page(browser):
    context = browser.new_context(viewport=LAPTOP)
    context.set_default_timeout(20_000)
    page = context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    # Refused forms answer 4xx on purpose; the browser logs those documents as failed resources.
    page.on("console", lambda message: errors.append(message.text)
            if message.type == "error" and not message.text.startswith("Failed to load resource") else None)
    page.on("response", lambda response: errors.append(f"{response.status} {response.url}")
            if response.status >= 400 and response.request.resource_type != "document" else None)
    yield page
    context.close()
    assert not errors, f"JavaScript errors, CSP violations or failed page resources: {errors}"


def wait_until(page, expression: str, timeout: float = 20.0) -> None:
    """Poll a JavaScript expression until it is true (``page.wait_for_function`` would need 'unsafe-eval',
    which the app's content security policy forbids; ``evaluate`` goes through the DevTools protocol)."""
    deadline = time.monotonic() + timeout
    while not page.evaluate(expression):
        assert time.monotonic() < deadline, f"timed out waiting for {expression}"
        time.sleep(0.05)


def error_text(page, field: str) -> str:
    """The reason shown beside ``field`` (without the "Error:" read out by screen readers)."""
    return page.text_content(f"#{field}-error").removeprefix("Error: ")


def shot(page, name: str, full_page: bool = True) -> None:
    """The whole page, or with ``full_page=False`` what the screen shows (a sticky bar where it sticks)."""
    if SCREENSHOTS is not None:
        page.screenshot(path=str(SCREENSHOTS / f"{name}.png"), full_page=full_page)


def database(app):
    return app.extensions["texplorer"].db


def photo_file(tmp_path, name="sample.png", size=320, seed=3) -> tuple[Path, np.ndarray]:
    rgb = np.random.default_rng(seed).integers(0, 256, (size, size, 3), dtype=np.uint8)
    rgb[: size // 2] //= 3  # a darker half, so the preview visibly is this photo
    path = tmp_path / name
    path.write_bytes(encode_png(rgb))
    return path, rgb


def start_scan(page, base: str, sample: str) -> None:
    page.goto(base + "/")
    page.fill("#operator", "Ann")
    page.fill("#sample_id", sample)
    page.fill("#label", "C6S1M1P2X1")
    page.click("button:has-text('Start the scan')")
    page.wait_for_url(base + "/session")


def record_step(page, number: int, name: str, screenshot: bool) -> str | None:
    """Record the step on the page; then its traces must be shown between the quality result and the
    keep/redo buttons. Returns the live progress text seen while recording (None when the step ended
    before the page's first poll: a 0.6 s step on a loaded machine can)."""
    page.click("button:has-text('Start recording')")
    page.wait_for_selector("#recording")
    progress = None
    if screenshot:
        try:
            wait_until(page, "!document.getElementById('elapsed') "
                             "|| document.getElementById('elapsed').textContent.length > 0")
            progress = page.evaluate("document.getElementById('elapsed')?.textContent ?? null")
        except playwright.Error as error:  # the page went on to the result while being asked
            if "context was destroyed" not in str(error):
                raise
        if progress is not None:
            shot(page, f"04-step-{number:02d}-{name}-recording")
    page.wait_for_selector("#quality", timeout=30_000)
    wait_until(page, "document.querySelector('#step-traces img').complete", timeout=30)
    assert page.evaluate("document.querySelector('#step-traces img').naturalWidth") == 800
    boxes = [page.locator(selector).first.bounding_box()
             for selector in ("#quality + *", "#step-traces img", "text=Redo this step")]
    assert boxes[0]["y"] < boxes[1]["y"] < boxes[2]["y"] and boxes[1]["height"] > 150
    if screenshot:
        shot(page, f"05-step-{number:02d}-{name}-quality")
    return progress


def test_full_scan_through_the_browser(page, server, tmp_path):
    base, app = server
    page.goto(base + "/")
    shot(page, "01-start")
    page.fill("#operator", "Ann")
    page.fill("#sample_id", "granite-12")
    page.fill("#picker-search", "granite")
    page.click("#picker-results button:has-text('C6S1M1')")
    page.select_option("#picker-p", "P2")
    assert page.input_value("#label") == "C6S1M1P2X1"
    wait_until(page, "document.getElementById('label-description').textContent.includes('granite')")
    assert page.inner_text("#label-description") == "granite (igneous stone, stone), polished, plain"
    shot(page, "02-start-picked")
    page.click("button:has-text('Start the scan')")

    page.wait_for_url(base + "/session")
    assert "granite (igneous stone, stone), polished, plain" in page.inner_text("main")
    sensor = app.extensions["texplorer"].operations.active.session.t_amb
    assert page.input_value("#t_amb") == f"{sensor:.1f}"
    page.fill("#t_amb", "23.4")
    page.click("button:has-text('Set the temperature')")
    page.wait_for_selector("text=Ambient temperature set to 23.4 °C.")
    shot(page, "03-session")
    page.click("text=Continue with the next step")

    steps = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press",
             "fold")
    chips = page.locator("nav[aria-label='Steps of this scan'] a").all_inner_texts()
    assert [chip.split(".", 1)[0] for chip in chips] == [str(n) for n in range(1, 12)]  # unique numbers
    progress = []
    for number, name in enumerate(steps, start=1):
        page.wait_for_url(f"{base}/session/step/{name}")
        assert page.inner_text("h1").startswith(f"Step {number}: ")
        progress.append(record_step(page, number, name, screenshot=name in ("tool_slide", "thermal", "fold")))
        if name == "thermal":
            assert not page.locator("#recording").count()
        page.click("text=Next step")
    seen = [text for text in progress if text is not None]
    assert seen, "no step showed its live progress while recording"
    assert all(re.fullmatch(r"\d+\.\d s of \d+\.\d s", text) for text in seen), seen

    page.wait_for_url(base + "/session/form")
    shot(page, "06-form-empty")
    upload, pixels = photo_file(tmp_path)
    page.set_input_files("#I_disp", str(upload))
    wait_until(page, "document.getElementById('I_disp-preview')?.naturalWidth > 0")
    page.click("button[name=capture][value=I_macro]")
    page.click("button[name=capture][value=I_illu]")
    wait_until(page, "document.getElementById('I_illu-preview')?.naturalWidth > 0")
    assert page.locator("#I_disp-preview").get_attribute("src").startswith("/session/photo/I_disp")
    page.fill("#mass_g", "512,5")
    page.fill("#volume_cm3", "190")
    page.check("input[name=volume_method][value=water]")
    page.check("label.choice:has-text('slightly adhesive') input")
    page.check("label.choice:has-text('material recovers shape') input >> nth=0")
    page.fill("#notes", "edge chipped")
    shot(page, "07-form-filled")
    page.click("button:has-text('Continue to the summary')")

    page.wait_for_url(base + "/session/summary")
    wait_until(page, "document.querySelector('.plot img')?.naturalWidth > 0", timeout=30)
    text = page.inner_text("main")
    assert "thermal cooling TCO (K)" in text and "no trained model" in text
    assert len(database(app)) == 0
    shot(page, "08-summary")
    page.click("button:has-text('Save the scan')")

    page.wait_for_url(base + "/db/scan/granite-12-001")
    assert "Scan granite-12-001 was saved." in page.inner_text("main")
    wait_until(page, "[...document.querySelectorAll('main img')].every(i => i.complete && i.naturalWidth)",
                           timeout=30_000)
    shot(page, "09-saved-scan")

    db = database(app)
    assert [r.scan_id for r in db.records()] == ["granite-12-001"]
    scan = db.get("granite-12-001")
    meta = scan.meta
    assert (meta.label, meta.operator, meta.sample_id, meta.t_amb) \
        == ("C6S1M1P2X1", "Ann", "granite-12", 23.4)
    assert (meta.mass_g, meta.volume_cm3, meta.atk, meta.cyd, meta.rigid) == (512.5, 190.0, 0.25, 0.0, False)
    assert "edge chipped" in meta.notes and meta.volume_method == "water"
    assert np.array_equal(scan.images["I_disp"], pixels)
    assert {"v_ts", "a_ts", "t_cool", "f_fold", "alpha_f", "dB"} <= set(scan.traces)
    assert scan["t_cool"].duration == pytest.approx(0.8, abs=0.1)
    assert db.check().ok

    page.click("nav >> text=Database")
    assert "1 scans of 1 materials" in page.inner_text("main")
    shot(page, "10-database")
    page.click("main table >> text=C6S1M1P2X1")
    page.click("text=granite-12-001")
    page.wait_for_url(base + "/db/scan/granite-12-001")
    with page.expect_download() as download:
        page.goto(base + "/db/")
        page.click("text=Feature table (CSV)")
    csv_lines = Path(download.value.path()).read_text().splitlines()
    assert len(csv_lines) == 2 and csv_lines[1].startswith("granite-12-001,")


def test_each_validation_error_is_shown_and_nothing_saved(page, server, tmp_path):
    base, app = server
    page.goto(base + "/")
    page.fill("#operator", "Ann")
    page.fill("#sample_id", "oak-01")
    page.fill("#label", "C6S1M1PX1")
    wait_until(page, "document.getElementById('label-description').classList.contains('bad')")
    page.click("button:has-text('Start the scan')")
    assert error_text(page, "label").startswith("'C6S1M1PX1' is not a label: P has no number")
    assert page.get_attribute("#label", "aria-invalid") == "true"
    shot(page, "11-start-errors")
    assert app.extensions["texplorer"].operations.active is None

    start_scan(page, base, "oak-01")
    page.click("nav[aria-label='Steps of this scan'] >> text=TU3 photos")
    page.wait_for_url(base + "/session/form")
    not_image = tmp_path / "photo.png"
    not_image.write_text("this is a text file called photo.png")
    too_big, _ = photo_file(tmp_path, "big.png", size=400)
    assert too_big.stat().st_size > UPLOAD_LIMIT
    good, _ = photo_file(tmp_path, "good.png")
    page.set_input_files("#I_disp", str(good))
    page.set_input_files("#I_macro", str(too_big))
    page.set_input_files("#I_illu", str(not_image))
    page.fill("#mass_g", "-5")
    page.fill("#volume_cm3", "12 l")
    page.check("input[name=volume_method][value=water]")
    # A choice off the five-step scale can only come from a tampered form; the server must refuse it too.
    page.eval_on_selector("input[name=atk][value='0.5']",
                          "radio => { radio.value = '0.3'; radio.checked = true; }")
    page.check("label.choice:has-text('material stays deformed') input")
    page.click("button:has-text('Continue to the summary')")

    page.wait_for_selector("#atk-error")
    errors = {name: error_text(page, name) for name in ("atk", "mass_g", "volume_cm3", "I_macro", "I_illu")}
    assert errors["atk"].startswith("0.3 is not on the five-step scale 0, 0.25, 0.5, 0.75, 1")
    assert errors["mass_g"] == "the mass must be positive (in g), got -5"
    assert errors["volume_cm3"] == "'12 l' is not a number in cm^3"
    assert errors["I_macro"] \
        == f"the file is {too_big.stat().st_size / 1024:.0f} KB; photos may be at most 391 KB"
    assert errors["I_illu"] == "not a PNG or JPEG file"
    assert not page.locator("#I_disp-error").count() and not page.locator("#cyd-error").count()
    assert page.input_value("#mass_g") == "-5"  # what was typed stays, to be corrected
    shot(page, "12-form-errors")

    session = app.extensions["texplorer"].operations.active.session
    assert set(session.photos) == {"I_disp"} and np.isnan(session.values["mass_g"])
    page.goto(base + "/session/summary")
    assert "Not ready to save yet" in page.inner_text("main")
    page.click("a:has-text('Abort the scan')")
    page.click("button:has-text('Discard and abort the scan')")
    page.wait_for_url(base + "/")
    assert "nothing was saved" in page.inner_text("main")
    db = database(app)
    assert len(db) == 0 and not any((db.root / "scans").iterdir())


def test_forged_or_missing_csrf_token_is_refused(page, server):
    base, app = server
    page.goto(base + "/")
    page.fill("#operator", "Ann")
    page.fill("#sample_id", "granite-01")
    page.fill("#label", "C6S1M1P2X1")
    page.eval_on_selector("input[name=csrf_token]", "input => { input.value = 'forged'; }")
    page.click("button:has-text('Start the scan')")
    assert "security token is missing or out of date" in page.inner_text("main")
    shot(page, "13-csrf-refused")
    form = {"operator": "Ann", "label": "C6S1M1P2X1", "sample_id": "x-1"}
    answer = page.request.post(base + "/", form=form)
    assert answer.status == 400
    assert app.extensions["texplorer"].operations.active is None


def test_keyboard_only_picker(page, server):
    base, _ = server
    page.goto(base + "/")
    page.keyboard.press("Tab")
    assert page.evaluate("document.activeElement.className") == "skip"
    page.focus("#picker-search")
    page.keyboard.type("oak")
    page.wait_for_selector("#picker-results button")
    page.keyboard.press("Enter")  # from the search box to the first match
    assert page.evaluate("document.activeElement.closest('#picker-results') !== null")
    page.keyboard.press("Enter")  # pick it; focus moves on to the processing shape
    assert page.evaluate("document.activeElement.id") == "picker-p"
    # no processing shape is taken for the operator (P1 would make planed oak natural): the label waits
    assert page.input_value("#label") == ""
    assert page.text_content("#label-description") == "C1S1M1: now choose its processing shape (P)"
    page.keyboard.press("ArrowDown")  # the prompt -> P1 on a focused select
    page.keyboard.press("ArrowDown")  # P1 -> P2
    wait_until(page, "document.getElementById('label').value === 'C1S1M1P2X1'")
    unlabelled = page.evaluate("""[...document.querySelectorAll('input:not([type=hidden]), select, textarea')]
        .filter(el => !(el.labels && el.labels.length) && !el.getAttribute('aria-label')).map(el => el.id)""")
    assert unlabelled == []


@pytest.mark.parametrize(("screen", "viewport"), [("laptop", LAPTOP), ("tablet", TABLET)])
def test_pages_fit_laptop_and_tablet(browser, server, screen, viewport):
    from conftest import make_scan

    base, app = server
    database(app).add(make_scan(0, sample_id="basalt-01", image_shape=(320, 320)))
    context = browser.new_context(viewport=viewport)
    page = context.new_page()
    try:
        for name, url in (("start", "/"), ("database", "/db/"), ("scans", "/db/scans"),
                          ("scan", "/db/scan/basalt-01-001")):
            page.goto(base + url)
            page.evaluate("[...document.images].forEach(i => { i.loading = 'eager'; })")  # the figures below
            wait_until(page, "[...document.images].every(i => i.complete)", timeout=60)
            overflow = page.evaluate("document.documentElement.scrollWidth - window.innerWidth")
            assert overflow <= 0, f"{url} is {overflow} px wider than a {screen} screen"
            shot(page, f"14-{name}-{screen}")
        start_scan(page, base, "granite-02")
        page.click("text=Continue with the next step")
        page.goto(base + "/session/form")
        assert page.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        shot(page, f"15-form-{screen}")
    finally:
        context.close()


def test_step_traces_on_a_tablet(browser, server):
    """After a recording the step's traces fit an 800 px tablet screen, between result and keep/redo."""
    base, _ = server
    context = browser.new_context(viewport={"width": 800, "height": 1280})
    page = context.new_page()
    try:
        start_scan(page, base, "granite-03")
        page.goto(base + "/session/step/finger_slide")
        record_step(page, 2, "finger_slide", screenshot=False)
        assert page.evaluate("document.documentElement.scrollWidth - window.innerWidth") <= 0
        shown = page.locator("#step-traces img").bounding_box()["width"]
        assert 680 <= shown <= 800  # at least 85 % of its own size: the figure's text stays legible
        shot(page, "16-step-traces-tablet")
    finally:
        context.close()


def test_export_job_with_progress_and_filter(page, server, tmp_path, monkeypatch):
    from conftest import make_scan

    from gui import exports

    base, app = server
    db = database(app)
    for index in range(1, 5):
        db.add(make_scan(index, sample_id="granite-01", scan_index=index, image_shape=(64, 64)))
    db.add(make_scan(9, label="C7S1M1P8X1", sample_id="steel-01", rigid=True, drop=("f_fold", "alpha_f")))
    # Hold the second chunk of feature extraction, so the page can be seen part-way through.
    gate, held = threading.Event(), threading.Event()
    original = exports.extract_database

    def extract_held(db, *, records, **kwargs):
        if any(record.scan_id == "granite-01-003" for record in records):
            held.set()
            gate.wait(20)
        return original(db, records=records, **kwargs)

    monkeypatch.setattr(exports, "FEATURE_CHUNK", 2)
    monkeypatch.setattr(exports, "extract_database", extract_held)
    page.set_viewport_size({"width": 800, "height": 900})
    page.goto(base + "/db/")
    page.fill("#export-label", "c6")
    page.fill("#export-license", "CC-BY-4.0")
    shot(page, "17-export-form")
    with page.expect_download(timeout=60_000) as download:
        page.click("button:has-text('Export bundle (ZIP)')")
        page.wait_for_url(f"{base}/db/export/*")
        assert held.wait(20)
        wait_until(page, "document.getElementById('export-count').textContent === 'step 1 of 2: 2 of 4 scans'")
        assert page.evaluate("document.getElementById('export-progress').value") == pytest.approx(0.25)
        assert "4 scan(s): label C6." in page.inner_text("main")
        shot(page, "18-export-progress")
        gate.set()
    path = Path(download.value.path())
    wait_until(page, "document.getElementById('export-phase').textContent.startsWith('Downloaded')")
    assert page.evaluate("document.getElementById('export-progress').value") == 1
    shot(page, "19-export-downloaded")
    name = download.value.suggested_filename
    assert name.startswith("texplorer-export-") and name in page.inner_text("#export-phase")
    with zipfile.ZipFile(path) as bundle:
        assert bundle.testzip() is None
        manifest = json.loads(bundle.read("manifest.json"))
        names = set(bundle.namelist())
    assert manifest["filters"] == {"label": "C6", "session": None}
    assert [scan["scan_id"] for scan in manifest["scans"]] == [f"granite-01-00{i}" for i in range(1, 5)]
    assert set(manifest["files"]) | {"manifest.json", "manifest.json.sha256"} == names
    gui_files = [p for p in (db.root / ".gui").rglob("*") if p.is_file()]
    assert gui_files == [] and not list((tmp_path / "exports").iterdir())


def test_a_taken_bundle_leaves_a_new_export_not_a_dead_link(page, server, browser):
    """After the automatic download the page offers a new export of the same scans; the bundle's link, tapped
    again (a page without script keeps showing it), answers with that page, not a bare refusal."""
    from conftest import make_scan

    base, app = server
    db = database(app)
    for index in (1, 2):
        db.add(make_scan(index, sample_id="granite-01", scan_index=index, image_shape=(64, 64)))
    page.goto(base + "/db/")
    page.fill("#export-label", "C6")
    page.fill("#export-license", "CC0-1.0")
    with page.expect_download(timeout=60_000) as download:
        page.click("button:has-text('Export bundle (ZIP)')")
    assert zipfile.is_zipfile(download.value.path())
    wait_until(page, "document.getElementById('export-phase').textContent.startsWith('Downloaded')")
    assert page.is_hidden("#export-download") and page.is_hidden("#export-cancel")
    assert page.get_attribute("#export-again", "href") == "/db/?label=C6#export-form"
    shot(page, "26-export-taken")
    bundle = page.get_attribute("#export-download", "href")
    taken = page.goto(base + bundle)  # the link of a page that did not update, tapped after the download
    assert taken.status == 409
    assert "This export has no bundle to download (downloaded, and no longer kept here)." in page.inner_text("main")
    assert page.is_hidden("#export-download") and page.is_visible("#export-again")
    shot(page, "27-export-taken-again")
    page.click("#export-again")
    page.wait_for_url(base + "/db/?label=C6#export-form")
    assert page.input_value("#export-label") == "C6"

    # Without script the page refreshes itself while the job runs, then shows the link; a second tap on it
    # (the page cannot know the first one downloaded the bundle) leads on to a new export.
    context = browser.new_context(viewport=LAPTOP, java_script_enabled=False, accept_downloads=True)
    plain = context.new_page()
    try:
        plain.goto(base + "/db/")
        plain.fill("#export-license", "CC0-1.0")
        plain.click("button:has-text('Export bundle (ZIP)')")
        plain.wait_for_selector("#export-download:not([hidden])", timeout=60_000)
        with plain.expect_download() as download:
            plain.click("#export-download")
        assert zipfile.is_zipfile(download.value.path())
        assert plain.is_visible("#export-download")
        plain.click("#export-download")
        plain.wait_for_selector("#export-again:not([hidden])")
        assert plain.get_attribute("#export-again", "href") == "/db/#export-form"
        shot(plain, "28-export-taken-no-script")
    finally:
        context.close()


def field_state(page, field: str) -> dict:
    """Whether ``field`` is marked invalid: its aria-invalid, its reason beside it, its red box."""
    return page.evaluate("""(name) => {
        const field = document.getElementById(name);
        return {invalid: field.getAttribute('aria-invalid'), reason: Boolean(document.getElementById(name + '-error')),
                box: Boolean(field.closest('.invalid')), described: field.getAttribute('aria-describedby')};
    }""", field)


MARKED = {"invalid": "true", "reason": True, "box": True}


def marked(page, field: str) -> bool:
    state = field_state(page, field)
    return {key: state[key] for key in MARKED} == MARKED


def test_a_corrected_field_loses_its_error_and_the_server_still_checks(page, server, tmp_path):
    base, _ = server
    page.goto(base + "/")
    page.click("button:has-text('Start the scan')")
    assert all(marked(page, name) for name in ("operator", "sample_id", "label"))
    page.fill("#sample_id", "granite 01")  # still not a sample id: the reason stays
    assert marked(page, "sample_id")
    page.fill("#sample_id", "granite-01")
    assert field_state(page, "sample_id") == {"invalid": None, "reason": False, "box": False,
                                              "described": "sample_id-hint"}
    page.fill("#operator", "Ann")
    assert not field_state(page, "operator")["invalid"] and marked(page, "label")
    page.fill("#label", "C6S1M1PX1")  # the server's label check, as it is typed, refuses it
    wait_until(page, "document.getElementById('label-description').classList.contains('bad')")
    assert marked(page, "label")
    page.fill("#label", "C6S1M1P2X1")
    wait_until(page, "!document.getElementById('label-error')")
    assert field_state(page, "label")["invalid"] is None
    shot(page, "29-start-corrected")
    page.click("button:has-text('Start the scan')")
    page.wait_for_url(base + "/session")

    page.goto(base + "/session/form")
    not_image = tmp_path / "photo.png"
    not_image.write_text("this is a text file called photo.png")
    page.set_input_files("#I_illu", str(not_image))
    page.fill("#mass_g", "-5")
    page.fill("#volume_cm3", "12 l")
    page.click("button:has-text('Continue to the summary')")
    page.wait_for_selector("#mass_g-error")
    assert all(marked(page, name) for name in ("mass_g", "volume_cm3", "I_illu", "I_disp"))
    assert all(field_state(page, name)["invalid"] == "true" for name in ("atk", "cyd"))
    shot(page, "30-form-errors")
    page.fill("#mass_g", "-6")  # a sign: the reason stays
    page.fill("#volume_cm3", "12 ")  # the volume's unit typed again: the reason goes as it changes
    assert marked(page, "mass_g") and not field_state(page, "volume_cm3")["invalid"]
    page.fill("#mass_g", "0")  # looks like a number to the browser; the server refuses it again below
    assert not field_state(page, "mass_g")["invalid"]
    page.check("label.choice:has-text('slightly adhesive') input")
    assert field_state(page, "atk") == {"invalid": None, "reason": False, "box": False, "described": None}
    assert field_state(page, "cyd")["invalid"] == "true"
    page.set_input_files("#I_illu", str(not_image))  # again not a photo: the reason stays
    page.evaluate("() => new Promise(done => setTimeout(done, 300))")
    assert marked(page, "I_illu")
    photo, _ = photo_file(tmp_path)
    page.set_input_files("#I_illu", str(photo))
    wait_until(page, "!document.getElementById('I_illu-error')")
    assert not field_state(page, "I_illu")["invalid"] and marked(page, "I_disp")
    shot(page, "31-form-corrected")
    page.click("button:has-text('Continue to the summary')")
    page.wait_for_selector("#mass_g-error")
    assert error_text(page, "mass_g") == "the mass must be positive (in g), got 0"
    assert not page.locator("#atk-error").count() and not page.locator("#I_illu-error").count()
