"""Find the planes: the depths that hold emission in one light field, then the emission on them (issue 36, step 1).

Whole flames are not depth-resolved by the data's normal matrices alone (NOTES.md,
"Depth resolution"), so depths come from the views: depth from focus.

1. **Regions.** The central sub-aperture view is a pinhole image, sharp at every depth:
   smoothed (Gaussian, 1 lenslet), thresholded at ``threshold`` of its maximum, dilated and
   labelled (:func:`skimage.measure.label`); each connected region holds one or more flames.
2. **Focus per pixel.** The views refocused band-limited at a coarse slope grid
   (:class:`lf_flame.refocus.shift_and_sum.FourierSlice`, which has no whole-lenslet bias);
   per slope the local Tenengrad energy (squared Sobel gradient, Krotkov 1987) smoothed
   over ``sigma`` lenslets. Each pixel of a region votes for the slope of its largest
   energy, if that energy's contrast over the curve's median is at least ``vote_floor`` of the
   region's (so a dim flame in front of a bright one has as many votes as lenslets it is sharp in).
3. **Depths per region.** Peaks of the region's vote histogram (several where flames stand
   one behind another, :func:`scipy.signal.find_peaks`); per peak the energy summed over the
   pixels that voted for it, and the slope of its maximum refined by a parabola through the
   log energy at the three grid slopes about it (a Gaussian peak: exact for one). Slope ->
   depth by :meth:`~lf_flame.optics.camera.PlenopticCamera.depth_for_slope`.
4. **Uncertainty.** The same refinement on the Laplacian energy (variance of Laplacian, Pech-
   Pacheco et al. 2000) gives a second depth; the uncertainty is the larger of half their
   difference and a tenth of the Tenengrad peak's half width at half maximum in depth (the
   resolution of the fit); ``width_mm`` is that full width.
5. **Planes.** Found depths closer than ``merge_mm`` are one plane (their vote-weighted
   mean depth); :func:`find_planes` then solves for the emission on those planes with
   ``reconstruct(views, emission_operator(camera, planes), "admm")``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage, signal
from skimage import measure

from ..optics.camera import PlenopticCamera
from ..refocus.shift_and_sum import FourierSlice, _check_finite, aperture_mask

#: Depths (mm from the focal plane) searched unless told: the paper camera's usable slopes (-1.9 .. +2.8).
DEPTH_RANGE_MM = (-15.0, 25.0)
#: Coarse slope step (lenslets per view step) on 15 views: about 0.33 mm of depth at the paper camera's focal
#: plane; on ``N`` views ``SLOPE_STEP * 14 / (N - 1)``, so that the outermost view moves as far per step.
SLOPE_STEP = 0.04
#: Found depths closer than this (mm) are solved as one plane.
MERGE_MM = 1.0
#: A depth the solve missed (:func:`missed_depths`): the residual views' Tenengrad energy over a region, refocused,
#: peaks at least ``RESIDUAL_CONTRAST`` times its median over the slopes, and at least ``RESIDUAL_SHARE`` of the
#: data's peak energy at the depths found there. Chosen on validation column scenes (``column_scene``, seeds
#: 3950000-3950015, 100 rays per pixel, noise-free and 14 dB; a ``/tmp`` probe): the 12 flames the votes missed
#: peak 14-82 times their median with 0.015-0.18 of the data's energy; the 20 residual misfits about found flames
#: 1.3-8.6 times (one 23 times, with 0.0009) with at most 0.008.
RESIDUAL_CONTRAST = 12.0
RESIDUAL_SHARE = 0.01
#: Rounds of :func:`missed_depths` in :func:`find_planes` (each a search of the residual and a solve).
PEEL_ROUNDS = 2
#: Lenslets a region is grown by to make its planes' support (:func:`plane_support`).
SUPPORT_DILATION = 3
#: Planes whose parallax across the aperture differs by less than this (lenslets) hold emission only in their own
#: regions where they meet (:func:`near_plane_support`). Chosen on validation scenes of ``experiments/cameras.py``
#: (seeds 57000-57005): on the rotated camera (12 views, a deep field) found planes lie 0.3-3 lenslets apart and
#: without it the flames' emission error p90 is 57 % (1 lenslet: 25 %; 2: 7.5 %; 3: 7.5 %; every plane held to its
#: regions: 7.1 %); on the paper camera 3 lenslets holds one pair (2.1 apart), its worst flame 11.0 -> 6.3 %, the
#: p90 unchanged (5.6 %), where holding every plane costs it (8.4 %).
NEAR_PARALLAX = 3.0
#: admm's knobs with a support (``lf-flame reconstruct --support``, ``find_planes(support=True)``): TV 0.3 flattens
#: flames a few lenslets wide (``experiments/depth.py --variant support``, validation seeds 100-107). Where planes
#: lie within a lenslet of parallax of each other (a camera of few views and a deep field: the rotated camera of
#: ``experiments/cameras.py``) their emission otherwise splits between them: on that camera's validation scenes
#: (seeds 57000-57004) the support took the worst flame per scene from 43-66 % to 2-20 %. On the paper camera
#: without it the flames' p90 is 6.1 % against 14.6 % with it (``results/depth.md``, ``results/depth_support.md``).
SUPPORT_KNOBS = {"lam": 0.01, "tv": 0.0}
#: The found planes' admm knobs where they differ from admm's own for the planes' grid and the light field's
#: noise level (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`), chosen on validation scenes of flames at random
#: depths (``python experiments/depth.py --tune``, ``results/depth_tune.md``; 20 scenes, 68 flames): flames a few
#: lenslets wide want no TV at 14 dB, where the paper's scenes chose TV 0.1: the emission error's 90th percentile
#: 8.8 % (worst 18.1 %) against admm's knobs' 15.9 % (23.7 %); noise-free 6.2 %.
FOUND_PLANES_KNOBS = {(2, "noisy"): {"tv": 0.0, "lam": 0.003}}


@dataclass
class FoundDepths:
    """Depths holding emission in one light field (:func:`find_depths`).

    Attributes
    ----------
    depths_mm, slopes, uncertainty_mm, width_mm, weight : ndarray of shape (K,)
        Each found depth (mm from the focal plane, positive farther), its refocus slope
        (lenslets per view step), its uncertainty (mm), the full width at half maximum of
        its sharpness peak (mm), and its share of its region's focus votes.
    region : ndarray of shape (K,), int
        The label (in ``labels``) of the region it was found in.
    masks : ndarray of shape (K, R, C), bool
        The lenslets that voted for it (its lateral footprint).
    labels : ndarray of shape (R, C), int
        Regions holding emission (0: none).
    planes_mm : ndarray of shape (P,)
        The planes to solve on: found depths merged within ``merge_mm``, ascending.
    plane_of : ndarray of shape (K,), int
        Each found depth's plane.
    curves : list of K ndarray
        Each depth's Tenengrad energy against ``grid_slopes``.
    grid_slopes : ndarray of shape (S,)
    time_s : float
    """

    depths_mm: np.ndarray
    slopes: np.ndarray
    uncertainty_mm: np.ndarray
    width_mm: np.ndarray
    weight: np.ndarray
    region: np.ndarray
    masks: np.ndarray
    labels: np.ndarray
    planes_mm: np.ndarray
    plane_of: np.ndarray
    curves: list = field(repr=False)
    grid_slopes: np.ndarray = field(repr=False)
    time_s: float = float("nan")


def _check_views(views, camera):
    if not isinstance(camera, PlenopticCamera):
        raise ValueError(f"camera must be a PlenopticCamera. Received: {type(camera).__name__}")
    v = np.asarray(views)
    n = camera.pixels_per_lenslet
    want = (n, n, camera.n_rows, camera.n_cols)
    if v.shape != want:
        raise ValueError(f"views must have shape (N, N, R, C) = {want} for this camera. Received: {v.shape}")
    if not np.issubdtype(v.dtype, np.number):
        raise ValueError(f"views must be numeric. Received dtype {v.dtype}")
    v = np.ascontiguousarray(v, np.float32)
    _check_finite("views", v)
    if float(v.max()) <= 0:
        raise ValueError("views hold no light (maximum <= 0): there is nothing to find")
    return v


def _peak_fit(curve, i):
    """Sub-step position (in grid steps) of the maximum near index ``i``: parabola through
    the log of the curve at ``i - 1, i, i + 1`` (a Gaussian peak); ``i`` at the grid's ends."""
    if i <= 0 or i >= len(curve) - 1:
        return float(i)
    y = np.log(np.maximum(curve[i - 1:i + 2], 1e-300))
    den = y[0] - 2 * y[1] + y[2]
    if not den < 0:
        return float(i)
    return float(i + np.clip(0.5 * (y[0] - y[2]) / den, -0.5, 0.5))


def _local_max(curve, i, reach):
    """Index of the curve's largest value within ``reach`` steps of ``i``."""
    a, b = max(0, i - reach), min(len(curve), i + reach + 1)
    return a + int(np.argmax(curve[a:b]))


def _half_width(curve, i):
    """Half width at half maximum (grid steps) of the peak at ``i`` (above the curve's minimum)."""
    base = float(curve.min())
    half = base + 0.5 * (float(curve[i]) - base)
    lo = i
    while lo > 0 and curve[lo] > half:
        lo -= 1
    hi = i
    while hi < len(curve) - 1 and curve[hi] > half:
        hi += 1
    return 0.5 * (hi - lo)


def find_depths(views, camera: PlenopticCamera, *, depth_range_mm=DEPTH_RANGE_MM, slope_step: float | None = None,
                threshold: float = 0.12, sigma: float = 1.5, min_pixels: int = 6, peak_fraction: float = 0.1,
                vote_floor: float = 0.02,
                min_separation_mm: float = 2.5, merge_mm: float = MERGE_MM) -> FoundDepths:
    """The depths that hold emission, per lateral region, several per region where flames stand one behind another.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`lf_flame.refocus.shift_and_sum.raw_to_views`), radiance units.
    camera : PlenopticCamera
        The camera that took them (slope <-> depth).
    depth_range_mm : (float, float)
        Depths searched (mm from the focal plane, positive farther), low < high.
    slope_step : float or None
        Step of the coarse slope grid (lenslets per view step), > 0; None: :data:`SLOPE_STEP`
        scaled to the views' count (``14 / (N - 1)``).
    threshold : float
        Emission is where the smoothed central view exceeds this fraction of its maximum, in (0, 1).
    sigma : float
        Lenslets over which the focus energy is smoothed, > 0.
    min_pixels : int
        Regions (and a region's depths) with fewer voting lenslets are dropped, >= 1.
    peak_fraction : float
        A region's second and later depths need this fraction of its largest vote peak, in (0, 1].
    vote_floor : float
        A lenslet votes if its focus contrast (largest energy over the median) is at least this
        fraction of the region's 99th percentile, in [0, 1).
    min_separation_mm : float
        Depths of one region closer than this are one peak (mm), >= 0.
    merge_mm : float
        Found depths closer than this share one plane (mm), >= 0.

    Returns
    -------
    FoundDepths

    Raises
    ------
    ValueError
        Views of another shape than the camera's, not finite, or without light; a camera
        that is not a :class:`PlenopticCamera`; a depth range the camera cannot image; a
        knob out of its range.
    """
    t0 = time.perf_counter()
    v = _check_views(views, camera)
    if slope_step is None:
        slope_step = SLOPE_STEP * 14.0 / max(v.shape[0] - 1, 1)
    lo, hi = (float(d) for d in depth_range_mm)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError(f"depth_range_mm must be two finite depths, low < high. Received: {depth_range_mm!r}")
    for name, val, ok in (("slope_step", slope_step, slope_step > 0), ("threshold", threshold, 0 < threshold < 1),
                          ("sigma", sigma, sigma > 0), ("min_pixels", min_pixels, min_pixels >= 1),
                          ("peak_fraction", peak_fraction, 0 < peak_fraction <= 1),
                          ("vote_floor", vote_floor, 0 <= vote_floor < 1),
                          ("min_separation_mm", min_separation_mm, min_separation_mm >= 0),
                          ("merge_mm", merge_mm, merge_mm >= 0)):
        if not (math.isfinite(float(val)) and ok):
            raise ValueError(f"{name} is out of range. Received: {val!r}")
    s_lo, s_hi = sorted((camera.slope_for_depth(lo), camera.slope_for_depth(hi)))  # raises where it cannot image
    n = camera.pixels_per_lenslet
    slopes = np.arange(s_lo - slope_step, s_hi + 1.5 * slope_step, slope_step)

    # 1. regions holding emission, from the central (pinhole) view
    centre = ndimage.gaussian_filter(v[n // 2, n // 2].astype(np.float64), 1.0)
    fg = centre > threshold * centre.max()
    fg = ndimage.binary_dilation(fg, iterations=2)
    labels = measure.label(fg, connectivity=2)
    sizes = np.bincount(labels.ravel())
    for lab in np.flatnonzero(sizes < min_pixels):
        labels[labels == lab] = 0

    # 2. focus energy per pixel and slope (band-limited refocusing)
    ten, lap = _focus_energy(v, slopes, sigma, laplacian=True)
    best = np.argmax(ten, axis=0)
    contrast = ten.max(axis=0) - np.median(ten, axis=0)

    # 3. depths per region
    dz_ds = abs(camera.depth_for_slope(slope_step) - camera.depth_for_slope(0.0)) / slope_step   # mm per slope
    sep_bins = max(1, int(round(min_separation_mm / (dz_ds * slope_step))))
    rows = []
    for lab in range(1, labels.max() + 1):
        reg = labels == lab
        if not reg.any():
            continue
        # one vote per lenslet whose focus stands out (contrast above vote_floor of the region's 99th percentile):
        # a dim flame in front of a bright one gets as many votes as lenslets it is sharp in
        sure = reg & (contrast >= vote_floor * np.percentile(contrast[reg], 99))
        hist = np.bincount(best[sure], minlength=len(slopes)).astype(np.float64)
        hist = ndimage.gaussian_filter1d(hist, 1.0, mode="constant")
        peaks, _ = signal.find_peaks(np.concatenate([[0.0], hist, [0.0]]), distance=sep_bins,
                                     height=peak_fraction * hist.max())
        peaks = peaks - 1
        total = hist.sum()
        if not len(peaks):
            continue
        owner = np.abs(peaks[:, None] - np.arange(len(slopes))[None, :]).argmin(axis=0)   # nearest peak per bin
        for q, p in enumerate(peaks):
            voters = sure & (owner[best] == q) & (np.abs(best - p) <= sep_bins)
            if voters.sum() < min_pixels:
                continue
            c_ten = ten[:, voters].sum(axis=1)
            c_lap = lap[:, voters].sum(axis=1)
            i = _local_max(c_ten, p, 2)
            s_ten = np.interp(_peak_fit(c_ten, i), np.arange(len(slopes)), slopes)
            j = _local_max(c_lap, p, 2)
            s_lap = np.interp(_peak_fit(c_lap, j), np.arange(len(slopes)), slopes)
            d_ten, d_lap = camera.depth_for_slope(s_ten), camera.depth_for_slope(s_lap)
            width = 2 * _half_width(c_ten, i) * slope_step * dz_ds
            rows.append(dict(depth=d_ten, slope=s_ten, unc=max(0.5 * abs(d_ten - d_lap), 0.1 * 0.5 * width),
                             width=width, weight=float(hist[p] / total), region=lab, mask=voters, curve=c_ten))
    rows.sort(key=lambda r: r["depth"])
    depths = np.array([r["depth"] for r in rows])
    planes, plane_of = merge_depths(depths, np.array([r["weight"] for r in rows]), merge_mm)
    R, C = labels.shape
    return FoundDepths(depths_mm=depths, slopes=np.array([r["slope"] for r in rows]),
                       uncertainty_mm=np.array([r["unc"] for r in rows]), width_mm=np.array([r["width"] for r in rows]),
                       weight=np.array([r["weight"] for r in rows]), region=np.array([r["region"] for r in rows], int),
                       masks=np.array([r["mask"] for r in rows], bool).reshape(len(rows), R, C), labels=labels,
                       planes_mm=planes, plane_of=plane_of, curves=[r["curve"] for r in rows], grid_slopes=slopes,
                       time_s=time.perf_counter() - t0)


def _focus_energy(views, slopes, sigma, laplacian=False):
    """The views refocused band-limited at ``slopes`` (:class:`FourierSlice`, circular aperture); per slope and
    lenslet the Tenengrad energy (squared Sobel gradient), and with ``laplacian`` the squared Laplacian, each
    smoothed over ``sigma`` lenslets: (S, R, C) float64 arrays."""
    mask = aperture_mask(views.shape[0], "circular")
    stack = FourierSlice(views, float(np.max(np.abs(slopes))) + 1e-9, mask).stack(slopes).astype(np.float64)
    ten = np.array([ndimage.gaussian_filter(ndimage.sobel(im, 0) ** 2 + ndimage.sobel(im, 1) ** 2, sigma)
                    for im in stack])
    if not laplacian:
        return ten
    return ten, np.array([ndimage.gaussian_filter(ndimage.laplace(im) ** 2, sigma) for im in stack])


def merge_depths(depths_mm, weights, merge_mm: float = MERGE_MM):
    """Planes from found depths: runs of ascending depths each within ``merge_mm`` of the
    previous one become one plane at their weighted mean depth.

    Parameters
    ----------
    depths_mm, weights : ndarray of shape (K,)
        Depths (mm, ascending) and positive weights.
    merge_mm : float

    Returns
    -------
    planes_mm : ndarray of shape (P,), ascending
    plane_of : ndarray of shape (K,), int

    Raises
    ------
    ValueError
        Depths not ascending or not finite, weights of another length.
    """
    d, w = np.asarray(depths_mm, np.float64), np.asarray(weights, np.float64)
    if d.shape != w.shape or d.ndim != 1 or not np.all(np.isfinite(d)) or np.any(np.diff(d) < 0):
        raise ValueError(f"depths must be finite, ascending and as many as the weights. Received: {d}, {w}")
    plane_of = np.zeros(len(d), int)
    for k in range(1, len(d)):
        plane_of[k] = plane_of[k - 1] + (d[k] - d[k - 1] > merge_mm)
    planes = np.array([np.average(d[plane_of == p], weights=np.maximum(w[plane_of == p], 1e-12))
                       for p in range(plane_of.max() + 1 if len(d) else 0)])
    return planes, plane_of


def plane_support(found: FoundDepths, dilation: int = SUPPORT_DILATION) -> np.ndarray:
    """Where each plane may hold emission: the regions its found depths were found in, dilated.

    Parameters
    ----------
    found : FoundDepths
    dilation : int
        Lenslets the regions are grown by (>= 0).

    Returns
    -------
    ndarray of bool, shape (P, R, C)
    """
    if int(dilation) != dilation or dilation < 0:
        raise ValueError(f"dilation must be an integer >= 0. Received: {dilation!r}")
    out = np.zeros((len(found.planes_mm),) + found.labels.shape, bool)
    for p, lab in zip(found.plane_of, found.region):
        out[p] |= found.labels == lab
    if dilation:
        out = np.array([ndimage.binary_dilation(m, iterations=int(dilation)) for m in out]).reshape(out.shape)
    return out


def near_plane_support(found: FoundDepths, camera: PlenopticCamera, parallax: float = NEAR_PARALLAX,
                       dilation: int = SUPPORT_DILATION) -> np.ndarray | None:
    """Where each plane may hold emission where found planes lie within ``parallax`` lenslets of
    each other: a plane is kept out of the regions of its near planes, unless it was found there too.

    Two planes whose refocus slopes differ by ``ds`` lenslets per view step move a point's image
    by ``|ds| (N - 1)`` lenslets between the outermost views (its parallax across the aperture,
    ``N`` views per axis): below about a lenslet the data barely tell them apart and a flame's
    light splits between them. Each lateral region then holds only the planes it was found on.
    Planes farther apart stay free everywhere (their data separate them): on a camera of many
    views this is no constraint at all.

    Parameters
    ----------
    found : FoundDepths
    camera : PlenopticCamera
        The camera of the views the depths were found in (slope <-> depth, views per axis).
    parallax : float
        Lenslets of parallax across the aperture below which two planes are near, >= 0.
    dilation : int
        Lenslets the regions are grown by (:func:`plane_support`).

    Returns
    -------
    ndarray of bool, shape (P, R, C), or None
        None where no two planes are near (nothing to hold).

    Raises
    ------
    ValueError
        ``parallax`` negative or not finite; ``dilation`` as :func:`plane_support`.
    """
    if not (math.isfinite(float(parallax)) and parallax >= 0):
        raise ValueError(f"parallax must be finite and >= 0 (lenslets). Received: {parallax!r}")
    own = plane_support(found, dilation)
    slopes = np.array([camera.slope_for_depth(float(d)) for d in found.planes_mm])
    near = np.abs(slopes[:, None] - slopes[None, :]) * (camera.pixels_per_lenslet - 1) < parallax
    np.fill_diagonal(near, False)
    if not near.any():
        return None
    out = np.ones_like(own)
    for p in range(len(own)):
        for q in np.flatnonzero(near[p]):
            out[p] &= ~own[q]
        out[p] |= own[p]
    return out


def missed_depths(residual, camera: PlenopticCamera, found: FoundDepths, *, contrast: float = RESIDUAL_CONTRAST,
                  share: float = RESIDUAL_SHARE, sigma: float = 1.5, min_separation_mm: float = 2.5,
                  merge_mm: float = MERGE_MM):
    """Depths the votes missed, found in a solve's residual: a flame behind (or before) another in the same
    columns, whose lenslets voted for the other.

    The residual views (data minus the found planes' prediction) are refocused band-limited at
    ``found.grid_slopes`` (:class:`~lf_flame.refocus.shift_and_sum.FourierSlice`); per region of
    ``found`` the Tenengrad energy summed over the region, at the slopes farther than
    ``min_separation_mm`` from the depths found there. Noise refocuses to a flat curve and a
    flame's missing light to a peak at its depth: where the peak stands ``contrast`` times
    above the curve's median and holds ``share`` of the data's peak energy at the region's
    found depths (``found.curves``; the solve's misfit about a found flame is fainter), its depth
    (refined as :func:`find_depths` refines) joins the region's, its footprint the region.

    Parameters
    ----------
    residual : ndarray of shape (N, N, R, C)
        Data minus prediction, 0 where not fitted.
    camera : PlenopticCamera
    found : FoundDepths
        The depths the solve was on.
    contrast : float
        Peak over median of the residual's focus curve, > 1 (:data:`RESIDUAL_CONTRAST`).
    share : float
        Peak over the data's, >= 0 (:data:`RESIDUAL_SHARE`).
    sigma, min_separation_mm, merge_mm : float
        As :func:`find_depths`.

    Returns
    -------
    FoundDepths or None
        ``found`` with the missed depths added (planes merged again), or None where none was missed.

    Raises
    ------
    ValueError
        A residual of another shape than the camera's views, or not finite; ``contrast`` <= 1, ``share`` < 0.
    """
    if not (math.isfinite(float(contrast)) and contrast > 1):
        raise ValueError(f"contrast must be a finite ratio > 1. Received: {contrast!r}")
    if not (math.isfinite(float(share)) and share >= 0):
        raise ValueError(f"share must be a finite ratio >= 0. Received: {share!r}")
    n = camera.pixels_per_lenslet
    r = np.ascontiguousarray(residual, np.float32)
    if r.shape != (n, n, camera.n_rows, camera.n_cols):
        raise ValueError(f"residual must have the camera's views' shape {(n, n, camera.n_rows, camera.n_cols)}. "
                         f"Received: {r.shape}")
    _check_finite("residual", r)
    if not np.any(r) or not len(found.depths_mm):
        return None
    slopes = found.grid_slopes
    ten = _focus_energy(r, slopes, sigma)
    depth_of = np.array([camera.depth_for_slope(float(s)) for s in slopes])
    dz_ds = abs(depth_of[-1] - depth_of[0]) / max(abs(slopes[-1] - slopes[0]), 1e-12)
    rows = []
    for lab in np.unique(found.region):
        reg = found.labels == lab
        curve = ten[:, reg].sum(axis=1)
        have = found.depths_mm[found.region == lab]
        free = np.all(np.abs(depth_of[:, None] - have[None]) > min_separation_mm, axis=1)
        if not free.any():
            continue
        i = int(np.flatnonzero(free)[np.argmax(curve[free])])
        data_peak = max(float(found.curves[k].max()) for k in np.flatnonzero(found.region == lab))
        if not (curve[i] >= contrast * np.median(curve) and curve[i] >= share * data_peak):
            continue
        s = float(np.interp(_peak_fit(curve, i), np.arange(len(slopes)), slopes))
        width = 2 * _half_width(curve, i) * (slopes[1] - slopes[0]) * dz_ds
        rows.append(dict(depth=camera.depth_for_slope(s), slope=s, unc=0.1 * 0.5 * width, width=width,
                         region=int(lab), mask=reg, curve=curve))
    if not rows:
        return None
    d = np.concatenate([found.depths_mm, [q["depth"] for q in rows]])
    order = np.argsort(d, kind="stable")
    cat = lambda old, key: np.concatenate([np.asarray(old), np.array([q[key] for q in rows])])[order]
    weight = np.concatenate([found.weight, np.zeros(len(rows))])[order]      # no votes: found in the residual
    planes, plane_of = merge_depths(d[order], weight, merge_mm)
    curves = list(found.curves) + [q["curve"] for q in rows]
    return FoundDepths(depths_mm=d[order], slopes=cat(found.slopes, "slope"), uncertainty_mm=cat(found.uncertainty_mm, "unc"),
                       width_mm=cat(found.width_mm, "width"), weight=weight, region=cat(found.region, "region"),
                       masks=np.concatenate([found.masks, np.array([q["mask"] for q in rows])])[order],
                       labels=found.labels, planes_mm=planes, plane_of=plane_of,
                       curves=[curves[k] for k in order], grid_slopes=slopes, time_s=found.time_s)


def peel_planes(found: FoundDepths, op, rec, data, fit, camera: PlenopticCamera, solve, rounds: int = PEEL_ROUNDS):
    """Search a solve's residual for depths the votes missed and solve again with them, up to ``rounds`` times
    (:func:`missed_depths`): :func:`find_planes`' and ``lf-flame reconstruct``'s route.

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
        ``solve(found) -> (op, rec)``: the planes of ``found`` solved as ``rec`` was.
    rounds : int
        >= 0.

    Returns
    -------
    found, op, rec
        With the missed depths, or the ones given.
    """
    if int(rounds) != rounds or rounds < 0:
        raise ValueError(f"rounds must be an integer >= 0. Received: {rounds!r}")
    y = np.asarray(data, np.float64)
    for _ in range(int(rounds)):
        residual = np.where(fit, y - (op @ np.ravel(rec.planes)).reshape(y.shape), 0.0)
        more = missed_depths(residual, camera, found)
        if more is None:
            break
        found = more
        op, rec = solve(found)
    return found, op, rec


def found_planes_knobs(views, saturation, subsamples: int):
    """admm's knobs on found planes: :data:`FOUND_PLANES_KNOBS` for the planes' grid and the light field's
    noise level, measured as :func:`~lf_flame.tomo.solvers.reconstruct` measures it (on its fitted pixels).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    saturation : float, ndarray of bool (True: left out) or None
        As :func:`~lf_flame.tomo.solvers.reconstruct`'s.
    subsamples : int
        Samples per lenslet and axis of the planes' grid.

    Returns
    -------
    dict or None
        ``reconstruct``'s keywords; None where admm's own knobs hold.
    """
    from .noise_knobs import noise_regime, relative_noise
    from .solvers import fitted_pixels
    fit = fitted_pixels(views, saturation)
    return FOUND_PLANES_KNOBS.get((int(subsamples), noise_regime(relative_noise(views, fit))))


def found_support(found: FoundDepths, camera: PlenopticCamera, subsamples: int = 1, *, support: bool = False,
                  near_parallax: float = NEAR_PARALLAX, dilation: int = SUPPORT_DILATION) -> np.ndarray | None:
    """admm's support of the found planes on the planes' grid: each plane held to its own regions
    (``support``, :func:`plane_support`), or only where near planes meet (:func:`near_plane_support`).

    Parameters
    ----------
    found : FoundDepths
    camera : PlenopticCamera
        The camera of the views the depths were found in.
    subsamples : int
        Samples per lenslet and axis of the planes' grid (the masks are repeated to it), >= 1.
    support : bool
        Every plane held to its regions; else only near planes, within ``near_parallax`` lenslets
        (0: none).
    near_parallax, dilation : float, int
        As :func:`near_plane_support`.

    Returns
    -------
    ndarray of bool, shape (P, s R, s C), or None (no support)
    """
    if int(subsamples) != subsamples or subsamples < 1:
        raise ValueError(f"subsamples must be an integer >= 1. Received: {subsamples!r}")
    m = plane_support(found, dilation) if support else near_plane_support(found, camera, near_parallax, dilation)
    s = int(subsamples)
    return None if m is None else m.repeat(s, axis=1).repeat(s, axis=2)


def find_planes(views, camera: PlenopticCamera, *, solver: str = "admm", saturation=1.0, support: bool = False,
                near_parallax: float = NEAR_PARALLAX, dilation: int = SUPPORT_DILATION, solve=None,
                subsamples: int | None = None, peel_rounds: int = PEEL_ROUNDS, **find_kw):
    """Found depths (:func:`find_depths`) and the emission on their planes.

    The planes' emission is ``reconstruct(views, emission_operator(camera, planes_mm), solver)``
    (:func:`lf_flame.tomo.solvers.reconstruct`, :func:`lf_flame.tomo.exact.emission_operator`),
    with ``support`` (admm) each plane's emission held to the regions its depths were found
    in (:func:`plane_support`): a flame's light cannot leak onto a plane found for another
    region, the prior of few depths per line of sight; without it, only planes within
    ``near_parallax`` lenslets of parallax of each other are held so where they meet
    (:func:`near_plane_support`; 0: never). ``solve``: more keywords of
    ``reconstruct`` (``iters``, ``lam``, ``tv``); None: admm's knobs by the noise, with
    :data:`FOUND_PLANES_KNOBS` for the grid and noise level where it holds them.
    ``experiments/depth.py --variant support`` measures ``support=True, solve=dict(lam=0.01,
    tv=0.0)`` (TV 0.3 flattens flames a few lenslets wide; chosen on validation renders, seeds
    100-107). ``subsamples``: samples per lenslet and axis of the planes' grid; None: admm's
    (:func:`lf_flame.tomo.noise_knobs.admm_subsamples`), 1 for the other solvers.
    ``peel_rounds``: up to this many times the solve's residual is searched for depths the
    votes missed (:func:`missed_depths`: flames behind others in the same columns) and the
    planes solved again with them (0: never).

    Returns
    -------
    found : FoundDepths
        With the depths found in the residual.
    op : the operator of the planes
    rec : Reconstruction
        Its ``planes`` (P, s R, s C) on ``found.planes_mm``; ``rec.time_s`` the solve's wall time.

    Raises
    ------
    ValueError
        As :func:`find_depths`; no emission found (no plane to solve on).
    """
    from .exact import emission_operator
    from .noise_knobs import admm_subsamples
    from .solvers import fitted_pixels, reconstruct
    found = find_depths(views, camera, **find_kw)
    if not len(found.planes_mm):
        raise ValueError("no emission found in the views: lower threshold or check the light field")
    y = np.asarray(views, np.float64)

    def solved(found):
        sub = subsamples if subsamples is not None else (
            admm_subsamples(len(found.planes_mm)) if solver == "admm" else 1)
        op = emission_operator(camera, [float(d) for d in found.planes_mm], subsamples=sub)
        s = getattr(op, "subsamples", 1)
        sup = found_support(found, camera, s, support=support, near_parallax=near_parallax,
                            dilation=dilation) if solver == "admm" else None
        knobs = found_planes_knobs(views, saturation, s) if solve is None and solver == "admm" else solve
        return op, reconstruct(y, op, solver, saturation=saturation, support=sup, **(knobs or {}))

    op, rec = solved(found)
    return peel_planes(found, op, rec, y, fitted_pixels(y, saturation), camera, solved, peel_rounds)
