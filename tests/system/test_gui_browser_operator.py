"""A lab operator's day in a real headless Chromium: an abort asks first, a sent form shows that it is busy
and cannot be sent twice, the summary and scan pages fit a tablet (768 px) and a laptop (1280 px), and no
page answers a server error for what a person can type.

Screenshots are written when ``$TEXPLORER_SCREENSHOTS`` names a folder (see ``test_gui_browser``).
"""

from __future__ import annotations

import logging
import threading
from urllib.parse import quote

import pytest

from scanner.scan import IMAGES
from system.test_gui_browser import (  # noqa: F401 - fixtures
    SCREENSHOTS,
    browser,
    page,
    playwright,
    record_step,
    server,
    shot,
    start_scan,
    wait_until,
)

TABLET = {"width": 768, "height": 1024}
DESKTOP = {"width": 1280, "height": 800}


@pytest.fixture
def tab(request):
    """A laptop-sized Chromium page that fails the test on script errors (``test_gui_browser.page``)."""
    return request.getfixturevalue("page")


@pytest.fixture
def chromium(request):
    """The headless Chromium of ``test_gui_browser``."""
    return request.getfixturevalue("browser")


@pytest.fixture
def paced_server(request):
    """The app with simulated devices paced in real time (``test_gui_browser.server``): its steps record
    long enough for the page to show them recording."""
    return request.getfixturevalue("server")


@pytest.fixture
def fast_server(tmp_path):
    """The app with simulated devices that do not wait in real time, on a free port; yields (url, app)."""
    from unit.test_gui import fast_config, make_app
    from werkzeug.serving import make_server

    logging.getLogger("werkzeug").setLevel(logging.WARNING)
    app = make_app(tmp_path / "db", fast_config())
    http = make_server("127.0.0.1", 0, app, threaded=True)
    thread = threading.Thread(target=http.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{http.server_port}", app
    http.shutdown()
    thread.join(10)
    app.extensions["texplorer"].shutdown()


def start(tab, base: str, sample: str = "granite-05") -> None:
    tab.goto(base + "/")
    tab.fill("#operator", "Ann")
    tab.fill("#sample_id", sample)
    tab.fill("#label", "C6S1M1P2X1")
    tab.click("button:has-text('Start the scan')")
    tab.wait_for_url(base + "/session")


def complete(app) -> None:
    """Record every step, take the photos and enter the TU4 values, as the operator would have."""
    from unit.test_gui import BASE

    op = app.extensions["texplorer"].operations.active
    session = op.session
    viewer = app.test_client()
    for step in session.steps:
        if step.kind == "record" and session.status(step.id).state != "recorded":
            op.touch()  # the page that polls while a step records (else the Peltier watchdog stops the heating)
            status = session.record(step.id)
            assert status.state == "recorded", status
            # the step page shows the recording's figure
            assert viewer.get(f"/session/step/{step.id}/traces.png", base_url=BASE).status_code == 200
    for name in IMAGES:
        session.capture_photo(name)
    session.set_values(atk=0.0, cyd=0.25, mass_g=512.5, volume_cm3=190.0, volume_method="water")
    op.changed()


def test_abort_asks_first_then_keeps_the_start_form(tab, fast_server):
    base, app = fast_server
    start(tab, base)
    tab.click("text=Continue with the next step")
    tab.click("button:has-text('Start recording')")
    tab.wait_for_selector("#quality", timeout=30_000)
    tab.click("a:has-text('Abort the scan')")
    tab.wait_for_url(lambda url: "/session/abort?back=" in url)
    text = tab.inner_text("main")
    assert "Abort the scan of granite-05?" in text and "1 recorded step: TU1 finger tap" in text
    shot(tab, "20-abort-confirm")
    tab.click("text=Keep scanning")
    tab.wait_for_url(f"{base}/session/step/finger_tap")
    assert app.extensions["texplorer"].operations.active.session.status("finger_tap").state == "recorded"

    tab.click("a:has-text('Abort the scan')")
    tab.click("button:has-text('Discard and abort the scan')")
    tab.wait_for_url(base + "/")
    assert app.extensions["texplorer"].operations.active is None
    assert [tab.input_value(f"#{name}") for name in ("operator", "sample_id", "label")] \
        == ["Ann", "granite-05", "C6S1M1P2X1"]
    assert len(app.extensions["texplorer"].db) == 0


RECORD_BUSY = """() => {
    // Headless Chromium runs no script of the old page while its form's request is on its way, so the page
    // notes what it shows in sessionStorage (kept across the navigation), to be read on the next tab.
    const note = document.getElementById('busy-note');
    sessionStorage.setItem('submits', '[]');
    window.addEventListener('submit', (event) => {
        const seen = JSON.parse(sessionStorage.getItem('submits'));
        seen.push(event.defaultPrevented ? 'refused' : 'sent');
        sessionStorage.setItem('submits', JSON.stringify(seen));
    });
    new MutationObserver(() => {
        const busy = document.querySelector('button.busy');
        if (!busy || sessionStorage.getItem('busy')) return;
        sessionStorage.setItem('busy', JSON.stringify({
            text: busy.textContent, noteShown: !note.hidden, note: note.textContent,
            allDisabled: [...document.querySelectorAll('main form button')].every(b => b.disabled),
            pageBusy: document.body.getAttribute('aria-busy')}));
    }).observe(document.body, {subtree: true, childList: true, attributes: true, characterData: true});
}"""


def test_a_sent_form_is_busy_and_cannot_be_sent_twice(tab, fast_server):
    import json

    base, app = fast_server
    start(tab, base)
    complete(app)
    tab.goto(base + "/session/summary")
    posts = []
    tab.on("request", lambda request: posts.append(request.url) if request.method == "POST" else None)
    tab.evaluate(RECORD_BUSY)
    tab.dblclick("button:has-text('Save the scan')")  # a double tap with gloves on
    tab.wait_for_url(f"{base}/db/scan/granite-05-001", wait_until="domcontentloaded")
    busy = json.loads(tab.evaluate("sessionStorage.getItem('busy')"))
    assert busy == {"text": "Saving the scan…", "noteShown": True, "allDisabled": True, "pageBusy": "true",
                    "note": "Saving the scan… Please wait; the page changes by itself."}
    # The second tap is refused by the form's guard if it comes before the buttons are disabled (a timer
    # of 0 ms after the first submit), and swallowed by the disabled button if it comes after (a loaded
    # machine): either way one request only.
    assert json.loads(tab.evaluate("sessionStorage.getItem('submits')")) in (["sent", "refused"], ["sent"])
    assert posts == [base + "/session/save"]
    assert [r.scan_id for r in app.extensions["texplorer"].db.records()] == ["granite-05-001"]
    # The camera buttons still say which photo to take (the button is disabled only after the form is sent).
    start(tab, base, "granite-09")
    tab.goto(base + "/session/form")
    tab.click("button[name=capture][value=I_macro]")
    tab.wait_for_selector("#I_macro-preview:not([hidden])")
    assert set(app.extensions["texplorer"].operations.active.session.photos) == {"I_macro"}


def overflow(tab) -> dict[str, float]:
    """How far the page and its main content reach beyond the screen, and the widest table beyond its box
    when that box does not scroll (all 0 when everything fits)."""
    return tab.evaluate("""() => {
        const main = document.querySelector('main');
        const tables = [...main.querySelectorAll('table')].map(table => {
            const box = table.closest('.table-wrap, details, .panel') || main;
            const scrolls = getComputedStyle(box).overflowX === 'auto';
            return scrolls ? 0 : table.getBoundingClientRect().right - box.getBoundingClientRect().right;
        });
        return {page: document.documentElement.scrollWidth - window.innerWidth,
                main: main.scrollWidth - main.clientWidth,
                table: Math.max(0, ...tables)};
    }""")


def smallest_text(tab) -> float:
    """The smallest font size (px) of any visible text in the main content."""
    return tab.evaluate("""() => Math.min(...[...document.querySelectorAll('main *')]
        .filter(el => [...el.childNodes].some(n => n.nodeType === 3 && n.textContent.trim())
                      && el.getClientRects().length)
        .map(el => parseFloat(getComputedStyle(el).fontSize)))""")


@pytest.mark.parametrize(("screen", "viewport"), [("tablet", TABLET), ("desktop", DESKTOP)])
def test_summary_and_scan_pages_fit_the_screen(chromium, fast_server, screen, viewport):
    base, app = fast_server
    context = chromium.new_context(viewport=viewport)
    tab = context.new_page()
    try:
        start(tab, base, "granite-06")
        complete(app)
        for name, url in (("summary", "/session/summary"), ("scan", None)):
            if url is None:
                tab.click("button:has-text('Save the scan')")
                tab.wait_for_url(f"{base}/db/scan/granite-06-001")
            else:
                tab.goto(base + url)
            tab.evaluate("[...document.images].forEach(i => { i.loading = 'eager'; })")
            wait_until(tab, "[...document.images].every(i => i.complete && i.naturalWidth)", timeout=60)
            assert overflow(tab) == {"page": 0, "main": 0, "table": 0}, name
            assert smallest_text(tab) >= 12, name
            # The step figures are 800 px wide with text of 14.5 px and more: shown at 85 % or more of their
            # size, no text of theirs is below 12 px.
            widths = tab.evaluate("[...document.querySelectorAll('.step-figures img')].map(i => i.width)")
            assert len(widths) == 9 and min(widths) >= 0.85 * 800, widths
            shot(tab, f"22-{name}-{screen}")
        tab.goto(base + "/db/scans")
        assert overflow(tab) == {"page": 0, "main": 0, "table": 0}
        shot(tab, f"23-scans-{screen}")
    finally:
        context.close()


def visit(tab, url: str) -> int:
    """The status of a page the browser opens (a download, such as the feature table, is fetched instead)."""
    try:
        return tab.goto(url).status
    except playwright.Error as error:
        if "Download is starting" not in str(error):
            raise
        return tab.request.get(url).status


def test_no_page_answers_a_server_error_in_the_browser(tab, fast_server):
    from conftest import make_scan
    from unit.test_gui_operator import PARAMETERS, routes

    base, app = fast_server
    app.extensions["texplorer"].db.add(make_scan(0, sample_id="granite-01", image_shape=(64, 64)))
    typed = ("ZZZ", "granite", "../../etc/passwd", "<script>alert(1)</script>", "é" * 100)
    statuses = {}
    for rule, arguments in routes(app):
        for value in typed:
            path = rule
            for name in arguments:
                path = path.replace(f"<{name}>", quote(value, safe="")).replace(f"<path:{name}>", quote(value))
            query = "&".join(f"{name}={quote(value, safe='')}" for name in PARAMETERS)
            for url in (path, f"{path}?{query}"):
                statuses[url] = visit(tab, base + url)
    assert [url for url, status in statuses.items() if status >= 500] == []
    # A misspelled material in the scans filter: the reason beside the field, the typed text kept.
    tab.goto(base + "/db/scans")
    tab.fill("#f-label", "graniet")
    tab.click("button:has-text('Filter')")
    assert "part of a material name, e.g. granite" in tab.inner_text("#label-error")
    assert tab.input_value("#f-label") == "graniet"
    tab.fill("#f-label", "Granite")
    tab.click("button:has-text('Filter')")
    assert "1 scan(s)." in tab.inner_text("main")


# -- in reach on a tablet ------------------------------------------------------------------------------------

CONTROLS = """() => [...document.querySelectorAll(
        '.top a, button, .button, input:not([type=hidden]), select, textarea, summary, .steps a')]
    .map(el => el.matches('input[type=radio], input[type=checkbox]') ? el.closest('label') || el : el)
    .filter(el => el.getClientRects().length && el.getBoundingClientRect().right > 0
                  && getComputedStyle(el).visibility !== 'hidden')
    .map(el => ({control: `${el.tagName.toLowerCase()}${el.id ? '#' + el.id : ''} ${el.type || ''} `
                          + (el.textContent || el.name || '').trim().slice(0, 30),
                 height: Math.round(10 * el.getBoundingClientRect().height) / 10}))"""
"""Every control a finger taps on the page, with its height in px: a radio button's label is its target."""


def short_controls(tab) -> list[dict]:
    """The visible controls of the page under 44 px tall (WCAG 2.5.5: a target of 44 x 44 CSS px)."""
    return [control for control in tab.evaluate(CONTROLS) if control["height"] < 44]


IN_VIEW = """(el) => {
    const box = el.getBoundingClientRect();
    const hit = document.elementFromPoint(box.left + box.width / 2, box.top + box.height / 2);
    return {top: Math.round(box.top), bottom: Math.round(box.bottom), scrolled: window.scrollY,
            inside: box.top >= 0 && box.left >= 0 && box.bottom <= innerHeight && box.right <= innerWidth,
            uncovered: el.contains(hit)};
}"""
"""Where an element is on the screen as the page opened, and whether it lies inside it, not covered."""


@pytest.mark.parametrize(("screen", "viewport"), [("tablet", TABLET), ("desktop", DESKTOP)])
def test_step_result_and_actions_in_reach_and_every_control_tall_enough(tab, paced_server, screen,
                                                                        viewport):
    """After a recording the verdict, Next step and Redo are on the screen as the page opens, on a tablet
    and a laptop, a tap step (short figure) and a slide step (tall figure); every control is 44 px tall."""
    base, app = paced_server
    tab.set_viewport_size(viewport)
    short = {}
    tab.goto(base + "/")
    tab.fill("#picker-search", "granite")
    tab.wait_for_selector("#picker-results button")
    short["start"] = short_controls(tab)
    start_scan(tab, base, f"granite-{screen}")
    short["session"] = short_controls(tab)
    places = {}
    for number, name in ((1, "finger_tap"), (2, "finger_slide")):
        tab.goto(f"{base}/session/step/{name}")
        short[name] = short_controls(tab)
        places[f"{name}, to record"] = {"start": tab.locator("text=Start recording").evaluate(IN_VIEW)}
        record_step(tab, number, name, screenshot=False)
        shot(tab, f"24-step-{number:02d}-{name}-{screen}", full_page=False)
        places[name] = {what: tab.locator(selector).first.evaluate(IN_VIEW) for what, selector in (
            ("verdict", "#quality + *"), ("next", "a:has-text('Next step')"), ("redo", "text=Redo this step"))}
        short[f"{name}, recorded"] = short_controls(tab)
    assert all(place["inside"] and place["uncovered"] and not place["scrolled"]
               for where in places.values() for place in where.values()), places
    complete(app)
    for name in ("form", "summary"):
        tab.goto(f"{base}/session/{name}")
        short[name] = short_controls(tab)
        shot(tab, f"25-{name}-controls-{screen}", full_page=False)
    assert short == dict.fromkeys(short, []), short
