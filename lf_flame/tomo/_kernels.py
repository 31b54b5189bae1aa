"""Numba kernels of the reconstruction stage, serving :mod:`lf_flame.tomo`. Private:
they take only arrays and trust their inputs; the public, validating API is
:class:`lf_flame.tomo.operator`.

The emission operator's map, recorded once ray by ray by the simulator's own tracer
(:func:`lf_flame.simulate._kernels.render_backward` with ``record``: each ray's weight
and the texel it reads on each plane), is stored as a sparse matrix in compressed rows
(:func:`ray_table_to_csr`): one row per view pixel in the views' order (N, N, R, C),
the rays of a pixel that read the same texel merged into one entry. Applying it is a
gather (:func:`csr_forward`) or a scatter (:func:`csr_adjoint`) in float64, with no
tracing, no random numbers and no transpose between the raw image and the views.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _pixel_entries(tab_texel, tab_weight, i, j, cols, vals):
    """The merged (texel, weight) entries of raw pixel (i, j) into ``cols``/``vals``; their count."""
    K, L = tab_texel.shape[2], tab_texel.shape[3]
    m = 0
    for k in range(K):
        w = tab_weight[i, j, k]
        if w == 0.0:
            continue
        for li in range(L):
            t = tab_texel[i, j, k, li]
            if t < 0:
                continue
            e = 0
            while e < m and cols[e] != t:
                e += 1
            if e == m:
                cols[m] = t
                vals[m] = 0.0
                m += 1
            vals[e] += w
    return m


@njit(cache=True)
def _csr_rows(tab_texel, tab_weight, n_pix, p0, p1, indptr, indices, data, fill):
    """Rows ``p0 <= p < p1`` (views order): their entry counts into ``indptr[p + 1]``, or,
    with ``fill``, their entries at ``indptr[p]``."""
    H, W, K, L = tab_texel.shape
    R, C = H // n_pix, W // n_pix
    cols = np.empty(K * L, np.int32)
    vals = np.empty(K * L, np.float64)
    for p in range(p0, p1):
        c = p % C
        r = (p // C) % R
        v = (p // (C * R)) % n_pix
        u = p // (C * R * n_pix)
        m = _pixel_entries(tab_texel, tab_weight, r * n_pix + u, c * n_pix + v, cols, vals)
        if not fill:
            indptr[p + 1] = m
            continue
        for e in range(m):
            indices[indptr[p] + e] = cols[e]
            data[indptr[p] + e] = vals[e]


@njit(parallel=True, cache=True)
def ray_table_to_csr(tab_texel, tab_weight, n_pix, n_blocks):
    """Compressed rows of the recorded map, built in ``n_blocks`` parallel blocks of rows.

    ``tab_texel`` (H, W, K, L) int32 (-1: no texel), ``tab_weight`` (H, W, K) float32.
    Row ``p = ((u N + v) R + r) C + c`` is raw pixel ``(r N + u, c N + v)``. Returns
    ``indptr`` (H W + 1,) int64, ``indices`` int32 and ``data`` float32 (the rays' summed
    weights per texel).
    """
    n = tab_texel.shape[0] * tab_texel.shape[1]
    indptr = np.zeros(n + 1, np.int64)
    indices = np.empty(0, np.int32)
    data = np.empty(0, np.float32)
    for b in prange(n_blocks):
        _csr_rows(tab_texel, tab_weight, n_pix, b * n // n_blocks, (b + 1) * n // n_blocks, indptr, indices, data,
                  False)
    indptr = np.cumsum(indptr)
    indices = np.empty(indptr[n], np.int32)
    data = np.empty(indptr[n], np.float32)
    for b in prange(n_blocks):
        _csr_rows(tab_texel, tab_weight, n_pix, b * n // n_blocks, (b + 1) * n // n_blocks, indptr, indices, data,
                  True)
    return indptr, indices, data


@njit(parallel=True, cache=True)
def csr_forward(indptr, indices, data, x, n_blocks, out):
    """``out = A x``: ``x`` (n_texels,) float64, ``out`` (n_rows,) float64; rows in
    ``n_blocks`` parallel blocks."""
    n = out.shape[0]
    for b in prange(n_blocks):
        for p in range(b * n // n_blocks, (b + 1) * n // n_blocks):
            s = 0.0
            for e in range(indptr[p], indptr[p + 1]):
                s += data[e] * x[indices[e]]
            out[p] = s


@njit(parallel=True, cache=True)
def csr_adjoint(indptr, indices, data, y, grad):
    """``A^T y`` into ``grad`` (n_blocks, n_texels) float64, zeroed by the caller: one row per
    parallel block of rows, summed by the caller (a fixed block count keeps the sum
    bit-identical at any thread count)."""
    n = y.shape[0]
    n_blocks = grad.shape[0]
    for b in prange(n_blocks):
        g = grad[b]
        for p in range(b * n // n_blocks, (b + 1) * n // n_blocks):
            yy = y[p]
            if yy == 0.0:
                continue
            for e in range(indptr[p], indptr[p + 1]):
                g[indices[e]] += data[e] * yy
