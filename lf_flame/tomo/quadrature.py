"""The exact map's kernels: per view and plane a convolution kernel by deterministic quadrature of the ray chain.

What :class:`lf_flame.tomo.exact.ExactOperator` applies by FFT (and
:class:`lf_flame.tomo.lattice.LatticeOperator` on other lattices), from the ray chain the renderer traces
(:func:`lf_flame.simulate.tracer.trace_coefficients`); the quadrature's loops are Numba kernels in
:mod:`lf_flame.tomo._exact_kernels`.

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
(:func:`lf_flame.tomo._exact_kernels.kernel_quadrature`): ``da`` by Gauss-Legendre on the pieces between the values
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
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.depth_range import check_planes_once
from ..simulate.scenes import FLAME_EFFECTS
from ..simulate.layers import Effects, Layer, Scene
from ..simulate.tracer import _stack_layers, trace_coefficients
from . import _exact_kernels
from .operator import plane_grid

#: Gauss-Legendre nodes per smooth piece of a pixel's ``da`` range (per axis). Against 32
#: nodes: largest tap off by 5.8e-5 of the largest tap, 5.6e-6 of the kernels' sum in all
#: (4 nodes: 2.0e-4, 2.3e-5; ``tests/test_exact_operator.py``).
QUADRATURE_NODES = 6
#: Largest deviation (texels, main-lens mm, radians) of a lenslet's chain from the first
#: lenslet's shifted by whole samples: above it the map is not a convolution.
SHIFT_TOLERANCE = 1e-6


# ---- the kernels -----------------------------------------------------------------------------
@dataclass(frozen=True)
class ExactKernels:
    """The exact map's convolution kernels and per-pixel weights (:func:`exact_kernels`).

    Attributes
    ----------
    kernels : ndarray of shape (N, N, P, Ty, Tx), float64
        The taps ``h`` (view row ``u``, view column ``v``, plane, tap row, tap column); tap
        ``(m, n)`` reads the plane at offset ``(tap_origin_y[u, k] + m, tap_origin_x[v, k] + n)``
        samples from the pixel's lenslet.
    tap_origin_y, tap_origin_x : ndarray of shape (N, P), int64
    weights : ndarray of shape (N, N, R, C), float64
        The per-pixel cos^4 drift ``w`` (1 without cos^4).
    depths_mm : tuple of float
        The planes' depth offsets (mm), as given.
    sizes_mm : tuple of (float, float)
        Each plane's grid frame (height, width) in mm; its sample is ``height / dims[1]`` mm.
    margin : float
    dims : (P, rows, cols)
        Model shape: ``subsamples`` times the lenslet grid per axis.
    dimsd : (N, N, R, C)
        Data shape (views).
    subsamples : int
        Samples per lenslet footprint and axis; above 1 ``kernels`` (and the tap origins)
        hold ``P subsamples^2`` phase kernels on the lenslet grid (:func:`_phase_kernels`).
    """

    kernels: np.ndarray
    tap_origin_y: np.ndarray
    tap_origin_x: np.ndarray
    weights: np.ndarray
    depths_mm: tuple
    sizes_mm: tuple
    margin: float
    dims: tuple
    dimsd: tuple
    subsamples: int = 1


def exact_kernels(camera: PlenopticCamera, depths_mm, *, margin: float = 1.0, effects: Effects = FLAME_EFFECTS,
                  quadrature_nodes: int = QUADRATURE_NODES, subsamples: int = 1, view_shifts=None) -> ExactKernels:
    """The exact map's kernels by quadrature of the tracer's ray chain (module docstring).

    What :class:`~lf_flame.tomo.exact.ExactOperator` builds its spectra from; parameters as there. Used alone
    where only the kernels are needed (:mod:`lf_flame.tomo.resolution`). With
    ``subsamples = s > 1`` the texel coordinates are those of the ``s``-times finer grid
    and the kernels are regrouped by phase (:func:`_phase_kernels`).

    ``view_shifts``: None, or ``M`` shifts (view steps, toward higher view indices along rows and
    columns): each view ``u`` is replaced by the ``M`` views of its pixel moved by each shift,
    view ``u M + k`` of ``N M`` per axis (:func:`sub_view_chain`; :class:`~lf_flame.tomo.exact.ExactOperator`'s
    sub-views).

    Returns
    -------
    ExactKernels

    Raises
    ------
    ValueError
        As :class:`~lf_flame.tomo.exact.ExactOperator` (all but the precision).
    """
    if not camera.perfect_grid:
        raise ValueError("the exact operator needs a perfect lenslet grid (square, unrotated, integer pitch); "
                         "decode the capture to such views first (lf_flame.real.decoding)")
    if effects.occlusion:
        raise ValueError("occlusion makes the light field non-linear in the emission: flames are optically "
                         "thin, set Effects(occlusion=False)")
    if effects.crosstalk:
        raise ValueError("the exact operator does not model crosstalk (an f-number-matched camera has none); "
                         "use lf_flame.tomo.operator.EmissionOperator for Effects(crosstalk=True)")
    if int(quadrature_nodes) != quadrature_nodes or quadrature_nodes < 1:
        raise ValueError(f"quadrature_nodes must be a positive integer. Received: {quadrature_nodes!r}")
    if int(subsamples) != subsamples or subsamples < 1:
        raise ValueError(f"subsamples must be a positive integer. Received: {subsamples!r}")
    sub = int(subsamples)
    depths = [float(d) for d in np.atleast_1d(np.asarray(depths_mm, dtype=np.float64))]
    if not depths:
        raise ValueError("depths_mm is empty: give at least one plane")
    check_planes_once(depths)     # two identical planes: the data cannot share their emission out
    R, C, N = camera.n_rows, camera.n_cols, camera.pixels_per_lenslet
    margin = float(margin)
    gr, gc = round(margin * R), round(margin * C)
    if not (math.isfinite(margin) and margin > 0) or abs(gr - margin * R) > 1e-9 or abs(gc - margin * C) > 1e-9:
        raise ValueError(f"margin must be positive and give whole samples on the {R} x {C} lenslet grid "
                         f"(margin * n_rows, margin * n_cols whole). Received: margin={margin!r}")
    sizes = [plane_grid(camera, d, margin) for d in depths]      # raises for a plane the camera cannot image
    P = len(depths)
    (cy, ay, ty, dty), (cx, ax, tx, dtx) = chain_coefficients(camera, depths, sizes, (gr, gc), effects)
    if view_shifts is not None:                                  # sub-views: each pixel moved by each shift
        (cy, ay, ty, dty), (cx, ax, tx, dtx) = (sub_view_chain(a, view_shifts)
                                                for a in ((cy, ay, ty, dty), (cx, ax, tx, dtx)))
        N = cy.shape[0]
    cy, cx = cy * sub, cx * sub                                  # texel coordinates on the finer grid

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
    _exact_kernels.kernel_quadrature(cy, ay, ty, m0y, cx, ax, tx, n0x, n_ty, n_tx, radius, bool(effects.cos4), xg, wg, h,
                                     moments)

    # per-pixel cos^4 drift: the pixel's mean cos^4 over the centre's (moment expansion)
    if effects.cos4:
        ry = (np.arange(R) - (R - 1) / 2)[None, :] * dty[:, None]          # (N, R) angle shift per row
        rx = (np.arange(C) - (C - 1) / 2)[None, :] * dtx[:, None]          # (N, C)
        weights = np.empty((N, N, R, C))
        _exact_kernels.cos4_weights(moments, ry, rx, weights)
    else:
        weights = np.ones((N, N, R, C))
    if sub > 1:
        h, m0y, n0x = _phase_kernels(h, m0y, n0x, sub)
    return ExactKernels(h, m0y, n0x, weights, tuple(depths), tuple(tuple(float(v) for v in s) for s in sizes),
                        margin, (P, sub * gr, sub * gc), (N, N, R, C), sub)


def chain_coefficients(camera: PlenopticCamera, depths, sizes, grid, effects: Effects = FLAME_EFFECTS):
    """Per axis, the ray chain of a pixel in lenslet 0 as affine functions of its ray samples.

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid.
    depths : sequence of float
        The planes' depths (mm), in the caller's order.
    sizes : sequence of (float, float)
        Each plane's grid frame (height, width), mm (:func:`~lf_flame.tomo.operator.plane_grid`).
    grid : (int, int)
        Samples per plane (rows, columns): one per lenslet footprint.
    effects : Effects

    Returns
    -------
    (row, column) : two tuples ``(texel, height, angle, step)``
        ``texel`` (N, P, 3): the texel coordinate read on each plane, ``c0 + c1 du + c2 da``
        (``du`` the ray's place in its pixel, ``da`` in its lenslet, each in [-1/2, 1/2) of a
        pitch); ``height`` (N, 3) on the main lens (mm) and ``angle`` (N, 3) at the field's
        centre alike; ``step`` (N,) the angle's change per lenslet (:meth:`ExactOperator._axis`).

    Raises
    ------
    ValueError
        A chain that is not shift-invariant across lenslets.
    """
    R, C, N = camera.n_rows, camera.n_cols, camera.pixels_per_lenslet
    zero = np.zeros(tuple(grid), np.float32)
    scene = Scene("operator", tuple(Layer(zero, None, d, (0.0, 0.0), s) for d, s in zip(depths, sizes)), effects)
    layers, z, _, _ = _stack_layers(camera, scene)               # nearest first
    order = sorted(range(len(depths)), key=lambda k: depths[k])
    ky_sorted, kx_sorted = trace_coefficients(camera, layers, z)
    inv = np.empty(len(depths), np.int64)
    inv[order] = np.arange(len(depths))                          # plane k is kernel layer inv[k]
    ky = np.concatenate([ky_sorted[:2], ky_sorted[2 + inv]])
    kx = np.concatenate([kx_sorted[:2], kx_sorted[2 + inv]])
    return _axis_chain(ky, N, R, "row"), _axis_chain(kx, N, C, "column")


def sub_view_chain(axis_chain, view_shifts):
    """One axis's chain (:func:`chain_coefficients`) of ``N`` views as that of their ``N M`` sub-views.

    Sub-view ``u M + k`` is view ``u``'s pixel moved by ``view_shifts[k]`` view steps toward higher
    view indices (:func:`exact_kernels`' ``view_shifts``). The chain is affine in the view index, so
    each coefficient's constant term moves by the shift times its step from view to view (the
    read-out image runs against the sensor along one axis: a pixel's own ray coordinate would not
    say which way).

    Parameters
    ----------
    axis_chain : (texel (N, P, 3), height (N, 3), angle (N, 3), step (N,))
    view_shifts : sequence of M float

    Returns
    -------
    The same four, of ``N M`` sub-views.

    Raises
    ------
    ValueError
        Shifts that are not finite, or fewer than 2 views.
    """
    sh = np.asarray(view_shifts, np.float64)
    coef, height, angle, step = axis_chain
    N = coef.shape[0]
    if N < 2 or sh.ndim != 1 or not np.all(np.isfinite(sh)):
        raise ValueError(f"view_shifts must be finite shifts (view steps) of a camera with 2 or more views per "
                         f"axis. Received: {view_shifts!r} for {N} views")

    def shifted(c):
        per_view = (c[-1, ..., 0] - c[0, ..., 0]) / (N - 1)
        c = np.repeat(c, len(sh), axis=0)
        c[..., 0] += np.tile(sh, N).reshape((-1,) + (1,) * (c.ndim - 2)) * per_view
        return c
    return shifted(coef), shifted(height), shifted(angle), np.repeat(step, len(sh))


def _phase_kernels(h, m0y, n0x, s):
    """Fine-grid kernels regrouped into ``s^2`` phase kernels per plane on the lenslet grid.

    On the ``s``-times finer grid a pixel of lenslet ``r`` reads fine sample
    ``s r + m0 + m``; writing ``m0 + m = s Q + a`` it reads sample ``r + Q`` of the phase
    image ``x_a[r] = x_fine[s r + a]``. So each phase ``(a, b)`` of plane ``k`` is one more
    plane of the lenslet-grid convolution, with the taps of that residue: the polyphase
    decomposition (Vaidyanathan, *Multirate Systems and Filter Banks*, 1993, ch. 4).

    Parameters
    ----------
    h : ndarray of shape (N, N, P, Ty, Tx)
        Taps on the fine grid; ``m0y`` (N, P) and ``n0x`` (N, P) their origins (fine samples).
    s : int

    Returns
    -------
    kernels : ndarray of shape (N, N, P s^2, Ty', Tx')
        Plane index ``k s^2 + a s + b`` (``a`` the row phase, ``b`` the column phase).
    tap_origin_y, tap_origin_x : ndarray of shape (N, P s^2), int64
        In lenslets, the same for every phase of a plane.
    """
    N, _, P, Tyf, Txf = h.shape
    q0y, q0x = m0y // s, n0x // s
    Ty, Tx = (Tyf + s - 2) // s + 1, (Txf + s - 2) // s + 1
    qy = m0y[:, :, None] + np.arange(Tyf)                        # (N, P, Tyf) fine sample read
    qx = n0x[:, :, None] + np.arange(Txf)
    ay, Qy = qy % s, qy // s - q0y[:, :, None]
    bx, Qx = qx % s, qx // s - q0x[:, :, None]
    u, v, k, m, n = np.ix_(*(np.arange(d) for d in h.shape))
    out = np.zeros((N, N, P, s, s, Ty, Tx))
    out[u, v, k, ay[u, k, m], bx[v, k, n], Qy[u, k, m], Qx[v, k, n]] = h
    return (out.reshape(N, N, P * s * s, Ty, Tx), np.repeat(q0y, s * s, axis=1), np.repeat(q0x, s * s, axis=1))


def _axis_chain(k, N: int, n_lenslets: int, name: str):
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
