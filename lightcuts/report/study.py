"""The efficiency study's table (Markdown, CSV fields) and its plot of error against time
(:mod:`lightcuts.pipeline.study`, ``lightcuts study``)."""

from __future__ import annotations

from pathlib import Path

#: A ladder point's CSV columns (points.csv): the row, the count and what it counts, the time and its
#: parts, the figures (docs/math.md, "Measuring efficiency").
POINT_FIELDS = ("label", "ladder", "samples", "seconds", "lights_seconds", "build_seconds", "render_seconds",
                "relmse", "relmse_raw", "block8_rms", "block8_rms_raw", "efficiency")


def at_key(measure: str, t: float) -> str:
    """The column of ``measure`` at ``t`` seconds, e.g. ``relmse_at_10s``."""
    return f"{measure}_at_{t:g}s"


def row_fields(times) -> list[str]:
    """table.csv's columns for the error at ``times``."""
    return (["label", "group", "integrator", "builder", "tracer", "ladder", "samples", "seconds", "relmse",
             "relmse_raw", "block8_rms", "block8_rms_raw", "efficiency"]
            + [at_key(m, t) for m in ("relmse", "block8_rms") for t in times]
            + ["ratio_best_builder", "ratio_samples"])


def columns(times) -> list[tuple[str, str, str | None]]:
    """(key, header, format) of the table shown (Markdown and report.html)."""
    cols = [("label", "Row", None), ("samples", "Samples", "{}"), ("ladder", "of", None),
            ("seconds", "Seconds", "{:.2f}"), ("relmse", "relMSE", "{:.3g}"), ("block8_rms", "8x8 RMS", "{:.2%}"),
            ("efficiency", "relMSE x s", "{:.3g}")]
    cols += [(at_key("relmse", t), f"relMSE at {t:g} s", "{:.3g}") for t in times]
    cols += [(at_key("block8_rms", t), f"8x8 RMS at {t:g} s", "{:.2%}") for t in times]
    return cols + [("ratio_best_builder", "relMSE / best builder's", "{:.2f}"), ("ratio_samples", "at samples", "{}")]


def _cell(row: dict, key: str, fmt: str | None) -> str:
    v = row.get(key)
    if v is None:
        return "not reached" if "_at_" in key else ""
    return str(v) if fmt is None else fmt.format(v)


def title(report: dict) -> str:
    ref = report["reference"]
    return (f"{report['name']}: efficiency against {ref['renderer']} at {ref['spp']} spp, "
            f"{report['resolution'][0]}x{report['resolution'][1]}, seed {report['seed']}")


def notes(report: dict) -> list[str]:
    """The lines under the table: the reference's own noise and what was done with it, the mask."""
    ref = report["reference"]
    rms = ref["block8_rms"]
    return [f"The reference's own relMSE {ref['relmse']:.3g} and 8x8 RMS "
            f"{'n/a' if rms is None else f'{100 * rms:.2f}%'} (from its two independent halves) are subtracted "
            "from every row's (relMSE directly, clamped at 0; 8x8 RMS in quadrature); report.json and the CSVs "
            "keep the measured values as *_raw.",
            f"relMSE = mean over pixels of (Y - Y_ref)^2 / (Y_ref^2 + {report['epsilon']:g}), Y luminance; "
            f"{report['masked_pixels']:,} pixels that see an emitter directly are left out of every figure.",
            "Samples: the row's last point (passes or spp); relMSE x s, its efficiency (lower is better); "
            f"'not reached': the row's ladder does not span that time (its budget is {report['budget']:g} s); "
            "relMSE / best builder's: at the largest sample count every builder of that row reached."]


def format_markdown(report: dict) -> str:
    """table.md's text."""
    cols = columns(report["times"])
    lines = [f"# {title(report)}", "", "| " + " | ".join(h for _, h, _ in cols) + " |",
             "|" + "|".join("---" if k == "label" else "---:" for k, _, _ in cols) + "|"]
    for r in report["rows"]:
        lines.append("| " + " | ".join(_cell(r, k, f) for k, _, f in cols) + " |")
    return "\n".join(lines + [""] + notes(report)) + "\n"


def error_time_plot(path: Path, report: dict) -> Path:
    """error-time.png: relMSE and 8x8 RMS against seconds, log-log, one line per row (the
    reference's share taken off; points at 0 left out), the reference's own level dashed."""
    from lightcuts.report.plots import new_figure, readable_log_ticks, save_png

    fig = new_figure((11.0, 4.6), 110, layout="constrained")
    axes = fig.subplots(1, 2)
    ref = report["reference"]
    for ax, key, name in ((axes[0], "relmse", "relMSE"), (axes[1], "block8_rms", "8x8 RMS")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        for r in report["rows"]:
            pts = [p for p in report["points"] if p["label"] == r["label"] and (p[key] or 0) > 0]
            if pts:
                ax.plot([p["seconds"] for p in pts], [p[key] for p in pts], "o-", ms=3, label=r["label"])
        if ref.get(key):
            ax.axhline(ref[key], color="0.4", ls="--", lw=1, label="the reference's own (subtracted)")
        for t in report["times"]:
            ax.axvline(t, color="0.8", lw=0.8)
        ax.set_xlabel("image seconds")
        ax.set_ylabel(f"{name} (the reference's share taken off)")
        ax.grid(True, which="both", alpha=0.3)
        if ax.has_data():
            ax.legend(fontsize="small")
            readable_log_ticks(ax)
    fig.suptitle(title(report))
    return save_png(fig, path)
