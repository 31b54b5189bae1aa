"""Depths the votes missed, found in a solve's residual (peel).

Where flames share columns each lenslet of :func:`lf_flame.tomo.depth.find_depths` votes once,
for the sharper or brighter flame, and the other may win no vote. After the solve on the voted
depths, the residual views (data minus the planes' prediction) refocused over each region
peak at a missed flame's depth, where noise refocuses flat (:func:`missed_depths`);
:func:`peel_planes` adds such depths and solves again, the route of
:func:`lf_flame.tomo.found_planes.find_planes` and ``lf-flame reconstruct``.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import PlenopticCamera
from ..refocus.shift_and_sum import _check_finite
from .depth import FoundDepths, depth_tolerances, plane_runs, searched_depths
from .focus import _focus_energy, _grid_depths, _half_width, _peak_fit

#: A depth the solve missed (:func:`missed_depths`): the residual views' Tenengrad energy over a region, refocused,
#: peaks at least ``RESIDUAL_PROMINENCE`` robust standard deviations (1.4826 times the median absolute deviation
#: over the slopes) above its median, and at least ``RESIDUAL_SHARE`` of the data's peak energy at the depths found
#: there. Noise adds a nearly flat floor to the curve: it raises the median but not the spread, so the prominence
#: keeps a missed flame's peak where the peak over the median (the first measure) falls below its threshold at 14 dB.
#: Chosen on 56 validation column scenes (``column_scene``, seeds 3950000-3950015 and 3960000-3960039, 100 rays per
#: pixel, noise-free and 14 dB; a ``/tmp`` probe): the flames the votes missed peak 8.4-109 deviations above the
#: median with 0.011-0.18 of the data's energy; the residual's misfits about found flames reach 6.5 deviations where
#: they hold 0.01 of it or more, and those that stand higher (up to 74) hold at most 0.0056.
RESIDUAL_PROMINENCE = 7.5
RESIDUAL_SHARE = 0.01
#: A colour capture's levelled mosaic (:func:`lf_flame.temperature.mosaic.monochrome_light_field`) leaves a residual
#: that alternates between its channels' samples where the flame's colour varies; on a hexagonal lattice the pattern
#: repeats every other row of lenslets and refocuses to sharp peaks at false depths (a new user's 50 x 43-lenslet
#: GRBG camera: 4 and 6 false depths beside 4 and 3 flames, the solve 3-5 times slower; the same camera on a square
#: grid, or without its mosaic, none). A hexagonal colour capture's residual is smoothed by a Gaussian of this many
#: lenslets before each search (:func:`missed_depths`' ``smooth``): on that camera's four captures 2 lenslets left
#: no false depth (1 lenslet: one, in one capture). Not on a square grid: on the paper camera's colour captures of
#: two flames one behind another (``experiments/studies/colour_behind_depths.py``, 9 scenes) the smoothed residual
#: lost every flame behind that the search had found there (14 -> 9 of 18 flames found).
COLOUR_RESIDUAL_SMOOTH = 2.0
#: Rounds of :func:`missed_depths` in :func:`~lf_flame.tomo.found_planes.find_planes` (each a search of the residual
#: and a solve).
PEEL_ROUNDS = 2


def missed_depths(residual, camera: PlenopticCamera, found: FoundDepths, *, prominence: float = RESIDUAL_PROMINENCE,
                  share: float = RESIDUAL_SHARE, excess: float = 0.0, sigma: float = 1.5,
                  min_separation_mm: float | None = None, merge_mm: float | None = None, regions=None,
                  possible: list | None = None, possible_prominence: float = RESIDUAL_PROMINENCE,
                  smooth: float = 0.0):
    """Depths the votes missed, found in a solve's residual: a flame behind (or before) another in the same
    columns, whose lenslets voted for the other.

    The residual views (data minus the found planes' prediction) are refocused band-limited at
    ``found.grid_slopes`` (:class:`~lf_flame.refocus.shift_and_sum.FourierSlice`); per region of
    ``found`` the Tenengrad energy summed over the region, at the slopes farther than
    ``min_separation_mm`` from the depths found there. Noise refocuses to a flat curve and a
    flame's missing light to a peak at its depth: where the peak stands ``prominence`` robust
    standard deviations (1.4826 times the median absolute deviation over the slopes) above the
    curve's median and holds ``share`` of the data's peak energy at the region's
    found depths (``found.curves``; the solve's misfit about a found flame is fainter), and its
    height above that median ``excess`` of it (the noise's floor left out), its depth
    (refined as :func:`~lf_flame.tomo.depth.find_depths` refines) joins the region's, its footprint the region.

    Parameters
    ----------
    residual : ndarray of shape (N, N, R, C)
        Data minus prediction, 0 where not fitted.
    camera : PlenopticCamera
    found : FoundDepths
        The depths the solve was on.
    prominence : float
        The peak's height above the residual's focus curve's median, in robust standard
        deviations of the curve, > 0 (:data:`RESIDUAL_PROMINENCE`).
    share : float
        Peak over the data's, >= 0 (:data:`RESIDUAL_SHARE`).
    excess : float
        The peak's height above the curve's median over the data's peak, >= 0 (0: not asked).
    sigma, min_separation_mm, merge_mm : float (the last two or None)
        As :func:`~lf_flame.tomo.depth.find_depths` (None: scaled to the camera as there).
    regions : sequence of int or None
        The regions (``found.region`` labels) to search; None: all.
    possible : list or None
        Where given, each peak that meets every test but ``prominence`` while standing at least
        ``possible_prominence`` deviations high is appended to it as a dict (``depth_mm``,
        ``prominence``, ``share``, ``region``): a depth seen, not taken.
    possible_prominence : float
        Deviations for ``possible`` (:data:`RESIDUAL_PROMINENCE`).
    smooth : float
        The residual's views smoothed by a Gaussian of this many lenslets (per view, >= 0; 0: not) before they are
        refocused (:data:`COLOUR_RESIDUAL_SMOOTH` for a colour capture's levelled mosaic on a hexagonal lattice).

    Returns
    -------
    FoundDepths or None
        ``found`` with the missed depths added (planes merged again), or None where none was missed.

    Raises
    ------
    ValueError
        A residual of another shape than the camera's views, or not finite; ``prominence`` <= 0, ``share`` < 0,
        ``smooth`` < 0 or not finite.
    """
    if not (math.isfinite(float(prominence)) and prominence > 0):
        raise ValueError(f"prominence must be finite and > 0. Received: {prominence!r}")
    for name, value in (("share", share), ("excess", excess)):
        if not (math.isfinite(float(value)) and value >= 0):
            raise ValueError(f"{name} must be a finite ratio >= 0. Received: {value!r}")
    n = camera.pixels_per_lenslet
    if not (math.isfinite(float(smooth)) and smooth >= 0):
        raise ValueError(f"smooth must be a finite width >= 0 (lenslets). Received: {smooth!r}")
    r = np.ascontiguousarray(residual, np.float32)
    if r.shape != (n, n, camera.n_rows, camera.n_cols):
        raise ValueError(f"residual must have the camera's views' shape {(n, n, camera.n_rows, camera.n_cols)}. "
                         f"Received: {r.shape}")
    _check_finite("residual", r)
    if smooth > 0:
        from scipy.ndimage import gaussian_filter
        r = gaussian_filter(r, (0, 0, float(smooth), float(smooth)))
    if not np.any(r) or not len(found.depths_mm):
        return None
    min_separation_mm = depth_tolerances(camera, n, min_separation_mm)[0]
    slopes = found.grid_slopes
    ten = _focus_energy(r, slopes, sigma, mask=found.views_mask)                # the views the votes searched
    depth_of = _grid_depths(camera, slopes)      # NaN where the grid runs past what the camera images
    ok = np.flatnonzero(np.isfinite(depth_of))
    dz_ds = abs(depth_of[ok[-1]] - depth_of[ok[0]]) / max(abs(slopes[ok[-1]] - slopes[ok[0]]), 1e-12)
    searched = sorted(camera.slope_for_depth(d) for d in searched_depths(camera, found))   # a peak past: at the end
    rows = []
    for lab in np.unique(found.region) if regions is None else np.intersect1d(found.region, regions):
        reg = found.labels == lab
        curve = ten[:, reg].sum(axis=1)
        have = found.depths_mm[found.region == lab]
        free = np.all(np.abs(depth_of[:, None] - have[None]) > min_separation_mm, axis=1)
        if not free.any():
            continue
        i = int(np.flatnonzero(free)[np.argmax(curve[free])])
        data_peak = max(float(found.curves[k].max()) for k in np.flatnonzero(found.region == lab))
        med = float(np.median(curve))
        spread = 1.4826 * float(np.median(np.abs(curve - med)))
        if not (curve[i] > med and curve[i] >= share * data_peak and curve[i] - med >= excess * data_peak):
            continue
        s = float(np.clip(np.interp(_peak_fit(curve, i), np.arange(len(slopes)), slopes), *searched))
        if not curve[i] - med >= prominence * spread:
            if possible is not None and curve[i] - med >= possible_prominence * spread:
                possible.append(dict(depth_mm=camera.depth_for_slope(s), prominence=(curve[i] - med) / spread,
                                     share=curve[i] / data_peak, region=int(lab)))
            continue
        width = 2 * _half_width(curve, i) * (slopes[1] - slopes[0]) * dz_ds
        rows.append(dict(depth=camera.depth_for_slope(s), slope=s, unc=0.1 * 0.5 * width, width=width,
                         region=int(lab), mask=reg, curve=curve))
    if not rows:
        return None
    d = np.concatenate([found.depths_mm, [q["depth"] for q in rows]])
    order = np.argsort(d, kind="stable")
    cat = lambda old, key: np.concatenate([np.asarray(old), np.array([q[key] for q in rows])])[order]
    weight = np.concatenate([found.weight, np.zeros(len(rows))])[order]      # no votes: found in the residual
    planes, plane_of = plane_runs(camera, n, d[order], weight, merge_mm)
    curves = list(found.curves) + [q["curve"] for q in rows]
    return FoundDepths(depths_mm=d[order], slopes=cat(found.slopes, "slope"), uncertainty_mm=cat(found.uncertainty_mm, "unc"),
                       width_mm=cat(found.width_mm, "width"), weight=weight, region=cat(found.region, "region"),
                       masks=np.concatenate([found.masks, np.array([q["mask"] for q in rows])])[order],
                       labels=found.labels, planes_mm=planes, plane_of=plane_of,
                       curves=[curves[k] for k in order], grid_slopes=slopes, time_s=found.time_s,
                       depth_range_mm=found.depth_range_mm, views_mask=found.views_mask)


def peel_planes(found: FoundDepths, op, rec, data, fit, camera: PlenopticCamera, solve, rounds: int = PEEL_ROUNDS,
                residual=None, smooth: float = 0.0):
    """Search a solve's residual for depths the votes missed and solve again with them, up to ``rounds`` times
    (:func:`missed_depths`): :func:`~lf_flame.tomo.found_planes.find_planes`' and ``lf-flame reconstruct``'s route.

    Parameters
    ----------
    found : FoundDepths
        The depths ``rec`` was solved on.
    op, rec : the operator of the planes and its :class:`~lf_flame.tomo.solvers.Reconstruction`
    data : ndarray of shape (N, N, R, C)
        The data ``rec`` fitted (the operator's units).
    fit : ndarray of bool of the data's shape
        The samples it fitted (:func:`lf_flame.tomo.solvers.fitted_pixels`).
    camera : PlenopticCamera
        The views' camera.
    solve : callable
        ``solve(found, start=None) -> (op, rec)``: the planes of ``found`` solved as ``rec`` was; ``start``, where
        given, a :class:`~lf_flame.tomo.solvers.Reconstruction` on as many planes a little apart in depth, which
        admm starts from (``reconstruct``'s ``start_planes``; :func:`~lf_flame.tomo.refine.refine_planes`).
    rounds : int
        >= 0.
    residual : callable or None
        ``residual(op, rec)``: the data minus ``rec``'s prediction where fitted
        (:class:`~lf_flame.tomo.solvers.Residuals`, which keeps the last ones for the route's next
        step); None: :func:`~lf_flame.tomo.solvers.fitted_residual` of ``data`` and ``fit``.
    smooth : float
        As :func:`missed_depths`.

    Returns
    -------
    found, op, rec
        With the missed depths, or the ones given.
    """
    from .solvers import Residuals
    if int(rounds) != rounds or rounds < 0:
        raise ValueError(f"rounds must be an integer >= 0. Received: {rounds!r}")
    residual = Residuals(data, fit) if residual is None else residual
    for _ in range(int(rounds)):
        more = missed_depths(residual(op, rec), camera, found, smooth=smooth)
        if more is None:
            break
        found = more
        op, rec = solve(found)
    return found, op, rec
