"""features.extract and extract_many (docs/features.md): 193 names in order, NaN exactly where data is missing,
parallel extraction in input order, per-scan failures, and the feature cache: the system tests (worker
processes and memory measured in subprocesses)."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
import math
import multiprocessing
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from unit.test_extraction import SIZE, _gated_mark, foam, foam_values

import features
from features import NAMES, ScanSource, extract, extract_many
from features.extraction import code_version, source_of
from scanner.runtime import local
from scanner.scan import Scan
from scanner.simulation import synthetic_scan


def _broken() -> Scan:
    raise OSError("disk on fire")


class CountingCache:
    def __init__(self) -> None:
        self.store: dict[tuple[str, str], dict[str, float]] = {}
        self.writes = 0

    def cached_features(self, content_hash, version):
        return self.store.get((content_hash, version))

    def store_features(self, content_hash, version, values):
        self.writes += 1
        self.store[(content_hash, version)] = dict(values)


def _source(scan: Scan, key: str | None = None) -> ScanSource:
    return dataclasses.replace(source_of(scan), cache_key=key)


def test_extract_many_keeps_order_reports_failures_and_uses_the_cache():
    scans = [foam(), synthetic_scan("float-glass", seed=3, image_size=SIZE, sample_id="glass-01")]
    broken = ScanSource("broken-001", "C1S1M1P1X1", "broken", _broken, "k-broken")
    cache = CountingCache()
    sources = [_source(scans[1], "k-glass"), broken, _source(scans[0], "k-foam")]
    space = extract_many(sources, workers=2, cache=cache, progress=False)
    assert space.scan_ids == (scans[1].scan_id, scans[0].scan_id)
    assert space.failed == (("broken-001", "OSError: disk on fire"),)
    np.testing.assert_array_equal(space.X[1], np.array(list(foam_values().values())))
    assert cache.writes == 2 and all(version == code_version() for _, version in cache.store)
    # Second run: nothing is loaded (the loaders would fail), every row comes from the cache.
    unloadable = [dataclasses.replace(s, load=_broken) for s in sources]
    again = extract_many(unloadable, workers=1, cache=cache, progress=False)
    np.testing.assert_array_equal(again.X, space.X)
    assert cache.writes == 2 and [scan_id for scan_id, _ in again.failed] == ["broken-001"]


_RESIDENT_AFTER_FREEING = """
import sys
import numpy as np
from scanner.runtime.memory import keep_freed_memory

def resident_mb():
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("VmRSS:")).split()[1]) / 1024

kept = keep_freed_memory() if sys.argv[1] == "keep" else None
before = resident_mb()
block = np.ones(2**24)  # 128 MB, more than glibc's largest mapping threshold
del block
print(kept, resident_mb() - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt is Linux-only")
def test_workers_keep_the_memory_they_free_for_the_next_scan():
    # By default glibc unmaps a freed 128 MB block at once (the next scan faults it in again); a worker
    # that keeps freed memory (extract_many's, keep_freed_memory) still holds it for its next allocation.
    held = {}
    for mode in ("default", "keep"):
        run = subprocess.run([sys.executable, "-c", _RESIDENT_AFTER_FREEING, mode], capture_output=True,
                             text=True, check=True, timeout=120)
        kept, megabytes = run.stdout.split()
        held[mode] = float(megabytes)
        assert kept == ("True" if mode == "keep" else "None")
    assert held["default"] < 16
    assert held["keep"] > 120


_RESIDENT_AFTER_GIVING_BACK = """
import numpy as np
from scanner.runtime.memory import give_back_free_memory, keep_freed_memory

def resident_mb():
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("VmRSS:")).split()[1]) / 1024

keep_freed_memory()
before = resident_mb()
block = np.ones(2**24)  # 128 MB
del block
held = resident_mb() - before
print(held, give_back_free_memory(), resident_mb() - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's malloc_trim is Linux-only")
def test_free_memory_is_given_back_before_workers_are_forked(monkeypatch):
    # A process that keeps its freed memory holds a freed 128 MB block until it gives it back; extract_many
    # does that once before forking its workers (a lighter fork), and not when it runs in this process.
    run = subprocess.run([sys.executable, "-c", _RESIDENT_AFTER_GIVING_BACK], capture_output=True, text=True,
                         check=True, timeout=120)
    held, gave, after = run.stdout.split()
    assert float(held) > 120 and gave == "True" and float(after) < 16
    calls = []
    monkeypatch.setattr(local, "give_back_free_memory", lambda: calls.append(1))
    scans = [synthetic_scan("oak-planed", seed=seed) for seed in (1, 2)]
    extract_many(scans, workers=1, progress=False)
    assert calls == []
    extract_many(scans, workers=2, progress=False)
    assert calls == [1]


_RESIDENT_IN_AND_AFTER_A_BLOCK = """
import numpy as np
from scanner.runtime.memory import reusing_freed_memory

def resident_mb():
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("VmRSS:")).split()[1]) / 1024

before = resident_mb()
with reusing_freed_memory():
    with reusing_freed_memory():  # nested (or in another thread): the outer block's end gives it back
        block = np.ones(2**24)  # 128 MB
        del block
    inner = resident_mb() - before
    block = np.ones(2**24)
    del block
    outer = resident_mb() - before
after = resident_mb() - before
block = np.ones(2**24)
del block
print(inner, outer, after, resident_mb() - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt is Linux-only")
def test_a_block_reuses_freed_memory_and_gives_it_back_at_its_end():
    # Inside reusing_freed_memory (extract of a scan with large photos) a freed 128 MB block stays for the
    # next allocation; when the last block ends the memory goes back, and later large blocks are again
    # returned when freed (the process does not keep its peak, unlike a worker with keep_freed_memory).
    run = subprocess.run([sys.executable, "-c", _RESIDENT_IN_AND_AFTER_A_BLOCK], capture_output=True, text=True,
                         check=True, timeout=120)
    inner, outer, after, later = map(float, run.stdout.split())
    assert inner > 120 and outer > 120
    assert after < 16 and later < 16


def _pid(item: object) -> int:
    """The worker's process id; ``"die"`` ends the worker as the kernel would (out of memory), and a folder
    waits there until another worker has come too (at most 20 s), so that a batch of two uses both."""
    if item == "die":
        os._exit(3)
    if isinstance(item, str):
        Path(item, str(os.getpid())).touch()
        deadline = time.monotonic() + 20
        while len(os.listdir(item)) < 2 and time.monotonic() < deadline:
            time.sleep(0.005)
    return os.getpid()


def _meeting(tmp_path: Path) -> list[str]:
    """A batch of two tasks that meet in a new folder."""
    folder = tmp_path / f"meet-{len(list(tmp_path.glob('meet-*')))}"
    folder.mkdir()
    return [str(folder)] * 2


def _ended(pid: int, within_s: float = 20.0) -> bool:
    """Whether process ``pid`` is gone (collected by its parent) within ``within_s`` seconds."""
    deadline = time.monotonic() + within_s
    while os.path.exists(f"/proc/{pid}") and time.monotonic() < deadline:
        time.sleep(0.02)
    return not os.path.exists(f"/proc/{pid}")


def _pids_of(pool: local.WorkerPool, items: list) -> set[int]:
    return {pid for _, pid in local.run_tasks(_pid, items, range(len(items)), pool.size, lambda n: None, pool)}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_a_worker_pool_keeps_its_processes_across_calls_and_ends_them_when_closed(tmp_path):
    pool = local.WorkerPool(2)
    with pool:
        assert pool._executor is None  # nothing forked before a batch needs it
        first = _pids_of(pool, _meeting(tmp_path))
        second = _pids_of(pool, _meeting(tmp_path))
        assert first == second and len(first) == 2 and os.getpid() not in first
    assert pool._executor is None and all(_ended(pid) for pid in first)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_a_dead_worker_fails_its_batch_and_the_next_batch_starts_new_workers(tmp_path):
    with local.WorkerPool(2) as pool:
        before = _pids_of(pool, _meeting(tmp_path))
        with pytest.raises(concurrent.futures.BrokenExecutor):
            _pids_of(pool, ["die"])
        after = _pids_of(pool, _meeting(tmp_path))
    assert len(after) == 2 and not after & before


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_a_worker_that_died_between_batches_costs_the_next_batch_nothing(tmp_path):
    # Killed while idle (out of memory between two chunks of an export): the pool is broken before the
    # next batch submits anything, which then runs on new workers instead of failing.
    import signal

    with local.WorkerPool(2) as pool:
        before = _pids_of(pool, _meeting(tmp_path))
        victim = min(before)
        os.kill(victim, signal.SIGKILL)
        deadline = time.monotonic() + 20
        while not pool._executor._broken and time.monotonic() < deadline:  # the pool notices the death
            time.sleep(0.02)
        after = _pids_of(pool, _meeting(tmp_path))
    assert len(after) == 2 and not after & before


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_a_kept_pool_serving_other_code_forks_new_workers(tmp_path):
    # extract_many serves a pool its code version and column names: workers forked before a family was
    # registered would compute the old columns, stored under the new version.
    with local.WorkerPool(2) as pool:
        first = _pids_of(pool.serving(("v1", ("a",))), _meeting(tmp_path))
        again = _pids_of(pool.serving(("v1", ("a",))), _meeting(tmp_path))
        other = _pids_of(pool.serving(("v2", ("a", "b"))), _meeting(tmp_path))
    assert first == again and not other & first and len(other) == 2


def test_extract_many_serves_the_kept_pool_its_code_version_columns_and_directory():
    with local.WorkerPool(2) as pool:
        extract_many([foam(), foam()], pool=pool, progress=False)
        assert pool._key == (code_version(), (features.REGISTRY.names, os.getcwd()))


def test_leaving_a_batch_early_leaves_the_kept_pool_usable(tmp_path):
    (tmp_path / "marks").mkdir()
    marks = [str(tmp_path / "marks" / f"{i}") for i in range(20)]
    with local.WorkerPool(2) as pool:
        results = local.run_tasks(_gated_mark, marks, range(len(marks)), 2, lambda n: None, pool)
        assert next(results) == (0, marks[0])
        results.close()
        (tmp_path / "gate").touch()
        assert len(_pids_of(pool, _meeting(tmp_path))) == 2  # runs after the tasks already handed over
    assert len(list((tmp_path / "marks").iterdir())) <= 6


def test_extract_many_with_a_kept_pool_equals_one_worker():
    scans = [foam(), synthetic_scan("float-glass", seed=3, image_size=SIZE, sample_id="glass-01"),
             synthetic_scan("oak-planed", seed=4, image_size=SIZE, sample_id="oak-01")]
    alone = extract_many(scans, workers=1, progress=False)
    with local.WorkerPool(2) as pool:
        for _ in range(2):
            kept = extract_many(scans, pool=pool, progress=False)
            np.testing.assert_array_equal(kept.X, alone.X)
            assert kept.scan_ids == alone.scan_ids
        assert extract_many(scans, workers=2, pool=pool, progress=False).scan_ids == alone.scan_ids
        with pytest.raises(ValueError, match="workers=3 with a pool of 2 workers"):
            extract_many(scans, workers=3, pool=pool, progress=False)


def _noting_loader(folder: str, scan: Scan, gate: str | None = None) -> Scan:
    """A ``ScanSource.load`` that notes the process loading the scan (a file named by its id in ``folder``) and
    waits (at most 20 s) until two processes have, so that two scans use both workers; with ``gate``, until
    that file exists too."""
    Path(folder, str(os.getpid())).touch()
    deadline = time.monotonic() + 20
    while (len(os.listdir(folder)) < 2 or (gate and not os.path.exists(gate))) and time.monotonic() < deadline:
        time.sleep(0.005)
    return scan


def _noted(folder: Path, scans: list[Scan], gate: Path | None = None) -> list[ScanSource]:
    folder.mkdir()
    return [ScanSource(f"scan-{i}", scan.meta.label, scan.meta.sample_id,
                       functools.partial(_noting_loader, str(folder), scan, gate and str(gate)))
            for i, scan in enumerate(scans)]


def _loaders(folder: Path) -> set[int]:
    return {int(path.name) for path in folder.iterdir()}


@functools.cache
def _small_scans() -> tuple[Scan, ...]:
    return tuple(synthetic_scan(material, seed=seed, image_size=(96, 96), sample_id=f"{material}-{seed}")
                 for material in ("oak-planed", "float-glass") for seed in (1, 2))


def _workers_of_a_call(tmp_path: Path, workers: int = 2) -> set[int]:
    folder = tmp_path / f"call-{len(list(tmp_path.glob('call-*')))}"
    space = extract_many(_noted(folder, list(_small_scans())), workers=workers, progress=False)
    assert len(space) == len(_small_scans()) and not space.failed
    return _loaders(folder)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_extract_many_keeps_its_workers_for_its_next_call_until_they_are_released(tmp_path):
    scans = list(_small_scans())
    alone = extract_many(scans, workers=1, progress=False)
    first = _workers_of_a_call(tmp_path)
    again = extract_many(_noted(tmp_path / "again", scans), workers=2, progress=False)
    assert _loaders(tmp_path / "again") == first and len(first) == 2 and os.getpid() not in first
    np.testing.assert_array_equal(again.X, alone.X)
    assert list(again.scan_ids) == [f"scan-{i}" for i in range(len(scans))]
    local.release_workers()
    assert all(_ended(pid) for pid in first)
    after = _workers_of_a_call(tmp_path)
    assert len(after) == 2 and not after & first


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_kept_workers_end_by_themselves_when_no_call_comes(tmp_path, monkeypatch):
    monkeypatch.setattr(local, "KEEP_WORKERS_S", 0.2)
    kept = _workers_of_a_call(tmp_path)
    assert all(_ended(pid) for pid in kept)
    assert local._KEPT._pool is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_kept_workers_are_forked_anew_for_other_code_another_number_or_another_directory(tmp_path, monkeypatch):
    # Workers forked before a family was registered would compute the old columns under the new version; a
    # scan's relative paths would be found from the old directory.
    calls = [_workers_of_a_call(tmp_path)]
    monkeypatch.setattr(features.REGISTRY, "code_version", lambda *modules, families=None: "other code")
    calls.append(_workers_of_a_call(tmp_path))
    monkeypatch.chdir(tmp_path)
    calls.append(_workers_of_a_call(tmp_path))
    calls.append(_workers_of_a_call(tmp_path, workers=3))
    three = set(local._KEPT._pool._executor._processes)
    calls.append(_workers_of_a_call(tmp_path, workers=3))
    assert len(three) == 3 and set(local._KEPT._pool._executor._processes) == three and calls[4] <= three
    for before, after in zip(calls[:3], calls[1:4], strict=True):
        assert len(after) >= 2 and not after & before and all(_ended(pid) for pid in before)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="looks processes up in /proc")
def test_a_call_made_while_another_threads_has_the_kept_workers_forks_its_own(tmp_path):
    # The web app extracts in several threads at once; one call at a time uses the kept workers.
    import threading

    scans = list(_small_scans())
    held = _noted(tmp_path / "held", scans[:2], gate=tmp_path / "gate")
    done: list = []
    thread = threading.Thread(target=lambda: done.append(extract_many(held, workers=2, progress=False)))
    thread.start()
    try:
        deadline = time.monotonic() + 20
        while len(os.listdir(tmp_path / "held")) < 2 and time.monotonic() < deadline:  # both kept workers busy
            time.sleep(0.005)
        own = extract_many(_noted(tmp_path / "own", scans), workers=2, progress=False)
    finally:
        (tmp_path / "gate").touch()
        thread.join(30)
    assert len(_loaders(tmp_path / "own")) == 2 and not _loaders(tmp_path / "own") & _loaders(tmp_path / "held")
    alone = extract_many(scans, workers=1, progress=False)
    np.testing.assert_array_equal(own.X, alone.X)
    np.testing.assert_array_equal(done[0].X, alone.X[:2])


def _lent_in_a_child(answers) -> None:
    with local._KEPT.lent(2, "key") as pool:
        answers.put(pool is None)


@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="needs fork")
def test_a_forked_process_does_not_use_its_parents_kept_workers(tmp_path):
    _workers_of_a_call(tmp_path)
    context = multiprocessing.get_context("fork")
    answers = context.Queue()
    child = context.Process(target=_lent_in_a_child, args=(answers,))
    child.start()
    try:
        assert answers.get(timeout=20) is True
    finally:
        child.join(20)


def test_complete_synthetic_scan_gives_193_finite_values():
    values = foam_values()
    assert tuple(values) == NAMES
    assert [name for name, value in values.items() if not math.isfinite(value)] == []


def test_sharing_the_display_photo_changes_no_value():
    # extract prepares I_disp once for TacTUM and the image features; alone, each prepares its own.
    scan = foam()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disp = features.image.compute(scan.images["I_disp"])
        alone = {**features.tactum.compute(scan), **{f"image.disp.{k}": value for k, value in disp.items()}}
    values = foam_values()
    assert {name: values[name] for name in alone} == alone


def test_a_photo_too_small_for_image_features_gives_nan_not_an_error():
    scan = synthetic_scan("float-glass", seed=2, image_size=(201, 400))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        values = extract(scan)
    assert all(math.isnan(values[n]) for n in NAMES if n.startswith("image."))
    assert any("smaller than 202 px" in str(w.message) for w in caught)


def _pid_and_blas(value: int) -> tuple[int, int, int]:
    from scanner.runtime.threads import thread_pools  # noqa: PLC0415 (in the child)

    return os.getpid(), value * 2, max((p["num_threads"] for p in thread_pools().info()), default=1)


def _refuse(value: int) -> None:
    raise ValueError(f"no {value}")


def test_run_aside_runs_in_a_forked_process_with_one_blas_thread_while_this_one_goes_on():
    future = local.run_aside(_pid_and_blas, 21)
    pid, doubled, blas = future.result(timeout=60)
    assert pid != os.getpid() and doubled == 42 and blas == 1
    failed = local.run_aside(_refuse, 7)
    with pytest.raises(ValueError, match="no 7"):
        failed.result(timeout=60)


def test_run_aside_runs_here_where_a_worker_server_serves_this_process(monkeypatch):
    monkeypatch.setitem(local._SERVER, "context", multiprocessing.get_context())
    future = local.run_aside(_pid_and_blas, 1)
    assert future.done() and future.result()[:2] == (os.getpid(), 2)
    with pytest.raises(ValueError, match="no 3"):
        local.run_aside(_refuse, 3).result()
