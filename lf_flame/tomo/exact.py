"""The camera's exact linear map, emission on planes -> views, as convolutions applied by FFT.

:class:`~lf_flame.tomo.operator.EmissionOperator` is the renderer with a few fixed random
rays per pixel: a Monte-Carlo estimate of the camera. :class:`ExactOperator` is the map
the renderer estimates, computed from the same ray chain
(:func:`lf_flame.simulate.tracer.trace_coefficients`, the backward ABCD chain of
:func:`lf_flame.simulate.tracer.backward_chain`) by deterministic quadrature, with no ray
sampled at random.

Why it is a convolution. On the plane grid of :func:`~lf_flame.tomo.operator.plane_grid`
(one sample per lenslet footprint) the texel coordinate of every plane steps by exactly
one sample per lenslet, and the ray of a given pixel within its lenslet image (view
``(u, v)``) meets the main lens at the same point whatever the lenslet: the texel a ray
reads is ``(r + m, c + n)`` with ``(m, n)`` set by the ray's samples alone, and the
aperture that clips it does not depend on the lenslet ``(r, c)``. So per view and plane
the map is a 2-D correlation over lenslets with a small kernel,

    ``views[u, v, r, c] = w[u, v, r, c] * sum_k sum_{m, n} h[u, v, k, m, n] x[k, r + m, c + n]``,

``x`` zero outside its grid. Only cos^4 drifts across the field (the ray's angle between
the lenslet array and the main lens changes with the lenslet): it is the per-pixel weight
``w``, 1 on the axis.

The kernels. ``h[u, v, k, m, n]`` is the mean, over the pixel's rays (its area times the
lenslet aperture: four sample coordinates ``du_y, da_y, du_x, da_x`` in [-1/2, 1/2), as
the renderer draws them), of aperture x cos^4 x [the ray reads texel offset (m, n)].
Per axis every traced quantity is affine in ``(du, da)``
(:func:`lf_flame.simulate._kernels.axis_coefficients`). The quadrature
(:func:`_kernel_quadrature`): ``da`` by Gauss-Legendre on the pieces between the values
where a texel boundary crosses a pixel edge (so each piece's integrand is smooth);
``du``, for each ``da`` node and tap, exactly: the interval of ``du`` reading that tap is
an interval of main-lens heights, so a pair of them (one per axis) is a rectangle on the
main lens, and its part inside the aperture disc, area and centroid, is computed in
closed form. cos^4 over that part to second order about its centroid (the angle is
affine in the height). cos^4 is taken at the field centre, its drift across the field
being ``w``: the ratio of the pixel's mean cos^4 (second-order moment expansion about
its rays' mean angle) to the centre's.

What is left out. The renderer looks texels up nearest and in float32; the quadrature
is in float64. The factorisation ``w * h`` leaves out the cos^4 drift *within* one
pixel's rays across the field (how weight moves between taps from the centre to the
rim); on the paper's camera the whole map stays within the 1,024-ray traced operator's
noise (below). Crosstalk (rays through the neighbouring lenslets) is not modelled: an
f-number-matched camera has none (the aperture stops every such ray), and it would cost
one convolution per neighbour.

Applied by FFT: ``x`` zero-padded to a canvas (``canvas_shape``) longer than the grid by
the largest kernel offset (no wrap-around reaches the views), SciPy's real 2-D FFTs
batched over planes and views, the per-frequency sum over planes (``A``) or views
(``A^T``, the conjugate kernels), and the inverse FFT cropped to the lenslet grid. The
adjoint is the exact transpose: the same kernels conjugated, padding and cropping swapped.

Precision: ``precision="float64"`` (the default) keeps the kernels' spectra complex128 and
the FFTs in float64: ``pylops.utils.dottest`` holds to 1e-12 and A^T is A's transpose to
float64 rounding, which the solvers' step sizes and the tests rely on. ``"float32"``
halves the kernels' memory and the FFTs' traffic; its rounding (~1e-7 relative) is far
below any data's noise, so it is for large stacks (``experiments/exact_operator.py``
measures both).
"""
from __future__ import annotations

import math
import os
import time

import numpy as np
import pylops
import scipy.fft
from numba import njit, prange

from ..optics.camera import PlenopticCamera
from ..simulate.scenes import FLAME_EFFECTS, Effects, Layer, Scene
from ..simulate.tracer import _stack_layers, trace_coefficients
from .operator import plane_grid

#: Gauss-Legendre nodes per smooth piece of a pixel's ``da`` range (per axis). Against 32
#: nodes: largest tap off by 5.8e-5 of the largest tap, 5.6e-6 of the kernels' sum in all
#: (4 nodes: 2.0e-4, 2.3e-5; ``tests/test_exact_operator.py``).
QUADRATURE_NODES = 6
#: Largest deviation (texels, main-lens mm, radians) of a lenslet's chain from the first
#: lenslet's shifted by whole samples: above it the map is not a convolution.
SHIFT_TOLERANCE = 1e-6
PRECISIONS = ("float64", "float32")


# ---- quadrature of the kernels (Numba) -----------------------------------------------------
@njit(inline="always", cache=True)
def _half_disc(y, r):
    """Area of the disc of radius ``r`` (centred at 0) above the line ``Y = y``."""
    if y >= r:
        return 0.0
    if y <= -r:
        return math.pi * r * r
    return r * r * math.acos(y / r) - y * math.sqrt(r * r - y * y)


@njit(inline="always", cache=True)
def _half_moment(y, r):
    """First moment (along Y) of the disc above ``Y = y``: ``2/3 (r^2 - y^2)^(3/2)``."""
    if abs(y) >= r:
        return 0.0
    return 2.0 / 3.0 * (r * r - y * y) ** 1.5


@njit(inline="always", cache=True)
def _arc(x, r):
    """``int_0^x sqrt(r^2 - X^2) dX`` for ``0 <= x <= r``."""
    return 0.5 * (x * math.sqrt(max(r * r - x * x, 0.0)) + r * r * math.asin(min(x / r, 1.0)))


@njit(inline="always", cache=True)
def _corner_pos(x, y, r):
    """Area and first moments (X, Y) of the disc within ``X >= x, Y >= y``, ``x, y >= 0``."""
    if x * x + y * y >= r * r:
        return 0.0, 0.0, 0.0
    sx = math.sqrt(r * r - y * y)
    area = _arc(sx, r) - _arc(x, r) - y * (sx - x)
    mx = ((r * r - x * x) ** 1.5 - y ** 3) / 3.0 - 0.5 * y * (sx * sx - x * x)
    my = 0.5 * ((r * r - y * y) * (sx - x) - (sx ** 3 - x ** 3) / 3.0)
    return area, mx, my


@njit(inline="always", cache=True)
def _corner(x, y, r):
    """Area and first moments (X, Y) of the disc within ``X >= x, Y >= y`` (any signs), by
    the disc's mirror symmetries."""
    if x >= 0.0 and y >= 0.0:
        return _corner_pos(x, y, r)
    if x < 0.0 and y >= 0.0:
        a, mx, my = _corner_pos(-x, y, r)
        return _half_disc(y, r) - a, mx, _half_moment(y, r) - my
    if x >= 0.0:
        a, mx, my = _corner_pos(x, -y, r)
        return _half_disc(x, r) - a, _half_moment(x, r) - mx, my
    a, mx, my = _corner_pos(-x, -y, r)
    return (math.pi * r * r - _half_disc(-x, r) - _half_disc(-y, r) + a, _half_moment(-x, r) - mx,
            _half_moment(-y, r) - my)


@njit(cache=True)
def _clip_to_disc(y0, y1, x0, x1, r):
    """The part of the rectangle ``[y0, y1] x [x0, x1]`` (mm, ``y`` along Y) inside the disc
    of radius ``r`` (``r <= 0``: no disc): its fraction of the rectangle's area and the
    offset of its centroid from the rectangle's centre (dy, dx)."""
    if r <= 0.0:
        return 1.0, 0.0, 0.0
    if max(y0 * y0, y1 * y1) + max(x0 * x0, x1 * x1) <= r * r:
        return 1.0, 0.0, 0.0
    ny = 0.0 if y0 <= 0.0 <= y1 else min(y0 * y0, y1 * y1)
    nx = 0.0 if x0 <= 0.0 <= x1 else min(x0 * x0, x1 * x1)
    if ny + nx >= r * r:
        return 0.0, 0.0, 0.0
    a00, x00, y00 = _corner(x0, y0, r)
    a10, x10, y10 = _corner(x1, y0, r)
    a01, x01, y01 = _corner(x0, y1, r)
    a11, x11, y11 = _corner(x1, y1, r)
    area = a00 - a10 - a01 + a11
    if area <= 0.0:
        return 0.0, 0.0, 0.0
    mx = (x00 - x10 - x01 + x11) / area - 0.5 * (x0 + x1)
    my = (y00 - y10 - y01 + y11) / area - 0.5 * (y0 + y1)
    return min(area / ((y1 - y0) * (x1 - x0)), 1.0), my, mx


@njit(cache=True)
def _axis_points(c, A, B, a0, a1, a2, t0, t1, t2, m0, n_taps, xg, wg, tap, wt, lo_mm, hi_mm, angle, slope, var):
    """Quadrature points of one axis of one view and plane; returns how many were written.

    Texel coordinate ``c + A du + B da``, main-lens height ``a0 + a1 du + a2 da`` (mm,
    ``a1 != 0``), angle ``t0 + t1 du + t2 da`` (rad), ``du, da`` in [-1/2, 1/2]. ``da`` is
    split where a texel boundary meets ``du = +-1/2`` and each piece integrated by
    Gauss-Legendre (``xg, wg`` on [-1, 1]); ``du`` exactly: for each ``da`` node and tap
    ``m0 + m`` the point holds the tap ``m``, the weight (``da`` weight x the length of the
    ``du`` interval reading that tap), that interval's main-lens heights (mm), its angle
    at the interval's middle, the angle's slope per mm of height and its variance over
    the interval.
    """
    bp = np.empty(4 + 2 * (n_taps + 2))
    bp[0] = -0.5
    bp[1] = 0.5
    nb = 2
    if B != 0.0:
        for s in (-0.5 * A, 0.5 * A):
            v0 = c + s - 0.5 * abs(B)
            v1 = c + s + 0.5 * abs(B)
            for j in range(int(math.floor(v0)) + 1, int(math.ceil(v1))):
                da = (j - c - s) / B
                if -0.5 < da < 0.5 and nb < bp.shape[0]:
                    bp[nb] = da
                    nb += 1
    bps = np.sort(bp[:nb])
    n = 0
    for seg in range(nb - 1):
        d0, d1 = bps[seg], bps[seg + 1]
        if d1 <= d0:
            continue
        half, mid = 0.5 * (d1 - d0), 0.5 * (d1 + d0)
        for g in range(xg.shape[0]):
            da = mid + half * xg[g]
            w = half * wg[g]
            base = c + B * da
            for m in range(n_taps):
                mm = m0 + m
                if A > 0.0:
                    lo, hi = (mm - base) / A, (mm + 1 - base) / A
                elif A < 0.0:
                    lo, hi = (mm + 1 - base) / A, (mm - base) / A
                elif math.floor(base) == mm:
                    lo, hi = -0.5, 0.5
                else:
                    continue
                lo = max(lo, -0.5)
                hi = min(hi, 0.5)
                if hi <= lo:
                    continue
                e0 = a0 + a1 * lo + a2 * da
                e1 = a0 + a1 * hi + a2 * da
                tap[n] = m
                wt[n] = w * (hi - lo)
                lo_mm[n] = min(e0, e1)
                hi_mm[n] = max(e0, e1)
                angle[n] = t0 + t1 * 0.5 * (lo + hi) + t2 * da
                slope[n] = t1 / a1
                var[n] = (t1 * (hi - lo)) ** 2 / 12.0
                n += 1
    return n


@njit(parallel=True, cache=True)
def _kernel_quadrature(cy, ay, ty, m0y, cx, ax, tx, n0x, n_taps_y, n_taps_x, radius, use_cos4, xg, wg, h, moments):
    """Kernels ``h`` (Nu, Nv, P, n_taps_y, n_taps_x) and, per view, the moments of its rays'
    angles (``moments`` (Nu, Nv, 6): mass, mean ty, mean tx, var ty, cov, var tx).

    ``cy`` (Nu, P, 3): texel coefficients (constant, du, da) of each view row ``u`` and
    plane; ``ay``, ``ty`` (Nu, 3): main-lens height and angle coefficients (angle at the
    reference lenslet); ``m0y`` (Nu, P) int64: first tap; ``cx``... the same along x.
    ``radius`` of the aperture (mm; <= 0: none). Each pair of points (one per axis) is a
    rectangle of main-lens heights: its part inside the aperture exactly (area and
    centroid in closed form), cos^4 over it to second order about its centroid.
    """
    Nu, P = cy.shape[0], cy.shape[1]
    Nv = cx.shape[0]
    n_g = xg.shape[0]
    cap_y = n_g * (3 + 2 * (n_taps_y + 2)) * n_taps_y
    cap_x = n_g * (3 + 2 * (n_taps_x + 2)) * n_taps_x
    for uv in prange(Nu * Nv):
        u = uv // Nv
        v = uv % Nv
        tp_y = np.empty(cap_y, np.int64)
        w_y = np.empty(cap_y)
        l_y = np.empty(cap_y)
        u_y = np.empty(cap_y)
        a_y = np.empty(cap_y)
        s_y = np.empty(cap_y)
        v_y = np.empty(cap_y)
        tp_x = np.empty(cap_x, np.int64)
        w_x = np.empty(cap_x)
        l_x = np.empty(cap_x)
        u_x = np.empty(cap_x)
        a_x = np.empty(cap_x)
        s_x = np.empty(cap_x)
        v_x = np.empty(cap_x)
        for k in range(P):
            ny = _axis_points(cy[u, k, 0], cy[u, k, 1], cy[u, k, 2], ay[u, 0], ay[u, 1], ay[u, 2],
                              ty[u, 0], ty[u, 1], ty[u, 2], m0y[u, k], n_taps_y, xg, wg, tp_y, w_y, l_y, u_y, a_y,
                              s_y, v_y)
            nx = _axis_points(cx[v, k, 0], cx[v, k, 1], cx[v, k, 2], ax[v, 0], ax[v, 1], ax[v, 2],
                              tx[v, 0], tx[v, 1], tx[v, 2], n0x[v, k], n_taps_x, xg, wg, tp_x, w_x, l_x, u_x, a_x,
                              s_x, v_x)
            s0 = sy = sx = syy = sxy = sxx = 0.0
            for p in range(ny):
                for q in range(nx):
                    frac, dy, dx = _clip_to_disc(l_y[p], u_y[p], l_x[q], u_x[q], radius)
                    mu = w_y[p] * w_x[q] * frac
                    if mu == 0.0:
                        continue
                    t_y = a_y[p] + s_y[p] * dy
                    t_x = a_x[q] + s_x[q] * dx
                    f = 1.0
                    if use_cos4:
                        t2 = 1.0 + t_y * t_y + t_x * t_x
                        f = 1.0 / (t2 * t2) + 0.5 * (
                            (-4.0 / t2 ** 3 + 24.0 * t_y * t_y / t2 ** 4) * v_y[p]
                            + (-4.0 / t2 ** 3 + 24.0 * t_x * t_x / t2 ** 4) * v_x[q])
                    h[u, v, k, tp_y[p], tp_x[q]] += mu * f
                    if k == 0:
                        s0 += mu
                        sy += mu * t_y
                        sx += mu * t_x
                        syy += mu * (t_y * t_y + v_y[p])
                        sxy += mu * t_y * t_x
                        sxx += mu * (t_x * t_x + v_x[q])
            if k == 0 and s0 > 0.0:
                my, mx = sy / s0, sx / s0
                moments[u, v, 0] = s0
                moments[u, v, 1] = my
                moments[u, v, 2] = mx
                moments[u, v, 3] = syy / s0 - my * my
                moments[u, v, 4] = sxy / s0 - my * mx
                moments[u, v, 5] = sxx / s0 - mx * mx


def _cos4_mean(ty, tx, var_y, cov, var_x):
    """Mean of ``1 / (1 + ty^2 + tx^2)^2`` over angles of mean (ty, tx) and that covariance
    (second-order expansion)."""
    s = 1.0 + ty * ty + tx * tx
    f = s ** -2
    hyy = -4.0 * s ** -3 + 24.0 * ty * ty * s ** -4
    hxx = -4.0 * s ** -3 + 24.0 * tx * tx * s ** -4
    hxy = 24.0 * ty * tx * s ** -4
    return f + 0.5 * (hyy * var_y + 2.0 * hxy * cov + hxx * var_x)


# ---- the operator ----------------------------------------------------------------------------
class ExactOperator(pylops.LinearOperator):
    """The light field as a linear map of the emission on ``P`` planes, exact (no ray sampling).

    The map :class:`~lf_flame.tomo.operator.EmissionOperator` estimates with random rays,
    computed by quadrature of the same ray chain and applied as per-view convolutions
    by FFT (module docstring). Same ``dims``, ``dimsd``, planes and grids as
    ``EmissionOperator(camera, depths_mm, margin=margin, effects=effects)``, so every
    solver of :mod:`lf_flame.tomo.solvers` takes it.

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid (square, unrotated, integer pitch).
    depths_mm : sequence of float
        Depth offsets (mm from the focal plane, > 0 farther) of the ``P`` planes.
    margin : float
        Field-of-view factor of the planes' grids (:func:`~lf_flame.tomo.operator.plane_grid`);
        the grid has ``round(margin * n_rows) x round(margin * n_cols)`` samples, one per
        lenslet footprint, so ``margin * n_rows`` and ``margin * n_cols`` must be whole.
    effects : Effects
        Aperture and cos^4 as asked; occlusion and crosstalk must be off.
    precision : {"float64", "float32"}
        Of the kernels' spectra and the FFTs (module docstring). The interface is float64.
    quadrature_nodes : int
        Gauss-Legendre nodes per smooth piece of a pixel (:data:`QUADRATURE_NODES`).
    workers : int or None
        Threads of SciPy's FFTs; None: all cores.

    Attributes
    ----------
    dims : (P, rows, cols)
        Model shape (plane as ``depths_mm``, rows down, columns right).
    dimsd : (N, N, R, C)
        Data shape: the views of :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    kernels : ndarray of shape (N, N, P, Ty, Tx), float64
        The taps ``h``; tap ``(m, n)`` reads the plane at offset ``(tap_origin_y[u, k] + m,
        tap_origin_x[v, k] + n)`` samples from the pixel's lenslet.
    tap_origin_y, tap_origin_x : ndarray of shape (N, P), int64
    weights : ndarray of shape (N, N, R, C), float64
        The per-pixel cos^4 drift ``w`` (1 without cos^4).
    canvas_shape : (int, int)
        The FFTs' size.
    nbytes : int
        Memory held: the kernels' spectra, the weights and the kernels.
    setup_s : float
        Wall time of ``__init__`` (quadrature, spectra), seconds.
    rays_per_pixel, seed : None
        No rays are sampled (for the solvers' records, which name the operator's sampling).

    Raises
    ------
    ValueError
        A non-perfect lenslet grid, occlusion or crosstalk on, no planes, a plane the
        camera cannot image, a margin that does not give whole samples, an unknown
        precision, fewer than 1 quadrature node, or a camera whose chain is not
        shift-invariant across lenslets (message names the deviation).

    Notes
    -----
    Measured on the paper's camera, 4 planes (shared 2-core machine, noisy; ``python
    experiments/exact_operator.py``, ``results/exact_operator.md``): setup 2.3 s (float64)
    / 1.8 s (float32), memory 217 / 123 MB (the spectra: ``N^2 P Lr (Lc/2 + 1)`` complex
    numbers on a 200 x 108 canvas); one ``A`` 180 / 115 ms and one ``A^T`` 213 / 127 ms
    (medians), beside the 4-ray recorded Monte-Carlo operator's 133 and 127 ms, its record
    6.6 s and 251 MB. On a flame scene its light field differs from a 1,024-ray traced
    operator's by 0.22 / 0.23 / 0.16 / 0.39 % per plane (+20 / +10 / 0 / -10 mm), that
    operator's own seed-to-seed noise to within 1 %; the 4-ray operator's by 8.5-15 %.
    """

    def __init__(self, camera: PlenopticCamera, depths_mm, *, margin: float = 1.0, effects: Effects = FLAME_EFFECTS,
                 precision: str = "float64", quadrature_nodes: int = QUADRATURE_NODES, workers: int | None = None):
        t_start = time.perf_counter()
        if not camera.perfect_grid:
            raise ValueError("the exact operator needs a perfect lenslet grid (square, unrotated, integer pitch); "
                             "decode the capture to such views first (lf_flame.real.decoding)")
        if effects.occlusion:
            raise ValueError("occlusion makes the light field non-linear in the emission: flames are optically "
                             "thin, set Effects(occlusion=False)")
        if effects.crosstalk:
            raise ValueError("the exact operator does not model crosstalk (an f-number-matched camera has none); "
                             "use lf_flame.tomo.operator.EmissionOperator for Effects(crosstalk=True)")
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}. Received: {precision!r}")
        if int(quadrature_nodes) != quadrature_nodes or quadrature_nodes < 1:
            raise ValueError(f"quadrature_nodes must be a positive integer. Received: {quadrature_nodes!r}")
        depths = [float(d) for d in np.atleast_1d(np.asarray(depths_mm, dtype=np.float64))]
        if not depths:
            raise ValueError("depths_mm is empty: give at least one plane")
        R, C, N = camera.n_rows, camera.n_cols, camera.pixels_per_lenslet
        margin = float(margin)
        gr, gc = round(margin * R), round(margin * C)
        if not (math.isfinite(margin) and margin > 0) or abs(gr - margin * R) > 1e-9 or abs(gc - margin * C) > 1e-9:
            raise ValueError(f"margin must be positive and give whole samples on the {R} x {C} lenslet grid "
                             f"(margin * n_rows, margin * n_cols whole). Received: margin={margin!r}")
        sizes = [plane_grid(camera, d, margin) for d in depths]      # raises for a plane the camera cannot image
        zero = np.zeros((gr, gc), np.float32)
        scene = Scene("operator", tuple(Layer(zero, None, d, (0.0, 0.0), s) for d, s in zip(depths, sizes)), effects)
        layers, z, _, _ = _stack_layers(camera, scene)               # nearest first
        order = sorted(range(len(depths)), key=lambda k: depths[k])
        ky_sorted, kx_sorted = trace_coefficients(camera, layers, z)
        P = len(depths)
        inv = np.empty(P, np.int64)
        inv[order] = np.arange(P)                                    # plane k is kernel layer inv[k]
        ky = np.concatenate([ky_sorted[:2], ky_sorted[2 + inv]])
        kx = np.concatenate([kx_sorted[:2], kx_sorted[2 + inv]])
        cy, ay, ty, dty = self._axis(ky, N, R, "row")
        cx, ax, tx, dtx = self._axis(kx, N, C, "column")

        # taps of each view and plane, and the canvas no wrap-around reaches
        def taps(coef):
            reach = 0.5 * (np.abs(coef[..., 1]) + np.abs(coef[..., 2]))
            first = np.floor(coef[..., 0] - reach).astype(np.int64)
            return first, int((np.floor(coef[..., 0] + reach).astype(np.int64) - first).max()) + 1
        m0y, n_ty = taps(cy)
        n0x, n_tx = taps(cx)
        xg, wg = np.polynomial.legendre.leggauss(int(quadrature_nodes))
        h = np.zeros((N, N, P, n_ty, n_tx))
        moments = np.zeros((N, N, 6))
        radius = camera.aperture_diameter_mm / 2 if effects.aperture else -1.0
        _kernel_quadrature(cy, ay, ty, m0y, cx, ax, tx, n0x, n_ty, n_tx, radius, bool(effects.cos4), xg, wg, h,
                           moments)

        # per-pixel cos^4 drift: the pixel's mean cos^4 over the centre's (moment expansion)
        if effects.cos4:
            ry = (np.arange(R) - (R - 1) / 2)[None, :] * dty[:, None]          # (N, R) angle shift per row
            rx = (np.arange(C) - (C - 1) / 2)[None, :] * dtx[:, None]          # (N, C)
            my, mx, vy, cv, vx = (moments[..., i] for i in range(1, 6))
            at = _cos4_mean(my[:, :, None, None] + ry[:, None, :, None], mx[:, :, None, None] + rx[None, :, None, :],
                            vy[..., None, None], cv[..., None, None], vx[..., None, None])
            centre = _cos4_mean(my, mx, vy, cv, vx)[..., None, None]
            weights = np.where(moments[..., :1, None] > 0, at / np.where(centre > 0, centre, 1.0), 0.0)
        else:
            weights = np.ones((N, N, R, C))
        weights = np.ascontiguousarray(np.broadcast_to(weights, (N, N, R, C)))

        lr = scipy.fft.next_fast_len(max(gr - int(m0y.min()), R + int((m0y + n_ty - 1).max()), gr), real=True)
        lc = scipy.fft.next_fast_len(max(gc - int(n0x.min()), C + int((n0x + n_tx - 1).max()), gc), real=True)
        cdt = np.complex128 if precision == "float64" else np.complex64
        # forward spectrum: conj(DFT of the taps placed at their offsets) = sum h e^{+2 pi i f m / L}
        fr = np.arange(lr)
        fc = np.arange(lc // 2 + 1)
        # phases from whole numbers modulo the canvas: exact whatever the offsets
        er = np.exp(2j * np.pi * ((fr[None, None, :, None] * (m0y[:, :, None, None] + np.arange(n_ty))) % lr) / lr)
        ec = np.exp(2j * np.pi * (((n0x[:, :, None, None] + np.arange(n_tx)[:, None]) * fc) % lc) / lc)
        spec = np.empty((N, N, P, lr, lc // 2 + 1), cdt)
        for u in range(N):
            tmp = np.einsum("krt,vkts->vkrs", er[u], h[u])
            spec[u] = np.einsum("vkrs,vksf->vkrf", tmp, ec)
        self._spec = spec.reshape(N * N, P, lr, lc // 2 + 1)
        self._real = np.float64 if precision == "float64" else np.float32
        self._w = weights.reshape(N * N, R, C).astype(self._real)

        self.camera, self.effects, self.precision = camera, effects, precision
        self.depths_mm = tuple(depths)
        self.sizes_mm = tuple(tuple(float(v) for v in s) for s in sizes)
        self.centres_mm = ((0.0, 0.0),) * P
        self.margin = margin
        self.rays_per_pixel = self.seed = None
        self.kernels, self.weights = h, weights
        self.tap_origin_y, self.tap_origin_x = m0y, n0x
        self.canvas_shape = (lr, lc)
        self.workers = os.cpu_count() if workers is None else int(workers)
        super().__init__(dtype=np.float64, dims=(P, gr, gc), dimsd=(N, N, R, C))
        self.nbytes = int(self._spec.nbytes + self._w.nbytes + h.nbytes + weights.nbytes)
        self.setup_s = time.perf_counter() - t_start

    @staticmethod
    def _axis(k, N, n_lenslets, name):
        """Per view, the texel (constant, du, da) coefficients of each plane (N, P, 3), main-lens
        height (N, 3) and angle at the field centre (N, 3), and the angle's step per lenslet (N,),
        from one axis's chain coefficients; ValueError if the chain is not shift-invariant."""
        P = k.shape[0] - 2
        kk = k[:, :3, :].reshape(2 + P, 3, n_lenslets, N)            # (q, coef, lenslet, view)
        lens = np.arange(n_lenslets)[:, None]
        dev = max(np.abs(kk[2:, 0] - kk[2:, 0, :1] - lens).max(),            # texel: one sample per lenslet
                  np.abs(kk[2:, 1:] - kk[2:, 1:, :1]).max(),                  # texel slopes: the same
                  np.abs(kk[0] - kk[0, :, :1]).max(),                          # main-lens height: the same
                  np.abs(kk[1, 1:] - kk[1, 1:, :1]).max())                     # angle slopes: the same
        step = (kk[1, 0, 1] - kk[1, 0, 0]) if n_lenslets > 1 else np.zeros(N)
        dev = max(dev, np.abs(kk[1, 0] - kk[1, 0, :1] - lens * step).max() if n_lenslets > 1 else 0.0)
        if not dev <= SHIFT_TOLERANCE:
            raise ValueError(f"the camera's ray chain is not shift-invariant across lenslets along the {name}s "
                             f"(deviation {dev:.3g} > {SHIFT_TOLERANCE}): the map is no convolution")
        coef = np.ascontiguousarray(kk[2:, :, 0].transpose(2, 0, 1))  # (N, P, 3) at lenslet 0
        height = np.ascontiguousarray(kk[0, :, 0].T)                  # (N, 3)
        angle = np.ascontiguousarray(kk[1, :, 0].T).copy()
        angle[:, 0] += (n_lenslets - 1) / 2 * step                    # at the field centre
        return coef, height, angle, np.asarray(step, np.float64)

    # ---- application -------------------------------------------------------------------
    def _matvec(self, x):
        P, gr, gc = self.dims
        N, _, R, C = self.dimsd
        s = self.canvas_shape
        xs = scipy.fft.rfft2(np.reshape(x, self.dims).astype(self._real, copy=False), s=s, workers=self.workers)
        ys = np.einsum("vkrf,krf->vrf", self._spec, xs)
        y = scipy.fft.irfft2(ys, s=s, workers=self.workers)[:, :R, :C] * self._w
        return y.astype(np.float64, copy=False).ravel()

    def _rmatvec(self, y):
        P, gr, gc = self.dims
        s = self.canvas_shape
        yw = np.reshape(y, (-1,) + tuple(self.dimsd[2:])).astype(self._real, copy=False) * self._w
        ys = scipy.fft.rfft2(yw, s=s, workers=self.workers)
        xs = np.einsum("vkrf,vrf->krf", self._spec, ys.conj()).conj()
        x = scipy.fft.irfft2(xs, s=s, workers=self.workers)[:, :gr, :gc]
        return x.astype(np.float64, copy=False).ravel()

    def normalised_adjoint(self, views) -> np.ndarray:
        """``A^T y / A^T 1``: each sample's weighted mean over the pixels that see it, a refocused stack.

        Parameters
        ----------
        views : ndarray of shape (N, N, R, C)

        Returns
        -------
        planes : ndarray of shape (P, rows, cols), float64; 0 where no pixel sees a sample.
        """
        num = self.rmatvec(np.asarray(views, np.float64).ravel())
        den = self.rmatvec(np.ones(self.shape[0]))
        seen = den > 1e-12 * max(float(den.max()), 1e-300)
        return np.where(seen, num / np.where(seen, den, 1.0), 0.0).reshape(self.dims)
