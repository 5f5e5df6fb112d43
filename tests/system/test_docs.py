"""The documentation: the code cites the papers and the project's own pages, not a document it does not ship: the
system tests (the site built, and opened in a browser, and the pages' examples run in subprocesses)."""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pytest
import scipy.io.wavfile
from unit.test_docs import PYTHON, ROOT, Block, _pages, blocks, runnable

SNIPPET = re.compile(r'^--8<-- "(?P<path>[^"]+)"$')


DEMO = ["demo", "--materials", "granite-polished", "oak-planed", "mild-steel-brushed", "polyurethane-foam",
        "--image-size", "256", "--classifier", "rf", "lda"]


"""The small demo database the examples run on: the command getting-started.md shows."""


def _pages_with_examples() -> list[str]:
    return [str(p.relative_to(ROOT)) for p in _pages() if any(runnable(b) for b in blocks(p))]


def _wav(path: Path, frequency: float, seed: int) -> None:
    """One second of a noisy tone as 16-bit PCM, a tool slide's sound for the walk-through of ingest.md."""
    rng = np.random.default_rng(seed)
    t = np.arange(44100) / 44100
    x = 0.3 * np.sin(2 * np.pi * frequency * t) + 0.05 * rng.standard_normal(t.size)
    path.parent.mkdir(parents=True, exist_ok=True)
    scipy.io.wavfile.write(path, 44100, (x * 32767).astype(np.int16))


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory) -> Path:
    """A working folder holding the small demo database (``texplorer-data``) and the tool-slide sounds of
    ingest.md's walk-through (``slides/<material>/<object>_<trial>.wav``)."""
    folder = tmp_path_factory.mktemp("examples")
    done = subprocess.run([_texplorer(), *DEMO, "--db", str(folder / "texplorer-data")], env=_environment(),
                          cwd=folder, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, f"texplorer {' '.join(DEMO)} exits {done.returncode}: {done.stderr[-2000:]}"
    for k, (material, frequency) in enumerate((("cardboard", 180.0), ("cork", 420.0), ("steel", 900.0))):
        for piece in (1, 2, 3, 4):
            for trial in (1, 2):
                _wav(folder / "slides" / material / f"{material}-{piece}_{trial:02d}.wav",
                     frequency * (1 + 0.02 * piece), seed=100 * k + 10 * piece + trial)
    return folder


def _texplorer() -> str:
    return str(Path(sys.executable).with_name("texplorer"))


def _environment() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "TEXPLORER_DB"}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    return env


def _run(block: Block, command: list[str], cwd: Path) -> None:
    done = subprocess.run(command, cwd=cwd, env=_environment(), capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{block} exits {done.returncode}:\n{block.body}\n{done.stdout}\n{done.stderr}"


@pytest.mark.slow
@pytest.mark.parametrize("page", _pages_with_examples())
def test_the_examples_of_a_page_run_as_written(page, demo_folder, tmp_path):
    """Every Python and shell block of the page, in order, in one folder
    holding a copy of the small demo database (a shell block, or a run of consecutive Python blocks, in a
    process of its own); the files the page shows (``# slides.toml``) are written
    there first, and the repository's docs/, tests/ and benchmarks/ are reachable by the relative paths the
    examples use."""
    work = tmp_path / "work"
    shutil.copytree(demo_folder, work, symlinks=True)
    for name in ("docs", "tests", "benchmarks"):
        (work / name).symlink_to(ROOT / name)
    python: list[Block] = []  # consecutive Python blocks run in one process, as a notebook's cells
    for block in [*filter(runnable, blocks(ROOT / page)), None]:
        if block is not None and block.lang in PYTHON:
            python.append(block)
            continue
        if python:
            code = "\n".join(_python_source(b) for b in python)
            _run(python[0], [sys.executable, "-c", code], work)
            python = []
        if block is None:
            break
        if block.file is not None:
            (work / block.file).write_text(block.body)
        else:
            _run(block, ["bash", "-euo", "pipefail", "-c", block.body], work)


def _python_source(block: Block) -> str:
    snippet = SNIPPET.match(block.body.strip())
    return (ROOT / "docs" / snippet["path"]).read_text() if snippet else block.body


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """``make docs``: the site built from the repository's pages (mkdocs build --strict), in a folder of its own."""
    if importlib.util.find_spec("mkdocs") is None or importlib.util.find_spec("mkdocstrings") is None:
        pytest.skip("mkdocs and mkdocstrings are not installed (pip install 'texplorer[docs]'; make install does)")
    folder = tmp_path_factory.mktemp("docs") / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(folder)],
                          cwd=ROOT, env={**_environment(), "NO_MKDOCS_2_WARNING": "1"}, capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    return folder


def _html_pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


@pytest.mark.slow
def test_the_site_builds_with_warnings_as_errors(site):
    """``make docs``: every page, link, anchor, image and API entry resolves (mkdocs build --strict), with no
    network (the theme's web fonts are off)."""
    assert (site / "features.html").is_file()
    assert "tactum.matx" in (site / "api" / "features.html").read_text()


LINK = re.compile(r"""<(?:a|link|script|img)\b[^>]*?\b(?:href|src)="(?P<url>[^"#?]*)""")


@pytest.mark.slow
def test_every_link_of_the_site_opens_a_file(site):
    """Opened from disk (README.md), a link to a folder shows the folder's listing, not its page: every link
    between the pages, and to their scripts, styles and images, names a file of the site (404.html, served
    only by a server, links from the site's root)."""
    broken = []
    for page in _html_pages(site):
        if page.name == "404.html":
            continue
        for url in {m["url"] for m in LINK.finditer(page.read_text(encoding="utf-8"))}:
            if url and not re.match(r"[a-z][a-z0-9+.-]*:", url) and not (page.parent / unquote(url)).is_file():
                broken.append(f"{page.relative_to(site)}: {url}")
    assert not broken, f"{len(broken)} links open no file:\n" + "\n".join(sorted(broken)[:40])


ROLE = re.compile(r":(?:func|class|data|meth|mod|attr):")
CODE = re.compile(r"<pre\b.*?</pre>|<code\b.*?</code>", re.S)


@pytest.mark.slow
def test_no_page_shows_a_sphinx_role(site):
    """The docstrings cite objects with Sphinx roles (``:func:`name```), which Markdown does not know: the
    API reference shows each as inline code (docs/hooks.py), never the role itself. Code is left as written."""
    shown = {}
    for page in _html_pages(site):
        roles = ROLE.findall(CODE.sub("", page.read_text(encoding="utf-8")))
        if roles:
            shown[str(page.relative_to(site))] = len(roles)
    assert not shown, f"pages showing Sphinx roles literally (page: how many): {shown}"


HTML_ELEMENTS = frozenset("""
    a abbr address area article aside audio b bdi bdo blockquote body br button canvas caption cite code col
    colgroup data datalist dd del details dfn dialog div dl dt em embed fieldset figcaption figure footer form
    h1 h2 h3 h4 h5 h6 head header hgroup hr html i iframe img input ins kbd label legend li link main map mark
    menu meta meter nav noscript object ol optgroup option output p picture pre progress q rp rt ruby s samp
    script search section select slot small source span strong style sub summary sup table tbody td template
    textarea tfoot th thead time title tr track u ul var video wbr
    svg path g circle ellipse line polygon polyline rect defs use symbol title desc lineargradient stop clippath
    math mi mo mn mrow msup msub mfrac msqrt mtext annotation semantics
    """.split())


@pytest.mark.slow
def test_no_page_holds_an_element_html_does_not_have(site):
    """A placeholder written bare in a page (``closest: <name>``) is read as an HTML element and vanishes:
    every placeholder is in a code span (or escaped), so no page holds an element HTML does not have."""
    from html.parser import HTMLParser

    class Elements(HTMLParser):
        def __init__(self):
            super().__init__()
            self.unknown: set[str] = set()

        def handle_starttag(self, tag, attrs):
            if tag not in HTML_ELEMENTS:
                self.unknown.add(tag)

    found: dict[str, set[str]] = {}
    for page in _html_pages(site):
        parser = Elements()
        parser.feed(page.read_text(encoding="utf-8"))
        for tag in parser.unknown:
            found.setdefault(tag, set()).add(str(page.relative_to(site)))
    assert not found, f"placeholders read as HTML elements (element: pages): {found}"


# -- the site in a browser: opened from disk (README.md) and served -------------------------------------------

CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]


@pytest.fixture(scope="module")
def served_site(site):
    """The built site served over HTTP on a free port of 127.0.0.1 in a thread; yields its address."""
    import functools
    import http.server
    import threading

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *_):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_port}"
    server.shutdown()
    thread.join(10)


@pytest.mark.slow
@pytest.mark.parametrize("opened", ["from disk", "served"])
def test_the_site_navigates_and_searches_in_a_browser(opened, site, request):
    """In Chromium, from ``site/index.html`` opened from disk (file://) and from the site served: the
    navigation's "Getting started" opens that page (not a folder's listing), and search finds a word of
    another page; with no script error and nothing fetched from anywhere but the site (no network)."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright for Python is not installed")
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    if not Path(chromium).is_file():
        pytest.skip("Debian's chromium is not installed (apt-get install chromium)")
    base = site.as_uri() if opened == "from disk" else request.getfixturevalue("served_site")
    errors: list[str] = []
    elsewhere: list[str] = []
    with sync_api.sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1366, "height": 800})
            page.set_default_timeout(20_000)
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
            page.on("request", lambda sent: None if sent.url.startswith(base) else elsewhere.append(sent.url))
            page.goto(f"{base}/index.html")
            with page.expect_navigation():
                page.locator(".md-nav--primary").get_by_role("link", name="Getting started", exact=True).click()
            heading = page.locator("h1").first.text_content() or ""
            assert heading.rstrip("¶").strip() == "Getting started", f"{page.url} shows {heading!r}"
            page.locator("input.md-search__input").click()
            page.keyboard.type("rejection")
            page.locator(".md-search-result__item").first.wait_for()
            found = page.locator(".md-search-result__link").evaluate_all("links => links.map(a => a.href)")
            assert any(url.startswith(f"{base}/trust") for url in found), found
        finally:
            browser.close()
    assert not errors, f"script errors: {errors}"
    assert not elsewhere, f"fetched from outside the site: {elsewhere}"


def _screenshots_module():
    """docs/screenshots.py, which is not a package module (it needs Playwright)."""
    pytest.importorskip("playwright.sync_api", reason="Playwright for Python is not installed")
    spec = importlib.util.spec_from_file_location("docs_screenshots", ROOT / "docs" / "screenshots.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_the_docs_show_every_screenshot_with_the_caption_its_page_is_checked_against():
    shots = _screenshots_module().SHOTS
    shown = {}
    for page in (ROOT / "docs").glob("*.md"):
        for caption, name in re.findall(r"!\[([^\]]*)\]\(screenshots/([\w-]+)\.png\)", page.read_text()):
            shown[name] = caption
    assert shown == {name: shot.caption for name, shot in shots.items()}
    assert sorted(p.stem for p in (ROOT / "docs" / "screenshots").glob("*.png")) == sorted(shots)


@pytest.mark.slow
def test_every_page_still_shows_what_its_screenshots_caption_says(tmp_path):
    """The walk of docs/screenshots.py (a scan through the browser, the database browser, the report) on a
    small database: each page is checked against its caption's elements before it is photographed, so a
    layout change that leaves a screenshot describing a page that no longer exists fails here."""
    screenshots = _screenshots_module()
    if not Path(screenshots.CHROMIUM).is_file():
        pytest.skip("Debian's chromium is not installed (apt-get install chromium)")
    db = tmp_path / "db"
    assert subprocess.run([_texplorer(), "demo", "--db", str(db), "--materials", "granite-polished", "oak-planed",
                           "--samples", "2", "--scans", "2", "--image-size", "320", "--classifier", "rf",
                           "--folds", "2", "--workers", "2"], capture_output=True, timeout=900).returncode == 0
    taken = screenshots.take(db, tmp_path / "shots")
    assert sorted(p.stem for p in taken) == sorted(screenshots.SHOTS)
