// The image viewer and sortable tables of a lightcuts report.html (lightcuts/report/html.py writes
// the page and the JSON it reads from the lc-data script element). Plain JavaScript, no library.
//
// Images arrive as linear values (float16, byte-shuffled, deflated, base64; see html.py's encode)
// and are tone-mapped here with the formulas of lightcuts/report/tonemap.py, operation by
// operation in float64, so the canvas shows the PNG's bytes. Scalar maps (cut sizes) go through
// the colour map they name; the error view colours the signed relative luminance error of the
// current image against the reference, (L - L_ref) / L_ref.
"use strict";

(function () {
  const LUM = [0.2126, 0.7152, 0.0722];
  const X_MAX = 1e30;
  const HABLE = [0.15, 0.50, 0.10, 0.20, 0.02, 0.30];
  const hable = (x) => {
    const [a, b, c, d, e, f] = HABLE;
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f;
  };
  const HABLE_WHITE = hable(11.2);
  const OPERATORS = ["clip", "reinhard", "aces", "hable"];

  function finite(v) {
    if (v !== v) return 0.0;  // NaN
    if (v === Infinity) return X_MAX;
    if (v === -Infinity) return 0.0;
    return v;
  }

  // (r, g, b) linear -> [R, G, B] 8-bit sRGB; mirrors tonemap.py's display, srgb_encode and srgb8.
  function toneMap(r, g, b, op, scale, out) {
    let x0 = Math.min(Math.max(finite(r) * scale, 0.0), X_MAX);
    let x1 = Math.min(Math.max(finite(g) * scale, 0.0), X_MAX);
    let x2 = Math.min(Math.max(finite(b) * scale, 0.0), X_MAX);
    if (op === "reinhard") {
      const lum = 0.2126 * x0 + 0.7152 * x1 + 0.0722 * x2;
      const k = 1.0 + lum;
      x0 = x0 / k; x1 = x1 / k; x2 = x2 / k;
    } else if (op === "aces") {
      x0 = (x0 * (2.51 * x0 + 0.03)) / (x0 * (2.43 * x0 + 0.59) + 0.14);
      x1 = (x1 * (2.51 * x1 + 0.03)) / (x1 * (2.43 * x1 + 0.59) + 0.14);
      x2 = (x2 * (2.51 * x2 + 0.03)) / (x2 * (2.43 * x2 + 0.59) + 0.14);
    } else if (op === "hable") {
      x0 = hable(2.0 * x0) / HABLE_WHITE; x1 = hable(2.0 * x1) / HABLE_WHITE; x2 = hable(2.0 * x2) / HABLE_WHITE;
    }
    out[0] = encode8(x0); out[1] = encode8(x1); out[2] = encode8(x2);
    return out;
  }

  function encode8(y) {
    y = Math.min(Math.max(y, 0.0), 1.0);
    const s = y <= 0.0031308 ? 12.92 * y : 1.055 * Math.pow(y, 1.0 / 2.4) - 0.055;
    return Math.floor(s * 255.0 + 0.5);
  }

  // ---- decoding -------------------------------------------------------------------------------

  const HALF = (function () {  // float16 bits -> value
    const t = new Float32Array(65536);
    for (let h = 0; h < 65536; h++) {
      const s = h & 0x8000 ? -1 : 1, e = (h >> 10) & 31, m = h & 1023;
      t[h] = e === 0 ? s * m * Math.pow(2, -24) : e === 31 ? (m ? NaN : s * Infinity)
        : s * (1024 + m) * Math.pow(2, e - 25);
    }
    return t;
  })();

  function bytesOf(b64) {
    const bin = atob(b64), out = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
    return out;
  }

  async function inflate(bytes) {
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Uint8Array(await new Response(stream).arrayBuffer());
  }

  // An array of html.py's encode: {dtype, shape, scale_log2, b64} -> Float32Array (or Uint8Array).
  // `bits`: the float16 bit patterns this one's were XORed with (html.py's encode with `base`),
  // or null; the array's own bit patterns are left in decode.bits.
  async function decode(a, bits) {
    const raw = await inflate(bytesOf(a.b64));
    const size = { f16: 2, f32: 4, u8: 1 }[a.dtype];
    const n = raw.length / size, plain = new Uint8Array(raw.length);
    for (let k = 0; k < size; k++) {  // undo the byte shuffle
      const base = k * n;
      for (let i = 0; i < n; i++) plain[i * size + k] = raw[base + i];
    }
    if (a.dtype === "u8") return plain;
    const out = new Float32Array(n), scale = Math.pow(2, a.scale_log2 || 0);
    if (a.dtype === "f16") {
      const u = new Uint16Array(plain.buffer);
      if (bits) for (let i = 0; i < n; i++) u[i] ^= bits[i];
      for (let i = 0; i < n; i++) out[i] = HALF[u[i]] * scale;
      decode.bits = u;
    } else {
      const f = new Float32Array(plain.buffer);
      for (let i = 0; i < n; i++) out[i] = f[i] * scale;
    }
    return out;
  }

  // ---- the viewer -----------------------------------------------------------------------------

  const $ = (id) => document.getElementById(id);

  async function start() {
    const D = JSON.parse($("lc-data").textContent);
    const tables = document.querySelectorAll("table.lc-sortable");
    tables.forEach(sortable);
    if (!D.layers || !D.layers.length) { document.body.dataset.ready = "1"; return; }
    const layers = [];
    for (const l of D.layers) {
      const v = await decode(l.values, l.values.xor != null ? layers[l.values.xor].bits : null);
      layers.push({ ...l, v, bits: decode.bits });
    }
    const maps = {};
    for (const [name, b64] of Object.entries(D.colormaps)) maps[name] = bytesOf(b64);
    const mask = D.mask ? await decode(D.mask) : null;
    const W = layers[0].w, H = layers[0].h;
    let sample = null;
    if (D.sample) {
      sample = { xy: await decode(D.sample.xy), rgb: await decode(D.sample.rgb) };
      sample.n = sample.xy.length / 2;
    }

    const S = {
      layer: 0, error: false, op: D.tonemap.type, exposure: D.tonemap.exposure,
      against: D.reference != null || D.sample ? "ref" : null, range: 0.1,
      view: { s: 1, x: 0, y: 0 },
    };
    const hdr = layers.map((l, i) => (l.kind === "hdr" ? i : -1)).filter((i) => i >= 0);
    if (S.against === null && hdr.length > 1) S.against = String(hdr[1]);
    if (D.reference != null) S.referenceLayer = D.reference;

    // UI
    const bar = $("lc-layers");
    layers.forEach((l, i) => {
      const b = document.createElement("button");
      b.textContent = (i < 10 ? `${(i + 1) % 10} ` : "") + l.name;
      b.title = l.kind === "hdr" ? "linear image" : `${l.name} (${D.scales[l.scale].unit})`;
      b.onclick = () => { S.layer = i; redraw(); };
      bar.appendChild(b);
    });
    const opSel = $("lc-tonemap");
    OPERATORS.forEach((o) => opSel.add(new Option(o, o)));
    opSel.value = S.op;
    opSel.onchange = () => { S.op = opSel.value; redraw(); };
    const exp = $("lc-exposure"), expOut = $("lc-exposure-value");
    exp.min = Math.min(-10, Math.floor(S.exposure)); exp.max = Math.max(10, Math.ceil(S.exposure));
    exp.value = S.exposure;
    exp.oninput = () => { S.exposure = parseFloat(exp.value); redraw(); };
    const errBox = $("lc-error"), against = $("lc-against"), range = $("lc-range");
    if (D.reference != null || sample) against.add(new Option("reference", "ref"));
    hdr.forEach((i) => against.add(new Option(layers[i].name, String(i))));
    if (S.against !== null) against.value = S.against;
    against.onchange = () => { S.against = against.value; redraw(); };
    [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1].forEach((r) => range.add(new Option(`+-${r * 100}%`, String(r))));
    range.value = String(S.range);
    range.onchange = () => { S.range = parseFloat(range.value); redraw(); };
    errBox.disabled = S.against === null;
    errBox.onchange = () => { S.error = errBox.checked; redraw(); };

    const canvas = $("lc-canvas"), ctx = canvas.getContext("2d");
    const off = document.createElement("canvas");
    off.width = W; off.height = H;
    const offCtx = off.getContext("2d");
    const pixels = offCtx.createImageData(W, H);
    let drawnKey = null;

    function lum(v, i) { return 0.2126 * v[3 * i] + 0.7152 * v[3 * i + 1] + 0.0722 * v[3 * i + 2]; }

    // The reference of the error view: {kind: "full", v} or {kind: "sample"}, or null.
    function reference() {
      if (S.against === null) return null;
      if (S.against === "ref") return D.reference != null ? { kind: "full", v: layers[D.reference].v, layer: D.reference }
        : { kind: "sample" };
      return { kind: "full", v: layers[+S.against].v, layer: +S.against };
    }

    // 1% of the reference's mean luminance over the pixels not masked, as relative_error's floor.
    function floorOf(ref) {
      let sum = 0, n = 0;
      if (ref.kind === "full") {
        for (let i = 0; i < W * H; i++) if (!mask || !mask[i]) { sum += lum(ref.v, i); n++; }
      } else {
        for (let k = 0; k < sample.n; k++) { sum += lum(sample.rgb, k); n++; }
      }
      return n ? 0.01 * sum / n : 0;
    }

    function errorColour(e, out) {
      const x = (e / S.range + 1) / 2, map = maps.diverging;
      const j = Math.max(0, Math.min(255, Math.floor(x * 256)));
      out[0] = map[3 * j]; out[1] = map[3 * j + 1]; out[2] = map[3 * j + 2];
      return out;
    }

    function paint() {  // the current layer (or its error view) into `pixels`, at image resolution
      const l = layers[S.layer], d = pixels.data, c = [0, 0, 0], scale = Math.pow(2, S.exposure);
      const ref = S.error && l.kind === "hdr" ? reference() : null;
      const key = [S.layer, S.op, S.exposure, ref ? S.against + ":" + S.range : "-"].join("|");
      if (key === drawnKey) return;
      if (ref && ref.kind === "full") {
        const floor = floorOf(ref);
        for (let i = 0; i < W * H; i++) {
          const r = lum(ref.v, i);
          if (mask && mask[i]) { c[0] = c[1] = c[2] = 96; }
          else if (!(r > floor)) { c[0] = c[1] = c[2] = 32; }
          else errorColour((lum(l.v, i) - r) / r, c);
          d[4 * i] = c[0]; d[4 * i + 1] = c[1]; d[4 * i + 2] = c[2]; d[4 * i + 3] = 255;
        }
      } else if (l.kind === "hdr") {
        const dim = ref ? 0.35 : 1;  // under the sample's markers the image is dimmed
        for (let i = 0; i < W * H; i++) {
          toneMap(l.v[3 * i], l.v[3 * i + 1], l.v[3 * i + 2], S.op, scale, c);
          d[4 * i] = c[0] * dim; d[4 * i + 1] = c[1] * dim; d[4 * i + 2] = c[2] * dim; d[4 * i + 3] = 255;
        }
      } else {
        const sc = D.scales[l.scale], map = maps[sc.map];
        for (let i = 0; i < W * H; i++) {
          const x = Math.min(Math.max((finite(l.v[i]) - sc.min) / (sc.max - sc.min), 0), 1);
          const j = Math.min(255, Math.floor(x * 256));
          d[4 * i] = map[3 * j]; d[4 * i + 1] = map[3 * j + 1]; d[4 * i + 2] = map[3 * j + 2]; d[4 * i + 3] = 255;
        }
      }
      offCtx.putImageData(pixels, 0, 0);
      drawnKey = key;
    }

    function markers() {  // the sample reference's pixels, coloured by the error there
      const l = layers[S.layer], c = [0, 0, 0], floor = floorOf({ kind: "sample" });
      const size = Math.max(S.view.s, 5);
      for (let k = 0; k < sample.n; k++) {
        const x = sample.xy[2 * k], y = sample.xy[2 * k + 1], r = lum(sample.rgb, k);
        if (!(r > floor)) continue;
        errorColour((lum(l.v, y * W + x) - r) / r, c);
        const cx = S.view.x + (x + 0.5) * S.view.s, cy = S.view.y + (y + 0.5) * S.view.s;
        ctx.fillStyle = "#000";
        ctx.fillRect(Math.round(cx - size / 2) - 1, Math.round(cy - size / 2) - 1, size + 2, size + 2);
        ctx.fillStyle = `rgb(${c[0]},${c[1]},${c[2]})`;
        ctx.fillRect(Math.round(cx - size / 2), Math.round(cy - size / 2), size, size);
      }
    }

    function legend() {
      const l = layers[S.layer], el = $("lc-legend"), g = el.getContext("2d");
      const ref = S.error && l.kind === "hdr" ? reference() : null;
      g.clearRect(0, 0, el.width, el.height);
      let map = null, lo = "", hi = "", mid = "";
      if (ref) {
        map = maps.diverging; lo = `-${S.range * 100}%`; hi = `+${S.range * 100}%`; mid = "0";
        $("lc-legend-text").textContent = ref.kind === "full"
          ? "(L - L_ref) / L_ref; dark grey: below 1% of the reference's mean, light grey: sees an emitter (left out)"
          : "(L - L_ref) / L_ref at the reference's pixels (squares); the image dimmed";
      } else if (l.kind === "scalar") {
        const sc = D.scales[l.scale];
        map = maps[sc.map]; lo = `${+sc.min.toPrecision(4)}`; hi = `${+sc.max.toPrecision(4)}`;
        $("lc-legend-text").textContent = sc.unit;
      } else {
        $("lc-legend-text").textContent = `${S.op}, ${S.exposure >= 0 ? "+" : ""}${S.exposure} stops`;
      }
      expOut.textContent = `${S.exposure >= 0 ? "+" : ""}${(+S.exposure).toFixed(1)}`;
      if (!map) return;
      for (let x = 0; x < 256; x++) {
        g.fillStyle = `rgb(${map[3 * x]},${map[3 * x + 1]},${map[3 * x + 2]})`;
        g.fillRect(x, 0, 1, 12);
      }
      g.fillStyle = "#ddd"; g.font = "11px sans-serif";
      g.textAlign = "left"; g.fillText(lo, 0, 26);
      g.textAlign = "center"; g.fillText(mid, 128, 26);
      g.textAlign = "right"; g.fillText(hi, 256, 26);
    }

    function redraw() {
      paint();
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = "#222";
      ctx.fillRect(0, 0, canvas.width, canvas.height);
      ctx.imageSmoothingEnabled = false;
      ctx.drawImage(off, S.view.x, S.view.y, W * S.view.s, H * S.view.s);
      const l = layers[S.layer];
      if (S.error && l.kind === "hdr" && reference() && reference().kind === "sample") markers();
      bar.querySelectorAll("button").forEach((b, i) => b.classList.toggle("on", i === S.layer));
      errBox.checked = S.error;
      legend();
    }

    function resize() {
      const w = Math.max(200, canvas.parentElement.clientWidth);
      const h = Math.max(200, Math.min(Math.round(window.innerHeight * 0.72), Math.round(w * H / W) + 2));
      if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; fit(); }
    }
    function fit() {
      const s = Math.min(canvas.width / W, canvas.height / H);
      S.view = { s, x: Math.round((canvas.width - W * s) / 2), y: Math.round((canvas.height - H * s) / 2) };
      redraw();
    }
    function zoomAt(f, px, py) {  // zoom by f about the canvas point (px, py)
      const s = Math.min(64, Math.max(0.05, S.view.s * f));
      S.view = { s, x: px - (px - S.view.x) * s / S.view.s, y: py - (py - S.view.y) * s / S.view.s };
      redraw();
    }
    function oneToOne() {
      S.view = { s: 1, x: Math.round((canvas.width - W) / 2), y: Math.round((canvas.height - H) / 2) };
      redraw();
    }

    $("lc-fit").onclick = fit;
    $("lc-one").onclick = oneToOne;
    $("lc-zoom-in").onclick = () => zoomAt(1.5, canvas.width / 2, canvas.height / 2);
    $("lc-zoom-out").onclick = () => zoomAt(1 / 1.5, canvas.width / 2, canvas.height / 2);
    canvas.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const r = canvas.getBoundingClientRect();
      zoomAt(Math.pow(1.2, -ev.deltaY / 100), ev.clientX - r.left, ev.clientY - r.top);
    }, { passive: false });
    let drag = null;
    canvas.addEventListener("pointerdown", (ev) => {
      drag = { x: ev.clientX, y: ev.clientY, vx: S.view.x, vy: S.view.y };
      canvas.setPointerCapture(ev.pointerId);
    });
    canvas.addEventListener("pointerup", () => { drag = null; });
    canvas.addEventListener("pointermove", (ev) => {
      const r = canvas.getBoundingClientRect();
      if (drag) {
        S.view.x = drag.vx + ev.clientX - drag.x; S.view.y = drag.vy + ev.clientY - drag.y;
        redraw();
      }
      readout(ev.clientX - r.left, ev.clientY - r.top);
    });

    function fmt(v) { return Math.abs(v) >= 1e4 || (v !== 0 && Math.abs(v) < 1e-3) ? v.toExponential(3) : v.toPrecision(4); }
    function readout(px, py) {
      const x = Math.floor((px - S.view.x) / S.view.s), y = Math.floor((py - S.view.y) / S.view.s);
      const out = $("lc-readout");
      if (x < 0 || y < 0 || x >= W || y >= H) { out.textContent = ""; return; }
      const l = layers[S.layer], i = y * W + x;
      let text = `(${x + D.origin[0]}, ${y + D.origin[1]}) ${l.name}: `;
      if (l.kind === "hdr") {
        text += `rgb ${fmt(l.v[3 * i])} ${fmt(l.v[3 * i + 1])} ${fmt(l.v[3 * i + 2])}, L ${fmt(lum(l.v, i))}`;
        const ref = reference();
        if (ref && ref.kind === "full" && ref.layer !== S.layer) {
          const r = lum(ref.v, i);
          text += `; ${layers[ref.layer].name} L ${fmt(r)}, error ${r > 0 ? ((lum(l.v, i) - r) / r * 100).toFixed(2) + "%" : "-"}`;
        }
        if (mask && mask[i]) text += " (sees an emitter)";
      } else {
        text += `${fmt(l.v[i])} ${D.scales[l.scale].unit}`;
      }
      out.textContent = text;
    }

    document.addEventListener("keydown", (ev) => {
      if (ev.target.tagName === "INPUT" || ev.target.tagName === "SELECT" || ev.ctrlKey || ev.metaKey || ev.altKey) return;
      const k = ev.key;
      const n = k === "0" ? 10 : +k;  // keys 1-9, then 0 for the tenth
      if (k.length === 1 && k >= "0" && k <= "9" && n <= layers.length) { S.layer = n - 1; redraw(); }
      else if (k === "e" && !errBox.disabled) { S.error = !S.error; redraw(); }
      else if (k === "f") fit();
      else if (k === "+" || k === "=") zoomAt(1.5, canvas.width / 2, canvas.height / 2);
      else if (k === "-") zoomAt(1 / 1.5, canvas.width / 2, canvas.height / 2);
      else if (k === "[" || k === "]") {
        S.exposure = Math.round((S.exposure + (k === "]" ? 0.5 : -0.5)) * 10) / 10;
        exp.value = S.exposure; redraw();
      } else return;
      ev.preventDefault();
    });
    window.addEventListener("resize", resize);
    resize();
    fit();
    window.lcViewer = { state: S, toneMap, layers, width: W, height: H };
    document.body.dataset.ready = "1";
  }

  // ---- sortable tables: a click on a header sorts by that column (numbers by value) -------------

  function sortable(table) {
    table.querySelectorAll("th").forEach((th, col) => {
      th.addEventListener("click", () => {
        const body = table.tBodies[0], rows = Array.from(body.rows);
        const dir = th.dataset.dir === "asc" ? -1 : 1;
        table.querySelectorAll("th").forEach((h) => delete h.dataset.dir);
        th.dataset.dir = dir === 1 ? "asc" : "desc";
        const val = (r) => {
          const c = r.cells[col], v = c.dataset.v;
          return v !== undefined && v !== "" ? parseFloat(v) : c.textContent;
        };
        rows.sort((a, b) => {
          const x = val(a), y = val(b);
          if (typeof x === "number" && typeof y === "number") return dir * (x - y);
          if (typeof x === "number") return -1;
          if (typeof y === "number") return 1;
          return dir * String(x).localeCompare(String(y));
        });
        rows.forEach((r) => body.appendChild(r));
      });
    });
  }

  start().catch((err) => { console.error(err); document.body.dataset.ready = "error"; });
})();
