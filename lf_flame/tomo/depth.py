"""Find the depths that hold emission in one light field: depth from focus, per region of the field.

Whole flames are not depth-resolved by the data's normal matrices alone (NOTES.md,
"Depth resolution"), so depths come from the views: depth from focus.

1. **Regions.** The central sub-aperture view is a pinhole image, sharp at every depth:
   smoothed (Gaussian, 1 lenslet), thresholded at ``threshold`` of its maximum, dilated and
   labelled (:func:`scipy.ndimage.label`, 8-connected); each connected region holds one or more flames.
   Where that covers more than :data:`BRIGHT_FIELD_SHARE` of the field (objects before a bright
   background, not flames on black), the regions are where the light field holds detail instead:
   the focus contrast of step 2 (each lenslet's largest focus energy over its median),
   smoothed and thresholded alike, so that objects apart are searched apart.
2. **Focus per pixel.** The views refocused band-limited at a coarse slope grid
   (:class:`lf_flame.refocus.shift_and_sum.FourierSlice`, which has no whole-lenslet bias);
   per slope the local Tenengrad energy (squared Sobel gradient, Krotkov 1987) smoothed
   over ``sigma`` lenslets. Each pixel of a region votes for the slope of its largest
   energy, if that energy's contrast over the curve's median is at least ``vote_floor`` of the
   region's (so a dim flame in front of a bright one has as many votes as lenslets it is sharp in).
3. **Depths per region.** Peaks of the region's vote histogram (several where flames stand
   one behind another, :func:`find_peaks`, SciPy's); per peak the energy summed over the
   pixels that voted for it, and the slope of its maximum refined by a parabola through the
   log energy at the three grid slopes about it (a Gaussian peak: exact for one). Slope ->
   depth by :meth:`~lf_flame.optics.camera.PlenopticCamera.depth_for_slope`.
4. **Uncertainty.** The same refinement on the Laplacian energy (variance of Laplacian, Pech-
   Pacheco et al. 2000) gives a second depth; the uncertainty is the larger of half their
   difference and a tenth of the Tenengrad peak's half width at half maximum in depth (the
   resolution of the fit); ``width_mm`` is that full width.
5. **Planes.** Found depths closer than ``merge_mm`` whose refocus slopes lie within
   :data:`MERGE_PARALLAX` lenslets of parallax across the aperture of each other are one plane
   (their vote-weighted mean depth). :func:`lf_flame.tomo.found_planes.find_planes` solves for the emission on those
   planes, and :mod:`lf_flame.tomo.peel` searches the solve's residual for depths the votes missed.

The depth tolerances (``min_separation_mm``, ``merge_mm``) were chosen in millimetres on the paper's camera
(and hold on the camera matrix of ``experiments/cameras.py``, whose deep fields see less parallax per
millimetre). On a camera whose parallax changes faster with depth they default to the depths of the
paper camera's parallax across the aperture (:func:`depth_scale` below 1): on a microscope, micrometres,
so that its depths tens of micrometres apart are not one plane.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from ..optics.camera import PlenopticCamera
from ..optics.depth_range import search_range_mm
from ..refocus.shift_and_sum import LIT_VIEW_SHARE, _check_finite, lit_views
from ..refocus.slope_search import MIN_SEARCH_VIEWS
from .focus import _focus_energy, _grid_depths, _half_width, _local_max, _peak_fit, find_peaks

#: Coarse slope step (lenslets per view step) on 15 views: about 0.33 mm of depth at the paper camera's focal
#: plane; on ``N`` views ``SLOPE_STEP * 14 / (N - 1)``, so that the outermost view moves as far per step.
SLOPE_STEP = 0.04
#: Vote bins per coarse slope step (:func:`_vote_bins`; the votes' histogram is smoothed over one vote bin): on the
#: coarse grid alone flames two steps apart in slope had one peak (docs/decisions.md, "Votes at half a slope step").
VOTE_SUBBINS = 2
#: Views per axis a depth search needs (:data:`lf_flame.refocus.slope_search.MIN_SEARCH_VIEWS`).
MIN_VIEWS = MIN_SEARCH_VIEWS
#: Depths closer than this (mm on the paper's camera: :func:`depth_scale` on another) the data barely tell apart
#: where nothing holds each plane to its own lines of sight (planes a user gives: the command line warns; flames paired
#: with planes): 1.69 lenslets of parallax across the paper camera's aperture at its focal plane.
MERGE_MM = 1.0
#: Found depths whose planes' parallax across the aperture differs by less than this (lenslets: their refocus slopes'
#: difference times ``N - 1``) are solved as one plane (:func:`find_depths`, :func:`merge_depths`' ``along``). They
#: lie in different regions (a region's depths are :data:`MIN_SEPARATION_MM` apart), and planes near in parallax are
#: held to their own regions where they meet (:func:`lf_flame.tomo.found_planes.near_plane_support`), so a plane of
#: its own costs a flame less than sharing one at a compromise depth. Chosen on 34 validation scenes
#: (``random_depth_scene``, the seeds of 3900000-3900199 whose depths merged, 121 flames, 100 rays per pixel; a ``/tmp``
#: probe; docs/decisions.md): against 1 mm, emission error p90 10.4 -> 7.0 % noise-free and 12.5 -> 10.5 % at 14 dB;
#: merging nothing let two far pairs (1.06-1.08 lenslets apart) take false depths from the residual's search at 14 dB.
MERGE_PARALLAX = 1.1
#: Depths of one region closer than this (mm on the paper's camera: :func:`depth_scale` on another) are one peak.
MIN_SEPARATION_MM = 2.5
#: Where the central view's bright regions (dilated) cover more than this share of the field, the light field is
#: taken for objects before a bright background and its regions come from its detail (:func:`find_depths`, step 1).
#: The project's flame scenes cover at most 0.55 (volume flames 10 mm wide; single flames 0.39-0.42, the others
#: 0.10-0.21), objects before a lit wall all of it.
BRIGHT_FIELD_SHARE = 0.75


def depth_scale(camera: PlenopticCamera, n_views: int) -> float:
    """Millimetres on ``camera`` per millimetre on the paper's camera at equal parallax across the aperture.

    A depth difference ``dz`` moves the refocus slope by ``dz / (dz/ds)`` lenslets per view step, and
    the outermost views apart by ``n_views - 1`` times that: the depth tolerances chosen on the paper
    camera (15 views) carry to another camera as the depths of the same parallax, ``dz/ds`` taken at
    each camera's focal plane (one coarse slope step, :data:`SLOPE_STEP` scaled to the views' count).

    Parameters
    ----------
    camera : PlenopticCamera
    n_views : int
        Views per axis of the light field searched (>= 2).

    Returns
    -------
    float
        1.0 on the paper's camera with its 15 views.
    """
    from ..optics.camera import PAPER_CAMERA

    def dz_ds(cam, n):
        return depth_per_slope(cam, SLOPE_STEP * 14.0 / max(n - 1, 1))
    n_paper = PAPER_CAMERA.pixels_per_lenslet
    return dz_ds(camera, n_views) / dz_ds(PAPER_CAMERA, n_paper) * (n_paper - 1) / max(n_views - 1, 1)


def depth_per_slope(camera: PlenopticCamera, step: float) -> float:
    """Millimetres of depth per unit of slope (lenslets per view step) at ``camera``'s focal plane: the depth that
    one slope ``step`` moves the focus, over ``step``.

    The step is taken toward the camera where one step the other way focuses at or beyond infinity (a camera
    focused metres away).

    Parameters
    ----------
    camera : PlenopticCamera
    step : float
        Slope step, lenslets per view step (> 0).

    Returns
    -------
    float
        mm per unit slope (> 0).

    Raises
    ------
    ValueError
        ``step`` not finite and > 0.
    """
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a finite slope > 0 (lenslets per view step). Received: {step!r}")
    try:
        return abs(camera.depth_for_slope(step) - camera.depth_for_slope(0.0)) / step
    except ValueError:
        return abs(camera.depth_for_slope(-step) - camera.depth_for_slope(0.0)) / step


def depth_tolerance_scale(camera: PlenopticCamera, n_views: int) -> float:
    """The factor on :data:`MERGE_MM` and :data:`MIN_SEPARATION_MM` for ``camera``: ``min(1, depth_scale)``.

    The tolerances hold in millimetres on cameras that see less parallax per millimetre than the paper's
    (validated on ``experiments/cameras.py``' matrix, :func:`depth_scale` 6-40 there); where a camera sees
    more (a microscope: :func:`depth_scale` about 0.001-0.01), they become the depths of the paper
    camera's parallax across the aperture (1.69 lenslets for :data:`MERGE_MM`).

    Parameters
    ----------
    camera : PlenopticCamera
    n_views : int
        Views per axis of the light field searched.

    Returns
    -------
    float
        In (0, 1]; 1.0 on the paper's camera.
    """
    return min(1.0, depth_scale(camera, n_views))


def depth_tolerances(camera: PlenopticCamera, n_views: int, min_separation_mm=None, merge_mm=None):
    """``(min_separation_mm, merge_mm)`` as given, or where None :data:`MIN_SEPARATION_MM` and :data:`MERGE_MM`
    times :func:`depth_tolerance_scale` (mm)."""
    if min_separation_mm is None or merge_mm is None:
        scale = depth_tolerance_scale(camera, n_views)
        min_separation_mm = MIN_SEPARATION_MM * scale if min_separation_mm is None else min_separation_mm
        merge_mm = MERGE_MM * scale if merge_mm is None else merge_mm
    return min_separation_mm, merge_mm


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
    possible : list of dict
        Depths the route's last search of the residual saw but did not take
        (:func:`lf_flame.tomo.refine.peel_and_refine`: a peak in the band where noisy light
        fields hold both faint flames and misfits): each ``depth_mm``, ``prominence`` (robust
        standard deviations of the residual's focus curve), ``share`` (of the data's peak
        energy) and ``region``. Empty from :func:`find_depths`.
    depth_range_mm : (float, float)
        The depths searched (mm from the focal plane), low < high.
    views_mask : ndarray of shape (N, N), bool, or None
        The views the search refocused (:func:`find_depths`' ``views_mask``), which a search of the
        residual takes too (:func:`lf_flame.tomo.peel.missed_depths`); None: the inscribed circle's.
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
    possible: list = field(default_factory=list, repr=False)
    depth_range_mm: tuple = (float("nan"), float("nan"))
    views_mask: np.ndarray | None = field(default=None, repr=False)


def searched_depths(camera: PlenopticCamera, found: FoundDepths) -> tuple[float, float]:
    """The depths (near, far; mm from the focal plane) ``found``'s search ran over: its ``depth_range_mm``, else (a
    record without one) the depths of its grid's slopes that the camera images. A depth found there (a peak fitted
    past the range's end, the grid running a step beyond it) is clipped to them."""
    lo, hi = (float(d) for d in found.depth_range_mm)
    if math.isfinite(lo) and math.isfinite(hi):
        return lo, hi
    d = _grid_depths(camera, found.grid_slopes)
    return float(np.nanmin(d)), float(np.nanmax(d))


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


def find_depths(views, camera: PlenopticCamera, *, depth_range_mm=None, slope_step: float | None = None,
                threshold: float = 0.12, sigma: float = 1.5, min_pixels: int = 6, peak_fraction: float = 0.1,
                vote_floor: float = 0.02,
                min_separation_mm: float | None = None, merge_mm: float | None = None,
                views_mask=None) -> FoundDepths:
    """The depths that hold emission, per lateral region, several per region where flames stand one behind another.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`lf_flame.refocus.shift_and_sum.raw_to_views`), radiance units.
    camera : PlenopticCamera
        The camera that took them (slope <-> depth).
    depth_range_mm : (float, float) or None
        Depths searched (mm from the focal plane, positive farther), low < high, clipped to the depths the camera
        can refocus (:func:`lf_flame.optics.depth_range.search_range_mm`); None: all of those
        (:func:`lf_flame.optics.depth_range.imaging_range_mm`, -23.0 .. +26.8 mm on the paper's camera).
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
    min_separation_mm : float or None
        Depths of one region closer than this are one peak (mm), >= 0; None:
        :data:`MIN_SEPARATION_MM` times :func:`depth_tolerance_scale`.
    merge_mm : float or None
        Found depths closer than this share one plane (mm), >= 0; None: those closer than :data:`MERGE_MM` (times
        :func:`depth_tolerance_scale`) whose planes' parallax across the aperture differs by less than
        :data:`MERGE_PARALLAX` lenslets (:func:`plane_runs`).
    views_mask : ndarray of shape (N, N), bool, or None
        The views refocused; None: those whose pixels lie inside the main lens's aperture image
        (:func:`lf_flame.refocus.shift_and_sum.lit_views`; decoded views take theirs with ``interpolated``: a
        partly lit view's parallax is smaller than its place says, and pulls the depths toward the focal plane).

    Returns
    -------
    FoundDepths

    Raises
    ------
    ValueError
        Views of another shape than the camera's, fewer than :data:`MIN_VIEWS` per axis, not finite, or without
        light; a camera that is not a :class:`PlenopticCamera`; a depth range not finite, not low < high, or
        wholly outside the depths the camera can refocus; a knob out of its range.
    """
    t0 = time.perf_counter()
    v = _check_views(views, camera)
    if v.shape[0] < MIN_VIEWS:
        raise ValueError(f"finding depths needs at least {MIN_VIEWS} views per axis; the light field has {v.shape[0]} "
                         f"x {v.shape[1]}, too few for parallax to tell depths apart: give the planes (--depth mm, or "
                         "--slope)")
    if slope_step is None:
        slope_step = SLOPE_STEP * 14.0 / max(v.shape[0] - 1, 1)
    min_separation_mm = depth_tolerances(camera, v.shape[0], min_separation_mm)[0]
    try:
        lo, hi = search_range_mm(camera, depth_range_mm)
    except ValueError as e:
        raise ValueError(f"depth_range_mm: {e}") from None
    for name, val, ok in (("slope_step", slope_step, slope_step > 0), ("threshold", threshold, 0 < threshold < 1),
                          ("sigma", sigma, sigma > 0), ("min_pixels", min_pixels, min_pixels >= 1),
                          ("peak_fraction", peak_fraction, 0 < peak_fraction <= 1),
                          ("vote_floor", vote_floor, 0 <= vote_floor < 1),
                          ("min_separation_mm", min_separation_mm, min_separation_mm >= 0),
                          ("merge_mm", 0.0 if merge_mm is None else merge_mm, merge_mm is None or merge_mm >= 0)):
        if not (math.isfinite(float(val)) and ok):
            raise ValueError(f"{name} is out of range. Received: {val!r}")
    s_lo, s_hi = sorted((camera.slope_for_depth(lo), camera.slope_for_depth(hi)))  # raises where it cannot image
    n = camera.pixels_per_lenslet
    slopes = np.arange(s_lo - slope_step, s_hi + 1.5 * slope_step, slope_step)

    # step 1: regions holding emission, from the central (pinhole) view; on a bright background, from the detail
    centre = ndimage.gaussian_filter(v[n // 2, n // 2].astype(np.float64), 1.0)
    fg = ndimage.binary_dilation(centre > threshold * centre.max(), iterations=2)
    bright = fg.mean() > BRIGHT_FIELD_SHARE
    if bright:      # the background's level taken from every view: the field's border, where refocusing runs out of
        v = v - np.median(v, axis=(2, 3), keepdims=True)         # views, then makes no edge of its own

    # focus energy per pixel and slope (band-limited refocusing; step 2, whose contrast step 1 may need)
    if views_mask is None:
        views_mask = lit_views(camera)
        if not views_mask.any():
            raise ValueError(f"no view of the camera's {v.shape[0]} x {v.shape[1]} lies inside the main lens's "
                             f"aperture image (aperture {camera.aperture_diameter_mm:.3g} mm: its image behind each "
                             f"lenslet covers less than {LIT_VIEW_SHARE:.0%} of even the central view's pixel): check "
                             "the camera's aperture_mm or f-number")
    views_mask = np.asarray(views_mask, bool)
    if views_mask.shape != v.shape[:2] or not views_mask.any():
        raise ValueError(f"views_mask must be a boolean (N, N) = {v.shape[:2]} array with a view. Received: "
                         f"{views_mask.shape}")
    ten, lap = _focus_energy(v, slopes, sigma, laplacian=True, mask=views_mask)
    best = np.argmax(ten, axis=0)
    vote = _vote_bins(ten, best, VOTE_SUBBINS)
    contrast = ten.max(axis=0) - np.median(ten, axis=0)
    if bright:
        detail = ndimage.gaussian_filter(contrast, 1.0)
        fg = ndimage.binary_dilation(detail > threshold * detail.max(), iterations=2)
    labels = ndimage.label(fg, np.ones((3, 3), bool), output=np.intp)[0]     # 8-connected, in raster order
    sizes = np.bincount(labels.ravel())
    for lab in np.flatnonzero(sizes < min_pixels):
        labels[labels == lab] = 0

    # 3. depths per region; a peak fitted past the range's end (the grid runs a step beyond it) at that end
    imaged = (s_lo, s_hi)
    dz_ds = depth_per_slope(camera, slope_step)
    sep_bins = max(1, int(round(min_separation_mm / (dz_ds * slope_step))))
    rows = []
    F = VOTE_SUBBINS
    for lab in range(1, labels.max() + 1):
        reg = labels == lab
        if not reg.any():
            continue
        # one vote per lenslet whose focus stands out (contrast above vote_floor of the region's 99th percentile):
        # a dim flame in front of a bright one gets as many votes as lenslets it is sharp in
        sure = reg & (contrast >= vote_floor * np.percentile(contrast[reg], 99))
        hist = np.bincount(vote[sure], minlength=F * (len(slopes) - 1) + 1).astype(np.float64)
        hist = ndimage.gaussian_filter1d(hist, 1.0, mode="constant")
        peaks = find_peaks(np.concatenate([[0.0], hist, [0.0]]), F * sep_bins, peak_fraction * hist.max())
        peaks = peaks - 1
        total = hist.sum()
        if not len(peaks):
            continue
        owner = np.abs(peaks[:, None] - np.arange(len(hist))[None, :]).argmin(axis=0)   # nearest peak per bin
        for q, pf in enumerate(peaks):
            voters = sure & (owner[vote] == q) & (np.abs(vote - pf) <= F * sep_bins + F // 2)
            if voters.sum() < min_pixels:
                continue
            p = int(round(pf / F))
            c_ten = ten[:, voters].sum(axis=1)
            c_lap = lap[:, voters].sum(axis=1)
            i = _local_max(c_ten, p, 2)
            if i in (0, len(slopes) - 1):       # the focus rises to the grid's end, a step past the range: a flame
                continue                        # beyond the depths searched, not one at their end
            s_ten = np.clip(np.interp(_peak_fit(c_ten, i), np.arange(len(slopes)), slopes), *imaged)
            j = _local_max(c_lap, p, 2)
            s_lap = np.clip(np.interp(_peak_fit(c_lap, j), np.arange(len(slopes)), slopes), *imaged)
            d_ten, d_lap = camera.depth_for_slope(s_ten), camera.depth_for_slope(s_lap)
            width = 2 * _half_width(c_ten, i) * slope_step * dz_ds
            rows.append(dict(depth=d_ten, slope=s_ten, unc=max(0.5 * abs(d_ten - d_lap), 0.1 * 0.5 * width),
                             width=width, weight=float(hist[pf] / total), region=lab, mask=voters, curve=c_ten))
    rows.sort(key=lambda r: r["depth"])
    depths = np.array([r["depth"] for r in rows])
    planes, plane_of = plane_runs(camera, n, depths, np.array([r["weight"] for r in rows]), merge_mm)
    R, C = labels.shape
    return FoundDepths(depths_mm=depths, slopes=np.array([r["slope"] for r in rows]),
                       uncertainty_mm=np.array([r["unc"] for r in rows]), width_mm=np.array([r["width"] for r in rows]),
                       weight=np.array([r["weight"] for r in rows]), region=np.array([r["region"] for r in rows], int),
                       masks=np.array([r["mask"] for r in rows], bool).reshape(len(rows), R, C), labels=labels,
                       planes_mm=planes, plane_of=plane_of, curves=[r["curve"] for r in rows], grid_slopes=slopes,
                       time_s=time.perf_counter() - t0, depth_range_mm=(lo, hi), views_mask=views_mask)


def _vote_bins(ten, best, subbins):
    """Each lenslet's vote: its focus curve's peak (``best``, the grid index of ``ten``'s largest energy) refined
    by a parabola through it and its neighbours, on a grid ``subbins`` times finer than the slopes': (R, C) int,
    0 .. ``subbins (S - 1)``. The coarse grid's bins alone cannot part two flames whose slopes lie within about two
    steps (their votes' histogram, smoothed over a bin, has one peak)."""
    S = ten.shape[0]
    b = np.clip(best, 1, S - 2)[None]
    y0, y1, y2 = (np.take_along_axis(ten, b + k, 0)[0] for k in (-1, 0, 1))
    den = y0 - 2 * y1 + y2
    with np.errstate(divide="ignore", invalid="ignore"):
        delta = np.where(den < 0, 0.5 * (y0 - y2) / den, 0.0)
    delta = np.where((best > 0) & (best < S - 1), np.clip(delta, -0.5, 0.5), 0.0)
    return np.rint((best + delta) * subbins).astype(np.intp)


def plane_runs(camera: PlenopticCamera, n_views: int, depths_mm, weights, merge_mm: float | None = None):
    """Planes from found depths (:func:`merge_depths`): within ``merge_mm`` (mm) of each other or, None, both
    within :data:`MERGE_MM` (times :func:`depth_tolerance_scale`) and within :data:`MERGE_PARALLAX` lenslets of
    parallax across the aperture (refocus slopes' difference times ``n_views - 1``). On the paper's camera the
    parallax binds (1.1 lenslets: 0.65 mm at the focal plane, 0.73 mm 20 mm beyond); on cameras that see less
    parallax per millimetre the millimetres do, as before.

    Parameters
    ----------
    camera : PlenopticCamera
    n_views : int
        Views per axis of the light field searched.
    depths_mm, weights, merge_mm
        As :func:`merge_depths` (``merge_mm`` None: as above).

    Returns
    -------
    planes_mm, plane_of
        As :func:`merge_depths`.
    """
    if merge_mm is not None:
        return merge_depths(depths_mm, weights, merge_mm)
    along = np.array([camera.slope_for_depth(float(d)) for d in np.asarray(depths_mm, np.float64)]) * (n_views - 1)
    if len(along) > 1 and along[-1] < along[0]:       # a slope that falls with depth: the same parallax apart
        along = -along
    return merge_depths(depths_mm, weights, depth_tolerances(camera, n_views)[1], along=along,
                        merge_along=MERGE_PARALLAX)


def merge_depths(depths_mm, weights, merge_mm: float = MERGE_MM, along=None, merge_along: float = 0.0):
    """Planes from found depths: runs of ascending depths each within ``merge_mm`` of the
    previous one (and within ``merge_along`` of it ``along`` a coordinate, where given) become one plane at their
    weighted mean depth.

    Parameters
    ----------
    depths_mm, weights : ndarray of shape (K,)
        Depths (mm, ascending) and positive weights.
    merge_mm : float
    along : ndarray of shape (K,) or None
        Each depth's coordinate, ascending with the depths (their parallax in lenslets: :func:`plane_runs`).
    merge_along : float
        The largest step ``along`` within a run, where ``along`` is given.

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
    u = np.zeros_like(d) if along is None else np.asarray(along, np.float64)
    if u.shape != d.shape or np.any(np.diff(u) < 0):
        raise ValueError(f"along must ascend with the depths, one per depth. Received: {along}")
    plane_of = np.zeros(len(d), int)
    for k in range(1, len(d)):
        plane_of[k] = plane_of[k - 1] + (d[k] - d[k - 1] > merge_mm or u[k] - u[k - 1] > merge_along)
    planes = np.array([np.average(d[plane_of == p], weights=np.maximum(w[plane_of == p], 1e-12))
                       for p in range(plane_of.max() + 1 if len(d) else 0)])
    return planes, plane_of

