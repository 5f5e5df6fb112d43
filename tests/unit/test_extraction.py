"""features.extract and extract_many (docs/features.md): 193 names in order, NaN exactly where data is missing,
parallel extraction in input order, per-scan failures, and the feature cache."""

from __future__ import annotations

import contextlib
import functools
import math
import os
import time
import warnings

import numpy as np
import pytest

import features
from features import NAMES, extract, extract_many, extraction, image
from scanner.scan import CHANNELS, IMAGES, Scan, Trace
from scanner.simulation import synthetic_scan

SIZE = (384, 384)
IMAGES_BY_SHORT = {short: variable for variable, short in IMAGES.items()}


@functools.cache
def foam() -> Scan:
    return synthetic_scan("polyurethane-foam", seed=11, image_size=SIZE)


@functools.cache
def foam_values() -> dict[str, float]:
    return extract(foam())


def test_193_names_in_spec_order():
    assert len(NAMES) == 193 == len(set(NAMES))
    assert NAMES[:15] == features.tactum.NAMES
    assert NAMES[15] == "image.disp.color" and NAMES[15 + 31] == "image.macro.color"
    assert NAMES[15 + 93] == "audio.finger.zcr" and NAMES[15 + 93 + 35] == "audio.tool.zcr"
    assert NAMES[-15:] == features.other.NAMES




def test_extraction_is_bit_identical_on_rerun():
    again = extract(synthetic_scan("polyurethane-foam", seed=11, image_size=SIZE))
    assert np.array_equal(np.array(list(again.values())), np.array(list(foam_values().values())), equal_nan=True)




@pytest.mark.parametrize(
    ("drop", "expected"),
    [
        ({"a_fs"}, {n for n in NAMES if n.startswith("audio.finger.")}),
        ({"t_cool"}, {"tactum.tco", "tactum.tpr", "other.cooling_rate"}),
        ({"dB"}, {"other.magnet_mean", "other.magnet_peak"}),
        ({"I_macro"}, {n for n in NAMES if n.startswith("image.macro.")}),
    ],
)
def test_a_missing_channel_makes_exactly_its_features_nan(drop, expected):
    scan = foam()
    partial = Scan(scan.meta, {k: v for k, v in scan.traces.items() if k not in drop},
                   {k: v for k, v in scan.images.items() if k not in drop})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = extract(partial)
    assert {name for name, value in values.items() if math.isnan(value)} == expected
    assert any(next(iter(drop)) in str(w.message) for w in caught)


@functools.cache
def foam_without_photos() -> tuple[Scan, dict[str, float]]:
    scan = Scan(foam().meta, foam().traces)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scan, extract(scan)


@pytest.mark.parametrize("channel", [name for name, spec in CHANNELS.items() if spec.min_n > 1])
def test_a_channel_too_short_for_its_features_counts_as_missing_and_is_named(channel):
    scan, full = foam_without_photos()
    need, trace = CHANNELS[channel].min_n, scan[channel]
    cut = Scan(scan.meta, {**scan.traces, channel: Trace(trace.data[:need - 1], trace.fs, trace.unit)})
    assert cut.short_channels() == {channel: need}
    with pytest.warns(UserWarning, match=rf"too short: {channel} \({need - 1} of the {need} samples its "
                                         r"features need\); treated as missing"):
        values = extract(cut)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        missing = extract(Scan(scan.meta, {k: v for k, v in scan.traces.items() if k != channel}))
    assert all(values[n] == missing[n] or (math.isnan(values[n]) and math.isnan(missing[n])) for n in NAMES)
    nan = {n for n, v in values.items() if math.isnan(v)}
    assert nan > {n for n, v in full.items() if math.isnan(v)}  # its features became NaN, no silent zero
    enough = Scan(scan.meta, {**scan.traces, channel: Trace(trace.data[:need], trace.fs, trace.unit)})
    assert enough.short_channels() == {}


def test_extract_many_accepts_plain_scans_in_process():
    space = extract_many([foam()], workers=1, progress=False)
    assert space.columns == NAMES and space.label_text == (foam().meta.label,)
    assert space.groups == (foam().meta.sample_id,)




def test_a_photo_too_small_for_tamura_coarseness_keeps_the_other_image_features():
    # 263 px: the 100 px crop leaves 63 px, one short of Tamura's two 32 px windows.
    scan = synthetic_scan("float-glass", seed=2, image_size=(263, 400))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = extract(scan)
    for short in ("disp", "macro", "illu"):
        assert math.isnan(values[f"image.{short}.tamura_coarseness"])
        with pytest.warns(image.ImageSizeWarning):
            computed = image.compute(scan.images[IMAGES_BY_SHORT[short]])
        assert all(values[f"image.{short}.{n}"] == computed[n] for n in image.NAMES if n != "tamura_coarseness")
    assert any("63x200 px (after cropping 100 px) is too small for tamura_coarseness" in str(w.message)
               for w in caught)


def test_large_photos_are_extracted_reusing_freed_memory(monkeypatch):
    # The decision is the photos' size; values are the same either way (only where memory comes from
    # changes), checked here bit for bit on a scan whose photos reach the size once the limit is lowered.
    scan = synthetic_scan("oak-planed", seed=2)
    plain = extract(scan)
    blocks = []
    original = extraction.reusing_freed_memory

    @contextlib.contextmanager
    def counted():
        blocks.append(1)
        with original():
            yield

    monkeypatch.setattr(extraction, "reusing_freed_memory", counted)
    assert _same_bits(extract(scan), plain)
    assert blocks == []
    monkeypatch.setattr(extraction, "REUSE_FROM_PIXELS", min(p.shape[0] * p.shape[1] for p in scan.images.values()))
    assert _same_bits(extract(scan), plain)
    assert blocks == [1]


def _same_bits(a: dict[str, float], b: dict[str, float]) -> bool:
    return list(a) == list(b) and np.array_equal(np.array(list(a.values())), np.array(list(b.values())),
                                                 equal_nan=True)


GATE_SECONDS = 3.0


def _gated_mark(path: str) -> str:
    """Mark the task as started; every task but the first then waits for the gate (at most GATE_SECONDS)."""
    with open(path, "w"):
        pass
    if os.path.basename(path) != "0":
        gate = os.path.join(os.path.dirname(os.path.dirname(path)), "gate")
        deadline = time.monotonic() + GATE_SECONDS
        while not os.path.exists(gate) and time.monotonic() < deadline:
            time.sleep(0.005)
    return path


def test_leaving_a_parallel_run_early_drops_the_tasks_not_started(tmp_path):
    # extract_many closes the results when its caller leaves early (Ctrl-C): the tasks not yet started
    # must not run on in the background (the pool is shut down without waiting, so they are cancelled).
    # Only task 0 can finish before the gate opens, so what has been handed to the workers when the run is
    # left does not depend on how busy the machine is: the two workers' tasks and the pool's call queue
    # (max_workers + 1 = 3 tasks, already marked running) at most, 6 with the first. With a waiting
    # shutdown all 20 run (close() returns only after ten rounds of GATE_SECONDS); so they do, on a busy
    # machine, when the cancelling is left to shutdown(cancel_futures=True): the pool's thread skips it
    # once the closed generator has dropped the executor.
    (tmp_path / "marks").mkdir()
    marks = [str(tmp_path / "marks" / f"{i}") for i in range(20)]
    results = extraction._run(_gated_mark, marks, range(len(marks)), 2, lambda n: None)
    assert next(results) == (0, marks[0])
    results.close()
    (tmp_path / "gate").touch()
    time.sleep(1.0)  # lets the tasks already handed over start (a task is marked when it starts)
    assert len(list((tmp_path / "marks").iterdir())) <= 6


# -- extract_many's own workers, kept for its next call ------------------------------------------------------


