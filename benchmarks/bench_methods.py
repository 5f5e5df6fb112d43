"""Time per classification of the related methods, next to the figures their papers report.

Each method is fitted on its simulated sensor (``scanner.simulation.recordings``) and then timed the way its
paper reports time: per sample, one sample at a time (median over samples), split into feature extraction
and classification. References in the same run: the batch prediction time per row (what one call on many
rows costs; the gap is scikit-learn's per-call input checking) and a bare FFT of the same signal for the
FFT-based features.

Paper figures: Xie et al. Table 5 (Python 3.5, Core i3 3.3 GHz): images -> sequences ~11.5 ms, feature
extraction ~4.6 ms, classification 0.7-212 us. Chathuranga et al. Table I (MATLAB, Core i5 3.1 GHz):
280 us per classification (proposed), 8 us (spatial period), 880 us (neural net). Huang and Wu
section 2.2 (MATLAB, Core i7 2.6 GHz): 0.47 s feature extraction per set.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
from sklearn.base import BaseEstimator

from scanner.simulation.recordings import array_recordings, biotac_recordings, soft3axis_recordings
from taxonomy import related as methods
from taxonomy.related import Dataset
from taxonomy.related.chathuranga_features import chathuranga4, chathuranga_period
from taxonomy.related.hoelscher_features import chu, mean23
from taxonomy.related.huang_features import huang7
from taxonomy.related.xie_features import xie_sequence_vector, xie_sequences

SAMPLES = 40
"""Samples timed one at a time per measurement (the median is reported)."""


def per_sample(fn: Callable[[object], object], items: Sequence[object]) -> float:
    """Median seconds of ``fn(item)`` over the items."""
    times = []
    for item in items:
        start = time.perf_counter()
        fn(item)
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def batch_per_row(model: BaseEstimator, X: np.ndarray) -> float:
    start = time.perf_counter()
    model.predict(X)
    return (time.perf_counter() - start) / len(X)


def line(what: str, seconds: float, paper: str, unit: str = "ms") -> None:
    scale = {"ms": 1e3, "us": 1e6, "s": 1.0}[unit]
    print(f"  {what:<46} {scale * seconds:10.3f} {unit:<2}   paper: {paper}")


def bench_xie() -> None:
    data = Dataset.from_recordings("array", array_recordings(trials=10))
    taxels = [r.role("taxels").data[:100] for r in data.recordings[:SAMPLES]]
    vectors = np.array([xie_sequence_vector(r) for r in data.recordings])
    y = data.y("property")
    print(f"Xie et al. 2019: {len(data)} simulated 44 x 44 slides, property level")
    line("images -> sequences S_a, S_v, S_s", per_sample(xie_sequences, taxels), "11.5 ms")
    steps = methods.xie_pipeline(methods.xie_classifier("knn", 5, 0), 8).fit(vectors, y)
    line("standardise + 11 features", per_sample(lambda v: steps[:1].transform(v[None]), vectors[:SAMPLES]),
         "4.6 ms")
    paper = {"linear-svm": "0.7", "rbf-svm": "23", "knn": "17", "lda": "0.7", "nb": "1.4", "rf": "2.8",
             "mlp": "3.5"}
    for name in methods.XIE_CLASSIFIERS:
        model = methods.xie_pipeline(methods.xie_classifier(name, 5, 0), 8).fit(vectors, y)
        features = model[:2].transform(vectors)
        rest = model[2:]
        single = per_sample(lambda row, rest=rest: rest.predict(row[None]), features[:SAMPLES])
        line(f"classify, {name} (batch {1e6 * batch_per_row(rest, features):.1f} us/row)", single,
             f"{paper[name]} us", "us")


def bench_chathuranga() -> None:
    data = Dataset.from_recordings("soft", soft3axis_recordings(trials=30))
    cache = methods.ExtractedSets(data)
    _, X, first = methods.palpation_table(data, cache.get("chathuranga4"), 3)
    y = data.y(data.label_level, first)
    model = methods.PairwiseEliminationSVM(palpations=3).fit(X, y)
    by_trial: dict[str, list] = {}
    for recording in data.recordings:
        by_trial.setdefault(methods.trial_of(recording), []).append(recording)
    trials = list(by_trial.values())[:SAMPLES]
    print(f"Chathuranga et al. 2015: {len(y)} simulated trials of 3 palpations, 8 materials")

    def classify(trial: list) -> object:
        row = np.concatenate([list(chathuranga4(r).values()) for r in trial])
        return model.predict(row[None])

    line("features + elimination, 3 palpations", per_sample(classify, trials), "280 us", "us")
    line("  of which the elimination", per_sample(lambda row: model.predict(row[None]), X[:SAMPLES]),
         "8 us per binary SVM", "us")
    periods = cache.get("chathuranga_period").X[first]
    nearest = methods.NearestSpatialPeriod().fit(periods, y)
    line("spatial period: feature + nearest class",
         per_sample(lambda r: nearest.predict([list(chathuranga_period(r[0]).values())]), trials),
         "8 us", "us")


def bench_huang() -> None:
    slides = biotac_recordings(trials=4, motions=["slide_left", "slide_right"])
    data = Dataset.from_recordings("biotac", slides)
    signals = [r.role("vibration") for r in data.recordings[:SAMPLES]]
    print(f"Huang and Wu 2021: {len(data)} simulated BioTac slides of "
          f"{signals[0].n} PAC samples")
    line("huang7 features of one recording", per_sample(huang7, data.recordings[:SAMPLES]),
         "0.47 s per set (MATLAB)")
    line("  reference: numpy rfft of the same signal", per_sample(lambda t: np.fft.rfft(t.data), signals),
         "-")
    X = np.array([list(huang7(r).values()) for r in data.recordings])
    y = data.y(data.label_level)
    for name in methods.HUANG_PAPER:
        model = methods.huang_classifier(name, 0).fit(X, y)
        line(f"classify, {name} (batch {1e6 * batch_per_row(model, X):.1f} us/row)",
             per_sample(lambda row, model=model: model.predict(row[None]), X[:SAMPLES]), "-", "us")


def bench_hoelscher() -> None:
    data = Dataset.from_recordings("biotac", biotac_recordings(trials=4))
    print(f"Hoelscher et al. 2015: {len(data)} simulated BioTac recordings, 5 motions")
    line("mean23 of one recording", per_sample(mean23, data.recordings[:SAMPLES]), "-")
    line("chu of one recording", per_sample(chu, data.recordings[:SAMPLES]), "-")
    X, first = methods.combined_table(data, methods.extract(data, "mean23"), data.motions())
    y = data.y(data.label_level, first)
    model = methods.MotionCombination(methods.hoelscher_features("mean23"),
                                      methods.hoelscher_classifier("linear-svm", 0), 5).fit(X, y)
    line("classify, 5 motions concatenated, linear SVM", per_sample(lambda row: model.predict(row[None]),
                                                                  X[:SAMPLES]), "-", "us")


if __name__ == "__main__":
    for bench in (bench_xie, bench_chathuranga, bench_huang, bench_hoelscher):
        bench()
        print()
