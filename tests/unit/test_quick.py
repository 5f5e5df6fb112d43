"""The quick scan: experts by step, the tempered product, the information gain per second, the stop, and the
walk of stored scans (docs/quick.md)."""

from __future__ import annotations

import contextlib
import dataclasses
import math
import re
import shutil
import sqlite3

import numpy as np
import pytest
from conftest import make_scan
from scipy.io import loadmat

from features import FeatureSpace, extract
from scanner.acquisition.config import ConfigError, parse_config
from scanner.acquisition.session import procedure, step_seconds
from scanner.cli import EXIT_ERROR, main
from scanner.scan import CHANNELS, PROCEDURE_STEPS, ScanError, check_steps
from scanner.storage.bundle import import_bundle
from scanner.storage.database import Database
from scanner.storage.matfile import load_scan, save_scan
from scanner.workflows.demo import simulated_database
from scanner.workflows.exchange import export_database
from taxonomy.learning.evaluation import EvaluationError
from taxonomy.learning.quick import (
    Expert,
    StepModel,
    contrast,
    entropy,
    evaluate_quick,
    experts_of,
    fit_tau,
    next_step,
    posterior,
    replay,
)
from unit.test_gui import BASE, make_app, post
from unit.test_session import FAST, fast_toml, run_cli

# -- a toy model with known answers ----------------------------------------------------------------------
#
# Two classes, equally frequent; every training row is one of each class. Step "a" completes an expert whose
# out-of-fold posterior is 0.9 for the row's own class, step "c" one at 0.7, step "b" one that cannot tell.


def _ratio(p_true: float) -> np.ndarray:
    """Log ratios ``log q - log pi`` of the two training rows (class 0, class 1) of an expert that gives the
    true class ``p_true``."""
    q = np.array([[p_true, 1 - p_true], [1 - p_true, p_true]])
    return np.log(q / 0.5)


def toy_model(tau: float = 1.0) -> StepModel:
    experts = (Expert(frozenset({"a"}), (0,)), Expert(frozenset({"b"}), (1,)), Expert(frozenset({"c"}), (2,)))
    ratios = np.stack([_ratio(0.9), _ratio(0.5), _ratio(0.7)])
    return StepModel(experts, (), np.array(["x", "y"]), np.log([0.5, 0.5]), np.ones(3), np.full(4, tau), ratios,
                     np.array([0, 1]), np.ones(2, dtype=bool), None, np.array([[0.0] * 3, [1.0] * 3]),
                     np.zeros((2, 3)))


def h2(p: float) -> float:
    """Binary entropy in bits."""
    return float(-p * np.log2(p) - (1 - p) * np.log2(1 - p))


def test_the_information_gain_of_each_step_is_the_drop_in_entropy_it_promises():
    gains = toy_model().gains(np.zeros((3, 2)), frozenset())
    assert gains["a"] == pytest.approx(1 - h2(0.9), abs=1e-12)
    assert gains["c"] == pytest.approx(1 - h2(0.7), abs=1e-12)
    assert gains["b"] == pytest.approx(0.0, abs=1e-12)


def test_the_gain_weighs_the_outcomes_by_the_current_probabilities():
    # After "c" said class x with 0.7, the outcome of "a" is class x's row with probability 0.7: posterior
    # 0.7 * 0.9 / (0.7 * 0.9 + 0.3 * 0.1) = 21/22, or class y's row (0.3): 0.7 * 0.1 / (0.07 + 0.27) = 7/34.
    model = toy_model()
    scan = np.stack([_ratio(0.9)[0], _ratio(0.5)[0], _ratio(0.7)[0]])  # a scan of class x
    now = model.predict(scan, {"c"})
    assert now == pytest.approx([0.7, 0.3])
    expected = h2(0.7) - (0.7 * h2(21 / 22) + 0.3 * h2(7 / 34))
    assert model.gains(scan, {"c"})["a"] == pytest.approx(expected, abs=1e-12)


def test_the_next_step_is_the_most_information_per_second_or_the_fixed_orders_next():
    model, nothing = toy_model(), np.zeros((3, 2))
    assert next_step(model, nothing, frozenset(), {"a": 1, "b": 1, "c": 1}) == "a"
    # a: 0.531 bits in 10 s; c: 0.119 bits in 1 s
    assert next_step(model, nothing, frozenset(), {"a": 10, "b": 1, "c": 1}) == "c"
    assert next_step(model, nothing, frozenset({"a", "c"}), {"a": 1, "b": 1, "c": 1}) == "b"  # the last one left
    assert next_step(model, nothing, frozenset({"a", "b", "c"}), {"a": 1, "b": 1, "c": 1}) is None
    assert next_step(model, nothing, frozenset({"b"}), {"a": 1, "b": 1, "c": 1}, order=["b", "c", "a"]) == "c"


def test_the_reason_for_a_step_is_how_far_it_swings_the_two_likeliest_classes_apart():
    model = toy_model()
    scan = np.stack([_ratio(0.9)[0], _ratio(0.5)[0], _ratio(0.7)[0]])
    a, b, swing = contrast(model, scan, {"c"}, "a")
    assert (a, b) == (0, 1) and swing == pytest.approx(2 * np.log(9))
    assert contrast(model, scan, {"c"}, "b")[2] == pytest.approx(0.0)


def test_a_quick_scan_stops_once_the_top_class_reaches_the_threshold():
    model = toy_model()
    scan = np.stack([_ratio(0.9)[0], _ratio(0.5)[0], _ratio(0.7)[0]])
    costs = {"a": 1.0, "b": 1.0, "c": 1.0}
    assert [d.step for d in replay(model, scan, costs, stop_at=0.85)] == ["a"]
    path = replay(model, scan, costs, stop_at=0.95)  # a: 0.9, then c: 21/22 = 0.9545
    assert [d.step for d in path] == ["a", "c"]
    assert path[-1].probabilities[0] == pytest.approx(21 / 22) and path[-1].seconds == 2.0
    assert [d.step for d in replay(model, scan, costs, stop_at=0.96)] == ["a", "c", "b"]  # never sure


def test_a_quick_scan_does_not_stop_while_the_recorded_steps_look_new():
    model = toy_model()
    scan = np.stack([_ratio(0.9)[0], _ratio(0.5)[0], _ratio(0.7)[0]])
    path = replay(model, scan, {"a": 1.0, "b": 1.0, "c": 1.0}, stop_at=0.85, novelty=np.full((3, 2), 9.0))
    assert [d.step for d in path] == ["a", "c", "b"] and not any(d.accepted for d in path)
    assert not path[-1].decided(0.85)


def test_the_product_is_tempered_by_tau():
    model = toy_model(tau=0.5)
    scan = np.stack([_ratio(0.9)[0], _ratio(0.5)[0], _ratio(0.7)[0]])
    p = model.predict(scan, {"a"})[0]
    assert p == pytest.approx(3 / 4)  # odds 9^0.5 = 3


def test_tau_is_recovered_from_rows_drawn_from_the_tempered_posterior():
    rng = np.random.default_rng(0)
    n, true_tau = 20000, 0.6
    log_prior = np.log(np.full(3, 1 / 3))
    sums = rng.normal(0.0, 2.0, (n, 3))
    p = posterior(log_prior, sums, true_tau)
    y = (rng.random(n)[:, None] > np.cumsum(p, axis=1)).sum(axis=1)
    tau = fit_tau(sums, y, log_prior)
    # standard error of the maximum-likelihood estimate from the observed information d2 NLL / d tau2
    eps = 1e-3
    nll = [-np.log(posterior(log_prior, sums, t)[np.arange(n), y]).sum() for t in (tau - eps, tau, tau + eps)]
    se = 1 / np.sqrt((nll[0] - 2 * nll[1] + nll[2]) / eps**2)
    assert abs(tau - true_tau) < 4 * se


def test_entropy_is_in_bits():
    assert entropy(np.array([0.5, 0.5])) == pytest.approx(1.0)
    assert entropy(np.array([1.0, 0.0])) == 0.0


def test_columns_are_grouped_by_the_steps_they_need():
    needs = {"tactum.matx": frozenset({"tool_slide", "friction"}), "audio.tool.zcr": frozenset({"tool_slide"}),
             "other.vib_std": frozenset({"tool_slide"}), "x.whole": frozenset()}
    experts = experts_of(["audio.tool.zcr", "tactum.matx", "x.whole", "other.vib_std"], needs)
    assert experts == (Expert(frozenset({"tool_slide"}), (0, 3)), Expert(frozenset({"tool_slide", "friction"}), (1,)))
    assert experts[1].name == "friction+tool_slide"


# -- walking stored scans ----------------------------------------------------------------------------------


def step_space(seed: int = 0) -> FeatureSpace:
    """Four materials, three samples each, two scans per sample: the tool slide's columns tell the materials
    apart, the TU4 values only the first two from the last two, the photos nothing."""
    rng = np.random.default_rng(seed)
    columns = ("audio.tool.zcr", "audio.tool.energy", "other.density", "image.disp.brightness")
    labels = ["C1S1M1P1X1", "C2S1M1P1X1", "C3S1M1P1X1", "C4S1M1P1X1"]
    rows, label_text, groups = [], [], []
    for m, label in enumerate(labels):
        for sample in range(3):
            centre = rng.normal(0, 0.05, 4)
            for _ in range(2):
                slide = [3.0 * m, -2.0 * m] + rng.normal(0, 0.2, 2)
                rows.append([*(slide + centre[:2]), (m // 2) + rng.normal(0, 0.2) + centre[2], rng.normal()])
                label_text.append(label)
                groups.append(f"{label}-{sample}")
    return FeatureSpace(X=np.array(rows), columns=columns, scan_ids=tuple(f"s{i}" for i in range(len(rows))),
                        label_text=tuple(label_text), groups=tuple(groups))


@pytest.fixture(autouse=True)
def few_trees(monkeypatch):
    """Twenty trees per expert: the walks below need the order of the steps, not the last point of accuracy."""
    monkeypatch.setattr("taxonomy.learning.quick.TREES", 20)


COSTS = {"finger_tap": 10.0, "tool_slide": 10.0, "photos": 60.0, "tu4": 120.0}
ORDER = ("finger_tap", "tool_slide", "photos", "tu4")


def test_stored_scans_walk_to_a_decision_after_the_step_that_tells_them_apart():
    result = evaluate_quick(step_space(), COSTS, ORDER, folds=3, workers=1)
    adaptive, fixed = result.summary("adaptive"), result.summary("fixed")
    decided = [w for w in result.walks["adaptive"] if w.decided]
    assert sum(w.steps == ("tool_slide",) for w in decided) >= 0.9 * len(decided)
    assert adaptive["decided"] >= 0.9 and adaptive["accuracy_decided"] >= 0.9
    assert adaptive["median_steps"] == 1 and adaptive["median_seconds"] == 10.0
    assert fixed["median_steps"] == 2 and fixed["median_seconds"] == 20.0  # the finger tap first, for nothing
    assert result.full_seconds == 200.0
    assert len(result.walks["adaptive"]) == len(result.full_correct) == 24
    assert result.line().startswith("quick: median 1 steps (10 s) to a decision, accuracy ")


def test_the_tables_count_decisions_by_steps_and_seconds():
    result = evaluate_quick(step_space(), COSTS, ORDER, folds=3, workers=1)
    steps = result.by_steps("fixed")
    assert [row[0] for row in steps][:2] == [1, 2] and steps[0][2] == 0.0  # nobody decides on the finger tap
    marks = result.by_seconds("adaptive", marks=(5, 15))
    assert [m for m, _, _ in marks] == [5.0, 15.0, 200.0] and marks[0][1] == 0.0
    assert marks[-1][1] == result.summary("adaptive")["decided"] and marks[1][1] >= 0.9 * marks[-1][1]


def test_a_step_the_order_lacks_or_a_step_without_time_is_refused():
    with pytest.raises(EvaluationError, match="no time given for step 'photos'"):
        evaluate_quick(step_space(), {"finger_tap": 1.0, "tool_slide": 1.0, "tu4": 1.0}, ORDER)
    with pytest.raises(EvaluationError, match="step 'photos' of the feature columns is not in the protocol"):
        evaluate_quick(step_space(), COSTS, ("tool_slide", "tu4"))


# -- the protocol's times and the command ------------------------------------------------------------------


def test_every_step_takes_its_recording_and_handling_time():
    config = parse_config({"handling": {"photos": 30.0}, "steps": {"tool_slide": 4.0}})
    seconds = step_seconds(config)
    assert list(seconds) == [step.id for step in procedure(config)]
    assert seconds["photos"] == 30.0 and seconds["tool_slide"] == 4.0 + 5.0
    assert seconds["thermal"] == config.steps.heat + config.steps.thermal + config.handling.thermal


@pytest.mark.parametrize(("value", "why"), [(-1.0, "must be between 0 and 3600 s"),
                                            ("slow", "must be a finite number")])
def test_a_bad_handling_time_is_refused_by_name(value, why):
    with pytest.raises(ConfigError, match=f"handling.tu4: {why}"):
        parse_config({"handling": {"tu4": value}})


def test_evaluate_quick_prints_the_tables_and_the_line(tmp_path, capsys):
    table = step_space().to_csv(tmp_path / "space.csv")
    assert main(["evaluate", "--quick", "--features", str(table), "--folds", "3", "--db", str(tmp_path / "db")]) == 0
    out = capsys.readouterr().out
    assert "quick scan, fine level: 3 grouped folds" in out and "the paper's fixed order" in out
    assert out.splitlines()[-2].startswith("quick: median 1 steps (10 s) to a decision")


# -- the quick scan in the terminal --------------------------------------------------------------------


@pytest.fixture(scope="module")
def three_materials(tmp_path_factory):
    """A database of granite, oak and foam: two samples of each, two scans per sample."""
    root = tmp_path_factory.mktemp("quick") / "db"
    simulated_database(root, materials=["granite-polished", "oak-planed", "polyurethane-foam"], scans_per_material=2,
                       samples_per_material=2, image_size=(256, 256), progress=False, workers=1).close()
    return root


def quick_argv(db, config: str, *extra: str) -> list[str]:
    return ["scan", "--db", str(db), "--quick", "--sample", "piece-01", "--operator", "ab", "--config", config, *extra]


def test_a_quick_scan_of_an_unlabelled_sample_stops_when_sure_and_saves_nothing(three_materials, tmp_path,
                                                                                 monkeypatch, capsys):
    config = fast_toml(tmp_path / "fast.toml", extra='material = "granite-polished"\n')
    before = sorted(p.name for p in three_materials.rglob("*.mat"))
    code, out = run_cli(monkeypatch, capsys, quick_argv(three_materials, config), "\n" * 40)
    assert code == 0, out
    assert "learning the quick scan from the 12 scans" in out and "scan of an unlabelled sample" in out
    assert re.search(r"next: (TU\d [a-z ]+) \([\d.]+ s\): the \1 tells the most trained materials apart per second",
                     out)
    assert "identified: stopped because granite" in out and "(C6S1M1P2X1) reached" in out
    last = out.strip().splitlines()[-1]
    assert "quick scan: granite" in last and "not saved" in last and "of 11 steps" in last
    assert sorted(p.name for p in three_materials.rglob("*.mat")) == before and len(Database(three_materials)) == 12


def test_a_quick_scan_goes_on_to_the_full_scan_and_saves_it_under_the_predicted_label(three_materials, tmp_path,
                                                                                       monkeypatch, capsys):
    db = tmp_path / "db"
    shutil.copytree(three_materials, db)
    config = fast_toml(tmp_path / "fast.toml", extra='material = "granite-polished"\n')
    steps = "\n\n" * 9  # record and keep each of the nine recorded steps
    text = f"\nf\n{steps}\n\n\n512\n190\nwater\n0\n0.25\n\n\ny\n"  # photos, TU4, label as predicted, save
    code, out = run_cli(monkeypatch, capsys, quick_argv(db, config), text)
    assert code == 0, out
    assert "saved piece-01-001" in out and "label: [Enter] C6S1M1P2X1" in out
    assert Database(db).get("piece-01-001").meta.label == "C6S1M1P2X1"


def test_a_scan_without_a_label_must_be_quick(tmp_path, capsys):
    assert main(["scan", "--db", str(tmp_path / "db"), "--sample", "x-01", "--operator", "ab"]) == EXIT_ERROR
    assert "--label is required (only a quick scan, --quick, may start without one)" in capsys.readouterr().err


def test_materials_never_trained_on_do_not_stop_as_known_ones():
    result = evaluate_quick(step_space(), COSTS, ORDER, folds=3, workers=1, open_set=True)
    unseen = result.unseen()
    assert unseen is not None and unseen["scans"] == 24  # every material held out once
    # A held-out material's tool slide lies between two trained ones', far from both: its novelty is refused,
    # so the quick scan never stops on it and leaves it to the full scan's rule.
    assert unseen["decided"] == 0.0
    assert all(w.steps[0] == "tool_slide" and not w.decided for w in result.walks["unseen"])
    assert evaluate_quick(step_space(), COSTS, ORDER, folds=3, workers=1).unseen() is None


# -- the quick scan in the web application -----------------------------------------------------------------


@pytest.fixture
def quick_app(three_materials, tmp_path):
    db = tmp_path / "db"
    shutil.copytree(three_materials, db)
    config = parse_config({**FAST, "simulated": {**FAST.get("simulated", {}), "material": "granite-polished"}})
    app = make_app(db, config)
    yield app, db
    app.extensions["texplorer"].shutdown()


def record_proposed(app, client) -> str:
    """Record the step the quick page proposes, as its step page would (the session's blocking call)."""
    page = client.get("/session/quick", base_url=BASE).text
    step_url = page.split('<a class="button big" href="', 1)[1].split('"', 1)[0]
    step_id = step_url.rsplit("/", 1)[1]
    app.extensions["texplorer"].operations.active.session.record(step_id)
    app.extensions["texplorer"].operations.active.changed()
    return step_id


def identified(app, sample_id: str):
    """A browser that started an unlabelled quick identification and took the proposed steps until it stopped."""
    client = app.test_client()
    post(client, "/", {"operator": "ab", "sample_id": sample_id, "label": "", "quick": "on"})
    record_proposed(app, client)
    while 'id="quick-stop"' not in client.get("/session/quick", base_url=BASE).text:
        record_proposed(app, client)
    return client


def test_a_quick_identification_in_the_web_app_proposes_steps_and_stops(quick_app):
    app, db = quick_app
    client = app.test_client()
    start = post(client, "/", {"operator": "ab", "sample_id": "piece-01", "label": "", "quick": "on"})
    assert start.status_code == 302, start.text
    page = client.get("/session/quick", base_url=BASE).text
    assert "Before the first step" in page and 'id="quick-reason">Why: the ' in page
    assert "tells the most trained materials apart per second" in page
    taken = [record_proposed(app, client)]
    while 'id="quick-stop"' not in (page := client.get("/session/quick", base_url=BASE).text) and len(taken) < 9:
        taken.append(record_proposed(app, client))
    assert 'id="quick-stop"' in page and "C6S1M1P2X1" in page.split('id="quick-predictions"', 1)[1][:400]
    done = post(client, "/session/quick/stop")
    assert done.status_code == 302 and done.location.endswith("/")
    page = client.get("/", base_url=BASE).text
    assert "Quick identification: granite" in page and f"after {len(taken)} of 11 steps" in page
    assert "Nothing was saved." in page and app.extensions["texplorer"].operations.active is None
    assert len(Database(db)) == 12


def test_going_on_to_the_full_scan_names_an_unlabelled_sample_by_the_quick_prediction(quick_app):
    app, _ = quick_app
    client = identified(app, "piece-02")
    went = post(client, "/session/quick/full")
    session = app.extensions["texplorer"].operations.active.session
    assert session.label == "C6S1M1P2X1"
    first_open = next(step for step in session.steps if step.id not in session.recorded_steps())
    assert went.location.endswith(f"/session/step/{first_open.id}")
    assert "the quick prediction; the summary lets you change it" in client.get(went.location, base_url=BASE).text


def test_a_quick_identification_needs_scans_to_learn_from(tmp_path):
    app = make_app(tmp_path / "empty")
    client = app.test_client()
    page = post(client, "/", {"operator": "ab", "sample_id": "piece-01", "label": "", "quick": "on"})
    assert page.status_code == 422 and "no scans to learn a quick scan from" in page.text
    app.extensions["texplorer"].shutdown()


# -- partial (quick) scans as stored scans ---------------------------------------------------------------


def partial_scan(scan_index: int = 1):
    """A scan holding only the tool slide and the photos: the others' channels and the TU4 values absent."""
    full = make_scan(0, scan_index=scan_index, sample_id="piece-01")
    keep = {name for name, spec in CHANNELS.items() if spec.step == "tool_slide"}
    meta = dataclasses.replace(full.meta, mass_g=math.nan, volume_cm3=math.nan, atk=math.nan, cyd=math.nan,
                               volume_method="", steps="photos, tool_slide")
    return dataclasses.replace(full, meta=meta, traces={k: v for k, v in full.traces.items() if k in keep},
                               raw={k: v for k, v in full.raw.items() if k in keep})


@pytest.mark.parametrize(("steps", "why"), [
    ("press,smell", "'smell' is not a step of the procedure"), ("press,press", "'press,press' names a step twice"),
    (",".join(PROCEDURE_STEPS), "names every step: a full scan stores meta.steps as empty text"),
    (3, "3 must be step names separated by commas")])
def test_a_bad_list_of_steps_is_refused_by_field(steps, why):
    with pytest.raises(ScanError, match=re.escape(why)) as caught:
        check_steps(steps)
    assert caught.value.field == "meta.steps"


def test_a_partial_scan_keeps_its_steps_through_the_file_and_the_catalog(tmp_path):
    scan = partial_scan()
    assert scan.meta.steps == "tool_slide,photos" and scan.meta.partial
    assert scan.meta.step_list == ("tool_slide", "photos")
    path = tmp_path / "piece-01-001.mat"
    save_scan(scan, path)
    assert loadmat(path, simplify_cells=True)["meta"]["steps"] == "tool_slide,photos"  # what MATLAB reads
    assert load_scan(path) == scan
    full = make_scan(1)
    save_scan(full, tmp_path / "full.mat")
    assert "steps" not in loadmat(tmp_path / "full.mat", simplify_cells=True)["meta"]
    assert load_scan(tmp_path / "full.mat").meta.steps == "" and not load_scan(tmp_path / "full.mat").meta.partial
    db = Database(tmp_path / "db")
    db.add(scan)
    db.add(full)
    assert {r.scan_id: r.steps for r in db.records()} == {"piece-01-001": "tool_slide,photos",
                                                          full.meta.scan_id: ""}
    with pytest.warns(UserWarning):
        values = extract(db.get("piece-01-001"))
    assert np.isnan(values["audio.finger.zcr"]) and np.isnan(values["other.density"])  # missing, never zero
    assert np.isnan(values["tactum.fst"]) and np.isnan(values["other.metal"])
    assert np.isfinite(values["image.disp.brightness"])


def test_a_catalog_of_schema_1_gains_the_steps_column_when_opened(tmp_path):
    db = Database(tmp_path / "db")
    db.add(make_scan(0))
    db.close()
    with contextlib.closing(sqlite3.connect(tmp_path / "db" / "catalog.sqlite")) as conn:
        conn.execute("ALTER TABLE scans DROP COLUMN steps")
        conn.execute("UPDATE info SET value = '1' WHERE key = 'catalog_schema'")
        conn.commit()
    db = Database(tmp_path / "db")
    assert [r.steps for r in db.records()] == [""]
    db.add(partial_scan())
    assert db.record("piece-01-001").partial
    with contextlib.closing(sqlite3.connect(tmp_path / "db" / "catalog.sqlite")) as conn:
        assert conn.execute("SELECT value FROM info WHERE key = 'catalog_schema'").fetchone() == ("2",)


def test_models_learn_from_full_scans_and_say_how_many_quick_ones_they_left_out(tmp_path, capsys):
    db = Database(tmp_path / "db")
    db.add(make_scan(0))
    db.add(partial_scan())
    assert main(["db", "list", "--db", str(tmp_path / "db")]) == 0
    out = capsys.readouterr().out
    assert "quick: tool_slide, photos" in out and "2 scan(s), 1 of them quick scans holding only some steps" in out
    assert main(["features", "--db", str(tmp_path / "db"), "--out", str(tmp_path / "f.csv")]) == 0
    assert "1 quick scan(s) holding only some steps left out" in capsys.readouterr().err
    assert len(FeatureSpace.from_csv(tmp_path / "f.csv")) == 1


def test_a_quick_scan_kept_from_the_terminal_is_a_partial_scan(three_materials, tmp_path, monkeypatch, capsys):
    db = tmp_path / "db"
    shutil.copytree(three_materials, db)
    config = fast_toml(tmp_path / "fast.toml", extra='material = "granite-polished"\n')
    text = "\n" + "\n\n\n" * 9  # keep t_amb; take, record and keep proposed steps until identified
    answers = iter(text.split("\n"))
    monkeypatch.setattr("scanner.cli.acquisition._read", lambda prompt: _answer(prompt, answers))
    code = main(quick_argv(db, config))
    out = capsys.readouterr().out
    assert code == 0, out
    record = Database(db).record("piece-01-001")
    assert record.partial and record.label == "C6S1M1P2X1"
    assert "saved piece-01-001" in out.strip().splitlines()[-1]


def _answer(prompt: str, answers) -> str:
    """The operator: keeps the quick scan once identified, keeps the predicted label, else presses Enter."""
    if prompt.startswith("[Enter] stop here, k keep"):
        return "k"
    return next(answers, "")


def test_a_quick_scan_kept_from_the_web_app_shows_its_steps(quick_app):
    app, db = quick_app
    client = identified(app, "piece-03")
    kept = post(client, "/session/quick/save")
    assert kept.location.endswith("/db/scan/piece-03-001")
    page = client.get(kept.location, base_url=BASE).text
    assert "was saved with" in page and 'id="scan-steps">a quick scan: ' in page
    assert Database(db).record("piece-03-001").partial


def test_a_quick_scan_travels_with_its_steps_through_export_and_import(tmp_path):
    source = Database(tmp_path / "source")
    source.add(make_scan(0))
    source.add(partial_scan())
    bundle = export_database(source, tmp_path / "bundle", license="CC-BY-4.0", creator="lab", workers=1).path
    target = Database(tmp_path / "target")
    import_bundle(target, bundle)
    assert target.record("piece-01-001").steps == "tool_slide,photos"
    assert target.get("piece-01-001") == source.get("piece-01-001")


def test_a_scan_that_never_stops_counts_the_whole_protocol():
    result = evaluate_quick(step_space(), COSTS, ORDER, folds=3, workers=1, stop_at=1.01)  # never sure enough
    adaptive = result.summary("adaptive")
    assert adaptive["decided"] == 0.0
    assert all(len(w.steps) == 3 for w in result.walks["adaptive"])  # the finger tap feeds no expert: skipped
    assert adaptive["median_steps"] == len(ORDER) and adaptive["median_seconds"] == 200.0
    assert adaptive["time_share"] == 1.0
