r"""The outputs of ``lightcuts compare`` (:mod:`lightcuts.commands.compare`): the 2008 paper's Fig. 8
table, cut-size heatmaps on one shared scale, their signed difference, and the machine's description.

A row is a dict with the keys of :data:`COLUMNS` (times in seconds; ``err_median`` / ``err_p99``:
per-pixel relative luminance error against the all-lights reference on the seeded pixel sample,
None without one; ``cut_vs_divisive_6d``: average cut size over divisive-6d's, None without that row)
and ``cut_unit``, what its cut sizes count (the integrator's ``cut_unit`` trait: light nodes per eye
ray for ``lightcuts``, pairs per pixel for ``multidimensional``), which the cut columns' headers and
the colour bars name.

The per-row heatmaps ``cutsize-<label>.png`` are colour-mapped pixel by pixel (one image pixel, one
PNG pixel) through :func:`cut_colours` with the same maximum, so the same cut size has the same colour
in every file; ``cutsizes.png`` shows them side by side under one colour bar, beside the signed
difference of two rows.
"""

from __future__ import annotations

import os
import platform
import re
from pathlib import Path

import numpy as np

from lightcuts.io import atomic_path, save_csv

#: (key, Markdown header, format) of the table's columns, in the paper's order, then ours.
COLUMNS = (
    ("label", "Clustering", "{}"),
    ("build_s", "Build (s)", "{:.3f}"),
    ("preprocess_s", "Preprocess total (s)", "{:.2f}"),
    ("cut_mean", "Avg cutsize", "{:.1f}"),
    ("image_s", "Image time (s)", "{:.2f}"),
    ("summed_s", "Summed time (s)", "{:.2f}"),
    ("cut_vs_divisive_6d", "Cut / divisive-6d", "{:.3f}"),
    ("cut_max", "Max cut", "{:.0f}"),
    ("shadow_rays_per_pixel", "Shadow rays / pixel", "{:.1f}"),
    ("err_median", "Error median", "{:.3%}"),
    ("err_p99", "Error p99", "{:.3%}"),
)
#: The CSV's columns: the table's plus what a row was made with.
CSV_FIELDS = tuple(k for k, _, _ in COLUMNS) + ("cut_unit", "builder", "metric", "c", "lights", "pixels_compared")
#: The columns whose header names the rows' cut unit.
_CUT_COLUMNS = ("cut_mean", "cut_max")


def cut_unit(rows: list[dict]) -> str | None:
    """The rows' common ``cut_unit`` (None if a row has none or they differ)."""
    units = {r.get("cut_unit") for r in rows}
    return units.pop() if len(units) == 1 else None


def file_label(label: str) -> str:
    """A row label as part of a file name (``agglomerative/walter2008`` -> ``agglomerative-walter2008``)."""
    return re.sub(r"[^A-Za-z0-9_.+-]+", "-", label)


def format_markdown(rows: list[dict], title: str) -> str:
    """The table as Markdown (a blank cell where a value is None); the cut columns' headers name
    the rows' :func:`cut_unit`, e.g. ``Avg cutsize (pairs per pixel)``."""
    unit = cut_unit(rows)
    heads = [f"{h} ({unit})" if unit and k in _CUT_COLUMNS else h for k, h, _ in COLUMNS]
    lines = [f"# {title}", "", "| " + " | ".join(heads) + " |",
             "|" + "|".join("---" if k == "label" else "---:" for k, _, _ in COLUMNS) + "|"]
    for r in rows:
        cells = [("" if r.get(k) is None else fmt.format(r[k])) for k, _, fmt in COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def format_mitsuba(m: dict) -> str:
    """The equal-time comparison with Mitsuba's path tracer as a Markdown section."""
    lines = ["", f"## Lightcuts and path tracing at equal time (Mitsuba {m['version']['version']}, "
                 f"{m['version']['variant']})", "",
             f"Both against Mitsuba's path tracer at {m['reference_spp']} spp ({m['reference_seconds']:.1f} s). "
             "Relative luminance error per pixel and of 8x8-block means.", "",
             "| Renderer | Image time (s) | Energy ratio | Pixel median | Pixel p99 | 8x8 median | 8x8 p99 |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    rows = [(f"lightcuts ({m['lightcuts_row']})", m["lightcuts"]),
            (f"Mitsuba path, {m['equal_time']['spp']} spp", m["equal_time"])]
    if "converging" in m:
        rows += [(f"lightcuts ({m['converging']['label']})", m["converging"]),
                 (f"Mitsuba path, {m['converging_equal_time']['spp']} spp", m["converging_equal_time"])]
    for name, r in rows:
        seconds = r["seconds"]
        ratio = "" if r["energy_ratio"] is None else f"{r['energy_ratio']:.4f}"
        b = r.get("block8", {})
        lines.append(f"| {name} | {seconds:.2f} | {ratio} | {r['pixel']['median']:.2%} | {r['pixel']['p99']:.2%} | "
                     f"{b.get('median', float('nan')):.2%} | {b.get('p99', float('nan')):.2%} |")
    return "\n".join(lines) + "\n"


def write_tables(folder: Path, rows: list[dict], title: str, extra: str = "") -> None:
    """``table.md`` (the table, then ``extra``) and ``table.csv`` in ``folder``, each written atomically."""
    with atomic_path(folder / "table.md") as tmp:
        tmp.write_text(format_markdown(rows, title) + extra)
    save_csv(folder / "table.csv", [{k: r.get(k) for k in CSV_FIELDS} for r in rows], list(CSV_FIELDS))


def shared_max(cut_images: dict[str, np.ndarray]) -> float:
    """The colour scale's top: the largest cut size of all rows (at least 1)."""
    return max([1.0] + [float(np.max(v)) for v in cut_images.values() if v.size])


def cut_colours(values: np.ndarray, vmax: float) -> np.ndarray:
    """(H, W) cut sizes -> (H, W, 3) uint8 RGB through matplotlib's ``inferno`` on [0, vmax]."""
    from matplotlib import colormaps

    x = np.clip(np.asarray(values, np.float64) / vmax, 0.0, 1.0)
    return np.round(colormaps["inferno"](x)[..., :3] * 255).astype(np.uint8)


def write_cut_images(folder: Path, cut_images: dict[str, np.ndarray], diff: tuple[str, str] | None,
                     title: str, unit: str | None = None) -> float:
    """``cutsize-<label>.png`` per row and ``cutsizes.png`` (all rows and the signed difference
    ``diff[0] - diff[1]``, colour bars naming ``unit``); returns the shared maximum."""
    from PIL import Image

    vmax = shared_max(cut_images)
    for label, values in cut_images.items():
        with atomic_path(folder / f"cutsize-{file_label(label)}.png", suffix=".png") as tmp:
            Image.fromarray(cut_colours(values, vmax)).save(tmp, format="PNG")
    _write_grid(folder / "cutsizes.png", cut_images, vmax, diff, title, f" ({unit})" if unit else "")
    return vmax


def _write_grid(path: Path, cut_images: dict, vmax: float, diff, title: str, unit: str) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    labels = list(cut_images)
    panels = len(labels) + (diff is not None)
    h, w = next(iter(cut_images.values())).shape
    size = 3.2
    fig = Figure(figsize=(size * panels + 1.6, size * h / w + 1.0), dpi=110, layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, panels, squeeze=False)[0]
    im = None
    for ax, label in zip(axes, labels):
        im = ax.imshow(cut_images[label], cmap="inferno", vmin=0.0, vmax=vmax, interpolation="nearest")
        ax.set_title(f"{label}\nmean {float(np.mean(cut_images[label])):.1f}", fontsize=8)
        ax.set_axis_off()
    fig.colorbar(im, ax=list(axes[:len(labels)]), fraction=0.02, pad=0.02, label=f"cut size{unit}")
    if diff is not None:
        a, b = diff
        d = cut_images[a].astype(np.float64) - cut_images[b]
        lim = max(1.0, float(np.abs(d).max()))
        ax = axes[-1]
        dm = ax.imshow(d, cmap="RdBu_r", vmin=-lim, vmax=lim, interpolation="nearest")
        ax.set_title(f"{a} - {b}\nmean {float(d.mean()):+.1f}", fontsize=8)
        ax.set_axis_off()
        fig.colorbar(dm, ax=ax, fraction=0.046, pad=0.02, label=f"cut size difference{unit}")
    fig.suptitle(title, fontsize=9)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")


def machine() -> dict:
    """CPU model, cores, numba threads and the versions a timing depends on."""
    import numba

    from lightcuts import __version__

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    try:
        from lightcuts.accel.embree.embree import embree_version

        embree = embree_version()
    except Exception as exc:  # reported, never fatal: the table is still valid
        embree = f"unavailable ({type(exc).__name__})"
    return {"cpu": cpu, "cores": os.cpu_count(), "threads": int(numba.get_num_threads()),
            "machine": platform.machine(), "python": platform.python_version(), "lightcuts": __version__,
            "numba": numba.__version__, "numpy": np.__version__, "embree": embree}
