"""Volumes (lf_flame.tomo.volume and 'lf-flame reconstruct --volume'): a dense stack with a prior, end to end."""
import dataclasses
import json

import h5py
import numpy as np
import pytest

from lf_flame.cli import main
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.tomo.volume import solve_volume, volume_depths

CAMERA_TOML = "[camera]\nn_rows = 41\nn_cols = 41\n"          # a 5.4 mm field


@pytest.fixture(scope="module")
def volume_raw(tmp_path_factory):
    d = tmp_path_factory.mktemp("volume")
    (d / "cam.toml").write_text(CAMERA_TOML)
    raw = d / "vol.npz"
    assert main(["simulate", "--scene", "volume", "--nominal", "--data-config", str(d / "cam.toml"),
                 "--rays-per-pixel", "16", "--out", str(raw)]) == 0
    return raw


def _error(capsys):
    out = capsys.readouterr().out
    return float(out.split("3-D relative error ")[1].split()[0]), out


def test_the_volumes_resolution_note_names_features_finer_than_the_planes_samples():
    """A feature finer than the planes' samples is not mapped (NaN): the note says so, not 'nan mm apart'."""
    import pandas as pd

    from lf_flame.cli.fit_notes import resolution_note
    table = pd.DataFrame({"feature_mm": [0.33, 1.3, 6.6], "spacing_interp_mm_10": [np.nan, 4.51, np.inf]})
    note = resolution_note(table, 10.0, 30.0)
    assert note.endswith("0.33 mm features finer than the planes' samples, 1.3 mm features 4.5 mm apart, "
                         "6.6 mm features > 30 mm apart") and "nan" not in note


def test_an_axis_depth_searched_about_an_uncertain_found_depth_is_warned_of(capsys):
    """On a camera whose found depths are uncertain by more than the axis search's half width (a user's: +-42 mm
    against 3 mm, the axis 4 mm off among minima that follow the planes' spacing) reconstruct --volume warns that the
    axis depth is known no better; a well-placed start (or an axis given) is not warned of."""
    from lf_flame.cli.volume import axis_depth_warning
    from lf_flame.tomo.axisymmetric import SEARCH_HALF_WIDTH_MM, AxisymmetricVolume
    axi = AxisymmetricVolume(np.zeros((2, 2)), np.zeros(2), np.zeros(2), np.zeros((1, 2, 2)), 0.1, -3.98, 0.02,
                             start_uncertainty_mm=42.0)
    for u, warned in ((42.0, True), (0.3, False), (float("nan"), False)):
        capsys.readouterr()
        axis_depth_warning(dataclasses.replace(axi, start_uncertainty_mm=u))
        err = capsys.readouterr().err
        assert ("the axis depth is known no better" in err) == warned and (f"+-{u:.2g} mm" in err) == warned
    assert SEARCH_HALF_WIDTH_MM < 42.0


def test_volume_cli_priors_write_the_stack_and_the_axisymmetric_one_wins(volume_raw, tmp_path, capsys):
    capsys.readouterr()
    errs = {}
    for prior in ("none", "axisymmetric"):
        out = tmp_path / f"{prior}.h5"
        assert main(["reconstruct", str(volume_raw), "--volume", "--from", "-2.5", "--to", "2.5", "--step", "0.5",
                     "--prior", prior, "--out", str(out)]) == 0
        captured = capsys.readouterr()
        errs[prior] = float(captured.out.split("3-D relative error ")[1].split()[0])
        text = captured.out
        assert "depth resolution of this stack" in text and "beyond the stack" not in text
        assert "the axis depth is known no better" not in captured.err      # found within a fraction of a mm
        with h5py.File(out) as f:
            np.testing.assert_allclose(f["depths_mm"][...], np.arange(-2.5, 2.51, 0.5))
            assert f["planes"].shape == (11, 41, 41) and f.attrs["volume"]
            settings = json.loads(f.attrs["settings"])
            assert settings["prior"] == prior and settings["step_mm"] == 0.5
            res = json.loads(f.attrs["depth_resolution"])
            assert len(res["feature_mm"]) == 5 and "spacing_interp_mm_10" in res
            assert ("extra/emission_r_y" in f) == (prior == "axisymmetric")
            if prior == "axisymmetric":
                assert abs(settings["axis_z_mm"]) < 0.5 and abs(settings["axis_x_mm"]) < 0.2   # the sheath's axis: 0, 0
                assert settings["beyond_field"] is False                     # the sheath stands inside the field
                assert 0 < settings["start_uncertainty_mm"] < 3.0            # its search's start well placed
            assert len(json.loads(f.attrs["edge_share"])) == 11
            misfit = json.loads(f.attrs["misfit"])       # the stack holds the sheath: no light left unexplained
            assert misfit["misfit"] < 0.05 and misfit["relative_residual"] < 0.1, misfit
        assert (tmp_path / f"{prior}.png").stat().st_size > 0
    # the sheath is axisymmetric: its prior resolves what the data alone leave to the dense stack
    assert errs["axisymmetric"] < 0.5 * errs["none"], errs
    # a stack beside the flame is scored against a truth moved onto its end planes: said so with the score (it had
    # been printed as any other, 0.756 against 0.765 for the stack over the flame)
    assert main(["reconstruct", str(volume_raw), "--volume", "--from", "4", "--to", "6", "--step", "0.5",
                 "--no-figure", "--out", str(tmp_path / "beside.h5")]) == 0
    assert "100 % of the scene's light lies beyond the stack: scored on its end planes" in capsys.readouterr().out


def test_volume_cli_refusals(volume_raw, tmp_path, capsys):
    out = str(tmp_path / "v.h5")
    cases = [(["--volume"], "--from MM and --to MM"),
             (["--from", "-3", "--to", "3"], "go with --volume"),
             (["--step", "1"], "--step go with --volume"),
             (["--volume", "--from", "-3", "--to", "3", "--depth", "0"], "drop --depth"),
             (["--volume", "--from", "-3", "--to", "3", "--prior", "tv", "--l1", "0.01"], "l1 weight with 'sparse'"),
             (["--volume", "--from", "3", "--to", "-3"], "near < far"),
             (["--volume", "--from", "-20", "--to", "20", "--step", "0.4"], "at most 81"),
             (["--volume", "--from", "400", "--to", "500"], "this camera refocuses")]
    for args, message in cases:
        capsys.readouterr()
        assert main(["reconstruct", str(volume_raw), *args, "--out", out]) == 2, args
        assert message in capsys.readouterr().err, args
    assert not (tmp_path / "v.h5").exists()                 # nothing written by a refused call


def test_solve_volume_refusals():
    cam = PlenopticCamera(n_rows=21, n_cols=21)
    views = np.zeros((cam.pixels_per_lenslet,) * 2 + (21, 21))
    with pytest.raises(ValueError, match="prior must be one of"):
        solve_volume(views, cam, -1.0, 1.0, 0.5, "smooth")
    with pytest.raises(ValueError, match="at least 2 planes"):
        volume_depths(0.0, 0.2, 0.5)
    with pytest.raises(ValueError, match="TV weight goes with"):
        solve_volume(views, cam, -1.0, 1.0, 0.5, "none", tv=0.1)


def test_the_tv_and_l1_weights_follow_the_noise(volume_raw):
    from lf_flame.cli._io import _raw_reader
    from lf_flame.real.readers import read_light_field
    from lf_flame.tomo.defaults import VOLUME_L1, VOLUME_TV
    from lf_flame.tomo.noise_knobs import noise_regime, relative_noise
    lf = read_light_field(volume_raw, raw_reader=_raw_reader)
    views, cam = lf.views, lf.camera
    noisy = np.clip(views + np.random.default_rng(0).normal(0, 0.05, views.shape), 0, None)
    for v in (views, noisy):
        regime = noise_regime(relative_noise(v, v < 1.0))
        rec, _ = solve_volume(v, cam, -1.0, 1.0, 0.5, "tv", resolution=False)
        assert rec.settings["tv"] == VOLUME_TV[regime] and rec.settings["prior"] == "tv"
        rec, _ = solve_volume(v, cam, -1.0, 1.0, 0.5, "sparse", resolution=False)
        assert rec.settings["l1"] == VOLUME_L1[regime]
    assert noise_regime(relative_noise(noisy, noisy < 1.0)) == "noisy"
    rec, _ = solve_volume(views, cam, -1.0, 1.0, 0.5, "sparse", l1=0.01, resolution=False)
    assert rec.settings["l1"] == 0.01


def test_the_edge_warning_names_the_planes_cut_and_says_when_the_light_beyond_was_modelled(capsys):
    from lf_flame.cli.fit_notes import edge_warning
    from lf_flame.tomo.solvers import Reconstruction
    planes = np.zeros((6, 20, 20))
    planes[:, 8:12, 8:12] = 1.0                                            # inside the field on every plane
    planes[:5, 8:12, 18:] = 1.0                                            # cut by the right edge on five
    rec = Reconstruction(planes, tuple(float(d) for d in range(6)), ((0.1, 0.1),) * 6, "admm")
    edge = edge_warning(rec, None)
    assert len(edge) == 6 and edge[5] == 0.0 and min(edge[:5]) > 0.3
    out, err = capsys.readouterr()
    assert "warning: the emission reaches the field's edge" in err and "+0.00 mm" in err and "and 1 more" in err
    assert "+5.00 mm" not in err and not out and "spread light there" not in err
    edge_warning(rec, None, stack=True)                                  # a dense stack without a prior: or spread light
    assert "on planes far from the flame, the solve spread light there" in capsys.readouterr().err
    edge_warning(rec, None, modelled=True)
    out, err = capsys.readouterr()
    assert "modelled its light from beyond the field" in out and not err
    # a plane far from the flame with a few stray samples at the border: most of its little light, not warned of
    faint = np.zeros((2, 20, 20))
    faint[0, 6:14, 6:14] = 1.0
    faint[1, 0, 5] = 0.5                                                  # 0.8 % of the bright plane's light
    edge = edge_warning(Reconstruction(faint, (0.0, 1.0), ((0.1, 0.1),) * 2, "admm"), None)
    assert edge[1] == 1.0 and not capsys.readouterr().err


def test_another_flames_stray_light_along_the_edge_is_not_a_flame_cut_by_it(capsys):
    """A plane whose flame stands inside the field, with another plane's stray light spread faintly along the border
    (a user's 99 x 98-lenslet capture: 1.2 % of a dim plane's light there, at most 1.7 % of its peak) is not warned of
    as cut; the same share as a body at the edge is."""
    from lf_flame.cli.fit_notes import edge_warning
    from lf_flame.tomo.solvers import EDGE_BODY, Reconstruction, edge_shares
    planes = np.zeros((2, 40, 40))
    planes[:, 15:25, 15:25] = 1.0                                          # each plane's flame, inside the field
    planes[0, 38:, 5:35] = 0.02                                            # stray light along the bottom edge
    planes[1, 38:, 18:21] = 0.2                                            # the flame's own light at the edge
    rec = Reconstruction(planes, (1.0, 2.0), ((0.1, 0.1),) * 2, "admm")
    edge = edge_warning(rec, None)
    assert edge[0] > 0.01 and edge[1] > 0.01
    assert list(edge_shares(planes, peak=True) >= EDGE_BODY) == [False, True]
    err = capsys.readouterr().err
    assert "+2.00 mm" in err and "+1.00 mm" not in err


def test_a_volume_moved_sideways_is_drawn_whole_and_cut_by_the_fields_edge(volume_raw, tmp_path, capsys):
    """simulate --scene volume --x: the axis moves right by x (the central view's light centroid with it), the object
    records it, and the sheath is drawn past the field's edge (its layers wider than the 1.2-field default); the
    command prints the share of its light outside the field (the centred sheath's: none)."""
    from lf_flame.cli._io import _raw_scene
    from lf_flame.refocus.shift_and_sum import raw_to_views
    from lf_flame.simulate.layers import light_outside_field
    (tmp_path / "cam.toml").write_text(CAMERA_TOML)
    moved = tmp_path / "moved.npz"
    capsys.readouterr()
    assert main(["simulate", "--scene", "volume", "--nominal", "--data-config", str(tmp_path / "cam.toml"),
                 "--x", "2.0", "--rays-per-pixel", "16", "--out", str(moved)]) == 0
    printed = capsys.readouterr().out
    cam = PlenopticCamera(n_rows=41, n_cols=41)
    centroids = []
    for path in (volume_raw, moved):
        raw = np.load(path)["raw"]
        view = raw_to_views(raw, cam.pixels_per_lenslet)[cam.pixels_per_lenslet // 2, cam.pixels_per_lenslet // 2]
        centroids.append(float((view.sum(axis=0) * np.arange(view.shape[1])).sum() / view.sum()))
    mm_per_lenslet = cam.field_of_view_mm(0.0)[1] / cam.n_cols
    shift_mm = (centroids[1] - centroids[0]) * mm_per_lenslet
    assert 1.0 < shift_mm < 2.2, shift_mm                          # cut by the edge: the light seen moves less
    scene = _raw_scene(moved, cam)
    assert scene.objects[0]["centre_x_mm"] == 2.0
    share = light_outside_field(scene, cam)
    assert 0.1 < share < 0.5 and f"{100 * share:.1f} % of its light lies outside the field of view" in printed
    assert light_outside_field(_raw_scene(volume_raw, cam), cam) < 0.001
    width = cam.field_of_view_mm(scene.layers[0].depth_offset_mm)[1]
    assert scene.layers[0].size_mm[1] > 1.2 * width + 0.1              # drawn past the default margin
