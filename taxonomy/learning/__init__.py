"""Classification of materials from their features: results (:mod:`.results`), classifiers,
cross-validation and metrics (:mod:`.evaluation`) and trained models in files (:mod:`.models`).

Imported by their own names, since they build on the features.
"""
