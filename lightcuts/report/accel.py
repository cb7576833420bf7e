r"""The table of ``lightcuts accel`` (:mod:`lightcuts.commands.accel`): the 2008 paper's Fig. 6
(triangles, build time, E(boxes), E(tris), E(cost), nodes) and the 1995 paper's study (memory,
voxels / items nu_1, depth, references per item), with eye and shadow image times.

A row is a dict: caster, triangles, build_s, build_tris_per_s, eye_s, shadows_s (seconds),
eye_mrays_per_s, shadows_mrays_per_s, eye_vs_first, shadows_vs_first (time over the first row's),
eye_mismatch, shadow_mismatch (rays answered differently from the first row), and whatever the
caster's ``stats()`` gave (the keys of :data:`COLUMNS` it has; other keys go to the CSV only).
A cell a caster has no value for is blank.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightcuts.io import atomic_path, save_csv

#: (key, Markdown header, format).
COLUMNS = (
    ("caster", "Caster", "{}"),
    ("triangles", "Triangles", "{:,}"),
    ("build_s", "Build (s)", "{:.3f}"),
    ("build_tris_per_s", "Build (Mtris/s)", None),
    ("E_boxes", "E(boxes)", "{:.1f}"),
    ("E_tris", "E(tris)", "{:.1f}"),
    ("E_cost", "E(cost)", "{:.1f}"),
    ("nodes", "Nodes", "{:,}"),
    ("memory_bytes", "Memory (MB)", None),
    ("voxels", "Voxels", "{:,}"),
    ("nu_1", "nu_1", "{:.2f}"),
    ("depth", "Depth", "{}"),
    ("refs_per_item", "Refs / item", "{:.2f}"),
    ("eye_s", "Eye (s)", "{:.3f}"),
    ("eye_vs_first", "Eye / first", "{:.2f}"),
    ("shadows_s", "Shadows (s)", "{:.3f}"),
    ("shadows_vs_first", "Shadows / first", "{:.2f}"),
    ("eye_mismatch", "Eye rays differing", "{:,}"),
    ("shadow_mismatch", "Shadow-image rays differing", "{:,}"),
)


def _cell(key: str, fmt: str | None, value) -> str:
    if value is None:
        return ""
    if key == "build_tris_per_s":
        return f"{value / 1e6:.2f}"
    if key == "memory_bytes":
        return f"{value / 2**20:.1f}"
    return fmt.format(value)


def format_markdown(rows: list[dict], title: str) -> str:
    """The table as Markdown, with only the columns some row has."""
    cols = [c for c in COLUMNS if any(r.get(c[0]) is not None for r in rows)]
    lines = [f"# {title}", "", "| " + " | ".join(h for _, h, _ in cols) + " |",
             "|" + "|".join("---" if k == "caster" else "---:" for k, _, _ in cols) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(_cell(k, f, r.get(k)) for k, _, f in cols) + " |")
    return "\n".join(lines) + "\n"


def write_tables(folder: Path, rows: list[dict], title: str) -> None:
    """``table.md`` and ``table.csv`` (every key of every row) in ``folder``, each atomically."""
    with atomic_path(folder / "table.md") as tmp:
        tmp.write_text(format_markdown(rows, title))
    keys = list(dict.fromkeys(k for r in rows for k in r))
    save_csv(folder / "table.csv", [{k: r.get(k) for k in keys} for r in rows], keys)


def _series(rows: list[dict], caster: str, key: str) -> tuple[np.ndarray, np.ndarray]:
    pts = [(r["triangles"], r[key]) for r in rows if r["caster"] == caster and r.get(key) is not None]
    return np.array([p[0] for p in pts], float), np.array([p[1] for p in pts], float)


def format_sweep(rows: list[dict]) -> str:
    """The growing-scenes summary (the 1995 paper's Figs. 11-13) as Markdown: per caster, the fitted
    exponents of eye-image time and memory against triangles, and at each size HUG's memory and eye
    time over the recursive grid's (MAXP 50 and 150) where those rows exist."""
    from lightcuts.report.scaling import fitted_exponent

    casters = list(dict.fromkeys(r["caster"] for r in rows))
    lines = ["# Growing scenes", "", "| Caster | Eye time ~ N^b | Memory ~ N^b | Largest scene: eye (s) | memory (MB) |",
             "|---|---:|---:|---:|---:|"]
    for c in casters:
        n, eye = _series(rows, c, "eye_s")
        _, mem = _series(rows, c, "memory_bytes")
        last = [r for r in rows if r["caster"] == c][-1]
        mem_last = "" if last.get("memory_bytes") is None else f"{last['memory_bytes'] / 2**20:.1f}"
        mem_b = "" if len(mem) < 2 else f"{fitted_exponent(n, mem):.2f}"
        lines.append(f"| {c} | {fitted_exponent(n, eye):.2f} | {mem_b} | {last['eye_s']:.3f} | {mem_last} |")
    by = {(r["caster"], r["triangles"]): r for r in rows}
    sizes = sorted({r["triangles"] for r in rows})
    if all((c, n) in by for c in ("hug", "recursive-grid-50") for n in sizes):
        lines += ["", "| Triangles | HUG memory / recursive-grid-50 | HUG eye / recursive-grid-50 | "
                      "HUG eye / recursive-grid-150 |", "|---:|---:|---:|---:|"]
        for n in sizes:
            h, r50 = by[("hug", n)], by[("recursive-grid-50", n)]
            r150 = by.get(("recursive-grid-150", n))
            vs150 = "" if r150 is None else f"{h['eye_s'] / r150['eye_s']:.2f}"
            lines.append(f"| {n:,} | {h['memory_bytes'] / r50['memory_bytes']:.2f} | {h['eye_s'] / r50['eye_s']:.2f} | "
                         f"{vs150} |")
    return "\n".join(lines) + "\n"


def plot_sweep(path: Path, rows: list[dict], title: str) -> Path:
    """Log-log eye-image time and memory against triangles per caster; written atomically."""
    from lightcuts.report.plots import loglog_panels

    panels = []
    for key, scale, label in (("eye_s", 1.0, "eye image time (s)"), ("memory_bytes", 2.0 ** -20, "memory (MB)")):
        series = []
        for c in dict.fromkeys(r["caster"] for r in rows):
            n, y = _series(rows, c, key)
            if len(n):
                series.append((c, n, y * scale))
        panels.append(("triangles", label, series))
    return loglog_panels(path, panels, title, (11.0, 4.6), legend_size="x-small")
