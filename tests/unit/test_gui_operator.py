"""A day of lab use of the web application, at server level: no page answers 5xx for anything a person can
type, searches match the way a person searches, an abort is confirmed and keeps the start form, step numbers
agree, and the slow pages reuse work done earlier in the scan."""

from __future__ import annotations

import html
import re
from urllib.parse import quote, urlencode

import pytest

from unit.test_gui import (
    active,
    database,
    field_error,
    get,
    make_app,
    post,
    record_all,
    start_session,
)

HOSTILE = ("ZZZ", "Z9", "granite", "c6", "C6S1M1P2X1", "C60", "../../etc/passwd", "%00", "\x00", "a" * 300,
           "<script>alert(1)</script>", "é", "-1", "0", "1e999", "nan", " ", "'", '"', "%", "*", "\\", "C6S1M1PX1")
"""Values a person (or a pasted link) may put into any path part or query parameter."""

PARAMETERS = ("label", "sample", "operator", "session", "q", "v", "lable", "sampel", "opertor", "step", "page")
"""The query parameters the pages read, and misspellings of them."""


def stock_app(db_root):
    """The web app on a database of three scans: two granite samples, one oak; operators Ann, bo, ann."""
    from conftest import make_scan

    app = make_app(db_root)
    db = database(app)
    db.add(make_scan(0, sample_id="granite-01", scan_index=1, operator="Ann", image_shape=(64, 64)))
    db.add(make_scan(1, sample_id="granite-02", scan_index=1, operator="bo", image_shape=(64, 64)))
    db.add(make_scan(2, label="C1S1M1P4X1", sample_id="oak-01", scan_index=1, operator="ann",
                     image_shape=(64, 64)))
    return app


@pytest.fixture
def stocked_app(tmp_path):
    app = stock_app(tmp_path / "db")
    yield app
    app.extensions["texplorer"].shutdown()


def routes(app) -> list[tuple[str, list[str]]]:
    """Every GET route's rule and the names of its path arguments (static files left out)."""
    return [(rule.rule, sorted(rule.arguments)) for rule in app.url_map.iter_rules()
            if "GET" in rule.methods and rule.endpoint != "static"]


def hostile_urls(app) -> list[str]:
    urls = []
    for rule, arguments in routes(app):
        for value in HOSTILE:
            path = rule
            for name in arguments:
                path = re.sub(rf"<(?:\w+:)?{name}>", quote(value, safe=""), path)
            query = urlencode(dict.fromkeys(PARAMETERS, value))
            urls += [path, f"{path}?{query}"]
    return urls


def walk(client, urls) -> list[str]:
    """The URLs that answered a server error."""
    return [f"{url} -> {answer.status_code}" for url in urls if (answer := get(client, url)).status_code >= 500]


def test_scan_filters_match_as_a_person_searches(stocked_app):
    client = stocked_app.test_client()

    def listed(**query) -> list[str]:
        page = get(client, "/db/scans?" + urlencode(query))
        assert page.status_code == 200, page.text
        return re.findall(r'href="/db/scan/([\w.-]+)"', page.text)

    assert listed(label="granite") == ["granite-01-001", "granite-02-001"]
    assert listed(label="Granite") == listed(label="stone") == listed(label="C6")
    assert listed(label="oak") == listed(label="wood") == ["oak-01-001"]
    assert listed(sample="granite") == ["granite-01-001", "granite-02-001"]
    assert listed(sample="GRANITE-02") == ["granite-02-001"]
    assert listed(operator="ann") == listed(operator="ANN") == ["oak-01-001", "granite-01-001"]  # in label order
    assert listed(label="granite", operator="Ann") == ["granite-01-001"]
    assert listed(label="C60") == []  # a valid class prefix that holds nothing


@pytest.mark.parametrize("text", ["Z9", "C6S1M1PX1", "zzz"])
def test_bad_label_filter_is_one_line_on_the_page(stocked_app, text):
    from taxonomy.labels import LabelError, parse_prefix

    page = get(stocked_app.test_client(), "/db/scans?" + urlencode({"label": text}))
    assert page.status_code == 422
    reason = field_error(page.text, "label")
    assert "\n" not in reason and "part of a material name, e.g. granite" in reason
    with pytest.raises(LabelError) as cli:  # the reason 'texplorer export --label' gives, then the names
        parse_prefix(text)
    assert reason.startswith(str(cli.value))
    assert f'value="{text}"' in page.text  # what was typed stays in the field


def test_material_page_of_a_bad_or_lower_case_label(stocked_app):
    client = stocked_app.test_client()
    answer = get(client, "/db/material/ZZZ")
    assert answer.status_code == 404 and "'ZZZ' is not a label" in html.unescape(answer.text)
    assert get(client, "/db/material/c6s1m1p2x1").status_code == 200
    assert get(client, "/db/material/C1S1M1P1X1").status_code == 404


def test_scan_table_shows_times_to_the_minute(stocked_app):
    record = database(stocked_app).records()[0]
    page = get(stocked_app.test_client(), "/db/scans").text
    date, clock = record.started.split("T")
    assert f'<time datetime="{record.started}">{date} {clock[:5]}</time>' in page


# -- aborting -----------------------------------------------------------------------------------------------


def test_abort_asks_first_naming_what_it_discards(client, app):
    start_session(client, operator="Ann", sample_id="granite-07")
    for step in ("finger_tap", "finger_slide"):
        assert post(client, f"/session/step/{step}/record").status_code == 302
        assert active(app).session.wait(30)
    assert post(client, "/session/step/fold/skip").status_code == 302
    post(client, "/session/form", {"capture": "I_disp"})
    page = get(client, "/session/step/tool_tap").text
    link = re.search(r'href="(/session/abort[^"]*)"', page).group(1)
    assert "Abort the scan" in page and "/session/step/tool_tap/abort" not in page
    # One tap on the abort button (or a POST without the confirmation) only asks.
    for answer in (get(client, html.unescape(link)), post(client, "/session/abort")):
        assert answer.status_code == 200
        text = html.unescape(answer.text)
        assert "Abort the scan of granite-07?" in text
        assert "2 recorded steps: TU1 finger tap, TU1 finger slide" in text
        assert "the fold's skip (rigid sample)" in text and "1 of 3 photos" in text
    # "Keep scanning" goes back to where the tap came from
    assert 'href="/session/step/tool_tap"' in get(client, html.unescape(link)).text
    assert active(app) is not None and active(app).session.status("finger_tap").state == "recorded"

    assert post(client, "/session/abort", {"confirm": "discard"}).headers["Location"] == "/"
    assert active(app) is None and len(database(app)) == 0
    start = get(client, "/").text
    for name, value in (("operator", "Ann"), ("sample_id", "granite-07"), ("label", "C6S1M1P2X1")):
        assert re.search(rf'id="{name}" name="{name}" type="text" value="{value}"', start), name


def test_after_a_save_the_start_form_keeps_the_operator_only(client, app):
    from unit.test_gui import noise_photo, png_upload

    start_session(client, operator="Ann", sample_id="granite-08")
    record_all(client, app)
    uploads = {name: png_upload(noise_photo(seed)) for seed, name in enumerate(("I_disp", "I_macro", "I_illu"))}
    post(client, "/session/form", {"atk": "0", "cyd": "0", "mass_g": "500", "volume_cm3": "190",
                                   "volume_method": "water", **uploads}, content_type="multipart/form-data")
    assert post(client, "/session/save").status_code == 302
    start = get(client, "/").text
    assert 'id="operator" name="operator" type="text" value="Ann"' in start
    assert 'id="sample_id" name="sample_id" type="text" value=""' in start


def test_abort_without_a_scan_and_a_foreign_back_link(client, app):
    assert get(client, "/session/abort").headers["Location"] == "/"  # nothing to abort: the start page
    start_session(client)
    page = get(client, "/session/abort?back=https://evil.example/").text
    assert 'href="https://evil.example/"' not in page and 'href="/session"' in page


def test_session_work_lists_nothing_for_a_new_scan():
    from scanner.acquisition.session import Session
    from unit.test_gui import fast_config

    with Session.open(fast_config(), label="C6S1M1P2X1", sample_id="g-1", operator="a") as session:
        assert session.work() == []
        session.set_values(mass_g=3.0, notes="x")
        assert session.work() == ["the TU4 values: mass, notes"]


# -- work done once, step numbers, legend ---------------------------------------------------------------


def complete_scan(client, app):
    """Record every step (viewing each one's traces as the step page does), take three photos, fill the form."""
    record_all(client, app)
    for step in ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction",
                 "press", "fold"):
        assert get(client, f"/session/step/{step}/traces.png?v=1").status_code == 200
    for name in ("I_disp", "I_macro", "I_illu"):
        post(client, "/session/form", {"capture": name})
    answer = post(client, "/session/form", {"atk": "0", "cyd": "0.25", "mass_g": "512,5 g",
                                            "volume_cm3": "190 ml", "volume_method": "water"})
    assert answer.headers["Location"] == "/session/summary"


def test_summary_and_saved_scan_reuse_the_step_figures_and_features(client, app, monkeypatch):
    from features import extract
    from features.extraction import code_version
    from gui import figures

    drawn = []
    original = figures.plot_step
    monkeypatch.setattr(figures, "plot_step", lambda traces, step, *args, **kwargs:
                        drawn.append(step) or original(traces, step, *args, **kwargs))
    start_session(client)
    complete_scan(client, app)
    assert len(drawn) == 9
    summary = get(client, "/session/summary").text
    images = re.findall(r'<img src="(/session/step/[^"]+)"', summary)
    assert len(images) == 9 and all(get(client, html.unescape(url)).status_code == 200 for url in images)
    assert len(drawn) == 9  # the summary drew nothing: the figures of the step pages
    assert "traces.png" in summary and "/session/summary/traces.png" in summary  # the whole figure on request

    scan_id = post(client, "/session/save").headers["Location"].rsplit("/", 1)[1]
    db = database(app)
    record = db.record(scan_id)
    cached = db.cached_features(record.content_hash, code_version())
    assert cached is not None
    stored = extract(db.get(scan_id))
    assert cached.keys() == stored.keys()
    assert all(cached[k] == stored[k] or (cached[k] != cached[k] and stored[k] != stored[k]) for k in stored)
    page = get(client, f"/db/scan/{scan_id}").text
    images = re.findall(rf'<img src="(/db/scan/{scan_id}/traces/[^"]+)"', page)
    assert len(images) == 9 and all(get(client, url).status_code == 200 for url in images)
    assert len(drawn) == 9  # kept at save: the scan's page drew nothing either


def test_stored_scans_without_kept_figures_draw_each_step_once(tmp_path):
    from conftest import make_scan

    app = make_app(tmp_path / "db")
    try:
        database(app).add(make_scan(0, sample_id="steel-01", rigid=True, drop=("f_fold", "alpha_f"),
                                    image_shape=(64, 64)))
        client = app.test_client()
        page = get(client, "/db/scan/steel-01-001").text
        assert "Step 9, TU2 fold: skipped: rigid sample." in page
        images = re.findall(r'<img src="(/db/scan/steel-01-001/traces/[^"]+)"', page)
        assert len(images) == 8
        first = get(client, images[0])
        assert first.status_code == 200 and first.data.startswith(b"\x89PNG")
        assert get(client, "/db/scan/steel-01-001/traces/photos.png").status_code == 404
    finally:
        app.extensions["texplorer"].shutdown()


def test_step_numbers_agree_and_the_legend_is_on_every_scan_page(client, app):
    start_session(client)
    chips = re.findall(r'aria-current="step">(\d+)\. ', get(client, "/session/form").text)
    form = get(client, "/session/form").text
    assert "<h1>Steps 10 and 11: photos, mass, volume and judgement</h1>" in form and chips == ["10"]
    assert ">11. TU4 mass, volume and judgement</a>" in form
    for url in ("/session", "/session/step/finger_slide", "/session/form"):
        page = get(client, url).text
        assert "What TU1–TU4 and the channel codes mean" in page, url
    step = html.unescape(get(client, "/session/step/finger_slide").text)
    assert "<code>a_fs</code> audio during the finger slide, full scale" in step


# -- texplorer serve, import, compare, demo ----------------------------------------------------------------


def test_figures_kept_at_save_are_served_while_being_written(tmp_path, monkeypatch):
    from gui import figures

    gate = __import__("threading").Event()
    written = figures.atomic_write_bytes
    monkeypatch.setattr(figures, "atomic_write_bytes", lambda path, data: gate.wait(30) and written(path, data))
    keeper = figures.Keeper()
    keeper.keep(tmp_path, "abc", {"press": b"\x89PNG press"})
    path = figures.cached_path(tmp_path, "abc", "press")
    assert keeper.pending(path) == b"\x89PNG press" and not path.exists()
    gate.set()
    keeper.wait(30)
    assert keeper.pending(path) is None and path.read_bytes() == b"\x89PNG press"
