"""The local runtime's worker processes (scanner.runtime.LocalRuntime): the same results as the serial loop,
a call aside in a process of its own, and extraction through the interface the features use."""

from __future__ import annotations

import concurrent.futures
import os

from features import extract_many
from scanner import runtime
from scanner.runtime.executors import LOCAL
from scanner.simulation import synthetic_scan


def _power(base: int, exponent: int) -> tuple[int, int]:
    return os.getpid(), base**exponent


def test_map_unordered_on_two_workers_equals_the_serial_loop():
    calls = [(3, k) for k in range(8)]
    here = dict(LOCAL.map_unordered(_power, calls, workers=1))
    there = dict(LOCAL.map_unordered(_power, calls, workers=2))
    assert {k: v for k, (_, v) in there.items()} == {k: v for k, (_, v) in here.items()} == {
        k: 3**k for k in range(8)}
    assert {pid for pid, _ in here.values()} == {os.getpid()}
    assert os.getpid() not in {pid for pid, _ in there.values()}


def test_submit_runs_aside_in_a_process_of_its_own():
    future = LOCAL.submit(_power, 2, 10)
    assert isinstance(future, concurrent.futures.Future)
    pid, value = future.result(timeout=120)
    assert value == 1024 and pid != os.getpid()


def test_extraction_runs_where_the_current_runtime_says():
    scans = [synthetic_scan(m, seed=1, image_size=(96, 96)) for m in ("oak-planed", "float-glass")]

    class Counting(runtime.LocalRuntime):
        extracted = 0

        def extract(self, fn, items, *args, **kwargs):
            Counting.extracted += len(items)
            return super().extract(fn, items, *args, **kwargs)

    serial = extract_many(scans, workers=1, progress=False)
    with runtime.using(Counting()):
        pooled = extract_many(scans, workers=2, progress=False)
    assert Counting.extracted == 2 and pooled.X.tobytes() == serial.X.tobytes() and pooled.failed == ()
