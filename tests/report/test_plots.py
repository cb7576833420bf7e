"""Log-log panels: tick labels that can be read (none overlaps another, at least two per axis)."""

import numpy as np
import pytest

import lightcuts.report.plots as plots


def _labels(fig):
    """Per axis of every panel: the drawn tick labels inside the view, as (text, window box)."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    out = []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            ticks = [t for t in axis.get_major_ticks() + axis.get_minor_ticks()
                     if lo <= t.get_loc() <= hi and t.label1.get_visible() and t.label1.get_text()]
            out.append([(t.label1.get_text(), t.label1.get_window_extent(renderer)) for t in ticks])
    return out


@pytest.mark.parametrize("lo, hi", [(0.3, 2.5), (0.9, 7.5), (3, 40), (1.2, 3.5), (0.081, 0.089), (1e-3, 30)])
def test_loglog_tick_labels_do_not_overlap(tmp_path, monkeypatch, lo, hi):
    figures = []
    save = plots.save_png
    monkeypatch.setattr(plots, "save_png", lambda fig, path: (figures.append(fig), save(fig, path))[1])
    x, y = np.geomspace(lo, hi, 5), np.geomspace(0.09, 0.012, 5)
    panels = [("seconds", "error", [("a", x, y), ("b", 1.1 * x, 0.8 * y)])] * 2
    plots.loglog_panels(tmp_path / "p.png", panels, "title", (10.0, 4.2))
    for labels in _labels(figures[0]):
        assert len(labels) >= 2, labels
        assert all("times" not in text and "mathdefault" not in text for text, _ in labels)  # plain numbers
        boxes = [b for _, b in labels]
        assert not any(boxes[i].overlaps(boxes[j]) for i in range(len(boxes)) for j in range(i + 1, len(boxes))), \
            [t for t, _ in labels]
