"""Numba kernels of :mod:`lf_flame.tomo.fourier`: the per-frequency sums over planes and views,
and the fill of the missing data, in one pass over memory each (threaded over views or
frequencies)."""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(parallel=True, cache=True, fastmath=False)
def forward(S, xs, out):
    """``out[v, m] = sum_k S[v, k, m] xs[k, m]``: S (V, P, M), xs (P, M), out (V, M), complex."""
    V, P, M = S.shape
    for v in nb.prange(V):
        for m in range(M):
            acc = S[v, 0, m] * xs[0, m]
            for k in range(1, P):
                acc += S[v, k, m] * xs[k, m]
            out[v, m] = acc


@nb.njit(parallel=True, cache=True, fastmath=False)
def adjoint(S, ys, out):
    """``out[k, m] = sum_v conj(S[v, k, m]) ys[v, m]``: S (V, P, M), ys (V, M), out (P, M), complex."""
    V, P, M = S.shape
    n_blocks = (M + 255) // 256
    for b in nb.prange(n_blocks):
        lo, hi = b * 256, min(M, b * 256 + 256)
        for k in range(P):
            for m in range(lo, hi):
                out[k, m] = 0
        for v in range(V):
            for k in range(P):
                for m in range(lo, hi):
                    out[k, m] += np.conj(S[v, k, m]) * ys[v, m]


@nb.njit(parallel=True, cache=True)
def fill(z, yt, y, w, mask):
    """Put the data ``yt`` into the canvas views ``z`` (V, Lr, Lc) where ``mask`` (V, R, C) holds,
    and return ``sum over mask of (w z - y)^2`` for the prediction that ``z`` held before."""
    V, R, C = y.shape
    part = np.zeros(V)
    for v in nb.prange(V):
        acc = 0.0
        for r in range(R):
            for c in range(C):
                if mask[v, r, c]:
                    d = w[v, r, c] * z[v, r, c] - y[v, r, c]
                    acc += d * d
                    z[v, r, c] = yt[v, r, c]
        part[v] = acc
    return part.sum()
