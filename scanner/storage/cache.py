"""The feature cache of a scan database: feature vectors keyed by a scan's content hash and the feature code's
version, in the catalog's ``feature_cache`` table (docs/database.md#the-feature-cache)."""

from __future__ import annotations

import json
import math

from scanner.storage.catalog import Catalog, catalog_call


class FeatureCacheTable(Catalog):
    """Feature vectors by content hash and code version (``features.FeatureCache``)."""

    @catalog_call
    def cached_features(self, content_hash: str, code_version: str) -> dict[str, float] | None:
        row = self._conn.execute("SELECT values_json FROM feature_cache WHERE content_hash = ? AND code_version = ?",
                                 (content_hash, code_version)).fetchone()
        if row is None:
            return None
        return {name: (math.nan if value is None else value) for name, value in json.loads(row[0]).items()}

    @catalog_call
    def store_features(self, content_hash: str, code_version: str, values: dict[str, float]) -> None:
        payload = json.dumps({k: (None if math.isnan(v) else v) for k, v in values.items()})
        with self._transaction() as conn:
            conn.execute("INSERT OR REPLACE INTO feature_cache VALUES (?, ?, ?)", (content_hash, code_version, payload))
