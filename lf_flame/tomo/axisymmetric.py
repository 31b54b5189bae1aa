"""Axisymmetric volumes: a laminar flame's emission ``e(r, y)`` about a vertical axis (issue 36, step 2).

A dense stack of planes does not resolve a whole flame in depth from the data alone
(README, "The camera's depth resolution"). A laminar flame is axisymmetric: its emission
is a function ``e(r, y)`` of the height ``y`` and the distance ``r`` from a vertical axis
at lateral position ``x0`` and depth ``z0``. That prior turns the ``P x rows x cols`` stack
into ``rows x n_r`` unknowns that every plane shares (the onion-peeling / Abel model of
flame tomography; e.g. Dasch, Appl. Opt. 31 (1992), here composed with the light-field map).

- :class:`RevolveOperator` (``R``): ``e`` on radial nodes ``r_j = j dr`` (linear "hat"
  interpolation in ``r``) and on the rows of the grid at the axis's depth (linear in
  height), revolved onto the planes of an exact operator: each voxel reads ``e`` at its
  distance from the axis, ``sqrt((x - x0)^2 + (z - z0)^2)``, and its height. A sparse
  matrix (at most four entries per voxel); ``R^T`` its exact transpose.
- :func:`solve_axisymmetric`: non-negative least squares on ``e`` with a small
  smoothness ``lam ||D e||^2`` (first differences along ``r`` and ``y``), by projected
  FISTA (Beck & Teboulle, SIAM J. Imaging Sci. 2 (2009)) on the exact operator's
  per-frequency normal matrices ``G(f)`` (:func:`lf_flame.tomo.fourier_system.normal_matrices`),
  with the sensor window's and saturated pixels' missing data filled from the prediction
  as :func:`lf_flame.tomo.fourier.solve_admm` does (each *fill* one ``H`` and one ``H^H``
  over the views; the FISTA steps between fills run on the planes alone).
- **Flames cut by the field's edge.** Where the light reaches an edge of the field
  (:func:`reaches_edge`), ``e`` is revolved onto the planes of
  :func:`wide_operator` (the field's planes widened by the exact operator's reach), so the light
  that parallax brings in from beyond the field is fitted too; the volume returned is the field's part.
- **The axis.** ``x0`` from the central view's (a pinhole image's) column centroid at the
  axis's depth (its mirror centre where the lit columns reach the view's edge); ``z0``
  searched by :func:`scipy.optimize.minimize_scalar` (bounded) on the data residual of a
  shorter solve, about a start from :func:`lf_flame.tomo.depth.find_depths` (its found depth
  with the most votes) unless given.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pylops
import scipy.fft
import scipy.sparse
from scipy import optimize

from . import _fourier_kernels
from .fourier import fill_data
from .noise_knobs import noise_regime, relative_noise
from .fourier_system import normal_matrices

#: Smoothness weight of :func:`solve_axisymmetric`, relative to the mean diagonal of ``R^T G R``, per noise level
#: of the light field (:func:`lf_flame.tomo.noise_knobs.noise_regime`), chosen on 3 validation volumes by the lowest
#: worst 3-D error (``python experiments/volume.py --set axi-lam``, ``results/volume_axi_lam.md``): at 14 dB
#: 9.4 % at 1 against 11.8 % at the 1e-3 set by hand before; noise-free the worst volume (a filled core, 15.2 %)
#: barely moves from 1e-3 to 3 (0.01 the lowest by 0.02 %), the median is lowest at 1 (4.0 against 4.5 %).
AXI_LAM = {"quiet": 0.01, "noisy": 1.0}
#: Fills of the missing data (outer iterations) and FISTA steps per fill of a final solve. 100 steps: a filled
#: core converges slowly near the axis (25 steps left a core 15.9 % off with its true axis, 100 steps 6.7 %).
AXI_FILLS = 8
AXI_INNER = 100
#: ... and of each solve of the axis search (a shorter one: only the residual's minimum matters). 50 steps per fill,
#: chosen on the validation volumes (``python experiments/volume.py --set search``, ``results/volume_search.md``):
#: with 15 the trials had not converged near a filled core's axis and their residual's minimum lay off it (cores
#: 0.24 and 0.37 mm off in depth noise-free, 0.01 and 0.12 mm with 50), at about 1.7 times the search's time.
SEARCH_FILLS = 3
SEARCH_INNER = 50
#: Half width (mm) of the bracket the axis depth is searched in about its start, and the search's tolerance.
SEARCH_HALF_WIDTH_MM = 3.0
SEARCH_TOL_MM = 0.05
#: Spacing (mm) of the scan that picks the residual's basin before the bounded search refines within one
#: spacing of the scan's best: the short trials' residual is not unimodal over the bracket for a filled core
#: (a validation core at -1.6 mm, seed 603: the bounded search alone stopped at -0.87 mm, 3-D error 31.7 %).
SEARCH_SCAN_MM = 0.5
#: Weight of the one-sided light in :func:`_mirror_centre`'s cost. Chosen on validation sheaths (``experiments/volume.py
#: --set edge``'s ``EDGE_VAL`` scenes, in a ``/tmp`` probe at 100 rays per pixel): at 14 dB the sheath 11.5 % outside
#: the field has two mirror centres of symmetric cost 0.000, its axis (87 % of the light both sides) and its right limb
#: (28 %), and without the term the limb won (5.25 mm for an axis at 3.5 mm); 0.02 moved the sheath 28.5 % outside
#: 0.1 mm inward, 0.005 found both within 0.05 mm.
MIRROR_ONE_SIDED = 0.005
#: Light in the outermost column or row of the views summed over the aperture (the slope-0 image), as a share of
#: its brightest column's or row's, above which the light reaches that edge of the field (:func:`reaches_edge`): a
#: flame cut by it, whose light from beyond the field :func:`solve_axisymmetric` then models (:func:`wide_operator`).
EDGE_SHARE = 0.05


def _grid_coordinates(op, p):
    """Row heights (rows,) and column positions (cols,) in mm of plane ``p`` of ``op`` (y up, x right)."""
    _, gr, gc = op.dims
    h, w = op.sizes_mm[p]
    cy, cx = op.centres_mm[p] if hasattr(op, "centres_mm") else (0.0, 0.0)
    return cy + (0.5 - (np.arange(gr) + 0.5) / gr) * h, cx + ((np.arange(gc) + 0.5) / gc - 0.5) * w


def _frame_at(op, depth_mm):
    """Frame (height, width) in mm of the planes' grid at ``depth_mm``, linear in depth between the planes."""
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
        h_ref, w_ref = _frame_at(op, z0)
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


# ---- the solver ------------------------------------------------------------------------------
@dataclass
class AxisymmetricVolume:
    """What :func:`solve_axisymmetric` returns.

    Attributes
    ----------
    emission : ndarray of shape (rows, n_r), float64
        ``e`` at ``heights_mm`` x ``radii_mm`` (the planes' units), non-negative.
    radii_mm, heights_mm : ndarray
    volume : ndarray of shape (P, rows, cols), float64
        ``e`` revolved onto the operator's planes.
    axis_x_mm, axis_z_mm : float
        The axis used (given or found).
    residual : float
        ``||M (w H R e - y)|| / ||M y||`` on the fitted pixels ``M``.
    search : list of (float, float)
        Each axis depth tried by the search (mm) and its residual (empty when ``z0`` was given).
    time_s : float
        Wall time, seconds (normal matrices, search and solve).
    lam : float
        The smoothness weight used (given, or :data:`AXI_LAM` for the light field's noise).
    beyond_field : bool
        Whether the light from beyond the field was modelled (``solve_axisymmetric``'s
        ``beyond_field``); ``heights_mm`` then span the widened grid.
    """

    emission: np.ndarray
    radii_mm: np.ndarray
    heights_mm: np.ndarray
    volume: np.ndarray
    axis_x_mm: float
    axis_z_mm: float
    residual: float
    search: list = field(default_factory=list)
    time_s: float = float("nan")
    lam: float = float("nan")
    beyond_field: bool = False


class _Normal:
    """The exact operator's per-frequency normal matrices, full, frequencies first, for ``G x`` on planes."""

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
        # real G (every perfect grid): real and imaginary parts as two columns of one real product
        cdt = np.complex64 if self.G.dtype == np.float32 else np.complex128
        flat = np.ascontiguousarray(xs.reshape(P, -1).T, cdt)
        out = np.matmul(self.G, flat.view(self.G.dtype).reshape(len(flat), P, 2))
        return np.ascontiguousarray(out.view(cdt).reshape(len(flat), P).T).reshape(xs.shape)


def _difference_operator(rows, n_r):
    """First differences of ``e`` (rows, n_r) along the height and the radius, stacked (sparse)."""
    dy = scipy.sparse.kron(scipy.sparse.diags([-1.0, 1.0], [0, 1], shape=(rows - 1, rows)), scipy.sparse.eye(n_r))
    dx = scipy.sparse.kron(scipy.sparse.eye(rows), scipy.sparse.diags([-1.0, 1.0], [0, 1], shape=(n_r - 1, n_r)))
    return scipy.sparse.vstack([dy, dx]).tocsr()


def _check(views, op, fit):
    v = np.asarray(views, np.float64)
    if v.shape != tuple(op.dimsd):
        raise ValueError(f"views must have the operator's data shape {tuple(op.dimsd)}. Received: {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("views hold NaN or infinite values")
    if not hasattr(op, "_spec"):
        raise ValueError("solve_axisymmetric needs an ExactOperator (lf_flame.tomo.exact): its normal matrices")
    if op.subsamples != 1:
        raise ValueError(f"solve_axisymmetric works on the lenslet grid: give an ExactOperator with subsamples=1. "
                         f"Received subsamples={op.subsamples}")
    f = v < 1.0 if fit is None else np.asarray(fit)
    if f.shape != v.shape or f.dtype != bool:
        raise ValueError(f"fit must be boolean of the views' shape {v.shape}. Received: {f.dtype} of shape {f.shape}")
    return v, f


def _resized(e, dims):
    """``e`` (rows, n_r) cut or padded with zeros to ``dims`` along the radius; None stays None."""
    if e is None:
        return None
    out = np.zeros(dims)
    n = min(dims[1], e.shape[1])
    out[:, :n] = e[:, :n]
    return out.ravel()


def _fit_emission(op, normal, yt, y, w, m, lit, revolve, lam, fills, inner, e0=None):
    """Projected FISTA on ``e`` between fills of the missing data; returns (e, residual)."""
    P, gr, gc = op.dims
    canvas = op.canvas_shape
    S = op._spec
    real = np.float32 if S.dtype == np.complex64 else np.float64
    D = _difference_operator(*revolve.dims)
    norm = float(np.linalg.norm(np.where(m, y, 0.0))) or 1.0

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
        res2 = _fourier_kernels.fill(z, yt, y, w, m)
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


def reaches_edge(views) -> tuple:
    """Which edges of the field a light field's light reaches (a flame cut by the field's edge).

    The views summed over the aperture (the slope-0 image, which holds the light that
    parallax brings in from beyond the field), less its dark floor (its 5th percentile: the
    mean of clipped noise), are summed along rows and along columns; an edge is reached where
    the outermost column or row holds more than :data:`EDGE_SHARE` of the brightest one.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)

    Returns
    -------
    (bool, bool, bool, bool)
        Top, bottom, left, right.
    """
    img = np.clip(np.asarray(views, np.float64), 0.0, None).sum(axis=(0, 1))
    img = img - np.percentile(img, 5)
    rows, cols = img.sum(axis=1), img.sum(axis=0)
    top_r, top_c = EDGE_SHARE * rows.max(), EDGE_SHARE * cols.max()
    return (bool(rows[0] > top_r), bool(rows[-1] > top_r), bool(cols[0] > top_c), bool(cols[-1] > top_c))


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


def _lit_profile(views):
    """The central view's column sums (clipped at 0), those below 5 % of the largest set to 0: its lit columns."""
    c = views.shape[0] // 2
    prof = np.clip(np.asarray(views[c, c], np.float64), 0.0, None).sum(axis=0)
    return np.where(prof > 0.05 * prof.max(), prof, 0.0) if prof.max() > 0 else prof


def _mirror_centre(prof):
    """Column (fractional, every 0.1) about which ``prof`` is most nearly mirror-symmetric over the columns both
    sides hold: the lowest ``sum (p - q)^2 / sum (p^2 + q^2)`` there (``q`` the mirror image) plus
    :data:`MIRROR_ONE_SIDED` x the share of the light whose mirror falls beyond the view, so that a limb's own
    symmetry near the edge does not pass for the flame's."""
    C = len(prof)
    cols = np.arange(C)
    lit = np.flatnonzero(prof > 0)
    best, best_cost = None, np.inf
    for c0 in np.arange(lit[0], lit[-1] + 1e-9, 0.1):
        both = (cols >= 2 * c0 - (C - 1)) & (cols <= 2 * c0)
        p = prof[both]
        q = np.interp(2 * c0 - cols[both], cols, prof)
        energy = float(np.sum(p * p + q * q))
        if not energy > 0:
            continue
        cost = float(np.sum((p - q) ** 2)) / energy + MIRROR_ONE_SIDED * (1.0 - p.sum() / prof.sum())
        if cost < best_cost:
            best, best_cost = float(c0), cost
    return best


def axis_x_from_views(views, op, axis_z_mm: float, fit=None) -> float:
    """Lateral position (mm) of a vertical axis of symmetry: the central view's column centroid at depth ``axis_z_mm``.

    The central sub-aperture view is a pinhole image: its column ``c`` sees the plane
    sample ``c`` at every depth, so the centroid column of an axisymmetric flame's image is
    its axis's, and the axis's position is that column's on the grid at the axis's depth.
    Where the lit columns reach the view's edge (a flame cut by the field's edge) the
    centroid is pulled inward: the axis is then the column about which the lit profile is
    most nearly mirror-symmetric over the columns both sides hold.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    op : ExactOperator
    axis_z_mm : float
    fit : ndarray of bool or None
        Pixels to use (saturated ones still count: they bound the light from below).

    Returns
    -------
    float
        x0 in mm (x right, 0 on the optical axis).

    Raises
    ------
    ValueError
        A central view without light.
    """
    prof = _lit_profile(views)
    if not prof.sum() > 0:
        raise ValueError("the central view holds no light: no axis to find")
    cbar = float(np.sum(np.arange(len(prof)) * prof) / prof.sum())
    if prof[0] > 0 or prof[-1] > 0:
        cbar = _mirror_centre(prof)
    _, w = _frame_at(op, axis_z_mm)
    gc = op.dims[2]
    return ((cbar + 0.5) / gc - 0.5) * w


def solve_axisymmetric(views, op, fit=None, *, axis_x_mm: float | None = None, axis_z_mm: float | None = None,
                       r_max_mm: float | None = None, dr_mm: float | None = None, lam: float | None = None,
                       fills: int = AXI_FILLS, inner: int = AXI_INNER, search_half_width_mm: float = SEARCH_HALF_WIDTH_MM,
                       search_fills: int = SEARCH_FILLS, search_inner: int = SEARCH_INNER,
                       search_tol_mm: float = SEARCH_TOL_MM, start_z_mm: float | None = None, camera=None,
                       normal=None, beyond_field: bool | None = None) -> AxisymmetricVolume:
    """An axisymmetric flame's emission ``e(r, y)`` and its volume from one light field (module docstring).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The light field (radiance units), :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    op : ExactOperator
        The dense stack the volume is returned on (its planes should span the flame).
    fit : ndarray of bool of shape (N, N, R, C) or None
        Pixels to fit (False: saturated, left out); None: ``views < 1``.
    axis_x_mm, axis_z_mm : float or None
        The axis (mm); None: found (``x0`` by :func:`axis_x_from_views`, ``z0`` by the search).
    r_max_mm : float or None
        Outermost radius (mm); None: 0.6 x the width of the central view's lit columns at
        the axis's depth (a flame's half width with a margin); where they reach the view's
        edge, 1.2 x the distance from the axis to their farther end (the uncut side's).
    dr_mm : float or None
        Radial node spacing (:class:`RevolveOperator`).
    lam : float or None
        Weight of ``||D e||^2`` (first differences in ``y`` and ``r``) relative to the mean
        diagonal of ``R^T G R`` (>= 0); None: :data:`AXI_LAM` for the light field's noise level
        (:func:`lf_flame.tomo.noise_knobs.relative_noise` of the fitted pixels).
    fills, inner : int
        Fills of the missing data and FISTA steps per fill of the final solve (>= 1).
    search_half_width_mm, search_fills, search_inner, search_tol_mm : float, int, int, float
        The axis depth's search: bracket ``start ± half width`` (mm), each trial's shorter solve,
        the tolerance (mm). The bracket is scanned every :data:`SEARCH_SCAN_MM` first; the
        bounded search (Brent) then refines within one spacing of the scan's lowest residual.
    start_z_mm : float or None
        Start of the search; None: the depth of :func:`lf_flame.tomo.depth.find_depths` with the
        most votes (``camera``'s).
    camera : PlenopticCamera or None
        For :func:`~lf_flame.tomo.depth.find_depths`; None: ``op.camera``.
    normal : object or None
        Normal matrices from an earlier call (``result``'s operator cache); None: computed
        (and kept on the operator solved on).
    beyond_field : bool or None
        Model the flame's light from beyond the field: ``e`` is revolved onto the planes of
        :func:`wide_operator` (``op``'s planes widened by the kernels' reach) and fitted there,
        and the volume returned is its part on ``op``'s grid. None: when the light reaches
        the field's edge (:func:`reaches_edge`) and ``op`` has margin 1.

    Returns
    -------
    AxisymmetricVolume

    Raises
    ------
    ValueError
        Views not of the operator's shape or not finite; not an exact operator; a fit mask
        not boolean of the views' shape; iterations below 1; a negative or non-finite
        ``lam``; a non-positive search width or tolerance; a radius or axis the
        :class:`RevolveOperator` refuses.
    """
    t0 = time.perf_counter()
    v, f = _check(views, op, fit)
    if lam is None:
        lam = AXI_LAM[noise_regime(relative_noise(v, f))]
    for name, k in (("fills", fills), ("inner", inner), ("search_fills", search_fills), ("search_inner", search_inner)):
        if int(k) != k or k < 1:
            raise ValueError(f"{name} must be an integer >= 1. Received: {k!r}")
    if not (math.isfinite(lam) and lam >= 0):
        raise ValueError(f"lam must be finite and >= 0. Received: {lam!r}")
    if not (search_half_width_mm > 0 and search_tol_mm > 0):
        raise ValueError(f"search_half_width_mm and search_tol_mm must be > 0. Received: {search_half_width_mm!r}, "
                         f"{search_tol_mm!r}")
    if beyond_field is None:
        beyond_field = op.margin == 1 and any(reaches_edge(v))
    model = op
    if beyond_field:
        model = op.__dict__.get("_axisymmetric_wide") or wide_operator(op)
        op.__dict__["_axisymmetric_wide"] = model
    if normal is None:
        normal = model.__dict__.get("_axisymmetric_normal") or _Normal(model)
        model.__dict__["_axisymmetric_normal"] = normal
    lit = model._lit
    y, yt, w, m, _ = fill_data(v, f, model)

    lit_cols = np.flatnonzero(_lit_profile(v))
    cut = len(lit_cols) and (lit_cols[0] == 0 or lit_cols[-1] == v.shape[3] - 1)

    def revolve_at(z0):
        x0 = axis_x_from_views(v, op, z0, f) if axis_x_mm is None else float(axis_x_mm)
        rmax = r_max_mm
        if rmax is None:
            _, wz = _frame_at(op, z0)
            left, right = (np.array([lit_cols[0], lit_cols[-1] + 1]) / op.dims[2] - 0.5) * wz
            rmax = 1.2 * (max(x0 - left, right - x0) if cut else 0.5 * (right - left))   # cut: the far side's
        return RevolveOperator(model, x0, z0, rmax, dr_mm)

    search = []
    # on the widened grid the light beyond the field is known through the fills alone: each trial, and the final
    # solve, start from the best trial's e (from zero, 3 fills leave it dark and bias the residual's minimum)
    warm = {}
    if axis_z_mm is None:
        if start_z_mm is None:
            from .depth import find_depths
            found = find_depths(v, camera if camera is not None else op.camera)
            if not len(found.depths_mm):
                raise ValueError("find_depths found no flame in the views: give axis_z_mm or start_z_mm")
            start_z_mm = float(found.depths_mm[np.argmax(found.weight)])     # the flame's: the most votes

        def trial(z0):
            rev = revolve_at(z0)
            e, res = _fit_emission(model, normal, yt, y, w, m, lit, rev, lam, search_fills, search_inner,
                                   _resized(warm.get("e"), rev.dims) if beyond_field else None)
            search.append((float(z0), float(res)))
            if res < warm.get("residual", np.inf):
                warm.update(e=e.reshape(rev.dims), residual=res)
            return res
        lo, hi = start_z_mm - search_half_width_mm, start_z_mm + search_half_width_mm
        scan = np.linspace(lo, hi, max(int(round((hi - lo) / SEARCH_SCAN_MM)), 1) + 1)
        k = int(np.argmin([trial(z) for z in scan]))
        best = optimize.minimize_scalar(trial, bounds=(scan[max(k - 1, 0)], scan[min(k + 1, len(scan) - 1)]),
                                        method="bounded", options=dict(xatol=search_tol_mm))
        axis_z_mm = float(best.x)
    rev = revolve_at(float(axis_z_mm))
    e, res = _fit_emission(model, normal, yt, y, w, m, lit, rev, lam, fills, inner,
                           _resized(warm.get("e"), rev.dims) if beyond_field else None)
    (_, gr, gc), (_, wr, wc) = op.dims, model.dims
    volume = (rev.matrix @ e).reshape(model.dims)[:, (wr - gr) // 2:(wr + gr) // 2, (wc - gc) // 2:(wc + gc) // 2]
    return AxisymmetricVolume(emission=e.reshape(rev.dims), radii_mm=rev.radii_mm, heights_mm=rev.heights_mm,
                              volume=volume, axis_x_mm=rev.axis_x_mm, axis_z_mm=float(axis_z_mm), residual=float(res),
                              search=search, time_s=time.perf_counter() - t0, lam=float(lam),
                              beyond_field=bool(beyond_field))
