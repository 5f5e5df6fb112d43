"""Preprocessing of raw scanner signals (docs/features.md#preprocessing): expected values derived by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal

from scanner.calibration import fsr_newtons
from scanner.preprocess import (
    QualityError,
    SlideWindow,
    band_limit,
    check_clipped,
    check_contact,
    check_slide,
    dft321,
    grayscale,
    remove_friction_offset,
    slide_signal,
    slide_start,
    slide_window,
)
from scanner.scan import Trace


def resting_then_sliding(n: int = 15000, burst_at: int = 2015, seed: int = 0) -> np.ndarray:
    """Quiet noise with 1 g of gravity on z, then a 30x louder slide from ``burst_at``."""
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, 0.01, (n, 3))
    v[:, 2] += 1.0
    v[burst_at:] += rng.normal(0.0, 0.3, (n - burst_at, 3))
    return v


# --- DFT321 ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [3000, 3001, 2, 3])
def test_dft321_preserves_energy_for_even_and_odd_lengths(n):
    a = np.random.default_rng(n).normal(size=(n, 3))
    y = dft321(a)
    assert y.shape == (n,)
    assert np.sum(y**2) == pytest.approx(np.sum(a**2), rel=1e-12)


def test_dft321_of_one_axis_is_that_axis():
    x = np.random.default_rng(1).normal(size=1001)
    assert np.array_equal(dft321(x), x)
    assert np.array_equal(dft321(x[:, None]), x)
    # Through the three-axis formula: the other axes add no magnitude and no phase.
    padded = np.column_stack([np.zeros_like(x), x, np.zeros_like(x)])
    np.testing.assert_allclose(dft321(padded), x, atol=1e-12)


def test_dft321_of_three_equal_axes_is_sqrt3_times_the_axis():
    # |A|^2 summed over three equal axes is 3 |A|^2, and A+A+A has the phase of A.
    x = np.random.default_rng(2).normal(size=999)
    np.testing.assert_allclose(dft321(np.column_stack([x, x, x])), math.sqrt(3.0) * x, atol=1e-12)


def test_dft321_of_opposite_axes_keeps_the_magnitude():
    # x and -x: magnitude sqrt(2)|X|, but A_x + A_y = 0 has phase 0 everywhere, so the result is the
    # zero-phase signal with spectrum sqrt(2)|X| and still carries the energy of both axes.
    x = np.random.default_rng(3).normal(size=512)
    y = dft321(np.column_stack([x, -x]))
    assert np.sum(y**2) == pytest.approx(2 * np.sum(x**2), rel=1e-12)
    np.testing.assert_allclose(np.fft.rfft(y).imag, 0.0, atol=1e-9)


# --- slide start and window -------------------------------------------------------------------------------

def test_slide_start_finds_the_frame_holding_the_burst():
    # The burst starts inside frame 67 (samples 2010..2039); the gravity offset would hide it from a
    # detector that did not remove the 0.25 s baseline (1 g on z dwarfs the 0.3 g burst per frame).
    assert slide_start(resting_then_sliding(burst_at=2015)) == 2010
    assert slide_start(resting_then_sliding(burst_at=2010)) == 2010


def test_slide_start_needs_strictly_more_than_ten_times_the_noise():
    v = np.zeros((3000, 3))
    v[:, 0] = np.where(np.arange(3000) % 2 == 0, 0.5, -0.5)  # baseline mean 0, frame energy 30 * 0.25 = 7.5
    v[1500:1530, 0] = 0.0
    v[1500:1503, 0] = 5.0                                    # frame 50: energy 75 = 10 x noise, not above
    v[1800:1830, 0] = 0.0
    v[1800:1803, 0] = 5.0
    v[1803, 0] = 0.5                                         # frame 60: energy 75.25
    assert slide_start(v) == 1800
    assert slide_start(v, factor=10.1) is None


def test_slide_start_none_without_slide_and_error_when_too_short():
    quiet = np.random.default_rng(4).normal(0.0, 0.01, (6000, 3))
    assert slide_start(quiet, factor=50.0) is None
    with pytest.raises(QualityError, match="window shorter than 1 s"):
        slide_start(quiet[:749])


def test_slide_start_accepts_one_axis():
    v = resting_then_sliding(burst_at=4500)[:, 0]
    assert slide_start(v) == 4500


def test_slide_window_aligns_audio_and_ir_with_the_vibration():
    window = SlideWindow(2010)
    assert window.vibration == slice(2010, 5010)
    assert window.ir == window.vibration
    assert window.audio == slice(29547, 29547 + 44100)        # 2010 * 44100 / 3000 = 29547 exactly
    # Same instant: audio sample / 44100 == vibration sample / 3000, in integers.
    assert window.audio.start * 3000 == window.vibration.start * 44100
    assert (window.audio.stop - window.audio.start) / 44100 == (window.vibration.stop - 2010) / 3000


def test_slide_window_rejects_an_audio_start_between_samples():
    with pytest.raises(ValueError, match="audio start"):
        SlideWindow(1)  # 14.7 audio samples
    with pytest.raises(ValueError, match="non-negative"):
        SlideWindow(-30)


def test_slide_window_quality_errors():
    v = resting_then_sliding(n=15000, burst_at=4500)
    assert slide_window(v).start == 4500
    with pytest.raises(QualityError, match="^no slide detected$"):
        slide_window(np.random.default_rng(5).normal(0.0, 0.01, (6000, 3)), factor=50.0)
    with pytest.raises(QualityError, match="^window shorter than 1 s: vibration"):
        slide_window(v[:7499])
    assert slide_window(v[:7500]).vibration.stop == 7500
    with pytest.raises(QualityError, match="^window shorter than 1 s: audio"):
        slide_window(v, audio_samples=4500 * 147 // 10 + 44099)
    with pytest.raises(QualityError, match="^window shorter than 1 s: IR"):
        slide_window(v, ir_samples=7499)


def test_check_slide_lists_the_problem():
    v = resting_then_sliding(burst_at=4500)
    assert check_slide(v) == []
    assert check_slide(v[:6000])[0].startswith("window shorter than 1 s")
    assert check_slide(np.random.default_rng(6).normal(0.0, 0.01, (6000, 3)), factor=50.0) == [
        "no slide detected"]


# --- band limit and the slide signal ----------------------------------------------------------------------

def _amplitude(y: np.ndarray, frequency: float, fs: float) -> float:
    """Amplitude of the sinusoid at ``frequency`` by projection over whole periods."""
    t = np.arange(y.size) / fs
    return math.hypot(2 * np.mean(y * np.sin(2 * np.pi * frequency * t)),
                      2 * np.mean(y * np.cos(2 * np.pi * frequency * t)))


@pytest.mark.parametrize("frequency", [10.0, 1000.0])
def test_band_limit_halves_a_sine_at_either_band_edge(frequency):
    # A Butterworth filter is -3 dB (gain 1/sqrt 2) at its band edges; forward-backward squares it: 1/2.
    fs = 3000.0
    t = np.arange(int(20 * fs)) / fs
    y = band_limit(np.sin(2 * np.pi * frequency * t), fs)
    middle = y[int(5 * fs):int(15 * fs)]
    assert _amplitude(middle, frequency, fs) == pytest.approx(0.5, abs=2e-4)


def test_band_limit_passes_the_band_without_delay_and_filters_each_axis_alone():
    fs = 3000.0
    t = np.arange(9000) / fs
    tone = np.sin(2 * np.pi * 120.0 * t)
    axes = np.column_stack([tone, np.zeros_like(tone), np.sin(2 * np.pi * 0.5 * t)])
    y = band_limit(axes, fs)
    middle = slice(3000, 6000)
    np.testing.assert_allclose(y[middle, 0], tone[middle], atol=2e-3)  # gain ~1 and zero phase
    np.testing.assert_allclose(y[:, 1], 0.0, atol=1e-15)
    assert np.max(np.abs(y[middle, 2])) < 1e-3                           # 0.5 Hz is far below the band
    np.testing.assert_array_equal(y[:, 0], band_limit(axes[:, 0], fs))


@pytest.mark.parametrize("fs", [3000.0, 10000.0])
def test_band_limit_equals_scipy_sosfiltfilt(fs):
    # The same recursion as scipy's, step by step. Only rounding can differ (a fused multiply-add where a
    # build of one of them uses it): each of the 9 operations per section and sample rounds by at most eps
    # of what it adds, and the filter passes that on with its l1 gain ||h||_1 in each of the two passes.
    sos = signal.butter(4, [10.0, 1000.0], btype="bandpass", fs=fs, output="sos")
    impulse = np.zeros(int(20 * fs))
    impulse[0] = 1.0
    gain = np.sum(np.abs(signal.sosfilt(sos, impulse)))
    rng = np.random.default_rng(int(fs))
    for n, axes in ((40, 1), (3001, 3), (15000, 3), (777, 2)):
        x = rng.standard_normal((n, axes)) * 10.0 ** rng.uniform(-6, 6) + rng.uniform(-1, 1, axes)
        bound = 9 * len(sos) * np.finfo(np.float64).eps * gain**2 * np.max(np.abs(x))
        np.testing.assert_allclose(band_limit(x, fs), signal.sosfiltfilt(sos, x, axis=0), rtol=0, atol=bound)
        np.testing.assert_allclose(band_limit(x[:, 0], fs), signal.sosfiltfilt(sos, x[:, 0]), rtol=0, atol=bound)


def test_band_limit_rejects_too_short_recordings():
    with pytest.raises(ValueError, match="too short to band-limit"):
        band_limit(np.zeros((20, 3)))


def test_slide_signal_filters_the_whole_recording_before_cutting_the_window():
    v = resting_then_sliding(burst_at=4500)
    trace = Trace(v, 3000.0, "g")
    window = SlideWindow(4500)
    expected = dft321(band_limit(v)[4500:7500])
    np.testing.assert_array_equal(slide_signal(trace), expected)
    cut_first = dft321(band_limit(v[4500:7500]))
    assert not np.allclose(slide_signal(trace, window), cut_first)  # the edges carry filter transients
    with pytest.raises(QualityError):
        slide_signal(Trace(v[:6000], 3000.0, "g"))


# --- friction and gray images -----------------------------------------------------------------------------

def test_remove_friction_offset_uses_the_first_tenth_of_a_second():
    f = np.full(900, 0.4)
    f[:300:2] = 0.3
    f[1:300:2] = 0.5                        # mean of the first 300 samples: 0.4
    f[300:] = 0.4 + np.arange(600) * 0.01
    out = remove_friction_offset(f)
    np.testing.assert_allclose(out[300:], np.arange(600) * 0.01, atol=1e-15)
    with pytest.raises(ValueError, match="f_frt"):
        remove_friction_offset(np.zeros((4, 2)))


def test_grayscale_is_bt601_luma_exactly():
    rgb = np.random.default_rng(7).integers(0, 256, (37, 53, 3), dtype=np.uint8)
    as_float = rgb.astype(np.float64)
    expected = 0.299 * as_float[..., 0] + 0.587 * as_float[..., 1] + 0.114 * as_float[..., 2]
    np.testing.assert_array_equal(grayscale(rgb), expected)
    np.testing.assert_array_equal(grayscale(rgb[5:30, 7:40]), expected[5:30, 7:40])


# --- quality checks ---------------------------------------------------------------------------------------

def test_check_clipped():
    assert check_clipped(np.array([0.1, 2.5, 4.9])) == []
    problems = check_clipped(np.array([0.0, 2.5, 5.0, 5.0]))
    assert len(problems) == 1 and problems[0].startswith("clipped: 3 of 4 samples")
    with pytest.raises(ValueError, match="low < high"):
        check_clipped(np.zeros(2), low=1.0, high=1.0)


def test_check_contact():
    assert check_contact(np.array([0.1, 0.6, 0.2])) == []
    problems = check_contact(fsr_newtons(np.zeros(10)))
    assert len(problems) == 1 and problems[0].startswith("no contact force: peak 0.098 N")
    assert check_contact(np.array([]))[0].startswith("no contact force")
