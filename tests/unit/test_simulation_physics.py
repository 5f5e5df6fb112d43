"""The simulated scanner as a source of information: every modality separates materials the way real
recordings do, every taxonomy label simulates, and a seed fixes a scan (docs/simulator.md)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from sklearn.ensemble import RandomForestClassifier

from scanner import simulation as sim
from scanner.simulation.contact import contact_mechanics
from scanner.simulation.derived import derived_material, material_for_label
from scanner.simulation.microphone import plate_mobility
from taxonomy.labels import Label
from taxonomy.table import load_taxonomy

SET = ("oak-planed", "cotton-woven", "pvc-sheet", "polyurethane-foam", "glazed-wall-tile", "granite-pointed",
       "mild-steel-brushed", "sandpaper-p80")
"""Eight materials of eight major classes for the separability test."""
SCANS = 2
IMAGE_SIZE = (288, 288)
"""Just above the 264 px the image features need."""


def piece_accuracy(x: np.ndarray, y: np.ndarray, pieces: np.ndarray) -> float:
    """Train on one piece of every material, test on the other, both ways (folds grouped by sample)."""
    correct = 0
    for test in (1, 2):
        forest = RandomForestClassifier(n_estimators=100, random_state=0).fit(x[pieces != test], y[pieces != test])
        correct += int(np.sum(forest.predict(x[pieces == test]) == y[pieces == test]))
    return correct / y.size


# -- every taxonomy label -------------------------------------------------------------------------------

def test_every_taxonomy_material_has_validated_parameters_hand_set_ones_unchanged():
    library = sim.load_materials()
    for material in load_taxonomy().materials():
        for p, x in ((1, 1), (2, 2), (5, 3), (7, 6), (16, 11)):
            label = material.label(p, x)
            simulated = material_for_label(label)
            assert simulated.label == str(label)
            hand_set = [m for m in library.values() if m.label == str(label)]
            assert simulated == (hand_set[0] if hand_set else derived_material(label))
            assert simulated.derived is not bool(hand_set)


def test_derived_parameters_follow_the_codes():
    # the description's density, a known constant, the finish, and the same material code gives the same
    # physical material under every finish apart from its surface
    ash = material_for_label("C1S1M4P1X1")
    assert ash.density_g_cm3 == 0.69 and ash.derived
    assert material_for_label("C7S4M1P1X1").density_g_cm3 == 11.3
    polished, pointed = material_for_label("C6S1M2P2X1"), material_for_label("C6S1M2P3X1")
    assert polished.roughness.micro_um < pointed.roughness.micro_um and polished.appearance.gloss > 0.5
    assert polished.compliance == pointed.compliance and polished.density_g_cm3 == pointed.density_g_cm3
    assert material_for_label("C1S1M1P2X1").compliance == sim.load_materials()["oak-planed"].compliance
    assert not material_for_label("C7S2M1P1X10").conductive  # anodised: the electrodes meet oxide


def test_a_label_of_a_class_without_physics_says_what_to_do():
    with pytest.raises(sim.SimulationError, match="no physics for C9S1 .* choose a material of the classes"):
        material_for_label("C9S1M1P1X1")
    with pytest.raises(sim.UnknownMaterialError, match="give a full taxonomy label such as C1S1M4P1X1"):
        sim.synthetic_scan("oak", seed=0)


def labels_to_scan() -> list[str]:
    """One derived material of every major class with every processing shape and extra attribute once."""
    materials = load_taxonomy().materials()
    firsts = [m for m in materials if not sim.is_hand_set(m.code)]
    majors = {}
    for m in firsts:
        majors.setdefault(m.code.split("S")[0], m)
    chosen = list(majors.values())
    return [str(chosen[k % len(chosen)].label(p, 1 + k % 11)) for k, p in enumerate(range(1, 17))]


@pytest.mark.parametrize("label", labels_to_scan())
def test_derived_labels_simulate_whole_scans(label):
    scan = sim.synthetic_scan(label, seed=3, image_size=(32, 32))
    assert scan.meta.label == label and scan.meta.device["material"] == label.lower()
    for trace in scan.traces.values():
        assert np.all(np.isfinite(trace.data))
    assert np.abs(scan["a_ts"].data).max() < 1.0 and np.abs(scan["v_ts"].data).max() <= 3.61


def test_a_seed_fixes_a_derived_scan():
    first = sim.synthetic_scan("C3S3M2P1X1", seed=11, image_size=(32, 32))
    again = sim.synthetic_scan("c3s3m2p1x1", seed=11, image_size=(32, 32))
    other = sim.synthetic_scan("C3S3M2P1X1", seed=12, image_size=(32, 32))
    for name, trace in first.traces.items():
        assert np.array_equal(trace.data, again.traces[name].data), name
    assert not np.array_equal(first["a_ts"].data, other["a_ts"].data)
    assert all(np.array_equal(first.images[k], again.images[k]) for k in first.images)


# -- the physics of the contact and the sound --------------------------------------------------------------

def test_hertz_contact_and_stick_slip_rate_closed_form():
    rubber = sim.load_materials()["silicone-rubber"]  # E = 1.5 MPa, mu_s 1.3, mu_k 1.0
    contact = contact_mechanics(rubber, sim.TOOL, 1.0)
    e_star = 1 / ((1 - 0.3**2) * (1 / 1.5 + 1 / 200000.0))
    radius = (3 * 1.0 * 3.0 / (4 * e_star)) ** (1 / 3)
    assert contact.radius_mm == pytest.approx(radius, rel=1e-12)
    assert contact.stick_slip_per_mm == pytest.approx(8 * e_star / 2.6 * radius / (2 * 0.3 * 1.0), rel=1e-9)
    glass = contact_mechanics(sim.load_materials()["float-glass"], sim.TOOL, 1.0)
    assert glass.stick_slip_per_mm * 130 > 44100 / 4  # a hard contact slips far above the audio band


def test_plate_modes_sit_at_the_closed_form_frequencies():
    steel = sim.load_materials()["mild-steel-brushed"]
    h = steel.sample_volume_cm3 / 100 * 1e-2
    stiffness = 210e9 * h**3 / (12 * (1 - 0.09))
    f11 = np.pi / 2 * np.sqrt(stiffness / (7850 * h)) * 2 / 0.1**2
    f = np.linspace(0.8 * f11, 1.2 * f11, 4001)
    mobility = np.abs(plate_mobility(steel, f, 0.5))
    assert f[np.argmax(mobility)] == pytest.approx(f11, rel=1e-3)


def test_sound_follows_the_slide_it_comes_from():
    """Faster slides are louder and brighter within the lavalier's band; before the slide only the room."""
    library = sim.load_materials()
    draw = sim.draw_operator(np.random.default_rng(5))

    def heard(speed: float) -> tuple[float, float, float]:
        out = sim.tool_slide(library["oak-planed"], np.random.default_rng(5),
                             dataclasses.replace(draw, tool_speed_mm_s=speed, tool_slide_start_s=0.6))
        audio = out["a_ts"]
        window = audio[44100:88200]
        power = np.abs(np.fft.rfft(window)) ** 2
        freqs = np.fft.rfftfreq(window.size, 1 / 44100)
        band = freqs < 7500  # above it the 16-bit floor, not the slide
        centroid = np.sum(freqs[band] * power[band]) / np.sum(power[band])
        return float(audio[:22050].std()), float(window.std()), float(centroid)

    (rest_slow, slow, centroid_slow), (rest_fast, fast, centroid_fast) = heard(50.0), heard(200.0)
    # Below the contact resonance the force grows as v^2 (m a), above it as the profile's height at the
    # higher temporal frequency (k z): the sound grows at least as the speed ratio 4, less the room's floor
    # in the slow level; 3 leaves that floor room.
    assert fast > 3 * slow and centroid_fast > centroid_slow
    assert max(rest_slow, rest_fast) < 0.05 * slow


def test_a_derived_sub_class_keeps_its_prototype_but_each_material_differs():
    beech_like = [material_for_label(f"C1S1M{m}P1X1") for m in (5, 6, 7)]
    assert len({m.density_g_cm3 for m in beech_like}) == 3
    assert all(m.appearance.texture == "grain" for m in beech_like)
    assert Label.parse(beech_like[0].label).codes()[1] == "C1S1"
