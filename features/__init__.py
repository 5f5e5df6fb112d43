"""texplorer features: pure functions from a scan to named feature values, and the feature space (docs/features.md).

``extract(scan)`` gives the features of every registered family (:mod:`features.registry`; the paper's 193,
:mod:`features.families`, in the order of docs/features.md); ``extract_many(scans, workers=None)`` builds a
:class:`FeatureSpace` in parallel, where :mod:`scanner.runtime` runs the work. Submodules:
``tactum``, ``image``, ``audio``, ``other``, ``related``, ``selection``, ``space``.
"""

from features import modern  # noqa: F401  (registers the opt-in families)
from features.extraction import (
    WORKER_SERVER_PRELOAD,
    FeatureCache,
    ScanSource,
    code_version,
    extract,
    extract_many,
)
from features.families import NAMES, SOLVER_RTOL
from features.registry import REGISTRY, Family
from features.space import FeatureSpace, FeatureSpaceError

__all__ = ["NAMES", "REGISTRY", "SOLVER_RTOL", "WORKER_SERVER_PRELOAD", "Family", "FeatureCache", "FeatureSpace",
           "FeatureSpaceError", "ScanSource", "code_version", "extract", "extract_many"]
