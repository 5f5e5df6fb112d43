"""Audio features, 35 per signal (docs/features.md#audio; paper section IV-D).

The paper computes "35 well-known audio features" with the MATLAB toolbox of Giannakopoulos & Pikrakis
(*Introduction to Audio Analysis: A MATLAB Approach*, 2014; repository
``pikrakis/Introduction-to-Audio-Analysis---a-MATLAB-approach``, ``library/stFeatureExtraction.m`` and the
``feature_*.m`` files it calls). This module follows that toolbox's formulas, rewritten for frame matrices:
every family function takes a 2-D array with one frame (or one frame's spectrum) per row and returns one
value (or one vector) per row, with no loop over frames.

Short-term analysis (``stFeatureExtraction.m``): window ``round(0.050 fs)`` and step ``round(0.025 fs)``
samples with MATLAB rounding (half away from zero: 2205 and 1103 at 44.1 kHz, 38 frames in 1 s); each frame
is multiplied by a symmetric Hamming window; its spectrum is ``|fft(frame)| / N`` over the first
``ceil(N/2)`` bins (``getDFT.m``); a frame with ``sum(|frame|) <= eps`` is silent and contributes zeros to
every feature. Each feature of ``compute`` is the mean over the frames. Deliberate differences from the
toolbox (docs/features.md#audio): the columns are in ``NAMES`` order (the toolbox puts the MFCCs before the harmonic
ratio and F0), and the toolbox's 3-point median filter on its last feature row (meant for F0, it hits the
12th chroma value) is not applied.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from features import kernels
from scanner.lazy import jit, library
from taxonomy.errors import ParameterError

cv2 = library("cv2")
sp_fft = library("scipy.fft")

EPS = float(np.finfo(np.float64).eps)
"""MATLAB's ``eps`` (2^-52): the toolbox's guard against division by zero and ``log(0)``."""

WINDOW_S = 0.050
STEP_S = 0.025
N_BLOCKS = 10
ROLLOFF_C = 0.90
N_MFCC = 13
N_CHROMA = 12
AUTOCORR_TOL = 1e-12
"""Autocorrelation values within this fraction of ``R(0)`` are FFT round-off and count as exactly 0."""
MIN_WINDOW = 20
"""Shortest window (samples) for which the 10 spectral sub-bands of the entropy are non-empty."""

NAMES: tuple[str, ...] = (
    "zcr",
    "energy",
    "energy_entropy",
    "spectral_centroid",
    "spectral_spread",
    "spectral_entropy",
    "spectral_flux",
    "spectral_rolloff",
    "harmonic_ratio",
    "f0",
    *(f"mfcc_{i:02d}" for i in range(1, N_MFCC + 1)),
    *(f"chroma_{i:02d}" for i in range(1, N_CHROMA + 1)),
)
"""The 35 feature names in column order; the caller prefixes them with ``audio.finger.``/``audio.tool.``."""


def matlab_round(x: float) -> int:
    """Round half away from zero, as MATLAB's ``round`` (numpy rounds half to even: 1102.5 -> 1102).

    Computed from the exact fractional part, so 0.49999999999999994 still rounds down.

    Parameters
    ----------
    x : float
        The value to round.

    Returns
    -------
    int
        The nearest integer; halves go away from zero.

    Examples
    --------
    >>> matlab_round(1102.5), matlab_round(-2.5), round(1102.5), matlab_round(0.49999999999999994)
    (1103, -3, 1102, 0)
    """
    magnitude = abs(x)
    floor = math.floor(magnitude)
    rounded = floor + 1 if magnitude - floor >= 0.5 else floor
    return int(math.copysign(rounded, x))


def window_and_step(fs: float) -> tuple[int, int]:
    """Window and step in samples, ``round(0.050 fs)`` and ``round(0.025 fs)`` (``stFeatureExtraction.m``).

    Parameters
    ----------
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    window, step : int
        The frame length and the hop between frame starts, rounded as MATLAB does (:func:`matlab_round`).

    Examples
    --------
    >>> window_and_step(44100.0)  # 1102.5 rounds up
    (2205, 1103)
    """
    return matlab_round(WINDOW_S * fs), matlab_round(STEP_S * fs)


def frames(signal: np.ndarray, fs: float = 44100.0) -> np.ndarray:
    """Hamming-windowed short-term frames, one per row, shape ``(n_frames, N)``.

    ``n_frames = floor((L - N) / step) + 1`` frames start at ``0, step, 2 step, ...`` and each is
    multiplied by the symmetric Hamming window ``0.54 - 0.46 cos(2 pi n / (N - 1))`` (MATLAB
    ``window(@hamming, N)``), as in ``stFeatureExtraction.m``.

    Parameters
    ----------
    signal : np.ndarray
        1-D real audio samples, at least one window long.
    fs : float
        Sampling rate in Hz; it sets the window and step (:func:`window_and_step`).

    Returns
    -------
    np.ndarray
        ``(n_frames, N)`` float64: the windowed frames, one per row.

    Raises
    ------
    ValueError
        If ``fs`` is not a positive finite number or gives a window under 20 samples, or the signal is
        not 1-D, not finite, or shorter than one window.

    Examples
    --------
    >>> framed = frames(np.ones(40), fs=400.0)  # window 20, step 10: (40 - 20) // 10 + 1 = 3 frames
    >>> framed.shape, np.round(framed[0, [0, 10, 19]], 4).tolist()  # a constant shows the Hamming window
    ((3, 20), [0.08, 0.9937, 0.08])
    """
    x = _checked_signal(signal, fs)
    window, step = window_and_step(fs)
    n_frames = (x.size - window) // step + 1
    framed = np.lib.stride_tricks.as_strided(x, (n_frames, window), (step * x.strides[0], x.strides[0]),
                                             writeable=False)
    return framed * _hamming(window)


@lru_cache(maxsize=8)
def _hamming(window: int) -> np.ndarray:
    """``np.hamming(window)``, made once per window length (read-only)."""
    weights = np.hamming(window)
    weights.flags.writeable = False
    return weights


def spectrum(framed: np.ndarray) -> np.ndarray:
    """Magnitude spectra ``|fft(frame)| / N`` over the first ``ceil(N/2)`` bins (``getDFT.m``).

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).

    Returns
    -------
    np.ndarray
        ``(n_frames, ceil(N/2))`` magnitudes.

    Examples
    --------
    >>> n = np.arange(8)
    >>> np.round(spectrum(np.cos(2 * np.pi * n / 8)[None]), 6).tolist()  # one cycle: half its amplitude in bin 1
    [[0.0, 0.5, 0.0, 0.0]]
    """
    return _spectrum(_magnitudes(framed), framed.shape[1])


def _magnitudes(framed: np.ndarray) -> np.ndarray:
    """``|fft(frame)|`` over bins 0 .. N//2: the one transform the spectrum and the chroma share."""
    return np.abs(sp_fft.rfft(framed, axis=1))


def _spectrum(magnitudes: np.ndarray, n: int) -> np.ndarray:
    return magnitudes[:, : (n + 1) // 2] / n


def zcr(framed: np.ndarray) -> np.ndarray:
    """Zero-crossing rate ``Z = 1/(2N) sum_n |sgn x(n) - sgn x(n-1)|`` with ``x(-1) = 0`` (``feature_zcr.m``).

    Because the sample before the frame counts as 0, a frame with a non-zero first sample gets an extra
    ``1/(2N)``; a sample that is exactly 0 counts as half a crossing on each side.

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` zero-crossing rates.

    Examples
    --------
    >>> zcr(np.array([[1.0, -1.0, 1.0, -1.0], [1.0, 1.0, 1.0, 1.0]])).tolist()  # (1 + 3 * 2) / 8 and 1 / 8
    [0.875, 0.125]
    """
    return _sign_changes(framed) / (2.0 * framed.shape[1])


@jit(**kernels.JIT)
def _sign_changes(rows: np.ndarray) -> np.ndarray:
    """Per row, ``sum_n |sgn x(n) - sgn x(n-1)|`` with ``x(-1) = 0``, counted in integers (exact)."""
    changes = np.zeros(rows.shape[0], dtype=np.int64)
    for row in range(rows.shape[0]):
        values = rows[row]
        # Each pair read afresh, so that no sign is carried from one step to the next (vectorised).
        count = abs(int(values[0] > 0) - int(values[0] < 0))
        for k in range(1, values.size):
            count += abs(int(values[k] > 0) - int(values[k] < 0) - int(values[k - 1] > 0) + int(values[k - 1] < 0))
        changes[row] = count
    return changes


def energy(framed: np.ndarray) -> np.ndarray:
    """Short-term energy ``E = 1/N sum_n x(n)^2`` (``feature_energy.m``).

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` energies.

    Examples
    --------
    >>> energy(np.array([[1.0, -1.0, 1.0, -1.0], [2.0, 2.0, 0.0, 0.0]])).tolist()
    [1.0, 2.0]
    """
    return np.mean(framed**2, axis=1)


def _block_entropy(values: np.ndarray, n_blocks: int) -> np.ndarray:
    """Entropy ``-sum_j e_j log2(e_j + eps)`` of the normalised energies ``e_j`` of ``n_blocks`` sub-blocks.

    The row is cut into ``n_blocks`` contiguous blocks of ``floor(len / n_blocks)`` values, trailing values
    dropped; ``e_j`` = block energy / (energy of the whole row + eps), as both toolbox entropies do.
    """
    return _block_entropy_of_squares(values**2, n_blocks)


def _block_entropy_of_squares(squares: np.ndarray, n_blocks: int, total: np.ndarray | None = None) -> np.ndarray:
    """:func:`_block_entropy` of the values whose squares are given; ``total`` is their row sum if known."""
    length = squares.shape[1] // n_blocks
    total = np.sum(squares, axis=1) if total is None else total
    blocks = squares[:, : length * n_blocks].reshape(squares.shape[0], n_blocks, length)
    shares = np.sum(blocks, axis=2) / (total[:, None] + EPS)
    return -np.sum(shares * np.log2(shares + EPS), axis=1)


def energy_entropy(framed: np.ndarray, n_blocks: int = N_BLOCKS) -> np.ndarray:
    """Entropy of energy over ``n_blocks`` sub-frames (``feature_energy_entropy.m``), in bits.

    0 when one sub-frame holds all the energy, ``log2(n_blocks)`` when all hold the same.

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).
    n_blocks : int
        Sub-frames of ``floor(N / n_blocks)`` samples each (trailing samples dropped).

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` entropies in bits.

    Examples
    --------
    >>> framed = np.array([[1.0, 1.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]])  # energy in 2 of 4 sub-frames, in all 4
    >>> np.round(energy_entropy(framed, n_blocks=4), 6).tolist()
    [1.0, 2.0]
    """
    return _block_entropy(framed, n_blocks)


def spectral_centroid_spread(spectra: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Spectral centroid and spread, both divided by ``fs/2`` (``feature_spectral_centroid.m``).

    With ``K`` bins, the toolbox's frequency axis ``m_k = fs/(2K) * k`` for ``k = 1..K`` (one bin above the
    DFT's ``(k-1) fs/N``) and ``X`` the spectrum divided by its maximum:
    ``C = sum(m X) / (sum X + eps)``, ``S = sqrt(sum((m - C)^2 X) / (sum X + eps))``. An all-zero spectrum
    gives 0 for both.

    Parameters
    ----------
    spectra : np.ndarray
        ``(n_frames, K)`` magnitude spectra, one per row (:func:`spectrum`).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    centroid, spread : np.ndarray
        ``(n_frames,)`` each, as fractions of ``fs/2``.

    Examples
    --------
    >>> spectra = np.array([[0.0, 0.0, 1.0, 0.0], [1.0, 1.0, 1.0, 1.0]])  # a line in bin 3 of 4; flat
    >>> centroid, spread = spectral_centroid_spread(spectra, 8.0)  # m = 1, 2, 3, 4 Hz; fs/2 = 4 Hz
    >>> np.round(centroid, 6).tolist(), np.round(spread, 6).tolist()  # 3/4, 2.5/4; 0, sqrt(1.25)/4
    ([0.75, 0.625], [0.0, 0.279508])
    """
    n_bins = spectra.shape[1]
    m = fs / (2.0 * n_bins) * np.arange(1, n_bins + 1)
    x = _scaled_to_peak(spectra, spectra.max(axis=1))
    weight = x.sum(axis=1) + EPS
    centroid = (x @ m) / weight
    _weigh_squared_deviations(x, m, centroid)
    spread = np.sqrt(np.sum(x, axis=1) / weight)
    return centroid / (fs / 2.0), spread / (fs / 2.0)


@jit(**kernels.JIT)
def _weigh_squared_deviations(x: np.ndarray, m: np.ndarray, centre: np.ndarray) -> None:
    """``x[i, k] = (m[k] - centre[i])^2 x[i, k]`` in place: the operations of the array expression, in one pass."""
    for i in range(x.shape[0]):
        for k in range(x.shape[1]):
            deviation = m[k] - centre[i]
            x[i, k] = deviation * deviation * x[i, k]


def _scaled_to_peak(rows: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """Each row divided by its ``peak``; rows whose peak is not positive become 0."""
    if np.all(peak > 0):
        return rows / peak[:, None]
    return np.divide(rows, peak[:, None], out=np.zeros_like(rows), where=peak[:, None] > 0)


def spectral_entropy(spectra: np.ndarray, n_blocks: int = N_BLOCKS) -> np.ndarray:
    """Entropy of the spectral energy over ``n_blocks`` sub-bands (``feature_spectral_entropy.m``), in bits.

    Same formula as ``energy_entropy`` on the magnitude spectrum; a flat spectrum gives
    ``log2(n_blocks)`` up to the trailing bins the sub-bands drop.

    Parameters
    ----------
    spectra : np.ndarray
        ``(n_frames, K)`` magnitude spectra, one per row (:func:`spectrum`).
    n_blocks : int
        Sub-bands of ``floor(K / n_blocks)`` bins each (trailing bins dropped).

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` entropies in bits.

    Examples
    --------
    >>> flat, two_bands = np.ones(20), np.repeat([1.0, 0.0], [4, 16])  # 10 sub-bands of 2 bins
    >>> np.round(spectral_entropy(np.vstack([flat, two_bands])), 6).tolist()  # log2(10) and log2(2)
    [3.321928, 1.0]
    """
    return _block_entropy(spectra, n_blocks)


def spectral_flux(spectra: np.ndarray) -> np.ndarray:
    """Spectral flux ``F_i = sum_k (X_i(k)/sum X_i - X_{i-1}(k)/sum(X_{i-1} + eps))^2`` (``feature_spectral_flux.m``).

    The first frame is compared with itself, as ``stFeatureExtraction.m`` does, so its flux is ~0. An
    all-zero current spectrum contributes 0 in place of the toolbox's 0/0.

    Parameters
    ----------
    spectra : np.ndarray
        ``(n_frames, K)`` magnitude spectra of consecutive frames, one per row (:func:`spectrum`).

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` fluxes.

    Examples
    --------
    >>> spectra = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])  # the energy moves to bin 1 in frame 2
    >>> np.round(spectral_flux(spectra), 6).tolist()  # (0 - 1)^2 + (1 - 0)^2
    [0.0, 0.0, 2.0]
    """
    return np.sum(_flux_terms(spectra, spectra.sum(axis=1), np.sum(spectra + EPS, axis=1)), axis=1)


@jit(**kernels.JIT)
def _flux_terms(spectra: np.ndarray, total: np.ndarray, total_eps: np.ndarray) -> np.ndarray:
    """The terms ``(X_i(k)/sum X_i - X_{i-1}(k)/sum(X_{i-1} + eps))^2`` of :func:`spectral_flux`, given the
    row sums: the divisions, difference and square of the array formula, in one pass."""
    terms = np.empty_like(spectra)
    for i in range(spectra.shape[0]):
        current, prior, out = spectra[i], spectra[max(i - 1, 0)], terms[i]
        scale, prior_scale = total[i], total_eps[max(i - 1, 0)]
        # One loop per case, without a test inside: vectorised.
        if scale > 0:
            for k in range(out.size):
                difference = current[k] / scale - prior[k] / prior_scale
                out[k] = difference * difference
        else:
            for k in range(out.size):
                difference = 0.0 - prior[k] / prior_scale
                out[k] = difference * difference
    return terms


def spectral_rolloff(spectra: np.ndarray, c: float = ROLLOFF_C) -> np.ndarray:
    """Spectral roll-off ``j / K`` (``feature_spectral_rolloff.m``).

    ``j`` is the first 0-based bin at which the cumulative spectral energy ``sum_{k<=j} X(k)^2`` exceeds
    ``c`` times the total; ``K`` the number of bins. If no bin does (an all-zero spectrum) the toolbox's
    loop runs off the end and gives ``(K-1)/K``.

    Parameters
    ----------
    spectra : np.ndarray
        ``(n_frames, K)`` magnitude spectra, one per row (:func:`spectrum`).
    c : float
        The share of the energy below the roll-off bin.

    Returns
    -------
    np.ndarray
        ``(n_frames,)`` roll-off bins as fractions of ``K``.

    Examples
    --------
    >>> spectral_rolloff(np.array([[1.0, 1.0, 1.0, 1.0], [2.0, 1.0, 0.0, 0.0]])).tolist()  # 4 > 3.6; 5 > 4.5
    [0.75, 0.25]
    """
    return _rolloff_of_power(spectra**2, c)


def _rolloff_of_power(power: np.ndarray, c: float = ROLLOFF_C, total: np.ndarray | None = None) -> np.ndarray:
    """:func:`spectral_rolloff` of the spectra whose squares are ``power`` (row sums ``total`` if known)."""
    total = power.sum(axis=1) if total is None else total
    return _first_exceeding(power, c * total) / power.shape[1]


@jit(**kernels.JIT)
def _first_exceeding(power: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """Per row, the first index whose running sum exceeds its threshold, else the last index.

    The running sum adds the values one by one from the first, as ``np.cumsum`` does, and stops there.
    """
    rows, bins = power.shape
    first = np.full(rows, bins - 1)
    for row in range(rows):
        cumulative = 0.0
        for k in range(bins):
            cumulative = power[row, k] if k == 0 else cumulative + power[row, k]
            if cumulative > thresholds[row]:
                first[row] = k
                break
    return first


def harmonic(framed: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Harmonic ratio and fundamental frequency in Hz per frame (``feature_harmonic.m``).

    With ``R(m)`` the autocorrelation at lag ``m``, ``m0`` the first lag ``m >= 2`` where ``R`` crosses
    from ``>= 0`` to ``< 0`` (``N`` if none) and ``M = min(round(0.016 fs), N-1)``, the normalised
    autocorrelation is ``Gamma(m) = R(m) / (sqrt(R(0) sum_{n<N-m} x(n)^2) + eps)`` for ``m0 <= m <= M``
    and 0 below ``m0``. If ``Gamma`` is noise-like (its zero-crossing rate, ``zcr``, exceeds 0.15) both
    values are 0 (unvoiced). Otherwise ``HR = max Gamma`` at lag ``T0`` (first maximum) and
    ``f0 = fs / T0``, set to 0 when it exceeds 5000 Hz or ``HR < 0.1``.

    ``R`` is computed by FFT, as MATLAB's ``xcorr`` does, for the lags up to ``M`` only: a crossing after
    ``M`` leaves ``Gamma`` all 0 wherever it is, and an FFT of ``N + M`` samples (instead of ``2N - 1``)
    holds those lags without wrap-around, at a third of the cost. Deliberately, values within
    ``1e-12 R(0)`` of zero are set to 0, so that nearly silent frames get the exact-arithmetic result on
    every machine instead of one decided by round-off.

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    ratio, f0 : np.ndarray
        ``(n_frames,)`` each: the harmonic ratio, and the fundamental frequency in Hz (0 where there is none).

    Examples
    --------
    >>> fs = 8000.0
    >>> tone = np.sin(2 * np.pi * 500.0 * np.arange(400) / fs)  # one 400-sample frame, a period of 16 samples
    >>> ratio, f0 = harmonic(frames(tone, fs), fs)
    >>> f0.tolist(), bool(ratio[0] > 0.99)
    ([500.0], True)
    >>> noise = np.random.default_rng(0).normal(size=400)
    >>> [values.tolist() for values in harmonic(frames(noise, fs), fs)]  # unvoiced
    [[0.0], [0.0]]
    """
    squares = framed**2
    return _harmonic(framed, fs, squares.sum(axis=1), squares[:, :_shared_head(framed.shape[1], fs)].sum(axis=1))


def _max_lag(n: int, fs: float) -> int:
    """``M = min(round(0.016 fs), N-1)``, the largest lag of :func:`harmonic`."""
    return min(matlab_round(0.016 * fs), n - 1)


def _shared_head(n: int, fs: float) -> int:
    """``N - M - 1``: the samples at the start of a frame that every head energy of :func:`harmonic` sums."""
    return n - _max_lag(n, fs) - 1


def _harmonic(framed: np.ndarray, fs: float, frame_energy: np.ndarray,
              shared_energy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`harmonic` given ``sum x^2`` of each frame and of its first :func:`_shared_head` samples."""
    autocorr = _autocorrelation(framed, _max_lag(framed.shape[1], fs))
    return _harmonic_of_autocorrelation(autocorr, frame_energy, framed, shared_energy, float(fs))


EXACT_SIGNS_BELOW = 1e150
"""Frame energies ``R(0)`` below which ``Gamma(m)`` has the sign of ``R(m)``: its denominator
``sqrt(R(0) sum x^2) + eps`` is then finite and at least eps, and ``|R(m)| > 1e-12 R(0)`` keeps the quotient
from rounding to 0."""


@jit(**kernels.JIT)
def _harmonic_of_autocorrelation(autocorr: np.ndarray, frame_energy: np.ndarray, framed: np.ndarray,
                                 shared_energy: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`harmonic` of each row from its autocorrelation ``R(0..M)``, ``R(0)`` as ``sum x^2``
    (``frame_energy``) and ``shared_energy = sum_{n < N-M-1} x(n)^2``, the part of every head energy
    ``sum_{n < N-m} x(n)^2`` that all lags share.

    The IEEE operations of the array formulation, in the same order (the head energies are that shared
    sum plus a running sum, the rest element by element), so every value is that of the formula bit for
    bit. Only fewer of them: below :data:`EXACT_SIGNS_BELOW` the voicing test needs only the signs of
    ``R``, an unvoiced frame needs no ``Gamma`` at all, and the maximum only the positive ones.
    """
    rows = framed.shape[0]
    max_lag = autocorr.shape[1] - 1
    ratio = np.zeros(rows)
    f0 = np.zeros(rows)
    heads = np.empty(max_lag)
    gamma = np.zeros(max_lag)
    masked = np.empty(max_lag + 1)
    for row in range(rows):
        # A loud row fills all of Gamma, a quiet voiced one only its positive lags: start every row from 0.
        gamma[:] = 0.0
        energy = frame_energy[row]
        # FFT round-off (~1e-15 R(0)) would otherwise decide the sign tests and, divided by the eps of an
        # all-zero head, the whole Gamma of a nearly silent frame; exact arithmetic gives 0 there.
        tolerance = AUTOCORR_TOL * energy
        for m in range(max_lag + 1):
            masked[m] = 0.0 if abs(autocorr[row, m]) <= tolerance else autocorr[row, m]
        first_zero = _first_downward_crossing(masked)
        exact_signs = energy < EXACT_SIGNS_BELOW
        if not exact_signs:
            _head_energies(framed[row], shared_energy[row], heads)
            _gamma(masked, energy, heads, first_zero, gamma, False)
        # Gamma is 0 below m0 and counts no crossing there.
        changes = 0
        before = 0
        for m in range(first_zero, max_lag + 1):
            value = masked[m] if exact_signs else gamma[m - 1]
            sign = int(value > 0) - int(value < 0)
            changes += abs(sign - before)
            before = sign
        if changes / (2.0 * max_lag) > 0.15:
            continue
        if exact_signs:
            _head_energies(framed[row], shared_energy[row], heads)
            _gamma(masked, energy, heads, first_zero, gamma, True)
        best, best_lag = _first_maximum(gamma)
        ratio[row] = best
        frequency = fs / (best_lag + 1.0)
        if frequency <= 5000.0 and best >= 0.1:
            f0[row] = frequency
    return ratio, f0


@jit(**kernels.JIT)
def _first_downward_crossing(autocorr: np.ndarray) -> int:
    """The first lag ``m >= 2`` with ``R(m) < 0 <= R(m-1)``; the number of lags given if none."""
    for m in range(2, autocorr.size):
        if autocorr[m] < 0 <= autocorr[m - 1]:
            return m
    return autocorr.size


@jit(**kernels.JIT)
def _head_energies(frame: np.ndarray, shared: float, heads: np.ndarray) -> None:
    """``heads[m-1] = sum_{n < N-m} x(n)^2`` for m = 1 .. M: ``shared`` (the sum of the first ``N-M-1``
    squares) plus the running sum of the squares after them, as ``np.cumsum`` adds them."""
    n, max_lag = frame.size, heads.size
    running = 0.0
    for k in range(max_lag):
        value = frame[n - max_lag - 1 + k] * frame[n - max_lag - 1 + k]
        running = value if k == 0 else running + value
        heads[max_lag - 1 - k] = running + shared


@jit(**kernels.JIT)
def _gamma(autocorr: np.ndarray, energy: float, heads: np.ndarray, first_zero: int, gamma: np.ndarray,
           positive_only: bool) -> None:
    """``Gamma(m) = R(m) / (sqrt(R(0) heads(m)) + eps)`` into ``gamma[m-1]`` for ``m >= m0`` (all of them, or
    only where ``R(m) > 0``, the only candidates for a maximum over values that include 0)."""
    for m in range(first_zero, autocorr.size):
        if autocorr[m] > 0 or not positive_only:
            gamma[m - 1] = autocorr[m] / (math.sqrt(energy * heads[m - 1]) + EPS)


@jit(**kernels.JIT)
def _first_maximum(values: np.ndarray) -> tuple[float, int]:
    """``(max, argmax)`` as numpy gives them: the first maximum, or the first NaN if there is one."""
    best, where = values[0], 0
    for k in range(values.size):
        if values[k] != values[k]:
            return values[k], k
        if values[k] > best:
            best, where = values[k], k
    return best, where


def _autocorrelation(framed: np.ndarray, max_lag: int) -> np.ndarray:
    """``R(m) = sum_n x(n) x(n+m)`` of each row for m = 0 .. max_lag, by FFT without wrap-around.

    ``cv2.dft`` on the rows and :func:`_power_in_place` for ``|X|^2`` (``cv2.mulSpectrums``'s values): half
    the time of ``scipy.fft`` here.
    """
    rows, n = framed.shape
    padded = np.empty((rows, cv2.getOptimalDFTSize(n + max_lag)))
    padded[:, :n] = framed
    padded[:, n:] = 0.0
    # All in the one padded array: a second array of this size costs more in fresh pages than it saves.
    spectra = cv2.dft(padded, dst=padded, flags=cv2.DFT_ROWS)
    _power_in_place(spectra)
    autocorr = cv2.dft(spectra, dst=spectra, flags=cv2.DFT_ROWS | cv2.DFT_INVERSE | cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE)
    return autocorr[:, :max_lag + 1]


def _power_in_place(packed: np.ndarray) -> None:
    """``|X|^2`` of rows of ``cv2.dft`` spectra packed as CCS (Re0, Re1, Im1, ..., [Re(L/2)]), in place.

    ``Re^2 + Im^2`` into the real parts and 0 into the imaginary ones: the operations, in their order, of
    ``cv2.mulSpectrums(X, X, DFT_ROWS, conjB=True)``, which would copy its aliased input first.
    """
    length = packed.shape[1]
    pairs = (length - 1) // 2
    real, imaginary = packed[:, 1:2 * pairs:2], packed[:, 2:2 * pairs + 1:2]
    real *= real
    imaginary *= imaginary
    real += imaginary
    imaginary[...] = 0.0
    packed[:, 0] *= packed[:, 0]
    if length % 2 == 0:
        packed[:, -1] *= packed[:, -1]


@lru_cache(maxsize=8)
def mfcc_filter_bank(n_bins: int, fs: float) -> np.ndarray:
    """The toolbox's 40 triangular filters, shape ``(40, n_bins)`` (``feature_mfccs_init.m``, after Slaney).

    Edge frequencies: 13 linear from 133.3333 Hz in steps of 66.66666666 Hz, then 29 log-spaced by the
    factor 1.0711703; filter ``j`` rises from edge ``j`` to edge ``j+1`` and falls to edge ``j+2``, with
    peak height ``2 / (upper - lower)`` (equal area). The filters are evaluated on the toolbox's axis
    ``f_k = k fs / n_bins`` for ``k = 0..n_bins-1`` although only the first half of the spectrum is passed
    in, so bin ``k`` stands for twice its true frequency; kept deliberately to match the toolbox.
    The returned array is read-only (it is cached).

    Parameters
    ----------
    n_bins : int
        Number of spectrum bins the filters apply to.
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    np.ndarray
        ``(40, n_bins)`` filter weights, read-only.

    Examples
    --------
    >>> bank = mfcc_filter_bank(1000, 10000.0)  # bin k at 10 k Hz on the toolbox's axis
    >>> bank.shape, round(float(bank[0, 20]), 4)  # filter 0 peaks at 200 Hz: 2 / (266.67 - 133.33)
    ((40, 1000), 0.015)
    """
    linear = 133.3333 + np.arange(13) * 66.66666666
    logarithmic = linear[-1] * 1.0711703 ** np.arange(1, 27 + 3)
    edges = np.concatenate([linear, logarithmic])
    lower, centre, upper = edges[:-2, None], edges[1:-1, None], edges[2:, None]
    height = 2.0 / (upper - lower)
    freqs = np.arange(n_bins) / n_bins * fs
    rising = ((freqs > lower) & (freqs <= centre)) * height * (freqs - lower) / (centre - lower)
    falling = ((freqs > centre) & (freqs < upper)) * height * (upper - freqs) / (upper - centre)
    bank = rising + falling
    bank.flags.writeable = False
    return bank


@lru_cache(maxsize=1)
def _dct_matrix(n_ceps: int = N_MFCC, n_filters: int = 40) -> np.ndarray:
    """Orthonormal DCT-II rows ``sqrt(2/J) cos(k (2j+1) pi / (2J))``, row 0 scaled by ``1/sqrt(2)``."""
    k = np.arange(n_ceps)[:, None]
    j = np.arange(n_filters)[None, :]
    matrix = np.sqrt(2.0 / n_filters) * np.cos(k * (2 * j + 1) * np.pi / (2 * n_filters))
    matrix[0] *= np.sqrt(0.5)
    matrix.flags.writeable = False
    return matrix


def mfcc(spectra: np.ndarray, fs: float) -> np.ndarray:
    """13 MFCCs per frame, ``c = DCT(log10(W X + eps))`` (``feature_mfccs.m``), shape ``(n_frames, 13)``.

    ``W`` is ``mfcc_filter_bank(K, fs)`` for the ``K`` spectrum bins and the DCT is the orthonormal DCT-II
    of the 40 filter outputs, first 13 coefficients. A silent spectrum gives ``c_0 = sqrt(40) log10(eps)``
    and zeros elsewhere.

    Parameters
    ----------
    spectra : np.ndarray
        ``(n_frames, K)`` magnitude spectra, one per row (:func:`spectrum`).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    np.ndarray
        ``(n_frames, 13)`` coefficients ``c_0 .. c_12``.

    Examples
    --------
    >>> c = mfcc(np.zeros((1, 1102)), 44100.0)  # a silent frame
    >>> round(float(c[0, 0]), 4), bool(np.allclose(c[0, 1:], 0.0))  # sqrt(40) * log10(2^-52) = -99.0018
    (-99.0018, True)
    """
    support, bank = _mfcc_bank_support(spectra.shape[1], float(fs))
    return np.log10(spectra[:, :support] @ bank + EPS) @ _dct_matrix().T


@lru_cache(maxsize=8)
def _mfcc_bank_support(n_bins: int, fs: float) -> tuple[int, np.ndarray]:
    """The bins the filters of :func:`mfcc_filter_bank` cover (the first ``support``, a sixth of them) and
    the bank on them, transposed (read-only).

    The bins above are 0 in every filter, so a finite spectrum's filter outputs are sums of the same
    products without them; only the BLAS may group those sums differently for the shorter rows (a
    difference of rounding, about 1e-16 of the output; none with 38 frames here)."""
    bank = mfcc_filter_bank(n_bins, fs)
    covered = np.flatnonzero(np.any(bank != 0, axis=0))
    support = int(covered[-1]) + 1 if covered.size else 0
    transposed = np.ascontiguousarray(bank[:, :support].T)
    transposed.flags.writeable = False
    return support, transposed


@lru_cache(maxsize=8)
def _chroma_classes(n: int, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """Per DFT bin of an ``n``-sample frame: whether it is in 55-2000 Hz, and its pitch class 0..11.

    The toolbox's chromatic scale is ``55 * 2^(i/12)`` Hz for every ``i >= 0`` up to the highest bin
    frequency; a bin takes the nearest note (first on ties), and note ``i`` has class ``i mod 12``, so
    class 0 (``chroma_01``) is A, class 1 A#, ..., class 11 G#.
    """
    freqs = np.arange(n // 2) * (fs / n)
    in_band = (freqs >= 55.0) & (freqs <= 2000.0)
    top = freqs[-1]
    n_notes = int(np.floor(12.0 * np.log2(top / 55.0))) + 2 if top >= 55.0 else 0
    notes = 55.0 * 2.0 ** (np.arange(n_notes) / 12.0)
    notes = notes[notes <= top]
    if notes.size == 0:
        # every bin then lies below 55 Hz and is out of band, so its class is never used
        notes = np.array([55.0])
    classes = np.argmin(np.abs(freqs[:, None] - notes[None, :]), axis=1) % N_CHROMA
    in_band.flags.writeable = False
    classes.flags.writeable = False
    return in_band, classes


def chroma(framed: np.ndarray, fs: float) -> np.ndarray:
    """12 chroma values per frame, ``C = y / (c + 1)`` (``feature_chroma_vector.m``), shape ``(n_frames, 12)``.

    Each frame is scaled to peak 1, ``|fft|`` is taken over the first ``floor(N/2)`` bins (not divided by
    ``N``), bins outside 55-2000 Hz are zeroed, then only strict local maxima are kept (neighbours outside
    the array count as 0). ``y`` sums the kept magnitudes per pitch class, ``c`` counts them. Pitch classes
    start at A (55 Hz): ``chroma_01`` is A, ``chroma_02`` A#, ..., ``chroma_12`` G#. An all-zero frame
    gives zeros.

    Parameters
    ----------
    framed : np.ndarray
        ``(n_frames, N)`` frames, one per row (:func:`frames`).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    np.ndarray
        ``(n_frames, 12)`` chroma values, pitch classes A .. G#.

    Examples
    --------
    >>> n = np.arange(8)  # at 880 Hz, bins 1 and 3 are 110 Hz (an A) and 330 Hz (nearest note E, 329.6 Hz)
    >>> frame = np.cos(2 * np.pi * n / 8) + 0.5 * np.cos(2 * np.pi * 3 * n / 8)  # peak 1.5 at n = 0
    >>> np.round(chroma(frame[None], 880.0), 6).tolist()  # A: (4 / 1.5) / 2, E: (2 / 1.5) / 2
    [[1.333333, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.666667, 0.0, 0.0, 0.0, 0.0]]
    """
    return _chroma(framed, _magnitudes(framed), fs)


def _chroma(framed: np.ndarray, magnitudes: np.ndarray, fs: float, peak: np.ndarray | None = None) -> np.ndarray:
    band, membership = _chroma_band(framed.shape[1], float(fs))
    peak = (_peak_magnitudes(framed) if peak is None else peak)[:, None]
    # Zeroed bins are never peaks, so only the band is looked at, between two zero bins.
    padded = np.zeros((framed.shape[0], band.stop - band.start + 2))
    magnitude = padded[:, 1:-1]
    np.divide(magnitudes[:, band], peak, out=magnitude, where=peak > 0)
    is_peak = (magnitude > padded[:, :-2]) & (magnitude > padded[:, 2:])
    sums = (magnitude * is_peak) @ membership
    counts = is_peak.astype(np.float64) @ membership
    return sums / (counts + 1.0)


def _peak_magnitudes(framed: np.ndarray) -> np.ndarray:
    """``max |x|`` of each row, from its maximum and minimum (no array of absolute values)."""
    return np.maximum(framed.max(axis=1), -framed.min(axis=1))


def _silent(framed: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """The rows with ``sum |x| <= eps`` (silent frames, ``stFeatureExtraction.m``), given their ``max |x|``.

    A rounded sum of non-negative terms is at least its largest term, so only rows whose peak is at most
    eps can be silent; those are summed as the toolbox does.
    """
    silent = peak <= EPS
    if silent.any():
        silent[silent] = np.sum(np.abs(framed[silent]), axis=1) <= EPS
    return silent


@lru_cache(maxsize=8)
def _chroma_band(n: int, fs: float) -> tuple[slice, np.ndarray]:
    """The bins of ``_chroma_classes`` in 55-2000 Hz (consecutive) and their one-hot pitch classes."""
    in_band, classes = _chroma_classes(n, fs)
    bins = np.flatnonzero(in_band)
    band = slice(int(bins[0]), int(bins[-1]) + 1) if bins.size else slice(0, 0)
    membership = np.eye(N_CHROMA)[classes[band]]
    membership.flags.writeable = False
    return band, membership


def frame_features(signal: np.ndarray, fs: float = 44100.0) -> np.ndarray:
    """The per-frame feature matrix, shape ``(n_frames, 35)``, columns in ``NAMES`` order.

    Rows of silent frames (``sum(|windowed frame|) <= eps``) are all zero, as in ``stFeatureExtraction.m``;
    they still serve as the previous spectrum of the next frame's flux.

    Parameters
    ----------
    signal : np.ndarray
        1-D real audio samples, at least one window long.
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    np.ndarray
        ``(n_frames, 35)`` float64: one row per frame (:func:`frames`), one column per name of ``NAMES``.

    Raises
    ------
    ValueError
        For bad input, see ``frames``.

    Examples
    --------
    >>> tone = np.sin(2 * np.pi * 441.0 * np.arange(44100) / 44100.0)  # 1 s of a 441 Hz tone
    >>> table = frame_features(tone)
    >>> table.shape, np.unique(np.round(table[:, NAMES.index("f0")], 6)).tolist()  # every frame's f0
    ((38, 35), [441.0])
    """
    framed = frames(signal, fs)
    n = framed.shape[1]
    table = np.empty((framed.shape[0], len(NAMES)))
    peak = _peak_magnitudes(framed)
    table[:, 0] = zcr(framed)
    # What several features share is computed once, and each large intermediate is let go as soon as its
    # features are done: fewer arrays alive at once means fewer fresh pages to fault in.
    squares = framed**2
    frame_energy = squares.sum(axis=1)  # energy, energy entropy and R(0) of the harmonic features
    shared_energy = squares[:, :_shared_head(n, fs)].sum(axis=1)
    table[:, 1] = frame_energy / n
    table[:, 2] = _block_entropy_of_squares(squares, N_BLOCKS, frame_energy)
    del squares
    table[:, 8], table[:, 9] = _harmonic(framed, fs, frame_energy, shared_energy)
    magnitudes = _magnitudes(framed)  # the transform of the spectrum and of the chroma
    table[:, 10 + N_MFCC:] = _chroma(framed, magnitudes, fs, peak)
    if magnitudes.shape[1] == (n + 1) // 2:  # odd N: the spectrum keeps every bin
        spectra = np.divide(magnitudes, n, out=magnitudes)
    else:
        spectra = _spectrum(magnitudes, n)
    del magnitudes
    power = spectra**2
    power_total = power.sum(axis=1)  # spectral entropy and roll-off
    table[:, 5] = _block_entropy_of_squares(power, N_BLOCKS, power_total)
    table[:, 7] = _rolloff_of_power(power, ROLLOFF_C, power_total)
    del power
    table[:, 3], table[:, 4] = spectral_centroid_spread(spectra, fs)
    table[:, 6] = spectral_flux(spectra)
    table[:, 10:10 + N_MFCC] = mfcc(spectra, fs)
    table[_silent(framed, peak)] = 0.0
    return table


def compute(signal: np.ndarray, fs: float = 44100.0) -> dict[str, float]:
    """The 35 audio features of one windowed signal: the mean of each ``frame_features`` column.

    Parameters
    ----------
    signal : np.ndarray
        1-D audio samples (full scale), normally the 1 s slide window of 44100 samples (docs/features.md#preprocessing).
    fs : float
        Sampling rate in Hz.

    Returns
    -------
    dict[str, float]
        Feature name (``NAMES``) to value; every value is finite.

    Raises
    ------
    ValueError
        If the signal is not 1-D, has non-finite samples or is shorter than one window, or ``fs`` is not a
        positive finite number or is too low for a 20-sample window.

    Examples
    --------
    >>> t = np.arange(44100) / 44100.0
    >>> round(compute(np.sin(2 * np.pi * 441.0 * t))["f0"], 6)
    441.0
    """
    means = frame_features(signal, fs).mean(axis=0)
    return {name: float(value) for name, value in zip(NAMES, means, strict=True)}


def _checked_signal(signal: np.ndarray, fs: float) -> np.ndarray:
    """The signal as float64 after checking it and ``fs``; raises ValueError naming the problem."""
    if not isinstance(fs, int | float | np.integer | np.floating) or not math.isfinite(fs) or fs <= 0:
        raise ParameterError(f"audio sampling rate must be a positive finite number, got {fs!r}")
    window, _ = window_and_step(fs)
    if window < MIN_WINDOW:
        raise ParameterError(f"audio sampling rate {fs} Hz gives a {window}-sample window; need >= {MIN_WINDOW}")
    x = np.asarray(signal)
    if x.ndim != 1:
        raise ParameterError(f"audio signal must be 1-D, got shape {x.shape}")
    if not (np.issubdtype(x.dtype, np.number) and not np.iscomplexobj(x)):
        raise ParameterError(f"audio signal must be real numbers, got dtype {x.dtype}")
    x = x.astype(np.float64, copy=False)  # read only: frames() makes new arrays
    if not np.all(np.isfinite(x)):
        raise ParameterError("audio signal contains NaN or infinite samples")
    if x.size < window:
        raise ParameterError(f"audio signal has {x.size} samples, fewer than one {window}-sample window")
    return x
