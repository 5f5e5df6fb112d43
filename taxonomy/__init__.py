"""texplorer taxonomy: C/S/M/P/X material labels, the taxonomy table and classification levels (SPEC 9)."""

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
    "Entry", "Label", "LabelError", "LabelNames", "Material", "Taxonomy", "TaxonomyError", "UnknownLabelError",
    "check_level", "format_code", "load_taxonomy", "parse_code", "read_table",
]
