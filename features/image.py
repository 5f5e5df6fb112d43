"""Image features, 31 per photo (docs/features.md#image), computed on the cropped photo
(docs/features.md#preprocessing).

The paper (Strese et al. 2020, section IV-C) lists colour, brightness, edginess, two DFT peak means,
14 Haralick features, Tamura coarseness and contrast, and 10 rotation-invariant LBP bins; docs/features.md#image fixes
every definition. ``compute`` returns the 31 values under ``NAMES``; the caller prefixes them with
``image.disp.``, ``image.macro.`` or ``image.illu.``. It works on a :class:`PreparedPhoto`: the crop, its
gray image, statistics and spectrum, each made once, which ``features.extract`` shares with TacTUM for
``I_disp``.

A 12-megapixel photo has ~11 million pixels. The per-pixel work of a photo (its gray images and GLCM
counts, LBP codes, Tamura coarseness) runs in the compiled single-pass loops of :mod:`features.kernels`;
the rest runs over bands of rows into preallocated buffers, so that a band's temporaries stay in cache
instead of costing a hundred megabytes per step. Both give the same float64 operations as the whole-image
formula, or exact integer counts, so they change no value (Tamura contrast's moment sums only regroup,
to rounding).
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Iterator, Sequence

import numpy as np

from features import kernels
from scanner.lazy import library
from scanner.preprocess import IMAGE_BORDER_PX, MIN_CROPPED_SIDE_PX, crop_image
from taxonomy.errors import ParameterError

cv2 = library("cv2")

HARALICK_NAMES = (
    "angular_second_moment", "contrast", "correlation", "sum_of_squares", "inverse_difference_moment",
    "sum_average", "sum_variance", "sum_entropy", "entropy", "difference_variance", "difference_entropy",
    "information_correlation_1", "information_correlation_2", "maximal_correlation_coefficient",
)
"""Haralick et al. 1973's f1..f14 in order; the columns are ``haralick_01`` .. ``haralick_14``."""

LBP_BINS = 10
"""Rotation-invariant uniform LBP with P = 8: labels 0..8 count the ones of a uniform code, 9 the rest."""

NAMES: tuple[str, ...] = (
    "color", "brightness", "edginess", "dft_80", "dft_85",
    *(f"haralick_{i:02d}" for i in range(1, len(HARALICK_NAMES) + 1)),
    "tamura_coarseness", "tamura_contrast",
    *(f"lbp_{i}" for i in range(LBP_BINS)),
)
"""The 31 feature names of one photo, in column order (docs/features.md#image)."""

GLCM_LEVELS = 32
GLCM_OFFSETS: tuple[tuple[int, int], ...] = ((0, 1), (-1, 1), (-1, 0), (-1, -1))
"""(row, column) steps to the neighbour at 0, 45, 90 and 135 degrees (rows grow downwards)."""

HUE_MIN_SATURATION = 51
HUE_MIN_VALUE = 51
"""8-bit S and V thresholds: ``S / 255 >= 0.2`` holds exactly for ``S >= 51`` (51 / 255 = 0.2)."""

CANNY_THRESHOLDS = (100, 200)
DFT_FRACTIONS = (0.80, 0.85)
TAMURA_KMAX = kernels.TAMURA_KERNEL_KMAX
"""Tamura coarseness's largest window, 2^5 px (Tamura et al. 1978; docs/features.md#image): the compiled kernel that
``compute`` runs is written out for exactly this value, so it is defined there."""

MIN_SIDE_PX = MIN_CROPPED_SIDE_PX
"""Smallest side of the cropped image any feature is defined on: a GLCM needs a pair of neighbours."""

FEATURE_MIN_SIDE_PX: dict[str, int] = {
    "tamura_coarseness": 2 * 2**TAMURA_KMAX, **{f"lbp_{i}": 3 for i in range(LBP_BINS)},
}
"""Features that need a larger cropped image (docs/features.md#image): Tamura coarseness two of its largest windows
side by side, LBP a pixel with all eight neighbours. Below that they are NaN (:class:`ImageSizeWarning`)."""


class ImageSizeWarning(UserWarning):
    """A photo too small for some features, which are NaN; the message names them and the size."""

_BAND_ELEMENTS = 1 << 15
"""Pixels per band of rows (256 KiB of float64): a band's few temporaries fit in a 2 MiB L2 cache."""

_BYTE_BAND_ELEMENTS = 1 << 19
"""Pixels per band for 8-bit work streamed through OpenCV (colour, GLCM counts): no float temporaries,
so larger bands just save calls; still far below 2^24, where calcHist's float32 counts stop being exact."""

_TAMURA_TILE = (256, 256)
"""Output rows and columns per Tamura tile; a tile also reads 2^kmax - 1 more rows and columns either side."""


def spans(n: int, per_span: int) -> Iterator[tuple[int, int]]:
    """Consecutive ``[start, stop)`` ranges of ``per_span`` indices (the last may be shorter) covering
    ``range(n)``: the bands of rows (and tiles' columns) in which photos and TacTUM's planes are processed.

    Parameters
    ----------
    n : int
        Number of indices to cover.
    per_span : int
        Indices per range (positive).

    Yields
    ------
    tuple of (int, int)
        ``(start, stop)`` of each range, in order.

    Examples
    --------
    >>> list(spans(5, 2))
    [(0, 2), (2, 4), (4, 5)]
    """
    for start in range(0, n, per_span):
        yield start, min(start + per_span, n)


def _rows_per_band(width: int, elements: int | None = None) -> int:
    return max(1, (elements or _BAND_ELEMENTS) // max(width, 1))


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8:
        raise ParameterError(f"expected an RGB photo as a uint8 array, got {getattr(rgb, 'dtype', type(rgb))}")
    if rgb.ndim != 3 or rgb.shape[2] != 3 or min(rgb.shape[:2]) == 0:
        raise ParameterError(f"expected an RGB photo of shape (h, w, 3), got {rgb.shape}")
    return rgb


def _check_side(shape: tuple[int, ...], min_side: int, purpose: str) -> None:
    if min(shape[:2]) < min_side:
        raise ParameterError(f"gray image of {shape[0]}x{shape[1]} px is smaller than the "
                         f"{min_side}x{min_side} px {purpose} needs")


def _check_gray(gray: np.ndarray, min_side: int = 1, purpose: str = "this feature") -> np.ndarray:
    """A 2-D float64 view or copy of ``gray``; ValueError if it is not 2-D, too small or not finite."""
    image = np.asarray(gray)
    if image.ndim != 2:
        raise ParameterError(f"expected a 2-D gray image, got shape {image.shape}")
    if image.dtype.kind not in "biuf":
        raise ParameterError(f"expected a numeric gray image, got dtype {image.dtype}")
    _check_side(image.shape, min_side, purpose)
    image = image.astype(np.float64, copy=False)
    if not np.isfinite(image.sum()):
        raise ParameterError("gray image contains NaN or infinite values")
    return image


class PreparedPhoto:
    """One photo, cropped, with the images and statistics several features share, each made on first use.

    ``features.extraction.extract`` prepares ``I_disp`` once and hands it to both ``tactum.compute`` (MaCo
    and MaRG need its gray image, Tamura contrast and spectrum) and :func:`compute`, so a scan computes
    them once. Every attribute equals what the public single-feature functions compute from the photo.

    Parameters
    ----------
    rgb : (h, w, 3) uint8 array
        The full photo, kept as ``source``; ``photo`` is its crop (docs/features.md#preprocessing), a view.
    keep_gray : bool
        False lets :attr:`spectrum` take over the memory of :attr:`gray` (for a photo whose gray image is
        not needed after its spectrum): fresh memory is slow to fault in, and a 12-megapixel gray image
        is 86 MB. A later :attr:`gray` is then computed again.
    buffer : ndarray, optional
        Memory for :attr:`gray`, from :meth:`release` of a photo of the same size; ignored if it does not
        fit (C-contiguous float64 of the cropped photo's height and width). Its values are overwritten.
    border : int
        Pixels cropped from every side: the scanner's photos keep the paper's 100 px (docs/features.md#preprocessing);
        photos and patches of an imported set are usually taken whole (0).

    Raises
    ------
    ValueError
        If ``rgb`` is not an RGB uint8 photo or too small to crop.
    """

    def __init__(self, rgb: np.ndarray, *, keep_gray: bool = True, buffer: np.ndarray | None = None,
                 border: int = IMAGE_BORDER_PX) -> None:
        self.source = rgb
        self.border = border
        self.photo = crop_image(_check_rgb(rgb), border)
        self.keep_gray = keep_gray
        fits = (buffer is not None and buffer.dtype == np.float64 and buffer.shape == self.photo.shape[:2]
                and buffer.flags.c_contiguous)
        self._buffer = buffer if fits else None
        self._spectrum_memory: np.ndarray | None = None

    @functools.cached_property
    def gray(self) -> np.ndarray:
        """``scanner.preprocess.grayscale`` of the cropped photo (float64, 0..255).

        Made by :func:`features.kernels.gray_images` with its 8-bit version, its extremes and the GLCM
        level counts, in one pass over the photo instead of reading the 86 MB of a 12-megapixel gray
        image again for each (made again after :meth:`release`, which forgets only the gray image).

        Returns
        -------
        numpy.ndarray
            (h, w) float64 gray values of the cropped photo.

        Examples
        --------
        >>> photo = PreparedPhoto(np.full((2, 3, 3), (255, 0, 0), np.uint8), border=0)  # pure red
        >>> np.round(photo.gray, 6).tolist()  # 0.299 * 255
        [[76.245, 76.245, 76.245], [76.245, 76.245, 76.245]]
        """
        buffer, self._buffer = self._buffer, None
        gray = np.empty(self.photo.shape[:2]) if buffer is None else buffer
        gray_u8 = np.empty(gray.shape, np.uint8)
        with_float32 = self.keep_gray and "gray32" not in self.__dict__
        gray32 = self._gray32_memory() if with_float32 else np.empty((0, 0), np.float32)
        triples = np.empty((GLCM_LEVELS,) * 3, np.int64)
        diagonal = np.empty((GLCM_LEVELS,) * 2, np.int64)
        edges = np.empty((2, GLCM_LEVELS, GLCM_LEVELS), np.int64)
        low, high, total = kernels.gray_images(self.photo, gray, gray_u8, gray32, GLCM_LEVELS, triples, diagonal,
                                               edges)
        self.__dict__.setdefault("gray_u8", gray_u8)
        if gray32.size:
            self.__dict__["gray32"] = gray32
        self.__dict__["extremes"] = (low, high)
        self.__dict__["mean"] = total / gray.size
        self.__dict__.setdefault("direction_counts", _counts_by_direction(triples, diagonal, edges))
        return gray

    def release(self) -> np.ndarray | None:
        """Give up the memory of the spectrum (else of the gray image) for the ``buffer`` of the next photo.

        Both are forgotten, with the float32 gray image, so they are computed again if asked for. None if
        neither the spectrum nor the gray image was computed.

        Returns
        -------
        numpy.ndarray or None
            (h, w) float64 memory of the cropped photo's size (its contents are no longer meaningful), or
            None.

        Examples
        --------
        >>> rgb = np.zeros((4, 4, 3), np.uint8)
        >>> photo = PreparedPhoto(rgb, border=0)
        >>> peak = photo.spectrum.peak
        >>> buffer = photo.release()
        >>> buffer.shape, PreparedPhoto(rgb, buffer=buffer, border=0).gray is buffer  # the next photo's gray
        ((4, 4), True)
        >>> PreparedPhoto(rgb, border=0).release() is None  # nothing computed, nothing to give
        True
        """
        self.__dict__.pop("gray32", None)
        self._spectrum_memory = None
        spectrum = self.__dict__.pop("spectrum", None)
        gray = self.__dict__.pop("gray", None)
        return gray if spectrum is None else spectrum.memory

    @functools.cached_property
    def gray32(self) -> np.ndarray:
        """:attr:`gray` as float32, as Harris corners want it.

        A photo that keeps its gray image holds this one in the first half of the memory its spectrum will
        take, one fresh allocation fewer; the spectrum then overwrites it (it is made again if asked for).

        Returns
        -------
        numpy.ndarray
            (h, w) float32 gray values.

        Examples
        --------
        >>> photo = PreparedPhoto(np.full((2, 3, 3), (255, 0, 0), np.uint8), border=0)
        >>> str(photo.gray32.dtype), round(float(photo.gray32[0, 0]), 3)
        ('float32', 76.245)
        """
        if not self.keep_gray:
            return self.gray.astype(np.float32)
        if "gray" not in self.__dict__:  # the pass that makes the gray image makes this one too
            _ = self.gray
            return self.__dict__["gray32"]
        gray32 = self._gray32_memory()
        np.copyto(gray32, self.gray, casting="same_kind")
        return gray32

    def _gray32_memory(self) -> np.ndarray:
        """A float32 image in the first half of fresh memory for the spectrum (see :attr:`gray32`)."""
        self._spectrum_memory = np.empty(self.photo.shape[:2])
        return self._spectrum_memory.reshape(-1).view(np.float32)[:self._spectrum_memory.size].reshape(
            self._spectrum_memory.shape)

    @functools.cached_property
    def gray_u8(self) -> np.ndarray:
        """``scanner.preprocess.gray_uint8`` of :attr:`gray` (made with it, see there).

        Returns
        -------
        numpy.ndarray
            (h, w) uint8 gray values, ``floor(gray + 0.5)``.

        Examples
        --------
        >>> photo = PreparedPhoto(np.full((2, 3, 3), (255, 0, 0), np.uint8), border=0)  # gray 76.245
        >>> photo.gray_u8.tolist()
        [[76, 76, 76], [76, 76, 76]]
        """
        _ = self.gray  # the pass over the photo stores this one too
        return self.__dict__["gray_u8"]

    @functools.cached_property
    def direction_counts(self) -> list[np.ndarray]:
        """:func:`_direction_counts` of the 32-level quantised :attr:`gray` (made with it, see there).

        Returns
        -------
        list of numpy.ndarray
            The (32, 32) int64 counts of (reference, neighbour) level pairs at 0, 45, 90 and 135 degrees
            (:data:`GLCM_OFFSETS`).

        Examples
        --------
        >>> photo = PreparedPhoto(np.full((2, 3, 3), (255, 0, 0), np.uint8), border=0)  # level floor(76.245 / 8)
        >>> [int(counts[9, 9]) for counts in photo.direction_counts]  # the pairs of a 2 x 3 image
        [4, 2, 3, 2]
        """
        _ = self.gray
        return self.__dict__["direction_counts"]

    @functools.cached_property
    def mean(self) -> float:
        """Mean gray value (:func:`_mean`'s order; made with :attr:`gray`).

        Returns
        -------
        float
            The mean of :attr:`gray`.

        Examples
        --------
        >>> rgb = np.zeros((4, 4, 3), np.uint8)
        >>> rgb[:, 2:] = 255  # left half black, right half white
        >>> round(PreparedPhoto(rgb, border=0).mean, 6)
        127.5
        """
        _ = self.gray
        return self.__dict__["mean"]

    @functools.cached_property
    def extremes(self) -> tuple[float, float]:
        """Smallest and largest gray value (made with :attr:`gray`).

        Returns
        -------
        tuple of (float, float)
            ``(min(gray), max(gray))``.

        Examples
        --------
        >>> rgb = np.zeros((4, 4, 3), np.uint8)
        >>> rgb[:, 2:] = 255
        >>> [round(v, 6) for v in PreparedPhoto(rgb, border=0).extremes]
        [0.0, 255.0]
        """
        _ = self.gray
        return self.__dict__["extremes"]

    @functools.cached_property
    def contrast(self) -> float:
        """Tamura contrast of :attr:`gray` (:func:`tamura_contrast`).

        Returns
        -------
        float
            ``sigma / kurt^(1/4)`` of the gray values; 0 for a constant photo.

        Examples
        --------
        >>> rgb = np.zeros((4, 4, 3), np.uint8)
        >>> rgb[:, 2:] = 255  # two equal halves: sigma 127.5, kurtosis 1
        >>> round(PreparedPhoto(rgb, border=0).contrast, 6)
        127.5
        """
        low, high = self.extremes
        return _tamura_contrast(self.gray, self.mean, low == high)

    @functools.cached_property
    def spectrum(self) -> RealSpectrum:
        """``Re(fft2(gray - mean(gray)))``, unscaled (:class:`RealSpectrum`).

        Returns
        -------
        RealSpectrum
            The half spectrum of the centred gray image.

        Examples
        --------
        >>> rgb = np.zeros((4, 4, 3), np.uint8)
        >>> rgb[::2, ::2] = rgb[1::2, 1::2] = 255  # a checkerboard: +-127.5 about the mean
        >>> round(PreparedPhoto(rgb, border=0).spectrum.peak, 6)  # all at frequency (2, 2): 127.5 * 16
        2040.0
        """
        gray, mean = self.gray, self.mean
        if self.keep_gray:
            memory, self._spectrum_memory = self._spectrum_memory, None
            self.__dict__.pop("gray32", None)
            return RealSpectrum(gray, mean=mean, out=memory)
        del self.gray
        return RealSpectrum(gray, mean=mean, overwrite=True)


def compute(rgb: np.ndarray, *, prepared: PreparedPhoto | None = None,
            border: int = IMAGE_BORDER_PX) -> dict[str, float]:
    """The 31 image features of one photo (docs/features.md#image) under the names of ``NAMES``.

    Parameters
    ----------
    rgb : (h, w, 3) uint8 array
        The full photo; ``border`` px are cropped from every side first (docs/features.md#preprocessing).
    prepared : PreparedPhoto, optional
        ``PreparedPhoto(rgb, border=border)`` when the caller shares it with other features; the values
        are the same. Its own border is used.
    border : int
        Crop of the scanner's photos (100 px, the paper's); 0 for patches and other labs' photos.

    Returns
    -------
    dict
        Feature name -> value; ``haralick_03`` and ``haralick_12`` are NaN for a constant image. Each
        feature needs only what its definition needs: on a cropped image smaller than
        :data:`FEATURE_MIN_SIDE_PX` (64 px for Tamura coarseness, 3 px for LBP) those features are NaN
        with an :class:`ImageSizeWarning`; the others are defined from 2 x 2 px (:data:`MIN_SIDE_PX`).

    Raises
    ------
    ValueError
        If ``rgb`` is not an RGB uint8 photo, or is not larger than the crop plus 2 px on each axis.

    Examples
    --------
    >>> photo = np.full((300, 300, 3), (0, 255, 0), np.uint8)
    >>> compute(photo)["color"]
    125.0
    """
    if prepared is not None and prepared.source is not rgb:
        raise ParameterError("the prepared photo was made from a different array than rgb")
    photo = PreparedPhoto(rgb, keep_gray=False, border=border) if prepared is None else prepared
    _check_side(photo.photo.shape, MIN_SIDE_PX, "any image feature")
    small = _too_small(photo)
    # The gray image of a uint8 photo is finite, so the cores run without the public functions' checks.
    gray, mean = photo.gray, photo.mean
    high = photo.extremes[1]
    first = [color(photo.photo), mean / 255.0, edginess(photo.gray_u8)]
    coarseness = math.nan if "tamura_coarseness" in small else _tamura_coarseness_of_photo(gray, high)
    lbp = [math.nan] * LBP_BINS if "lbp_0" in small else _lbp_histogram(gray)
    rest = [*_haralick_from_counts(photo.direction_counts), coarseness, photo.contrast, *lbp]
    # Last: the spectrum of a photo prepared here is computed in the memory of its gray image.
    dft = _dft_peak_means(photo.spectrum, DFT_FRACTIONS)
    return dict(zip(NAMES, map(float, [*first, *dft, *rest]), strict=True))


def _too_small(photo: PreparedPhoto) -> list[str]:
    """Features the cropped photo is too small for (:data:`FEATURE_MIN_SIDE_PX`), with a warning naming them."""
    h, w = photo.photo.shape[:2]
    small = [name for name, side in FEATURE_MIN_SIDE_PX.items() if min(h, w) < side]
    if small:
        needs = {("lbp_0..9" if name.startswith("lbp_") else name): FEATURE_MIN_SIDE_PX[name] for name in small}
        warnings.warn(f"image of {h}x{w} px (after cropping {photo.border} px) is too small for "
                      + ", ".join(f"{name} (needs {side}x{side} px)" for name, side in needs.items())
                      + "; NaN", ImageSizeWarning, stacklevel=3)
    return small


def color(rgb: np.ndarray) -> float:
    """Dominant hue in degrees, the centre of the fullest 10-degree hue bin (paper: I_col; docs/features.md#image).

    ``cv2.cvtColor(rgb, COLOR_RGB2HSV)`` gives the hue in 2-degree steps (0..179, so 0..358 degrees);
    over the pixels with ``S / 255 >= 0.2`` and ``V / 255 >= 0.2`` a 36-bin histogram with bins
    ``[10 b, 10 b + 10)`` is built and ``10 b + 5`` of its fullest bin (the first on ties) returned.

    Parameters
    ----------
    rgb : (h, w, 3) uint8 array
        An RGB photo (the cropped one, in :func:`compute`).

    Returns
    -------
    float
        5, 15, ..., 355, or -1 if no pixel is saturated and bright enough.

    Examples
    --------
    >>> color(np.full((4, 4, 3), (0, 255, 0), np.uint8))  # green: hue 120 degrees
    125.0
    """
    rgb = _check_rgb(rgb)
    counts = np.zeros(180, np.int64)
    lower, upper = (0, HUE_MIN_SATURATION, HUE_MIN_VALUE), (255, 255, 255)
    for start, stop in spans(rgb.shape[0], _rows_per_band(rgb.shape[1], _BYTE_BAND_ELEMENTS)):
        hsv = cv2.cvtColor(rgb[start:stop], cv2.COLOR_RGB2HSV)
        mask = cv2.inRange(hsv, lower, upper)
        counts += cv2.calcHist([hsv], [0], mask, [180], [0, 180]).ravel().astype(np.int64)
    per_bin = counts.reshape(36, 5).sum(axis=1)  # hue h covers degrees 2h, so bin b holds h = 5b .. 5b + 4
    if per_bin.sum() == 0:
        return -1.0
    return float(10 * int(np.argmax(per_bin)) + 5)


def brightness(gray: np.ndarray) -> float:
    """Mean gray value / 255 (paper: I_br; docs/features.md#image), in [0, 1] for a gray image in 0..255.

    Parameters
    ----------
    gray : 2-D array
        Gray values in 0..255 (``scanner.preprocess.grayscale``).

    Returns
    -------
    float
        The mean gray value divided by 255.

    Raises
    ------
    ValueError
        If ``gray`` is not a non-empty 2-D numeric array of finite values.

    Examples
    --------
    >>> brightness(np.array([[0.0, 255.0], [127.5, 127.5]]))
    0.5
    """
    return _mean(_check_gray(gray)) / 255.0


def _mean(image: np.ndarray) -> float:
    """Mean of a 2-D float64 image, summed in :func:`features.kernels.pixel_sum`'s order, the one order of
    every image feature's mean (the prepared photo sums its gray image in that order as it makes it)."""
    return kernels.pixel_sum(np.ascontiguousarray(image)) / image.size


def edginess(gray_u8: np.ndarray) -> float:
    """Fraction of pixels marked by ``cv2.Canny(gray_u8, 100, 200)`` (paper: I_edg; docs/features.md#image).

    Parameters
    ----------
    gray_u8 : (h, w) uint8 array
        The 8-bit gray image of docs/features.md#preprocessing (``scanner.preprocess.gray_uint8``).

    Returns
    -------
    float
        The share of edge pixels, in [0, 1].

    Raises
    ------
    ValueError
        If ``gray_u8`` is not a non-empty 2-D uint8 array.

    Examples
    --------
    >>> step = np.zeros((8, 8), np.uint8)
    >>> step[:, 4:] = 255  # a vertical step: one column of edge pixels
    >>> float(edginess(step))
    0.125
    """
    image = np.asarray(gray_u8)
    if image.dtype != np.uint8 or image.ndim != 2 or image.size == 0:
        raise ParameterError(f"expected a 2-D uint8 gray image, got {image.dtype} of shape {image.shape}")
    edges = cv2.Canny(image, *CANNY_THRESHOLDS)
    return np.count_nonzero(edges) / edges.size


class RealSpectrum:
    """The real part of the 2-D DFT of a real M x N image, ``Re Y = Re(fft2(image))``, at half the cost.

    ``Re Y`` is the DFT of the image's point-symmetric part ``e(m, n) = (x(m, n) + x(-m, -n)) / 2``
    (indices modulo M and N), and the DFT of a point-symmetric image takes half the work of a real one:
    the row transforms of rows -m are the conjugates of those of rows m, so only rows 0 .. M//2 are
    transformed, and each column of those transforms is Hermitian, so a real-output inverse transform of
    its conjugate direction gives the column of ``Re Y``. ``cv2.dft`` does both, 2-3 times faster than
    ``numpy.fft`` or ``scipy.fft`` on the prime-factor sizes of cropped photos (2824 x 3832 =
    8 * 353 x 8 * 479); the two take 60 % of one whole-image ``cv2.dft`` and round within a few units of
    the last place of the largest value.

    :attr:`values` holds column l = 0 .. N//2 of ``Re Y`` as row l, its frequency k at position ``-k mod M``
    (the inverse transform's order). ``Re Y(k, l) = Re Y(-k, -l)``, so columns 1 .. (N-1)//2 stand for
    columns N-l too and count twice; column 0 and, for even N, column N/2 count once.

    Parameters
    ----------
    image : (M, N) float64 array
    mean : float
        Transform ``image - mean`` (the subtraction is done as the point-symmetric part is made, in the
        same pass).
    overwrite : bool
        Compute the spectrum in the memory of ``image`` (saves an image-sized buffer); it is kept as
        :attr:`memory`, and its contents are lost.
    out : ndarray, optional
        Memory for the spectrum instead (a C-contiguous float64 array of the image's shape); ``image`` is
        then left as it is.
    """

    def __init__(self, image: np.ndarray, *, mean: float = 0.0, overwrite: bool = False,
                 out: np.ndarray | None = None) -> None:
        if image.ndim != 2 or image.size == 0 or image.dtype != np.float64:
            raise ParameterError(f"expected a non-empty 2-D float64 image, got {image.dtype} of shape "
                             f"{image.shape}")
        self.shape: tuple[int, int] = image.shape
        if out is not None:
            self.memory = out
        else:
            self.memory = image if overwrite and image.flags.c_contiguous else np.empty(image.shape)
        kernels.centred_point_symmetric_rows(image, mean, self.memory)
        self.values = _real_spectrum(self.memory)
        self._selection: tuple[float, list[tuple[np.ndarray, int]]] | None = None

    @functools.cached_property
    def parts(self) -> list[tuple[np.ndarray, int]]:
        """Every value of the spectrum once, as (view of :attr:`values`, multiplicity) pairs.

        Returns
        -------
        list of (numpy.ndarray, int)
            Columns 1 .. (N-1)//2 (multiplicity 2), column 0 and, for even N, column N/2 (1 each).

        Examples
        --------
        >>> spectrum = RealSpectrum(np.ones((2, 4)))
        >>> [(part.shape, weight) for part, weight in spectrum.parts]
        [((1, 2), 2), ((1, 2), 1), ((1, 2), 1)]
        >>> sum(weight * part.size for part, weight in spectrum.parts)  # M x N values
        8
        """
        n = self.shape[1]
        parts = [(self.values[1:(n - 1) // 2 + 1], 2), (self.values[:1], 1)]
        if n % 2 == 0 and n > 1:
            parts.append((self.values[n // 2:], 1))
        return parts

    @functools.cached_property
    def peak(self) -> float:
        """The largest value, ``max(Re(fft2(image)))``.

        Returns
        -------
        float
            The largest real part of the spectrum.

        Examples
        --------
        >>> RealSpectrum(np.ones((2, 4))).peak  # all in the DC term: the sum of the image
        8.0
        """
        return max(float(part.max()) for part, _ in self.parts if part.size)

    def peaks(self, fraction: float) -> list[tuple[np.ndarray, int]]:
        """The values ``>= fraction * peak``, per part with its multiplicity, in the order of :attr:`parts`.

        A selection at a lower fraction holds every higher one, so it is kept and narrowed down: MaRG
        (0.75) and the DFT peak means (0.80, 0.85) scan the whole spectrum once.

        Parameters
        ----------
        fraction : float
            Share of :attr:`peak` a value must reach.

        Returns
        -------
        list of (numpy.ndarray, int)
            The selected values of every part of :attr:`parts`, with the part's multiplicity.

        Examples
        --------
        >>> image = 1 + np.cos(2 * np.pi * np.arange(4) / 4) * np.ones((2, 1))  # rows [2, 1, 0, 1]
        >>> spectrum = RealSpectrum(image)  # DC 8; 4 at (0, 1) and at its mirror (0, 3)
        >>> [(np.round(values, 6).tolist(), weight) for values, weight in spectrum.peaks(0.4)]
        [([4.0], 2), ([8.0], 1), ([], 1)]
        """
        threshold = fraction * self.peak
        if self._selection is None or threshold < self._selection[0]:
            self._selection = threshold, [(part[part >= threshold], weight) for part, weight in self.parts]
        return [(values[values >= threshold], weight) for values, weight in self._selection[1]]

    def peak_sum(self, fraction: float) -> tuple[float, float]:
        """Sum and number of the values ``>= fraction * peak``, each counted with its multiplicity.

        Parameters
        ----------
        fraction : float
            Share of :attr:`peak` a value must reach.

        Returns
        -------
        total, count : float
            The sum and the number of the values of the full spectrum at or above ``fraction * peak``.

        Examples
        --------
        >>> image = 1 + np.cos(2 * np.pi * np.arange(4) / 4) * np.ones((2, 1))
        >>> [round(v, 6) for v in RealSpectrum(image).peak_sum(0.4)]  # 8 + 4 + 4, three values
        [16.0, 3.0]
        """
        total = count = 0.0
        for kept, weight in self.peaks(fraction):
            total += weight * float(kept.sum())
            count += weight * kept.size
        return total, count

    def at(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """``Re Y(k, l)`` on the grid of frequencies ``rows`` x ``cols`` (integers, taken modulo M and N).

        Parameters
        ----------
        rows, cols : array-like of int
            Frequencies ``k`` and ``l``; negative ones count from the end (modulo M and N).

        Returns
        -------
        numpy.ndarray
            (len(rows), len(cols)) values of ``Re(fft2(image))``.

        Examples
        --------
        >>> image = 1 + np.cos(2 * np.pi * np.arange(4) / 4) * np.ones((2, 1))
        >>> np.round(RealSpectrum(image).at([0], [0, 1, -1]), 6).tolist()  # column 3 read as its mirror
        [[8.0, 4.0, 4.0]]
        """
        m, n = self.shape
        rows = np.mod(np.asarray(rows, dtype=np.intp), m)[:, None]
        cols = np.mod(np.asarray(cols, dtype=np.intp), n)[None, :]
        # Columns right of N/2 are read at (-k, -l); frequency k sits at position -k.
        mirrored = cols > n // 2
        return self.values[np.where(mirrored, n - cols, cols), np.where(mirrored, rows, np.mod(-rows, m))]


def _real_spectrum(image: np.ndarray) -> np.ndarray:
    """:attr:`RealSpectrum.values` from ``image`` (C-contiguous) whose rows 0 .. M//2 hold the point-symmetric
    part (:func:`features.kernels.centred_point_symmetric_rows`); its memory is reused for the result."""
    m, n = image.shape
    half = m // 2 + 1
    rows = cv2.dft(image[:half], dst=image[:half], flags=cv2.DFT_ROWS)
    columns = _hermitian_columns(rows, m, n)
    values = image.reshape(-1)[:columns.shape[0] * m].reshape(columns.shape[0], m)
    return cv2.dft(columns[:, 1:m + 1], dst=values, flags=cv2.DFT_ROWS | cv2.DFT_INVERSE | cv2.DFT_REAL_OUTPUT)


def _hermitian_columns(rows: np.ndarray, m: int, n: int) -> np.ndarray:
    """The columns l = 0 .. N//2 of the row transforms ``rows`` (CCS-packed, rows 0 .. M//2) as rows that
    ``cv2.dft``'s real-output inverse reads at ``[:, 1:M+1]``: ``Re Z(0)``, then ``Re Z(j), Im Z(j)``
    for j = 1 .. (M-1)//2, then ``Re Z(M/2)`` for even M.

    The complex columns are transposed as pairs, which puts ``Im Z(0)`` (0 for a point-symmetric image)
    right after ``Re Z(0)``; it is overwritten by ``Re Z(0)`` to start the packed row one place later.
    """
    half = rows.shape[0]
    inner = (n - 1) // 2
    real_columns = [0] + ([n - 1] if n % 2 == 0 and n > 1 else [])
    columns = np.empty((inner + len(real_columns), 2 * half))
    if inner:
        pairs = rows[:, 1:1 + 2 * inner].reshape(half, inner, 2)
        cv2.transpose(pairs, dst=columns[1:1 + inner].reshape(inner, half, 2))
        columns[1:1 + inner, 1] = columns[1:1 + inner, 0]
    for target, source in zip([0, inner + 1], real_columns, strict=False):
        packed = columns[target, 1:m + 1]
        packed[0] = rows[0, source]
        packed[1::2] = rows[1:1 + m // 2, source]
        packed[2::2] = 0.0
    return columns


def dft_peak_means(gray: np.ndarray, fractions: Sequence[float] = DFT_FRACTIONS) -> tuple[float, ...]:
    """Mean of the strongest real DFT coefficients (paper: I_dft1, I_dft2; docs/features.md#image ``dft_80``,
    ``dft_85``).

    With ``X = Re(fft2(I - mean(I))) / sqrt(M N)``, for each fraction f the mean of the values
    ``X >= f * max(X)``. Only the half spectrum is computed (:class:`RealSpectrum`); the other half's real
    parts are the same values, so they are counted twice instead. The result equals the full-spectrum
    mean to rounding.

    Parameters
    ----------
    gray : 2-D array
        Gray values, at least 2 x 2 px.
    fractions : sequence of float
        Shares of the largest value a coefficient must reach.

    Returns
    -------
    tuple of float
        One mean per fraction, in the order given.

    Examples
    --------
    >>> n = np.arange(64)
    >>> grating = 100 + 10 * np.cos(2 * np.pi * 4 * n / 64) * np.ones((32, 1))  # amplitude 10
    >>> [round(v, 6) for v in dft_peak_means(grating)]  # 10 * sqrt(32 * 64) / 2
    [226.27417, 226.27417]
    """
    image = _check_gray(gray, min_side=2, purpose="the DFT peak mean")
    return _dft_peak_means(RealSpectrum(image, mean=_mean(image)), fractions)


def _dft_peak_means(spectrum: RealSpectrum, fractions: Sequence[float]) -> tuple[float, ...]:
    """``dft_peak_means`` of the image whose centred spectrum is ``spectrum``."""
    scale = np.sqrt(spectrum.shape[0] * spectrum.shape[1])
    means = []
    for fraction in fractions:
        total, count = spectrum.peak_sum(fraction)
        means.append(float(total / count / scale))
    return tuple(means)


def quantize(gray: np.ndarray, levels: int = GLCM_LEVELS) -> np.ndarray:
    """Gray levels for the GLCM: ``q = min(floor(gray * levels / 256), levels - 1)`` as uint8 (docs/features.md#image).

    0-based (0 .. levels-1); Haralick's formulas use ``q + 1``. Values below 0 map to 0.

    Parameters
    ----------
    gray : 2-D array
        Gray values in 0..255.
    levels : int
        Number of gray levels, 1..256.

    Returns
    -------
    numpy.ndarray
        The levels as a uint8 array of the image's shape.

    Raises
    ------
    ValueError
        If ``levels`` is out of range or ``gray`` is not a non-empty 2-D array of finite values.

    Examples
    --------
    >>> quantize(np.array([[-5.0, 7.9, 8.0, 255.0]])).tolist()  # 8 gray values per level
    [[0, 0, 1, 31]]
    """
    if not 1 <= levels <= 256:
        raise ParameterError(f"levels must be in 1..256, got {levels}")
    return _quantize(_check_gray(gray, purpose="quantisation"), levels)


def _quantize(image: np.ndarray, levels: int) -> np.ndarray:
    out = np.empty(image.shape, np.uint8)
    scratch = np.empty((_rows_per_band(image.shape[1]), image.shape[1]))
    for start, stop in spans(image.shape[0], scratch.shape[0]):
        scaled = np.multiply(image[start:stop], levels / 256, out=scratch[:stop - start])
        # Truncating the clipped, non-negative value is the floor of the formula.
        out[start:stop] = np.clip(scaled, 0, levels - 1, out=scaled)
    return out


def _pair_views(q: np.ndarray, offset: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Aligned views (reference pixel, neighbour at ``offset``) over every pair inside the image."""
    dr, dc = offset
    h, w = q.shape
    rows = slice(max(0, -dr), h - max(0, dr))
    cols = slice(max(0, -dc), w - max(0, dc))
    neighbour_rows = slice(max(0, dr), h - max(0, -dr))
    neighbour_cols = slice(max(0, dc), w - max(0, -dc))
    return q[rows, cols], q[neighbour_rows, neighbour_cols]


def glcm(q: np.ndarray, offset: tuple[int, int] = (0, 1), levels: int = GLCM_LEVELS) -> np.ndarray:
    """Symmetric, normalised gray-level co-occurrence matrix (Haralick et al. 1973, eq. 1; docs/features.md#image).

    ``P[i, j]`` is the share of pixel pairs (reference, neighbour at ``offset`` = (rows, columns)) with
    levels (i, j) or (j, i): the pairs are counted in both orders and the counts divided by their sum.
    The pairs are counted by ``cv2.calcHist`` over the (level, level) pairs, which gives the counts of
    ``np.bincount`` on pair codes at a third of its cost, as exact integers.

    Parameters
    ----------
    q : 2-D integer array
        Gray levels 0 .. levels-1 (``quantize``).
    offset : (int, int)
        Step from a pixel to its neighbour; ``GLCM_OFFSETS`` are 0, 45, 90 and 135 degrees at distance 1.
    levels : int
        Number of gray levels, 1..256: the matrix is ``levels x levels``.

    Returns
    -------
    (levels, levels) float array
        The symmetric matrix ``P``, summing to 1.

    Raises
    ------
    ValueError
        If ``q`` is not a 2-D integer array of levels in 0 .. levels-1, or has no pixel pair at ``offset``.

    Examples
    --------
    >>> glcm(np.array([[0, 0, 1]]), (0, 1), levels=2) * 4  # pairs (0,0), (0,1) and their mirrors
    array([[2., 1.],
           [1., 0.]])
    """
    q = np.asarray(q)
    if q.ndim != 2 or q.dtype.kind not in "iu":
        raise ParameterError(f"expected a 2-D integer array of gray levels, got {q.dtype} of shape {q.shape}")
    if not 1 <= levels <= 256:
        raise ParameterError(f"levels must be in 1..256, got {levels}")
    if q.size and (q.min() < 0 or q.max() >= levels):
        raise ParameterError(f"gray levels must lie in 0..{levels - 1}, got {q.min()}..{q.max()}")
    reference, neighbour = _pair_views(q.astype(np.uint8, copy=False), offset)
    if reference.size == 0:
        raise ParameterError(f"a {q.shape[0]}x{q.shape[1]} image has no pixel pairs at offset {offset}")
    return _symmetric_normalised(_histogram([reference, neighbour], levels))


def _histogram(images: list[np.ndarray], levels: int) -> np.ndarray:
    """Counts of the level tuples (one level per image, same shape) as an int64 levels^len(images) array.

    Band by band, so that every call's float32 bins stay below 2^24, where they are exact.
    """
    dims = len(images)
    counts = np.zeros((levels,) * dims, np.int64)
    rows, cols = images[0].shape
    for start, stop in spans(rows, _rows_per_band(cols, _BYTE_BAND_ELEMENTS)):
        band = [image[start:stop] for image in images]
        bins = cv2.calcHist(band, list(range(dims)), None, [levels] * dims, [0, levels] * dims)
        counts += bins.astype(np.int64)
    return counts


def _symmetric_normalised(counts: np.ndarray) -> np.ndarray:
    counts = counts + counts.T
    return counts / counts.sum()


def _direction_counts(q: np.ndarray, levels: int) -> list[np.ndarray]:
    """Pair counts (reference, neighbour) for each of ``GLCM_OFFSETS``, the same as ``glcm`` counts them.

    One 3-D histogram of the L-shaped triples (q[r, c], q[r, c+1], q[r+1, c]) holds a pair of each of
    0, 45 and 90 degrees, at half the cost of three pair histograms; the triples miss the last row's
    0-degree pairs and the last column's 90-degree pairs, which are counted apart. 135 degrees is counted
    alone. (:func:`features.kernels.gray_images` counts the same tuples of a photo as it makes its gray
    image.)
    """
    corner, right, below = q[:-1, :-1], q[:-1, 1:], q[1:, :-1]
    edges = np.stack([_histogram([q[-1:, :-1], q[-1:, 1:]], levels), _histogram([q[1:, -1:], q[:-1, -1:]], levels)])
    return _counts_by_direction(_histogram([corner, right, below], levels),
                                _histogram(list(_pair_views(q, GLCM_OFFSETS[3])), levels), edges)


def _counts_by_direction(triples: np.ndarray, diagonal: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """The four directions' pair counts from the triple counts, the 135-degree pair counts and the pairs
    the triples miss (``edges[0]`` the last row's at 0 degrees, ``edges[1]`` the last column's at 90)."""
    return [
        triples.sum(axis=2) + edges[0],  # (r, c) -> (r, c+1)
        triples.sum(axis=0).T,           # (r+1, c) -> (r, c+1)
        triples.sum(axis=1).T + edges[1],  # (r+1, c) -> (r, c)
        diagonal,
    ]


def _entropies(p: np.ndarray) -> np.ndarray:
    """``-sum p ln p`` over the last axis of ``p`` (stacked distributions), with ``0 ln 0 = 0``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return -np.sum(np.where(p > 0, p * np.log(p), 0.0), axis=-1)


def _maximal_correlations(p: np.ndarray, px: np.ndarray, py: np.ndarray) -> np.ndarray:
    """f14 of stacked GLCMs: sqrt of the second-largest eigenvalue of ``Q(i,j) = sum_k p(i,k) p(j,k) / (px(i) py(k))``.

    ``Q = Dx^-1/2 A A^T Dx^1/2`` with ``A = Dx^-1/2 P Dy^-1/2``, so Q's eigenvalues are the squared
    singular values of A and f14 is A's second singular value, computed without squaring (exact even
    where the eigenvalue is tiny). Rows and columns of unoccupied levels are 0/0 in Q; they are set to 0
    in A, which adds only zero singular values, so that all GLCMs go through one stacked SVD. 0 with
    fewer than two occupied levels.
    """
    occupied = np.minimum((px > 0).sum(axis=1), (py > 0).sum(axis=1))
    if p.shape[1] < 2:
        return np.zeros(p.shape[0])
    outer = px[:, :, None] * py[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(outer > 0, p / np.sqrt(outer), 0.0)
    return np.where(occupied >= 2, np.linalg.svd(a, compute_uv=False)[:, 1], 0.0)


def haralick_from_glcm(p: np.ndarray) -> np.ndarray:
    """Haralick et al. 1973's 14 texture features f1..f14 of one normalised GLCM (docs/features.md#image).

    Gray levels are 1-based (i, j = 1 .. Ng), logarithms natural, ``p_x``/``p_y`` the marginals,
    ``p_{x+y}(k)`` (k = 2 .. 2 Ng) and ``p_{x-y}(k)`` (k = 0 .. Ng-1) the sum and |difference|
    distributions:

    - f1 ASM ``sum p^2``; f2 contrast ``sum k^2 p_{x-y}(k)``;
    - f3 correlation ``sum (i - mu_x)(j - mu_y) p / (sigma_x sigma_y)``, NaN if a sigma is 0 (0/0);
    - f4 sum of squares ``sum (i - mu_x)^2 p(i, j)``; f5 IDM ``sum p / (1 + (i - j)^2)``;
    - f6 sum average ``sum k p_{x+y}(k)``; f7 sum variance ``sum (k - f6)^2 p_{x+y}(k)`` (not the
      paper's typo with f8); f8 sum entropy; f9 entropy HXY;
    - f10 difference variance: the variance of the |i - j| distribution; f11 difference entropy;
    - f12 ``(HXY - HXY1) / max(HX, HY)``, NaN if both marginal entropies are 0 (0/0);
      f13 ``sqrt(1 - exp(-2 (HXY2 - HXY)))``;
    - f14 maximal correlation coefficient, see ``_maximal_correlations``; 0 with fewer than two
      occupied levels.

    Parameters
    ----------
    p : (Ng, Ng) array
        A normalised GLCM: non-negative, summing to 1 (``glcm``).

    Returns
    -------
    (14,) float array
        f1 .. f14.

    Raises
    ------
    ValueError
        If ``p`` is not square, has a negative entry or does not sum to 1.

    Examples
    --------
    >>> f = haralick_from_glcm(np.array([[0.0, 0.5], [0.5, 0.0]]))  # every neighbour differs by 1 level
    >>> f[:3].tolist()
    [0.5, 1.0, -1.0]
    """
    p = np.asarray(p, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] != p.shape[1] or p.size == 0:
        raise ParameterError(f"expected a square GLCM, got shape {p.shape}")
    if not (np.all(p >= 0) and np.isclose(p.sum(), 1.0)):
        raise ParameterError("GLCM entries must be non-negative and sum to 1")
    return _haralick_features(p[None])[0]


def _haralick_features(p: np.ndarray) -> np.ndarray:
    """:func:`haralick_from_glcm` of a stack of GLCMs (B, Ng, Ng) at once, as a (B, 14) array: the four
    directions of a photo in one set of array operations instead of four."""
    batch, ng = p.shape[0], p.shape[1]
    level = np.arange(1, ng + 1, dtype=np.float64)
    i, j = level[:, None], level[None, :]
    px, py = p.sum(axis=2), p.sum(axis=1)
    mu_x, mu_y = px @ level, py @ level
    var_x = np.sum((level - mu_x[:, None]) ** 2 * px, axis=1)
    var_y = np.sum((level - mu_y[:, None]) ** 2 * py, axis=1)
    flat = p.reshape(batch, -1)
    sum_index = (i + j - 2).astype(np.intp).ravel()
    diff_index = np.abs(np.subtract.outer(np.arange(ng), np.arange(ng))).ravel()
    p_sum = np.stack([np.bincount(sum_index, row, minlength=2 * ng - 1) for row in flat])
    p_diff = np.stack([np.bincount(diff_index, row, minlength=ng) for row in flat])
    k_sum = np.arange(2, 2 * ng + 1, dtype=np.float64)
    k_diff = np.arange(ng, dtype=np.float64)

    covariance = np.sum((i - mu_x[:, None, None]) * (j - mu_y[:, None, None]) * p, axis=(1, 2))
    sum_average = p_sum @ k_sum
    mean_diff = p_diff @ k_diff
    hxy = _entropies(flat)
    hx, hy = _entropies(px), _entropies(py)
    pxpy = (px[:, :, None] * py[:, None, :]).reshape(batch, -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        hxy1 = -np.sum(np.where(flat > 0, flat * np.log(pxpy), 0.0), axis=1)
        sigma = np.sqrt(var_x * var_y)
        correlation = np.where(sigma > 0, covariance / sigma, np.nan)
        h_max = np.maximum(hx, hy)
        information_1 = np.where(h_max > 0, (hxy - hxy1) / h_max, np.nan)
    hxy2 = _entropies(pxpy)
    return np.stack([
        np.sum(flat * flat, axis=1),
        p_diff @ k_diff**2,
        correlation,
        var_x,
        np.sum(p / (1.0 + (i - j) ** 2), axis=(1, 2)),
        sum_average,
        np.sum((k_sum - sum_average[:, None]) ** 2 * p_sum, axis=1),
        _entropies(p_sum),
        hxy,
        np.sum((k_diff - mean_diff[:, None]) ** 2 * p_diff, axis=1),
        _entropies(p_diff),
        information_1,
        np.sqrt(np.maximum(0.0, 1.0 - np.exp(-2.0 * (hxy2 - hxy)))),
        _maximal_correlations(p, px, py),
    ], axis=1)


def haralick(gray: np.ndarray) -> np.ndarray:
    """The 14 Haralick features of a gray image, averaged over 0, 45, 90 and 135 degrees (docs/features.md#image).

    32 levels (``quantize``), distance 1, symmetric normalised GLCMs (``glcm``), each feature computed
    per direction (``haralick_from_glcm``) and then averaged. f3 and f12 are NaN for a constant image.

    Parameters
    ----------
    gray : 2-D array
        Gray values in 0..255, at least 2 x 2 px.

    Returns
    -------
    (14,) float array
        ``haralick_01`` .. ``haralick_14``.

    Raises
    ------
    ValueError
        If ``gray`` is not a 2-D array of finite values of at least 2 x 2 px.

    Examples
    --------
    >>> stripes = np.tile([0.0, 255.0], (4, 2))  # columns of levels 0 and 31 in turn
    >>> haralick(stripes)[:2].tolist()  # ASM 0.5 in every direction; contrast 31^2 at 0, 45, 135 degrees
    [0.5, 720.75]
    """
    return _haralick(_check_gray(gray, min_side=2, purpose="the GLCM"))


def _haralick(image: np.ndarray) -> np.ndarray:
    return _haralick_from_counts(_direction_counts(_quantize(image, GLCM_LEVELS), GLCM_LEVELS))


def _haralick_from_counts(directions: list[np.ndarray]) -> np.ndarray:
    """:func:`haralick` from the pair counts of the four directions (:func:`_direction_counts`)."""
    return np.mean(_haralick_features(np.stack([_symmetric_normalised(counts) for counts in directions])), axis=0)


def tamura_coarseness(gray: np.ndarray, kmax: int = TAMURA_KMAX) -> float:
    """Tamura coarseness F_crs (Tamura et al. 1978, eqs. 1-4; docs/features.md#image), mean best window size in px.

    For k = 1..kmax, with ``A_k`` the mean over a 2^k x 2^k window: at pixel (r, c) the horizontal
    difference compares the windows on columns [c-2^k, c-1] and [c, c+2^k-1] (rows
    [r-2^(k-1), r+2^(k-1)-1]); the vertical difference is the same transposed; ``E_k`` is the larger
    absolute difference. ``S_best = 2^k`` for the k with the largest ``E_k``; the smallest k wins ties, and
    values within ``1e-9 * max(gray)`` of the largest count as ties (interpretation: the first k whose
    ``E_k`` reaches ``max_k E_k - tol``). The feature is the mean of ``S_best`` over the pixels whose row
    and column lie in [2^kmax, size - 2^kmax], where every window fits.

    The window sums are built as a pyramid: each level adds four windows of the level below, so every
    sum is a short fixed-order float64 sum (no running or integral-image sums, whose rounding grows with
    the image and would break exact ties).

    Parameters
    ----------
    gray : 2-D array
        Gray values, at least ``2 * 2^kmax`` px on each side.
    kmax : int
        The largest window is ``2^kmax`` px (at least 1).

    Returns
    -------
    float
        The mean best window size in px, between 2 and ``2^kmax``.

    Raises
    ------
    ValueError
        If ``kmax < 1``, or ``gray`` is too small, not 2-D or not finite.

    Examples
    --------
    >>> stripes = np.tile(np.repeat([0.0, 255.0], 8), (80, 6))[:, :95]  # vertical stripes 8 px wide
    >>> tamura_coarseness(stripes)  # columns 32..63 hold four whole stripes
    3.5
    """
    if kmax < 1:
        raise ParameterError(f"kmax must be at least 1, got {kmax}")
    image = _check_gray(gray, min_side=2 * 2**kmax, purpose=f"Tamura coarseness with kmax={kmax}")
    return _tamura_coarseness(image, kmax, 1e-9 * float(image.max()))


def _tamura_coarseness_of_photo(gray: np.ndarray, high: float) -> float:
    """:func:`tamura_coarseness` of the gray image of an 8-bit photo whose largest value is ``high``.

    :func:`features.kernels.tamura_coarseness_total` runs on the integers ``rint(1000 gray)``, which are
    exactly ``299 R + 587 G + 114 B`` for such an image: then every window sum and difference is exact in
    int32 (at most 1024 * 255000 < 2^31). The decisions equal the float64 ones: distinct ``E_k`` differ by
    at least 1 / (1000 * 4^kmax) ~ 1e-6 gray levels, far more than the tie tolerance (at most 2.6e-7 for
    gray values up to 255) and float64 rounding, while equal ones stay equal (within rounding) in float64.
    """
    # The tolerance in the kernel's unit, 1 / (1000 * 4^kmax) gray levels; for integers E >= M - tol is
    # E >= M - floor(tol).
    tolerance = math.floor(1e-9 * high * 1000 * 4**TAMURA_KMAX)
    margin = 2**TAMURA_KMAX
    h, w = gray.shape
    return kernels.tamura_coarseness_total(gray, tolerance) / ((h - 2 * margin + 1) * (w - 2 * margin + 1))


def _tamura_coarseness(image: np.ndarray, kmax: int, tolerance: float) -> float:
    """Tamura coarseness of float64 gray values, with the tie ``tolerance`` in gray levels, tile by tile."""
    margin = 2**kmax
    h, w = image.shape
    dtype = image.dtype
    # Sums over 4^k pixels scaled by 4^(kmax-k) put every E_k in units of 1 / 4^kmax of ``image``'s unit.
    tolerance *= 4**kmax
    out_rows, out_cols = h - 2 * margin + 1, w - 2 * margin + 1
    tile_rows, tile_cols = min(_TAMURA_TILE[0], out_rows), min(_TAMURA_TILE[1], out_cols)
    in_shape = (tile_rows + 2 * margin - 1, tile_cols + 2 * margin - 1)
    pair_buffer, *level_buffers = (np.empty(in_shape, dtype) for _ in range(3))
    horizontal_buffer, vertical_buffer = np.empty((2, tile_rows, tile_cols), dtype)
    prefix_buffers = np.empty((kmax, tile_rows, tile_cols), dtype)
    hit_buffer = np.empty((tile_rows, tile_cols), np.uint8)
    total = 0
    for row, row_stop in spans(out_rows, tile_rows):
        for col, col_stop in spans(out_cols, tile_cols):
            n, m = row_stop - row, col_stop - col
            # Tile-local (i, j) is image pixel (row + i, col + j); output pixels are i = margin .. margin+n-1,
            # j = margin .. margin+m-1. Level k holds the window sum with its top-left corner at (i, j).
            level = image[row:row_stop + 2 * margin - 1, col:col_stop + 2 * margin - 1]
            prefixes: list[np.ndarray] = []
            for k in range(1, kmax + 1):
                size, half = 2**k, 2 ** (k - 1)
                rows, cols = level.shape
                pairs = cv2.add(level[:-half], level[half:], dst=pair_buffer[:rows - half, :cols])
                level = cv2.add(pairs[:, :-half], pairs[:, half:],
                                dst=level_buffers[k % 2][:rows - half, :cols - half])
                beside = level[margin - half:margin - half + n]  # top rows of the side-by-side windows
                left = margin - size
                horizontal = cv2.absdiff(beside[:, margin:margin + m], beside[:, left:left + m],
                                         dst=horizontal_buffer[:n, :m])
                stacked = level[:, margin - half:margin - half + m]  # left columns of the stacked windows
                vertical = cv2.absdiff(stacked[margin:margin + n], stacked[left:left + n],
                                       dst=vertical_buffer[:n, :m])
                first = prefix_buffers[0, :n, :m]
                contrast = cv2.max(horizontal, vertical, dst=first if k == 1 else horizontal)
                if k < kmax:
                    np.multiply(contrast, 4 ** (kmax - k), out=contrast)
                # prefix_k = max(E_1 .. E_k): the first k whose prefix reaches max_k E_k - tol is S_best's k.
                if k > 1:
                    contrast = cv2.max(prefixes[-1], contrast, dst=prefix_buffers[k - 1, :n, :m])
                prefixes.append(contrast)
            threshold = np.subtract(prefixes[-1], tolerance, out=prefixes[-1])
            hit = hit_buffer[:n, :m]
            previous = 0
            for k, prefix in enumerate(prefixes[:-1], start=1):
                count = cv2.countNonZero(cv2.compare(prefix, threshold, cv2.CMP_GE, dst=hit))
                total += 2**k * (count - previous)
                previous = count
            total += 2**kmax * (n * m - previous)
    return total / (out_rows * out_cols)


def tamura_contrast(gray: np.ndarray) -> float:
    """Tamura contrast ``sigma / kurt^(1/4)`` with ``kurt = mu4 / sigma^4`` (Tamura et al. 1978, eq. 5).

    Population moments over all pixels; 0 for a constant image (docs/features.md#image), tested as min == max because
    ``x - mean(x)`` of a constant need not be exactly 0.

    Parameters
    ----------
    gray : array
        Gray values (2-D; other shapes are taken as one row).

    Returns
    -------
    float
        The contrast; 0 for a constant or empty image.

    Examples
    --------
    >>> tamura_contrast(np.array([[0.0, 255.0]]))  # sigma 127.5, kurtosis 1
    127.5
    >>> tamura_contrast(np.full((3, 3), 9.0))
    0.0
    """
    values = np.asarray(gray, dtype=np.float64)
    values = values if values.ndim == 2 else values.reshape(1, -1)
    if values.size == 0:
        return 0.0
    low, high = values.min(), values.max()
    return _tamura_contrast(values, _mean(values), low == high)


def _tamura_contrast(values: np.ndarray, mean: float, constant: bool) -> float:
    if constant:
        return 0.0
    # One compiled pass, not a BLAS dot product, whose threads would make the rounding vary with their
    # number (extract_many's workers run one thread each).
    second, fourth = kernels.central_moment_sums(np.ascontiguousarray(values), mean)
    variance = second / values.size
    kurtosis = fourth / values.size / variance**2
    return float(np.sqrt(variance) / kurtosis**0.25)


_LBP_POINTS = 8
_LBP_RADIUS = 1.0


def _lbp_offsets() -> tuple[np.ndarray, np.ndarray]:
    """Neighbour offsets (rows, columns) exactly as scikit-image computes them: rounded to 5 decimals."""
    angles = 2 * np.pi * np.arange(_LBP_POINTS, dtype=np.float64) / _LBP_POINTS
    return np.round(-_LBP_RADIUS * np.sin(angles), 5), np.round(_LBP_RADIUS * np.cos(angles), 5)


@functools.cache
def _uniform_labels() -> np.ndarray:
    """Label of each 8-bit code (bit p = neighbour p >= centre) under scikit-image's "uniform" method.

    A code with at most two 0/1 changes between consecutive neighbours 0..7 (not wrapping around) is
    labelled by its number of ones, any other code 9 (Ojala et al. 2002, LBP^riu2). Made once (read-only).
    """
    codes = np.arange(256)
    bits = (codes[:, None] >> np.arange(_LBP_POINTS)) & 1
    changes = np.abs(np.diff(bits, axis=1)).sum(axis=1)
    labels = np.where(changes <= 2, bits.sum(axis=1), _LBP_POINTS + 1)
    labels.flags.writeable = False
    return labels


def _interpolation_weights(n: int, offset: float) -> tuple[np.ndarray, np.ndarray]:
    """``(1 - f, f)``, ``f = x - floor(x)`` for ``x = index + offset``, index 0..n-1, rounded as skimage."""
    position = np.arange(n, dtype=np.float64) + offset
    fraction = position - np.floor(position)
    return 1 - fraction, fraction


def lbp_histogram(gray: np.ndarray) -> np.ndarray:
    """Normalised histogram of rotation-invariant uniform LBP codes, P = 8, R = 1 (docs/features.md#image,
    ``lbp_0..9``).

    The codes are those of ``skimage.feature.local_binary_pattern(gray, 8, 1, method="uniform")``,
    reproduced bit for bit in one pass (:func:`features.kernels.lbp_code_counts`): neighbours on the axes
    are pixels, the four diagonal ones are bilinearly interpolated at offsets of +-0.70711 px with
    scikit-image's weights and operation order, and a neighbour counts as 1 when it is >= the centre. The
    histogram runs over the pixels at least 1 px from the border and sums to 1.

    Parameters
    ----------
    gray : 2-D array
        Gray values, at least 3 x 3 px.

    Returns
    -------
    (10,) float array
        Shares of labels 0..9.

    Raises
    ------
    ValueError
        If ``gray`` is not a 2-D array of finite values of at least 3 x 3 px.

    Examples
    --------
    >>> spot = np.zeros((3, 3))
    >>> spot[1, 1] = 9.0  # one inner pixel, brighter than all its neighbours: code 0, label 0
    >>> lbp_histogram(spot).tolist()
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    >>> lbp_histogram(9.0 - spot).tolist()  # darker than all: eight ones, label 8
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    """
    return _lbp_histogram(_check_gray(gray, min_side=3, purpose="LBP"))


def _lbp_histogram(image: np.ndarray) -> np.ndarray:
    """:func:`lbp_histogram` by :func:`features.kernels.lbp_code_counts`, one pass over the image.

    scikit-image interpolates at absolute coordinates, so the weights differ (in the last bits) per row and
    column: rows for the neighbours above and below, columns for those right and left.
    """
    h, w = image.shape
    diagonal = float(abs(_lbp_offsets()[0][1]))
    code_counts = kernels.lbp_code_counts(np.ascontiguousarray(image), _interpolation_weights(w, diagonal),
                                          _interpolation_weights(w, -diagonal),
                                          _interpolation_weights(h, -diagonal), _interpolation_weights(h, diagonal))
    histogram = np.bincount(_uniform_labels(), weights=code_counts, minlength=LBP_BINS)
    return histogram / histogram.sum()
