"""Feature quality against its slow references: the studentized-range table within its tolerance of SciPy's
numerical integration, and many class pairs through the table equal to the pair-by-pair loop (the system
tests: seconds of SciPy integration each)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
from unit.test_selection import loop_fq

from features.selection import (
    SF_TOLERANCE,
    feature_quality,
    studentized_range_sf,
)


def test_many_pairs_through_the_interpolation_table_match_the_loop():
    # 100 classes of 2 rows: 4950 pairs, enough to take the table path
    rng = np.random.default_rng(5)
    y = [f"m{i // 2}" for i in range(200)]
    column = (np.arange(200) // 2 * 0.05 + rng.standard_normal(200)).round(1)
    fq = feature_quality(column[:, None], y)
    assert fq[0] == pytest.approx(loop_fq(column.tolist(), y), abs=100 * SF_TOLERANCE)


@pytest.mark.parametrize("k", [3, 40, 184])
def test_studentized_range_table_stays_within_tolerance(k):
    rng = np.random.default_rng(k)
    q = np.concatenate([rng.uniform(0, 13, 4000), [0.0, 1e-3, 20.0, 50.0]])
    fast = studentized_range_sf(q, k)
    probe = np.concatenate([rng.choice(q.size, 300, replace=False), np.arange(q.size - 4, q.size)])
    exact = scipy.stats.studentized_range.sf(q[probe], k, np.inf)
    np.testing.assert_allclose(fast[probe], exact, rtol=0, atol=SF_TOLERANCE)
