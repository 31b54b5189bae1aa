import numpy as np
import pytest

from lf_flame import scenes, simulate
from lf_flame.camera import PAPER_CAMERA
from lf_flame.refocus import (aperture_mask, find_sharpest_slope, focal_stack, normalized_variance, raw_to_views,
                              refocus, tenengrad, variance_of_laplacian, views_to_raw)


@pytest.fixture
def views():
    return np.random.default_rng(0).random((5, 5, 12, 9), dtype=np.float32)


def test_views_round_trip_and_axis_order():
    raw = np.arange(6 * 3 * 4 * 3, dtype=np.float32).reshape(6 * 3, 4 * 3)
    v = raw_to_views(raw, 3)
    assert v.shape == (3, 3, 6, 4)
    assert v[1, 2, 4, 3] == raw[4 * 3 + 1, 3 * 3 + 2]
    assert np.array_equal(views_to_raw(v), raw)


def test_raw_not_a_lenslet_grid_rejected():
    with pytest.raises(ValueError, match="lenslet"):
        raw_to_views(np.zeros((16, 15)), 15)


def test_slope_zero_is_mean_of_views(views):
    assert np.allclose(focal_stack(views, [0.0])[0], views.mean(axis=(0, 1)), atol=1e-6)


@pytest.mark.parametrize("slope", [-3.3, -1.0, 0.37, 2.5, 40.0])
def test_constant_light_field_stays_constant(slope):
    v = np.full((5, 5, 10, 8), 0.3, np.float32)
    out = focal_stack(v, [slope])[0]
    covered = out != 0  # a pixel no view reaches (huge slopes) is 0, never NaN
    assert np.all(np.isfinite(out)) and np.allclose(out[covered], 0.3, atol=1e-6)


@pytest.mark.parametrize("slope", [-2.0, -1.0, 1.0, 2.0])
def test_integer_slopes_match_integer_shift_reference(views, slope):
    n, _, R, C = views.shape
    acc, cnt = np.zeros((R, C)), np.zeros((R, C))
    for u in range(n):
        for v in range(n):
            du, dv = int(slope * (u - 2)), int(slope * (v - 2))
            for r in range(R):
                for c in range(C):
                    if 0 <= r + du < R and 0 <= c + dv < C:
                        acc[r, c] += views[u, v, r + du, c + dv]
                        cnt[r, c] += 1
    ref = np.where(cnt > 0, acc / np.maximum(cnt, 1), 0)
    assert np.allclose(focal_stack(views, [slope])[0], ref, atol=1e-6)


def test_focal_stack_equals_single_slopes(views):
    slopes = [-1.3, 0.2, 0.75]
    stack = focal_stack(views, slopes)
    for s, img in zip(slopes, stack):
        assert np.array_equal(img, focal_stack(views, [s])[0])


def test_nan_rejected(views):
    views[0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        focal_stack(views, [0.0])


def test_refocused_point_concentrates_at_its_slope(small_camera):
    cam = small_camera
    dz = 10.0
    raw = simulate.render(cam, scenes.point_scene(cam, dz, size_mm=0.2), 64, 0)
    s = cam.slope_for_depth(dz)
    at, off = refocus(raw, [s, 0.0], cam.pixels_per_lenslet, aperture_mask(15, "circular"))
    assert at.max() > 10 * off.max()
    r, c = np.unravel_index(np.argmax(at), at.shape)
    assert (r, c) == (20, 20)
    assert at[r - 1:r + 2, c - 1:c + 2].sum() > 0.8 * at.sum()  # into one pixel, up to the source size and bilinear spread


def test_sharpness_metrics_zero_on_constant_region():
    img = np.full((9, 9), 0.4)
    for metric in (variance_of_laplacian, tenengrad, normalized_variance):
        assert metric(img) == pytest.approx(0.0, abs=1e-20)
    assert normalized_variance(np.zeros((4, 4))) == 0.0


def test_slope_search_finds_paper_planes():
    cam = PAPER_CAMERA
    sc = scenes.shapes_scene(cam, np.random.default_rng(0), vary=False)
    views = raw_to_views(simulate.render(cam, sc, 4, 0), cam.pixels_per_lenslet)
    for obj in sc.objects:
        res = find_sharpest_slope(views, obj["roi"], mask=aperture_mask(15, "circular"))
        assert abs(res.slope - cam.slope_for_depth(obj["depth_offset_mm"])) <= 0.05, obj["name"]
        assert res.scores.max() > 1.2 * np.median(res.scores)  # a peaked curve
