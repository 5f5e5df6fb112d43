"""Image features (docs/features.md#image): closed-form answers on synthetic images, plus the libraries the definitions
name."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from skimage.feature import local_binary_pattern

from features import image
from scanner.preprocess import crop_image, gray_uint8, grayscale

LN2 = math.log(2.0)


def textured_photo(h: int = 300, w: int = 330, seed: int = 0) -> np.ndarray:
    """Noise plus a grating, in colour: every feature is non-degenerate on it."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0:h, 0:w]
    base = 120 + 60 * np.sin(2 * np.pi * cols / 23) * np.cos(2 * np.pi * rows / 41)
    noise = rng.normal(0, 25, (h, w, 3))
    tint = np.array([1.0, 0.7, 0.4])
    return np.clip(base[..., None] * tint + noise, 0, 255).astype(np.uint8)


# --- names and the whole photo ------------------------------------------------------------------------


def test_names_are_the_31_columns_in_spec_order():
    assert len(image.NAMES) == 31
    assert image.NAMES[:5] == ("color", "brightness", "edginess", "dft_80", "dft_85")
    assert image.NAMES[5:19] == tuple(f"haralick_{i:02d}" for i in range(1, 15))
    assert image.NAMES[19:21] == ("tamura_coarseness", "tamura_contrast")
    assert image.NAMES[21:] == tuple(f"lbp_{i}" for i in range(10))


def test_compute_gives_31_finite_values_equal_to_the_single_features():
    photo = textured_photo()
    values = image.compute(photo)
    assert tuple(values) == image.NAMES
    assert all(math.isfinite(v) and isinstance(v, float) for v in values.values())

    cropped = crop_image(photo)
    gray = grayscale(cropped)
    assert values["color"] == image.color(cropped)
    assert values["brightness"] == image.brightness(gray)
    assert (values["dft_80"], values["dft_85"]) == image.dft_peak_means(gray)
    assert values["tamura_contrast"] == image.tamura_contrast(gray)
    assert values["tamura_coarseness"] == image.tamura_coarseness(gray)
    assert [values[f"haralick_{i:02d}"] for i in range(1, 15)] == image.haralick(gray).tolist()
    assert [values[f"lbp_{i}"] for i in range(10)] == image.lbp_histogram(gray).tolist()
    assert sum(values[f"lbp_{i}"] for i in range(10)) == pytest.approx(1.0, abs=1e-12)


def test_bands_and_tiles_change_no_value(monkeypatch):
    # Default sizes process this small photo in one band and one tile; tiny ones split every step.
    photo = textured_photo(seed=1)
    expected = image.compute(photo)
    monkeypatch.setattr(image, "_BAND_ELEMENTS", 50)
    monkeypatch.setattr(image, "_BYTE_BAND_ELEMENTS", 70)
    monkeypatch.setattr(image, "_TAMURA_TILE", (3, 7))
    banded = image.compute(photo)
    # Only Tamura contrast sums per band, which regroups its moment sums.
    assert banded.pop("tamura_contrast") == pytest.approx(expected.pop("tamura_contrast"), rel=1e-14)
    assert banded == expected


def test_compute_crops_100_px_before_anything():
    photo = np.zeros((300, 320, 3), np.uint8)
    photo[100:200, 100:220] = (0, 255, 0)  # the cropped centre is pure green, the border black
    values = image.compute(photo)
    assert values["color"] == 125.0
    assert values["brightness"] == pytest.approx(0.587 * 255 / 255, rel=1e-12)
    assert values["edginess"] == 0.0


@pytest.mark.parametrize("value", [0, 97, 255])
def test_compute_on_a_constant_photo(value):
    values = image.compute(np.full((270, 281, 3), value, np.uint8))
    undefined = {"haralick_03", "haralick_12"}  # correlation and IMC1 are 0/0
    assert all(math.isnan(values[name]) for name in undefined)
    assert all(math.isfinite(v) for name, v in values.items() if name not in undefined)
    assert values["color"] == -1.0 and values["edginess"] == 0.0 and values["tamura_contrast"] == 0.0
    assert values["tamura_coarseness"] == 2.0 and values["lbp_8"] == 1.0
    assert values["dft_80"] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("photo", "message"), [
    (np.zeros((300, 300, 3), np.float64), "uint8"),
    (np.zeros((300, 300), np.uint8), r"shape \(h, w, 3\)"),
    (np.zeros((300, 300, 4), np.uint8), r"shape \(h, w, 3\)"),
    ([[1, 2, 3]], "uint8"),
    (np.zeros((200, 300, 3), np.uint8), "too small to crop"),
    (np.zeros((201, 300, 3), np.uint8), r"1x100 px is smaller than the 2x2 px any image feature needs"),
])
def test_compute_rejects_bad_photos(photo, message):
    with pytest.raises(ValueError, match=message):
        image.compute(photo)
    with pytest.raises(ValueError, match="1x300 px is smaller than the 2x2 px"):
        image.compute(np.zeros((1, 300, 3), np.uint8), border=0)






# --- colour, brightness, edginess ---------------------------------------------------------------------


def solid(rgb: tuple[int, int, int], h: int = 6, w: int = 7) -> np.ndarray:
    return np.full((h, w, 3), rgb, np.uint8)


@pytest.mark.parametrize(("rgb", "hue_bin_centre"), [
    ((0, 255, 0), 125.0),     # green: 120 degrees -> bin [120, 130)
    ((255, 0, 0), 5.0),       # red: 0 degrees
    ((0, 0, 255), 245.0),     # blue: 240 degrees
    ((255, 255, 0), 65.0),    # yellow: 60 degrees
    ((255, 204, 204), 5.0),   # S = 255 - 204 = 51, i.e. exactly 0.2: counts
    ((51, 0, 0), 5.0),        # V = 51 / 255 = 0.2: counts
    ((255, 205, 205), -1.0),  # S = 50 < 0.2 * 255
    ((50, 0, 0), -1.0),       # V = 50 < 0.2 * 255
    ((128, 128, 128), -1.0),  # gray: no saturation
])
def test_color_is_the_centre_of_the_dominant_hue_bin(rgb, hue_bin_centre):
    assert image.color(solid(rgb)) == hue_bin_centre


def test_color_takes_the_fullest_bin_and_the_first_on_ties():
    photo = solid((255, 0, 0), w=8)
    photo[:, 4:] = (0, 255, 0)
    assert image.color(photo) == 5.0  # 24 red, 24 green pixels: the lower bin wins
    photo[:, 3] = (0, 255, 0)
    assert image.color(photo) == 125.0


def test_brightness_is_the_mean_gray_over_255():
    assert image.brightness(np.full((5, 5), 255.0)) == 1.0
    assert image.brightness(np.array([[0.0, 255.0], [0.0, 255.0]])) == 0.5
    assert image.brightness(np.full((3, 4), 51.0)) == pytest.approx(0.2, rel=1e-15)


def test_edginess_of_a_step_edge_is_one_column():
    step = np.zeros((40, 50), np.uint8)
    step[:, 25:] = 255
    # Both columns beside the step have the same Sobel magnitude; non-maximum suppression keeps one.
    assert image.edginess(step) == pytest.approx(40 / (40 * 50), rel=1e-15)
    assert image.edginess(np.full((40, 50), 77, np.uint8)) == 0.0


def test_edginess_wants_an_8_bit_image():
    with pytest.raises(ValueError, match="uint8"):
        image.edginess(np.zeros((10, 10)))


# --- DFT peak means -----------------------------------------------------------------------------------


def test_dft_peak_means_of_cosine_gratings_are_their_half_amplitudes():
    m, n = 32, 64
    rows, cols = np.mgrid[0:m, 0:n]
    a1, a2 = 10.0, 8.2  # a2 / a1 = 0.82: above the 0.80 threshold, below 0.85
    gray = (100 + a1 * np.cos(2 * np.pi * 3 * cols / n)
            + a2 * np.cos(2 * np.pi * (2 * rows / m + 5 * cols / n))
            + 30 * np.sin(2 * np.pi * 7 * cols / n))  # a sine has no real part, however strong
    # A cosine of amplitude A puts A * M * N / 2 at (k, l) and (-k, -l); normalised by sqrt(M N).
    half = np.sqrt(m * n) / 2
    original = gray.copy()
    dft_80, dft_85 = image.dft_peak_means(gray)
    np.testing.assert_array_equal(gray, original)
    assert dft_80 == pytest.approx((a1 + a2) / 2 * half, rel=1e-9)
    assert dft_85 == pytest.approx(a1 * half, rel=1e-9)


@pytest.mark.parametrize("shape", [(2, 2), (2, 3), (3, 2), (5, 5), (6, 5), (5, 6), (6, 6), (31, 40),
                                   (40, 31)])
def test_dft_peak_means_follow_the_full_spectrum_definition(shape):
    gray = np.random.default_rng(sum(shape)).uniform(0, 255, shape)
    # Centred with the features' own mean: the DC term is zero up to the mean's rounding, and at the
    # fraction 0 its sign decides whether it is kept.
    spectrum = np.fft.fft2(gray - image._mean(gray)).real / np.sqrt(gray.size)
    fractions = (0.8, 0.85, 0.0, -10.0)  # the last one keeps every value: the mean of the whole spectrum
    expected = [spectrum[spectrum >= f * spectrum.max()].mean() for f in fractions]
    assert image.dft_peak_means(gray, fractions) == pytest.approx(expected, rel=1e-10)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (1, 8), (7, 1), (8, 1), (2, 2), (5, 6), (6, 5), (6, 6),
                                   (7, 7), (31, 40)])
def test_real_spectrum_of_an_impulse_is_a_cosine_at_every_frequency(shape):
    # A unit impulse at (p, q) has the spectrum exp(-2 pi i (k p / M + l q / N)): real part a cosine.
    m, n = shape
    p, q = (m - 1) // 2, n // 3
    impulse = np.zeros(shape)
    impulse[p, q] = 1.0
    spectrum = image.RealSpectrum(impulse)
    rows, cols = np.arange(-m, m), np.arange(-n, n)  # every frequency, negative ones too
    expected = np.cos(2 * np.pi * (rows[:, None] * p / m + cols[None, :] * q / n))
    np.testing.assert_allclose(spectrum.at(rows, cols), expected, rtol=0, atol=1e-12)
    # The parts hold every one of the M N values once, counting each by its multiplicity.
    values = np.concatenate([np.repeat(part.ravel(), weight) for part, weight in spectrum.parts])
    np.testing.assert_allclose(np.sort(values), np.sort(expected[m:, n:].ravel()), rtol=0, atol=1e-12)
    assert spectrum.peak == pytest.approx(1.0, abs=1e-12)


def test_real_spectrum_equals_numpy_fft2_on_random_images_of_every_parity():
    # The point-symmetric half transform against the whole complex DFT, value by value and as a multiset.
    rng = np.random.default_rng(11)
    shapes = [(m, n) for m in range(1, 12) for n in range(1, 12)] + [(64, 101), (101, 64), (128, 130)]
    for shape in shapes:
        gray = rng.uniform(0, 255, shape)
        expected = np.real(np.fft.fft2(gray))
        spectrum = image.RealSpectrum(gray)
        scale = np.abs(expected).max()
        rows, cols = np.arange(shape[0]), np.arange(shape[1])
        np.testing.assert_allclose(spectrum.at(rows, cols), expected, rtol=0, atol=1e-14 * scale)
        values = np.concatenate([np.repeat(part.ravel(), weight) for part, weight in spectrum.parts])
        np.testing.assert_allclose(np.sort(values), np.sort(expected.ravel()), rtol=0, atol=1e-14 * scale)


def test_real_spectrum_peak_sums_of_two_gratings_and_narrowed_selections():
    # Cosines of amplitude 10 and 8 put 10 M N / 2 and 8 M N / 2 at (0, +-3) and (+-2, +-5).
    m, n = 32, 64
    rows, cols = np.mgrid[0:m, 0:n]
    gray = 10 * np.cos(2 * np.pi * 3 * cols / n) + 8 * np.cos(2 * np.pi * (2 * rows / m + 5 * cols / n))
    half = m * n / 2
    spectrum = image.RealSpectrum(gray)
    assert spectrum.peak_sum(0.75) == pytest.approx((2 * 18 * half, 4), rel=1e-12)
    assert spectrum.peak_sum(0.85) == pytest.approx((2 * 10 * half, 2), rel=1e-12)
    assert spectrum.peak_sum(0.5) == pytest.approx((2 * 18 * half, 4), rel=1e-12)
    # Every value: the spectrum sums to M N gray[0, 0] (the inverse DFT at the origin), here M N 18.
    assert spectrum.peak_sum(-1e9) == pytest.approx((18 * m * n, m * n), rel=1e-12)
    # A selection narrowed from a lower fraction is the fresh one, bit for bit.
    fresh = image.RealSpectrum(gray)
    assert [spectrum.peak_sum(f) for f in (0.8, 0.85)] == [fresh.peak_sum(f) for f in (0.8, 0.85)]


@pytest.mark.parametrize("shape", [(1, 1), (1, 6), (2, 5), (5, 2), (6, 7), (7, 6), (33, 40)])
def test_real_spectrum_of_the_centred_image_is_the_spectrum_of_its_subtraction_bit_for_bit(shape):
    # The mean is subtracted in the pass that makes the point-symmetric part, in place or not.
    gray = np.random.default_rng(shape[0] * 100 + shape[1]).uniform(0, 255, shape)
    mean = float(np.mean(gray))
    expected = image.RealSpectrum(gray - mean).values
    np.testing.assert_array_equal(image.RealSpectrum(gray, mean=mean).values, expected)
    out = np.full(shape, np.nan)
    np.testing.assert_array_equal(image.RealSpectrum(gray, mean=mean, out=out).values, expected)
    in_place = gray.copy()
    np.testing.assert_array_equal(image.RealSpectrum(in_place, mean=mean, overwrite=True).values, expected)


def test_real_spectrum_in_place_and_rejects_bad_images():
    gray = np.random.default_rng(3).uniform(size=(9, 12))
    original = gray.copy()
    kept = image.RealSpectrum(original)
    np.testing.assert_array_equal(original, gray)  # a copy was used
    scratch = gray.copy()
    in_place = image.RealSpectrum(scratch, overwrite=True)
    assert in_place.memory is scratch and np.shares_memory(in_place.values, scratch)
    np.testing.assert_array_equal(in_place.values, kept.values)
    for bad in (np.zeros((0, 3)), np.zeros(5), np.zeros((4, 4), np.float32)):
        with pytest.raises(ValueError, match="2-D float64"):
            image.RealSpectrum(bad)


# --- the prepared photo shared between features -------------------------------------------------------


def test_prepared_photo_holds_what_the_public_functions_compute():
    rgb = textured_photo(seed=4)
    prepared = image.PreparedPhoto(rgb)
    gray = grayscale(crop_image(rgb))
    assert prepared.source is rgb
    np.testing.assert_array_equal(prepared.photo, crop_image(rgb))
    np.testing.assert_array_equal(prepared.gray, gray)
    np.testing.assert_array_equal(prepared.gray_u8, gray_uint8(gray))
    # The mean is summed in the order of every image feature's mean (image._mean), not numpy's.
    assert prepared.mean == image._mean(gray)
    assert prepared.extremes == (gray.min(), gray.max())
    assert prepared.contrast == image.tamura_contrast(gray)
    assert image._dft_peak_means(prepared.spectrum, image.DFT_FRACTIONS) == image.dft_peak_means(gray)


@pytest.mark.parametrize("keep_gray", [True, False])
def test_the_float32_gray_image_is_the_gray_image_rounded_and_survives_the_spectrum(keep_gray):
    rgb = textured_photo(seed=9)
    gray = grayscale(crop_image(rgb))
    prepared = image.PreparedPhoto(rgb, keep_gray=keep_gray)
    np.testing.assert_array_equal(prepared.gray32, gray.astype(np.float32))
    assert prepared.gray32.dtype == np.float32 and prepared.gray32.flags.c_contiguous
    assert image._dft_peak_means(prepared.spectrum, image.DFT_FRACTIONS) == image.dft_peak_means(gray)
    np.testing.assert_array_equal(prepared.gray32, gray.astype(np.float32))  # made again if overwritten


def test_a_photo_that_does_not_keep_its_gray_image_computes_the_spectrum_in_its_memory():
    rgb = textured_photo(seed=6)
    gray = grayscale(crop_image(rgb))
    private = image.PreparedPhoto(rgb, keep_gray=False)
    buffer = private.gray
    assert private.spectrum.memory is buffer
    assert image._dft_peak_means(private.spectrum, image.DFT_FRACTIONS) == image.dft_peak_means(gray)
    np.testing.assert_array_equal(private.gray, gray)  # asked again: computed again
    assert private.contrast == image.tamura_contrast(gray)


def test_a_released_buffer_holds_the_next_photos_gray_image():
    first, second = textured_photo(seed=7), textured_photo(seed=8)
    photo = image.PreparedPhoto(first)
    assert photo.release() is None  # nothing computed yet
    spectrum = photo.spectrum.memory
    buffer = photo.release()
    assert buffer is spectrum
    following = image.PreparedPhoto(second, buffer=buffer)
    assert following.gray is buffer
    np.testing.assert_array_equal(following.gray, grayscale(crop_image(second)))
    np.testing.assert_array_equal(photo.gray, grayscale(crop_image(first)))  # released: computed again
    assert image.compute(second, prepared=following) == image.compute(second)
    for unfit in (np.empty((3, 4)), np.empty(buffer.shape, np.float32), np.empty(buffer.shape[::-1]).T):
        assert image.PreparedPhoto(second, buffer=unfit).gray is not unfit


def test_compute_with_a_prepared_photo_gives_the_same_values():
    rgb = textured_photo(seed=5)
    alone = image.compute(rgb)
    prepared = image.PreparedPhoto(rgb)
    prepared.spectrum.peak_sum(0.75)  # as TacTUM's MaRG leaves it: a wider selection made first
    assert image.compute(rgb, prepared=prepared) == alone
    assert image.compute(rgb, prepared=prepared) == alone
    with pytest.raises(ValueError, match="different array"):
        image.compute(rgb.copy(), prepared=prepared)
    with pytest.raises(ValueError, match="too small to crop"):
        image.PreparedPhoto(np.zeros((200, 300, 3), np.uint8))


# --- Haralick -----------------------------------------------------------------------------------------


def test_quantize_uses_floor_of_gray_times_32_over_256():
    gray = np.array([[0.0, 7.999, 8.0, 127.9], [128.0, 247.99, 248.0, 255.0]])
    assert image.quantize(gray).tolist() == [[0, 0, 1, 15], [16, 30, 31, 31]]
    assert image.quantize(gray).dtype == np.uint8


def test_glcm_counts_pairs_both_ways_per_direction():
    q = np.array([[0, 0, 1], [2, 1, 1]])
    expected = {  # hand-enumerated pairs (reference, neighbour), each also counted reversed
        (0, 1): [[2, 1, 0], [1, 2, 1], [0, 1, 0]],    # (0,0) (0,1) (2,1) (1,1)
        (-1, 0): [[0, 1, 1], [1, 2, 0], [1, 0, 0]],   # (2,0) (1,0) (1,1)
        (-1, 1): [[0, 0, 1], [0, 2, 0], [1, 0, 0]],   # (2,0) (1,1)
        (-1, -1): [[0, 2, 0], [2, 0, 0], [0, 0, 0]],  # (1,0) (1,0)
    }
    for offset, counts in expected.items():
        counts = np.array(counts, float)
        np.testing.assert_array_equal(image.glcm(q, offset, levels=3), counts / counts.sum())


@pytest.mark.parametrize("shape", [(2, 2), (2, 5), (7, 3), (40, 53)])
def test_haralick_counts_every_direction_as_glcm_does(shape):
    q = np.random.default_rng(shape[0]).integers(0, 32, shape).astype(np.uint8)
    for offset, counts in zip(image.GLCM_OFFSETS, image._direction_counts(q, 32), strict=True):
        np.testing.assert_array_equal(image._symmetric_normalised(counts), image.glcm(q, offset))


def test_glcm_rejects_levels_out_of_range():
    with pytest.raises(ValueError, match="0..2"):
        image.glcm(np.array([[0, 3]]), (0, 1), levels=3)
    with pytest.raises(ValueError, match="no pixel pairs"):
        image.glcm(np.array([[0, 1]]), (-1, 0), levels=2)


@pytest.mark.parametrize("shape", [(2, 2), (2, 9), (7, 2), (41, 37), (300, 330)])
def test_the_prepared_photo_counts_the_pairs_of_every_direction_as_the_gray_image_gives_them(shape):
    # features.kernels.gray_images counts the level tuples row by row as it makes the gray image.
    rng = np.random.default_rng(shape[0] + shape[1])
    for photo in (rng.integers(0, 256, (*shape, 3)).astype(np.uint8), textured_photo(*shape, seed=3)
                  if min(shape) > 2 else np.full((*shape, 3), 77, np.uint8)):
        prepared = image.PreparedPhoto(photo, border=0)
        expected = image._direction_counts(image.quantize(grayscale(photo)), image.GLCM_LEVELS)
        for ours, theirs in zip(prepared.direction_counts, expected, strict=True):
            np.testing.assert_array_equal(ours, theirs)


def test_haralick_of_a_constant_image():
    f = image.haralick(np.full((20, 30), 100.0))  # level q = 12, 1-based 13
    assert f[0] == 1.0  # ASM
    assert f[1] == 0.0  # contrast
    assert math.isnan(f[2]) and math.isnan(f[11])  # correlation and IMC1 are 0/0
    assert f[3] == 0.0 and f[4] == 1.0
    assert f[5] == 26.0  # sum average: 13 + 13
    assert f[6] == 0.0 and f[7] == 0.0 and f[8] == 0.0 and f[9] == 0.0 and f[10] == 0.0
    assert f[12] == 0.0  # IMC2: HXY2 = HXY = 0
    assert f[13] == 0.0  # fewer than two occupied levels


def test_haralick_of_a_checkerboard():
    # 9 rows (odd), so the diagonal pairs split evenly into a-a and b-b.
    rows, cols = np.mgrid[0:9, 0:10]
    gray = np.where((rows + cols) % 2 == 0, 40.0, 120.0)  # levels q = 5 and 15, 1-based 6 and 16
    ia, ib = 6, 16
    d = ib - ia
    # 0 and 90 degrees: p(a,b) = p(b,a) = 1/2. 45 and 135 degrees: p(a,a) = p(b,b) = 1/2.
    # Averages of the two kinds of GLCM:
    expected = [
        0.5,                            # ASM: 1/2 in both
        d**2 / 2,                       # contrast: d^2 and 0
        0.0,                            # correlation: -1 and +1
        d**2 / 4,                       # variance of a fair two-level marginal
        (1 / (1 + d**2) + 1) / 2,       # IDM
        ia + ib,                        # sum average, 1-based
        d**2 / 2,                       # sum variance: 0 and d^2 (sums 2 ia and 2 ib, half each)
        LN2 / 2,                        # sum entropy: 0 and ln 2
        LN2,                            # entropy
        0.0,                            # difference variance: |i - j| is constant in both
        0.0,                            # difference entropy
        -1.0,                           # IMC1: (ln 2 - 2 ln 2) / ln 2
        math.sqrt(3) / 2,               # IMC2: sqrt(1 - exp(-2 (2 ln 2 - ln 2)))
        1.0,                            # maximal correlation: Q has eigenvalues 1, 1
    ]
    np.testing.assert_allclose(image.haralick(gray), expected, rtol=1e-12, atol=1e-12)


def two_level_glcm_features() -> list[float]:
    """The 14 features of P = [[1/2, 1/8], [1/8, 1/4]] on levels 1, 2, derived by hand."""
    hx = -(5 / 8 * math.log(5 / 8) + 3 / 8 * math.log(3 / 8))
    hxy = 7 / 4 * LN2  # -(1/2 ln 1/2 + 2 (1/8) ln 1/8 + 1/4 ln 1/4)
    hxy1 = -(1 / 2 * math.log(25 / 64) + 2 / 8 * math.log(15 / 64) + 1 / 4 * math.log(9 / 64))
    hxy2 = 2 * hx
    return [
        11 / 32,                                        # 1/4 + 2/64 + 1/16
        1 / 4,                                          # p_{x-y}(1) = 1/4
        7 / 15,                                         # cov 7/64 over variance 15/64
        15 / 64,                                        # (5/8)(3/8)
        7 / 8,                                          # 3/4 + (1/4) / 2
        11 / 4,                                         # p_{x+y} = 1/2, 1/4, 1/4 at k = 2, 3, 4
        11 / 16,                                        # (9/16)/2 + (1/16)/4 + (25/16)/4
        3 / 2 * LN2,
        hxy,
        3 / 16,                                         # variance of a 3/4 : 1/4 split of 0 and 1
        -(3 / 4 * math.log(3 / 4) + 1 / 4 * math.log(1 / 4)),
        (hxy - hxy1) / hx,
        math.sqrt(1 - math.exp(-2 * (hxy2 - hxy))),
        7 / 15,                                         # |ac - b^2| / (px1 px2) for a 2x2 GLCM
    ]


def test_haralick_from_a_hand_computed_two_level_glcm():
    p = np.array([[1 / 2, 1 / 8], [1 / 8, 1 / 4]])
    np.testing.assert_allclose(image.haralick_from_glcm(p), two_level_glcm_features(), rtol=1e-12)
    padded = np.zeros((32, 32))
    padded[:2, :2] = p  # unoccupied higher levels change nothing
    np.testing.assert_allclose(image.haralick_from_glcm(padded), two_level_glcm_features(), rtol=1e-12)


def test_haralick_from_glcm_rejects_non_distributions():
    with pytest.raises(ValueError, match="square"):
        image.haralick_from_glcm(np.ones((2, 3)) / 6)
    with pytest.raises(ValueError, match="sum to 1"):
        image.haralick_from_glcm(np.ones((2, 2)))


def test_haralick_agrees_with_mahotas_after_its_documented_differences():
    mahotas = pytest.importorskip("mahotas")
    rng = np.random.default_rng(3)
    gray = np.cumsum(rng.uniform(0, 1, (60, 70)), axis=1)
    gray = gray / gray.max() * 255
    # (4 directions, 13 features)
    theirs = mahotas.features.haralick(image.quantize(gray), use_x_minus_y_variance=True)
    theirs[:, 5] += 2  # 0-based levels in the sum average
    theirs[:, [7, 8, 10]] *= LN2  # log2 entropies
    info = -np.log(1 - theirs[:, 12] ** 2) / 2 * LN2  # HXY2 - HXY back in nats
    theirs[:, 12] = np.sqrt(1 - np.exp(-2 * info))
    np.testing.assert_allclose(image.haralick(gray)[:13], theirs.mean(axis=0), rtol=1e-10)


# --- Tamura -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(1, 5), (7, 1), (40, 33), (300, 301)])
def test_tamura_contrast_equals_the_moments_formula(shape):
    # The compiled pass sums per row; the rounding of either sum is a few hundred ulps at most.
    gray = np.random.default_rng(shape[0]).gamma(2.0, 30.0, shape)
    centred = gray - gray.mean()
    variance, fourth = np.mean(centred**2), np.mean(centred**4)
    expected = np.sqrt(variance) / (fourth / variance**2) ** 0.25
    assert image.tamura_contrast(gray) == pytest.approx(expected, rel=1e-13)


def test_tamura_contrast_of_two_level_images():
    half = np.array([[10.0, 30.0]] * 4)  # p = 1/2: sigma = 10, kurtosis 1
    assert image.tamura_contrast(half) == pytest.approx(10.0, rel=1e-14)
    quarter = np.array([[0.0, 0.0, 0.0, 8.0]] * 3)  # p = 1/4, d = 8
    sigma = math.sqrt(3 / 16) * 8
    kurtosis = (3 / 16) * (27 / 64 + 1 / 64) / (3 / 16) ** 2  # p q (q^3 + p^3) / (p q)^2 = 7/3
    assert image.tamura_contrast(quarter) == pytest.approx(sigma / kurtosis**0.25, rel=1e-14)


@pytest.mark.parametrize("value", [0.0, 0.1, 40.32, 77.7, 255.0])
def test_tamura_contrast_of_a_constant_image_is_zero(value):
    assert image.tamura_contrast(np.full((31, 47), value)) == 0.0


def stripes(width: int, h: int, w: int) -> np.ndarray:
    """Vertical 0/255 stripes ``width`` px wide with an edge at column 32 (the first one counted)."""
    cols = np.arange(w)
    return np.tile(np.where(((cols - 32) // width) % 2 == 0, 0.0, 255.0), (h, 1))


def test_tamura_coarseness_of_wide_stripes():
    # Stripes 64 px wide: a window pair straddles at most one edge. At distance t from it,
    # E_k = 255 (1 - |t|/2^k) for |t| < 2^k, else 0; so t = 0 ties at every k (S = 2), 1 <= |t| <= 31 picks
    # k = 5 (S = 32), and pixels farther away see no difference at all (S = 2). Per 64-column stripe:
    # 62 pixels of 32, 2 of 2.
    gray = stripes(64, 80, 2 * 64 + 63)
    assert image.tamura_coarseness(gray) == pytest.approx((62 * 32 + 2 * 2) / 64, rel=1e-15)
    assert image.tamura_coarseness(gray.T) == pytest.approx((62 * 32 + 2 * 2) / 64, rel=1e-15)


def test_tamura_coarseness_of_narrow_stripes_prefers_the_smaller_window_on_ties():
    # Stripes 8 px wide: windows of 16 and 32 px average whole periods (E = 0); E_8 = E_4 everywhere and
    # E_2 is smaller except on the edge. By position t in a stripe: S = 2, 4, 4, 4, 2, 4, 4, 4.
    gray = stripes(8, 70, 4 * 8 + 63)
    assert image.tamura_coarseness(gray) == pytest.approx(28 / 8, rel=1e-15)


def test_tamura_coarseness_counts_differences_below_1e9_of_the_maximum_as_ties():
    gray = stripes(8, 70, 4 * 8 + 63)
    noise = np.random.default_rng(11).uniform(-1, 1, gray.shape)
    # 1e-12 * 255 is far below the tolerance 1e-9 * 255: the ties between E_4 and E_8 survive.
    assert image.tamura_coarseness(gray + 1e-12 * noise) == pytest.approx(28 / 8, rel=1e-15)
    # 1e-4 breaks them at random, half of them in favour of the larger window.
    assert image.tamura_coarseness(gray + 1e-4 * noise) > 28 / 8 + 0.5


def test_tamura_coarseness_of_a_constant_image_is_the_smallest_window():
    assert image.tamura_coarseness(np.full((64, 64), 93.3)) == 2.0
    assert image.tamura_coarseness(np.zeros((70, 80))) == 2.0


def tamura_coarseness_by_definition(gray: np.ndarray, kmax: int = 5) -> float:
    """docs/features.md#image read literally: explicit window means per pixel."""
    h, w = gray.shape
    margin, tolerance = 2**kmax, 1e-9 * gray.max()
    best = []
    for r in range(margin, h - margin + 1):
        for c in range(margin, w - margin + 1):
            e = []
            for k in range(1, kmax + 1):
                s, half = 2**k, 2 ** (k - 1)
                horizontal = gray[r - half:r + half, c:c + s].mean() - gray[r - half:r + half, c - s:c].mean()
                vertical = gray[r:r + s, c - half:c + half].mean() - gray[r - s:r, c - half:c + half].mean()
                e.append(max(abs(horizontal), abs(vertical)))
            e = np.array(e)
            best.append(2 ** (1 + int(np.argmax(e >= e.max() - tolerance))))
    return float(np.mean(best))


@pytest.mark.parametrize("tile", [None, (5, 9)])
@pytest.mark.parametrize("kind", ["noise", "levels", "blocks"])
def test_tamura_coarseness_follows_the_definition_pixel_by_pixel(kind, tile, monkeypatch):
    if tile:
        monkeypatch.setattr(image, "_TAMURA_TILE", tile)
    rng = np.random.default_rng(5)
    shape = (75, 90)
    if kind == "noise":
        gray = rng.uniform(0, 255, shape)
    elif kind == "levels":
        gray = rng.integers(0, 3, shape) * 100.0
    else:
        gray = np.kron(rng.integers(0, 2, (19, 23)), np.ones((4, 4)))[:75, :90] * 255.0
    assert image.tamura_coarseness(gray) == tamura_coarseness_by_definition(gray)


@pytest.mark.parametrize("kind", ["texture", "flat_blocks", "one_level_steps"])
def test_compute_gives_the_float64_tamura_coarseness(kind):
    rng = np.random.default_rng(7)
    if kind == "texture":
        photo = textured_photo(seed=7)
    elif kind == "flat_blocks":  # exact ties everywhere inside the blocks
        photo = np.kron(rng.integers(0, 256, (8, 9, 3)), np.ones((40, 40, 1)))[:300, :330].astype(np.uint8)
    else:  # neighbouring windows differ by the smallest steps an 8-bit photo allows
        photo = (100 + np.cumsum(rng.integers(0, 2, (300, 330, 3)), axis=1) // 40).astype(np.uint8)
    gray = grayscale(crop_image(photo))
    assert image.compute(photo)["tamura_coarseness"] == image.tamura_coarseness(gray)


@pytest.mark.parametrize("shape", [(64, 64), (65, 200), (200, 65), (301, 257)])
def test_the_compiled_tamura_coarseness_of_a_photo_is_the_float64_one(shape):
    # The kernel streams a ring of 64 rows of window sums: images of exactly the largest windows, of
    # a few rows more, and of several turns of the ring, each against the float64 definition path.
    rng = np.random.default_rng(shape[0] * shape[1])
    for photo in (rng.integers(0, 256, (*shape, 3)).astype(np.uint8),
                  np.kron(rng.integers(0, 256, (shape[0] // 8 + 1, shape[1] // 8 + 1, 3)),
                          np.ones((8, 8, 1)))[:shape[0], :shape[1]].astype(np.uint8)):
        gray = grayscale(photo)
        assert image._tamura_coarseness_of_photo(gray, float(gray.max())) == image.tamura_coarseness(gray)


def test_the_compiled_tamura_coarseness_holds_at_the_largest_window_differences():
    # Black and white 32 px blocks: window sums and their differences reach 4^5 * 255000, the most the
    # kernel's int32 arithmetic must hold (2^31 / 8); a wrap-around would change the chosen windows.
    rng = np.random.default_rng(8)
    for block in (32, 16, 1):
        levels = rng.integers(0, 2, (300 // block + 1, 330 // block + 1, 1)) * 255
        photo = np.kron(levels, np.ones((block, block, 3)))[:300, :330].astype(np.uint8)
        gray = grayscale(photo)
        assert image._tamura_coarseness_of_photo(gray, float(gray.max())) == image.tamura_coarseness(gray)


def test_tamura_coarseness_needs_room_for_the_largest_window():
    with pytest.raises(ValueError, match="smaller than the 64x64 px"):
        image.tamura_coarseness(np.zeros((63, 100)))
    assert image.tamura_coarseness(np.zeros((8, 8)), kmax=2) == 2.0


# --- LBP ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", [0.0, 0.1, 40.32, 128.0, 255.0])
def test_lbp_of_a_constant_image_is_all_in_bin_8(value):
    # Every neighbour equals the centre, so every bit is 1: a uniform code with eight ones.
    expected = np.zeros(10)
    expected[8] = 1.0
    np.testing.assert_array_equal(image.lbp_histogram(np.full((12, 15), value)), expected)


@pytest.mark.parametrize("transpose", [False, True])
def test_lbp_of_a_ramp_is_all_in_bin_5(transpose):
    # Along a ramp the three neighbours behind the centre are lower and the other five are >= it:
    # one run of five ones, a uniform code labelled 5.
    ramp = np.tile(np.arange(20.0), (16, 1))
    expected = np.zeros(10)
    expected[5] = 1.0
    np.testing.assert_array_equal(image.lbp_histogram(ramp.T if transpose else ramp), expected)


def test_lbp_of_a_single_bright_pixel():
    # 5x5 zeros with one bright pixel in the middle: the 3x3 interior has the peak (no neighbour >= it,
    # label 0) and eight pixels that see it among otherwise equal neighbours (all ones, label 8).
    gray = np.zeros((5, 5))
    gray[2, 2] = 100.0
    expected = np.zeros(10)
    expected[0], expected[8] = 1 / 9, 8 / 9
    np.testing.assert_allclose(image.lbp_histogram(gray), expected, rtol=1e-15)


@pytest.mark.parametrize("shape", [(3, 3), (6, 9), (41, 37)])
@pytest.mark.parametrize("kind", ["noise", "few_levels", "smooth"])
def test_lbp_matches_scikit_image_exactly(shape, kind):
    rng = np.random.default_rng(shape[0] * shape[1])
    if kind == "noise":
        gray = rng.uniform(0, 255, shape)
    elif kind == "few_levels":  # many exact ties between neighbours
        gray = rng.integers(0, 3, shape) * 40.32
    else:
        gray = np.cumsum(np.cumsum(rng.uniform(0, 1, shape), axis=0), axis=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # skimage warns about float images; the definition asks for float64
        codes = local_binary_pattern(gray, 8, 1, method="uniform")[1:-1, 1:-1]
    expected = np.bincount(codes.astype(int).ravel(), minlength=10) / codes.size
    np.testing.assert_array_equal(image.lbp_histogram(gray), expected)


def test_lbp_matches_scikit_image_across_powers_of_two():
    # Rows and columns 512 and 513 are where skimage's interpolation weights change binade.
    gray = np.random.default_rng(13).uniform(0, 255, (530, 520))
    gray[100:140] = 77.7  # a flat stretch: exact ties
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        codes = local_binary_pattern(gray, 8, 1, method="uniform")[1:-1, 1:-1]
    expected = np.bincount(codes.astype(int).ravel(), minlength=10) / codes.size
    np.testing.assert_array_equal(image.lbp_histogram(gray), expected)


# --- gray input checks --------------------------------------------------------------------------------


@pytest.mark.parametrize("function", [image.brightness, image.dft_peak_means, image.haralick,
                                      image.tamura_coarseness, image.lbp_histogram])
def test_gray_features_reject_bad_images(function):
    with pytest.raises(ValueError, match="2-D gray image"):
        function(np.zeros((70, 70, 3)))
    nan_image = np.zeros((70, 70))
    nan_image[3, 4] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        function(nan_image)


def test_the_prepared_gray_images_of_every_rgb_colour():
    # The prepared photo makes its gray images in one compiled pass: gray + 0.5 truncated instead of
    # floored and clipped, and Tamura coarseness on rint(1000 gray) as integers. All three must equal the
    # straightforward formulas for every one of the 2^24 colours (their gray values lie in 0 .. 255 plus
    # rounding), and the thousandths must be exactly 299 R + 587 G + 114 B.
    red, green = np.meshgrid(np.arange(256), np.arange(256), indexing="ij")
    for blue in range(256):
        rgb = np.stack([red, green, np.full_like(red, blue)], axis=-1).astype(np.uint8)
        photo = image.PreparedPhoto(rgb, border=0)
        gray = grayscale(rgb)
        np.testing.assert_array_equal(photo.gray, gray)
        np.testing.assert_array_equal(photo.gray_u8, gray_uint8(gray))
        assert photo.extremes == (gray.min(), gray.max())
        np.testing.assert_array_equal(np.rint(1000 * photo.gray), 299 * red + 587 * green + 114 * blue)
