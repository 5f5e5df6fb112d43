"""Cross-validation, metrics and reports of ``taxonomy.learning.evaluation`` on small synthetic feature spaces:
the system tests (worker processes and cross-validation of every classifier)."""

from __future__ import annotations

import html
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
from sklearn.metrics import confusion_matrix, f1_score
from sklearn.model_selection import cross_val_predict
from unit.test_evaluation import labelled_space

from taxonomy.learning.evaluation import (
    CLASSIFIERS,
    cv_splits,
    evaluate,
    evaluate_grid,
    make_pipeline,
)
from taxonomy.reports.report import write_report


@pytest.mark.parametrize("classifier", list(CLASSIFIERS))
def test_report_numbers_equal_a_direct_cross_val_predict(classifier):
    space = labelled_space()
    y = space.y("fine")
    report = evaluate(space, classifier, level="fine", n_features=3, folds=4, seed=2)
    splits, grouped = cv_splits(y, space.groups, folds=4, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predicted = cross_val_predict(make_pipeline(classifier, 3, seed=2), space.X, y, cv=splits)
    np.testing.assert_array_equal(report.y_pred, predicted)
    accuracy = [np.mean(predicted[test] == y[test]) for _, test in splits]
    # Per fold: macro F1 over the classes present in the fold's true labels; the headline pools every fold.
    f1 = [f1_score(y[test], predicted[test], labels=np.unique(y[test]), average="macro", zero_division=0)
          for _, test in splits]
    np.testing.assert_allclose(report.accuracy, accuracy)
    np.testing.assert_allclose(report.f1, f1)
    assert report.f1_pooled == pytest.approx(f1_score(y, predicted, average="macro"))
    assert report.accuracy_mean == pytest.approx(np.mean(accuracy))
    assert report.accuracy_std == pytest.approx(np.std(accuracy, ddof=1))
    classes = sorted(set(y))
    assert list(report.classes) == classes
    np.testing.assert_array_equal(report.confusion, confusion_matrix(y, predicted, labels=classes))
    assert report.grouped == grouped and report.folds == 4 and report.seed == 2


def test_reruns_are_identical():
    space = labelled_space()
    first = evaluate(space, "rf", level="fine", n_features=3, folds=3, seed=5)
    second = evaluate(space, "rf", level="fine", n_features=3, folds=3, seed=5)
    np.testing.assert_array_equal(first.y_pred, second.y_pred)
    assert first.to_dict() == second.to_dict()


def test_grid_in_worker_processes_equals_single_evaluations():
    space = labelled_space()
    sets = {"tactum": "tactum", "all": None}
    reports = evaluate_grid(space, classifiers=("lda", "nb"), levels=("coarse", "fine"), set_sizes=(2,),
                            feature_sets=sets, folds=3, seed=4, workers=2)
    keys = [(r.classifier, r.feature_set, r.level) for r in reports]
    assert keys == [(c, s, level) for c in ("lda", "nb") for s in sets for level in ("coarse", "fine")]
    for report in reports:
        single = evaluate(space, report.classifier, report.level, 2, folds=3, seed=4,
                          feature_set=sets[report.feature_set])
        np.testing.assert_array_equal(report.y_pred, single.y_pred)
        assert report.selected == single.selected


def test_report_figures_drawn_by_worker_processes_equal_those_drawn_here(tmp_path):
    space = labelled_space()
    reports = evaluate_grid(space, classifiers=("nb", "lda"), levels=("coarse", "medium"), set_sizes=(3,),
                            feature_sets={"image": "image", "all": None}, folds=3, workers=1)
    here = write_report(tmp_path / "here", space, reports, level="medium", n_features=3, workers=1)
    there = write_report(tmp_path / "there", space, reports, level="medium", n_features=3, workers=2)
    names = sorted(p.name for p in here.parent.iterdir())
    assert names == sorted(p.name for p in there.parent.iterdir()) and len(names) == 10
    for name in names:
        assert (here.parent / name).read_bytes() == (there.parent / name).read_bytes(), name


def test_html_report_is_one_offline_folder(tmp_path):
    space = labelled_space()
    reports = evaluate_grid(space, classifiers=("nb", "lda"), levels=("coarse", "medium"), set_sizes=(3,),
                            feature_sets={"image": "image", "all": None}, folds=3, workers=1)
    page = write_report(tmp_path / "report", space, reports, level="medium", n_features=3)
    names = sorted(p.name for p in page.parent.iterdir())
    assert names == ["boxes.png", "confusion_coarse.png", "confusion_medium.png", "fq_ranking.png", "index.html",
                     "pca.png", "reliability.png", "scores_coarse_X3.png", "scores_medium_X3.png", "spearman.png"]
    text = page.read_text(encoding="utf-8")
    assert text.count('src="data:image/png;base64,') == 9
    # Offline: nothing fetched; the one script is the inline sorter of the tables.
    assert "http" not in text and "<link" not in text and text.count("<script") == 1 and "<script src" not in text
    # One column per figure, every header sortable; a chance row per level.
    assert text.count('<th scope="col" data-sort>accuracy %</th>') == 1
    first = reports[0]
    assert f'<td class="num" data-v="{first.accuracy_pooled:.6g}">{100 * first.accuracy_pooled:.1f}</td>' in text
    assert '<tr class="chance"><td colspan="3">chance, coarse</td>' in text and 'href="#results-0"' in text
    coarse_rows = re.findall(r"<tr><td>\w+</td><td>\w+</td><td>coarse</td>(.*?)</tr>", text)
    assert len(coarse_rows) == 4 and all('<td class="num">-</td>' in row for row in coarse_rows)  # r_C
    words = re.sub(r'src="data:image/png;base64,[^"]*"|<script>.*?</script>', "", text, flags=re.S)
    assert "nan" not in words.lower() and "r_C" not in words.split("coarse level (", 1)[1].split(")", 1)[0]


def test_a_cli_report_states_the_mlp_stops_once_and_its_figures_agree(tmp_path):
    # 16 materials: the paper's MLP stops at its 200 L-BFGS iterations in some fits (tests/unit/test_evaluation.py).
    table = labelled_space(materials=16).to_csv(tmp_path / "features.csv")
    run = subprocess.run([sys.executable, "-m", "scanner.cli", "evaluate", "--db", str(tmp_path / "db"), "--features",
                          str(table), "--classifier", "mlp", "nb", "--level", "fine", "--n", "3", "--feature-set",
                          "tactum", "audio", "--folds", "3", "--workers", "1", "--report", str(tmp_path / "r")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "ConvergenceWarning" not in run.stderr
    [note] = [line for line in run.stdout.splitlines() if "L-BFGS" in line]
    assert re.fullmatch(r"note: The MLP stopped at the paper's 200 L-BFGS iterations before converging in \d+ of "
                        r"\d+ fits, .*", note)
    page = (tmp_path / "r" / "index.html").read_text(encoding="utf-8")
    words = html.unescape(re.sub(r'src="data:image/png;base64,[^"]*"', "", page))
    assert words.count("L-BFGS") == 1 and note.removeprefix("note: ") in words
    # The results table: accuracy and 95 % interval per (classifier, feature set, level).
    cells = {row[:3]: row[3:] for row in re.findall(
        r'<tr><td>(\w+)</td><td>(\w+)</td><td>(\w+)</td><td class="num"[^>]*>([\d.]+)</td>'
        r'<td class="num"[^>]*>([\d.]+-[\d.]+)</td>', words)}
    assert len(cells) == 4
    # Side by side: the same accuracy and interval, the one kind of interval of the report.
    heads = re.findall(r"<th>(\w+), X3</th>", words)
    side = re.findall(r"<tr><td>(\w+)</td>((?:<td>[^<]*</td>)+)</tr>", words.split("Feature sets side by side")[1])
    assert heads == ["mlp", "nb"] and [s for s, _ in side] == ["tactum", "audio"]
    for feature_set, row in side:
        for classifier, cell in zip(heads, re.findall(r"<td>([^<]*)</td>", row), strict=True):
            accuracy, interval = cells[(classifier, feature_set, "fine")]
            assert cell.split()[:2] == [accuracy, f"({interval})"]
    assert "Wilson interval" not in words
    # The confusion matrix's title: the table's accuracy of the result it shows, to the decimal.
    shown = re.search(r"confusion matrix of the best classifier at the fine level \(fine: (\w+), (\w+), X3; "
                      r"accuracy ([\d.]+) %", words)
    assert shown.group(3) == cells[(shown.group(1), shown.group(2), "fine")][0]
    assert float(shown.group(3)) == max(float(accuracy) for accuracy, _ in cells.values())
