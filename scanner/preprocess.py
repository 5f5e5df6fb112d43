"""Preprocessing of raw scanner signals (docs/features.md#preprocessing): pure functions, no state, no I/O.

Slide signals go band limit -> 1 s window -> DFT321, in that order (docs/features.md#preprocessing): filtering the
whole recording first keeps the filter transients out of the window. The quality checks used by the guided session live
here too, because they are decided on the same preprocessed signals.

Quality checks come in two forms. ``check_*`` functions return a list of human-readable problems (empty
means the step is fine), which is what a session shows before offering a redo. :func:`slide_window` and
:func:`slide_signal` raise :class:`QualityError` instead, because without a slide there is no window to
return; its message is the same problem text.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import lru_cache

import numpy as np

from scanner.lazy import jit, library
from scanner.scan import Trace
from taxonomy.errors import ParameterError, TexplorerError

signal = library("scipy.signal")

IMAGE_BORDER_PX = 100
"""Pixels cropped from every border of a photo before any image feature (docs/features.md#preprocessing)."""

MIN_CROPPED_SIDE_PX = 2
"""Smallest side of the cropped photo any image feature is defined on: a GLCM needs a pair of neighbours."""

MIN_PHOTO_SIDE_PX = 2 * IMAGE_BORDER_PX + MIN_CROPPED_SIDE_PX
"""Smallest side of a photo with image features (202 px): below it the image family and TacTUM's macro
features of the photos are missing."""


def small_photo_note(height: int, width: int) -> str | None:
    """One line when photos of ``height`` x ``width`` px are too small for any image feature, else None."""
    if min(height, width) >= MIN_PHOTO_SIDE_PX:
        return None
    return (f"photos of {width} x {height} px leave nothing for the image features after the {IMAGE_BORDER_PX} px "
            f"border crop: they need at least {MIN_PHOTO_SIDE_PX} x {MIN_PHOTO_SIDE_PX} px, so the image features "
            "and TacTUM's MaCo and MaRG will be missing")

VIBRATION_FS = 3000.0
"""Sample rate of the DAQ channels (accelerometer, IR, FSR, flex, metal), Hz."""

AUDIO_FS = 44100.0
"""Sample rate of the microphone, Hz."""

BAND_HZ = (10.0, 1000.0)
"""Pass band of the slide vibration signals (docs/features.md#preprocessing)."""

WINDOW_SECONDS = 1.0
"""Length of the slide window cut from each slide recording (docs/features.md#preprocessing)."""

NO_SLIDE = "no slide detected"
SHORT_WINDOW = "window shorter than 1 s"
CLIPPED = "clipped"
NO_CONTACT = "no contact force"


class QualityError(TexplorerError, ValueError):
    """A recorded step fails a quality check; the message is the problem as shown to the operator."""


def crop_image(image: np.ndarray, border: int = IMAGE_BORDER_PX) -> np.ndarray:
    """Remove ``border`` pixels from every side of an (h, w[, 3]) image (docs/features.md#preprocessing).

    The scanner's photo unit TU3 vignettes at the borders; cropping keeps only the evenly lit centre.
    """
    h, w = image.shape[:2]
    if h <= 2 * border or w <= 2 * border:
        raise ParameterError(f"image of {h}x{w} px is too small to crop {border} px from every border")
    return image[border:h - border, border:w - border]


def grayscale(rgb: np.ndarray) -> np.ndarray:
    """Luma ``0.299 R + 0.587 G + 0.114 B`` as float64 in 0..255, not rounded (ITU-R BT.601;
    docs/features.md#preprocessing)."""
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ParameterError(f"expected an RGB image of shape (h, w, 3), got {rgb.shape}")
    # Channel by channel with one scratch array: the same IEEE operations, in the same order, as the
    # expression in the docstring, without a (h, w, 3) float64 copy (seconds on a 12 MP photo).
    gray = np.multiply(rgb[..., 0], 0.299, dtype=np.float64)
    scratch = np.multiply(rgb[..., 1], 0.587, dtype=np.float64)
    gray += scratch
    np.multiply(rgb[..., 2], 0.114, out=scratch, dtype=np.float64)
    gray += scratch
    return gray


def gray_uint8(gray: np.ndarray) -> np.ndarray:
    """8-bit version of a float gray image: ``floor(gray + 0.5)`` clipped to 0..255 (docs/features.md#preprocessing)."""
    return np.clip(np.floor(np.asarray(gray, dtype=np.float64) + 0.5), 0, 255).astype(np.uint8)


def _axes(v: np.ndarray) -> np.ndarray:
    """A recording as (n, axes) float64; a 1-D recording is one axis."""
    array = np.asarray(v, dtype=np.float64)
    if array.ndim == 1:
        return array[:, None]
    if array.ndim != 2:
        raise ParameterError(f"expected a recording of shape (n,) or (n, axes), got {array.shape}")
    return array


def slide_start(v: np.ndarray, *, fs: float = VIBRATION_FS, frame: int = 30, noise_frames: int = 25,
                factor: float = 10.0) -> int | None:
    """Sample index where a slide starts in a resting-then-sliding vibration recording (docs/features.md#preprocessing).

    Each axis loses its mean over the first 0.25 s (gravity and offset). The frame energy is the sum of the
    squared samples over a ``frame``-sample frame (10 ms) and over all axes; the noise level is the mean
    energy of the first ``noise_frames`` frames. The start is the first frame, searching from frame 0 and
    ignoring a trailing partial frame, whose energy is strictly greater than ``factor`` x noise.

    Parameters
    ----------
    v : array of shape (n, axes) or (n,)
        Acceleration in g.
    fs : float
        Sample rate in Hz (fixes the 0.25 s baseline).
    frame, noise_frames, factor
        Frame length in samples, frames in the noise estimate, threshold over the noise level.

    Returns
    -------
    int or None
        Start sample index (frame index x ``frame``), or None if no frame exceeds the threshold.

    Raises
    ------
    QualityError
        If the recording holds fewer than ``noise_frames`` whole frames (no noise level to compare with).
    """
    a = _axes(v)
    n_frames = a.shape[0] // frame
    if n_frames < noise_frames:
        raise QualityError(f"{SHORT_WINDOW}: {a.shape[0]} samples hold fewer than the {noise_frames} "
                           f"frames of {frame} samples needed for the noise level")
    baseline = a[:int(round(0.25 * fs))].mean(axis=0)
    centred = a[:n_frames * frame] - baseline
    energy = np.sum((centred**2).reshape(n_frames, frame, a.shape[1]), axis=(1, 2))
    noise = energy[:noise_frames].mean()
    above = np.flatnonzero(energy > factor * noise)
    return None if above.size == 0 else int(above[0]) * frame


def _exact_samples(seconds: float | Fraction, fs: float, what: str) -> int:
    count = Fraction(seconds) * Fraction(fs)
    if count.denominator != 1:
        raise ParameterError(f"{what} at {float(count):g} is not a whole sample at {fs:g} Hz")
    return int(count)


@lru_cache(maxsize=64)
def _window_samples(start: int, fs: float, audio_fs: float, seconds: float) -> tuple[int, int, int]:
    """Audio start, vibration length and audio length of a window in whole samples; ValueError if one is
    not whole."""
    return (_exact_samples(Fraction(start) / Fraction(fs), audio_fs, "audio start"),
            _exact_samples(seconds, fs, "window length"),
            _exact_samples(seconds, audio_fs, "audio window length"))


@dataclass(frozen=True)
class SlideWindow:
    """The 1 s slide window shared by the vibration, IR and audio of one slide (docs/features.md#preprocessing).

    ``start`` is the vibration sample index from :func:`slide_start`. IR is sampled with the vibration, so
    it uses the same samples; audio starts at ``start * audio_fs / fs``, which must be a whole sample
    (it is for every 10 ms frame boundary: 30 samples at 3000 Hz are 441 at 44100 Hz).

    Examples
    --------
    >>> w = SlideWindow(1500)
    >>> w.vibration, w.audio
    (slice(1500, 4500, None), slice(22050, 66150, None))
    """

    start: int
    fs: float = VIBRATION_FS
    audio_fs: float = AUDIO_FS
    seconds: float = WINDOW_SECONDS

    def __post_init__(self) -> None:
        if isinstance(self.start, bool) or int(self.start) != self.start or self.start < 0:
            raise ParameterError(f"window start must be a non-negative sample index, got {self.start!r}")
        object.__setattr__(self, "start", int(self.start))
        # Checked and kept once: exact fractions cost more than everything else a window does.
        object.__setattr__(self, "_samples", _window_samples(self.start, self.fs, self.audio_fs, self.seconds))

    @property
    def length(self) -> int:
        """Samples of vibration (and IR) in the window: 3000."""
        return self._samples[1]

    @property
    def audio_start(self) -> int:
        """First audio sample: ``start x audio_fs / fs``, exact."""
        return self._samples[0]

    @property
    def audio_length(self) -> int:
        """Samples of audio in the window: 44100."""
        return self._samples[2]

    @property
    def vibration(self) -> slice:
        """Vibration samples of the window."""
        return slice(self.start, self.start + self.length)

    @property
    def ir(self) -> slice:
        """IR reflectance samples of the window (recorded on the DAQ with the vibration)."""
        return self.vibration

    @property
    def audio(self) -> slice:
        """Audio samples of the window."""
        return slice(self.audio_start, self.audio_start + self.audio_length)


def slide_window(v: np.ndarray, *, fs: float = VIBRATION_FS, audio_samples: int | None = None,
                 ir_samples: int | None = None, audio_fs: float = AUDIO_FS, frame: int = 30,
                 noise_frames: int = 25, factor: float = 10.0) -> SlideWindow:
    """The 1 s window after the slide start of a vibration recording (docs/features.md#preprocessing).

    ``audio_samples`` and ``ir_samples``, when given, are the lengths of the parallel audio and IR
    recordings, which must hold the whole window too.

    Raises
    ------
    QualityError
        "no slide detected" if no frame exceeds the threshold; "window shorter than 1 s" if less than
        1 s of any of the recordings follows the start.
    """
    start = slide_start(v, fs=fs, frame=frame, noise_frames=noise_frames, factor=factor)
    return window_at(start, len(v), fs=fs, audio_samples=audio_samples, ir_samples=ir_samples, audio_fs=audio_fs)


def window_at(start: int | None, n: int, *, fs: float = VIBRATION_FS, audio_samples: int | None = None,
              ir_samples: int | None = None, audio_fs: float = AUDIO_FS) -> SlideWindow:
    """:func:`slide_window` from a slide start already found (:func:`slide_start`; ``n`` vibration samples),
    with the same checks and errors."""
    if start is None:
        raise QualityError(NO_SLIDE)
    window = SlideWindow(start, fs=fs, audio_fs=audio_fs)
    lengths = {"vibration": (n, window.vibration, fs), "IR": (ir_samples, window.ir, fs),
               "audio": (audio_samples, window.audio, audio_fs)}
    for what, (n, part, rate) in lengths.items():
        if n is not None and n < part.stop:
            raise QualityError(f"{SHORT_WINDOW}: {what} has {max(n - part.start, 0) / rate:.3f} s "
                               f"after the slide start at {start / fs:.3f} s")
    return window


def check_slide(v: np.ndarray, *, fs: float = VIBRATION_FS, audio_samples: int | None = None,
                ir_samples: int | None = None, factor: float = 10.0) -> list[str]:
    """Problems of a slide recording: "no slide detected", "window shorter than 1 s: ..." or none.

    The same decision as :func:`slide_window`, as a list for the session's redo prompt.
    """
    try:
        slide_window(v, fs=fs, audio_samples=audio_samples, ir_samples=ir_samples, factor=factor)
    except QualityError as problem:
        return [str(problem)]
    return []


def check_clipped(volts: np.ndarray, low: float = 0.0, high: float = 5.0) -> list[str]:
    """["clipped: ..."] if any sample reached the input range ``[low, high]`` V, else [].

    A sample at or beyond a rail is counted: a saturated ADC or sensor output sits exactly at it.
    """
    values = np.asarray(volts, dtype=np.float64)
    if not low < high:
        raise ParameterError(f"clipping range must have low < high, got [{low}, {high}]")
    at_rail = int(np.count_nonzero((values <= low) | (values >= high)))
    if at_rail == 0:
        return []
    return [f"{CLIPPED}: {at_rail} of {values.size} samples at the {low:g}..{high:g} V limits"]


def check_contact(force: np.ndarray, min_newtons: float = 0.5) -> list[str]:
    """["no contact force: ..."] if the force never reaches ``min_newtons``, else [].

    The default 0.5 N is about five times the unloaded FSR reading of eq. 1 (0.098 N at 0 V), so resting
    the unit on a sample without pressing does not pass.
    """
    values = np.asarray(force, dtype=np.float64)
    if values.size == 0:
        return [f"{NO_CONTACT}: the recording is empty"]
    peak = float(values.max())
    if peak >= min_newtons:
        return []
    return [f"{NO_CONTACT}: peak {peak:.3f} N is below {min_newtons:g} N"]


@lru_cache(maxsize=8)
def _bandpass(fs: float) -> tuple[np.ndarray, np.ndarray, int]:
    """The band-pass as second-order sections, ``sosfilt_zi`` of them and ``sosfiltfilt``'s default pad
    length (read-only)."""
    sos = signal.butter(4, list(BAND_HZ), btype="bandpass", fs=fs, output="sos")
    zi = signal.sosfilt_zi(sos)
    padlen = 3 * (2 * len(sos) + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum()))
    sos.flags.writeable = zi.flags.writeable = False
    return sos, zi, int(padlen)


def band_limit(v: np.ndarray, fs: float = VIBRATION_FS) -> np.ndarray:
    """Each axis band-limited to 10-1000 Hz, zero phase (docs/features.md#preprocessing).

    ``scipy.signal.butter(4, [10, 1000], btype="bandpass", fs=fs, output="sos")`` applied forward and
    backward with ``sosfiltfilt`` along the samples of the *whole* recording.

    Parameters
    ----------
    v : array of shape (n,) or (n, axes)
    fs : float
        Sample rate in Hz; must exceed 2000 Hz so the upper band edge lies below Nyquist.
    """
    array = np.asarray(v, dtype=np.float64)
    if fs <= 2 * BAND_HZ[1]:
        raise ParameterError(f"sample rate {fs:g} Hz is too low for a {BAND_HZ[1]:g} Hz band edge")
    sos, zi, padlen = _bandpass(float(fs))
    if array.shape[0] <= padlen:
        raise ParameterError(f"recording of {array.shape[0]} samples is too short to band-limit "
                         f"(needs more than {padlen})")
    return _sosfiltfilt(sos, zi, padlen, array)


def _sosfiltfilt(sos: np.ndarray, zi: np.ndarray, padlen: int, x: np.ndarray) -> np.ndarray:
    """``scipy.signal.sosfiltfilt(sos, x, axis=0)`` with its ``sosfilt_zi`` (``zi``) and pad length
    given, step by step as scipy takes them: odd extension, the forward pass started from the steady
    state of the first sample, the backward pass from that of the last output. The passes are
    :func:`_sosfilt_rows`, in a third less time; the result is scipy's to rounding (the compiled passes may
    fuse a multiply and an add, which scipy's C loop rounds separately; the tests bound the difference)."""
    columns = x.reshape(x.shape[0], -1)
    # scipy's odd extension: the ends mirrored through the end samples
    forward = np.concatenate((2 * columns[:1] - columns[padlen:0:-1], columns,
                              2 * columns[-1:] - columns[-2:-(padlen + 2):-1]))
    _sosfilt_rows(sos, forward, zi[:, :, None] * forward[0], False)
    _sosfilt_rows(sos, forward, zi[:, :, None] * forward[-1], True)  # in place, last sample first
    return forward[padlen:-padlen].reshape(x.shape)


@jit(cache=True, nogil=True)  # nogil: extractions run in several threads (the web app)
def _sosfilt_rows(sos: np.ndarray, x: np.ndarray, state: np.ndarray, backwards: bool) -> None:
    """``scipy.signal.sosfilt`` along axis 0 of ``x`` (samples, signals) in place, from the last sample to the
    first if ``backwards``, from the filter state ``state`` (sections, 2, signals), updated: the transposed
    direct form II of scipy's ``_sosfilt``, the same operations in the same order, only one sample of every
    signal at a time."""
    n = x.shape[0]
    for step in range(n):
        k = n - 1 - step if backwards else step
        for i in range(x.shape[1]):
            current = x[k, i]
            for s in range(sos.shape[0]):
                output = sos[s, 0] * current + state[s, 0, i]
                state[s, 0, i] = sos[s, 1] * current - sos[s, 4] * output + state[s, 1, i]
                state[s, 1, i] = sos[s, 2] * current - sos[s, 5] * output
                current = output
            x[k, i] = current


def dft321(a: np.ndarray) -> np.ndarray:
    """Combine the axes of a vibration into one signal with the same spectrum energy (Landin et al. 2010).

    With ``A_x, A_y, A_z`` the FFTs of the axes, bin k of the result has magnitude
    ``sqrt(|A_x|^2 + |A_y|^2 + |A_z|^2)`` and the phase of ``A_x + A_y + A_z`` for k = 0..N//2; the
    other bins are the complex conjugate mirror and the result is the real part of the inverse FFT
    (docs/features.md#preprocessing). It preserves energy, ``sum(y^2) == sum over axes of sum(a^2)``, for even and odd
    N.

    Parameters
    ----------
    a : array of shape (n, axes) or (n,)

    Returns
    -------
    ndarray of shape (n,)
        A single axis is returned unchanged (as a copy).
    """
    array = _axes(a)
    if array.shape[1] == 1:
        # The formula is the identity for one axis; skipping it keeps the samples bit-exact.
        return array[:, 0].copy()
    n = array.shape[0]
    spectra = np.fft.rfft(array, axis=0)
    magnitude = np.sqrt(np.sum(spectra.real**2 + spectra.imag**2, axis=1))
    phase = np.angle(np.sum(spectra, axis=1))
    return np.fft.irfft(magnitude * np.exp(1j * phase), n=n)


def slide_signal(trace: Trace, window: SlideWindow | None = None) -> np.ndarray:
    """The slide signal ``v`` (from ``v_ts``) or ``v_f`` (from ``v_fs``): band limit, window, DFT321.

    docs/features.md#preprocessing, in that order. ``window`` defaults to the one detected on ``trace`` itself.

    Raises
    ------
    QualityError
        If no slide is detected or less than 1 s follows the start.
    """
    data = trace.data
    if window is None:
        window = slide_window(data, fs=trace.fs)
    if window.vibration.stop > trace.n:
        raise QualityError(f"{SHORT_WINDOW}: {(trace.n - window.start) / trace.fs:.3f} s after the start")
    return dft321(band_limit(data, trace.fs)[window.vibration])


def remove_friction_offset(f_frt: np.ndarray, fs: float = VIBRATION_FS) -> np.ndarray:
    """``f_frt`` minus its mean over the first 0.1 s (300 samples at 3000 Hz), docs/features.md#preprocessing.

    The tangential FSR is preloaded by the casing; the unit does not touch the sample at first, so that
    mean is the zero of the friction force. A recording shorter than 0.1 s uses all of it.
    """
    values = np.asarray(f_frt, dtype=np.float64)
    if values.ndim != 1 or values.size == 0:
        raise ParameterError(f"f_frt must be a non-empty 1-D force trace, got shape {values.shape}")
    return values - values[:int(round(0.1 * fs))].mean()
