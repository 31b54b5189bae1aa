"""Numba kernels of :mod:`lf_flame.tomo.focus`: the focus measures of a refocused stack.

Each pass is SciPy's ``ndimage.correlate1d`` with ``mode="reflect"`` (``d c b a | a b c d | d c b a``) as its
C loop sums (the kernel's centre tap first, then the pairs of taps at ``-j`` and ``+j`` from the farthest in,
added for a symmetric kernel and subtracted for an antisymmetric one), so that the Tenengrad energy
``ndimage.sobel(im, 0) ** 2 + ndimage.sobel(im, 1) ** 2`` and the squared ``ndimage.laplace(im)``, each smoothed
by ``ndimage.gaussian_filter``, come out the same to the last bit, one thread per image of the stack.
Arrays and scalars only; :func:`lf_flame.tomo.focus._focus_energy` builds the Gaussian's taps.
"""
import numpy as np
from numba import njit, prange


@njit(inline="always", cache=True)
def _mirror(i, n):
    """Index ``i`` of a line of ``n`` samples extended by reflection, period ``2 n``."""
    if 0 <= i < n:
        return i
    i %= 2 * n
    return i if i < n else 2 * n - 1 - i


@njit(cache=True)
def _gaussian(e, w, tmp, out):
    """``out`` = ``e`` (R, C) correlated with the symmetric taps ``w`` (2 r + 1) along rows, then columns. Each
    output sums as SciPy's does; the taps' loop runs outside the columns' so that the columns' loop vectorises."""
    R, C = e.shape
    r = (w.shape[0] - 1) // 2
    for i in range(R):
        row = tmp[i]
        for j in range(C):
            row[j] = e[i, j] * w[r]
        for k in range(-r, 0):
            a, b, wk = e[_mirror(i + k, R)], e[_mirror(i - k, R)], w[r + k]
            for j in range(C):
                row[j] += (a[j] + b[j]) * wk
    lo, hi = min(r, C), max(C - r, min(r, C))          # the columns whose taps all fall inside the row
    for i in range(R):
        t, o = tmp[i], out[i]
        for j in range(C):
            o[j] = t[j] * w[r]
        for k in range(-r, 0):
            wk = w[r + k]
            for j in range(lo):
                o[j] += (t[_mirror(j + k, C)] + t[_mirror(j - k, C)]) * wk
            for j in range(lo, hi):
                o[j] += (t[j + k] + t[j - k]) * wk
            for j in range(hi, C):
                o[j] += (t[_mirror(j + k, C)] + t[_mirror(j - k, C)]) * wk


@njit(parallel=True, cache=True)
def focus_measures(stack, w, laplacian, ten, lap):
    """Per image of ``stack`` (S, R, C) float64: ``ten`` (S, R, C) the Gaussian-smoothed (taps ``w``) squared Sobel
    gradient, and with ``laplacian`` ``lap`` (S, R, C) the smoothed squared Laplacian (module docstring)."""
    S, R, C = stack.shape
    for s in prange(S):
        im = stack[s]
        d = np.empty((R, C))
        gy = np.empty((R, C))
        e = np.empty((R, C))
        tmp = np.empty((R, C))
        for i in range(R):                               # sobel(im, 0): [-1, 0, 1] along rows, [1, 2, 1] along columns
            im_m, im_p = im[_mirror(i - 1, R)], im[_mirror(i + 1, R)]
            for j in range(C):
                acc = im[i, j] * 0.0
                acc += (im_m[j] - im_p[j]) * -1.0
                d[i, j] = acc
        for i in range(R):
            for j in range(C):
                acc = d[i, j] * 2.0
                acc += (d[i, _mirror(j - 1, C)] + d[i, _mirror(j + 1, C)]) * 1.0
                gy[i, j] = acc
        for i in range(R):                               # sobel(im, 1): [-1, 0, 1] along columns, [1, 2, 1] rows
            for j in range(C):
                acc = im[i, j] * 0.0
                acc += (im[i, _mirror(j - 1, C)] - im[i, _mirror(j + 1, C)]) * -1.0
                d[i, j] = acc
        for i in range(R):
            d_m, d_p = d[_mirror(i - 1, R)], d[_mirror(i + 1, R)]
            for j in range(C):
                acc = d[i, j] * 2.0
                acc += (d_m[j] + d_p[j]) * 1.0
                e[i, j] = gy[i, j] * gy[i, j] + acc * acc
        _gaussian(e, w, tmp, ten[s])
        if laplacian:                                    # laplace(im): [1, -2, 1] along rows plus along columns
            for i in range(R):
                im_m, im_p = im[_mirror(i - 1, R)], im[_mirror(i + 1, R)]
                for j in range(C):
                    a = im[i, j] * -2.0
                    a += (im_m[j] + im_p[j]) * 1.0
                    b = im[i, j] * -2.0
                    b += (im[i, _mirror(j - 1, C)] + im[i, _mirror(j + 1, C)]) * 1.0
                    v = a + b
                    e[i, j] = v * v
            _gaussian(e, w, tmp, lap[s])
