"""Audio-feature benchmark: ``features.audio.compute`` on 1 s of 44.1 kHz audio against same-process references.

References: the bare framing + ``numpy.fft.rfft`` of all 38 frames (the floor any short-term spectral
feature pays), and pyAudioAnalysis's ``ShortTermFeatures.feature_extraction`` with the same window and step
when it is importable (it is not a project dependency; its per-frame Python loop computes 34 related,
not identical, features). Ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from timing import median_time

from features import audio

FS = 44100.0
TARGET_MS = 50.0


def numpy_reference(signal: np.ndarray) -> np.ndarray:
    window, step = audio.window_and_step(FS)
    framed = np.lib.stride_tricks.sliding_window_view(signal, window)[::step] * np.hamming(window)
    return np.abs(np.fft.rfft(framed, axis=1))


def pyaudioanalysis_reference() -> Callable[[np.ndarray], object] | str:
    """The pyAudioAnalysis call, or the reason it cannot run."""
    try:
        from pyAudioAnalysis import ShortTermFeatures
    except ImportError as error:
        return f"pyAudioAnalysis not importable ({error}); install it in the venv to compare"
    window, step = audio.window_and_step(FS)
    return lambda signal: ShortTermFeatures.feature_extraction(signal, FS, window, step, deltas=False)


def main() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(int(FS)) / FS
    signals = {
        "white noise": rng.standard_normal(t.size),
        "harmonic tone 220 Hz + noise": sum(np.sin(2 * np.pi * h * 220.0 * t) / h for h in range(1, 6))
        + 0.05 * rng.standard_normal(t.size),
    }
    reference = pyaudioanalysis_reference()
    print(f"features.audio.compute on 1 s at {FS:.0f} Hz (38 frames of 2205 samples), median of 15 runs")
    for name, signal in signals.items():
        ours = median_time(lambda s=signal: audio.compute(s, FS))
        floor = median_time(lambda s=signal: numpy_reference(s))
        verdict = "ok" if ours * 1e3 < TARGET_MS else f"SLOWER than the {TARGET_MS:.0f} ms target"
        print(f"  {name:30s} compute {ours * 1e3:6.2f} ms ({verdict})")
        print(f"  {'':30s} numpy framing + rfft {floor * 1e3:6.2f} ms   ratio {ours / floor:6.1f}x")
        if isinstance(reference, str):
            print(f"  {'':30s} pyAudioAnalysis skipped: {reference}")
        else:
            theirs = median_time(lambda s=signal: reference(s), repeat=5)
            print(f"  {'':30s} pyAudioAnalysis feature_extraction {theirs * 1e3:6.2f} ms"
                  f"   ratio {ours / theirs:6.3f}x (below 1 = faster)")


if __name__ == "__main__":
    main()
