"""Numba kernel of :mod:`lf_flame.tomo.refine`: a plane's predicted views' derivative in its slope, in one
threaded pass over the views."""
from __future__ import annotations

from numba import njit, prange


@njit(parallel=True, cache=True)
def slope_derivative(a, u, fit, out):
    """``out = -(u_i d/dr + u_j d/dc) a`` where ``fit``, else 0: ``a``, ``fit`` and ``out`` (N, N, R, C) (float64,
    bool, float64), ``u`` (N,) each view's offset from the centre (view steps). Each derivative is the five-point
    central one, ``(a[-2] - 8 a[-1] + 8 a[+1] - a[+2]) / 12`` along the lenslets' rows or columns, the edges padded
    by their values. Threads over views."""
    N, _, R, C = a.shape
    for task in prange(N * N):
        i, j = task // N, task % N
        g = a[i, j]
        for r in range(R):
            r0, r1, r3, r4 = max(r - 2, 0), max(r - 1, 0), min(r + 1, R - 1), min(r + 2, R - 1)
            for c in range(C):
                if not fit[i, j, r, c]:
                    out[i, j, r, c] = 0.0
                    continue
                c0, c1, c3, c4 = max(c - 2, 0), max(c - 1, 0), min(c + 1, C - 1), min(c + 2, C - 1)
                dr = (g[r0, c] - 8 * g[r1, c] + 8 * g[r3, c] - g[r4, c]) / 12.0
                dc = (g[r, c0] - 8 * g[r, c1] + 8 * g[r, c3] - g[r, c4]) / 12.0
                out[i, j, r, c] = -(u[i] * dr + u[j] * dc)
