"""Compiled per-pixel loops of the image features: one pass over a photo where whole-array code needs many.

A 12-megapixel photo has ~11 million pixels. Written with whole-array operations, each step of LBP,
Tamura coarseness or the gray-level co-occurrence counts reads and writes the image again (LBP: about 40
passes; Tamura: about 45 per tile), so memory traffic, not arithmetic, sets their time. Here each is one
loop that keeps a pixel's intermediates in registers, compiled by numba (Lam et al. 2015, LLVM).

Every kernel does the same IEEE operations in the same order as the formulation it replaces, so the
results are bit for bit the same: numba compiles without ``fastmath``, which keeps LLVM from reassociating
sums or contracting a product and a sum into one fused multiply-add (the rounding of ``a * b + c`` is
that of two operations). Integer results (counts, window sums) are exact anyway. The two long sums
(:func:`pixel_sum`, :func:`central_moment_sums`) fix their own order, documented there, and are equal to
rounding to numpy's. ``tests/unit/test_image.py`` compares each kernel with the straightforward formulation on
random images, and the gray images with it for every 8-bit colour.

``cache=True`` stores the machine code beside this file (or in numba's user cache if that is read-only),
so only the first run on a machine compiles (about a second per kernel).
"""

from __future__ import annotations

import numpy as np

from scanner.lazy import jit

JIT = {"cache": True, "nogil": True, "boundscheck": False}
"""The options of every compiled kernel of the feature code: cached machine code; no GIL held, as extractions
run in several threads at once (the web app); no ``fastmath``: see the module docstring."""


GRAY_PRODUCTS = np.multiply.outer(np.array([0.299, 0.587, 0.114]), np.arange(256.0))
"""``0.299 v``, ``0.587 v`` and ``0.114 v`` for every 8-bit value v (rows R, G, B), each the float64 product
``scanner.preprocess.grayscale`` computes: three loads from a 6 KB table instead of three conversions and
three multiplications per pixel (about 15 % of :func:`gray_images`'s time). A global, so that numba compiles
it in as a constant."""
GRAY_PRODUCTS.flags.writeable = False


@jit(**JIT)
def gray_images(rgb: np.ndarray, gray: np.ndarray, gray_u8: np.ndarray, gray32: np.ndarray, levels: int,
                triples: np.ndarray, diagonal: np.ndarray, edges: np.ndarray) -> tuple[float, float, float]:
    """The gray image of an 8-bit RGB photo and what is made from it, in one pass over its pixels.

    Per pixel, exactly as ``scanner.preprocess.grayscale``, ``scanner.preprocess.gray_uint8`` and
    ``features.image._quantize`` compute them:

    - ``gray = 0.299 R + 0.587 G + 0.114 B`` (float64, left to right), written into ``gray``; the three
      products are read from :data:`GRAY_PRODUCTS`, where they are the same float64 products;
    - ``gray_u8 = uint8(gray + 0.5)``: ``gray_uint8``'s ``clip(floor(gray + 0.5), 0, 255)``, as the gray
      value of an 8-bit colour lies in [0, 255 + a few ulp], where truncation is the floor and nothing
      needs clipping;
    - ``gray32 = float32(gray)`` for Harris corners, unless ``gray32`` is empty (shape (0, 0));
    - the GLCM level ``q = trunc(clip(gray * levels / 256, 0, levels - 1))``, kept for two rows only: the
      level tuples ``features.image._direction_counts`` counts are counted from them as the rows arrive.

    Counts (int64, zeroed here), for q the image of levels:

    - ``triples[a, b, c]``: the L-shaped triples ``(q[r, c], q[r, c+1], q[r+1, c])``;
    - ``diagonal[a, b]``: the pairs ``(q[r, c], q[r-1, c-1])`` (135 degrees);
    - ``edges[0, a, b]``: the last row's pairs ``(q[-1, c], q[-1, c+1])``; ``edges[1, a, b]``: the last
      column's pairs ``(q[r, -1], q[r-1, -1])``, which the triples miss.

    Each histogram is kept four times over and added up at the end: neighbouring pixels often share
    their levels, and consecutive increments of one counter would wait for each other.

    Parameters
    ----------
    rgb : uint8 array of shape (h, w, 3)
        The photo.
    gray : float64 array of shape (h, w)
        Filled with the gray image.
    gray_u8 : uint8 array of shape (h, w)
        Filled with the rounded gray image.
    gray32 : float32 array of shape (h, w) or (0, 0)
        Filled with the float32 gray image; an empty array skips it.
    levels : int
        Number of GLCM gray levels (at most 256).
    triples : int64 array of shape (levels, levels, levels)
        Filled with the counts of the L-shaped triples.
    diagonal : int64 array of shape (levels, levels)
        Filled with the counts of the 135-degree pairs.
    edges : int64 array of shape (2, levels, levels)
        Filled with the counts of the last row's and the last column's pairs.

    Returns
    -------
    (float, float, float)
        The smallest and largest gray value, and the sum of all (:func:`pixel_sum`'s order).

    Examples
    --------
    A white and a black diagonal of a 2 x 2 photo, on 2 levels (white is level 1, black 0):

    >>> import numpy as np
    >>> from features.kernels import gray_images
    >>> rgb = np.zeros((2, 2, 3), np.uint8)
    >>> rgb[0, 0] = rgb[1, 1] = 255
    >>> gray, gray_u8 = np.empty((2, 2)), np.empty((2, 2), np.uint8)
    >>> triples, diagonal = np.empty((2, 2, 2), np.int64), np.empty((2, 2), np.int64)
    >>> edges = np.empty((2, 2, 2), np.int64)
    >>> gray_images(rgb, gray, gray_u8, np.empty((0, 0), np.float32), 2, triples, diagonal, edges)
    (0.0, 255.0, 510.0)
    >>> gray_u8.tolist()
    [[255, 0], [0, 255]]
    >>> np.argwhere(triples).tolist(), np.argwhere(diagonal).tolist(), np.argwhere(edges).tolist()
    ([[1, 0, 0]], [[1, 1]], [[0, 0, 1], [1, 1, 0]])
    """
    h, w = gray.shape
    red, green, blue = GRAY_PRODUCTS[0], GRAY_PRODUCTS[1], GRAY_PRODUCTS[2]
    with_float32 = gray32.shape[0] > 0
    total = 0.0
    scale = levels / 256.0
    top = levels - 1.0
    quantised = np.empty((2, w), np.uint8)  # row r's levels at r % 2
    # int32: a photo within the pixel limit (16384 px a side) puts at most 2^26 counts in each copy.
    triple_counts = np.zeros((4, levels, levels, levels), np.int32)
    diagonal_counts = np.zeros((4, levels, levels), np.int32)
    edges[:] = 0
    low, high = np.inf, -np.inf
    for r in range(h):
        row, row_u8 = gray[r], gray_u8[r]
        current, previous = quantised[r & 1], quantised[(r - 1) & 1]
        for c in range(w):
            value = red[rgb[r, c, 0]] + green[rgb[r, c, 1]] + blue[rgb[r, c, 2]]
            row[c] = value
            row_u8[c] = np.uint8(value + 0.5)
            low = min(low, value)
            high = max(high, value)
            current[c] = np.uint8(min(max(value * scale, 0.0), top))
        total += _row_sum(row)
        if with_float32:
            row32 = gray32[r]
            for c in range(w):
                row32[c] = np.float32(row[c])
        if r > 0:
            for c in range(w - 1):
                triple_counts[c & 3, previous[c], previous[c + 1], current[c]] += 1
            for c in range(1, w):
                diagonal_counts[c & 3, current[c], previous[c - 1]] += 1
            edges[1, current[w - 1], previous[w - 1]] += 1
    last = quantised[(h - 1) & 1]
    for c in range(w - 1):
        edges[0, last[c], last[c + 1]] += 1
    triples[:] = triple_counts.sum(axis=0)
    diagonal[:] = diagonal_counts.sum(axis=0)
    return low, high, total


@jit(**JIT)
def pixel_sum(image: np.ndarray) -> float:
    """The sum of a 2-D float64 image: each row in four interleaved partial sums, then the rows in order.

    The mean gray value of every image feature comes from this one order (:func:`gray_images` adds up
    its rows the same way), so that a feature computed alone equals the same feature from the prepared
    photo bit for bit. Its rounding error is near (row length / 4 + rows) ulps, the order of numpy's
    pairwise sum.

    Parameters
    ----------
    image : float64 array of shape (h, w)
        The image.

    Returns
    -------
    float
        The sum of its pixels.

    Examples
    --------
    >>> import numpy as np
    >>> from features.kernels import pixel_sum
    >>> pixel_sum(np.arange(12.0).reshape(3, 4))
    66.0
    """
    total = 0.0
    for r in range(image.shape[0]):
        total += _row_sum(image[r])
    return total


@jit(**JIT, inline="always")
def _row_sum(row: np.ndarray) -> float:
    """Sum of a row in four partial sums (columns c mod 4), so that the additions need not wait for each other."""
    s0 = s1 = s2 = s3 = 0.0
    n = row.shape[0]
    quads = n - n % 4
    for c in range(0, quads, 4):
        s0 += row[c]
        s1 += row[c + 1]
        s2 += row[c + 2]
        s3 += row[c + 3]
    for c in range(quads, n):
        s0 += row[c]
    return (s0 + s1) + (s2 + s3)


@jit(**JIT)
def central_moment_sums(gray: np.ndarray, mean: float) -> tuple[float, float]:
    """``sum (x - mean)^2`` and ``sum (x - mean)^4`` over a 2-D image, in one pass.

    Tamura contrast's moments (``features.image._tamura_contrast``). Each row is summed in four
    interleaved partial sums (columns c mod 4), so that the additions need not wait for each other, and
    the rows' sums are added up; the rounding error stays near (row length / 4 + rows) ulps, the order of
    numpy's pairwise sums.

    Parameters
    ----------
    gray : float64 array of shape (h, w)
        The image.
    mean : float
        The value the deviations are taken from (the image's mean).

    Returns
    -------
    (float, float)
        The sums of the squared and of the fourth powers of the deviations.

    Examples
    --------
    Every pixel lies 1 from the mean 2:

    >>> import numpy as np
    >>> from features.kernels import central_moment_sums
    >>> central_moment_sums(np.array([[1.0, 3.0], [1.0, 3.0]]), 2.0)
    (4.0, 4.0)
    """
    second = fourth = 0.0
    for r in range(gray.shape[0]):
        row = gray[r]
        s0 = s1 = s2 = s3 = f0 = f1 = f2 = f3 = 0.0
        n = row.shape[0]
        quads = n - n % 4
        for c in range(0, quads, 4):
            d0, d1, d2, d3 = row[c] - mean, row[c + 1] - mean, row[c + 2] - mean, row[c + 3] - mean
            q0, q1, q2, q3 = d0 * d0, d1 * d1, d2 * d2, d3 * d3
            s0 += q0
            s1 += q1
            s2 += q2
            s3 += q3
            f0 += q0 * q0
            f1 += q1 * q1
            f2 += q2 * q2
            f3 += q3 * q3
        for c in range(quads, n):
            d0 = row[c] - mean
            q0 = d0 * d0
            s0 += q0
            f0 += q0 * q0
        second += (s0 + s1) + (s2 + s3)
        fourth += (f0 + f1) + (f2 + f3)
    return second, fourth


@jit(**JIT)
def centred_point_symmetric_rows(image: np.ndarray, mean: float, out: np.ndarray) -> None:
    """Rows 0 .. M//2 of ``out`` become ``((x(m, n) - mean) + (x(-m, -n) - mean)) / 2`` (indices modulo M, N).

    The point-symmetric part of the centred image, which ``features.image.RealSpectrum`` transforms,
    with the subtraction, the sum and the halving in that order. ``out`` may be ``image`` itself: row m
    of the result needs only rows m and M - m, and row M - m > M/2 is never written; the two rows that
    pair with themselves (0 and M/2) are read from a copy.

    Parameters
    ----------
    image : float64 array of shape (M, N)
        The image.
    mean : float
        The value subtracted (the image's mean).
    out : float64 array of shape (M, N)
        Rows 0 .. M//2 are written; may be ``image``.

    Examples
    --------
    On a 2 x 3 image both rows pair with themselves: columns 1 and 2 are each other's mirror.

    >>> import numpy as np
    >>> from features.kernels import centred_point_symmetric_rows
    >>> image = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    >>> out = np.zeros_like(image)
    >>> centred_point_symmetric_rows(image, 3.5, out)
    >>> out.tolist()
    [[-2.5, -1.0, -1.0], [0.5, 2.0, 2.0]]
    """
    m, n = image.shape
    mirror = np.empty(n)
    for row in range(m // 2 + 1):
        partner = (m - row) % m
        source = image[partner]
        if partner == row:
            mirror[:] = source
            source = mirror
        here, target = image[row], out[row]
        target[0] = ((here[0] - mean) + (source[0] - mean)) * 0.5
        for col in range(1, n):
            target[col] = ((here[col] - mean) + (source[n - col] - mean)) * 0.5


@jit(**JIT)
def lbp_code_counts(image: np.ndarray, right: tuple[np.ndarray, np.ndarray], left: tuple[np.ndarray, np.ndarray],
                    up: tuple[np.ndarray, np.ndarray], down: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Counts of the 256 LBP codes (P = 8, R = 1) over the pixels at least 1 px from the border.

    Bit p of a code is ``neighbour p >= centre``, neighbour p at angle 2 pi p / 8 counter-clockwise from
    the right (rows grow down), as ``skimage.feature.local_binary_pattern`` orders them. The four
    diagonal neighbours are interpolated as scikit-image does: along the row first, ``(1 - f) x + f y``
    with the column weights ``right``/``left`` (``(1 - f, f)`` per column, towards the right and left
    neighbour column), then between two such rows with the row weights ``up``/``down``. Two products and
    their sum, in that order, give scikit-image's rounding; the weights come from
    ``features.image._interpolation_weights``, per absolute row and column as scikit-image computes them.

    Parameters
    ----------
    image : float64 array of shape (h, w)
        Gray image, C-contiguous.
    right, left : (array of shape (w,), array of shape (w,))
        ``(1 - f, f)`` per column of the interpolation towards the right and the left neighbour column.
    up, down : (array of shape (h,), array of shape (h,))
        ``(1 - f, f)`` per row of the interpolation towards the row above and the row below.

    Returns
    -------
    int64 array of shape (256,)
        The number of interior pixels with each code.

    Examples
    --------
    On an image growing downwards the neighbours below and beside a pixel count, those above do not: bits
    0 (right), 4 (left), 5, 6 and 7 (below), code ``1 + 16 + 32 + 64 + 128 = 241`` at all 3 x 4 interior
    pixels. The diagonal neighbours lie ``f = sqrt(1/2)`` px along each axis:

    >>> import numpy as np
    >>> from features.kernels import lbp_code_counts
    >>> def weights(n, f):
    ...     return np.full(n, 1 - f), np.full(n, f)
    >>> f = np.sqrt(0.5)
    >>> image = np.arange(5.0)[:, None] * np.ones(6)
    >>> counts = lbp_code_counts(image, weights(6, f), weights(6, 1 - f), weights(5, 1 - f), weights(5, f))
    >>> np.flatnonzero(counts).tolist(), int(counts[241])
    ([241], 12)
    """
    h, w = image.shape
    right0, right1 = right
    left0, left1 = left
    up0, up1 = up
    down0, down1 = down
    counts = np.zeros((4, 256), np.int64)  # four interleaved histograms: no wait on the previous count
    towards_right = np.empty((3, w))  # row r lerped towards its right neighbour column, row r at r % 3
    towards_left = np.empty((3, w))
    codes = np.empty(w, np.uint8)
    for r in range(min(2, h)):
        _lerp_row(image[r], right0, right1, left0, left1, towards_right[r], towards_left[r])
    for r in range(1, h - 1):
        before, here, after = (r - 1) % 3, r % 3, (r + 1) % 3
        _lerp_row(image[r + 1], right0, right1, left0, left1, towards_right[after], towards_left[after])
        tr_before, tr_here, tr_after = towards_right[before], towards_right[here], towards_right[after]
        tl_before, tl_here, tl_after = towards_left[before], towards_left[here], towards_left[after]
        above, row, below = image[r - 1], image[r], image[r + 1]
        u0, u1, d0, d1 = up0[r], up1[r], down0[r], down1[r]
        for c in range(1, w - 1):
            centre = row[c]
            code = np.uint8((d0 * tr_here[c] + d1 * tr_after[c]) >= centre) << 7
            code |= np.uint8(below[c] >= centre) << 6
            code |= np.uint8((d0 * tl_here[c] + d1 * tl_after[c]) >= centre) << 5
            code |= np.uint8(row[c - 1] >= centre) << 4
            code |= np.uint8((u0 * tl_before[c] + u1 * tl_here[c]) >= centre) << 3
            code |= np.uint8(above[c] >= centre) << 2
            code |= np.uint8((u0 * tr_before[c] + u1 * tr_here[c]) >= centre) << 1
            code |= np.uint8(row[c + 1] >= centre)
            codes[c] = code
        for c in range(1, w - 1):
            counts[c & 3, codes[c]] += 1
    return counts.sum(axis=0)


@jit(**JIT, inline="always")
def _lerp_row(row: np.ndarray, right0: np.ndarray, right1: np.ndarray, left0: np.ndarray, left1: np.ndarray,
              towards_right: np.ndarray, towards_left: np.ndarray) -> None:
    """A row interpolated towards its right and its left neighbour column (interior columns)."""
    for c in range(1, row.shape[0] - 1):
        towards_right[c] = right0[c] * row[c] + right1[c] * row[c + 1]
        towards_left[c] = left0[c] * row[c - 1] + left1[c] * row[c]


_I32 = np.int32
"""Tamura coarseness's window sums, their differences and the scaled ``E_k`` all fit in int32 (each at most
4^5 * 255000 = 261,120,000 < 2^31), but numba widens int32 arithmetic to int64; cast back after each step,
twice as many pixels fit in a vector register (the kernel takes 16 % less time)."""

TAMURA_KERNEL_KMAX = 5
"""The window sizes :func:`tamura_coarseness_total` is written for: 2^1 .. 2^5, the paper's
(``features.image.TAMURA_KMAX`` is this value)."""


@jit(**JIT)
def tamura_coarseness_total(gray: np.ndarray, tolerance: int) -> int:
    """Sum over the output pixels of Tamura's best window size ``S_best`` for kmax = 5, in one pass.

    The image is read as ``t = rint(1000 gray)`` (int32, exact for gray images of 8-bit photos, see
    ``features.image._tamura_coarseness_of_photo``), so every window sum is an exact integer. Level k holds the sums of
    the 2^k x 2^k windows by their top-left pixel, each the sum of four windows of level k - 1; the rows
    of each level live in a ring of 64 rows, made as the photo's rows arrive. At output pixel (r, c),
    ``E_k = max(|S_k(r - h, c) - S_k(r - h, c - 2^k)|, |S_k(r, c - h) - S_k(r - 2^k, c - h)|)`` with
    h = 2^(k-1) (the window means' differences of ``features.image.tamura_coarseness`` times 4^k), scaled
    by 4^(5 - k) to a common unit; ``S_best = 2^k`` for the first k with ``E_k >= max E - tolerance``.

    The five levels are written out rather than looped over: with them as constants the compiler keeps
    a pixel's ten window differences in registers (a loop over k takes twice the time).

    Parameters
    ----------
    gray : (h, w) float64 array, h and w at least 64
        Gray image (values of an 8-bit photo's gray image, 0..255).
    tolerance : int
        The tie tolerance in units of ``1 / (1000 * 4^5)`` gray levels.

    Returns
    -------
    int
        The sum of ``S_best`` over the ``(h - 63) (w - 63)`` output pixels (rows and columns 32 .. h - 32
        and 32 .. w - 32); divided by their number, Tamura coarseness.

    Examples
    --------
    On a flat image every ``E_k`` is 0, so every output pixel takes the smallest window, 2: a 70 x 70
    image has 7 x 7 output pixels.

    >>> import numpy as np
    >>> from features.kernels import tamura_coarseness_total
    >>> tamura_coarseness_total(np.full((70, 70), 100.0), 0)
    98
    """
    h, w = gray.shape
    margin = 32
    levels = np.zeros((6, 64, w), np.int32)  # level k, row i at i % 64 (i & 63)
    total = 0
    for x in range(h):
        base, row = levels[0, x & 63], gray[x]
        for j in range(w):
            base[j] = np.int32(np.rint(row[j] * 1000.0))
        # Row x completes level k's row x - (2^k - 1), from level k - 1's rows x - (2^k - 1) and x - (2^(k-1) - 1);
        # the window halves are literals, so that each loop is compiled for its own offsets.
        if x >= 1:
            _window_sums(levels[0, (x - 1) & 63], levels[0, x & 63], 1, levels[1, (x - 1) & 63])
        if x >= 3:
            _window_sums(levels[1, (x - 3) & 63], levels[1, (x - 1) & 63], 2, levels[2, (x - 3) & 63])
        if x >= 7:
            _window_sums(levels[2, (x - 7) & 63], levels[2, (x - 3) & 63], 4, levels[3, (x - 7) & 63])
        if x >= 15:
            _window_sums(levels[3, (x - 15) & 63], levels[3, (x - 7) & 63], 8, levels[4, (x - 15) & 63])
        if x >= 31:
            _window_sums(levels[4, (x - 31) & 63], levels[4, (x - 15) & 63], 16, levels[5, (x - 31) & 63])
        r = x - (margin - 1)  # the newest row whose windows are all complete
        if margin <= r <= h - margin:
            total += _best_sizes(levels, r, w, tolerance)
    return total


@jit(**JIT, inline="always")
def _window_sums(top: np.ndarray, bottom: np.ndarray, half: int, out: np.ndarray) -> None:
    """Row of level k from rows i and i + h of level k - 1: four windows of side h make one of side 2h."""
    for j in range(out.shape[0] - 2 * half + 1):
        out[j] = _I32(_I32(top[j] + bottom[j]) + _I32(top[j + half] + bottom[j + half]))


@jit(**JIT, inline="always")
def _best_sizes(levels: np.ndarray, r: int, w: int, tolerance: int) -> int:
    """Sum of ``S_best`` over output row r (columns 32 .. w - 32), see :func:`tamura_coarseness_total`."""
    m1, c1, t1 = levels[1, (r - 1) & 63], levels[1, r & 63], levels[1, (r - 2) & 63]
    m2, c2, t2 = levels[2, (r - 2) & 63], levels[2, r & 63], levels[2, (r - 4) & 63]
    m3, c3, t3 = levels[3, (r - 4) & 63], levels[3, r & 63], levels[3, (r - 8) & 63]
    m4, c4, t4 = levels[4, (r - 8) & 63], levels[4, r & 63], levels[4, (r - 16) & 63]
    m5, c5, t5 = levels[5, (r - 16) & 63], levels[5, r & 63], levels[5, (r - 32) & 63]
    tie = _I32(tolerance)
    total = 0
    for c in range(32, w - 32 + 1):
        e1 = _I32(max(abs(_I32(m1[c] - m1[c - 2])), abs(_I32(c1[c - 1] - t1[c - 1]))) * _I32(256))
        e2 = _I32(max(abs(_I32(m2[c] - m2[c - 4])), abs(_I32(c2[c - 2] - t2[c - 2]))) * _I32(64))
        e3 = _I32(max(abs(_I32(m3[c] - m3[c - 8])), abs(_I32(c3[c - 4] - t3[c - 4]))) * _I32(16))
        e4 = _I32(max(abs(_I32(m4[c] - m4[c - 16])), abs(_I32(c4[c - 8] - t4[c - 8]))) * _I32(4))
        e5 = _I32(max(abs(_I32(m5[c] - m5[c - 32])), abs(_I32(c5[c - 16] - t5[c - 16]))))
        threshold = _I32(max(max(max(e1, e2), max(e3, e4)), e5) - tie)
        best = _I32(32)
        if e4 >= threshold:
            best = _I32(16)
        if e3 >= threshold:
            best = _I32(8)
        if e2 >= threshold:
            best = _I32(4)
        if e1 >= threshold:
            best = _I32(2)
        total += best
    return total
