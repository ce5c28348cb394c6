"""The plots of ``flow_bag``'s reports, drawn with matplotlib on its Agg canvas.

Figures are ``matplotlib.figure.Figure`` objects attached to ``FigureCanvasAgg`` explicitly: no pyplot, no
global backend selection, nothing changed in matplotlib's process-wide state by importing this module. Every
function tolerates missing values: None, NaN and inf are left out (an empty panel says "no data"), so a
plot never fails a report.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..core.errors import FileFormatError

Number = float | int | None
Points = Sequence[tuple[Number, Number]]  # (x, y) pairs


def finite(values: Sequence[Number]) -> list[float]:
    """The values that are real finite numbers (None, NaN, inf dropped)."""
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


def finite_points(points: Points) -> tuple[list[float], list[float]]:
    """(xs, ys) of the pairs whose x and y are both finite numbers."""
    keep = [(float(x), float(y)) for x, y in points
            if x is not None and y is not None and math.isfinite(float(x)) and math.isfinite(float(y))]
    return [p[0] for p in keep], [p[1] for p in keep]


def new_figure(rows: int, width: float = 7.2, row_height: float = 2.4) -> tuple[Figure, list[Axes]]:
    """A figure of ``rows`` stacked axes, ``width`` x ``rows * row_height`` inches, on an Agg canvas."""
    fig = Figure(figsize=(width, row_height * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, squeeze=False)[:, 0]
    return fig, list(axes)


def _no_data(ax: Axes) -> None:
    ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="0.4")


def line_panel(ax: Axes, series: Mapping[str, Points], title: str, xlabel: str, ylabel: str) -> None:
    """One line with markers per named series of (x, y); non-finite points left out."""
    drawn = 0
    for name, pts in series.items():
        xs, ys = finite_points(pts)
        if xs:
            ax.plot(xs, ys, marker="o", markersize=3, linewidth=1.5, label=name)
            drawn += 1
    ax.set(title=title, xlabel=xlabel, ylabel=ylabel)
    ax.grid(True, alpha=0.3)
    if drawn:
        ax.set_ylim(bottom=0)
        ax.legend(fontsize="small")
    else:
        _no_data(ax)


def bar_panel(ax: Axes, labels: Sequence[str], groups: Mapping[str, Sequence[Number]], title: str,
              ylabel: str) -> None:
    """Grouped bars: one group per label, one bar per named group; a missing value gets no bar and a
    grey "n/a" at the base instead."""
    n = max(len(groups), 1)
    width = 0.8 / n
    x = np.arange(len(labels))
    drawn = 0
    for k, (name, values) in enumerate(groups.items()):
        pos = x - 0.4 + width * (k + 0.5)
        ok = [i for i, v in enumerate(values) if finite([v])]
        if ok:
            ax.bar(pos[ok], [float(values[i]) for i in ok], width, label=name)
            drawn += 1
        for i in set(range(len(values))) - set(ok):
            ax.text(pos[i], 0, "n/a", rotation=90, ha="center", va="bottom", fontsize=7, color="0.5")
    ax.set_xticks(x, labels, rotation=30 if len(labels) > 4 else 0, ha="right" if len(labels) > 4 else "center",
                  fontsize="small")
    ax.set(title=title, ylabel=ylabel)
    ax.grid(True, axis="y", alpha=0.3)
    if drawn:
        ax.legend(fontsize="small")
    elif not labels:
        _no_data(ax)


def histogram_panel(ax: Axes, samples: Mapping[str, Sequence[Number]], title: str, xlabel: str,
                    bins: int = 30) -> None:
    """Step histograms on shared bins, one per named sample, with its median as a dashed line."""
    clean = {name: finite(v) for name, v in samples.items()}
    pooled = [v for vs in clean.values() for v in vs]
    ax.set(title=title, xlabel=xlabel, ylabel="frames")
    ax.grid(True, alpha=0.3)
    if not pooled:
        _no_data(ax)
        return
    lo, hi = min(pooled), max(pooled)
    edges = np.linspace(lo, hi if hi > lo else lo + 1.0, bins + 1)
    for name, vs in clean.items():
        if vs:
            (patch,) = ax.hist(vs, bins=edges, histtype="step", linewidth=1.5,
                               label=f"{name} (median {np.median(vs):.3g})")[2]
            ax.axvline(float(np.median(vs)), color=patch.get_edgecolor(), linestyle="--", linewidth=1)
    ax.legend(fontsize="small")


def save(fig: Figure, path: Path, dpi: int = 100) -> None:
    """Write ``fig`` as PNG; FileFormatError if the file cannot be written."""
    try:
        fig.savefig(path, dpi=dpi, format="png")
    except OSError as exc:
        raise FileFormatError(f"cannot write {path}: {exc}") from exc
