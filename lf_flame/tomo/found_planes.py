"""The emission on found planes: each plane's support, the found planes' admm knobs, and the route
:func:`find_planes` (depths found, :mod:`lf_flame.tomo.depth`; solved; the residual searched for
depths the votes missed, :mod:`lf_flame.tomo.peel`; solved again; the depths of flames one behind another
refined by the residual, :mod:`lf_flame.tomo.refine`).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy import ndimage

from ..optics.camera import PlenopticCamera
from .depth import FoundDepths, find_depths
from .peel import PEEL_ROUNDS
from .refine import REFINE_STEPS, peel_and_refine

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
    near = near_pairs(camera, found.planes_mm, parallax)
    own = plane_support(found, dilation)
    if not near.any():
        return None
    out = np.ones_like(own)
    for p in range(len(own)):
        for q in np.flatnonzero(near[p]):
            out[p] &= ~own[q]
        out[p] |= own[p]
    return out


def near_pairs(camera: PlenopticCamera, depths_mm, parallax: float = NEAR_PARALLAX) -> np.ndarray:
    """Which planes lie within ``parallax`` lenslets of parallax across the aperture of each other
    (:func:`near_plane_support`): ``|ds| (N - 1) < parallax``, ``ds`` their slopes' difference (lenslets per view
    step), ``N`` the views per axis.

    Parameters
    ----------
    camera : PlenopticCamera
    depths_mm : sequence of P float
        The planes (mm from the focus distance).
    parallax : float
        Lenslets, >= 0.

    Returns
    -------
    ndarray of bool, shape (P, P), False on the diagonal

    Raises
    ------
    ValueError
        ``parallax`` negative or not finite.
    """
    near = _parallax(camera, depths_mm, depths_mm, parallax) < parallax
    np.fill_diagonal(near, False)
    return near


def _parallax(camera: PlenopticCamera, a_mm, b_mm, parallax: float) -> np.ndarray:
    """``|ds| (N - 1)`` (lenslets) between each depth of ``a_mm`` and each of ``b_mm`` (mm), ``(len(a), len(b))``,
    after checking the bar ``parallax`` (:func:`near_pairs`)."""
    if not (math.isfinite(float(parallax)) and parallax >= 0):
        raise ValueError(f"parallax must be finite and >= 0 (lenslets). Received: {parallax!r}")
    a, b = ([camera.slope_for_depth(float(d)) for d in x] for x in (a_mm, b_mm))
    return np.abs(np.subtract.outer(np.asarray(a, float), np.asarray(b, float))) * (camera.pixels_per_lenslet - 1)


def planes_without_flames(found: FoundDepths, camera: PlenopticCamera, depths_mm,
                          parallax: float = NEAR_PARALLAX) -> np.ndarray:
    """Which planes given by the user lie farther than ``parallax`` lenslets of parallax across the aperture (as
    :func:`near_pairs` measures it) from every depth the depth search found: no flame stands near them, and what
    their solve puts on them is other flames' light.

    Parameters
    ----------
    found : FoundDepths
        :func:`~lf_flame.tomo.depth.find_depths` of the light field the planes are solved on.
    camera : PlenopticCamera
    depths_mm : sequence of P float
        The given planes (mm from the focus distance).
    parallax : float
        Lenslets, >= 0.

    Returns
    -------
    ndarray of bool, shape (P,)

    Raises
    ------
    ValueError
        ``parallax`` negative or not finite.
    """
    return (_parallax(camera, depths_mm, found.depths_mm, parallax) >= parallax).all(axis=1)


def on_given_planes(found: FoundDepths, depths_mm) -> FoundDepths:
    """The depths found in a light field put on planes given by the user: each on the nearest given plane
    (``planes_mm`` the given depths, ``plane_of`` the nearest's index), so that :func:`found_support` holds given
    planes near each other to the regions where the data put their flames, as it holds found planes. A given plane
    that no found depth is nearest to holds no region of its own: kept out of its near planes' regions.

    Parameters
    ----------
    found : FoundDepths
        :func:`~lf_flame.tomo.depth.find_depths` of the same light field.
    depths_mm : sequence of P float
        The given planes (mm from the focus distance).

    Returns
    -------
    FoundDepths

    Raises
    ------
    ValueError
        No given plane.
    """
    given = np.asarray(depths_mm, np.float64).ravel()
    if not given.size:
        raise ValueError("no given plane to put the found depths on")
    plane_of = np.abs(np.asarray(found.depths_mm, np.float64)[:, None] - given[None, :]).argmin(axis=1)
    return dataclasses.replace(found, planes_mm=given, plane_of=plane_of)


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


def find_planes(views, camera: PlenopticCamera, *, solver: str = "admm", saturation=1.0, support: bool = False,
                near_parallax: float = NEAR_PARALLAX, dilation: int = SUPPORT_DILATION, solve=None,
                subsamples: int | None = None, peel_rounds: int = PEEL_ROUNDS, refine_steps: int = REFINE_STEPS,
                unit: float | None = None, **find_kw):
    """Found depths (:func:`~lf_flame.tomo.depth.find_depths`) and the emission on their planes.

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
    votes missed (:func:`~lf_flame.tomo.peel.missed_depths`: flames behind others in the same columns) and the
    planes solved again with them (0: never). ``refine_steps``: Gauss-Newton steps on the slopes of the planes
    that hold flames one behind another, each solved again (:func:`~lf_flame.tomo.refine.refine_planes`; 0: none),
    after which their regions are searched once more (:func:`~lf_flame.tomo.refine.peel_and_refine`).
    ``unit``: the views' unit where ``saturation`` is a mask (:func:`~lf_flame.tomo.solvers.reconstruct`'s).

    Returns
    -------
    found : FoundDepths
        With the depths found in the residual.
    op : the operator of the planes
    rec : Reconstruction
        Its ``planes`` (P, s R, s C) on ``found.planes_mm`` (``s`` the operator's ``subsamples``:
        :func:`lf_flame.tomo.truth.bin_planes` gives the lenslet grid's (P, R, C) that
        :func:`lf_flame.measure.diagnostics.measure_flame` measures); ``rec.time_s`` the solve's wall time.

    Raises
    ------
    ValueError
        As :func:`~lf_flame.tomo.depth.find_depths`; no emission found (no plane to solve on).
    """
    from .exact import emission_operator
    from .noise_knobs import admm_subsamples
    from .solvers import fitted_pixels, reconstruct
    found = find_depths(views, camera, **find_kw)
    if not len(found.planes_mm):
        raise ValueError("no emission found in the views: lower threshold or check the light field")
    y = np.asarray(views, np.float64)

    def solved(found, start=None):
        sub = subsamples if subsamples is not None else (
            admm_subsamples(len(found.planes_mm)) if solver == "admm" else 1)
        op = emission_operator(camera, [float(d) for d in found.planes_mm], subsamples=sub)
        s = getattr(op, "subsamples", 1)
        sup = found_support(found, camera, s, support=support, near_parallax=near_parallax,
                            dilation=dilation) if solver == "admm" else None
        knobs = dict((found_planes_knobs(views, saturation, s) if solve is None and solver == "admm" else solve) or {})
        if start is not None and solver == "admm" and start.planes.shape == tuple(op.dims):
            knobs["start_planes"] = start.planes
        return op, reconstruct(y, op, solver, saturation=saturation, support=sup, unit=unit, **knobs)

    op, rec = solved(found)
    fit = fitted_pixels(y, saturation)
    return peel_and_refine(found, op, rec, y, fit, camera, solved, peel_rounds, refine_steps)
