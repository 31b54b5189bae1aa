"""Numba kernel of :mod:`lf_flame.tomo.revolve`: the per-frequency normal matrices applied to the planes'
spectra in one threaded pass."""
from __future__ import annotations

import numpy as np
from numba import njit, prange

#: Frequencies per task of :func:`normal_apply`: their spectra on every plane, gathered once, stay in cache
#: while the frequencies' matrices stream past.
CHUNK = 64


@njit(parallel=True, cache=True, fastmath={'contract'})
def normal_apply(G, xs, out):
    """``out[:, f] = G[f] xs[:, f]`` for every frequency ``f``: ``G`` (F, P, P) real, ``xs`` and ``out`` (P, F)
    complex (the planes' spectra, flattened over the canvas's frequencies). Each chunk of :data:`CHUNK`
    frequencies gathered into real and imaginary rows (F, P) first, so that every sum runs over contiguous
    memory (the compiler vectorises it, in ``G``'s precision). Threads over the chunks."""
    F, P = G.shape[0], G.shape[1]
    for c in prange((F + CHUNK - 1) // CHUNK):
        f0, f1 = c * CHUNK, min(F, (c + 1) * CHUNK)
        xr = np.empty((f1 - f0, P), G.dtype)
        xi = np.empty((f1 - f0, P), G.dtype)
        for k in range(P):
            for f in range(f0, f1):
                xr[f - f0, k] = xs[k, f].real
                xi[f - f0, k] = xs[k, f].imag
        for f in range(f0, f1):
            g, a, b = G[f], xr[f - f0], xi[f - f0]
            for i in range(P):
                sr = g[i, 0] * a[0]
                si = g[i, 0] * b[0]
                for k in range(1, P):
                    sr += g[i, k] * a[k]
                    si += g[i, k] * b[k]
                out[i, f] = sr + 1j * si
