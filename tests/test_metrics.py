import numpy as np
import pytest

from lf_flame.measure.metrics import psnr_per_plane, ssim_per_plane


def test_identical_images():
    a = np.random.default_rng(0).random((4, 20, 10))
    assert np.allclose(ssim_per_plane(a, a), 1.0)
    assert np.all(np.isinf(psnr_per_plane(a, a)))


def test_psnr_known_value():
    a = np.zeros((1, 10, 10))
    b = np.full((1, 10, 10), 0.1)  # MSE 0.01 -> 20 dB at MAX 1
    assert np.isclose(psnr_per_plane(a, b)[0], 20.0)


def test_ssim_of_constant_images_is_finite():
    a = np.zeros((1, 16, 16))
    b = np.full((1, 16, 16), 0.5)
    s = ssim_per_plane(a, b)
    assert np.all(np.isfinite(s)) and s[0] < 0.1


def test_shape_mismatch_and_nan():
    with pytest.raises(ValueError, match="shape"):
        ssim_per_plane(np.zeros((1, 8, 8)), np.zeros((1, 8, 9)))
    with pytest.raises(ValueError, match="NaN"):
        psnr_per_plane(np.zeros((1, 8, 8)), np.full((1, 8, 8), np.nan))
