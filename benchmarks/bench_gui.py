"""Web application benchmark: click to page of the operator's slow actions, with the simulated scanner
(default step lengths, 512 px photos), through Flask's test client (server time, figures included).

The reference, run in the same process, is drawing the whole scan's figure (``plot_scan``), what the
summary and the saved scan's page drew on every first view before the step figures were kept; the
ratios compare across machines.
"""

from __future__ import annotations

import io
import re
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_gui import get, make_app, post, record_all  # noqa: E402

from scanner.acquisition.config import Config, SimulatedConfig  # noqa: E402
from taxonomy.reports.plots import plot_scan  # noqa: E402


def page_with_images(client, url: str) -> str:
    """GET a page and every figure it shows (not the photos); returns the page's text."""
    page = get(client, url)
    assert page.status_code == 200, (url, page.status_code)
    for src in re.findall(r'<img src="([^"]+)"', page.text):
        if "/photo/" not in src:
            assert get(client, src.replace("&amp;", "&")).status_code == 200, src
    return page.text


def one_scan(root: Path, config: Config) -> tuple[float, float, float]:
    """A scan through the pages: seconds to the summary, to the saved scan, and of the reference figure."""
    app = make_app(root, config)
    client = app.test_client()
    post(client, "/", {"operator": "ab", "label": "C6S1M1P2X1", "sample_id": "granite-01"})
    record_all(client, app)
    for step in ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction",
                 "press", "fold"):  # each step page shows its figure after the recording
        assert get(client, f"/session/step/{step}/traces.png").status_code == 200
    for name in ("I_disp", "I_macro", "I_illu"):
        post(client, "/session/form", {"capture": name})
    started = time.perf_counter()
    answer = post(client, "/session/form", {"atk": "0", "cyd": "0.25", "mass_g": "512", "volume_cm3": "190",
                                            "volume_method": "water"})
    page_with_images(client, answer.headers["Location"])
    summary = time.perf_counter() - started
    scan = app.extensions["texplorer"].operations.active.summary_cache["scan"]
    started = time.perf_counter()
    plot_scan(scan, io.BytesIO())
    whole = time.perf_counter() - started
    started = time.perf_counter()
    saved = post(client, "/session/save").headers["Location"]
    page_with_images(client, saved)
    save = time.perf_counter() - started
    app.extensions["texplorer"].shutdown()
    return summary, save, whole


def main() -> None:
    config = Config(simulated=SimulatedConfig(realtime=False, image_size=(512, 512)))
    with tempfile.TemporaryDirectory() as tmp:
        one_scan(Path(tmp) / "warm-up", config)  # the first scan of a server also loads and compiles code
        summary, save, whole = one_scan(Path(tmp) / "db", config)
    print(f"continue to the summary (page and figures): {summary:.2f} s")
    print(f"save, to the saved scan's page and figures: {save:.2f} s")
    print(f"reference, the whole scan's figure (plot_scan): {whole:.2f} s; summary / reference "
          f"{summary / whole:.3f}, save / reference {save / whole:.3f}")


if __name__ == "__main__":
    main()
