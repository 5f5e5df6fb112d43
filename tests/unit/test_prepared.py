"""One prepared scan per extraction: each slide channel's start, band-limited vibration and slide signal
are computed once and handed to every family, and the values are those each family computes alone."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import make_scan

from features import extract, other, tactum
from features.families import audio_features
from features.prepared import PreparedScan
from scanner import preprocess
from scanner.scan import Scan
from scanner.simulation import synthetic_scan


@pytest.fixture
def counted(monkeypatch):
    calls = {"slide_start": 0, "band_limit": 0, "dft321": 0}

    def counting(name):
        original = getattr(preprocess, name)

        def wrapper(*args, **kwargs):
            calls[name] += 1
            return original(*args, **kwargs)
        return wrapper

    from features import prepared
    for name in calls:
        monkeypatch.setattr(prepared, name, counting(name))
    return calls


@pytest.fixture(scope="module")
def slid() -> Scan:
    return synthetic_scan("granite-polished", seed=4, image_size=(64, 64))


def test_each_slide_channel_is_prepared_once_per_extraction(counted, slid):
    scan = slid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        extract(scan)
    # v_ts (TacTUM, other, audio), v_fs (other, audio): one slide start each; the band limit of v_ts,
    # v_fs and v_tt and the DFT321 of the two slide windows once each.
    assert counted == {"slide_start": 2, "band_limit": 3, "dft321": 2}


def test_families_give_the_same_values_alone_and_prepared(slid):
    scan = slid
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prepared = PreparedScan(scan)
        shared = {**tactum.compute(scan, prepared=prepared), **audio_features(scan, prepared),
                  **other.compute(scan, prepared=prepared)}
        alone = {**tactum.compute(scan), **audio_features(scan), **other.compute(scan)}
    assert list(shared) == list(alone)
    np.testing.assert_array_equal(np.array(list(shared.values())), np.array(list(alone.values())))


def test_a_failed_slide_check_is_raised_again_not_recomputed(counted):
    scan = make_scan(seconds=0.5, images=False)
    prepared = PreparedScan(scan)
    for _ in range(3):
        with pytest.raises(preprocess.QualityError):
            prepared.slide_signal("v_ts")
    assert counted["slide_start"] == 1
