"""Axisymmetric volumes (lf_flame.tomo.axisymmetric): the revolve operator, the solve, the axis search, bad input."""
import numpy as np
import pylops
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.simulate.scenes_volume import axisymmetric_flame_scene
from lf_flame.tomo.axis import axis_x_from_views
from lf_flame.tomo.axisymmetric import solve_axisymmetric
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.revolve import RevolveOperator

AXIS = (0.3, 0.2)           # x0, z0 (mm)
R_MAX = 2.0


@pytest.fixture(scope="module")
def op():
    cam = PlenopticCamera(n_rows=41, n_cols=41)                   # a 5.4 mm field
    return ExactOperator(cam, list(np.arange(-3.0, 3.01, 0.5)), precision="float64")


def ring(rev):
    """A sheath-like e(y, r): a ring of radius 1 mm, brightest at mid-height."""
    r, y = rev.radii_mm[None, :], rev.heights_mm[:, None]
    return np.exp(-(r - 1.0) ** 2 / (2 * 0.3 ** 2)) * np.clip(1 - np.abs(y) / 2.2, 0, None)


def data(op, e, rev):
    views = (op @ (rev @ e.ravel())).reshape(op.dimsd)
    scale = 0.8 / views.max()                                      # below the clipping level, as a render
    return views * scale, e * scale


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_the_normal_matrices_multiply_each_frequency(op, precision):
    """``NormalMatrices.apply``'s kernel against NumPy: ``G(f) xs(f)`` at every frequency of the canvas, to the
    operator's precision."""
    import scipy.fft

    from lf_flame.tomo.revolve import NormalMatrices
    o = op if precision == "float64" else ExactOperator(op.camera, op.depths_mm, precision="float32")
    nm = NormalMatrices(o)
    assert not np.iscomplexobj(nm.G)                                # a perfect grid's matrices are real
    P = o.dims[0]
    x = np.zeros((P,) + o.canvas_shape, np.float64 if precision == "float64" else np.float32)
    x[:, :o.dims[1], :o.dims[2]] = np.random.default_rng(1).random(o.dims)
    xs = scipy.fft.rfft2(x)
    want = np.einsum("fik,kf->if", nm.G.astype(np.float64), xs.reshape(P, -1).astype(np.complex128))
    got = nm.apply(xs)
    assert got.shape == xs.shape and got.dtype == xs.dtype
    err = np.linalg.norm(got.reshape(P, -1) - want) / np.linalg.norm(want)
    assert err < (1e-12 if precision == "float64" else 1e-6), err


def test_revolve_is_linear_and_its_adjoint_exact(op):
    rev = RevolveOperator(op, *AXIS, R_MAX)
    assert rev.dims == (41, len(rev.radii_mm)) and rev.dimsd == op.dims
    assert pylops.utils.dottest(rev, *rev.shape, rtol=1e-12, complexflag=0)
    # a voxel reads e at its own distance from the axis: a constant e is 1 inside the cylinder, 0 well outside
    x = (rev @ np.ones(rev.shape[1])).reshape(op.dims)
    p = list(op.depths_mm).index(0.0)
    cols = ((np.arange(41) + 0.5) / 41 - 0.5) * op.sizes_mm[p][1]
    r = np.hypot(cols - AXIS[0], 0.0 - AXIS[1])
    mid = x[p, 20]
    assert np.allclose(mid[r < R_MAX - 0.2], 1.0) and np.all(mid[r > R_MAX + 0.2] == 0)


def test_known_emission_is_recovered(op):
    rev = RevolveOperator(op, *AXIS, R_MAX)
    views, e = data(op, ring(rev), rev)
    res = solve_axisymmetric(views, op, np.ones(views.shape, bool), axis_x_mm=AXIS[0], axis_z_mm=AXIS[1],
                             r_max_mm=R_MAX, lam=0.0, fills=2, inner=300)
    assert res.residual < 1e-3
    truth = (rev @ e.ravel()).reshape(op.dims)
    assert np.linalg.norm(res.volume - truth) / np.linalg.norm(truth) < 0.01
    assert np.linalg.norm(res.emission - e) / np.linalg.norm(e) < 0.01


def test_the_weight_follows_the_noise(op):
    from lf_flame.tomo.axisymmetric import AXI_LAM
    rev = RevolveOperator(op, *AXIS, R_MAX)
    views, _ = data(op, ring(rev), rev)
    loud = views + np.random.default_rng(5).normal(scale=0.03 * views.max(), size=views.shape)
    kw = dict(axis_x_mm=AXIS[0], axis_z_mm=AXIS[1], r_max_mm=R_MAX, fills=1, inner=10)
    for v, regime in ((views, "quiet"), (loud, "noisy")):
        res = solve_axisymmetric(v, op, **kw)
        assert res.lam == AXI_LAM[regime]
        np.testing.assert_array_equal(res.emission, solve_axisymmetric(v, op, lam=AXI_LAM[regime], **kw).emission)
    assert solve_axisymmetric(loud, op, lam=0.5, **kw).lam == 0.5                 # a weight given is kept


def test_axis_search_finds_the_axis(op):
    rev = RevolveOperator(op, *AXIS, R_MAX)
    views, _ = data(op, ring(rev), rev)
    res = solve_axisymmetric(views, op, np.ones(views.shape, bool), r_max_mm=R_MAX, start_z_mm=-0.8,
                             search_half_width_mm=2.0, fills=2, inner=100)
    assert abs(res.axis_x_mm - AXIS[0]) < 0.05
    assert abs(res.axis_z_mm - AXIS[1]) < 0.1
    assert len(res.search) >= 4 and min(s[1] for s in res.search) <= res.search[0][1]
    # the bracket (-2.8 to +1.2 mm) is scanned every SEARCH_SCAN_MM before the bounded search refines, so
    # a residual with several dips cannot hold the search in the first one it meets
    from lf_flame.tomo.axisymmetric import SEARCH_SCAN_MM
    scan = np.arange(-2.8, 1.2 + 1e-9, SEARCH_SCAN_MM)
    assert np.allclose([z for z, _ in res.search[:len(scan)]], scan)


def test_the_axis_search_stays_within_the_stack(op):
    """A search that would start outside the stack's depths (the flame with the most votes beyond it) is refused,
    naming the stack; inside it, the scan is clipped to the stack's ends."""
    rev = RevolveOperator(op, *AXIS, R_MAX)
    views, _ = data(op, ring(rev), rev)
    far = float(np.max(op.depths_mm)) + 5.0
    with pytest.raises(ValueError, match="outside the stack's"):
        solve_axisymmetric(views, op, r_max_mm=R_MAX, start_z_mm=far, fills=1, inner=5)
    edge = float(np.max(op.depths_mm)) - 0.5
    res = solve_axisymmetric(views, op, r_max_mm=R_MAX, start_z_mm=edge, search_half_width_mm=2.0, fills=1, inner=5)
    assert max(z for z, _ in res.search) <= np.max(op.depths_mm)


def test_axis_x_from_a_rendered_view():
    cam = PlenopticCamera(n_rows=41, n_cols=41)
    op = ExactOperator(cam, [-1.0, 0.0, 1.0], precision="float32")
    scene = axisymmetric_flame_scene(cam, centre_depth_mm=0.0, centre_x_mm=0.6, diameter_mm=2.5, core=0.5,
                                     n_layers=8)
    from lf_flame.tomo.truth import scene_truth
    views = (op @ scene_truth(scene, op).ravel()).reshape(op.dimsd)
    assert abs(axis_x_from_views(views, op, 0.0) - 0.6) < 0.05


def test_bad_input_is_refused(op):
    with pytest.raises(ValueError, match="r_max_mm must be positive"):
        RevolveOperator(op, 0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="finite"):
        RevolveOperator(op, float("nan"), 0.0, 1.0)
    with pytest.raises(ValueError, match="reaches no plane"):
        RevolveOperator(op, 0.0, 40.0, 1.0)
    views = np.zeros(op.dimsd)
    with pytest.raises(ValueError, match="data shape"):
        solve_axisymmetric(views[:, :, :-1], op, axis_x_mm=0.0, axis_z_mm=0.0, r_max_mm=1.0)
    with pytest.raises(ValueError, match="fills"):
        solve_axisymmetric(views, op, axis_x_mm=0.0, axis_z_mm=0.0, r_max_mm=1.0, fills=0)
    with pytest.raises(ValueError, match="lam"):
        solve_axisymmetric(views, op, axis_x_mm=0.0, axis_z_mm=0.0, r_max_mm=1.0, lam=-1.0)
    with pytest.raises(ValueError, match="fit"):
        solve_axisymmetric(views, op, np.ones(3, bool), axis_x_mm=0.0, axis_z_mm=0.0, r_max_mm=1.0)
    with pytest.raises(ValueError, match="no light"):
        solve_axisymmetric(views, op, axis_z_mm=0.0, r_max_mm=1.0)
    with pytest.raises(ValueError, match="core"):
        axisymmetric_flame_scene(op.camera, core=1.5)
    from lf_flame.tomo.exact import ExactOperator
    fine = ExactOperator(op.camera, op.depths_mm[:2], subsamples=2)
    with pytest.raises(ValueError, match="subsamples=1"):
        solve_axisymmetric(np.zeros(fine.dimsd), fine, axis_x_mm=0.0, axis_z_mm=0.0, r_max_mm=1.0)


def test_a_flame_cut_by_the_fields_edge(op):
    """A ring whose far side leaves the field (axis 2.0 mm from the centre of a 5.4 mm field): its light from beyond
    the field is modelled on the widened grid, the axis comes back and the field's part of the volume with it."""
    from lf_flame.tomo.axis import reaches_edge
    from lf_flame.tomo.revolve import wide_operator
    wide = wide_operator(op)
    (_, gr, gc), (_, wr, wc) = op.dims, wide.dims
    assert (wr - gr) % 2 == 0 and (wc - gc) % 2 == 0 and wc - gc >= 2 * int(-op.tap_origin_x.min())
    axis = (2.0, AXIS[1])
    rev = RevolveOperator(wide, *axis, R_MAX)
    views, e = data(wide, ring(rev), rev)
    r0, c0 = (wr - gr) // 2, (wc - gc) // 2
    whole = (rev @ e.ravel()).reshape(wide.dims)
    truth = whole[:, r0:r0 + gr, c0:c0 + gc]
    assert 0.1 < 1 - truth.sum() / whole.sum() < 0.4                                      # a cut flame
    assert reaches_edge(views) == (False, False, False, True)
    centred = RevolveOperator(op, *AXIS, R_MAX)
    inside = data(op, ring(centred), centred)[0]
    assert reaches_edge(inside) == (False,) * 4                                           # the ring inside the field
    noise = np.random.default_rng(1).normal(scale=0.05, size=views.shape)           # clipped at 0, as a sensor's
    assert reaches_edge(np.clip(inside + noise, 0, None)) == (False,) * 4           # its floor is no light
    assert reaches_edge(np.clip(views + noise, 0, None)) == (False, False, False, True)
    kw = dict(r_max_mm=R_MAX, fills=8, inner=100, lam=0.0)
    res = solve_axisymmetric(views, op, np.ones(views.shape, bool), axis_x_mm=axis[0], axis_z_mm=axis[1], **kw)
    assert res.beyond_field and res.volume.shape == op.dims
    assert np.linalg.norm(res.volume - truth) / np.linalg.norm(truth) < 0.03
    inside = solve_axisymmetric(views, op, np.ones(views.shape, bool), axis_x_mm=axis[0], axis_z_mm=axis[1],
                                beyond_field=False, **kw)
    # what it replaces: the field's grid alone cannot explain the light from beyond the edge
    assert inside.residual > 5 * res.residual and not inside.beyond_field
    assert np.linalg.norm(inside.volume - truth) > 2 * np.linalg.norm(res.volume - truth)
    # the axis found: the central view's profile is cut, its mirror centre is the axis
    assert abs(axis_x_from_views(views, op, axis[1]) - axis[0]) < 0.05
    found = solve_axisymmetric(views, op, np.ones(views.shape, bool), start_z_mm=-0.8, search_half_width_mm=2.0,
                               r_max_mm=R_MAX, fills=2, inner=100)
    assert abs(found.axis_x_mm - axis[0]) < 0.05 and abs(found.axis_z_mm - axis[1]) < 0.1
    with pytest.raises(ValueError, match="margin and subsamples 1"):
        wide_operator(wide)
