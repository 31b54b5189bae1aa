"""The exact operator's per-frequency normal matrices and their factors (the systems of Fourier ADMM).

Per spatial frequency ``f`` the map from the ``P`` planes to the views is a ``V x P`` matrix
``H(f)`` and ``H^H H`` is a ``P x P`` Hermitian matrix ``G(f)``
(:mod:`lf_flame.tomo.fourier`, which solves with them): here they are computed from the kernels'
taps (:func:`normal_matrices`), ``G + lam |D|^2 + rho`` factorised once per operator and weight
(:class:`FourierSystem`) and kept on the operator (:func:`fourier_system`, :func:`admm_system`).
``lam`` and ``rho`` are relative to ``g0``, the mean of ``G``'s diagonal at zero frequency.
"""
from __future__ import annotations

import math
import time

import numpy as np
import scipy.fft

from . import _fourier_kernels
from .defaults import ADMM_LAM, ADMM_RHO, ADMM_RHO_TV, ADMM_TV


#: Largest imaginary part of the normal matrices, relative to their largest entry, that is
#: float64 rounding: below it (a camera symmetric under a half turn of the views, as every
#: perfect grid is) they are real, and factorised and applied in real arithmetic.
REAL_TOLERANCE = 1e-9


def normal_matrices(op) -> np.ndarray:
    """The lower triangles of the exact operator's per-frequency normal matrices ``G(f) = H(f)^H H(f)``.

    Computed from the taps, not from the spectra: per pair of planes ``(k, l)``, the
    circular cross-correlation of their kernels summed over the views (at most
    ``V Ty Tx Ty Tx`` products, a few hundred thousand on the paper's camera), whose real FFT
    is ``G_lk`` (Wiener-Khinchin). On the paper's 4-plane stack this is some 50 x cheaper
    than the ``V P^2`` products per frequency of the spectra.

    Parameters
    ----------
    op : ExactOperator

    Returns
    -------
    G : ndarray of shape (P, P, Lr, Lc // 2 + 1), float64 or complex128
        ``G[l, k]`` for ``l >= k`` (the upper triangle is not written); float64 when every
        imaginary part is below :data:`REAL_TOLERANCE` of the largest entry.
    """
    h = np.ascontiguousarray(op.kernels, np.float64)
    oy = np.ascontiguousarray(op.tap_origin_y, np.int64)
    ox = np.ascontiguousarray(op.tap_origin_x, np.int64)
    P = h.shape[2]
    Lr, Lc = op.canvas_shape
    G = np.empty((P, P, Lr, Lc // 2 + 1), np.float64)
    for k in range(P):
        c = np.zeros((P - k, Lr, Lc))
        _fourier_kernels.correlate_taps(h, oy, ox, k, c)
        col = scipy.fft.rfft2(c, workers=op.workers)                  # conj(G_kl) = G_lk, l >= k
        if G.dtype == np.float64 and np.abs(col.imag).max() > REAL_TOLERANCE * np.abs(col).max():
            G = G.astype(np.complex128)                               # the columns so far were real
        G[k:, k] = col if G.dtype == np.complex128 else col.real
    return G


class FourierSystem:
    """The per-frequency Cholesky factors of ``G(f) + lam |D(f)|^2 + rho`` of an exact operator.

    Parameters
    ----------
    op : ExactOperator
    lam, rho : float
        Gradient weight and ADMM penalty, relative to :attr:`g0` (>= 0 and > 0).

    Attributes
    ----------
    g0 : float
        Mean of ``G``'s diagonal at zero frequency.
    factor : ndarray of shape (n_blocks, 1 or 2, P (P + 1) / 2, BLOCK)
        The lower Cholesky factors, computed in float64 (complex128 where ``G`` is complex),
        packed by rows in blocks of frequencies, real and imaginary parts apart, diagonals as
        their reciprocals (:func:`~lf_flame.tomo._fourier_kernels.factor_packed`: a block's
        factors lie together in memory) and kept in the operator's real precision (float32
        on a float32 operator: a solve reads them at every ADMM step, so their memory is the
        solves' time); frequency last, in SIMD lanes.
    spec : ndarray of shape (V', P, Lr, Lc // 2 + 1)
        The operator's spectra of its lit views (``op``'s own array, not a copy).
    lit : ndarray of int
        The views with light.
    setup_s : float
        Wall time of the construction, seconds.
    nbytes : int
        Memory of the factors.

    Raises
    ------
    ValueError
        A negative, zero (``rho``) or non-finite weight; a matrix that is not positive
        definite (NaN taps).
    """

    def __init__(self, op, lam: float = ADMM_LAM, rho: float = ADMM_RHO):
        t0 = time.perf_counter()
        if not (math.isfinite(lam) and math.isfinite(rho) and lam >= 0 and rho > 0):
            raise ValueError(f"lam must be finite and >= 0 and rho finite and > 0. Received: lam={lam!r}, rho={rho!r}")
        self.spec, self.lit = op._spec, op._lit
        G = normal_matrices(op)
        P, _, Lr, F = G.shape
        self.g0 = float(np.mean(np.diagonal(G[:, :, 0, 0]).real))
        lap = (4 * np.sin(np.pi * np.arange(Lr) / Lr)[:, None] ** 2
               + 4 * np.sin(np.pi * np.arange(F) / op.canvas_shape[1])[None, :] ** 2)   # |D(f)|^2, (Lr, F)
        for k in range(P):
            G[k, k] += self.g0 * (lam * lap + rho)
        self.factor, bad = _fourier_kernels.factor_packed(G.reshape(P, P, -1), op._real)
        del G
        if bad:
            raise ValueError(f"{bad} of the per-frequency normal matrices are not positive definite: the operator's "
                             "kernels hold NaN or infinite taps")
        self.lam, self.rho = float(lam), float(rho)
        self.nbytes = int(self.factor.nbytes)
        self.setup_s = time.perf_counter() - t0

    def solve(self, rhs):
        """``(G + lam |D|^2 + rho)^-1 rhs`` per frequency; rhs and result of shape (P, Lr, F), complex."""
        out = np.array(rhs, dtype=np.result_type(rhs.dtype, np.complex64), order="C")
        _fourier_kernels.cholesky_solve(self.factor, out.reshape(len(out), -1))
        return out


def fourier_system(op, lam: float = ADMM_LAM, rho: float = ADMM_RHO) -> FourierSystem:
    """The operator's :class:`FourierSystem` for ``(lam, rho)``, built once and kept on ``op``."""
    cache = op.__dict__.setdefault("_fourier_systems", {})
    key = (float(lam), float(rho))
    if key not in cache:
        if len(cache) >= 3:                                          # a few at a time: a dense stack's are large
            cache.pop(next(iter(cache)))
        cache[key] = FourierSystem(op, lam, rho)
    return cache[key]


def admm_system(op, lam: float = ADMM_LAM, tv: float = ADMM_TV, rho: float = ADMM_RHO,
                rho_tv: float = ADMM_RHO_TV) -> FourierSystem:
    """The :class:`FourierSystem` that :func:`~lf_flame.tomo.fourier.solve_admm` uses for these knobs (kept on ``op``):
    with TV on, its split's penalty ``rho_tv`` joins ``lam`` in the same per-frequency matrix.

    Raises
    ------
    ValueError
        ``lam`` negative or not finite, refused before ``rho_tv`` joins it (a negative ``lam`` with TV on had passed
        :class:`FourierSystem`'s check as ``lam + rho_tv`` and given planes of NaN); :class:`FourierSystem`'s errors.
    """
    check_lam(lam)
    return fourier_system(op, lam + (rho_tv if tv > 0 else 0.0), rho)


def check_lam(lam) -> None:
    """Refuse a gradient weight ``lam`` (admm's ``lam ||grad x||^2``) that is negative or not finite."""
    try:
        value = float(lam)
    except (TypeError, ValueError):
        value = math.nan
    if isinstance(lam, bool) or not (math.isfinite(value) and value >= 0):
        raise ValueError(f"lam, the weight of the planes' gradient (admm), must be a finite number >= 0: a negative "
                         f"weight rewards rough planes and the solve has no bounded answer (give lam=0 for none, or "
                         f"leave it None to take it from the data's noise). Received: lam={lam!r}")
