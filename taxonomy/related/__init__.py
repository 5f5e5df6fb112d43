"""The related methods on the same footing: each seed paper's features, classifiers and protocol
(docs/features.md#related).

:func:`compare` runs every method that applies to a :class:`Dataset` (our scans, imported recordings or a
simulated sensor) and returns one :class:`taxonomy.learning.results.Result` per (method, feature set, classifier,
motions, level), the type the project's own evaluation returns too (:func:`taxonomy.learning.results.format_comparison`
prints them as a table): accuracy and macro F1 over the splits of the method's published protocol, and the time per
classification split into feature extraction and the classifier itself.

=============  =========================================================================================
method         features, classifiers and protocol
=============  =========================================================================================
``fishel``     ``fishel3`` on scans (Strese et al. 2020, Fig. 18) with the project's classifiers,
               5-fold CV grouped by sample, coarse, medium and fine levels.
``xie``        ``xie11`` (Xie et al. 2019): sequences standardised on the training rows -> 11 features ->
               standardised -> PCA -> linear SVM (L2 penalty, squared hinge, C = 1), RBF SVM (C = 1),
               kNN (k = 10 at the label level, 5 at coarser levels), LDA (SVD), Gaussian NB, random forest
               (10 trees), MLP 100-50-25-8; the PCA dimension (1..11) is swept with the linear SVM by an
               inner 5-fold CV on the training folds; 5-fold CV; every level of the dataset (Xie's
               property and material levels).
``huang``      ``huang7`` (Huang and Wu 2021): RBF SVM (C = 30, gamma = 0.1), random forest (100 trees, depth not
               limited), kNN (k = 5); 10-fold CV.
``chathuranga``  ``chathuranga4`` (Chathuranga et al. 2015): pairwise RBF SVMs (sigma = 1) keeping the top 50 % of the
               candidates after each of three palpations; baselines: nearest spatial period V / f_p and a
               two-layer net (10 sigmoid units) on friction coefficient, x variance and x kurtosis of
               one palpation; repeated holdout of 1/6 of the trials (the paper: 20 of 120 per class).
``hoelscher``  Hoelscher, Peters and Hermans 2015 (BioTac): ``xu3``, ``chu``, ``mean23`` (PCA to
               8), ``dallaire``, ``chitta``, ``temperature``, each standardised on the training rows, with
               naive Bayes, a full-covariance Gaussian, linear and RBF SVMs (grid search on a 20 %
               validation split of the training rows) and a random forest (100 trees, depth 3); every
               single motion under repeated leave-one-trial-per-object-out splits; the mean features of
               all motions combined by concatenation (linear SVM), voting (linear SVM, Gaussian) and summed
               probabilities (Gaussian); the material-class level and held-out objects.
=============  =========================================================================================

Interpretations (the papers leave them open): features entering an SVM, kNN or net are standardised on
the training rows; Xie's PCA dimension is chosen inside the training folds, not once on all data; the
Gaussian classifier shrinks each class covariance by 10 % towards the identity
(:class:`ShrunkGaussian`), since nine training rows cannot fill an 8x8 covariance; voting ties are broken
by a seeded random choice, as the paper breaks them at random.

Timing: ``feature_seconds`` is the extraction time of the recordings one classification needs (measured
while extracting, plus any feature step inside the fitted pipeline), ``classify_seconds`` the median time
to classify one row with the fitted model (rows timed one at a time, as a deployed classifier sees them).
"""
from taxonomy.related.chathuranga import (
    CHATHURANGA_PAPER,
    NearestSpatialPeriod,
    PairwiseEliminationSVM,
    palpation_table,
    run_chathuranga,
)
from taxonomy.related.compare import (
    METHOD_ROLES,
    METHODS,
    Method,
    MethodComparison,
    applicable,
    compare,
    compare_methods,
    every,
    not_applicable,
)
from taxonomy.related.datasets import (
    REPEATS,
    SEED,
    TIMED_ROWS,
    Dataset,
    Extracted,
    ExtractedSets,
    MethodError,
    MethodSkipped,
    extract,
    motion_of,
    object_of,
    trial_of,
)
from taxonomy.related.fishel import run_fishel
from taxonomy.related.hoelscher import (
    COMBINATIONS,
    HOELSCHER_CLASSIFIERS,
    HOELSCHER_PAPER,
    HOELSCHER_SETS,
    MEAN_DIMENSIONS,
    MotionCombination,
    ShrunkGaussian,
    ValidationSplit,
    combined_table,
    hoelscher_classifier,
    hoelscher_features,
    run_hoelscher,
)
from taxonomy.related.huang import HUANG_PAPER, huang_classifier, run_huang
from taxonomy.related.scoring import (
    Maker,
    Scores,
    Split,
    holdout_splits,
    kfold_splits,
    leave_object_out_splits,
    one_per_object_splits,
    score,
    scored,
    usable_rows,
)
from taxonomy.related.xie import (
    XIE_CLASSIFIERS,
    XIE_MAX_DIMENSIONS,
    XIE_PAPER,
    pca_sweep,
    run_xie,
    slides_first,
    xie_classifier,
    xie_pipeline,
)

__all__ = [
    "applicable", "CHATHURANGA_PAPER", "COMBINATIONS", "combined_table", "compare", "compare_methods",
    "MethodComparison", "Dataset", "every", "extract", "Extracted", "ExtractedSets", "hoelscher_classifier",
    "HOELSCHER_CLASSIFIERS",
    "hoelscher_features", "HOELSCHER_PAPER", "HOELSCHER_SETS", "holdout_splits", "huang_classifier", "HUANG_PAPER",
    "kfold_splits", "leave_object_out_splits", "Maker", "MEAN_DIMENSIONS", "Method", "METHOD_ROLES", "MethodError",
    "METHODS", "MethodSkipped", "motion_of", "MotionCombination", "NearestSpatialPeriod", "not_applicable",
    "object_of", "one_per_object_splits", "PairwiseEliminationSVM", "palpation_table", "pca_sweep", "REPEATS",
    "run_chathuranga", "run_fishel", "run_hoelscher", "run_huang", "run_xie", "score", "scored", "Scores", "SEED",
    "ShrunkGaussian", "slides_first", "Split", "TIMED_ROWS", "trial_of", "usable_rows", "ValidationSplit",
    "xie_classifier", "XIE_CLASSIFIERS", "XIE_MAX_DIMENSIONS", "XIE_PAPER", "xie_pipeline",
]
