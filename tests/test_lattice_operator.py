"""The exact operator of decoded views (:mod:`lf_flame.tomo.lattice`): its kernels, decoding's
interpolation, the hexagonal lattice's storage and resampling, and flames solved with them against
the square camera's operator and the square grid a hexagonal camera's views are resampled onto.

The cameras are ``examples/own_camera.toml`` with a hexagonal and a square grid (10.57 px pitch,
rotated 0.4°), as ``experiments/cameras.py`` builds them; the capture one of its ``simulate --scene
depth`` scenes.
"""
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pylops
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.real import calibration as calibrate
from lf_flame.real import decoding, view_grid
from lf_flame.real.lightfield import from_decoded
from lf_flame.simulate import scenes, tracer
from lf_flame.simulate.scenes_depth import camera_depth_scene
from lf_flame.tomo import lattice as hx
from lf_flame.tomo.decoded import decoded_plane_truth
from lf_flame.tomo.quadrature import exact_kernels
from lf_flame.tomo.truth import bin_planes

from test_decoding import _camera

SEED = 4242
RAYS = 48


@pytest.mark.parametrize("shifts", [None, (-1 / 3, 0.0, 1 / 3)], ids=["views", "sub-views"])
def test_square_lattice_kernels_are_the_exact_quadratures(shifts):
    """The same low-discrepancy means on a square lattice give the closed-form quadrature's taps: the ray chain,
    the aperture, cos^4 and the texel offsets are read as the square camera's; so are the sub-views of samples off
    their view's place (a colour capture's nearest pixels)."""
    tiny = PlenopticCamera(n_rows=15, n_cols=17, pixels_per_lenslet=9 if shifts is None else 5)
    depths = [-8.0, 0.0, 6.0]
    ek = exact_kernels(tiny, depths, view_shifts=shifts)
    lk = hx.lattice_kernels(tiny, depths, (tiny.n_rows, tiny.n_cols), layout="square", points=2 ** 16,
                            view_shifts=shifts)
    N, P = ek.kernels.shape[0], len(depths)
    diff = total = 0.0
    for u in range(N):
        for v in range(N):
            for k in range(P):
                canvas = np.zeros((2, 64, 64))
                for i, (h, oy, ox) in enumerate(((ek.kernels, ek.tap_origin_y, ek.tap_origin_x),
                                                 (lk.kernels, lk.tap_origin_y, lk.tap_origin_x))):
                    t = h[u, v, k]
                    canvas[i, 32 + oy[u, k]:32 + oy[u, k] + t.shape[0], 32 + ox[v, k]:32 + ox[v, k] + t.shape[1]] += t
                diff += np.abs(canvas[0] - canvas[1]).sum()
                total += canvas[0].sum()
    assert diff / total < 2e-3, diff / total


def test_hexagon_points_fill_the_cell_uniformly():
    """Every point lies in the site's hexagon, and as many fall in the central band |col| < 1/4 as its
    area's share, 7/12 (a pointy hexagon of inradius 1/2: heights (2/sqrt 3)(1 - |col|))."""
    u = hx.rd_points(2 ** 14, 2) - 0.5
    rows, cols = hx.hexagon_points(u[:, 0], u[:, 1])
    j, i = hx.nearest_site(rows, cols)
    assert np.all(j == 0) and np.all(i == 0)
    assert abs(np.mean(np.abs(cols) < 0.25) - 7 / 12) < 0.005
    assert abs(rows.mean()) < 0.01 and abs(cols.mean()) < 0.01


def test_nearest_site_is_the_nearest_of_the_lattice():
    rng = np.random.default_rng(0)
    y, x = rng.uniform(-5, 5, (2, 2000))
    j, i = hx.nearest_site(y, x)
    d = (y - j * math.sqrt(3) / 2) ** 2 + (x - i - j / 2) ** 2
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            other = (y - (j + dj) * math.sqrt(3) / 2) ** 2 + (x - (i + di) - (j + dj) / 2) ** 2
            assert np.all(d <= other + 1e-12)


def test_axial_storage_keeps_each_row_and_marks_the_lenslets():
    a = np.arange(5 * 4).reshape(5, 4) + 1.0
    ax, inside = hx.to_axial(a)
    assert ax.shape == (5, 4 + 2) and inside.sum() == a.size
    for j in range(5):
        assert np.array_equal(ax[j][inside[j]], a[j])
        assert np.flatnonzero(inside[j])[0] == 2 - j // 2         # odd rows half a pitch right: skew i = c - j // 2


@pytest.fixture(scope="module")
def capture():
    """The hexagonal camera, its calibration, a depth scene and its decoded light field (with the lattice's views)."""
    cam = _camera("hex")
    white = tracer.render(cam, scenes.white_scene(cam), 16, 0)
    scene = camera_depth_scene(cam, np.random.default_rng(SEED))
    raw = tracer.render(cam, scene, RAYS, SEED)
    cal = calibrate.calibrate(white)
    lattice = decoding.decode(raw, cal, white, resample=False)
    lf = from_decoded(view_grid.on_square_grid(lattice, cal), cal, cam, lattice_views=lattice)
    return cam, scene, lf, cal


def test_decoding_keeps_the_lattice_and_resamples_it_as_before(capture):
    lf, cal = capture[2:]
    assert lf.lattice_views.shape[2:] == (cal.n_rows, cal.n_cols)
    R, C = lf.lattice_views.shape[2:]
    assert lf.views.shape[2:] == (int(math.floor((R - 1) * math.sqrt(3) / 2)) + 1, C - 1)
    assert np.array_equal(lf.views, view_grid.hex_to_square(lf.lattice_views))


@pytest.fixture(scope="module")
def operator(capture):
    lf = capture[2]
    return hx.LatticeOperator(lf.camera, [-6.0, 9.0], lf.lattice_views.shape[2:], subsamples=2, precision="float64")


def test_the_lattice_operator_has_its_adjoint_and_binned_planes(operator):
    assert operator.dims[1:] == tuple(2 * np.array(operator.inside.shape))
    assert pylops.utils.dottest(operator, *operator.shape, rtol=1e-10)
    coarse = operator.binned()
    x = np.random.default_rng(2).random(coarse.dims)
    fine = x.repeat(2, axis=1).repeat(2, axis=2)
    assert np.allclose(coarse.matvec(x.ravel()), operator.matvec(fine.ravel()), rtol=1e-9, atol=1e-12)


def test_resampling_onto_the_square_grid_keeps_affine_emission(operator):
    """Barycentric interpolation is exact for an affine function of the position: the square grid's
    samples of ``1 + 0.3 y - 0.2 x`` (pitches) from the lattice's, away from the array's border."""
    s, (R, _) = operator.subsamples, operator.lattice_shape
    off = (R - 1) // 2
    j, i = np.meshgrid(np.arange(operator.dims[1]), np.arange(operator.dims[2]), indexing="ij")
    y, x = j * math.sqrt(3) / 2 / s, (i - s * off) / s + j / (2 * s)
    planes = np.broadcast_to(1 + 0.3 * y - 0.2 * x, operator.dims)
    rows, cols = 10, 8
    sq = operator.to_square(planes, rows, cols)
    ys, xs = np.meshgrid((np.arange(s * rows) + 0.5) / s - 0.5, (np.arange(s * cols) + 0.5) / s, indexing="ij")
    assert np.allclose(sq[:, 1:, :], (1 + 0.3 * ys - 0.2 * xs)[1:], atol=1e-12)
    back = operator.from_square(np.ones((1, s * rows, s * cols), bool))
    yy, xx = y[back[0]], x[back[0]]                           # every site taken lies in the square grid's field
    assert yy.min() >= -0.5 and yy.max() < rows - 0.5 and xx.min() >= 0 and xx.max() < cols


def test_a_hexagonal_cameras_flames_are_solved_on_its_own_lattice(capture):
    """At the flames' depths, admm on the lattice's views (resampled onto the square grid afterwards)
    against admm on the views resampled onto the square grid: every flame nearer its truth, on average the more
    so with decoding's interpolation in the lattice's operator (here 11.2 / 14.4 % on the square grid; on the
    lattice 6.6 / 13.4 % without the interpolation, 6.8 / 11.7 % with it)."""
    from lf_flame.cli.planes import run_reconstruction
    scene, lf = capture[1:3]
    depths = sorted({round(o["depth_offset_mm"], 3) for o in scene.objects})
    op, rec = run_reconstruction(lf, depths)
    lat = hx.solve_on_lattice(lf, rec, op)
    assert lat.square.planes.shape == rec.planes.shape and lat.square.settings["lattice"] == "hexagonal"
    blind = hx.solve_on_lattice(dataclasses.replace(lf, interpolation=None), rec, op)
    s = op.subsamples
    errors = []
    for k, d in enumerate(depths):
        layers = [L for L, o in zip(scene.layers, scene.objects) if abs(o["depth_offset_mm"] - d) < 1e-3]
        truth = sum(decoded_plane_truth(L, lf.camera, d, (op.dims[1] // s, op.dims[2] // s), lf.frame.rotation_deg,
                                        lf.frame.centre_lenslets) for L in layers)
        errors.append([np.linalg.norm(bin_planes(r.planes, s)[k] - truth) / np.linalg.norm(truth)
                       for r in (rec, blind.square, lat.square)])
    errors = np.array(errors)
    print("square grid, lattice without and with the interpolation:", errors.round(3).tolist())
    assert np.all(errors[:, 1:].max(axis=1) < errors[:, 0]), errors
    assert errors[:, 2].mean() < errors[:, 1].mean() < 0.8 * errors[:, 0].mean(), errors


def test_interpolation_phases_are_nil_where_lenslet_centres_sit_on_pixels(capture):
    """A grid whose lenslet centres fall on pixel centres is decoded without interpolating with an
    odd number of views (an even number samples halfway between pixels: phase 1/2), and the kernels
    are the same with phases 0 as without; the hexagonal camera's phases spread over [0, 1)."""
    cal = capture[3]
    on_pixels = dataclasses.replace(cal, layout="square", pitch_px=10.0, rotation_deg=0.0, origin_px=(5.5, 5.5))
    assert np.abs(view_grid.interpolation_phases(on_pixels, 9)).max() < 1e-9
    assert np.abs(view_grid.interpolation_phases(on_pixels, 10) - 0.5).max() < 1e-9
    phases = view_grid.interpolation_phases(cal, 10)
    assert np.histogram(phases[0], bins=4, range=(0, 1))[0].min() > 0.15 * phases.shape[1]
    lf = capture[2]
    plain = hx.lattice_kernels(lf.camera, [5.0], (6, 8), points=2 ** 10)
    nil = hx.lattice_kernels(lf.camera, [5.0], (6, 8), points=2 ** 10, interpolation=(np.zeros((2, 7)), 1))
    assert np.array_equal(plain.kernels, nil.kernels)


def test_decoded_square_views_are_solved_with_their_interpolation():
    """The example camera (square grid, 10.57 px pitch: the samples' phases spread between pixels): admm with
    decoding's interpolation in the operator against the square camera's exact operator, at the flames'
    depths: nearer the truth on average by a fifth or more (here 4.8 / 8.5 % -> 3.8 / 4.3 %)."""
    from lf_flame.cli.planes import run_reconstruction
    cam = _camera("square")
    white = tracer.render(cam, scenes.white_scene(cam), 16, 0)
    scene = camera_depth_scene(cam, np.random.default_rng(SEED))
    raw = tracer.render(cam, scene, RAYS, SEED)
    cal = calibrate.calibrate(white)
    lf = from_decoded(decoding.decode(raw, cal, white), cal, cam)
    depths = sorted({round(o["depth_offset_mm"], 3) for o in scene.objects})
    errors = []
    for light_field in (dataclasses.replace(lf, interpolation=None), lf):
        op, rec = run_reconstruction(light_field, depths)
        assert isinstance(op, hx.LatticeOperator) == (light_field.interpolation is not None)
        s = op.subsamples
        for k, d in enumerate(depths):
            layers = [L for L, o in zip(scene.layers, scene.objects) if abs(o["depth_offset_mm"] - d) < 1e-3]
            truth = sum(decoded_plane_truth(L, lf.camera, d, (op.dims[1] // s, op.dims[2] // s), lf.frame.rotation_deg,
                                            lf.frame.centre_lenslets) for L in layers)
            errors.append(np.linalg.norm(bin_planes(rec.planes, s)[k] - truth) / np.linalg.norm(truth))
    errors = np.array(errors).reshape(2, -1)
    print("without, with the interpolation:", errors.round(3).tolist())
    assert errors[1].mean() < 0.8 * errors[0].mean(), errors


def test_a_hexagonal_capture_goes_through_the_command_line_on_its_lattice(tmp_path, capsys):
    """simulate -> calibrate -> decode (the lattice's views and clipped samples kept beside the square
    grid's) -> reconstruct at given depths: solved again on the lattice, its clipped samples left out."""
    import h5py

    from lf_flame import cli
    from lf_flame.tomo.files import load_reconstruction
    sheet = (Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
    cam = tmp_path / "hex.toml"
    cam.write_text(sheet.replace('layout = "square"', 'layout = "hex"'))
    run = lambda *a: cli.main([str(x) for x in a])                                   # noqa: E731
    assert run("simulate", "--camera", cam, "--scene", "white", "--out", tmp_path / "white.npz") == 0
    assert run("calibrate", tmp_path / "white.npz", "--out", tmp_path / "cal.json") == 0
    assert run("simulate", "--camera", cam, "--scene", "depth", "--seed", SEED, "--rays-per-pixel", 8,
               "--out", tmp_path / "scene.npz") == 0
    z = dict(np.load(tmp_path / "scene.npz"))
    z["raw"] = np.minimum(2.0 * z["raw"], 1.0).astype(np.float32)                  # the flames' cores clip
    np.savez(tmp_path / "bright.npz", **z)
    depths = sorted({round(o["depth_offset_mm"], 2) for o in json.loads(str(z["objects"]))})
    assert run("decode", tmp_path / "bright.npz", "--calibration", tmp_path / "cal.json",
               "--out", tmp_path / "views.h5") == 0
    with h5py.File(tmp_path / "views.h5") as f:
        lattice, clipped = f["lattice_views"][...], f["lattice_clipped"][...]
        assert lattice.shape[2:] == tuple(json.loads(f.attrs["calibration"])[k] for k in ("n_rows", "n_cols"))
        assert 0 < clipped.sum() < 0.15 * clipped.size
        assert np.array_equal(f["views"][...], view_grid.hex_to_square(lattice))
    left_out = {}
    for saturation in ("file", "none"):                          # none: every sample fitted, clipped or not
        capsys.readouterr()
        assert run("reconstruct", tmp_path / "views.h5", "--camera", cam, "--calibration", tmp_path / "cal.json",
                   *[x for d in depths for x in ("--depth", d)], *(["--saturation", "none"] if saturation == "none"
                                                                    else []), "--out", tmp_path / "rec.h5") == 0
        assert "solved again on the hexagonal lattice" in capsys.readouterr().out
        rec = load_reconstruction(tmp_path / "rec.h5")
        assert rec.settings["lattice"] == "hexagonal" and np.isfinite(rec.planes).all() and rec.planes.max() > 0
        with h5py.File(tmp_path / "rec.h5") as f:
            assert f.attrs["operator"] == "exact, with decoding's interpolation, on the hexagonal lattice"
        left_out[saturation] = rec.settings["n_saturated"]
    assert left_out["file"] - left_out["none"] >= 0.9 * clipped.sum(), (left_out, clipped.sum())


def test_impossible_lattices_and_views_are_refused(capture):
    lf = capture[2]
    with pytest.raises(ValueError, match="too small"):
        hx.LatticeOperator(lf.camera, [5.0], (1, 8))
    with pytest.raises(ValueError, match="layout"):
        hx.LatticeOperator(lf.camera, [5.0], (6, 8), layout="triangle")
    square = hx.LatticeOperator(lf.camera, [5.0], (6, 8), layout="square")
    with pytest.raises(ValueError, match="hexagonal"):
        square.to_square(np.zeros(square.dims), 6, 8)
    bad = lf.lattice_views.copy()
    bad[0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="lattice views"):
        dataclasses.replace(lf, lattice_views=bad)
    with pytest.raises(ValueError, match="no hexagonal lattice views"):
        hx.solve_on_lattice(dataclasses.replace(lf, lattice_views=None), None, None)


def test_left_out_samples_are_counted_among_the_lattices_own(operator):
    """On the axial array the cells that hold no lenslet are no samples: a solve's ``n_saturated`` counts only the
    lenslets' samples left out, of ``n_samples`` (the lenslets' samples), as ``reconstruct`` and ``sequence`` report."""
    from lf_flame.tomo.solvers import reconstruct
    rng = np.random.default_rng(5)
    inside = np.broadcast_to(operator.inside, operator.dimsd)
    clipped = inside & (rng.random(operator.dimsd) < 0.01)
    leave = clipped | ~inside
    rec = reconstruct(rng.random(operator.dimsd), operator, "adjoint", saturation=leave)
    assert rec.settings["n_saturated"] == int(clipped.sum()) > 0
    assert rec.settings["n_samples"] == int(inside.sum()) < leave.size
