"""The project's feature families on generic recordings, by role (features.recordings)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from features import audio, image, recordings, signals
from features.recordings import Windowing
from features.space import FeatureSpace
from scanner.scan import Recording, Trace


def test_whole_recording_audio_in_chunks_equals_the_one_pass_mean():
    x = np.random.default_rng(0).standard_normal(8000 * 20)  # 799 frames: four chunks
    chunked, whole = signals.audio_features(x, 8000.0), audio.compute(x, 8000.0)
    # The same frame rows, summed in another order: equal to float64 rounding of a 799-term mean.
    assert chunked == pytest.approx(whole, rel=1e-12, abs=1e-12)


def test_the_vibration_band_follows_the_rate():
    assert signals.vibration_band(3000.0) == (10.0, 1000.0)
    assert signals.vibration_band(1000.0) == (10.0, 450.0)
    quiet = Recording("slow", {"v": Trace(np.ones(100), 20.0, "g")}, {"vibration": "v"}, "x")
    # 0.45 x 20 Hz is below the 10 Hz lower edge: only the generic family of a slow vibration applies.
    assert recordings.families(quiet) == ["generic.vibration"]


def test_friction_of_a_constant_coefficient_is_that_coefficient():
    fs = 200.0
    t = np.arange(400) / fs
    fz = np.clip((t - 0.2) * 10, 0, 3)  # no load during the first 0.1 s, so the tare is 0
    xyz = np.column_stack([0.3 * fz, 0.4 * fz, fz])  # |(x, y)| = 0.5 fz
    values = signals.friction_features(xyz, fs)
    assert values["tactum.force_xyz.frs"] == pytest.approx(0.5, rel=1e-12)
    assert values["tactum.force_xyz.fst"] == pytest.approx(0.5, rel=1e-12)  # slopes scale alike


def recording(seconds: float = 2.0, name: str = "r", **group: str) -> Recording:
    rng = np.random.default_rng(1)
    tone = np.sin(2 * np.pi * 250.0 * np.arange(int(seconds * 4000)) / 4000)
    return Recording(name, {"a": Trace(0.5 * tone + 0.01 * rng.standard_normal(tone.size), 4000.0, "FS"),
                            "v": Trace(rng.standard_normal((int(seconds * 3000), 3)), 3000.0, "g")},
                     {"audio": "a", "vibration": "v", "photo": "p"}, "cork", group,
                     {"label_level": "material"}, {"p": rng.integers(0, 256, (40, 50, 3), dtype=np.uint8)})


def test_every_family_by_role_and_windows_combined_or_as_rows():
    r = recording()
    assert recordings.families(r) == ["audio.audio", "audio.vibration", "image.photo", "vibration"]
    with pytest.warns(image.ImageSizeWarning, match="40x50 px"):
        (whole,) = recordings.recording_rows(r)
    assert whole["audio.audio.f0"] == pytest.approx(250.0, rel=1e-9)
    assert math.isnan(whole["image.photo.tamura_coarseness"]) and not math.isnan(whole["image.photo.lbp_0"])
    with pytest.warns(image.ImageSizeWarning):
        rows = recordings.recording_rows(r, Windowing(0.5, "rows"))
        (mean,) = recordings.recording_rows(r, Windowing(0.5, "mean"))
    assert len(rows) == 4
    first = signals.audio_features(r.channels["a"].data[:2000], 4000.0)
    assert rows[0]["audio.audio.zcr"] == first["zcr"]
    assert mean["audio.audio.zcr"] == pytest.approx(np.mean([row["audio.audio.zcr"] for row in rows]), rel=1e-15)
    assert all(row["image.photo.color"] == whole["image.photo.color"] for row in rows)  # photos are whole


def test_a_set_space_keeps_labels_groups_levels_and_the_split(tmp_path):
    rs = [recording(1.0, f"r{i}", object=f"o{i // 2}") for i in range(4)]
    rs = [Recording(r.name, r.channels, r.roles, ("cork", "felt")[i % 2], r.group,
                    {"label_level": "material", "levels": {"hardness": "soft"}, "split": ("train", "test")[i // 2]},
                    r.images) for i, r in enumerate(rs)]
    space, notes = recordings.feature_space(rs, Windowing(0.5, "rows"))
    # Warnings in extraction are returned, naming their recording, not raised.
    assert len(notes) == 4 and notes[0].startswith("recording 'r0': image of 40x50 px (after cropping 0 px)")
    assert space.scan_ids[:2] == ("r0#w000", "r0#w001") and space.groups[:4] == ("o0",) * 4
    assert space.label_level == "material" and space.levels == {"hardness": ("soft",) * 8}
    assert space.split == ("train",) * 4 + ("test",) * 4 and space.level_names == ("hardness", "material")
    assert space.y("fine").tolist() == ["cork", "cork", "felt", "felt"] * 2
    with pytest.raises(ValueError, match="no level 'coarse' in this feature space"):
        space.y("coarse")
    back = FeatureSpace.from_csv(space.to_csv(tmp_path / "f.csv"))
    assert (back.levels, back.split, back.label_level) == (space.levels, space.split, space.label_level)
    with pytest.raises(recordings.ParameterError, match="has no group 'trial'"):
        recordings.fold_group(rs[0], "trial")
