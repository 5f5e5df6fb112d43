"""Plots for researchers (SPEC 8 "Reports and plots"): PNG files drawn with matplotlib's Agg canvas.

Figures are built on ``matplotlib.figure.Figure`` with an Agg canvas, never through ``pyplot``, so plotting
works headless and does not touch global backend state.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from scanner.scan import Scan

_AXES = ("x", "y", "z")
_MISSING = "not recorded"


def _time(n: int, fs: float) -> np.ndarray:
    return np.arange(n) / fs


def _note(ax: Axes, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, color="0.4")


def _acceleration(ax: Axes, scan: Scan, name: str, title: str) -> None:
    trace = scan.get(name)
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


def _lines(ax: Axes, scan: Scan, names: Sequence[str], labels: Sequence[str], title: str, ylabel: str,
           lw: float = 0.7) -> None:
    ax.set_title(title)
    drawn = False
    for name, label in zip(names, labels, strict=True):
        trace = scan.get(name)
        if trace is None:
            continue
        ax.plot(_time(trace.n, trace.fs), trace.data, lw=lw, label=f"{label} ({name})", alpha=0.8)
        drawn = True
    if not drawn:
        _note(ax, _MISSING)
        return
    ax.set_xlabel("time (s)")
    ax.set_ylabel(ylabel)
    ax.legend(loc="upper right", fontsize="small")


def _fold(ax: Axes, scan: Scan) -> None:
    ax.set_title("fold (f_fold, alpha_f)")
    force, angle = scan.get("f_fold"), scan.get("alpha_f")
    if force is None or angle is None:
        _note(ax, "fold skipped: rigid sample" if scan.meta.rigid else _MISSING)
        return
    ax.plot(_time(force.n, force.fs), force.data, lw=0.7, color="C3", label="force")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("fold force (N)", color="C3")
    twin = ax.twinx()
    twin.plot(_time(angle.n, angle.fs), angle.data, lw=0.7, color="C0", label="angle")
    twin.set_ylabel("flex angle (deg)", color="C0")


def _thermal(ax: Axes, scan: Scan) -> None:
    ax.set_title("thermal cooling (t_cool)")
    trace = scan.get("t_cool")
    if trace is None:
        _note(ax, _MISSING)
        return
    ax.plot(_time(trace.n, trace.fs), trace.data, ".-", lw=0.7, ms=2, label="MLX90614 object")
    if np.isfinite(scan.meta.t_amb):
        ax.axhline(scan.meta.t_amb, color="0.5", ls="--", lw=0.8, label=f"t_amb {scan.meta.t_amb:.2f} degC")
    ax.set_xlabel("time after heating (s)")
    ax.set_ylabel("temperature (degC)")
    ax.legend(loc="upper right", fontsize="small")


def _metal_magnet(ax: Axes, scan: Scan) -> None:
    ax.set_title("metal electrodes (m) and magnetometer (dB)")
    metal, field = scan.get("m"), scan.get("dB")
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


def plot_scan(scan: Scan, path: str | os.PathLike[str], title: str | None = None) -> None:
    """Every channel of one scan on one page, like the paper's Fig. 9, saved as a PNG at ``path``.

    Panels: the four TU1 accelerations (3 axes each), audio, IR reflectance, friction forces, press force,
    fold force and angle, thermal cooling against the ambient temperature, metal electrode and magnetometer,
    the TU4 values, and the three photos. A channel the scan does not have is marked "not recorded"
    (the fold as skipped when the sample was flagged rigid).
    """
    figure = Figure(figsize=(22, 17), layout="constrained")
    FigureCanvasAgg(figure)
    grid = figure.subplots(4, 4)
    for ax, (name, label) in zip(grid[0], (("v_ft", "finger tap"), ("v_fs", "finger slide"),
                                           ("v_tt", "tool tap"), ("v_ts", "tool slide")), strict=True):
        _acceleration(ax, scan, name, label)
    _lines(grid[1, 0], scan, ("a_fs", "a_ts"), ("finger", "tool"), "audio", "audio (full scale)", lw=0.3)
    _lines(grid[1, 1], scan, ("r_fs", "r_ts"), ("finger slide", "tool slide"), "IR reflectance", "IR (V)")
    _lines(grid[1, 2], scan, ("f_frn", "f_frt"), ("normal", "tangential"), "friction slide", "force (N)")
    _lines(grid[1, 3], scan, ("f_press",), ("normal",), "press, 4.0 mm indentation", "force (N)")
    _fold(grid[2, 0], scan)
    _thermal(grid[2, 1], scan)
    _metal_magnet(grid[2, 2], scan)
    _summary(grid[2, 3], scan)
    for ax, (name, label) in zip(grid[3], (("I_disp", "photo"), ("I_macro", "macro lens"),
                                           ("I_illu", "flash")), strict=False):
        _photo(ax, scan, name, label)
    grid[3, 3].set_axis_off()
    figure.suptitle(title or f"{scan.meta.label}  {scan.scan_id}", fontsize=16)
    figure.savefig(os.fspath(path), dpi=80)
