"""texplorer features: pure functions from a scan to named feature values, and the feature space (docs/features.md).

``extract(scan)`` gives the features of every registered family (:mod:`features.registry`; the paper's 193,
:mod:`features.families`, in the order of docs/features.md); ``extract_many(scans, workers=None)`` builds a
:class:`FeatureSpace` in parallel, on workers kept for its next call (``release_workers()`` ends them; a
:class:`WorkerPool` keeps its own across the calls of a job that extracts in batches; a server that extracts for
many threads at once shares one bounded set, ``share_workers()``). Submodules:
``tactum``, ``image``, ``audio``, ``other``, ``related``, ``selection``, ``space``.
"""

from features import modern  # noqa: F401  (registers the opt-in families)
from features.extraction import (
    FeatureCache,
    ScanSource,
    SharedWorkers,
    WorkerPool,
    code_version,
    end_shared_workers,
    extract,
    extract_many,
    job_workers,
    release_workers,
    share_workers,
    start_workers_from_a_server,
)
from features.families import NAMES, SOLVER_RTOL
from features.registry import REGISTRY, Family
from features.space import FeatureSpace, FeatureSpaceError

__all__ = ["NAMES", "REGISTRY", "SOLVER_RTOL", "Family", "FeatureCache", "FeatureSpace", "FeatureSpaceError",
           "ScanSource", "SharedWorkers", "WorkerPool", "code_version", "end_shared_workers", "extract", "extract_many",
           "job_workers", "release_workers", "share_workers",
           "start_workers_from_a_server"]
