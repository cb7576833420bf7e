"""Figures of the reports (log-log plots of ``lightcuts scaling`` and ``lightcuts accel --sweep``):
an off-screen matplotlib figure, side-by-side log-log panels, the atomic PNG write."""

from __future__ import annotations

import math
from pathlib import Path

from lightcuts.errors import LightcutsError
from lightcuts.io import atomic_path


def new_figure(figsize: tuple[float, float], dpi: int, layout: str | None = None):
    """A matplotlib Figure on the Agg canvas (no display needed); LightcutsError without matplotlib."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise LightcutsError("plots need matplotlib: pip install matplotlib") from None
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig, path: Path) -> Path:
    """Write the figure as PNG, atomically."""
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    return path


def loglog_panels(path: Path, panels: list, title: str, figsize: tuple[float, float], dpi: int = 110,
                  legend_size: str = "small") -> Path:
    """Log-log panels side by side, written atomically as PNG.

    panels : [(x label, y label, [(series label, x (K,), y (K,)), ...]), ...], one per panel, each
        series drawn as points joined by lines, in the axes' colour cycle
    """
    fig = new_figure(figsize, dpi, layout="constrained")
    axes = fig.subplots(1, len(panels))
    for ax, (xlabel, ylabel, series) in zip(axes, panels):
        for label, x, y in series:
            ax.loglog(x, y, "o-", label=label)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=legend_size)
        readable_log_ticks(ax)
    fig.suptitle(title)
    return save_png(fig, path)


def readable_log_ticks(ax) -> None:
    """Label a log-log axes' ticks as plain numbers (0.02, 5, 300), spaced by the span each axis
    shows: powers of ten over more than four decades, 1-2-5 steps over more than 1.2, 1-2-3-5 over
    more than half a decade, every digit below, evenly spaced values below a third of a decade;
    minor ticks unlabelled. (matplotlib's default labels minor ticks ``3x10^0`` on short spans,
    where they run into each other.)"""
    from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        decades = abs(math.log10(hi / lo)) if lo > 0 and hi > 0 else 0.0
        if decades < 1 / 3:
            axis.set_major_locator(MaxNLocator(nbins=4))
        else:
            subs = ((1.0,) if decades > 4 else (1.0, 2.0, 5.0) if decades > 1.2 else (1.0, 2.0, 3.0, 5.0)
                    if decades > 0.5 else tuple(float(k) for k in range(1, 10)))
            axis.set_major_locator(LogLocator(base=10.0, subs=subs, numticks=30))
        axis.set_major_formatter(plain)
        axis.set_minor_formatter(NullFormatter())
