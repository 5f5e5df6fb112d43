"""The web app's routes under hostile input: every GET route, with every hostile or misspelled value in each
path part and query parameter, answers without a server error, also with a scan in progress (the system
test: about two thousand requests through the app)."""

from __future__ import annotations

import pytest
from unit.test_gui import active, post, start_session
from unit.test_gui_operator import HOSTILE, hostile_urls, stock_app, walk


@pytest.fixture
def stocked_app(tmp_path):
    app = stock_app(tmp_path / "db")
    yield app
    app.extensions["texplorer"].shutdown()


def test_no_route_answers_5xx_for_hostile_or_misspelled_input(stocked_app):
    client = stocked_app.test_client()
    urls = hostile_urls(stocked_app)
    assert len(urls) > 20 * len(HOSTILE)
    assert walk(client, urls) == []
    # The same with a scan in progress (the session's pages answer instead of redirecting) and one step recorded.
    start_session(client)
    assert post(client, "/session/step/finger_tap/record").status_code == 302
    assert active(stocked_app).session.wait(30)
    assert walk(client, urls) == []
