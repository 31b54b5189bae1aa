"""Solvers on the exact operator's per-frequency normal matrices (Fourier ADMM).

On :class:`~lf_flame.tomo.exact.ExactOperator` the light field is, per view ``v`` and
plane ``k``, a convolution on an FFT canvas followed by a crop to the sensor's window and a
per-pixel weight ``w`` (cos^4 drift). Without the crop, per spatial frequency ``f`` the
map from the ``P`` planes to the ``V`` views is a ``V x P`` matrix ``H(f)``, and
``H^H H`` is a ``P x P`` Hermitian matrix ``G(f)``: the normal equations of the whole
stack split into one small system per frequency (the light-field deconvolution of
Broxton et al., Opt. Express 21 (2013), and the per-frequency depth analysis of Ng,
Stanford thesis (2006), ch. 5, put in matrix form).

What is not diagonal in frequency, and how it is handled (:func:`solve_admm`):

- **The window.** A view's samples outside the sensor (the canvas's border) are not
  measured, nor are saturated pixels. They are missing data, filled from the current
  prediction: ``z = M y~ + (1 - M) H s``, ``M`` the measured-and-unsaturated mask and
  ``y~ = y / w`` the data with the cos^4 drift divided out. Minimising
  ``1/2 ||H x - z||^2`` over ``x`` decreases ``1/2 ||M (H x - y~)||^2``
  (a majorise-minimise step, the EM algorithm for missing data: Dempster, Laird & Rubin,
  J. R. Stat. Soc. B 39 (1977)). Each *fill* costs one ``H`` and one ``H^H`` over the
  views (two batches of FFTs); everything between fills runs on the ``P`` planes alone.
  The fills converge slowly where flames stand near the window's edge (their defocused
  light leaves the sensor), so each fill predicts from ``s + momentum (s - s_prev)``
  (heavy-ball momentum, chosen on validation renders; it beat FISTA's schedule in a probe).
  Momentum on inexact ADMM steps (a few per fill) is not monotone, and where most samples
  are missing it can diverge: once a fill's residual exceeds :data:`~lf_flame.tomo.defaults.ADMM_DIVERGENCE`
  times the best so far, the fills restart from the best fill's planes without momentum and
  with :data:`~lf_flame.tomo.defaults.ADMM_RESTART_INNER` times the ADMM steps (an adaptive
  restart: O'Donoghue & Candès, Found. Comput. Math. 15 (2015)).
  Dividing by ``w`` (0.97-1.02 on the paper's camera) weights the pixels by ``w^2`` in
  the fit, not as the sensor's noise would: a 3-6 % change of weight at the rim, far
  below the noise's own spread.
- **Non-negativity and the plane's support.** ADMM (Boyd et al., Found. Trends Mach.
  Learn. 3 (2011), scaled form) on ``x = s``: the ``x``-step is the per-frequency solve
  ``(G + lam |D|^2 + rho) x = H^H z + rho (s - d)``, with ``(G + lam |D|^2 + rho)^-1``
  computed once per operator and weight (:class:`~lf_flame.tomo.fourier_system.FourierSystem`); the ``s``-step keeps
  ``x + d`` non-negative and zero outside the plane's grid.
- **Smoothness.** ``lam ||grad x_k||^2`` per plane (periodic differences on the canvas,
  symbol ``|D(f)|^2 = 4 sin^2(pi f_r / L_r) + 4 sin^2(pi f_c / L_c)``): Tikhonov on the
  gradient, chosen on validation renders (``experiments/exact_operator.py``). Optional
  isotropic TV (``tv > 0``) as a third ADMM split ``g = grad x`` whose penalty joins
  ``lam`` in the same per-frequency matrix, so it costs no more FFTs.

- **The start and the stopping.** The fills converge on the window's light (given its true
  value, one fill reaches the floor: a probe on validation renders), so the first fill may
  predict the missing data from the normalised back-projection ``H^H (M y~) / H^H (M 1)``
  (``start="refocused"``), and the fills may stop once the planes settle (``tol``); both are
  knobs chosen on validation renders (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`).

On an operator with ``subsamples > 1`` (a finer grid than the lenslets) all of this runs on
its phase planes (:meth:`~lf_flame.tomo.exact.ExactOperator.to_phases`): the gradient and
TV are those of each phase image on the lenslet grid, not of the finer grid (which would
couple the phases and make ``G`` complex); the knobs were chosen on validation renders with
that regulariser (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`).

``lam`` and ``rho`` are given relative to ``g0``, the mean of ``G``'s diagonal at zero
frequency (the squared light a unit plane sends to the views), so that the same values
serve any camera and radiance scale.
"""
from __future__ import annotations

import contextlib
import hashlib
import math

import numpy as np
import scipy.fft

from . import _fourier_kernels
from .defaults import (ADMM_DIVERGENCE, ADMM_FILLS, ADMM_INNER, ADMM_LAM, ADMM_MOMENTUM, ADMM_ONE_THREAD_SAMPLES,
                       ADMM_RESTART_INNER, ADMM_RHO, ADMM_RHO_TV, ADMM_STARTS, ADMM_TV, COARSE_KNOBS, WIENER_RHO)
from .fourier_system import admm_system, fourier_system


def fill_data(views, fit, op):
    """The lit views' data for the fills of the missing data (:func:`solve_admm`).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        float32 (read as they are) or any other real type (as float64).
    fit : ndarray of bool, shape (N, N, R, C)
        The pixels to fit.
    op : ExactOperator

    Returns
    -------
    yt : ndarray of shape (V', R, C), in the operator's precision
        The views with light (``op._lit``) divided by their weights (the cos^4 drift) where fitted and seen
        (weight above 0), 0 elsewhere.
    w2 : ndarray of shape (V', R, C), in the operator's precision
        The weights squared there, 0 elsewhere: the fit's weights (``(w z - y)^2 = w^2 (z - y / w)^2``) and
        its mask (``w2 > 0``).
    norm : float
        The norm of the fitted and seen samples of the views.
    """
    R, C = op.dimsd[2:]
    V = len(op._lit)
    yt, w2 = (np.empty((V, R, C), op._real) for _ in range(2))
    views = np.asarray(views)
    views = views if views.dtype == np.float32 else np.asarray(views, np.float64)
    sq = _fourier_kernels.gather_data(np.ascontiguousarray(op.from_samples(views)),
                                      np.ascontiguousarray(op.from_samples(np.asarray(fit, bool), False)), op._w,
                                      np.asarray(op._lit, np.int64), yt, w2)
    return yt, w2, math.sqrt(sq)


@contextlib.contextmanager
def solve_threads(op):
    """Run a solve on ``op`` on one thread (Numba's and ``op.workers`` for SciPy's FFTs) where its
    views are fewer samples than :data:`~lf_flame.tomo.defaults.ADMM_ONE_THREAD_SAMPLES`; as set
    otherwise (and for an operator that is not exact). Yields the threads used."""
    import numba
    canvas = getattr(op, "canvas_shape", None)
    if canvas is None or len(op._lit) * canvas[0] * canvas[1] >= ADMM_ONE_THREAD_SAMPLES:
        yield numba.get_num_threads()
        return
    threads, workers = numba.get_num_threads(), op.workers
    numba.set_num_threads(1)
    op.workers = 1
    try:
        yield 1
    finally:
        numba.set_num_threads(threads)
        op.workers = workers


def solve_admm(views, op, fit, *, fills: int = ADMM_FILLS, inner: int = ADMM_INNER, lam: float = ADMM_LAM,
               rho: float = ADMM_RHO, tv: float = ADMM_TV, rho_tv: float = ADMM_RHO_TV, momentum: float = ADMM_MOMENTUM,
               l1: float = 0.0, support=None, start: str = "zero", tol: float = 0.0, coarse_knobs=None, callback=None,
               state: dict | None = None, start_planes=None):
    """Non-negative emission on the exact operator's planes by Fourier ADMM with missing data.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The light field (radiance units), already checked against ``op``.
    op : ExactOperator
    fit : ndarray of bool, shape (N, N, R, C)
        The pixels to fit (False: saturated, left out as missing data).
    fills : int
        Fills of the missing data (outer iterations, >= 1); each costs one ``H`` and
        one ``H^H`` over the views (the first only ``H^H``).
    inner : int
        ADMM iterations per fill (>= 1), on the planes alone.
    lam, rho : float
        Weight of ``||grad x||^2`` and the ADMM penalty, relative to ``g0`` (:class:`~lf_flame.tomo.fourier_system.FourierSystem`).
    tv, rho_tv : float
        Weight of isotropic TV per plane (absolute, as :func:`~lf_flame.tomo.solvers.reconstruct`'s
        ``pd-tv``; 0: none) and its split's penalty relative to ``g0``.
    momentum : float
        In [0, 1): each fill predicts the missing data from ``s + momentum (s - s_prev)``;
        0 after a restart (the fills diverging: module docstring).
    l1 : float
        Weight of ``||x||_1`` (sparsity: with ``x >= 0`` it is the emission's sum, which a dense
        stack can spend on fewer planes per line of sight), in [0, 1) as a fraction of
        ``max(H^H y)``, the weight above which ``x = 0`` is the solution (LASSO's
        ``lambda_max``; Tibshirani, J. R. Stat. Soc. B 58 (1996)). 0: none. Its proximal step
        with the non-negativity: ``s = max(x + d - l1 lambda_max / (rho g0), 0)``.
    support : ndarray of bool, shape (P, rows, cols), or None
        Where each plane may hold emission (the non-negativity projection also zeroes the
        rest): the lateral footprints of the flames found at each depth
        (:func:`lf_flame.tomo.found_planes.find_planes`). None: everywhere.
    start : {"zero", "refocused", "coarse"}
        Where the first fill predicts the missing data from. ``"zero"``: nothing (the
        missing data start at 0). ``"refocused"``: the normalised back-projection
        ``H^H (M y~) / H^H (M 1)`` (shift-and-sum refocusing through the operator over the
        fitted pixels, :func:`backprojection_weight`), scaled to the data by least squares; it costs
        one ``H`` and one ``H^H`` more (the second kept on ``op`` per mask) and takes the
        missing data's fills, slow where flames stand near the window's edge, most of the way
        at once (the window's light is what the fills converge on: given its true value one
        fill reaches the floor, a probe on validation renders). ``"coarse"`` (a grid finer
        than the lenslets only): the planes solved first on the lenslet grid
        (:func:`coarse_operator`, with ``coarse_knobs``), each lenslet's value given to its
        ``s x s`` samples, and the ADMM steps start from them too: a coarse-to-fine start
        whose fills cost a quarter of the spectra's (the views' FFTs are the same).
    tol : float
        >= 0: stop after fill ``j >= 2`` once the planes' relative change over the fill,
        ``||s_j - s_(j-1)|| / ||s_j||``, is at most ``tol``; ``fills`` is then a cap. 0: run
        every fill.
    coarse_knobs : dict or None
        The lenslet grid's solve of the coarse start: ``fills`` (a cap), ``lam``, ``tv``,
        ``l1``, ``start`` (``"zero"`` or ``"refocused"``) and ``tol``, as
        :data:`~lf_flame.tomo.defaults.COARSE_KNOBS` holds them per noise level (what
        :func:`lf_flame.tomo.solvers.reconstruct` passes). None: the quiet ones.
    callback : callable or None
        ``callback(j, x)`` after fill ``j`` (1-based) with the planes (flat).
    start_planes : ndarray of shape (P, rows / s, cols / s) or ``op.dims``, or None
        Planes on the lenslet grid to start from (a learned reconstructor's,
        :func:`lf_flame.learn.reconstructor.reconstruction`), or on the planes' grid (a solve's at
        nearby depths, :func:`lf_flame.tomo.refine.refine_planes`): they take the coarse start's
        place (``start`` is then not used), on any grid.
    state : dict or None
        A recording's solve carried from frame to frame (the EM fills continued across
        frames, as an online EM does: Cappé & Moulines, J. R. Stat. Soc. B 71 (2009)). Empty:
        this solve runs as asked and leaves in it its planes, ADMM duals, the l1 scale and
        a prediction of the missing data: its last fill's, where it ran two or more (no ``H``
        spent: one fill older than the planes), else the next fill's (one ``H`` more).
        Holding them (the previous frame's, same operator and knobs): the solve continues from
        them (``start`` is not used): its first fill takes the missing data from that prediction
        (no ``H`` spent on it), its ADMM steps start from the planes and duals, and ``tol`` may
        stop it after that fill. Two fills a frame then cost one ``H`` and two ``H^H``.

    Returns
    -------
    planes : ndarray of shape (P, rows, cols), float64, non-negative
    residuals : list of float
        ``||M (w H v - y)|| / ||M y||`` at the point ``v`` each fill after the first predicts
        from (no extra operator application is spent on it): ``len(residuals) + 1`` fills ran
        (every fill's, ``len(residuals)`` fills, when continuing a ``state`` whose prediction
        was the next fill's; a last fill's views hold the previous frame's data, not a
        prediction of this one's).
    system_s : float
        Seconds spent building the :class:`~lf_flame.tomo.fourier_system.FourierSystem` (0 when ``op`` had it), and for the
        coarse start the lenslet grid's operator and system where this call built them.

    Raises
    ------
    ValueError
        Fills or inner iterations below 1, a momentum outside [0, 1), negative weights, a
        support that is not boolean of the planes' shape, an unknown start, a negative tol, the
        coarse start on the lenslet grid, a ``state`` from another operator.
    """
    if support is not None and (np.asarray(support).dtype != bool or np.shape(support) != tuple(op.dims)):
        raise ValueError(f"support must be boolean of the planes' shape {tuple(op.dims)}. Received: "
                         f"{np.asarray(support).dtype} of shape {np.shape(support)}")
    if int(fills) != fills or fills < 1 or int(inner) != inner or inner < 1:
        raise ValueError(f"fills and inner must be integers >= 1. Received: fills={fills!r}, inner={inner!r}")
    if not 0 <= momentum < 1 or not (tv >= 0 and rho_tv > 0 and math.isfinite(tv) and math.isfinite(rho_tv)):
        raise ValueError(f"momentum must be in [0, 1), tv >= 0 and rho_tv > 0, finite. Received: momentum={momentum!r}, "
                         f"tv={tv!r}, rho_tv={rho_tv!r}")
    if not 0 <= l1 < 1:
        raise ValueError(f"l1 must be in [0, 1) (a fraction of the weight that zeroes every plane). Received: {l1!r}")
    if start not in ADMM_STARTS or not (tol >= 0 and math.isfinite(tol)):
        raise ValueError(f"start must be one of {ADMM_STARTS} and tol finite and >= 0. Received: start={start!r}, "
                         f"tol={tol!r}")
    P, gr, gc = op.phase_dims                                        # the lenslet grid's planes (phases)
    canvas = op.canvas_shape
    cont = bool(state)                                               # continuing a recording's solve
    if cont and (state["s"].shape != (P,) + canvas or state["z"].shape != (len(op._lit),) + canvas):
        raise ValueError(f"the state holds planes {state['s'].shape} and views {state['z'].shape}: another "
                         f"operator's (planes {(P,) + canvas}, views {(len(op._lit),) + canvas} here)")
    if cont:
        start = "zero"                                               # not used: the state is the start
    elif start_planes is not None:                                   # the given planes take the coarse solve's place
        xc = np.asarray(start_planes, op._real)
        if xc.shape not in ((P // op.subsamples ** 2, gr, gc), tuple(op.dims)) or not np.all(np.isfinite(xc)):
            raise ValueError(f"start_planes must be finite planes of shape {(P // op.subsamples ** 2, gr, gc)} (the "
                             f"lenslet grid) or {tuple(op.dims)} (the planes' grid). Received: {xc.shape}")
        start = "coarse"
    elif start == "coarse" and op.subsamples == 1:
        raise ValueError("the coarse start solves on the lenslet grid first: it needs a finer grid (subsamples > 1)")
    kept = list(op.__dict__.get("_fourier_systems", {}).values())
    system = admm_system(op, lam, tv, rho, rho_tv)
    system_s = 0.0 if any(system is k for k in kept) else system.setup_s
    sub = op.subsamples
    if start == "coarse" and start_planes is None:   # the lenslet grid's solve: each lenslet's value on its s x s samples is on every phase
        kn = COARSE_KNOBS["quiet"] if coarse_knobs is None else coarse_knobs
        coarse, coarse_s = coarse_operator(op)
        coarse_support = None if support is None else \
            np.asarray(support).reshape(P // sub ** 2, gr, sub, gc, sub).any(axis=(2, 4))
        xc, _, cs = solve_admm(views, coarse, fit, fills=kn["fills"], inner=inner, lam=kn["lam"], rho=rho,
                               tv=kn["tv"], rho_tv=rho_tv, momentum=momentum, l1=kn["l1"], support=coarse_support,
                               start=kn["start"], tol=kn["tol"])
        system_s += coarse_s + cs
    if support is not None:
        support = op.to_phases(support)
    yt, w2, norm = fill_data(views, fit, op)
    norm = norm or 1.0
    z = None if cont else np.zeros((len(system.lit),) + canvas, op._real)
    s = np.zeros((P,) + canvas, op._real)
    lam_max = None
    if start == "refocused" or (start == "coarse" and l1 > 0):   # H^H (M y~): the start's numerator, l1's scale
        _fourier_kernels.fill(z, yt, w2)
        num = op.adjoint_canvas(z)[:, :gr, :gc]
        lam_max = float(num.max())
    if start == "refocused":   # the normalised back-projection, scaled to the data: the first fill predicts from it
        den = backprojection_weight(op, w2 > 0)
        s[:, :gr, :gc] = np.where(den > 0, np.maximum(num, 0) / np.where(den > 0, den, 1), 0)
    elif start == "coarse":
        s[:, :gr, :gc] = op.to_phases(xc) if xc.shape == tuple(op.dims) else \
            np.repeat(xc, sub ** 2, axis=0)                          # phase k s^2 + a s + b of plane k
    if start != "zero":
        if support is not None:
            s[:, :gr, :gc] *= support
        z = op.forward_canvas(s)
    if start == "refocused":
        a = _least_squares_scale(z, yt, w2 > 0)
        s *= a
        z *= a
    s_prev, d, r = s, np.zeros_like(s), np.empty_like(s)
    gy, gx, ey, ex = (np.zeros_like(s) for _ in range(4))
    if cont:
        s, d, (gy, gx, ey, ex), z, lam_max = state["s"], state["d"], state["tv"], state["z"], state["lam_max"]
        s_prev = s
    scored = not cont or state.get("z_predicts", True)               # the first fill's views predict this frame
    if support is None:
        support = np.ones((P, gr, gc), bool)
    kappa = tv / (rho_tv * system.g0) if tv > 0 else 0.0
    residuals, best, s_best, restarted = [], math.inf, s, False
    for j in range(1, int(fills) + 1):
        if j > 1:   # predict from the extrapolated planes (heavy-ball momentum on the fills), data where measured
            z = op.forward_canvas(s + momentum * (s - s_prev))
        residual = _fourier_kernels.fill(z, yt, w2)
        if j > 1 or (cont and scored):
            if not restarted and math.sqrt(residual) / norm > ADMM_DIVERGENCE * best:
                # the fills diverge (momentum on inexact ADMM steps): restart from the planes of the best fill so
                # far, without momentum and with ADMM_RESTART_INNER times the ADMM steps per fill
                restarted, momentum, inner, s = True, 0.0, ADMM_RESTART_INNER * int(inner), s_best
                z = op.forward_canvas(s)
                residual = _fourier_kernels.fill(z, yt, w2)
            residuals.append(math.sqrt(residual) / norm)
            if residuals[-1] < best:
                best, s_best = residuals[-1], s
        b = op.adjoint_spectrum(z)                                   # H^H z, (P, Lr, F)
        if j == 1:   # the l1 step from H^H y (without a start the first fill's z is the data)
            if l1 > 0 and lam_max is None:
                lam_max = float(scipy.fft.irfft2(b, s=canvas, workers=op.workers)[:, :gr, :gc].max())
            shrink_l1 = l1 * lam_max / (rho * system.g0) if l1 > 0 else 0.0
        s_prev = s
        for _ in range(int(inner)):
            _fourier_kernels.admm_target(s, d, gy, gx, ey, ex, rho_tv / rho if tv > 0 else 0.0, r)
            x = scipy.fft.irfft2(system.solve(b + system.g0 * rho * scipy.fft.rfft2(r, workers=op.workers)),
                                 s=canvas, workers=op.workers)
            s = np.empty_like(s_prev)
            _fourier_kernels.admm_project(x, d, shrink_l1, support, gr, gc, s)
            if tv > 0:   # isotropic shrinkage of the gradient (the TV split), then its dual
                _fourier_kernels.tv_shrink(x, kappa, gy, gx, ey, ex)
        if callback is not None:
            callback(j, op.from_phases(s[:, :gr, :gc]).astype(np.float64).ravel())
        if tol > 0 and (j > 1 or cont) and (np.linalg.norm(s[:, :gr, :gc] - s_prev[:, :gr, :gc])
                                  <= tol * np.linalg.norm(s[:, :gr, :gc])):
            break
    if state is not None:   # the next frame's missing data: the last fill's prediction, or the next fill's
        fresh = j == 1
        state.update(s=s, d=d, tv=(gy, gx, ey, ex), lam_max=lam_max, z_predicts=fresh,
                     z=op.forward_canvas(s + momentum * (s - s_prev)).astype(op._real, copy=False) if fresh else z)
    return op.from_phases(s[:, :gr, :gc]).astype(np.float64), residuals, system_s


def coarse_operator(op):
    """The same planes' operator on the lenslet grid (``subsamples`` 1), binned once and kept on ``op``.

    Parameters
    ----------
    op : ExactOperator
        On a grid finer than the lenslets.

    Returns
    -------
    coarse : ExactOperator
        :meth:`~lf_flame.tomo.exact.ExactOperator.binned`: its phase kernels summed.
    setup_s : float
        Seconds spent building it in this call (0 when ``op`` had it).
    """
    kept = op.__dict__.get("_coarse_operator")
    if kept is not None:
        return kept, 0.0
    coarse = op.__dict__["_coarse_operator"] = op.binned()
    return coarse, coarse.setup_s


def backprojection_weight(op, m) -> np.ndarray:
    """``H^H (M 1)`` on the lenslet grid's phase planes: how much of each sample the fitted pixels see.

    The denominator of the normalised back-projection (:func:`solve_admm`'s refocused start),
    kept on ``op`` for the last mask (a light field without saturated pixels shares its
    operator's).

    Parameters
    ----------
    op : ExactOperator
    m : ndarray of bool of shape (V', R, C)
        The fitted pixels of the lit views (:func:`fill_data`'s ``w2 > 0``).

    Returns
    -------
    ndarray of shape (P s^2, rows, cols), in the operator's precision
    """
    key = hashlib.blake2b(np.packbits(m).tobytes(), digest_size=16).digest() + bytes(str(m.shape), "ascii")
    kept = op.__dict__.get("_backprojection_weight")
    if kept is None or kept[0] != key:
        _, gr, gc = op.phase_dims
        den = op.adjoint_canvas(m)[:, :gr, :gc]
        kept = op.__dict__["_backprojection_weight"] = (key, np.where(den > 1e-6 * den.max(), den, 0).astype(op._real))
    return kept[1]


def wiener_start(views, op, fit=None, *, lam: float = ADMM_LAM, rho: float = WIENER_RHO):
    """The one-pass physics start of a learned reconstructor: a per-frequency Tikhonov (Wiener) solve and the
    normalised back-projection, on the lenslet grid.

    ``x = (G + lam |D|^2 + rho)^-1 H^H (M y~)``: the normal equations of the whole stack solved once per
    frequency (:class:`~lf_flame.tomo.fourier_system.FourierSystem`), with the unmeasured samples (the canvas outside the sensor's
    window, pixels left out of the fit) taken as zero rather than filled (:func:`solve_admm` fills them),
    and no non-negativity: near the field's edge and between planes it is biased, which is what a
    learned stage on top of it corrects. Its numerator's normalised form ``H^H (M y~) / H^H (M 1)`` is
    the refocused stack through the same kernels. One batch of view FFTs, one adjoint product of the
    spectra and ``P`` inverse FFTs: some 20 ms for the paper's 4 planes on 2 cores.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The light field (radiance units), of ``op``'s camera.
    op : ExactOperator
        On any grid: a finer one (``subsamples > 1``) is binned to the lenslet grid (:func:`coarse_operator`).
    fit : ndarray of bool of shape (N, N, R, C) or None
        The pixels to use (False: clipped); None: all.
    lam, rho : float
        Gradient weight and ridge, relative to ``g0`` (:class:`~lf_flame.tomo.fourier_system.FourierSystem`).

    Returns
    -------
    wiener, refocused : ndarray of shape (P, rows, cols), in the operator's precision
        On the lenslet grid; ``refocused`` is 0 where no fitted pixel sees a sample.
    """
    if op.subsamples > 1:
        op, _ = coarse_operator(op)
    if fit is None:
        fit = np.ones(np.shape(views), bool)
    yt, w2, _ = fill_data(views, fit, op)
    _, gr, gc = op.phase_dims
    rhs = op.adjoint_spectrum(yt)                                    # the window, zero-padded to the canvas
    wiener = scipy.fft.irfft2(fourier_system(op, lam, rho).solve(rhs), s=op.canvas_shape, workers=op.workers)
    back = scipy.fft.irfft2(rhs, s=op.canvas_shape, workers=op.workers)[:, :gr, :gc]
    den = backprojection_weight(op, w2 > 0)
    refocused = np.divide(back, den, out=np.zeros_like(back), where=den > 0)
    return np.ascontiguousarray(wiener[:, :gr, :gc]), refocused


def _least_squares_scale(z, yt, m) -> float:
    """``a`` minimising ``||M (a z - y~)||`` over the fitted pixels (``z`` the canvas views, ``yt`` and ``m`` the
    sensor's); 1 where ``z`` is dark there."""
    R, C = m.shape[1:]
    zz = np.where(m, z[:, :R, :C], 0)
    den = float(np.vdot(zz, zz))
    return float(np.vdot(zz, yt)) / den if den > 0 else 1.0
