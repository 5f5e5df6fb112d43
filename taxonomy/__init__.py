"""texplorer taxonomy: C/S/M/P/X material labels, the taxonomy table and classification levels (SPEC 9)."""

import importlib

from taxonomy.errors import TexplorerError
from taxonomy.labels import LEVELS, Label, LabelError, check_level, format_code, parse_code
from taxonomy.table import (
    ENV_VAR,
    KINDS,
    SHIPPED_TABLE,
    Entry,
    LabelNames,
    Material,
    Taxonomy,
    TaxonomyError,
    UnknownLabelError,
    load_taxonomy,
    read_table,
)

__all__ = [
    "ENV_VAR", "KINDS", "LEVELS", "SHIPPED_TABLE",
    "Entry", "Label", "LabelError", "LabelNames", "Material", "Taxonomy", "TaxonomyError", "TexplorerError",
    "UnknownLabelError",
    "check_level", "format_code", "load_taxonomy", "parse_code", "read_table",
    "CLASSIFIERS", "EvaluationError", "Report", "evaluate", "evaluate_grid", "make_pipeline", "r_c",
    "ModelError", "TrainedModel", "load_model", "predict_top", "save_model", "train_model",
]

_LAZY = {
    **dict.fromkeys(("CLASSIFIERS", "EvaluationError", "Report", "evaluate", "evaluate_grid", "make_pipeline",
                     "r_c"), "taxonomy.evaluation"),
    **dict.fromkeys(("ModelError", "TrainedModel", "load_model", "predict_top", "save_model", "train_model"),
                    "taxonomy.models"),
}


def __getattr__(name: str) -> object:
    # scikit-learn and skops take seconds to import; ``import scanner`` (which needs the labels) stays fast.
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'taxonomy' has no attribute {name!r}")
