r"""Build time against the number of lights (the 2008 paper's Fig. 9): fitted exponents, the
log-log plot and the text table of ``lightcuts scaling`` (:mod:`lightcuts.commands.scaling`).

Rows are dicts with n_requested, n_lights, builder, median_s, min_s, repeats, depth
(:data:`CSV_FIELDS`). The exponent is the least-squares slope b of log t = a + b log N.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


CSV_FIELDS = ("n_requested", "n_lights", "builder", "median_s", "min_s", "repeats", "depth")


def fitted_exponent(n: np.ndarray, seconds: np.ndarray) -> float:
    """Slope b of log t = a + b log N (least squares); nan with fewer than two sizes."""
    n, seconds = np.asarray(n, float), np.asarray(seconds, float)
    ok = (n > 0) & (seconds > 0)
    if len(np.unique(n[ok])) < 2:
        return float("nan")
    return float(np.polyfit(np.log(n[ok]), np.log(seconds[ok]), 1)[0])


def plot_scaling(path: Path, rows: list[dict], title: str) -> Path:
    """Log-log build time against N per builder, with O(N) and O(N^2) guides; written atomically."""
    from lightcuts.report.plots import new_figure, save_png

    fig = new_figure((6.4, 4.8), 120)
    ax = fig.add_subplot()
    builders = list(dict.fromkeys(r["builder"] for r in rows))
    all_n = np.array([r["n_lights"] for r in rows], float)
    for b in builders:
        n = np.array([r["n_lights"] for r in rows if r["builder"] == b], float)
        t = np.array([r["median_s"] for r in rows if r["builder"] == b], float)
        ax.loglog(n, t, "o-", label=f"{b} (N^{fitted_exponent(n, t):.2f})")
    # Trend lines through the smallest size's fastest time, as guides to the eye.
    n0 = all_n.min()
    t0 = min(r["median_s"] for r in rows if r["n_lights"] == n0)
    span = np.array([all_n.min(), all_n.max()])
    ax.loglog(span, t0 * span / n0, "--", color="0.5", lw=1, label="O(N)")
    ax.loglog(span, t0 * (span / n0) ** 2, ":", color="0.5", lw=1, label="O(N^2)")
    ax.set_xlabel("number of lights N")
    ax.set_ylabel("tree build time (s, median)")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    return save_png(fig, path)


def format_table(rows: list[dict]) -> str:
    head = f"{'N':>9} {'builder':<22} {'median s':>10} {'min s':>10} {'depth':>6}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['n_lights']:>9} {r['builder']:<22} {r['median_s']:>10.4f} {r['min_s']:>10.4f} "
                     f"{r['depth']:>6}")
    builders = list(dict.fromkeys(r["builder"] for r in rows))
    for b in builders:
        n = [r["n_lights"] for r in rows if r["builder"] == b]
        t = [r["median_s"] for r in rows if r["builder"] == b]
        lines.append(f"fitted exponent {b}: {fitted_exponent(np.array(n), np.array(t)):.2f}")
    return "\n".join(lines)


RENDER_CSV_FIELDS = ("n_requested", "n_lights", "builder", "cut_mean", "cut_max", "shadow_rays_per_pixel",
                     "render_s")


def grouped_series(rows: list[dict], group: str, x: str, y: str, symbol: str) -> list[tuple]:
    """One log-log series per value of ``rows[i][group]`` (in first-seen order): ``(label, xs, ys)``
    with the fitted exponent in the label, e.g. ``agglomerative (N^0.02)``."""
    series = []
    for name in dict.fromkeys(r[group] for r in rows):
        xs = np.array([r[x] for r in rows if r[group] == name], float)
        ys = np.array([r[y] for r in rows if r[group] == name], float)
        series.append((f"{name} ({symbol}^{fitted_exponent(xs, ys):.2f})", xs, ys))
    return series


def plot_render_scaling(path: Path, rows: list[dict], title: str) -> Path:
    """Log-log average cut size and render time against N per builder (``lightcuts scaling
    --render``), each builder's fitted exponent in the legend; written atomically."""
    from lightcuts.report.plots import loglog_panels

    panels = [("number of lights N", label, grouped_series(rows, "builder", "n_lights", key, "N"))
              for key, label in (("cut_mean", "average cut size (nodes per eye ray)"), ("render_s", "render time (s)"))]
    return loglog_panels(path, panels, title, (11.0, 4.4))


def format_render_table(rows: list[dict]) -> str:
    head = f"{'N':>9} {'builder':<22} {'avg cut':>9} {'max cut':>8} {'rays/px':>9} {'render s':>9}"
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['n_lights']:>9} {r['builder']:<22} {r['cut_mean']:>9.1f} {r['cut_max']:>8.0f} "
                     f"{r['shadow_rays_per_pixel']:>9.1f} {r['render_s']:>9.3f}")
    for b in dict.fromkeys(r["builder"] for r in rows):
        n = np.array([r["n_lights"] for r in rows if r["builder"] == b], float)
        cut = np.array([r["cut_mean"] for r in rows if r["builder"] == b], float)
        lines.append(f"fitted exponent of the cut size, {b}: {fitted_exponent(n, cut):.2f}")
    return "\n".join(lines)


#: ``lightcuts scaling --gather`` (:mod:`lightcuts.commands.scaling_gather`): a row per (gather
#: points G, integrator). cut_per_pixel: light nodes over a pixel's G eye rays (lightcuts) or
#: (gather, light) pairs (multidimensional); cut_per_gather = cut_per_pixel / G; image_diff_*: the
#: multidimensional image's relative luminance difference from the lightcut's at the same G.
GATHER_CSV_FIELDS = ("gather", "integrator", "image_s", "cut_per_pixel", "shadow_rays_per_pixel", "cut_per_gather",
                     "cut_max_per_pixel", "n_lights", "image_diff_median", "image_diff_max")


def plot_gather_scaling(path: Path, rows: list[dict], title: str) -> Path:
    """Log-log image time and cut per pixel against gather points per pixel, one series per
    integrator with its fitted exponent in the legend; written atomically."""
    from lightcuts.report.plots import loglog_panels

    keys = (("image_s", "image time (s)"), ("cut_per_pixel", "cut per pixel (light nodes or pairs)"))
    panels = [("gather points per pixel G", label, grouped_series(rows, "integrator", "gather", key, "G"))
              for key, label in keys]
    return loglog_panels(path, panels, title, (11.0, 4.4))


def format_gather_table(rows: list[dict]) -> str:
    head = f"{'G':>5} {'integrator':<18} {'image s':>9} {'cut/px':>10} {'cut/G':>8} {'rays/px':>10} {'diff med':>9}"
    lines = [head, "-" * len(head)]
    for r in rows:
        diff = "" if r["image_diff_median"] is None else f"{r['image_diff_median']:.3%}"
        lines.append(f"{r['gather']:>5} {r['integrator']:<18} {r['image_s']:>9.3f} {r['cut_per_pixel']:>10.1f} "
                     f"{r['cut_per_gather']:>8.1f} {r['shadow_rays_per_pixel']:>10.1f} {diff:>9}")
    for name in dict.fromkeys(r["integrator"] for r in rows):
        g = np.array([r["gather"] for r in rows if r["integrator"] == name], float)
        for key, what in (("image_s", "image time"), ("cut_per_pixel", "cut per pixel")):
            y = np.array([r[key] for r in rows if r["integrator"] == name], float)
            lines.append(f"fitted exponent of the {what}, {name}: {fitted_exponent(g, y):.2f}")
    return "\n".join(lines)
