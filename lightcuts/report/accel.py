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
