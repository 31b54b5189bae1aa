"""Solvers of the emission on planes from one light field.

:func:`reconstruct` runs one of :data:`SOLVERS` on an :class:`~lf_flame.tomo.operator.EmissionOperator`:
damped LSQR (Sun, Hossain, Xu et al., Opt. Commun. 390 (2017)), FISTA with non-negativity,
primal-dual (Chambolle-Pock) with TV and non-negativity (Viganò et al., Opt. Express
(2018), plenoptomos), Richardson-Lucy (Broxton et al., Opt. Express 21 (2013); napari-LF),
or the normalised adjoint (plain refocusing). Saturated pixels are left out of the fit. The solvers on
PyLops and PyProximal live in :mod:`lf_flame.tomo.proximal`, imported when one of them is asked for.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from tqdm.auto import tqdm

from .defaults import (ADMM_TV, DEFAULT_ITERS, DEFAULT_SOLVER, DEFAULT_TV, EXACT_SOLVER,  # noqa: F401
                       SOLVERS)   # (re-exported)
from .operator import EmissionOperator, check_views

# ---- solvers ---------------------------------------------------------------------------
# SOLVERS, DEFAULT_ITERS, DEFAULT_TV and DEFAULT_SOLVER live in .defaults (no PyLops there:
# the command line's parser reads them) and are re-exported here.


@dataclass
class Reconstruction:
    """Emission on planes recovered from one light field (:func:`reconstruct`).

    Attributes
    ----------
    planes : ndarray of shape (P, rows, cols), float64
        Emission (the scene's radiance units) on each plane, rows down, columns right.
    depths_mm : tuple of P float
        Depth offset of each plane (mm from the focal plane).
    sample_mm : tuple of P (float, float)
        Size (height, width) of one grid sample on each plane, mm.
    solver : str
    settings : dict
        The solver's knobs (iterations, damping, TV weight, step, rays per pixel, seed).
    residuals : ndarray of shape (n,)
        Relative data residual ``||A x - y|| / ||y||`` per iteration (for FISTA at the
        point where the gradient is taken; for the primal-dual solver NaN between its
        records, :data:`PD_RESIDUAL_EVERY`; for admm one per fill after the first, at the planes
        that fill predicts from), saturated pixels left out.
    time_s : float
        Wall time of the solve (the operator built, the step size found, the iterations).
    """

    planes: np.ndarray
    depths_mm: tuple
    sample_mm: tuple
    solver: str
    settings: dict = field(default_factory=dict)
    residuals: np.ndarray = field(default_factory=lambda: np.zeros(0))
    time_s: float = 0.0


#: Width (lenslets) of the band along a plane's border whose share of the emission :func:`edge_shares` reports.
EDGE_BAND_LENSLETS = 2
#: A plane holding more than this share of its emission in that band reaches the field's edge: light of its
#: flame falls outside the views, which no solver recovers (``lf-flame reconstruct`` warns and records it).
EDGE_SHARE_WARN = 0.01
#: Planes holding less than this share of the brightest plane's light are not warned of (their edge share is
#: recorded): on a dense stack, planes beyond a flame's depth hold a few stray samples, near the border as anywhere
#: (a new user's centred sheath, nothing outside the field: 3.9 % of a plane holding 0.1 % of the brightest's light).
EDGE_PLANE_FLOOR = 0.01
#: A plane's brightest sample in that band must reach this share of the plane's brightest for a warning: the flame's
#: body reaches the edge, not another flame's stray light. A Gaussian flame cut by the edge
#: (a test camera's, 32 rays) reads 1.0 with its centre on the edge and 0.22 with 3.7 % of its light in the band; the
#: stray light of a flame 20 mm nearer on a dim plane of a user's 99 x 98-lenslet capture (1.2 % of that plane's light
#: in the band) 0.017, and the quick start's planes 0.003-0.035 (:func:`edge_shares`' ``peak``).
EDGE_BODY = 0.1


def edge_shares(planes, samples_per_lenslet: int = 1, band_lenslets: int = EDGE_BAND_LENSLETS,
                peak: bool = False) -> np.ndarray:
    """Each plane's share of its emission within ``band_lenslets`` of the grid's border, or (``peak``) its brightest
    sample there over its brightest sample (:data:`EDGE_BODY`).

    Parameters
    ----------
    planes : ndarray of shape (P, rows, cols)
        Emission (non-negative parts are counted).
    samples_per_lenslet : int
        The grid's samples per lenslet and axis (an operator's ``subsamples``).
    band_lenslets : int
    peak : bool
        The band's brightest sample over the plane's, in place of its sum over the plane's.

    Returns
    -------
    ndarray of shape (P,)
        ``sum(band) / sum(plane)`` (``max(band) / max(plane)``) of the positive emission, in [0, 1]; 0 for an empty
        plane.
    """
    x = np.clip(np.asarray(planes, np.float64), 0, None)
    b = int(band_lenslets) * int(samples_per_lenslet)
    band = x.copy()
    band[:, b:x.shape[1] - b, b:x.shape[2] - b] = 0.0
    if peak:
        part, whole = band.max(axis=(1, 2), initial=0.0), x.max(axis=(1, 2), initial=0.0)
    else:
        part, whole = band.sum(axis=(1, 2)), x.sum(axis=(1, 2))
    return np.where(whole > 0, part / np.where(whole > 0, whole, 1.0), 0.0)


#: A solve leaving more than this share of the light field unexplained beyond its noise (:func:`data_misfit`), and
#: more than :data:`MISFIT_NOISE` times the noise's share, does not hold the scene: ``lf-flame reconstruct`` warns
#: (and records the misfit in every file). On validation renders of the paper camera (``/tmp`` probe, 8 random-depth
#: scenes, seeds 3900000-3900007, and 9 column scenes, 3960000-3960008, 100 rays per pixel) the found planes leave
#: 0-0.052 noise-free and 0.047-0.097 at 14 dB, except one column scene at 14 dB (0.142, a flame 40 % off); the
#: paper's four planes under flames at other depths 0.32-0.54; the votes' planes without a flame they missed 0.19.
MISFIT_WARN = 0.1
#: The noise's estimate (:func:`lf_flame.tomo.noise_knobs.noise_norm`) reads 89-95 % of the noise: a misfit up to
#: about half the noise's share is that shortfall, not the scene's.
MISFIT_NOISE = 0.6


def fitted_residual(op, planes, data, fit) -> np.ndarray:
    """Data minus the planes' prediction where fitted, 0 elsewhere.

    Parameters
    ----------
    op : EmissionOperator or ExactOperator
    planes : ndarray of the operator's ``dims`` (P, rows, cols)
    data : ndarray of shape (N, N, R, C)
    fit : ndarray of bool of the data's shape
        The fitted samples (:func:`fitted_pixels`).

    Returns
    -------
    ndarray of shape (N, N, R, C), float64
    """
    y = np.asarray(data, np.float64)
    return np.where(fit, y - (op @ np.ravel(planes)).reshape(y.shape), 0.0)


class Residuals:
    """:func:`fitted_residual` of one light field for the solves asked about, the last two kept: the found planes'
    route (:func:`lf_flame.tomo.refine.peel_and_refine`) asks for a solve's residual in one step (its search of
    the residual, a refinement's cost) and again in the next.

    Parameters
    ----------
    data : ndarray of shape (N, N, R, C)
    fit : ndarray of bool of the data's shape

    Call ``residuals(op, rec)`` with an operator and its :class:`Reconstruction`: an ndarray of shape
    (N, N, R, C), float64, to read only (the same array for the same two objects).
    """

    def __init__(self, data, fit):
        self.data, self.fit, self._kept = data, fit, []

    def __call__(self, op, rec) -> np.ndarray:
        for o, r, res in self._kept:
            if o is op and r is rec:
                return res
        res = fitted_residual(op, rec.planes, self.data, self.fit)
        self._kept = self._kept[-1:] + [(op, rec, res)]
        return res


def data_misfit(views, op: EmissionOperator, planes, saturation=1.0) -> dict:
    """How much of a light field its planes leave unexplained beyond the noise.

    The relative residual ``||W (A x - y)|| / ||W y||`` (``W`` the fitted samples, as
    :func:`reconstruct` fits) holds the noise, ``||W n|| / ||W y||``
    (:func:`lf_flame.tomo.noise_knobs.noise_norm`, from Immerkaer's mask), and what the
    planes cannot produce: light of flames off the planes, beyond the field, or a camera
    model that is not the camera's. The misfit is that second part,
    ``sqrt(max(residual^2 - noise^2, 0))``; ``lf-flame reconstruct`` records it and warns
    above :data:`MISFIT_WARN` and :data:`MISFIT_NOISE` times the noise's share
    (:func:`misfit_is_high`).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    op : EmissionOperator
        The planes' operator.
    planes : ndarray of the operator's ``dims`` (P, rows, cols)
    saturation : float, ndarray of bool or None
        As :func:`reconstruct`.

    Returns
    -------
    dict
        ``relative_residual``, ``noise_share`` (the noise's expected part of it) and
        ``misfit``, each a share of ``||W y||``.

    Raises
    ------
    ValueError
        Views or planes that do not fit the operator, NaN or inf in them.
    """
    from .noise_knobs import noise_norm
    y = check_views(views, op)
    x = np.asarray(planes, np.float64)
    if x.size != op.shape[1] or not np.all(np.isfinite(x)):
        raise ValueError(f"planes must be finite with the operator's {op.shape[1]} samples {tuple(op.dims)}. "
                         f"Received: {x.shape}")
    fit = fitted_pixels(y, saturation)
    norm = float(np.linalg.norm(np.where(fit, y, 0.0))) or 1.0
    res = float(np.linalg.norm(fitted_residual(op, x, y, fit))) / norm
    noise = noise_norm(y, fit) / norm
    return dict(relative_residual=res, noise_share=noise, misfit=math.sqrt(max(res * res - noise * noise, 0.0)))


def misfit_is_high(misfit: dict) -> bool:
    """:func:`data_misfit`'s record above :data:`MISFIT_WARN` and :data:`MISFIT_NOISE` times its noise's share."""
    return misfit["misfit"] > max(MISFIT_WARN, MISFIT_NOISE * misfit["noise_share"])


def lipschitz_bound(op: EmissionOperator) -> float:
    """Upper bound of ``||A||^2`` (the gradient's Lipschitz constant of ``1/2 ||A x - y||^2``).

    Every entry of ``A`` is non-negative, so ``||A||_2^2 <= ||A||_1 ||A||_inf`` = (largest
    column sum) x (largest row sum) (Schur's test; Horn & Johnson, Matrix Analysis,
    5.6.P) from one ``A^T 1`` and one ``A 1``. On the paper's camera it is 1.2x the
    largest singular value squared found by power iteration, at a tenth of its cost.
    """
    return float(op.rmatvec(np.ones(op.shape[0])).max() * op.matvec(np.ones(op.shape[1])).max())


#: More than this share of the lit samples at or above the saturation level given: :func:`reconstruct` warns (the
#: views in other units than the level's: a light field x 1000 fitted with the default level 1 had lost every sample
#: above it, its planes 100 % off, without a word; over-exposed captures of the paper camera clip 10-27 %).
SATURATED_WARN = 0.5


def reconstruct(views, op: EmissionOperator, solver: str | None = None, iters: int | None = None, *,
                damp: float = 0.0, tv: float | None = None, lam: float | None = None, saturation=1.0,
                progress: bool = False, callback=None, support=None, l1: float | None = None, start: str | None = None,
                tol: float | None = None, state: dict | None = None, start_planes=None,
                unit: float | None = None) -> Reconstruction:
    """Recover the emission on the operator's planes from one light field.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`lf_flame.refocus.shift_and_sum.raw_to_views`), radiance units.
    op : EmissionOperator
        The camera and the planes (their depths and grids).
    solver : str or None
        One of :data:`SOLVERS`; None: :data:`~lf_flame.tomo.defaults.EXACT_SOLVER` on an
        :class:`~lf_flame.tomo.exact.ExactOperator`, :data:`DEFAULT_SOLVER` on a traced one.

        - ``"adjoint"``: ``A^T y / A^T 1``, plain refocusing through the same rays (no iterations).
        - ``"lsqr"``: damped LSQR (Tikhonov, ``damp``), PyLops; may go negative.
        - ``"fista"``: accelerated proximal gradient on ``1/2 ||A x - y||^2`` with
          non-negativity (``pyproximal.Box(lower=0)``), step ``1 / L``
          (:func:`lipschitz_bound`); Beck & Teboulle, SIAM J. Imaging Sci. 2 (2009).
        - ``"pd-tv"``: PyProximal's primal-dual (Chambolle & Pock, J. Math. Imaging Vis.
          40 (2011)) on ``1/2 ||A x - y||^2 + tv sum ||grad x_k||`` (isotropic TV per
          plane) with ``x >= 0``.
        - ``"rl"``: Richardson-Lucy, ``x <- x A^T(y / A x) / A^T 1`` (the light-field
          microscopy default, 15 iterations; Broxton et al. 2013), non-negative.
        - ``"admm"``: on an :class:`~lf_flame.tomo.exact.ExactOperator` only: per-frequency
          ADMM with the window and saturated pixels as missing data, non-negative, with
          ``lam ||grad x||^2`` (and TV when ``tv > 0``); its iterations are the fills of the
          missing data (:func:`lf_flame.tomo.fourier.solve_admm`).
    iters : int or None
        Iterations; None: :data:`DEFAULT_ITERS`, admm's by the data's noise (below).
    damp, tv : float
        LSQR's damping and the TV weight (>= 0; None: pd-tv's :data:`DEFAULT_TV`, admm's by
        the data's noise); ignored by the other solvers. admm with ``iters``, ``tv`` or ``lam``
        None measures the views' relative noise (:func:`lf_flame.tomo.noise_knobs.relative_noise`,
        ``settings["noise"]``) and takes the knobs it was not given from
        :data:`~lf_flame.tomo.defaults.ADMM_KNOBS` for the operator's grid (``op.subsamples``)
        and the noise level (:func:`lf_flame.tomo.noise_knobs.admm_knobs`).
    lam : float or None
        admm's gradient weight relative to the stack's light; None: by the noise (above).
    saturation : float, ndarray of bool of shape (N, N, R, C), or None
        The sensor's clipping level in the views' units (1.0: :func:`lf_flame.simulate.tracer.render`'s),
        or which samples to leave out (True: clipped; decoded views carry it,
        :func:`lf_flame.real.decoding.clipped_samples`, since white-image division leaves
        no single level). A pixel at or above the level holds only a lower bound of its
        light: the iterative solvers leave it out of the fit (weight 0 in ``||W (A x - y)||``;
        Richardson-Lucy: ratio left out). None: every pixel is fitted. The count is
        ``settings["n_saturated"]``; ``settings["saturation"]`` is ``"mask"`` for a mask. A level
        is also the views' unit: they are solved divided by it (the weights ``tv`` and ``damp`` and
        admm's noise regimes are chosen where the sensor clips at 1), so that the planes scale with
        the data (counts of a 12- or 16-bit sensor, or [0, 1], give the same planes in their units).
    unit : float or None
        The views' unit where ``saturation`` is a mask or None: the sensor's clipping level in the views' units
        (a capture's in counts with its defective pixels' mask, decoded views of a capture in counts:
        :attr:`lf_flame.real.lightfield.LightField.unit`); they are solved divided by it, as by a level. None: the
        level where ``saturation`` is one, else 1 (the views' own units).
    progress : bool
        A tqdm bar over the iterations.
    callback : callable or None
        ``callback(k, x)`` after iteration ``k`` (1-based) with the iterate ``x`` (flat,
        read-only use): error-against-iterations curves from one run.
    support : ndarray of bool of shape (P, rows, cols) or None
        admm only: where each plane may hold emission (:func:`lf_flame.tomo.fourier.solve_admm`).
    l1 : float or None
        admm only: the sparsity weight in [0, 1) (a fraction of the weight that zeroes every
        plane, :func:`lf_flame.tomo.fourier.solve_admm`); 0: none; None: admm's by the noise
        (above).
    start, tol : str, float or None
        admm only: where the first fill predicts the missing data from and the stopping
        tolerance (:func:`lf_flame.tomo.fourier.solve_admm`); None: by the noise with the other
        knobs (:func:`lf_flame.tomo.noise_knobs.admm_knobs`; ``tol`` 0 when ``iters`` is given).
        ``settings["fills_run"]`` counts the fills that ran. The coarse start's lenslet-grid
        solve takes the lenslet grid's knobs for the noise level (the quiet ones where the
        noise was not measured).
    state : dict or None
        admm only: a recording's solve carried from frame to frame
        (:func:`lf_flame.tomo.fourier.solve_admm`): give an empty dict with the first frame
        and the same dict with each next one; ``settings["start"]`` is then ``"continued"``
        from the second frame on.

    start_planes : ndarray of shape (P, rows, cols) on the lenslet grid or ``op.dims``, or None
        admm only: planes to start from in place of the coarse start (a learned reconstructor's, or
        a solve's at nearby depths), ``settings["start"]`` ``"given"``
        (:func:`lf_flame.tomo.fourier.solve_admm`).

    Returns
    -------
    Reconstruction
        Its ``settings["sub_views"]``: the sub-views per view and axis where ``op`` models each
        sample at its own pixel (:class:`~lf_flame.tomo.exact.ExactOperator`'s ``sample_offsets``).

    Raises
    ------
    ValueError
        An unknown solver, negative or fractional iterations (admm: fewer than 1), negative weights, views of another
        camera (shape), NaN or inf in the views, a saturation level that is not positive, a saturation mask that is
        not boolean of the views' shape, every sample left out of the fit, several planes on one view per lenslet
        (no parallax to tell them apart).
    """
    iters_given, tv_given = iters is not None, tv is not None
    solver, iters, tv, y = _checked_inputs(views, op, solver, iters, damp, tv, saturation)
    t0 = time.perf_counter()
    given_level = saturation
    if unit is not None and not (math.isfinite(float(unit)) and unit > 0):
        raise ValueError(f"unit must be a positive finite level (the sensor's clipping level). Received: {unit!r}")
    unit = float(saturation) if np.ndim(saturation) == 0 and saturation is not None else (
        1.0 if unit is None else float(unit))
    if unit != 1.0:     # the weights (tv, damp) and noise regimes are in units where the sensor clips at 1: solved there
        y = y / np.asarray(unit, y.dtype)
        saturation = 1.0 if np.ndim(saturation) == 0 and saturation is not None else saturation   # a mask stays
        start_planes = None if start_planes is None else np.asarray(start_planes) / unit
    p = _fitted_problem(op, y, saturation)
    if p.n_sat == p.y.size:
        raise ValueError(f"every one of the views' {p.y.size} samples is left out of the fit (clipped, or in a saturation "
                         "mask): there is nothing to solve")
    n_left, n_samples = left_out_samples(op, p.fit)
    lit = int(np.count_nonzero(p.y > 0))
    if np.ndim(given_level) == 0 and given_level is not None and n_left > SATURATED_WARN * max(lit, 1):
        warnings.warn(f"{n_left} of the views' {lit} lit samples ({100 * n_left / max(lit, 1):.0f} %) are at or above "
                      f"the saturation level {given_level:g} and left out of the fit: views in other units than the "
                      "sensor's clipping level (give it: saturation=LEVEL), or a capture over-exposed", UserWarning,
                      stacklevel=2)
    settings = dict(iters=iters, rays_per_pixel=op.rays_per_pixel, seed=op.seed,
                    saturation="mask" if np.ndim(given_level) > 0 else given_level, n_saturated=n_left,
                    n_samples=n_samples)
    if getattr(op, "offset_bins", None):                              # each sample at its own pixel
        settings["sub_views"] = op.offset_bins
    step = _Steps(iters, f"reconstruct ({solver})", progress, callback)
    if (support is not None or l1 or start is not None or tol is not None or state is not None
            or start_planes is not None) and solver != "admm":
        raise ValueError(f"a support, l1, start, start planes, tol and state are for the admm only. Received "
                         f"solver={solver!r}")
    if solver == "admm":
        from .fourier import solve_threads
        with solve_threads(op) as settings["threads"]:
            x, residuals = _solve_admm(p, settings, step, iters if iters_given else None, tv if tv_given else None,
                                       lam=lam, l1=l1, start=start, tol=tol, support=support, state=state,
                                       start_planes=start_planes)
    elif solver == "adjoint":
        x, residuals = _solve_adjoint(p)
    elif solver == "lsqr":
        from .proximal import solve_lsqr
        x, residuals = solve_lsqr(p, settings, step, iters, damp)
    elif solver == "fista":
        from .proximal import solve_fista
        x, residuals = solve_fista(p, settings, step, iters, lipschitz_bound(op))
    elif solver == "pd-tv":
        from .proximal import solve_pd_tv
        x, residuals = solve_pd_tv(p, settings, step, iters, tv, lipschitz_bound(op))
    else:  # rl
        x, residuals = _solve_rl(p, step, iters)
    step.bar.close()
    return _reconstruction(op, x if unit == 1.0 else np.asarray(x) * unit, solver, settings, residuals, t0)


def _checked_inputs(views, op, solver, iters, damp, tv, saturation):
    """:func:`reconstruct`'s inputs checked: ``(solver, iters, tv, y)``, the solver (None: the
    operator's default), iterations and TV weight with their defaults, and the views flat
    (:func:`~lf_flame.tomo.operator.check_views`); the saturation level or mask refused if invalid."""
    if solver is None:
        from .exact import ExactOperator
        solver = EXACT_SOLVER if isinstance(op, ExactOperator) else DEFAULT_SOLVER
    if solver not in SOLVERS:
        raise ValueError(f"solver must be one of {SOLVERS}. Received: {solver!r}")
    if op.dimsd[0] == 1 and op.dims[0] > 1:
        raise ValueError(f"one view per lenslet sees no parallax: the light of {op.dims[0]} planes cannot be told "
                         "apart (any share between them fits the data alike); give one plane, or views of more than "
                         "one pixel per lenslet")
    if iters is not None and (isinstance(iters, bool) or not float(iters).is_integer()):
        raise ValueError(f"iters must be a whole number of iterations. Received: {iters!r}")
    iters = DEFAULT_ITERS[solver] if iters is None else int(iters)
    if solver == "admm" and iters < 1:
        raise ValueError(f"iters (admm's fills of the missing data) must be >= 1. Received: {iters}")
    tv = DEFAULT_TV if tv is None else tv
    if iters < 0 or damp < 0 or tv < 0 or not (math.isfinite(damp) and math.isfinite(tv)):
        raise ValueError(f"iters, damp and tv must be finite and >= 0. Received: {iters}, {damp}, {tv}")
    mask = np.ndim(saturation) > 0
    if mask and (np.asarray(saturation).dtype != bool or np.shape(saturation) != tuple(op.dimsd)):
        raise ValueError(f"a saturation mask must be boolean of the views' shape {tuple(op.dimsd)}. Received: "
                         f"{np.asarray(saturation).dtype} of shape {np.shape(saturation)}")
    if not mask and saturation is not None and not (math.isfinite(saturation) and saturation > 0):
        raise ValueError(f"saturation must be a positive finite level, a mask or None. Received: {saturation!r}")
    return solver, iters, tv, check_views(views, op, keep_float32=solver == "admm").ravel()


@dataclass
class _Problem:
    """What a solver fits: the views ``y`` (flat), the samples that carry their light (``fit``), and, built on
    first use (admm needs neither), the fitted data ``W y`` (``W`` the 0/1 weight of ``fit``) and ``||y||``."""

    op: EmissionOperator
    y: np.ndarray
    fit: np.ndarray
    n_sat: int

    @cached_property
    def yw(self) -> np.ndarray:
        return self.y if self.n_sat == 0 else np.where(self.fit, self.y, 0.0)

    @cached_property
    def norm(self) -> float:
        return float(np.linalg.norm(self.y)) or 1.0


def fitted_pixels(views, saturation) -> np.ndarray:
    """The pixels :func:`reconstruct` fits: below the saturation level, False in a saturation mask, all for None.

    Parameters
    ----------
    views : ndarray (any shape)
    saturation : float, ndarray of bool of the views' shape (True: clipped) or None

    Returns
    -------
    ndarray of bool of the views' shape
    """
    views = np.asarray(views)
    if np.ndim(saturation) > 0:
        return ~np.asarray(saturation, bool).reshape(views.shape)
    return np.ones(views.shape, bool) if saturation is None else views < saturation


def left_out_samples(op: EmissionOperator, fit) -> tuple[int, int]:
    """The samples left out of the fit and the samples there are: on a hexagonal lattice's axial array
    (:class:`~lf_flame.tomo.lattice.LatticeOperator`'s ``inside``) only its cells that hold a lenslet are samples.

    Parameters
    ----------
    op : EmissionOperator
    fit : ndarray of bool of ``op.dimsd``'s size
        The fitted samples (:func:`fitted_pixels`).

    Returns
    -------
    (left out, samples) : (int, int)
    """
    fit = np.asarray(fit, bool).reshape(op.dimsd)
    inside = getattr(op, "inside", None)
    if inside is None:
        return int(fit.size - np.count_nonzero(fit)), int(fit.size)
    inside = np.broadcast_to(inside, fit.shape)
    return int(np.count_nonzero(inside & ~fit)), int(np.count_nonzero(inside))


def _fitted_problem(op: EmissionOperator, y: np.ndarray, saturation) -> _Problem:
    """The saturation mask: samples at or above the level, or True in a mask, left out of the fit
    (none for None)."""
    fit = fitted_pixels(y, np.ravel(saturation) if np.ndim(saturation) > 0 else saturation)   # carry their light
    return _Problem(op, y, fit, int(y.size - np.count_nonzero(fit)))


#: A solve's progress bar shows once it has run this long (s): the found planes' route solves 4-8 times in a few
#: seconds, where a bar each was a screenful of finished bars on stderr.
PROGRESS_DELAY_S = 2.0


class _Steps:
    """Called after each iteration with the iterate: counts it, moves the tqdm bar (shown after
    :data:`PROGRESS_DELAY_S`) and calls :func:`reconstruct`'s ``callback(k, x)`` (``k`` 1-based, ``x`` flat)."""

    def __init__(self, total: int, desc: str, progress: bool, callback):
        self.count, self.callback = 0, callback
        self.bar = tqdm(total=total, desc=desc, unit="it", disable=not progress, delay=PROGRESS_DELAY_S)

    def __call__(self, x):
        self.count += 1
        self.bar.update()
        if self.callback is not None:
            self.callback(self.count, np.ravel(x))


def _solve_admm(p: _Problem, settings: dict, step: _Steps, iters, tv, *, lam, l1, start, tol, support, state=None,
                start_planes=None):
    """``"admm"`` (:func:`lf_flame.tomo.fourier.solve_admm`), the knobs not given by the data's noise
    (:func:`lf_flame.tomo.noise_knobs.admm_knobs`): ``(x, residuals)``."""
    from .exact import ExactOperator
    from .defaults import COARSE_KNOBS, OFFSET_KNOBS
    from .noise_knobs import admm_knobs, noise_regime
    from .fourier import solve_admm
    from .fourier_system import check_lam
    op = p.op
    if not isinstance(op, ExactOperator):
        raise ValueError("the admm solver works on the exact operator's per-frequency matrices: give an "
                         "lf_flame.tomo.exact.ExactOperator")
    if lam is not None:                     # before the noise is measured (a negative lam had given planes of NaN)
        check_lam(lam)
    if op.offset_bins is not None and iters is None:                  # samples off the views' grid: slower fills
        iters, tol = OFFSET_KNOBS["fills"], OFFSET_KNOBS["tol"] if tol is None else tol
    knobs = admm_knobs(p.y.reshape(op.dimsd), p.fit.reshape(op.dimsd), iters, tv, lam, op.subsamples, l1, start, tol)
    iters = knobs.pop("fills")
    settings.update(iters=iters, subsamples=op.subsamples, **knobs)
    if state:
        settings["start"] = "continued"                               # from the previous frame's solve
    elif start_planes is not None:
        settings["start"] = "given"
    step.bar.total = iters                                            # the fills the noise chose
    planes, residuals, settings["system_s"] = solve_admm(
        p.y.reshape(op.dimsd), op, p.fit.reshape(op.dimsd), fills=iters, lam=knobs["lam"], tv=knobs["tv"],
        l1=knobs["l1"], start=knobs["start"], tol=knobs["tol"], support=support, callback=lambda j, x: step(x),
        coarse_knobs=COARSE_KNOBS[noise_regime(knobs["noise"])] if math.isfinite(knobs["noise"]) else None,
        state=state, start_planes=start_planes)
    settings["fills_run"] = step.count
    return planes.ravel(), residuals


def _solve_adjoint(p: _Problem):
    """``"adjoint"``: ``A^T y / A^T 1``, no iterations: ``(x, residuals)``."""
    x = p.op.normalised_adjoint(p.y.reshape(p.op.dimsd)).ravel()
    return x, [float(np.linalg.norm(p.op.matvec(x) - p.y)) / p.norm]


#: ``rl``'s floors, relative: the planes' samples that no fitted ray sees (``A^T 1`` below this share of its maximum:
#: an FFT operator leaves its rounding where nothing is seen) and the prediction a data sample is divided by (this
#: share of the data's peak: a prediction at an FFT's rounding, a dark sample's noise over it, made ratios of 1e12
#: that overflowed the float32 operator of decoded views into NaN).
RL_SEEN = 1e-6


def _solve_rl(p: _Problem, step: _Steps, iters: int):
    """``"rl"``: Richardson-Lucy from a flat start at the data's level, the saturated samples'
    ratio left out: ``(x, residuals)``."""
    op, y, fit, residuals = p.op, p.y, p.fit, []
    ones = op.rmatvec(fit.astype(np.float64))
    seen = ones > RL_SEEN * ones.max()                 # an FFT operator's adjoint leaves rounding where nothing is seen
    yp = np.clip(p.yw, 0.0, None)
    n = op.shape[1]
    x = np.full(n, max(float(yp[fit].mean()) if p.n_sat < y.size else 0.0, 1e-12))   # flat start, the data's level
    floor = RL_SEEN * max(float(yp.max()), 1e-12)     # a prediction near 0 (an FFT's rounding): no ratio of 1e12
    for _ in range(iters):
        ax = op.matvec(x)
        residuals.append(float(np.linalg.norm(np.where(fit, ax - y, 0.0))) / p.norm)
        ratio = np.where(fit, yp / np.maximum(ax, floor), 0.0)
        x = np.where(seen, x * op.rmatvec(ratio) / np.where(seen, ones, 1.0), 0.0)
        step(x)
    return x, residuals


def _reconstruction(op: EmissionOperator, x, solver: str, settings: dict, residuals, t0: float) -> Reconstruction:
    """The result record: the planes on the operator's grids, each grid's sample size (mm) and the wall
    time since ``t0``."""
    sample = tuple((h / op.dims[1], w / op.dims[2]) for h, w in op.sizes_mm)
    return Reconstruction(np.asarray(x).reshape(op.dims), op.depths_mm, sample, solver, settings,
                          np.asarray(residuals, np.float64), time.perf_counter() - t0)
