"""Flame diagnostics on flames rendered by the real simulator, at the paper's depths and others."""
import dataclasses

import numpy as np
import pandas as pd
import pytest
from scipy import ndimage

from lf_flame.measure.diagnostics import (TIP_PEDESTAL_MM, EmptyPlaneError, flame_truth, lenslet_size_mm,
                                          lenslet_to_object_mm, measure_flame)
from lf_flame.measure.scoring import error_table, measure_stack, score_stacks
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.refocus.shift_and_sum import aperture_mask, refocus
from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate

# two thirds of the paper's lenslet grid, the paper's optics; flames scaled to fit the field
CAM = PlenopticCamera(n_rows=120, n_cols=60)
TEMPLATE_SCALE = 0.64 * 120 / 180


def _render(depths, seed=1, keep=None, radiance=None):
    """Flame scene at ``depths`` (regime "paper"), refocused at each flame's analytic slope.
    ``keep``: indices of the flames kept (the others removed); ``radiance``: per-flame scale."""
    sc = scenes.flame_scene(CAM, np.random.default_rng(seed), template_scale=TEMPLATE_SCALE, depths_mm=depths,
                            regime="paper")
    layers = list(sc.layers)
    if radiance is not None:
        layers = [dataclasses.replace(la, radiance=(r * la.radiance).astype(np.float32))
                  for la, r in zip(layers, radiance)]
    keep = range(len(layers)) if keep is None else keep
    sc = dataclasses.replace(sc, layers=tuple(layers[k] for k in keep), objects=tuple(sc.objects[k] for k in keep))
    raw = simulate.render(CAM, sc, 4, seed=0)
    n = CAM.pixels_per_lenslet
    stack = refocus(raw, [CAM.slope_for_depth(o["depth_offset_mm"]) for o in sc.objects], n,
                    aperture_mask(n, "circular"))
    return stack, sc.objects


def test_lenslet_scale_follows_the_magnification():
    # one lenslet sees pitch * z / d mm of the plane at object distance z
    for dz in (-40.0, -10.0, 0.0, 20.0, 60.0):
        z = CAM.focus_distance_mm + dz
        assert lenslet_size_mm(CAM, dz) == pytest.approx(CAM.mla_pitch_mm * z / CAM.mla_distance_mm, rel=1e-12)
        # round trip with the camera's own object -> lenslet map (pixel centres at i + 0.5)
        r, c = CAM.object_to_lenslet(3.0, -2.0, dz)
        y, x = lenslet_to_object_mm(CAM, r - 0.5, c - 0.5, dz)
        assert (y, x) == pytest.approx((3.0, -2.0), abs=1e-9)


def test_height_of_a_lone_flame_at_two_magnifications():
    """The same flame (same template) at +30 and -15 mm: 14.5 % taller in object space at
    +30, yet the same size in lenslets. A depth-independent lenslet -> mm scale would give
    the same height at both and miss the ratio by 14.5 %."""
    meas, truth = {}, {}
    for dz in (30.0, -15.0):
        stack, objects = _render((dz, 0.0, 0.0, 0.0), keep=[0])
        m = measure_flame(stack[0], CAM, dz, columns=flame_truth(objects[0])["columns"])
        t = flame_truth(objects[0])
        meas[dz], truth[dz] = m, t
        # absolute: height within 6 % (the base extrapolation's bias, docs/diagnostics.md), centre within a lenslet
        assert m.height_mm == pytest.approx(t["height_mm"], rel=0.06)
        assert m.base_y_mm == pytest.approx(t["base_y_mm"], abs=0.06 * t["height_mm"])
        assert m.tip_y_mm == pytest.approx(t["tip_y_mm"], abs=0.06 * t["height_mm"])
        assert abs(m.centroid_x_mm - t["centre_x_mm"]) < m.lenslet_mm
        # the region, the profiles and the widths are those of this flame
        assert m.mask.sum() > 100 and 0 < m.base_width_mm <= m.max_width_mm < 0.3 * t["height_mm"]
        assert len(m.radial) == 3 and m.axial_height_mm.shape == m.axial_intensity.shape
        assert m.axial_intensity.max() > m.threshold
        assert m.flags == () and m.trusted  # a clean lone flame is trusted
    true_ratio = truth[30.0]["height_mm"] / truth[-15.0]["height_mm"]
    assert true_ratio == pytest.approx(CAM.object_distance_mm(30.0) / CAM.object_distance_mm(-15.0))
    assert meas[30.0].height_mm / meas[-15.0].height_mm == pytest.approx(true_ratio, rel=0.02)


@pytest.mark.parametrize("depths", [(30.0, 12.0, -4.0, -15.0), (20.0, 10.0, 0.0, -10.0)])
def test_heights_beside_blurred_flames(depths):
    """Four flames, each plane holding the three others out of focus; depths the paper's
    and others. Every height within 0.5 mm, every centroid on its own flame."""
    stack, objects = _render(depths)
    df = score_stacks(stack[None], CAM, [objects])
    assert (df.failure == "").all()
    assert (df.height_err_mm < 0.5).all(), df[["depth_mm", "height_mm_true", "height_mm"]]
    assert (df["flags"] == "").all(), df[["depth_mm", "flags", "tip_pedestal_mm"]]  # nothing to distrust
    # the flames stand 0.225 of the field apart: a centroid on the wrong flame is off by > 1.5 mm
    assert (df.centre_x_err_mm < 0.3).all()
    t = error_table(df)
    assert list(t.depth_mm) == list(depths) and (t.n == 1).all() and (t.n_failed == 0).all()
    assert (t.n_flagged == 0).all() and (t.share_over_1mm == 0).all()


def test_the_sharp_region_wins_over_a_brighter_blurred_one():
    """A dim sharp-edged flame-like bar and, apart from it in the same band, a brighter
    smooth blob (what defocus makes of a flame): the sharp one is measured."""
    plane = np.zeros((CAM.n_rows, CAM.n_cols))
    plane[40:100, 10:18] = 0.4                                   # in focus: hard edges
    blob = np.zeros_like(plane)
    blob[50:90, 36:50] = 1.0
    plane += ndimage.gaussian_filter(blob, 4.0)                  # blurred, peak ~0.9
    assert plane[:, 36:50].max() > 2 * plane[:, 10:18].max()
    m = measure_flame(plane, CAM, 0.0)
    y, x = lenslet_to_object_mm(CAM, 69.5, 13.5, 0.0)
    assert m.centroid_x_mm == pytest.approx(x, abs=0.5 * m.lenslet_mm)
    assert m.centroid_y_mm == pytest.approx(y, abs=0.5 * m.lenslet_mm)
    assert m.mask[:, 30:].sum() == 0
    # a bar has hard ends: both edges within a lenslet of them
    assert m.height_mm == pytest.approx(60 * m.lenslet_mm, abs=m.lenslet_mm)
    assert m.max_width_mm == pytest.approx(8 * m.lenslet_mm)
    assert m.trusted  # hard ends are edges found, not cut by the threshold


# ---- flags: measurements the method cannot trust ----------------------------------
BAND = (12, 40)


def _flame(base=100, tip=40, col=24.0, half_width=4.0, peak=0.5):
    """A planted in-focus flame (R, C) at 0 mm: luminosity rising linearly over the bottom
    30 % of rows ``base``..``tip`` and falling linearly to zero at the tip (its edges
    extrapolate exactly), hard sides narrowing towards the tip."""
    r = np.arange(CAM.n_rows)[:, None] + 0.5
    c = np.arange(CAM.n_cols)[None, :] + 0.5
    eta = (base - r) / (base - tip)
    axial = np.where((eta >= 0) & (eta <= 1), np.where(eta < 0.3, eta / 0.3, (1 - eta) / 0.7), 0.0)
    return peak * axial * (np.abs(c - col) <= half_width * np.sqrt(np.clip(1 - eta, 0.05, 1)))


def _blur(rows, cols, amplitude, sigma):
    """A bright box ``rows`` × ``cols`` blurred by a Gaussian of ``sigma`` lenslets: what
    defocus makes of another flame."""
    box = np.zeros((CAM.n_rows, CAM.n_cols))
    box[slice(*rows), slice(*cols)] = 1.0
    return amplitude * ndimage.gaussian_filter(box, sigma)


def test_the_planted_flame_alone_is_measured_and_trusted():
    m = measure_flame(_flame(), CAM, 0.0, columns=BAND)
    assert m.height_mm == pytest.approx(60 * m.lenslet_mm, abs=0.1)
    assert m.flags == () and m.trusted and m.tip_pedestal_mm < 0.01
    assert m.summary()["flags"] == ""


def test_a_sliver_of_light_from_outside_the_band_is_flagged_merged():
    """A bright blur standing left of the band (the case of ``lf-flame simulate --scene
    flame``'s +20 mm plane, measured 6.97 mm for 20.15): the region is the sliver of it
    inside the band's border, sharper than the flame merged with the rest; the walk runs
    along the band's border. Not caught by the pedestal (below its threshold)."""
    m = measure_flame(_flame() + _blur((10, 80), (0, 12), 2.0, 5.0), CAM, 0.0, columns=BAND)
    assert abs(m.height_mm - 60 * m.lenslet_mm) > 1.0  # the method fails here
    assert m.mask[:, BAND[0]].any() and not m.mask[:, 20:].any()  # on the sliver, not the flame
    assert "merged" in m.flags and not m.trusted
    assert m.tip_pedestal_mm < TIP_PEDESTAL_MM  # the band's border alone catches it
    assert m.summary()["flags"] == ";".join(m.flags)


def test_a_tip_on_other_flames_light_is_flagged_merged():
    """A broad blur over the flame's tip (a taller flame behind, out of focus) raises the
    tip's fitted rows: the extrapolated tip comes out > 1 mm too high. Its walk stays on
    the flame's columns (no band border): the pedestal catches it."""
    r = np.arange(CAM.n_rows)[:, None]
    c = np.arange(CAM.n_cols)[None, :]
    pedestal = 0.15 * np.exp(-(r - 40) ** 2 / (2 * 15 ** 2) - (c - 22) ** 2 / (2 * 12 ** 2))
    m = measure_flame(_flame() + pedestal, CAM, 0.0, columns=BAND)
    assert m.height_mm - 60 * m.lenslet_mm > 1.0
    assert m.tip_pedestal_mm > TIP_PEDESTAL_MM and m.flags == ("merged",)


def test_a_dim_flame_cut_by_the_threshold_is_flagged_no_edge():
    """A dim flame beside a blur three times brighter in its band: the 30 % threshold cuts
    the flame at 70 % of its peak, above the fitted range, and the edge returned is the
    threshold's: 5 mm short."""
    m = measure_flame(_flame() + _blur((10, 60), (2, 16), 1.5, 4.0), CAM, 0.0, columns=BAND)
    assert 60 * m.lenslet_mm - m.height_mm > 3.0
    assert not m.mask[:, :18].any()  # the flame's own region...
    assert "no-edge" in m.flags and not m.trusted  # ...but not its edge


@pytest.mark.parametrize("where", ["top", "bottom", "left"])
def test_a_flame_cut_by_the_field_is_flagged_cut(where):
    """The flame runs out of the plane: the true tip (base, side) may lie outside."""
    flame, band = {"top": (_flame(base=70, tip=-10), BAND), "bottom": (_flame(base=130, tip=60), BAND),
                   "left": (_flame(col=2.0), (0, 20))}[where]
    m = measure_flame(flame, CAM, 0.0, columns=band)
    assert "cut" in m.flags and not m.trusted
    # the same flame inside the field is trusted
    assert measure_flame(_flame(), CAM, 0.0, columns=band if where != "left" else (12, 40)).trusted


def test_a_dim_flame_beside_bright_blur_in_a_render_is_flagged():
    """Rendered: the 0 mm flame at 30 % radiance, its tip on the blur of the taller +10 and
    +20 mm flames, comes out > 1 mm too tall; flagged, the other planes trusted."""
    stack, objects = _render((20.0, 10.0, 0.0, -10.0), radiance=(1.0, 1.0, 0.3, 1.0))
    df = score_stacks(stack[None], CAM, [objects])
    assert df.height_err_mm[2] > 1.0 and df["flags"][2] == "merged"
    assert (df["flags"].drop(2) == "").all() and (df.height_err_mm.drop(2) < 0.5).all()
    t = error_table(df.assign(all=0), by=("all",))
    assert t.n_flagged[0] == 1 and t.share_over_1mm[0] == 0.25 and t.share_over_1mm_trusted[0] == 0.0
    assert t.height_err_mm_max[0] == pytest.approx(df.height_err_mm.max())
    assert t.height_err_mm_max_trusted[0] == pytest.approx(df.height_err_mm.drop(2).max())


def test_error_table_tail_columns():
    err = [0.1, 0.2, 0.3, 1.5, 0.4, 2.5, np.nan, 0.2]
    flags = ["", "", "", "merged", "", "", "", "cut"]
    df = pd.DataFrame(dict(depth_mm=[10.0] * 8, height_err_mm=err, height_mm_true=5.0, height_mm=5.0,
                           base_err_mm=0.0, tip_err_mm=0.0, centre_x_err_mm=0.0, flags=flags,
                           failure=[""] * 6 + ["no flame"] + [""]))
    t = error_table(df).iloc[0]
    measured = np.array([0.1, 0.2, 0.3, 1.5, 0.4, 2.5, 0.2])
    trusted = np.array([0.1, 0.2, 0.3, 0.4, 2.5])
    assert (t.n, t.n_failed, t.n_flagged) == (8, 1, 2)
    assert t.share_over_1mm == pytest.approx(2 / 7) and t.share_over_1mm_trusted == pytest.approx(1 / 5)
    assert t.height_err_mm_p90 == pytest.approx(np.quantile(measured, 0.9))
    assert t.height_err_mm_p90_trusted == pytest.approx(np.quantile(trusted, 0.9))
    assert (t.height_err_mm_max, t.height_err_mm_max_trusted) == (2.5, 2.5)
    assert t.height_err_mm == pytest.approx(measured.mean())


def test_bad_input():
    plane = np.zeros((CAM.n_rows, CAM.n_cols), np.float32)
    with pytest.raises(ValueError, match="empty"):
        measure_flame(plane, CAM, 0.0)
    with pytest.raises(EmptyPlaneError):
        measure_flame(plane, CAM, 0.0)
    plane[50, 30] = 1.0  # one bright lenslet is not a flame: the plane holds light, too little to be one
    with pytest.raises(EmptyPlaneError, match="region of 10 lenslets or more .* holds light, but is empty of flames"):
        measure_flame(plane, CAM, 0.0)
    with pytest.raises(EmptyPlaneError, match="no light"):
        measure_flame(plane, CAM, 0.0, columns=(0, 10))
    with pytest.raises(ValueError, match="shape"):
        measure_flame(np.ones((CAM.n_rows, CAM.n_cols + 1)), CAM, 0.0)
    with pytest.raises(ValueError, match="shape"):
        measure_flame(np.ones((4, CAM.n_rows, CAM.n_cols)), CAM, 0.0)
    nan = np.ones((CAM.n_rows, CAM.n_cols))
    nan[3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        measure_flame(nan, CAM, 0.0)
    ones = np.ones((CAM.n_rows, CAM.n_cols))
    with pytest.raises(ValueError, match="columns"):
        measure_flame(ones, CAM, 0.0, columns=(10, 5))
    with pytest.raises(ValueError, match="columns"):
        measure_flame(ones, CAM, 0.0, columns=(0, CAM.n_cols + 1))
    with pytest.raises(ValueError, match="segment_fraction"):
        measure_flame(ones, CAM, 0.0, segment_fraction=1.5)
    with pytest.raises(ValueError, match="edge_fit_range"):
        measure_flame(ones, CAM, 0.0, edge_fit_range=(0.6, 0.2))
    with pytest.raises(ValueError, match="focal length"):  # a plane in front of the main lens's focus
        measure_flame(ones, CAM, -(CAM.focus_distance_mm - CAM.main_focal_mm))
    with pytest.raises(ValueError, match="not a flame"):
        flame_truth(dict(name="circle", depth_offset_mm=0.0, centre_x_mm=0.0, roi=(0, 1, 0, 1)))
    obj = dict(name="f", depth_offset_mm=0.0, height_mm=5.0, base_y_mm=-3.0, centre_x_mm=0.0, roi=(0, 120, 0, 60))
    with pytest.raises(ValueError, match="one plane per object"):
        measure_stack(np.ones((2, CAM.n_rows, CAM.n_cols)), CAM, [obj])
    with pytest.raises(ValueError, match="NaN"):
        measure_stack(nan[None], CAM, [obj])
    with pytest.raises(ValueError, match="depths_mm"):
        scenes.flame_scene(CAM, np.random.default_rng(0), depths_mm=(10.0, 0.0))


def test_an_empty_prediction_is_a_failure_not_a_number():
    stack, objects = _render((20.0, 10.0, 0.0, -10.0))
    stack[2] = 0.0
    df = score_stacks(stack[None], CAM, [objects], route="test")
    assert list(df.failure != "") == [False, False, True, False]
    assert np.isnan(df.height_err_mm[2]) and np.isfinite(df.height_err_mm.drop(2)).all()
    t = error_table(df)
    assert t.set_index("depth_mm").n_failed.to_dict() == {20.0: 0, 10.0: 0, 0.0: 1, -10.0: 0}
    assert isinstance(t, pd.DataFrame) and (df.route == "test").all()


def test_cli_profiles_writes_csv_and_figure(tmp_path, capsys):
    import json

    from lf_flame.cli import main
    depths = (20.0, 10.0, 0.0, -10.0)
    sc = scenes.flame_scene(CAM, np.random.default_rng(5), template_scale=TEMPLATE_SCALE, regime="paper")
    raw = simulate.render(CAM, sc, 4, seed=0)
    src = tmp_path / "flame.npz"
    np.savez(src, raw=raw, camera=CAM.to_json(), objects=json.dumps(sc.objects, default=float))
    assert main(["profiles", str(src), "--route", "fourier", "--out", str(tmp_path / "p")]) == 0
    assert "planes at the depths of the flames the file stores (+20.00, +10.00, +0.00, -10.00 mm: the scene's " \
           "truth, not found" in capsys.readouterr().out                    # said, not taken quietly
    df = pd.read_csv(tmp_path / "p.csv")
    assert list(df.depth_mm) == list(depths) and list(df.plane) == [0, 1, 2, 3]
    assert df.slope.values == pytest.approx([CAM.slope_for_depth(d) for d in depths], rel=1e-4)
    assert (df.height_err_mm < 0.5).all() and df.failure.isna().all()
    assert "flags" in df and df["flags"].isna().all()  # the column is there, empty: all trusted
    axial = pd.read_csv(tmp_path / "p.axial.csv")
    assert set(axial.depth_mm) == set(depths) and (axial.height_mm.groupby(axial.plane).max() > 3).all()
    assert (tmp_path / "p.png").stat().st_size > 20_000
    # a raw image that stores no flames: its planes are the depths found in the views, not the paper's
    from lf_flame.simulate.scenes_depth import random_depth_scene
    other = random_depth_scene(CAM, np.random.default_rng(11), n_flames=2)
    np.savez(tmp_path / "bare.npz", raw=simulate.render(CAM, other, 8, seed=1), camera=CAM.to_json())
    assert main(["profiles", str(tmp_path / "bare.npz"), "--route", "fourier", "--no-figure", "--out",
                 str(tmp_path / "b")]) == 0
    assert "the scene's truth" not in capsys.readouterr().out
    assert not (tmp_path / "b.png").exists() and (tmp_path / "b.axial.csv").exists()    # --no-figure: the CSVs only
    true = sorted(o["depth_offset_mm"] for o in other.objects)
    found = pd.read_csv(tmp_path / "b.csv")
    assert np.allclose(sorted(found.depth_mm), true, atol=0.5), (found.depth_mm, true)
    # the stored planes exist only in a dataset
    assert main(["profiles", str(src), "--route", "ground-truth", "--out", str(tmp_path / "q")]) == 2
    assert "DATASET.h5:INDEX" in capsys.readouterr().err


def _profiles_routes():
    """The routes ``lf-flame profiles --route`` offers that need neither a dataset nor a trained model."""
    import argparse

    from lf_flame.cli import build_parser
    from lf_flame.routes import parse_route
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    route = next(a for a in sub.choices["profiles"]._actions if a.dest == "route")
    return [r for r in route.choices if parse_route(r).kind in ("refocus", "emission")]


@pytest.fixture(scope="module")
def small_flame_npz(tmp_path_factory):
    """A flame scene on half the test camera's grid (60 x 30 lenslets), as 'lf-flame simulate' stores it."""
    import json
    cam = PlenopticCamera(n_rows=60, n_cols=30)
    sc = scenes.flame_scene(cam, np.random.default_rng(5), template_scale=0.64 * 60 / 180, regime="paper")
    src = tmp_path_factory.mktemp("profiles") / "flame.npz"
    np.savez(src, raw=simulate.render(cam, sc, 4, seed=0), camera=cam.to_json(),
             objects=json.dumps(sc.objects, default=float))
    return src


def test_profiles_of_a_uniform_light_field_warn_and_flag_every_plane(tmp_path, capsys):
    """A light field of one value throughout (0.5) had been measured as a flame 3.7 mm tall at 2 mm without a word
    or a flag (reconstruct had warned of a black level): profiles now warns that its views carry no structure and
    flags every plane's measurement no-structure."""
    from lf_flame.cli import main
    np.save(tmp_path / "const.npy", np.full((360, 270), 0.5))
    (tmp_path / "small.toml").write_text("[camera]\npixels_per_lenslet = 9\nn_rows = 40\nn_cols = 30\n")
    assert main(["profiles", str(tmp_path / "const.npy"), "--camera", str(tmp_path / "small.toml"), "--depth", "0",
                 "--depth", "2", "--out", str(tmp_path / "p"), "--no-figure"]) == 0
    err = capsys.readouterr().err
    assert "const.npy's views carry no structure" in err, err
    table = pd.read_csv(tmp_path / "p.csv")
    assert table.height_mm.notna().all() and table["flags"].str.endswith("no-structure").all(), table


def test_profiles_refuses_a_stored_flame_without_its_depth_in_one_line(small_flame_npz, tmp_path, capsys):
    """An .npz whose objects lack depth_offset_mm on one flame had ended 'profiles' in a KeyError traceback
    (cli/profiles.py:109): now one line naming the file, the flame and the key."""
    import json
    from lf_flame.cli import main
    with np.load(small_flame_npz) as z:
        stored = {k: z[k] for k in z.files}
    objects = json.loads(str(stored["objects"]))
    del objects[1]["depth_offset_mm"]
    stored["objects"] = np.array(json.dumps(objects))
    np.savez(tmp_path / "nodepth.npz", **stored)
    assert main(["profiles", str(tmp_path / "nodepth.npz"), "--route", "shift-sum", "--out", str(tmp_path / "p"),
                 "--no-figure"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "nodepth.npz: its stored flame 1" in err and "depth_offset_mm" in err, err


@pytest.mark.parametrize("route", _profiles_routes())
def test_profiles_measures_every_route_on_the_lenslet_grid(route, small_flame_npz):
    """Every route 'profiles' offers measures the flames (admm's planes, on a 2 x 2 finer grid,
    are averaged to the lenslets): each plane on the lenslet grid, each height within 0.6 mm
    of the truth (flames 3-7 mm tall on this grid of 0.13 mm lenslets)."""
    import argparse

    from lf_flame.cli.profiles import profiles_table
    a = argparse.Namespace(raw=str(small_flame_npz), route=route, slope=None, camera=None, model_dir=None)
    cam, stack, depths, ms, objects, df = profiles_table(a)
    assert stack.shape == (4, cam.n_rows, cam.n_cols) and (cam.n_rows, cam.n_cols) == (60, 30)
    assert all(m is not None for m in ms) and (df.route == route).all()
    assert (df.height_err_mm.abs() < 0.6).all(), df[["depth_mm", "height_mm", "height_mm_true"]]


def test_profiles_planes_given_keep_their_depths_and_take_the_truth_of_the_flame_there(small_flame_npz):
    """Planes given by --depth on a simulated flame file are measured at those depths: each takes the truth of the
    flame standing at its depth (within the camera's merge tolerance, 1 mm), none where no flame stands; three planes
    for four flames are measured too. (They were measured as the scene's own planes, labelled and scored as its
    flames by their order: a plane at -5 mm as the -10 mm flame.)"""
    import argparse
    import json

    from lf_flame.cli.profiles import profiles_table
    from lf_flame.measure.figures import profiles_figure
    given = [20.3, 10.0, -5.0]
    a = argparse.Namespace(raw=str(small_flame_npz), route="shift-sum", slope=None, camera=None, model_dir=None,
                           depth=given)
    cam, stack, depths, ms, objects, df = profiles_table(a)
    assert depths == given and list(df.depth_mm) == given and len(stack) == 3
    assert [None if o is None else o["depth_offset_mm"] for o in objects] == [20.0, 10.0, None]
    heights = {o["depth_offset_mm"]: o["height_mm"] for o in json.loads(str(np.load(small_flame_npz)["objects"]))}
    assert df.height_mm_true.iloc[:2].tolist() == [heights[20.0], heights[10.0]] and np.isnan(df.height_mm_true[2])
    assert df.slope.values == pytest.approx([cam.slope_for_depth(d) for d in given], rel=1e-6)
    fig = profiles_figure(cam, stack, depths, ms, objects, "shift-sum")
    titles = [ax.get_title() for ax in fig.axes[:3]]
    assert ["(true" in t for t in titles] == [True, True, False], titles


def test_profiles_figure_of_planes_without_a_flame_draws_without_warnings():
    """Planes where no flame was found (a tiny camera's, a dark capture's): the figure says so on each plane and
    draws no empty legend (matplotlib warned "No artists with labels found")."""
    import warnings

    from lf_flame.measure.figures import profiles_figure
    cam = PlenopticCamera(n_rows=20, n_cols=10)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = profiles_figure(cam, np.zeros((2, 20, 10)), [5.0, -5.0], [None, None], None, "shift-sum")
    assert all("no flame found" in ax.get_title() for ax in fig.axes[:2])


def test_profiles_figure_explains_its_lines_and_units(small_flame_npz):
    """The planes in mm with one colour bar; a legend names the outline and the measured and
    true edges; the profiles' axes carry units and a legend (planes by colour, heights by style)."""
    import argparse

    from lf_flame.cli.profiles import profiles_table, value_label
    from lf_flame.measure.figures import profiles_figure
    a = argparse.Namespace(raw=str(small_flame_npz), route="shift-sum", slope=None, camera=None, model_dir=None)
    cam, stack, depths, ms, objects, df = profiles_table(a)
    fig = profiles_figure(cam, stack, depths, ms, objects, "shift-sum", value_label("shift-sum"))
    bar = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    *planes, axial, radial = [ax for ax in fig.axes if ax not in bar]
    assert all(ax.get_xlabel() == "x (mm)" for ax in planes) and planes[0].get_ylabel() == "y (mm)"
    assert [ax.get_title().split("\n")[0] for ax in planes] == ["+20 mm", "+10 mm", "+0 mm", "-10 mm"]
    assert len(bar) == 1 and bar[0].get_ylabel() == "refocused radiance (a.u.)"
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["measured flame region (outline)", "measured base and tip", "true base and tip"]
    assert "(mm)" in axial.get_xlabel() and "(a.u.)" in axial.get_ylabel() and axial.get_legend() is not None
    assert "(mm)" in radial.get_xlabel() and "(a.u.)" in radial.get_ylabel()
    assert {"25 % of the height", "-10 mm"} <= {t.get_text() for t in radial.get_legend().get_texts()}


def test_profiles_default_route_measures_where_refocused_planes_merge(tmp_path):
    """Without --route, 'profiles' measures admm's planes of emission: on this varied scene the
    refocused +10 mm plane's flame merges with its neighbours' blur (shift-sum: 3.8 mm too tall),
    the default measures every flame within 0.3 mm."""
    import json

    from lf_flame.cli import main
    sc = scenes.flame_scene(CAM, np.random.default_rng(3), template_scale=TEMPLATE_SCALE, regime="varied")
    src = tmp_path / "flame.npz"
    np.savez(src, raw=simulate.render(CAM, sc, 4, seed=0), camera=CAM.to_json(),
             objects=json.dumps(sc.objects, default=float))
    assert main(["profiles", str(src), "--out", str(tmp_path / "p")]) == 0
    df = pd.read_csv(tmp_path / "p.csv")
    assert (df.height_err_mm.abs() < 0.3).all() and df["flags"].isna().all(), df[["route", "height_err_mm"]]
    assert (df.route == "reconstruct-admm").all()


def test_flame_tail_experiment_writes_csv_and_md(tmp_path):
    """``experiments/studies/flame_tail.py`` at a tiny size: every plane in the CSV, the tail in the md."""
    import importlib.util
    from pathlib import Path
    spec = importlib.util.spec_from_file_location(
        "flame_tail", Path(__file__).resolve().parents[1] / "experiments" / "studies" / "flame_tail.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.main(["--n", "2", "--seed0", "990000", "--out", str(tmp_path / "tail")]) == 0
    df = pd.read_csv(tmp_path / "tail.csv", keep_default_na=False, na_values=[""])
    assert len(df) == 2 * 2 * 4 and list(df.columns) == list(mod.CSV_COLUMNS)
    assert set(df.regime) == {"varied", "paper"} and df.height_err_mm.notna().all()
    md = (tmp_path / "tail.md").read_text()
    assert "% > 1 mm trusted" in md and "Detector's confusion" in md and "--seed0 990000" in md


def test_a_route_is_parsed_once_into_one_value():
    """Every caller (command line, recordings, diagnostics, experiments) gets the same Route
    from a name: the adjoint is plain refocusing under both its names."""
    from lf_flame.measure.diagnostics import EMISSION_MEASURE
    from lf_flame.routes import Route, measure_settings, parse_route, route_names
    adj = parse_route("reconstruct-adjoint")
    assert adj == parse_route("refocus-adjoint") and (adj.kind, adj.solver, adj.tomographic) == ("refocus", "adjoint",
                                                                                                 True)
    assert parse_route("refocus-shift-sum") == parse_route("shift-sum") == Route("refocus", "shift-sum")
    assert parse_route("shift-sum-nearest").options == {"interpolation": "nearest"}
    assert parse_route("fourier").options == {"method": "fourier"}
    pd_tv = parse_route("reconstruct-pd-tv")
    assert (pd_tv.kind, pd_tv.solver, pd_tv.emission, pd_tv.tomographic) == ("emission", "pd-tv", True, True)
    assert parse_route("truth").emission and not parse_route("truth").tomographic
    assert parse_route("network").kind == "learned" and parse_route("ground-truth").kind == "stored"
    assert parse_route(pd_tv) is pd_tv
    for name in route_names():
        r = parse_route(name)
        assert measure_settings(name) == measure_settings(r) == (EMISSION_MEASURE if r.kind == "emission" else {})
    with pytest.raises(ValueError, match="unknown route 'reconstruct-bogus'.*shift-sum"):
        parse_route("reconstruct-bogus")
    with pytest.raises(ValueError, match="unknown route"):
        measure_settings("refocus")


def test_planes_of_emission_are_measured_with_their_own_edges():
    """On the true emission (sharp: no other plane's blur), the emission settings' edges
    lie closer to the flame's than the refocused planes' defaults, which undershoot the
    base (lf_flame.measure.diagnostics.EMISSION_MEASURE; results/reconstruct_edges.csv)."""
    from lf_flame.measure.diagnostics import EMISSION_MEASURE
    from lf_flame.routes import measure_settings
    from lf_flame.tomo.operator import EmissionOperator
    from lf_flame.tomo.truth import scene_truth
    assert measure_settings("reconstruct-pd-tv") == measure_settings("truth") == EMISSION_MEASURE
    assert measure_settings("shift-sum") == measure_settings("refocus-adjoint") == {}
    # the command line's name of the same plain refocusing is measured the same way
    assert measure_settings("reconstruct-adjoint") == {}
    errs = {"truth": [], "shift-sum": []}
    for seed in (1, 2, 3):
        sc = scenes.flame_scene(CAM, np.random.default_rng(seed), template_scale=TEMPLATE_SCALE, regime="paper")
        depths = [o["depth_offset_mm"] for o in sc.objects]
        truth = scene_truth(sc, EmissionOperator(CAM, depths, rays_per_pixel=1))
        for plane, obj, d in zip(truth, sc.objects, depths):
            t = flame_truth(obj)
            for route in errs:
                m = measure_flame(plane, CAM, d, columns=t["columns"], **measure_settings(route))
                assert m.trusted
                errs[route].append(abs(m.height_mm - t["height_mm"]))
    assert max(errs["truth"]) < 0.15
    assert np.mean(errs["truth"]) < 0.5 * np.mean(errs["shift-sum"])


def test_on_a_plane_of_emission_the_flame_is_the_region_with_the_most_light_not_a_speckled_ghost():
    """A plane of emission solved from few data (a 6-view camera, a recording on the lenslet grid) holds its flame and,
    apart from it, another flame's speckled ghost above 5 % of its peak: the emission settings measure the flame (the
    region holding the most light), where the sharpest region, the refocused planes' rule, is the ghost."""
    from lf_flame.measure.diagnostics import EMISSION_MEASURE
    from lf_flame.tomo.operator import EmissionOperator
    from lf_flame.tomo.truth import scene_truth
    sc = scenes.flame_scene(CAM, np.random.default_rng(1), template_scale=TEMPLATE_SCALE, regime="paper")
    sc = dataclasses.replace(sc, layers=sc.layers[2:3], objects=sc.objects[2:3])        # one flame
    obj, t = sc.objects[0], flame_truth(sc.objects[0])
    plane = scene_truth(sc, EmissionOperator(CAM, [obj["depth_offset_mm"]], rays_per_pixel=1))[0].astype(float)
    c = obj["roi"][3] + 3                                                   # beside it: a speckled patch
    rng = np.random.default_rng(0)
    plane[20:60, c:c + 8] = rng.uniform(0, 0.4, (40, 8)) * plane.max() * (rng.uniform(size=(40, 8)) < 0.5)
    assert plane[:, c:].sum() < 0.5 * plane[:, :c].sum()
    emission = measure_flame(plane, CAM, obj["depth_offset_mm"], **EMISSION_MEASURE)
    sharpest = measure_flame(plane, CAM, obj["depth_offset_mm"], **dict(EMISSION_MEASURE, pick="sharpest"))
    assert emission.trusted and abs(emission.height_mm - t["height_mm"]) < 0.15
    assert not emission.mask[:, c:].any() and not sharpest.mask[:, :c].any()       # the flame; the ghost
    with pytest.raises(ValueError, match="pick must be one of"):
        measure_flame(plane, CAM, obj["depth_offset_mm"], pick="largest")


@pytest.mark.parametrize("planes", [["--depths", "auto"], ["--depth", "20", "--depth", "10", "--depth", "0.02"]])
def test_profiles_measures_each_flame_side_by_side_on_one_plane(tmp_path, planes):
    """Two flames side by side at 0 and +0.05 mm, one plane for both: their depths found (and merged onto one plane,
    each in its own columns), or the planes given by --depth (no depth search to tell them apart: the plane of
    emission is split into its flames' column bands). profiles gives each its row, measured in its own columns and
    paired with its own flame's truth by its place across the field (it measured the plane's sharpest or brightest
    region alone, the 13 mm flame without a row, and a truth read by depth alone gave both rows one flame's height);
    the other planes keep one row each."""
    import json

    import pandas as pd

    from lf_flame.cli import main
    from lf_flame.optics.camera import PAPER_CAMERA
    from lf_flame.simulate import tracer
    from lf_flame.simulate.scenes import flame_scene
    scene = flame_scene(PAPER_CAMERA, np.random.default_rng(0), regime="paper", depths_mm=(20.0, 10.0, 0.05, 0.0))
    np.savez(tmp_path / "two.npz", raw=tracer.render(PAPER_CAMERA, scene, 4, 0), camera=PAPER_CAMERA.to_json(),
             objects=json.dumps(scene.objects, default=float))
    assert main(["profiles", str(tmp_path / "two.npz"), *planes, "--no-figure", "--out", str(tmp_path / "p")]) == 0
    df = pd.read_csv(tmp_path / "p.csv")
    shared = df[df.depth_mm.abs() < 1.0].sort_values("centroid_x_mm")
    assert len(df) == 4 and sorted(shared.flame) == [0, 1], df
    near = sorted(scene.objects[2:], key=lambda o: o["centre_x_mm"])
    for (_, row), o in zip(shared.iterrows(), near):
        assert abs(row.height_mm - o["height_mm"]) < 0.3 and abs(row.centroid_x_mm - o["centre_x_mm"]) < 0.3, df
        assert row.height_mm_true == pytest.approx(o["height_mm"], abs=0.01), df
    assert (df[df.depth_mm.abs() >= 1.0].flame == 0).all()


def test_separate_flame_bands_take_regions_apart_by_columns_that_hold_their_share_of_the_light():
    """Two blobs side by side: two bands meeting halfway and covering the plane; a faint speck (under the share of
    the brightest region's light) or a blob above another (overlapping columns): the whole plane."""
    from lf_flame.measure.diagnostics import SEPARATE_SHARE, separate_flame_bands
    from lf_flame.optics.camera import PlenopticCamera
    cam = PlenopticCamera(n_rows=40, n_cols=60)
    plane = np.zeros((40, 60))
    plane[10:30, 10:16] = 1.0
    plane[12:28, 40:45] = 0.6
    assert separate_flame_bands(plane, cam) == [(0, 28), (28, 60)]
    faint = plane.copy()
    faint[12:28, 40:45] = 0.9 * SEPARATE_SHARE * 120 / 80          # its light under the share of the first's
    assert separate_flame_bands(faint, cam) == [None]
    stacked = np.zeros((40, 60))
    stacked[2:15, 10:16], stacked[20:35, 12:18] = 1.0, 0.8
    assert separate_flame_bands(stacked, cam) == [None]
    assert separate_flame_bands(np.zeros((40, 60)), cam) == [None]
    with pytest.raises(ValueError, match="share"):
        separate_flame_bands(plane, cam, share=0.0)


def test_profiles_warns_as_reconstruct_does_of_the_planes_it_measures(small_flame_npz, tmp_path, capsys):
    """The planes profiles measures are reconstruct's, and so are its warnings: two planes given for four flames
    leave light unexplained (a user's widths came out 3x and centroids 1.8 mm off with no word); an over-exposed
    capture holds a lower bound (its intensities 74 % low with no word). The scene's own planes: neither."""
    import json

    from lf_flame.cli import main
    z = np.load(small_flame_npz)
    depths = [str(o["depth_offset_mm"]) for o in json.loads(str(z["objects"]))]
    bright = tmp_path / "bright.npz"
    np.savez(bright, raw=np.clip(5 * z["raw"], 0, 1), camera=z["camera"], objects=z["objects"])
    for src, planes, misfit, clipped in ((small_flame_npz, depths, False, False),
                                         (small_flame_npz, depths[:1] + depths[-1:], True, False),
                                         (bright, depths, None, True)):
        capsys.readouterr()
        assert main(["profiles", str(src), "--no-figure", "--out", str(tmp_path / "p"),
                     *[x for d in planes for x in ("--depth", d)]]) == 0
        out = capsys.readouterr()
        text = out.out + out.err
        if misfit is not None:
            assert ("unexplained beyond its noise" in text) == misfit, text
        assert ("of the lit pixels are clipped" in text) == clipped, text


def test_profiles_finds_the_planes_of_a_file_that_stores_its_flames_when_asked(small_flame_npz, tmp_path, capsys):
    """A simulated file's planes are its flames' true depths unless asked otherwise: --depths auto (or a
    --search-range, which had been ignored in silence there) finds them as reconstruct does, within the range, and
    still scores the stored flames beside them; --depths scene of a file without flames is refused."""
    import json

    import pandas as pd

    from lf_flame.cli import main
    z = np.load(small_flame_npz)
    true = sorted(float(o["depth_offset_mm"]) for o in json.loads(str(z["objects"])))
    out = str(tmp_path / "p")
    assert main(["profiles", str(small_flame_npz), "--no-figure", "--out", out]) == 0
    assert "the scene's truth, not found" in capsys.readouterr().out
    assert sorted(pd.read_csv(out + ".csv").depth_mm) == pytest.approx(true)
    assert main(["profiles", str(small_flame_npz), "--depths", "auto", "--no-figure", "--out", out]) == 0
    assert "the scene's truth" not in capsys.readouterr().out
    found = pd.read_csv(out + ".csv")
    assert sorted(found.depth_mm) != pytest.approx(true, abs=1e-6)              # found, not given
    assert sorted(found.depth_mm) == pytest.approx(true, abs=0.5) and found.height_mm_true.notna().all()
    lo, hi = true[0] - 2.0, true[-1] + 2.0
    assert main(["profiles", str(small_flame_npz), "--search-range", str(lo), str(hi), "--no-figure",
                 "--out", out]) == 0
    assert "the scene's truth" not in capsys.readouterr().out
    ranged = pd.read_csv(out + ".csv")
    assert sorted(ranged.depth_mm) == pytest.approx(true, abs=0.5) and ranged.depth_mm.between(lo, hi).all()
    bare = tmp_path / "bare.npz"
    np.savez(bare, raw=z["raw"], camera=z["camera"])
    capsys.readouterr()
    assert main(["profiles", str(bare), "--depths", "scene", "--no-figure", "--out", out]) == 2
    assert "stores no flames" in capsys.readouterr().err


def test_profiles_out_named_as_its_csv_writes_that_csv(small_flame_npz, tmp_path):
    """``--out PREFIX`` named as one of its files (``p.csv``) writes ``p.csv``, ``p.axial.csv``, not ``p.csv.csv``
    (resolution's ``--out r.csv`` had)."""
    from lf_flame.cli import main
    assert main(["profiles", str(small_flame_npz), "--route", "shift-sum", "--no-figure",
                 "--out", str(tmp_path / "p.csv")]) == 0
    assert (tmp_path / "p.csv").is_file() and (tmp_path / "p.axial.csv").is_file()
    assert not (tmp_path / "p.csv.csv").exists()
