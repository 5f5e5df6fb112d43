"""Audio-feature benchmark: ``features.audio.compute`` on 1 s of 44.1 kHz audio against same-process references.

References: the bare framing + ``numpy.fft.rfft`` of all 38 frames (the floor any short-term spectral
feature pays), and pyAudioAnalysis's ``ShortTermFeatures.feature_extraction`` with the same window and step
(a development dependency; its per-frame Python loop computes 34 related, not identical, features). The
goal is at most 1/8 of pyAudioAnalysis's time. One core (BLAS and OpenCV threads 1), CPU time, best of
interleaved rounds so that both see the same load. Ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_variable] = "1"

import math  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from features import audio  # noqa: E402

FS = 44100.0
TARGET_RATIO = 1 / 8
"""``compute`` at most this share of pyAudioAnalysis's short-term extraction of the same signal."""


def numpy_reference(signal: np.ndarray) -> np.ndarray:
    window, step = audio.window_and_step(FS)
    framed = np.lib.stride_tricks.sliding_window_view(signal, window)[::step] * np.hamming(window)
    return np.abs(np.fft.rfft(framed, axis=1))


def pyaudioanalysis_reference() -> Callable[[np.ndarray], object] | str:
    """The pyAudioAnalysis call, or the reason it cannot run."""
    try:
        from pyAudioAnalysis import ShortTermFeatures
    except ImportError as error:
        return f"pyAudioAnalysis not importable ({error}); `make install` puts it in the venv"
    window, step = audio.window_and_step(FS)
    return lambda signal: ShortTermFeatures.feature_extraction(signal, FS, window, step, deltas=False)


def best_cpu_times(stages: dict[str, Callable[[], object]], rounds: int, burst: int = 3) -> dict[str, float]:
    """Least CPU seconds of one run of each stage over ``rounds`` rounds that run every stage ``burst`` times
    in a row, after a warm-up: every stage sees the same load, and each runs with its data in cache as it
    would when called alone (one stage run right after another's evicts its data)."""
    for stage in stages.values():
        stage()
    best = dict.fromkeys(stages, math.inf)
    for _ in range(rounds):
        for name, stage in stages.items():
            for _ in range(burst):
                start = time.process_time()
                stage()
                best[name] = min(best[name], time.process_time() - start)
    return best


def main() -> None:
    cv2.setNumThreads(1)
    rng = np.random.default_rng(0)
    t = np.arange(int(FS)) / FS
    signals = {
        "white noise": rng.standard_normal(t.size),
        "harmonic tone 220 Hz + noise": sum(np.sin(2 * np.pi * h * 220.0 * t) / h for h in range(1, 6))
        + 0.05 * rng.standard_normal(t.size),
    }
    reference = pyaudioanalysis_reference()
    print(f"features.audio.compute on 1 s at {FS:.0f} Hz (38 frames of 2205 samples), one core, CPU time, "
          f"best of 15 interleaved rounds of 3 runs; load average {os.getloadavg()[0]:.1f}")
    for name, signal in signals.items():
        stages = {"compute": lambda s=signal: audio.compute(s, FS), "floor": lambda s=signal: numpy_reference(s)}
        if not isinstance(reference, str):
            stages["pyAudioAnalysis"] = lambda s=signal: reference(s)
        times = best_cpu_times(stages, 15)
        ours, floor = times["compute"], times["floor"]
        print(f"  {name:30s} compute {ours * 1e3:6.2f} ms")
        print(f"  {'':30s} numpy framing + rfft {floor * 1e3:6.2f} ms   ratio {ours / floor:6.1f}x")
        if isinstance(reference, str):
            print(f"  {'':30s} pyAudioAnalysis skipped: {reference}")
            continue
        theirs = times["pyAudioAnalysis"]
        met = "met" if ours / theirs <= TARGET_RATIO else "NOT met"
        print(f"  {'':30s} pyAudioAnalysis feature_extraction {theirs * 1e3:6.2f} ms   ratio {ours / theirs:6.3f}x, "
              f"{theirs / ours:4.1f} times faster (goal >= {1 / TARGET_RATIO:.0f}: {met})")


if __name__ == "__main__":
    main()
