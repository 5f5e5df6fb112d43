"""The simulated scanner: channel layout, determinism, physics that the features rely on, library checks."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from scanner import simulation as sim
from scanner.scan import CHANNELS

SMALL = (48, 64)
BAND = signal.butter(4, [10, 1000], btype="bandpass", fs=3000, output="sos")

DEFAULT_LABELS = {
    "C1S1M1P4X1", "C1S1M2P4X2", "C1S1M3P4X1", "C1S2M1P4X1", "C1S3M1P4X1", "C2S1M1P1X1", "C2S2M1P1X1",
    "C2S2M2P6X1", "C2S3M1P1X1", "C2S4M1P1X1", "C2S4M2P1X1", "C3S1M1P2X1", "C3S1M2P1X1", "C3S2M1P7X1",
    "C3S2M2P7X1", "C3S3M1P1X1", "C3S4M2P1X1", "C4S1M1P2X1", "C4S3M1P1X1", "C5S1M1P2X1", "C5S1M1P9X1",
    "C6S1M1P2X1", "C6S1M1P3X1", "C6S2M1P1X1", "C6S3M1P2X1", "C7S1M1P8X1", "C7S1M1P5X1", "C7S2M1P1X1",
    "C7S3M1P2X1", "C8S1M1P6X1", "C8S2M1P1X3", "C8S2M1P1X4",
}


@pytest.fixture(scope="module")
def library() -> dict[str, sim.Material]:
    return sim.load_materials()


@pytest.fixture(scope="module")
def oak_scan():
    return sim.synthetic_scan("oak-planed", seed=11, image_size=SMALL, fold_skip_probability=0.0)


def operator(seed: int = 0, **changes) -> sim.OperatorDraw:
    return dataclasses.replace(sim.draw_operator(np.random.default_rng(seed)), **changes)


def band_rms(v: np.ndarray, start: int) -> float:
    window = signal.sosfiltfilt(BAND, v, axis=0)[start:start + 3000]
    return float(np.sqrt(np.mean(np.sum(window**2, axis=1))))


# -- the library --------------------------------------------------------------------------------------

def test_default_library_is_the_agreed_32_materials_all_named_by_the_taxonomy(library):
    from taxonomy import load_taxonomy

    assert len(library) == 32
    assert {m.label for m in library.values()} == DEFAULT_LABELS
    taxonomy = load_taxonomy()
    for material in library.values():
        taxonomy.check(material.label)
    majors = {re.match(r"C(\d+)", m.label).group(1) for m in library.values()}
    assert majors == {str(c) for c in range(1, 9)}


def test_close_pairs_differ_only_where_intended(library):
    polished, pointed = library["granite-polished"], library["granite-pointed"]
    assert polished.label[:6] == pointed.label[:6] and polished.density_g_cm3 == pointed.density_g_cm3
    balsa, pine = library["balsa-planed"], library["pine-planed"]
    assert balsa.density_g_cm3 / pine.density_g_cm3 == pytest.approx(0.32)
    assert balsa.roughness.macro_spacing_mm == pine.roughness.macro_spacing_mm
    assert balsa.appearance.texture == pine.appearance.texture == "grain"


def test_library_values_are_physically_ordered(library):
    foam, steel = library["polyurethane-foam"], library["mild-steel-brushed"]
    assert foam.thermal.heat_rise_k > 25 * steel.thermal.heat_rise_k
    assert steel.thermal.cooling_rate_per_s > 10 * foam.thermal.cooling_rate_per_s
    assert all(m.friction.kinetic <= m.friction.static for m in library.values())
    assert {m.magnetic for m in library.values()} == {"ferro", "para", "none", "dia"}
    assert {m.appearance.texture for m in library.values()} == set(sim.TEXTURES)


VALID = """
[test-material]
label = "C6S1M1P2X1"
name = "test granite"
density_g_cm3 = 2.65
sample_volume_cm3 = 100.0
conductive = false
magnetic = "none"
magnet_response_ut = 0.0
adhesive_tack = 0.0
yielding = 0.0

[test-material.roughness]
micro_um = 0.1
cutoff_per_mm = 3.0
exponent = 3.0
macro_spacing_mm = 3.0
macro_height_um = 0.0
macro_duty = 0.5
macro_regularity = 0.0

[test-material.friction]
static = 0.5
kinetic = 0.4

[test-material.compliance]
stiffness_n_per_mm = "rigid"
elastic_modulus_mpa = 50000.0
loss_factor = 0.005
relaxation = 0.0
relaxation_time_s = 1.0
foldable = false

[test-material.thermal]
heat_rise_k = 0.3
cooling_rate_per_s = 0.4

[test-material.reflectance]
level = 0.5
variation = 0.2

[test-material.appearance]
texture = "speckle"
colors = [[170, 165, 160], [40, 38, 38]]
frequency_per_mm = 0.8
orientation_deg = 0.0
contrast = 0.8
duty = 0.35
relief = 0.0
gloss = 0.9
"""


def write_library(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "lab-materials.toml"
    path.write_text(text)
    return path


def test_a_valid_library_file_loads(tmp_path):
    materials = sim.load_materials(write_library(tmp_path, VALID))
    material = materials["test-material"]
    assert material.compliance.rigid and material.compliance.stiffness_n_per_mm == np.inf
    assert material.appearance.colors == ((170.0, 165.0, 160.0), (40.0, 38.0, 38.0))


@pytest.mark.parametrize(("old", "new", "message"), [
    ("density_g_cm3 = 2.65\n", "", r"density_g_cm3 is missing"),
    ("density_g_cm3 = 2.65", 'density_g_cm3 = "heavy"', r"density_g_cm3 must be a number, got str"),
    ("static = 0.5", "static = -1.0", r"friction\.static = -1\.0 is out of range \[0\.05, 3\]"),
    ("kinetic = 0.4", "kinetic = 0.7", r"friction\.kinetic = 0\.7 exceeds static = 0\.5"),
    ('magnetic = "none"', 'magnetic = "super"', r"magnetic = 'super' is unknown \(one of: ferro, para, none"),
    ('magnet_response_ut = 0.0', 'magnet_response_ut = 3.0', r"magnet_response_ut = 3\.0 does not fit"),
    ('texture = "speckle"', 'texture = "plaid"', r"appearance\.texture = 'plaid' is unknown"),
    ('label = "C6S1M1P2X1"', 'label = "C6S1M1P2"',
     r"label = 'C6S1M1P2' is not of the form C<c>S<s>M<m>P<p>X<x>"),
    ('conductive = false', 'conductive = "no"', r"conductive must be true or false"),
    ("adhesive_tack = 0.0", "adhesive_tack = 0.3", r"adhesive_tack = 0\.3 is not on the five-step scale"),
    ("colors = [[170, 165, 160], [40, 38, 38]]", "colors = [[170, 165]]",
     r"appearance\.colors must be 1-3 RGB"),
    ("micro_um = 0.1", "micro_um = 0.1\nmicro_nm = 3.0", r"roughness\.micro_nm is not a known field"),
    ("foldable = false", "foldable = false\nfold_angle_deg = 20.0",
     r"compliance\.fold_angle_deg is only allowed for foldable materials"),
    ('stiffness_n_per_mm = "rigid"', 'stiffness_n_per_mm = "soft"', r"stiffness_n_per_mm must be a number"),
    ("[test-material.thermal]\nheat_rise_k = 0.3\ncooling_rate_per_s = 0.4\n", "", r"thermal is missing"),
])
def test_library_errors_name_file_material_and_field(tmp_path, old, new, message):
    assert old in VALID
    path = write_library(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(sim.SimulationError) as caught:
        sim.load_materials(path)
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith("lab-materials.toml: material 'test-material': ")
    assert re.search(message, text), text


def test_library_file_errors(tmp_path):
    with pytest.raises(sim.SimulationError, match="not valid TOML"):
        sim.load_materials(write_library(tmp_path, "[broken"))
    with pytest.raises(sim.SimulationError, match="material library not found"):
        sim.load_materials(tmp_path / "missing.toml")
    with pytest.raises(sim.UnknownMaterialError, match="unknown material 'unobtainium'"):
        sim.synthetic_scan("unobtainium", seed=0)


# -- channels, determinism, meta -------------------------------------------------------------------------

EXPECTED_SHAPES = {
    "v_ft": (15000, 3), "v_fs": (15000, 3), "v_tt": (15000, 3), "v_ts": (15000, 3),  # 5 s x 3000 Hz
    "a_fs": (220500,), "a_ts": (220500,),  # 5 s x 44100 Hz
    "r_fs": (15000,), "r_ts": (15000,), "f_frn": (15000,), "f_frt": (15000,), "f_press": (15000,),
    "f_fold": (15000,), "alpha_f": (15000,),
    "t_cool": (200,),  # 10 s x 20 Hz
    "m": (3000,),  # 1 s x 3000 Hz
    "dB": (80,),  # 1 s x 80 Hz
}


def test_every_channel_at_its_rate_shape_and_unit(oak_scan):
    assert set(oak_scan.traces) == set(CHANNELS)
    for name, shape in EXPECTED_SHAPES.items():
        trace = oak_scan[name]
        assert trace.data.shape == shape, name
        assert trace.fs == CHANNELS[name].fs and trace.unit == CHANNELS[name].unit, name
    assert np.all(np.abs(oak_scan["a_ts"].data) <= 1.0) and np.all(np.abs(oak_scan["a_fs"].data) <= 1.0)
    assert set(np.unique(oak_scan["m"].data)) <= {-1.0, 1.0}
    gravity = oak_scan["v_ts"].data[:1000].mean(axis=0)
    assert np.linalg.norm(gravity) == pytest.approx(1.0, abs=0.01) and np.argmax(np.abs(gravity)) == 2


def test_meta_of_a_scan(oak_scan, library):
    meta = oak_scan.meta
    assert meta.label == "C1S1M1P4X1" and meta.sample_id == "oak-planed-01" and meta.scan_index == 1
    assert meta.session_id == "sim" and meta.operator == "sim" and not meta.rigid
    assert meta.device["simulator"] == "texplorer-sim" and meta.device["seed"] == "11"
    import scanner

    assert meta.software_version == scanner.__version__
    assert meta.atk in (0.0, 0.25) and meta.cyd in (0.0, 0.25)  # oak is judged 0, +0.25 at most
    assert 15.0 < meta.t_amb < 28.0 and round(meta.t_amb / 0.02, 6).is_integer()
    assert set(oak_scan.images) == {"I_disp", "I_macro", "I_illu"}


def test_same_seed_gives_a_bit_identical_scan_and_another_seed_does_not(oak_scan):
    again = sim.synthetic_scan("oak-planed", seed=11, image_size=SMALL, fold_skip_probability=0.0)
    assert again.meta == oak_scan.meta
    assert all(again[name] == oak_scan[name] for name in CHANNELS)
    assert all(np.array_equal(again.images[k], oak_scan.images[k]) for k in oak_scan.images)
    other = sim.synthetic_scan("oak-planed", seed=12, image_size=SMALL, fold_skip_probability=0.0)
    differing = [name for name in CHANNELS if other[name] != oak_scan[name]]
    assert set(differing) == set(CHANNELS) - {"m"}  # oak never conducts: m is -1 throughout
    assert not np.array_equal(other.images["I_disp"], oak_scan.images["I_disp"])


# -- TU1: slides and taps ---------------------------------------------------------------------------------


def test_the_ir_reads_a_static_level_before_the_slide(library):
    draw = operator(0, tool_slide_start_s=0.6)
    out = sim.tool_slide(library["granite-polished"], np.random.default_rng(0), draw)
    rest, moving = out["r_ts"][:1500], out["r_ts"][2100:]
    assert rest.std() < 0.005 and moving.std() > 10 * rest.std()


def test_vibration_grows_and_brightens_with_speed(library):
    def rms_and_centroid(speed: float) -> tuple[float, float]:
        out = sim.tool_slide(library["oak-planed"], np.random.default_rng(2),
                             operator(2, tool_speed_mm_s=speed, tool_slide_start_s=0.5))
        window = signal.sosfiltfilt(BAND, out["v_ts"], axis=0)[1600:4600, 2]
        spectrum = np.abs(np.fft.rfft(window))
        freqs = np.fft.rfftfreq(window.size, 1 / 3000)
        return float(window.std()), float(np.sum(freqs * spectrum) / np.sum(spectrum))

    slow, fast = rms_and_centroid(40.0), rms_and_centroid(220.0)
    assert fast[0] > 3 * slow[0]
    assert fast[1] > slow[1] + 50


def test_rough_surfaces_vibrate_and_sound_more_than_smooth_ones(library):
    draw = operator(4, tool_speed_mm_s=130.0, tool_slide_start_s=0.5)
    levels = {}
    for slug in ("float-glass", "oak-planed", "sandpaper-p80"):
        out = sim.tool_slide(library[slug], np.random.default_rng(4), draw)
        levels[slug] = (band_rms(out["v_ts"], 1500), float(out["a_ts"][22050:].std()))
    assert levels["float-glass"][0] < levels["oak-planed"][0] < levels["sandpaper-p80"][0]
    assert levels["float-glass"][1] < levels["oak-planed"][1] < levels["sandpaper-p80"][1]


def test_contact_resonance_closed_form(library):
    steel_modulus = dataclasses.replace(library["oak-planed"].compliance, elastic_modulus_mpa=210000.0)
    steel_like = dataclasses.replace(library["oak-planed"], compliance=steel_modulus)
    # f_mat = 900 Hz at 210 GPa, in series with the tool's own 1400 Hz: 1/f^2 = 1/900^2 + 1/1400^2
    assert sim.contact_frequency_hz(steel_like, sim.TOOL) == pytest.approx(757.06, abs=0.01)
    sixteenth = dataclasses.replace(steel_modulus, elastic_modulus_mpa=210000.0 / 16)
    # a 16x softer material halves f_mat (fourth root): 1/f^2 = 1/450^2 + 1/1400^2
    assert sim.contact_frequency_hz(dataclasses.replace(steel_like, compliance=sixteenth), sim.TOOL) == \
        pytest.approx(428.41, abs=0.01)


def test_taps_ring_higher_on_stiffer_materials(library):
    def ring_frequency(slug: str) -> float:
        v = sim.tool_tap(library[slug], np.random.default_rng(0), operator(0))["v_tt"]
        z = signal.sosfiltfilt(BAND, v, axis=0)[:, 2]
        peak = int(np.argmax(np.abs(z)))
        window = z[peak:peak + 600]
        return float(np.argmax(np.abs(np.fft.rfft(window))) * 3000 / window.size)

    steel, oak, cork = (ring_frequency(s) for s in ("mild-steel-brushed", "oak-planed", "cork-board"))
    assert steel == pytest.approx(sim.contact_frequency_hz(library["mild-steel-brushed"], sim.TOOL), abs=15)
    assert oak == pytest.approx(sim.contact_frequency_hz(library["oak-planed"], sim.TOOL), abs=15)
    assert steel > oak > cork


# -- TU2 --------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def foam_and_steel():
    foam = sim.synthetic_scan("polyurethane-foam", seed=5, image_size=SMALL)
    steel = sim.synthetic_scan("mild-steel-brushed", seed=5, image_size=SMALL, fold_skip_probability=0.0)
    return foam, steel


def test_foam_heats_up_and_steel_barely(foam_and_steel):
    foam, steel = foam_and_steel
    foam_rise = foam["t_cool"].data.max() - foam.meta.t_amb
    steel_rise = steel["t_cool"].data.max() - steel.meta.t_amb
    assert foam_rise > 8.0 and steel_rise < 0.8
    t = foam["t_cool"].data
    assert t[-1] - foam.meta.t_amb < 0.7 * foam_rise  # it cools toward t_amb
    assert np.argmax(t) > 0  # the sensor arrives over the heated spot during the first samples
    steps = np.concatenate([foam["t_cool"].data, steel["t_cool"].data]) / 0.02
    assert np.allclose(steps, np.round(steps), atol=1e-6)  # MLX90614 steps of 0.02 degC


def test_cooling_follows_the_library_rate(library):
    foam = library["polyurethane-foam"]
    t = sim.thermal(foam, np.random.default_rng(0), operator(0, heat_delay_s=1.0))["t_cool"]
    peak = int(np.argmax(t))
    amb = operator(0).t_amb
    rise = t[peak:] - amb
    times = np.arange(rise.size) / 20
    rate = -np.polyfit(times[rise > 1.0], np.log(rise[rise > 1.0]), 1)[0]
    assert rate == pytest.approx(foam.thermal.cooling_rate_per_s, rel=0.1)


def test_foam_folds_and_steel_does_not(foam_and_steel):
    foam, steel = foam_and_steel
    assert foam["alpha_f"].data.std() > 10.0
    assert steel["alpha_f"].data.std() < 1.0 and not steel.meta.rigid


def test_rigid_fold_is_skipped_or_recorded_flat(library):
    steel, foam = library["mild-steel-brushed"], library["polyurethane-foam"]
    assert sim.fold(steel, np.random.default_rng(0), operator(0, skips_rigid_fold=True)) == {}
    flat = sim.fold(steel, np.random.default_rng(0), operator(0, skips_rigid_fold=False))
    assert flat["alpha_f"].std() < 1.0 and flat["f_fold"].max() > 1.0
    assert "alpha_f" in sim.fold(foam, np.random.default_rng(0), operator(0, skips_rigid_fold=True))
    skipped = sim.synthetic_scan("mild-steel-brushed", seed=5, image_size=SMALL, fold_skip_probability=1.0)
    assert skipped.meta.rigid and skipped.get("alpha_f") is None and skipped.get("f_fold") is None


def test_press_reads_stiffness_times_4_mm_or_the_operator(foam_and_steel, library):
    foam, steel = foam_and_steel
    # polyurethane foam: 0.3 N/mm x 4.0 mm = 1.2 N, relaxing by 25 % with tau 1.5 s while held
    assert foam["f_press"].data.max() == pytest.approx(1.2, abs=0.02)
    relaxed = foam["f_press"].data.max() - foam["f_press"].data[-1]
    assert 1.2 * 0.25 * (1 - np.exp(-3.4 / 1.5)) - 0.02 < relaxed < 1.2 * 0.25 + 0.02
    assert 6.0 * 0.85 < steel["f_press"].data.max() < 15.0 * 1.15
    cork = sim.press(library["cork-board"], np.random.default_rng(0), operator(0, press_force_n=10.0))
    assert cork["f_press"].max() == pytest.approx(10.0, rel=0.15)  # 8 N/mm x 4 mm = 32 N is out of reach


def test_friction_slide_has_stiction_kinetic_ratio_and_release(library):
    oak = library["oak-planed"]
    draw = operator(3, friction_normal_n=5.0, friction_factor=1.1)
    out = sim.friction_slide(oak, np.random.default_rng(3), draw)
    normal, tangential = out["f_frn"], out["f_frt"] - out["f_frt"][:300].mean()
    end = int(np.nonzero(normal > 0.05 * normal.max())[0][-1])
    assert end < normal.size - 600  # released at least 0.2 s before the end (so FRS finds an end)
    assert normal[-300:].max() < 0.15  # the FSR floor of eq. (1), 0.098 N, plus noise
    sliding = slice(int(2.0 * 3000), int(3.5 * 3000))
    ratio = tangential[sliding].mean() / normal[sliding].mean()
    assert ratio == pytest.approx(oak.friction.kinetic * 1.1, rel=0.08)
    peak = int(np.argmax(tangential))
    assert tangential[peak] / normal[peak] == pytest.approx(oak.friction.static * 1.1, rel=0.1)


def test_fsr_floor_is_eq_1_at_zero_volts(library):
    out = sim.press(library["float-glass"], np.random.default_rng(0), operator(0, press_start_s=0.8))
    assert out["f_press"][:600].mean() == pytest.approx(9.81 * 0.01, rel=0.01)


@pytest.mark.parametrize(("slug", "low", "high"), [
    ("mild-steel-brushed", 5.0, 100.0), ("aluminium-sheet", 0.05, 1.0), ("oak-planed", -0.05, 0.05),
    ("copper-polished", -1.0, -0.02),
])
def test_magnetometer_sign_follows_the_magnetic_type_and_electrodes_find_metal(slug, low, high, library):
    material = library[slug]
    out = sim.static_touch(material, np.random.default_rng(0), operator(0))
    assert low < out["dB"].mean() < high
    steps = out["dB"] / 0.1
    assert np.allclose(steps, np.round(steps), atol=1e-6)
    if material.conductive:
        assert out["m"].mean() > 0.8 and np.all(out["m"][-2000:] == 1.0)
    else:
        assert np.all(out["m"] == -1.0)


# -- TU3, TU4 --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("slug", ["polyurethane-foam", "mild-steel-brushed", "oak-planed", "printer-paper"])
def test_density_from_mass_and_volume(slug, library):
    scan = sim.synthetic_scan(slug, seed=0, image_size=SMALL)
    assert scan.meta.mass_g / scan.meta.volume_cm3 == pytest.approx(library[slug].density_g_cm3, rel=0.06)
    sample = sim.sample_of(library[slug], f"{slug}-01")
    for seed in range(1, 6):
        measured = sim.tu4(sample, np.random.default_rng(seed), operator(seed))
        density = measured["mass_g"] / measured["volume_cm3"]
        assert density == pytest.approx(library[slug].density_g_cm3, rel=0.06)


def test_judged_values_stay_on_the_scale(library):
    paper = library["printer-paper"]  # yielding 0.75
    assert sim.tu4(paper, np.random.default_rng(0), operator(0, cyd_offset=0.25))["cyd"] == 1.0
    assert sim.tu4(paper, np.random.default_rng(0), operator(0, cyd_offset=-0.25))["cyd"] == 0.5
    glass = library["float-glass"]  # adhesive tack 0
    assert sim.tu4(glass, np.random.default_rng(0), operator(0, atk_offset=-0.25))["atk"] == 0.0


def test_photos_are_rgb_uint8_of_the_asked_size_and_differ_between_materials(library):
    draw = operator(0)
    shots = {slug: sim.photos(library[slug], np.random.default_rng(0), draw, (96, 128))
             for slug in ("oak-planed", "mild-steel-brushed", "perforated-steel-plate")}
    for images in shots.values():
        assert set(images) == {"I_disp", "I_macro", "I_illu"}
        for image in images.values():
            assert image.dtype == np.uint8 and image.shape == (96, 128, 3)
        assert images["I_illu"].mean() > images["I_disp"].mean()  # the flash
    means = [images["I_disp"].reshape(-1, 3).mean(axis=0) for images in shots.values()]
    assert min(np.abs(a - b).max() for i, a in enumerate(means) for b in means[i + 1:]) > 10
    oak = shots["oak-planed"]["I_disp"].astype(float)
    assert oak[..., 0].mean() > oak[..., 2].mean() + 30  # wood is brown: red well above blue


def test_perforated_photo_shows_the_hole_pitch(library):
    """8 mm pitch over the 60 mm field of a 256 px photo: a hole every 34.1 px along the rows."""
    look = dataclasses.replace(library["perforated-steel-plate"].appearance, orientation_deg=0.0)
    plate = dataclasses.replace(library["perforated-steel-plate"], appearance=look)
    draw = operator(0, photo_rotation_deg=0.0)
    image = sim.photos(plate, np.random.default_rng(0), draw, (256, 256))["I_disp"]
    profile = image.astype(float).mean(axis=(0, 2))
    spectrum = np.abs(np.fft.rfft(profile - profile.mean()))
    assert np.argmax(spectrum) in (7, 8)  # 60 / 8 = 7.5 cycles across the image


# -- the scan plot -----------------------------------------------------------------------------------------


