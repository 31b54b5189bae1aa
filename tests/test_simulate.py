import dataclasses

import numba
import numpy as np
import pytest

from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.refocus.shift_and_sum import raw_to_views


def _render(cam, scene, rpp=16, seed=0, **effects):
    if effects:
        scene = dataclasses.replace(scene, effects=dataclasses.replace(scene.effects, **effects))
    return simulate.render(cam, scene, rpp, seed)


def test_in_focus_point_lights_exactly_one_lenslet(small_camera):
    cam, n = small_camera, small_camera.pixels_per_lenslet
    raw = _render(cam, scenes.point_scene(cam, 0.0))
    blocks = raw.reshape(cam.n_rows, n, cam.n_cols, n).sum(axis=(1, 3))
    assert blocks[20, 20] > 0
    assert np.count_nonzero(blocks) == 1


@pytest.mark.parametrize("dz", [20.0, -10.0, 12.0])
def test_defocused_point_disc_matches_geometric_optics(small_camera, dz):
    cam, n = small_camera, small_camera.pixels_per_lenslet
    raw = _render(cam, scenes.point_scene(cam, dz), rpp=100)
    blocks = raw.reshape(cam.n_rows, n, cam.n_cols, n).sum(axis=(1, 3))
    # blur disc on the MLA: D |d - z_i| / z_i, in lenslets
    zi = cam.image_distance_mm(cam.object_distance_mm(dz))
    expected = cam.aperture_diameter_mm * abs(cam.mla_distance_mm - zi) / zi / cam.mla_pitch_mm
    # a chord of length L lights ceil(L) or ceil(L) + 1 lenslets: the widest row's count
    # minus one estimates the diameter to within one lenslet
    widest = np.count_nonzero(blocks, axis=1).max()
    assert abs(widest - 1 - expected) <= 1.0, (widest, expected)


@pytest.mark.parametrize("dz", [-10.0, -4.0, 6.0, 15.0, 20.0])
def test_parallax_across_views_matches_analytic_slope(small_camera, dz):
    cam = small_camera
    size = 2 * cam.mla_pitch_mm * cam.object_distance_mm(dz) / cam.mla_distance_mm  # more hits, same centroid
    views = raw_to_views(_render(cam, scenes.point_scene(cam, dz, size_mm=size), rpp=64), cam.pixels_per_lenslet)
    us = np.arange(3, 12)  # views well inside the aperture
    rows = np.arange(cam.n_rows) + 0.5
    cent = [np.sum(views[u, 7].sum(axis=1) * rows) / views[u, 7].sum() for u in us]
    slope = np.polyfit(us - 7, cent, 1)[0]
    assert abs(slope - cam.slope_for_depth(dz)) < 0.02, (slope, cam.slope_for_depth(dz))


def test_uniform_plane_flux_is_exact_without_aperture(small_camera, uniform_scene):
    raw = _render(small_camera, uniform_scene(small_camera, 0.5), rpp=4)
    assert np.allclose(raw, 0.5, atol=1e-6)


def test_uniform_plane_flux_with_aperture(small_camera, uniform_scene):
    cam = small_camera
    raw = _render(cam, uniform_scene(cam, 1.0), rpp=16, aperture=True)
    # the aperture's image through each lenslet is a disc of diameter D g / d inside a
    # block of side N * pixel pitch: the expected mean signal is their area ratio
    disc = cam.aperture_diameter_mm * cam.sensor_distance_mm / cam.mla_distance_mm
    expected = np.pi / 4 * (disc / cam.lenslet_image_pitch_mm) ** 2
    assert abs(raw.mean() / expected - 1) < 0.01


def test_cos4_falloff_profile(small_camera, uniform_scene):
    cam, n = small_camera, small_camera.pixels_per_lenslet
    raw = _render(cam, uniform_scene(cam, 1.0), rpp=16, cos4=True)
    block = raw[20 * n:21 * n, 20 * n:21 * n]  # the central lenslet
    delta = (np.arange(n) - (n - 1) / 2) * cam.pixel_pitch_mm
    tan2 = (delta[:, None] ** 2 + delta[None, :] ** 2) / cam.sensor_distance_mm ** 2
    expected = 1.0 / (1.0 + tan2) ** 2
    assert np.allclose(block, expected, rtol=0.01)
    assert block[0, 0] < 0.97 * block[7, 7]  # the fall-off is there


def test_occlusion_hides_farther_layer(small_camera):
    cam = small_camera
    h, w = cam.field_of_view_mm(0.0)
    near = scenes.Layer(np.zeros((2, 2), np.float32), np.ones((2, 2), np.float32), -10.0, (0, 0), (5 * h, 5 * w))
    far = scenes.Layer(np.ones((2, 2), np.float32), None, 10.0, (0, 0), (5 * h, 5 * w))
    opaque = scenes.Scene("o", (far, near), scenes.Effects(aperture=False, cos4=False, occlusion=True))
    thin = dataclasses.replace(opaque, effects=scenes.Effects(aperture=False, cos4=False, occlusion=False))
    assert simulate.render(cam, opaque, 1).max() == 0.0
    assert np.allclose(simulate.render(cam, thin, 1), 1.0)


def test_same_seed_bit_identical_across_thread_counts(small_camera):
    cam = small_camera
    sc = scenes.shapes_scene(cam, np.random.default_rng(3))
    a = simulate.render(cam, sc, 4, seed=11)
    old = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        b = simulate.render(cam, sc, 4, seed=11)
    finally:
        numba.set_num_threads(old)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, simulate.render(cam, sc, 4, seed=12))


def test_sensor_noise_and_bit_depth(small_camera, uniform_scene):
    cam = small_camera
    sc = uniform_scene(cam, 0.5)
    noisy = _render(cam, sc, rpp=1, full_well_e=1000.0, read_noise_e=2.0, bit_depth=8)
    assert np.isclose(noisy.mean(), 0.5, atol=0.01)
    assert np.isclose(noisy.std(), np.sqrt(0.5 * 1000 + 4) / 1000, rtol=0.1)  # shot + read noise
    assert len(np.unique(noisy)) <= 256 and np.allclose(noisy * 255, np.round(noisy * 255), atol=1e-4)


@pytest.mark.parametrize("kw, message", [
    (dict(bit_depth=0), "bit_depth must be a whole number of bits from 1 to 32"),
    (dict(bit_depth=-3), "bit_depth"), (dict(bit_depth=12.5), "bit_depth"), (dict(bit_depth=True), "bit_depth"),
    (dict(full_well_e=0.0), "full_well_e must be a finite number of electrons > 0"),
    (dict(full_well_e=np.inf), "full_well_e"),
    (dict(full_well_e=1e4, read_noise_e=np.nan), "read_noise_e must be a finite number of electrons >= 0"),
    (dict(full_well_e=1e4, read_noise_e=-5.0), "read_noise_e"),
    (dict(read_noise_e=50.0), "read_noise_e=50.0 needs full_well_e")])
def test_impossible_sensor_settings_are_refused(kw, message):
    """A sensor that would render NaN (no bits, no full well) or ignore its read noise is refused, naming it."""
    with pytest.raises(ValueError, match=message):
        scenes.Effects(**kw)
    scenes.Effects(full_well_e=np.float32(1e4), read_noise_e=0.0, bit_depth=np.int64(12))   # NumPy numbers are fine


def test_scenes_refuse_a_nan_depth_and_no_texels(small_camera):
    with pytest.raises(ValueError, match="finite number of mm"):
        scenes.point_scene(small_camera, np.nan)
    with pytest.raises(ValueError, match="texels_per_lenslet must be a finite number > 0"):
        scenes.flame_scene(small_camera, np.random.default_rng(0), texels_per_lenslet=0)
    with pytest.raises(ValueError, match="rays_per_pixel and seed must be whole numbers"):
        simulate.render(small_camera, scenes.point_scene(small_camera, 0.0), 4, None)


def test_layer_behind_camera_rejected(small_camera):
    layer = scenes.Layer(np.ones((2, 2), np.float32), None, -400.0, (0, 0), (1, 1))
    with pytest.raises(ValueError, match="behind the (camera|main lens)"):
        simulate.render(small_camera, scenes.Scene("bad", (layer,), scenes.Effects()), 1)


def test_nan_radiance_rejected(small_camera):
    layer = scenes.Layer(np.full((2, 2), np.nan, np.float32), None, 0.0, (0, 0), (1, 1))
    with pytest.raises(ValueError, match="NaN"):
        simulate.render(small_camera, scenes.Scene("bad", (layer,), scenes.Effects()), 1)


def test_scenes_declare_their_effects(small_camera):
    rng = np.random.default_rng(0)
    assert scenes.shapes_scene(small_camera, rng).effects.occlusion is True
    assert scenes.flame_scene(small_camera, rng).effects.occlusion is False


def test_flame_heights_follow_the_paper(small_camera):
    rng = np.random.default_rng(1)
    heights = np.array([[o["height_template_mm"] for o in scenes.flame_scene(small_camera, rng).objects]
                        for _ in range(300)])
    assert np.allclose(heights.mean(axis=0), scenes.FLAME_HEIGHT_MEAN_MM, atol=0.3)
    assert np.allclose(heights.std(axis=0), scenes.FLAME_HEIGHT_SD_MM, atol=0.2)


def test_flames_fill_any_cameras_field_as_they_fill_the_papers(small_camera):
    """The flame scene's default scale follows the camera's field: each flame's height over the field's height at its
    depth is the paper camera's, on a camera of another field (the small camera's is 0.23 of the paper's)."""
    from lf_flame.optics.camera import PAPER_CAMERA

    def filled(cam):
        return [o["height_mm"] / cam.field_of_view_mm(o["depth_offset_mm"])[0]
                for o in scenes.flame_scene(cam, np.random.default_rng(0), vary=False).objects]
    assert small_camera.field_of_view_mm(0.0)[0] < 0.5 * PAPER_CAMERA.field_of_view_mm(0.0)[0]
    np.testing.assert_allclose(filled(small_camera), filled(PAPER_CAMERA), rtol=1e-9)
    assert max(filled(PAPER_CAMERA)) < 0.9


def test_kernel_chain_matches_numpy_abcd_chain_to_1e12(small_camera):
    """The kernel's per-ray chain against explicit RayTransferMatrix products, random rays."""
    from lf_flame.simulate import _kernels as _simulate_kernels
    cam = small_camera
    rng = np.random.default_rng(0)
    n = 10_000
    y_s = rng.uniform(-2, 2, n)
    y_c = rng.uniform(-2, 2, n)
    y_l = y_c + rng.uniform(-0.06, 0.06, n)
    chain = simulate.backward_chain(cam)
    got = _simulate_kernels.trace_rays(y_s, y_l, y_c, *(m.matrix for m in chain))
    gap, lenslet_inv, mla_to_lens, lens_inv = chain
    t0 = (y_l - gap.A * y_s) / gap.B
    y1, t1 = gap.apply(y_s, t0)
    _, t2 = lenslet_inv.apply(y1 - y_c, t1)
    y_m, t_m = mla_to_lens.apply(y1, t2)
    y_o, t_o = lens_inv.apply(y_m, t_m)
    assert np.allclose(y1, y_l, rtol=0, atol=1e-12)
    for a, b in zip(got, (y_m, t_m, y_o, t_o)):
        assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b)))


def test_affine_coefficients_reproduce_the_chain(small_camera):
    """K[q, 0] + K[q, 1] du + K[q, 2] da + K[q, 3] o equals the traced ray (float64)."""
    from lf_flame.simulate import _kernels as _simulate_kernels
    cam, n = small_camera, small_camera.pixels_per_lenslet
    chain = [m.matrix for m in simulate.backward_chain(cam)]
    z = np.array([cam.object_distance_mm(10.0)])
    K = _simulate_kernels.axis_coefficients(cam.n_rows, n, cam.mla_pitch_mm, cam.pixel_pitch_mm, 1.0, *chain, z,
                                   np.array([3.0]), np.array([-2.0]))
    rng = np.random.default_rng(1)
    i = rng.integers(0, cam.n_rows * n, 1000)
    du, da = rng.uniform(-0.5, 0.5, 1000), rng.uniform(-1.5, 1.5, 1000)
    o = np.floor(da + 0.5)
    y_s = (i + 0.5 - cam.n_rows * n / 2) * cam.pixel_pitch_mm + du * cam.pixel_pitch_mm
    y_c = (i // n + 0.5 - cam.n_rows / 2) * cam.mla_pitch_mm
    y_m, t_m, y_o, t_o = _simulate_kernels.trace_rays(y_s, y_c + da * cam.mla_pitch_mm, y_c + o * cam.mla_pitch_mm,
                                                      *chain)
    affine = lambda q: K[q, 0, i] + K[q, 1, i] * du + K[q, 2, i] * da + K[q, 3, i] * o  # noqa: E731
    assert np.allclose(affine(0), y_m, rtol=0, atol=1e-12)
    assert np.allclose(affine(1), t_m, rtol=0, atol=1e-12)
    assert np.allclose(affine(2), 3.0 - 2.0 * (y_o - z[0] * t_o), rtol=0, atol=1e-11)


@pytest.mark.parametrize("name,crosstalk", [("shapes", False), ("flame", False), ("shapes", True)])
def test_kernel_render_matches_numpy_reference(small_camera, name, crosstalk):
    cam = small_camera
    sc = scenes.SCENES[name](cam, np.random.default_rng(5))
    sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, crosstalk=crosstalk))
    fast = simulate.render(cam, sc, 4, seed=2)
    ref = np.clip(simulate.render_reference(cam, sc, 4, seed=2), 0, 1)
    diff = np.abs(fast - ref)
    # float32 affine maps vs the float64 chain: only rays within ~1e-4 texel of a texel
    # border may pick the other texel
    assert np.mean(diff > 1e-5) < 1e-3
    assert abs(fast.mean() - ref.mean()) < 1e-4


def test_content_culling_is_exact(small_camera):
    """Skipping rays that cannot reach a layer's content changes no pixel."""
    from lf_flame.simulate import _kernels as _simulate_kernels
    cam = small_camera
    sc = scenes.shapes_scene(cam, np.random.default_rng(2))
    layers, z, rad, alpha = simulate._stack_layers(cam, sc)
    ky, kx = simulate.trace_coefficients(cam, layers, z)
    box = simulate.content_box(rad, alpha)
    full = np.array([[0, rad.shape[1], 0, rad.shape[2]]] * len(layers))
    assert np.all(box[:, 1] - box[:, 0] < rad.shape[1])  # culling has something to skip
    outs = []
    for b in (box, full):
        out = np.empty(cam.sensor_shape, np.float32)
        _simulate_kernels.render_backward(ky, kx, cam.pixels_per_lenslet, rad, alpha, b, True, 38.9, True, 1, 4, 0, out,
                                          False, np.zeros((1, 1)), np.zeros((1, 1)), False, *simulate.NO_TABLE)
        outs.append(out)
    assert np.array_equal(*outs)


def test_crosstalk_needs_a_faster_main_lens(small_camera):
    """f-number matched: the aperture stops all light through neighbouring lenslets;
    a main lens 1.5x wider lets an in-focus point's light into the neighbours' blocks."""
    n = small_camera.pixels_per_lenslet
    for aperture_scale, leaks in ((1.0, False), (1.5, True)):
        cam = dataclasses.replace(small_camera, aperture_mm=small_camera.aperture_diameter_mm * aperture_scale)
        pt = scenes.point_scene(cam, 0.0)
        blocks = {}
        for xt in (False, True):
            raw = _render(cam, pt, rpp=64, crosstalk=xt)
            blocks[xt] = raw.reshape(cam.n_rows, n, cam.n_cols, n).sum(axis=(1, 3))
        assert np.count_nonzero(blocks[False]) == 1
        assert (np.count_nonzero(blocks[True]) > 1) == leaks
        if not leaks:  # same light, other samples: equal within Monte-Carlo noise
            assert abs(blocks[True].sum() / blocks[False].sum() - 1) < 0.15


def test_bench_sim_quick_writes_results(tmp_path):
    """`make bench-sim` in miniature: every section present, error falls with rays per pixel."""
    import importlib.util
    import pathlib

    import pandas as pd
    path = pathlib.Path(__file__).parents[1] / "experiments" / "bench_sim.py"
    spec = importlib.util.spec_from_file_location("bench_sim", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.main(["--quick", "--out", str(tmp_path)])
    df = pd.read_csv(tmp_path / "bench_sim.csv")
    assert set(df.section) == {"throughput", "effects", "sampling", "forward vs backward"}
    for scene in ("shapes", "flame"):
        rmse = df[(df.section == "sampling") & (df.scene == scene)].sort_values("rays_per_pixel").rmse.to_numpy()
        assert np.all(np.diff(rmse) < 0)
    fb = df[df.section == "forward vs backward"]
    assert fb.rmse.notna().all() and (tmp_path / "bench_sim.md").exists() and (tmp_path / "bench_sim.json").exists()
