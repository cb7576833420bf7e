"""The efficiency study's figures (lightcuts.report.efficiency) on synthetic images whose error is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lightcuts.report.efficiency import (EPSILON, at_time, block_rms, measure, ratios_at_equal_samples,
                                         reference_figures, reference_relmse, relmse, subtract, subtract_rms)

H = W = 512


def _grey(lum: np.ndarray) -> np.ndarray:
    """(H, W, 3) with every channel ``lum``: its luminance is ``lum`` (the weights sum to 1)."""
    return np.repeat(np.asarray(lum, np.float64)[..., None], 3, axis=2)


def _scene(seed: int = 0) -> np.ndarray:
    """A smooth luminance field from 0.05 to 2 (both sides of sqrt(epsilon))."""
    y, x = np.mgrid[0:H, 0:W] / H
    return 0.05 + 1.95 * (0.5 + 0.5 * np.sin(6 * x + 3 * y + seed)) ** 2


def test_known_noise_gives_known_relmse():
    rng = np.random.default_rng(1)
    mu = _scene()
    sigma = 0.02 + 0.1 * mu  # noise that grows with the signal
    image = _grey(mu + sigma * rng.standard_normal(mu.shape))
    expected = float(np.mean(sigma ** 2 / (mu ** 2 + EPSILON)))
    # the mean of 262,144 scaled chi-squares of one degree: relative spread sqrt(2 / N) = 0.3%
    assert relmse(image, _grey(mu)) == pytest.approx(expected, rel=0.015)


def test_relmse_is_the_formula_on_luminance_and_leaves_the_mask_out():
    rng = np.random.default_rng(2)
    ref = rng.random((8, 8, 3))
    image = ref + rng.normal(0, 0.1, ref.shape)
    w = np.array([0.2126, 0.7152, 0.0722])
    yi, yr = image @ w, ref @ w
    mask = np.zeros((8, 8), bool)
    mask[2:4] = True
    image[mask] = 1e6  # whatever a masked pixel holds
    yi[mask] = 1e6
    expected = np.mean(((yi - yr) ** 2 / (yr ** 2 + 0.5))[~mask])
    assert relmse(image, ref, mask, epsilon=0.5) == pytest.approx(expected, rel=1e-12)


def test_two_independent_halves_estimate_the_reference_noise():
    """A reference R = (A + B) / 2 of halves with noise sigma_h each has variance sigma_h^2 / 2 per pixel;
    (Y_A - Y_B)^2 / 4 estimates it, and an independent image's relMSE against R, less it, is the
    image's own relMSE against the truth."""
    rng = np.random.default_rng(3)
    mu = _scene(1)
    sigma_h, sigma_i = 0.03 * np.sqrt(mu), 0.05 * np.sqrt(mu)
    a = _grey(mu + sigma_h * rng.standard_normal(mu.shape))
    b = _grey(mu + sigma_h * rng.standard_normal(mu.shape))
    reference = (a + b) / 2
    image = _grey(mu + sigma_i * rng.standard_normal(mu.shape))
    true_ref = float(np.mean(sigma_h ** 2 / 2 / (mu ** 2 + EPSILON)))
    true_image = float(np.mean(sigma_i ** 2 / (mu ** 2 + EPSILON)))
    noise = reference_relmse(a, b)
    assert noise == pytest.approx(true_ref, rel=0.02)
    assert relmse(reference, _grey(mu)) == pytest.approx(true_ref, rel=0.02)  # the same quantity, measured
    raw = relmse(image, reference)
    assert raw == pytest.approx(true_image + true_ref, rel=0.02)
    assert subtract(raw, noise) == pytest.approx(true_image, rel=0.03)
    figures = reference_figures(a, b)
    assert figures["relmse"] == noise
    m = measure(image, reference, figures)
    assert m["relmse_raw"] == raw and m["relmse"] == subtract(raw, noise)


def test_block_rms_of_known_block_errors():
    """Every 8x8 block off by its own factor 1 + d: the RMS of the block means' relative error is
    the RMS of d; the reference's share comes off in quadrature."""
    rng = np.random.default_rng(4)
    ref = _grey(_scene(2))
    d = rng.uniform(-0.2, 0.2, (H // 8, W // 8))
    image = ref * (1 + np.kron(d, np.ones((8, 8))))[..., None]
    assert block_rms(image, ref) == pytest.approx(math.sqrt(np.mean(d ** 2)), rel=1e-9)
    mask = np.zeros((H, W), bool)
    mask[:8, :8] = True  # the first block is left out
    assert block_rms(image, ref, mask) == pytest.approx(math.sqrt(np.mean(np.delete(d.ravel(), 0) ** 2)), rel=1e-9)
    assert block_rms(image[:7, :7], ref[:7, :7]) is None
    assert subtract_rms(0.05, 0.03) == pytest.approx(0.04)
    assert subtract_rms(0.02, 0.03) == 0.0 and subtract(1e-3, 2e-3) == 0.0


def test_reference_block_noise_matches_the_truth():
    rng = np.random.default_rng(5)
    mu = _scene(3)
    sigma_h = 0.2 * mu
    a = _grey(mu + sigma_h * rng.standard_normal(mu.shape))
    b = _grey(mu + sigma_h * rng.standard_normal(mu.shape))
    # a block mean of 64 pixels with sigma_h / sqrt(2) each: relative sd 0.2 / sqrt(2) / 8
    truth = block_rms((a + b) / 2, _grey(mu))
    assert reference_figures(a, b)["block8_rms"] == pytest.approx(truth, rel=0.1)
    assert truth == pytest.approx(0.2 / math.sqrt(2) / 8, rel=0.1)


def test_equal_time_interpolates_in_log_log():
    t = [1.0, 2.0, 4.0, 8.0, 16.0]
    e = [0.5 / s for s in t]  # an unbiased estimator: error x time constant
    assert at_time(t, e, 3.0) == pytest.approx(0.5 / 3.0, rel=1e-12)
    assert at_time(t, e, 10.0) == pytest.approx(0.05, rel=1e-12)
    assert at_time(t[::-1], e[::-1], 3.0) == pytest.approx(0.5 / 3.0, rel=1e-12)  # any order
    assert at_time(t, e, 4.0) == e[2]
    assert at_time(t, e, 16.0) == e[-1] and at_time(t, e, 1.0) == e[0]
    assert at_time(t, e, 0.5) is None and at_time(t, e, 16.5) is None  # not reached
    bent = [1.0, 0.3, 0.2, 0.15, 0.14]  # a biased one flattens: still log-log linear between points
    w = math.log(5 / 4) / math.log(2)
    assert at_time(t, bent, 5.0) == pytest.approx(0.2 ** (1 - w) * 0.15 ** w, rel=1e-12)
    assert at_time(t, [1.0, 0.0, 0.2, 0.1, 0.05], 1.5) is None  # no log of 0
    assert at_time([], [], 1.0) is None


def test_variance_ratio_at_equal_samples():
    curves = {"a": {1: 0.4, 2: 0.2, 4: 0.1, 8: 0.05}, "b": {1: 0.8, 2: 0.4, 4: 0.2}, "c": {1: 0.3, 2: 0.3, 4: 0.12}}
    n, ratios = ratios_at_equal_samples(curves)
    assert n == 4  # the largest count all reached
    assert ratios == pytest.approx({"a": 1.0, "b": 2.0, "c": 1.2})
    curves["c"][4] = 0.0  # below the reference's noise there: the next count down
    n, ratios = ratios_at_equal_samples(curves)
    assert n == 2 and ratios == pytest.approx({"a": 1.0, "b": 2.0, "c": 1.5})
    assert ratios_at_equal_samples({"a": {1: 1.0}, "b": {2: 1.0}}) == (None, {})
