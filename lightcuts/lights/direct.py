"""Direct lights: the emissive triangles sampled into oriented point lights (Lightcuts 2005, section 6).

An emissive triangle t has one-sided radiance ``Le_t`` (RGB) along its normal and area ``A_t``; its
power is ``pi * Le_t * A_t``. Its contribution to a receiver is the integral over the triangle of
``Le_t * cos_l * G``, estimated by point lights on the triangle: a light at ``y`` with intensity ``I``
along the triangle's normal contributes ``I * max(0, n . w) / r^2``, so the estimator is unbiased
when ``E[sum_k I_k g(y_k)] = sum_t Le_t * integral_t g dA`` for every function ``g`` on the emitters.

Sampling (``count`` = N lights over E emitter triangles of non-zero power, weight ``w_t = A_t *
luminance(Le_t)``):

* N >= E (the usual case: a few large emitters, many lights): proportional allocation, a stratified
  sample with the triangles as strata. Triangle t gets a fixed number ``n_t >= 1`` of lights,
  ``n_t`` as close to ``N * w_t / sum(w)`` as the floor of one allows (largest remainders), and each
  of its lights has intensity ``Le_t * A_t / n_t``. The positions within the triangle are a jittered
  Hammersley set (first coordinate stratified in ``n_t`` strata, second a randomly shifted radical
  inverse) mapped by the area-preserving square-to-triangle map. Because ``n_t`` does not depend on
  the random numbers, the estimator is unbiased, and the total power is exact per RGB channel:
  ``sum_k pi * I_k = pi * sum_t Le_t * A_t``.
* N < E (finely tessellated emitters): some triangles must go without a light, and then no
  estimator is both unbiased and exact per channel when the emitters differ in colour (a light in a
  red triangle cannot carry a green one's power without biasing where that power lands). We keep it
  unbiased: jittered stratified sampling of the power CDF (one stratum of width 1/N per light), the
  remainder of the stratum sample reused as one coordinate inside the chosen triangle, and the
  Horvitz-Thompson weight ``I_k = Le_t * A_t / (N * p_t) = Le_t * sum(w) / (N * luminance(Le_t))``.
  Every light then carries exactly ``sum(w) / N`` of luminance, so the total luminance power is exact;
  RGB power is exact when all emitters share one chromaticity, and exact in expectation otherwise.
"""

from __future__ import annotations

import numpy as np

from lightcuts.lights.lightset import LUMINANCE, LightSet


def radical_inverse_base2(i: np.ndarray) -> np.ndarray:
    """(n,) float64 in [0, 1): van der Corput's radical inverse of the integers ``i`` (bits reversed)."""
    x = np.asarray(i, np.uint64) & np.uint64(0xFFFFFFFF)
    for shift, mask in ((16, 0x0000FFFF), (8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
        s, m = np.uint64(shift), np.uint64(mask)
        x = ((x >> s) & m) | ((x & m) << s)
    return x.astype(np.float64) * 2.0 ** -32


def square_to_triangle(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-preserving map of the unit square onto the triangle ``b0, b1 >= 0, b0 + b1 <= 1``.

    The low-distortion map of Heitz (2019), as in pbrt-v4's ``SampleUniformTriangle``: it keeps
    stratified points stratified, which the classic ``sqrt`` map distorts. Returns (b0, b1).
    """
    first = u < v
    b0 = np.where(first, u / 2, u - v / 2)
    b1 = np.where(first, v - u / 2, v / 2)
    return b0, b1


def allocate_proportional(weights: np.ndarray, n: int) -> np.ndarray:
    """(E,) int64 counts >= 1 summing to ``n`` (``n >= E``), proportional to ``weights`` where possible.

    Strata whose proportional quota is below one get exactly one; the rest share what remains in
    proportion to their weights (repeated until no quota falls below one), rounded by largest
    remainders with ties to the lower index (Hamilton's method): deterministic.
    """
    w = np.asarray(weights, np.float64)
    if n < len(w):
        raise ValueError(f"cannot give {len(w)} strata at least one of {n} samples")
    fixed = np.zeros(len(w), bool)
    while True:
        free = ~fixed
        quota = np.zeros(len(w))
        quota[free] = (n - np.count_nonzero(fixed)) * w[free] / w[free].sum()
        newly = free & (quota < 1.0)
        if not newly.any():
            break
        fixed |= newly
    counts = np.where(fixed, 1, np.floor(quota)).astype(np.int64)
    frac = np.where(fixed, -1.0, quota - np.floor(quota))
    order = np.argsort(-frac, kind="stable")
    counts[order[: n - counts.sum()]] += 1
    return counts


def direct_lights(scene, count: int, seed: int) -> LightSet:
    """Sample the scene's emissive triangles into ``count`` oriented lights (see the module docstring).

    scene : Scene with ``emission`` (F, 3) radiance, W/(m^2 sr), one-sided along the face normal
    count : number of lights (> 0)
    seed : int, the only source of randomness (``np.random.default_rng(seed)``)

    Returns an ``oriented`` LightSet: positions on the emitter triangles, the emitters' unit normals,
    intensity (count, 3) W/sr, ``indirect`` all False. Empty if the scene emits no power.
    """
    count = int(count)
    tri = scene.emitters
    area = scene.face_areas[tri]
    le = scene.emission[tri]
    weight = area * (le @ LUMINANCE)
    keep = weight > 0  # zero-area emitters have no power: no light goes there
    tri, area, le, weight = tri[keep], area[keep], le[keep], weight[keep]
    if count <= 0 or len(tri) == 0:
        return LightSet(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), "oriented")
    rng = np.random.default_rng(seed)
    if count >= len(tri):
        n_t = allocate_proportional(weight, count)
        which = np.repeat(np.arange(len(tri)), n_t)
        first = np.cumsum(n_t) - n_t
        i = np.arange(count) - first[which]  # index of the light within its triangle
        u = (i + rng.random(count)) / n_t[which]
        v = (radical_inverse_base2(i) + rng.random(len(tri))[which]) % 1.0
        intensity = le[which] * (area / n_t)[which, None]
    else:
        cdf = np.cumsum(weight)
        total = cdf[-1]
        x = (np.arange(count) + rng.random(count)) / count * total
        which = np.minimum(np.searchsorted(cdf, x, side="right"), len(tri) - 1)
        lo = cdf[which] - weight[which]
        u = np.clip((x - lo) / weight[which], 0.0, np.nextafter(1.0, 0.0))
        v = (radical_inverse_base2(np.arange(count)) + rng.random()) % 1.0
        intensity = le[which] * (total / (count * (le[which] @ LUMINANCE)))[:, None]
    b0, b1 = square_to_triangle(u, v)
    corners = scene.triangles[tri[which]]
    position = corners[:, 0] + b0[:, None] * (corners[:, 1] - corners[:, 0]) \
        + b1[:, None] * (corners[:, 2] - corners[:, 0])
    normal = scene.face_normals[tri[which]]
    return LightSet(position, normal, intensity, "oriented", np.zeros(count, bool),
                    {"direct_count": count, "direct_emitters": len(tri)})
