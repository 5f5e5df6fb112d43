"""Plots for researchers (docs/evaluation.md#reports): PNG files drawn with matplotlib's Agg canvas.

Figures are built on ``matplotlib.figure.Figure`` with an Agg canvas, never through ``pyplot``, so plotting
works headless and does not touch global backend state.
"""

from __future__ import annotations

import functools
import os
import textwrap
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

import numpy as np
import scipy.stats

from scanner.lazy import library
from scanner.scan import Scan, Trace
from taxonomy.errors import ParameterError
from taxonomy.labels import LabelError, major_class
from taxonomy.learning.results import Result
from taxonomy.table import Taxonomy, load_taxonomy

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn (new_figure)
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

figures = library("matplotlib.figure", workers=False)  # imported when a figure is drawn (new_figure)
agg = library("matplotlib.backends.backend_agg", workers=False)

Traces = Mapping[str, Trace]
"""Channel name -> trace: a scan's ``traces`` or one recorded step's."""
PlotTarget = str | os.PathLike[str] | BinaryIO
"""A PNG file name, or a binary file object (a web page's image drawn in memory)."""

_AXES = ("x", "y", "z")
_MISSING = "not recorded"


def _time(n: int, fs: float) -> np.ndarray:
    return np.arange(n) / fs


def _note(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.4")


def _acceleration(ax: Axes, traces: Traces, name: str, title: str) -> None:
    trace = traces.get(name)
    ax.set_title(f"{title} ({name})")
    if trace is None:
        _note(ax, _MISSING)
        return
    t = _time(trace.n, trace.fs)
    for axis, label in enumerate(_AXES):
        ax.plot(t, trace.data[:, axis], lw=0.5, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("acceleration (g)")
    ax.legend(loc="upper right", fontsize="small", ncols=3)


_ENVELOPE_ABOVE = 20000
"""Traces longer than this (the 44.1 kHz audio) are drawn as their min/max envelope: same look, far faster."""


def _trace(ax: Axes, data: np.ndarray, fs: float, label: str, lw: float) -> None:
    if data.size <= _ENVELOPE_ABOVE:
        ax.plot(_time(data.size, fs), data, lw=lw, label=label, alpha=0.8)
        return
    block = int(np.ceil(data.size / 2000))
    usable = data[: data.size // block * block].reshape(-1, block)
    t = (np.arange(usable.shape[0]) + 0.5) * block / fs
    ax.fill_between(t, usable.min(axis=1), usable.max(axis=1), label=label, alpha=0.6, lw=0)


def _lines(ax: Axes, traces: Traces, names: Sequence[str], labels: Sequence[str], title: str, ylabel: str,
           lw: float = 0.7) -> None:
    ax.set_title(title)
    drawn = False
    for name, label in zip(names, labels, strict=True):
        trace = traces.get(name)
        if trace is None:
            continue
        _trace(ax, trace.data, trace.fs, f"{label} ({name})", lw)
        drawn = True
    if not drawn:
        _note(ax, _MISSING)
        return
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.legend(loc="upper right", fontsize="small")


def _fold(ax: Axes, traces: Traces, rigid: bool) -> None:
    ax.set_title("fold (f_fold, alpha_f)")
    force, angle = traces.get("f_fold"), traces.get("alpha_f")
    if force is None or angle is None:
        _note(ax, "fold skipped: rigid sample" if rigid else _MISSING)
        return
    ax.plot(_time(force.n, force.fs), force.data, lw=0.7, color="C3", label="force")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fold force (N)", color="C3")
    twin = ax.twinx()
    twin.plot(_time(angle.n, angle.fs), angle.data, lw=0.7, color="C0", label="angle")
    twin.set_ylabel("flex angle (deg)", color="C0")


def _thermal(ax: Axes, traces: Traces, t_amb: float) -> None:
    ax.set_title("thermal cooling (t_cool)")
    trace = traces.get("t_cool")
    if trace is None:
        _note(ax, _MISSING)
        return
    ax.plot(_time(trace.n, trace.fs), trace.data, ".-", lw=0.7, ms=2, label="MLX90614 object")
    if np.isfinite(t_amb):
        ax.axhline(t_amb, color="0.5", ls="--", lw=0.8, label=f"t_amb {t_amb:.2f} degC")
    ax.set_xlabel("time after heating (s)")
    ax.set_ylabel("temperature (degC)")
    ax.legend(loc="upper right", fontsize="small")


def _metal_magnet(ax: Axes, traces: Traces) -> None:
    ax.set_title("metal electrodes (m) and magnetometer (dB)")
    metal, field = traces.get("m"), traces.get("dB")
    if metal is None and field is None:
        _note(ax, _MISSING)
        return
    ax.set_xlabel("time (s)")
    if metal is not None:
        ax.plot(_time(metal.n, metal.fs), metal.data, lw=0.8, color="C2")
    ax.set_ylabel("metal m (+1 conductive, -1 not)", color="C2")
    ax.set_ylim(-1.3, 1.3)
    twin = ax.twinx()
    if field is not None:
        twin.plot(_time(field.n, field.fs), field.data, ".-", lw=0.7, ms=3, color="C4")
        low, high = float(field.data.min()), float(field.data.max())
        pad = max(0.5, 0.1 * (high - low))
        twin.set_ylim(min(low, 0.0) - pad, max(high, 0.0) + pad)
    twin.set_ylabel("dB (uT)", color="C4")


def _photo(ax: Axes, scan: Scan, name: str, title: str) -> None:
    ax.set_title(f"{title} ({name})")
    ax.set_axis_off()
    image = scan.images.get(name)
    if image is None:
        _note(ax, _MISSING)
        return
    ax.imshow(image, interpolation="nearest")


def _summary(ax: Axes, scan: Scan) -> None:
    meta = scan.meta
    ax.set_axis_off()
    density = meta.mass_g / meta.volume_cm3 if meta.volume_cm3 > 0 else float("nan")
    rows = [
        ("label", meta.label), ("sample", meta.sample_id), ("scan", str(meta.scan_index)),
        ("operator", meta.operator), ("started", meta.started), ("t_amb", f"{meta.t_amb:.2f} degC"),
        ("mass", f"{meta.mass_g:.1f} g"), ("volume", f"{meta.volume_cm3:.1f} cm^3"),
        ("density", f"{density:.3f} g/cm^3"), ("adhesive tack", f"{meta.atk:g}"),
        ("yielding", f"{meta.cyd:g}"), ("fold skipped as rigid", "yes" if meta.rigid else "no"),
    ]
    text = "\n".join(f"{key:>22s}: {value}" for key, value in rows)
    ax.text(0.0, 1.0, text, va="top", ha="left", family="monospace", fontsize=9, transform=ax.transAxes)


def plot_scan(scan: Scan, path: PlotTarget, title: str | None = None) -> None:
    """Every channel of one scan on one page, like the paper's Fig. 9, saved as a PNG at ``path``.

    Panels: the four TU1 accelerations (3 axes each), audio, IR reflectance, friction forces, press force,
    fold force and angle, thermal cooling against the ambient temperature, metal electrode and magnetometer,
    the TU4 values, and the three photos. A channel the scan does not have is marked "not recorded"
    (the fold as skipped when the sample was flagged rigid).
    """
    figure = new_figure(figsize=(22, 17), layout="constrained")
    grid = figure.subplots(4, 4)
    traces = scan.traces
    for ax, step in zip(grid[0], ("finger_tap", "finger_slide", "tool_tap", "tool_slide"), strict=True):
        _acceleration(ax, traces, *_ACCELERATION[step])
    _lines(grid[1, 0], traces, ("a_fs", "a_ts"), ("finger", "tool"), "audio", "audio (full scale)")
    _lines(grid[1, 1], traces, ("r_fs", "r_ts"), ("finger slide", "tool slide"), "IR reflectance", "IR (V)")
    _lines(grid[1, 2], traces, ("f_frn", "f_frt"), ("normal", "tangential"), "friction slide", "force (N)")
    _lines(grid[1, 3], traces, ("f_press",), ("normal",), "press, 4.0 mm indentation", "force (N)")
    _fold(grid[2, 0], traces, scan.meta.rigid)
    _thermal(grid[2, 1], traces, scan.meta.t_amb)
    _metal_magnet(grid[2, 2], traces)
    _summary(grid[2, 3], scan)
    for ax, (name, label) in zip(grid[3], (("I_disp", "photo"), ("I_macro", "macro lens"),
                                           ("I_illu", "flash")), strict=False):
        _photo(ax, scan, name, label)
    grid[3, 3].set_axis_off()
    figure.suptitle(title or f"{scan.meta.label}  {scan.scan_id}", fontsize=16)
    figure.savefig(_target(path), dpi=80, format="png")


_ACCELERATION = {"finger_tap": ("v_ft", "finger tap"), "finger_slide": ("v_fs", "finger slide"),
                 "tool_tap": ("v_tt", "tool tap"), "tool_slide": ("v_ts", "tool slide")}
"""The acceleration channel and its title for each TU1 step."""

STEP_PLOT_WIDTH_PX = 800
"""Width of :func:`plot_step`'s figure: a tablet's screen, so the page shows it at (about) its own size."""


def _step_panels(step: str, traces: Traces, t_amb: float, rigid: bool) -> list[Callable[[Axes], None]]:
    """The panels of :func:`plot_scan` that show the channels one step of the procedure records."""
    if step in _ACCELERATION:
        panels = [functools.partial(_acceleration, traces=traces, name=_ACCELERATION[step][0],
                                    title=_ACCELERATION[step][1])]
        if step.endswith("slide"):
            who, s = ("finger", "fs") if step == "finger_slide" else ("tool", "ts")
            panels += [functools.partial(_lines, traces=traces, names=(f"a_{s}",), labels=(who,), title="audio",
                                         ylabel="audio (full scale)"),
                       functools.partial(_lines, traces=traces, names=(f"r_{s}",), labels=(f"{who} slide",),
                                         title="IR reflectance", ylabel="IR (V)")]
        return panels
    others: dict[str, Callable[[Axes], None]] = {
        "static": functools.partial(_metal_magnet, traces=traces),
        "thermal": functools.partial(_thermal, traces=traces, t_amb=t_amb),
        "friction": functools.partial(_lines, traces=traces, names=("f_frn", "f_frt"),
                                      labels=("normal", "tangential"), title="friction slide", ylabel="force (N)"),
        "press": functools.partial(_lines, traces=traces, names=("f_press",), labels=("normal",),
                                   title="press, 4.0 mm indentation", ylabel="force (N)"),
        "fold": functools.partial(_fold, traces=traces, rigid=rigid),
    }
    if step not in others:
        raise ParameterError(f"{step!r} is not a recorded step (known: {', '.join([*_ACCELERATION, *others])})")
    return [others[step]]


def plot_step(traces: Traces, step: str, path: PlotTarget, title: str = "", *, t_amb: float = float("nan"),
              rigid: bool = False) -> None:
    """The channels one step records, with the panels of :func:`plot_scan`, as a PNG for a tablet screen.

    ``traces`` maps channel names to traces (a recorded step's ``StepResult.traces`` or a whole scan's);
    ``step`` is a step of the guided session (``finger_tap`` ... ``fold``). The figure is 800 px wide with
    one panel per row, so on a tablet its text is drawn at about its own size.
    """
    panels = _step_panels(step, traces, t_amb, rigid)
    dpi = 125  # 6.4 in x 125 dpi = 800 px; text in points grows with the dpi, so it stays legible
    figure = new_figure(figsize=(STEP_PLOT_WIDTH_PX / dpi, 0.5 + 2.6 * len(panels)), layout="constrained")
    axes = figure.subplots(len(panels), 1, squeeze=False)[:, 0]
    for ax, panel in zip(axes, panels, strict=True):
        panel(ax)
    if title:
        figure.suptitle(title, fontsize=11)
    figure.savefig(_target(path), dpi=dpi, format="png")


def _target(path: PlotTarget) -> str | BinaryIO:
    return path if hasattr(path, "write") else os.fspath(path)


# -- evaluation plots (paper Figs. 14-18) -------------------------------------------------------------


def new_figure(*args: Any, **kwargs: Any) -> Figure:
    """A matplotlib figure on an Agg canvas. matplotlib is imported here, when a figure is drawn: it takes a
    third of a second that every command and page drawing no figure would pay."""
    figure = figures.Figure(*args, **kwargs)
    agg.FigureCanvasAgg(figure)
    return figure


def _canvas(width: float, height: float) -> Figure:
    figure = new_figure(figsize=(width, height), layout="constrained")
    return figure


def _save(figure: Figure, path: str | os.PathLike[str], dpi: int = 100) -> Path:
    figure.savefig(os.fspath(path), dpi=dpi)
    return Path(path)


def _major_class(code: str) -> str:
    """``"C6"`` of ``"C6S1M1P2X1"``; a code without a major class stays as it is."""
    try:
        return major_class(code)
    except LabelError:
        return code


def _label_size(count: int) -> float:
    """Tick label font size that keeps ``count`` labels legible side by side."""
    return float(np.clip(300 / max(count, 1), 5, 10))


NAME_WIDTH = 32
"""Characters of a class name in a figure; longer names are shortened at a word with "…"."""


def class_labels(classes: Sequence[str], taxonomy: Taxonomy | None = None, width: int = NAME_WIDTH) -> list[str]:
    """Tick labels that name each class and keep its code: ``"granite, polished (C6S1M1P2X1)"``.

    Names come from :meth:`taxonomy.table.Taxonomy.class_name` (``taxonomy``, default the shipped table with
    the lab's extension), shortened to ``width`` characters; a class that is not a taxonomy code in its
    canonical spelling (classes of other data sets) stays as it is.
    """
    table = taxonomy if taxonomy is not None else load_taxonomy()
    labels = []
    for code in classes:
        try:
            if code != code.strip().upper():  # "c3" of another data set is no taxonomy code
                raise ParameterError(code)
            name = _shorten(table.class_name(code), width)
        except ValueError:
            labels.append(code)
            continue
        labels.append(f"{name} ({code})")
    return labels


def plot_scores(reports: Sequence[Result], level: str, n_features: int | None,
                path: str | os.PathLike[str]) -> Path:
    """Accuracy (top) and macro F1 (bottom) per feature set and classifier, like the paper's Figs. 16-18.

    Bars are the pooled out-of-fold accuracy and macro F1 with their 95 % bootstrap intervals
    (``Result.intervals``); the dotted line marks the best accuracy and its F1, as in Fig. 17; the dashed
    red line is chance (the most frequent class; ``1 / K`` for macro F1). Only the reports at ``level``
    with ``n_features`` are drawn.
    """
    chosen = [r for r in reports if r.level == level and r.n_features == n_features]
    if not chosen:
        raise ParameterError(f"no report at level {level} with {n_features} features to plot")
    sets = list(dict.fromkeys(r.feature_set for r in chosen))
    classifiers = list(dict.fromkeys(r.classifier for r in chosen))
    cell = {(r.classifier, r.feature_set): r for r in chosen}
    figure = _canvas(max(8.0, 1.3 * len(sets) + 4), 7.5)
    top, bottom = figure.subplots(2, 1, sharex=True)
    width = 0.8 / len(classifiers)
    x = np.arange(len(sets))
    for k, name in enumerate(classifiers):
        rows = [cell.get((name, s)) for s in sets]
        offset = x - 0.4 + (k + 0.5) * width
        for ax, value, interval, scale in ((top, "accuracy_pooled", "accuracy_ci", 100.0),
                                           (bottom, "f1_pooled", "f1_ci", 1.0)):
            heights = np.array([scale * getattr(r, value) if r else np.nan for r in rows])
            bounds = np.array([[scale * v for v in getattr(r, interval)] if r else [np.nan, np.nan] for r in rows])
            errors = np.nan_to_num(np.abs(bounds.T - heights))
            ax.bar(offset, heights, width, yerr=errors, capsize=2, label=name, color=f"C{k}",
                   error_kw={"elinewidth": 0.8})
    best = max(chosen, key=lambda r: r.accuracy_pooled)
    top.axhline(100 * best.accuracy_pooled, color="0.3", ls=":", lw=1,
                label=f"best {100 * best.accuracy_pooled:.1f} % ({best.classifier}, {best.feature_set})")
    bottom.axhline(best.f1_pooled, color="0.3", ls=":", lw=1)
    top.axhline(100 * chosen[0].chance, color="C3", ls="--", lw=1,
                label=f"chance {100 * chosen[0].chance:.1f} % (most frequent class)")
    bottom.axhline(chosen[0].chance_f1, color="C3", ls="--", lw=1)
    top.set_ylim(0, 105)
    top.set_ylabel("accuracy (%), 95 % CI")
    bottom.set_ylabel("macro F1 (pooled), 95 % CI")
    bottom.set_ylim(0, 1.05)
    bottom.set_xticks(x, sets)
    bottom.set_xlabel("feature set")
    figure.legend(*top.get_legend_handles_labels(), loc="outside right upper", fontsize="small")
    first = chosen[0]
    size = "all features" if n_features is None else f"X{n_features}"
    top.set_title(_wrap(f"{level} classification with {size} ({first.protocol} protocol, "
                        f"{first.splitting}, {len(first.classes)} classes)", 60), fontsize=10)
    return _save(figure, path)


def plot_fq_ranking(ranking: Sequence[tuple[str, float]], selected: Sequence[str],
                    path: str | os.PathLike[str], top: int = 30) -> Path:
    """The ``top`` features by feature quality FQ (eq. 31) as horizontal bars, best at the top.

    Features the selector accepted are coloured and numbered in acceptance order; the others were
    rejected for correlation with a better one or came after the n-th acceptance.
    """
    shown = list(ranking[:top])
    order = {name: i + 1 for i, name in enumerate(selected)}
    figure = _canvas(8.0, max(3.0, 0.22 * len(shown) + 1.2))
    ax = figure.subplots()
    y = np.arange(len(shown))
    colours = ["C1" if name in order else "0.7" for name, _ in shown]
    ax.barh(y, [fq for _, fq in shown], color=colours)
    ax.set_yticks(y, [f"{name}  [{order[name]}]" if name in order else name for name, _ in shown],
                  fontsize=_label_size(len(shown)) - 1)
    ax.invert_yaxis()
    ax.set_xlim(0, 100)
    ax.set_xlabel("feature quality FQ (%)")
    # Over the figure, not the axes: long feature names leave the axes narrow, and a title centred on them
    # ran off the figure's edge.
    figure.suptitle(_wrap(f"top {len(shown)} of {len(ranking)} features by FQ; selected in orange [acceptance "
                          "order]", 72))
    return _save(figure, path)


def plot_spearman(X: np.ndarray, names: Sequence[str], path: str | os.PathLike[str]) -> Path:
    """Spearman rank correlation between the columns of ``X`` (e.g. the selected features) as a heat map."""
    X = np.asarray(X, dtype=np.float64)
    rho = np.atleast_2d(scipy.stats.spearmanr(X).statistic) if X.shape[1] > 1 else np.ones((1, 1))
    if rho.shape == (1, 1) and X.shape[1] == 2:
        rho = np.array([[1.0, rho[0, 0]], [rho[0, 0], 1.0]])
    n = len(names)
    figure = _canvas(max(4.5, 0.6 * n + 3), max(4.0, 0.6 * n + 2))
    ax = figure.subplots()
    image = ax.imshow(rho, cmap="RdBu_r", vmin=-1, vmax=1)
    size = _label_size(n)
    ax.set_xticks(range(n), names, rotation=60, ha="right", fontsize=size)
    ax.set_yticks(range(n), names, fontsize=size)
    if n <= 15:
        for i in range(n):
            for j in range(n):
                ax.text(j, i, f"{rho[i, j]:.2f}", ha="center", va="center", fontsize=size - 1,
                        color="white" if abs(rho[i, j]) > 0.6 else "black")
    figure.colorbar(image, ax=ax, label="Spearman rho", shrink=0.8)
    ax.set_title("Spearman correlation of the selected features")
    return _save(figure, path)


def plot_pca_variance(X: np.ndarray, path: str | os.PathLike[str], marks: Sequence[int] = (3, 10)) -> Path:
    """Explained variance over the principal components of the min-max scaled features (paper Fig. 15).

    Columns with NaN and constant columns are left out; the cumulative share at ``marks`` components is
    written on the curve (the paper: 3 components explain ~30 %, 10 ~62 %).
    """
    X = np.asarray(X, dtype=np.float64)
    X = X[:, np.isfinite(X).all(axis=0)]
    X = X[:, np.ptp(X, axis=0) > 0] if X.size else X
    if X.shape[0] < 2 or X.shape[1] < 1:
        raise ParameterError("PCA needs at least two rows and one finite, non-constant column")
    scaled = (X - X.min(axis=0)) / np.ptp(X, axis=0)
    singular = np.linalg.svd(scaled - scaled.mean(axis=0), compute_uv=False)
    share = 100 * singular**2 / np.sum(singular**2)
    cumulative = np.cumsum(share)
    components = np.arange(1, share.size + 1)
    figure = _canvas(8.0, 4.5)
    ax = figure.subplots()
    ax.bar(components, share, color="C0", label="per component")
    ax.plot(components, cumulative, color="C1", marker=".", ms=3, label="cumulative")
    for mark in marks:
        if mark <= share.size:
            # Below and right of the rising curve, inside the axes: to its left the text ran into the
            # y axis label, above it into the title.
            ax.annotate(f"{mark} PCs: {cumulative[mark - 1]:.0f} %", (mark, cumulative[mark - 1]),
                        xytext=(14, -24), textcoords="offset points", fontsize=9, ha="left", va="top",
                        arrowprops={"arrowstyle": "-", "color": "0.4"})
    ax.set_xlim(0.3, min(share.size, 60) + 0.7)
    ax.set_ylim(0, 102)
    ax.set_xlabel("principal component")
    ax.set_ylabel("explained variance (%)")
    ax.set_title(f"PCA of {X.shape[1]} scaled features over {X.shape[0]} scans")
    ax.legend(loc="lower right")
    return _save(figure, path)


def plot_feature_boxes(values: np.ndarray, classes: Sequence[str], feature: str,
                       path: str | os.PathLike[str], max_classes: int = 40, title: str | None = None,
                       taxonomy: Taxonomy | None = None) -> Path:
    """Box plot of one feature per class (paper Fig. 14); at most ``max_classes`` classes, in label order.

    The boxes lie horizontally, one row per class named as :func:`class_labels` names it, so the names read
    left to right. NaN values are left out of their class's box.
    """
    values = np.asarray(values, dtype=np.float64)
    classes = np.asarray(classes)
    names = sorted(set(classes.tolist()))
    shown = names[:max_classes]
    data = [values[(classes == c) & np.isfinite(values)] for c in shown]
    size = min(_label_size(len(shown)), 9.0)
    figure = _canvas(9.0, max(3.0, 0.26 * len(shown) + 1.6))
    ax = figure.subplots()
    ax.boxplot(data, tick_labels=class_labels(shown, taxonomy), widths=0.6, flierprops={"markersize": 3},
               orientation="horizontal")
    ax.invert_yaxis()  # first class at the top, as in a table
    ax.tick_params(axis="y", labelsize=size)
    ax.grid(axis="x", color="0.9")
    ax.set_xlabel(feature)
    note = f" (first {len(shown)} of {len(names)} classes)" if len(shown) < len(names) else ""
    ax.set_title(_wrap((title or f"{feature} per class") + note, 70))
    return _save(figure, path)


def _shorten(text: str, width: int) -> str:
    """``text`` cut at a word to about ``width`` characters, marked with "…" where it was cut."""
    if len(text) <= width:
        return text
    kept = textwrap.shorten(text, width - 2, placeholder="").rstrip(" ,;")
    return f"{kept or text[:width - 2]} …"


def _wrap(text: str, width: int) -> str:
    """A title over several lines rather than wider than its figure."""
    return "\n".join(textwrap.wrap(text, width)) or text


def plot_confusion(confusion: np.ndarray, classes: Sequence[str], path: str | os.PathLike[str],
                   title: str = "confusion matrix", max_labels: int = 40, taxonomy: Taxonomy | None = None) -> Path:
    """Confusion matrix normalised per true class (rows true, columns predicted).

    Up to ``max_labels`` classes every class is labelled with its name and code (:func:`class_labels`) on
    the rows, and on the columns too up to 12 classes (with counts in the cells); with more, the columns
    show the codes alone, which stay legible side by side. Beyond ``max_labels`` the axes are labelled by
    major class C, whose blocks are outlined, so misclassifications that leave the major class (eq. 32)
    stand out.
    """
    confusion = np.asarray(confusion, dtype=np.float64)
    n = len(classes)
    totals = confusion.sum(axis=1, keepdims=True)
    share = np.divide(confusion, totals, out=np.zeros_like(confusion), where=totals > 0)
    # The matrix gets a fixed size per class and the saved figure grows around it to hold every label
    # (bbox_inches="tight"): a layout engine shrinks a fixed-aspect image between long tick labels instead.
    side = float(np.clip(0.3 * n, 4.0, 12.0))
    figure = new_figure(figsize=(side + 1.0, side))
    ax = figure.add_axes((0.0, 0.0, side / (side + 1.0), 1.0))
    image = ax.imshow(share, cmap="Blues", vmin=0, vmax=1, interpolation="nearest")
    xlabel = "predicted class"
    if n <= max_labels:
        size = min(_label_size(n), 9.0)
        named = class_labels(classes, taxonomy)
        if n <= 12:
            ax.set_xticks(range(n), named, rotation=90, fontsize=size)
        else:
            ax.set_xticks(range(n), classes, rotation=90, fontsize=size)
            xlabel = "predicted class (codes; names on the left)"
        ax.set_yticks(range(n), named, fontsize=size)
        if n <= 12:
            for i, j in zip(*np.nonzero(confusion), strict=True):
                ax.text(j, i, f"{confusion[i, j]:.0f}", ha="center", va="center", fontsize=9,
                        color="white" if share[i, j] > 0.5 else "black")
    else:
        majors = [_major_class(c) for c in classes]
        starts = [i for i in range(n) if i == 0 or majors[i] != majors[i - 1]]
        ends = [*starts[1:], n]
        centres = [(a + b - 1) / 2 for a, b in zip(starts, ends, strict=True)]
        labels = class_labels([majors[a] for a in starts], taxonomy)
        ax.set_xticks(centres, labels, fontsize=9, rotation=90)
        ax.set_yticks(centres, labels, fontsize=9)
        for edge in starts[1:]:
            ax.axhline(edge - 0.5, color="0.6", lw=0.5)
            ax.axvline(edge - 0.5, color="0.6", lw=0.5)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("true class")
    ax.set_title(_wrap(title, int(side * 16)))
    bar = figure.add_axes((side / (side + 1.0) + 0.25 / (side + 1.0), 0.15, 0.2 / (side + 1.0), 0.7))
    figure.colorbar(image, cax=bar, label="share of the true class")
    figure.savefig(_target(path), dpi=90, bbox_inches="tight", pad_inches=0.15, format="png")
    return Path(path)


def plot_reliability(reports: Sequence[Result], path: str | os.PathLike[str]) -> Path:
    """Reliability diagrams of calibrated probabilities, one panel per result (Guo et al. 2017, Fig. 1).

    Each populated bin of top-label confidence is a point at (mean confidence, accuracy), its area growing
    with the scans in it; the diagonal is perfect calibration and the dashed red line chance (the most
    frequent class). The title gives the result and its expected calibration error (ECE).
    """
    chosen = [r for r in reports if r.reliability is not None]
    if not chosen:
        raise ParameterError("no result with calibrated probabilities to plot")
    columns = min(3, len(chosen))
    rows = -(-len(chosen) // columns)
    figure = _canvas(3.2 * columns, 3.2 * rows)
    axes = np.atleast_1d(figure.subplots(rows, columns, squeeze=False)).ravel()
    for ax, report in zip(axes, chosen, strict=False):
        bins = report.reliability
        ax.plot([0, 1], [0, 1], color="0.5", lw=1, label="calibrated")
        ax.axhline(report.chance, color="C3", ls="--", lw=1, label="chance")
        ax.plot(bins.confidence, bins.accuracy, color="C0", lw=1)
        ax.scatter(bins.confidence, bins.accuracy, s=12 + 200 * bins.count / bins.count.sum(), color="C0",
                   zorder=3, label="bins (area: scans)")
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1.02)
        ax.set_aspect("equal")
        ax.set_title(f"{report.classifier}, {report.feature_set}, {report.level}, "
                     f"{'all' if report.n_features is None else f'X{report.n_features}'}\nECE {report.ece:.3f}",
                     fontsize=9)
        ax.set_xlabel("confidence (top probability)", fontsize=8)
        ax.set_ylabel("accuracy", fontsize=8)
    for ax in axes[len(chosen):]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7, loc="upper left")
    return _save(figure, path, dpi=90)


def plot_open_set(report: Result, path: str | os.PathLike[str]) -> Path:
    """Histograms of the rejection score of known and unknown test scans of an open-set result, with the
    ROC curve beside them; the ROC's diagonal is chance (AUROC 0.5)."""
    if not report.open_set:
        raise ParameterError("not an open-set result")
    figure = _canvas(9.0, 3.4)
    left, right = figure.subplots(1, 2)
    score = report.open_score
    bins = np.linspace(score.min(), score.max(), 30)
    left.hist(score[report.known], bins, alpha=0.6, label="known materials", color="C0")
    left.hist(score[~report.known], bins, alpha=0.6, label="held-out materials", color="C3")
    left.set_xlabel("rejection score s(x)")
    left.set_ylabel("test scans")
    left.legend(fontsize=8)
    order = np.argsort(-score, kind="stable")
    unknown = ~report.known[order]
    tpr = np.r_[0, np.cumsum(unknown) / max(unknown.sum(), 1)]
    fpr = np.r_[0, np.cumsum(~unknown) / max((~unknown).sum(), 1)]
    right.plot(fpr, tpr, color="C0", label=f"AUROC {report.auroc:.3f}")
    right.plot([0, 1], [0, 1], color="C3", ls="--", lw=1, label="chance (0.5)")
    right.set_xlabel("known scans rejected")
    right.set_ylabel("unknown scans rejected")
    right.set_aspect("equal")
    right.legend(fontsize=8, loc="lower right")
    figure.suptitle(f"{report.classifier}, {report.level}: known-class accuracy {100 * report.known_accuracy:.1f} % "
                    f"(closed set {100 * report.closed_accuracy:.1f} %), unknown rejected "
                    f"{100 * report.unknown_rejected:.1f} %", fontsize=9)
    return _save(figure, path, dpi=90)
