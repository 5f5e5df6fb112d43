"""MaCo's corners (Strese et al. 2020, section IV-A1b): Harris corners against OpenCV's, bit for bit, and the
determinant-of-Hessian scales against whole-image filtering."""

from __future__ import annotations

import platform

import cv2
import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from features import corners as detector


def test_harris_corners_of_a_square():
    gray = np.zeros((200, 220))
    gray[60:140, 50:150] = 255.0
    corners = detector.harris_corners(gray)
    truth = np.array([[60, 50], [60, 149], [139, 50], [139, 149]])
    distance = np.linalg.norm(corners[:, None, :] - truth[None, :, :], axis=2)
    assert corners.dtype.kind == "i"
    assert np.all(distance.min(axis=0) <= 2.0)   # every true corner found
    assert np.all(distance.min(axis=1) <= 3.0)   # nothing else
    assert detector.harris_corners(np.full((50, 50), 7.0)).shape == (0, 2)


def _good_features_to_track(gray: np.ndarray) -> np.ndarray:
    """MaCo's corners as the paper finds them (section IV-A1b): OpenCV's detector with its parameters."""
    points = cv2.goodFeaturesToTrack(gray.astype(np.float32), maxCorners=100, qualityLevel=0.01, minDistance=10,
                                     blockSize=3, useHarrisDetector=True, k=0.04)
    if points is None:
        return np.empty((0, 2), np.intp)
    return np.rint(points.reshape(-1, 2)).astype(np.intp)[:, ::-1]


def _harris_test_image(kind: str, h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    rows, cols = np.mgrid[:h, :w]
    if kind == "noise":
        return rng.uniform(0, 255, (h, w))
    if kind == "few levels":
        return rng.integers(0, 3, (h, w)) * 80.0
    if kind == "blurred":
        return gaussian_filter(rng.uniform(0, 255, (h, w)), 3.0)
    if kind == "step":
        return np.where((rows > h // 3) & (cols > w // 4), 200.0, 5.0)
    return (rows % 7 + cols % 5) * 10.0


@pytest.mark.parametrize("kind", ["noise", "few levels", "blurred", "step", "lattice"])
def test_harris_corners_are_those_of_good_features_to_track_in_the_same_order(kind):
    # Few levels and lattices make many equal responses, so the order of ties is checked too.
    rng = np.random.default_rng(len(kind))
    for h, w in [(3, 3), (17, 400), (240, 181), (301, 302)]:
        gray = _harris_test_image(kind, h, w, rng)
        np.testing.assert_array_equal(detector.harris_corners(gray), _good_features_to_track(gray))


def test_harris_corners_of_large_images_from_the_strongest_responses_or_from_all():
    # From 2^20 pixels on, the corners are first looked for among the strongest responses: enough on a
    # texture and on a few squares over faint noise (no other candidate passes the threshold); a small
    # checkerboard's crowded corners over noise leave too few there, and every candidate is looked at.
    rng = np.random.default_rng(12)
    texture = gaussian_filter(rng.uniform(0, 255, (1100, 1000)), 2.0)
    squares = rng.uniform(0, 2, (1100, 1000))
    for top, left in [(100, 100), (500, 600), (800, 200)]:
        squares[top:top + 150, left:left + 150] += 200
    crowded = rng.uniform(0, 90, (1100, 1000))
    rows, cols = np.mgrid[:60, :60]
    crowded[500:560, 500:560] = ((rows // 3 + cols // 3) % 2) * 255.0
    for gray, decided in ((texture, True), (squares, True), (crowded, False)):
        response = cv2.cornerHarris(gray.astype(np.float32), 3, 3, 0.04)
        threshold = float(response.max()) * 0.01
        found = detector._corners_above(response, threshold, detector._strong_cut(response))
        assert (found is not None) == decided
        np.testing.assert_array_equal(detector.harris_corners(gray), _good_features_to_track(gray))


def _known_harris_loops() -> tuple[int, int]:
    loops = detector._harris_loops()
    # Every x86-64 build of OpenCV has one of the known layouts: there, falling back would be a defect.
    assert loops is not None or platform.machine().lower() not in ("x86_64", "amd64")
    if loops is None:
        pytest.skip("this OpenCV's calcHarris matches none of the known loop layouts, so harris_response "
                    "calls cornerHarris")
    return loops


@pytest.mark.parametrize("kind", ["noise", "few levels", "blurred", "step", "lattice"])
def test_the_harris_response_is_that_of_corner_harris_bit_for_bit(kind):
    # Shapes with every remainder of the pixel count modulo 8 (the vector loops' tails), single rows and
    # columns, bands of 64 rows cut at several places; values of three magnitudes.
    loops = _known_harris_loops()
    rng = np.random.default_rng(len(kind) + 40)
    for h, w in [(1, 1), (1, 37), (29, 1), (2, 2), (3, 5), (31, 33), (64, 9), (65, 11), (129, 130), (200, 301)]:
        for scale in (1 / 255, 1.0, 40.0):
            gray = (_harris_test_image(kind, h, w, rng) * scale).astype(np.float32)
            expected = cv2.cornerHarris(gray, 3, 3, 0.04)
            np.testing.assert_array_equal(detector._harris_response(gray, loops).view(np.uint32),
                                          expected.view(np.uint32))
            np.testing.assert_array_equal(detector.harris_response(gray), expected)




def test_the_harris_loop_layout_is_the_one_layout_that_reproduces_corner_harris():
    # The probes tell the layouts apart: the one found reproduces cornerHarris on them, every other
    # layout misses on some probe, so a wrong layout can never be taken for the right one.
    loops = _known_harris_loops()
    probes = detector._harris_probes()
    for layout in detector._HARRIS_LOOPS:
        same = all(np.array_equal(detector._harris_response(probe, layout), cv2.cornerHarris(probe, 3, 3, 0.04))
                   for probe in probes)
        assert same == (layout == loops), layout


def test_candidates_in_batches_come_in_the_order_of_one_full_sort():
    # Larger value first, ties by larger index, as OpenCV sorts; batches of 3, 12, 48, ... candidates.
    rng = np.random.default_rng(3)
    index = rng.permutation(1000)[:200]
    value = rng.integers(0, 20, 200).astype(np.float32)
    batches = list(detector._strongest_first(index, value, batch=3))
    assert len(batches) > 2
    order = sorted(range(200), key=lambda i: (-value[i], -index[i]))
    np.testing.assert_array_equal(np.concatenate(batches), index[order])


@pytest.mark.parametrize("shape", [(40, 50), (140, 97)])
def test_hessian_response_equals_whole_image_filtering_up_to_the_border(shape):
    gray = gaussian_filter(np.random.default_rng(8).uniform(0, 255, shape), 1.0)
    h, w = shape
    points = np.array([[0, 0], [h - 1, w - 1], [2, w // 2], [h // 2, w // 2], [h - 3, 1]])
    for sigma in detector.DOH_SCALES[[0, 5, 10, 15]]:
        l_xx = gaussian_filter(gray, sigma, order=(0, 2), mode="reflect", truncate=4.0)
        l_yy = gaussian_filter(gray, sigma, order=(2, 0), mode="reflect", truncate=4.0)
        l_xy = gaussian_filter(gray, sigma, order=(1, 1), mode="reflect", truncate=4.0)
        whole = sigma**4 * (l_xx * l_yy - l_xy**2)
        expected = whole[points[:, 0], points[:, 1]]
        np.testing.assert_allclose(detector.hessian_response(gray, points, sigma), expected,
                                   rtol=1e-9, atol=1e-9 * np.abs(whole).max())


def _reflected(index: np.ndarray, n: int) -> np.ndarray:
    folded = np.mod(index, 2 * n)
    return np.where(folded >= n, 2 * n - 1 - folded, folded)


def _neighbourhood_doh(gray: np.ndarray, corners: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``detector.hessian_response`` the straightforward way -- each corner's whole (2r+1)^2 neighbourhood
    gathered through reflected indices, weighted along axis 0, then axis 1 -- and a bound on how far a
    sum of the same products grouped otherwise can round away from it.

    Summing n terms one way rounds by at most (n - 1) u times the sum of their magnitudes (u = eps/2):
    here 2(2r+1) + 2 additions and products along the longest path, and the folded quarter (3 additions,
    then r+1 and r+1 terms) about 2r + 7; together below (4r + 8) eps. A product ab is then off by at
    most |a| db + |b| da + da db.
    """
    radius = detector._radius(sigma)
    offsets = np.arange(-radius, radius + 1)
    h, w = gray.shape
    w0, w1, w2 = (detector.gaussian_weights(sigma, order) for order in (0, 1, 2))
    rounding = (4 * radius + 8) * np.finfo(np.float64).eps
    values, bounds = [], []
    for row, col in corners:
        patch = gray[_reflected(row + offsets, h)[:, None], _reflected(col + offsets, w)[None, :]]
        l_yy, l_xx, l_xy = (w2 @ patch) @ w0, (w0 @ patch) @ w2, (w1 @ patch) @ w1
        d_yy, d_xx, d_xy = (rounding * (np.abs(a) @ np.abs(patch) @ np.abs(b))
                            for a, b in ((w2, w0), (w0, w2), (w1, w1)))
        values.append(sigma**4 * (l_xx * l_yy - l_xy**2))
        bounds.append(sigma**4 * (abs(l_xx) * d_yy + abs(l_yy) * d_xx + d_xx * d_yy + 2 * abs(l_xy) * d_xy + d_xy**2))
    return np.array(values), np.array(bounds)


@pytest.mark.parametrize("shape", [(40, 50), (140, 97), (312, 312)])
def test_folded_corner_responses_equal_the_whole_neighbourhood_sums(shape):
    # (40, 50) is smaller than the largest neighbourhood (131 px): its borders reflect several times.
    rng = np.random.default_rng(shape[0])
    gray = gaussian_filter(rng.uniform(0, 255, shape), 1.5)
    corners = np.column_stack([rng.integers(0, shape[0], 40), rng.integers(0, shape[1], 40)])
    corners[:3] = [[0, 0], [shape[0] - 1, shape[1] - 1], [shape[0] // 2, shape[1] // 2]]
    expected, bounds = zip(*(_neighbourhood_doh(gray, corners, sigma) for sigma in detector.DOH_SCALES), strict=True)
    expected, bounds = np.stack(expected, axis=1), np.stack(bounds, axis=1)
    for k, sigma in enumerate(detector.DOH_SCALES):
        assert np.all(np.abs(detector.hessian_response(gray, corners, sigma) - expected[:, k]) <= bounds[:, k])
    # The scale is the same wherever the largest response leads the next by more than both bounds.
    magnitude = np.abs(expected)
    best = np.argmax(magnitude, axis=1)
    rest = np.where(np.arange(len(detector.DOH_SCALES)) == best[:, None], -np.inf, magnitude - bounds)
    decided = magnitude[np.arange(len(best)), best] - bounds[np.arange(len(best)), best] > rest.max(axis=1)
    assert decided.mean() > 0.9
    np.testing.assert_array_equal(detector.corner_scales(gray, corners)[decided], detector.DOH_SCALES[best[decided]])


def test_gaussian_weights_are_exactly_symmetric_or_antisymmetric():
    # The folded neighbourhood sums rely on it: w(-d) = w(d) for orders 0 and 2, -w(d) for order 1.
    for sigma in detector.DOH_SCALES:
        for order, sign in ((0, 1.0), (1, -1.0), (2, 1.0)):
            weights = detector.gaussian_weights(sigma, order)
            np.testing.assert_array_equal(weights, sign * weights[::-1])


@pytest.mark.parametrize("k", [4, 8, 11])
def test_corner_scale_of_a_gaussian_blob_is_its_width(k):
    # At the centre of exp(-r^2 / 2 s^2), sigma^4 det H = (sigma^2 s^2 / (s^2 + sigma^2)^2)^2, largest at
    # sigma = s.
    s = 1.2 * 2 ** (k / 4)
    yy, xx = np.mgrid[:200, :200]
    gray = 100.0 * np.exp(-((yy - 100) ** 2 + (xx - 100) ** 2) / (2 * s**2))
    assert detector.corner_scales(gray, np.array([[100, 100]]))[0] == pytest.approx(s, rel=1e-12)
