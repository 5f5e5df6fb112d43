"""texplorer features: pure functions from a scan to named feature values, and the feature space (SPEC 7, 8).

``extract(scan)`` gives the 193 features in SPEC order; ``extract_many(scans, workers=None)`` builds a
:class:`FeatureSpace` in parallel. Submodules: ``tactum``, ``image``, ``audio``, ``other``, ``space``.
"""

from features.extraction import NAMES, SOLVER_RTOL, FeatureCache, ScanSource, code_version, extract, extract_many
from features.space import MODALITIES, FeatureSpace, FeatureSpaceError

__all__ = ["MODALITIES", "NAMES", "SOLVER_RTOL", "FeatureCache", "FeatureSpace", "FeatureSpaceError", "ScanSource",
           "code_version", "extract", "extract_many"]
