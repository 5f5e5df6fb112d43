"""The 15 TacTUM features (Strese et al. 2020, section IV-A; docs/features.md#tactum).

Each feature is a pure function of arrays, named as in the paper; :func:`compute` gathers the inputs of one
:class:`scanner.Scan` (preprocessed as in docs/features.md#preprocessing) and returns the 15 values in :data:`NAMES`
order. A value that is undefined (0/0, x/0, a missing channel, a stored slide that fails its quality check) is
NaN, never 0 or inf, except where docs/features.md#tactum says 0 (the compliance features of a rigid sample).

Notation: ``v`` is the tool-slide signal (``v_ts`` band-limited, 1 s window, DFT321), ``va = |v|``,
``mean`` and ``std`` are population statistics, ``MA100`` is MATLAB's ``movmean(x, 100)``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numba
import numpy as np
import pywt

from features import kernels
from features.image import PreparedPhoto, RealSpectrum, spans, tamura_contrast
from features.prepared import PreparedScan
from scanner.preprocess import (
    QualityError,
    remove_friction_offset,
)
from scanner.scan import JUDGED_SCALE, Scan

NAMES = (
    "tactum.matx", "tactum.maco", "tactum.marg", "tactum.miro", "tactum.mico",
    "tactum.fst", "tactum.frs", "tactum.atk", "tactum.ccp", "tactum.cdf",
    "tactum.cdp", "tactum.crx", "tactum.cyd", "tactum.tco", "tactum.tpr",
)
"""The TacTUM feature names, in feature-space order (docs/features.md#tactum)."""

MATX_WEIGHTS = (3.0, 2.0, 4.0)
"""Weights of VS, FV and RV in MaTX (paper eq. 7, from the paper's feature optimisation)."""

MOVING_MEAN = 100
"""Window of the moving mean in MaTX (paper eq. 2, 5, 6)."""

DOH_SCALES = 1.2 * 2.0 ** (np.arange(16) / 4.0)
"""Scale ladder of the determinant-of-Hessian detector in MaCo: 1.2 * 2^(k/4), k = 0..15 (docs/features.md#tactum)."""

TOP_SCALES = 10
"""Number of largest corner scales averaged in MaCo (paper eq. 8, n = 10)."""

PEAK_FRACTION = 0.75
"""Spectrum peaks kept in MaRG: at least this fraction of the maximum (paper eq. 10, a = 0.75)."""

GAUSS_SIGMA = 25.0
"""Standard deviation, in frequency bins, of the inverted Gaussian in MaRG (paper eq. 11)."""

GAUSS_HALF = 100
"""The inverted Gaussian covers offsets -100..99 around the spectrum centre (a 200 x 200 window)."""

WAVELET = "db8"
"""Wavelet of MiRO (paper section IV-A2)."""

SLOPE_LAG = 30
"""Samples between the two ends of a force slope: 10 ms at 3000 Hz (paper section IV-A3)."""

FORCE_RISE = 0.05
"""A force "has risen" above this fraction of its maximum (FRS segment end, CDP damping start)."""

INDENTATION_MM = 4.0
"""Indentation fixed by the TU2 casing when pressing (paper eq. 19, Delta x)."""

RIGID_STD_DEG = 1.0
"""A sample is rigid if the flex angle while folding varies by less than this (paper section IV-A4)."""

PEAK_SECONDS = 5.0
"""TPR looks for the heating peak in the first 5 s of ``t_cool`` (docs/features.md#tactum, item 15)."""


class MissingDataWarning(UserWarning):
    """A scan lacks an input (or a stored slide fails its check), so the features needing it are NaN."""


def _ratio(numerator: float, denominator: float) -> float:
    """``numerator / denominator``, NaN where that is 0/0 or x/0."""
    return math.nan if denominator == 0 else float(numerator / denominator)


def _samples(x: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(x, dtype=np.float64)
    if array.ndim != 1 or array.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D array, got shape {array.shape}")
    return array


# --- 1. MaTX -------------------------------------------------------------------------------------------

def movmean(x: np.ndarray, window: int = MOVING_MEAN) -> np.ndarray:
    """Centred moving mean that shrinks at the ends, MATLAB ``movmean(x, window)``.

    Sample i averages ``x[i - window//2 .. i + window - window//2 - 1]`` clipped to the signal, so for the
    even window 100 of the paper (``MA100``, eq. 2) that is samples [i-50, i+49].

    Examples
    --------
    >>> movmean(np.array([1.0, 2.0, 3.0, 4.0]), 2)
    array([1. , 1.5, 2.5, 3.5])
    """
    values = _samples(x, "x")
    if window < 1:
        raise ValueError(f"moving-mean window must be at least 1 sample, got {window}")
    before = window // 2
    after = window - before - 1
    n = values.size
    # Full convolution index j sums x[j - window + 1 .. j]; the window of sample i ends at i + after.
    sums = np.convolve(values, np.ones(window))[after:after + n]
    index = np.arange(n)
    counts = np.minimum(index + after, n - 1) - np.maximum(index - before, 0) + 1
    return sums / counts


def vs(va: np.ndarray) -> float:
    """Vibrotactile spikiness, paper eq. 2-4: ``log10(1 + mean(va_D))``.

    ``va_th = std(va) + mean(va) + MA100(va)`` (eq. 2), ``va_D = va * (va > va_th)`` (eq. 3).
    Interpretation (docs/features.md#tactum): the bar over ``va_D`` in eq. 4 that did not survive is a mean.

    Parameters
    ----------
    va : array of shape (n,)
        Absolute slide vibration ``|v|`` in g.
    """
    va = _samples(va, "va")
    threshold = np.std(va) + np.mean(va) + movmean(va)
    return float(np.log10(1.0 + np.mean(va * (va > threshold))))


def fv(f_frt: np.ndarray) -> float:
    """Friction variation, paper eq. 5: ``std(f_frt - MA100(f_frt))`` over the whole friction slide (N)."""
    f_frt = _samples(f_frt, "f_frt")
    return float(np.std(f_frt - movmean(f_frt)))


def rv(r_window: np.ndarray) -> float:
    """Reflectance variation, paper eq. 6: ``std(r_w - MA100(r_w))`` over the 1 s slide window of r_ts (V)."""
    r_window = _samples(r_window, "r_window")
    return float(np.std(r_window - movmean(r_window)))


def matx(v: np.ndarray, f_frt: np.ndarray, r_window: np.ndarray) -> float:
    """Macrotexture, paper eq. 7: ``3 VS + 2 FV + 4 RV`` (weights from the paper's optimisation)."""
    w_vs, w_fv, w_rv = MATX_WEIGHTS
    return w_vs * vs(np.abs(_samples(v, "v"))) + w_fv * fv(f_frt) + w_rv * rv(r_window)


# --- 2. MaCo -------------------------------------------------------------------------------------------

HARRIS = {"maxCorners": 100, "qualityLevel": 0.01, "minDistance": 10, "blockSize": 3, "k": 0.04}
"""``cv2.goodFeaturesToTrack`` parameters of MaCo's Harris corners (docs/features.md#tactum)."""

_HARRIS_APERTURE = 3
"""Sobel aperture ``goodFeaturesToTrack`` gives ``cornerHarris`` (its ``gradientSize`` default)."""


def harris_corners(gray: np.ndarray) -> np.ndarray:
    """Up to 100 Harris corners of a gray image as integer (row, column) pixels (paper section IV-A1b).

    ``cv2.goodFeaturesToTrack(gray.astype(float32), maxCorners=100, qualityLevel=0.01, minDistance=10,
    blockSize=3, useHarrisDetector=True, k=0.04)``, rounded to the nearest pixel (docs/features.md#tactum); the corners
    are the same, in the same order, from :func:`_harris_corners`.
    """
    return _harris_corners(np.asarray(gray, dtype=np.float32))


def _harris_corners(gray32: np.ndarray) -> np.ndarray:
    """``goodFeaturesToTrack``'s corners, its steps run one by one: a 12-megapixel photo has ~10^6 local
    maxima, and OpenCV finds and sorts them all (two thirds of its time) where the 100 corners need only
    the strongest few thousand. The response is ``cornerHarris``'s bit for bit (:func:`harris_response`),
    its threshold and the 3 x 3 maxima are OpenCV's own functions, so every value and decision is the same.
    """
    response = harris_response(gray32)
    threshold = cv2.minMaxLoc(response)[1] * HARRIS["qualityLevel"]
    if response.size >= _HARRIS_CUT_MIN_PIXELS:
        corners = _corners_above(response, threshold, _strong_cut(response))
        if corners is not None:
            return corners
    cv2.threshold(response, threshold, 0, cv2.THRESH_TOZERO, dst=response)
    # A candidate is a non-zero interior value equal to the largest of its 3 x 3 neighbourhood.
    is_max = cv2.compare(response, cv2.dilate(response, None), cv2.CMP_EQ)
    cv2.bitwise_and(is_max, cv2.compare(response, 0, cv2.CMP_NE), dst=is_max)
    is_max[[0, -1], :] = 0
    is_max[:, [0, -1]] = 0
    index = np.flatnonzero(is_max)
    return _spaced_strongest(index, response.ravel()[index], response.shape[1])[0]


def harris_response(gray32: np.ndarray) -> np.ndarray:
    """``cv2.cornerHarris(gray32, 3, 3, 0.04)``, bit for bit, with half its memory in about 55 % of its time.

    ``cornerHarris`` makes the Sobel derivatives ``Dx``, ``Dy`` of the whole image (scale 1/12), the three
    products ``Dx^2, Dx Dy, Dy^2`` as one 3-channel image, their unnormalised 3 x 3 box sums, and
    ``R = (a c - b^2) - k (a + c)^2``: five image-sized float32 temporaries (260 MB for a cropped
    12-megapixel photo), in memory it faults in afresh each time. The same steps run here with OpenCV's
    own Sobel and box filter, so every value is the same:

    - the derivatives in bands of :data:`_HARRIS_BAND_ROWS` rows, each read with one more row either
      side (a 3 x 3 Sobel is local), multiplied into the three product planes at once;
    - each plane's box sums by ``cv2.boxFilter`` over the whole plane, in place: the box filter keeps
      running column sums from the top of the image, so it must see the whole plane, and one channel of
      a 3-channel box filter is the box filter of that channel;
    - ``R`` by :func:`_harris_of_box_sums`, into the first plane (see there for ``calcHarris``'s three
      roundings).

    Where that does not reproduce ``cornerHarris`` on this machine (:func:`_harris_loops`), it is called.
    """
    image = np.ascontiguousarray(gray32, dtype=np.float32)
    loops = _harris_loops()
    if loops is None:
        return cv2.cornerHarris(image, HARRIS["blockSize"], _HARRIS_APERTURE, HARRIS["k"])
    return _harris_response(image, loops)


_HARRIS_BAND_ROWS = 64
"""Rows of the Sobel derivatives made at a time: their bands (2 x 64 rows of a 2824 px wide photo, 1.4 MB)
stay in cache while they are multiplied."""

_HARRIS_SCALE = 1.0 / ((1 << (_HARRIS_APERTURE - 1)) * HARRIS["blockSize"])
"""``cornerHarris``'s derivative scale for float images, 1 / (2^(ksize - 1) blockSize) = 1/12."""


def _harris_response(image: np.ndarray, loops: tuple[int, int]) -> np.ndarray:
    """:func:`harris_response` of a C-contiguous float32 image for a ``calcHarris`` whose two vector loops
    take ``loops`` pixels at a time."""
    h, w = image.shape
    planes = np.empty((3, h, w), np.float32)  # numpy's memory: large blocks are faulted in as huge pages
    for start, stop in spans(h, _HARRIS_BAND_ROWS):
        above, below = max(start - 1, 0), min(stop + 1, h)
        band = image[above:below]
        inner = slice(start - above, start - above + stop - start)
        dx = cv2.Sobel(band, cv2.CV_32F, 1, 0, ksize=_HARRIS_APERTURE, scale=_HARRIS_SCALE)[inner]
        dy = cv2.Sobel(band, cv2.CV_32F, 0, 1, ksize=_HARRIS_APERTURE, scale=_HARRIS_SCALE)[inner]
        _gradient_products(dx, dy, planes[:, start:stop])
    size = (HARRIS["blockSize"], HARRIS["blockSize"])
    for plane in planes:
        cv2.boxFilter(plane, -1, size, dst=plane, normalize=False)
    wide_end, narrow_end = _loop_ends(h * w, loops)
    _harris_of_box_sums(planes, np.float32(HARRIS["k"]), HARRIS["k"], wide_end, narrow_end)
    return planes[0]


def _loop_ends(n_pixels: int, loops: tuple[int, int]) -> tuple[int, int]:
    """Where ``calcHarris``'s wide and narrow vector loops end on ``n_pixels`` (0 lanes: no such loop)."""
    wide, narrow = loops
    wide_end = n_pixels - n_pixels % wide if wide else 0
    narrow_end = wide_end + (n_pixels - wide_end) // narrow * narrow if narrow else wide_end
    return wide_end, narrow_end


@numba.njit(**kernels.JIT)
def _gradient_products(dx: np.ndarray, dy: np.ndarray, planes: np.ndarray) -> None:
    """``planes[0..2] = Dx^2, Dx Dy, Dy^2`` (float32 products, as ``cornerHarris`` makes them)."""
    for i in range(dx.shape[0]):
        for j in range(dx.shape[1]):
            x, y = dx[i, j], dy[i, j]
            planes[0, i, j] = x * x
            planes[1, i, j] = x * y
            planes[2, i, j] = y * y


@numba.njit(**kernels.JIT)
def _harris_of_box_sums(planes: np.ndarray, k32: np.float32, k: float, wide_end: int, narrow_end: int) -> None:
    """``R = (a c - b^2) - k (a + c)^2`` from the box sums ``a, b, c = planes[0..2]``, into ``planes[0]``.

    OpenCV's ``calcHarris`` reads the image as one long row and rounds differently in its three loops
    (t = a + c in float32):

    - pixels before ``wide_end`` (its AVX loop, 8 at a time): ``(a c - b b) - k32 (t t)``, float32;
    - then up to ``narrow_end`` (its 128-bit loop, 4 at a time): ``(a c - b b) - (k32 t) t``, float32;
    - the rest (its scalar loop, whose k is a double): ``float(double(a c - b b) - (k t) t)``.
    """
    flat = planes.reshape(3, -1)
    a, b, c = flat[0], flat[1], flat[2]
    for i in range(wide_end):
        t = a[i] + c[i]
        a[i] = (a[i] * c[i] - b[i] * b[i]) - k32 * (t * t)
    for i in range(wide_end, narrow_end):
        t = a[i] + c[i]
        a[i] = (a[i] * c[i] - b[i] * b[i]) - (k32 * t) * t
    for i in range(narrow_end, a.shape[0]):
        t = a[i] + c[i]
        a[i] = np.float32(np.float64(a[i] * c[i] - b[i] * b[i]) - k * np.float64(t) * np.float64(t))


_HARRIS_LOOPS = ((8, 4), (0, 4), (8, 0), (0, 0))
"""Lanes of ``calcHarris``'s wide (AVX) and narrow (128-bit) vector loops in the builds OpenCV makes: both
on x86-64 with AVX, the narrow one alone on other SIMD machines, none without SIMD."""


def _harris_probes() -> list[np.ndarray]:
    """The fixed probes :func:`_harris_loops` tells the loop layouts apart on: twelve random float32 images
    of 31 x 33 px, four each of values up to 1, 255 and 1e4."""
    rng = np.random.default_rng(20201)
    return [(rng.random((31, 33)) * scale).astype(np.float32) for scale in (1.0, 255.0, 1e4) for _ in range(4)]


@lru_cache(maxsize=1)
def _harris_loops() -> tuple[int, int] | None:
    """The vector loops of this OpenCV's ``calcHarris`` (see :func:`_harris_of_box_sums`), or None if
    :func:`_harris_response` reproduces ``cornerHarris`` for none or for several of :data:`_HARRIS_LOOPS`:
    then ``cornerHarris`` itself is called.

    Found once per process on fixed random probes of 31 x 33 px: their 1023 pixels end in 7 that fill no
    AVX vector, of which 3 fill no 128-bit one; values of three magnitudes, four probes each, so that the
    three formulas differ on some pixel of every part.
    """
    probes = _harris_probes()
    expected = [cv2.cornerHarris(probe, HARRIS["blockSize"], _HARRIS_APERTURE, HARRIS["k"]) for probe in probes]
    matching = [loops for loops in _HARRIS_LOOPS
                if all(np.array_equal(_harris_response(probe, loops), values)
                       for probe, values in zip(probes, expected, strict=True))]
    return matching[0] if len(matching) == 1 else None


_HARRIS_CUT_MIN_PIXELS = 1 << 20
"""Images from this size on look for their corners among the strongest responses first."""

_HARRIS_CUT_SHARE = 1 / 512
"""Share of the responses above the first cut: ~20,000 of a 12-megapixel photo."""


def _strong_cut(response: np.ndarray, step: int = 16) -> float:
    """A response value about :data:`_HARRIS_CUT_SHARE` of the pixels reach, from every 16th row and column."""
    sample = response[::step, ::step].ravel()
    keep = max(1, int(sample.size * _HARRIS_CUT_SHARE))
    return float(np.partition(sample, sample.size - keep)[sample.size - keep])


def _corners_above(response: np.ndarray, threshold: float, cut: float) -> np.ndarray | None:
    """The corners, found among the candidates whose response reaches ``cut``; None if those do not decide
    them (fewer than ``maxCorners`` kept while weaker candidates exist), so that all must be looked at.

    Each pixel reaching the cut is tested as ``goodFeaturesToTrack`` tests it: its 3 x 3 neighbourhood,
    thresholded by ``cv2.threshold`` with the same arguments, has its value as the largest.
    """
    h, w = response.shape
    strong = cv2.compare(response, cut, cv2.CMP_GE)
    strong[[0, -1], :] = 0
    strong[:, [0, -1]] = 0
    points = cv2.findNonZero(strong)
    if points is None:
        return None if cut > threshold else np.empty((0, 2), dtype=np.intp)
    cols, rows = points.reshape(-1, 2).astype(np.intp).T
    offsets = np.arange(-1, 2)
    around = response[(rows[:, None] + offsets)[:, :, None], (cols[:, None] + offsets)[:, None, :]].reshape(-1, 9)
    kept = cv2.threshold(around, threshold, 0, cv2.THRESH_TOZERO)[1]
    centre = kept[:, 4]
    is_max = (centre != 0) & (centre == kept.max(axis=1))
    corners, complete = _spaced_strongest(rows[is_max] * w + cols[is_max], centre[is_max], w)
    return corners if complete or cut <= threshold else None


def _strongest_first(index: np.ndarray, value: np.ndarray, batch: int = 4096) -> Iterator[np.ndarray]:
    """``index`` in OpenCV's order (largest value first, ties by larger index), one batch at a time.

    Each batch holds every candidate at least as strong as its weakest, so the order across batches is
    the order of one full sort.
    """
    while index.size:
        if index.size > batch:
            cut = np.partition(value, index.size - batch)[index.size - batch]
            top = value >= cut
        else:
            top = np.ones(index.size, bool)
        chosen, chosen_value = index[top], value[top]
        yield chosen[np.lexsort((-chosen, -chosen_value))]
        index, value = index[~top], value[~top]
        batch *= 4


def _spaced_strongest(index: np.ndarray, value: np.ndarray, width: int) -> tuple[np.ndarray, bool]:
    """The strongest candidates, each at least ``minDistance`` px (Euclidean) from every stronger one kept,
    until ``maxCorners``: ``goodFeaturesToTrack``'s greedy pass (its grid only speeds up the same test).
    Also whether ``maxCorners`` were reached."""
    limit, reach2 = HARRIS["maxCorners"], HARRIS["minDistance"] ** 2
    kept = np.empty((limit, 2), dtype=np.intp)
    n = 0
    for ordered in _strongest_first(index, value):
        rows, cols = np.divmod(ordered, width)
        n = _keep_spaced(rows, cols, kept, n, reach2)
        if n == limit:
            return kept, True
    return kept[:n], False


@numba.njit(**kernels.JIT)
def _keep_spaced(rows: np.ndarray, cols: np.ndarray, kept: np.ndarray, n: int, reach2: int) -> int:
    """The greedy pass of :func:`_spaced_strongest` over one batch of ordered candidates: each is kept if its
    squared distance to every corner kept so far is at least ``reach2`` (integers, so exact), until ``kept``
    is full. Returns the number kept."""
    for candidate in range(rows.shape[0]):
        if n == kept.shape[0]:
            break
        row, col = rows[candidate], cols[candidate]
        spaced = True
        for other in range(n):
            dr, dc = kept[other, 0] - row, kept[other, 1] - col
            if dr * dr + dc * dc < reach2:
                spaced = False
                break
        if spaced:
            kept[n, 0], kept[n, 1] = row, col
            n += 1
    return n


def _radius(sigma: float, truncate: float = 4.0) -> int:
    """Kernel half-width of ``scipy.ndimage.gaussian_filter`` for ``sigma`` and ``truncate``."""
    return int(truncate * sigma + 0.5)


def gaussian_weights(sigma: float, order: int, truncate: float = 4.0) -> np.ndarray:
    """Correlation weights of ``scipy.ndimage.gaussian_filter1d(x, sigma, order=order, truncate=truncate)``.

    The sampled Gaussian ``phi(x) = exp(-x^2 / (2 sigma^2))`` on x = -r..r, r = int(truncate sigma + 0.5),
    normalised to sum 1, times its derivative polynomial (1, -x / sigma^2 or (x^2 - sigma^2) / sigma^4),
    reversed because scipy correlates with it.
    """
    if order not in (0, 1, 2):
        raise ValueError(f"Gaussian derivative order must be 0, 1 or 2, got {order}")
    x = np.arange(-_radius(sigma, truncate), _radius(sigma, truncate) + 1, dtype=np.float64)
    sigma2 = sigma * sigma
    phi = np.exp(-0.5 / sigma2 * x**2)
    phi /= phi.sum()
    polynomial = (np.ones_like(x), -x / sigma2, (x**2 - sigma2) / sigma2**2)[order]
    return (polynomial * phi)[::-1]


@numba.njit(**kernels.JIT)
def _reflect(index: int, n: int) -> int:
    """Index into a length-n axis under scipy.ndimage's "reflect" mode (d c b a | a b c d | d c b a)."""
    if 0 <= index < n:
        return index  # no division for the indices inside
    folded = index % (2 * n)
    return 2 * n - 1 - folded if folded >= n else folded


@lru_cache(maxsize=8)
def _folded_weights(sigmas: tuple[float, ...]) -> np.ndarray:
    """The weights of :func:`gaussian_weights` of orders 0, 1, 2 for each sigma at the offsets 0..R from the
    centre (R the largest radius, 0 past a sigma's own), shape ``(3, len(sigmas), R + 1)``, read-only.

    The weights are symmetric (orders 0, 2) or antisymmetric (order 1) about the centre, exactly: a
    weighted sum over a neighbourhood is the sum of these half weights over its folded quarter
    (:func:`_doh_at`). The centre weights of orders 0 and 2 are halved (exactly), since the fold counts
    the centre row and column twice.
    """
    largest = max(_radius(sigma) for sigma in sigmas)
    weights = np.zeros((3, len(sigmas), largest + 1))
    for k, sigma in enumerate(sigmas):
        radius = _radius(sigma)
        for order in (0, 1, 2):
            weights[order, k, :radius + 1] = gaussian_weights(sigma, order)[radius:]
    weights[[0, 2], :, 0] *= 0.5
    weights.flags.writeable = False
    return weights


@numba.njit(**kernels.JIT)
def _doh_at(gray: np.ndarray, corners: np.ndarray, weights: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """``Lxx Lyy - Lxy^2`` at each corner for each scale of ``weights`` (:func:`_folded_weights`), shape
    ``(n_corners, n_scales)``; ``L..`` as :func:`gaussian_weights` filtering with reflected borders.

    Each corner's (2R+1)^2 neighbourhood is folded once into its quarter: the sums ``q+`` of the four
    pixels at offsets (+-dy, +-dx) and the alternating sums ``q-`` (+ - - +). The symmetric weights of
    ``Lxx`` and ``Lyy`` then see ``q+`` only and the antisymmetric ``Lxy`` ``q-`` only, so every scale
    reads a quarter of its neighbourhood; the axis-0 sums come first, as in ``gaussian_filter``. The
    additions are grouped differently from a sum over the whole neighbourhood: the values agree to
    rounding (about 1e-16 of the sum of the magnitudes of the terms).
    """
    h, w = gray.shape
    largest = weights.shape[2] - 1
    responses = np.empty((corners.shape[0], weights.shape[1]))
    rows_plus, rows_minus = np.empty(largest + 1, np.intp), np.empty(largest + 1, np.intp)
    cols_plus, cols_minus = np.empty(largest + 1, np.intp), np.empty(largest + 1, np.intp)
    even = np.empty((largest + 1, largest + 1))
    odd = np.empty((largest + 1, largest + 1))
    along0 = np.empty((3, largest + 1))
    for corner in range(corners.shape[0]):
        row, col = corners[corner, 0], corners[corner, 1]
        for d in range(largest + 1):
            rows_plus[d], rows_minus[d] = _reflect(row + d, h), _reflect(row - d, h)
            cols_plus[d], cols_minus[d] = _reflect(col + d, w), _reflect(col - d, w)
        for dy in range(largest + 1):
            above, below = gray[rows_plus[dy]], gray[rows_minus[dy]]
            for dx in range(largest + 1):
                a, b = above[cols_plus[dx]], below[cols_plus[dx]]
                c, d = above[cols_minus[dx]], below[cols_minus[dx]]
                even[dy, dx] = (a + b) + (c + d)
                odd[dy, dx] = (a - b) - (c - d)
        for k in range(weights.shape[1]):
            radius = radii[k]
            along0[:, :radius + 1] = 0.0
            for dy in range(radius + 1):
                w0, w1, w2 = weights[0, k, dy], weights[1, k, dy], weights[2, k, dy]
                for dx in range(radius + 1):
                    along0[0, dx] += w0 * even[dy, dx]
                    along0[1, dx] += w1 * odd[dy, dx]
                    along0[2, dx] += w2 * even[dy, dx]
            l_xx = l_xy = l_yy = 0.0
            for dx in range(radius + 1):
                l_xx += along0[0, dx] * weights[2, k, dx]
                l_xy += along0[1, dx] * weights[1, k, dx]
                l_yy += along0[2, dx] * weights[0, k, dx]
            responses[corner, k] = l_xx * l_yy - l_xy * l_xy
    return responses


def _scale_responses(gray: np.ndarray, corners: np.ndarray, sigmas: tuple[float, ...]) -> np.ndarray:
    """``sigma^4 (Lxx Lyy - Lxy^2)`` at the corners, one column per sigma."""
    image = np.asarray(gray, dtype=np.float64)
    points = np.asarray(corners, dtype=np.intp).reshape(-1, 2)
    radii = np.array([_radius(sigma) for sigma in sigmas], dtype=np.intp)
    return np.array(sigmas) ** 4 * _doh_at(image, points, _folded_weights(sigmas), radii)


def hessian_response(gray: np.ndarray, corners: np.ndarray, sigma: float) -> np.ndarray:
    """Scale-normalised determinant of Hessian ``sigma^4 (Lxx Lyy - Lxy^2)`` at the given pixels.

    ``L..`` are ``scipy.ndimage.gaussian_filter(gray, sigma, order=..., mode="reflect", truncate=4.0)``,
    evaluated only at ``corners`` (integer (row, column) pairs) from their reflected neighbourhoods, so the
    values equal whole-image filtering (to rounding) at a fraction of its cost.
    """
    return _scale_responses(gray, corners, (float(sigma),))[:, 0]


def corner_scales(gray: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Scale of each corner: the sigma of :data:`DOH_SCALES` maximising ``|sigma^4 (Lxx Lyy - Lxy^2)|``.

    The determinant-of-Hessian detector that SURF approximates (paper eq. 8, ``detectSURFFeatures``;
    docs/features.md#tactum); the first maximum on ties.
    """
    responses = _scale_responses(gray, corners, tuple(DOH_SCALES.tolist()))
    return DOH_SCALES[np.argmax(np.abs(responses), axis=1)]


def _photo_scales(photo: PreparedPhoto) -> np.ndarray:
    """``corner_scales(gray, harris_corners(gray))`` of a prepared photo, Harris on its float32 gray image."""
    return corner_scales(photo.gray, _harris_corners(photo.gray32))


def top_scales_mean(scales: np.ndarray, n: int = TOP_SCALES) -> float:
    """Mean of the ``n`` largest scales (of all if fewer); NaN if there are none (paper eq. 8)."""
    values = np.sort(np.asarray(scales, dtype=np.float64))[::-1]
    return math.nan if values.size == 0 else float(np.mean(values[:n]))


def maco(v: np.ndarray, gray: np.ndarray, *, contrast: float | None = None) -> float:
    """Macrotexture coarseness, paper eq. 8: ``mean(va) * C(I_disp) * mean(top-10 corner scales)``.

    ``C`` is the Tamura contrast of the gray photo (docs/features.md#image); pass it as ``contrast`` when it is already
    known. The photo is the cropped ``I_disp`` (docs/features.md#preprocessing: image features use the cropped photo).
    """
    if contrast is None:
        contrast = tamura_contrast(gray)
    return _maco(v, contrast, corner_scales(gray, harris_corners(gray)))


def _maco(v: np.ndarray, contrast: float, scales: np.ndarray) -> float:
    return float(np.mean(np.abs(_samples(v, "v")))) * contrast * top_scales_mean(scales)


# --- 3. MaRG -------------------------------------------------------------------------------------------

def kept_peak_mean(gray: np.ndarray) -> float:
    """Mean of the filtered spectrum over its kept peaks, paper eq. 9-11 (docs/features.md#tactum, item 3).

    ``X = Re(fft2(I - mean(I))) / sqrt(M N)`` centred at (M//2, N//2); the kept peaks are the elements with
    ``X >= 0.75 max(X)``; each is weighted by ``G' = 1 - G``, G a Gaussian of sigma 25 bins normalised to
    peak 1 on the offsets -100..99 around the centre, and ``G' = 1`` outside that window.
    Interpretations (docs/features.md#marg): the mean is removed, else the DC term is the only peak; the average runs
    over the kept peaks, else the zeros of the removed elements drown them.

    The spectrum is the half spectrum of :class:`features.image.RealSpectrum`, shared with the image
    features' ``dft_80`` and ``dft_85``.
    """
    image = np.asarray(gray, dtype=np.float64)
    if image.ndim != 2 or image.size == 0:
        raise ValueError(f"gray must be a non-empty 2-D image, got shape {image.shape}")
    return _kept_peak_mean(RealSpectrum(image - image.mean(), overwrite=True))


def _kept_peak_mean(spectrum: RealSpectrum) -> float:
    """:func:`kept_peak_mean` from the unscaled spectrum of the centred image; ``X`` is it over sqrt(M N)."""
    m, n = spectrum.shape
    threshold = PEAK_FRACTION * spectrum.peak
    total, count = spectrum.peak_sum(PEAK_FRACTION)
    dy, dx, gauss = _centre_gaussian(m, n)
    window = spectrum.at(dy, dx)
    # X * G' = X - X * G, and G' = 1 outside the window.
    total -= np.sum(np.where(window >= threshold, window * gauss, 0.0))
    return float(total / count / math.sqrt(m * n))


@lru_cache(maxsize=8)
def _centre_gaussian(m: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The offsets -100..99 around the centre of an m x n spectrum that lie in it, and the Gaussian ``G``
    of MaRG (eq. 11) on them (made once per photo size; read-only)."""
    dy = np.arange(max(-GAUSS_HALF, -(m // 2)), min(GAUSS_HALF, m - m // 2))
    dx = np.arange(max(-GAUSS_HALF, -(n // 2)), min(GAUSS_HALF, n - n // 2))
    gauss = np.exp(-(dy[:, None] ** 2 + dx[None, :] ** 2) / (2.0 * GAUSS_SIGMA**2))
    for array in (dy, dx, gauss):
        array.flags.writeable = False
    return dy, dx, gauss


def marg(v: np.ndarray, gray: np.ndarray, *, contrast: float | None = None) -> float:
    """Macrotexture regularity, paper eq. 12: ``mean(va) * (mean(X_filt over kept peaks) - C(I_disp))``.

    See :func:`kept_peak_mean` for ``X_filt``; ``C`` is the Tamura contrast (pass it if known).
    """
    if contrast is None:
        contrast = tamura_contrast(gray)
    return _marg(v, kept_peak_mean(gray), contrast)


def _marg(v: np.ndarray, peak_mean: float, contrast: float) -> float:
    return float(np.mean(np.abs(_samples(v, "v")))) * (peak_mean - contrast)


# --- 4, 5. MiRO, MiCO ------------------------------------------------------------------------------------

def wavelet_detail(v: np.ndarray, level: int, wavelet: str = WAVELET, levels: int = 5) -> np.ndarray:
    """The level-``level`` detail of ``v`` reconstructed to full length (MATLAB ``wrcoef("d", ...)``).

    ``pywt.wavedec(v, wavelet, level=levels, mode="symmetric")``, every coefficient array but that level's
    zeroed, ``pywt.waverec``, the first ``len(v)`` samples: the ``levels`` details plus the approximation
    sum to ``v``. Signed; MiRO takes its absolute value.
    """
    values = _samples(v, "v")
    if not 1 <= level <= levels:
        raise ValueError(f"detail level must be in 1..{levels}, got {level}")
    return _detail_of(pywt.wavedec(values, wavelet, level=levels, mode="symmetric"), level, wavelet, values.size)


def _detail_of(coefficients: list[np.ndarray], level: int, wavelet: str, size: int) -> np.ndarray:
    """The level-``level`` detail reconstructed from a ``pywt.wavedec`` decomposition (see :func:`wavelet_detail`)."""
    only = [np.zeros_like(c) for c in coefficients]
    only[-level] = coefficients[-level]
    return pywt.waverec(only, wavelet, mode="symmetric")[:size]


def miro(v: np.ndarray) -> float:
    """Microtexture roughness, paper eq. 13-14: ``log10(1 + mean(|d|))``, ``d = D1 - (mean D1 / mean D5) D5``.

    ``Dk = |level-k detail of v|`` (db8, :func:`wavelet_detail`); ``d = D1`` if ``mean(D5) = 0``.
    Interpretation of eq. 13-14 (docs/features.md#tactum): the bars are means, so d removes from D1 the share of D5
    scaled to D1's level; MiRO grows with the signal's amplitude and does not change when D5 alone is scaled.
    """
    values = _samples(v, "v")
    coefficients = pywt.wavedec(values, WAVELET, level=5, mode="symmetric")  # one decomposition for both
    d1 = np.abs(_detail_of(coefficients, 1, WAVELET, values.size))
    d5 = np.abs(_detail_of(coefficients, 5, WAVELET, values.size))
    mean_d5 = np.mean(d5)
    d = d1 if mean_d5 == 0 else d1 - (np.mean(d1) / mean_d5) * d5
    return float(np.log10(1.0 + np.mean(np.abs(d))))


def spectral_centroid(x: np.ndarray, fs: float) -> float:
    """Spectral centroid in Hz, paper eq. 15: ``fs * sum(f_i |X_i|) / sum(|X_i|)``.

    Over the ``rfft`` bins i = 0..N//2 with ``f_i = i / N`` (no window), so a pure tone on a bin returns its
    frequency. NaN for an all-zero signal.

    Examples
    --------
    >>> t = np.arange(3000) / 3000.0
    >>> round(spectral_centroid(np.sin(2 * np.pi * 250.0 * t), 3000.0), 6)
    250.0
    """
    values = _samples(x, "x")
    magnitude = np.abs(np.fft.rfft(values))
    bins = np.arange(magnitude.size) / values.size
    return _ratio(fs * float(bins @ magnitude), float(magnitude.sum()))


def mico(v: np.ndarray, fs: float = 3000.0) -> float:
    """Microtexture coarseness, paper eq. 15: the spectral centroid of ``v`` in Hz (fs = 3000 Hz)."""
    return spectral_centroid(v, fs)


# --- 6, 7. FST, FRS ------------------------------------------------------------------------------------

def slope(f: np.ndarray, lag: int = SLOPE_LAG) -> np.ndarray:
    """Force change over a 10 ms window: ``slope[i] = f[i + lag] - f[i]`` (paper section IV-A3)."""
    values = _samples(f, "f")
    return values[lag:] - values[:-lag]


def fst(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Tactile stiction, paper eq. 16: ``max slope(f_frt) / max slope(f_frn)``.

    NaN if a trace is not longer than the 30-sample slope window or the normal slope maximum is 0.
    ``lag`` is the 10 ms window in samples (30 at the scanner's 3 kHz).
    """
    f_frn, f_frt = _samples(f_frn, "f_frn"), _samples(f_frt, "f_frt")
    if min(f_frn.size, f_frt.size) <= lag:
        return math.nan
    return _ratio(float(slope(f_frt, lag).max()), float(slope(f_frn, lag).max()))


def sliding_segment(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> tuple[int, int]:
    """First and last (inclusive) sample of the sliding phase (Strese et al. 2020, section IV-A3, eq. 17;
    docs/features.md#frs).

    Start: the first index of the largest friction slope plus 30 (the end of the stiction window).
    End: the last sample where ``f_frn`` exceeds 5 % of its maximum.
    """
    start = int(np.argmax(slope(f_frt, lag))) + lag
    above = np.flatnonzero(f_frn > FORCE_RISE * np.max(f_frn))
    return start, int(above[-1]) if above.size else -1


def frs(f_frn: np.ndarray, f_frt: np.ndarray, lag: int = SLOPE_LAG) -> float:
    """Sliding resistance, paper eq. 17: ``mean(f_frt[s..e]) / mean(f_frn[s..e])`` (e inclusive).

    ``f_frt`` after :func:`scanner.preprocess.remove_friction_offset`; ``s, e`` from
    :func:`sliding_segment`. NaN if the segment is empty or the normal force averages 0 over it.
    """
    f_frn, f_frt = _samples(f_frn, "f_frn"), _samples(f_frt, "f_frt")
    if min(f_frn.size, f_frt.size) <= lag:
        return math.nan
    start, end = sliding_segment(f_frn, f_frt, lag)
    if end < start:
        return math.nan
    segment = slice(start, end + 1)
    return _ratio(float(np.mean(f_frt[segment])), float(np.mean(f_frn[segment])))


# --- 8, 13. ATK, CYD -----------------------------------------------------------------------------------

def judged(value: float, name: str) -> float:
    """An operator's judgement on the five-step scale {0, 0.25, 0.5, 0.75, 1}; NaN means not judged."""
    number = float(value)
    if math.isnan(number) or number in JUDGED_SCALE:
        return number
    raise ValueError(f"{name} = {value!r} is not on the five-step scale 0, 0.25, 0.5, 0.75, 1")


def atk(value: float) -> float:
    """Adhesive tack, paper eq. 18: the operator's value in {0, 0.25, 0.5, 0.75, 1}."""
    return judged(value, "tactum.atk")


def cyd(value: float) -> float:
    """Yielding, paper eq. 24: the operator's value in {0, 0.25, 0.5, 0.75, 1}."""
    return judged(value, "tactum.cyd")


# --- 9-12. Compliance ----------------------------------------------------------------------------------

def is_rigid(alpha_f: np.ndarray | None, skipped: bool) -> bool | None:
    """Whether a sample counts as rigid for the compliance features (Strese et al. 2020, section IV-A4, eqs. 19-20;
    docs/features.md#ccp).

    With a stored flex angle: ``std(alpha_f) < 1 deg`` (the skip flag is then ignored). Without one:
    rigid if the fold step was skipped as rigid (``meta.rigid``), else unknown (None).
    """
    if alpha_f is not None:
        return bool(np.std(_samples(alpha_f, "alpha_f")) < RIGID_STD_DEG)
    return True if skipped else None


def ccp(f_press: np.ndarray, rigid: bool) -> float:
    """Tactile compliance, paper eq. 19-20: 0 if rigid, else ``max(f_press) / 4.0 mm`` (N/mm)."""
    return 0.0 if rigid else float(np.max(_samples(f_press, "f_press"))) / INDENTATION_MM


def cdf(alpha_f: np.ndarray) -> float:
    """Local deformation, paper eq. 21: ``std(alpha_f)`` in degrees (0 for a fold skipped as rigid)."""
    return float(np.std(_samples(alpha_f, "alpha_f")))


def cdp(f_fold: np.ndarray, alpha_f: np.ndarray, rigid: bool, fs: float = 3000.0) -> float:
    """Damping, paper eq. 22: ``(f[n_max] - f[n_min]) / ((alpha[n_max] - alpha[n_min]) / dt)``.

    0 if rigid. The damping phase runs from the start of the force rise (``n_min``, the first sample of
    ``f_fold`` above 5 % of its peak) to the force maximum (``n_max``, first on ties), ``dt = (n_max -
    n_min) / fs``. NaN if the phase is empty (dt = 0) or the angle does not change over it.
    """
    if rigid:
        return 0.0
    f_fold, alpha_f = _samples(f_fold, "f_fold"), _samples(alpha_f, "alpha_f")
    if f_fold.size != alpha_f.size:
        raise ValueError(f"f_fold ({f_fold.size}) and alpha_f ({alpha_f.size}) must have the same length")
    n_max = int(np.argmax(f_fold))
    rise = np.flatnonzero(f_fold > FORCE_RISE * f_fold[n_max])
    if rise.size == 0 or rise[0] >= n_max:
        return math.nan
    n_min = int(rise[0])
    dt = (n_max - n_min) / fs
    angular_speed = _ratio(alpha_f[n_max] - alpha_f[n_min], dt)
    return _ratio(float(f_fold[n_max] - f_fold[n_min]), angular_speed)


def crx(f_press: np.ndarray, rigid: bool) -> float:
    """Relaxation, paper eq. 23: 0 if rigid, else ``max(f_press) - f_press[-1]`` (N)."""
    if rigid:
        return 0.0
    f_press = _samples(f_press, "f_press")
    return float(np.max(f_press) - f_press[-1])


# --- 14, 15. TCO, TPR ----------------------------------------------------------------------------------

def tco(t_cool: np.ndarray, t_amb: float) -> float:
    """Thermal cooling, paper eq. 28-29: ``max(t_cool) - t_amb`` (K)."""
    return float(np.max(_samples(t_cool, "t_cool")) - t_amb)


def tpr(t_cool: np.ndarray, t_amb: float, fs: float = 20.0) -> float:
    """Thermal persistence, paper eq. 30: ``sqrt((t_max,5s - t_amb)^2 + (t_cool[-1] - t_amb)^2)``.

    ``t_max,5s = max(t_cool[first 5 s])`` (Strese et al. 2020, eq. 30; docs/features.md#tpr).

    ``t_cool`` sampled at ``fs`` (20 Hz) with t = 0 at its first sample; the first 5 s are t < 5 s.
    """
    t_cool = _samples(t_cool, "t_cool")
    early = t_cool[:max(1, int(round(PEAK_SECONDS * fs)))]
    return float(math.hypot(float(np.max(early)) - t_amb, float(t_cool[-1]) - t_amb))


# --- the scan ------------------------------------------------------------------------------------------

@dataclass
class _Inputs:
    """The preprocessed inputs of one scan; ``problems`` says why an absent input is absent."""

    values: dict[str, object] = field(default_factory=dict)
    problems: dict[str, str] = field(default_factory=dict)

    def put(self, key: str, value: object | None, problem: str = "") -> None:
        self.values[key] = value
        if value is None:
            self.problems[key] = problem

    def get(self, key: str) -> object | None:
        return self.values.get(key)


def _slide_inputs(prepared: PreparedScan, inputs: _Inputs) -> None:
    """``v`` and the IR window ``r_w`` of the tool slide; a failed slide check leaves both absent."""
    v_ts, r_ts = prepared.scan.get("v_ts"), prepared.scan.get("r_ts")
    if v_ts is None:
        inputs.put("v", None, "v_ts is missing")
        inputs.put("r_w", None, "v_ts is missing")
        return
    try:
        window = prepared.slide_window("v_ts")
    except QualityError as problem:
        inputs.put("v", None, f"v_ts: {problem}")
        inputs.put("r_w", None, f"v_ts: {problem}")
        return
    inputs.put("v", prepared.slide_signal("v_ts"))
    if r_ts is None:
        inputs.put("r_w", None, "r_ts is missing")
    elif r_ts.n < window.ir.stop:
        inputs.put("r_w", None, f"r_ts: window shorter than 1 s ({r_ts.n} samples, window ends at "
                                f"{window.ir.stop})")
    else:
        inputs.put("r_w", r_ts.data[window.ir])


def _photo_inputs(scan: Scan, inputs: _Inputs, disp: PreparedPhoto | None) -> None:
    """The prepared ``I_disp``: its cropped gray image, Tamura contrast and spectrum serve MaCo and MaRG."""
    image = scan.images.get("I_disp")
    if image is None:
        inputs.put("photo", None, "I_disp is missing")
        return
    try:
        inputs.put("photo", PreparedPhoto(image) if disp is None else disp)
    except ValueError as problem:
        inputs.put("photo", None, f"I_disp: {problem}")


def _gather(prepared: PreparedScan, disp: PreparedPhoto | None) -> _Inputs:
    scan = prepared.scan
    inputs = _Inputs()
    _slide_inputs(prepared, inputs)
    _photo_inputs(scan, inputs, disp)
    for name in ("f_frn", "f_press", "f_fold", "alpha_f", "t_cool"):
        trace = scan.get(name)
        inputs.put(name, None if trace is None else trace.data, f"{name} is missing")
    f_frt = scan.get("f_frt")
    inputs.put("f_frt", None if f_frt is None else remove_friction_offset(f_frt.data, f_frt.fs),
               "f_frt is missing")
    t_amb = scan.meta.t_amb
    inputs.put("t_amb", None if math.isnan(t_amb) else t_amb, "meta.t_amb (ambient temperature) is unknown")
    return inputs


def _compliance(inputs: _Inputs, skipped: bool) -> dict[str, tuple[Callable[..., float], tuple[str, ...]]]:
    """CCP, CDF, CDP, CRX as (function, input keys), after the rigidity decision of Strese et al. 2020, eqs. 19-20;
    docs/features.md#ccp."""
    rigid = is_rigid(inputs.get("alpha_f"), skipped)
    zero = (lambda: 0.0, ())
    if rigid and inputs.get("alpha_f") is None:
        return {"tactum.ccp": zero, "tactum.cdf": zero, "tactum.cdp": zero, "tactum.crx": zero}
    if rigid:
        return {"tactum.ccp": zero, "tactum.cdf": (cdf, ("alpha_f",)), "tactum.cdp": zero, "tactum.crx": zero}
    # Not rigid, or unknown because alpha_f is missing without the skip flag: then all four need alpha_f.
    unknown = ("alpha_f",) if rigid is None else ()
    return {"tactum.ccp": (lambda f, *_: ccp(f, False), ("f_press", *unknown)),
            "tactum.cdf": (cdf, ("alpha_f",)),
            "tactum.cdp": (lambda f, a: cdp(f, a, False), ("f_fold", "alpha_f")),
            "tactum.crx": (lambda f, *_: crx(f, False), ("f_press", *unknown))}


def _recipes(inputs: _Inputs, scan: Scan) -> dict[str, tuple[Callable[..., float], tuple[str, ...]]]:
    """Every feature as (function, input keys), in :data:`NAMES` order."""
    atk_value, cyd_value = atk(scan.meta.atk), cyd(scan.meta.cyd)
    recipes = {
        "tactum.matx": (matx, ("v", "f_frt", "r_w")),
        "tactum.maco": (lambda v, photo: _maco(v, photo.contrast, _photo_scales(photo)), ("v", "photo")),
        "tactum.marg": (lambda v, photo: _marg(v, _kept_peak_mean(photo.spectrum), photo.contrast),
                        ("v", "photo")),
        "tactum.miro": (miro, ("v",)),
        "tactum.mico": (mico, ("v",)),
        "tactum.fst": (fst, ("f_frn", "f_frt")),
        "tactum.frs": (frs, ("f_frn", "f_frt")),
        "tactum.atk": (lambda: atk_value, ()),
        "tactum.cyd": (lambda: cyd_value, ()),
        "tactum.tco": (tco, ("t_cool", "t_amb")),
        "tactum.tpr": (tpr, ("t_cool", "t_amb")),
    }
    recipes.update(_compliance(inputs, scan.meta.rigid))
    return {name: recipes[name] for name in NAMES}


def compute(scan: Scan, *, disp: PreparedPhoto | None = None, prepared: PreparedScan | None = None) -> dict[str, float]:
    """The 15 TacTUM features of a scan, in :data:`NAMES` order (docs/features.md#tactum).

    Inputs are preprocessed as in docs/features.md#preprocessing: ``v`` from ``v_ts`` (band limit, slide window,
    DFT321), the IR window of ``r_ts`` at the same samples, ``f_frt`` without its friction offset, the cropped gray
    ``I_disp``. A feature whose input is absent is NaN, and one :class:`MissingDataWarning` per absent
    channel (or failed slide check) names it and the features it made NaN.

    Parameters
    ----------
    scan : Scan
    disp : PreparedPhoto, optional
        ``PreparedPhoto(scan.images["I_disp"])`` when the caller shares it with the image features; the
        values are the same.
    prepared : PreparedScan, optional
        The scan prepared once for every feature family (:func:`features.extract`); the values are the same.

    Raises
    ------
    ValueError
        If ``meta.atk`` or ``meta.cyd`` is neither NaN nor on the five-step scale, or ``disp`` was not
        prepared from this scan's ``I_disp``.
    """
    if disp is not None and disp.source is not scan.images.get("I_disp"):
        raise ValueError("disp was not prepared from this scan's I_disp photo")
    inputs = _gather(prepared if prepared is not None else PreparedScan(scan), disp)
    values: dict[str, float] = {}
    blocked: dict[str, list[str]] = {}
    for name, (function, keys) in _recipes(inputs, scan).items():
        absent = [key for key in keys if inputs.get(key) is None]
        for key in absent:
            blocked.setdefault(inputs.problems[key], []).append(name)
        values[name] = math.nan if absent else float(function(*(inputs.get(key) for key in keys)))
    for problem, names in blocked.items():
        warnings.warn(f"scan {scan.scan_id}: {problem}; {', '.join(dict.fromkeys(names))} set to NaN",
                      MissingDataWarning, stacklevel=2)
    return values
