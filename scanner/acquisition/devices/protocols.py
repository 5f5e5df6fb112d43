"""The device interfaces (docs/devices.md): what the recorder needs from a DAQ, a sensor board, a microphone, a camera
and the Peltier element.

Each interface has a real, a simulated and a replay implementation that satisfy the same
``typing.Protocol``; the configuration (:mod:`scanner.acquisition.config`), not ``if`` statements in the recorder,
chooses between them (:func:`scanner.acquisition.devices.open_devices`). Every ``start`` takes the procedure step the
operator is about to perform: a real device ignores it (or uses it to name its task), a simulated one plays
that step of the simulated sample, a replay one plays that step of the stored scan.

Errors are one line for the operator: :class:`DeviceUnavailable` when a device, its driver or its library
cannot be used at all; :class:`AcquisitionError` when data was lost during a recording (a DAQ buffer overrun,
a lost serial connection, 1 s of silence), which fails the step instead of leaving a silent gap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from taxonomy.errors import TexplorerError


class DeviceError(TexplorerError, RuntimeError):
    """A device failed; the message says which and why in one line."""


class DeviceUnavailable(DeviceError):
    """A device, its driver or its client library cannot be used (not installed, not plugged in)."""


class AcquisitionError(DeviceError):
    """Data was lost or not delivered during a recording; the step fails and can be redone."""


class BoardTimeout(AcquisitionError):
    """The serial board sent nothing for longer than its timeout (1 s)."""


class ConnectionLost(AcquisitionError):
    """The connection to a device was lost during a recording (it may have been re-established since)."""


@runtime_checkable
class Daq(Protocol):
    """Analog inputs sampled continuously at ``rate`` Hz and the Peltier's digital output line.

    ``read_into`` fills a preallocated (channels, block) float64 array with the next ``block`` samples per
    channel, in volts, in the order of :data:`scanner.acquisition.config.DAQ_ROLES`; it blocks until they are there and
    raises :class:`AcquisitionError` on a buffer overrun.
    """

    rate: float
    block: int
    channels: tuple[str, ...]

    def describe(self) -> dict[str, str]: ...

    def arm(self, step: str) -> None:
        """Prepare the acquisition of ``step`` so that :meth:`start` is quick."""
        ...

    def start(self, step: str) -> float:
        """Start acquiring (arming first if needed); returns the ``perf_counter()`` of the first sample."""
        ...

    def read_into(self, out: np.ndarray) -> None: ...

    def stop(self) -> None: ...

    def set_peltier(self, on: bool) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class BoardSample:
    """One checksummed data line of the sensor board: ``kind`` "T" (object, ambient degC) or "M" (bx, by,
    bz uT), the board's millisecond counter and the values."""

    kind: str
    ms: int
    values: tuple[float, ...]


@dataclass
class BoardStats:
    """What the serial driver dropped and repaired: lines with a bad checksum, garbage bytes skipped while
    resynchronising, samples missing according to the board's counter, reconnections."""

    bad_checksums: int = 0
    garbage_bytes: int = 0
    missing_samples: int = 0
    reconnects: int = 0


@runtime_checkable
class SensorBoard(Protocol):
    """The serial sensor board (docs/devices.md): MLX90614 temperatures, MAG3110 field, Peltier relay."""

    stats: BoardStats

    def describe(self) -> dict[str, str]: ...

    def ambient(self) -> float:
        """One MLX90614 ambient temperature reading, degC."""
        ...

    def calibrate_magnetometer(self) -> None: ...

    def start(self, kind: str, hz: float) -> None:
        """Start the "T" (temperature) or "M" (magnetometer) stream at ``hz``."""
        ...

    def read(self, timeout: float) -> list[BoardSample]:
        """The data lines received since the last call; waits up to ``timeout`` s for at least one."""
        ...

    def stop(self) -> None: ...

    def heat(self, ms: int) -> None:
        """Switch the Peltier on for ``ms`` milliseconds (the board switches it off itself after that)."""
        ...

    def heat_off(self) -> None: ...

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the connection failed or dropped since the last check."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class AudioCapture:
    """What a microphone recorded: samples (full scale), the time of the first one (``perf_counter``) and
    how many callbacks reported an input overflow (samples lost)."""

    samples: np.ndarray
    first_sample_time: float
    overflows: int


@runtime_checkable
class Microphone(Protocol):
    """A mono microphone at ``rate`` Hz, recorded through a callback into a queue."""

    rate: float

    def describe(self) -> dict[str, str]: ...

    def start(self, step: str) -> float:
        """Start recording; returns the ``perf_counter`` time of the first sample (estimated)."""
        ...

    def read(self) -> np.ndarray:
        """Samples that arrived since the last call (maybe none)."""
        ...

    def stop(self, until: float | None = None) -> AudioCapture:
        """Stop; everything recorded since ``start``. With ``until`` (a ``perf_counter`` time), first record
        on until the samples reach that time (bounded by the input latency and a short grace period)."""
        ...

    def close(self) -> None: ...


@runtime_checkable
class Camera(Protocol):
    """Takes the TU3 photos: ``capture("I_disp" | "I_macro" | "I_illu")`` -> RGB uint8 (h, w, 3)."""

    def describe(self) -> dict[str, str]: ...

    def capture(self, photo: str) -> np.ndarray: ...

    def close(self) -> None: ...


@runtime_checkable
class Peltier(Protocol):
    """The Peltier element, switched by the board's relay or the DAQ's digital line.

    ``on(seconds)`` is bounded by the device itself where it can be (the board refuses more than 5 s and
    switches off on its own); ``check()`` raises if the device lost its connection while heating.
    """

    def on(self, seconds: float) -> None: ...

    def off(self) -> None: ...

    def check(self) -> None: ...
