"""MiniRocket through the project's wiring against sktime's own call, in the same run, on one core.

- one 5 s, 44.1 kHz recording (the ``audio`` role): its length rule (8 windows of 2048 samples), the
  fitted :class:`features.random_kernels.RandomKernels` transform and the mean over the windows, against
  ``MiniRocket.transform`` of the same 8 windows, and against ``MiniRocket.transform`` of the whole
  recording as one series (what the length rule saves);
- one scan's slide signals (``v_ts``, ``v_tt``, ``a_ts``, ``f_frt`` of the regression scan): cutting the
  signals from the scan (``extract(scan, ["signal"])``) and transforming them, against sktime's transforms
  of the same instances;
- the fit on 1,000 recordings (``v_ts``: 3000 samples each) against ``MiniRocket.fit`` of the same panel.

Memory: the series handed to the kernels per recording, by the rule and whole, and the peak resident
memory of the process after each part. Ratios, not absolute times, compare across machines.
"""

from __future__ import annotations

import resource
from pathlib import Path

import numpy as np
from timing import best_time, median_time

from features import extract
from features.modern import ROLE_RULES, SCAN_SIGNALS, instances
from features.random_kernels import RandomKernels
from scanner.runtime.threads import one_blas_thread
from scanner.storage.matfile import load_scan

FS = 44100.0
SECONDS = 5.0
FIT_ROWS = 1000
SCAN = Path(__file__).resolve().parents[1] / "tests" / "regression" / "scans" / "granite-polished-01-001.mat"


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def line(name: str, ours: float, reference_name: str, reference: float) -> None:
    print(f"  {name:<28} {ours * 1e3:9.2f} ms   {reference_name:<44} {reference * 1e3:9.2f} ms"
          f"   ratio {ours / reference:6.2f}x")


def sound(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(int(FS * SECONDS)) / FS
    return np.sin(2 * np.pi * (200 + 10 * seed) * t) + 0.1 * rng.standard_normal(t.size)


def recording_part(MiniRocket: type) -> None:
    rule = ROLE_RULES["audio"].rule
    columns = [f"signal.audio.{k:05d}" for k in range(rule.samples)]
    train = np.stack([instances(sound(seed), FS, rule).reshape(-1) for seed in range(16)])
    step = RandomKernels("minirocket", columns).fit(train)
    library = MiniRocket(random_state=0).fit(train.reshape(-1, 1, rule.length))
    x = sound(99)

    def ours() -> np.ndarray:
        return step.transform(instances(x, FS, rule).reshape(1, -1))

    windows = instances(x, FS, rule)[:, None, :]
    print(f"MiniRocket of one {SECONDS:g} s recording at {FS:.0f} Hz ({rule.describe()}), 9,996 features; "
          f"median of 5")
    line("ours (rule + transform)", median_time(ours, 5), "MiniRocket.transform of the 8 windows",
         median_time(lambda: library.transform(windows), 5))
    whole = x[None, None, :]
    whole_fit = MiniRocket(random_state=0).fit(np.stack([sound(s) for s in range(4)])[:, None, :])
    line("", median_time(ours, 5), "MiniRocket.transform of the whole series",
         best_time(lambda: whole_fit.transform(whole), 2))
    print(f"  series handed to the kernels: {windows.size * 4 / 1024:.0f} KiB by the rule, "
          f"{whole.size * 4 / 1024:.0f} KiB whole (float32); peak RSS so far {peak_mb():.0f} MB")


def scan_part(MiniRocket: type) -> None:
    scan = load_scan(SCAN)
    values = extract(scan, ["signal"])
    columns = list(values)
    row = np.array([list(values.values())])
    rng = np.random.default_rng(0)
    train = row + 0.01 * rng.standard_normal((8, row.shape[1]))
    step = RandomKernels("minirocket", columns).fit(train)
    panels = {name: row[:, [c.startswith(f"signal.{name}.") for c in columns]].reshape(-1, 1, spec.rule.length)
              for name, spec in SCAN_SIGNALS.items()}
    libraries = {name: MiniRocket(random_state=0).fit(
        train[:, [c.startswith(f"signal.{name}.") for c in columns]].reshape(-1, 1, spec.rule.length))
        for name, spec in SCAN_SIGNALS.items()}

    def ours() -> np.ndarray:
        cut = extract(scan, ["signal"])
        return step.transform(np.array([list(cut.values())]))

    def theirs() -> None:
        for name, library in libraries.items():
            library.transform(panels[name])

    rules = ", ".join(f"{n}: {s.rule.describe()}" for n, s in SCAN_SIGNALS.items())
    print(f"MiniRocket of one scan's signals ({rules})")
    line("ours (cut from scan + transform)", median_time(ours, 5), "MiniRocket.transform of the same instances",
         median_time(theirs, 5))
    print(f"  peak RSS so far {peak_mb():.0f} MB")


def fit_part(MiniRocket: type) -> None:
    rule = SCAN_SIGNALS["v_ts"].rule
    rng = np.random.default_rng(1)
    X = rng.standard_normal((FIT_ROWS, rule.samples)).astype(np.float64)
    columns = [f"signal.v_ts.{k:05d}" for k in range(rule.samples)]
    print(f"fit on {FIT_ROWS} recordings of {rule.length} samples (v_ts); best of 3")
    line("RandomKernels.fit", best_time(lambda: RandomKernels("minirocket", columns).fit(X), 3),
         "MiniRocket.fit", best_time(lambda: MiniRocket(random_state=0).fit(X[:, None, :]), 3))
    print(f"  peak RSS so far {peak_mb():.0f} MB (the panel alone: {X.nbytes / 2**20:.0f} MB)")


def main() -> None:
    try:
        from sktime.transformations.rocket import MiniRocket
    except ImportError as error:
        print(f"bench_modern skipped: sktime not importable ({error}); pip install -e '.[modern]'")
        return
    with one_blas_thread():
        recording_part(MiniRocket)
        scan_part(MiniRocket)
        fit_part(MiniRocket)


if __name__ == "__main__":
    main()
