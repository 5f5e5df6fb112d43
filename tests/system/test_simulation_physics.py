"""The simulated scanner's every modality carries information: on a small simulated set each family separates
the materials far above chance while a shuffled-label control stays at chance (the system tests: a
simulated set of whole scans, about a minute of CPU)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from unit.test_simulation_physics import IMAGE_SIZE, SCANS, SET, piece_accuracy

from features import REGISTRY, extract
from scanner import simulation as sim


@pytest.fixture(scope="module")
def small_set():
    """Features of 2 pieces x 2 scans of each material of SET: (X by family, labels, piece numbers)."""
    rows, labels, pieces = [], [], []
    for slug in SET:
        for piece in (1, 2):
            for index in range(1, SCANS + 1):
                scan = sim.synthetic_scan(slug, seed=sim.scan_seed(7, slug, index, piece), scan_index=index,
                                          sample_id=sim.sample_id_of(slug, piece), image_size=IMAGE_SIZE)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    rows.append(extract(scan))
                labels.append(slug)
                pieces.append(piece)
    by_family = {name: np.nan_to_num(np.array([[row[c] for c in REGISTRY[name].columns] for row in rows]))
                 for name in REGISTRY.modalities}
    return by_family, np.array(labels), np.array(pieces)


@pytest.mark.parametrize("family", ["tactum", "image", "audio", "other"])
def test_every_modality_separates_materials_and_a_shuffled_control_does_not(small_set, family):
    by_family, labels, pieces = small_set
    chance = 1 / len(SET)
    assert piece_accuracy(by_family[family], labels, pieces) >= 4 * chance
    # Labels shuffled within each piece: the same features carry no information about them. The mean of ten
    # shuffles has a standard error of about sqrt(chance (1 - chance) / 32 / 10) = 1.8 %, so 2 x chance is
    # more than six standard errors above its expectation.
    rng = np.random.default_rng(0)
    shuffled = []
    for _ in range(10):
        permuted = labels.copy()
        for piece in (1, 2):
            permuted[pieces == piece] = rng.permutation(labels[pieces == piece])
        shuffled.append(piece_accuracy(by_family[family], permuted, pieces))
    assert np.mean(shuffled) < 2 * chance
