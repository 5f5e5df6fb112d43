"""Related-work feature sets (docs/features.md#related) on inputs whose answers are known in closed form."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import make_meta
from scipy import signal

from features.recordings import scan_recording
from features.tactum import mico
from scanner.preprocess import slide_signal
from scanner.scan import Recording, Scan, Trace
from taxonomy.related.chathuranga_features import (
    chathuranga4,
    chathuranga_period,
    covariance_frobenius,
    friction_features,
)
from taxonomy.related.fishel_features import fishel3
from taxonomy.related.hoelscher_features import (
    MAX_EXPONENT,
    _exponential,
    chitta,
    chu,
    dallaire,
    electrode_norm,
    electrode_polynomials,
    energy_spectral_density,
    mean23,
    pressure_statistics,
    settled,
    spectral_moments,
    temperature,
    threshold_crossings,
    time_constant,
    upper_spectrum_sum,
    xu3,
)
from taxonomy.related.huang_features import band_means, huang7
from taxonomy.related.inputs import RelatedFeatureError
from taxonomy.related.sets import FEATURE_SETS, compute
from taxonomy.related.xie_features import XieFeatures, wavelet_l1, xie11, xie11_from_sequences, xie_sequences

HADAMARD = np.array([[1, 1, 1, 1], [1, -1, 1, -1], [1, 1, -1, -1], [1, -1, -1, 1]], dtype=float)


def tone(frequency: float, fs: float, seconds: float, amplitude: float = 1.0,
         phase: float = 0.0) -> np.ndarray:
    t = np.arange(int(round(fs * seconds))) / fs
    return amplitude * np.sin(2 * np.pi * frequency * t + phase)


def recording(**roles: Trace) -> Recording:
    channels = {role: trace for role, trace in roles.items()}
    return Recording("r1", channels, {role: role for role in roles}, "sponge", {"object": "sponge-1"})


# -- inputs and errors -------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(FEATURE_SETS))
def test_every_set_names_the_roles_it_needs(name):
    bare = Recording("bare", {"x": Trace(np.zeros(10), 100.0, "-")})
    with pytest.raises(RelatedFeatureError) as info:
        compute(name, bare)
    message = str(info.value)
    assert "\n" not in message and name in message and "'bare'" in message
    needed = ("taxels or electrodes",) if name == "xie11" else FEATURE_SETS[name].roles
    assert all(role in message for role in needed)


def test_missing_role_lists_only_the_absent_ones():
    partial = recording(heat_flow=Trace(np.ones(10), 100.0, "-"))
    with pytest.raises(RelatedFeatureError, match="xu3 needs the role.*electrodes, vibration, heat_flow; "
                                               "recording 'r1' lacks electrodes, vibration$"):
        xu3(partial)


def test_unknown_set():
    with pytest.raises(RelatedFeatureError, match="unknown feature set 'nope'"):
        compute("nope", recording(vibration=Trace(np.zeros(4), 10.0, "-")))


# -- fishel3 on scans --------------------------------------------------------------------------------

def _fishel_scan(amplitude: float = 0.4) -> Scan:
    fs = 3000.0
    v_ts = np.zeros((9000, 3))
    v_ts[1500:, 0] = amplitude * np.sin(2 * np.pi * 250.0 * np.arange(7500) / fs)
    f_frn = np.full(9000, 2.0)
    f_frt = np.where(np.arange(9000) >= 600, 1.0, 0.0)
    traces = {"v_ts": Trace(v_ts, fs, "g"), "f_frn": Trace(f_frn, fs, "N"), "f_frt": Trace(f_frt, fs, "N")}
    return Scan(make_meta(), traces)


def test_fishel3_traction_roughness_fineness():
    scan = _fishel_scan(0.4)
    values = fishel3(scan)
    # Normal force 2 N throughout, friction steps to 1 N: the sliding segment averages 1 / 2.
    assert values["fishel3.traction"] == pytest.approx(0.5, abs=1e-12)
    v = slide_signal(scan["v_ts"])
    assert values["fishel3.roughness"] == pytest.approx(math.log10(np.mean(v**2)), rel=1e-12)
    # A 0.4 g sine at 250 Hz: mean(v^2) = 0.08 g^2. The magnitude centroid sums the small broadband
    # leakage of the band-pass at the slide onset over 1500 bins, so it lies near, not at, the tone.
    assert values["fishel3.roughness"] == pytest.approx(math.log10(0.08), abs=0.01)
    assert values["fishel3.fineness"] == pytest.approx(mico(v, 3000.0), rel=1e-12)
    assert 240.0 < values["fishel3.fineness"] < 300.0


def test_fishel3_needs_the_friction_channels():
    scan = _fishel_scan()
    partial = Scan(scan.meta, {"v_ts": scan["v_ts"], "f_frn": scan["f_frn"]})
    with pytest.raises(RelatedFeatureError, match="fishel3 needs the scan channels v_ts, f_frn, f_frt; scan "
                                               "granite-01-001 lacks f_frt"):
        fishel3(partial)


def test_fishel3_without_a_slide_is_nan_not_an_error():
    scan = _fishel_scan(0.0)
    values = fishel3(scan)
    assert values["fishel3.traction"] == pytest.approx(0.5)
    assert math.isnan(values["fishel3.roughness"]) and math.isnan(values["fishel3.fineness"])


# -- xie11 -------------------------------------------------------------------------------------------

def test_xie_sequences_of_known_images():
    frames = np.array([[[0.0, 1.0], [2.0, 3.0]], [[0.0, 0.0], [0.0, 4.0]]])
    s_a, s_v, s_s = xie_sequences(frames)
    assert s_a.tolist() == [3.0, 1.0]
    assert s_v.tolist() == [1.25, 3.0]  # var(0, 1, 2, 3) and var(0, 0, 0, 4), population
    assert s_s.tolist() == [6.0, 4.0]


def test_wavelet_l1_of_a_constant_and_of_an_impulse():
    # db3 has vanishing moments, so a constant has no details; each cA4 coefficient is c * sqrt(2)^4.
    l1 = wavelet_l1(np.full(100, 2.0))
    assert l1[0] == pytest.approx(10 * 4 * 2.0, rel=1e-12) and np.all(np.abs(l1[1:]) < 1e-12)
    # A unit impulse at an interior even index meets the odd-indexed taps of the decomposition high-pass.
    impulse = np.zeros(100)
    impulse[50] = 1.0
    taps = np.abs(np.array(__import__("pywt").Wavelet("db3").dec_hi))
    assert wavelet_l1(impulse, level=1)[1] == pytest.approx(taps[1::2].sum(), rel=1e-12)


def test_xie11_from_known_sequences():
    n = 100
    s_a, s_v = np.full(n, 5.0), np.full(n, 0.5)
    constant = xie11_from_sequences(s_a, s_v, np.full(n, 3.0))
    assert constant.tolist()[:3] == [5.0, 0.5, 3.0]
    assert constant[3] == pytest.approx(10 * 4 * 3.0) and np.all(np.abs(constant[4:8]) < 1e-12)
    assert constant[8] == pytest.approx(n * 9.0) and constant[9] == 0.0 and constant[10] == 0.0
    ramp = xie11_from_sequences(s_a, s_v, 0.25 * np.arange(n))
    assert ramp[9] == pytest.approx(0.25 * math.sqrt(n - 1), rel=1e-12)  # CID of a ramp, eq. (2)
    assert ramp[8] == pytest.approx(0.0625 * sum(i * i for i in range(n)), rel=1e-12)  # eq. (1)
    assert ramp[10] == pytest.approx(0.25 * math.sqrt((n * n - 1) / 12.0), rel=1e-12)


def test_xie_features_standardise_on_training_rows_only():
    rng = np.random.default_rng(0)
    train, test = rng.normal(5.0, 2.0, (30, 300)), rng.normal(5.0, 2.0, (4, 300))
    step = XieFeatures().fit(train)
    out = step.transform(train)
    # Every column of the standardised training vectors has mean 0, so the three sequence means do too.
    assert out.shape == (30, 11) and np.allclose(out[:, :3].mean(axis=0), 0.0, atol=1e-12)
    assert np.allclose(step.transform(test), step.transform(np.vstack([test, train]))[:4])
    unchanged = XieFeatures().fit(train).transform(test)
    assert np.array_equal(unchanged, step.transform(test))


def test_xie11_needs_one_second_of_frames():
    short = recording(taxels=Trace(np.ones((50, 4, 4)), 100.0, "-"))
    with pytest.raises(RelatedFeatureError, match=r"xie11 needs 1 s of taxels \(100 frames at 100 Hz\); "
                                                  r"recording 'r1' has 50"):
        xie11(short)
    electrodes = recording(electrodes=Trace(np.arange(300.0).reshape(150, 2), 100.0, "-"))
    assert xie11(electrodes)["xie11.mean_sa"] == pytest.approx(1.99)  # one zero electrode in row 0


# -- huang7 ------------------------------------------------------------------------------------------

def test_band_means_of_a_sum_of_sines():
    fs = 2200.0
    x = 7.0 + tone(30.0, fs, 1.0, 3.0) + tone(75.0, fs, 1.0, 5.0) + tone(130.0, fs, 1.0, 2.0, 0.3)
    # 1 s: 1 Hz bins, 20 per band; a sine of amplitude A puts A / 2 into one bin. The offset is removed.
    expected = [0.0, 3.0 / 40, 0.0, 5.0 / 40, 0.0, 0.0, 2.0 / 40]
    values = huang7(recording(vibration=Trace(x, fs, "bit")))
    assert list(values) == ["huang7.band_000_020", "huang7.band_020_040", "huang7.band_040_060",
                            "huang7.band_060_080", "huang7.band_080_100", "huang7.band_100_120",
                            "huang7.band_120_140"]
    assert np.allclose(list(values.values()), expected, atol=1e-12)


def test_band_means_bins_at_band_edges_and_short_signals():
    # 0.5 s at 200 Hz: 2 Hz bins; 20 Hz belongs to band 1, not band 0; 100 Hz (Nyquist) is in band 5.
    x = tone(20.0, 200.0, 0.5, 2.0)
    means = band_means(x, 200.0)
    assert means[0] == pytest.approx(0.0, abs=1e-12) and means[1] == pytest.approx(1.0 / 10)
    assert math.isnan(means[6])  # no bin at or above 120 Hz


# -- chathuranga4 and baselines ----------------------------------------------------------------------

def test_frobenius_norm_of_a_known_covariance():
    a, b, c = 2.0, 0.5, 3.0
    xyz = np.tile(np.column_stack([a * HADAMARD[:, 1], b * HADAMARD[:, 2], c * HADAMARD[:, 3]]), (2, 1))
    xyz += [1.0, -2.0, 4.0]
    # Orthogonal zero-mean columns: the covariance is diag(a^2, b^2, c^2).
    assert covariance_frobenius(xyz) == pytest.approx(math.sqrt(a**4 + b**4 + c**4), rel=1e-12)
    same = np.column_stack([HADAMARD[:, 1], HADAMARD[:, 1], np.zeros(4)])
    assert covariance_frobenius(same) == pytest.approx(2.0)  # [[1, 1, 0], [1, 1, 0], [0, 0, 0]]
    values = chathuranga4(recording(force_xyz=Trace(xyz, 1000.0, "V")))
    assert values == pytest.approx({"chathuranga4.frobenius": math.sqrt(a**4 + b**4 + c**4),
                                    "chathuranga4.mean_x": 1.0, "chathuranga4.mean_y": -2.0,
                                    "chathuranga4.mean_z": 4.0})


def test_spatial_period_is_velocity_over_principal_frequency():
    x = 3.0 + tone(5.0, 1000.0, 1.0) + 0.2 * tone(40.0, 1000.0, 1.0)
    xyz = np.column_stack([x, np.zeros_like(x), np.ones_like(x)])
    r = Recording("p", {"s": Trace(xyz, 1000.0, "V")}, {"force_xyz": "s"}, "denim",
                  meta={"velocity_mm_s": 15.0})
    assert chathuranga_period(r) == {"chathuranga_period.lambda": pytest.approx(3.0)}
    with pytest.raises(RelatedFeatureError, match="velocity_mm_s"):
        chathuranga_period(Recording("p", {"s": Trace(xyz, 1000.0, "V")}, {"force_xyz": "s"}))


def test_friction_features():
    xyz = np.column_stack([np.full(8, 3.0), np.full(8, 4.0), np.full(8, 10.0)])
    mu, var_x, kurt_x = friction_features(xyz)
    assert mu == pytest.approx(0.5) and var_x == 0.0 and math.isnan(kurt_x)
    two_point = np.column_stack([np.tile([1.0, -1.0], 4), np.zeros(8), np.tile([1.0, 0.0], 4)])
    mu, var_x, kurt_x = friction_features(two_point)
    # z = 0 rows are left out of the ratio; +-1 has variance 1 and Pearson kurtosis 1.
    assert mu == pytest.approx(1.0) and var_x == pytest.approx(1.0) and kurt_x == pytest.approx(1.0)


# -- xu3 ---------------------------------------------------------------------------------------------

def test_xu3():
    fs, n = 2200.0, 4400
    electrodes = np.full((200, 19), 3000.0)
    electrodes[:, 17] += np.linspace(0.0, math.e, 200)
    vibration = tone(100.0, fs, n / fs, 0.2)
    heat_flow = np.concatenate([np.linspace(0, 50, 100), np.linspace(50, -20, 100)])
    r = recording(electrodes=Trace(electrodes, 100.0, "bit"), vibration=Trace(vibration, fs, "bit"),
                  heat_flow=Trace(heat_flow, 100.0, "bit"))
    values = xu3(r)
    assert values["xu3.compliance"] == pytest.approx(1.0, rel=1e-12)  # ln(e)
    # The variance of a 0.2 sine well inside the pass band (filter edges leave a small deficit).
    assert values["xu3.texture"] == pytest.approx(math.log(0.02), abs=2e-3)
    assert values["xu3.thermal"] == pytest.approx(70.0)
    # Fewer than 18 electrodes: the mean electrode; a flat one has ln(0) = NaN.
    few = recording(electrodes=Trace(np.ones((200, 3)), 100.0, "bit"), vibration=Trace(vibration, fs, "bit"),
                    heat_flow=Trace(heat_flow, 100.0, "bit"))
    assert math.isnan(xu3(few)["xu3.compliance"])


# -- chu ---------------------------------------------------------------------------------------------

def test_pressure_statistics_of_a_constant_and_a_ramp():
    assert pressure_statistics(np.full(300, 4.0), 100.0).tolist() == pytest.approx([4.0, 4.0, 0.0])
    ramp = 0.5 * np.arange(300.0)
    high, mean, change = pressure_statistics(ramp, 100.0)
    # A symmetric window keeps a ramp in the interior: slope 0.5 per sample = 50 per second.
    assert change == pytest.approx(50.0, rel=1e-12)
    assert mean < ramp.mean() + 1e-9 and high <= ramp[-1]


def test_spectral_moments_of_two_tones():
    fs = 1000.0
    x = tone(100.0, fs, 2.0, 1.0) + tone(300.0, fs, 2.0, 1.0)
    frequency, energy = energy_spectral_density(x, fs)
    area, centroid, variance, skewness, kurtosis = spectral_moments(frequency, energy)
    assert area == pytest.approx(np.sum(x**2) / fs, rel=1e-12)  # Parseval: the signal's energy
    assert centroid == pytest.approx(200.0) and variance == pytest.approx(100.0**2)
    assert skewness == pytest.approx(0.0, abs=1e-9) and kurtosis == pytest.approx(1.0)
    one = spectral_moments(*energy_spectral_density(tone(125.0, fs, 1.0), fs))
    assert one[1] == pytest.approx(125.0) and one[2] == pytest.approx(0.0, abs=1e-6)


def test_time_constant_of_an_exponential():
    t = np.arange(1500) / 100.0
    assert time_constant(30.0 + 5.0 * np.exp(-t / 2.5), 100.0) == pytest.approx(2.5, rel=1e-6)
    assert math.isnan(time_constant(np.full(100, 3.0), 100.0))


def test_time_constant_far_below_the_start_fits_without_overflow():
    # tau = 0.05 s against a start of duration / 3 = 4.3 s: on its way the optimiser tries growing curves
    # (tau < 0) whose exp(-t / tau) overflowed to inf ("overflow encountered in exp").
    t = np.arange(130) / 10.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tau = time_constant(20.0 + 10.0 * np.exp(-t / 0.05), 10.0)
    # Exact samples: the fit ends on the generating tau within curve_fit's xtol, its relative step at the end.
    assert tau == pytest.approx(0.05, rel=1.49012e-8)
    # The capped model is the formula itself wherever exp does not overflow, and finite where it would.
    np.testing.assert_array_equal(_exponential(t, 20.0, 10.0, 0.05), 20.0 + 10.0 * np.exp(-t / 0.05))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        growing = _exponential(np.array([0.0, 1000.0]), 20.0, 10.0, -1.0)
    assert growing[0] == 30.0 and growing[1] == 20.0 + 10.0 * math.exp(MAX_EXPONENT)


def test_electrode_polynomials_of_known_components():
    n = 101
    t = np.linspace(0.0, 1.0, n)
    s1 = 3.0 * (t - 0.5)  # odd about the centre
    s2 = 0.5 * ((t - 0.5) ** 2 - np.mean((t - 0.5) ** 2))  # even: orthogonal to s1, smaller variance
    u1 = np.array([0.6, 0.8, 0.0])
    u2 = np.array([0.0, 0.0, -1.0])
    electrodes = 100.0 + np.outer(s1, u1) + np.outer(s2, u2)
    coefficients = electrode_polynomials(electrodes)
    expected_pc1 = [0, 0, 0, 0, 3.0, -1.5]
    # PC2's loading -1 is flipped positive: scores -s2 = -0.5 t^2 + 0.5 t - (0.125 - 0.5 mean(...)).
    c0 = -0.5 * (0.25 - np.mean((t - 0.5) ** 2))
    expected_pc2 = [0, 0, 0, -0.5, 0.5, c0]
    assert np.allclose(coefficients, [*expected_pc1, *expected_pc2], atol=1e-8)


def test_chu_returns_22_values():
    rng = np.random.default_rng(1)
    t = np.arange(400) / 100.0
    r = recording(pressure_dc=Trace(100 + t, 100.0, "bit"),
                  vibration=Trace(rng.normal(size=8800), 2200.0, "bit"),
                  heat_flow=Trace(np.full(400, 2.0), 100.0, "bit"),
                  temperature=Trace(30 + 3 * np.exp(-t / 1.5), 100.0, "bit"),
                  electrodes=Trace(rng.normal(size=(400, 19)), 100.0, "bit"))
    values = chu(r)
    assert len(values) == 22 and list(values)[-1] == "chu.pc2_p0"
    assert values["chu.tac_area"] == pytest.approx(8.0)
    assert values["chu.tdc_tau"] == pytest.approx(1.5, rel=1e-6)


# -- mean23, dallaire, chitta, temperature -----------------------------------------------------------

def test_mean23_is_the_channel_means():
    r = recording(pressure_dc=Trace(np.full(10, 1.0), 100.0, "-"),
                  vibration=Trace(np.full(220, 2.0), 2200.0, "-"),
                  temperature=Trace(np.full(10, 3.0), 100.0, "-"),
                  heat_flow=Trace(np.full(10, 4.0), 100.0, "-"),
                  electrodes=Trace(np.tile(np.arange(19.0), (10, 1)), 100.0, "-"))
    values = mean23(r)
    assert len(values) == 23 and list(values.values()) == [1.0, 2.0, 3.0, 4.0, *range(19)]
    assert list(values)[4] == "mean23.electrode_01"


def test_dallaire_on_a_sine_and_a_ramp():
    n, period = 4000, 40  # fs / f = 40 samples: the samples include both peaks
    x = 2.0 * np.sin(2 * np.pi * np.arange(n) / period)
    values = dallaire(recording(vibration=Trace(x, 4000.0, "-")))
    assert values["dallaire.variance"] == pytest.approx(2.0)
    assert values["dallaire.skewness"] == pytest.approx(0.0, abs=1e-12)
    assert values["dallaire.kurtosis"] == pytest.approx(1.5)
    assert values["dallaire.moment5"] == pytest.approx(0.0, abs=1e-10)
    # 100 whole periods of 4 A each, less the last step back to 0 that the final sample does not take.
    expected = 4 * 2.0 * n / period - 2.0 * math.sin(2 * math.pi / period)
    assert values["dallaire.total_variation"] == pytest.approx(expected, rel=1e-12)
    # 100 Hz of 4000 Hz is bin 100 < N / 4: nothing in the upper half of the spectrum.
    assert values["dallaire.upper_spectrum"] == pytest.approx(0.0, abs=1e-8)
    assert threshold_crossings(np.linspace(-3.0, 5.0, 77)) == 20
    assert threshold_crossings(np.array([0.0, 1.0, 0.0, 1.0])) == 60


def test_upper_spectrum_sum_of_a_high_tone():
    n = 400
    high = 3.0 * np.cos(2 * np.pi * 150 * np.arange(n) / n)  # bin 150 >= 400 / 4
    low = np.cos(2 * np.pi * 20 * np.arange(n) / n)
    assert upper_spectrum_sum(high + low) == pytest.approx(3.0 * n / 2)


def test_chitta_electrode_norm():
    assert chitta(recording(electrodes=Trace(np.full((500, 19), 7.0), 100.0, "-"))) == \
        pytest.approx({"chitta.mean": 0.0, "chitta.variance": 0.0}, abs=1e-9)
    fs, f = 100.0, 20.0
    t = np.arange(2000) / fs
    pair = np.column_stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)])
    sos = signal.butter(1, 5.0, btype="highpass", fs=fs, output="sos")
    _, response = signal.sosfreqz(sos, worN=[f], fs=fs)
    norm = electrode_norm(pair, fs)
    # cos and sin pass with the same gain and phase: their norm is the gain (after the start transient).
    assert np.allclose(norm[200:], abs(response[0]), rtol=1e-9)


def test_temperature_features():
    fs = 100.0
    tac = np.concatenate([np.linspace(0.0, 10.0, 100), np.linspace(10.0, 4.0, 500), np.full(900, 4.0)])
    tdc = np.concatenate([np.full(600, 35.0), np.full(900, 31.0)])
    values = temperature(recording(heat_flow=Trace(tac, fs, "-"), temperature=Trace(tdc, fs, "-")))
    assert values == pytest.approx({"temperature.tac_mean": 4.0, "temperature.tdc_mean": 31.0,
                                    "temperature.tac_change": 6.0})
    # A 4 s slide has no 6 s to wait: the second half is used (interpretation).
    assert settled(np.arange(400.0), fs).tolist() == list(np.arange(200.0, 400.0))


def test_scan_recording_roles():
    scan = _fishel_scan()
    r = scan_recording(scan)
    assert dict(r.roles) == {"vibration": "v"} and r.label == scan.meta.label
    assert np.array_equal(r.channels["v"].data, slide_signal(scan["v_ts"])) and r.channels["v"].fs == 3000.0
    resting = scan_recording(_fishel_scan(0.0))
    assert resting.channels["v"].n == 9000  # no slide: the whole band-limited recording
    assert dict(r.group) == {"object": "granite-01", "trial": "001"} and r.channels["f_frn"] == scan["f_frn"]
