"""``fishel``: the ``fishel3`` features on scans (Strese et al. 2020, Fig. 18) with the project's six
classifiers, 5-fold CV grouped by sample, at the coarse, medium and fine levels."""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import MinMaxScaler

from taxonomy.learning.evaluation import classifier_estimators, cv_splits
from taxonomy.learning.results import Result, warning_notes
from taxonomy.related.datasets import Dataset, ExtractedSets, object_of
from taxonomy.related.scoring import score, scored, usable_rows


def run_fishel(dataset: Dataset, cache: ExtractedSets, seed: int, repeats: int) -> list[Result]:
    """``fishel3`` with the project's classifiers, 5-fold CV grouped by sample (fewer folds when a class
    has fewer scans), every taxonomy level."""
    extracted = cache.get("fishel3")
    rows, columns, notes = usable_rows(extracted, range(len(dataset)))
    X = extracted.X[np.ix_(rows, columns)]
    groups = [object_of(dataset.recordings[i]) for i in rows]
    # The fine labels decide the grouping, so every level is split alike (as
    # taxonomy.learning.evaluation.evaluate does).
    fine = dataset.y(dataset.label_level, rows)
    folds = max(2, min(5, int(np.unique(fine, return_counts=True)[1].min())))
    results = []
    for level in dataset.levels():
        y = dataset.y(level, rows)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            splits, grouped = cv_splits(y, groups, folds, seed, grouping_labels=fine)
        splitting = f"{len(splits)}-fold CV{' by sample' if grouped else ''}"
        for name in classifier_estimators(seed):
            def make(_: int, __: np.ndarray, name: str = name) -> Pipeline:
                return Pipeline([("scale", MinMaxScaler()),
                                 ("classify", _without_probability(classifier_estimators(seed)[name]))])
            seconds = float(np.nanmedian(extracted.seconds[rows]))
            results.append(scored(score(make, X, y, splits), len(rows), seconds,
                                  [*notes, *warning_notes(caught)], method="fishel", feature_set="fishel3",
                                  classifier=name, motions="tool slide + friction", level=level,
                                  splitting=splitting, seed=seed))
    return results


def _without_probability(classifier: BaseEstimator) -> BaseEstimator:
    """The classifier without Platt scaling (the SVM's ``probability``): predictions do not use it, it
    costs an internal 5-fold fit, and scikit-learn 1.9 deprecates the argument."""
    params = classifier.get_params(deep=False)
    if "probability" not in params:
        return classifier
    del params["probability"]
    return type(classifier)(**params)
