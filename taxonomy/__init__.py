"""texplorer taxonomy: C/S/M/P/X material labels, the taxonomy table and classification levels (docs/taxonomy.md).

This package's surface is the ground layer that every other layer builds on: labels, the taxonomy table
and the project's base error. The learning modules are imported by their own names, since they build on
the features, which build on the scan model, which needs the labels:

- :mod:`taxonomy.learning.evaluation`: classifiers, cross-validation and metrics (``evaluate``, ``evaluate_grid``);
- :mod:`taxonomy.learning.models`: trained models (``train_model``, ``predict_top``);
- :mod:`taxonomy.related`: the related papers' methods (``compare``);
- :mod:`taxonomy.reports.report`, :mod:`taxonomy.reports.plots`: tables, HTML reports and figures.
"""

from taxonomy.errors import ParameterError, TexplorerError
from taxonomy.labels import LEVELS, Label, LabelError, check_level, format_code, parse_code
from taxonomy.table import (
    ENV_VAR,
    KINDS,
    SHIPPED_TABLE,
    Entry,
    LabelNames,
    MaterialChoice,
    Taxonomy,
    TaxonomyError,
    UnknownLabelError,
    load_taxonomy,
    read_table,
)

__all__ = [
    "ENV_VAR", "KINDS", "LEVELS", "SHIPPED_TABLE",
    "Entry", "Label", "LabelError", "LabelNames", "MaterialChoice", "ParameterError", "Taxonomy", "TaxonomyError",
    "TexplorerError", "UnknownLabelError",
    "check_level", "format_code", "load_taxonomy", "parse_code", "read_table",
]
