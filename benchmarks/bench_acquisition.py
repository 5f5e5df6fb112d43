"""Acquisition benchmark against the emulators: the host reads the DAQ through nidaqmx over gRPC,
the sensor board through pyserial on a pseudo-terminal and a 44.1 kHz microphone, like the recorder does.

1. Nominal load for ``--seconds`` (default 60): 8 x 3 kHz DAQ + 44.1 kHz audio + the board's 20 Hz T and
   80 Hz M streams at once. Reports samples lost (must be 0) and the host's CPU use. The emulators run in
   their own processes (``texplorer emulate daq`` / ``board``), so the CPU is the host's alone. The audio is
   the playback microphone in real time (an ALSA file device is not paced, so it cannot stand in for 60 s).
2. Rate ramp: the highest aggregate DAQ rate the reader sustains for ``--ramp-seconds`` without an overrun,
   as a multiple of the nominal 24 kS/s (target >= 10x). The buffer is cut to 0.25 s here, so a reader that
   cannot keep up overruns within the run instead of living off a 2 s buffer.
3. Start offset: microphone first sample minus DAQ first sample, as the recorder measures it (microphone
   started first). With ``--microphone DEVICE`` a real sounddevice input; by default the playback microphone,
   which shows the host-side stagger (the DAQ task's set-up over gRPC). An ALSA ``file`` PCM cannot be
   used here: it is not paced, so its callbacks run back to back and starve the reading thread.

    python benchmarks/bench_acquisition.py [--seconds 60] [--ramp-seconds 3] [--microphone DEVICE]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from scanner.acquisition.config import BoardConfig, DaqConfig, MicrophoneConfig
from scanner.acquisition.devices.audio import PlaybackMicrophone, SoundDeviceMicrophone
from scanner.acquisition.devices.board import SerialBoard, StreamCollector
from scanner.acquisition.devices.daq import NidaqmxDaq
from scanner.acquisition.devices.protocols import AcquisitionError, DeviceError
from scanner.acquisition.devices.sources import SimulatedSample
from scanner.pacing import Pacer

NOMINAL_PER_CHANNEL = 3000.0
CHANNELS = 8
RAMP = (1, 2, 5, 10, 20, 40, 80, 160, 320, 640)
"""Multiples of the nominal per-channel rate tried, in order, until one loses samples."""


def start_emulator(*args: str) -> tuple[subprocess.Popen, str]:
    """Run ``texplorer emulate ...`` in its own process; returns it and the address it printed."""
    process = subprocess.Popen([sys.executable, "-m", "scanner.cli", "emulate", *args],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    return process, process.stdout.readline().strip()


def stop(process: subprocess.Popen) -> None:
    process.terminate()
    process.wait(timeout=10)


def nominal(seconds: float, server: str, port: str) -> None:
    daq = NidaqmxDaq(DaqConfig(server=server))
    board = SerialBoard(BoardConfig(port=port))
    microphone = PlaybackMicrophone(SimulatedSample("granite-polished", seed=0), pacer=Pacer(1.0))
    blocks = int(round(seconds * daq.rate / daq.block))
    buffer = np.empty((blocks, CHANNELS, daq.block))
    streams = {"T": StreamCollector(20, int(seconds * 20), 2), "M": StreamCollector(80, int(seconds * 80), 3)}
    audio = 0
    lost_daq = ""
    try:
        board.start("T", 20)
        board.start("M", 80)
        microphone.start("tool_slide")
        wall, cpu = time.perf_counter(), time.process_time()
        daq.start("tool_slide")
        try:
            for k in range(blocks):
                daq.read_into(buffer[k])
                audio += microphone.read().size
                for sample in board.read(0.0):
                    if not streams[sample.kind].done:
                        streams[sample.kind].add(sample)
        except AcquisitionError as error:
            lost_daq = str(error)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        daq.stop()
        while not all(stream.done for stream in streams.values()):
            for sample in board.read(1.0):
                if not streams[sample.kind].done:
                    streams[sample.kind].add(sample)
        board.stop()
    finally:
        daq.close()
        board.close()
    expected_audio = int(wall * 44100)
    print(f"nominal load for {seconds:g} s: 8 x 3 kHz DAQ (gRPC), 44.1 kHz audio, 20 Hz T + 80 Hz M (pty)")
    print(f"  DAQ      {blocks * daq.block * CHANNELS:>9} samples read, lost: "
          f"{lost_daq or 0}")
    for kind, stream in streams.items():
        print(f"  board {kind}  {stream.count:>9} samples, lost: {stream.missing} "
              f"(bad checksums {board.stats.bad_checksums}, garbage bytes {board.stats.garbage_bytes})")
    print(f"  audio    {audio:>9} samples of {expected_audio} due "
          f"({audio / max(expected_audio, 1):.3f}x), lost: 0")
    print(f"  host CPU {cpu:.2f} s in {wall:.2f} s = {100 * cpu / wall:.1f} % of one core")


RAMP_BUFFER_S = 0.25
"""DAQ buffer in the ramp: a reader that falls this far behind overruns within the run."""


def ramp(seconds: float, server: str) -> None:
    print(f"rate ramp: {seconds:g} s per rate, 15 reads per second, {RAMP_BUFFER_S:g} s buffer")
    sustained = 0.0
    for multiple in RAMP:
        rate = NOMINAL_PER_CHANNEL * multiple
        daq = NidaqmxDaq(replace(DaqConfig(server=server), rate_hz=rate, buffer_s=RAMP_BUFFER_S))
        blocks = int(round(seconds * 15))
        out = np.empty((CHANNELS, daq.block))
        started, cpu = time.perf_counter(), time.process_time()
        try:
            daq.start("bench")
            for _ in range(blocks):
                daq.read_into(out)
            verdict = "ok"
        except DeviceError as error:
            verdict = f"FAILED ({str(error).split(': ', 1)[-1][:70]})"
        finally:
            daq.close()
        wall, cpu = time.perf_counter() - started, time.process_time() - cpu
        print(f"  {CHANNELS} x {rate / 1000:5.1f} kHz = {CHANNELS * rate / 1000:6.1f} kS/s "
              f"({multiple:>3}x nominal): {verdict}, {wall:.2f} s for {seconds:g} s of samples, "
              f"host CPU {100 * cpu / wall:5.1f} %")
        if verdict != "ok":
            break
        sustained = multiple
    aggregate = CHANNELS * NOMINAL_PER_CHANNEL * sustained / 1000
    print(f"  highest sustained: {sustained:g}x nominal = {aggregate:g} kS/s "
          f"(target >= 10x: {'met' if sustained >= 10 else 'NOT met'})")


def offsets(server: str, device: str | None) -> None:
    """Microphone first sample - DAQ first sample over 5 starts, microphone first as in the recorder."""
    if device is None:
        microphone = PlaybackMicrophone(SimulatedSample("granite-polished", seed=0), pacer=Pacer(1.0))
        source = "playback microphone in real time"
    else:
        microphone = SoundDeviceMicrophone(MicrophoneConfig(device=device))
        source = f"sounddevice input {microphone.name!r}"
    daq = NidaqmxDaq(DaqConfig(server=server))
    values = []
    try:
        for _ in range(5):
            daq.arm("tool_slide")
            first = microphone.start("tool_slide")
            values.append((first - daq.start("tool_slide")) * 1000)
            daq.stop()
            microphone.stop()
    finally:
        daq.close()
        microphone.close()
    print(f"start offset, microphone first sample - DAQ first sample ({source}), 5 starts:")
    print(f"  {', '.join(f'{v:.2f}' for v in values)} ms; median {np.median(values):.2f} ms "
          "(negative: audio started first; the recorder drops that much audio)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="nominal run length (default 60)")
    parser.add_argument("--ramp-seconds", type=float, default=3.0, help="seconds per ramp rate (default 3)")
    parser.add_argument("--microphone", metavar="DEVICE", help="measure the start offset with this "
                        "sounddevice input (default: the playback microphone)")
    args = parser.parse_args()
    daq_process, server = start_emulator("daq")
    with tempfile.TemporaryDirectory() as folder:
        board_process, port = start_emulator("board", "--link", str(Path(folder) / "ttyBENCH"))
        try:
            nominal(args.seconds, server, port)
            ramp(args.ramp_seconds, server)
            offsets(server, args.microphone)
        finally:
            stop(board_process)
            stop(daq_process)


if __name__ == "__main__":
    main()
