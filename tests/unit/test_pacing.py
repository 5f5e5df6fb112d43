"""The one real-time clock of playback and replay (scanner.pacing), on a clock that moves only when slept on."""

from __future__ import annotations

import math

import pytest

from scanner.pacing import Pacer
from taxonomy.errors import ParameterError


class FakeClock:
    def __init__(self) -> None:
        self.now = 50.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def test_a_wait_returns_when_the_recording_time_over_speed_has_passed():
    clock = FakeClock()
    pacer = Pacer(2.0, clock=clock, sleep=clock.sleep)
    assert pacer.start() == 50.0
    pacer.wait(1.0)                      # 1 s of recording at twice the speed: 0.5 s
    clock.now += 0.25                    # the consumer's own time counts towards the next deadline
    pacer.wait(2.0)
    assert clock.sleeps == [0.5, 0.25]
    assert pacer.elapsed() == 2.0
    pacer.wait(1.5)                      # a deadline already passed: no sleep
    assert clock.sleeps == [0.5, 0.25]


def test_speed_zero_never_sleeps_and_keeps_virtual_time():
    clock = FakeClock()
    pacer = Pacer(0.0, clock=clock, sleep=clock.sleep)
    pacer.wait(3.0)
    pacer.wait(1.0)
    assert clock.sleeps == [] and pacer.elapsed() == 3.0
    pacer.start()
    assert pacer.elapsed() == 0.0


def test_infinite_speed_never_sleeps():
    clock = FakeClock()
    pacer = Pacer(math.inf, clock=clock, sleep=clock.sleep)
    pacer.wait(1e6)
    assert clock.sleeps == []


def test_a_negative_speed_is_refused():
    with pytest.raises(ParameterError, match="pacing speed must be >= 0, got -1"):
        Pacer(-1)
