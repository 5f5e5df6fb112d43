"""Take the documentation's screenshots (docs/screenshots/*.png) in headless Chromium.

Usage, from the repository's root, after ``make demo`` (or on any demo database)::

    .venv/bin/python docs/screenshots.py texplorer-data

It serves the web application on the database with the simulated scanner (``texplorer serve`` on a free
port, steps shortened so the walk through a scan takes seconds), runs one scan of polished granite through
the browser the way an operator does, and photographs the start page, a recorded step, the operator form,
the summary with the prediction, one scan in the database browser, and the evaluation report
(``<db>/report/index.html``). The scan is aborted at the summary, so the database is left as it was.
Before each photograph the page is checked against :data:`SHOTS`, what the docs' caption of that
screenshot says it shows: a page whose structure changed stops the run naming what is missing
(``tests/system/test_docs.py`` runs the walk, and checks that the docs use these captions).

Needs Playwright (a development dependency) and Debian's ``chromium`` (``apt-get install chromium``).
"""

from __future__ import annotations

import argparse
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from playwright.sync_api import Error, Page, sync_playwright

HERE = Path(__file__).resolve().parent
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
VIEWPORT = {"width": 1200, "height": 800}
STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press", "fold")
CONFIG = """\
# Short steps so that a scan takes seconds; the simulated scanner in real time, as an operator sees it.
[steps]
finger_tap = 0.8
finger_slide = 2.4
tool_tap = 0.8
tool_slide = 2.4
static = 0.4
heat = 0.8
thermal = 1.0
friction = 0.8
press = 0.8
fold = 0.8

[simulated]
realtime = true
image_size = [320, 320]
"""


@dataclass(frozen=True)
class Shot:
    """One screenshot: its caption in the docs (``![caption](screenshots/NAME.png)``) and what the page must
    show for that caption to describe it (Playwright selectors, each matching at least one element)."""

    caption: str
    shows: tuple[str, ...]


SHOTS = {
    "start": Shot("The start page with the taxonomy picker",
                  ("#operator", "#picker-search", "#picker-p", "#sample_id", "button:has-text('Start the scan')")),
    "step": Shot("A recorded step: its traces and the quality check",
                 ("#quality", "#step-traces img", "text=Next step", "text=Redo")),
    "form": Shot("The operator form",
                 ("#I_disp-preview", "#mass_g", "#volume_cm3", "input[name=atk]", "input[name=cyd]")),
    "summary": Shot("The summary with the prediction",
                    ("ol.predictions", "button:has-text('Save the scan')", "a:has-text('Abort the scan')")),
    "browser": Shot("One scan in the database browser",
                    ("main h1:has-text('Scan')", "main img", "main table")),
    "report": Shot("The evaluation report of the small demo database below", ("table", "img")),
}
"""Every screenshot of the docs; :func:`take` checks each page against its entry before photographing it."""


class StructureChanged(AssertionError):
    """A page no longer shows what its screenshot's caption says."""


def check_shows(page: Page, name: str) -> None:
    """Raise :class:`StructureChanged` naming the first thing of ``SHOTS[name]`` the page does not show."""
    for selector in SHOTS[name].shows:
        if page.locator(selector).count() == 0:
            raise StructureChanged(f"{name}.png: the page shows no {selector!r}, so the caption "
                                   f"{SHOTS[name].caption!r} no longer describes it; update the page, the caption "
                                   "and docs/screenshots.py together")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def serve(db: Path, config: Path, port: int) -> subprocess.Popen:
    """``texplorer serve`` in a child process, returned once it answers."""
    texplorer = Path(sys.executable).with_name("texplorer")
    server = subprocess.Popen([str(texplorer), "serve", "--db", str(db), "--config", str(config),
                               "--port", str(port)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1).close()
            return server
        except OSError:
            if server.poll() is not None:
                raise SystemExit(f"texplorer serve ended: {server.stderr.read().decode()}") from None
            time.sleep(0.2)
    server.terminate()
    raise SystemExit("texplorer serve did not answer within 60 s")


def wait_until(page: Page, expression: str, timeout: float = 30.0) -> None:
    """Poll a JavaScript expression (the app's content security policy forbids ``wait_for_function``)."""
    deadline = time.monotonic() + timeout
    while not _holds(page, expression):
        if time.monotonic() > deadline:
            raise TimeoutError(expression)
        time.sleep(0.05)


def _holds(page: Page, expression: str) -> bool:
    try:
        return bool(page.evaluate(expression))
    except Error:  # the page is being replaced (a form was submitted): ask the next one
        return False


def record(page: Page) -> None:
    page.click("button:has-text('Start recording')")
    page.wait_for_selector("#quality", timeout=30_000)
    wait_until(page, "document.querySelector('#step-traces img').complete")


def take(db: Path, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    shots: list[Path] = []
    with tempfile.TemporaryDirectory() as scratch:
        config = Path(scratch) / "screenshots.toml"
        config.write_text(CONFIG)
        port = free_port()
        base = f"http://127.0.0.1:{port}"
        server = serve(db, config, port)
        try:
            with sync_playwright() as driver:
                browser = driver.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
                page = browser.new_context(viewport=VIEWPORT).new_page()
                page.set_default_timeout(30_000)

                def shot(name: str, full_page: bool = False) -> None:
                    check_shows(page, name)
                    path = out / f"{name}.png"
                    page.screenshot(path=str(path), full_page=full_page)
                    shots.append(path)

                page.goto(base + "/")
                page.fill("#operator", "Ann")
                page.fill("#sample_id", "granite-docs")
                page.fill("#picker-search", "granite")
                page.click("#picker-results button:has-text('C6S1M1')")
                page.select_option("#picker-p", "P2")
                wait_until(page, "document.getElementById('label-description').textContent.includes('polished')")
                shot("start")
                page.click("button:has-text('Start the scan')")
                page.wait_for_url(base + "/session")
                page.click("text=Continue with the next step")
                for name in STEPS:
                    page.wait_for_url(f"{base}/session/step/{name}")
                    record(page)
                    if name == "tool_slide":
                        shot("step", full_page=True)
                    page.click("text=Next step")
                page.wait_for_url(base + "/session/form")
                for photo in ("I_disp", "I_macro", "I_illu"):
                    page.click(f"button[name=capture][value={photo}]")
                    wait_until(page, f"document.getElementById('{photo}-preview').naturalWidth > 0")
                page.fill("#mass_g", "512")
                page.fill("#volume_cm3", "190")
                page.check("input[name=volume_method][value=water]")
                page.check("label.choice:has-text('not adhesive') input")
                page.check("label.choice:has-text('material recovers shape') input >> nth=0")
                shot("form", full_page=True)
                page.click("button:has-text('Continue to the summary')")
                page.wait_for_url(base + "/session/summary", timeout=300_000)  # features and prediction
                shot("summary", full_page=True)
                page.click("a:has-text('Abort the scan') >> nth=0")  # asks first, on a page of its own
                page.click("button:has-text('Discard and abort the scan')")
                page.wait_for_url(base + "/")

                page.goto(base + "/db/")
                page.click("main table >> text=C6S1M1P2X1")
                page.click("main a:has-text('granite-polished-01-001')")
                # the trace figure is drawn and the features extracted on the first view
                wait_until(page, "document.querySelector('main img')?.complete", timeout=300)
                shot("browser")

                report = db.resolve() / "report" / "index.html"
                if report.is_file():
                    page.goto(report.as_uri())
                    wait_until(page, "Array.from(document.images).every(i => i.complete)")
                    shot("report")
                browser.close()
        finally:
            server.terminate()
            server.wait(30)
    return shots


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("db", type=Path, help="a demo database (make demo)")
    parser.add_argument("--out", type=Path, default=HERE / "screenshots", help="folder for the PNG files")
    args = parser.parse_args()
    for path in take(args.db, args.out):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
