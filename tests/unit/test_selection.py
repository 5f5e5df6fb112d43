"""Feature quality and the FQ selector against hand-derived values and a plain loop over class pairs."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.stats
from sklearn.utils.estimator_checks import parametrize_with_checks

from features.selection import (
    FQSelector,
    PartwiseFQSelector,
    accept_uncorrelated,
    feature_quality,
    select_features,
)
from features.space import FeatureSpace
from taxonomy.errors import ParameterError


def loop_ranks(values: list[float]) -> list[float]:
    """Average 1-based rank of every value, by counting (no library ranking)."""
    ordered = sorted(values)
    ranks = []
    for value in values:
        below = sum(1 for other in ordered if other < value)
        equal = sum(1 for other in ordered if other == value)
        ranks.append(below + (equal + 1) / 2)
    return ranks


def loop_fq(column: list[float], y: list[str]) -> float:
    """docs/evaluation.md written out literally: one class pair at a time, scipy's studentized range per pair."""
    n = len(column)
    ranks = loop_ranks(column)
    ties = [column.count(value) for value in set(column)]
    v = n * (n + 1) / 12 - sum(t**3 - t for t in ties) / (12 * (n - 1))
    classes = sorted(set(y))
    members = {c: [r for r, label in zip(ranks, y, strict=True) if label == c] for c in classes}
    p = []
    for a, b in itertools.combinations(classes, 2):
        mean_a = sum(members[a]) / len(members[a])
        mean_b = sum(members[b]) / len(members[b])
        se = math.sqrt(v * (1 / len(members[a]) + 1 / len(members[b])))
        q = math.sqrt(2) * abs(mean_a - mean_b) / se
        p.append(min(1.0, float(scipy.stats.studentized_range.sf(q, len(classes), np.inf))))
    return 100 * (1 - sum(p) / len(p))


# -- feature quality: closed forms -------------------------------------------------------------------


def two_class_fq(mean_rank_gap: float, v: float, n_a: int, n_b: int) -> float:
    """k = 2: the range of two standard normals is sqrt(2) |Z|, so P(Q > q) = erfc(q / 2)."""
    se = math.sqrt(v * (1 / n_a + 1 / n_b))
    return 100 * (1 - math.erfc(mean_rank_gap / (math.sqrt(2) * se)))


def test_two_separated_pairs_give_the_normal_two_sided_p_value():
    # ranks 1, 2 | 3, 4: mean ranks 1.5 and 3.5, no ties: v = 4 * 5 / 12
    fq = feature_quality([[10.0], [20.0], [30.0], [40.0]], ["a", "a", "b", "b"])
    assert fq[0] == pytest.approx(two_class_fq(2.0, 5 / 3, 2, 2), abs=1e-9)
    assert fq[0] == pytest.approx(87.87, abs=0.005)


def test_two_separated_groups_of_five():
    # mean ranks 3 and 8, v = 10 * 11 / 12
    column = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 2.0, 2.1, 2.2, 2.3, 2.4])
    fq = feature_quality(column[:, None], ["x"] * 5 + ["y"] * 5)
    assert fq[0] == pytest.approx(two_class_fq(5.0, 110 / 12, 5, 5), abs=1e-9)


def test_ties_enter_the_variance_and_the_ranks():
    # values 1, 1 | 2, 3: ranks 1.5, 1.5 | 3, 4; one tie of t = 2: v = 20/12 - (8 - 2)/(12 * 3) = 1.5
    fq = feature_quality([[1.0], [1.0], [2.0], [3.0]], ["a", "a", "b", "b"])
    assert fq[0] == pytest.approx(two_class_fq(2.0, 1.5, 2, 2), abs=1e-9)


def test_identical_groups_have_zero_quality():
    # both classes hold ranks {1.5, 3.5}: equal mean ranks, p = 1 for the only pair
    fq = feature_quality([[1.0], [2.0], [1.0], [2.0]], ["a", "a", "b", "b"])
    assert fq[0] == 0.0


def test_unequal_class_sizes_use_tukey_kramer_standard_error():
    # ranks 1 | 2, 3, 4: mean ranks 1 and 3, v = 5/3, se = sqrt(v (1 + 1/3))
    fq = feature_quality([[0.0], [5.0], [6.0], [7.0]], ["a", "b", "b", "b"])
    assert fq[0] == pytest.approx(two_class_fq(2.0, 5 / 3, 1, 3), abs=1e-9)


def test_three_classes_match_the_pairwise_loop():
    column = [3.0, 1.0, 2.0, 2.0, 7.0, 5.0, 6.0, 9.0, 8.0, 8.0, 4.0, 4.0]
    y = ["a", "a", "a", "a", "b", "b", "b", "b", "c", "c", "c", "c"]
    assert feature_quality(np.array(column)[:, None], y)[0] == pytest.approx(loop_fq(column, y), abs=1e-9)


def test_many_columns_and_classes_match_the_loop():
    rng = np.random.default_rng(3)
    y = [f"c{i}" for i in rng.integers(0, 9, 60)]
    shift = np.array([int(c[1:]) for c in y])[:, None] * [0, 0.5, 1, 2, 0]
    X = np.round(rng.standard_normal((60, 5)) * 2 + shift)
    fq = feature_quality(X, y)
    expected = [loop_fq(X[:, j].tolist(), y) for j in range(X.shape[1])]
    np.testing.assert_allclose(fq, expected, rtol=0, atol=1e-9)


def test_unusable_columns_and_single_class_give_zero():
    X = np.array([[1.0, 4.0, 1.0, np.nan], [2.0, 4.0, 2.0, 2.0], [3.0, 4.0, 3.0, 3.0], [4.0, 4.0, 4.0, 4.0]])
    fq = feature_quality(X, ["a", "a", "b", "b"])
    assert fq[0] > 0 and fq[2] == fq[0]
    assert fq[1] == 0.0 and fq[3] == 0.0
    np.testing.assert_array_equal(feature_quality(X, ["a"] * 4), np.zeros(4))


@pytest.mark.parametrize(("X", "y", "message"), [
    ([1.0, 2.0, 3.0], ["a", "a", "b"], "2-D"),
    ([[1.0], [2.0]], ["a", "b", "c"], "one class per row"),
    ([["x"], ["y"]], ["a", "b"], "numeric"),
])
def test_bad_input_is_named(X, y, message):
    with pytest.raises(ParameterError, match=message):
        feature_quality(X, y)


# -- selector ----------------------------------------------------------------------------------------


def classed_columns(rng: np.random.Generator, n_per_class: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """Four classes; column 0 separates them best, column 1 a little, column 2 is noise."""
    y = np.repeat(np.arange(4), n_per_class)
    noise = rng.standard_normal((y.size, 3))
    X = np.column_stack([y * 3.0 + noise[:, 0] * 0.1, y * 0.5 + noise[:, 1], noise[:, 2]])
    return X, y


def test_duplicated_column_is_never_selected_twice():
    X, y = classed_columns(np.random.default_rng(0))
    X = np.column_stack([X, X[:, 0]])
    selector = FQSelector(n_features=4).fit(X, y)
    assert selector.fq_[3] == selector.fq_[0]
    assert 0 in selector.selected_ and 3 not in selector.selected_


def test_acceptance_order_is_fq_descending_and_correlations_stay_below_the_limit():
    X, y = classed_columns(np.random.default_rng(1))
    selector = FQSelector(n_features=3, max_corr=0.5).fit(X, y)
    fq = selector.fq_[selector.selected_]
    assert list(fq) == sorted(fq, reverse=True)
    for a, b in itertools.combinations(selector.selected_, 2):
        assert abs(scipy.stats.spearmanr(X[:, a], X[:, b]).statistic) < 0.5
    np.testing.assert_array_equal(selector.get_support(), np.isin(np.arange(3), selector.selected_))
    assert list(selector.transform(X).T.tolist()) == [X[:, j].tolist() for j in sorted(selector.selected_)]


def test_equal_fq_is_broken_by_the_lower_column_index():
    # same class mean ranks (so equal FQ), different order inside the classes; rho = 0.524
    first = [4.0, 3.0, 2.0, 1.0, 8.0, 7.0, 6.0, 5.0]
    second = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    y = [0, 0, 0, 0, 1, 1, 1, 1]
    selector = FQSelector(n_features=2, max_corr=0.6).fit(np.column_stack([first, second]), y)
    assert selector.fq_[0] == selector.fq_[1]
    assert selector.selected_.tolist() == [0, 1]
    strict = FQSelector(n_features=2, max_corr=0.5).fit(np.column_stack([second, first]), y)
    assert strict.selected_.tolist() == [0]


def test_nan_and_constant_columns_are_never_selected_so_fewer_may_be_kept():
    X = np.array([[np.nan, 1.0, 0.0], [1.0, 1.0, 1.0], [5.0, 1.0, 2.0], [6.0, 1.0, 3.0]])
    selector = FQSelector(n_features=3).fit(X, [0, 0, 1, 1])
    assert selector.selected_.tolist() == [2]
    assert selector.transform(X).shape == (4, 1)


def test_a_nan_correlation_rejects():
    rho = np.array([[1.0, np.nan, 0.1], [np.nan, 1.0, 0.2], [0.1, 0.2, 1.0]])
    assert accept_uncorrelated([0, 1, 2], rho, n_features=3, max_corr=0.5) == [0, 2]


def test_selection_stops_at_n():
    X, y = classed_columns(np.random.default_rng(2))
    assert FQSelector(n_features=1).fit(X, y).selected_.tolist() == [0]


@pytest.mark.parametrize(("params", "message"), [
    ({"n_features": 0}, "n_features"), ({"n_features": 2.5}, "n_features"),
    ({"max_corr": 0.0}, "max_corr"), ({"max_corr": 1.5}, "max_corr"),
])
def test_bad_parameters_are_named(params, message):
    X, y = classed_columns(np.random.default_rng(0))
    with pytest.raises(ValueError, match=message):
        FQSelector(**params).fit(X, y)


def test_one_class_is_refused():
    with pytest.raises(ValueError, match="at least two classes"):
        FQSelector().fit([[1.0], [2.0]], [0, 0])


def test_partwise_selection_is_fq_selection_within_each_part():
    # Part 0 holds three informative columns, part 1 two weaker ones, the trailing columns (a random-kernel
    # step's output) are part 2: a joint ranking would keep part 0's; each part keeps its own best here.
    rng = np.random.default_rng(4)
    y = np.repeat(np.arange(4), 10)
    X = rng.standard_normal((40, 9))
    X[:, :3] += 3.0 * y[:, None] * np.array([1.0, -1.0, 0.5])
    X[:, 3:5] += 0.8 * y[:, None]
    X[:, 7] += 0.5 * y
    parts = (0, 0, 0, 1, 1)
    selector = PartwiseFQSelector(n_features=2, parts=parts).fit(X, y)
    expected = []
    for columns in (np.arange(0, 3), np.arange(3, 5), np.arange(5, 9)):
        within = FQSelector(n_features=2).fit(X[:, columns], y)
        expected += columns[within.selected_].tolist()
        np.testing.assert_array_equal(selector.fq_[columns], within.fq_)
    assert selector.selected_.tolist() == expected
    assert set(selector.selected_.tolist()) & {5, 6, 7, 8}  # the trailing part keeps its own
    np.testing.assert_array_equal(selector.transform(X), X[:, np.sort(expected)])
    # One part: the joint FQ selection itself.
    one = PartwiseFQSelector(n_features=3, parts=(0,) * 9).fit(X, y)
    assert one.selected_.tolist() == FQSelector(n_features=3).fit(X, y).selected_.tolist()
    with pytest.raises(ValueError, match="10 column parts for 9 columns"):
        PartwiseFQSelector(parts=(0,) * 10).fit(X, y)


@parametrize_with_checks([FQSelector(n_features=2), PartwiseFQSelector(n_features=1)])
def test_scikit_learn_estimator_checks(estimator, check):
    check(estimator)


# -- whole feature space -----------------------------------------------------------------------------


def test_select_features_ranks_every_column_of_a_space():
    X, y = classed_columns(np.random.default_rng(4))
    labels = [f"C{c + 1}S1M1P1X1" for c in y]
    space = FeatureSpace(X, ("other.a", "other.b", "other.c"), tuple(f"s{i}" for i in range(len(y))),
                         tuple(labels), tuple(f"g{i}" for i in range(len(y))))
    selection = select_features(space, level="coarse", n_features=2)
    fq = feature_quality(X, y)
    assert [name for name, _ in selection.ranking][0] == "other.a"
    assert [value for _, value in selection.ranking] == sorted(fq, reverse=True)
    assert selection.selected[0] == "other.a"
    text = selection.format(top=3)
    assert "other.a" in text and "selected" in text
