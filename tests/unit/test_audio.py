"""Audio features (docs/features.md#audio): closed-form answers on synthetic frames, spectra and signals.

Numbers used below, at fs = 44100 Hz: window N = 2205, step 1103, K = ceil(N/2) = 1103 spectrum bins,
DFT bin spacing fs/N = 20 Hz exactly, so a tone at 20 k0 Hz sits on bin k0. The symmetric Hamming window
``w(n) = 0.54 - 0.46 cos(2 pi n / (N-1))`` has ``sum w = 0.54 N - 0.46`` and
``sum w^2 = 0.54^2 N - 2 (0.54)(0.46) + 0.46^2 (N+1)/2`` (the cosine sums over one period vanish; the
extra sample n = N-1 adds cos(2 pi) = 1).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from features import audio

FS = 44100.0
N = 2205
K = 1103
T = np.arange(44100) / FS


def tone(freq: float, phase: float = 0.3) -> np.ndarray:
    return np.sin(2 * np.pi * freq * T + phase)


def one_hot(n_bins: int, *indices: int) -> np.ndarray:
    rows = np.zeros((len(indices), n_bins))
    rows[np.arange(len(indices)), indices] = 1.0
    return rows


# --- names, rounding, framing -------------------------------------------------------------------------


def test_names_are_the_35_columns_in_order():
    assert len(audio.NAMES) == 35
    assert audio.NAMES[:10] == (
        "zcr", "energy", "energy_entropy", "spectral_centroid", "spectral_spread", "spectral_entropy",
        "spectral_flux", "spectral_rolloff", "harmonic_ratio", "f0",
    )
    assert audio.NAMES[10:23] == tuple(f"mfcc_{i:02d}" for i in range(1, 14))
    assert audio.NAMES[23:] == tuple(f"chroma_{i:02d}" for i in range(1, 13))


@pytest.mark.parametrize(
    ("x", "expected"),
    [(1102.5, 1103), (2.5, 3), (-2.5, -3), (3.5, 4), (2.4999, 2), (0.49999999999999994, 0), (705.6, 706)],
)
def test_matlab_round_is_half_away_from_zero(x, expected):
    assert audio.matlab_round(x) == expected


def test_window_and_step_use_matlab_rounding():
    # 0.025 * 44100 = 1102.5 exactly; numpy's round-half-even would give 1102
    assert audio.window_and_step(44100.0) == (2205, 1103)
    assert audio.window_and_step(22050.0) == (1103, 551)


def test_one_second_at_44100_holds_38_frames():
    # floor((44100 - 2205) / 1103) + 1 = 37 + 1; with a step of 1102 it would be 39
    assert audio.frames(np.ones(44100)).shape == (38, N)
    assert audio.frame_features(np.ones(44100)).shape == (38, 35)


def test_frames_start_every_step_and_carry_a_symmetric_hamming_window():
    ramp = np.arange(44100, dtype=float)
    framed = audio.frames(ramp)
    assert framed[1, 0] == pytest.approx(1103 * 0.08)
    assert framed[37, N - 1] == pytest.approx((37 * 1103 + N - 1) * 0.08)
    window = audio.frames(np.ones(N))[0]
    assert window[0] == pytest.approx(0.08) and window[-1] == pytest.approx(0.08)
    assert window[(N - 1) // 2] == pytest.approx(1.0)


def test_one_window_long_signal_gives_one_frame():
    assert audio.frame_features(np.ones(N)).shape == (1, 35)


# --- time-domain features -----------------------------------------------------------------------------


def test_zcr_counts_the_sample_before_the_frame_as_zero():
    # |1-0| + 3 sign flips of 2 -> 7 / (2*4); a zero sample is half a crossing on each side
    assert audio.zcr(np.array([[1.0, -1.0, 1.0, -1.0]]))[0] == pytest.approx(7 / 8)
    assert audio.zcr(np.array([[1.0, 0.0, -1.0, 0.0]]))[0] == pytest.approx(4 / 8)
    assert audio.zcr(np.zeros((1, 5)))[0] == 0.0


def test_zcr_of_a_sine_counts_its_crossings_per_frame():
    # sin(2 pi (n - 0.5) / 100) crosses zero between samples at n = 50 m + 0.5; the Hamming window is
    # positive, so it keeps the signs. Frame 0 (n = 0..2204) holds m = 0..44: 45 crossings; frame 1
    # (n = 1103..3307) holds m = 23..66: 44 crossings; plus 1 for the first sample against the zero before.
    sine = np.sin(2 * np.pi * (np.arange(44100) - 0.5) / 100.0)
    rates = audio.zcr(audio.frames(sine))
    assert rates[0] == pytest.approx((2 * 45 + 1) / (2 * N))
    assert rates[1] == pytest.approx((2 * 44 + 1) / (2 * N))


def test_energy_of_a_constant_signal_is_its_square_times_the_mean_squared_window():
    sum_w2 = 0.54**2 * N - 2 * 0.54 * 0.46 + 0.46**2 * (N + 1) / 2
    assert audio.energy(np.full((2, 4), 3.0)) == pytest.approx([9.0, 9.0])
    assert audio.compute(np.full(44100, 3.0))["energy"] == pytest.approx(9.0 * sum_w2 / N, rel=1e-12)


def test_energy_entropy_of_concentrated_and_even_energy():
    concentrated = np.zeros((1, 20))
    concentrated[0, 3] = 1.0
    assert audio.energy_entropy(concentrated)[0] == pytest.approx(0.0, abs=1e-12)
    assert audio.energy_entropy(np.ones((1, 20)))[0] == pytest.approx(math.log2(10))
    # 25 samples: ten blocks of 2, the last 5 dropped but counted in the total: e_j = 2/25
    assert audio.energy_entropy(np.ones((1, 25)))[0] == pytest.approx(-10 * 0.08 * math.log2(0.08))


# --- spectral features --------------------------------------------------------------------------------


def test_spectrum_is_the_first_half_of_the_dft_magnitude_over_n():
    framed = np.array([[1.0, 1.0, 1.0, 1.0, 1.0], [1.0, -1.0, 1.0, -1.0, 1.0]])
    spectra = audio.spectrum(framed)
    assert spectra.shape == (2, 3)
    assert spectra[0] == pytest.approx([1.0, 0.0, 0.0], abs=1e-15)
    # DC of the alternating row is 1/5; ceil(5/2) = 3 bins
    assert spectra[1, 0] == pytest.approx(0.2)


def test_centroid_and_spread_on_the_toolbox_axis():
    # the toolbox maps 0-based bin k to (k+1) fs/(2K) Hz, so after dividing by fs/2: (k+1)/K
    centroid, spread = audio.spectral_centroid_spread(one_hot(100, 9), 8000.0)
    assert centroid[0] == pytest.approx(10 / 100) and spread[0] == pytest.approx(0.0, abs=1e-12)
    two = one_hot(100, 9)[0] + one_hot(100, 29)[0]
    centroid, spread = audio.spectral_centroid_spread(two[None, :], 8000.0)
    assert centroid[0] == pytest.approx(20 / 100) and spread[0] == pytest.approx(10 / 100)


@pytest.mark.parametrize("bin_index", [22, 250, 551, 750])
def test_centroid_and_rolloff_of_a_pure_tone(bin_index):
    # A tone on bin k0 puts the Hamming main lobe on bins k0-1, k0, k0+1 with magnitudes in the ratio
    # 0.23 : 0.54 : 0.23, symmetric about k0, so the centroid is bin k0, i.e. (k0+1)/K. Its energy
    # fractions are 0.133, 0.734, 0.133: the cumulative energy passes 90 % only at bin k0+1, so the
    # roll-off is (k0+1)/K.
    features = audio.compute(tone(20.0 * bin_index))
    assert features["spectral_centroid"] == pytest.approx((bin_index + 1) / K, rel=1e-4)
    assert features["spectral_rolloff"] == pytest.approx((bin_index + 1) / K, rel=1e-12)
    assert features["spectral_spread"] < 2 / K


def test_rolloff_is_the_first_bin_passing_the_energy_share():
    # energies 0.85 + 0.15: 90 % is passed only at the second bin; 0.95 + 0.05 at the first
    spectra = np.zeros((3, 10))
    spectra[0, [2, 7]] = np.sqrt([0.85, 0.15])
    spectra[1, [2, 7]] = np.sqrt([0.95, 0.05])
    spectra[2, 4] = 1.0
    assert audio.spectral_rolloff(spectra) == pytest.approx([7 / 10, 2 / 10, 4 / 10])


def test_spectral_entropy_of_flat_spectra_and_white_noise():
    assert audio.spectral_entropy(np.ones((1, 20)))[0] == pytest.approx(math.log2(10))
    assert audio.spectral_entropy(np.ones((1, 25)))[0] == pytest.approx(-10 * 0.08 * math.log2(0.08))
    noise = np.random.default_rng(0).standard_normal(44100)
    assert audio.compute(noise)["spectral_entropy"] == pytest.approx(math.log2(10), rel=0.01)


def test_flux_between_disjoint_and_scaled_spectra():
    # frame 0 is compared with itself; disjoint unit spectra differ by 1 in two bins: 1 + 1 = 2; the
    # flux of a scaled copy is 0 because both spectra are normalised to sum 1
    spectra = np.vstack([one_hot(8, 1), one_hot(8, 5), 3.0 * one_hot(8, 5)])
    assert audio.spectral_flux(spectra) == pytest.approx([0.0, 2.0, 0.0], abs=1e-12)


def test_flux_of_a_stationary_tone_is_near_zero():
    assert audio.compute(tone(440.0))["spectral_flux"] < 1e-5
    noise = np.random.default_rng(1).standard_normal(44100)
    assert audio.compute(noise)["spectral_flux"] > 1e-4


# --- harmonic ratio and F0 ----------------------------------------------------------------------------


@pytest.mark.parametrize("f0", [441.0, 220.0, 150.0])
def test_f0_of_a_harmonic_tone(f0):
    harmonic_tone = sum(np.sin(2 * np.pi * h * f0 * T + h) / h for h in range(1, 5))
    features = audio.compute(harmonic_tone)
    assert features["f0"] == pytest.approx(f0, rel=0.02)
    assert features["harmonic_ratio"] > 0.9


def test_f0_of_an_integer_period_is_exact():
    # period 100 samples: the normalised autocorrelation peaks at lag 100, f0 = 44100 / 100
    ratio, f0 = audio.harmonic(audio.frames(tone(441.0)), FS)
    assert np.all(f0 == 441.0)
    assert np.all(ratio > 0.95) and np.all(ratio <= 1.0)


def test_white_noise_is_unvoiced():
    noise = np.random.default_rng(2).standard_normal(44100)
    features = audio.compute(noise)
    assert features["harmonic_ratio"] < 0.1
    assert features["f0"] == 0.0


def test_harmonic_of_a_zero_frame_is_zero():
    ratio, f0 = audio.harmonic(np.zeros((1, N)), FS)
    assert ratio[0] == 0.0 and f0[0] == 0.0


def _straightforward_harmonic(frame: np.ndarray, fs: float) -> tuple[float, float]:
    """``feature_harmonic.m`` for one frame, term by term: the direct autocorrelation over every lag."""
    n = frame.size
    r = np.correlate(frame, frame, "full")[n - 1:]
    r[np.abs(r) <= audio.AUTOCORR_TOL * np.sum(frame**2)] = 0.0
    m0 = next((m for m in range(2, n) if r[m] < 0 <= r[m - 1]), n)
    max_lag = min(audio.matlab_round(0.016 * fs), n - 1)
    gamma = np.zeros(max_lag)
    for m in range(max(m0, 1), max_lag + 1):
        gamma[m - 1] = r[m] / (math.sqrt(r[0] * np.sum(frame[:n - m] ** 2)) + audio.EPS)
    signs = np.sign(gamma)
    zcr = np.sum(np.abs(np.diff(signs, prepend=0.0))) / (2 * max_lag)
    if zcr > 0.15:
        return 0.0, 0.0
    ratio, f0 = float(gamma.max()), fs / (int(np.argmax(gamma)) + 1)
    return ratio, f0 if f0 <= 5000.0 and ratio >= 0.1 else 0.0


@pytest.mark.parametrize("fs", [44100.0, 8000.0, 400.0])
def test_harmonic_by_fft_equals_the_direct_autocorrelation(fs):
    # The FFT holds only the lags up to M; the direct sums hold them all, so a crossing after M counts too.
    rng = np.random.default_rng(int(fs))
    t = np.arange(int(fs)) / fs
    signals = [rng.standard_normal(t.size), np.sin(2 * np.pi * 97 * t) + 0.02 * rng.standard_normal(t.size),
               np.where(t < 0.5, 0.0, np.sin(2 * np.pi * 51 * t)), np.sign(np.sin(2 * np.pi * 140 * t))]
    for signal in signals:
        framed = audio.frames(signal, fs)
        ratio, f0 = audio.harmonic(framed, fs)
        expected = np.array([_straightforward_harmonic(frame, fs) for frame in framed])
        # FFT and direct sums round differently, by ~1e-15 of R(0) over about 10^3 terms.
        np.testing.assert_allclose(ratio, expected[:, 0], rtol=1e-11, atol=1e-12)
        np.testing.assert_array_equal(f0, expected[:, 1])


def test_zcr_and_chroma_equal_their_float_formulas_on_random_frames():
    # zcr counts sign changes in integers; chroma looks only at the 55-2000 Hz bins. Both as the formulas.
    framed = audio.frames(np.random.default_rng(4).standard_normal(44100))
    framed[0, :50] = 0.0
    signs = np.sign(framed)
    zcr = np.abs(np.diff(signs, axis=1, prepend=0.0)).sum(axis=1) / (2.0 * N)
    np.testing.assert_array_equal(audio.zcr(framed), zcr)
    in_band, classes = audio._chroma_classes(N, FS)
    magnitude = np.abs(np.fft.rfft(framed, axis=1)[:, :N // 2]) * in_band / np.abs(framed).max(axis=1)[:, None]
    padded = np.pad(magnitude, ((0, 0), (1, 1)))
    is_peak = (magnitude > padded[:, :-2]) & (magnitude > padded[:, 2:])
    sums = np.stack([(magnitude * is_peak)[:, classes == c].sum(axis=1) for c in range(12)], axis=1)
    counts = np.stack([is_peak[:, classes == c].sum(axis=1) for c in range(12)], axis=1)
    np.testing.assert_allclose(audio.chroma(framed, FS), sums / (counts + 1.0), rtol=1e-12)


# --- the one-pass kernels against the array formulas ---------------------------------------------------


def _array_harmonic(framed: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """``audio.harmonic`` as whole-array operations: every Gamma of every frame, masks, crossings and the
    zero-crossing rate of Gamma as in the formula (the straightforward form of the one-pass kernel)."""
    n = framed.shape[1]
    max_lag = min(audio.matlab_round(0.016 * fs), n - 1)
    autocorr = audio._autocorrelation(framed, max_lag).copy()
    squares = framed**2
    frame_energy = squares.sum(axis=1, keepdims=True)
    autocorr[np.abs(autocorr) <= audio.AUTOCORR_TOL * frame_energy] = 0.0
    crossing = (autocorr[:, 2:] < 0) & (autocorr[:, 1:-1] >= 0)
    first_zero = np.where(crossing.any(axis=1), crossing.argmax(axis=1) + 2, autocorr.shape[1])
    shared = n - max_lag - 1
    heads = np.cumsum(squares[:, shared:n - 1], axis=1)
    heads += squares[:, :shared].sum(axis=1, keepdims=True)
    denominator = np.sqrt(frame_energy * heads[:, ::-1]) + audio.EPS
    lags = np.arange(1, max_lag + 1)
    gamma = np.where(lags >= first_zero[:, None], autocorr[:, 1:] / denominator, 0.0)
    signs = (gamma > 0).astype(np.int64) - (gamma < 0)
    zcr = (np.abs(np.diff(signs, axis=1)).sum(axis=1) + np.abs(signs[:, 0])) / (2.0 * max_lag)
    voiced = zcr <= 0.15
    ratio = np.where(voiced, gamma.max(axis=1), 0.0)
    f0 = fs / (gamma.argmax(axis=1) + 1.0)
    return ratio, np.where(voiced & (f0 <= 5000.0) & (ratio >= 0.1), f0, 0.0)


def _kernel_test_signals(fs: float) -> list[np.ndarray]:
    rng = np.random.default_rng(int(fs) + 7)
    t = np.arange(int(fs)) / fs
    return [rng.standard_normal(t.size), sum(np.sin(2 * np.pi * h * 180.0 * t) / h for h in range(1, 6)),
            np.sin(2 * np.pi * 97 * t) + 0.3 * rng.standard_normal(t.size),
            np.where(t < 0.4, 1e-200 * rng.standard_normal(t.size), np.sign(np.sin(2 * np.pi * 140 * t))),
            1e-160 * rng.standard_normal(t.size),   # squares underflow: tolerance 0, subnormal R
            1e76 * np.sin(2 * np.pi * 210 * t),      # R(0) > 1e150: Gamma's denominator overflows
            1e155 * rng.standard_normal(t.size),    # squares overflow: R(0) and R infinite or NaN
            # Frames of both kinds in one matrix: a loud unvoiced frame (whole Gamma) before quiet voiced
            # ones (Gamma at its positive lags only) must leave nothing behind for them.
            np.where(t < 0.05, 1e74 * np.sin(2 * np.pi * min(8000.0, fs / 2.5) * t), np.sin(2 * np.pi * 200 * t))]


@pytest.mark.parametrize("fs", [44100.0, 8000.0, 400.0])
def test_harmonic_kernel_equals_the_array_formula_bit_for_bit(fs):
    # The same IEEE operations in the same order (the voicing from the signs of R, Gamma only where it
    # can be the maximum): equal, not close.
    for signal in _kernel_test_signals(fs):
        framed = audio.frames(signal, fs)
        with np.errstate(over="ignore", invalid="ignore"):
            expected = _array_harmonic(framed, fs)
            ratio, f0 = audio.harmonic(framed, fs)
        np.testing.assert_array_equal(ratio, expected[0])
        np.testing.assert_array_equal(f0, expected[1])


@pytest.mark.parametrize("length", [2, 3, 4, 27, 36, 2916])
def test_power_spectrum_in_place_equals_mul_spectrums(length):
    # The CCS packing has a lone last real part for even lengths only.
    rng = np.random.default_rng(length)
    rows = np.zeros((5, length))
    rows[:, :max(1, 3 * length // 4)] = rng.standard_normal((5, max(1, 3 * length // 4))) * 1e5
    packed = cv2.dft(rows, flags=cv2.DFT_ROWS)
    expected = cv2.mulSpectrums(packed, packed, cv2.DFT_ROWS, conjB=True)
    audio._power_in_place(packed)
    np.testing.assert_array_equal(packed, expected)


def test_rolloff_equals_the_cumulative_sum_formula_bit_for_bit():
    rng = np.random.default_rng(11)
    spectra = np.abs(rng.standard_normal((40, 300))) * rng.uniform(0, 1, (40, 1)) ** 8
    spectra[3] = 0.0
    spectra[5, 100:] = 0.0
    power = spectra**2
    cumulative = np.cumsum(power, axis=1)
    exceeded = cumulative > 0.9 * power.sum(axis=1, keepdims=True)
    expected = np.where(exceeded.any(axis=1), exceeded.argmax(axis=1), 299) / 300
    np.testing.assert_array_equal(audio.spectral_rolloff(spectra), expected)


def test_flux_and_centroid_equal_their_array_formulas_bit_for_bit():
    rng = np.random.default_rng(12)
    spectra = np.abs(rng.standard_normal((30, 257))) * rng.uniform(0, 2, (30, 1))
    spectra[[0, 7, 8]] = 0.0
    previous = np.concatenate([spectra[:1], spectra[:-1]])
    total = spectra.sum(axis=1, keepdims=True)
    current = np.divide(spectra, total, out=np.zeros_like(spectra), where=total > 0)
    prior = previous / np.sum(previous + audio.EPS, axis=1, keepdims=True)
    np.testing.assert_array_equal(audio.spectral_flux(spectra), np.sum((current - prior) ** 2, axis=1))
    m = 16000.0 / (2.0 * 257) * np.arange(1, 258)
    peak = spectra.max(axis=1, keepdims=True)
    x = np.divide(spectra, peak, out=np.zeros_like(spectra), where=peak > 0)
    weight = x.sum(axis=1) + audio.EPS
    centroid = (x @ m) / weight
    spread = np.sqrt(np.sum((m - centroid[:, None]) ** 2 * x, axis=1) / weight)
    got = audio.spectral_centroid_spread(spectra, 16000.0)
    np.testing.assert_array_equal(got[0], centroid / 8000.0)
    np.testing.assert_array_equal(got[1], spread / 8000.0)


@pytest.mark.parametrize("fs", [44100.0, 8000.0])
def test_frame_matrix_equals_the_features_computed_one_by_one(fs):
    # frame_features shares sums, peaks and transforms between the features; computed one at a time
    # from the frames the values are the same bit for bit, silent rows included.
    for signal in _kernel_test_signals(fs)[:4]:
        signal = np.where(np.arange(signal.size) < signal.size // 3, 0.0, signal)
        framed = audio.frames(signal, fs)
        spectra = audio.spectrum(framed)
        ratio, f0 = audio.harmonic(framed, fs)
        expected = np.column_stack([
            audio.zcr(framed), audio.energy(framed), audio.energy_entropy(framed),
            *audio.spectral_centroid_spread(spectra, fs), audio.spectral_entropy(spectra),
            audio.spectral_flux(spectra), audio.spectral_rolloff(spectra), ratio, f0,
            audio.mfcc(spectra, fs), audio.chroma(framed, fs)])
        expected[np.sum(np.abs(framed), axis=1) <= audio.EPS] = 0.0
        np.testing.assert_array_equal(audio.frame_features(signal, fs), expected)


# --- MFCC ---------------------------------------------------------------------------------------------


def test_mfcc_filter_bank_triangles_have_unit_area():
    # every triangle has height 2 / (upper - lower): area 1 Hz^-1 * Hz; a 10 Hz grid integrates it
    bank = audio.mfcc_filter_bank(1000, 10000.0)
    assert bank.shape == (40, 1000)
    assert bank.sum(axis=1) * 10.0 == pytest.approx(np.ones(40), abs=0.01)
    # first filter: lower 133.3333, centre 199.99999666, upper 266.66666332 Hz; 170 Hz is on the rise
    assert bank[0, 17] == pytest.approx(2 / 133.33333332 * (170 - 133.3333) / 66.66666666)
    assert bank[0, 13] == 0.0 and bank[0, 27] == 0.0


def test_mfcc_filter_bank_uses_the_toolbox_frequency_axis():
    # bin k stands for k fs / K (not k fs / N): 39.98 Hz per bin at 44.1 kHz, so the first filter
    # (133.3-266.7 Hz) covers bins 4, 5, 6 (159.9, 199.9, 239.9 Hz)
    bank = audio.mfcc_filter_bank(K, FS)
    assert np.flatnonzero(bank[0]).tolist() == [4, 5, 6]


def test_mfcc_of_silence_and_of_constant_filter_outputs():
    # orthonormal DCT-II of a constant vector L: c0 = sqrt(40) L, the rest 0
    silent = audio.mfcc(np.zeros((1, K)), FS)
    assert np.all(np.isfinite(silent))
    assert silent[0, 0] == pytest.approx(math.sqrt(40) * math.log10(audio.EPS))
    assert silent[0, 1:] == pytest.approx(np.zeros(12), abs=1e-9)
    bank = audio.mfcc_filter_bank(K, FS)
    flat, *_ = np.linalg.lstsq(bank, np.full(40, 0.01), rcond=None)
    ceps = audio.mfcc(flat[None, :], FS)
    assert ceps[0, 0] == pytest.approx(math.sqrt(40) * -2.0, rel=1e-9)
    assert ceps[0, 1:] == pytest.approx(np.zeros(12), abs=1e-9)


def test_silence_gives_zeros_everywhere():
    features = audio.compute(np.zeros(44100))
    assert list(features) == list(audio.NAMES)
    assert all(value == 0.0 for value in features.values())


def test_silent_frames_contribute_zero_rows():
    # frames 0..7 end before sample 11000 (7 * 1103 + 2204 = 9925) and are silent
    signal = np.where(np.arange(44100) < 11000, 0.0, tone(440.0))
    table = audio.frame_features(signal)
    assert np.all(table[:8] == 0.0)
    assert np.all(table[20, [0, 1, 3]] > 0.0)
    assert audio.compute(signal)["energy"] == pytest.approx(table[:, 1].sum() / 38)


# --- chroma -------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("freq", "chroma_index"),
    [(440.0, 0), (523.25, 3), (659.26, 7), (830.61, 11)],
)
def test_chroma_peaks_at_the_pitch_class_counted_from_a(freq, chroma_index):
    # feature_chroma_vector.m builds the scale 55 * 2^(i/12) Hz from A1 and takes class rem(i+1, 12)
    # (12 for 0): A -> chroma_01, C (3 semitones up) -> chroma_04, E (7) -> chroma_08, G# (11) -> chroma_12
    features = audio.compute(tone(freq))
    values = [features[f"chroma_{i:02d}"] for i in range(1, 13)]
    assert int(np.argmax(values)) == chroma_index


def test_chroma_of_a440_is_half_its_peak_magnitude():
    # A440 sits on bin 22; scaled to peak 1 its |fft| there is sum(w) / 2, the only peak in its class
    # (y / (c + 1) with c = 1) and the other classes hold at most faint side-lobe peaks
    features = audio.compute(tone(440.0))
    expected = (0.54 * N - 0.46) / 2 / 2
    assert features["chroma_01"] == pytest.approx(expected, rel=0.01)
    assert max(features[f"chroma_{i:02d}"] for i in range(2, 13)) < 0.01 * expected


def test_chroma_of_a_zero_frame_is_zero():
    assert np.all(audio.chroma(np.zeros((2, N)), FS) == 0.0)


# --- the whole vector ---------------------------------------------------------------------------------


def test_compute_returns_35_finite_floats_deterministically():
    noise = np.random.default_rng(3).standard_normal(44100)
    first, second = audio.compute(noise), audio.compute(noise.copy())
    assert list(first) == list(audio.NAMES)
    assert all(isinstance(value, float) and math.isfinite(value) for value in first.values())
    assert first == second


def test_compute_matches_the_frame_matrix_mean():
    signal = tone(300.0) + 0.1 * np.random.default_rng(4).standard_normal(44100)
    means = audio.frame_features(signal).mean(axis=0)
    assert list(audio.compute(signal).values()) == pytest.approx(list(means), rel=1e-15)


def test_integer_samples_are_accepted():
    ints = (1000 * tone(440.0)).astype(np.int16)
    assert audio.compute(ints)["f0"] == pytest.approx(441.0, rel=0.02)


@pytest.mark.parametrize(
    ("signal", "fs", "message"),
    [
        (np.zeros((2, 44100)), FS, "1-D"),
        (np.r_[np.zeros(44099), np.nan], FS, "NaN"),
        (np.r_[np.zeros(44099), np.inf], FS, "infinite"),
        (np.zeros(N - 1), FS, "fewer than one 2205-sample window"),
        (np.zeros(0), FS, "fewer than one"),
        (np.zeros(44100), 0.0, "positive finite"),
        (np.zeros(44100), -44100.0, "positive finite"),
        (np.zeros(44100), float("nan"), "positive finite"),
        (np.zeros(44100), 100.0, "5-sample window"),
        (np.zeros(44100, dtype=complex), FS, "real numbers"),
        (np.array(["a"] * 44100), FS, "real numbers"),
    ],
)
def test_bad_input_raises_a_one_line_value_error(signal, fs, message):
    with pytest.raises(ValueError, match=message) as caught:
        audio.compute(signal, fs)
    assert "\n" not in str(caught.value)
