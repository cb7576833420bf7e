"""Figures of the reports (log-log plots of ``lightcuts scaling`` and ``lightcuts accel --sweep``):
an off-screen matplotlib figure, side-by-side log-log panels, the atomic PNG write."""

from __future__ import annotations

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
    fig.suptitle(title)
    return save_png(fig, path)
