"""The 15 TacTUM features (docs/features.md#tactum) on inputs whose answers are known in closed form: the system
tests (simulated scans at 256 px)."""

from __future__ import annotations

import warnings

import pytest

from features import tactum
from scanner import simulation
from scanner.scan import Scan


def _simulated(slug: str, seed: int) -> Scan:
    return simulation.synthetic_scan(slug, seed=seed, image_size=(256, 256))


@pytest.mark.parametrize(("soft", "hard"), [("polyurethane-foam", "mild-steel-brushed")])
def test_foam_is_more_compliant_and_holds_heat_more_than_steel(soft, hard):
    for seed in range(3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", tactum.MissingDataWarning)
            foam, steel = tactum.compute(_simulated(soft, seed)), tactum.compute(_simulated(hard, seed))
        assert foam["tactum.ccp"] > steel["tactum.ccp"]
        assert foam["tactum.tco"] > steel["tactum.tco"]
        assert foam["tactum.tpr"] > steel["tactum.tpr"]


@pytest.mark.parametrize(("rough", "smooth"), [("sandpaper-p80", "float-glass")])
def test_sandpaper_is_rougher_than_glass(rough, smooth):
    for seed in range(3):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", tactum.MissingDataWarning)
            paper, glass = tactum.compute(_simulated(rough, seed)), tactum.compute(_simulated(smooth, seed))
        assert paper["tactum.matx"] > glass["tactum.matx"]
        assert paper["tactum.miro"] > glass["tactum.miro"]
