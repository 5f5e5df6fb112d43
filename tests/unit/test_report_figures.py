"""The figures of an evaluation report agree with its tables: one kind of interval, titles that give the table's
numbers, titles inside their figure."""

from __future__ import annotations

import re

import numpy as np
import pytest
from matplotlib.image import imread

from taxonomy.learning.evaluation import evaluate_grid
from taxonomy.learning.results import Result
from taxonomy.reports.plots import plot_fq_ranking
from taxonomy.reports.report import cell_text, confusion_title, format_table, side_by_side
from unit.test_evaluation import labelled_space

INTERVAL = re.compile(r"\b(\d+\.\d)-(\d+\.\d)\b")


def _bootstrap_text(result: Result) -> str:
    low, high = result.accuracy_ci
    return f"{100 * low:.1f}-{100 * high:.1f}"


def test_every_accuracy_interval_is_the_bootstrap_over_groups_of_the_table():
    space = labelled_space()
    reports = evaluate_grid(space, classifiers=("nb", "lda"), levels=("coarse", "fine"), set_sizes=(3,),
                            feature_sets={"tactum": "tactum", "all": None}, folds=3, workers=1, calibrate=False)
    result = {(r.classifier, r.feature_set, r.level): r for r in reports}
    blocks = side_by_side(reports)
    assert [level for level, _, _ in blocks] == ["coarse", "fine"]
    for level, heads, rows in blocks:
        for feature_set, cells in rows:
            for head, cell in zip(heads, cells, strict=True):
                r = result[(head.split(",")[0], feature_set, level)]
                # "91.2 (87.0-94.3)  0.1 s": the table's accuracy and interval, the same digits
                accuracy, interval = cell.split()[:2]
                assert (accuracy, interval) == (cell_text(r).split()[0], f"({_bootstrap_text(r)})")
    # The text table: every interval in it is a result's bootstrap interval, and every result's is there.
    table = "\n".join(line for line in format_table(reports).splitlines() if line.startswith(("nb", "lda")))
    found = {m.group(0) for m in INTERVAL.finditer(table)}
    assert found == {_bootstrap_text(r) for r in reports}


def _result(confusion: np.ndarray, accuracy: list[float]) -> Result:
    classes = ("C1S1M1P1X1", "C2S1M1P1X1")
    return Result(method="texplorer", feature_set="all", classifier="rf", level="fine", protocol="nested",
                  splitting="2 grouped folds", classes=classes, accuracy=np.array(accuracy),
                  f1=np.ones(len(accuracy)), confusion=confusion, n_samples=int(confusion.sum()), seed=0,
                  n_features=10)


def test_the_confusion_matrix_title_gives_the_accuracy_of_the_table():
    # Folds of 50 and 3 scans, 47 and 3 right: the mean over folds is 97.0 %, the pooled accuracy of the
    # table and of the matrix (its trace over its sum) 50 / 53 = 94.3 %.
    report = _result(np.array([[27, 3], [0, 23]]), [47 / 50, 3 / 3])
    assert report.accuracy_mean == pytest.approx(0.97)
    assert cell_text(report).split()[0] == "94.3"
    # Three misclassifications, all from C1 to C2: r_C = 1.
    assert confusion_title(report) == "fine: rf, all, X10; accuracy 94.3 %, r_C 1.00"


def test_the_fq_title_stays_inside_the_figure(tmp_path):
    # Long feature names (the catch22 family's) leave the axes narrow; the title once ran off the right edge.
    names = [f"catch22.a_fs.SB_MotifThree_quantile_hh_{k:02d}" for k in range(40)]
    ranking = [(name, 90.0 - k) for k, name in enumerate(names)]
    path = plot_fq_ranking(ranking, names[:10:3], tmp_path / "fq.png")
    pixels = imread(path)[:, :, :3]
    edges = np.concatenate([pixels[0], pixels[-1], pixels[:, 0], pixels[:, -1]])
    assert np.all(edges == 1.0)  # nothing drawn on the image's border: white, as the figure's background
