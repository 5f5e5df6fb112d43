"""MaCo's corners (Strese et al: the system tests (Harris on a photo-sized image)."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.ndimage import gaussian_filter
from unit.test_corners import _known_harris_loops

from features import corners as detector
from features.image import PreparedPhoto


def test_the_harris_response_of_a_photo_is_that_of_corner_harris():
    photo = np.kron(np.random.default_rng(3).integers(0, 256, (40, 52, 3)), np.ones((13, 11, 1))).astype(np.uint8)
    gray = PreparedPhoto(gaussian_filter(photo, (1.5, 1.5, 0)).astype(np.uint8)).gray32
    response = detector._harris_response(gray, _known_harris_loops())
    np.testing.assert_array_equal(response, cv2.cornerHarris(gray, 3, 3, 0.04))
    # Another dtype or a strided view is taken as its float32 copy, as cornerHarris would need it.
    view = gray.astype(np.float64)[::2, 1::3]
    expected = cv2.cornerHarris(np.ascontiguousarray(view, dtype=np.float32), 3, 3, 0.04)
    np.testing.assert_array_equal(detector.harris_response(view), expected)
