"""``huang``: Huang and Wu's seven band means of the vibration (Huang and Wu 2021), RBF SVM, random forest and kNN,
10-fold CV."""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.ensemble import RandomForestClassifier
from sklearn.neighbors import KNeighborsClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from taxonomy.learning.results import Result
from taxonomy.related.datasets import Dataset, ExtractedSets, slides_first
from taxonomy.related.scoring import kfold_splits, score, scored, usable_rows

HUANG_PAPER = {"svm": "95 +- 2.3 %, 0.47 s features", "rf": "94 +- 2.2 %, 0.47 s features",
               "knn": "94 +- 2.2 %, 0.47 s features"}
"""Huang and Wu Table 4 and section 2.2."""


def huang_classifier(name: str, seed: int) -> BaseEstimator:
    """Huang and Wu's grid-searched classifiers: RBF SVM C = 30, gamma = 0.1; 100 trees; k = 5."""
    return {
        "svm": lambda: Pipeline([("scale", StandardScaler()),
                                 ("classify", SVC(kernel="rbf", C=30.0, gamma=0.1))]),
        "rf": lambda: RandomForestClassifier(n_estimators=100, max_depth=None, random_state=seed, n_jobs=1),
        "knn": lambda: Pipeline([("scale", StandardScaler()),
                                 ("classify", KNeighborsClassifier(n_neighbors=5))]),
    }[name]()


def run_huang(dataset: Dataset, cache: ExtractedSets, seed: int, repeats: int) -> list[Result]:
    """Huang and Wu: seven band means, RBF SVM / random forest / kNN, 10-fold CV at the label level."""
    extracted = cache.get("huang7")
    chosen, motions = slides_first(dataset, range(len(dataset)))
    rows, columns, notes = usable_rows(extracted, chosen)
    X = extracted.X[np.ix_(rows, columns)]
    y = dataset.y(dataset.label_level, rows)
    splits = kfold_splits(y, 10, seed)
    seconds = float(np.nanmedian(extracted.seconds[rows]))
    results = []
    for name in HUANG_PAPER:
        def make(_: int, __: np.ndarray, name: str = name) -> BaseEstimator:
            return huang_classifier(name, seed)
        results.append(scored(score(make, X, y, splits), len(rows), seconds, notes, method="huang",
                              feature_set="huang7", classifier=name, motions=motions, level=dataset.label_level,
                              splitting=f"{len(splits)}-fold CV", seed=seed, paper=HUANG_PAPER[name]))
    return results
