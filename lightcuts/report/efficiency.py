r"""The figures of the efficiency study (``lightcuts study``): an estimator's error against a long
reference, the reference's own share of it, efficiency and the error at a given time
(docs/math.md, "Measuring efficiency").

On luminance Y (:data:`lightcuts.lights.lightset.LUMINANCE`), over the pixels not in ``mask`` (those
that see an emitter directly, :func:`lightcuts.integrators.primary.emitter_mask`):

* relMSE = mean over pixels of (Y_I - Y_R)^2 / (Y_R^2 + epsilon), epsilon = :data:`EPSILON` (0.01,
  in the image's units, as the path-guiding and denoising papers take it: below Y_R ~ 0.1 it turns
  into an absolute error, so that black pixels do not dominate);
* the reference's own relMSE, from its two independent halves A and B (R = (A + B) / 2): the noise
  variance of R per pixel is estimated by (Y_A - Y_B)^2 / 4, whose expectation is Var(Y_R);
  an image independent of R scores relMSE_true + that on average, so :func:`subtract` takes it off;
* the 8x8 RMS: the root mean square of the relative error of 8x8 block means
  (:func:`lightcuts.report.images.compare_images`, its ``block8`` ``rms``; blocks holding a masked
  pixel and blocks darker than 1% of the mean left out), the reference's share taken off in quadrature;
* efficiency = relMSE x seconds (lower is better): for an unbiased estimator relMSE falls as
  1 / time, so the product does not depend on the time;
* the error at a time t: log-log interpolation between the two points of a curve around t
  (:func:`at_time`), None outside the curve.
"""

from __future__ import annotations

import math

import numpy as np

#: relMSE's epsilon, added to the squared reference luminance.
EPSILON = 0.01


def _luminance(image) -> np.ndarray:
    from lightcuts.lights.lightset import LUMINANCE

    return np.asarray(image, np.float64) @ LUMINANCE


def _mean_relative(squared: np.ndarray, y_ref: np.ndarray, mask, epsilon: float) -> float:
    """Mean of ``squared / (y_ref^2 + epsilon)`` over the pixels not in ``mask`` (0 if none)."""
    keep = np.ones(y_ref.shape, bool) if mask is None else ~np.asarray(mask, bool)
    if keep.shape != y_ref.shape:
        raise ValueError(f"mask has shape {keep.shape}; expected {y_ref.shape}")
    return float(np.mean(squared[keep] / (y_ref[keep] ** 2 + epsilon))) if keep.any() else 0.0


def relmse(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None,
           epsilon: float = EPSILON) -> float:
    """Mean of (Y_I - Y_R)^2 / (Y_R^2 + epsilon) over the pixels not in ``mask``; image and
    reference (H, W, 3) linear RGB, mask (H, W) bool (True: left out). 0 when every pixel is masked."""
    y, r = _luminance(image), _luminance(reference)
    if y.shape != r.shape:
        raise ValueError(f"images differ in shape: {np.shape(image)} and {np.shape(reference)}")
    return _mean_relative((y - r) ** 2, r, mask, epsilon)


def reference_relmse(half_a: np.ndarray, half_b: np.ndarray, mask: np.ndarray | None = None,
                     epsilon: float = EPSILON) -> float:
    """The relMSE the reference R = (A + B) / 2 scores against the exact image, estimated from its
    two independent halves: mean of ((Y_A - Y_B)^2 / 4) / (Y_R^2 + epsilon) over the pixels not
    in ``mask``."""
    a, b = _luminance(half_a), _luminance(half_b)
    if a.shape != b.shape:
        raise ValueError(f"halves differ in shape: {np.shape(half_a)} and {np.shape(half_b)}")
    return _mean_relative((a - b) ** 2 / 4.0, (a + b) / 2.0, mask, epsilon)


def subtract(raw: float, noise: float) -> float:
    """An image's relMSE with the reference's own (``noise``) taken off, clamped at 0."""
    return max(0.0, raw - noise)


def subtract_rms(raw: float, noise: float) -> float:
    """An RMS error with the reference's own RMS (``noise``) taken off in quadrature, clamped at 0."""
    return math.sqrt(max(0.0, raw * raw - noise * noise))


def block_rms(image: np.ndarray, reference: np.ndarray, mask: np.ndarray | None = None) -> float | None:
    """RMS relative error of the 8x8 block means (:func:`lightcuts.report.images.compare_images`);
    None for an image smaller than a block."""
    from lightcuts.report.images import compare_images

    block = compare_images(image, reference, mask=mask).get("block8")
    return None if block is None else block["rms"]


def reference_figures(half_a: np.ndarray, half_b: np.ndarray, mask: np.ndarray | None = None,
                      epsilon: float = EPSILON) -> dict:
    """The reference's own noise: {"relmse", "block8_rms"} (None for an image smaller than a block)
    of R = (A + B) / 2 against the exact image, from its halves."""
    from lightcuts.report.images import compare_images

    reference = (np.asarray(half_a, np.float64) + np.asarray(half_b, np.float64)) / 2.0
    noise = compare_images(reference, reference, mask=mask, halves=(half_a, half_b))["reference_noise"]
    return {"relmse": reference_relmse(half_a, half_b, mask, epsilon),
            "block8_rms": noise["block8"]["rms"] if "block8" in noise else None}


def measure(image: np.ndarray, reference: np.ndarray, noise: dict, mask: np.ndarray | None = None,
            epsilon: float = EPSILON) -> dict:
    """An image's figures against the reference whose own are ``noise`` (:func:`reference_figures`):
    {"relmse_raw", "relmse" (the reference's taken off), "block8_rms_raw", "block8_rms"}."""
    raw = relmse(image, reference, mask, epsilon)
    rms = block_rms(image, reference, mask)
    return {"relmse_raw": raw, "relmse": subtract(raw, noise["relmse"]), "block8_rms_raw": rms,
            "block8_rms": None if rms is None or noise["block8_rms"] is None else subtract_rms(rms, noise["block8_rms"])}


def efficiency(relmse_value: float | None, seconds: float) -> float | None:
    """relMSE x seconds (lower is better)."""
    return None if relmse_value is None else float(relmse_value) * float(seconds)


def at_time(seconds, values, t: float) -> float | None:
    """The value of a curve (``seconds`` (K,), ``values`` (K,), any order) at time ``t`` by
    interpolation in log-log between the points just before and after it; the point's own value at a
    point's time; None where ``t`` lies outside the curve's times or a bracketing value is not
    positive (a log needs it)."""
    pts = sorted((float(s), v) for s, v in zip(seconds, values) if v is not None and s > 0)
    if not pts or not pts[0][0] <= t <= pts[-1][0]:
        return None
    for s, v in pts:
        if s == t:
            return float(v)
    (s0, v0), (s1, v1) = next((a, b) for a, b in zip(pts, pts[1:]) if a[0] < t < b[0])
    if v0 <= 0 or v1 <= 0:
        return None
    w = math.log(t / s0) / math.log(s1 / s0)
    return float(math.exp((1 - w) * math.log(v0) + w * math.log(v1)))


def ratios_at_equal_samples(curves: dict) -> tuple[int | None, dict]:
    """Each row's relMSE over the best row's at the largest sample count all rows reached and where
    every row's relMSE is positive. curves : label -> {samples: relMSE}. Returns (that count, label
    -> ratio); (None, {}) without such a count."""
    common = set.intersection(*(set(c) for c in curves.values())) if curves else set()
    for n in sorted(common, reverse=True):
        values = {label: c[n] for label, c in curves.items()}
        if all(v is not None and v > 0 for v in values.values()):
            best = min(values.values())
            return n, {label: v / best for label, v in values.items()}
    return None, {}
