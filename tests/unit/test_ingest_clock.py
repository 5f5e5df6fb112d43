"""Timestamps of a regular clock logged with jitter: kept as the regular stream, slips reported."""

from __future__ import annotations

import numpy as np
import pytest

from scanner.storage import ingest
from scanner.storage.ingest.clock import JITTER_MAD, regular_clock

RATE = 100.0
ROWS = 3000


def mapping(rate: float | None = None) -> ingest.IngestMapping:
    given = f"rate = {rate!r}\n" if rate is not None else ""
    return ingest.parse_mapping(
        '[[files]]\nglob = "**/*.csv"\ntime_column = "t"\n' + given
        + '[[files.channels]]\nname = "taxels"\nrole = "electrodes"\ncolumns = ["e1", "e2"]\n', "clock")


def write(folder, times: np.ndarray, values: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    lines = "".join(f"{t!r},{a!r},{b!r}\n" for t, (a, b) in zip(times.tolist(), values.tolist(), strict=True))
    (folder / "r1.csv").write_text("t,e1,e2\n" + lines)


def channel(root, rate: float | None = None):
    report = ingest.ingest(root, mapping(rate))
    (recording,) = report.recordings
    return recording, recording.channels["taxels"], [str(n) for n in report.notes]


@pytest.fixture
def samples():
    rng = np.random.default_rng(7)
    return rng.normal(size=(ROWS, 2))


def host_times(rng: np.random.Generator, jitter_periods: float, rows: int = ROWS) -> np.ndarray:
    """A 100 Hz clock from t = 12.3 s read with white host jitter of ``jitter_periods`` periods rms."""
    times = 12.3 + np.arange(rows) / RATE + rng.normal(scale=jitter_periods / RATE, size=rows)
    assert np.all(np.diff(times) > 0)
    return times


def test_a_jittered_regular_stream_is_bit_identical_to_the_regular_one(tmp_path, samples):
    write(tmp_path / "regular" / "cork", 12.3 + np.arange(ROWS) / RATE, samples)
    write(tmp_path / "jittered" / "cork", host_times(np.random.default_rng(1), 0.12), samples)
    _, regular, _ = channel(tmp_path / "regular")
    recording, jittered, notes = channel(tmp_path / "jittered")
    assert np.array_equal(jittered.data, samples) and np.array_equal(regular.data, samples)
    # The slope fitted to 3000 stamps has a standard error of sigma / sqrt(sum (n - mean)^2) = 1.2 ms / 4.7e4
    # = 2.6e-8 s, 2.6e-6 of the period: 2e-5 is eight standard errors.
    assert jittered.fs == pytest.approx(RATE, rel=2e-5) and regular.fs == pytest.approx(RATE, rel=1e-9)
    clock = recording.meta["time_base"]["channels"]["taxels"]["clock"]
    assert clock["dropped"] == 0 and clock["duplicated"] == 0
    assert clock["jitter_rms_s"] == pytest.approx(1.2e-3, rel=0.1)  # 3000 draws: 2.6 % standard error
    assert not recording.meta["time_base"]["channels"]["taxels"]["resampled"]
    assert any("Hz clock, jitter 1.19 ms rms" in n and "kept as a regular stream" in n for n in notes)


def test_a_given_nominal_rate_is_kept_exactly(tmp_path, samples):
    write(tmp_path / "lab" / "cork", host_times(np.random.default_rng(2), 0.1), samples)
    _, jittered, _ = channel(tmp_path / "lab", rate=RATE)
    assert jittered.fs == RATE and np.array_equal(jittered.data, samples)


def test_dropped_samples_are_bridged_and_duplicates_left_out(tmp_path, samples):
    times = host_times(np.random.default_rng(3), 0.05)
    keep = np.ones(ROWS, dtype=bool)
    keep[[500, 1700]] = False  # two samples lost on the way
    times, values = times[keep], samples[keep]
    # One sample delivered twice (the host logged it again 2 ms later).
    times = np.insert(times, 901, times[900] + 0.002)
    values = np.insert(values, 901, values[900], axis=0)
    write(tmp_path / "lab" / "cork", times, values)
    recording, taxels, notes = channel(tmp_path / "lab")
    clock = recording.meta["time_base"]["channels"]["taxels"]["clock"]
    assert (clock["dropped"], clock["duplicated"]) == (2, 1)
    assert taxels.data.shape == (ROWS, 2)
    kept = np.flatnonzero(keep)
    assert np.array_equal(taxels.data[kept], samples[kept])  # every sample in its own slot
    for lost in (500, 1700):  # bridged linearly from its neighbours
        assert taxels.data[lost] == pytest.approx((samples[lost - 1] + samples[lost + 1]) / 2, rel=1e-12)
    assert any("2 dropped, 1 duplicated" in n for n in notes)


def test_timestamps_without_a_clock_are_resampled_as_before(tmp_path, samples):
    rng = np.random.default_rng(4)
    times = 12.3 + np.sort(rng.uniform(0, ROWS / RATE, size=ROWS))  # no clock: Poisson-like arrivals
    assert regular_clock(times) is None
    write(tmp_path / "lab" / "cork", times, samples)
    recording, _, notes = channel(tmp_path / "lab")
    info = recording.meta["time_base"]["channels"]["taxels"]
    assert info["resampled"] and "clock" not in info


def test_the_clock_fit_recovers_slots_period_and_jitter():
    rng = np.random.default_rng(5)
    slots = np.delete(np.arange(2000), [10, 11, 1500])  # a two-sample and a one-sample drop
    times = 4.0 + slots * 0.002 + rng.normal(scale=0.1 * 0.002, size=slots.size)
    clock = regular_clock(times)
    assert clock is not None and np.array_equal(clock.slots, slots)
    assert clock.period == pytest.approx(0.002, rel=1e-5) and clock.dropped == 3 and clock.duplicated == 0
    # Jitter beyond JITTER_MAD periods (0.3 periods rms: median absolute 0.2) is no clock.
    noisy = 4.0 + np.arange(2000) * 0.002 + rng.normal(scale=0.3 * 0.002, size=2000)
    assert 0.3 * 0.6745 > JITTER_MAD and regular_clock(np.sort(noisy)) is None
