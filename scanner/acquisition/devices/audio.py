"""The microphone (docs/devices.md): 44100 Hz mono, recorded together with the DAQ during the TU1 slides.

:class:`SoundDeviceMicrophone` uses ``sounddevice`` (PortAudio): the stream's callback copies each block
into a queue as 16-bit samples scaled to full scale, and counts blocks whose status reports an input
overflow (samples lost); the count stays with the recording
(:class:`~scanner.acquisition.devices.protocols.AudioCapture`). ``start`` returns when the first block has arrived,
with the estimated time of its first sample, so the recorder can measure the audio/DAQ start offset.
:class:`PlaybackMicrophone` is the simulated and replay microphone.

``sounddevice`` is imported only when a real microphone is opened; without the PortAudio library the error is
one line (``DeviceUnavailable``).
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Any

import numpy as np

from scanner.acquisition.config import MicrophoneConfig
from scanner.acquisition.devices.protocols import AcquisitionError, AudioCapture, DeviceError, DeviceUnavailable
from scanner.acquisition.devices.sources import SignalSource
from scanner.lazy import optional
from scanner.pacing import Pacer

FIRST_BLOCK_TIMEOUT_S = 2.0
TAIL_GRACE_S = 0.5
"""How long past its input latency :meth:`SoundDeviceMicrophone.stop` waits for the samples it was asked for."""
FULL_SCALE = 32768.0
"""16-bit samples are read as integers (exact through any ALSA plug conversion) and scaled to [-1, 1)."""


def _import_sounddevice() -> Any:
    try:
        return optional("sounddevice", None, "the microphone", install="pip install sounddevice",
                        error=DeviceUnavailable)
    except OSError as exc:
        raise DeviceUnavailable(f"the microphone needs the PortAudio library ({exc}): install libportaudio2 "
                                "(Debian/Ubuntu) or portaudio (Homebrew)") from None


def _device(name: str) -> int | str | None:
    name = name.strip()
    if not name:
        return None
    return int(name) if name.isdigit() else name


class SoundDeviceMicrophone:
    """A PortAudio input device through ``sounddevice``: name or index (``microphone.device``), mono."""

    def __init__(self, config: MicrophoneConfig) -> None:
        self._sd = _import_sounddevice()
        self.config = config
        self.rate = float(config.rate_hz)
        self.device = _device(config.device)
        try:
            info = self._sd.query_devices(self.device, "input")
        except (ValueError, self._sd.PortAudioError) as exc:
            raise DeviceUnavailable(f"microphone {config.device or '(default)'}: {exc}") from None
        self.name = str(info["name"])
        self._stream: Any = None
        self._blocks: queue.Queue[np.ndarray] = queue.Queue()
        self._recorded: list[np.ndarray] = []
        self._first = threading.Event()
        self._first_time = 0.0
        self._arrived = 0
        self._latency = 0.0
        self._overflows = 0

    def describe(self) -> dict[str, str]:
        return {"microphone": f"{self.name} ({self.rate:g} Hz)"}

    def _callback(self, indata: np.ndarray, frames: int, time_info: Any, status: Any) -> None:
        arrived = time.perf_counter()
        if status.input_overflow:
            self._overflows += 1
        if not self._first.is_set():
            # The block's first sample was captured its own length plus the input latency ago.
            self._first_time = arrived - frames / self.rate - self._latency
            self._first.set()
        self._blocks.put(indata[:, 0] / FULL_SCALE)
        self._arrived += frames

    def start(self, step: str) -> float:
        """Open and start the stream; returns once the first block arrived, with its first sample's time."""
        self.stop_stream()
        self._blocks = queue.Queue()
        self._recorded = []
        self._first.clear()
        self._arrived = 0
        self._overflows = 0
        try:
            self._stream = self._sd.InputStream(samplerate=self.rate, channels=1, dtype="int16",
                                                blocksize=self.config.blocksize, device=self.device,
                                                callback=self._callback)
            self._latency = float(self._stream.latency)
            self._stream.start()
        except self._sd.PortAudioError as exc:
            self.stop_stream()
            raise DeviceError(f"microphone {self.name}: cannot start: {exc}") from None
        if not self._first.wait(FIRST_BLOCK_TIMEOUT_S):
            self.stop_stream()
            raise AcquisitionError(f"microphone {self.name}: no audio within {FIRST_BLOCK_TIMEOUT_S:g} s")
        return self._first_time

    def read(self) -> np.ndarray:
        """Samples that arrived since the last call (they are kept for :meth:`stop` too)."""
        blocks = []
        while True:
            try:
                blocks.append(self._blocks.get_nowait())
            except queue.Empty:
                break
        self._recorded += blocks
        return np.concatenate(blocks) if blocks else np.zeros(0)

    def stop(self, until: float | None = None) -> AudioCapture:
        if until is not None and self._stream is not None:
            deadline = time.perf_counter() + self._latency + TAIL_GRACE_S
            while (self._first_time + self._arrived / self.rate < until
                   and time.perf_counter() < deadline):
                time.sleep(0.002)
        self.stop_stream()
        self.read()
        samples = np.concatenate(self._recorded) if self._recorded else np.zeros(0)
        return AudioCapture(samples, self._first_time, self._overflows)

    def stop_stream(self) -> None:
        stream, self._stream = self._stream, None
        if stream is not None:
            try:
                stream.stop()
            finally:
                stream.close()

    def close(self) -> None:
        self.stop_stream()


class PlaybackMicrophone:
    """The simulated or replay microphone: plays ``source.audio(step)`` on ``pacer``'s clock.

    Share the DAQ's pacer: at speed 0 the recording is then exactly as long as the DAQ was read. Past the
    end of the take it records silence.
    """

    def __init__(self, source: SignalSource, *, rate: float = 44100.0, pacer: Pacer | None = None) -> None:
        self.source = source
        self.rate = float(rate)
        self.pacer = pacer or Pacer(0.0)
        self._audio = np.zeros(0)
        self._delivered = 0

    def describe(self) -> dict[str, str]:
        return {"microphone": f"lavalier ({self.source.kind})"}

    def start(self, step: str) -> float:
        self._audio = self.source.audio(step, "microphone")
        self._delivered = 0
        return self.pacer.start()

    def _segment(self, start: int, end: int) -> np.ndarray:
        """Samples start..end of the take, silence past its end."""
        part = self._audio[start:end]
        return np.concatenate([part, np.zeros(end - start - len(part))])

    def read(self) -> np.ndarray:
        end = int(self.pacer.elapsed() * self.rate)
        if end <= self._delivered:
            return np.zeros(0)
        out = self._segment(self._delivered, end)
        self._delivered = end
        return out

    def stop(self, until: float | None = None) -> AudioCapture:
        if until is not None and 0 < self.pacer.speed < float("inf"):
            self.pacer.wait((until - self.pacer.started) * self.pacer.speed)
        end = max(int(round(self.pacer.elapsed() * self.rate)), self._delivered)
        # Playback shares the DAQ's clock, restarted when the DAQ starts: the take's sample 0 is the DAQ's.
        return AudioCapture(self._segment(0, end), self.pacer.started, 0)

    def close(self) -> None:
        self._audio = np.zeros(0)
