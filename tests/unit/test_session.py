"""The guided session: its state machine, operator values and photos, abort and save, the Peltier when a
worker thread fails, and whole ``texplorer scan`` runs through simulated devices and through the emulators."""

from __future__ import annotations

import io
import math
import sys
import threading

import cv2
import numpy as np
import pytest

from features import extract
from scanner.acquisition.config import ConfigError, parse_config
from scanner.acquisition.session import Session, SessionError, SessionState, StepState, procedure
from scanner.cli import main
from scanner.storage.database import Database
from unit.test_gui import density_model

FAST = {"steps": {"finger_tap": 2.0, "finger_slide": 2.0, "tool_tap": 2.0, "tool_slide": 2.0, "static": 0.5,
                  "heat": 0.1, "thermal": 1.0, "friction": 1.5, "press": 1.5, "fold": 1.5},
        "simulated": {"realtime": False, "image_size": [300, 300]}}
RECORDED = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press",
            "fold")


def fast_toml(path, devices: str = "", extra: str = "") -> str:
    steps = "\n".join(f"{k} = {v}" for k, v in FAST["steps"].items())
    path.write_text(f"{devices}\n[steps]\n{steps}\n[simulated]\nrealtime = false\nimage_size = [300, 300]\n"
                    f"{extra}")
    return str(path)


@pytest.fixture
def session():
    with Session.open(parse_config(FAST), label="C6S1M1P2X1", sample_id="granite-01", operator="ab") as s:
        yield s


def complete(session: Session, skip_fold: bool = False) -> None:
    for step in RECORDED:
        if step == "fold" and skip_fold:
            session.skip("fold")
        else:
            assert session.record(step).state is StepState.RECORDED
    for name in ("I_disp", "I_macro", "I_illu"):
        session.capture_photo(name)
    session.set_values(atk=0.0, cyd=0.25, mass_g=512.0, volume_cm3=190.0, volume_method="water")


def test_steps_follow_spec_4_with_configured_durations():
    steps = procedure(parse_config(FAST))
    assert [s.id for s in steps] == [*RECORDED, "photos", "tu4"]
    assert [s.number for s in steps] == list(range(1, 12))  # unique: the operator is told 'step 6'
    assert [s.id for s in steps if s.skippable] == ["fold"]
    by_id = {s.id: s for s in steps}
    assert by_id["thermal"].duration_s == pytest.approx(1.1)          # heating + cooling record
    assert by_id["finger_slide"].channels == ("v_fs", "a_fs", "r_fs")
    assert by_id["static"].channels == ("m", "dB")
    assert by_id["photos"].channels == ("I_disp", "I_macro", "I_illu")
    assert [by_id[s].kind for s in ("photos", "tu4", "press")] == ["photos", "form", "record"]
    assert all(s.title and s.instruction for s in steps)


def test_ambient_temperature_is_read_from_the_board_and_editable(session):
    sample_t_amb = session.devices.board.source.t_amb
    assert session.t_amb == pytest.approx(sample_t_amb, abs=0.1)
    session.t_amb = 23.4
    assert session.t_amb == 23.4
    with pytest.raises(SessionError, match="t_amb: 120 degC is outside the sensor's -40..85 degC"):
        session.t_amb = 120
    with pytest.raises(SessionError, match="t_amb: must be a number"):
        session.t_amb = "warm"


def test_transitions_are_checked(session):
    with pytest.raises(SessionError, match="photos is not recorded with the devices"):
        session.record("photos")
    with pytest.raises(SessionError, match="unknown step 'squeeze'"):
        session.record("squeeze")
    assert session.record("press").state is StepState.RECORDED
    with pytest.raises(SessionError, match="press is recorded: redo it first"):
        session.record("press")
    session.redo("press")
    assert session.status("press").state is StepState.PENDING and session.result("press") is None
    with pytest.raises(SessionError, match="press cannot be skipped"):
        session.skip("press")
    session.skip("fold")
    assert session.rigid and session.status("fold").state is StepState.SKIPPED
    session.redo("fold")
    assert not session.rigid
    with pytest.raises(SessionError, match="tu4 values are edited with set_values"):
        session.redo("tu4")


def test_cannot_save_before_everything_is_done(session, tmp_path):
    db = Database(tmp_path / "db")
    session.record("finger_tap")
    with pytest.raises(SessionError) as error:
        session.save(db)
    message = str(error.value)
    assert message.startswith("cannot save yet, missing: finger_slide (pending), tool_tap (pending)")
    assert "photo I_disp" in message and message.endswith("cyd, volume_method")
    assert len(db) == 0 and session.state is SessionState.OPEN


@pytest.mark.parametrize(("values", "message"), [
    ({"atk": 0.3}, "atk: 0.3 is not on the five-step scale 0, 0.25, 0.5, 0.75, 1"),
    ({"cyd": "soft"}, "cyd: must be a number"),
    ({"mass_g": -2}, "mass_g: must be positive"),
    ({"volume_cm3": math.inf}, "volume_cm3: must be finite"),
    ({"volume_method": "sand"}, "volume_method: 'sand' is not one of water, micro-pearls"),
    ({"notes": "line\x00break"}, "notes: must be printable text"),
    ({"density": 2.7}, "unknown value 'density'"),
])
def test_operator_values_are_validated(session, values, message):
    with pytest.raises(SessionError, match=message):
        session.set_values(**values)


def test_photos_from_uploads_and_the_camera(session):
    rgb = np.zeros((40, 50, 3), np.uint8)
    rgb[:, :, 0] = 255
    ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    session.set_photo("I_disp", png.tobytes())
    assert np.array_equal(session.photos["I_disp"], rgb)
    with pytest.raises(SessionError, match="I_macro: not a PNG or JPEG file"):
        session.set_photo("I_macro", b"GIF89a" + bytes(50))
    with pytest.raises(SessionError, match="'I_top' is not a photo"):
        session.set_photo("I_top", rgb)
    with pytest.raises(SessionError, match=r"I_macro: the image has 25,001,984 pixels \(16384 x 1526\)"):
        session.set_photo("I_macro", np.broadcast_to(rgb[:1, :1], (1526, 16384, 3)))  # refused, not saved later
    assert session.capture_photo("I_macro").shape == (300, 300, 3)
    assert session.status("photos").state is StepState.PENDING
    session.capture_photo("I_illu")
    assert session.status("photos").state is StepState.RECORDED
    session.redo("photos")
    assert session.photos == {}


def test_a_complete_scan_is_saved_with_finite_features(session, tmp_path):
    db = Database(tmp_path / "db")
    complete(session)
    session.set_values(notes="edge chipped")
    scan_id = session.save(db)
    assert scan_id == "granite-01-001" and session.state is SessionState.SAVED and session.devices is None
    scan = db.get(scan_id)
    assert scan.meta.label == "C6S1M1P2X1" and scan.meta.operator == "ab" and not scan.meta.rigid
    assert scan.meta.notes == "edge chipped" and scan.meta.volume_method == "water"
    assert scan.meta.calibration["accel_V_per_g_x"] == 0.33
    assert scan.meta.calibration["audio_offset_fs_s"] == 0.0
    assert scan.missing_channels() == [] and set(scan.raw) >= {"v_ts", "f_frn", "m"}
    assert scan["a_fs"].n == 2 * 44100 and scan["v_fs"].n == 6000 and scan["t_cool"].n == 20
    values = np.array(list(extract(scan).values()))
    assert values.size == 193 and np.isfinite(values).all()
    with pytest.raises(SessionError, match="the session is saved"):
        session.record("press")


def test_a_sample_of_another_material_is_refused_before_scanning(session, tmp_path):
    db = Database(tmp_path / "db")
    complete(session)
    session.save(db)
    with pytest.raises(SessionError, match="sample granite-01 is C6S1M1P2X1 in the database, not C1S1M1P4X1"):
        Session.open(parse_config(FAST), label="C1S1M1P4X1", sample_id="granite-01", operator="ab", db=db)
    with pytest.raises(SessionError, match="C6S1M1"):
        Session.open(parse_config(FAST), label="C6S1M1", sample_id="granite-01", operator="ab", db=db)


def test_skipping_the_fold_saves_a_rigid_scan(session, tmp_path):
    db = Database(tmp_path / "db")
    complete(session, skip_fold=True)
    scan = db.get(session.save(db))
    assert scan.meta.rigid and "f_fold" not in scan.traces and scan.missing_channels() == []


def test_replay_devices_play_a_stored_scan_back(session, tmp_path):
    db = Database(tmp_path / "db")
    complete(session)
    stored = db.get(session.save(db))
    path = db.root / db.record(stored.scan_id).path
    replayed = {name: "replay" for name in ("daq", "board", "microphone", "camera")}
    config = parse_config({**FAST, "devices": replayed, "replay": {"scan": str(path), "speed": 0}})
    with Session.open(config, label="C6S1M1P2X1", sample_id="granite-01", operator="cd", db=db) as replay:
        assert replay.devices.describe()["daq"] == "NI USB-6002 (replay)"
        complete(replay)
        again = replay.scan(2)
    # the DAQ plays the stored raw volts, which convert to the stored values again, bit for bit
    for name in ("v_ft", "v_fs", "v_tt", "v_ts", "r_fs", "r_ts", "f_frn", "f_frt", "f_press", "f_fold",
                 "alpha_f", "m", "a_fs", "a_ts", "t_cool"):
        assert again[name] == stored[name], name
    assert again["dB"].data == pytest.approx(stored["dB"].data, abs=1e-12)
    assert all(np.array_equal(again.images[name], stored.images[name]) for name in stored.images)


def test_abort_leaves_the_database_untouched(session, tmp_path):
    db = Database(tmp_path / "db")
    complete(session)
    before = sorted(p.name for p in (tmp_path / "db").rglob("*"))
    session.abort()
    assert session.state is SessionState.ABORTED and session.devices is None
    assert sorted(p.name for p in (tmp_path / "db").rglob("*")) == before and len(db) == 0
    with pytest.raises(SessionError, match="the session is aborted"):
        session.save(db)


def test_worker_thread_recording_with_live_level(session):
    recording, release = threading.Event(), threading.Event()

    def level(reading) -> None:
        recording.set()
        release.wait(10.0)

    session.start_step("press", level=level)
    assert recording.wait(10.0) and session.running and session.level is not None
    with pytest.raises(SessionError, match="another step is recording"):
        session.record("friction")
    release.set()
    assert session.wait(10.0)
    assert session.status("press").state is StepState.RECORDED and session.worker_error is None


def test_abort_during_heating_in_a_worker_switches_off(tmp_path):
    config = parse_config({**FAST, "steps": {**FAST["steps"], "heat": 3.0}})
    session = Session.open(config, label="C6S1M1P2X1", sample_id="granite-01", operator="ab")
    board = session.devices.board
    heating = threading.Event()
    session.start_step("thermal", level=lambda reading: heating.set())
    assert heating.wait(5.0)
    session.abort()
    assert session.status("thermal").state is StepState.FAILED
    assert session.status("thermal").error == "cancelled while heating"
    (on, asked), (off, then) = board.heat_log[:2]        # closing the devices adds more HEAT 0 after these
    assert (asked, then) == (3000, 0) and off - on < 1.0


def test_an_exception_in_the_worker_thread_fails_the_step_and_switches_off(session):
    board = session.devices.board

    def broken_display(reading) -> None:
        raise RuntimeError("display crashed")

    session.start_step("thermal", level=broken_display)
    assert session.wait(10.0)
    status = session.status("thermal")
    assert status.state is StepState.FAILED and status.error == "RuntimeError: display crashed"
    assert isinstance(session.worker_error, RuntimeError)
    assert [ms for _, ms in board.heat_log][-2:] == [100, 0]
    session.redo("thermal")
    assert session.record("thermal").state is StepState.RECORDED


def test_unknown_simulated_material_is_a_config_error():
    with pytest.raises(ConfigError, match="has no physics for C9S9 .* choose a material of the classes C1-C8"):
        Session.open(parse_config(FAST), label="C9S9M9P9X9", sample_id="x-01", operator="ab")
    with pytest.raises(SessionError, match="sample id 'a/b' must be"):
        Session.open(parse_config(FAST), label="C6S1M1P2X1", sample_id="a/b", operator="ab")


# -- texplorer scan in the terminal --------------------------------------------------------------------

def answers(record_steps: int = 9, before: str = "", fold: str = "\n\n") -> str:
    """Operator input: keep t_amb, record + keep each step, three camera photos, TU4 values, save."""
    steps = "\n\n" * (record_steps - 1) + fold
    return f"\n{before}{steps}\n\n\n512\n190\nwater\n0\n0.25\n\ny\n"


def run_cli(monkeypatch, capsys, argv: list[str], text: str) -> tuple[int, str]:
    monkeypatch.setattr(sys, "stdin", io.StringIO(text))
    code = main(argv)
    return code, capsys.readouterr().out


def test_texplorer_scan_with_simulated_devices(tmp_path, monkeypatch, capsys):
    config = fast_toml(tmp_path / "fast.toml")
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
            "--operator", "ab", "--config", config]
    code, out = run_cli(monkeypatch, capsys, argv, answers())
    assert code == 0, out
    assert "step 9/11: TU2 fold" in out and "saved granite-01-001" in out
    scan = Database(tmp_path / "db").get("granite-01-001")
    assert not scan.meta.rigid and scan.meta.mass_g == 512.0 and scan.meta.cyd == 0.25
    assert np.isfinite(np.array(list(extract(scan).values()))).all()
    # a second scan of the same sample is the next index, and skipping the fold makes it rigid
    code, out = run_cli(monkeypatch, capsys, argv, answers(fold="s\n"))
    assert code == 0 and "saved granite-01-002" in out
    assert Database(tmp_path / "db").get("granite-01-002").meta.rigid


def test_texplorer_scan_aborted_saves_nothing(tmp_path, monkeypatch, capsys):
    config = fast_toml(tmp_path / "fast.toml")
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
            "--operator", "ab", "--config", config]
    code, out = run_cli(monkeypatch, capsys, argv, "\n\n\na\nyes\n")
    assert code == 1 and "scan aborted (aborted by the operator): nothing was saved" in out
    assert "aborting discards: 1 recorded step: TU1 finger tap" in out
    assert not (tmp_path / "db").exists()
    code, out = run_cli(monkeypatch, capsys, argv, "\n\n")
    assert code == 1 and "scan aborted (input ended)" in out


def test_texplorer_scan_with_a_missing_model_fails_before_scanning(tmp_path, monkeypatch, capsys):
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
            "--operator", "ab", "--model", str(tmp_path / "none.skops")]
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    assert main(argv) == 1
    captured = capsys.readouterr()
    assert "none.skops" in captured.err and "step 1/11" not in captured.out


def test_texplorer_scan_reprompts_bad_values(tmp_path, monkeypatch, capsys):
    config = fast_toml(tmp_path / "fast.toml")
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
            "--operator", "ab", "--config", config]
    text = answers().replace("\n512\n190\nwater\n0\n", "\nheavy\n5 kg\n512,5 g\n190 ml\nsand\nw\n0.3\n0\n")
    code, out = run_cli(monkeypatch, capsys, argv, text)
    assert code == 0, out
    # One line each, the web form's words (scanner.acquisition.entries parses both)
    assert "  'heavy' is not a number in g\n" in out and "  '5 kg' is not a number in g\n" in out
    assert "could not convert" not in out
    assert "  choose how the volume was measured: water (water displacement), micro-pearls" in out
    assert "  0.3 is not on the five-step scale 0, 0.25, 0.5, 0.75, 1" in out
    meta = Database(tmp_path / "db").get("granite-01-001").meta
    assert (meta.mass_g, meta.volume_cm3, meta.volume_method) == (512.5, 190.0, "water")


def test_texplorer_scan_abort_asks_first_and_says_how_to_start_again(tmp_path, monkeypatch, capsys):
    config = fast_toml(tmp_path / "fast.toml")
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C6S1M1P2X1", "--sample", "granite-01",
            "--operator", "Ann B", "--config", config]
    # 'a' at the mass prompt, then Enter: the scan goes on and is saved; 'n' at the end asks too.
    text = answers().replace("\n512\n", "\na\n\n512\n").replace("\ny\n", "\nn\n\ny\n")
    code, out = run_cli(monkeypatch, capsys, argv, text)
    assert code == 0 and "saved granite-01-001" in out, out
    assert "aborting discards: 9 recorded steps: TU1 finger tap" in out and "3 of 3 photos" in out
    assert "not saving discards: 9 recorded steps" in out
    code, out = run_cli(monkeypatch, capsys, argv, "\n\n\na\nyes\n")
    assert code == 1
    again = out.split("to scan this sample again: ", 1)[1].splitlines()[0]
    assert again == (f"texplorer scan --db {tmp_path / 'db'} --label C6S1M1P2X1 --sample granite-01 "
                     f"--operator 'Ann B' --config {config}")




def test_photos_too_small_for_the_image_features_are_warned_about_at_the_start_and_when_set():
    small = {**FAST, "simulated": {"realtime": False, "image_size": [200, 240]}}
    with Session.open(parse_config(small), label="C6S1M1P2X1", sample_id="granite-01", operator="ab") as s:
        assert s.warnings == ["photos of 240 x 200 px leave nothing for the image features after the 100 px "
                              "border crop: they need at least 202 x 202 px, so the image features and TacTUM's "
                              "MaCo and MaRG will be missing"]
    with Session.open(parse_config(FAST), label="C6S1M1P2X1", sample_id="granite-01", operator="ab") as s:
        assert s.warnings == []
        s.set_photo("I_disp", np.zeros((202, 202, 3), np.uint8))  # the smallest photo with image features
        assert s.warnings == []
        s.set_photo("I_macro", np.zeros((150, 400, 3), np.uint8))
        s.set_photo("I_illu", np.zeros((150, 400, 3), np.uint8))
        assert len(s.warnings) == 1 and s.warnings[0].startswith("photos of 400 x 150 px leave nothing")


def test_texplorer_scan_checks_the_label_against_the_model_before_saving(tmp_path, monkeypatch, capsys):
    model = density_model(tmp_path / "density.skops")  # granite polished vs oak, by density
    config = fast_toml(tmp_path / "fast.toml")
    argv = ["scan", "--db", str(tmp_path / "db"), "--label", "C1S1M1P4X1", "--sample", "oak-01", "--operator", "ab",
            "--config", config, "--model", str(model)]
    # oak by its label, granite by its density (512 g in 190 cm^3); an unknown label first, then the predicted
    text = answers().replace("\n0.25\n\ny\n", "\n0.25\n\nC99S1\np\ny\n")
    code, out = run_cli(monkeypatch, capsys, argv, text)
    assert code == 0, out
    assert "1. C6S1M1P2X1  100.0 %  granite (igneous stone, stone), polished, plain" in out
    assert ("check the label: your label oak (hardwood, wood), planed, plain (C1S1M1P4X1) differs from the "
            "prediction at level fine: the model predicts granite (igneous stone, stone), polished, plain "
            "(C6S1M1P2X1) at 100.0 %") in out
    assert "[p] save as C6S1M1P2X1, [Enter] keep C1S1M1P4X1, or type another label: " in out
    assert "  'C99S1' is not a label: missing M<number>" in out  # refused in one line, and asked again
    assert "the scan will be saved as C6S1M1P2X1" in out
    assert [r.label for r in Database(tmp_path / "db").records()] == ["C6S1M1P2X1"]
