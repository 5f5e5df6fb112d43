"""Real-time pacing: the one clock that holds a playback back to the time of its recording.

The playback devices (:mod:`scanner.acquisition.devices`: the DAQ, the sensor board and the microphone
playing a simulated sample or a stored scan) and :func:`scanner.replay.paced_steps` (a stored scan step by
step, as ``texplorer replay --pace`` shows it) wait on a :class:`Pacer`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from taxonomy.errors import ParameterError


class Pacer:
    """Holds a playback back to real time and tells how far a recording is.

    ``speed`` 1 is real time, 2 twice as fast, ``math.inf`` never waits on the clock; 0 never waits either
    (tests, batch replay), and then time is *virtual*, advanced by the waits themselves, so a microphone
    sharing the DAQ's pacer records as long as the DAQ was read. Deadlines are measured from :meth:`start`,
    so time a consumer spends between waits is not added to the pacing. ``clock`` and ``sleep`` are
    replaceable for tests and simulations.
    """

    def __init__(self, speed: float = 1.0, *, clock: Callable[[], float] = time.perf_counter,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if speed < 0:
            raise ParameterError(f"pacing speed must be >= 0, got {speed!r}")
        self.speed = float(speed)
        self.clock = clock
        self.sleep = sleep
        self.started = clock()
        self.virtual = 0.0

    def start(self) -> float:
        """Restart the clock; returns the clock's time of the start."""
        self.started = self.clock()
        self.virtual = 0.0
        return self.started

    def wait(self, seconds: float) -> None:
        """Return when ``seconds`` of the recording have passed (at once at speed 0 or infinity)."""
        self.virtual = max(self.virtual, seconds)
        if self.speed == 0:
            return
        delay = self.started + seconds / self.speed - self.clock()
        if delay > 0:
            self.sleep(delay)

    def elapsed(self) -> float:
        """Seconds of recording since :meth:`start`: real (times speed) or virtual at speed 0."""
        if self.speed == 0:
            return self.virtual
        return (self.clock() - self.started) * self.speed
