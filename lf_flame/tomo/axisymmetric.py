"""Axisymmetric volumes: a laminar flame's emission ``e(r, y)`` about a vertical axis.

A dense stack of planes does not resolve a whole flame in depth from the data alone
(README, "The camera's depth resolution"). A laminar flame is axisymmetric: its emission
is a function ``e(r, y)`` of the height ``y`` and the distance ``r`` from a vertical axis
at lateral position ``x0`` and depth ``z0``. That prior turns the ``P x rows x cols`` stack
into ``rows x n_r`` unknowns that every plane shares (the onion-peeling / Abel model of
flame tomography; e.g. Dasch, Appl. Opt. 31 (1992), here composed with the light-field map).

- :class:`~lf_flame.tomo.revolve.RevolveOperator` (``R``): ``e`` on radial nodes ``r_j = j dr`` (linear "hat"
  interpolation in ``r``) and on the rows of the grid at the axis's depth (linear in
  height), revolved onto the planes of an exact operator: each voxel reads ``e`` at its
  distance from the axis, ``sqrt((x - x0)^2 + (z - z0)^2)``, and its height. A sparse
  matrix (at most four entries per voxel); ``R^T`` its exact transpose.
- :func:`solve_axisymmetric`: non-negative least squares on ``e`` with a small
  smoothness ``lam ||D e||^2`` (first differences along ``r`` and ``y``), by projected
  FISTA (Beck & Teboulle, SIAM J. Imaging Sci. 2 (2009)) on the exact operator's
  per-frequency normal matrices ``G(f)`` (:func:`lf_flame.tomo.fourier_system.normal_matrices`),
  with the sensor window's and saturated pixels' missing data filled from the prediction
  as :func:`lf_flame.tomo.fourier.solve_admm` does (each *fill* one ``H`` and one ``H^H``
  over the views; the FISTA steps between fills run on the planes alone).
- **Flames cut by the field's edge.** Where the light reaches an edge of the field
  (:func:`~lf_flame.tomo.axis.reaches_edge`), ``e`` is revolved onto the planes of
  :func:`~lf_flame.tomo.revolve.wide_operator` (the field's planes widened by the exact operator's reach), so the light
  that parallax brings in from beyond the field is fitted too; the volume returned is the field's part.
- **The axis.** ``x0`` from the central view's (a pinhole image's) column centroid at the
  axis's depth (its mirror centre where the lit columns reach the view's edge); ``z0``
  searched by :func:`scipy.optimize.minimize_scalar` (bounded) on the data residual of a
  shorter solve, about a start from :func:`lf_flame.tomo.depth.find_depths` (its found depth
  with the most votes) unless given.

The model and its fit for one axis are :mod:`lf_flame.tomo.revolve`'s; what the views tell before
any fit (the axis's lateral position, a cut by the field's edge) :mod:`lf_flame.tomo.axis`'s; this
module is the route: the axis's depth searched, the final fit, the volume.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from .axis import axis_x_from_views, lit_profile, reaches_edge
from .fourier import fill_data
from .noise_knobs import noise_regime, relative_noise
from .revolve import NormalMatrices, RevolveOperator, fit_emission, frame_at, resized_emission, wide_operator

#: Smoothness weight of :func:`solve_axisymmetric`, relative to the mean diagonal of ``R^T G R``, per noise level
#: of the light field (:func:`lf_flame.tomo.noise_knobs.noise_regime`), chosen on 3 validation volumes by the lowest
#: worst 3-D error (``python experiments/volume.py --set axi-lam``, ``results/volume_axi_lam.md``): at 14 dB
#: 9.4 % at 1 against 11.8 % at the 1e-3 set by hand before; noise-free the worst volume (a filled core, 15.2 %)
#: barely moves from 1e-3 to 3 (0.01 the lowest by 0.02 %), the median is lowest at 1 (4.0 against 4.5 %).
AXI_LAM = {"quiet": 0.01, "noisy": 1.0}
#: Fills of the missing data (outer iterations) and FISTA steps per fill of a final solve. 100 steps: a filled
#: core converges slowly near the axis (25 steps left a core 15.9 % off with its true axis, 100 steps 6.7 %).
AXI_FILLS = 8
AXI_INNER = 100
#: ... and of each solve of the axis search (a shorter one: only the residual's minimum matters). 50 steps per fill,
#: chosen on the validation volumes (``python experiments/volume.py --set search``, ``results/volume_search.md``):
#: with 15 the trials had not converged near a filled core's axis and their residual's minimum lay off it (cores
#: 0.24 and 0.37 mm off in depth noise-free, 0.01 and 0.12 mm with 50), at about 1.7 times the search's time.
SEARCH_FILLS = 3
SEARCH_INNER = 50
#: Half width (mm) of the bracket the axis depth is searched in about its start, and the search's tolerance.
SEARCH_HALF_WIDTH_MM = 3.0
SEARCH_TOL_MM = 0.05
#: Spacing (mm) of the scan that picks the residual's basin before the bounded search refines within one
#: spacing of the scan's best: the short trials' residual is not unimodal over the bracket for a filled core
#: (a validation core at -1.6 mm, seed 603: the bounded search alone stopped at -0.87 mm, 3-D error 31.7 %).
SEARCH_SCAN_MM = 0.5
@dataclass
class AxisymmetricVolume:
    """What :func:`solve_axisymmetric` returns.

    Attributes
    ----------
    emission : ndarray of shape (rows, n_r), float64
        ``e`` at ``heights_mm`` x ``radii_mm`` (the planes' units), non-negative.
    radii_mm, heights_mm : ndarray
    volume : ndarray of shape (P, rows, cols), float64
        ``e`` revolved onto the operator's planes.
    axis_x_mm, axis_z_mm : float
        The axis used (given or found).
    residual : float
        ``||M (w H R e - y)|| / ||M y||`` on the fitted pixels ``M``.
    search : list of (float, float)
        Each axis depth tried by the search (mm) and its residual (empty when ``z0`` was given).
    time_s : float
        Wall time, seconds (normal matrices, search and solve).
    lam : float
        The smoothness weight used (given, or :data:`AXI_LAM` for the light field's noise).
    beyond_field : bool
        Whether the light from beyond the field was modelled (``solve_axisymmetric``'s
        ``beyond_field``); ``heights_mm`` then span the widened grid.
    start_uncertainty_mm : float
        Where the axis depth was searched about the depth found with the most votes: that depth's uncertainty
        (:class:`~lf_flame.tomo.depth.FoundDepths`' ``uncertainty_mm``, mm); NaN otherwise. Wider than the search's
        half width (:data:`SEARCH_HALF_WIDTH_MM`), the camera does not place the flame well enough in depth for the
        search: its residual's minima are then those of the planes' spacing (a user's camera of 30 mm depth
        resolution: axis 4 mm off, no word).
    """

    emission: np.ndarray
    radii_mm: np.ndarray
    heights_mm: np.ndarray
    volume: np.ndarray
    axis_x_mm: float
    axis_z_mm: float
    residual: float
    search: list = field(default_factory=list)
    time_s: float = float("nan")
    lam: float = float("nan")
    beyond_field: bool = False
    start_uncertainty_mm: float = float("nan")


def _check(views, op, fit):
    v = np.asarray(views, np.float64)
    if v.shape != tuple(op.dimsd):
        raise ValueError(f"views must have the operator's data shape {tuple(op.dimsd)}. Received: {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError("views hold NaN or infinite values")
    if not hasattr(op, "_spec"):
        raise ValueError("solve_axisymmetric needs an ExactOperator (lf_flame.tomo.exact): its normal matrices")
    if op.subsamples != 1:
        raise ValueError(f"solve_axisymmetric works on the lenslet grid: give an ExactOperator with subsamples=1. "
                         f"Received subsamples={op.subsamples}")
    f = v < 1.0 if fit is None else np.asarray(fit)
    if f.shape != v.shape or f.dtype != bool:
        raise ValueError(f"fit must be boolean of the views' shape {v.shape}. Received: {f.dtype} of shape {f.shape}")
    return v, f


def solve_axisymmetric(views, op, fit=None, *, axis_x_mm: float | None = None, axis_z_mm: float | None = None,
                       r_max_mm: float | None = None, dr_mm: float | None = None, lam: float | None = None,
                       fills: int = AXI_FILLS, inner: int = AXI_INNER, search_half_width_mm: float = SEARCH_HALF_WIDTH_MM,
                       search_fills: int = SEARCH_FILLS, search_inner: int = SEARCH_INNER,
                       search_tol_mm: float = SEARCH_TOL_MM, start_z_mm: float | None = None, camera=None,
                       normal=None, beyond_field: bool | None = None) -> AxisymmetricVolume:
    """An axisymmetric flame's emission ``e(r, y)`` and its volume from one light field (module docstring).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The light field (radiance units), :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    op : ExactOperator
        The dense stack the volume is returned on (its planes should span the flame).
    fit : ndarray of bool of shape (N, N, R, C) or None
        Pixels to fit (False: saturated, left out); None: ``views < 1``.
    axis_x_mm, axis_z_mm : float or None
        The axis (mm); None: found (``x0`` by :func:`~lf_flame.tomo.axis.axis_x_from_views`, ``z0`` by the search).
    r_max_mm : float or None
        Outermost radius (mm); None: 0.6 x the width of the central view's lit columns at
        the axis's depth (a flame's half width with a margin); where they reach the view's
        edge, 1.2 x the distance from the axis to their farther end (the uncut side's).
    dr_mm : float or None
        Radial node spacing (:class:`~lf_flame.tomo.revolve.RevolveOperator`).
    lam : float or None
        Weight of ``||D e||^2`` (first differences in ``y`` and ``r``) relative to the mean
        diagonal of ``R^T G R`` (>= 0); None: :data:`AXI_LAM` for the light field's noise level
        (:func:`lf_flame.tomo.noise_knobs.relative_noise` of the fitted pixels).
    fills, inner : int
        Fills of the missing data and FISTA steps per fill of the final solve (>= 1).
    search_half_width_mm, search_fills, search_inner, search_tol_mm : float, int, int, float
        The axis depth's search: bracket ``start ± half width`` (mm), each trial's shorter solve,
        the tolerance (mm). The bracket is scanned every :data:`SEARCH_SCAN_MM` first; the
        bounded search (Brent) then refines within one spacing of the scan's lowest residual.
    start_z_mm : float or None
        Start of the search; None: the depth of :func:`lf_flame.tomo.depth.find_depths` with the
        most votes (``camera``'s).
    camera : PlenopticCamera or None
        For :func:`~lf_flame.tomo.depth.find_depths`; None: ``op.camera``.
    normal : object or None
        Normal matrices from an earlier call (``result``'s operator cache); None: computed
        (and kept on the operator solved on).
    beyond_field : bool or None
        Model the flame's light from beyond the field: ``e`` is revolved onto the planes of
        :func:`~lf_flame.tomo.revolve.wide_operator` (``op``'s planes widened by the kernels' reach) and fitted there,
        and the volume returned is its part on ``op``'s grid. None: when the light reaches
        the field's edge (:func:`~lf_flame.tomo.axis.reaches_edge`) and ``op`` has margin 1.

    Returns
    -------
    AxisymmetricVolume

    Raises
    ------
    ValueError
        Views not of the operator's shape or not finite; not an exact operator; a fit mask
        not boolean of the views' shape; iterations below 1; a negative or non-finite
        ``lam``; a non-positive search width or tolerance; a radius or axis the
        :class:`~lf_flame.tomo.revolve.RevolveOperator` refuses; a search that would start outside
        the stack's depths (the search stays within them).
    """
    t0 = time.perf_counter()
    v, f = _check(views, op, fit)
    if lam is None:
        lam = AXI_LAM[noise_regime(relative_noise(v, f))]
    for name, k in (("fills", fills), ("inner", inner), ("search_fills", search_fills), ("search_inner", search_inner)):
        if int(k) != k or k < 1:
            raise ValueError(f"{name} must be an integer >= 1. Received: {k!r}")
    if not (math.isfinite(lam) and lam >= 0):
        raise ValueError(f"lam must be finite and >= 0. Received: {lam!r}")
    if not (search_half_width_mm > 0 and search_tol_mm > 0):
        raise ValueError(f"search_half_width_mm and search_tol_mm must be > 0. Received: {search_half_width_mm!r}, "
                         f"{search_tol_mm!r}")
    if beyond_field is None:
        beyond_field = op.margin == 1 and any(reaches_edge(v))
    model = op
    if beyond_field:
        model = op.__dict__.get("_axisymmetric_wide") or wide_operator(op)
        op.__dict__["_axisymmetric_wide"] = model
    if normal is None:
        normal = model.__dict__.get("_axisymmetric_normal") or NormalMatrices(model)
        model.__dict__["_axisymmetric_normal"] = normal
    lit = model._lit
    yt, w2, norm = fill_data(v, f, model)

    lit_cols = np.flatnonzero(lit_profile(v))
    cut = len(lit_cols) and (lit_cols[0] == 0 or lit_cols[-1] == v.shape[3] - 1)

    def revolve_at(z0):
        x0 = axis_x_from_views(v, op, z0, f) if axis_x_mm is None else float(axis_x_mm)
        rmax = r_max_mm
        if rmax is None:
            _, wz = frame_at(op, z0)
            left, right = (np.array([lit_cols[0], lit_cols[-1] + 1]) / op.dims[2] - 0.5) * wz
            rmax = 1.2 * (max(x0 - left, right - x0) if cut else 0.5 * (right - left))   # cut: the far side's
        return RevolveOperator(model, x0, z0, rmax, dr_mm)

    search, start_unc = [], float("nan")
    # on the widened grid the light beyond the field is known through the fills alone: each trial, and the final
    # solve, start from the best trial's e (from zero, 3 fills leave it dark and bias the residual's minimum)
    warm = {}
    if axis_z_mm is None:
        if start_z_mm is None:
            from .depth import find_depths
            found = find_depths(v, camera if camera is not None else op.camera)
            if not len(found.depths_mm):
                raise ValueError("find_depths found no flame in the views: give axis_z_mm or start_z_mm")
            start_z_mm = float(found.depths_mm[np.argmax(found.weight)])     # the flame's: the most votes
            start_unc = float(found.uncertainty_mm[np.argmax(found.weight)])

        def trial(z0):
            rev = revolve_at(z0)
            e, res = fit_emission(model, normal, yt, w2, norm, lit, rev, lam, search_fills, search_inner,
                                   resized_emission(warm.get("e"), rev.dims) if beyond_field else None)
            search.append((float(z0), float(res)))
            if res < warm.get("residual", np.inf):
                warm.update(e=e.reshape(rev.dims), residual=res)
            return res
        z_lo, z_hi = float(np.min(op.depths_mm)), float(np.max(op.depths_mm))
        if not z_lo <= start_z_mm <= z_hi:
            raise ValueError(f"the axis is searched about {start_z_mm:+.2f} mm (the flame found with the most votes), "
                             f"outside the stack's {z_lo:+g} to {z_hi:+g} mm: widen the stack about it (the command's "
                             "--from, --to), or give the axis's depth (solve_axisymmetric's axis_z_mm, in Python)")
        lo, hi = max(start_z_mm - search_half_width_mm, z_lo), min(start_z_mm + search_half_width_mm, z_hi)
        scan = np.linspace(lo, hi, max(int(round((hi - lo) / SEARCH_SCAN_MM)), 1) + 1)
        k = int(np.argmin([trial(z) for z in scan]))
        best = optimize.minimize_scalar(trial, bounds=(scan[max(k - 1, 0)], scan[min(k + 1, len(scan) - 1)]),
                                        method="bounded", options=dict(xatol=search_tol_mm))
        axis_z_mm = float(best.x)
    rev = revolve_at(float(axis_z_mm))
    e, res = fit_emission(model, normal, yt, w2, norm, lit, rev, lam, fills, inner,
                           resized_emission(warm.get("e"), rev.dims) if beyond_field else None)
    (_, gr, gc), (_, wr, wc) = op.dims, model.dims
    volume = (rev.matrix @ e).reshape(model.dims)[:, (wr - gr) // 2:(wr + gr) // 2, (wc - gc) // 2:(wc + gc) // 2]
    return AxisymmetricVolume(emission=e.reshape(rev.dims), radii_mm=rev.radii_mm, heights_mm=rev.heights_mm,
                              volume=volume, axis_x_mm=rev.axis_x_mm, axis_z_mm=float(axis_z_mm), residual=float(res),
                              search=search, time_s=time.perf_counter() - t0, lam=float(lam),
                              beyond_field=bool(beyond_field), start_uncertainty_mm=start_unc)
