"""The Fourier ADMM solver on the exact operator (lf_flame.tomo.fourier): its kernels, the
missing data (window, saturated pixels), its planted recovery, and its refusals."""
import copy
import math

import numpy as np
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.tomo import _fourier_kernels as K
from lf_flame.tomo import noise_knobs as knobs_mod
from lf_flame.tomo import fourier, fourier_system
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.operator import EmissionOperator
from lf_flame.tomo.solvers import reconstruct

DEPTHS = (20.0, 10.0, 0.0, -10.0)


@pytest.fixture(scope="module")
def camera():
    """The paper's optics, 40 x 24 lenslets of 15 x 15 pixels."""
    return PlenopticCamera(n_rows=40, n_cols=24)


@pytest.fixture(scope="module")
def op(camera):
    return ExactOperator(camera, DEPTHS)


@pytest.fixture(scope="module")
def planted(op):
    """Smooth non-negative blobs on every plane, some near the window's edge (their light leaves
    the sensor), and their exact light field."""
    P, R, C = op.dims
    yy, xx = np.mgrid[0:R, 0:C]
    rng = np.random.default_rng(5)
    x = np.zeros(op.dims)
    for k in range(P):
        for _ in range(3):
            cy, cx = rng.uniform(2, R - 2), rng.uniform(2, C - 2)
            x[k] += rng.uniform(0.3, 1.0) * np.exp(-((yy - cy) ** 2 + (xx - cx) ** 2) / (2 * rng.uniform(1.5, 4) ** 2))
    return x, op.matvec(x.ravel()).reshape(op.dimsd)


def rel(a, b):
    return np.linalg.norm((a - b).reshape(len(b), -1), axis=1) / np.linalg.norm(b.reshape(len(b), -1), axis=1)


def test_the_numba_sums_are_the_einsums(op):
    S = fourier_system.fourier_system(op).spec
    rng = np.random.default_rng(0)
    xs = rng.normal(size=S.shape[1:]) + 1j * rng.normal(size=S.shape[1:])
    ys = rng.normal(size=(S.shape[0],) + S.shape[2:]) + 1j * rng.normal(size=(S.shape[0],) + S.shape[2:])
    np.testing.assert_allclose(K.spectra_forward(S, xs), np.einsum("vkrf,krf->vrf", S, xs), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(K.spectra_adjoint(S, ys), np.einsum("vkrf,vrf->krf", S.conj(), ys), rtol=1e-10,
                               atol=1e-10)


def test_the_packed_spectra_are_the_complex_ones_to_16_bits(op):
    """PackedSpectra (the float32 operator's storage): each view and plane's parts to 1/32767 of its largest,
    the products as the complex einsums to that, a spectrum of zeros packed as zeros (no division by its
    scale), and binning the phases the sum of the unpacked ones."""
    S = op._spec.astype(np.complex64)
    S[3, 1] = 0                                                      # a plane this view does not see
    packed = K.PackedSpectra(S.shape)
    with np.errstate(all="raise"):                                   # no 0 / 0 for the plane of zeros
        for i in range(len(S)):
            packed.put(i, S[i])
    assert packed.nbytes < S.nbytes / 1.9 and len(packed) == len(S)
    s = S.reshape(len(S), S.shape[1], -1)                            # the kernel packs as NumPy's float32 formula
    scale = np.maximum(np.abs(s.real).max(axis=2), np.abs(s.imag).max(axis=2))
    scale = np.where(scale > 0, scale / 32767.0, 1.0).astype(np.float32)
    with np.errstate(all="ignore"):
        assert np.array_equal(packed.scale, scale)
        assert np.array_equal(packed.re, np.rint(s.real / scale[..., None]).astype(np.int16))
        assert np.array_equal(packed.im, np.rint(s.imag / scale[..., None]).astype(np.int16))
    top = np.maximum(np.abs(S.real), np.abs(S.imag)).max(axis=(2, 3))
    for i in (0, 3, len(S) - 1):
        err = np.abs(packed.view(i) - S[i]).max(axis=(1, 2))
        assert np.all(err <= top[i] / 32767 * 0.71 + 1e-12)           # half a step per part, both parts
    assert not np.any(packed.view(3)[1]) and np.all(np.isfinite(packed.scale))
    rng = np.random.default_rng(0)
    xs = (rng.normal(size=S.shape[1:]) + 1j * rng.normal(size=S.shape[1:])).astype(np.complex64)
    ys = (rng.normal(size=(S.shape[0],) + S.shape[2:]) + 1j * rng.normal(size=(S.shape[0],) + S.shape[2:]))
    want_f, want_a = np.einsum("vkrf,krf->vrf", S, xs), np.einsum("vkrf,vrf->krf", S.conj(), ys)
    got_f, got_a = K.spectra_forward(packed, xs), K.spectra_adjoint(packed, ys)
    assert got_f.dtype == got_a.dtype == np.complex64
    assert np.linalg.norm(got_f - want_f) < 3e-5 * np.linalg.norm(want_f)
    assert np.linalg.norm(got_a - want_a) < 3e-5 * np.linalg.norm(want_a)
    binned = packed.binned(2)
    want = np.stack([packed.view(i) for i in range(len(S))]).reshape(len(S), -1, 2, *S.shape[2:]).sum(axis=2)
    assert binned.shape == (len(S), S.shape[1] // 2) + S.shape[2:]
    np.testing.assert_allclose(np.stack([binned.view(i) for i in range(len(S))]), want, rtol=0,
                               atol=2e-4 * np.abs(want).max())
    ref = K.PackedSpectra(binned.shape)                              # the one-pass kernel packs as put packs
    for i in range(len(S)):
        ref.put(i, want[i])
    assert all(np.array_equal(getattr(binned, k), getattr(ref, k)) for k in ("re", "im", "scale"))


_SUMS_SCRIPT = """
import sys
import numpy as np
from lf_flame.tomo import _fourier_kernels as K
rng = np.random.default_rng(0)
V, P, M = 40, 8, 3000
re, im = (rng.integers(-32767, 32767, (V, P, M)).astype(np.int16) for _ in range(2))
scale = rng.random((V, P)).astype(np.float32)
ys = (rng.normal(size=(V, M)) + 1j * rng.normal(size=(V, M))).astype(np.complex64)
adj = np.empty((P, M), np.complex64)
K.adjoint_packed(re, im, scale, ys, adj, 2)
xs = rng.normal(size=(2, P, M)).astype(np.float32)
fwd = np.empty((V, M), np.complex64)
K.forward_packed(re, im, scale, xs[0], xs[1], fwd)
np.savez(sys.argv[1], adj=adj, fwd=fwd)
"""


def test_the_sums_are_the_same_compiled_here_or_loaded_from_numbas_cache(tmp_path):
    """The spectra's sums give the same numbers to the bit in a process that compiles them and in one that loads
    them from Numba's cache (a fresh cache directory, the same script run twice): with reassociating fast-math a
    parallel kernel's two builds sum in different orders (0.69 apart in adjoint_packed's sums)."""
    import os
    import subprocess
    import sys
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    outs = [tmp_path / f"sums_{i}.npz" for i in range(2)]
    for out in outs:                                                  # the first compiles and caches, the second loads
        subprocess.run([sys.executable, "-c", _SUMS_SCRIPT, str(out)], env=env, check=True, timeout=300)
    assert any((tmp_path / "numba").rglob("*.nbc"))
    first, second = np.load(outs[0]), np.load(outs[1])
    for k in ("adj", "fwd"):
        assert np.array_equal(first[k], second[k]), k


def test_the_data_gather_and_the_fill_are_the_array_formulas():
    """gather_data and fill (branch-free kernels) against NumPy: y / w and w^2 on the lit views where fitted
    and seen (0 where a weight is 0 or the pixel is left out), and the fill's residual and written views."""
    rng = np.random.default_rng(3)
    views = rng.random((9, 6, 5))
    fit = rng.random(views.shape) < 0.8
    w_all = (0.9 + 0.2 * rng.random(views.shape)).astype(np.float32)
    w_all[:, 0] = 0                                                  # a row no pixel sees
    lit = np.array([1, 4, 7])
    yt, w2 = (np.empty((3, 6, 5), np.float32) for _ in range(2))
    with np.errstate(all="raise"):
        sq = K.gather_data(views, fit, w_all, lit, yt, w2)
    want_m = fit[lit] & (w_all[lit] > 0)
    w = w_all[lit].astype(np.float64)
    np.testing.assert_allclose(w2, np.where(want_m, w ** 2, 0), rtol=1e-6)
    np.testing.assert_array_equal(w2 > 0, want_m)
    np.testing.assert_allclose(yt, np.where(want_m, views[lit] / np.where(want_m, w, 1), 0), rtol=1e-6)
    assert np.isclose(sq, np.sum(np.where(want_m, views[lit], 0) ** 2), rtol=1e-12)
    z = rng.random((3, 8, 7)).astype(np.float32)
    old = z.copy()
    res = K.fill(z, yt, w2)
    d = np.where(want_m, w * old[:, :6, :5] - views[lit], 0)
    assert np.isclose(res, np.sum(d ** 2), rtol=1e-5)
    np.testing.assert_array_equal(z[:, :6, :5], np.where(want_m, yt, old[:, :6, :5]))
    np.testing.assert_array_equal(z[:, 6:], old[:, 6:])
    np.testing.assert_array_equal(z[:, :, 5:], old[:, :, 5:])


def test_the_fused_admm_steps_are_the_array_formulas():
    """The Numba kernels of the ADMM steps between fills against their NumPy formulas."""
    rng = np.random.default_rng(2)
    s, d, gy, gx, ey, ex, x = rng.normal(size=(7, 3, 9, 8)).astype(np.float32)
    D_T = lambda a, b: (np.roll(a, 1, axis=1) - a) + (np.roll(b, 1, axis=2) - b)   # noqa: E731
    out = np.empty_like(s)
    K.admm_target(s, d, gy, gx, ey, ex, 0.7, out)
    np.testing.assert_allclose(out, s - d + 0.7 * D_T(gy - ey, gx - ex), rtol=1e-5, atol=1e-5)
    support = rng.random((3, 6, 5)) > 0.3
    dd, new = d.copy(), np.empty_like(s)
    K.admm_project(x, dd, 0.1, support, 6, 5, new)
    ref = np.zeros_like(s)
    ref[:, :6, :5] = np.maximum(x[:, :6, :5] + d[:, :6, :5] - 0.1, 0) * support
    np.testing.assert_allclose(new, ref, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(dd, d + x - ref, rtol=1e-6, atol=1e-6)
    vy, vx = np.roll(x, -1, axis=1) - x + ey, np.roll(x, -1, axis=2) - x + ex
    keep = np.maximum(1 - 0.5 / np.hypot(vy, vx), 0)
    K.tv_shrink(x, 0.5, gy, gx, ey, ex)
    np.testing.assert_allclose(gy, keep * vy, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(ex, vx - keep * vx, rtol=1e-5, atol=1e-5)


def _gram(op):
    """``G(f) = H(f)^H H(f)`` the slow way, from the operator's spectra: (Lr, F, P, P)."""
    return np.einsum("vkrf,vlrf->rfkl", op._spec.conj(), op._spec)


def test_the_normal_matrices_from_the_taps_are_those_of_the_spectra(op):
    G = fourier_system.normal_matrices(op)
    ref = _gram(op)
    P = G.shape[0]
    low = np.tril_indices(P)
    np.testing.assert_allclose(G[low[0], low[1]], np.moveaxis(ref[..., low[0], low[1]], -1, 0),
                               rtol=0, atol=1e-9 * np.abs(ref).max())
    # a perfect grid is symmetric under a half turn of the views: the matrices are real
    assert G.dtype == np.float64 and np.abs(ref.imag).max() < 1e-6 * np.abs(ref).max()


def test_the_per_frequency_solve_inverts_the_normal_matrices(op):
    """(G + ...)^-1 applied to H^H H x gives back x (lam, rho -> 0): G is H^H H per frequency."""
    system = fourier_system.FourierSystem(op, lam=0.0, rho=1e-9)
    S = system.spec
    P, Lr, F = S.shape[1:]
    rng = np.random.default_rng(1)
    x = rng.normal(size=(P, Lr, F)) + 1j * rng.normal(size=(P, Lr, F))
    back = system.solve(K.spectra_adjoint(S, K.spectra_forward(S, x)))
    # frequencies where G is well conditioned (the others carry no light to tell planes apart)
    cond = np.linalg.cond(_gram(op))
    good = cond < 1e3
    assert good.mean() > 0.2
    np.testing.assert_allclose(back[:, good], x[:, good], rtol=1e-5, atol=1e-5)


def test_a_matrix_that_is_not_positive_definite_is_refused(op):
    bad = np.ones((2, 2, 3))                                  # rank one: its second pivot is 0
    packed, n_bad = K.factor_packed(bad, np.float64)
    assert n_bad == 3 and np.isnan(bad[1, 1]).all() and np.isnan(packed[0, 0, 2, :3]).all()
    broken = copy.copy(op)
    broken.kernels = op.kernels.copy()
    broken.kernels[0, 0, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="not positive definite"):
        fourier_system.FourierSystem(broken)


def test_planted_emission_is_recovered_and_the_fills_are_what_recover_it(op, planted):
    x, views = planted
    # noise-free data: no TV needed (its bias would be the error measured), more fills than the default
    one = reconstruct(views, op, "admm", 1, tv=0.0, l1=0.0, saturation=None)
    full = reconstruct(views, op, "admm", 8, tv=0.0, l1=0.0, saturation=None)
    assert (full.planes >= 0).all()
    assert rel(full.planes, x).max() < 0.08
    # zero-filled data outside the window (one fill) is far worse: the fills carry the window
    assert rel(one.planes, x).max() > 2 * rel(full.planes, x).max()



def test_the_noise_estimate_and_the_knobs_it_picks(op, planted):
    x, views = planted
    peak = np.percentile(views[6:9, 6:9], 99.9)
    rng = np.random.default_rng(3)
    for sigma in (0.003, 0.03):   # white noise of known deviation on smooth emission: measured within 10 %
        noisy = views + rng.normal(scale=sigma * peak, size=views.shape)
        assert knobs_mod.relative_noise(noisy) == pytest.approx(sigma, rel=0.1)
    assert knobs_mod.relative_noise(views) < 0.5 * knobs_mod.ADMM_QUIET_NOISE      # exact light field: quiet
    assert knobs_mod.relative_noise(np.zeros_like(views)) == 0.0
    # the defaults follow the noise: the quiet knobs on the exact light field, the noisy ones at 3 %
    knobs = knobs_mod.ADMM_KNOBS
    quiet = reconstruct(views, op, "admm", saturation=None).settings
    assert (quiet["iters"], quiet["tv"], quiet["lam"], quiet["l1"]) == tuple(knobs[1, "quiet"][k] for k in
                                                                             ("fills", "tv", "lam", "l1"))
    loud_views = views + rng.normal(scale=0.03 * peak, size=views.shape)
    loud = reconstruct(loud_views, op, "admm", saturation=None).settings
    assert (loud["iters"], loud["tv"], loud["lam"], loud["l1"]) == tuple(knobs[1, "noisy"][k] for k in
                                                                         ("fills", "tv", "lam", "l1"))
    assert loud["noise"] > knobs_mod.ADMM_QUIET_NOISE > quiet["noise"]
    # a knob given is kept, the others still follow the noise
    mixed = reconstruct(views, op, "admm", 2, saturation=None).settings
    assert (mixed["iters"], mixed["tv"]) == (2, knobs[1, "quiet"]["tv"])
    # the finer grid has its own knobs; the routes take it on all but dense stacks
    names = ("fills", "tv", "lam", "l1", "start", "tol")
    for v, regime in ((views, "quiet"), (loud_views, "noisy")):
        got = knobs_mod.admm_knobs(v, None, subsamples=2)
        assert tuple(got[k] for k in names) == tuple(knobs[2, regime][k] for k in names)
    # every knob given: the noise is not measured, the fills given all run from the default start
    given = knobs_mod.admm_knobs(views, None, 3, 0.0, 0.01, 2, 0.0)
    assert math.isnan(given["noise"]) and (given["start"], given["tol"]) == (knobs_mod.ADMM_START, 0.0)
    assert knobs_mod.admm_subsamples(4) == knobs_mod.ADMM_SUBSAMPLES == 2
    assert knobs_mod.admm_subsamples(knobs_mod.SUBSAMPLES_MAX_PLANES + 1) == 1
    with pytest.raises(ValueError, match="subsamples"):
        knobs_mod.admm_knobs(views, None, subsamples=3)


def test_saturated_pixels_are_left_out(op, planted):
    x, views = planted
    level = float(np.quantile(views, 0.995))
    clipped = np.minimum(views, level)
    kept = reconstruct(clipped, op, "admm", saturation=level)
    assert kept.settings["n_saturated"] > 0
    # what a saturated pixel holds does not matter: it is missing data
    other = np.where(clipped >= level, 50 * level, clipped)
    again = reconstruct(other, op, "admm", saturation=level)
    np.testing.assert_allclose(again.planes, kept.planes, rtol=1e-6, atol=1e-9)
    fitted_as_is = reconstruct(clipped, op, "admm", saturation=None)
    assert rel(kept.planes, x).max() < rel(fitted_as_is.planes, x).max()


@pytest.mark.parametrize("solver", ["admm", "pd-tv"])
def test_the_planes_scale_with_the_data_in_the_units_of_its_clipping_level(op, planted, solver):
    """The same light field in counts (x 1000, the sensor clipping at 1000) or at 1e-3 gives the same planes in its
    units: the weights (tv, and admm's noise regimes) are applied where the level is 1. As absolute weights they had
    made the planes of data x 1e-3 differ by 40 % from those of the data (a user's CLI run, TV 0.1)."""
    x, views = planted
    noisy = np.clip(views + np.random.default_rng(2).normal(0, 0.02 * views.max(), views.shape), 0, None)
    level = float(np.quantile(noisy, 0.999))
    data = np.minimum(noisy, level) / level                  # the sensor's units: clipping at 1
    ref = reconstruct(data, op, solver, 3, tv=0.1, saturation=1.0)
    for c in (1e3, 1e-3):
        scaled = reconstruct(data * c, op, solver, 3, tv=0.1, saturation=c)
        assert rel(scaled.planes / c, ref.planes).max() < 1e-4, (c, rel(scaled.planes / c, ref.planes))
        assert scaled.settings["saturation"] == c and scaled.settings["n_saturated"] == ref.settings["n_saturated"]
    with pytest.warns(UserWarning, match=r"are at or above the saturation level 1 and left out"):
        reconstruct(data * 1e3, op, solver, 1)              # counts fitted with the default level: said
    # with a mask of the samples to leave out (a capture's defective pixels, decoded views) the level is the unit
    # given beside it: a capture in counts with 5 defective pixels had given planes 25 % off those of its [0, 1] file
    mask = data >= 1.0
    mask.flat[::997] = True
    ref = reconstruct(data, op, solver, 3, tv=0.1, saturation=mask)
    for c in (1e3, 1e-3):
        scaled = reconstruct(data * c, op, solver, 3, tv=0.1, saturation=mask, unit=c)
        assert rel(scaled.planes / c, ref.planes).max() < 1e-4, (c, rel(scaled.planes / c, ref.planes))
        assert scaled.settings["saturation"] == "mask" and scaled.settings["n_saturated"] == ref.settings["n_saturated"]
    with pytest.raises(ValueError, match="unit must be a positive finite level"):
        reconstruct(data, op, solver, 1, saturation=mask, unit=0.0)


def test_refusals(camera, op, planted):
    _, views = planted
    with pytest.raises(ValueError, match="ExactOperator"):
        reconstruct(views, EmissionOperator(camera, DEPTHS, rays_per_pixel=1), "admm")
    with pytest.raises(ValueError, match="fills"):
        reconstruct(views, op, "admm", 0)
    with pytest.raises(ValueError, match="momentum"):
        fourier.solve_admm(views, op, np.ones(op.dimsd, bool), momentum=1.0)
    with pytest.raises(ValueError, match="lam"):
        fourier_system.FourierSystem(op, lam=-1.0)


@pytest.mark.parametrize("lam", [-1.0, -1e-9, float("nan"), float("inf")])
def test_a_negative_or_non_finite_lam_is_refused_with_tv_on_or_off(op, planted, lam):
    """admm's gradient weight below 0 or not finite is refused up front, naming lam, with TV on as off: with TV on a
    lam of -1 had passed the system's check as lam + rho_tv (0) and was solved as if it were 0 (a small camera's
    flames: planes all NaN), and NaN or inf had been refused only once the noise was measured, as 'lam=nan' or
    'lam=inf' plus rho_tv; solve_admm refuses them too."""
    _, views = planted
    for tv in (0.1, 0.0):
        with pytest.raises(ValueError, match="lam, the weight of the planes' gradient .* must be a finite number >= 0"):
            reconstruct(views, op, "admm", lam=lam, tv=tv)
        with pytest.raises(ValueError, match="finite number >= 0"):
            fourier.solve_admm(views, op, np.ones(op.dimsd, bool), lam=lam, tv=tv)


def test_the_default_solver_follows_the_operator(camera, op, planted):
    _, views = planted
    assert reconstruct(views, op, iters=1).solver == "admm"
    traced = EmissionOperator(camera, list(DEPTHS), rays_per_pixel=1)
    assert reconstruct(views, traced, iters=1).solver == "pd-tv"


def test_the_refocused_start_takes_the_window_most_of_the_way(op, planted):
    """The missing data predicted from the normalised back-projection (scaled to the data) leave
    the first fills closer to the planted emission than missing data that start at zero (on the
    paper's camera the gain is larger: ``experiments/fourier_solver.py --stage tune``)."""
    x, views = planted
    fit = np.ones(op.dimsd, bool)
    err = {start: [rel(fourier.solve_admm(views, op, fit, fills=f, tv=0.0, lam=0.03, start=start)[0], x).max()
                   for f in (1, 2)] for start in ("zero", "refocused")}
    assert err["refocused"][0] < 0.85 * err["zero"][0] and err["refocused"][1] < 0.9 * err["zero"][1]
    # the back-projection's weight is H^H of the fitted pixels: kept for the last mask, rebuilt for another
    w = fourier.backprojection_weight(op, np.ones((len(op._lit),) + op.dimsd[2:], bool))
    part = np.ones((len(op._lit),) + op.dimsd[2:], bool)
    part[:, :5] = False
    w_part = fourier.backprojection_weight(op, part)
    assert (w_part <= w + 1e-6 * w.max()).all() and w_part[:, :2].max() < 0.5 * w[:, :2].max()


def test_the_coarse_start_solves_the_lenslet_grid_first(camera, op, planted):
    """On a 2 x 2 grid per lenslet, the coarse start (the lenslet grid's solve, each lenslet's value on its
    four samples) leaves the first fill closer to the planted emission than the refocused start; it keeps its
    lenslet-grid operator on the fine one, honours a support, and is refused on the lenslet grid itself."""
    x, _ = planted
    fine = ExactOperator(camera, DEPTHS, subsamples=2)
    xf = np.repeat(np.repeat(x, 2, axis=1), 2, axis=2)                  # smooth blobs on the fine grid
    views = fine.matvec(xf.ravel()).reshape(fine.dimsd)
    fit = np.ones(fine.dimsd, bool)
    knobs = dict(tv=0.0, lam=0.003, l1=0.0)
    err = {start: rel(fourier.solve_admm(views, fine, fit, fills=1, start=start, **knobs)[0], xf).max()
           for start in ("refocused", "coarse")}
    assert err["coarse"] < 0.5 * err["refocused"]
    coarse, built_s = fourier.coarse_operator(fine)
    assert built_s == 0.0 and coarse.subsamples == 1 and coarse.dims == op.dims   # kept from the solves above
    support = np.zeros(fine.dims, bool)
    support[:, : fine.dims[1] // 2] = True                                 # the upper half of every plane
    planes = fourier.solve_admm(views, fine, fit, fills=2, start="coarse", support=support, **knobs)[0]
    assert planes[~support].max() == 0 and planes[support].max() > 0
    with pytest.raises(ValueError, match="finer grid"):
        fourier.solve_admm(planted[1], op, np.ones(op.dimsd, bool), start="coarse")


def test_given_start_planes_take_the_coarse_starts_place(camera, op, planted):
    """Planes given on the lenslet grid (a learned reconstructor's) start the fine grid's fills: the truth binned
    leaves the first fill far closer than the zero start, on either grid, without the coarse solve; through
    ``reconstruct`` the record says so; planes on the fine grid start it with their detail within a lenslet; a
    start of another shape or with NaN is refused."""
    x, _ = planted
    fine = ExactOperator(camera, DEPTHS, subsamples=2)
    xf = np.repeat(np.repeat(x, 2, axis=1), 2, axis=2)
    views = fine.matvec(xf.ravel()).reshape(fine.dimsd)
    fit = np.ones(fine.dimsd, bool)
    knobs = dict(tv=0.0, lam=0.003, l1=0.0, fills=1)
    given = rel(fourier.solve_admm(views, fine, fit, start_planes=x, **knobs)[0], xf).max()
    zero = rel(fourier.solve_admm(views, fine, fit, start="zero", **knobs)[0], xf).max()
    assert given < 0.3 * zero, (given, zero)
    lens = fourier.solve_admm(planted[1], op, np.ones(op.dimsd, bool), start_planes=x, **knobs)[0]
    assert rel(lens, x).max() < 0.3 * rel(fourier.solve_admm(planted[1], op, np.ones(op.dimsd, bool),
                                                             start="zero", **knobs)[0], x).max()
    rec = reconstruct(views, fine, "admm", iters=1, start_planes=x)
    assert rec.settings["start"] == "given" and rec.settings["fills_run"] == 1
    # on the planes' grid (a solve's at nearby depths): detail within a lenslet that the binned start cannot hold
    ripple = xf * (1.0 + 0.5 * (np.indices(xf.shape[1:]).sum(axis=0) % 2))
    v2 = fine.matvec(ripple.ravel()).reshape(fine.dimsd)
    on_grid = rel(fourier.solve_admm(v2, fine, fit, start_planes=ripple, **knobs)[0], ripple).max()
    binned = ripple.reshape(len(x), x.shape[1], 2, x.shape[2], 2).mean(axis=(2, 4))
    assert on_grid < 0.5 * rel(fourier.solve_admm(v2, fine, fit, start_planes=binned, **knobs)[0], ripple).max()
    for bad in (x[:, :-1], np.where(x > 0.5 * x.max(), np.nan, x)):
        with pytest.raises(ValueError, match="start_planes"):
            fourier.solve_admm(views, fine, fit, start_planes=bad, **knobs)
    with pytest.raises(ValueError, match="admm only"):
        reconstruct(planted[1], op, "fista", start_planes=x)


def test_the_stopping_tolerance_ends_the_fills_once_the_planes_settle(op, planted):
    x, views = planted
    fit = np.ones(op.dimsd, bool)
    knobs = dict(tv=0.0, lam=0.03, start="refocused")
    full, res_full, _ = fourier.solve_admm(views, op, fit, fills=12, **knobs)
    assert len(res_full) + 1 == 12                                   # tol 0: every fill runs
    loose, res_loose, _ = fourier.solve_admm(views, op, fit, fills=12, tol=10.0, **knobs)
    assert len(res_loose) + 1 == 2                                   # any change passes: the second fill stops
    changes = []
    fourier.solve_admm(views, op, fit, fills=12, callback=lambda j, s: changes.append(s.copy()), **knobs)
    step = [np.linalg.norm(b - a) / np.linalg.norm(b) for a, b in zip(changes, changes[1:])]
    tol = 0.5 * (step[3] + step[4]) if step[3] > step[4] else step[4] * 1.0001
    mid, res_mid, _ = fourier.solve_admm(views, op, fit, fills=12, tol=tol, **knobs)
    assert len(res_mid) + 1 == 6                                    # stops after the first fill whose change <= tol
    assert rel(mid, x).max() < 1.5 * rel(full, x).max()
    with pytest.raises(ValueError, match="start"):
        fourier.solve_admm(views, op, fit, start="focal")
    with pytest.raises(ValueError, match="tol"):
        fourier.solve_admm(views, op, fit, tol=-1.0)


@pytest.mark.parametrize("complex_matrices", [False, True])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_packed_cholesky_solve_matches_a_dense_solve(complex_matrices, dtype):
    """factor_packed + cholesky_solve against numpy's solve, per frequency, real and complex
    matrices, over more frequencies than one block (the last one partial)."""
    P, M = 5, K.BLOCK + 37
    rng = np.random.default_rng(7)
    B = rng.normal(size=(M, P, P)) + (1j * rng.normal(size=(M, P, P)) if complex_matrices else 0)
    A = B @ np.conj(np.swapaxes(B, 1, 2)) + P * np.eye(P)                  # Hermitian positive definite, (M, P, P)
    b = rng.normal(size=(P, M)) + 1j * rng.normal(size=(P, M))
    want = np.linalg.solve(A, b.T[..., None])[..., 0].T
    L = np.ascontiguousarray(np.moveaxis(A, 0, -1))
    packed, n_bad = K.factor_packed(L, dtype)
    assert n_bad == 0
    assert packed.dtype == dtype and packed.shape[1] == (2 if complex_matrices else 1)
    got = np.array(b, np.result_type(dtype, np.complex64))
    K.cholesky_solve(packed, got)
    np.testing.assert_allclose(got, want, rtol=0, atol=(1e-4 if dtype == np.float32 else 1e-10) * np.abs(want).max())


def test_a_recording_continues_the_previous_frames_solve(camera, op, planted):
    """A state carried from frame to frame: the next frame's one fill starts from the last one's planes,
    duals and its last fill's prediction of the missing data, and lands far closer to that frame's emission than
    one fill from scratch, as close as four; a state from another operator is refused."""
    x, views = planted
    fit = np.ones(op.dimsd, bool)
    knobs = dict(tv=0.0, lam=0.03, start="refocused")
    state = {}
    fourier.solve_admm(views, op, fit, fills=4, state=state, **knobs)
    assert {"s", "d", "z", "tv", "lam_max"} <= set(state)
    x2 = 1.04 * x                                                      # the next frame: 4 % brighter (a flicker)
    views2 = op.matvec(x2.ravel()).reshape(op.dimsd)
    assert not state["z_predicts"]                                     # the last fill's views: no H spent
    cont, res, _ = fourier.solve_admm(views2, op, fit, fills=1, state=state, **knobs)
    assert res == []                                                   # they hold the last frame's data
    assert state["z_predicts"]                                         # one fill: the next fill's prediction made
    assert len(fourier.solve_admm(views2, op, fit, fills=2, state=dict(state), **knobs)[1]) == 2
    one = rel(fourier.solve_admm(views2, op, fit, fills=1, **knobs)[0], x2).max()
    four = rel(fourier.solve_admm(views2, op, fit, fills=4, **knobs)[0], x2).max()
    assert rel(cont, x2).max() < 0.3 * one and rel(cont, x2).max() < 1.2 * four
    other = ExactOperator(camera, DEPTHS[:2])
    with pytest.raises(ValueError, match="another operator"):
        fourier.solve_admm(other.matvec(np.ones(other.shape[1])).reshape(other.dimsd), other,
                           np.ones(other.dimsd, bool), state=state)


def test_fills_that_diverge_restart_without_momentum(tmp_path, monkeypatch):
    """A colour capture's red channel (three quarters of the samples missing) on the example camera's decoded
    views, solved without TV as the colour routes do: the heavy-ball fills on inexact ADMM steps diverge (the
    residual grows a hundredfold); the restart brings them back from the best fill, without momentum."""
    import contextlib
    import io
    import json
    from pathlib import Path

    from lf_flame.cli import main
    from lf_flame.real.readers import read_light_field
    from lf_flame.tomo.decoded import fit_data

    cam = tmp_path / "colour.toml"
    cam.write_text((Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml").read_text()
                   + 'cfa = "RGGB"\n')
    for argv in (("simulate", "--camera", cam, "--scene", "white", "--rays-per-pixel", 4, "--out", tmp_path / "w.npz"),
                 ("calibrate", tmp_path / "w.npz", "--out", tmp_path / "cal.json"),
                 ("simulate", "--camera", cam, "--scene", "colour-depth", "--seed", 58002, "--rays-per-pixel", 16,
                  "--out", tmp_path / "s.npz"),
                 ("decode", tmp_path / "s.npz", "--calibration", tmp_path / "cal.json", "--camera", cam,
                  "--out", tmp_path / "s.h5")):
        with contextlib.redirect_stdout(io.StringIO()):
            assert main([str(a) for a in argv]) == 0
    lf = read_light_field(tmp_path / "s.h5", cam)
    depths = sorted(o["depth_offset_mm"] for o in json.loads(str(np.load(tmp_path / "s.npz")["objects"])))
    op = ExactOperator(lf.camera, depths, subsamples=2, precision="float32")
    views, left_out = fit_data(lf, op)
    fit = ~left_out & (lf.channels == 0)
    views = views / views[fit].max()
    _, guarded, _ = fourier.solve_admm(views, op, fit, fills=25, lam=0.01, tv=0.0)
    monkeypatch.setattr(fourier, "ADMM_DIVERGENCE", math.inf)
    _, unguarded, _ = fourier.solve_admm(views, op, fit, fills=25, lam=0.01, tv=0.0)
    assert unguarded[-1] > 10 * min(unguarded)                    # the hard case: without the restart it diverges
    assert guarded[-1] < 1.5 * min(guarded) and guarded[-1] < 0.3


def test_the_package_sets_its_runtime_defaults_unless_the_user_says_otherwise():
    """Importing lf_flame sets OMP_WAIT_POLICY=PASSIVE (spinning threads hold the cores the FFTs need),
    JAX_PYLOPS=0 (PyLops does not import JAX, which lf_flame does not hand it) and, on glibc, keeps freed arrays'
    memory for the next ones (a 20 MiB array's pages stay in the process after it is freed), and keeps a user's
    own settings."""
    import os
    import subprocess
    import sys
    code = ("import os, sys, lf_flame, pylops, numpy as np; "
            "rss = lambda: int(open('/proc/self/statm').read().split()[1]) * os.sysconf('SC_PAGE_SIZE'); "
            "a = np.ones(20 << 17); held = rss(); del a; "
            "print(os.environ['OMP_WAIT_POLICY'], os.environ['JAX_PYLOPS'], 'jax' in sys.modules, "
            "lf_flame.MALLOC_TUNED, "
            "held - rss() < 10 << 20)")
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "JAX_PYLOPS", "MALLOC_TRIM_THRESHOLD_",
                                                                "MALLOC_MMAP_THRESHOLD_", "GLIBC_TUNABLES")}

    def run(**extra):
        return subprocess.run([sys.executable, "-c", code], env={**env, **extra}, capture_output=True, text=True,
                              check=True).stdout.split()
    tuned = sys.platform.startswith("linux")
    assert run() == ["PASSIVE", "0", "False", str(tuned), str(tuned)]
    assert run(OMP_WAIT_POLICY="ACTIVE", JAX_PYLOPS="1", MALLOC_TRIM_THRESHOLD_="131072") == ["ACTIVE", "1", "True",
                                                                                             "False", "False"]


def test_small_solves_run_on_one_thread(op, planted, monkeypatch):
    """Below ADMM_ONE_THREAD_SAMPLES view samples a solve runs on one thread (Numba's and the FFTs'), recorded
    in its settings, the threads restored after; at or above it, as set. The planes agree either way."""
    import numba
    size = len(op._lit) * op.canvas_shape[0] * op.canvas_shape[1]
    threads, workers = numba.get_num_threads(), op.workers
    planes = []
    for limit, want in ((size + 1, 1), (size, threads)):
        monkeypatch.setattr(fourier, "ADMM_ONE_THREAD_SAMPLES", limit)
        with fourier.solve_threads(op) as used:
            assert used == want and numba.get_num_threads() == want and op.workers == (1 if want == 1 else workers)
        assert numba.get_num_threads() == threads and op.workers == workers
        rec = reconstruct(planted[1], op, "admm", 2)
        assert rec.settings["threads"] == want and numba.get_num_threads() == threads and op.workers == workers
        planes.append(rec.planes)
    np.testing.assert_allclose(planes[0], planes[1], rtol=1e-4, atol=1e-6 * np.abs(planes[1]).max())
    with fourier.solve_threads(EmissionOperator.__new__(EmissionOperator)) as used:     # not exact: as set
        assert used == threads
