import numpy as np
import pytest

from lf_flame.measure.metrics import own_error, psnr_per_plane, ssim_per_plane


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
    # one 2-D image (it had been scored row by row: 32 values) and integer images (uint8 against a data range of 1)
    with pytest.raises(ValueError, match=r"stack of planes \(P, rows, cols\); one image is x\[None\]"):
        ssim_per_plane(np.zeros((32, 32)), np.zeros((32, 32)))
    with pytest.raises(ValueError, match="holds integers"):
        psnr_per_plane(np.zeros((1, 8, 8), np.uint8), np.ones((1, 8, 8), np.uint8))


def test_own_error_is_one_renders_error_from_two():
    """Two renders of one image with independent errors of the same size: the estimate is one render's own error
    against the image (which it never sees), not the two renders' difference."""
    rng = np.random.default_rng(0)
    image = rng.random((60, 40)) + 0.5
    first, second = (image + 0.02 * rng.standard_normal(image.shape) for _ in range(2))
    true = np.linalg.norm(first - image) / np.linalg.norm(first)
    assert own_error(first, second) == pytest.approx(true, rel=0.05)
    assert own_error(first, first) == 0.0
    with pytest.raises(ValueError, match="shape"):
        own_error(first, second[:-1])
    with pytest.raises(ValueError, match="NaN"):
        own_error(first, np.full_like(second, np.nan))
    with pytest.raises(ValueError, match="no light"):
        own_error(np.zeros_like(first), second)
