"""Numba kernels of :mod:`lf_flame.tomo.lattice`: the lattice operator's kernels by quasi-Monte Carlo.

Each view's rays (points of the R_d sequence over a pixel and a lenslet cell) carried through the
affine ray chain onto every plane, binned at their nearest lattice site. Arrays and scalars only;
:func:`lf_flame.tomo.lattice.lattice_kernels` validates its inputs and draws the points.
"""
import math

import numpy as np
from numba import njit, prange

_H = math.sqrt(3) / 2


@njit(inline="always", cache=True)
def _nearest_site(y, x, hexagonal):
    """:func:`lf_flame.tomo.lattice.nearest_site` of one point: ``(j, i)``."""
    if not hexagonal:
        return math.floor(y + 0.5), math.floor(x + 0.5)
    j = math.floor(y / _H)
    i = np.rint(x - j / 2)
    d = (y - j * _H) ** 2 + (x - i - j / 2) ** 2
    j1 = j + 1
    i1 = np.rint(x - j1 / 2)
    if (y - j1 * _H) ** 2 + (x - i1 - j1 / 2) ** 2 < d:
        return j1, i1
    return j, i


@njit(parallel=True, cache=True)
def nearest_sites(y, x, hexagonal, j, i):
    """:func:`_nearest_site` of each point of ``y``, ``x`` (flat float64) into ``j``, ``i`` (int64)."""
    for n in prange(y.shape[0]):
        jj, ii = _nearest_site(y[n], x[n], hexagonal)
        j[n], i[n] = int(jj), int(ii)


@njit(inline="always", cache=True)
def _ray_sites(a, b, k, r, cy, cx, du_y, du_x, da_y, da_x, s, centre, hexagonal):
    """The fine lattice site of ray ``r`` of view ``(a, b)`` on plane ``k``."""
    y = s * (cy[a, k, 0] + cy[a, k, 1] * du_y[r] + cy[a, k, 2] * da_y[r] - 0.5) + centre
    x = s * (cx[b, k, 0] + cx[b, k, 1] * du_x[r] + cx[b, k, 2] * da_x[r] - 0.5) + centre
    return _nearest_site(y, x, hexagonal)


@njit(inline="always", cache=True)
def _lit(a, b, r, ay, ax, du_y, du_x, da_y, da_x, r2):
    hy = ay[a, 0] + ay[a, 1] * du_y[r] + ay[a, 2] * da_y[r]
    hx = ax[b, 0] + ax[b, 1] * du_x[r] + ax[b, 2] * da_x[r]
    return hy * hy + hx * hx <= r2


@njit(parallel=True, cache=True)
def lattice_bounds(cy, ay, cx, ax, du_y, du_x, da_y, da_x, r2, s, centre, hexagonal, bounds):
    """The sites any lit ray reaches, per view row ``a``: ``bounds[a] = (j_min, j_max, i_min, i_max)``
    (int64; ``j_min > j_max`` where no ray of that row passes the aperture)."""
    N, P = cy.shape[0], cy.shape[1]
    n = du_y.shape[0]
    for a in prange(N):
        jlo, jhi, ilo, ihi = 1 << 60, -(1 << 60), 1 << 60, -(1 << 60)
        for b in range(N):
            for r in range(n):
                if not _lit(a, b, r, ay, ax, du_y, du_x, da_y, da_x, r2):
                    continue
                for k in range(P):
                    j, i = _ray_sites(a, b, k, r, cy, cx, du_y, du_x, da_y, da_x, s, centre, hexagonal)
                    jlo, jhi = min(jlo, int(j)), max(jhi, int(j))
                    ilo, ihi = min(ilo, int(i)), max(ihi, int(i))
        bounds[a, 0], bounds[a, 1], bounds[a, 2], bounds[a, 3] = jlo, jhi, ilo, ihi


@njit(parallel=True, cache=True)
def lattice_taps(cy, ay, ty, cx, ax, tx, du_y, du_x, da_y, da_x, r2, use_cos4, s, centre, hexagonal, j0, i0, h):
    """Add each lit ray's weight (``1 / n``, times cos^4 of its angle with ``use_cos4``) to the tap of the
    site it reaches: ``h`` (N, N, P, n_j, n_i) float64, site ``(j, i)`` at ``[j - j0, i - i0]``, summed in
    the rays' order per tap. Threads over view rows (each writes its own ``h[a]``)."""
    N, P = cy.shape[0], cy.shape[1]
    n = du_y.shape[0]
    for a in prange(N):
        for b in range(N):
            for r in range(n):
                if not _lit(a, b, r, ay, ax, du_y, du_x, da_y, da_x, r2):
                    continue
                w = 1.0
                if use_cos4:
                    ang_y = ty[a, 0] + ty[a, 1] * du_y[r] + ty[a, 2] * da_y[r]
                    ang_x = tx[b, 0] + tx[b, 1] * du_x[r] + tx[b, 2] * da_x[r]
                    w = 1.0 / (1.0 + ang_y * ang_y + ang_x * ang_x) ** 2
                w = w / n
                for k in range(P):
                    j, i = _ray_sites(a, b, k, r, cy, cx, du_y, du_x, da_y, da_x, s, centre, hexagonal)
                    h[a, b, k, int(j) - j0, int(i) - i0] += w
