"""The exact operator (lf_flame.tomo.exact): its adjoint, its agreement with the traced
operator within that operator's own Monte-Carlo noise, and its convolution structure."""
import numpy as np
import pylops
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.simulate import scenes
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.operator import EmissionOperator
from lf_flame.tomo.solvers import reconstruct
from lf_flame.tomo.truth import scene_truth

PAPER_DEPTHS = (20.0, 10.0, 0.0, -10.0)
OTHER_DEPTHS = (-25.0, -4.0, 6.0, 33.0)
#: Rays per pixel of the traced reference in the tests: the test stays seconds; its
#: Monte-Carlo noise is measured in the test (two seeds), and the exact operator must sit
#: within it. ``experiments/exact_operator.py`` repeats this at 1,024+ rays on the paper's camera.
RAYS = 128


@pytest.fixture(scope="module")
def camera():
    """The paper's optics, 30 x 20 lenslets of 15 x 15 pixels."""
    return PlenopticCamera(n_rows=30, n_cols=20)


@pytest.fixture(scope="module")
def exact(camera):
    return ExactOperator(camera, PAPER_DEPTHS + OTHER_DEPTHS)


@pytest.mark.parametrize("depths", [PAPER_DEPTHS, OTHER_DEPTHS, (35.0,)], ids=["paper", "others", "one"])
def test_the_adjoint_passes_the_dot_test(camera, depths):
    op = ExactOperator(camera, depths)
    np.random.seed(0)   # dottest draws from numpy's global generator
    assert pylops.utils.dottest(op, *op.shape, rtol=1e-10, raiseerror=False)
    assert op.dims == (len(depths), camera.n_rows, camera.n_cols)
    assert op.dimsd == EmissionOperator(camera, depths, rays_per_pixel=1).dimsd


def _emissions(op, camera):
    """Per plane: impulses (interior and at the border) and the paper's flames (their truth on
    the operator's grid, the four flames reused at the other depths)."""
    P, gr, gc = op.dims
    imp = np.zeros((gr, gc))
    imp[[3, 12, 20, 27, 0, gr - 1], [4, 10, 15, 7, 9, gc - 1]] = 1.0
    paper = scenes.flame_scene(camera, np.random.default_rng(2), regime="paper")
    flames = scene_truth(paper, EmissionOperator(camera, PAPER_DEPTHS, rays_per_pixel=1))
    return {"impulses": [imp] * P, "flames": [flames[k % 4] for k in range(P)]}


@pytest.fixture(scope="module")
def traced_light_fields(camera, exact):
    """For each emission and plane: the exact light field and two traced ones (seeds 1 and 2)."""
    ops = [EmissionOperator(camera, exact.depths_mm, rays_per_pixel=RAYS, seed=s, ray_table=False) for s in (1, 2)]
    out = {}
    for name, planes in _emissions(exact, camera).items():
        for k, plane in enumerate(planes):
            x = np.zeros(exact.dims)
            x[k] = plane
            out[name, k] = exact.matvec(x.ravel()), [o.matvec(x.ravel()) for o in ops]
    return out


@pytest.mark.parametrize("name", ["impulses", "flames"])
@pytest.mark.parametrize("k", range(len(PAPER_DEPTHS + OTHER_DEPTHS)),
                         ids=[f"{d:+g}mm" for d in PAPER_DEPTHS + OTHER_DEPTHS])
def test_the_exact_light_field_is_the_traced_one_within_its_noise(traced_light_fields, name, k):
    """||A_exact x - A_s1 x|| against the traced operator's own noise, ||A_s1 x - A_s2 x|| / sqrt 2.

    If the exact operator is the map the traced one estimates, the ratio is 1 up to the
    sampling of the noise itself (the pixels' ray shifts are independent: over tens of
    thousands of pixels the ratio's spread is ~1 %); a bias b adds sqrt(1 + b^2 / noise^2).
    1.1 admits a bias of at most 0.46 x the noise, per plane."""
    ye, (y1, y2) = traced_light_fields[name, k]
    noise = np.linalg.norm(y1 - y2) / np.sqrt(2)
    assert noise > 0 and np.linalg.norm(y1) > 0
    ratio = np.linalg.norm(ye - y1) / noise
    assert 0.9 < ratio < 1.1, f"exact vs traced {ratio:.3f} x the traced noise ({noise / np.linalg.norm(y1):.2e})"
    # the same against the other seed and the two seeds' mean (noise / sqrt 2): no bias hides in one draw
    assert np.linalg.norm(ye - (y1 + y2) / 2) / (noise / np.sqrt(2)) < 1.1


def test_the_cos4_drift_across_the_field_is_the_traced_one(camera):
    """Without the aperture, a uniform plane at focus: every pixel reads one texel, so the traced
    noise is only cos^4's spread within a pixel (~1e-4 per pixel at 32 rays), and the field's cos^4 drift (~1e-3 on
    this small camera) is the signal: exact within 1.1 x the traced noise, pixel by pixel in norm."""
    fx = scenes.Effects(aperture=False, cos4=True, occlusion=False)
    exact = ExactOperator(camera, (0.0,), effects=fx)
    x = np.ones(exact.shape[1])
    ye = exact.matvec(x)
    y1, y2 = (EmissionOperator(camera, (0.0,), effects=fx, rays_per_pixel=32, seed=s, ray_table=False).matvec(x)
              for s in (1, 2))
    noise = np.linalg.norm(y1 - y2) / np.sqrt(2)
    assert np.linalg.norm(ye - y1) < 1.1 * noise
    assert np.ptp(exact.weights) > 20 * noise / np.sqrt(y1.size)     # the drift is far above the per-pixel noise


def test_shifting_the_emission_by_one_sample_shifts_every_view_by_one_lenslet(exact):
    """The map is a convolution over lenslets times the per-pixel cos^4 weight: away from the
    borders (farther than the largest kernel offset), A(x shifted) / w is A(x) / w shifted."""
    P, gr, gc = exact.dims
    rng = np.random.default_rng(5)
    x = np.zeros(exact.dims)
    x[:, 8:22, 6:14] = rng.random((P, 14, 8))
    w = exact.weights
    seen = w > 0
    for axis, (dr, dc) in ((1, (1, 0)), (2, (0, 1))):
        y0 = exact.matvec(x.ravel()).reshape(exact.dimsd)
        y1 = exact.matvec(np.roll(x, 1, axis=axis).ravel()).reshape(exact.dimsd)
        a = np.where(seen, y1 / np.where(seen, w, 1), 0)[:, :, dr:, dc:]
        b = np.where(seen, y0 / np.where(seen, w, 1), 0)[:, :, :gr - dr, :gc - dc]
        assert b.max() > 0.1
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * b.max())
        # and the weight itself is what makes A not shift-invariant: cos^4 drifts across the field
        assert 1e-3 < np.ptp(w[seen]) < 0.05


def test_the_kernels_have_converged_in_the_quadrature(camera):
    """6 Gauss-Legendre nodes per smooth piece (the default) against 32: no tap off by more than
    1e-4 of the largest, 1e-5 of the kernels' sum in all (measured: 5.8e-5 and 5.6e-6; 4 nodes:
    2.0e-4 and 2.3e-5), far below the traced operator's noise at 1,024 rays (~1e-3)."""
    a = ExactOperator(camera, (20.0, -10.0), quadrature_nodes=6).kernels
    b = ExactOperator(camera, (20.0, -10.0), quadrature_nodes=32).kernels
    assert np.abs(a - b).max() < 1e-4 * b.max()
    assert np.abs(a - b).sum() < 1e-5 * b.sum()


def test_float32_is_float64_to_its_packed_spectra(camera):
    """float32 keeps the spectra in 16-bit fixed point (a quarter of complex128's memory): A and A^T
    within 2e-5 of float64's (measured 4e-6), each still the other's transpose to float32 rounding."""
    op64 = ExactOperator(camera, PAPER_DEPTHS)
    op32 = ExactOperator(camera, PAPER_DEPTHS, precision="float32")
    assert op32._spec.nbytes * 4 < op64._spec.nbytes * 1.01
    x = np.random.default_rng(0).random(op64.shape[1])
    y = np.random.default_rng(1).random(op64.shape[0])
    for f, g in ((op64.matvec(x), op32.matvec(x)), (op64.rmatvec(y), op32.rmatvec(y))):
        assert np.linalg.norm(f - g) < 2e-5 * np.linalg.norm(f)
    assert abs(np.dot(op32.matvec(x), y) - np.dot(x, op32.rmatvec(y))) < 1e-6 * np.dot(op64.matvec(x), y)


@pytest.mark.parametrize("depths, subsamples, precision", [
    (PAPER_DEPTHS, 1, "float64"), (OTHER_DEPTHS, 1, "float32"), ((35.0,), 1, "float64"), ((15.0, -5.0), 2, "float32")],
    ids=["paper", "others-float32", "one-far", "finer-float32"])
def test_the_taps_apply_the_map_the_spectra_give(camera, depths, subsamples, precision, monkeypatch):
    """H and H^H on the canvas by direct sums over the taps (the kernels' rows padded to fours, tap origins of
    both signs, planes far from focus whose taps wrap around the canvas; in float32 the views whose kernels
    separate filtered by rows and columns, the clipped ones whole) are the spectra's circular correlation:
    to float64 rounding with complex128 spectra, to their 16-bit fixed point in float32; the adjoint of a window
    smaller than the canvas is that of the window zero-padded."""
    import lf_flame.tomo.exact as exact_module
    op = ExactOperator(camera, depths, subsamples=subsamples, precision=precision)
    rng = np.random.default_rng(5)
    x = rng.standard_normal((op.phase_dims[0],) + op.canvas_shape).astype(op._real)
    z = rng.standard_normal((len(op._lit),) + op.canvas_shape).astype(op._real)
    R, C = op.view_dims[2:]
    window = z[:, :R, :C].copy()
    padded = np.zeros_like(z)
    padded[:, :R, :C] = window
    got = {}
    for route, limit in (("taps", np.inf), ("fft", -1)):
        monkeypatch.setattr(exact_module, "TAPS_FORWARD_MAX", limit)
        monkeypatch.setattr(exact_module, "TAPS_ADJOINT_MAX", limit)
        monkeypatch.setattr(exact_module, "TAPS_MIN_COLUMNS", 0)
        got[route] = (op.forward_canvas(x), op.adjoint_canvas(z), op.adjoint_canvas(window), op.adjoint_canvas(padded),
                      np.fft.irfft2(op.adjoint_spectrum(z), s=op.canvas_shape))
    tol = 1e-12 if precision == "float64" else 3e-5
    plan = op._taps()
    if precision == "float32":                                   # both kinds of view: whole kernels, separated
        assert len(plan.rows) and len(plan.rows_s)
    for a, b in zip(got["taps"], got["fft"]):
        assert np.abs(a - b).max() < tol * np.abs(b).max()
    assert np.abs(got["taps"][2] - got["taps"][3]).max() < tol * np.abs(got["taps"][3]).max()
    assert got["taps"][0].dtype == got["taps"][1].dtype == op._real


def test_the_solvers_take_it(camera):
    """FISTA on the exact operator recovers a planted emission from its own data (no inverse
    crime intended: this checks only that the solvers accept the operator unchanged)."""
    op = ExactOperator(camera, (20.0, -10.0))
    x = np.zeros(op.dims)
    x[0, 5:12, 4:8] = 0.8
    x[1, 14:24, 9:15] = 0.5
    rec = reconstruct(op.matvec(x.ravel()).reshape(op.dimsd), op, "fista", 60)
    assert rec.residuals[-1] < 0.05 * rec.residuals[0]
    assert np.linalg.norm(rec.planes - x) < 0.2 * np.linalg.norm(x)
    assert rec.settings["rays_per_pixel"] is None
    adj = reconstruct(op.matvec(x.ravel()).reshape(op.dimsd), op, "adjoint")
    assert adj.planes.shape == op.dims


def test_bad_input_is_refused(camera):
    with pytest.raises(ValueError, match="crosstalk"):
        ExactOperator(camera, (0.0,), effects=scenes.Effects(occlusion=False, crosstalk=True))
    with pytest.raises(ValueError, match="occlusion"):
        ExactOperator(camera, (0.0,), effects=scenes.Effects(occlusion=True))
    with pytest.raises(ValueError, match="perfect lenslet grid"):
        ExactOperator(PlenopticCamera(n_rows=24, n_cols=16, pixels_per_lenslet=5, grid_rotation_deg=0.5), (0.0,))
    with pytest.raises(ValueError, match="empty"):
        ExactOperator(camera, [])
    with pytest.raises(ValueError, match="precision"):
        ExactOperator(camera, (0.0,), precision="float16")
    with pytest.raises(ValueError, match="margin"):
        ExactOperator(camera, (0.0,), margin=1.01)
    with pytest.raises(ValueError, match="focal length"):
        ExactOperator(camera, (-camera.focus_distance_mm + 1.0,))
    with pytest.raises(ValueError, match=r"planes at \+0 mm are given more than once"):
        ExactOperator(camera, (0.0, 0.0, 10.0))          # two identical planes: their emission cannot be shared out


# ---- a finer grid than the lenslets (subsamples) ---------------------------------------------
def test_a_finer_grid_is_the_traced_operator_on_that_grid(camera):
    """``subsamples=2``: the exact map from a grid of 2 x 2 samples per lenslet footprint is the
    traced operator on the same grid (``grid_shape``) within that operator's noise, per plane,
    and its adjoint passes the dot test."""
    op = ExactOperator(camera, PAPER_DEPTHS, subsamples=2)
    assert op.dims == (4, 2 * camera.n_rows, 2 * camera.n_cols) and op.phase_dims == (16, camera.n_rows, camera.n_cols)
    np.random.seed(0)
    assert pylops.utils.dottest(op, *op.shape, rtol=1e-10, raiseerror=False)
    traced = [EmissionOperator(camera, PAPER_DEPTHS, grid_shape=op.dims[1:], rays_per_pixel=RAYS, seed=s,
                               ray_table=False) for s in (1, 2)]
    flames = scene_truth(scenes.flame_scene(camera, np.random.default_rng(2), regime="paper"), op)
    for k in range(4):
        x = np.zeros(op.dims)
        x[k] = flames[k]
        ye, y1, y2 = op.matvec(x.ravel()), traced[0].matvec(x.ravel()), traced[1].matvec(x.ravel())
        noise = np.linalg.norm(y1 - y2) / np.sqrt(2)
        assert 0.9 < np.linalg.norm(ye - y1) / noise < 1.1, k


def test_phases_round_trip_and_keep_the_lenslet_grid(camera):
    op = ExactOperator(camera, (10.0,), subsamples=2)
    x = np.random.default_rng(0).random(op.dims)
    np.testing.assert_array_equal(op.from_phases(op.to_phases(x)), x)
    np.testing.assert_array_equal(op.to_phases(x)[1], x[0, 0::2, 1::2])      # phase (0, 1) of plane 0
    # equal phases are the lenslet grid's texels: the same views as the plain operator, to the
    # quadrature's accuracy (its pieces split at the finer grid's boundaries too; test above: 5.6e-6)
    coarse = ExactOperator(camera, (10.0,))
    xc = np.random.default_rng(1).random(coarse.dims)
    xf = np.repeat(np.repeat(xc, 2, axis=1), 2, axis=2)
    yc = coarse.matvec(xc.ravel())
    assert np.linalg.norm(op.matvec(xf.ravel()) - yc) < 1e-5 * np.linalg.norm(yc)
    with pytest.raises(ValueError, match="subsamples"):
        ExactOperator(camera, (10.0,), subsamples=0)


def test_the_binned_operator_is_the_lenslet_grids(camera):
    """A finer operator binned to the lenslets (its phase kernels summed) is the plain operator to the
    quadrature's accuracy, both ways, with its own exact adjoint and per-frequency matrices."""
    depths = (15.0, -5.0)
    fine = ExactOperator(camera, depths, subsamples=2)
    coarse, plain = fine.binned(), ExactOperator(camera, depths)
    assert coarse.subsamples == 1 and coarse.dims == plain.dims and coarse.binned() is coarse
    rng = np.random.default_rng(2)
    x, y = rng.random(plain.dims).ravel(), rng.random(plain.dimsd).ravel()
    for a, b in ((coarse.matvec(x), plain.matvec(x)), (coarse.rmatvec(y), plain.rmatvec(y))):
        assert np.linalg.norm(a - b) < 1e-4 * np.linalg.norm(b)   # the quadrature's accuracy (1.8e-5 here)
    np.random.seed(0)   # dottest draws from numpy's global generator
    assert pylops.utils.dottest(coarse, *coarse.shape, rtol=1e-10, raiseerror=False)
    from lf_flame.tomo.fourier_system import normal_matrices
    G, G0 = normal_matrices(coarse), normal_matrices(plain)
    low = np.tril_indices(len(depths))
    assert np.abs(G[low] - G0[low]).max() < 1e-4 * np.abs(G0[low]).max()


def test_a_finer_grid_resolves_what_the_lenslet_grid_aliases():
    """Emission with detail finer than a lenslet (stripes of 1.3 lenslets), off focus, rendered by
    the tracer: its light field carries that detail in the views' parallax, so the solve on a
    2 x 2 grid, binned back to the lenslets, is nearer the truth than the solve on the lenslet
    grid (measured 0.058 / 0.071 against 0.102 / 0.106 per plane at these settings)."""
    from lf_flame.refocus.shift_and_sum import raw_to_views
    from lf_flame.simulate.scenes import FLAME_EFFECTS, _layer_grid
    from lf_flame.simulate.layers import Layer, Scene
    from lf_flame.simulate.tracer import render
    from lf_flame.tomo.fourier import solve_admm
    cam = PlenopticCamera(n_rows=32, n_cols=32)
    layers = []
    for dz, off in ((10.0, -0.6), (-10.0, 0.6)):
        y, x, size, _ = _layer_grid(cam, dz, 4.0, 1.0)
        h = size[0]
        r2 = ((y - off * h / 4) ** 2 + (x + off * h / 5) ** 2) / (0.15 * h) ** 2
        rad = 0.6 * np.exp(-r2) * (1 + 0.5 * np.cos(2 * np.pi * x / (1.3 * h / cam.n_rows)))
        layers.append(Layer(rad.astype(np.float32), None, dz, (0.0, 0.0), size))
    scene = Scene("stripes", tuple(layers), FLAME_EFFECTS)
    views = raw_to_views(render(cam, scene, 256, 1), cam.pixels_per_lenslet)
    coarse = ExactOperator(cam, (10.0, -10.0), precision="float32")
    fine = ExactOperator(cam, (10.0, -10.0), precision="float32", subsamples=2)
    truth = scene_truth(scene, coarse)
    xc = solve_admm(views, coarse, views < 1, fills=10, tv=0.0, lam=0.003)[0]
    xf = solve_admm(views, fine, views < 1, fills=10, tv=0.0, lam=0.003)[0].reshape(2, 32, 2, 32, 2).mean(axis=(2, 4))
    err = [np.linalg.norm(x - truth, axis=(1, 2)) / np.linalg.norm(truth, axis=(1, 2)) for x in (xc, xf)]
    assert np.all(err[1] < 0.8 * err[0]), err


def test_cos4_mean_is_the_second_order_mean_over_the_angles():
    """The per-pixel cos^4 drift's moment expansion: the mean of 1 / (1 + ty^2 + tx^2)^2 over Gaussian angles of
    a given mean and covariance, within the expansion's fourth-order error, where its value at the mean is off."""
    from lf_flame.tomo._exact_kernels import cos4_mean
    mean, cov = np.array([0.5, -0.3]), np.array([[0.006, 0.002], [0.002, 0.004]])
    t = np.random.default_rng(0).multivariate_normal(mean, cov, 4_000_000)
    mc = float(np.mean((1.0 + t[:, 0] ** 2 + t[:, 1] ** 2) ** -2))       # Monte-Carlo error ~1e-5
    got = float(cos4_mean(mean[0], mean[1], cov[0, 0], cov[0, 1], cov[1, 1]))
    at_mean = float((1.0 + mean @ mean) ** -2)
    assert abs(got / mc - 1) < 3e-4 and abs(at_mean / mc - 1) > 5e-3, (got, mc, at_mean)


def test_the_disc_clip_is_the_area_and_centroid_a_fine_grid_counts():
    """The quadrature's aperture clip (the closed-form corners, each edge's terms computed once): a rectangle's
    share inside the disc and its centroid's offset, against the midpoints of a 1,200 x 1,200 grid, for
    rectangles in every quadrant, across the axes, crossing the rim, and wholly inside or outside."""
    from lf_flame.tomo._exact_kernels import N_EDGE_TERMS, _clip_by_terms, _edge_terms

    def _clip_to_disc(y0, y1, x0, x1, r):                             # as kernel_quadrature clips one pair
        if max(y0 * y0, y1 * y1) + max(x0 * x0, x1 * x1) <= r * r:
            return 1.0, 0.0, 0.0
        t = np.empty((4, N_EDGE_TERMS))
        for row, e in zip(t, (y0, y1, x0, x1)):
            _edge_terms(e, r, row)
        return _clip_by_terms(y0, y1, x0, x1, *t, r)

    r, n = 2.0, 1200
    rng = np.random.default_rng(5)
    rects = [(-2.5, -1.0, 0.5, 1.9), (1.2, 1.9, -1.9, -0.8), (-1.9, -1.2, -1.9, -1.0), (-0.4, 0.6, 1.1, 2.3),
             (-2.1, 2.1, -0.3, 0.2), (-0.5, 0.5, -0.5, 0.5), (2.1, 2.4, 0.1, 0.3)]
    for _ in range(30):
        y0, x0 = rng.uniform(-2.4, 2.2, 2)
        rects.append((y0, y0 + rng.uniform(0.05, 1.5), x0, x0 + rng.uniform(0.05, 1.5)))
    for y0, y1, x0, x1 in rects:
        yy = y0 + (np.arange(n) + 0.5) * (y1 - y0) / n
        xx = x0 + (np.arange(n) + 0.5) * (x1 - x0) / n
        inside = yy[:, None] ** 2 + xx[None, :] ** 2 <= r * r
        frac, dy, dx = _clip_to_disc(y0, y1, x0, x1, r)
        assert abs(frac - inside.mean()) < 3e-3, (y0, y1, x0, x1, frac, inside.mean())
        if inside.mean() > 0.02:
            cy = (inside * yy[:, None]).sum() / inside.sum() - 0.5 * (y0 + y1)
            cx = (inside * xx[None, :]).sum() / inside.sum() - 0.5 * (x0 + x1)
            assert abs(dy - cy) < 3e-3 * (y1 - y0) + 1e-9 and abs(dx - cx) < 3e-3 * (x1 - x0) + 1e-9, \
                (y0, y1, x0, x1, dy, cy, dx, cx)


# ---- samples off the views' grid (a colour capture's nearest pixels) ---------------------------
def _offsets(camera, value):
    N = camera.pixels_per_lenslet
    return np.broadcast_to(np.asarray(value, np.float64), (N, N, camera.n_rows, camera.n_cols, 2)).copy()


def test_a_sample_off_its_view_is_the_finer_cameras_pixels_there():
    """A pixel moved by a third of a view step is the mean of the M = 3 times finer camera's pixels one step over:
    the sub-views of ``sample_offsets`` agree with the exact operator of a camera of pixels a third the size (same
    optics) within its quadrature, in both axes' directions (the read-out image runs against the sensor along one
    axis: a sign off there gives 0.27 instead of 3e-5)."""
    N, M = 5, 3
    cam = PlenopticCamera(n_rows=24, n_cols=20, pixels_per_lenslet=N)
    fine = ExactOperator(PlenopticCamera(n_rows=24, n_cols=20, pixels_per_lenslet=N * M), (-6.0, 9.0))
    x = np.random.default_rng(1).random(fine.shape[1])
    yf = (fine @ x).reshape(fine.dimsd)
    for k, shift in ((0, -1), (2, +1), (1, 0)):
        d = (k + 0.5) / M - 0.5                                          # the bin's centre: -1/3, +1/3, 0
        for axis in (0, 1):
            off = _offsets(cam, 0.0)
            off[..., axis] = d
            y = (ExactOperator(cam, (-6.0, 9.0), sample_offsets=off, offset_bins=M) @ x).reshape(N, N, 24, 20)
            idx = [np.arange(N)[:, None] * M + np.arange(M)[None, :] + (shift if a == axis else 0) for a in (0, 1)]
            ref = np.array([[yf[np.ix_(idx[0][u], idx[1][v])].mean(axis=(0, 1)) for v in range(1, N - 1)]
                            for u in range(1, N - 1)])
            assert np.linalg.norm(y[1:-1, 1:-1] - ref) < 1e-4 * np.linalg.norm(ref), (k, axis)


def test_sampled_operator_is_a_linear_operator_with_its_adjoint(camera):
    rng = np.random.default_rng(0)
    op = ExactOperator(camera, (-5.0, 8.0), sample_offsets=rng.uniform(-0.5, 0.5, _offsets(camera, 0).shape))
    assert op.view_dims == (45, 45, 30, 20) and op.dimsd == (15, 15, 30, 20) and op.offset_bins == 3
    assert pylops.utils.dottest(op, op.shape[0], op.shape[1], rtol=1e-10)
    plain = ExactOperator(camera, (-5.0, 8.0))
    one = ExactOperator(camera, (-5.0, 8.0), sample_offsets=_offsets(camera, 0.2), offset_bins=1)
    x = rng.random(plain.shape[1])
    assert np.array_equal(plain @ x, one @ x)                            # one bin: every sample at its view's place
    # the coarse start's binned operator keeps the samples' sub-views
    fine = ExactOperator(camera, (-5.0, 8.0), subsamples=2, sample_offsets=_offsets(camera, 0.3))
    xc = rng.random((2, 30, 20))
    assert np.allclose(fine.binned() @ xc.ravel(), fine @ np.repeat(np.repeat(xc, 2, 1), 2, 2).ravel())
    for bad, match in ((_offsets(camera, 0)[:-1], "sample_offsets must be"), (_offsets(camera, 1.5), "within one"),
                       (_offsets(camera, np.nan), "finite")):
        with pytest.raises(ValueError, match=match):
            ExactOperator(camera, (0.0,), sample_offsets=bad)
    with pytest.raises(ValueError, match="offset_bins"):
        ExactOperator(camera, (0.0,), sample_offsets=_offsets(camera, 0), offset_bins=0)


def test_admm_runs_more_fills_on_samples_off_the_grid(camera):
    """The fills have most of each sub-view to fill: admm's cap and tolerance there are OFFSET_KNOBS' unless told."""
    from lf_flame.tomo.defaults import OFFSET_KNOBS
    op = ExactOperator(camera, (0.0,), precision="float32", sample_offsets=_offsets(camera, 0.25), offset_bins=3)
    y = op @ np.pad(np.ones((1, 10, 8)), ((0, 0), (10, 10), (6, 6))).ravel()
    rec = reconstruct(y.reshape(op.dimsd), op, "admm")
    assert rec.settings["iters"] == OFFSET_KNOBS["fills"] and rec.settings["tol"] == OFFSET_KNOBS["tol"]
    assert reconstruct(y.reshape(op.dimsd), op, "admm", 3).settings["iters"] == 3


def test_sub_views_only_where_the_planes_parallax_calls_for_them(camera):
    """A sample up to half a step off its view sees a plane of slope ``s`` up to ``|s| / 2`` lenslets off: whole
    views where that is within OFFSET_TOLERANCE on every plane, OFFSET_BINS sub-views (or the cap) elsewhere."""
    from lf_flame.tomo.exact import OFFSET_BINS, OFFSET_TOLERANCE, offset_bins_for
    for d in (0.0, 0.5, 1.0, 2.0, 10.0):
        near = abs(camera.slope_for_depth(d)) / 2 <= OFFSET_TOLERANCE
        assert offset_bins_for(camera, (0.0, d)) == (1 if near else OFFSET_BINS)
        assert offset_bins_for(camera, (d,), cap=2) == (1 if near else 2)
    assert offset_bins_for(camera, (0.0,)) == 1 and offset_bins_for(camera, (-1.0, 10.0)) == OFFSET_BINS
    assert offset_bins_for(camera, (0.5,)) == 1 and offset_bins_for(camera, (1.0,)) == OFFSET_BINS    # 0.06, 0.12
    at_focus = ExactOperator(camera, (0.0,), sample_offsets=_offsets(camera, 0.4))
    assert at_focus.offset_bins is None and at_focus.view_dims == at_focus.dimsd
