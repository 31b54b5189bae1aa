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
halves the FFTs' traffic and keeps the spectra in 16-bit fixed point, a quarter of float64's
memory (:class:`~lf_flame.tomo._fourier_kernels.PackedSpectra`: each view and plane's
real and imaginary parts scaled to their largest); A and A^T stay each other's transpose
to float32 rounding, and both are within 1-2e-5 of float64's, far below any data's noise
(a render's own error is 0.4 % at 400 rays per pixel), so it is for large stacks and the
solvers (``experiments/exact_operator.py`` measures both).
"""
from __future__ import annotations

import math
import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import pylops
import scipy.fft

from ..optics.camera import PlenopticCamera
from ..simulate.scenes import FLAME_EFFECTS, Effects, Layer, Scene
from ..simulate.tracer import _stack_layers, trace_coefficients
from . import _exact_kernels, _fourier_kernels
from .operator import normalised_adjoint, plane_grid

#: Gauss-Legendre nodes per smooth piece of a pixel's ``da`` range (per axis). Against 32
#: nodes: largest tap off by 5.8e-5 of the largest tap, 5.6e-6 of the kernels' sum in all
#: (4 nodes: 2.0e-4, 2.3e-5; ``tests/test_exact_operator.py``).
QUADRATURE_NODES = 6
#: Largest deviation (texels, main-lens mm, radians) of a lenslet's chain from the first
#: lenslet's shifted by whole samples: above it the map is not a convolution.
SHIFT_TOLERANCE = 1e-6
PRECISIONS = ("float64", "float32")
#: The most sub-views per view and axis of :class:`ExactOperator` for samples off the views' grid (a colour
#: capture's pixels, up to half a step away): each sample is then modelled within 1/6 of a step.
OFFSET_BINS = 3
#: How far (lenslets) a sample's view of a plane may lie from where its pixel sees it before the samples' offsets
#: are modelled (:func:`offset_bins_for`; a sample half a step off sees a plane of slope ``s`` ``|s| / 2`` lenslets
#: off). Chosen on the colour camera's validation captures (``experiments/cameras_colour.py --seed0 58100``, a
#: ``/tmp`` probe): at 0.1 the scene of two flames at -3.4 and -6.3 mm (slopes 0.11 and 0.20) ran on whole views,
#: its flames 6.4 -> 10.1 % and 4.0 -> 6.9 % (emission p90 8.8 -> 10.0 %); at 0.05 and 0.03 every figure was the
#: 3 sub-views'.
OFFSET_TOLERANCE = 0.05


def _cos4_mean(ty, tx, var_y, cov, var_x):
    """Mean of ``1 / (1 + ty^2 + tx^2)^2`` over angles of mean (ty, tx) and that covariance
    (second-order expansion: ``f + (f_yy var_y + 2 f_xy cov + f_xx var_x) / 2`` with ``i = 1 / (1 + ty^2 + tx^2)``,
    ``f = i^2``, ``f_yy = -4 i^3 + 24 ty^2 i^4``, ``f_xy = 24 ty tx i^4``; the powers formed once: 3x faster
    on the paper camera's 3.6 M pixels than with ``s ** -k``, the same to 4e-16)."""
    i = 1.0 / (1.0 + ty * ty + tx * tx)
    i2 = i * i
    quad = ty * ty * var_y + 2.0 * ty * tx * cov + tx * tx * var_x
    return i2 * (1.0 - 2.0 * i * (var_y + var_x) + 12.0 * i2 * quad)


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

    What :class:`ExactOperator` builds its spectra from; parameters as there. Used alone
    where only the kernels are needed (:mod:`lf_flame.tomo.resolution`). With
    ``subsamples = s > 1`` the texel coordinates are those of the ``s``-times finer grid
    and the kernels are regrouped by phase (:func:`_phase_kernels`).

    ``view_shifts``: None, or ``M`` shifts (view steps, toward higher view indices along rows and
    columns): each view ``u`` is replaced by the ``M`` views of its pixel moved by each shift,
    view ``u M + k`` of ``N M`` per axis (:func:`sub_view_chain`; :class:`ExactOperator`'s sub-views).

    Returns
    -------
    ExactKernels

    Raises
    ------
    ValueError
        As :class:`ExactOperator` (all but the precision).
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
        my, mx, vy, cv, vx = (moments[..., i] for i in range(1, 6))
        at = _cos4_mean(my[:, :, None, None] + ry[:, None, :, None], mx[:, :, None, None] + rx[None, :, None, :],
                        vy[..., None, None], cv[..., None, None], vx[..., None, None])
        centre = _cos4_mean(my, mx, vy, cv, vx)[..., None, None]
        weights = np.where(moments[..., :1, None] > 0, at / np.where(centre > 0, centre, 1.0), 0.0)
    else:
        weights = np.ones((N, N, R, C))
    weights = np.ascontiguousarray(np.broadcast_to(weights, (N, N, R, C)))
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
    return ExactOperator._axis(ky, N, R, "row"), ExactOperator._axis(kx, N, C, "column")


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
        Threads of SciPy's FFTs and of the spectra's construction; None: all cores.
    subsamples : int
        Samples per lenslet footprint and axis of the planes' grids (default 1). Off focus
        the views see a plane at sub-lenslet shifts (their parallax), so a light field
        carries detail finer than a lenslet there; ``2`` models it (a 2 x 2 grid per lenslet,
        applied as ``4 P`` phase planes of the same convolutions: :func:`_phase_kernels`),
        at ``subsamples^2`` times the unknowns. At focus every view sees a sample's whole
        footprint, so there only the phases' sum is measured.
    sample_offsets : ndarray of shape (N, N, R, C, 2) or None
        Where each view sample's pixel lies from its view's place (view steps, along the
        views' rows and columns, within one step): a colour capture decoded pixel by pixel
        (:func:`lf_flame.real.decoding.sample_offsets`), whose samples sit up to half a pixel
        from the grid of views. Each view is then modelled by ``offset_bins`` sub-views per
        axis, its pixel moved by ``(k + 1/2) / M - 1/2`` steps (``k < M``; ``exact_kernels``'s
        ``view_shifts``), and each sample read from its nearest sub-view: the map stays a
        convolution per sub-view, at ``M^2`` times the views' cost. None: every sample at its
        view's place.
    offset_bins : int or None
        ``M``, sub-views per view and axis with ``sample_offsets``; None: as the planes need
        (:func:`offset_bins_for`, at most :data:`OFFSET_BINS`). 1: whole views (the offsets not modelled).

    Attributes
    ----------
    dims : (P, rows, cols)
        Model shape (plane as ``depths_mm``, rows down, columns right): ``subsamples``
        times the lenslet grid per axis.
    phase_dims : (P subsamples^2, rows / subsamples, cols / subsamples)
        The planes as the convolutions see them (:meth:`to_phases`).
    dimsd : (N, N, R, C)
        Data shape: the views of :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    offset_bins : int or None
        ``M`` where the samples' offsets are modelled (above 1), else None.
    view_dims : (N', N', R, C)
        The views the kernels are of: ``dimsd``, or with ``sample_offsets`` the ``N' = N M``
        sub-views per axis (:meth:`to_samples`, :meth:`from_samples`).
    kernels : ndarray of shape (N', N', P', Ty, Tx), float64
        The taps ``h`` of the ``P' = phase_dims[0]`` phase planes; tap ``(m, n)`` reads the
        phase plane at offset ``(tap_origin_y[u, k] + m, tap_origin_x[v, k] + n)`` lenslets
        from the pixel's lenslet.
    tap_origin_y, tap_origin_x : ndarray of shape (N', P'), int64
    weights : ndarray of shape (N', N', R, C), float64
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
        precision, fewer than 1 quadrature node or subsample, or a camera whose chain is not
        shift-invariant across lenslets (message names the deviation); sample offsets of
        another shape than the views', not finite or more than a view step; fewer than 1 bin.

    Notes
    -----
    Measured on the paper's camera, 4 planes (shared 2-core machine, noisy; ``python
    experiments/exact_operator.py``, ``results/exact_operator.md``; the cost figures predate
    the lit-view spectra built by BLAS and the Numba sums, which lowered them: a float32
    setup of 0.7 s in ``results/fourier_solver_dense.csv``): setup 2.3 s (float64)
    / 1.8 s (float32), memory 217 / 123 MB (the spectra: ``N^2 P Lr (Lc/2 + 1)`` complex, now of the lit views only,
    numbers on a 200 x 108 canvas); one ``A`` 180 / 115 ms and one ``A^T`` 213 / 127 ms
    (medians), beside the 4-ray recorded Monte-Carlo operator's 133 and 127 ms, its record
    6.6 s and 251 MB. On a flame scene its light field differs from a 1,024-ray traced
    operator's by 0.22 / 0.23 / 0.16 / 0.39 % per plane (+20 / +10 / 0 / -10 mm), that
    operator's own seed-to-seed noise to within 1 %; the 4-ray operator's by 8.5-15 %.
    """

    def __init__(self, camera: PlenopticCamera, depths_mm, *, margin: float = 1.0, effects: Effects = FLAME_EFFECTS,
                 precision: str = "float64", quadrature_nodes: int = QUADRATURE_NODES, workers: int | None = None,
                 subsamples: int = 1, sample_offsets=None, offset_bins: int | None = None):
        t_start = time.perf_counter()
        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {PRECISIONS}. Received: {precision!r}")
        self._gather, shifts, self.offset_bins = None, {}, None
        if sample_offsets is not None and offset_bins is None:
            offset_bins = offset_bins_for(camera, depths_mm)
        if sample_offsets is not None and offset_bins != 1:
            if isinstance(offset_bins, bool) or int(offset_bins) != offset_bins or offset_bins < 1:
                raise ValueError(f"offset_bins must be an integer >= 1. Received: {offset_bins!r}")
            self.offset_bins = int(offset_bins)
            shifts = dict(view_shifts=(np.arange(self.offset_bins) + 0.5) / self.offset_bins - 0.5)
        ek = self._kernels(camera, depths_mm, margin=margin, effects=effects, quadrature_nodes=quadrature_nodes,
                           subsamples=subsamples, **shifts)
        if sample_offsets is not None:                            # checked whether modelled or not
            self._gather = _offset_gather(ek.dimsd, sample_offsets, self.offset_bins or 1)
        h, weights, m0y, n0x = ek.kernels, ek.weights, ek.tap_origin_y, ek.tap_origin_x
        sub = ek.subsamples
        (N, _, R, C), (P, gr, gc), (n_ty, n_tx) = ek.dimsd, (h.shape[2], ek.dims[1] // sub, ek.dims[2] // sub), h.shape[3:]

        lr = scipy.fft.next_fast_len(max(gr - int(m0y.min()), R + int((m0y + n_ty - 1).max()), gr), real=True)
        lc = scipy.fft.next_fast_len(max(gc - int(n0x.min()), C + int((n0x + n_tx - 1).max()), gc), real=True)
        cdt = np.complex128 if precision == "float64" else np.complex64
        # the views with light: a view outside the aperture has no taps and no spectrum
        lit = np.flatnonzero(np.abs(h).reshape(N * N, -1).max(axis=1) > 0)
        # forward spectrum: conj(DFT of the taps placed at their offsets) = sum h e^{+2 pi i f m / L}
        fr = np.arange(lr)
        fc = np.arange(lc // 2 + 1)
        # phases from whole numbers modulo the canvas: exact whatever the offsets
        er = np.exp(2j * np.pi * ((fr[None, None, :, None] * (m0y[:, :, None, None] + np.arange(n_ty))) % lr) / lr)
        ec = np.exp(2j * np.pi * (((n0x[:, :, None, None] + np.arange(n_tx)[:, None]) * fc) % lc) / lc)
        self._real = np.float64 if precision == "float64" else np.float32
        # in the operator's precision (float32: complex64 products, 2.5e-7 of the largest entry from complex128's on
        # the 81-plane stack); one view per task on the workers' threads (BLAS releases the GIL): the spectra's
        # first touch of fresh memory, most of the time on one thread, is shared too
        er, ec, hr = er.astype(cdt), ec.astype(cdt), h.astype(self._real)
        shape = (len(lit), P, lr, lc // 2 + 1)
        spec = np.empty(shape, cdt) if precision == "float64" else _fourier_kernels.PackedSpectra(shape)
        workers = os.cpu_count() if workers is None else int(workers)

        store = spec.__setitem__ if precision == "float64" else spec.put

        def view_spectrum(i):                                     # (P, Lr, Ty) @ (P, Ty, Tx) @ (P, Tx, F), BLAS
            u, v = divmod(int(lit[i]), N)
            store(i, (er[u] @ hr[u, v]) @ ec[v])
        with ThreadPoolExecutor(max(1, workers)) as pool:
            list(pool.map(view_spectrum, range(len(lit))))
        self._spec, self._lit = spec, lit                             # (V', P, Lr, F): lit views only
        self._w = weights.reshape(N * N, R, C).astype(self._real)

        self.camera, self.effects, self.precision = camera, effects, precision
        self.quadrature_nodes = int(quadrature_nodes)
        self.depths_mm = ek.depths_mm
        self.sizes_mm = ek.sizes_mm
        self.centres_mm = ((0.0, 0.0),) * len(ek.depths_mm)
        self.margin = ek.margin
        self.rays_per_pixel = self.seed = None
        self.kernels, self.weights = h, weights
        self.tap_origin_y, self.tap_origin_x = m0y, n0x
        self.canvas_shape = (lr, lc)
        self.workers = workers
        self.subsamples, self.phase_dims = sub, (P, gr, gc)
        self.view_dims = (N, N, R, C)
        n = camera.pixels_per_lenslet
        super().__init__(dtype=np.float64, dims=ek.dims, dimsd=(n, n, R, C))
        self.setup_s = time.perf_counter() - t_start

    #: What :meth:`binned` copies as it is (a subclass adds its own).
    _SHARED = ("camera", "effects", "precision", "quadrature_nodes", "depths_mm", "sizes_mm", "centres_mm", "margin",
               "rays_per_pixel", "seed", "weights", "canvas_shape", "workers", "_lit", "_real", "_w", "view_dims",
               "_gather", "offset_bins")

    @staticmethod
    def _kernels(camera, depths_mm, **kw) -> ExactKernels:
        """The map's kernels (:func:`exact_kernels`); a subclass on another lattice gives its own."""
        return exact_kernels(camera, depths_mm, **kw)

    def binned(self) -> "ExactOperator":
        """The same planes on the lenslet grid (``subsamples`` 1), from this operator's kernels.

        A plane that holds one value over each lenslet's ``s x s`` samples gives every phase
        image the same picture, so the lenslet grid's kernel of a plane is the sum of its
        ``s^2`` phase kernels (:func:`_phase_kernels` read backwards), on the same taps and
        origins, and its spectra are the sums of theirs: the same optics and quadrature, no
        second quadrature (a few hundredths of a second against a new operator's setup).

        Returns
        -------
        ExactOperator
            ``self`` when ``subsamples`` is 1. Its ``setup_s`` is the binning's time.
        """
        s2 = self.subsamples ** 2
        if s2 == 1:
            return self
        t0 = time.perf_counter()
        new = object.__new__(type(self))
        for name in self._SHARED:
            setattr(new, name, getattr(self, name))
        (Pp, gr, gc), (N, _) = self.phase_dims, self.view_dims[:2]
        P = Pp // s2
        new.kernels = self.kernels.reshape((N, N, P, s2) + self.kernels.shape[3:]).sum(axis=3)
        new.tap_origin_y = np.ascontiguousarray(self.tap_origin_y[:, ::s2])   # the same for every phase
        new.tap_origin_x = np.ascontiguousarray(self.tap_origin_x[:, ::s2])
        new._spec = self._spec.binned(s2) if isinstance(self._spec, _fourier_kernels.PackedSpectra) else \
            self._spec.reshape((len(self._lit), P, s2) + self._spec.shape[2:]).sum(axis=2)
        new.subsamples, new.phase_dims = 1, (P, gr, gc)
        pylops.LinearOperator.__init__(new, dtype=np.float64, dims=(P, gr, gc), dimsd=self.dimsd)
        new.setup_s = time.perf_counter() - t0
        return new

    @property
    def nbytes(self) -> int:
        """Memory held: the kernels' spectra, the weights and the kernels."""
        return int(self._spec.nbytes + self._w.nbytes + self.kernels.nbytes + self.weights.nbytes)

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
    def to_phases(self, x) -> np.ndarray:
        """Planes ``(P, s rows, s cols)`` as their phase images ``(P s^2, rows, cols)`` on the lenslet grid.

        Phase ``(a, b)`` of plane ``k`` is entry ``k s^2 + a s + b``: ``x[k, a::s, b::s]``
        (:func:`_phase_kernels`). The identity (a view) when ``subsamples`` is 1.
        """
        s, (P, gr, gc) = self.subsamples, self.phase_dims
        x = np.reshape(x, self.dims)
        if s == 1:
            return x
        return x.reshape(-1, gr, s, gc, s).transpose(0, 2, 4, 1, 3).reshape(P, gr, gc)

    def from_phases(self, xp) -> np.ndarray:
        """The inverse of :meth:`to_phases`: phase images ``(P s^2, rows, cols)`` as planes ``self.dims``."""
        s, (P, gr, gc) = self.subsamples, self.phase_dims
        xp = np.reshape(xp, (P, gr, gc))
        if s == 1:
            return xp
        return xp.reshape(-1, s, s, gr, gc).transpose(0, 3, 1, 4, 2).reshape(self.dims)

    def to_samples(self, views) -> np.ndarray:
        """The data's samples ``dimsd`` read from views of ``view_dims`` (each sample from its
        sub-view with ``sample_offsets``; else the views as they are). Any dtype."""
        v = np.reshape(views, -1)
        return np.reshape(v if self._gather is None else v[self._gather], self.dimsd)

    def from_samples(self, samples, fill=0) -> np.ndarray:
        """The transpose of :meth:`to_samples`: data ``dimsd`` placed in views ``(N'^2, R, C)``, every
        sub-view sample that no data sample reads set to ``fill``."""
        a = np.asarray(samples)
        if self._gather is not None:
            v = np.full(int(np.prod(self.view_dims)), fill, a.dtype)
            v[self._gather] = a.ravel()
            a = v
        return a.reshape((-1,) + tuple(self.view_dims[2:]))

    def _matvec(self, x):
        N, _, R, C = self.view_dims
        s = self.canvas_shape
        xs = scipy.fft.rfft2(self.to_phases(x).astype(self._real, copy=False), s=s, workers=self.workers)
        ys = _fourier_kernels.spectra_forward(self._spec, xs)
        y = np.zeros((N * N, R, C), self._real)
        y[self._lit] = scipy.fft.irfft2(ys, s=s, workers=self.workers)[:, :R, :C]
        return self.to_samples(y * self._w).astype(np.float64, copy=False).ravel()

    def _rmatvec(self, y):
        P, gr, gc = self.phase_dims
        s = self.canvas_shape
        yw = self.from_samples(np.reshape(y, self.dimsd))[self._lit].astype(self._real, copy=False) * self._w[self._lit]
        xs = _fourier_kernels.spectra_adjoint(self._spec, scipy.fft.rfft2(yw, s=s, workers=self.workers))
        x = scipy.fft.irfft2(xs, s=s, workers=self.workers)[:, :gr, :gc]
        return self.from_phases(x).astype(np.float64, copy=False).ravel()

    def normalised_adjoint(self, views) -> np.ndarray:
        """``A^T y / A^T 1``: each sample's weighted mean over the pixels that see it, a refocused stack.

        Parameters
        ----------
        views : ndarray of shape (N, N, R, C)

        Returns
        -------
        planes : ndarray of shape (P, rows, cols), float64; 0 where no pixel sees a sample.
        """
        return normalised_adjoint(self, views)


def offset_bins_for(camera: PlenopticCamera, depths_mm, cap: int = OFFSET_BINS) -> int:
    """The sub-views per view and axis that samples off the views' grid need on these planes: 1 or ``cap``.

    A sample whose pixel lies ``d`` view steps off its view's place (``|d|`` up to 1/2) sees a
    plane of slope ``s`` (lenslets per view step,
    :meth:`~lf_flame.optics.camera.PlenopticCamera.slope_for_depth`) ``|s| d`` lenslets off. Where
    that stays within :data:`OFFSET_TOLERANCE` on every plane (``max |s| / 2``: near focus) the
    whole views do (1), else ``cap``. No count between: with an even count no sub-view lies at the
    view's place, and for the emission 2 sub-views gave larger errors than 3 on 3 of 4 validation
    captures of the colour camera (flames at their true depths, a ``/tmp`` probe). The temperature
    route's cap of 2 was chosen with its own knobs
    (:data:`lf_flame.temperature.channels.DECODED_OFFSET_KNOBS`).

    Parameters
    ----------
    camera : PlenopticCamera
        The views' camera.
    depths_mm : sequence of float
        The planes (mm from the focus distance).
    cap : int

    Returns
    -------
    int
    """
    top = max(abs(camera.slope_for_depth(float(d))) for d in np.atleast_1d(depths_mm))
    return 1 if top / 2 <= OFFSET_TOLERANCE else int(cap)


def _offset_gather(view_dims, sample_offsets, M: int) -> np.ndarray | None:
    """Flat indices into the sub-views ``view_dims`` = (N M, N M, R, C) of each sample's nearest sub-view
    (:class:`ExactOperator`'s ``sample_offsets``), for the data (N, N, R, C) raveled; None for ``M`` 1 (whole
    views), the offsets checked either way."""
    N, R, C = view_dims[0] // M, view_dims[2], view_dims[3]
    off = np.asarray(sample_offsets, np.float64)
    if off.shape != (N, N, R, C, 2):
        raise ValueError(f"sample_offsets must be (N, N, R, C, 2) = {(N, N, R, C, 2)}, the views' shape and 2. "
                         f"Received: {off.shape}")
    if not np.all(np.isfinite(off)):
        raise ValueError("sample_offsets must be finite (NaN or inf found)")
    if np.abs(off).max() > 1.0:
        raise ValueError(f"sample_offsets must be within one view step of each view's place (largest "
                         f"{np.abs(off).max():.3g})")
    if M == 1:
        return None
    k = np.clip(np.floor((off + 0.5) * M), 0, M - 1).astype(np.int64)
    u = np.arange(N)[:, None, None, None] * M + k[..., 0]
    v = np.arange(N)[None, :, None, None] * M + k[..., 1]
    r, c = np.arange(R)[:, None], np.arange(C)[None, :]
    return (((u * (N * M) + v) * R + r) * C + c).ravel()


def emission_operator(camera: PlenopticCamera, depths_mm, *, rays_per_pixel: int | None = None,
                      effects: Effects = FLAME_EFFECTS, subsamples: int = 1, sample_offsets=None):
    """The camera's operator for ``depths_mm``: exact when it can be, traced when asked or needed.

    Parameters
    ----------
    camera : PlenopticCamera
    depths_mm : sequence of float
        Depth offsets (mm) of the planes.
    rays_per_pixel : int or None
        None: the :class:`ExactOperator` (float32: its rounding, ~1e-7, is far below any
        light field's noise) where the camera is a perfect lenslet grid and ``effects`` has no
        crosstalk, else the traced :class:`~lf_flame.tomo.operator.EmissionOperator` at 4 rays
        per pixel. A number: the traced operator at that many rays (the reference).
    effects : Effects
    subsamples : int
        The exact operator's samples per lenslet and axis (:class:`ExactOperator`); a
        traced operator keeps one per lenslet.
    sample_offsets : ndarray of shape (N, N, R, C, 2) or None
        Each sample's place off its view's (:class:`ExactOperator`; a light field's
        :attr:`~lf_flame.real.lightfield.LightField.sample_offsets`): the exact operator only.

    Returns
    -------
    ExactOperator or EmissionOperator

    Raises
    ------
    ValueError
        From the operator chosen (a plane the camera cannot image, no planes ...).
    """
    from .operator import EmissionOperator
    if rays_per_pixel is None and camera.perfect_grid and not effects.crosstalk and not effects.occlusion:
        return ExactOperator(camera, depths_mm, effects=effects, precision="float32", subsamples=subsamples,
                             sample_offsets=sample_offsets)
    if sample_offsets is not None:
        raise ValueError("samples off the views' grid (a colour capture's) are modelled by the exact operator only: "
                         "it needs a perfect lenslet grid and no crosstalk, and no rays_per_pixel")
    return EmissionOperator(camera, list(depths_mm), rays_per_pixel=4 if rays_per_pixel is None else int(rays_per_pixel),
                            effects=effects)
