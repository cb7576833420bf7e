r"""Tone mapping: linear HDR RGB -> 8-bit sRGB, for the PNGs and the HTML report's viewer.

A tone map is an exposure in stops (the linear values are scaled by ``2**exposure``) and an
operator taking the scaled value ``x >= 0`` to display-linear ``y`` in [0, 1]:

* ``clip``: ``y = min(x, 1)`` per channel (the plain PNG);
* ``reinhard``: Reinhard et al. 2002's global operator on luminance, ``y = x / (1 + L)`` with
  ``L = 0.2126 r + 0.7152 g + 0.0722 b`` (Rec. 709), so hue is kept; channels above 1 are clipped;
* ``aces``: Narkowicz's fit of the ACES filmic curve, ``y = x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)``
  per channel;
* ``hable``: Hable's filmic curve ("Uncharted 2"), ``f(2 x) / f(11.2)`` per channel with
  ``f(x) = (x (A x + C B) + D E) / (x (A x + B) + D F) - E / F``, A..F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30.

``y`` is encoded with the sRGB curve and rounded half up to 8 bits. Negative and NaN values count
as 0 and scaled values are capped at 1e30 (the operators' squares stay finite), so any float input
gives a defined pixel. ``viewer.js`` repeats these formulas operation by operation in float64, so the
viewer shows the PNG's bytes (the browser tests compare the two).
"""

from __future__ import annotations

import numpy as np

#: The operators, in the order the viewer lists them.
OPERATORS = ("clip", "reinhard", "aces", "hable")
#: Scaled values are capped here before the operator, so that its squares stay finite.
X_MAX = 1e30
_HABLE = (0.15, 0.50, 0.10, 0.20, 0.02, 0.30)
_HABLE_WHITE = 11.2


def _hable(x: np.ndarray) -> np.ndarray:
    a, b, c, d, e, f = _HABLE
    return (x * (a * x + c * b) + d * e) / (x * (a * x + b) + d * f) - e / f


def display(rgb: np.ndarray, op: str = "clip", exposure: float = 0.0) -> np.ndarray:
    """(..., 3) linear RGB -> (..., 3) float64 display-linear values in [0, 1]."""
    if op not in OPERATORS:
        raise ValueError(f"tone map {op!r} is not one of {', '.join(OPERATORS)}")
    x = np.nan_to_num(np.asarray(rgb, np.float64), nan=0.0, posinf=X_MAX, neginf=0.0)
    with np.errstate(over="ignore"):  # a large exposure overflows to inf, which the cap takes
        x = np.minimum(np.maximum(x * (2.0 ** exposure), 0.0), X_MAX)
    if op == "reinhard":
        lum = 0.2126 * x[..., 0] + 0.7152 * x[..., 1] + 0.0722 * x[..., 2]
        y = x / (1.0 + lum)[..., None]
    elif op == "aces":
        y = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)
    elif op == "hable":
        y = _hable(2.0 * x) / _hable(np.float64(_HABLE_WHITE))
    else:
        y = x
    return np.minimum(np.maximum(y, 0.0), 1.0)


def srgb_encode(y: np.ndarray) -> np.ndarray:
    """The sRGB curve (IEC 61966-2-1) on display-linear values in [0, 1]."""
    y = np.asarray(y, np.float64)
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1.0 / 2.4) - 0.055)


def srgb8(rgb: np.ndarray, op: str = "clip", exposure: float = 0.0) -> np.ndarray:
    """(H, W, 3) linear RGB -> (H, W, 3) uint8 sRGB through the tone map ``op`` after ``exposure`` stops."""
    return np.floor(srgb_encode(display(rgb, op, exposure)) * 255.0 + 0.5).astype(np.uint8)


def of(tonemap) -> tuple[str, float]:
    """(operator, exposure) of a config's ``render.tonemap`` (anything with ``type`` and ``exposure``);
    None: ``clip`` at 0 stops."""
    return ("clip", 0.0) if tonemap is None else (tonemap.type, float(tonemap.exposure))
