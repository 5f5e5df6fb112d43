"""Evaluation reports (docs/evaluation.md): a text table for the terminal and a self-contained HTML page with plots.

``format_table(reports)`` prints one block per set size and protocol: a row per classifier and feature
set, a column per level, each cell ``accuracy % (mean +- std over folds)  macro F1  r_C``.

``write_report(folder, space, reports)`` writes ``index.html`` and its PNG figures into ``folder``. The page
embeds the figures as base64 data, so ``index.html`` alone opens offline; the PNGs beside it are for papers
and slides. Figures: accuracy and F1 per classifier and feature set for every level and set size (paper
Figs. 16-18), the FQ ranking and the Spearman heat map of the features selected on all rows (Table IV's
view), the PCA explained variance (Fig. 15), per-class box plots of the best feature (Fig. 14) and the
confusion matrix of the best classifier at every level.
"""

from __future__ import annotations

import base64
import html
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from features.selection import Selection, select_features
from features.space import FeatureSpace
from scanner.storage.files import atomic_write_bytes
from taxonomy.labels import LEVELS
from taxonomy.learning.results import COLUMNS, Result, best_per_method, format_r_c, major_class, result_notes, size_name
from taxonomy.reports.plots import (
    plot_confusion,
    plot_feature_boxes,
    plot_fq_ranking,
    plot_pca_variance,
    plot_scores,
    plot_spearman,
)

CELL_LEGEND = ("accuracy % (mean +- std over folds), macro F1, r_C (paper eq. 32; - where undefined: no "
               "misclassification, or the coarse level, where every misclassification leaves the major class)")
PAGE_STYLE = ("body{font-family:sans-serif;margin:2em;max-width:1200px}table{border-collapse:collapse;"
              "margin-bottom:1.5em;display:block;overflow-x:auto;max-width:100%}"
              "td,th{border:1px solid #ccc;padding:2px 8px;font-family:monospace;"
              "white-space:pre;text-align:left}figure{margin:1.5em 0}img{max-width:100%}"
              "figcaption{color:#444}")
"""The CSS of every texplorer report page; a wide table scrolls inside the page (a tablet's 800 px)."""


def cell_text(report: Result) -> str:
    """``"90.2 +- 1.2  0.90  0.05"``: accuracy in percent, macro F1 and r_C.

    r_C is NaN where it is undefined (``taxonomy.learning.results.r_c``: no misclassification, or the coarse
    level) and shown as ``-`` then, never as a number.
    """
    return (f"{100 * report.accuracy_mean:5.1f} +- {100 * report.accuracy_std:4.1f}  {report.f1_mean:4.2f}  "
            f"{format_r_c(report.r_c):>4}")


WILSON_Z = 1.959963984540054
"""The 97.5 % quantile of the standard normal: a two-sided 95 % interval."""


def wilson_interval(correct: int, total: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of a proportion ``correct / total`` (Wilson 1927): the interval of
    the out-of-fold accuracy, every classified row one trial."""
    if total <= 0:
        return math.nan, math.nan
    p, z2 = correct / total, WILSON_Z**2
    centre = (p + z2 / (2 * total)) / (1 + z2 / total)
    half = WILSON_Z * math.sqrt(p * (1 - p) / total + z2 / (4 * total**2)) / (1 + z2 / total)
    return max(0.0, centre - half), min(1.0, centre + half)


def side_by_side(reports: Sequence[Result]) -> list[tuple[str, list[str], list[tuple[str, list[str]]]]]:
    """Per level: the column heads (classifier, set size) and a row per feature set, each cell the pooled
    out-of-fold accuracy with its 95 % interval and the seconds the evaluation took
    (``"91.2 [87.0, 94.3]  12.1 s"``). Empty with a single feature set."""
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
    tested = report.confusion.sum()
    low, high = wilson_interval(int(np.trace(report.confusion)), int(tested))
    seconds = "" if math.isnan(report.seconds) else f"  {report.seconds:.1f} s"
    return f"{100 * np.trace(report.confusion) / max(tested, 1):5.1f} [{100 * low:.1f}, {100 * high:.1f}]{seconds}"


def _level_order(reports: Sequence[Result]) -> list[str]:
    """The levels of the reports, coarse to fine: the taxonomy's, then a set's own in the order evaluated."""
    return [level for level in dict.fromkeys([*LEVELS, *(r.level for r in reports)])
            if any(r.level == level for r in reports)]


def _blocks(reports: Sequence[Result]) -> list[tuple[str, list[str], list[tuple[str, str, list[str]]]]]:
    """Per (set size, protocol): a title, the levels present, and rows (classifier, feature set, cells)."""
    blocks = []
    for size, protocol in dict.fromkeys((r.n_features, r.protocol) for r in reports):
        chosen = [r for r in reports if r.n_features == size and r.protocol == protocol]
        levels = _level_order(chosen)
        cell = {(r.classifier, r.feature_set, r.level): r for r in chosen}
        rows = []
        for classifier, feature_set in dict.fromkeys((r.classifier, r.feature_set) for r in chosen):
            found = [cell.get((classifier, feature_set, level)) for level in levels]
            rows.append((classifier, feature_set, [cell_text(r) if r else "" for r in found]))
        first = chosen[0]
        unit = "sample" if first.taxonomy else "the set's groups"
        split = (f"grouped by {unit}" if all(r.grouped for r in chosen)
                 else f"NOT grouped by {unit}: {'scans of one sample' if first.taxonomy else 'a group'} "
                      "in training and test")
        splits = "the set's train/test split" if first.given_split else f"{first.folds} folds {split}"
        title = f"{size_name(size)}, {protocol} protocol, {splits}, seed {first.seed}"
        blocks.append((title, levels, rows))
    return blocks


def format_table(reports: Sequence[Result]) -> str:
    """The classifier x feature set x level table as text, one block per set size and protocol.

    Parameters
    ----------
    reports : sequence of Result
        As :func:`taxonomy.learning.evaluation.evaluate_grid` returns them.

    Returns
    -------
    str
        Accuracy mean +- std (%), macro F1 and r_C per cell; ``-`` where r_C is undefined.
    """
    if not reports:
        return "no results"
    lines = [f"cells: {CELL_LEGEND}"]
    for title, levels, rows in _blocks(reports):
        width_c = max(len("classifier"), *(len(r[0]) for r in rows))
        width_s = max(len("feature set"), *(len(r[1]) for r in rows))
        width = max(len(cell) for row in rows for cell in row[2])
        lines += ["", title,
                  (f"{'classifier':<{width_c}}  {'feature set':<{width_s}}  "
                   + "  ".join(f"{level:<{width}}" for level in levels)).rstrip()]
        for classifier, feature_set, cells in rows:
            lines.append((f"{classifier:<{width_c}}  {feature_set:<{width_s}}  "
                          + "  ".join(f"{cell:<{width}}" for cell in cells)).rstrip())
    return "\n".join(lines)


# -- HTML page ---------------------------------------------------------------------------------------


def write_report(folder: str | os.PathLike[str], space: FeatureSpace, reports: Sequence[Result],
                 level: str = "fine", n_features: int = 10, feature: str | None = None, top: int = 30,
                 max_classes: int = 40) -> Path:
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
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    figures: list[tuple[str, Path]] = []
    order = _level_order(reports)
    for lvl, size in sorted(dict.fromkeys((r.level, r.n_features) for r in reports),
                            key=lambda key: (math.inf if key[1] is None else key[1], order.index(key[0]))):
        figures.append((f"{lvl} classification with {size_name(size)}: accuracy and macro F1 per feature set",
                        plot_scores(reports, lvl, size, folder / f"scores_{lvl}_{size_name(size)}.png")))
    level = space.check_level(level)
    # The signal columns (input of the random-kernel step, docs/modern-features.md) are samples, not features.
    space = space.subset([c for c in space.columns if not c.startswith("signal.")])
    selection = select_features(space, level, n_features)
    figures += _selection_figures(folder, space, selection, top)
    figures.append(("explained variance over the principal components (Fig. 15)",
                    plot_pca_variance(space.X, folder / "pca.png")))
    feature = feature or selection.ranking[0][0]
    figures.append(_boxes(folder, space, feature, level, max_classes))
    for lvl in order:
        at_level = [r for r in reports if r.level == lvl]
        if at_level:
            best = max(at_level, key=lambda r: r.accuracy_mean)
            r_c = "" if math.isnan(best.r_c) else f", r_C {best.r_c:.2f}"
            title = (f"{lvl}: {best.classifier}, {best.feature_set}, {size_name(best.n_features)}; accuracy "
                     f"{100 * best.accuracy_mean:.1f} %{r_c}")
            figures.append((f"confusion matrix of the best classifier at the {lvl} level ({title})",
                            plot_confusion(best.confusion, best.classes, folder / f"confusion_{lvl}.png",
                                           title=title, max_labels=max_classes)))
    page = folder / "index.html"
    atomic_write_bytes(page, _html(space, reports, selection, figures).encode("utf-8"))
    return page


def _selection_figures(folder: Path, space: FeatureSpace, selection: Selection,
                       top: int) -> list[tuple[str, Path]]:
    figures = [(f"feature quality FQ at the {selection.level} level; orange: the {len(selection.selected)} "
                f"features FQSelector keeps on all rows (|Spearman rho| < {selection.max_corr:g})",
                plot_fq_ranking(selection.ranking, selection.selected, folder / "fq_ranking.png", top))]
    if len(selection.selected) >= 2:
        figures.append(("Spearman correlation of the selected features",
                        plot_spearman(space.subset(selection.selected).X, selection.selected,
                                      folder / "spearman.png")))
    return figures


def _boxes(folder: Path, space: FeatureSpace, feature: str, level: str,
           max_classes: int) -> tuple[str, Path]:
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
    path = plot_feature_boxes(values, classes, feature, folder / "boxes.png", max_classes=max_classes,
                              title=f"{feature} per {level} class{scope}")
    return f"{feature} per class at the {level} level{scope} (Fig. 14)", path


def _html(space: FeatureSpace, reports: Sequence[Result], selection: Selection,
          figures: list[tuple[str, Path]]) -> str:
    e = html.escape
    counts = ", ".join(f"{np.unique(space.y(level)).size} {level}" for level in space.level_names)
    rows, groups = ("scans", "samples") if space.label_level is None else ("recordings", "groups")
    split = (f" (the set's split: {space.split.count('train')} train, {space.split.count('test')} test)"
             if space.split else "")
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        "<title>texplorer evaluation report</title>",
        f"<style>{PAGE_STYLE}</style></head><body>",
        "<h1>texplorer evaluation report</h1>",
        f"<p>{len(space)} {rows}{e(split)}, {len(set(space.groups))} {groups}, {len(space.columns)} features; "
        f"classes: {e(counts)}.</p>",
        f"<p>Selected on all rows at the {e(selection.level)} level: {e(', '.join(selection.selected))}.</p>",
    ]
    if reports:
        parts.append(f"<h2>Cross-validated results</h2><p>Cells: {e(CELL_LEGEND)}.</p>")
        for title, levels, rows in _blocks(reports):
            parts.append(f"<h3>{e(title)}</h3><table><tr><th>classifier</th><th>feature set</th>"
                         + "".join(f"<th>{e(level)}</th>" for level in levels) + "</tr>")
            for classifier, feature_set, cells in rows:
                parts.append(f"<tr><td>{e(classifier)}</td><td>{e(feature_set)}</td>"
                             + "".join(f"<td>{e(cell)}</td>" for cell in cells) + "</tr>")
            parts.append("</table>")
        compared = side_by_side(reports)
        if compared:
            parts.append("<h2>Feature sets side by side</h2><p>Per level, every feature set on the same folds: "
                         "out-of-fold accuracy % [95 % Wilson interval] and the seconds its folds took (fitting "
                         "the transform, scaling, selection and the classifier, summed over folds).</p>")
            for level, heads, set_rows in compared:
                parts.append(f"<h3>{e(level)}</h3><table><tr><th>feature set</th>"
                             + "".join(f"<th>{e(head)}</th>" for head in heads) + "</tr>")
                for feature_set, cells in set_rows:
                    parts.append(f"<tr><td>{e(feature_set)}</td>" + "".join(f"<td>{e(c)}</td>" for c in cells)
                                 + "</tr>")
                parts.append("</table>")
        grouping = "grouped by sample" if space.label_level is None else "grouped by the set's groups"
        splits = {"the set's own train/test split" if r.given_split else
                  grouping if r.grouped else "not grouped" for r in reports}
        parts.append(f"<p>Folds: {e(', '.join(sorted(splits)))}.</p>")
        notes = list(dict.fromkeys(note for r in reports for note in r.notes))
        dropped = sorted({c for r in reports for c in r.dropped})
        if dropped:
            parts.append(f"<p>Left out for NaN values: {e(', '.join(dropped))}.</p>")
        if notes:
            parts.append("<h3>Warnings</h3><ul>" + "".join(f"<li>{e(n)}</li>" for n in notes) + "</ul>")
    parts.append("<h2>Figures</h2>")
    parts.extend(_figure_html(caption, path) for caption, path in figures)
    parts.append("</body></html>")
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
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 1.5 + 0.22 * len(results)), layout="constrained")
    FigureCanvasAgg(figure)
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
