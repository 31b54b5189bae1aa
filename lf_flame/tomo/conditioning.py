"""The exact operator's per-frequency conditioning: the views' kernel responses ``H_vk(f)``, the stack's normal
matrix ``G(f)`` and the condition number of every pair of planes' 2 x 2 block, from which
:mod:`lf_flame.tomo.resolution` maps the camera's depth resolution (its docstring holds the physics and sources).
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .quadrature import ExactKernels


def _sample_mm(kern: ExactKernels, axis: str) -> np.ndarray:
    """Each plane's sample size (mm) along the frequency's direction, (P,)."""
    P, gr, gc = kern.dims
    rows = np.array([s[0] for s in kern.sizes_mm]) / gr
    cols = np.array([s[1] for s in kern.sizes_mm]) / gc
    return {"rows": rows, "columns": cols, "diagonal": 0.5 * (rows + cols)}[axis]


def kernel_response(kern: ExactKernels, freq, planes, axis: str = "rows") -> np.ndarray:
    """The views' kernel responses ``H_vk(f)``: the Fourier transform over lenslets of each
    view's kernel on a plane, at one lateral frequency per entry.

    ``H_vk(f) = sum_{m, n} h[u, v, k, m, n] exp(2 pi i (f_y (oy[u, k] + m) + f_x (ox[v, k] + n)))``
    with the taps' offsets ``oy``, ``ox`` (:class:`~lf_flame.tomo.quadrature.ExactKernels`): the
    spectrum :class:`~lf_flame.tomo.exact.ExactOperator` applies, at any frequency.

    Parameters
    ----------
    kern : ExactKernels
    freq : array_like of shape (Q,)
        Frequencies, cycles per lenslet (= per plane sample).
    planes : array_like of int, shape (Q,)
        The plane of each entry.
    axis : {"rows", "columns", "diagonal"}
        ``(f_y, f_x) = (f, 0)``, ``(0, f)`` or ``(f, f) / sqrt 2``.

    Returns
    -------
    H : ndarray of shape (Q, N * N), complex128
        Views in row-major order ``(u, v)``.
    """
    return _response(kern, _reduced(kern, axis), freq, planes, axis)


def _reduced(kern: ExactKernels, axis: str) -> np.ndarray:
    """The kernels plane first, summed over the taps the frequency does not vary along:
    (P, N, N, Ty) for rows, (P, N, N, Tx) for columns, (P, N, N, Ty, Tx) for the diagonal."""
    h = np.moveaxis(kern.kernels, 2, 0)
    return np.ascontiguousarray({"rows": lambda: h.sum(-1), "columns": lambda: h.sum(-2), "diagonal": lambda: h}[axis]())


def _response(kern: ExactKernels, red: np.ndarray, freq, planes, axis: str) -> np.ndarray:
    """:func:`kernel_response` on the kernels :func:`_reduced` for ``axis``."""
    f = np.asarray(freq, np.float64).ravel()
    k = np.asarray(planes, np.int64).ravel()
    N, _, _, Ty, Tx = kern.kernels.shape
    fy, fx = {"rows": (f, 0 * f), "columns": (0 * f, f), "diagonal": (f / math.sqrt(2), f / math.sqrt(2))}[axis]
    py = np.exp(2j * np.pi * fy[:, None, None] * (kern.tap_origin_y[:, k].T[:, :, None] + np.arange(Ty)))  # (Q, N, Ty)
    px = np.exp(2j * np.pi * fx[:, None, None] * (kern.tap_origin_x[:, k].T[:, :, None] + np.arange(Tx)))  # (Q, N, Tx)
    if axis == "rows":
        H = np.einsum("qut,quvt->quv", py, red[k]) * px[:, None, :, 0]
    elif axis == "columns":
        H = np.einsum("qvs,quvs->quv", px, red[k]) * py[:, :, None, 0]
    else:
        H = np.einsum("qut,qvs,quvts->quv", py, px, red[k], optimize=True)
    return H.reshape(len(k), N * N)


def normal_matrix(kern: ExactKernels, freq: float, axis: str = "rows") -> np.ndarray:
    """The stack's normal matrix at one lateral frequency, ``G(f) = sum_v conj(H_v) H_v^T``.

    Parameters
    ----------
    kern : ExactKernels
    freq : float
        Cycles per lenslet.
    axis : {"rows", "columns", "diagonal"}

    Returns
    -------
    G : ndarray of shape (P, P), complex128, Hermitian positive semi-definite
        ``G[k, l] = sum_v conj(H_vk) H_vl``, the planes in the kernels' order.
    """
    P = kern.dims[0]
    H = kernel_response(kern, np.full(P, float(freq)), np.arange(P), axis)    # (P, V)
    return H.conj() @ H.T


def _cond2(Hi, Hj) -> np.ndarray:
    """Condition numbers of the 2 x 2 normal matrices of response pairs (Q, V) -> (Q,)."""
    a = np.einsum("qv,qv->q", Hi.conj(), Hi).real
    c = np.einsum("qv,qv->q", Hj.conj(), Hj).real
    b = np.einsum("qv,qv->q", Hi.conj(), Hj)
    big = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + np.abs(b) ** 2)
    det = a * c - np.abs(b) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(det > 1e-13 * big * big, big * big / det, np.inf)


def pair_conditions(kern: ExactKernels, feature_mm: float, axis: str = "rows") -> np.ndarray:
    """Condition number of the 2 x 2 normal block of every pair of planes, for one feature size.

    Parameters
    ----------
    kern : ExactKernels
        Of a stack of evenly spaced planes in increasing depth.
    feature_mm : float
        Half a period, mm; the pair ``(i, j)`` is read at ``f = (a_i + a_j) / (4 s)`` cycles
        per lenslet (module docstring).
    axis : {"rows", "columns", "diagonal"}

    Returns
    -------
    cond : ndarray of shape (P - 1, P - 1), float64
        ``cond[s - 1, i]`` for planes ``i`` and ``i + s``; NaN where ``i + s >= P`` and where
        the feature is finer than either plane's sample (``f > 0.5``); ``inf`` where the
        block is singular to rounding.
    """
    P = kern.dims[0]
    a = _sample_mm(kern, axis)
    red = _reduced(kern, axis)
    out = np.full((P - 1, P - 1), np.nan)
    for s in range(1, P):
        i = np.arange(P - s)
        j = i + s
        f = (a[i] + a[j]) / (4.0 * feature_mm)
        ok = np.maximum(a[i], a[j]) / (2.0 * feature_mm) <= 0.5
        if ok.any():
            i, j, f = i[ok], j[ok], f[ok]
            out[s - 1, i] = _cond2(_response(kern, red, f, i, axis), _response(kern, red, f, j, axis))
    return out
