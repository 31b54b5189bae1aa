"""An axisymmetric emission ``e(r, y)`` revolved onto an exact operator's planes, and its fit for one axis.

The model of :mod:`lf_flame.tomo.axisymmetric` (whose docstring states it in full):

- :class:`RevolveOperator` (``R``): ``e`` on radial nodes ``r_j = j dr`` (linear "hat"
  interpolation in ``r``) and on the rows of the grid at the axis's depth (linear in
  height), revolved onto the planes: each voxel reads ``e`` at its distance from the axis,
  ``sqrt((x - x0)^2 + (z - z0)^2)``, and its height. A sparse matrix (at most four entries
  per voxel); ``R^T`` its exact transpose.
- :func:`fit_emission`: non-negative least squares on ``e`` with a smoothness
  ``lam ||D e||^2`` (first differences along ``r`` and ``y``), by projected FISTA (Beck &
  Teboulle, SIAM J. Imaging Sci. 2 (2009)) on the exact operator's per-frequency normal
  matrices (:class:`NormalMatrices`), the missing data filled between FISTA runs.
- :func:`wide_operator`: the planes widened by the kernels' reach, for a flame cut by the
  field's edge.
"""
from __future__ import annotations

import math

import numpy as np
import pylops
import scipy.fft
import scipy.sparse

from . import _fourier_kernels
from .fourier_system import normal_matrices


def _grid_coordinates(op, p):
    """Row heights (rows,) and column positions (cols,) in mm of plane ``p`` of ``op`` (y up, x right)."""
    _, gr, gc = op.dims
    h, w = op.sizes_mm[p]
    cy, cx = op.centres_mm[p] if hasattr(op, "centres_mm") else (0.0, 0.0)
    return cy + (0.5 - (np.arange(gr) + 0.5) / gr) * h, cx + ((np.arange(gc) + 0.5) / gc - 0.5) * w


def frame_at(op, depth_mm):
    """Frame (height, width) in mm of the planes' grid at ``depth_mm``, linear in depth between the planes
    (extrapolated as such beyond them)."""
    d = np.asarray(op.depths_mm, np.float64)
    order = np.argsort(d)
    hs = np.array([s[0] for s in op.sizes_mm])[order]
    ws = np.array([s[1] for s in op.sizes_mm])[order]
    if len(d) == 1:
        return float(hs[0]), float(ws[0])
    ds = d[order]
    # the frame is proportional to the object distance: linear in depth, extrapolated as such
    fh = np.polyfit(ds, hs, 1)
    fw = np.polyfit(ds, ws, 1)
    return float(np.polyval(fh, depth_mm)), float(np.polyval(fw, depth_mm))


class RevolveOperator(pylops.LinearOperator):
    """An axisymmetric emission ``e(y, r)`` revolved onto a stack of planes (module docstring).

    Parameters
    ----------
    op : ExactOperator or EmissionOperator
        Its planes (``dims`` (P, rows, cols), ``depths_mm``, ``sizes_mm``, ``centres_mm``) are the target grid.
    axis_x_mm, axis_z_mm : float
        The vertical axis: lateral position (mm, x right, 0 on the optical axis) and depth
        (mm from the focal plane, positive farther).
    r_max_mm : float
        Outermost radial node (mm): the emission is zero beyond it.
    dr_mm : float or None
        Radial node spacing (mm); None: one lateral sample of the grid at the axis's depth.

    Attributes
    ----------
    dims : (rows, n_r)
        Model: ``e[i, j]`` at height ``heights_mm[i]`` (the rows of the grid at the axis's
        depth, row 0 the top) and radius ``radii_mm[j] = j dr_mm``; the planes' units (the
        emission a plane sample at that radius and height holds).
    dimsd : (P, rows, cols)
        The planes of ``op``.
    radii_mm, heights_mm : ndarray
    matrix : scipy.sparse.csr_matrix of shape (P rows cols, rows n_r)

    Raises
    ------
    ValueError
        Non-finite axis, a non-positive or non-finite ``r_max_mm`` or ``dr_mm``, fewer than
        two radial nodes, an axis whose cylinder misses every plane sample.
    """

    def __init__(self, op, axis_x_mm: float, axis_z_mm: float, r_max_mm: float, dr_mm: float | None = None):
        x0, z0, rmax = float(axis_x_mm), float(axis_z_mm), float(r_max_mm)
        if not (math.isfinite(x0) and math.isfinite(z0)):
            raise ValueError(f"the axis must be finite. Received: x0={axis_x_mm!r}, z0={axis_z_mm!r}")
        if not (math.isfinite(rmax) and rmax > 0):
            raise ValueError(f"r_max_mm must be positive and finite. Received: {r_max_mm!r}")
        P, gr, gc = op.dims
        h_ref, w_ref = frame_at(op, z0)
        dr = w_ref / gc if dr_mm is None else float(dr_mm)
        if not (math.isfinite(dr) and dr > 0):
            raise ValueError(f"dr_mm must be positive and finite. Received: {dr_mm!r}")
        n_r = int(math.floor(rmax / dr + 1e-9)) + 1
        if n_r < 2:
            raise ValueError(f"r_max_mm={rmax:g} gives fewer than two radial nodes at dr={dr:g} mm")
        self.radii_mm = np.arange(n_r) * dr
        self.heights_mm = (0.5 - (np.arange(gr) + 0.5) / gr) * h_ref
        rows, cols, vals = [], [], []
        for p in range(P):
            ys, xs = _grid_coordinates(op, p)
            r = np.hypot(xs - x0, op.depths_mm[p] - z0)                 # (cols,)
            rf = r / dr
            j0 = np.floor(rf).astype(np.int64)
            t = rf - j0
            fi = (0.5 - ys / h_ref) * gr - 0.5                           # fractional row of e, (rows,)
            i0 = np.floor(fi).astype(np.int64)
            s = fi - i0
            vox = (p * gr + np.arange(gr)[:, None]) * gc + np.arange(gc)[None, :]
            for di, wi in ((0, 1.0 - s), (1, s)):
                ii = i0 + di
                for dj, wj in ((0, 1.0 - t), (1, t)):
                    jj = j0 + dj
                    wgt = wi[:, None] * wj[None, :]
                    ok = ((ii >= 0) & (ii < gr))[:, None] & (jj < n_r)[None, :] & (wgt > 0)
                    rows.append(vox[ok])
                    cols.append((np.broadcast_to(ii[:, None], ok.shape) * n_r + jj[None, :])[ok])
                    vals.append(wgt[ok])
        rows, cols, vals = (np.concatenate(a) for a in (rows, cols, vals))
        if not len(vals):
            raise ValueError(f"an axis at x0={x0:g} mm, z0={z0:g} mm with r_max={rmax:g} mm reaches no plane sample")
        self.matrix = scipy.sparse.csr_matrix((vals, (rows, cols)), shape=(P * gr * gc, gr * n_r))
        self._mt = self.matrix.T.tocsr()
        self.axis_x_mm, self.axis_z_mm, self.r_max_mm, self.dr_mm = x0, z0, float(self.radii_mm[-1]), dr
        super().__init__(dtype=np.float64, dims=(gr, n_r), dimsd=(P, gr, gc))

    def _matvec(self, e):
        return self.matrix @ np.ravel(e)

    def _rmatvec(self, x):
        return self._mt @ np.ravel(x)


class NormalMatrices:
    """The exact operator's per-frequency normal matrices ``G(f)``, full, frequencies first, for ``G x`` on planes.

    Parameters
    ----------
    op : ExactOperator

    Attributes
    ----------
    G : ndarray of shape (Lr F, P, P)
        Real on a perfect grid, else complex; the operator's precision.
    g0 : float
        The mean of ``G``'s diagonal at zero frequency.
    shape : (Lr, F)
        The canvas's real-FFT shape.
    """

    def __init__(self, op):
        G = normal_matrices(op)                                      # (P, P, Lr, F), lower triangle
        P = G.shape[0]
        iu = np.triu_indices(P, 1)
        G[iu[0], iu[1]] = np.conj(G[iu[1], iu[0]])
        real = np.float32 if op._spec.dtype == np.complex64 else np.float64
        dt = real if G.dtype == np.float64 else np.result_type(real, np.complex64)
        self.G = np.ascontiguousarray(G.reshape(P, P, -1).transpose(2, 0, 1), dt)   # (Lr F, P, P)
        self.g0 = float(np.mean(np.diagonal(G[:, :, 0, 0]).real))
        self.shape = G.shape[2:]

    def apply(self, xs):
        """``G(f) xs(f)`` for spectra ``xs`` (P, Lr, F)."""
        P = xs.shape[0]
        if np.iscomplexobj(self.G):
            flat = np.ascontiguousarray(xs.reshape(P, -1).T).astype(self.G.dtype)
            return np.matmul(self.G, flat[:, :, None])[:, :, 0].T.reshape(xs.shape)
        # real G (every perfect grid): one threaded pass over the matrices (the spectra gathered per chunk of
        # frequencies), 1.5x faster than a batched matmul of real and imaginary columns and its transposes
        from ._revolve_kernels import normal_apply
        cdt = np.complex64 if self.G.dtype == np.float32 else np.complex128
        out = np.empty(xs.shape, cdt)
        normal_apply(self.G, np.ascontiguousarray(xs.reshape(P, -1), cdt), out.reshape(P, -1))
        return out


def _difference_operator(rows, n_r):
    """First differences of ``e`` (rows, n_r) along the height and the radius, stacked (sparse)."""
    dy = scipy.sparse.kron(scipy.sparse.diags([-1.0, 1.0], [0, 1], shape=(rows - 1, rows)), scipy.sparse.eye(n_r))
    dx = scipy.sparse.kron(scipy.sparse.eye(rows), scipy.sparse.diags([-1.0, 1.0], [0, 1], shape=(n_r - 1, n_r)))
    return scipy.sparse.vstack([dy, dx]).tocsr()


def resized_emission(e, dims):
    """``e`` (rows, n_r) cut or padded with zeros to ``dims`` along the radius, flat (a start of
    :func:`fit_emission` for another radius); None stays None."""
    if e is None:
        return None
    out = np.zeros(dims)
    n = min(dims[1], e.shape[1])
    out[:, :n] = e[:, :n]
    return out.ravel()


def fit_emission(op, normal, yt, w2, norm, lit, revolve, lam, fills, inner, e0=None):
    """An axisymmetric emission ``e`` for one axis: projected FISTA between fills of the missing data.

    Minimises ``1/2 ||M (w H R e - y)||^2 + lam_abs/2 ||D e||^2`` over ``e >= 0`` (module docstring), the
    missing data filled from the prediction as :func:`lf_flame.tomo.fourier.solve_admm` does.

    Parameters
    ----------
    op : ExactOperator
        The planes ``revolve`` maps onto.
    normal : NormalMatrices
        ``op``'s per-frequency normal matrices.
    yt, w2, norm, lit
        The data as :func:`lf_flame.tomo.fourier.fill_data` returns them, and ``op``'s lit views.
    revolve : RevolveOperator
    lam : float
        Weight of ``||D e||^2`` relative to ``g0`` times the mean diagonal of ``R^T R``.
    fills, inner : int
        Fills of the missing data and FISTA steps per fill.
    e0 : ndarray of shape ``revolve.dims`` (flat) or None
        Where to start (its negative part dropped); None: zero.

    Returns
    -------
    e : ndarray of shape (rows n_r,), float64, non-negative
    residual : float
        ``||M (w H R e - y)|| / ||M y||`` at the last fill (NaN with one fill from zero).
    """
    P, gr, gc = op.dims
    canvas = op.canvas_shape
    S = op._spec
    real = np.float32 if S.dtype == np.complex64 else np.float64
    D = _difference_operator(*revolve.dims)
    norm = norm or 1.0

    def planes(e):
        x = np.zeros((P,) + canvas, real)
        x[:, :gr, :gc] = (revolve.matrix @ e).reshape(P, gr, gc)
        return x

    def normal_e(e):                                                 # R^T G R e, planes cropped to the grid
        gx = scipy.fft.irfft2(normal.apply(scipy.fft.rfft2(planes(e), workers=op.workers)), s=canvas,
                              workers=op.workers)
        return revolve._mt @ gx[:, :gr, :gc].astype(np.float64).ravel()

    # Lipschitz constant of the data term on e (power iteration), and the smoothness weight
    rng = np.random.default_rng(0)
    v = rng.random(revolve.shape[1])
    for _ in range(12):
        v = normal_e(v)
        v /= np.linalg.norm(v) or 1.0
    L_data = float(v @ normal_e(v))
    diag = np.asarray(revolve.matrix.power(2).sum(axis=0)).ravel()
    lam_abs = lam * normal.g0 * float(diag[diag > 0].mean())
    L = 1.05 * L_data + 8.0 * lam_abs
    e = np.zeros(revolve.shape[1]) if e0 is None else np.maximum(np.asarray(e0, np.float64), 0.0)
    z = np.zeros((len(lit),) + canvas, real)
    residual = float("nan")
    for j in range(int(fills) + 1):
        if j > 0 or e0 is not None:                                  # predict the missing data from e
            hv = _fourier_kernels.spectra_forward(S, scipy.fft.rfft2(planes(e), workers=op.workers))
            z = scipy.fft.irfft2(hv, s=canvas, workers=op.workers)
        res2 = _fourier_kernels.fill(z, yt, w2)
        if j > 0 or e0 is not None:
            residual = math.sqrt(res2) / norm
        if j == int(fills):
            break
        b = scipy.fft.irfft2(_fourier_kernels.spectra_adjoint(S, scipy.fft.rfft2(z, workers=op.workers)), s=canvas,
                             workers=op.workers)[:, :gr, :gc]
        rtb = revolve._mt @ b.astype(np.float64).ravel()
        u, t = e.copy(), 1.0
        for _ in range(int(inner)):
            grad = normal_e(u) - rtb + lam_abs * (D.T @ (D @ u))
            e_new = np.maximum(u - grad / L, 0.0)
            t_new = 0.5 * (1.0 + math.sqrt(1.0 + 4.0 * t * t))
            u = e_new + ((t - 1.0) / t_new) * (e_new - e)
            e, t = e_new, t_new
    return e, residual


def wide_operator(op):
    """The exact operator's planes on a grid wider than the field by the kernels' reach.

    A view pixel at the field's edge reads the planes up to the kernels' largest offset
    beyond it (its parallax): emission there is light in the data that a grid the size
    of the field cannot explain. This operator's planes (same camera, depths, effects and
    precision) hold it; the field's grid is its central ``op.dims[1:]`` samples (an even
    number of extra samples per axis, so the two grids' samples coincide).

    Parameters
    ----------
    op : ExactOperator
        With ``margin`` 1 and ``subsamples`` 1.

    Returns
    -------
    ExactOperator
        ``margin`` the smallest ``1 + t`` with ``t n_rows`` and ``t n_cols`` even integers
        that reach as far as the kernels on both axes.

    Raises
    ------
    ValueError
        An operator with a margin or subsamples other than 1.
    """
    from .exact import ExactOperator
    if op.margin != 1 or op.subsamples != 1:
        raise ValueError(f"wide_operator widens a field-sized lenslet grid: margin and subsamples 1. "
                         f"Received: margin={op.margin!r}, subsamples={op.subsamples!r}")
    _, _, R, C = op.dimsd
    ty, tx = op.kernels.shape[3:]
    reach_y = max(-int(op.tap_origin_y.min()), int((op.tap_origin_y + ty - 1).max()), 1)
    reach_x = max(-int(op.tap_origin_x.min()), int((op.tap_origin_x + tx - 1).max()), 1)
    k = reach_x                                                  # k extra columns per side; rows k R / C per side
    while (k * R) % C or (k * R) // C < reach_y:
        k += 1
    return ExactOperator(op.camera, list(op.depths_mm), margin=1.0 + 2.0 * k / C, effects=op.effects,
                         precision=op.precision, quadrature_nodes=op.quadrature_nodes, workers=op.workers)
