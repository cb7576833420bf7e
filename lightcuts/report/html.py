r"""``report.html``: a run's report as one self-contained page that opens offline (no server, no
network): an image viewer, the run's tables (sortable) and plots, its config and machine.

The viewer (``viewer/viewer.js``, ``viewer/viewer.css``, package data, inlined into the page) flips
between the run's images with number keys or buttons; zoom (wheel, +/-) and pan (drag) are shared
by every image; it tone-maps the linear values itself (:mod:`lightcuts.report.tonemap`'s operators,
exposure in stops, the same bytes as the PNGs) and shows the signed relative luminance error of an
image against the reference in false colour: a whole reference image (the render's all-lights
reference, the path tracer's image), another image of the run (a compare row against another), or
a reference known only at a sample of pixels (compare's), shown as squares over the dimmed image.
Pixels of the ``mask`` (those that see an emitter directly) are grey there.

Images travel as float16 (about 3 significant digits: the error view resolves 0.1%), divided by a
power of two so that the largest finite value fits, their bit patterns XORed with the first image
of the same size (an image equal to it, such as the agglomerative-heap row's beside agglomerative's,
then costs next to nothing; one that differs, about as much as alone), their bytes shuffled
(the high bytes of all values, then the low ones) and deflated, in base64: :func:`encode`. The browser inflates them
(``DecompressionStream``, in every browser since 2023). :func:`viewer_values` gives the values the
viewer computes with, for tests.
"""

from __future__ import annotations

import base64
import html
import json
import math
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lightcuts.io import atomic_path

VIEWER = Path(__file__).with_name("viewer")
#: deflate level of the embedded arrays (6 is 5% smaller and twice the time).
LEVEL = 1


@dataclass
class Layer:
    """An image of the viewer: ``values`` (H, W, 3) linear RGB, or (H, W) scalars drawn through the
    colour scale named ``scale`` (a key of ``write_report``'s ``scales``)."""

    name: str
    values: np.ndarray
    scale: str | None = None


@dataclass
class Scale:
    """A colour scale of scalar layers: [``min``, ``max``] through matplotlib's colour map ``map``
    (index floor(256 x), as matplotlib's own lookup)."""

    max: float
    unit: str
    map: str = "inferno"
    min: float = 0.0


@dataclass
class Table:
    """A sortable table: ``columns`` (key, header, format: a ``str.format`` pattern or None for
    ``str``), one dict per row; a missing or None cell is blank."""

    title: str
    columns: list
    rows: list
    note: str = ""


@dataclass
class Page:
    """Everything a report.html shows, in page order."""

    title: str
    subtitle: str = ""
    notes: list = field(default_factory=list)
    layers: list = field(default_factory=list)
    scales: dict = field(default_factory=dict)
    #: index of the layer the error view compares with by default
    reference: int | None = None
    #: a reference known at a sample of pixels: (xy (K, 2) int, window coordinates; rgb (K, 3))
    sample: tuple | None = None
    #: (H, W) bool, pixels that see an emitter directly (grey in the error view)
    mask: np.ndarray | None = None
    #: the image window's top-left pixel in the full image (a crop's x0, y0), for the readout
    origin: tuple = (0, 0)
    tonemap: object = None
    tables: list = field(default_factory=list)
    #: (caption, PNG path)
    plots: list = field(default_factory=list)
    config: dict | None = None
    machine: dict | None = None
    record: dict | None = None


def _scale_log2(a: np.ndarray) -> int:
    finite = np.abs(a[np.isfinite(a)])
    top = float(finite.max()) if finite.size else 0.0
    return math.ceil(math.log2(top)) - 15 if top > 0 else 0


def _typed(a: np.ndarray, dtype: str) -> tuple[np.ndarray, int]:
    """(a in ``dtype``, scale_log2): f16 values divided by 2**scale_log2 first, so that the largest
    finite one lands in [2^14, 2^15] (0 for f32 and u8)."""
    k = _scale_log2(a.astype(np.float64)) if dtype == "f16" else 0
    typed = {"f16": np.float16, "f32": np.float32, "u8": np.uint8}[dtype]
    with np.errstate(over="ignore", invalid="ignore"):
        return np.ascontiguousarray((a / 2.0 ** k if k else a).astype(typed)), k


def encode(a: np.ndarray, dtype: str = "f16", base: tuple[int, np.ndarray] | None = None) -> dict:
    """An array for the page: {"dtype", "shape", "scale_log2", "b64", "xor"} (:func:`_typed`).
    base : (its index in the page, an f16 array of the same shape), or None: this array's float16
        bit patterns are XORed with base's (recorded as "xor"): zeros where the two are equal."""
    typed, k = _typed(np.asarray(a), dtype)
    raw = typed.view(np.uint16) if dtype == "f16" else typed.view(np.uint8)
    if base is not None:
        raw = raw ^ _typed(np.asarray(base[1]), "f16")[0].view(np.uint16)
    shuffled = raw.view(np.uint8).reshape(-1, typed.itemsize).T.tobytes()
    return {"dtype": dtype, "shape": list(typed.shape), "scale_log2": k, "xor": None if base is None else base[0],
            "b64": base64.b64encode(zlib.compress(shuffled, LEVEL)).decode("ascii")}


def viewer_values(a: np.ndarray) -> np.ndarray:
    """float64: the values the viewer decodes from ``encode(a)`` (float16 rounding, the power-of-two scale)."""
    a = np.asarray(a, np.float64)
    k = _scale_log2(a)
    with np.errstate(over="ignore"):
        return (a / 2.0 ** k).astype(np.float16).astype(np.float64) * 2.0 ** k


def colormap(name: str) -> bytes:
    """256 RGB bytes of a matplotlib colour map, as :func:`lightcuts.report.compare.cut_colours` rounds them."""
    from matplotlib import colormaps

    return np.round(colormaps[name](np.arange(256))[:, :3] * 255).astype(np.uint8).tobytes()


def _cell(value, fmt) -> str:
    if value is None:
        return "<td></td>"
    text = fmt.format(value) if fmt else f"{value:.4g}" if isinstance(value, float) else str(value)
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return f'<td class="n" data-v="{value!r}">{html.escape(text)}</td>'
    return f"<td>{html.escape(text)}</td>"


def table_html(t: Table) -> str:
    heads = "".join(f"<th>{html.escape(h)}</th>" for _, h, _ in t.columns)
    body = "\n".join("<tr>" + "".join(_cell(r.get(k), f) for k, _, f in t.columns) + "</tr>" for r in t.rows)
    note = f'<p class="note">{html.escape(t.note)}</p>' if t.note else ""
    return (f"<h2>{html.escape(t.title)}</h2>{note}\n<div class=\"wide\"><table class=\"lc-sortable\"><thead><tr>"
            f"{heads}</tr></thead><tbody>\n{body}\n</tbody></table></div>")


_VIEWER_HTML = """<h2>Images</h2>
<div class="bar" id="lc-layers"></div>
<div class="bar">
 <label>tone map <select id="lc-tonemap"></select></label>
 <label>exposure <input type="range" id="lc-exposure" step="0.1"> <span id="lc-exposure-value"></span> stops</label>
 <label><input type="checkbox" id="lc-error"> error view</label>
 <label>against <select id="lc-against"></select></label>
 <label>range <select id="lc-range"></select></label>
 <button id="lc-fit">fit</button><button id="lc-one">1:1</button>
 <button id="lc-zoom-in">+</button><button id="lc-zoom-out">&minus;</button>
</div>
<div id="lc-stage"><canvas id="lc-canvas" width="960" height="540"></canvas></div>
<div class="bar"><canvas id="lc-legend" width="256" height="30"></canvas><span id="lc-legend-text"></span></div>
<div id="lc-readout"></div>
<p class="keys">Keys: 1-9, 0 image, e error view, [ ] exposure -/+ 0.5 stop, + - zoom, f fit;
 wheel zooms, drag pans.</p>
"""


def page_html(page: Page) -> str:
    """The page's HTML text."""
    from lightcuts.report.tonemap import of

    op, exposure = of(page.tonemap)
    data = {"layers": [], "scales": {k: vars(s) for k, s in page.scales.items()}, "tonemap": {"type": op,
            "exposure": exposure}, "reference": page.reference, "origin": list(page.origin), "mask": None,
            "sample": None, "colormaps": {}}
    first = {}  # shape -> (index, values) of the first image of that shape, the others' XOR base
    for i, layer in enumerate(page.layers):
        v = np.asarray(layer.values)
        base = first.setdefault(v.shape, (i, v)) if v.ndim == 3 else None
        data["layers"].append({"name": layer.name, "kind": "hdr" if v.ndim == 3 else "scalar", "scale": layer.scale,
                               "w": int(v.shape[1]), "h": int(v.shape[0]),
                               "values": encode(v, base=base if base and base[0] != i else None)})
    if page.layers:
        names = {"diverging": "RdBu_r", **{s.map: s.map for s in page.scales.values()}}
        data["colormaps"] = {k: base64.b64encode(colormap(m)).decode("ascii") for k, m in names.items()}
    if page.mask is not None:
        data["mask"] = encode(np.asarray(page.mask, np.uint8), "u8")
    if page.sample is not None:
        xy, rgb = page.sample
        data["sample"] = {"xy": encode(np.asarray(xy, np.float32), "f32"), "rgb": encode(rgb, "f32")}
    parts = [f"<h1>{html.escape(page.title)}</h1>"]
    if page.subtitle:
        parts.append(f'<p class="sub">{html.escape(page.subtitle)}</p>')
    parts += [f'<p class="note">{html.escape(n)}</p>' for n in page.notes]
    if page.layers:
        parts.append(_VIEWER_HTML)
    parts += [table_html(t) for t in page.tables]
    if page.plots:
        parts.append("<h2>Plots</h2>")
        for caption, path in page.plots:
            png = base64.b64encode(Path(path).read_bytes()).decode("ascii")
            parts.append(f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{png}">'
                         f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    if page.machine:
        parts.append(table_html(Table("Machine", [(k, k, None) for k in page.machine], [page.machine])))
    for title, value in (("Config", page.config), ("report.json", page.record)):
        if value is not None:
            parts.append(f"<h2>{title}</h2><details><summary>show</summary><pre>"
                         f"{html.escape(json.dumps(value, indent=2))}</pre></details>")
    script = json.dumps(data, separators=(",", ":")).replace("<", "\\u003c")  # no tag can close or open
    return ("<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(page.title)}</title>\n<style>{(VIEWER / 'viewer.css').read_text()}</style></head>\n"
            f"<body><main>\n{chr(10).join(parts)}\n</main>\n"
            f"<script type=\"application/json\" id=\"lc-data\">{script}</script>\n"
            f"<script>{(VIEWER / 'viewer.js').read_text()}</script>\n</body></html>\n")


def write_report(path, page: Page) -> dict:
    """Write ``page`` to ``path`` (report.html) atomically; returns {"bytes", "seconds"}."""
    t0 = time.perf_counter()
    text = page_html(page)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return {"bytes": len(text.encode("utf-8")), "seconds": time.perf_counter() - t0}
