r"""``lightcuts scaling``: light-tree build time against the number of lights (the 2008 paper's Fig. 9).

For every size N, the config's scene gets N indirect VPLs (``lights.indirect.count = N``, no direct
lights, no sun or environment); every builder builds a tree over them (``build_tree``: topology plus
bounds, cones, intensities and representatives), once to warm up numba and then ``repeats`` timed
runs, of which the median is reported. Outputs, written atomically to ``--out`` (default
``renders/<name>-scaling/``):

- ``scaling.csv``: n_requested, n_lights, builder, median_s, min_s, repeats, depth;
- ``scaling.png``: log-log build time against N per builder, O(N) and O(N^2) trend lines, and each
  builder's fitted exponent (least squares on log t = a + b log N) in the legend.

The particle tracer returns about N VPLs (its paths end by Russian roulette), so the plots use the
actual count. Timings are wall-clock on a possibly shared machine: compare builders within a run.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from lightcuts.errors import LightcutsError
from lightcuts.io import atomic_path, save_csv

# The greedy reference is O(N^2) (at best): above this size a scaling run would take hours.
GREEDY_MAX_N = 20000
CSV_FIELDS = ("n_requested", "n_lights", "builder", "median_s", "min_s", "repeats", "depth")


def parse_sizes(text: str) -> list[int]:
    """``"50000,100000"`` -> [50000, 100000]; LightcutsError for anything but positive integers."""
    try:
        sizes = [int(s) for s in str(text).replace(" ", "").split(",") if s]
    except ValueError:
        raise LightcutsError(f"--sizes {text!r}: expected comma-separated positive integers") from None
    if not sizes or min(sizes) < 1:
        raise LightcutsError(f"--sizes {text!r}: expected comma-separated positive integers")
    return sorted(set(sizes))


def resolve_builders(text: str | None) -> list[str]:
    """Builder names from ``--builders`` (default: every registered builder but greedy), checked."""
    from lightcuts.trees.registry import BUILDERS, get_builder, load_builtins

    load_builtins()
    if text is None:
        return [b for b in BUILDERS.names() if b != "greedy"]
    names = [b.strip() for b in text.split(",") if b.strip()]
    if not names:
        raise LightcutsError("--builders: no builder names given")
    for b in names:
        get_builder(b)  # LightcutsError listing the valid names
    return names


def fitted_exponent(n: np.ndarray, seconds: np.ndarray) -> float:
    """Slope b of log t = a + b log N (least squares); nan with fewer than two sizes."""
    n, seconds = np.asarray(n, float), np.asarray(seconds, float)
    ok = (n > 0) & (seconds > 0)
    if len(np.unique(n[ok])) < 2:
        return float("nan")
    return float(np.polyfit(np.log(n[ok]), np.log(seconds[ok]), 1)[0])


def time_builder(lights, builder: str, repeats: int, metric: str, c, seed: int) -> tuple[float, float, int]:
    """(median s, min s, depth) of ``repeats`` timed build_tree calls (the caller warms up numba)."""
    from lightcuts.trees.build import build_tree

    times = []
    tree = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        tree = build_tree(lights, builder=builder, metric=metric, c=c, seed=seed)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), tree.depth()


def write_csv(path: Path, rows: list[dict]) -> Path:
    return save_csv(path, rows, CSV_FIELDS)


def plot_scaling(path: Path, rows: list[dict], title: str) -> Path:
    """Log-log build time against N per builder, with O(N) and O(N^2) guides; written atomically."""
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:
        raise LightcutsError("scaling plot needs matplotlib: pip install matplotlib") from None

    fig = Figure(figsize=(6.4, 4.8), dpi=120)
    FigureCanvasAgg(fig)
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
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png")
    return path


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


def run_scaling(args) -> list[dict]:
    """The ``lightcuts scaling`` command (args: config, overrides, sizes, builders, repeats, out).

    Returns the table rows (also written to ``scaling.csv``).
    """
    from tqdm import tqdm

    from lightcuts.config import load_config
    from lightcuts.pipeline import make_caster, make_lights, make_scene

    sizes = parse_sizes(args.sizes)
    builders = resolve_builders(args.builders)
    repeats = int(args.repeats)
    if repeats < 1:
        raise LightcutsError(f"--repeats {repeats}: must be at least 1")
    if "greedy" in builders and max(sizes) > GREEDY_MAX_N:
        raise LightcutsError(f"--builders greedy: the O(N^2) reference is for N <= {GREEDY_MAX_N}, "
                             f"got --sizes up to {max(sizes)}")
    overrides = list(args.overrides or [])
    base = overrides + ["lights.direct.count=0", "lights.sun=null", "lights.environment=null"]
    cfg = load_config(args.config, base + [f"lights.indirect.count={sizes[0]}"])
    out = Path(args.out) if args.out else Path("renders") / f"{cfg.name}-scaling"
    scene = make_scene(cfg)
    caster = make_caster(cfg, scene)

    rows = []
    warmed = set()
    with tqdm(total=len(sizes) * len(builders), desc="scaling", unit="tree") as bar:
        for n in sizes:
            cfg_n = load_config(args.config, base + [f"lights.indirect.count={n}"])
            bar.set_postfix_str(f"tracing {n} VPLs")
            lights = make_lights(cfg_n, scene, caster)["oriented"]
            for b in builders:
                bar.set_postfix_str(f"N={len(lights)} {b}")
                if b not in warmed:  # numba compiles (or loads its cache) on the first call
                    time_builder(lights, b, 1, cfg.tree.metric, cfg.tree.c, cfg.seed)
                    warmed.add(b)
                med, best, depth = time_builder(lights, b, repeats, cfg.tree.metric, cfg.tree.c, cfg.seed)
                rows.append(dict(n_requested=n, n_lights=len(lights), builder=b, median_s=med, min_s=best,
                                 repeats=repeats, depth=depth))
                bar.update(1)
    write_csv(out / "scaling.csv", rows)
    plot_scaling(out / "scaling.png", rows,
                 f"{cfg.name}: light tree build time ({cfg.tree.metric}, median of {repeats})")
    print(format_table(rows))
    print(f"-> {out / 'scaling.csv'}, {out / 'scaling.png'}")
    return rows
