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
from scanner.runtime import local
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
    results = local.run_tasks(_gated_mark, marks, range(len(marks)), 2, lambda n: None)
    assert next(results) == (0, marks[0])
    results.close()
    (tmp_path / "gate").touch()
    time.sleep(1.0)  # lets the tasks already handed over start (a task is marked when it starts)
    assert len(list((tmp_path / "marks").iterdir())) <= 6


# -- extract_many's own workers, kept for its next call ------------------------------------------------------




# -- one bounded set of workers shared by a server's threads ---------------------------------------------------


def _gated_run(path: str) -> str:
    """Leave a mark of this run (one file per run), then wait for the gate beside the marks' folder."""
    folder = os.path.dirname(path)
    with open(os.path.join(folder, f"{os.path.basename(path)}-{os.getpid()}-{time.monotonic_ns()}"), "w"):
        pass
    gate = os.path.join(os.path.dirname(folder), "gate")
    deadline = time.monotonic() + 20
    while not os.path.exists(gate) and time.monotonic() < deadline:
        time.sleep(0.005)
    return os.path.basename(path)


def test_concurrent_batches_of_the_same_work_share_one_run_of_it(tmp_path):
    import threading

    (tmp_path / "marks").mkdir()
    items = [str(tmp_path / "marks" / f"scan-{i}") for i in range(5)]
    pool = local.SharedWorkers(2)
    results: dict[str, list] = {}

    def batch(name):
        results[name] = sorted(local.run_tasks(_gated_run, items, range(5), 2, lambda n: None, pool, keys=items))

    try:
        threads = [threading.Thread(target=batch, args=(name,)) for name in ("a", "b")]
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not (len(pool._waiting) == 5
                                                   and all(n == 2 for _, n in pool._waiting.values())):
            time.sleep(0.01)
        (tmp_path / "gate").touch()
        for thread in threads:
            thread.join(60)
    finally:
        pool.close()
    expected = [(i, f"scan-{i}") for i in range(5)]
    assert results == {"a": expected, "b": expected}
    runs = sorted(p.name.split("-")[1] for p in (tmp_path / "marks").iterdir())
    assert runs == ["0", "1", "2", "3", "4"]  # each scan ran once for both batches
    assert pool._waiting == {}


def test_a_batch_that_leaves_early_drops_only_the_work_no_other_batch_waits_for(tmp_path):
    (tmp_path / "marks").mkdir()
    pool = local.SharedWorkers(2)
    try:
        # six tasks fill the two workers, the call queue (workers + 1) and the queue behind it
        busy = [pool._submit(_gated_run, str(tmp_path / "marks" / f"busy-{i}")) for i in range(6)]
        shared = pool._submit(_gated_run, str(tmp_path / "marks" / "shared"), "shared")
        assert pool._submit(_gated_run, str(tmp_path / "marks" / "shared"), "shared") is shared
        pool._done_with([shared])  # one of the two batches leaves
        assert not shared.cancelled() and pool._waiting["shared"][1] == 1
        pool._done_with([shared])  # the other one too: nobody waits for it any more
        assert shared.cancelled()
        (tmp_path / "gate").touch()
        assert [f.result(timeout=60) for f in busy] == [f"busy-{i}" for i in range(6)]
    finally:
        pool.close()


def test_the_same_work_twice_in_one_batch_answers_both_rows(tmp_path):
    import threading

    (tmp_path / "marks").mkdir()
    pool = local.SharedWorkers(2)
    item = str(tmp_path / "marks" / "scan")

    def open_gate_once_both_wait():  # (an open gate could let the first finish before the second is queued)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and pool._waiting.get("k", (None, 0))[1] < 2:
            time.sleep(0.005)
        (tmp_path / "gate").touch()

    opener = threading.Thread(target=open_gate_once_both_wait)
    opener.start()
    try:
        got = sorted(local.run_tasks(_gated_run, [item, item], [3, 7], 2, lambda n: None, pool, keys=["k", "k"]))
    finally:
        opener.join()
        pool.close()
    assert got == [(3, "scan"), (7, "scan")]
    assert len(list((tmp_path / "marks").iterdir())) == 1


def test_sharing_workers_needs_the_worker_server(monkeypatch):
    from taxonomy.errors import TexplorerError

    monkeypatch.setitem(local._SERVER, "context", None)
    with pytest.raises(TexplorerError, match=r"share_workers\(\) needs the worker server"):
        local.share_workers(2)


def _pid_or_die(item: str) -> int:
    if item == "die":
        os._exit(1)  # a worker killed mid-task (out of memory, say)
    return os.getpid()


def test_shared_workers_start_again_after_one_died():
    import concurrent.futures

    pool = local.SharedWorkers(2)
    try:
        with pytest.raises(concurrent.futures.BrokenExecutor):
            list(local.run_tasks(_pid_or_die, ["die", "a"], [0, 1], 2, lambda n: None, pool))
        assert len(dict(local.run_tasks(_pid_or_die, ["a", "b"], [0, 1], 2, lambda n: None, pool))) == 2
    finally:
        pool.close()
