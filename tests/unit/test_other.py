"""Tests of the 15 other features (docs/features.md#other) with answers known in closed form."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import make_meta

from features import other
from features.tactum import MissingDataWarning
from scanner import simulation
from scanner.preprocess import slide_signal
from scanner.scan import Scan, Trace

FS = 3000.0
START = 1500
"""Slide start of the synthetic slides: 0.5 s of rest, a multiple of the 30-sample frame."""

DOCUMENTED_NAMES = [
    "density", "metal", "magnet_mean", "magnet_peak", "reflect_static", "reflect_mean", "cooling_rate",
    "vib_std", "vib_kurtosis", "vib_energy", "finger_vib_energy", "finger_vib_centroid", "tap_peak",
    "tap_centroid", "tap_decay",
]


def tone(freq: float, n: int, onset: int) -> np.ndarray:
    """``sin(2 pi freq t)`` from sample ``onset`` on (t = 0 there), zero before."""
    k = np.arange(n) - onset
    return np.where(k >= 0, np.sin(2 * np.pi * freq * k / FS), 0.0)


def decaying(freq: float, tau: float, n: int, onset: int = 0, phase: float = 0.0) -> np.ndarray:
    """``exp(-t / tau) cos(2 pi freq t + phase)`` from ``onset`` on (t = 0 there), zero before."""
    k = np.arange(n) - onset
    t = np.clip(k, 0, None) / FS
    return np.where(k >= 0, np.exp(-t / tau) * np.cos(2 * np.pi * freq * t + phase), 0.0)


def slide(freq: float, axes: tuple[float, float, float], seed: int, n: int = 15000) -> np.ndarray:
    """A resting-then-sliding recording: faint noise, then a tone on the three axes from START on."""
    noise = 1e-6 * np.random.default_rng(seed).standard_normal((n, 3))
    return np.outer(tone(freq, n, START), axes) + noise


def ir_trace(n: int = 15000) -> np.ndarray:
    """IR: a ramp 0.5 + i/1000 V while resting, 2.0 V in the slide window, 9.0 V after it."""
    index = np.arange(n)
    return np.where(index < START, 0.5 + index / 1000.0, np.where(index < START + 3000, 2.0, 9.0))


def t_cool_trace(rate: float = 0.3, t_amb: float = 22.0, t_max: float = 30.0) -> np.ndarray:
    """2 s of heating (linear rise), then 10 s of exact exponential cooling, 20 Hz."""
    t = np.arange(200) / 20.0
    heating = np.linspace(t_amb, t_max, 40, endpoint=False)
    return np.concatenate([heating, t_amb + (t_max - t_amb) * np.exp(-rate * t)])


def good_scan(drop: tuple[str, ...] = (), **meta) -> Scan:
    """A scan whose other features are all defined and known: see the tests for the expected values."""
    channels = {
        "v_ts": Trace(slide(250.0, (0.3, 0.4, 0.0), seed=1), FS, "g"),
        "r_ts": Trace(ir_trace(), FS, "V"),
        "v_fs": Trace(slide(400.0, (0.2, 0.0, 0.0), seed=2), FS, "g"),
        "v_tt": Trace(np.outer(decaying(300.0, 0.01, 15000, 6000, -np.pi / 2), (1.2, 1.6, 0.0)), FS, "g"),
        "t_cool": Trace(t_cool_trace(), 20.0, "degC"),
        "m": Trace(np.r_[np.ones(1800), -np.ones(1200)], FS, "-"),
        "dB": Trace(np.r_[np.full(40, 2.0), -35.0, np.full(39, 3.0)], 80.0, "uT"),
    }
    values = dict(t_amb=22.0, mass_g=27.0, volume_cm3=10.0)
    values.update(meta)
    traces = {name: trace for name, trace in channels.items() if name not in drop}
    return Scan(make_meta(**values), traces)


# --- names and the scan ---------------------------------------------------------------------------------

def test_names_are_the_spec_list_in_order():
    assert other.NAMES == tuple(f"other.{name}" for name in DOCUMENTED_NAMES)


def test_compute_on_a_known_scan():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = other.compute(good_scan())
    assert list(values) == list(other.NAMES)
    assert values["other.density"] == pytest.approx(2.7, rel=1e-15)
    assert values["other.metal"] == 1.0
    assert values["other.magnet_mean"] == pytest.approx((40 * 2.0 - 35.0 + 39 * 3.0) / 80, rel=1e-12)
    assert values["other.magnet_peak"] == -35.0
    # Resting ramp 0.5 + i/1000 over i = 0..1499: mean 0.5 + 1499/2000.
    assert values["other.reflect_static"] == pytest.approx(0.5 + 1499 / 2000, rel=1e-12)
    assert values["other.reflect_mean"] == pytest.approx(2.0, rel=1e-12)
    assert values["other.cooling_rate"] == pytest.approx(0.3, rel=1e-6)
    # v = DFT321 of the in-phase 0.3/0.4 axes = a 0.5 g sine of 250 whole periods in the window; the
    # band limit and the onset at the window start cost about 1e-4.
    assert values["other.vib_std"] == pytest.approx(0.5 / math.sqrt(2), rel=1e-3)
    assert values["other.vib_kurtosis"] == pytest.approx(1.5, rel=1e-3)
    assert values["other.vib_energy"] == pytest.approx(0.125, rel=1e-3)
    assert values["other.finger_vib_energy"] == pytest.approx(0.02, rel=1e-3)
    # A 2 g tap (1.2, 1.6 on two axes), 2 exp(-t/tau) sin(2 pi 300 t), tau 10 ms: its largest samples are
    # k = 2 and 3, 2 sin(0.4 pi) exp(-2 / 30) g; the band limit changes that by about 1 %.
    crest = 2 * math.sin(0.4 * math.pi) * math.exp(-2 / 30)
    assert values["other.tap_peak"] == pytest.approx(crest, rel=0.02)
    assert values["other.tap_decay"] == pytest.approx(0.01, rel=0.05)
    assert all(math.isfinite(value) for value in values.values())


def test_compute_takes_the_finger_features_from_the_finger_slide():
    scan = good_scan()
    values = other.compute(scan)
    v_f = slide_signal(scan["v_fs"])
    assert values["other.finger_vib_energy"] == other.vib_energy(v_f)
    assert values["other.finger_vib_centroid"] == other.vib_centroid(v_f, FS)
    # The 400 Hz finger tone, not the 250 Hz tool tone; its sharp onset in the window adds leakage above.
    assert 400.0 < values["other.finger_vib_centroid"] < 460.0


def test_compute_is_deterministic():
    first, second = other.compute(good_scan()), other.compute(good_scan())
    assert first.keys() == second.keys()
    assert all(first[k] == second[k] for k in first)


MISSING = {
    "m": {"metal"},
    "dB": {"magnet_mean", "magnet_peak"},
    "r_ts": {"reflect_static", "reflect_mean"},
    "v_ts": {"reflect_static", "reflect_mean", "vib_std", "vib_kurtosis", "vib_energy"},
    "t_cool": {"cooling_rate"},
    "v_fs": {"finger_vib_energy", "finger_vib_centroid"},
    "v_tt": {"tap_peak", "tap_centroid", "tap_decay"},
}


@pytest.mark.parametrize("channel", sorted(MISSING))
def test_missing_channel_makes_exactly_its_features_nan_with_a_warning(channel):
    with pytest.warns(MissingDataWarning, match=rf"\b{channel} is missing") as caught:
        values = other.compute(good_scan(drop=(channel,)))
    nan = {name.removeprefix("other.") for name, value in values.items() if math.isnan(value)}
    assert nan == MISSING[channel]
    assert len(caught) == (2 if channel == "v_ts" else 1)


@pytest.mark.parametrize(("field", "features"), [("mass_g", {"density"}), ("volume_cm3", {"density"}),
                                                  ("t_amb", {"cooling_rate"})])
def test_unknown_meta_value_makes_its_feature_nan_with_a_warning(field, features):
    with pytest.warns(MissingDataWarning, match=f"meta.{field}"):
        values = other.compute(good_scan(**{field: math.nan}))
    assert {name.removeprefix("other.") for name, value in values.items() if math.isnan(value)} == features


def test_failed_slide_check_makes_the_slide_features_nan():
    scan = good_scan()
    resting = Trace(1e-3 * np.random.default_rng(5).standard_normal((15000, 3)), FS, "g")
    no_slide = Scan(scan.meta, {**scan.traces, "v_ts": resting})
    with pytest.warns(MissingDataWarning, match="no slide detected"):
        values = other.compute(no_slide)
    nan = {name.removeprefix("other.") for name, value in values.items() if math.isnan(value)}
    assert nan == {"reflect_static", "reflect_mean", "vib_std", "vib_kurtosis", "vib_energy"}


def test_ir_shorter_than_the_slide_window_keeps_the_static_reflectance():
    scan = good_scan()
    short = Scan(scan.meta, {**scan.traces, "r_ts": Trace(ir_trace()[:4000], FS, "V")})
    with pytest.warns(MissingDataWarning, match="shorter than 1 s.*other.reflect_mean set to NaN"):
        values = other.compute(short)
    # The IR ends inside the window: reflect_static is still the mean of the 0.5 + i/1000 V ramp before START.
    assert values["other.reflect_static"] == pytest.approx(0.5 + (START - 1) / 2000, rel=1e-14)
    assert math.isnan(values["other.reflect_mean"]) and math.isfinite(values["other.vib_std"])
    shorter = Scan(scan.meta, {**scan.traces, "r_ts": Trace(ir_trace()[:1000], FS, "V")})
    with pytest.warns(MissingDataWarning, match="shorter than 1 s"):
        values = other.compute(shorter)
    assert values["other.reflect_static"] == pytest.approx(0.5 + 999 / 2000, rel=1e-14)  # all of it rests


# --- density, metal, magnetism --------------------------------------------------------------------------

def test_density_is_mass_over_volume():
    assert other.density(27.0, 10.0) == 2.7
    assert other.density(0.6, 4.0) == 0.15


@pytest.mark.parametrize(("mass", "volume"), [(math.nan, 10.0), (27.0, math.nan), (math.nan, math.nan)])
def test_density_of_unmeasured_mass_or_volume_is_nan(mass, volume):
    assert math.isnan(other.density(mass, volume))


@pytest.mark.parametrize(("mass", "volume"),
                         [(0.0, 1.0), (-1.0, 1.0), (1.0, 0.0), (1.0, -2.0), (math.inf, 1.0)])
def test_density_rejects_non_positive_values(mass, volume):
    with pytest.raises(ValueError, match="must be positive"):
        other.density(mass, volume)


@pytest.mark.parametrize(("m", "expected"), [
    ([1, 1, -1], 1.0), ([1, -1, -1], 0.0), ([1] * 5, 1.0), ([-1] * 5, 0.0),
    ([1, -1, 1, -1], 0.0),  # mean exactly 0 is not conductive
])
def test_metal_is_one_only_for_a_positive_mean(m, expected):
    assert other.metal(np.array(m, dtype=float)) == expected


def test_magnet_mean():
    assert other.magnet_mean(np.array([1.0, 2.0, 3.0, -2.0])) == 1.0


@pytest.mark.parametrize(("dB", "expected"), [
    ([1.0, 3.0, -7.0, 5.0], -7.0),  # a negative spike beats smaller positives
    ([1.0, -2.0, 4.0], 4.0),
    ([5.0, -5.0], 5.0),  # first on ties
    ([-0.5], -0.5),
])
def test_magnet_peak_is_the_signed_sample_of_largest_magnitude(dB, expected):
    assert other.magnet_peak(np.array(dB)) == expected


@pytest.mark.parametrize("bad", [np.array([]), np.zeros((3, 2)), np.array([1.0, np.nan])])
def test_array_features_reject_empty_multi_axis_or_non_finite_input(bad):
    for feature in (other.metal, other.magnet_mean, other.magnet_peak, other.vib_std, other.reflect_mean):
        with pytest.raises(ValueError, match="1-D|non-finite"):
            feature(bad)


# --- IR reflectance -------------------------------------------------------------------------------------

def test_reflect_static_is_the_mean_before_the_start():
    r = np.arange(3000) / 1000.0
    assert other.reflect_static(r, 1500) == pytest.approx(1499 / 2000, rel=1e-15)
    assert other.reflect_static(r, 1) == 0.0
    assert other.reflect_static(r, 3000) == pytest.approx(2999 / 2000, rel=1e-15)


def test_reflect_static_is_nan_without_resting_samples():
    assert math.isnan(other.reflect_static(np.ones(100), 0))


@pytest.mark.parametrize("start", [-1, 101, 2.5])
def test_reflect_static_rejects_a_start_outside_the_recording(start):
    with pytest.raises(ValueError, match="slide start"):
        other.reflect_static(np.ones(100), start)


def test_reflect_mean():
    assert other.reflect_mean(np.array([1.0, 2.0, 6.0])) == 3.0


# --- cooling --------------------------------------------------------------------------------------------

def test_cooling_rate_of_an_exact_exponential():
    assert other.cooling_rate(t_cool_trace(rate=0.3), 22.0) == pytest.approx(0.3, abs=1e-6)
    fast = t_cool_trace(rate=1.7, t_amb=18.0, t_max=45.0)
    assert other.cooling_rate(fast, 18.0) == pytest.approx(1.7, abs=1e-6)


def test_cooling_rate_uses_the_sample_rate():
    # The same samples read at 10 Hz span twice the time: half the rate.
    assert other.cooling_rate(t_cool_trace(rate=0.3), 22.0, fs=10.0) == pytest.approx(0.15, abs=1e-6)


def test_cooling_rate_starts_at_the_maximum():
    # Anything before the maximum (here a rise that would spoil a fit over the whole trace) is ignored.
    trace = t_cool_trace(rate=0.5)
    assert other.cooling_rate(trace[trace.argmax():], 22.0) == pytest.approx(0.5, abs=1e-6)
    assert other.cooling_rate(trace, 22.0) == pytest.approx(0.5, abs=1e-6)


@pytest.mark.parametrize("seed", range(4))
def test_cooling_rate_with_noise(seed):
    noisy = t_cool_trace(rate=0.3) + 0.05 * np.random.default_rng(seed).standard_normal(240)
    assert other.cooling_rate(noisy, 22.0) == pytest.approx(0.3, rel=0.03)


def test_cooling_rate_is_the_least_squares_rate_in_degc():
    # Only r free: at the returned r the derivative of sum(res^2) in r vanishes and nearby rates fit worse.
    noisy = t_cool_trace(rate=0.3) + 0.2 * np.random.default_rng(7).standard_normal(240)
    rate = other.cooling_rate(noisy, 22.0)
    tail = noisy[noisy.argmax():]
    t = np.arange(tail.size) / 20.0

    def cost(r: float) -> float:
        return float(np.sum((22.0 + (tail[0] - 22.0) * np.exp(-r * t) - tail) ** 2))

    gradient = (cost(rate + 1e-7) - cost(rate - 1e-7)) / 2e-7
    assert abs(gradient) < 1e-4 * cost(rate)
    assert cost(rate) < cost(rate * 0.99) and cost(rate) < cost(rate * 1.01)


@pytest.mark.parametrize(("t_amb", "fs"), [(math.inf, 20.0), (22.0, 0.0), (22.0, math.nan)])
def test_cooling_rate_rejects_infinite_ambient_or_bad_rate(t_amb, fs):
    with pytest.raises(ValueError, match="t_amb|sample rate"):
        other.cooling_rate(t_cool_trace(), t_amb, fs)


def test_cooling_rate_of_a_flat_trace_is_zero():
    assert other.cooling_rate(np.full(50, 30.0), 22.0) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("t_cool", "t_amb"), [
    (t_cool_trace(), math.nan),  # ambient unknown
    (np.linspace(22.0, 30.0, 50), 22.0),  # maximum at the last sample: nothing to fit
    (np.full(50, 22.0), 22.0),  # T_max == t_amb: r does not change the model
    (np.r_[30.0, np.full(20, 22.0)], 22.0),  # instant drop to ambient: the optimum is r = infinity
    (np.r_[30.0, np.full(20, 21.0)], 22.0),  # below ambient at once: the same
])
def test_cooling_rate_is_nan_where_undefined(t_cool, t_amb):
    assert math.isnan(other.cooling_rate(t_cool, t_amb))


# --- slide vibration ------------------------------------------------------------------------------------

def test_vibration_statistics_of_a_sine():
    v = 0.8 * np.sin(2 * np.pi * np.arange(3000) / 30.0)
    assert other.vib_std(v) == pytest.approx(0.8 / math.sqrt(2), rel=1e-12)
    assert other.vib_kurtosis(v) == pytest.approx(1.5, rel=1e-12)  # Pearson: excess would be -1.5
    assert other.vib_energy(v) == pytest.approx(0.32, rel=1e-12)


def test_vibration_statistics_of_a_two_level_signal():
    # +-1 around a mean of 2: population std 1 (the sample std would be 2/sqrt(3)), kurtosis 1.
    v = np.array([3.0, 1.0, 3.0, 1.0])
    assert other.vib_std(v) == 1.0
    assert other.vib_kurtosis(v) == 1.0
    assert other.vib_energy(v) == 5.0


def test_kurtosis_of_a_single_spike():
    # One spike of height h in n samples: mu4 / sigma^4 = (n^2 - 3n + 3) / (n - 1) (for n = 10: 73/9).
    v = np.zeros(10)
    v[3] = 4.0
    assert other.vib_kurtosis(v) == pytest.approx(73 / 9, rel=1e-12)


def test_kurtosis_of_a_constant_signal_is_nan():
    assert math.isnan(other.vib_kurtosis(np.full(100, 0.3)))
    assert other.vib_std(np.full(100, 0.3)) == 0.0
    # Whatever the constant: 0.2 and 0.1 have no exact binary mean, whose rounding left residues of 1e-17
    # that scored as a signal of kurtosis 1.0.
    for constant in (0.1, 0.2, 1.2, -7.7, 1e300):
        assert math.isnan(other.vib_kurtosis(np.full(100, constant)))


def test_vibration_centroid_of_a_tone_is_its_frequency():
    t = np.arange(3000) / FS
    assert other.vib_centroid(np.sin(2 * np.pi * 400.0 * t), FS) == pytest.approx(400.0, rel=1e-9)
    assert math.isnan(other.vib_centroid(np.zeros(3000), FS))


# --- tool tap -------------------------------------------------------------------------------------------

def tap(freq: float = 300.0, tau: float = 0.01, axes=(3.0, 4.0, 12.0), n: int = 3000, onset: int = 1000):
    """A band-limited tap as docs/features.md#other sees it: a decaying cosine on three in-phase axes."""
    return np.outer(decaying(freq, tau, n, onset), axes)


def geometric_centroid(freq: float, tau: float, n: int) -> float:
    """Spectral centroid of ``r^k cos(theta k)``, k < n, from the DFT as two geometric series.

    ``X_j = 1/2 sum (r e^{i(theta - w_j)})^k + 1/2 sum (r e^{-i(theta + w_j)})^k`` with ``w_j = 2 pi j / n``,
    each sum ``(1 - z^n) / (1 - z)``; the centroid is ``fs sum (j/n) |X_j| / sum |X_j|`` over j = 0..n//2.
    """
    r, theta = math.exp(-1.0 / (FS * tau)), 2 * math.pi * freq / FS
    j = np.arange(n // 2 + 1)
    omega = 2 * np.pi * j / n
    z1, z2 = r * np.exp(1j * (theta - omega)), r * np.exp(-1j * (theta + omega))
    magnitude = np.abs(0.5 * (1 - z1**n) / (1 - z1) + 0.5 * (1 - z2**n) / (1 - z2))
    return float(FS * np.sum(j / n * magnitude) / np.sum(magnitude))


def test_tap_peak_is_the_root_of_the_largest_three_axis_energy():
    assert other.tap_peak(tap()) == pytest.approx(13.0, rel=1e-15)  # sqrt(3^2 + 4^2 + 12^2)
    assert other.tap_peak(np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 2.0], [2.0, 0.0, 0.0]])) == 3.0


def test_tap_response_is_150_samples_from_the_peak_combined_by_dft321():
    y = other.tap_response(tap())
    # In-phase axes (3, 4, 12) combine to 13 times the common signal, which peaks at its onset.
    expected = 13.0 * decaying(300.0, 0.01, 3000, 1000)[1000:1150]
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12)


def test_tap_response_is_shorter_at_the_end_of_the_recording():
    a = tap(n=1100)
    assert other.tap_response(a).shape == (100,)


def test_tap_centroid_of_a_decaying_cosine_matches_the_geometric_series():
    _, centroid, _ = other.tap_features(tap(freq=300.0, tau=0.01), FS)
    assert centroid == pytest.approx(geometric_centroid(300.0, 0.01, 150), rel=1e-9)
    _, centroid, _ = other.tap_features(tap(freq=600.0, tau=0.004, n=1120), FS)  # 120 samples left
    assert centroid == pytest.approx(geometric_centroid(600.0, 0.004, 120), rel=1e-9)


def test_tap_centroid_of_a_long_ring_is_near_its_frequency():
    # tau >> 50 ms: a nearly pure tone of 15 whole periods in the 150 samples.
    _, centroid, _ = other.tap_features(tap(freq=300.0, tau=100.0), FS)
    assert centroid == pytest.approx(300.0, rel=1e-3)


@pytest.mark.parametrize(("freq", "tau"), [(300.0, 0.01), (600.0, 0.01), (450.0, 0.005)])
def test_tap_decay_recovers_tau(freq, tau):
    # The Hilbert envelope of a finite segment is not exactly exponential at its ends: a few % at most.
    _, _, decay = other.tap_features(tap(freq=freq, tau=tau), FS)
    assert decay == pytest.approx(tau, rel=0.03)


def test_tap_decay_uses_the_sample_rate():
    y = 13.0 * decaying(300.0, 0.01, 150)
    assert other.tap_decay(y, 1500.0) == pytest.approx(2 * other.tap_decay(y, FS), rel=1e-6)


def test_tap_too_near_the_end_has_no_centroid_or_decay():
    a = np.zeros((3000, 3))
    a[-29] = (0.0, 3.0, 4.0)  # 29 samples from the peak on: fewer than 30
    peak, centroid, decay = other.tap_features(a, FS)
    assert peak == 5.0
    assert math.isnan(centroid) and math.isnan(decay)


def test_tap_with_exactly_30_samples_left_is_analysed():
    # An impulse has a flat spectrum: centroid fs * mean(j / N) over j = 0..N//2 = fs / 4 for even N.
    a = np.zeros((3000, 3))
    a[-30] = (0.0, 3.0, 4.0)
    peak, centroid, _ = other.tap_features(a, FS)
    assert peak == 5.0
    assert centroid == pytest.approx(FS / 4, rel=1e-12)


def test_tap_decay_of_a_zero_envelope_is_nan():
    assert math.isnan(other.tap_decay(np.zeros(150), FS))
    assert math.isnan(other.tap_centroid(np.zeros(150), FS))


def test_tap_decay_of_a_growing_response_is_nan():
    # A rising envelope fits only a negative tau, which docs/features.md#other rejects.
    t = np.arange(150) / FS
    assert math.isnan(other.tap_decay(np.exp(t / 0.01) * np.cos(2 * np.pi * 300.0 * t), FS))


def test_tap_features_reject_a_one_dimensional_tap():
    with pytest.raises(ValueError, match=r"\(n, axes\)"):
        other.tap_features(np.ones(100), FS)


# --- simulated materials --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def simulated():
    """Other features of simulated scans, by (material slug, seed)."""
    cache: dict[tuple[str, int], dict[str, float]] = {}

    def features(slug: str, seed: int) -> dict[str, float]:
        if (slug, seed) not in cache:  # a slug the library lacks fails here, naming it
            cache[slug, seed] = other.compute(simulation.synthetic_scan(slug, seed=seed, image_size=(64, 64)))
        return cache[slug, seed]

    return features


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_metal_conducts_and_foam_does_not(simulated, seed):
    assert simulated("mild-steel-brushed", seed)["other.metal"] == 1.0
    assert simulated("polyurethane-foam", seed)["other.metal"] == 0.0


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_ferromagnetic_steel_moves_the_field_far_more_than_aluminium(simulated, seed):
    steel = abs(simulated("mild-steel-brushed", seed)["other.magnet_peak"])
    aluminium = abs(simulated("aluminium-sheet", seed)["other.magnet_peak"])
    assert steel > 10 * aluminium


@pytest.mark.parametrize("seed", [0, 1])
def test_simulated_balsa_is_much_lighter_than_pine(simulated, seed):
    balsa, pine = simulated("balsa-planed", seed), simulated("pine-planed", seed)
    assert balsa["other.density"] < 0.5 * pine["other.density"]


@pytest.mark.parametrize("seed", range(5))
def test_fitted_features_are_within_their_solver_tolerance_of_the_converged_fit(seed):
    # features.SOLVER_RTOL claims each fit's stopping rule leaves its result within that relative distance
    # of the least-squares optimum: compare with the same fits run to xtol = ftol = 1e-15, on noisy taps
    # (a large-residual fit, where the default stopping rule stops farthest out) and noisy cooling curves.
    from scipy import optimize, signal

    rng = np.random.default_rng(seed)
    y = decaying(rng.uniform(200.0, 800.0), rng.uniform(0.003, 0.03), 150) + rng.normal(0.0, 0.05, 150)
    envelope = np.abs(signal.hilbert(y))
    t = np.arange(150) / FS
    (_, tau), _ = optimize.curve_fit(lambda t, a, tau: a * np.exp(-t / tau), t, envelope,
                                     p0=(float(envelope.max()), other.TAP_TAU0), xtol=1e-15, ftol=1e-15)
    assert other.tap_decay(y, FS) == pytest.approx(tau, rel=other.SOLVER_RTOL["other.tap_decay"])

    t = np.arange(600) / 20.0
    t_cool = 22.0 + rng.uniform(3.0, 12.0) * np.exp(-rng.uniform(0.01, 0.3) * t) + rng.normal(0.0, 0.05, 600)
    tail = t_cool[int(np.argmax(t_cool)):]
    excess, t = tail[0] - 22.0, t[:tail.size]
    fit = optimize.least_squares(lambda r: 22.0 + excess * np.exp(-r[0] * t) - tail, [0.1], method="lm",
                                 xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert other.cooling_rate(t_cool, 22.0) == pytest.approx(fit.x[0], rel=other.SOLVER_RTOL["other.cooling_rate"])
