import numpy as np
import pytest

from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.refocus import _kernels as _refocus_kernels
from lf_flame.refocus.shift_and_sum import _EXPONENT_BITS, FourierSlice, _check_finite, aperture_mask, focal_stack, raw_to_views, refocus, refocus_views, views_to_raw
from lf_flame.refocus.slope_search import find_sharpest_slope, normalized_variance, tenengrad, variance_of_laplacian


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


@pytest.mark.parametrize("method", ["fourier", "shift-sum"])
def test_views_near_float32s_largest_are_refocused_without_overflow(views, method):
    """Views up to 1e38 (float32, finite) are refocused as the views times 1e38, finite: the Fourier slice's complex64
    spectrum had overflowed into inf (views of 1e37 here; a small camera's flames times 1e34, written with exit 0)
    and shift-and-sum's float32 sums had been refused as 'views contain NaN or inf'. Both scale by a power of two
    (exact) and back; the slope search finds the same slope on them (its float32 mean light had overflowed, and the
    region been refused as having no light). A float64 raw image past float32's largest is refused naming the overflow and the way out,
    where raw_to_views had returned views of inf."""
    slopes = [-1.3, 0.0, 0.37]
    want = refocus_views(views, slopes, method=method).astype(np.float64) * 1e38
    got = refocus_views(views * np.float32(1e38), slopes, method=method)
    assert got.dtype == np.float32 and np.all(np.isfinite(got))
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6 * np.abs(want).max())
    assert np.array_equal(refocus_views(views * np.float32(2.0 ** 70), slopes, method=method),
                          refocus_views(views, slopes, method=method) * np.float32(2.0 ** 70))   # exact
    roi, grid = (2, 10, 2, 7), dict(lo=-1.0, hi=1.0, method=method)    # the slope search on them: the same slope
    assert find_sharpest_slope(views * np.float32(1e37), roi, **grid).slope == find_sharpest_slope(views, roi,
                                                                                                   **grid).slope
    raw = views_to_raw(views).astype(np.float64) * 1e39
    with pytest.raises(ValueError, match=r"the raw image overflows float32 \(its values reach 1e\+39.*scale the data "
                                         "down"):
        raw_to_views(raw, 5)
    with pytest.raises(ValueError, match="views contains NaN or inf"):      # NaN is still NaN
        bad = views.copy()
        bad[0, 0, 0, 0] = np.nan
        focal_stack(bad, slopes, check_finite=False)


@pytest.mark.parametrize("slope", [-2.0, -1.0, 1.0, 2.0, 0.6, -1.3])
def test_nearest_path_matches_integer_shift_reference(views, slope):
    n, _, R, C = views.shape
    acc, cnt = np.zeros((R, C)), np.zeros((R, C))
    for u in range(n):
        for v in range(n):
            du, dv = int(np.floor(slope * (u - 2) + 0.5)), int(np.floor(slope * (v - 2) + 0.5))
            for r in range(R):
                for c in range(C):
                    if 0 <= r + du < R and 0 <= c + dv < C:
                        acc[r, c] += views[u, v, r + du, c + dv]
                        cnt[r, c] += 1
    ref = np.where(cnt > 0, acc / np.maximum(cnt, 1), 0)
    assert np.allclose(focal_stack(views, [slope], interpolation="nearest")[0], ref, atol=1e-6)
    if slope == int(slope):
        assert np.allclose(focal_stack(views, [slope])[0], ref, atol=1e-6)


def test_integer_slopes_exact_between_integer_and_bilinear_paths():
    v = np.random.default_rng(1).random((15, 15, 40, 30), dtype=np.float32)
    slopes = [-2.0, -1.0, 0.0, 1.0, 3.0]
    assert np.array_equal(focal_stack(v, slopes, interpolation="nearest"), focal_stack(v, slopes))
    assert not np.array_equal(focal_stack(v, [0.5], interpolation="nearest"), focal_stack(v, [0.5]))


def test_bilinear_matches_per_view_reference(views):
    """Separable two-pass kernel == the textbook per-view bilinear shift-and-sum."""
    n, _, R, C = views.shape
    slope = 0.37
    acc, cnt = np.zeros((R, C)), np.zeros((R, C))
    for u in range(n):
        for v in range(n):
            y = np.arange(R)[:, None] + slope * (u - 2) + np.zeros((1, C))
            x = np.arange(C)[None, :] + slope * (v - 2) + np.zeros((R, 1))
            ok = (y >= 0) & (y <= R - 1) & (x >= 0) & (x <= C - 1)
            y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
            fy, fx = y - y0, x - x0
            y1, x1 = np.minimum(y0 + 1, R - 1), np.minimum(x0 + 1, C - 1)
            y0, x0 = np.clip(y0, 0, R - 1), np.clip(x0, 0, C - 1)
            img = views[u, v].astype(np.float64)
            val = ((1 - fy) * (1 - fx) * img[y0, x0] + (1 - fy) * fx * img[y0, x1]
                   + fy * (1 - fx) * img[y1, x0] + fy * fx * img[y1, x1])
            acc += np.where(ok, val, 0)
            cnt += ok
    ref = np.where(cnt > 0, acc / np.maximum(cnt, 1), 0)
    assert np.allclose(focal_stack(views, [slope])[0], ref, atol=2e-6)


def test_no_light_lost_in_float32_sums():
    """225 views summed in float32, two-level: the mean matches float64 to 2 ulp-ish."""
    v = (1.0 + np.random.default_rng(2).random((15, 15, 60, 30)) * 1e-3).astype(np.float32)
    out = focal_stack(v, [0.0])[0]
    ref = v.astype(np.float64).mean(axis=(0, 1))
    assert np.max(np.abs(out - ref) / ref) < 4e-7


def test_stack_independent_of_task_split():
    v = np.random.default_rng(3).random((15, 15, 37, 21), dtype=np.float32)
    sh = np.array([1.7, -0.4])[:, None] * (np.arange(15) - 7.0)[None, :]
    outs = []
    for rows_per_task in (1, 5, 16, 37):
        out = np.empty((2, 37, 21), np.float32)
        _refocus_kernels.shift_sum_stack(v.reshape(15, 15, -1), 37, sh, sh, np.ones((15, 15), bool), out, rows_per_task)
        outs.append(out)
    assert all(np.array_equal(outs[0], o) for o in outs[1:])


@pytest.fixture(scope="module")
def smooth_views():
    from scipy import ndimage
    rng = np.random.default_rng(4)
    return ndimage.gaussian_filter(rng.random((15, 15, 60, 40)), (0, 0, 2, 2)).astype(np.float32)


def test_fourier_slice_agrees_with_shift_sum(smooth_views):
    fs = FourierSlice(smooth_views, 2.5)
    for slopes, tol in (([-2.0, 0.0, 1.0], 3e-4), ([-1.249, 0.3, 2.281], 1e-3)):
        a, b = focal_stack(smooth_views, slopes), fs.stack(slopes)
        rmse = np.sqrt(np.mean((a - b) ** 2, axis=(1, 2)))
        assert np.all(rmse < tol), rmse


@pytest.mark.parametrize("n", [14, 10, 2])
def test_fourier_slice_takes_an_even_number_of_views(smooth_views, n):
    """Decoded views of any pitch: half-integer view offsets refocus where shift-and-sum does
    (a sign error in the half-view correction moves each plane by slope / 2: RMSE ~ 2e-2)."""
    v = smooth_views[:n, :n]
    slopes = [-2.0, -1.249, 0.3, 1.0, 2.281]
    a, b = focal_stack(v, slopes), FourierSlice(v, 2.5).stack(slopes)
    rmse = np.sqrt(np.mean((a - b)[:, 5:-5, 5:-5] ** 2, axis=(1, 2)))
    assert np.all(rmse < 2e-3), rmse


def test_fourier_slice_of_one_view_is_that_view():
    """One view (an angular grid of M = 2 slots, narrower than the 4-tap kernel, whose taps wrap around it more
    than once): every slope refocuses to the view itself."""
    v = np.random.default_rng(0).random((1, 1, 9, 7)).astype(np.float32)
    for img in FourierSlice(v, 1.0).stack([-1.0, -0.3, 0.0, 0.7]):
        np.testing.assert_allclose(img, v[0, 0], atol=2e-3)


def test_fourier_constant_light_field_stays_constant():
    c = np.full((15, 15, 30, 20), 0.3, np.float32)
    for img in FourierSlice(c, 2.5).stack([0.0, 0.37, -2.5]):
        covered = img != 0
        assert np.all(np.isfinite(img)) and covered.mean() > 0.5
        assert np.allclose(img[covered], 0.3, atol=1e-3)


def test_fourier_slices_of_one_shape_and_slopes_share_their_view_counts_but_not_their_masks(smooth_views,
                                                                                           monkeypatch):
    """The count of views reaching each pixel is kept for the last two slopes, shapes and masks (the depth search
    and its residual's searches refocus alike): stacks with a circular, a square and again a circular mask at the
    same slopes, of a light field whose views outside the circle are lit, each refocus as shift-and-sum does with
    that mask. A count kept without its mask (the square's count read from the circle's: 177 views for 225) breaks
    it. A count larger than the keeping limit is not kept, and its stack is the same."""
    from lf_flame.refocus import shift_and_sum as S
    slopes = [-1.0, 0.2, 1.3]
    v = smooth_views + np.float32(5.0) * (1 - aperture_mask(15, "circular"))[:, :, None, None]   # lit outside
    for shape in ("circular", "square", "circular"):
        mask = aperture_mask(15, shape)
        a, b = focal_stack(v, slopes, mask), FourierSlice(v, 2.0, mask).stack(slopes)
        rmse = np.sqrt(np.mean((a - b)[:, 10:-10, 10:-10] ** 2, axis=(1, 2)))     # apart from the border's views
        assert np.all(rmse < 5e-3), (shape, rmse)
    FourierSlice(v, 2.0, mask).stack([0.5])                                       # a third: the oldest let go
    assert len(S._SLICE_COUNTS) == 2
    monkeypatch.setattr(S, "_SLICE_COUNTS", {})
    monkeypatch.setattr(S, "SLICE_COUNT_KEEP_BYTES", 0)
    np.testing.assert_array_equal(FourierSlice(v, 2.0, mask).stack(slopes), b)
    assert not S._SLICE_COUNTS


def test_no_slopes_and_no_views_are_refused(smooth_views):
    from lf_flame.refocus.shift_and_sum import aperture_mask, refocus_views
    for method in ("shift-sum", "fourier"):        # the Fourier route had failed inside NumPy on an empty array
        with pytest.raises(ValueError, match="slopes must be a non-empty 1-D sequence"):
            refocus_views(smooth_views, [], method=method)
    for n in (-3, 0, 2.5):
        with pytest.raises(ValueError, match="views per axis, must be a whole number >= 1"):
            aperture_mask(n)
    from lf_flame.refocus.shift_and_sum import views_to_raw
    with pytest.raises(ValueError, match=r"views must have shape \(N, N, R, C\)"):
        views_to_raw(smooth_views[0])


def test_fourier_rejects_bad_input(smooth_views):
    with pytest.raises(ValueError, match="max_slope"):
        FourierSlice(smooth_views, 1.0).stack([1.5])
    bad = smooth_views.copy()
    bad[3, 3, 5, 5] = np.inf
    with pytest.raises(ValueError, match="NaN or inf"):
        FourierSlice(bad, 1.0)
    with pytest.raises(ValueError, match="method"):
        refocus(np.zeros((30, 30)), [0.0], 15, method="fft")


def test_focal_stack_equals_single_slopes(views):
    slopes = [-1.3, 0.2, 0.75]
    stack = focal_stack(views, slopes)
    for s, img in zip(slopes, stack):
        assert np.array_equal(img, focal_stack(views, [s])[0])


def test_nan_rejected(views):
    views[0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        focal_stack(views, [0.0])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_finite_check_finds_nan_and_inf_anywhere(dtype):
    """The bit-level check (lanes of 64, a tail, chunks of 2^16) misses no position."""
    utype, exponent = _EXPONENT_BITS[np.dtype(dtype)]
    small = np.linspace(-3e38 if dtype == np.float32 else -1e308, 1e30, 203).astype(dtype)
    assert _refocus_kernels.max_exponent(small.view(utype), utype(exponent)) != exponent  # large but finite
    for i in range(small.size):
        for bad in (np.nan, np.inf, -np.inf):
            a = small.copy()
            a[i] = bad
            assert _refocus_kernels.max_exponent(a.view(utype), utype(exponent)) == exponent
    big = np.ones(3 * 2 ** 16 + 5, dtype)
    _check_finite("x", big)
    for i in (0, 2 ** 16 - 1, 2 ** 16, 2 * 2 ** 16 + 7, big.size - 1):
        a = big.copy()
        a[i] = np.nan
        with pytest.raises(ValueError, match="x contains NaN or inf"):
            _check_finite("x", a)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("interpolation", ["bilinear", "nearest"])
def test_non_finite_caught_by_kernel_without_input_check(views, bad, interpolation):
    """With check_finite=False the kernel's own check of its output still refuses NaN/inf."""
    views[3, 4, 10, 7] = bad
    with pytest.raises(ValueError, match="NaN or inf"):
        focal_stack(views, [-1.25, 0.0, 1.15], interpolation=interpolation, check_finite=False)


@pytest.mark.parametrize("method", ["shift-sum", "fourier"])
def test_refocused_point_concentrates_at_its_slope(small_camera, method):
    cam = small_camera
    dz = 10.0
    raw = simulate.render(cam, scenes.point_scene(cam, dz, size_mm=0.2), 64, 0)
    s = cam.slope_for_depth(dz)
    at, off = refocus(raw, [s, 0.0], cam.pixels_per_lenslet, aperture_mask(15, "circular"), method=method)
    assert at.max() > 10 * off.max()
    r, c = np.unravel_index(np.argmax(at), at.shape)
    assert (r, c) == (20, 20)
    assert at[r - 1:r + 2, c - 1:c + 2].sum() > 0.8 * at.sum()  # into one pixel, up to the source size and bilinear spread


def test_sharpness_metrics_zero_on_constant_region():
    img = np.full((9, 9), 0.4)
    for metric in (variance_of_laplacian, tenengrad, normalized_variance):
        assert metric(img) == pytest.approx(0.0, abs=1e-20)
    assert normalized_variance(np.zeros((4, 4))) == 0.0


@pytest.mark.parametrize("depths", [(20.0, 10.0, 0.0, -10.0), (-15.0, -5.0, 5.0, 25.0), (-12.0, -2.0, 8.0, 18.0)])
def test_slope_search_finds_each_plane(depths):
    """Within 0.05 of the analytic slope at the paper's depths and others in -15..+25 mm."""
    cam = PAPER_CAMERA
    sc = scenes.shapes_scene(cam, np.random.default_rng(0), vary=False, depths_mm=depths)
    views = raw_to_views(simulate.render(cam, sc, 4, 0), cam.pixels_per_lenslet)
    for obj in sc.objects:
        res = find_sharpest_slope(views, obj["roi"], mask=aperture_mask(15, "circular"))
        assert abs(res.slope - cam.slope_for_depth(obj["depth_offset_mm"])) <= 0.05, obj["name"]
        assert res.scores.max() > 1.2 * np.median(res.scores)  # a peaked curve


def test_slope_search_refuses_what_has_no_focus_and_stays_on_its_grid():
    """Views with no light or a constant image, and a region off the views' grid, are refused (each had returned a
    confident slope, -3.05 for zeros: outside the -3 ... 3 searched); a flame at the grid's end is found on it."""
    n, R, C = 15, 20, 12
    for views, roi, text, grid in ((np.zeros((n, n, R, C)), (0, R, 0, C), "no focus to find", {}),
                                   (np.full((n, n, R, C), 0.3), (0, R, 0, C), "no focus to find", {}),
                                   (np.random.default_rng(0).random((n, n, R, C)), (100, 110, 0, 10),
                                    "outside the views", {}),
                                   (np.random.default_rng(0).random((n, n, R, C)), (0, R, 0, C),
                                    r"reach past \+-3 lenslets per view step", dict(lo=-1e3, hi=1e3, coarse_step=10)),
                                   (np.random.default_rng(0).random((2, 2, R, C)), (0, R, 0, C),
                                    "a slope search needs at least 3 views per axis", {})):
        with pytest.raises(ValueError, match=text):             # the last had asked for 44 GiB on the paper camera
            find_sharpest_slope(views, roi, **grid)
    cam = PAPER_CAMERA
    sc = scenes.point_scene(cam, -10.0, size_mm=0.5)
    views = raw_to_views(simulate.render(cam, sc, 4, 0), cam.pixels_per_lenslet)
    lo = cam.slope_for_depth(-10.0) + 0.02                     # the flame's slope just below the grid's end
    res = find_sharpest_slope(views, sc.objects[0]["roi"], lo=lo, hi=lo + 1.0)
    assert res.slopes.min() >= lo - 1e-9 and res.slope == pytest.approx(lo, abs=0.006)


def test_slope_search_refuses_light_no_slope_moves_and_light_in_one_view():
    """A hot pixel (light in one view alone) has no parallax: refused, where the centre view's had returned +3.0025
    (fourier: past the +3 searched, its curve flat to 0.24 %) or -3.0 (shift-sum: flat), and an outer view's the
    slope its interpolation happened to sharpen (-3.0, +2.95). The same pixel over light every view sees alike (no
    view holds the region's light) is refused as flat: its sharpness varies by 0.2 % (fourier) from -3 to +3. The
    grid, coarse and fine, stays within lo .. hi (its last coarse step had been 3.0375)."""
    mask = aperture_mask(9, "circular")
    grid = dict(lo=-3.0, hi=3.0, coarse_step=0.0875, fine_step=0.00875, mask=mask)
    for u, v in ((4, 4), (0, 4), (1, 6)):
        views = np.zeros((9, 9, 40, 30), np.float32)
        views[u, v, 20, 15] = 0.5
        for method in ("fourier", "shift-sum"):
            with pytest.raises(ValueError, match=rf"comes from one view, \({u}, {v}\), alone \(100 % of it\)"):
                find_sharpest_slope(views, (0, 40, 0, 30), method=method, **grid)
    views = np.full((9, 9, 40, 30), 0.01, np.float32)
    views[4, 4, 20, 15] = 0.5
    for method in ("fourier", "shift-sum"):
        with pytest.raises(ValueError, match="as sharp at every slope .*no slope moves its light"):
            find_sharpest_slope(views, (5, 35, 5, 25), method=method, **grid)
    views = np.zeros((9, 9, 40, 30), np.float32)          # a point at slope +3 (on the grid's end) in every view
    for u in range(9):
        for v in range(9):
            views[u, v, 20 + 3 * (u - 4), 15 + 3 * (v - 4)] = 0.5
    res = find_sharpest_slope(views, (0, 40, 0, 30), **grid)
    assert res.slopes.max() <= 3.0 and res.slope == pytest.approx(3.0, abs=0.01)


def test_cli_refocus_and_slopes(tmp_path, small_camera, capsys):
    import pandas as pd
    from lf_flame.cli import main
    cam = small_camera
    sc = scenes.point_scene(cam, 10.0, size_mm=0.2)
    raw = simulate.render(cam, sc, 16, 0)
    np.savez(tmp_path / "p.npz", raw=raw, camera=cam.to_json())
    s = cam.slope_for_depth(10.0)
    for method in ("shift-sum", "fourier"):
        assert main(["refocus", str(tmp_path / "p.npz"), "--slope", str(s), "--method", method,
                     "--out", str(tmp_path / f"{method}.npz")]) == 0
        stack = np.load(tmp_path / f"{method}.npz")["stack"]
        assert stack.shape == (1, cam.n_rows, cam.n_cols) and np.unravel_index(stack[0].argmax(), stack[0].shape) == (20, 20)
        assert f"refocused 1 plane ({method})" in capsys.readouterr().out          # "1 planes" before
    assert main(["slopes", str(tmp_path / "p.npz"), "--roi", "10", "31", "10", "31", "--lo", "-2", "--hi", "2"]) == 0
    df = pd.read_csv(tmp_path / "p.slopes.csv")
    assert abs(df.slope[0] - s) <= 0.05 and abs(df.depth_mm[0] - 10.0) < 1.0
    assert (tmp_path / "p.slopes.png").stat().st_size > 0
    assert "p.slopes.csv" in capsys.readouterr().out
    # --out is the calibration mode's: with RAW it is refused (it had been ignored, the files going beside RAW)
    assert main(["slopes", str(tmp_path / "p.npz"), "--out", str(tmp_path / "s.csv")]) == 2
    assert "--out belongs to the calibration mode" in capsys.readouterr().err
    # a prefix ending in / is a folder: the files go in it, named after the raw image (it had written ./sl.slopes.csv)
    assert main(["slopes", str(tmp_path / "p.npz"), "--roi", "10", "31", "10", "31", "--lo", "-2", "--hi", "2",
                 "--out-prefix", str(tmp_path / "sl") + "/"]) == 0
    assert (tmp_path / "sl" / "p.slopes.csv").is_file() and (tmp_path / "sl" / "p.slopes.png").is_file()
    # a search beyond what a camera refocuses is refused before it starts (-100 ... 100 had taken 24 GB and been killed)
    assert main(["slopes", str(tmp_path / "p.npz"), "--lo", "-100", "--hi", "100"]) == 2
    assert "--lo -100, --hi 100: slopes beyond 3 lenslets per view" in capsys.readouterr().err


def test_bench_refocus_quick(tmp_path):
    import importlib.util
    import pandas as pd
    spec = importlib.util.spec_from_file_location("bench_refocus", "experiments/bench_refocus.py")
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    bench.main(["--quick", "--out", str(tmp_path)])
    df = pd.read_csv(tmp_path / "bench_refocus.csv")
    assert {"shift-sum bilinear", "shift-sum nearest", "fourier", "lf-read", "inner-loop floor"} <= set(df.method)
    floor = df[df.method == "inner-loop floor"].iloc[0]  # covers every view sample once per plane
    assert int(floor.note.split()[0]) >= 4 * 15 * 15 * 45 * 40 and floor.ms_median > 0
    agree = df[df.method == "agreement"].set_index("what")
    assert agree.loc["fourier vs shift-sum bilinear, integer slopes", "rmse_interior"] < 1e-3
    slopes = pd.read_csv(tmp_path / "slopes_depths.csv")
    assert slopes.error_fourier.abs().max() <= 0.05


def test_lit_views_are_the_inscribed_circle_where_the_aperture_fills_the_lenslet_images():
    """The paper camera's aperture image fills its lenslet images: the views a depth search takes are the inscribed
    circle's (its partly lit views 71 % or more inside); stopped down to f/8 (its aperture image 0.7 of a lenslet
    image) the rim's views go, and an interpolated sample's wider footprint keeps none that a pixel loses."""
    import dataclasses
    from lf_flame.refocus.shift_and_sum import lit_views
    circle = aperture_mask(PAPER_CAMERA.pixels_per_lenslet, "circular")
    assert np.array_equal(lit_views(PAPER_CAMERA), circle)
    stopped = dataclasses.replace(PAPER_CAMERA, aperture_mm=0.7 * PAPER_CAMERA.aperture_diameter_mm)
    lit, wide = lit_views(stopped), lit_views(stopped, tent=1.0)
    assert np.all(lit <= circle) and np.all(wide <= lit) and lit.sum() < circle.sum()
    u = np.arange(15) - 7.0
    assert np.all(np.hypot(u[:, None], u[None, :])[lit] <= 0.7 * 7.5 + 0.5)
    with pytest.raises(ValueError, match="share"):
        lit_views(PAPER_CAMERA, share=0.0)
