"""The 15 TacTUM features (docs/features.md#tactum) on inputs whose answers are known in closed form."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import pywt
from scipy.ndimage import gaussian_filter

from features import corners, tactum
from features.image import PreparedPhoto, tamura_contrast
from scanner.preprocess import crop_image, grayscale, slide_signal
from scanner.scan import Scan, ScanError, ScanMeta, Trace
from taxonomy.errors import ParameterError

FS = 3000.0


def meta(**overrides) -> ScanMeta:
    values = dict(label="C3S4M2P2X1", operator="op", sample_id="epoxy-01", scan_index=1, session_id="s-1",
                  started="2026-11-21T09:00:00+00:00", t_amb=21.0, atk=0.25, cyd=0.75)
    values.update(overrides)
    return ScanMeta(**values)


def sliding_vibration(n: int = 15000, start: int = 4500, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, 0.005, (n, 3))
    v[:, 2] += 1.0
    v[start:] += rng.normal(0.0, 0.2, (n - start, 3))
    return v


def full_traces(seed: int = 0) -> dict[str, Trace]:
    rng = np.random.default_rng(seed)
    n = 15000
    ramp = np.clip((np.arange(n) - 1000) / 1500, 0.0, 1.0)
    return {
        "v_ts": Trace(sliding_vibration(seed=seed), FS, "g"),
        "r_ts": Trace(1.2 + 0.01 * rng.normal(size=n), FS, "V"),
        "f_frn": Trace(0.1 + 3.0 * ramp, FS, "N"),
        "f_frt": Trace(0.2 + 1.0 * ramp + 0.01 * rng.normal(size=n), FS, "N"),
        "f_press": Trace(0.1 + 4.0 * ramp, FS, "N"),
        "f_fold": Trace(0.1 + 2.0 * ramp, FS, "N"),
        "alpha_f": Trace(30.0 * ramp, FS, "deg"),
        "t_cool": Trace(21.0 + 8.0 * np.exp(-np.arange(200) / 60.0), 20.0, "degC"),
    }


def photo(seed: int = 0, shape: tuple[int, int] = (320, 360)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    gray = gaussian_filter(rng.uniform(0, 255, shape), 2.0)
    gray = (gray - gray.min()) / np.ptp(gray) * 255
    return np.repeat(gray.astype(np.uint8)[..., None], 3, axis=2)


def full_scan(*, drop: tuple[str, ...] = (), traces: dict[str, Trace] | None = None, image: bool = True,
              **meta_overrides) -> Scan:
    channels = {**full_traces(), **(traces or {})}
    channels = {name: trace for name, trace in channels.items() if name not in drop}
    return Scan(meta(**meta_overrides), channels, {"I_disp": photo()} if image else {})


def direct_movmean(x: np.ndarray, window: int) -> np.ndarray:
    """MATLAB movmean by its definition: the mean of x[i - window//2 .. i + (window-1)//2 ... ] clipped."""
    before, after = window // 2, window - window // 2 - 1
    return np.array([np.mean(x[max(0, i - before):i + after + 1]) for i in range(x.size)])


# --- names and order ------------------------------------------------------------------------------------

def test_names_are_the_fifteen_in_paper_order():
    assert tactum.NAMES == ("tactum.matx", "tactum.maco", "tactum.marg", "tactum.miro", "tactum.mico",
                            "tactum.fst", "tactum.frs", "tactum.atk", "tactum.ccp", "tactum.cdf",
                            "tactum.cdp", "tactum.crx", "tactum.cyd", "tactum.tco", "tactum.tpr")


def test_compute_returns_finite_floats_in_order_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = tactum.compute(full_scan())
    assert tuple(values) == tactum.NAMES
    assert all(isinstance(value, float) and math.isfinite(value) for value in values.values())
    assert values["tactum.atk"] == 0.25 and values["tactum.cyd"] == 0.75


def test_compute_is_deterministic():
    assert tactum.compute(full_scan()) == tactum.compute(full_scan())


# --- 1. MaTX ----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("window", [1, 2, 3, 4, 5, 6])
def test_movmean_matches_the_direct_definition_on_short_inputs(window):
    for n in range(1, 9):
        x = np.random.default_rng(n).normal(size=n)
        np.testing.assert_allclose(tactum.movmean(x, window), direct_movmean(x, window), rtol=1e-13)


def test_ma100_window_is_fifty_before_and_forty_nine_after():
    x = np.zeros(301)
    x[150] = 100.0
    ma = tactum.movmean(x)
    # Sample i sees x[150] iff i - 50 <= 150 <= i + 49, i.e. 101 <= i <= 200.
    assert np.flatnonzero(ma).tolist() == list(range(101, 201))
    np.testing.assert_allclose(ma[101:201], 1.0)
    edge = np.arange(1.0, 11.0)
    assert tactum.movmean(edge)[0] == pytest.approx(np.mean(edge))  # shrinks to the 10 samples there are


def test_vs_keeps_only_the_planted_spikes():
    n, base, height = 3000, 0.01, 1.0
    va = np.full(n, base)
    spikes = [400, 1700, 2999]         # the last one sits where MA100 shrinks to 50 samples
    va[spikes] += height
    va[1000] += 0.02                   # a bump below std + mean + MA100: removed
    va[420] += 0.04                    # above std + mean, but MA100 there holds the spike at 400: removed
    kept = 3 * (base + height)
    assert tactum.vs(va) == pytest.approx(math.log10(1.0 + kept / n), rel=1e-12)
    assert tactum.vs(np.full(n, 0.3)) == 0.0


def test_matx_weights_each_component():
    n = 3000
    flat = np.full(n, 2.0)
    alternating = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    rv = np.std(alternating - direct_movmean(alternating, 100))
    assert tactum.rv(alternating) == pytest.approx(rv, rel=1e-12)
    assert tactum.matx(np.zeros(n), flat, alternating) == pytest.approx(4 * rv, rel=1e-12)
    assert tactum.matx(np.zeros(n), alternating, flat) == pytest.approx(2 * rv, abs=1e-12)
    spikes = np.zeros(n)
    spikes[[500, 2500]] = [1.0, -1.0]   # MaTX takes |v|
    assert tactum.matx(spikes, flat, flat) == pytest.approx(3 * math.log10(1 + 2 / n), abs=1e-12)


# --- 2. MaCo ----------------------------------------------------------------------------------------------

def test_top_scales_mean():
    assert tactum.top_scales_mean(np.arange(1.0, 13.0)) == pytest.approx(np.mean(np.arange(3.0, 13.0)))
    assert tactum.top_scales_mean(np.array([2.0, 4.0])) == 3.0
    assert math.isnan(tactum.top_scales_mean(np.array([])))


def test_maco_is_vibration_times_contrast_times_top_scales():
    gray = grayscale(photo(1, (200, 240)))
    v = np.where(np.arange(3000) % 2 == 0, 0.5, -0.5)
    scales = corners.corner_scales(gray, corners.harris_corners(gray))
    assert scales.size > 10
    expected = 0.5 * tamura_contrast(gray) * np.mean(np.sort(scales)[-10:])
    assert tactum.maco(v, gray) == pytest.approx(expected, rel=1e-12)
    assert math.isnan(tactum.maco(v, np.full((60, 60), 9.0)))   # no corner


# --- 3. MaRG ----------------------------------------------------------------------------------------------

def test_marg_of_a_constant_image_is_zero():
    v = np.ones(3000)
    assert tactum.marg(v, np.full((128, 130), 77.3)) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("axis", "frequency", "weight"), [
    (0, 100, (2.0 - math.exp(-8.0)) / 2),    # offsets -100 (inside the window) and +100 (outside)
    (1, 30, 1.0 - math.exp(-0.72)),          # offsets +-30: 1 - exp(-900 / 1250)
])
def test_marg_of_a_cosine_grating(axis, frequency, weight):
    # I = 128 + A cos(2 pi f m / M): the centred spectrum has two peaks A sqrt(MN) / 2 at offsets +-f and
    # (numerically) zeros elsewhere; the Tamura contrast of a cosine is (A / sqrt 2) / 1.5^(1/4).
    m, n, amplitude = 256, 255, 50.0
    index = np.arange((m, n)[axis])
    profile = 128.0 + amplitude * np.cos(2 * np.pi * frequency * index / index.size)
    gray = np.broadcast_to(profile[:, None] if axis == 0 else profile[None, :], (m, n)).copy()
    peak_mean = amplitude * math.sqrt(m * n) / 2 * weight
    assert tactum.kept_peak_mean(gray) == pytest.approx(peak_mean, rel=1e-9)
    contrast = amplitude / math.sqrt(2) / 1.5**0.25
    v = np.where(np.arange(3000) % 3 == 0, -2.0, 2.0)
    assert tactum.marg(v, gray) == pytest.approx(2.0 * (peak_mean - contrast), rel=1e-9)


def spec_kept_peak_mean(gray: np.ndarray) -> float:
    """Strese et al. 2020, eqs. 9-12; docs/features.md#marg written out: full fft2, fftshift, G' element by element."""
    m, n = gray.shape
    x = np.fft.fftshift(np.fft.fft2(gray - gray.mean()).real / math.sqrt(m * n))
    g_prime = np.ones((m, n))
    for i in range(max(0, m // 2 - 100), min(m, m // 2 + 100)):
        for j in range(max(0, n // 2 - 100), min(n, n // 2 + 100)):
            g_prime[i, j] = 1 - math.exp(-((i - m // 2) ** 2 + (j - n // 2) ** 2) / (2 * 25.0**2))
    kept = x >= 0.75 * x.max()
    return float(np.mean((x * g_prime)[kept]))


# (353, 479): the primes of a cropped 12-megapixel photo (2824 x 3832 = 8 * 353 x 8 * 479).
@pytest.mark.parametrize("shape", [(64, 64), (63, 65), (230, 301), (256, 255), (353, 479), (1, 301), (300, 1),
                                   (2, 3)])
def test_kept_peak_mean_from_the_half_spectrum_equals_the_full_spectrum(shape):
    rng = np.random.default_rng(shape[0])
    rows, cols = np.mgrid[:shape[0], :shape[1]]
    gray = (5 * rng.uniform(size=shape) + 50 * np.cos(2 * np.pi * (7 * rows / shape[0] + 11 * cols / shape[1]))
            + 30 * np.cos(2 * np.pi * (-100 * rows / shape[0] + 3 * cols / shape[1])))
    assert tactum.kept_peak_mean(gray) == pytest.approx(spec_kept_peak_mean(gray), rel=1e-12)


def test_compute_with_the_prepared_photo_of_the_image_features_gives_the_same_values():
    scan = full_scan()
    disp = PreparedPhoto(scan.images["I_disp"])
    alone = tactum.compute(scan)
    assert tactum.compute(scan, disp=disp) == alone
    gray = grayscale(crop_image(scan.images["I_disp"]))
    v = slide_signal(scan["v_ts"])
    assert alone["tactum.marg"] == tactum.marg(v, gray)
    assert alone["tactum.maco"] == tactum.maco(v, gray)
    with pytest.raises(ValueError, match="I_disp"):
        tactum.compute(scan, disp=PreparedPhoto(photo(seed=1)))


# --- 4. MiRO ----------------------------------------------------------------------------------------------

def _two_level_signal(c1: float, c5: float, n: int = 3000) -> np.ndarray:
    """One db8 coefficient at level 1 (index 250) and one at level 5 (index 60), the rest zero."""
    coefficients = pywt.wavedec(np.zeros(n), "db8", level=5, mode="symmetric")
    coefficients[-1][250] = c1
    coefficients[-5][60] = c5
    return pywt.waverec(coefficients, "db8", mode="symmetric")[:n]


def test_miro_of_planted_wavelet_coefficients():
    n, c1 = 3000, 2.0
    v = _two_level_signal(c1, 0.7)
    back = pywt.wavedec(v, "db8", level=5, mode="symmetric")
    assert back[-1][250] == pytest.approx(c1) and back[-5][60] == pytest.approx(0.7)
    # D1 is |c1| |rec_hi| around sample 500, D5 a level-5 wavelet around sample 1900: disjoint, so
    # |d| = D1 on D1's support and (mean D1 / mean D5) D5 on D5's: sum |d| = 2 sum D1 = 2 |c1| sum |rec_hi|.
    rec_hi = np.abs(pywt.Wavelet("db8").rec_hi).sum()
    assert tactum.miro(v) == pytest.approx(math.log10(1 + 2 * c1 * rec_hi / n), rel=1e-9)
    # Scaling D5 leaves d unchanged.
    assert tactum.miro(_two_level_signal(c1, 7.0)) == pytest.approx(tactum.miro(v), rel=1e-12)
    assert tactum.miro(np.zeros(n)) == 0.0   # mean(D5) = 0: d = D1, no 0/0


def test_wavelet_details_and_approximation_sum_to_the_signal():
    v = np.random.default_rng(9).normal(size=3000)
    coefficients = pywt.wavedec(v, "db8", level=5, mode="symmetric")
    approximation = pywt.waverec([coefficients[0]] + [np.zeros_like(c) for c in coefficients[1:]],
                                 "db8", mode="symmetric")[:3000]
    total = approximation + sum(tactum.wavelet_detail(v, level) for level in range(1, 6))
    np.testing.assert_allclose(total, v, atol=1e-10)


# --- 5. MiCO ----------------------------------------------------------------------------------------------

def test_mico_of_a_pure_tone_is_its_frequency():
    t = np.arange(3000) / FS
    assert tactum.mico(np.sin(2 * np.pi * 437.0 * t)) == pytest.approx(437.0, rel=1e-9)


def test_spectral_centroid_of_two_tones_is_the_magnitude_weighted_mean():
    # Bin magnitudes are N a / 2 for an amplitude a, so the centroid weights the frequencies by amplitude.
    t = np.arange(2000) / 2000.0
    x = 3.0 * np.sin(2 * np.pi * 100.0 * t) + 1.0 * np.cos(2 * np.pi * 500.0 * t)
    assert tactum.spectral_centroid(x, 2000.0) == pytest.approx((3 * 100 + 1 * 500) / 4, rel=1e-9)
    assert math.isnan(tactum.spectral_centroid(np.zeros(64), 2000.0))


# --- 6, 7. FST, FRS ---------------------------------------------------------------------------------------

FN, FT = 3.0, 1.2


def friction_forces() -> tuple[np.ndarray, np.ndarray]:
    """Normal: 0, a 300-sample rise to FN at 900, flat to 9000, a 310-sample fall. Tangential: a
    30-sample rise from 900 to FT at 930, flat until 9310, then 0."""
    n = 12000
    f_frn = np.zeros(n)
    f_frn[600:900] = FN * np.arange(300) / 300
    f_frn[900:9001] = FN
    f_frn[9000:9310] = FN * (1 - np.arange(310) / 310)
    f_frt = np.zeros(n)
    f_frt[900:930] = FT * np.arange(30) / 30
    f_frt[930:9310] = FT
    return f_frn, f_frt


def test_fst_is_the_ratio_of_the_largest_10ms_slopes():
    f_frn, f_frt = friction_forces()
    # Largest 30-sample rise: FT for the tangential force, FN * 30 / 300 for the normal one.
    assert tactum.fst(f_frn, f_frt) == pytest.approx(FT / (FN / 10), rel=1e-12)


def test_frs_averages_over_the_sliding_segment():
    f_frn, f_frt = friction_forces()
    # s = 900 + 30 = 930; the normal force exceeds 5 % of FN until 9000 + 294 (1 - j / 310 > 0.05 for
    # j < 294.5).
    assert tactum.sliding_segment(f_frn, f_frt) == (930, 9294)
    normal_sum = FN * (9000 - 930) + sum(FN * (1 - j / 310) for j in range(295))
    count = 9294 - 930 + 1
    assert tactum.frs(f_frn, f_frt) == pytest.approx(FT / (normal_sum / count), rel=1e-12)


def test_a_friction_slide_too_short_for_its_slope_window_is_refused_by_name():
    with pytest.raises(ParameterError, match="the sliding phase needs more than 30 samples of f_frt, got 30"):
        tactum.sliding_segment(np.ones(100), np.ones(30))
    with pytest.raises(ParameterError, match="f_frn must be a non-empty 1-D array"):
        tactum.sliding_segment(np.ones((10, 2)), np.ones(100))
    assert math.isnan(tactum.frs(np.ones(100), np.ones(30)))  # the feature of such a slide is undefined


def test_friction_features_are_nan_when_undefined():
    assert math.isnan(tactum.fst(np.ones(100), np.linspace(0, 1, 100)))   # no normal slope: x / 0
    assert math.isnan(tactum.fst(np.ones(30), np.ones(30)))               # shorter than the window
    f_frn = np.zeros(200)
    f_frn[10] = 1.0
    f_frt = np.linspace(0.0, 1.0, 200)                                    # slides after the normal force
    assert math.isnan(tactum.frs(f_frn, f_frt))


def test_compute_removes_the_friction_offset_before_frs():
    f_frn, f_frt = friction_forces()
    scan = full_scan(traces={"f_frn": Trace(f_frn, FS, "N"), "f_frt": Trace(f_frt + 0.35, FS, "N")})
    values = tactum.compute(scan)
    assert values["tactum.frs"] == pytest.approx(tactum.frs(f_frn, f_frt), rel=1e-12)
    assert values["tactum.fst"] == pytest.approx(FT / (FN / 10), rel=1e-12)


# --- 8, 13. ATK, CYD --------------------------------------------------------------------------------------

@pytest.mark.parametrize("bad", [0.3, -0.25, 1.25, 2.0])
def test_judged_values_off_the_scale_raise(bad):
    with pytest.raises(ValueError, match="five-step scale"):
        tactum.atk(bad)
    with pytest.raises(ValueError, match="tactum.cyd"):
        tactum.cyd(bad)
    with pytest.raises(ScanError):
        meta(atk=bad)


def test_judged_values_on_the_scale_and_not_judged():
    assert [tactum.atk(x) for x in (0, 0.25, 0.5, 0.75, 1)] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert math.isnan(tactum.cyd(math.nan))
    values = tactum.compute(full_scan(atk=math.nan, cyd=1.0))
    assert math.isnan(values["tactum.atk"]) and values["tactum.cyd"] == 1.0


# --- 9-12. Compliance -------------------------------------------------------------------------------------

FP, F_END, FF, OMEGA = 6.0, 4.5, 2.0, 12.0


def compliance_traces() -> dict[str, Trace]:
    n = 9000
    f_press = np.full(n, 0.1)
    f_press[1000:2000] = np.linspace(0.1, FP, 1000)
    f_press[2000:] = np.linspace(FP, F_END, n - 2000)
    f_fold = np.zeros(n)
    f_fold[1000:2511] = FF * np.arange(1511) / 1510     # peak FF at 2510; 5 % of FF first exceeded at 1076
    f_fold[2511:] = FF * 0.8
    alpha_f = OMEGA * np.arange(n) / FS                  # OMEGA deg/s throughout
    return {"f_press": Trace(f_press, FS, "N"), "f_fold": Trace(f_fold, FS, "N"),
            "alpha_f": Trace(alpha_f, FS, "deg")}


def test_compliance_of_a_deformable_sample():
    traces = compliance_traces()
    values = tactum.compute(full_scan(traces=traces))
    n = traces["alpha_f"].n
    assert values["tactum.ccp"] == pytest.approx(FP / 4.0, rel=1e-12)
    assert values["tactum.crx"] == pytest.approx(FP - F_END, rel=1e-12)
    assert values["tactum.cdf"] == pytest.approx(OMEGA / FS * math.sqrt((n**2 - 1) / 12), rel=1e-9)
    # n_min = 1076, n_max = 2510: the force rises FF (1 - 76/1510) while the angle turns at OMEGA.
    assert values["tactum.cdp"] == pytest.approx(FF * (1 - 76 / 1510) / OMEGA, rel=1e-9)


def test_compliance_is_zero_when_the_flex_angle_barely_moves():
    traces = compliance_traces()
    wobble = 0.9 * np.where(np.arange(traces["alpha_f"].n) % 2 == 0, 1.0, -1.0)   # std 0.9 deg < 1 deg
    values = tactum.compute(full_scan(traces={**traces, "alpha_f": Trace(wobble, FS, "deg")}))
    assert [values[f"tactum.{name}"] for name in ("ccp", "cdp", "crx")] == [0.0, 0.0, 0.0]
    assert values["tactum.cdf"] == pytest.approx(0.9, rel=1e-12)


def test_compliance_is_zero_when_the_fold_was_skipped_as_rigid():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = tactum.compute(full_scan(drop=("f_fold", "alpha_f", "f_press"), rigid=True))
    assert [values[f"tactum.{name}"] for name in ("ccp", "cdf", "cdp", "crx")] == [0.0] * 4


def test_compliance_is_nan_without_flex_angle_or_rigid_flag():
    with pytest.warns(tactum.MissingDataWarning, match="alpha_f is missing") as caught:
        values = tactum.compute(full_scan(drop=("alpha_f",)))
    assert all(math.isnan(values[f"tactum.{name}"]) for name in ("ccp", "cdf", "cdp", "crx"))
    assert len(caught) == 1
    assert "tactum.ccp, tactum.cdf, tactum.cdp, tactum.crx" in str(caught[0].message)


def test_cdp_nan_when_the_angle_does_not_change():
    f_fold = np.linspace(0.0, 1.0, 100)
    assert math.isnan(tactum.cdp(f_fold, np.full(100, 5.0), rigid=False))
    assert tactum.cdp(f_fold, np.full(100, 5.0), rigid=True) == 0.0


# --- 14, 15. TCO, TPR -------------------------------------------------------------------------------------

T_AMB = 21.0


def test_tco_and_tpr_of_an_exponential_decay():
    t = np.arange(200) / 20.0
    delta, tau = 8.0, 3.0
    t_cool = T_AMB + delta * np.exp(-t / tau)
    assert tactum.tco(t_cool, T_AMB) == pytest.approx(delta, rel=1e-12)
    assert tactum.tpr(t_cool, T_AMB) == pytest.approx(math.hypot(delta, delta * math.exp(-9.95 / tau)), rel=1e-12)


def test_tpr_looks_for_the_peak_in_the_first_five_seconds_only():
    # a t exp(-t / tau) peaks at t = tau = 6 s (sample 120), after the 5 s window (samples 0..99).
    t = np.arange(200) / 20.0
    a, tau = 3.0, 6.0
    t_cool = T_AMB + a * t * np.exp(-t / tau)
    assert tactum.tco(t_cool, T_AMB) == pytest.approx(a * tau / math.e, rel=1e-12)
    early, last = a * 4.95 * math.exp(-4.95 / tau), a * 9.95 * math.exp(-9.95 / tau)
    assert tactum.tpr(t_cool, T_AMB) == pytest.approx(math.hypot(early, last), rel=1e-12)


def test_thermal_features_of_a_scan():
    values = tactum.compute(full_scan())
    assert values["tactum.tco"] == pytest.approx(8.0, rel=1e-12)
    with pytest.warns(tactum.MissingDataWarning, match="t_amb"):
        values = tactum.compute(full_scan(t_amb=math.nan))
    assert math.isnan(values["tactum.tco"]) and math.isnan(values["tactum.tpr"])


# --- missing inputs ---------------------------------------------------------------------------------------

@pytest.mark.parametrize(("drop", "nan"), [
    ("v_ts", {"matx", "maco", "marg", "miro", "mico"}),
    ("r_ts", {"matx"}),
    ("f_frt", {"matx", "fst", "frs"}),
    ("f_frn", {"fst", "frs"}),
    ("f_press", {"ccp", "crx"}),
    ("f_fold", {"cdp"}),
    ("t_cool", {"tco", "tpr"}),
])
def test_a_missing_channel_makes_exactly_its_features_nan_with_one_warning(drop, nan):
    with pytest.warns(tactum.MissingDataWarning) as caught:
        values = tactum.compute(full_scan(drop=(drop,)))
    assert {name.removeprefix("tactum.") for name, value in values.items() if math.isnan(value)} == nan
    assert len(caught) == 1
    assert f"{drop} is missing" in str(caught[0].message)


def test_a_missing_photo_makes_maco_and_marg_nan():
    with pytest.warns(tactum.MissingDataWarning, match="I_disp is missing") as caught:
        values = tactum.compute(full_scan(image=False))
    assert {name for name, value in values.items() if math.isnan(value)} == {"tactum.maco", "tactum.marg"}
    assert len(caught) == 1


def test_two_missing_channels_give_two_warnings():
    with pytest.warns(tactum.MissingDataWarning) as caught:
        tactum.compute(full_scan(drop=("f_frn", "f_frt")))
    assert sorted(str(w.message).split(": ")[1].split(";")[0] for w in caught) == [
        "f_frn is missing", "f_frt is missing"]


def test_a_stored_slide_without_slide_start_makes_the_slide_features_nan():
    # Steady noise: no 10 ms frame carries ten times the mean energy of the first 25.
    resting = Trace(np.random.default_rng(10).normal(0.0, 0.01, (15000, 3)), FS, "g")
    with pytest.warns(tactum.MissingDataWarning, match="v_ts: no slide detected") as caught:
        values = tactum.compute(full_scan(traces={"v_ts": resting}))
    assert len(caught) == 1
    nan = {name for name, value in values.items() if math.isnan(value)}
    assert nan == {"tactum.matx", "tactum.maco", "tactum.marg", "tactum.miro", "tactum.mico"}


def test_a_short_ir_window_makes_only_matx_nan():
    with pytest.warns(tactum.MissingDataWarning, match="r_ts: window shorter than 1 s"):
        values = tactum.compute(full_scan(traces={"r_ts": Trace(np.ones(7000), FS, "V")}))
    assert {name for name, value in values.items() if math.isnan(value)} == {"tactum.matx"}


def test_compute_uses_the_preprocessed_tool_slide():
    scan = full_scan()
    v = slide_signal(scan["v_ts"])
    values = tactum.compute(scan)
    assert values["tactum.miro"] == tactum.miro(v)
    assert values["tactum.mico"] == tactum.mico(v)
    r_w = scan["r_ts"].data[4500:7500]
    f_frt = scan["f_frt"].data
    assert values["tactum.matx"] == pytest.approx(tactum.matx(v, f_frt, r_w), rel=1e-12)


# --- physical direction on simulated materials --------------------------------------------------------------


