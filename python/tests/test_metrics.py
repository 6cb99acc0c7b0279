"""Metrics: values derived by hand, and the invariants the field relies on."""

import math

import numpy as np

import uwnr
from conftest import gradient, water


def test_psnr_of_a_constant_error_of_a_tenth_is_20_db():
    a = np.full((32, 32, 3), 0.5, np.float32)
    b = a + np.float32(0.1)
    assert abs(uwnr.metrics.psnr(a, b) - 20.0) < 1e-4


def test_psnr_matches_the_formula_on_8_bit_data():
    a, b = gradient(40, 40), water(40, 40)
    mse = np.mean((a.astype(np.float64) - b) ** 2)
    assert abs(uwnr.metrics.psnr(a, b) - 10 * math.log10(255**2 / mse)) < 1e-6


def test_identical_images():
    a = gradient(32, 32)
    assert uwnr.metrics.psnr(a, a) == math.inf
    assert abs(uwnr.metrics.ssim(a, a) - 1.0) < 1e-12
    assert abs(uwnr.metrics.ssim(a, a, gray=True) - 1.0) < 1e-12


def test_full_reference_metrics_are_symmetric_and_dtype_blind():
    a, b = gradient(32, 32), water(32, 32)
    assert uwnr.metrics.ssim(a, b) == uwnr.metrics.ssim(b, a)
    assert uwnr.metrics.psnr(a, b) == uwnr.metrics.psnr(b, a)
    assert abs(uwnr.metrics.ssim(a, b) - uwnr.metrics.ssim(a.astype(np.float32) / 255, b)) < 1e-9
    assert 0 < uwnr.metrics.ssim(a, b) < 1


def test_no_reference_metrics_are_finite_even_on_flat_images():
    for img in (gradient(48, 48), np.full((48, 48, 3), 90, np.uint8)):
        assert math.isfinite(uwnr.metrics.uiqm(img))
        assert math.isfinite(uwnr.metrics.uciqe(img))
    assert uwnr.metrics.uciqe(gradient(48, 48)) > uwnr.metrics.uciqe(np.full((48, 48, 3), 90, np.uint8))
