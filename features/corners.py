"""MaCo's corners (Strese et al. 2020, section IV-A1b, eq. 8): Harris corners and their scales.

:func:`harris_corners` gives the corners of ``cv2.goodFeaturesToTrack`` with the Harris detector, in the same
order, from a response that equals ``cv2.cornerHarris`` bit for bit (:func:`harris_response`);
:func:`corner_scales` gives each corner the scale of the determinant-of-Hessian detector that SURF
approximates, evaluated only at the corners (:func:`hessian_response`).
"""

from __future__ import annotations

from collections.abc import Iterator
from functools import lru_cache

import numpy as np

from features import kernels
from features.image import spans
from scanner.lazy import jit, library
from taxonomy.errors import ParameterError

cv2 = library("cv2")

DOH_SCALES = 1.2 * 2.0 ** (np.arange(16) / 4.0)
"""Scale ladder of the determinant-of-Hessian detector in MaCo: 1.2 * 2^(k/4), k = 0..15 (Strese et al. 2020,
section IV-A1b)."""


HARRIS = {"maxCorners": 100, "qualityLevel": 0.01, "minDistance": 10, "blockSize": 3, "k": 0.04}
"""``cv2.goodFeaturesToTrack`` parameters of MaCo's Harris corners (Strese et al. 2020, section IV-A1b)."""

_HARRIS_APERTURE = 3
"""Sobel aperture ``goodFeaturesToTrack`` gives ``cornerHarris`` (its ``gradientSize`` default)."""


def harris_corners(gray: np.ndarray) -> np.ndarray:
    """Up to 100 Harris corners of a gray image as integer (row, column) pixels (paper section IV-A1b).

    ``cv2.goodFeaturesToTrack(gray.astype(float32), maxCorners=100, qualityLevel=0.01, minDistance=10,
    blockSize=3, useHarrisDetector=True, k=0.04)``, rounded to the nearest pixel; the corners
    are the same, in the same order, from :func:`_harris_corners`.

    Parameters
    ----------
    gray : array of shape (h, w)
        Gray image.

    Returns
    -------
    ndarray of shape (k, 2)
        Integer (row, column) of each corner, strongest first, ``k <= 100``.

    Examples
    --------
    The four corners of a bright square:

    >>> import numpy as np
    >>> from features.corners import harris_corners
    >>> gray = np.zeros((64, 64))
    >>> gray[16:48, 16:48] = 200.0
    >>> sorted(harris_corners(gray).tolist())
    [[16, 16], [16, 47], [47, 16], [47, 47]]
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
    """``cv2.cornerHarris(gray32, 3, 3, 0.04)``, bit for bit, with half its memory (time: docs/performance.md).

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

    Parameters
    ----------
    gray32 : array of shape (h, w)
        Gray image (converted to float32).

    Returns
    -------
    ndarray of shape (h, w), float32
        The Harris response R of each pixel.

    Examples
    --------
    R is 0 on flat ground, negative on an edge and largest at a corner:

    >>> import numpy as np
    >>> from features.corners import harris_response
    >>> gray32 = np.zeros((64, 64), np.float32)
    >>> gray32[16:48, 16:48] = 200.0
    >>> response = harris_response(gray32)
    >>> float(response[2, 2]), bool(response[32, 16] < 0), bool(response[16, 16] == response.max())
    (0.0, True, True)
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


@jit(**kernels.JIT)
def _gradient_products(dx: np.ndarray, dy: np.ndarray, planes: np.ndarray) -> None:
    """``planes[0..2] = Dx^2, Dx Dy, Dy^2`` (float32 products, as ``cornerHarris`` makes them)."""
    for i in range(dx.shape[0]):
        for j in range(dx.shape[1]):
            x, y = dx[i, j], dy[i, j]
            planes[0, i, j] = x * x
            planes[1, i, j] = x * y
            planes[2, i, j] = y * y


@jit(**kernels.JIT)
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


@jit(**kernels.JIT)
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

    Parameters
    ----------
    sigma : float
        Standard deviation of the Gaussian in samples.
    order : int
        Derivative order: 0, 1 or 2.
    truncate : float
        Half-width of the kernel in standard deviations.

    Returns
    -------
    ndarray of shape (2 r + 1,)
        The weights.

    Raises
    ------
    ParameterError
        If ``order`` is not 0, 1 or 2.

    Examples
    --------
    With ``truncate = 1`` the order-0 weights are ``(e^-1/2, 1, e^-1/2) / (1 + 2 e^-1/2)``; filtering an
    impulse with scipy gives the weights back, reversed:

    >>> import numpy as np
    >>> from scipy.ndimage import gaussian_filter1d
    >>> from features.corners import gaussian_weights
    >>> np.round(gaussian_weights(1.0, 0, truncate=1.0), 6).tolist()
    [0.274069, 0.451863, 0.274069]
    >>> impulse = np.zeros(9)
    >>> impulse[4] = 1.0
    >>> bool(np.allclose(gaussian_filter1d(impulse, 1.0, order=1)[::-1], gaussian_weights(1.0, 1)))
    True
    """
    if order not in (0, 1, 2):
        raise ParameterError(f"Gaussian derivative order must be 0, 1 or 2, got {order}")
    x = np.arange(-_radius(sigma, truncate), _radius(sigma, truncate) + 1, dtype=np.float64)
    sigma2 = sigma * sigma
    phi = np.exp(-0.5 / sigma2 * x**2)
    phi /= phi.sum()
    polynomial = (np.ones_like(x), -x / sigma2, (x**2 - sigma2) / sigma2**2)[order]
    return (polynomial * phi)[::-1]


@jit(**kernels.JIT)
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


@jit(**kernels.JIT)
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

    Parameters
    ----------
    gray : array of shape (h, w)
        Gray image.
    corners : array of shape (k, 2)
        Integer (row, column) of the pixels.
    sigma : float
        Scale of the Gaussian derivatives in pixels.

    Returns
    -------
    ndarray of shape (k,)
        The response at each pixel.

    Examples
    --------
    The same values as filtering the whole image, at pixels inside and on the border:

    >>> import numpy as np
    >>> from scipy.ndimage import gaussian_filter
    >>> from features.corners import hessian_response
    >>> gray = np.random.default_rng(0).random((40, 40))
    >>> corners = np.array([[0, 0], [20, 13], [39, 5]])
    >>> l_xx, l_yy, l_xy = (gaussian_filter(gray, 2.0, order=order) for order in ((0, 2), (2, 0), (1, 1)))
    >>> whole = 2.0**4 * (l_xx * l_yy - l_xy**2)[corners[:, 0], corners[:, 1]]
    >>> bool(np.allclose(hessian_response(gray, corners, 2.0), whole, rtol=1e-9, atol=1e-15))
    True
    """
    return _scale_responses(gray, corners, (float(sigma),))[:, 0]


def corner_scales(gray: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Scale of each corner: the sigma of :data:`DOH_SCALES` maximising ``|sigma^4 (Lxx Lyy - Lxy^2)|``.

    The determinant-of-Hessian detector that SURF approximates (paper eq. 8, ``detectSURFFeatures``);
    the first maximum on ties.

    Parameters
    ----------
    gray : array of shape (h, w)
        Gray image.
    corners : array of shape (k, 2)
        Integer (row, column) of the corners (:func:`harris_corners`).

    Returns
    -------
    ndarray of shape (k,)
        The scale of each corner in pixels, one of :data:`DOH_SCALES`.

    Examples
    --------
    The scale of a Gaussian blob at its centre is the blob's own sigma, here 4.8 px (``1.2 * 2^(8/4)``):

    >>> import numpy as np
    >>> from features.corners import corner_scales
    >>> rows, cols = np.mgrid[:64, :64]
    >>> blob = np.exp(-((rows - 32) ** 2 + (cols - 32) ** 2) / (2 * 4.8**2))
    >>> corner_scales(blob, np.array([[32, 32]])).tolist()
    [4.8]
    """
    responses = _scale_responses(gray, corners, tuple(DOH_SCALES.tolist()))
    return DOH_SCALES[np.argmax(np.abs(responses), axis=1)]
