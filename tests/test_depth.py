"""Find the planes (lf_flame.tomo.depth), its scenes (lf_flame.simulate.scenes_depth) and score_flames."""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.optics.depth_range import imaging_range_mm
from lf_flame.optics.camera_file import load_camera_file
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate import tracer
from lf_flame.simulate.scenes_depth import behind_scene, random_depth_scene
from lf_flame.tomo.depth import (MERGE_MM, MERGE_PARALLAX, depth_scale, depth_tolerance_scale, find_depths,
                                 merge_depths, plane_runs)
from lf_flame.tomo.exact import emission_operator
from lf_flame.tomo.found_planes import find_planes
from lf_flame.tomo.operator import plane_grid
from lf_flame.tomo.scoring import score_flames
from lf_flame.tomo.truth import resample_layer


@pytest.fixture(scope="module")
def cam():
    return PlenopticCamera(n_rows=60, n_cols=40)


def _views(cam, scene, seed, rays=32):
    return raw_to_views(tracer.render(cam, scene, rays, seed), cam.pixels_per_lenslet)


@pytest.fixture(scope="module")
def planted(cam):
    scene = random_depth_scene(cam, np.random.default_rng(7), n_flames=2, height_range=(2.0, 5.0))
    return scene, _views(cam, scene, 7)


@pytest.fixture(scope="module")
def behind(cam):
    scene = behind_scene(cam, np.random.default_rng(3), 5.0)
    return scene, _views(cam, scene, 3)


def test_planted_depths_found(cam, planted):
    scene, views = planted
    found = find_depths(views, cam)
    true = sorted(o["depth_offset_mm"] for o in scene.objects)
    assert abs(true[1] - true[0]) > 1.0                    # two depths, not on any grid
    assert len(found.depths_mm) == 2, found.depths_mm
    np.testing.assert_allclose(found.depths_mm, true, atol=0.3)
    assert np.all(found.uncertainty_mm > 0) and np.all(np.isfinite(found.uncertainty_mm))
    assert len(found.planes_mm) == 2 and found.masks.shape == (2, cam.n_rows, cam.n_cols)


def test_two_flames_behind_one_another_both_found(cam, behind):
    scene, views = behind
    found = find_depths(views, cam)
    true = sorted(o["depth_offset_mm"] for o in scene.objects)
    assert len(found.depths_mm) == 2, found.depths_mm
    np.testing.assert_allclose(found.depths_mm, true, atol=0.5)
    assert found.region[0] == found.region[1]              # one region, two depths


def test_find_planes_emission_scored(cam, behind):
    scene, views = behind
    found, op, rec = find_planes(views, cam)
    df = score_flames(rec.planes, found.planes_mm, scene, cam, found=list(zip(found.depths_mm, found.masks)))
    assert len(df) == 2 and df.depth_err_mm.abs().max() < 0.5
    assert df.rel_err.max() < 0.2, df.rel_err.values
    assert df.share_near.min() > 0.9


def test_the_routes_residuals_are_kept_for_the_last_two_solves_only(cam, planted):
    """The found planes' route asks for a solve's residual in one step and again in the next: ``Residuals`` gives
    the same array for the same operator and solve, a new one for another solve of the same operator, and keeps
    the last two. Kept by the operator alone, a second solve would read the first's residual."""
    import dataclasses

    from lf_flame.tomo.solvers import Residuals, fitted_pixels, fitted_residual
    _, views = planted
    found, op, rec = find_planes(views, cam, peel_rounds=0, refine_steps=0)
    y = np.asarray(views, np.float64)
    fit = fitted_pixels(y, 1.0)
    residuals = Residuals(y, fit)
    recs = [rec] + [dataclasses.replace(rec, planes=rec.planes * f) for f in (0.5, 0.25)]
    first = residuals(op, recs[0])
    np.testing.assert_array_equal(first, fitted_residual(op, rec.planes, y, fit))
    assert residuals(op, recs[0]) is first
    second = residuals(op, recs[1])
    assert second is not first and np.abs(second - first).max() > 0
    np.testing.assert_array_equal(second, fitted_residual(op, recs[1].planes, y, fit))
    assert residuals(op, recs[0]) is first                           # two kept
    residuals(op, recs[2])
    assert residuals(op, recs[1]) is second
    again = residuals(op, recs[0])
    assert again is not first                                        # the first of three was let go
    np.testing.assert_array_equal(again, first)


def test_the_found_planes_take_their_own_knobs_on_noisy_data(cam, planted):
    from lf_flame.tomo.defaults import ADMM_KNOBS
    from lf_flame.tomo.found_planes import FOUND_PLANES_KNOBS
    _, views = planted
    loud = views + np.random.default_rng(2).normal(scale=0.03 * views.max(), size=views.shape)
    (key, own), = FOUND_PLANES_KNOBS.items()
    assert key == (2, "noisy") and any(own[k] != ADMM_KNOBS[key][k] for k in own)
    got = find_planes(loud, cam)[2].settings
    assert got["subsamples"] == 2 and got["noise"] > 0.005
    assert {k: got[k] for k in own} == own                               # the route's own where it holds them
    assert (got["iters"], got["l1"]) == (ADMM_KNOBS[key]["fills"], ADMM_KNOBS[key]["l1"])   # admm's elsewhere
    quiet = find_planes(views, cam)[2].settings
    assert (quiet["tv"], quiet["lam"]) == (ADMM_KNOBS[2, "quiet"]["tv"], ADMM_KNOBS[2, "quiet"]["lam"])
    assert find_planes(loud, cam, solve=dict(tv=0.3))[2].settings["tv"] == 0.3    # knobs given are kept


def test_score_flames_truth_and_off_planes(cam, planted):
    scene, _ = planted
    depths = [o["depth_offset_mm"] for o in scene.objects]
    truth = np.array([resample_layer(L, (cam.n_rows, cam.n_cols), plane_grid(cam, d)) for L, d in zip(scene.layers,
                                                                                                          depths)])
    df = score_flames(truth, depths, scene, cam)
    np.testing.assert_allclose(df.depth_err_mm, 0.0, atol=1e-12)
    np.testing.assert_allclose(df.rel_err, 0.0, atol=1e-9)
    np.testing.assert_allclose(df.share_near, 1.0)
    off = [d + 2.0 for d in depths]                         # the same images 2 mm off: no share within 1 mm
    df = score_flames(truth, off, scene, cam)
    np.testing.assert_allclose(df.depth_err_mm, 2.0)
    np.testing.assert_allclose(df.share_near, 0.0)
    # a found depth whose footprint misses the flame does not count for it
    empty = np.zeros((cam.n_rows, cam.n_cols), bool)
    df = score_flames(truth, depths, scene, cam, found=[(depths[0], empty)])
    assert df.depth_mm.isna().all()


def test_score_flames_heights_on_the_planes(cam, planted):
    scene, _ = planted
    depths = [o["depth_offset_mm"] for o in scene.objects]
    truth = np.array([resample_layer(L, (cam.n_rows, cam.n_cols), plane_grid(cam, d)) for L, d in zip(scene.layers,
                                                                                                          depths)])
    df = score_flames(truth, depths, scene, cam)
    assert df.height_err_mm.abs().max() < 0.3, df.height_err_mm.values       # the truth measures true heights
    np.testing.assert_allclose(df.height_mm_found - df.height_mm, df.height_err_mm)
    # flame 0 with its upper half gone (the tip is row 0's side): measured about half as tall
    cut = truth.copy()
    rows = np.flatnonzero(truth[0].max(axis=1) > 0)
    cut[0, : (rows[0] + rows[-1]) // 2] = 0.0
    df = score_flames(cut, depths, scene, cam)
    assert df.height_err_mm[0] < -0.3 * df.height_mm[0] and abs(df.height_err_mm[1]) < 0.3
    # a route's own footprint does not cut its flame (the lenslets that voted for a flame in front
    # of another cover only where it is the sharper one): its lower half alone still gives the height
    foot = [t > 0 for t in truth]
    foot[0][: (rows[0] + rows[-1]) // 2] = False
    df = score_flames(truth, depths, scene, cam, found=list(zip(depths, foot)))
    assert df.height_err_mm.abs().max() < 0.3, df.height_err_mm.values
    # another flame merged onto flame 0's plane, in its columns above it and holding more light (a plane of
    # emission's flame is the region holding the most): measured in its place unless the route's footprint of that
    # other depth tells them apart
    merged = truth.copy()
    top = rows[0] - 4
    merged[0, 2:top] = truth[0, rows[0]:rows[0] + top - 2]
    merged[0, 2:top] *= 2 * truth[0].sum() / merged[0, 2:top].sum()
    other = np.zeros_like(foot[0])
    other[2:top] = merged[0, 2:top] > 0
    both = [(depths[0], truth[0] > 0), (depths[1], foot[1])]
    df = score_flames(merged, depths, scene, cam, found=both)
    assert abs(df.height_err_mm[0]) > 0.3 * df.height_mm[0], df.height_err_mm.values
    df = score_flames(merged, depths, scene, cam, found=both + [(depths[0] + 0.3, other)])
    assert df.height_err_mm.abs().max() < 0.3, df.height_err_mm.values
    # where the other's voters cover only part of it, the rest is told apart by the regions the
    # depths were found in
    part = other.copy()
    part[(2 + top) // 2:] = False
    df = score_flames(merged, depths, scene, cam, found=both + [(depths[0] + 0.3, part)])
    assert abs(df.height_err_mm[0]) > 0.3 * df.height_mm[0], df.height_err_mm.values
    regions = [(d, m, m) for d, m in both] + [(depths[0] + 0.3, part, other)]
    df = score_flames(merged, depths, scene, cam, found=regions)
    assert df.height_err_mm.abs().max() < 0.3, df.height_err_mm.values
    # an empty plane: no height, the diagnostics' reason kept
    cut[1] = 0.0
    df = score_flames(cut, depths, scene, cam)
    assert np.isnan(df.height_err_mm[1]) and "empty" in df.height_failure[1]


def test_l1_gathers_a_dense_stack_towards_the_flames_depths(cam, planted):
    from lf_flame.tomo.exact import ExactOperator
    from lf_flame.tomo.solvers import reconstruct
    scene, views = planted
    depths = list(np.arange(-12.0, 12.1, 1.0))
    op = ExactOperator(cam, depths)
    share = {l1: score_flames(reconstruct(views, op, "admm", l1=l1).planes, depths, scene, cam).share_near.values
             for l1 in (0.0, 0.02)}
    assert np.all(share[0.02] > share[0.0] + 0.05), share
    assert reconstruct(views, op, "admm", l1=0.99).planes.max() == 0.0      # past lambda_max: nothing
    with pytest.raises(ValueError, match="l1"):
        reconstruct(views, op, "admm", l1=1.0)
    with pytest.raises(ValueError, match="l1"):
        reconstruct(views, op, "fista", l1=0.02)


@pytest.mark.parametrize("shape", [(3, 60, 31), (2, 7, 9), (2, 3, 2), (1, 1, 5)])
@pytest.mark.parametrize("sigma", [1.5, 0.7, 0.1])
def test_the_focus_measures_are_scipys_sobel_laplace_and_gaussian_to_the_bit(shape, sigma):
    """The depth search's Tenengrad energy and squared Laplacian, each smoothed, from the Numba kernel: equal to the
    last bit to SciPy's ``ndimage`` filters they replaced (the depth search's results unchanged), on images smaller
    than the Gaussian's reach too (reflected more than once: 1-3 lenslets across). A sum in another order, an
    edge mirrored without the edge sample or a tap off by one breaks it."""
    from scipy import ndimage

    from lf_flame.tomo._focus_kernels import focus_measures
    from lf_flame.tomo.focus import _gaussian_taps
    stack = np.random.default_rng(sum(shape)).random(shape) * 1e3
    ten, lap = np.empty_like(stack), np.empty_like(stack)
    focus_measures(stack, _gaussian_taps(sigma), True, ten, lap)
    np.testing.assert_array_equal(ten, [ndimage.gaussian_filter(ndimage.sobel(im, 0) ** 2 + ndimage.sobel(im, 1) ** 2,
                                                                sigma) for im in stack])
    np.testing.assert_array_equal(lap, [ndimage.gaussian_filter(ndimage.laplace(im) ** 2, sigma) for im in stack])


def test_merge_depths():
    planes, of = merge_depths(np.array([0.0, 0.5, 3.0]), np.array([1.0, 3.0, 1.0]), 1.0)
    np.testing.assert_allclose(planes, [0.375, 3.0])
    np.testing.assert_array_equal(of, [0, 0, 1])
    with pytest.raises(ValueError, match="ascending"):
        merge_depths(np.array([1.0, 0.0]), np.array([1.0, 1.0]))
    planes, of = merge_depths(np.array([0.0, 0.5, 0.9]), np.ones(3), 1.0, along=np.array([0.0, 2.0, 2.5]),
                              merge_along=1.0)      # joined only where both steps are short
    np.testing.assert_array_equal(of, [0, 1, 1])
    with pytest.raises(ValueError, match="along must ascend"):
        merge_depths(np.array([0.0, 0.5]), np.ones(2), 1.0, along=np.array([1.0, 0.0]))


def test_found_depths_share_a_plane_only_within_a_lenslet_of_parallax():
    """Flames side by side 0.5-1 mm apart in depth (0.9-1.7 lenslets of parallax across the paper camera's aperture)
    are solved each on its own plane: on one plane at their mean depth a flame 0.42 mm off lost 15-22 % of its
    emission, and the residual's search took the misfit for a flame. Within MERGE_PARALLAX (0.39 mm at +15 mm: 0.61
    lenslet) they share one; on a camera that sees less parallax per millimetre the millimetres bind, as before."""
    planes, of = plane_runs(PAPER_CAMERA, 15, np.array([-6.69, -5.86, 15.15, 15.54]), np.ones(4))
    np.testing.assert_allclose(planes, [-6.69, -5.86, 15.345])
    np.testing.assert_array_equal(of, [0, 1, 2, 2])
    np.testing.assert_array_equal(plane_runs(PAPER_CAMERA, 15, np.array([-6.69, -5.86]), np.ones(2), 1.0)[1], [0, 0])
    deep = load_camera_file(Path(__file__).resolve().parents[1] / "examples/own_camera.toml")
    n = deep.pixels_per_lenslet
    assert abs(deep.slope_for_depth(0.9) - deep.slope_for_depth(0.0)) * (n - 1) < MERGE_PARALLAX
    np.testing.assert_array_equal(plane_runs(deep, n, np.array([0.0, 0.9, 2.1]), np.ones(3))[1], [0, 0, 1])


@pytest.mark.parametrize("camera_file", ["examples/own_camera.toml", "data_gen/napari_lf/seaurchin.toml",
                                         "data_gen/napari_lf/GUVExperim1.toml"])
def test_depth_tolerances_carry_the_paper_cameras_parallax(camera_file):
    """MERGE_MM on the paper camera and MERGE_MM * depth_scale on another camera move the outermost views
    apart by the same parallax; the tolerances keep millimetres on deep fields and shrink on microscopes."""
    other = load_camera_file(Path(__file__).resolve().parents[1] / camera_file)
    paper = (PAPER_CAMERA.slope_for_depth(MERGE_MM) - PAPER_CAMERA.slope_for_depth(0.0)) * 14
    assert depth_scale(PAPER_CAMERA, 15) == depth_tolerance_scale(PAPER_CAMERA, 15) == 1.0
    for n in (other.pixels_per_lenslet, 7):
        dz = MERGE_MM * depth_scale(other, n)
        assert (other.slope_for_depth(dz) - other.slope_for_depth(0.0)) * (n - 1) == pytest.approx(paper, rel=0.05)
        assert depth_tolerance_scale(other, n) == min(1.0, depth_scale(other, n))
    assert (depth_tolerance_scale(other, other.pixels_per_lenslet) < 0.05) == ("napari" in camera_file)


def test_a_camera_focused_metres_away_searches_its_depths(tmp_path, capsys):
    """A camera focused 10 m away (a furnace's): one coarse slope step beyond its focal plane focuses past infinity,
    and the depth search's scale is taken a step toward the camera; reconstruct finds its depths and solves them
    (it stopped with "focuses at or beyond infinity" before any search, --search-range or not)."""
    from lf_flame.cli import main
    toml = tmp_path / "far.toml"
    toml.write_text("[main_lens]\nfocal_length_mm = 100.0\nf_number = 20.0\nfocus_distance_mm = 10000\n"
                    "[microlens_array]\npitch_um = 150.0\nfocal_length_mm = 3.0\n"
                    "[sensor]\npixel_size_um = 15.4455\nrows = 200\ncols = 200\n")
    far = load_camera_file(toml)
    with pytest.raises(ValueError, match="infinity"):
        far.depth_for_slope(0.04)                       # the step beyond its focal plane
    assert 0 < depth_scale(far, far.pixels_per_lenslet) < np.inf
    raw = tmp_path / "far.npz"
    assert main(["simulate", "--scene", "flame", "--camera", str(toml), "--rays-per-pixel", "2", "--out",
                 str(raw)]) == 0
    assert main(["reconstruct", str(raw), "--no-figure", "--out", str(tmp_path / "far.h5")]) == 0
    assert "found 1 depth" in capsys.readouterr().out


def test_planes_given_closer_than_the_merge_depth_are_warned_of(capsys):
    """Planes given 0.001 mm apart (a flame's emission split 50/50 between them, without a word) are warned of,
    naming both and the camera's merge depth, and asked whether they were metres where every one lies within 1 mm
    of focus (a user's 0.091, 0.101, -0.068 had been warned of as close planes alone); planes 1 mm or more apart on
    the paper's camera are not; a plane given twice is still refused."""
    from lf_flame.cli.planes import check_planes
    check_planes(PAPER_CAMERA, [16.46, 8.15, 8.151, 0.0])
    out = capsys.readouterr().out
    assert "+8.15 and +8.151 mm lie closer than 1 mm" in out and "split" in out and "metres" not in out
    check_planes(PAPER_CAMERA, [0.02, 0.01, -0.01])                  # +20, +10 and -10 mm given in metres
    assert "were these given in metres?" in capsys.readouterr().out
    check_planes(PAPER_CAMERA, [20.0, 10.0, 1.0, 0.0, -10.0])
    assert capsys.readouterr().out == ""
    with pytest.raises(ValueError, match="more than once"):
        check_planes(PAPER_CAMERA, [10.0, 10.0])


def test_a_flame_past_the_searched_depths_is_found_at_their_end_not_beyond(cam, planted):
    """The search grid runs a step past the searched depths' ends; a flame beyond them peaks there and is found at
    the range's end (the residual's search and the refinement alike), never past it: a plane outside the searched
    depths would lie where the user asked not to look, or outside what the camera refocuses."""
    scene, views = planted
    near = min(o["depth_offset_mm"] for o in scene.objects)
    rng = (near + 0.1, 12.0)                               # the nearer flame lies 0.1 mm short of the range
    found = find_depths(views, cam, depth_range_mm=rng)
    assert found.depths_mm.min() == pytest.approx(rng[0], abs=1e-9), found.depths_mm
    routed, _, _ = find_planes(views, cam, depth_range_mm=rng)
    assert routed.depths_mm.min() >= rng[0] - 1e-9 and routed.planes_mm.min() >= rng[0] - 1e-9, routed.depths_mm


def test_refusals(cam, planted):
    scene, views = planted
    with pytest.raises(ValueError, match="shape"):
        find_depths(views[:, :, :-1], cam)
    bad = views.copy()
    bad[0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        find_depths(bad, cam)
    with pytest.raises(ValueError, match="no light"):
        find_depths(np.zeros_like(views), cam)
    with pytest.raises(ValueError, match="depth_range_mm"):
        find_depths(views, cam, depth_range_mm=(5.0, -5.0))
    stopped = PlenopticCamera(n_rows=60, n_cols=40, aperture_mm=1.0)     # its aperture image under one pixel
    with pytest.raises(ValueError, match="no view of the camera's 15 x 15 lies inside the main lens's aperture"):
        find_depths(views, stopped)
    near = imaging_range_mm(cam)[0]
    with pytest.raises(ValueError, match="depth_range_mm: depths -60 .. -30 mm lie outside what this camera can"):
        find_depths(views, cam, depth_range_mm=(-60.0, -30.0))   # wholly beyond the near end: no depth invented
    assert near > -30.0
    clipped = find_depths(views, cam, depth_range_mm=(-200.0, 5.0))  # reaching inside the focal length: clipped
    assert clipped.depth_range_mm == (near, 5.0)
    with pytest.raises(ValueError, match="threshold"):
        find_depths(views, cam, threshold=1.5)
    with pytest.raises(ValueError, match="PlenopticCamera"):
        find_depths(views, "paper")
    for n in (1, 2):        # one view holds no parallax; a decoded --views 1 capture had 'found' two depths
        few = PlenopticCamera(n_rows=12, n_cols=12, pixels_per_lenslet=n)
        with pytest.raises(ValueError, match="at least 3 views per axis.*--depth"):
            find_depths(np.ones((n, n, 12, 12)), few)
    with pytest.raises(ValueError, match="n_flames"):
        random_depth_scene(cam, np.random.default_rng(0), n_flames=5)
    with pytest.raises(ValueError, match="separation_mm"):
        behind_scene(cam, np.random.default_rng(0), 50.0)
    with pytest.raises(ValueError, match="height_range"):
        random_depth_scene(cam, np.random.default_rng(0), height_range=(3.0, 1.0))
    with pytest.raises(ValueError, match="planes"):
        score_flames(np.zeros((2, 5, 5)), [0.0, 1.0], scene, cam)


def test_cli_reconstruct_finds_the_planes_by_default(cam, planted, tmp_path, capsys):
    import json

    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    scene, views = planted
    raw = tmp_path / "lf.npz"
    np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
    out = tmp_path / "auto.h5"
    assert main(["reconstruct", str(raw), "--out", str(out)]) == 0          # no planes given: --depths auto
    printed = capsys.readouterr().out
    assert "found 2 depths" in printed
    true = sorted(o["depth_offset_mm"] for o in scene.objects)
    with h5py.File(out) as f:
        assert f.attrs["depths_from"] == "auto" and f.attrs["solver"] == "admm"
        # the time printed and recorded is the route's (the search and every solve), not its last solve's alone
        route_s = float(f.attrs["route_time_s"])
        assert route_s > f.attrs["time_s"], (route_s, f.attrs["time_s"])
        assert f"in {route_s:.2f} s (its last solve {f.attrs['time_s']:.2f} s)" in printed
        found = json.loads(f.attrs["found_depths"])
        np.testing.assert_allclose(sorted(r["depth_mm"] for r in found), true, atol=0.3)
        assert all(r["uncertainty_mm"] > 0 for r in found)
        np.testing.assert_allclose(sorted(f["depths_mm"][...]), true, atol=0.3)
    # a search narrowed to the nearer flame's depths (--search-range) finds it alone, and says where it searched
    lo, hi = true[0] - 2.0, (true[0] + true[1]) / 2
    assert main(["reconstruct", str(raw), "--search-range", str(lo), str(hi), "--no-figure", "--out", str(out)]) == 0
    assert f"found 1 depth (searched {lo:+.1f} .. {hi:+.1f} mm" in capsys.readouterr().out
    with h5py.File(out) as f:
        np.testing.assert_allclose(f["depths_mm"][...], true[:1], atol=0.3)
    assert main(["reconstruct", str(raw), "--search-range", "400", "500", "--out", str(out)]) == 2
    assert "outside what this camera can refocus" in capsys.readouterr().err
    assert main(["reconstruct", str(raw), "--depths", "1.5,-2", "--solver", "adjoint", "--out", str(out)]) == 0
    with h5py.File(out) as f:
        np.testing.assert_allclose(f["depths_mm"][...], [1.5, -2.0])
        assert "found_depths" not in f.attrs
    capsys.readouterr()
    assert main(["reconstruct", str(raw), "--depths", "auto", "--depth", "0", "--out", str(out)]) == 2
    assert "one way" in capsys.readouterr().err
    assert main(["reconstruct", str(raw), "--depths", "near", "--out", str(out)]) == 2
    assert "--depths takes" in capsys.readouterr().err


def test_the_cli_solves_found_planes_as_the_library_route(cam, planted, tmp_path, capsys):
    """On noisy data, ``lf-flame reconstruct`` with found depths takes the found planes' own knobs, as
    ``find_planes`` (whose runs the published figures are): the same settings and the same planes; a TV weight
    given is kept."""
    import json

    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    _, views = planted
    loud = np.clip(views + np.random.default_rng(2).normal(scale=0.03 * views.max(), size=views.shape), 0, None)
    raw = tmp_path / "loud.npz"
    np.savez(raw, raw=views_to_raw(loud), camera=cam.to_json())
    out = tmp_path / "auto.h5"
    assert main(["reconstruct", str(raw), "--out", str(out)]) == 0
    from lf_flame.real.lightfield import from_raw
    lf = from_raw(views_to_raw(loud), cam)                 # as the CLI reads it (noise spikes taken for defects)
    found, _, rec = find_planes(lf.views, cam, saturation=lf.fit_mask())
    with h5py.File(out) as f:
        got = json.loads(f.attrs["settings"])
        np.testing.assert_allclose(f["depths_mm"][...], found.planes_mm)
        np.testing.assert_allclose(f["planes"][...], rec.planes, rtol=1e-4, atol=1e-5 * rec.planes.max())
    keys = ("tv", "lam", "l1", "iters")
    assert {k: got[k] for k in keys} == {k: rec.settings[k] for k in keys}
    assert main(["reconstruct", str(raw), "--tv", "0.3", "--out", str(out)]) == 0
    with h5py.File(out) as f:
        assert json.loads(f.attrs["settings"])["tv"] == 0.3
    capsys.readouterr()


def test_reconstruct_warns_when_a_plane_reaches_the_fields_edge(cam, planted, tmp_path, capsys):
    """A flame cut by the field's edge: ``reconstruct`` warns and records each plane's share of emission in the
    border band; flames inside the field give no warning."""
    import json

    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.simulate import scenes
    h, w = cam.field_of_view_mm(5.0)
    yy, xx = np.mgrid[-1:1:64j, -1:1:64j]
    blob = np.exp(-(yy ** 2 + xx ** 2) / 0.2).astype(np.float32)
    cut = scenes.Scene("cut", (scenes.Layer(blob, None, 5.0, (0.0, w / 2), (0.6 * h, 0.6 * w)),), scenes.FLAME_EFFECTS)
    for name, views, planes, cut_by_edge in (("cut", _views(cam, cut, 1), ["--depth", "5"], True),
                                             ("inside", planted[1], [], False)):    # its found depths
        raw = tmp_path / f"{name}.npz"
        np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
        out = tmp_path / f"{name}.h5"
        assert main(["reconstruct", str(raw), *planes, "--out", str(out)]) == 0
        err = capsys.readouterr().err
        with h5py.File(out) as f:
            share = json.loads(f.attrs["edge_share"])
        assert ("cut by the field of view" in err) == cut_by_edge, (name, share)
        assert (max(share) > 0.01) == cut_by_edge, (name, share)


def test_support_holds_each_plane_to_its_regions(cam, planted):
    from lf_flame.tomo.found_planes import plane_support
    from lf_flame.tomo.solvers import reconstruct
    scene, views = planted
    found, op, rec = find_planes(views, cam, support=True, solve=dict(lam=0.01, tv=0.0))
    sup = plane_support(found)
    sup = sup.repeat(op.subsamples, axis=1).repeat(op.subsamples, axis=2)           # on the planes' grid
    assert sup.shape == rec.planes.shape and not np.any(sup[0] & sup[1])     # two regions, one plane each
    assert np.all(rec.planes[~sup] == 0) and np.all(rec.planes[sup].sum() > 0)
    df = score_flames(rec.planes, found.planes_mm, scene, cam, found=list(zip(found.depths_mm, found.masks)))
    assert df.share_near.min() > 0.99 and df.rel_err.max() < 0.2, df[["rel_err", "share_near"]]
    with pytest.raises(ValueError, match="support"):
        reconstruct(views, op, "admm", support=sup[:1])
    with pytest.raises(ValueError, match="admm only"):
        reconstruct(views, op, "fista", support=sup)


def _found(cam, planes_mm, regions_of_plane, labels):
    """FoundDepths with one found depth per (plane, region) pair, for the support masks."""
    from lf_flame.tomo.depth import FoundDepths
    pairs = [(p, r) for p, regs in enumerate(regions_of_plane) for r in regs]
    k = len(pairs)
    depths = np.array([planes_mm[p] for p, _ in pairs], float)
    return FoundDepths(depths_mm=depths, slopes=np.array([cam.slope_for_depth(d) for d in depths]),
                       uncertainty_mm=np.zeros(k), width_mm=np.ones(k), weight=np.ones(k),
                       region=np.array([r for _, r in pairs]), masks=np.array([labels == r for _, r in pairs]),
                       labels=labels, planes_mm=np.asarray(planes_mm, float),
                       plane_of=np.array([p for p, _ in pairs]), curves=[], grid_slopes=np.zeros(1))


def test_near_plane_support_holds_only_near_planes(cam):
    """Planes within the parallax bar are kept out of each other's regions, not out of their own nor out of a
    region they share; planes farther apart are free everywhere."""
    from lf_flame.tomo.found_planes import found_support, near_plane_support
    labels = np.zeros((cam.n_rows, cam.n_cols), int)
    labels[5:20, 3:12], labels[5:20, 25:35], labels[35:50, 10:30] = 1, 2, 3
    per_mm = abs(cam.slope_for_depth(1.0) - cam.slope_for_depth(0.0)) * (cam.pixels_per_lenslet - 1)
    near = 2.0 / per_mm                                   # two lenslets of parallax apart, in mm
    found = _found(cam, [0.0, near], [(1, 3), (2, 3)], labels)   # region 3 holds both planes
    sup = near_plane_support(found, cam, parallax=3.0, dilation=0)
    assert sup.shape == (2,) + labels.shape
    assert not sup[0][labels == 2].any() and not sup[1][labels == 1].any()      # out of the other's region
    assert sup[0][labels == 1].all() and sup[1][labels == 2].all()              # in its own
    assert sup[:, labels == 3].all() and sup[:, labels == 0].all()             # shared region, empty field
    assert near_plane_support(found, cam, parallax=1.5, dilation=0) is None    # 2 lenslets apart: not near
    far = _found(cam, [0.0, 4 * near], [(1,), (2,)], labels)
    assert near_plane_support(far, cam, parallax=3.0) is None
    grid = found_support(found, cam, 2, near_parallax=3.0, dilation=0)
    assert grid.shape == (2, 2 * cam.n_rows, 2 * cam.n_cols) and np.array_equal(grid[:, ::2, ::2], sup)
    with pytest.raises(ValueError, match="parallax"):
        near_plane_support(found, cam, parallax=float("nan"))


def test_near_planes_keep_their_light_apart(cam):
    """Two flames side by side about two lenslets of parallax apart: without the near planes' support a little
    of each flame's light lands on the other's plane; with it (the default) none does, and no flame is worse."""
    from lf_flame.simulate import scenes
    from lf_flame.simulate.scenes_depth import _flame
    flames = [_flame(cam, d, 4.0, 0.3, cx, -2.0, 0.8, 4.0, f"flame_{k}") for k, (d, cx) in
              enumerate(((5.0, -1.2), (6.3, 1.2)))]
    scene = scenes.Scene("pair", tuple(f[0] for f in flames), scenes.FLAME_EFFECTS, tuple(f[1] for f in flames))
    views = _views(cam, scene, 1)
    scores = {}
    for parallax in (3.0, 0.0):
        found, _, rec = find_planes(views, cam, near_parallax=parallax)
        assert len(found.planes_mm) == 2
        scores[parallax] = score_flames(rec.planes, found.planes_mm, scene, cam,
                                        found=list(zip(found.depths_mm, found.masks)))
    assert scores[3.0].share_near.min() > 0.999 and scores[0.0].share_near.min() < 0.995, scores
    assert scores[3.0].rel_err.max() < scores[0.0].rel_err.max() + 0.005, scores


def test_planes_given_near_each_other_keep_their_light_apart(cam, tmp_path, capsys):
    """``reconstruct --depth`` with two planes about two lenslets of parallax apart, each at a flame's depth: the
    depth search's regions are put on the given planes, which then keep their flames' light apart, as found planes
    do (solved free: 99.0 % of each flame on its own plane, here 100 %), no flame worse; planes given far apart are
    solved as before."""
    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.simulate import scenes
    from lf_flame.simulate.scenes_depth import _flame
    flames = [_flame(cam, d, 4.0, 0.3, cx, -2.0, 0.8, 4.0, f"flame_{k}") for k, (d, cx) in
              enumerate(((5.0, -1.2), (6.3, 1.2)))]
    scene = scenes.Scene("pair", tuple(f[0] for f in flames), scenes.FLAME_EFFECTS, tuple(f[1] for f in flames))
    raw = tmp_path / "pair.npz"
    np.savez(raw, raw=views_to_raw(_views(cam, scene, 1)), camera=cam.to_json())
    for planes, held in ((["--depth", "5.0", "--depth", "6.3"], True), (["--depth", "-8", "--depth", "6.3"], False)):
        out = tmp_path / f"pair{held}.h5"
        assert main(["reconstruct", str(raw), *planes, "--no-figure", "--out", str(out)]) == 0
        assert ("are held to the regions their depths were found in" in capsys.readouterr().out) == held
        with h5py.File(out) as f:
            solved, support = f["planes"][:], json.loads(f.attrs["settings"]).get("support")
            record = json.loads(f.attrs["given_planes_held"]) if "given_planes_held" in f.attrs else None
        if not held:
            assert record is None and support is None
            continue
        assert support == "near planes" and [r["plane_mm"] for r in record] == [5.0, 6.3]
        df = score_flames(solved, [5.0, 6.3], scene, cam)
        assert df.share_near.min() > 0.999, df
        assert df.rel_err.max() < 0.05, df                        # as free planes (4.2 %): no flame worse


def test_planes_without_flames_are_those_far_in_parallax_from_every_found_depth(cam):
    from lf_flame.tomo.found_planes import planes_without_flames
    found = _found(cam, [0.0, 6.0], [[0], [1]], np.zeros((cam.n_rows, cam.n_cols), int))
    per_mm = abs(cam.slope_for_depth(1.0) - cam.slope_for_depth(0.0)) * (cam.pixels_per_lenslet - 1)
    near = 2.9 / per_mm                                   # 2.9 lenslets of parallax from the flame at 0 mm
    assert list(planes_without_flames(found, cam, [0.0, -near, 6.0 + 4.0 / per_mm, 3.0])) == [False, False, True,
                                                                                              3.0 * per_mm >= 3.0]
    assert list(planes_without_flames(found, cam, [-near], parallax=2.0)) == [True]
    assert planes_without_flames(dataclasses.replace(found, depths_mm=np.zeros(0)), cam, [0.0]).all()
    with pytest.raises(ValueError, match="parallax"):
        planes_without_flames(found, cam, [0.0], parallax=-1.0)


def test_a_plane_given_where_no_flame_stands_is_warned_of(cam, planted, tmp_path, capsys):
    """``reconstruct`` and ``profiles`` with a plane given far from both flames: the depth search finds no flame near
    it, and both commands say so (the file records it, profiles flags its rows), instead of the edge warning's "the
    flame is cut" or a flame measured there without a word; planes at the flames give no such warning."""
    import h5py
    import pandas as pd

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    scene, views = planted
    true = sorted(float(o["depth_offset_mm"]) for o in scene.objects)
    lo, hi = imaging_range_mm(cam)
    empty = max((d for d in np.linspace(lo + 1, hi - 1, 41)), key=lambda d: min(abs(d - t) for t in true))
    raw = tmp_path / "planted.npz"
    np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
    for planes, without in ((true, []), (true + [empty], [empty])):
        given = [x for d in planes for x in ("--depth", f"{d:.4f}")]
        out = tmp_path / f"r{len(planes)}.h5"
        assert main(["reconstruct", str(raw), *given, "--no-figure", "--out", str(out)]) == 0
        err = capsys.readouterr().err
        assert ("finds no flame near the plane at" in err) == bool(without), err
        assert "the flame is cut by the field of view" not in err
        with h5py.File(out) as f:
            assert json.loads(f.attrs["planes_without_flame"]) == pytest.approx(without, abs=1e-3)
        assert main(["profiles", str(raw), *given, "--no-figure", "--out", str(tmp_path / f"p{len(planes)}")]) == 0
        df = pd.read_csv(tmp_path / f"p{len(planes)}.csv")
        flagged = df["flags"].astype(str).str.contains("no-flame-found")
        assert set(df.depth_mm[flagged].round(3)) == {round(d, 3) for d in without}, df[["depth_mm", "flags"]]


def test_a_flame_hidden_behind_others_is_not_taken_for_an_empty_plane(cam, tmp_path, capsys):
    """Three flames in one column band, whose third the depth search's votes miss (its lenslets vote for the
    others): given the three true depths, ``reconstruct`` does not warn that no flame stands at the third, as the
    solve without its plane leaves its light unexplained (the data need it)."""
    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.simulate.scenes_depth import column_scene
    from lf_flame.tomo.found_planes import planes_without_flames
    scene = column_scene(cam, np.random.default_rng(4))
    views = _views(cam, scene, 4)
    true = sorted(float(o["depth_offset_mm"]) for o in scene.objects)
    assert planes_without_flames(find_depths(views, cam), cam, true).any()         # the votes miss one
    raw = tmp_path / "column.npz"
    np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
    out = tmp_path / "column.h5"
    assert main(["reconstruct", str(raw), *[x for d in true for x in ("--depth", f"{d:.4f}")], "--no-figure",
                 "--out", str(out)]) == 0
    assert "finds no flame near" not in capsys.readouterr().err
    with h5py.File(out) as f:
        assert json.loads(f.attrs["planes_without_flame"]) == []


def test_column_scenes_stand_flames_one_behind_another():
    """Two or three flames in one column band, 3-15 mm apart in depth, brightness within the ratio, a flame near
    focus in at least a third of the scenes; bad counts and short ranges refused."""
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.simulate.scenes_depth import COLUMN_RATIO, COLUMN_SEPARATION_MM, column_scene
    counts, near = set(), 0
    for seed in range(30):
        sc = column_scene(PAPER_CAMERA, np.random.default_rng(seed))
        d = np.array([o["depth_offset_mm"] for o in sc.objects])
        counts.add(len(d))
        assert np.all(np.diff(d) >= COLUMN_SEPARATION_MM[0]) and np.all(np.diff(d) <= COLUMN_SEPARATION_MM[1])
        x = np.array([o["centre_x_mm"] for o in sc.objects])
        assert np.ptp(x) <= 0.8 + 1e-9                                     # one column band
        r = np.array([o["radiance"] for o in sc.objects])
        assert r.max() <= 1.0 and r.max() / r.min() <= (COLUMN_RATIO[1] / COLUMN_RATIO[0]) + 1e-9
        near += bool(np.any(np.abs(d) <= 3.0))
    assert counts == {2, 3} and near >= 10, (counts, near)            # at least the third drawn so
    with pytest.raises(ValueError, match="n_flames"):
        column_scene(PAPER_CAMERA, np.random.default_rng(0), n_flames=4)
    with pytest.raises(ValueError, match="too short"):
        column_scene(PAPER_CAMERA, np.random.default_rng(0), n_flames=3, depth_range=(-5.0, 5.0))


def test_a_flame_behind_others_is_found_in_the_residual(cam):
    """Three flames in one column band: the votes find two (the third's lenslets vote for the others), the solve's
    residual refocuses sharply at the third's depth, and the planes solved again with it recover every flame."""
    from lf_flame.simulate.scenes_depth import column_scene
    from lf_flame.tomo.peel import missed_depths
    scene = column_scene(cam, np.random.default_rng(4))
    views = _views(cam, scene, 4)
    true = [o["depth_offset_mm"] for o in scene.objects]
    scores = {}
    for rounds in (0, 2):
        found, _, rec = find_planes(views, cam, peel_rounds=rounds)
        scores[rounds] = score_flames(rec.planes, found.planes_mm, scene, cam,
                                      found=list(zip(found.depths_mm, found.masks)))
    assert scores[0].depth_mm.isna().sum() == 1                                   # the votes miss one
    assert scores[2].depth_mm.notna().all() and scores[2].depth_err_mm.abs().max() < 0.5, (true, scores[2])
    assert scores[2].rel_err.max() < 0.1 < scores[0].rel_err.max(), scores
    # a residual of noise alone holds no missed depth
    found, op, rec = find_planes(views, cam)
    noise = np.random.default_rng(0).normal(0.0, 0.01, views.shape)
    assert missed_depths(noise, cam, found) is None
    # noise on the residual raises its focus curve's floor, not its peak's prominence: the missed flame stays found
    # with noise of 0.3 of the data's peak (where the peak is 6 times the curve's median, under 12 times at 14 dB)
    found, op, rec = find_planes(views, cam, peel_rounds=0)
    y = np.asarray(views, np.float64)
    residual = y - (op @ np.ravel(rec.planes)).reshape(y.shape)
    loud = residual + np.random.default_rng(1).normal(0.0, 0.3 * y.max(), y.shape)
    more = missed_depths(loud, cam, found)
    assert more is not None and len(more.depths_mm) == len(found.depths_mm) + 1
    assert np.min(np.abs(more.depths_mm - sorted(true)[0])) < 0.5, (true, more.depths_mm)


def test_a_quiet_light_fields_faint_flame_is_found_at_a_lower_prominence(cam, monkeypatch):
    """In a quiet light field the search after the refinement finds a flame several times fainter than the one it
    stands behind whose residual peak stands under :data:`REFINED_PROMINENCE` (asked of noisy light fields): the peak's
    height above the residual's floor holds :data:`REFINED_SHARE` of the data's energy, which no misfit does."""
    import lf_flame.tomo.refine as refine
    from lf_flame.simulate.scenes_depth import column_scene
    from lf_flame.tomo.noise_knobs import noise_regime, relative_noise
    scene = column_scene(cam, np.random.default_rng(86))
    views = _views(cam, scene, 86)
    assert noise_regime(relative_noise(views)) == "quiet"
    scores = {}
    for prominence in (refine.REFINED_PROMINENCE, refine.REFINED_QUIET_PROMINENCE):
        with monkeypatch.context() as mp:
            mp.setattr(refine, "REFINED_QUIET_PROMINENCE", prominence)
            # searched over -15 .. +25 mm, whose residual curve puts this flame's peak between the two prominences
            found, _, rec = find_planes(views, cam, depth_range_mm=(-15.0, 25.0))
        scores[prominence] = score_flames(rec.planes, found.planes_mm, scene, cam,
                                          found=list(zip(found.depths_mm, found.masks)))
    strict, quiet = scores[refine.REFINED_PROMINENCE], scores[refine.REFINED_QUIET_PROMINENCE]
    assert strict.depth_mm.isna().sum() == 1, strict
    assert quiet.depth_mm.notna().all() and quiet.depth_err_mm.abs().max() < 0.1, quiet
    assert quiet.rel_err.max() < 0.1, quiet
    # the peak's height above the residual's floor: asked more of than the data hold, nothing is found
    from lf_flame.tomo.peel import missed_depths
    found = find_depths(views, cam)
    assert missed_depths(views, cam, found, prominence=1.0, share=0.0) is not None
    assert missed_depths(views, cam, found, prominence=1.0, share=0.0, excess=1e6) is None
    with pytest.raises(ValueError, match="excess"):
        missed_depths(views, cam, found, excess=-1.0)

def test_a_noisy_light_fields_faint_flame_short_of_the_prominence_is_reported(cam, monkeypatch, tmp_path, capsys):
    """Where the light field's noise asks :data:`REFINED_PROMINENCE` of the search after the refinement, a faint
    flame whose residual peak stands between :data:`POSSIBLE_PROMINENCE` and it is not solved on but reported in
    ``found.possible`` at its depth; ``lf-flame reconstruct`` warns with the planes to give and records it."""
    import json

    import h5py

    import lf_flame.tomo.noise_knobs as noise_knobs
    import lf_flame.tomo.refine as refine
    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.simulate.scenes_depth import column_scene
    scene = column_scene(cam, np.random.default_rng(86))
    views = _views(cam, scene, 86)
    faint = min((o for o in scene.objects), key=lambda o: o["radiance"] * o["height_mm"])["depth_offset_mm"]
    monkeypatch.setattr(noise_knobs, "noise_regime", lambda noise: "noisy")
    narrow = (-15.0, 25.0)        # searched over these depths, the flame's residual peak stands between the two
    found, _, _ = find_planes(views, cam, depth_range_mm=narrow)
    assert np.min(np.abs(found.depths_mm - faint)) > 1.0, found.depths_mm          # not taken
    assert len(found.possible) == 1, found.possible
    p = found.possible[0]
    assert abs(p["depth_mm"] - faint) < 0.5 and refine.POSSIBLE_PROMINENCE <= p["prominence"] < refine.REFINED_PROMINENCE
    assert p["share"] >= refine.REFINED_SHARE
    # over the camera's whole imaging range (the default, as on the command line) it stands higher: asked more
    raw = tmp_path / "column.npz"
    np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
    out = tmp_path / "column.h5"
    with monkeypatch.context() as mp:
        mp.setattr(refine, "REFINED_PROMINENCE", 1e3)
        assert main(["reconstruct", str(raw), "--no-figure", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    with h5py.File(out) as f:
        recorded = json.loads(f.attrs["possible_depths"])
    assert len(recorded) == 1 and abs(recorded[0]["depth_mm"] - faint) < 0.5, recorded
    assert f"a flame may stand at {recorded[0]['depth_mm']:+.2f} mm" in err and "--depth" in err, err
    # asked to stand higher than it does, it is not reported
    monkeypatch.setattr(refine, "POSSIBLE_PROMINENCE", p["prominence"] + 0.1)
    assert find_planes(views, cam, depth_range_mm=narrow)[0].possible == []
    # a recording's planes, found in its first frame as reconstruct finds them, warn of it too
    import dataclasses

    import lf_flame.cli.planes as planes
    from lf_flame.cli.sequence import first_frame_depths

    class Frames:
        def frames(self, start, stop):
            yield views_to_raw(views)
    monkeypatch.setattr(planes, "solve_found", lambda lf, f: (dataclasses.replace(f, possible=[p]), None, None))
    planes, _ = first_frame_depths(Frames(), cam)
    err = capsys.readouterr().err
    assert f"a flame may stand at {p['depth_mm']:+.2f} mm" in err and f"--depth {planes[0]:.2f}" in err, err


def test_a_faint_flame_behind_refined_ones_is_found_in_their_residual(cam, monkeypatch):
    """A faint flame behind a brighter one near focus: the first search of the residual misses it (the misfit of
    the others' unrefined depths is as strong), the search after the refinement finds it, and every flame comes back
    within 10 %."""
    import lf_flame.tomo.refine as refine
    from lf_flame.simulate.scenes_depth import column_scene
    scene = column_scene(cam, np.random.default_rng(378))
    views = _views(cam, scene, 378)
    scores = {}
    for share in (1.0, refine.REFINED_SHARE):          # 1.0: no search after the refinement
        monkeypatch.setattr(refine, "REFINED_SHARE", share)
        found, _, rec = find_planes(views, cam)
        scores[share] = score_flames(rec.planes, found.planes_mm, scene, cam,
                                     found=list(zip(found.depths_mm, found.masks)))
    before, after = scores[1.0], scores[refine.REFINED_SHARE]
    assert before.depth_mm.isna().sum() == 1, before
    assert after.depth_mm.notna().all() and after.depth_err_mm.abs().max() < 0.1, after
    assert after.rel_err.max() < 0.1, after


def test_the_search_after_the_refinement_skips_regions_of_merged_planes(cam, behind):
    """Only regions of several depths, each on its own plane, are searched again: a merged plane is not refined and
    keeps its misfit."""
    import dataclasses

    from lf_flame.tomo.refine import refined_regions
    found = find_depths(behind[1], cam)
    five = dataclasses.replace(found, region=np.array([0, 0, 1, 1, 2]), plane_of=np.array([0, 1, 2, 2, 3]))
    assert refined_regions(five) == [0]                 # region 1 shares a plane, region 2 holds one depth
    apart = dataclasses.replace(five, plane_of=np.arange(5))
    assert refined_regions(apart) == [0, 1]


def test_the_cli_finds_the_hidden_flame_as_the_library_route(cam, tmp_path, capsys):
    """``lf-flame reconstruct`` searches its solve's residual as ``find_planes`` does: it says what it found there,
    and records every depth with the planes of the library route."""
    import json

    import h5py

    from lf_flame.cli import main
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.simulate.scenes_depth import column_scene
    views = _views(cam, column_scene(cam, np.random.default_rng(4)), 4)
    raw = tmp_path / "column.npz"
    np.savez(raw, raw=views_to_raw(views), camera=cam.to_json())
    out = tmp_path / "column.h5"
    assert main(["reconstruct", str(raw), "--out", str(out)]) == 0
    assert "found in the residual" in capsys.readouterr().out
    found, _, rec = find_planes(raw_to_views(views_to_raw(views), cam.pixels_per_lenslet), cam)
    assert len(found.depths_mm) == 3
    with h5py.File(out) as f:
        np.testing.assert_allclose([d["depth_mm"] for d in json.loads(f.attrs["found_depths"])], found.depths_mm)
        np.testing.assert_allclose(f["depths_mm"][...], found.planes_mm)
        np.testing.assert_allclose(f["planes"][...], rec.planes, rtol=1e-4, atol=1e-5 * rec.planes.max())


def test_score_flames_one_found_depth_for_flames_side_by_side_not_behind(cam, planted, behind):
    """A depth found over two flames side by side (a camera too coarse in depth to part them) is each one's
    depth; over two flames in the same columns it is one's, and the other is missed."""
    for (scene, _), shared in ((planted, True), (behind, False)):
        depths = [o["depth_offset_mm"] for o in scene.objects]
        truth = np.array([resample_layer(L, (cam.n_rows, cam.n_cols), plane_grid(cam, d))
                          for L, d in zip(scene.layers, depths)])
        mid = float(np.mean(depths))
        both = np.ones((cam.n_rows, cam.n_cols), bool)
        df = score_flames(truth, depths, scene, cam, found=[(mid, both)])
        if shared:
            np.testing.assert_allclose(df.depth_mm, mid)
        else:
            assert df.depth_mm.isna().sum() == 1 and np.nanmax(df.depth_mm) == mid


def test_data_misfit_tells_planes_that_hold_the_scene_from_planes_that_do_not(cam, planted):
    """The found planes explain the light field to its noise; planes 5 mm off leave light unexplained, noise or not.
    The noise's own estimate reads the noise that was added (white, of known deviation)."""
    from lf_flame.tomo.noise_knobs import noise_norm
    from lf_flame.tomo.solvers import data_misfit, misfit_is_high, reconstruct
    scene, views = planted
    sigma = 0.05 * float(views.max())
    loud = views + np.random.default_rng(5).normal(0.0, sigma, views.shape)
    added = sigma * np.sqrt(views.size)
    assert 0.9 < noise_norm(loud) / added < 1.1
    for v in (views, loud):
        found, op, rec = find_planes(v, cam)
        good = data_misfit(v, op, rec.planes, None)
        off_op = emission_operator(cam, [d + 5.0 for d in found.planes_mm], subsamples=op.subsamples)
        off = data_misfit(v, off_op, reconstruct(v, off_op, "admm", saturation=None).planes, None)
        assert not misfit_is_high(good) and misfit_is_high(off), (good, off)
        assert off["misfit"] > 3 * good["misfit"] and off["relative_residual"] > good["relative_residual"]
    with pytest.raises(ValueError, match="planes must be finite"):
        data_misfit(views, op, rec.planes[:1], None)


def test_reconstruct_warns_when_its_planes_leave_light_unexplained(cam, planted, tmp_path, capsys):
    """``reconstruct`` on planes where no flame stands warns that light is left unexplained and records the
    misfit, and adds that more fills may explain more where admm ran every fill of its cap with its residual still
    falling (where it had levelled off or risen, more fills had made a user's misfit worse); on the found planes
    it records the misfit without a warning."""
    import json

    import h5py

    from lf_flame.cli import main
    from lf_flame.cli.fit_notes import STILL_FALLING
    from lf_flame.refocus.shift_and_sum import views_to_raw
    raw = tmp_path / "planted.npz"
    np.savez(raw, raw=views_to_raw(planted[1]), camera=cam.to_json())
    far = max(o["depth_offset_mm"] for o in planted[0].objects) + 6.0
    for planes, warned in (([], False), (["--depth", f"{far:.2f}"], True), (["--depth", f"{far:.2f}", "--iters", "1"],
                                                                           True)):
        out = tmp_path / "rec.h5"
        assert main(["reconstruct", str(raw), *planes, "--out", str(out)]) == 0
        err = capsys.readouterr().err
        with h5py.File(out) as f:
            misfit = json.loads(f.attrs["misfit"])
            settings = json.loads(f.attrs["settings"])
            r = f["residuals"][...]
        assert ("unexplained beyond its noise" in err) == warned, (planes, misfit, err)
        assert (misfit["misfit"] > 0.1) == warned, misfit
        falling = len(r) < 2 or r[-1] < (1 - STILL_FALLING) * r[-2]      # still falling, or too few fills to tell
        assert ("more fills (--iters)" in err) == (warned and settings["fills_run"] >= settings["iters"] and falling), \
            (err, r)
    assert "--iters" in planes and "fills' cap (1)" in err


def test_the_misfit_warning_suggests_more_fills_only_while_the_residual_still_falls(cam, planted, tmp_path, capsys):
    """The same high misfit at admm's fills' cap: "more fills (--iters)" is suggested where the residual still fell
    over the last fill, not where it levelled off or rose (a user's 16-bit capture: 0.585 at 2 fills, 0.719 at 20,
    and the warning had asked for more)."""
    import dataclasses

    from lf_flame.cli.fit_notes import misfit_warning
    from lf_flame.real.readers import read_light_field
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.tomo.solvers import reconstruct
    np.savez(tmp_path / "planted.npz", raw=views_to_raw(planted[1]), camera=cam.to_json())
    lf = read_light_field(tmp_path / "planted.npz")
    far = max(o["depth_offset_mm"] for o in planted[0].objects) + 6.0
    op = emission_operator(cam, [far], subsamples=2)
    rec = reconstruct(lf.views, op, "admm", iters=4, saturation=None)
    for residuals, advised in (([0.50, 0.45, 0.40], True), ([0.50, 0.52, 0.55], False), ([0.50, 0.499, 0.4985],
                                                                                          False)):
        capsys.readouterr()
        misfit_warning(lf, op, dataclasses.replace(rec, residuals=np.array(residuals)), saturation=None)
        err = capsys.readouterr().err
        assert "unexplained beyond its noise" in err and ("more fills (--iters)" in err) == advised, (residuals, err)


def test_the_slope_jacobian_is_the_five_point_stencil_on_the_fitted_samples():
    """``slope_jacobian``'s kernel against NumPy: each view's five-point derivatives along rows and columns (edges
    padded by their values) weighted by the view's offset, 0 on the samples not fitted."""
    from lf_flame.tomo.refine import slope_jacobian
    rng = np.random.default_rng(4)
    a = rng.normal(size=(3, 3, 7, 6))
    fit = rng.random(a.shape) < 0.7

    class Op:                                    # the prediction of plane p alone is ``a`` times its value
        dimsd = a.shape

        def matvec(self, x):
            return a.ravel() * x.sum()

    def d(axis):
        b = np.pad(a, [(2, 2) if k == axis else (0, 0) for k in range(4)], mode="edge")
        n = a.shape[axis]
        return sum(w * np.take(b, range(2 + k, 2 + k + n), axis=axis) for k, w in ((-2, 1), (-1, -8), (1, 8),
                                                                                   (2, -1))) / 12.0
    u = np.arange(3) - 1.0
    want = np.where(fit, -(u[:, None, None, None] * d(2) + u[None, :, None, None] * d(3)), 0.0)
    got = slope_jacobian(Op(), np.ones((2, 1, 1)), fit, [1])
    assert got.shape == (1,) + a.shape
    np.testing.assert_allclose(got[0], want, rtol=1e-12, atol=1e-12)


def test_refined_depths_of_flames_one_behind_another(cam, behind):
    """Two flames in one column band: the votes' depths are pulled by each other's defocused light; Gauss-Newton on
    the planes' slopes against the residual brings both closer to the truth and lowers the residual."""
    from lf_flame.tomo.refine import refine_planes, slope_jacobian
    from lf_flame.tomo.solvers import fitted_pixels, reconstruct
    scene, views = behind
    true = np.array(sorted(o["depth_offset_mm"] for o in scene.objects))
    found, op, rec = find_planes(views, cam, refine_steps=0)
    y = np.asarray(views, np.float64)
    fit = fitted_pixels(y, 1.0)
    # the Jacobian in a slope matches a finite difference of the operator
    s0 = cam.slope_for_depth(found.planes_mm[0])
    moved = emission_operator(cam, [cam.depth_for_slope(s0 + 0.01)] + list(found.planes_mm[1:]),
                              subsamples=op.subsamples)
    x0 = rec.planes.copy()
    x0[1:] = 0
    numeric = ((moved @ x0.ravel()) - (op @ x0.ravel())).reshape(y.shape) / 0.01
    J = slope_jacobian(op, rec.planes, np.ones(y.shape, bool))[0]
    assert np.vdot(J, numeric) / (np.linalg.norm(J) * np.linalg.norm(numeric)) > 0.9
    assert 0.8 < np.linalg.norm(J) / np.linalg.norm(numeric) < 1.25

    def solve(f, start=None):
        o = emission_operator(cam, [float(d) for d in f.planes_mm], subsamples=op.subsamples)
        return o, reconstruct(y, o, "admm")
    op, rec = solve(found)
    before = np.abs(np.sort(found.depths_mm) - true)
    res0 = np.linalg.norm(np.where(fit, (op @ rec.planes.ravel()).reshape(y.shape) - y, 0))
    f2, op2, rec2 = refine_planes(found, op, rec, y, fit, cam, solve, steps=2)
    after = np.abs(np.sort(f2.depths_mm) - true)
    res2 = np.linalg.norm(np.where(fit, (op2 @ rec2.planes.ravel()).reshape(y.shape) - y, 0))
    assert res2 < res0 and after.max() < before.max() and after.max() < 0.1, (true, found.depths_mm, f2.depths_mm)
    assert f2.depths_mm.shape == found.depths_mm.shape and f2.planes_mm.shape == found.planes_mm.shape



def test_the_secant_lengthens_a_gauss_newton_step_by_the_curvature_it_met():
    """Two overlapping peaks whose centres are fitted by variable projection (their heights solved at each pair of
    centres, as the planes are at each pair of depths): Gauss-Newton's J^T J leaves out that one height absorbs
    part of the other centre's move, so a step goes only part of the way. The curvature the first step met sets
    the second step's length: the ratio of J^T J to the projected (Kaufman) curvature along it, and the lengthened
    second step lands far nearer the true centres than the plain one. A step that met no curvature, or negative,
    is not lengthened; a tiny one is lengthened at most REFINE_SECANT_MAX times."""
    from lf_flame.tomo.refine import REFINE_SECANT_MAX, secant_scale
    t = np.linspace(-6, 6, 400)
    s_true = np.array([0.0, 2.5])
    y = np.exp(-(t[:, None] - s_true) ** 2 / 2) @ np.array([1.0, 0.6])

    def state(s):
        A = np.exp(-(t[:, None] - s) ** 2 / 2)
        x = np.linalg.lstsq(A, y, rcond=None)[0]
        J = (x * (t[:, None] - s) * A).T                   # d(A_k x_k)/ds_k
        return A, y - A @ x, J
    s0 = s_true + 0.1
    A, r, J = state(s0)
    b, JJ = J @ r, J @ J.T
    ds = np.linalg.solve(JJ, b)
    _, r1, J1 = state(s0 + ds)
    b1 = J1 @ r1
    scale = secant_scale(ds, b, JJ, b1)
    projected = J @ (np.eye(len(t)) - A @ np.linalg.pinv(A)) @ J.T
    assert scale == pytest.approx((ds @ JJ @ ds) / (ds @ projected @ ds), rel=0.05) and scale > 1.2
    step = np.linalg.solve(J1 @ J1.T, b1)
    plain, lengthened = (np.abs(s0 + ds + k * step - s_true).max() for k in (1.0, scale))
    assert lengthened < 0.4 * plain, (plain, lengthened)
    assert secant_scale(ds, b, JJ, b) == 1.0                  # no change of the gradient: no curvature met
    assert secant_scale(ds, b1, JJ, b) == 1.0                 # the gradient rose along the step: not convex
    assert secant_scale(ds, b, JJ, b + 1e-6 * (b1 - b)) == REFINE_SECANT_MAX


def test_the_route_lengthens_its_refinement_steps_in_a_quiet_light_field_only(cam, behind, monkeypatch):
    """find_planes' refinement takes the secant's longer steps where the solves converge (a quiet light field), and
    plain Gauss-Newton steps where noise stops them early (their gradients rough: mixed on validation scenes)."""
    from lf_flame.tomo import refine
    from lf_flame.tomo.noise_knobs import noise_regime, relative_noise
    from lf_flame.tomo.solvers import fitted_pixels
    _, views = behind
    noisy = views + np.random.default_rng(0).normal(0, 0.05 * views.max(), views.shape)
    scales = []
    real = refine.secant_scale
    monkeypatch.setattr(refine, "secant_scale", lambda *a: scales.append(real(*a)) or scales[-1])
    for v, quiet in ((views, True), (noisy, False)):
        assert (noise_regime(relative_noise(v, fitted_pixels(v, 1.0))) == "quiet") == quiet
        scales.clear()
        find_planes(v, cam)
        assert bool(scales) == quiet, scales


def test_a_warm_refinement_step_that_does_not_lower_the_residual_is_solved_cold(cam, behind):
    """A quiet light field's refinement solves each step from the planes before it; where that warm solve does not
    lower the residual (a plane moved millimetres keeps its old depth's fit through the few fills: a colour
    camera's flame found in the residual 3.9 mm off stayed there), the step is solved cold before the refinement
    stops. Here every warm solve is made useless (empty planes): the depths still refine as cold solves refine them."""
    import dataclasses

    from lf_flame.tomo.refine import refine_planes
    from lf_flame.tomo.solvers import fitted_pixels, reconstruct
    scene, views = behind
    found, op, rec = find_planes(views, cam, refine_steps=0)
    y = np.asarray(views, np.float64)
    fit = fitted_pixels(y, 1.0)
    calls = []

    def solve(f, start=None):
        o = emission_operator(cam, [float(d) for d in f.planes_mm], subsamples=op.subsamples)
        calls.append(start is not None)
        return o, (dataclasses.replace(start, planes=0 * start.planes) if start is not None else
                   reconstruct(y, o, "admm"))
    op, rec = solve(found)
    cold = refine_planes(found, op, rec, y, fit, cam, solve, steps=2)[0]
    warm = refine_planes(found, op, rec, y, fit, cam, solve, steps=2, warm=True)[0]
    moved = np.abs(cold.planes_mm - found.planes_mm).max()
    assert any(calls) and moved > 0.2, (found.planes_mm, cold.planes_mm)
    np.testing.assert_allclose(warm.planes_mm, cold.planes_mm, atol=1e-9)

def test_the_refinement_stays_within_the_depths_the_camera_images(cam, behind):
    """A found depth's reach (REFINE_REACH times its uncertainty) that runs past the depths the camera images
    (here nearer than the main lens's focal length, as a far camera's wide uncertainties near its range's end do):
    the refinement stops it at the nearest depth the search ran over instead of converting an impossible depth to a
    slope (which raised 'at or inside the main-lens focal length')."""
    import dataclasses

    from lf_flame.tomo.focus import _grid_depths
    from lf_flame.tomo.refine import refine_planes
    from lf_flame.tomo.solvers import fitted_pixels, reconstruct
    _, views = behind
    found, op, rec = find_planes(views, cam, refine_steps=0)
    wide = dataclasses.replace(found, uncertainty_mm=np.full(len(found.depths_mm), 1e4))
    assert np.all(cam.focus_distance_mm + wide.depths_mm - 3e4 < cam.main_focal_mm)
    y = np.asarray(views, np.float64)

    def solve(f, start=None):
        o = emission_operator(cam, [float(d) for d in f.planes_mm], subsamples=op.subsamples)
        return o, reconstruct(y, o, "admm")
    f2, _, _ = refine_planes(wide, op, rec, y, fitted_pixels(y, 1.0), cam, solve, steps=2)
    searched = _grid_depths(cam, found.grid_slopes)
    assert np.all(np.isfinite(f2.planes_mm)) and np.all(f2.planes_mm >= np.nanmin(searched)), f2.planes_mm


def test_objects_before_a_bright_background_are_searched_apart(cam, planted):
    """Two flames 1.2 mm apart in depth, side by side, before a lit wall 20 mm behind focus: the central view is
    bright everywhere, so the regions come from the light field's detail, and each flame's depth is found in its
    own region (one region, as brightness alone gives, merges them into one peak)."""
    import dataclasses

    from lf_flame.simulate.layers import Layer
    from lf_flame.tomo import depth
    layers = tuple(dataclasses.replace(L, depth_offset_mm=d) for L, d in zip(planted[0].layers, (3.0, 4.2)))
    rows, cols = layers[0].radiance.shape
    h, w = cam.field_of_view_mm(20.0)
    yy, xx = np.mgrid[0:rows, 0:cols] / np.array([rows, cols])[:, None, None]
    wall = Layer(radiance=(0.4 + 0.1 * np.sin(3 * np.pi * yy) * np.cos(2.4 * np.pi * xx)).astype(np.float32),
                 alpha=None, depth_offset_mm=20.0, centre_mm=(0.0, 0.0), size_mm=(1.5 * h, 1.5 * w))
    views = _views(cam, dataclasses.replace(planted[0], layers=layers + (wall,)), 7)
    found = find_depths(views, cam)
    assert found.labels.max() == 2 and found.depths_mm == pytest.approx([3.0, 4.2], abs=0.1), found.depths_mm
    with pytest.MonkeyPatch.context() as mp:                         # brightness alone: one region, one peak
        mp.setattr(depth, "BRIGHT_FIELD_SHARE", 2.0)
        assert len(find_depths(views, cam).depths_mm) == 1


def test_the_depth_search_takes_a_grid_that_runs_past_infinity():
    """A camera focused far (10 m) images out to infinity within a slope step of its imaging range's far end (a real
    camera's 50 mm lens at 250 mm too): the search grid runs past the slope that focuses at infinity, where
    converting the grid's slopes to depths raised 'focuses at or beyond infinity' in the residual's search. Both
    searches skip those slopes."""
    from lf_flame.tomo.peel import missed_depths
    far = PlenopticCamera(focus_distance_mm=10000.0, n_rows=60, n_cols=40)
    scene = random_depth_scene(far, np.random.default_rng(5), n_flames=2)
    views = _views(far, scene, 5, rays=8)
    found = find_depths(views, far)
    assert found.grid_slopes.max() > far.slope_for_depth(1e15)
    assert len(found.depths_mm) and np.all(np.isfinite(found.depths_mm))
    more = missed_depths(views, far, found, prominence=1.0, share=0.0)      # the data as the residual: a peak
    assert more is not None and np.all(np.isfinite(more.depths_mm))


def test_a_uniform_bright_field_holds_no_depth(cam):
    """A flat bright field (a white image given as a capture, decoded: every lit view 1): nothing in it is in focus
    at any depth. The search takes the background's level from each view before refocusing, so the field's border,
    where refocusing runs out of views, makes no edge; it found several depths on that border."""
    from lf_flame.refocus.shift_and_sum import aperture_mask
    n = cam.pixels_per_lenslet
    views = np.broadcast_to(aperture_mask(n, "circular")[:, :, None, None], (n, n, cam.n_rows, cam.n_cols))
    found = find_depths(views.astype(np.float32), cam)
    assert len(found.depths_mm) == 0, found.depths_mm


def test_the_peak_finder_is_scipys():
    """find_peaks gives scipy.signal.find_peaks' peaks (plateaus, ties, ends, distance, height)."""
    from scipy.signal import find_peaks as scipy_find_peaks

    from lf_flame.tomo.focus import find_peaks
    rng = np.random.default_rng(0)
    plateaus = 0
    for trial in range(400):
        n = int(rng.integers(3, 60))
        # few levels: ties between peaks and flat tops are common; smooth curves as the votes' histograms
        x = rng.integers(0, 4, n).astype(float) if trial % 2 else np.round(rng.random(n) * 8) / 8
        distance, height = float(rng.choice([1, 1.5, 2, 3, 7])), float(rng.choice([0.0, 0.5, 1.0, 2.0]))
        plateaus += int(np.any((x[1:-2] == x[2:-1]) & (x[1:-2] > 0)))
        want = scipy_find_peaks(x, distance=distance, height=height)[0]
        np.testing.assert_array_equal(find_peaks(x, distance, height), want, err_msg=f"{x}, {distance}, {height}")
    assert plateaus > 100


def test_a_refinement_step_keeps_the_planes_in_order_and_apart():
    """``kept_apart``: a refined plane that would pass another, or come within the merge distance of it, stays where
    it was (once put back, the plane beside it is checked again); moves that keep the planes apart are kept, and a
    plane the step does not refine is never moved."""
    from lf_flame.tomo.refine import kept_apart
    before = np.array([-3.0, 2.0, 8.0])
    np.testing.assert_array_equal(kept_apart([-2.0, 9.0, 8.0], before, [0, 1], 1.0), [-2.0, 2.0, 8.0])
    np.testing.assert_array_equal(kept_apart([-3.0, 4.5, 5.0], before, [1, 2], 1.0), [-3.0, 2.0, 8.0])
    np.testing.assert_array_equal(kept_apart([1.5, 7.4, 8.0], before, [0, 1], 1.0), [-3.0, 2.0, 8.0])
    np.testing.assert_array_equal(kept_apart([-1.0, 0.5, 8.0], before, [0, 1], 1.0), [-1.0, 0.5, 8.0])
    np.testing.assert_array_equal(kept_apart([-3.0, 7.5, 8.0], before, [1], 0.4), [-3.0, 7.5, 8.0])


def test_profiles_solve_the_found_planes_as_reconstruct_does(cam, behind, tmp_path, capsys):
    """``profiles`` of a light field whose depths it finds measures the planes ``reconstruct`` writes: the depths
    after the residual's search and the refinement (two flames one behind another, which the votes place off),
    each plane the reconstruction's binned to the lenslets."""
    import argparse

    import pandas as pd

    from lf_flame.cli import main
    from lf_flame.cli.profiles import profiles_table
    from lf_flame.refocus.shift_and_sum import views_to_raw
    from lf_flame.tomo.files import load_reconstruction
    from lf_flame.tomo.truth import bin_planes
    raw = tmp_path / "behind.npz"
    np.savez(raw, raw=views_to_raw(behind[1]), camera=cam.to_json())
    assert main(["reconstruct", str(raw), "--no-figure", "--out", str(tmp_path / "rec.h5")]) == 0
    out, err = capsys.readouterr()
    assert "planes after the residual's search and refinement" in out
    assert "reconstruct (admm)" not in err, err          # its solves' progress bars: none for a second's solves
    rec = load_reconstruction(tmp_path / "rec.h5")
    voted = find_depths(behind[1], cam).planes_mm
    assert np.abs(np.asarray(rec.depths_mm) - voted).max() > 0.05, (rec.depths_mm, voted)
    assert main(["profiles", str(raw), "--no-figure", "--out", str(tmp_path / "p")]) == 0
    np.testing.assert_allclose(pd.read_csv(tmp_path / "p.csv").depth_mm, rec.depths_mm, atol=1e-3)  # %.5g
    a = argparse.Namespace(raw=str(raw), route="reconstruct-admm", slope=None, depth=None, camera=None,
                           model_dir=None, search_range=None)
    stack = profiles_table(a)[1]
    want = bin_planes(rec.planes, rec.planes.shape[1] // cam.n_rows)
    np.testing.assert_allclose(stack, want, atol=1e-4 * np.abs(want).max())


def test_a_quiet_light_fields_refinement_starts_from_the_planes_before_it(cam, behind):
    """Two flames one behind another: each refinement step of a quiet light field solves from the planes a step
    before (admm's ``start_planes``), not from its coarse start; a noisy one's from its own coarse start (warm, its
    depths came out worse on validation scenes: refine.py's notes)."""
    from lf_flame.tomo.noise_knobs import noise_regime
    scene, views = behind
    found, _, rec = find_planes(views, cam)
    voted = find_depths(views, cam).planes_mm
    assert len(found.planes_mm) == len(voted) and not np.allclose(found.planes_mm, voted)   # a step was taken
    assert rec.settings["start"] == "given", rec.settings
    rng = np.random.default_rng(5)
    noisy = views + rng.normal(0.0, 0.05 * float(views.max()), views.shape).astype(views.dtype)
    found_n, _, rec_n = find_planes(noisy, cam)
    assert noise_regime(rec_n.settings["noise"]) == "noisy" and rec_n.settings["start"] != "given", rec_n.settings
    assert not np.allclose(found_n.planes_mm, find_depths(noisy, cam).planes_mm)            # a step was taken


def test_a_plane_that_solves_to_nothing_is_dropped_with_its_depths(cam, planted):
    """A found plane whose emission is 0 everywhere (a depth voted for where the planes explain nothing: a capture
    decoded with one view more than its 9.999 px lenslet images hold whole found -60.01 mm, at its search's near end)
    is dropped with its depths, the rest solved again from their planes; where no plane (or every plane) is empty,
    nothing changes and nothing is solved again."""
    import dataclasses

    from lf_flame.tomo.refine import without_empty_planes
    from lf_flame.tomo.solvers import Reconstruction
    scene, views = planted
    found = find_depths(views, cam)
    P = len(found.planes_mm)
    assert P >= 2 and len(found.depths_mm) == P
    planes = np.ones((P, 4, 4))
    planes[0] = 0.0
    rec = Reconstruction(planes=planes, depths_mm=tuple(found.planes_mm), sample_mm=((1.0, 1.0),) * P, solver="admm")
    calls = []

    def solve(f, start=None):
        calls.append((f, start))
        return "op", dataclasses.replace(start, depths_mm=tuple(f.planes_mm))

    kept, op, out = without_empty_planes(found, "old op", rec, solve)
    assert list(kept.planes_mm) == list(found.planes_mm[1:]) and op == "op" and len(calls) == 1
    assert list(kept.depths_mm) == [d for d, p in zip(found.depths_mm, found.plane_of) if p != 0]
    assert list(kept.plane_of) == [p - 1 for p in found.plane_of if p != 0]
    assert len(kept.curves) == len(kept.masks) == len(kept.region) == len(kept.depths_mm)
    assert np.array_equal(calls[0][1].planes, planes[1:])           # started from the planes kept
    for full in (np.ones((P, 4, 4)), np.zeros((P, 4, 4))):
        same = without_empty_planes(found, "old op", dataclasses.replace(rec, planes=full), solve)
        assert same[0] is found and same[1] == "old op" and len(calls) == 1


def test_flames_side_by_side_two_coarse_slope_steps_apart_are_parted_on_few_views(tmp_path):
    """On a camera of 8 views (coarse slope step 0.08 lenslets per view) the paper's flames at 0 and +34 mm stand
    0.17 apart in slope, and +34 and +75 mm 0.16: one region each pair. Their votes' histogram on the coarse grid,
    smoothed over a bin, had one peak per pair (two depths found, -30 and +49 mm); the votes refined to half a step
    part them: four depths, each within 0.03 lenslets per view of its flame's slope."""
    from lf_flame.cli import main
    from lf_flame.real.readers import read_light_field
    toml = tmp_path / "cam8.toml"
    toml.write_text("[main_lens]\nfocal_length_mm = 50.0\nmla_distance_mm = 60.0\n"
                    "[microlens_array]\npitch_um = 79.2\nfocal_length_mm = 1.0\n"
                    "[sensor]\npixel_size_um = 10.065\nrows = 160\ncols = 256\n")
    raw = tmp_path / "f8.npz"
    assert main(["simulate", "--scene", "flame", "--camera", str(toml), "--rays-per-pixel", "4", "--out",
                 str(raw)]) == 0
    lf = read_light_field(raw)
    assert lf.views.shape[:2] == (8, 8)
    found = find_depths(lf.views, lf.camera, views_mask=lf.lit_views())
    true = sorted(o["depth_offset_mm"] for o in json.loads(str(np.load(raw)["objects"])))
    assert len(found.depths_mm) == 4, found.depths_mm
    err = [lf.camera.slope_for_depth(f) - lf.camera.slope_for_depth(t) for f, t in zip(found.depths_mm, true)]
    assert np.max(np.abs(err)) <= 0.03, (found.depths_mm, true, err)
