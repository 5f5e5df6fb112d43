"""Image features (docs/features.md#image): closed-form answers on synthetic images, plus the libraries the
definitions name: the system tests (every image feature on photos of many sizes)."""

from __future__ import annotations

import numpy as np
import pytest

from features import image
from scanner.preprocess import grayscale


def test_the_crop_is_a_parameter_and_patches_keep_every_pixel():
    rng = np.random.default_rng(5)
    patch = rng.integers(0, 256, (256, 256, 3), dtype=np.uint8)
    whole = image.compute(patch, border=0)
    assert all(np.isfinite(list(whole.values())))
    gray = grayscale(patch)
    assert whole["brightness"] == pytest.approx(gray.mean() / 255, rel=1e-12)
    assert whole["tamura_coarseness"] == image.tamura_coarseness(gray)
    framed = np.pad(patch, ((10, 10), (10, 10), (0, 0)))
    assert image.compute(framed, border=10) == whole  # cropping 10 px gives back the patch


@pytest.mark.parametrize(("side", "nan"), [(63, {"tamura_coarseness"}), (3, {"tamura_coarseness"}),
                                           (2, {"tamura_coarseness", *(f"lbp_{i}" for i in range(10))})])
def test_each_feature_needs_only_the_size_its_definition_needs(side, nan):
    patch = np.random.default_rng(side).integers(0, 256, (side, side + 5, 3), dtype=np.uint8)
    with pytest.warns(image.ImageSizeWarning, match=rf"image of {side}x{side + 5} px \(after cropping 0 px\) "
                      r"is too small for tamura_coarseness \(needs 64x64 px\)"):
        values = image.compute(patch, border=0)
    assert {name for name, value in values.items() if np.isnan(value)} == nan
    gray = grayscale(patch)
    assert values["haralick_01"] == pytest.approx(image.haralick(gray)[0], rel=1e-12)
    if side >= 3:
        assert values["lbp_0"] == image.lbp_histogram(gray)[0]
