"""What report.html weighs and what writing it adds to a run: a compare's page (its rows kept in a
row store, so a second run renders nothing) and a render's page, each written ``--repeats`` times.

    python benchmarks/bench_report.py configs/kitchen.yaml --store /tmp/kitchen-rows [--set key=value ...]

The first run renders the compare's rows (the config's size, the default five rows, 1,024 reference
pixels) into ``--store``; later runs read them. Prints the page's size, what an image weighs in it,
and the median time of the page alone (data encoding and HTML).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import load_average, timed  # noqa: E402


def main(argv=None) -> int:
    import lightcuts
    from lightcuts.config import load_config
    from lightcuts.report import pages
    from lightcuts.report.html import encode, write_report

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("config")
    ap.add_argument("--store", required=True, help="the compare's row store (made on the first run)")
    ap.add_argument("--set", dest="overrides", action="append", default=[])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    cfg = load_config(args.config, args.overrides)
    c = lightcuts.compare(cfg, store=args.store, progress=False)
    out = Path(tempfile.mkdtemp())
    page = lambda: write_report(out / "report.html", pages.compare(c))  # noqa: E731
    seconds, _, stats = timed(page, args.repeats, warmup=True)
    h, w = next(iter(c.images.values())).shape[:2]
    image = len(encode(next(iter(c.images.values())))["b64"])
    cut = len(encode(next(iter(c.cut_sizes.values())))["b64"])
    print(f"load {load_average():.2f}; compare of {len(c.rows)} rows at {w}x{h}: "
          f"report.html {stats['bytes'] / 2**20:.2f} MB (an image {image / 2**20:.2f} MB, "
          f"a cut-size map {cut / 2**20:.2f} MB in base64), "
          f"{seconds:.3f} s (median of {args.repeats})")
    r = lightcuts.render(cfg, progress=False)
    seconds, _, stats = timed(lambda: write_report(out / "render.html", pages.render(r)), args.repeats, warmup=True)
    print(f"render at {w}x{h}: report.html {stats['bytes'] / 2**20:.2f} MB, {seconds:.3f} s (median of {args.repeats})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
