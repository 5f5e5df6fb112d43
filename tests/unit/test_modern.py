"""The modern feature families (features.modern, features.random_kernels, features.feature_sets): each
reproduces its library's values on fixed signals, a pure tone's scattering energy sits in the band of its
frequency, the cache key follows the families' parameters, and no random-kernel transform sees a test fold."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

pycatch22 = pytest.importorskip("pycatch22", reason="the modern families need texplorer[modern]")
kymatio_1d = pytest.importorskip("kymatio.scattering1d.frontend.numpy_frontend",
                                 reason="the modern families need texplorer[modern]")
rocket = pytest.importorskip("sktime.transformations.rocket", reason="the modern families need texplorer[modern]")

from features import extract, feature_sets, modern  # noqa: E402
from features.extraction import code_version  # noqa: E402
from features.random_kernels import ParameterError, RandomKernels, signal_layout  # noqa: E402
from features.recordings import band_limited, feature_space  # noqa: E402
from features.registry import REGISTRY, ScanRegistry  # noqa: E402
from scanner.preprocess import dft321, slide_signal  # noqa: E402
from scanner.scan import Recording, Trace  # noqa: E402
from scanner.simulation.contrasts import contrast_recordings  # noqa: E402
from scanner.simulation.materials import SimulationError  # noqa: E402
from scanner.storage.matfile import load_scan  # noqa: E402

SCAN = Path(__file__).parents[1] / "regression" / "scans" / "granite-polished-01-001.mat"


@pytest.fixture(scope="module")
def scan():
    return load_scan(SCAN)


@pytest.fixture(scope="module")
def values(scan):
    return extract(scan, ["signal", "catch22", "scattering"])


def _slide_instance(scan) -> np.ndarray:
    """The tool-slide vibration cut by hand: band limit, 1 s window, DFT321 (the rule keeps its 3000)."""
    signal = slide_signal(scan["v_ts"])
    assert signal.size == modern.SCAN_SIGNALS["v_ts"].rule.length
    return signal


# -- the default stays the paper's ------------------------------------------------------------------

def test_default_extraction_is_the_papers_193(scan):
    assert len(REGISTRY.names) == 193
    assert set(REGISTRY.opt_in) >= {"signal", "catch22", "scattering"}
    assert not set(REGISTRY.opt_in) & set(REGISTRY.modalities)
    assert tuple(extract(scan)) == REGISTRY.names


def test_opt_in_families_come_after_the_default_columns(values):
    assert tuple(values)[:0] == ()
    assert all(c.split(".")[0] in ("signal", "catch22", "scattering") for c in values)
    assert tuple(values) == REGISTRY.columns_of(["signal", "catch22", "scattering"])


# -- each family is its library's values --------------------------------------------------------------

def test_signal_columns_are_the_slide_signal(scan, values):
    kept = np.array([values[f"signal.v_ts.{k:05d}"] for k in range(3000)])
    np.testing.assert_array_equal(kept, _slide_instance(scan))


def test_catch22_is_pycatch22_on_the_slide_signal(scan, values):
    expected = pycatch22.catch22_all(_slide_instance(scan).tolist())
    assert tuple(expected["names"]) == modern.CATCH22_NAMES
    got = [values[f"catch22.v_ts.{name}"] for name in modern.CATCH22_NAMES]
    np.testing.assert_array_equal(got, expected["values"])


def test_catch22_of_windows_is_the_mean_of_pycatch22(scan, values):
    """The sound's 8 windows of 2048 samples spread over its slide window: the mean of the 8 catch22s."""
    a = scan["a_ts"]
    start = int(round(slide_window_start(scan) * a.fs / scan["v_ts"].fs))
    sound = a.data[start:start + 44100]
    starts = np.round(np.linspace(0, sound.size - 2048, 8)).astype(int)
    each = [pycatch22.catch22_all(sound[s:s + 2048].tolist())["values"] for s in starts]
    got = [values[f"catch22.a_ts.{name}"] for name in modern.CATCH22_NAMES]
    np.testing.assert_allclose(got, np.mean(each, axis=0), rtol=1e-15, atol=0)


def slide_window_start(scan) -> int:
    from scanner.preprocess import slide_window

    return slide_window(scan["v_ts"].data, fs=scan["v_ts"].fs).start


def test_scattering_is_kymatio_on_the_slide_signal(scan, values):
    x = _slide_instance(scan)
    transform = kymatio_1d.ScatteringNumPy1D(J=modern.scattering_octaves(3000), shape=3000, Q=modern.SCATTERING_Q)
    means = transform(x[None, :])[0].mean(axis=-1)
    order = np.asarray(transform.meta()["order"])
    expected = np.where(order > 0, np.log(means + modern.SCATTERING_LOG_FLOOR), means)
    names = modern.scattering_names(3000)
    assert len(names) == order.size and [n.split("_")[0] for n in names] == [f"s{o}" for o in order]
    got = [values[f"scattering.v_ts.{name}"] for name in names]
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("length", [3000, 2048, 1024, 512])
def test_scattering_names_follow_kymatios_coefficients(length):
    order = np.asarray(modern.scattering_transform(length).meta()["order"])
    names = modern.scattering_names(length)
    assert [n.split("_")[0] for n in names] == [f"s{o}" for o in order]


def test_multirocket_of_windows_is_the_mean_over_windows():
    """A signal of 8 windows (a_ts): fitted on every window of the rows, each row the mean of its windows."""
    rng = np.random.default_rng(2)
    X = rng.standard_normal((4, 8 * 2048))
    columns = ["image.disp.x", *(f"signal.a_ts.{k:05d}" for k in range(8 * 2048))]
    X = np.hstack([np.arange(4.0)[:, None], X])
    step = RandomKernels("multirocket", columns, num_kernels=84, random_state=3).fit(X)
    panel = X[:, 1:].reshape(32, 1, 2048)
    reference = rocket.MultiRocket(num_kernels=84, random_state=3).fit(panel)
    # sktime gives float32; the mean over the windows is taken in float64.
    expected = np.asarray(reference.transform(panel), dtype=np.float64).reshape(4, 8, -1).mean(axis=1)
    got = step.transform(X)
    np.testing.assert_array_equal(got[:, 0], np.arange(4.0))  # the kept column passes through
    np.testing.assert_array_equal(got[:, 1:], expected)
    assert step.get_feature_names_out()[0] == "image.disp.x"
    assert step.get_feature_names_out()[1] == "multirocket.a_ts.00000"


def test_role_families_follow_the_role_rules():
    """A 5 s vibration at 2 kHz: resampled to 3 kHz, 4 windows of 3000 samples; catch22 their mean."""
    rng = np.random.default_rng(4)
    data = rng.standard_normal((10000, 3))
    recording = Recording("r", {"acc": Trace(data, 2000.0, "g")}, {"vibration": "acc"}, label="a")
    space, notes = feature_space([recording, dataclasses.replace(recording, name="s", label="b")],
                                 chosen=feature_sets.role_families_for(["catch22", "minirocket"]))
    assert not notes
    v = modern.resample(dft321(band_limited(data, 2000.0)), 2000.0, 3000.0)
    assert v.size == 15000
    starts = np.round(np.linspace(0, v.size - 3000, 4)).astype(int)
    expected = np.mean([pycatch22.catch22_all(v[s:s + 3000].tolist())["values"] for s in starts], axis=0)
    row = dict(zip(space.columns, space.X[0], strict=True))
    np.testing.assert_allclose([row[f"catch22.vibration.{n}"] for n in modern.CATCH22_NAMES], expected,
                               rtol=1e-15, atol=0)
    np.testing.assert_array_equal([row[f"signal.vibration.{k:05d}"] for k in range(3000)], v[:3000])


# -- closed form --------------------------------------------------------------------------------------

@pytest.mark.parametrize("hz", [120.0, 440.0, 900.0])
def test_pure_tone_scattering_energy_sits_in_the_band_of_its_frequency(hz):
    """A first-order coefficient is the mean of |x * psi_lambda|: a tone at f excites the wavelets whose
    band holds f, and the largest is the one whose centre frequency is nearest f (within half the spacing
    of the centres, a factor 2^(1/Q) on the log-frequency axis)."""
    fs, n = 3000.0, 3000
    x = np.sin(2 * np.pi * hz * np.arange(n) / fs)
    values = modern.scattering(x[None, :])
    meta = modern.scattering_transform(n).meta()
    first = np.flatnonzero(np.asarray(meta["order"]) == 1)
    centres = np.asarray(meta["xi"])[first, 0] * fs
    loudest = centres[np.argmax(values[first])]
    assert abs(math.log2(loudest / hz)) <= 0.5 / modern.SCATTERING_Q + 1e-9
    # Far from the tone the energy is orders of magnitude lower.
    far = np.abs(np.log2(centres / hz)) > 2
    assert values[first][far].max() < values[first].max() - math.log(100)


# -- the length rule ----------------------------------------------------------------------------------

def test_length_rule_cuts_evenly_spread_windows_and_pads_short_signals():
    rule = modern.LengthRule(100, windows=3)
    x = np.arange(1000.0)
    cut = modern.instances(x, 1000.0, rule)
    np.testing.assert_array_equal(cut[:, 0], [0.0, 450.0, 900.0])
    short = modern.instances(np.arange(40.0), 1000.0, rule)
    assert short.shape == (3, 100) and (short[:, 40:] == 0).all()
    whole = modern.instances(x, 1000.0, modern.LengthRule(64, whole=True))
    assert whole.shape == (1, 64)
    with pytest.raises(modern.ParameterError, match="length >= 16"):
        modern.LengthRule(8)


def test_a_long_recording_costs_its_rule_not_its_length():
    """Ten minutes of sound at 44.1 kHz become 8 x 2048 samples (the cost of the kernels is bounded)."""
    x = np.random.default_rng(0).standard_normal(int(600 * 44100))
    cut = modern.instances(x, 44100.0, modern.ROLE_RULES["audio"].rule)
    assert cut.shape == (8, 2048)


# -- cache key --------------------------------------------------------------------------------------

def test_cache_key_changes_with_a_familys_parameters():
    base = code_version(["catch22"])
    assert base != code_version() and base != code_version(["scattering"])
    family = REGISTRY.chosen(["catch22"])[0]
    registry = ScanRegistry()
    registry.register(dataclasses.replace(family, params={**family.params, "v_ts": modern.LengthRule(2048)}))
    other = ScanRegistry()
    other.register(family)
    assert registry.code_version("features.extraction", families=["catch22"]) != \
        other.code_version("features.extraction", families=["catch22"])
    assert other.code_version("features.extraction", families=["catch22"]) == base


# -- feature sets -----------------------------------------------------------------------------------

def test_feature_set_names():
    assert feature_sets.parts("fusion") == ("paper", "catch22", "scattering", "minirocket")
    assert feature_sets.kernels_of("paper+multirocket") == "multirocket"
    assert feature_sets.families_for(["all", "tactum"]) is None
    assert feature_sets.families_for(["paper+minirocket"]) == (*REGISTRY.modalities, "signal")
    with pytest.raises(feature_sets.FeatureSetError, match="one random-kernel transform"):
        feature_sets.parts("minirocket+multirocket")
    with pytest.raises(feature_sets.FeatureSetError, match="unknown feature set 'rocket'"):
        feature_sets.parts("paper+rocket")


def test_a_fused_set_is_selected_family_by_family():
    paper = ["tactum.cdp", "image.macro.lbp_1", "audio.tool.zcr", "other.density"]
    columns = [*paper, "signal.v_ts.00000", "signal.v_ts.00001", "catch22.v_ts.mode_5", "scattering.v_ts.s1_00"]
    # The paper's modalities are one part; each modern family another; signal columns a kernel step replaces
    # are not listed (its output, after the columns it passes through, is the last part).
    assert feature_sets.column_parts(columns, kernels=True) == (0, 0, 0, 0, 1, 2)
    assert feature_sets.column_parts([*paper, "catch22.v_ts.mode_5"]) == (0, 0, 0, 0, 1)
    assert feature_sets.column_parts(paper) is None  # one family: selected as a whole, as the paper's
    assert feature_sets.column_parts(["signal.v_ts.00000"], kernels=True) is None
    assert feature_sets.column_parts([*paper, "signal.v_ts.00000"], kernels=True) == (0, 0, 0, 0)


def test_signal_layout_refuses_a_partial_signal():
    with pytest.raises(ParameterError, match="expected 3000 consecutive columns"):
        signal_layout([f"signal.v_ts.{k:05d}" for k in range(2999)])


# -- no transform sees a test fold --------------------------------------------------------------------


def test_contrast_sets_are_balanced_and_unit_power():
    for which in ("spectral", "timing"):
        recordings = contrast_recordings(which, per_class=3)
        labels = [r.label for r in recordings]
        assert len(set(labels)) in (3, 4) and all(labels.count(label) == 3 for label in set(labels))
        for r in recordings:
            np.testing.assert_allclose(np.mean(r.role("vibration").data ** 2), 1.0, rtol=1e-12)


def test_a_noisy_contrast_set_holds_its_clean_recordings_at_the_asked_ratio():
    """At 0 dB the clean unit-RMS signal and the noise have equal power, so the noisy recording correlates
    with its clean one at 1/sqrt(2); the cross term of two independent series of n samples moves the
    correlation by about 1/sqrt(n) (n = 6000: 0.013), so 4/sqrt(n) bounds it."""
    for which in ("spectral", "timing"):
        clean = contrast_recordings(which, per_class=2)
        noisy = contrast_recordings(which, per_class=2, snr_db=0.0)
        for a, b in zip(clean, noisy, strict=True):
            x, y = a.role("vibration").data, b.role("vibration").data
            assert a.name == b.name and a.label == b.label
            np.testing.assert_allclose(np.mean(y**2), 1.0, rtol=1e-12)
            assert abs(np.corrcoef(x, y)[0, 1] - 2**-0.5) < 4 / np.sqrt(x.size)
    with pytest.raises(SimulationError, match="snr_db must be a finite number"):
        contrast_recordings("spectral", snr_db=float("nan"))


def test_walked_selection_equals_the_whole_matrix_selection():
    """Above FULL_SPEARMAN_MAX columns the selector walks the FQ order with only the correlations it needs;
    the choice is that of the whole Spearman matrix, and rho agrees to rounding."""
    from features.selection import accept_uncorrelated, spearman_matrix, walk_uncorrelated

    rng = np.random.default_rng(5)
    base = rng.standard_normal((40, 6))
    X = np.hstack([base, base @ rng.standard_normal((6, 60)) + 0.3 * rng.standard_normal((40, 60))])
    order = rng.permutation(X.shape[1])
    rho = spearman_matrix(X)
    expected = accept_uncorrelated(order, rho, 10, 0.5)
    accepted, walked = walk_uncorrelated(X, order, 10, 0.5)
    assert accepted == expected
    np.testing.assert_allclose(walked, rho[np.ix_(expected, expected)], rtol=0, atol=1e-12)




def _robot_run(label: str, rng: np.random.Generator) -> Recording:
    """A terrain run: a 3-axis gyroscope at 100 Hz and a 2-column wheel current at 6.5 Hz, 12 s."""
    gyro = rng.normal(size=(1200, 3)) * (1.0 if label == "snow" else 0.3)
    current = 2.0 + 0.1 * rng.normal(size=(78, 2))
    return Recording(f"{label}-{rng.integers(1 << 30)}", {"gyro": Trace(gyro, 100.0, "rad/s"),
                                                          "current": Trace(current, 6.5, "A")},
                     {"signal_gyro": "gyro", "signal_current": "current"}, label)


def test_modern_families_run_on_a_generic_channel_but_not_on_one_at_a_few_hz():
    from features.recordings import Windowing

    recording = _robot_run("snow", np.random.default_rng(5))
    chosen = feature_sets.role_families_for(["fusion"])
    space, notes = feature_space([recording], Windowing(5.0, "rows"), chosen=chosen)
    assert notes == [] and len(space) == 2
    columns = list(space.columns)
    for kind, width in (("catch22", 22), ("scattering", len(modern.scattering_names(512))),
                        ("signal", modern.GENERIC_RULE.samples)):
        assert sum(c.startswith(f"{kind}.signal_gyro.") for c in columns) == width
        assert not any(c.startswith(f"{kind}.signal_current.") for c in columns)  # 6.5 Hz: the slow family's
    # catch22 of the first 5 s window: its three axes, each minus its mean, combined by DFT321, one 512-sample
    # instance zero-padded at its end (four spread over a window that short are the same instance).
    window = recording.channels["gyro"].data[:500]
    combined = np.pad(dft321(window - window.mean(axis=0)), (0, 12))
    expected = pycatch22.catch22_all(combined.tolist())["values"]
    got = space.X[0, [columns.index(f"catch22.signal_gyro.{name}") for name in modern.CATCH22_NAMES]]
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_minirocket_reads_a_generic_channels_signal_by_its_rule():
    from features.random_kernels import signal_rule
    from taxonomy.learning.evaluation import evaluate_grid

    assert signal_rule("signal_gyro") == modern.GENERIC_RULE
    rng = np.random.default_rng(6)
    space, _ = feature_space([_robot_run(label, rng) for label in ("snow", "ice") for _ in range(5)],
                             chosen=feature_sets.role_families_for(["minirocket"]))
    result, = evaluate_grid(space, classifiers=["lda"], set_sizes=[None], feature_sets={"minirocket": "minirocket"},
                            calibrate=False, group_by="recording", workers=1)
    assert result.accuracy_pooled >= 0.9  # the gyroscope's level of noise tells the two apart
