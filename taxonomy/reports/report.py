"""Evaluation reports (docs/evaluation.md): a text table for the terminal and a self-contained HTML page with plots.

``format_table(reports)`` prints one block per set size and protocol: a row per classifier and feature
set, a column per level, each cell ``accuracy %  95 % interval  macro F1 (pooled)  macro F1 (per fold)
r_C``, then the chance row and the coarse and medium accuracy derived from the fine prediction.
``format_open_set(reports)`` prints the figures of an open-set evaluation.

``write_report(folder, space, reports)`` writes ``index.html`` and its PNG figures into ``folder``. The page
embeds the figures as base64 data, so ``index.html`` alone opens offline; the PNGs beside it are for papers
and slides. Figures: accuracy and F1 per classifier and feature set for every level and set size (paper
Figs. 16-18), the FQ ranking and the Spearman heat map of the features selected on all rows (Table IV's
view), the PCA explained variance (Fig. 15), per-class box plots of the best feature (Fig. 14) and the
confusion matrix of the best classifier at every level, the reliability diagram of every classifier's
calibrated probabilities and, for an open-set evaluation, the rejection score's histograms and ROC. Every
table has one column per figure and sorts by any column (a click on its header); every chart draws chance.
"""

from __future__ import annotations

import base64
import html
import math
import operator
import os
from collections.abc import Mapping, Sequence
from functools import partial
from pathlib import Path

import numpy as np

from features.selection import Selection, select_features
from features.space import FeatureSpace
from scanner.runtime.local import worker_map
from scanner.storage.files import atomic_write_bytes
from taxonomy.labels import LEVELS
from taxonomy.learning.evaluation import MLP_MAX_ITER
from taxonomy.learning.metrics import auroc, bootstrap_interval
from taxonomy.learning.quick import QuickResult
from taxonomy.learning.results import (
    COLUMNS,
    Result,
    best_per_method,
    format_r_c,
    history_words,
    major_class,
    result_notes,
    size_name,
)
from taxonomy.reports.plots import (
    new_figure,
    plot_confusion,
    plot_feature_boxes,
    plot_fq_ranking,
    plot_open_set,
    plot_pca_variance,
    plot_reliability,
    plot_scores,
    plot_spearman,
)

CELL_LEGEND = ("accuracy % of the pooled out-of-fold predictions, its 95 % interval (percentile bootstrap over "
               "the folds' groups, 1000 resamples), macro F1 of the pooled predictions, macro F1 per fold over "
               "the classes present in the fold, r_C (paper eq. 32; - where undefined: no misclassification, "
               "or the coarse level, where every misclassification leaves the major class); chance: accuracy of "
               "always answering the most frequent class, and 1 / K for macro F1")
INTERVAL_SENTENCE = ("Every accuracy interval of this report, in the tables, the side-by-side section and the "
                     "charts, is this bootstrap: the scans of one group (a sample, by default) are not independent "
                     "trials, the groups are, so an interval that counts every scan as a trial (Wilson's) would be "
                     "narrower than the data support.")
F1_SENTENCE = ("Macro F1 is computed once over all out-of-fold predictions pooled (the headline); the per-fold "
               "figure averages each fold's F1 over the classes present in that fold, since a fold grouped by "
               "sample holds only some classes and a class absent from it would otherwise count as F1 0.")
PAGE_STYLE = ("body{font-family:sans-serif;margin:1em auto;max-width:1200px;padding:0 1em;line-height:1.4}"
              ".scroll{overflow-x:auto;max-width:100%;margin-bottom:1.5em}table{border-collapse:collapse}"
              "td,th{border:1px solid #ccc;padding:2px 6px;text-align:left;font-size:0.9em}"
              "td.num{font-family:monospace;text-align:right;white-space:nowrap}"
              "th{background:#f3f3f3;vertical-align:bottom}th[data-sort]{cursor:pointer}"
              "th[data-sort]::after{content:' \\2195';color:#999}tr.chance td{color:#a00;font-style:italic}"
              "nav ul{columns:2;max-width:40em}figure{margin:1.5em 0}img{max-width:100%;height:auto}"
              "figcaption{color:#444}@media(max-width:800px){body{margin:0.5em;padding:0 0.5em}"
              "td,th{padding:2px 3px;font-size:0.8em}nav ul{columns:1}}")
"""The CSS of every texplorer report page: readable at a tablet's 768 px (a wider table scrolls inside its
box, numbers never wrap)."""
SORT_SCRIPT = ("document.querySelectorAll('th[data-sort]').forEach(function(th){th.addEventListener('click',"
               "function(){var table=th.closest('table'),body=table.tBodies[0],k=th.cellIndex,"
               "up=th.dataset.dir!=='asc';th.dataset.dir=up?'asc':'desc';var rows=Array.from(body.rows)"
               ".filter(function(r){return !r.classList.contains('chance')});rows.sort(function(a,b){"
               "var x=a.cells[k].dataset.v||a.cells[k].textContent,y=b.cells[k].dataset.v||b.cells[k].textContent,"
               "p=parseFloat(x),q=parseFloat(y),c=(isNaN(p)||isNaN(q))?x.localeCompare(y):p-q;return up?c:-c});"
               "rows.forEach(function(r){body.insertBefore(r,body.querySelector('tr.chance'))})})})")
"""Sorts a table by the column whose header is clicked (ascending, then descending); the chance row stays
last. Inline, so the page still opens offline as one file."""


def convergence_note(reports: Sequence[Result]) -> str:
    """One sentence on the fits of the paper's MLP that stopped at its L-BFGS iteration limit before
    converging, over every result (``Result.unconverged``); empty when none did.

    The paper's setting makes these stops expected, so the report states them once, with their count,
    instead of a ConvergenceWarning per fit (:func:`taxonomy.learning.evaluation.iteration_limit_stops`).
    """
    stopped = sum(r.unconverged[0] for r in reports)
    if not stopped:
        return ""
    fits = sum(r.unconverged[1] for r in reports)
    return (f"The MLP stopped at the paper's {MLP_MAX_ITER} L-BFGS iterations before converging in {stopped} of "
            f"{fits} fits, as the paper's setting implies; scikit-learn's ConvergenceWarning about it, which "
            "suggests scaling the data, is not repeated per fit: the pipeline scales every feature to [0, 1] "
            "already.")


def _note_lines(reports: Sequence[Result]) -> list[str]:
    note = convergence_note(reports)
    return [f"note: {note}"] if note else []


def _percent(value: float) -> str:
    return "-" if math.isnan(value) else f"{100 * value:.1f}"


def _with_unit(value: float) -> str:
    """A share as ``98.4 %``, or ``-`` where there is none."""
    return "-" if math.isnan(value) else f"{_percent(value)} %"


def _interval(bounds: tuple[float, float], scale: float = 100.0, digits: int = 1) -> str:
    low, high = bounds
    return "-" if math.isnan(low) else f"{scale * low:.{digits}f}-{scale * high:.{digits}f}"


def cell_text(report: Result) -> str:
    """``"90.2  86.0-93.1  0.90  0.91  0.05"``: pooled accuracy in percent, its 95 % interval, macro F1
    pooled and per fold, r_C.

    r_C is NaN where it is undefined (``taxonomy.learning.results.r_c``: no misclassification, or the coarse
    level) and shown as ``-`` then, never as a number.
    """
    return (f"{_percent(report.accuracy_pooled):>5}  {_interval(report.accuracy_ci):>11}  {report.f1_pooled:4.2f}  "
            f"{report.f1_mean:4.2f}  {format_r_c(report.r_c):>4}")


def side_by_side(reports: Sequence[Result]) -> list[tuple[str, list[str], list[tuple[str, list[str]]]]]:
    """Per level: the column heads (classifier, set size) and a row per feature set, each cell the pooled
    out-of-fold accuracy with the 95 % interval of the results table (``Result.accuracy_ci``) and the seconds
    the evaluation took (``"91.2 (87.0-94.3)  12.1 s"``). Empty with a single feature set."""
    if len({r.feature_set for r in reports}) < 2:
        return []
    blocks = []
    for level in _level_order(reports):
        at_level = [r for r in reports if r.level == level]
        heads = list(dict.fromkeys((r.classifier, r.n_features) for r in at_level))
        cell = {(r.feature_set, r.classifier, r.n_features): r for r in at_level}
        rows = []
        for feature_set in dict.fromkeys(r.feature_set for r in at_level):
            found = [cell.get((feature_set, *head)) for head in heads]
            rows.append((feature_set, [_side_cell(r) if r else "" for r in found]))
        blocks.append((level, [f"{c}, {size_name(n)}" for c, n in heads], rows))
    return blocks


def _side_cell(report: Result) -> str:
    seconds = "" if math.isnan(report.seconds) else f"  {report.seconds:.1f} s"
    return f"{_percent(report.accuracy_pooled):>5} ({_interval(report.accuracy_ci)}){seconds}"


def _level_order(reports: Sequence[Result]) -> list[str]:
    """The levels of the reports, coarse to fine: the taxonomy's, then a set's own in the order evaluated."""
    return [level for level in dict.fromkeys([*LEVELS, *(r.level for r in reports)])
            if any(r.level == level for r in reports)]


UNGROUPED_SENTENCE = ("NOT grouped: every row its own group, so windows of one recording are in training "
                      "and test (the protocol of published window-level results; neighbouring windows leak)")


def _block_title(chosen: Sequence[Result]) -> str:
    first = chosen[0]
    unit = first.group_by if first.taxonomy or first.group_by != "sample" else "the set's groups"
    split = (f"grouped by {unit}" if all(r.grouped for r in chosen)
             else f"NOT grouped by {unit}: {'scans of one ' + unit if first.taxonomy else 'a group'} "
                  "in training and test")
    if first.group_by == "none" and not first.taxonomy:
        split = UNGROUPED_SENTENCE
    splits = "the set's train/test split" if first.given_split else f"{first.folds} folds {split}"
    voted = ", recordings voted by their windows" if first.voted else ""
    if first.history:
        voted = f", {history_words(first.history)}"
    return f"{size_name(first.n_features)}, {first.protocol} protocol, {splits}{voted}, seed {first.seed}"


def _block_results(reports: Sequence[Result]) -> list[list[Result]]:
    """The reports per (set size, protocol), in order of appearance."""
    return [[r for r in reports if (r.n_features, r.protocol) == key]
            for key in dict.fromkeys((r.n_features, r.protocol) for r in reports)]


def _blocks(reports: Sequence[Result]) -> list[tuple[str, list[str], list[tuple[str, str, list[str]]]]]:
    """Per (set size, protocol): a title, the levels present, and rows (classifier, feature set, cells)."""
    blocks = []
    for chosen in _block_results(reports):
        levels = _level_order(chosen)
        cell = {(r.classifier, r.feature_set, r.level): r for r in chosen}
        rows = []
        for classifier, feature_set in dict.fromkeys((r.classifier, r.feature_set) for r in chosen):
            found = [cell.get((classifier, feature_set, level)) for level in levels]
            rows.append((classifier, feature_set, [cell_text(r) if r else "" for r in found]))
        blocks.append((_block_title(chosen), levels, rows))
    return blocks


def _chance(chosen: Sequence[Result], level: str) -> Result | None:
    return next((r for r in chosen if r.level == level), None)


def _derived(chosen: Sequence[Result]) -> list[tuple[str, str, list[str]]]:
    """Rows (classifier, feature set, [coarse, medium accuracy %]) of the fine results cut to the coarser
    levels; empty where no fine result of taxonomy codes is there."""
    return [(r.classifier, r.feature_set, [_percent(r.derived_accuracy(level)) for level in ("coarse", "medium")])
            for r in chosen if r.level == "fine" and r.taxonomy and r.y_pred is not None]


def format_table(reports: Sequence[Result]) -> str:
    """The classifier x feature set x level table as text, one block per set size and protocol: a row per
    classifier and feature set, the chance row, then the coarse and medium accuracy of the fine prediction.

    Parameters
    ----------
    reports : sequence of Result
        As :func:`taxonomy.learning.evaluation.evaluate_grid` returns them.

    Returns
    -------
    str
        The table, one block per set size and protocol.
    """
    if not reports:
        return "no results"
    lines = [f"cells: {CELL_LEGEND}", F1_SENTENCE, *_note_lines(reports)]
    for chosen, (title, levels, rows) in zip(_block_results(reports), _blocks(reports), strict=True):
        width_c = max(len("classifier"), *(len(r[0]) for r in rows))
        width_s = max(len("feature set"), *(len(r[1]) for r in rows))
        width = max(len(cell) for row in rows for cell in row[2])
        lines += ["", title,
                  (f"{'classifier':<{width_c}}  {'feature set':<{width_s}}  "
                   + "  ".join(f"{level:<{width}}" for level in levels)).rstrip()]
        for classifier, feature_set, cells in rows:
            lines.append((f"{classifier:<{width_c}}  {feature_set:<{width_s}}  "
                          + "  ".join(f"{cell:<{width}}" for cell in cells)).rstrip())
        chance = [_chance(chosen, level) for level in levels]
        lines.append((f"{'chance':<{width_c + width_s + 2}}  " + "  ".join(
            f"{f'{_percent(r.chance):>5} %, F1 {r.chance_f1:.2f}':<{width}}" for r in chance
            if r is not None)).rstrip())
        derived = _derived(chosen)
        if derived:
            lines.append("accuracy % of the fine prediction cut to coarse / medium (beside the levels trained "
                         "directly above):")
            lines += [f"  {c:<{width_c}}  {fs:<{width_s}}  coarse {a:>5}  medium {b:>5}" for c, fs, (a, b) in derived]
    return "\n".join(lines)


def format_protocols(grouped: Sequence[Result], ungrouped: Sequence[Result]) -> str:
    """The grouped and the ungrouped (``--group-by none``) accuracy of the same cells side by side: how much
    of a window-level figure is leakage between the windows of one recording.

    Parameters
    ----------
    grouped, ungrouped : sequence of Result
        The same grid evaluated with the set's groups and with every row its own group.

    Returns
    -------
    str
        One line per cell (classifier, feature set, level, set size): both pooled accuracies and their
        difference in points.
    """
    other = {(r.classifier, r.feature_set, r.level, r.n_features): r for r in ungrouped}
    rows = [("classifier", "feature set", "level", "features", f"grouped by {_unit(grouped[0])} %",
             "NOT grouped %", "difference")]
    for r in grouped:
        twin = other.get((r.classifier, r.feature_set, r.level, r.n_features))
        if twin is not None:
            rows.append((r.classifier, r.feature_set, r.level, size_name(r.n_features),
                         f"{100 * r.accuracy_pooled:.1f}", f"{100 * twin.accuracy_pooled:.1f}",
                         f"{100 * (twin.accuracy_pooled - r.accuracy_pooled):+.1f} points"))
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    lines = ["side by side: pooled accuracy with the recordings' windows kept together (leakage-free) and "
             "split over the folds (published protocol)"]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in rows]
    return "\n".join(lines)


def _unit(report: Result) -> str:
    return "the set's groups" if report.group_by in ("sample", "the set's groups") else report.group_by


OPEN_SET_COLUMNS = ("classifier", "feature set", "level", "features", "AUROC", "95 % CI", "known accuracy %",
                    "closed-set accuracy %", "unknown rejected %", "chance AUROC")


def _open_set_cells(r: Result) -> list[str]:
    low, high = _auroc_interval(r)
    return [r.classifier, r.feature_set, r.level, size_name(r.n_features), f"{r.auroc:.3f}",
            "-" if math.isnan(low) else f"{low:.3f}-{high:.3f}", _percent(r.known_accuracy),
            _percent(r.closed_accuracy), _percent(r.unknown_rejected), "0.500"]


def _auroc_interval(r: Result) -> tuple[float, float]:
    """95 % bootstrap interval of the AUROC over the test instances' groups (samples)."""
    groups = r.groups if r.groups is not None else np.arange(len(r.open_score)).astype(str)
    def resampled(weights: np.ndarray) -> float:
        rows = np.repeat(np.arange(weights.size), weights.astype(int))
        return auroc(r.open_score[rows], ~r.known[rows])

    return bootstrap_interval(resampled, groups, r.seed)


def format_open_set(reports: Sequence[Result]) -> str:
    """The open-set figures as text: AUROC (chance 0.5) with its interval, the known-class accuracy at the
    learned threshold beside the closed-set accuracy of the same folds, and the share of unknown scans
    rejected."""
    if not reports:
        return "no results"
    rows = [OPEN_SET_COLUMNS[:-1], *(_open_set_cells(r)[:-1] for r in reports)]
    widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
    lines = [f"open set: {reports[0].splitting}; AUROC of known against held-out materials (chance 0.500), "
             f"accuracy on known materials with the rejection rule (a rejected scan counts as wrong) and "
             f"without it, share of held-out materials' scans rejected"]
    lines += ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in rows]
    return "\n".join([*lines, *_note_lines(reports)])


def format_quick(result: QuickResult) -> str:
    """The quick scan's figures as text: per order, the share decided and the accuracy after each number of
    steps and by each time mark, then the one line of :meth:`QuickResult.line`."""
    lines = [f"quick scan, {result.level} level: {result.splitting}; stops at a calibrated {result.stop_at:.2f} with "
             f"the novelty accepted; the full protocol takes {result.full_seconds:.0f} s"]
    for order, title in (("adaptive", "adaptive order (most information per second next)"),
                         ("fixed", "the paper's fixed order")):
        s = result.summary(order)
        lines += ["", f"{title}: median {s['median_steps']:g} steps ({s['median_seconds']:.0f} s), "
                  f"{100 * s['decided']:.1f} % decided, mean time {100 * s['time_share']:.1f} % of the full "
                  f"protocol, {100 * s['accuracy']:.1f} % right (undecided scans answered by the full scan)",
                  "  steps  mean s  decided  right of decided  right now"]
        lines += [f"  {k:>5}  {sec:>6.0f}  {100 * dec:>6.1f} %  {_with_unit(acc):>16}  {100 * now:>7.1f} %"
                  for k, sec, dec, acc, now in result.by_steps(order)]
        lines += ["  by s   decided  right of decided"]
        lines += [f"  {mark:>4.0f}  {100 * dec:>7.1f} %  {_with_unit(acc):>16}"
                  for mark, dec, acc in result.by_seconds(order)]
    unseen = result.unseen()
    if unseen is not None:
        lines += ["", f"held-out materials (a fifth of the materials per fold, never trained on): a quick scan "
                  f"stopped on {100 * unseen['decided']:.1f} % of their {unseen['scans']:.0f} scans, each one named "
                  f"as a trained material (median {unseen['median_steps']:g} steps); the others went on to the "
                  "full scan, whose rule decides whether they are new"]
    lines += [*(f"note: {note}" for note in result.notes), result.line()]
    return "\n".join(lines)


# -- HTML page ---------------------------------------------------------------------------------------


def write_report(folder: str | os.PathLike[str], space: FeatureSpace, reports: Sequence[Result],
                 level: str = "fine", n_features: int = 10, feature: str | None = None, top: int = 30,
                 max_classes: int = 40, workers: int | None = 1) -> Path:
    """Write ``index.html`` and its PNG figures into ``folder``; returns the path of ``index.html``.

    Parameters
    ----------
    space : features.space.FeatureSpace
        The feature space the reports were computed on (for FQ, Spearman, PCA and box plots).
    reports : list of Result
        From ``taxonomy.learning.evaluation.evaluate`` / ``evaluate_grid``; may be empty.
    level, n_features : str, int
        Level and set size of the FQ ranking and Spearman heat map (selection on all rows).
    feature : str, optional
        Feature of the box plots; default the one with the highest FQ.
    top, max_classes : int
        Bars in the FQ chart; classes in the box plot (beyond it only the major class with the most
        classes is shown, as in the paper's Fig. 14) and labelled classes in a confusion matrix.
    workers : int, optional
        Processes drawing the figures (:func:`scanner.runtime.local.worker_map`; None: every core).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    level = space.check_level(level)
    # The signal columns (input of the random-kernel step, docs/modern-features.md) are samples, not features.
    space = space.subset([c for c in space.columns if not c.startswith("signal.")])
    selection = select_features(space, level, n_features)
    plan = _figures(folder, space, reports, selection, level, feature, top, max_classes)
    drawn = dict(worker_map(operator.call, [plot for _, plot in plan], workers))
    figures = [(caption, drawn[k]) for k, (caption, _) in enumerate(plan)]
    page = folder / "index.html"
    atomic_write_bytes(page, _html(space, reports, selection, figures).encode("utf-8"))
    return page


Figure = tuple[str, partial]
"""A figure of the report: its caption, and the plotting call that draws it and returns its file."""


def _figures(folder: Path, space: FeatureSpace, reports: Sequence[Result], selection: Selection, level: str,
             feature: str | None, top: int, max_classes: int) -> list[Figure]:
    """The report's figures in page order: scores per (level, set size), FQ ranking and Spearman heat map,
    PCA, box plots, reliability diagrams, open-set scores, and the best confusion matrix per level."""
    figures: list[Figure] = []
    order = _level_order(reports)
    for lvl, size in sorted(dict.fromkeys((r.level, r.n_features) for r in reports),
                            key=lambda key: (math.inf if key[1] is None else key[1], order.index(key[0]))):
        figures.append((f"{lvl} classification with {size_name(size)}: accuracy and macro F1 per feature set",
                        partial(plot_scores, reports, lvl, size, folder / f"scores_{lvl}_{size_name(size)}.png")))
    figures += _selection_figures(folder, space, selection, top)
    figures.append(("explained variance over the principal components (Fig. 15)",
                    partial(plot_pca_variance, space.X, folder / "pca.png")))
    figures.append(_boxes(folder, space, feature or selection.ranking[0][0], level, max_classes))
    calibrated = _calibration_results(reports)
    if calibrated:
        figures.append(("reliability diagrams of the calibrated probabilities, one per classifier (accuracy "
                        "against confidence per bin; diagonal: calibrated; dashed: chance); ECE in each title",
                        partial(plot_reliability, calibrated, folder / "reliability.png")))
    for k, r in enumerate(x for x in reports if x.open_set):
        figures.append((f"open set, {r.classifier} {r.feature_set} {r.level} {size_name(r.n_features)}: rejection "
                        "score of known and held-out materials, and the ROC curve (dashed: chance)",
                        partial(plot_open_set, r, folder / f"open_set_{k}.png")))
    for lvl in order:
        at_level = [r for r in reports if r.level == lvl]
        if at_level:
            best = max(at_level, key=lambda r: r.accuracy_pooled)
            title = confusion_title(best)
            figures.append((f"confusion matrix of the best classifier at the {lvl} level ({title})",
                            partial(plot_confusion, best.confusion, best.classes, folder / f"confusion_{lvl}.png",
                                    title=title, max_labels=max_classes)))
    return figures


def confusion_title(report: Result) -> str:
    """The title of a result's confusion matrix: what ran, and the pooled accuracy and r_C as the results
    table gives them (the matrix sums the pooled out-of-fold predictions)."""
    r_c = "" if math.isnan(report.r_c) else f", r_C {format_r_c(report.r_c)}"
    return (f"{report.level}: {report.classifier}, {report.feature_set}, {size_name(report.n_features)}; accuracy "
            f"{_percent(report.accuracy_pooled)} %{r_c}")


def _calibrated_share(closed: Sequence[Result]) -> str:
    """Empty when every result is calibrated, else which ones are (texplorer demo calibrates only the results
    of the reliability diagram)."""
    calibrated = sum(r.probability is not None for r in closed)
    if calibrated == len(closed):
        return ""
    return (f" for the {calibrated} of {len(closed)} results with an ECE, those of the reliability diagram "
            "(the others are not calibrated, which leaves their predictions unchanged; texplorer evaluate "
            "calibrates every result)")


def _calibration_results(reports: Sequence[Result]) -> list[Result]:
    """One calibrated result per classifier for the reliability diagram: at the finest level evaluated,
    with every feature ("all") and the larger set size where there, else its most accurate."""
    order = _level_order(reports)
    chosen = []
    for classifier in dict.fromkeys(r.classifier for r in reports):
        mine = [r for r in reports if r.classifier == classifier and r.reliability is not None and not r.open_set]
        if not mine:
            continue
        finest = [r for r in mine if r.level == max((r.level for r in mine), key=order.index)]
        chosen.append(max(finest, key=lambda r: (r.feature_set == "all",
                                                 math.inf if r.n_features is None else r.n_features,
                                                 r.accuracy_pooled)))
    return chosen


def _selection_figures(folder: Path, space: FeatureSpace, selection: Selection, top: int) -> list[Figure]:
    figures = [(f"feature quality FQ at the {selection.level} level; orange: the {len(selection.selected)} "
                f"features FQSelector keeps on all rows (|Spearman rho| < {selection.max_corr:g})",
                partial(plot_fq_ranking, selection.ranking, selection.selected, folder / "fq_ranking.png", top))]
    if len(selection.selected) >= 2:
        figures.append(("Spearman correlation of the selected features",
                        partial(plot_spearman, space.subset(selection.selected).X, selection.selected,
                                folder / "spearman.png")))
    return figures


def _boxes(folder: Path, space: FeatureSpace, feature: str, level: str, max_classes: int) -> Figure:
    """Box plots of ``feature`` per class; too many classes: those of the major class with the most."""
    classes = space.y(level)
    values = space.subset([feature]).X[:, 0]
    scope = ""
    if np.unique(classes).size > max_classes and space.label_level is None:
        majors = np.array([major_class(c) for c in classes])
        names = np.unique(majors)
        counts = [np.unique(classes[majors == m]).size for m in names]
        chosen = names[int(np.argmax(counts))]
        keep = majors == chosen
        classes, values, scope = classes[keep], values[keep], f" within {chosen}"
    return (f"{feature} per class at the {level} level{scope} (Fig. 14)",
            partial(plot_feature_boxes, values, classes, feature, folder / "boxes.png", max_classes=max_classes,
                    title=f"{feature} per {level} class{scope}"))


RESULT_COLUMNS = ("classifier", "feature set", "level", "accuracy %", "95 % CI", "fold mean +- sd",
                  "macro F1", "F1 per fold", "r_C", "from fine %", "ECE", "chance %")
"""The HTML results table: one column per figure (``from fine``: the coarse or medium accuracy of the same
classifier's fine prediction cut to that level)."""


def _td(text: str, value: float | None = None) -> str:
    """A numeric cell; ``value`` sorts it (NaN sorts as text: "-")."""
    e = html.escape
    sort = "" if value is None or math.isnan(value) else f' data-v="{value:.6g}"'
    return f'<td class="num"{sort}>{e(text)}</td>'


def _result_row(r: Result, fine: Result | None) -> str:
    e = html.escape
    derived = fine.derived_accuracy(r.level) if fine is not None and r.level != "fine" else math.nan
    low, high = r.accuracy_ci
    flow, fhigh = r.f1_ci
    cells = [
        _td(_percent(r.accuracy_pooled), r.accuracy_pooled),
        _td(_interval(r.accuracy_ci), low),
        _td(f"{100 * r.accuracy_mean:.1f} +- {100 * r.accuracy_std:.1f}", r.accuracy_mean),
        _td(f"{r.f1_pooled:.2f}" + ("" if math.isnan(flow) else f" ({flow:.2f}-{fhigh:.2f})"), r.f1_pooled),
        _td(f"{r.f1_mean:.2f}", r.f1_mean),
        _td(format_r_c(r.r_c), r.r_c),
        _td(_percent(derived), derived),
        _td("-" if math.isnan(r.ece) else f"{r.ece:.3f}", r.ece),
        _td(_percent(r.chance), r.chance),
    ]
    del high
    return (f"<tr><td>{e(r.classifier)}</td><td>{e(r.feature_set)}</td><td>{e(r.level)}</td>"
            + "".join(cells) + "</tr>")


def _results_table(chosen: Sequence[Result]) -> str:
    e = html.escape
    fine = {(r.classifier, r.feature_set): r for r in chosen if r.level == "fine"}
    order = _level_order(chosen)
    rows = sorted(chosen, key=lambda r: (order.index(r.level),))
    head = "".join(f'<th scope="col" data-sort>{e(c)}</th>' for c in RESULT_COLUMNS)
    body = [_result_row(r, fine.get((r.classifier, r.feature_set))) for r in rows]
    chance = [f'<tr class="chance"><td colspan="3">chance, {e(level)}</td>'
              f'<td class="num">{_percent(r.chance)}</td><td colspan="2"></td>'
              f'<td class="num">{r.chance_f1:.2f}</td><td colspan="4"></td>'
              f'<td class="num">{_percent(r.chance)}</td></tr>'
              for level in order for r in [_chance(chosen, level)] if r is not None]
    return (f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>' + "".join(body + chance)
            + "</tbody></table></div>")


def _open_set_table(reports: Sequence[Result]) -> str:
    e = html.escape
    head = "".join(f'<th scope="col" data-sort>{e(c)}</th>' for c in OPEN_SET_COLUMNS)
    rows = []
    for r in reports:
        cells = _open_set_cells(r)
        rows.append("<tr>" + "".join(f"<td>{e(c)}</td>" for c in cells[:4])
                    + _td(cells[4], r.auroc) + _td(cells[5]) + _td(cells[6], r.known_accuracy)
                    + _td(cells[7], r.closed_accuracy) + _td(cells[8], r.unknown_rejected) + _td(cells[9], 0.5)
                    + "</tr>")
    return (f'<div class="scroll"><table><thead><tr>{head}</tr></thead><tbody>' + "".join(rows)
            + "</tbody></table></div>")


def _html(space: FeatureSpace, reports: Sequence[Result], selection: Selection,
          figures: list[tuple[str, Path]]) -> str:
    e = html.escape
    counts = ", ".join(f"{np.unique(space.y(level)).size} {level}" for level in space.level_names)
    rows, groups = ("scans", "samples") if space.label_level is None else ("recordings", "groups")
    split = (f" (the set's split: {space.split.count('train')} train, {space.split.count('test')} test)"
             if space.split else "")
    closed = [r for r in reports if not r.open_set]
    open_set = [r for r in reports if r.open_set]
    mlp_note = convergence_note(reports)  # stated once, in the protocol section or else under the open set
    blocks = _block_results(closed)
    toc = [(f"results-{k}", _block_title(chosen)) for k, chosen in enumerate(blocks)]
    if open_set:
        toc.append(("open-set", "Open set: unknown materials"))
    if closed:
        toc.append(("protocol", "How the figures were computed"))
    toc.append(("figures", "Figures"))
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        "<title>texplorer evaluation report</title>",
        f"<style>{PAGE_STYLE}</style></head><body>",
        "<h1>texplorer evaluation report</h1>",
        f"<p>{len(space)} {rows}{e(split)}, {len(set(space.groups))} {groups}, {len(space.columns)} features; "
        f"classes: {e(counts)}.</p>",
        f"<p>Selected on all rows at the {e(selection.level)} level: {e(', '.join(selection.selected))}.</p>",
        '<nav aria-label="contents"><h2>Contents</h2><ul>'
        + "".join(f'<li><a href="#{anchor}">{e(title)}</a></li>' for anchor, title in toc) + "</ul></nav>",
    ]
    if closed:
        parts.append(f"<h2>Cross-validated results</h2><p>{e(F1_SENTENCE)} A click on a column's header sorts "
                     "the table by it.</p>")
        for (anchor, title), chosen in zip(toc, blocks, strict=False):
            parts.append(f'<h3 id="{anchor}">{e(title)}</h3>' + _results_table(chosen))
        compared = side_by_side(closed)
        if compared:
            parts.append("<h2>Feature sets side by side</h2><p>Per level, every feature set on the same folds: "
                         "pooled out-of-fold accuracy % (its 95 % interval, the bootstrap over the folds' groups of "
                         "the tables above) and the seconds its folds took (fitting the transform, scaling, "
                         "selection and the classifier, summed over folds).</p>")
            for level, heads, set_rows in compared:
                parts.append(f"<h3>{e(level)}</h3><table><tr><th>feature set</th>"
                             + "".join(f"<th>{e(head)}</th>" for head in heads) + "</tr>")
                for feature_set, cells in set_rows:
                    parts.append(f"<tr><td>{e(feature_set)}</td>" + "".join(f"<td>{e(c)}</td>" for c in cells)
                                 + "</tr>")
                parts.append("</table>")
    if open_set:
        parts.append('<h2 id="open-set">Open set: unknown materials</h2>'
                     f"<p>{e(open_set[0].splitting)}. AUROC: how well the rejection score separates scans of "
                     "held-out materials from scans of trained ones (0.5 is chance, 1 perfect). Known accuracy: "
                     "the trained materials' scans classified right and not rejected, at the threshold each "
                     "fold's model learned inside its training scans; closed-set accuracy: the same scans "
                     "without rejection. Unknown rejected: the share of held-out materials' scans the rule "
                     "calls unknown.</p>" + _open_set_table(open_set))
        if mlp_note and not closed:
            parts.append(f"<p>{e(mlp_note)}</p>")
    if closed:
        grouping = {r.group_by for r in closed}
        splits = {"the set's own train/test split" if r.given_split else
                  f"grouped by {r.group_by}" if r.grouped else "not grouped" for r in closed}
        parts.append(f'<h2 id="protocol">How the figures were computed</h2><p>Folds: {e(", ".join(sorted(splits)))}'
                     f" (groups: {e(', '.join(sorted(grouping)))}). {e(CELL_LEGEND)}. {e(INTERVAL_SENTENCE)} "
                     "Probabilities are calibrated by temperature scaling inside each fold's training rows "
                     "(Guo et al. 2017)"
                     f"{e(_calibrated_share(closed))}; "
                     "ECE: expected calibration error over 10 confidence bins. From fine: the coarse or medium "
                     "accuracy of the fine prediction cut to that level, beside the classifier trained at that "
                     "level directly.</p>")
        if mlp_note:
            parts.append(f"<p>{e(mlp_note)}</p>")
        notes = list(dict.fromkeys(note for r in reports for note in r.notes))
        dropped = sorted({c for r in reports for c in r.dropped})
        if dropped:
            parts.append(f"<p>Left out for NaN values: {e(', '.join(dropped))}.</p>")
        if notes:
            parts.append("<h3>Warnings</h3><ul>" + "".join(f"<li>{e(n)}</li>" for n in notes) + "</ul>")
    parts.append('<h2 id="figures">Figures</h2>')
    parts.extend(_figure_html(caption, path) for caption, path in figures)
    parts.append(f"<script>{SORT_SCRIPT}</script></body></html>")
    return "\n".join(parts)


def _figure_html(caption: str, path: Path) -> str:
    """A figure embedded as base64 PNG data, so the page opens without the files beside it; it links to the
    PNG beside the page, to see a large figure (a fine-level confusion matrix) at full size on a tablet."""
    e = html.escape
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><a href="{e(path.name)}"><img src="data:image/png;base64,{data}" alt="{e(path.name)}"></a>'
            f"<figcaption>{e(caption)} ({e(path.name)}; select the figure for full size)</figcaption></figure>")


# -- comparison of the related methods (docs/features.md#related) ------------------------------------------


def write_comparison(folder: str | os.PathLike[str], results: Sequence[Result], title: str,
                     outcome: Mapping[str, str] | None = None) -> Path:
    """Write the related-methods comparison as ``index.html`` (same page format as :func:`write_report`).

    The page holds what became of every method (``outcome``: ran, or why not), the comparison table
    (:data:`taxonomy.learning.results.COLUMNS`, times per classification), the notes naming their method, an
    accuracy chart of every result and the confusion matrix of each method's best result; the PNGs are
    written beside it and embedded in it. Returns the path of ``index.html``.
    """
    e = html.escape
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    figures = []
    if results:
        chart = _plot_comparison(results, folder / "comparison.png")
        figures.append(("accuracy of every method, feature set, classifier and motion set (mean +- std over "
                        "splits); grey ticks: the most frequent class", chart))
    for best in best_per_method(results):
        caption = (f"{best.method}: {best.feature_set}, {best.classifier}, {best.motions}, {best.level}; "
                   f"accuracy {100 * best.accuracy_mean:.1f} %")
        figures.append((f"confusion matrix of the best {best.method} result ({caption})",
                        plot_confusion(best.confusion, best.classes, folder / f"confusion_{best.method}.png",
                                       title=caption)))
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             "<title>texplorer comparison of related methods</title>",
             f"<style>{PAGE_STYLE}</style></head><body>", "<h1>Related methods on the same footing</h1>",
             f"<p>{e(title)}</p>"]
    if outcome:
        parts.append("<table><tr><th>method</th><th>outcome</th></tr>" + "".join(
            f"<tr><td>{e(name)}</td><td>{e(status)}</td></tr>" for name, status in outcome.items()) + "</table>")
    parts.append("<table><tr>" + "".join(f"<th>{e(c)}</th>" for c in COLUMNS) + "</tr>")
    parts += ["<tr>" + "".join(f"<td>{e(cell)}</td>" for cell in r.cells()) + "</tr>" for r in results]
    parts.append("</table><p>Times per classification: feature extraction in ms, classifier in us (one row "
                 "at a time). Paper: the figure its paper reports for that configuration.</p>")
    notes = result_notes(results)
    details = [f"{r.method} {r.feature_set} {r.classifier}: {r.detail}" for r in results if r.detail]
    for heading, items in (("Notes", notes), ("Details", details)):
        if items:
            parts.append(f"<h3>{heading}</h3><ul>" + "".join(f"<li>{e(i)}</li>" for i in items) + "</ul>")
    parts.append("<h2>Figures</h2>")
    parts.extend(_figure_html(caption, path) for caption, path in figures)
    parts.append("</body></html>")
    page = folder / "index.html"
    atomic_write_bytes(page, "\n".join(parts).encode("utf-8"))
    return page


def _plot_comparison(results: Sequence[Result], path: Path) -> Path:
    """Horizontal accuracy bars, one per result, coloured by method, with the majority-class rate."""
    figure = new_figure(figsize=(10, 1.5 + 0.22 * len(results)), layout="constrained")
    ax = figure.subplots()
    methods = list(dict.fromkeys(r.method for r in results))
    y = np.arange(len(results))[::-1]
    colours = [f"C{methods.index(r.method)}" for r in results]
    ax.barh(y, [100 * r.accuracy_mean for r in results], xerr=[100 * r.accuracy_std for r in results],
            color=colours, error_kw={"elinewidth": 0.8})
    ax.scatter([100 * r.chance for r in results], y, marker="|", color="0.4", s=80, zorder=3)
    labels = [f"{r.method} {r.feature_set} {r.classifier} {r.motions} {r.level}" for r in results]
    ax.set_yticks(y, labels, fontsize=float(np.clip(300 / max(len(results), 1), 5, 9)))
    ax.set_xlim(0, 105)
    ax.set_xlabel("accuracy (%)")
    figure.savefig(os.fspath(path), dpi=90)
    return path
