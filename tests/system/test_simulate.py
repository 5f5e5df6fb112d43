"""The simulated scanner: channel layout, determinism, physics that the features rely on, library checks: the
system tests (simulated databases and many simulated scans)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy import signal
from unit.test_simulate import BAND, SMALL, operator

from scanner import simulation as sim
from scanner.simulation.database import synthetic_database


@pytest.fixture(scope="module")
def library() -> dict[str, sim.Material]:
    return sim.load_materials()


def slide_start(v: np.ndarray, factor: float = 10.0) -> int | None:
    """docs/features.md#preprocessing slide-start detector, written out independently of the code under test."""
    x = v - v[:750].mean(axis=0)
    frames = x.shape[0] // 30
    energy = (x[: frames * 30] ** 2).reshape(frames, 30, 3).sum(axis=(1, 2))
    above = np.nonzero(energy > factor * energy[:25].mean())[0]
    return int(above[0]) * 30 if above.size else None


def test_scans_of_a_database_are_reproducible_one_by_one():
    scans = list(sim.synthetic_scans(["float-glass"], scans_per_material=2, seed=3, image_size=SMALL))
    ids = [(s.meta.sample_id, s.meta.scan_index) for s in scans]
    assert ids == [("float-glass-01", 1), ("float-glass-01", 2)]
    alone = sim.synthetic_scan("float-glass", seed=sim.scan_seed(3, "float-glass", 2), scan_index=2,
                               sample_id="float-glass-01", image_size=SMALL)
    assert alone.meta == scans[1].meta and alone["v_ts"] == scans[1]["v_ts"]
    assert scans[0]["v_ts"] != scans[1]["v_ts"]
    assert sim.scan_seed(3, "float-glass", 2) != sim.scan_seed(3, "float-glass", 1)
    assert sim.scan_seed(3, "float-glass", 2) != sim.scan_seed(4, "float-glass", 2)


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="image_size must be two integers >= 16"):
        sim.synthetic_scan("float-glass", seed=0, image_size=(8, 8))
    with pytest.raises(ValueError, match="scans_per_material must be an integer >= 1, got 0"):
        next(sim.synthetic_scans(["float-glass"], scans_per_material=0))
    with pytest.raises(ValueError, match="samples_per_material must be an integer >= 1, got 0"):
        synthetic_database("unused", ["float-glass"], samples_per_material=0)
    assert not Path("unused").exists()
    with pytest.raises(ValueError, match="fold_skip_probability must be in"):
        sim.draw_operator(np.random.default_rng(0), fold_skip_probability=1.5)


def test_samples_of_a_material_are_distinct_pieces_with_their_own_scans():
    scans = list(sim.synthetic_scans(["float-glass"], scans_per_material=2, seed=3, image_size=SMALL,
                                     samples_per_material=2))
    assert [s.scan_id for s in scans] == ["float-glass-01-001", "float-glass-01-002", "float-glass-02-001",
                                          "float-glass-02-002"]
    # The first sample is the one-sample database's; the second is another piece (mass differs).
    first = list(sim.synthetic_scans(["float-glass"], scans_per_material=2, seed=3, image_size=SMALL))
    assert [s.meta for s in first] == [s.meta for s in scans[:2]]
    assert scans[2].meta.mass_g != scans[0].meta.mass_g
    assert sim.scan_seed(3, "float-glass", 1, sample=2) != sim.scan_seed(3, "float-glass", 1)


def test_synthetic_database_stores_every_scan(tmp_path):
    database = synthetic_database(tmp_path / "db", ["copper-polished"], scans_per_material=2, seed=1,
                                  image_size=SMALL, progress=False)
    assert len(database) == 2
    stored = database.get("copper-polished-01-002")
    fresh = sim.synthetic_scan("copper-polished", seed=sim.scan_seed(1, "copper-polished", 2), scan_index=2,
                               image_size=SMALL)
    assert stored["t_cool"] == fresh["t_cool"] and stored.meta.label == "C7S3M1P2X1"
    database.close()


@pytest.mark.parametrize("slug", ["polyurethane-foam", "float-glass", "sandpaper-p80",
                                  "perforated-steel-plate"])
def test_slide_start_is_found_after_the_rest_with_a_second_of_slide(slug, library):
    for seed in range(3):
        draw = operator(seed)
        out = {**sim.finger_slide(library[slug], np.random.default_rng(seed), draw),
               **sim.tool_slide(library[slug], np.random.default_rng(seed), draw)}
        for name, true_start in (("v_fs", draw.finger_slide_start_s), ("v_ts", draw.tool_slide_start_s)):
            start = slide_start(out[name])
            assert start is not None, (slug, seed, name)
            assert 0.4 <= start / 3000 <= 0.8 and out[name].shape[0] - start >= 3000
            assert abs(start / 3000 - true_start) <= 0.011, (slug, seed, name)  # the frame holding the start


@pytest.mark.parametrize("speed", [60.0, 200.0])
def test_perforated_plate_repeats_at_spacing_over_speed(speed, library):
    """8 mm hole pitch at v mm/s: period 8/v s = 24000/v samples, in the IR and the vibration envelope."""
    draw = operator(1, tool_speed_mm_s=speed, tool_slide_start_s=0.5)
    out = sim.tool_slide(library["perforated-steel-plate"], np.random.default_rng(1), draw)
    expected = 8.0 / speed * 3000
    lo, hi = int(expected / 2), int(expected * 1.5)

    ir = out["r_ts"][1800:] - out["r_ts"][1800:].mean()
    ir_lag = lo + int(np.argmax(np.correlate(ir, ir, "full")[ir.size - 1:][lo:hi]))
    assert ir_lag == pytest.approx(expected, rel=0.05)

    # The holes' share of the vibration's energy is small at a slow slide (their acceleration grows as v^2),
    # so the envelope's autocorrelation is summed over three slides of independent draws: the period
    # adds up, the noise's fluctuations do not.
    correlation = 0.0
    for seed in (1, 2, 3):
        slide = out if seed == 1 else sim.tool_slide(library["perforated-steel-plate"], np.random.default_rng(seed),
                                                     operator(seed, tool_speed_mm_s=speed, tool_slide_start_s=0.5))
        energy = np.sum(signal.sosfiltfilt(BAND, slide["v_ts"], axis=0)[1800:] ** 2, axis=1)
        energy = signal.sosfiltfilt(signal.butter(2, 100, fs=3000, output="sos"), energy)
        energy -= energy.mean()
        correlation = correlation + np.correlate(energy, energy, "full")[energy.size - 1:] / np.sum(energy**2)
    vib_lag = lo + int(np.argmax(correlation[lo:hi]))
    assert vib_lag == pytest.approx(expected, rel=0.15)


@pytest.fixture(scope="module")
def foam_and_steel():
    foam = sim.synthetic_scan("polyurethane-foam", seed=5, image_size=SMALL)
    steel = sim.synthetic_scan("mild-steel-brushed", seed=5, image_size=SMALL, fold_skip_probability=0.0)
    return foam, steel


def test_plot_scan_writes_one_page_png_also_without_fold_channels(tmp_path, foam_and_steel):
    from taxonomy.reports.plots import plot_scan

    skipped = sim.synthetic_scan("float-glass", seed=2, image_size=SMALL, fold_skip_probability=1.0)
    for name, scan in (("foam", foam_and_steel[0]), ("glass", skipped)):
        path = tmp_path / f"{name}.png"
        plot_scan(scan, path, title=name)
        header = path.read_bytes()[:24]
        assert header[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")
        assert (width, height) == (22 * 80, 17 * 80)  # 22 x 17 inches at 80 dpi


def test_plot_step_draws_one_steps_channels_800_px_wide(foam_and_steel):
    import io

    from scanner.acquisition.config import Config
    from scanner.acquisition.session import procedure
    from taxonomy.reports.plots import plot_step

    scan = foam_and_steel[0]
    recorded = [step.id for step in procedure(Config()) if step.kind == "record"]
    for step in recorded:
        out = io.BytesIO()
        plot_step(scan.traces, step, out, title=step, t_amb=scan.meta.t_amb)
        header = out.getvalue()[:24]
        width, height = int.from_bytes(header[16:20], "big"), int.from_bytes(header[20:24], "big")
        panels = 3 if step in ("finger_slide", "tool_slide") else 1  # acceleration, audio, IR of a slide
        assert (width, height) == (800, int((0.5 + 2.6 * panels) * 125)), step  # Agg truncates
    with pytest.raises(ValueError, match="'tu4' is not a recorded step"):
        plot_step(scan.traces, "tu4", io.BytesIO())
