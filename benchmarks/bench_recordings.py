"""Feature time per recording for each family of ``features.recordings`` (a lab's own recordings).

Inputs: a 5 s, 44.1 kHz sound (as the ``audio`` role, and as a one-axis ``vibration``), a 1024 x 1024
photo (``photo``, no crop) and a 5 s, 1 kHz three-axis force (``force_xyz``). Each family's time per
recording is set against a reference run in the same process on the same input:

- audio: librosa's MFCC (``librosa.feature.mfcc``, 13 coefficients, the same 2205-sample window and
  1103-sample hop) when librosa is installed (a dev extra), and the bare framing + ``rfft`` of every frame
  (the floor any short-term spectral feature pays);
- image: 14 Haralick features of the same gray image by mahotas (a dev extra), the usual library for them;
- vibration: the zero-phase band-pass alone (``scipy.signal.sosfiltfilt``), which every ``v`` needs;
- friction: the mean of the force (one pass over the samples), the floor of any friction feature.

Ratios, not absolute times, compare across machines. The photo is timed a few times only (seconds each).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from bench_audio import numpy_reference
from timing import best_time, median_time

from features import audio, recordings, signals
from scanner.preprocess import gray_uint8, grayscale
from scanner.scan import Recording, Trace

FS = 44100.0
SECONDS = 5.0
SIDE = 1024


def inputs() -> tuple[Recording, np.ndarray]:
    rng = np.random.default_rng(0)
    t = np.arange(int(FS * SECONDS)) / FS
    sound = sum(np.sin(2 * np.pi * h * 220.0 * t) / h for h in range(1, 6)) + 0.05 * rng.standard_normal(t.size)
    y, x = np.mgrid[0:SIDE, 0:SIDE]
    gray = 128 + 60 * np.sin(2 * np.pi * (x + 0.3 * y) / 17.0) + rng.normal(0, 20, (SIDE, SIDE))
    photo = np.clip(np.stack([gray, 0.8 * gray, 0.6 * gray], axis=2), 0, 255).astype(np.uint8)
    force = np.column_stack([0.4 * np.ones(5000), 0.1 * rng.standard_normal(5000), 2 + 0.1 * rng.standard_normal(5000)])
    recording = Recording("bench", {"a": Trace(sound, FS, "FS"), "v": Trace(sound, FS, "g"),
                                    "f": Trace(force, 1000.0, "N")},
                          {"audio": "a", "vibration": "v", "force_xyz": "f", "photo": "p"}, "x",
                          images={"p": photo})
    return recording, sound


def librosa_mfcc() -> Callable[[np.ndarray], object] | str:
    """librosa's MFCC with our window and hop, or the reason it cannot run."""
    try:
        import librosa
    except ImportError as error:
        return f"librosa not importable ({error}); pip install -e '.[dev]' to compare"
    window, step = audio.window_and_step(FS)
    return lambda x: librosa.feature.mfcc(y=x, sr=int(FS), n_mfcc=13, n_fft=window, hop_length=step,
                                          window="hamming", center=False)


def mahotas_haralick() -> Callable[[np.ndarray], object] | str:
    try:
        import mahotas.features
    except ImportError as error:
        return f"mahotas not importable ({error})"
    return lambda gray: mahotas.features.haralick(gray, return_mean=True, compute_14th_feature=True)


def line(name: str, ours: float, reference_name: str, reference: float) -> None:
    print(f"  {name:<16} {ours * 1e3:9.2f} ms per recording   {reference_name:<40} {reference * 1e3:9.2f} ms"
          f"   ratio {ours / reference:6.2f}x")


def main() -> None:
    recording, sound = inputs()
    print(f"features.recordings on one recording: {SECONDS:g} s at {FS:.0f} Hz, a {SIDE}x{SIDE} photo, "
          f"5 s of 1 kHz force; median of repeated runs (photo: best of 3)")
    for family in ("audio.audio", "audio.vibration", "vibration", "friction"):
        ours = median_time(lambda f=family: recordings.recording_rows(recording, applied=[f]), repeat=5)
        if family.startswith("audio"):
            line(family, ours, "numpy framing + rfft of every frame", median_time(lambda: numpy_reference(sound), 5))
            reference = librosa_mfcc()
            if isinstance(reference, str):
                print(f"  {'':16} librosa skipped: {reference}")
            else:
                line("", ours, "librosa.feature.mfcc (13 coefficients)",
                     median_time(lambda mfcc=reference: mfcc(sound), 5))
        elif family == "vibration":
            line(family, ours, "sosfiltfilt band-pass alone",
                 median_time(lambda: signals.band_limited(sound, FS), 5))
        else:
            force = recording.channels["f"].data
            line(family, ours, "mean of the force", median_time(lambda f=force: f.mean(axis=0), 15))
    photo = recording.images["p"]
    ours = best_time(lambda: recordings.recording_rows(recording, applied=["image.photo"]), repeat=3)
    reference = mahotas_haralick()
    if isinstance(reference, str):
        print(f"  image.photo {ours * 1e3:9.2f} ms per recording; mahotas skipped: {reference}")
    else:
        gray = gray_uint8(grayscale(photo))
        line("image.photo", ours, "mahotas Haralick (14 features) alone", best_time(lambda: reference(gray), 3))


if __name__ == "__main__":
    main()
