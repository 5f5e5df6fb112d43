"""``xie``: Xie et al.'s 11 features of a pressure array (Xie et al. 2019), a PCA swept inside the training folds
and seven classifiers, 5-fold CV."""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.decomposition import PCA
from sklearn.discriminant_analysis import LinearDiscriminantAnalysis
from sklearn.ensemble import RandomForestClassifier
from sklearn.naive_bayes import GaussianNB
from sklearn.neighbors import KNeighborsClassifier
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC, LinearSVC

from taxonomy.learning.results import Result
from taxonomy.related.datasets import Dataset, ExtractedSets, slides_first
from taxonomy.related.scoring import kfold_splits, score, scored, usable_rows
from taxonomy.related.xie_features import XieFeatures

XIE_CLASSIFIERS = ("linear-svm", "rbf-svm", "knn", "lda", "nb", "rf", "mlp")
XIE_PAPER = {
    "property": {"linear-svm": "92.0 %, 4.6 ms + 0.7 us", "rbf-svm": "94.1 %, 4.3 ms + 23 us",
                 "knn": "95.8 %, 4.6 ms + 17 us", "lda": "91.0 %, 4.7 ms + 0.7 us",
                 "nb": "77.4 %, 4.4 ms + 1.4 us",
                 "rf": "90.6 %, 4.8 ms + 2.8 us", "mlp": "94.8 %, 4.5 ms + 3.5 us"},
    "material": {"linear-svm": "84.0 %, 4.9 ms + 1.4 us", "rbf-svm": "85.4 %, 4.6 ms + 49 us",
                 "knn": "85.8 %, 4.9 ms + 212 us", "lda": "80.6 %, 5.0 ms + 1.4 us",
                 "nb": "73.6 %, 4.2 ms + 2.1 us",
                 "rf": "80.2 %, 4.4 ms + 118 us", "mlp": "90.3 %, 4.8 ms + 3.5 us"},
}
"""Xie et al. Tables 4 and 5: accuracy, feature extraction time and classification time per sample."""

XIE_MAX_DIMENSIONS = 11


def xie_classifier(name: str, k: int, seed: int) -> BaseEstimator:
    """One of Xie et al.'s seven classifiers (section 3.5)."""
    return {
        "linear-svm": lambda: LinearSVC(penalty="l2", loss="squared_hinge", C=1.0, random_state=seed),
        "rbf-svm": lambda: SVC(kernel="rbf", C=1.0),
        "knn": lambda: KNeighborsClassifier(n_neighbors=k),
        "lda": lambda: LinearDiscriminantAnalysis(solver="svd"),
        "nb": GaussianNB,
        "rf": lambda: RandomForestClassifier(n_estimators=10, random_state=seed, n_jobs=1),
        "mlp": lambda: MLPClassifier(hidden_layer_sizes=(100, 50, 25, 8), max_iter=1000, random_state=seed),
    }[name]()


def xie_pipeline(classifier: BaseEstimator, dimensions: int) -> Pipeline:
    """Sequence vectors -> standardised sequences -> 11 features -> standardised -> PCA -> classifier."""
    return Pipeline([("features", XieFeatures()), ("scale", StandardScaler()),
                     ("pca", PCA(n_components=dimensions)), ("classify", classifier)])


def pca_sweep(X: np.ndarray, y: np.ndarray, seed: int, folds: int = 5) -> np.ndarray:
    """Mean inner-CV accuracy of the linear SVM for 1..11 principal components (Xie et al. Fig. 4).

    The 11 features of each inner training fold are computed once and shared by every dimension.
    """
    inner = kfold_splits(y, folds, seed)
    most = min(XIE_MAX_DIMENSIONS, *(len(train) for train, _ in inner))
    accuracy = np.zeros(most)
    for train, test in inner:
        features = Pipeline([("features", XieFeatures()), ("scale", StandardScaler())]).fit(X[train])
        F_train, F_test = features.transform(X[train]), features.transform(X[test])
        for d in range(1, most + 1):
            pca = PCA(n_components=d).fit(F_train)
            svm = xie_classifier("linear-svm", 1, seed).fit(pca.transform(F_train), y[train])
            accuracy[d - 1] += np.mean(svm.predict(pca.transform(F_test)) == y[test]) / len(inner)
    return accuracy




def run_xie(dataset: Dataset, cache: ExtractedSets, seed: int, repeats: int) -> list[Result]:
    """Xie et al.: PCA dimension swept per training fold with the linear SVM, then seven classifiers."""
    extracted = cache.get("xie_sequences")
    chosen, motions = slides_first(dataset, range(len(dataset)))
    rows, columns, notes = usable_rows(extracted, chosen)
    X = extracted.X[np.ix_(rows, columns)]
    seconds = float(np.nanmedian(extracted.seconds[rows]))
    results = []
    for level in dataset.levels():
        y = dataset.y(level, rows)
        splits = kfold_splits(y, 5, seed)
        dims = [int(np.argmax(pca_sweep(X[train], y[train], seed)) + 1) for train, _ in splits]
        kind = "property" if level == "property" else "material"
        neighbours = 10 if level == dataset.label_level else 5
        for name in XIE_CLASSIFIERS:
            def make(fold: int, y_train: np.ndarray, name: str = name, dims: list[int] = dims,
                     neighbours: int = neighbours) -> Pipeline:
                # The paper's k, at most the smallest training class (a class of 5 has no 10 neighbours).
                k = min(neighbours, int(np.unique(y_train, return_counts=True)[1].min()))
                return xie_pipeline(xie_classifier(name, k, seed), dims[fold])
            scores = score(make, X, y, splits)
            stages = (f"per sample: images -> sequences {1e3 * seconds:.2f} ms, standardised sequences -> "
                      f"11 features {1e3 * scores.feature_seconds:.2f} ms, PCA + classifier "
                      f"{1e6 * scores.classify_seconds:.0f} us; PCA dimensions per fold {dims}")
            results.append(scored(scores, len(rows), seconds, notes, method="xie", feature_set="xie11",
                                  classifier=name, motions=motions, level=level, splitting=f"{len(splits)}-fold CV",
                                  seed=seed, paper=XIE_PAPER[kind][name], detail=stages))
    return results
