"""``lightcuts convert IMAGE.exr [--out IMAGE.png] [--tonemap OP] [--exposure STOPS]``: a linear EXR
(any run's ``image.exr``, ``reference.exr``, a compare row's, a path tracer's) as an 8-bit sRGB PNG
through a tone map (:mod:`lightcuts.report.tonemap`), without the config or a render.

``--out`` defaults to the EXR's name with ``.png``; it is written atomically. A missing or unreadable
EXR, an ``--out`` that is not a ``.png`` or cannot be written, or an exposure out of range stops with
one line before anything is written.
"""

from __future__ import annotations

from pathlib import Path

from lightcuts.errors import LightcutsError
from lightcuts.limits import MAX_EXPOSURE

#: The operators, as lightcuts.report.tonemap.OPERATORS (kept here so ``--help`` imports no numpy).
OPERATORS = ("clip", "reinhard", "aces", "hable")


def add_parser(sub) -> None:
    p = sub.add_parser("convert", help="an EXR as a tone-mapped sRGB PNG")
    p.add_argument("image", help="a linear RGB .exr")
    p.add_argument("--out", default=None, help="the PNG (default the EXR's name with .png)")
    p.add_argument("--tonemap", choices=OPERATORS, default="clip",
                   help="clip (default), reinhard (on luminance), aces (Narkowicz's fit) or hable (filmic)")
    p.add_argument("--exposure", type=float, default=0.0, help="stops applied before the tone map (default 0)")
    p.set_defaults(func=run)


def run(args) -> int:
    from lightcuts.config.schema import ToneMap
    from lightcuts.io import check_output_file
    from lightcuts.report.images import read_exr, write_png

    if not abs(args.exposure) <= MAX_EXPOSURE:  # NaN fails too
        raise LightcutsError(f"--exposure {args.exposure}: must be within [-{MAX_EXPOSURE:g}, {MAX_EXPOSURE:g}] stops")
    out = Path(args.out) if args.out else Path(args.image).with_suffix(".png")
    if out.suffix.lower() != ".png":
        raise LightcutsError(f"--out {str(out)!r}: must end in .png")
    check_output_file(out, "--out")
    rgb = read_exr(args.image)
    write_png(out, rgb, ToneMap(type=args.tonemap, exposure=args.exposure))
    print(f"{args.image}: {rgb.shape[1]}x{rgb.shape[0]}, {args.tonemap}, exposure {args.exposure:g} -> {out}")
    return 0

