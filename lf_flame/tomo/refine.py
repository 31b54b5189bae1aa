"""Found depths refined by the data: Gauss-Newton on the planes' slopes (variable projection).

Depth from focus (:func:`lf_flame.tomo.depth.find_depths`) reads each depth from its voters'
sharpness, and where flames share columns one flame's defocused light moves the other's peak:
found depths of flames one behind another come out tenths of a millimetre (up to a millimetre)
off. The solve's residual pins them more tightly. With the planes ``x`` solved at slopes ``s``,
the residual's gradient in each plane's slope at the solution is ``J_p^T r`` (the envelope
theorem: ``x`` is optimal, so its change does not count; Golub & Pereyra, SIAM J. Numer. Anal.
10 (1973)), with ``r = W (A x - y)`` and ``J_p = d(A_p x_p)/ds_p``: a plane's views move by
``s_p u`` lenslets in view ``u``, so ``J_p = -sum_u u . grad (A_p x_p)_u``, the views' spatial
derivatives (five-point stencil) weighted by their offsets. One Gauss-Newton step in all the
refined planes' slopes, ``(J^T J) ds = -J^T r``, then the planes solved again at the new depths;
kept where the residual falls (:func:`refine_planes`). ``J^T J`` is not the full variable projection's curvature:
where flames stand one behind another, a plane's move is partly absorbed by the other planes' emission (Kaufman's
Jacobian projects ``J`` off the operator's span: BIT 15 (1975)), the cost curves less than ``J^T J`` predicts and a
step goes only part of the way. The change of the gradient over one step measures the curvature it met, and in a
quiet light field the next step is lengthened by the ratio (:func:`secant_scale`, a secant condition along the
step as in quasi-Newton methods: Nocedal & Wright, Numerical Optimization, ch. 6), with no solve more.

Once the flames found one behind another sit at their refined depths their misfit shrinks, and a
fainter flame behind them that the first search of the residual missed stands out of it:
:func:`peel_and_refine`, the route of :func:`lf_flame.tomo.found_planes.find_planes` and
``lf-flame reconstruct``, searches those regions once more (:data:`REFINED_PROMINENCE`,
:data:`REFINED_SHARE`) and refines again with what it finds.

In a quiet light field (:func:`~lf_flame.tomo.noise_knobs.noise_regime`) each step's solve starts from the planes
of the step before (``warm``), a step away in depth, in place of its coarse solve on the lenslet grid. On 32
validation column scenes (``column_scene``, seeds 3950000-3950031, 100 rays per pixel, noise-free; a ``/tmp`` probe,
the route timed warm and cold in turn): route median 3.00 -> 2.89 s and 3.04 -> 2.71 s (two halves of 16 scenes),
depth error p90 0.063 -> 0.064 and 0.035 -> 0.035 mm, emission error p90 4.3 -> 3.8 % and 2.7 -> 2.7 %. A noisy
one's solves start cold: warm at 14 dB (16 of those scenes) the depth error p90 was 0.086 -> 0.179 mm (the
few fills that regularise a noisy solve start from the old depths' fit).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..optics.camera import PlenopticCamera
from .depth import FoundDepths, depth_tolerances, searched_depths
from .peel import PEEL_ROUNDS, missed_depths, peel_planes

#: Gauss-Newton steps of :func:`refine_planes` (each a solve at the new depths). Chosen on 25 validation column
#: scenes (``column_scene``, seeds 3950000-3950015 and 3960000-3960008, 100 rays per pixel; a ``/tmp`` probe), 66
#: flames, noise-free / 14 dB: depth error p90 0.35 / 0.36 mm without, 0.13 / 0.16 with one step, 0.050 / 0.088
#: with two (worst 1.24 / 1.27 -> 0.62 / 0.59 -> 0.27 / 0.59 mm), emission p90 7.6 -> 4.6 -> 3.6 % noise-free
#: (20.7 -> 20.3 -> 20.6 % at 14 dB, where noise dominates); time per light field, median, 2.2 -> 3.7 -> 5.5 s.
REFINE_STEPS = 2
#: The most :func:`secant_scale` lengthens a Gauss-Newton step by, in a quiet light field. Chosen on 107 validation
#: column scenes (``column_scene``, seeds 3950000-3950157: every one whose nearest two flames stand within 5 mm, and
#: every eighth of the others; 100 rays per pixel; a ``/tmp`` probe, plain Gauss-Newton and this in turn): noise-free,
#: depth error p90 0.065 -> 0.034 mm, worst 0.66 -> 0.40 mm, emission p90 4.4 -> 3.9 %, worst 27 -> 24 % (157 flames:
#: 54 depths better by more than 0.01 mm, 4 worse; 22 emissions better by more than 0.5 pt, none worse), the same
#: time (median 1.67 / 1.71 s). At 14 dB, where the solves stop early and their gradients are rough, mixed (depth p90
#: 0.086 -> 0.104 mm, worst 0.79 -> 0.54 mm; emissions 6 better, 9 worse): a noisy light field takes plain steps.
REFINE_SECANT_MAX = 4.0
#: Largest step (lenslets per view step) of one plane's slope in one step.
REFINE_MAX_SLOPE = 0.1
#: Steps smaller than this (lenslets per view step; about 0.01 mm on the paper camera) end the refinement.
REFINE_TOL = 1e-3
#: A refined depth stays within this many times its found uncertainty of where it was found: the depths the
#: validation scenes of :data:`REFINE_STEPS` moved toward their truth went up to 2.2 times theirs, and a plane
#: without a flame of its own (a false depth) would otherwise drift to a neighbour's depth and take its light.
REFINE_REACH = 3.0
#: After the refinement, the regions that hold several depths are searched once more for a flame the residual's
#: first search (:data:`~lf_flame.tomo.peel.RESIDUAL_PROMINENCE`, :data:`~lf_flame.tomo.peel.RESIDUAL_SHARE`)
#: missed: a peak this many robust standard deviations above the residual's focus curve's median, holding this
#: share of the data's peak energy (:func:`~lf_flame.tomo.peel.missed_depths`). Chosen on 54 validation column
#: scenes (``column_scene``, seeds 3950000-3950015, 3960000-3960021, and 16 of seeds 3970000-3971999 where a flame
#: less than a fifth as bright (radiance x height) stands behind a taller, brighter one within 3 mm of focus; 100
#: rays per pixel, noise-free and 14 dB; a ``/tmp`` probe of each region's highest peak after the refinement):
#: the 5 flames still missed stand 18.9-77 deviations high with 0.0071-0.0092 of the data's energy; misfits about
#: found flames holding 0.002 of it or more reach 7.1 deviations, and those standing 12 or more hold at most 0.0002.
#: Only regions whose depths each have a plane of their own are searched so (:func:`peel_and_refine`).
REFINED_PROMINENCE = 12.0
REFINED_SHARE = 0.002
#: In a quiet light field (:func:`~lf_flame.tomo.noise_knobs.noise_regime`) that search asks the peak to stand only
#: this many deviations high, where its height above the curve's median (the noise's floor left out) holds
#: :data:`REFINED_SHARE` of the data's energy. Chosen on 76 validation column scenes (``column_scene``, seeds
#: 3950000-3950023, 3960000-3960021, and 30 of seeds 3980000-3984999 where a flame less than a tenth as bright
#: (radiance x height) shares the band; 100 rays per pixel, noise-free and 14 dB; a ``/tmp`` probe of each region's
#: highest free peak after the route): noise-free, the flame still missed stood 6.8 deviations high, 0.41 % above the
#: median, where no false peak held more than 0.03 % (some stood 21 deviations high); at 14 dB the noise's peaks
#: reach 0.55 % above the median at 4.5 deviations, beside missed flames at 4.0-9.1 deviations and 0.27-0.40 %, so a
#: noisy light field keeps :data:`REFINED_PROMINENCE`.
REFINED_QUIET_PROMINENCE = 5.0
#: In a noisy light field the peaks of that search standing this many deviations high (holding
#: :data:`REFINED_SHARE`) but short of :data:`REFINED_PROMINENCE` are reported, not taken (``FoundDepths.possible``;
#: ``lf-flame reconstruct`` warns): there faint flames and misfits stand alike. On 70 validation column scenes at
#: 14 dB (``column_scene``, seeds 3950000-3950015, 3960000-3960021, and 32 of seeds 3980000-3984999 where a flame less
#: than a tenth as bright shares the band; 100 rays per pixel; a ``/tmp`` probe of each region's highest peak after
#: the route), 4 flames were missed: their peaks stood 9.1, 6.2, 5.1 and 4.0 deviations high; the highest peaks
#: with no flame 8.1, 7.1 and 6.1 (the rest 4.5 or less). From 5 deviations: 3 of the 4 reported, beside 3 false ones
#: in 70 light fields. A solve's residual drop did not tell them apart either (adding the depth lowered the squared
#: residual by 0.4-2.8 % for the flames, -0.1-1.2 % for the others).
POSSIBLE_PROMINENCE = 5.0


def slope_jacobian(op, planes, fit, which=None) -> np.ndarray:
    """Each plane's predicted views' derivative in its slope, ``J_p = d(A_p x_p)/ds_p``, on the fitted samples.

    Parameters
    ----------
    op : ExactOperator or EmissionOperator
        The planes' operator (views (N, N, R, C)).
    planes : ndarray of shape ``op.dims`` (P, rows, cols)
    fit : ndarray of bool of shape (N, N, R, C)
    which : sequence of int or None
        The planes to derive (one apply of ``op`` each); None: all.

    Returns
    -------
    ndarray of shape (len(which), N, N, R, C)
        0 where not fitted. View ``(i, j)`` lies ``(i - (N - 1) / 2, j - (N - 1) / 2)`` view steps from the centre;
        a plane at slope ``s`` moves by ``s`` lenslets per view step along rows and columns.
    """
    from ._refine_kernels import slope_derivative
    x = np.asarray(planes, np.float64)
    n = op.dimsd[0]
    u = np.arange(n) - (n - 1) / 2            # about the aperture's centre (a view there for odd N)
    which = range(len(x)) if which is None else list(which)
    fit = np.broadcast_to(np.asarray(fit, bool), op.dimsd)
    out = np.empty((len(which),) + tuple(op.dimsd))
    for k, p in enumerate(which):
        one = np.zeros_like(x)
        one[p] = x[p]
        slope_derivative(op.matvec(one.ravel()).reshape(op.dimsd), u, fit, out[k])
    return out


def refine_planes(found: FoundDepths, op, rec, data, fit, camera: PlenopticCamera, solve,
                  steps: int = REFINE_STEPS, residual=None, warm: bool = False, secant: bool = False):
    """Refine the planes that hold flames one behind another (depths found in a region that holds
    several) by Gauss-Newton on their slopes against the solve's residual (the module's notes), each
    within :data:`REFINE_REACH` times its found uncertainty of where it was found (a reach past the depths
    the searched depths stops at their end, :func:`~lf_flame.tomo.depth.searched_depths`). A plane that merged
    several found depths (within ``merge_mm``) is a compromise between them and is left where it is; a step never
    takes a plane past another nor within the merge distance of it (:func:`kept_apart`).

    Parameters
    ----------
    found, op, rec, data, fit, camera, solve, residual
        As :func:`~lf_flame.tomo.peel.peel_planes`.
    steps : int
        Gauss-Newton steps, >= 0 (:data:`REFINE_STEPS`).
    warm : bool
        Each step's solve starts from the planes before it (``solve(found, start=rec)``: no coarse solve), not from
        its own coarse start: :func:`peel_and_refine` asks it for a quiet light field (the module's notes). A step
        whose warm solve does not lower the residual is solved cold before the refinement stops: a plane moved
        millimetres kept its old depth's fit through the warm start's few fills.
    secant : bool
        Each step after the first lengthened by :func:`secant_scale` (at most :data:`REFINE_SECANT_MAX` times):
        :func:`peel_and_refine` asks it for a quiet light field, whose solves are converged enough for their
        gradients to measure the curvature.

    Returns
    -------
    found, op, rec
        At the refined depths (each depth of a refined plane moved with it), or the ones given where
        no plane holds flames one behind another, no step lowered the residual, or ``rec`` is a learned
        reconstructor's (not a least-squares solution: the gradient above does not hold).

    Raises
    ------
    ValueError
        ``steps`` not an integer >= 0.
    """
    if int(steps) != steps or steps < 0:
        raise ValueError(f"steps must be an integer >= 0. Received: {steps!r}")
    per_region, per_plane = np.bincount(found.region), np.bincount(found.plane_of)
    todo = sorted({int(p) for p, r in zip(found.plane_of, found.region) if per_region[r] > 1 and per_plane[p] == 1})
    if not todo or rec.solver == "learned":
        return found, op, rec
    from .solvers import Residuals
    fit = np.asarray(fit, bool)
    residual = Residuals(data, fit) if residual is None else residual
    k_of = {int(p): k for k, p in enumerate(found.plane_of)}          # each refined plane holds one depth
    near, far = searched_depths(camera, found)
    gap = depth_tolerances(camera, camera.pixels_per_lenslet)[1]      # planes the data barely tell apart
    reach = {p: REFINE_REACH * found.uncertainty_mm[k_of[p]] for p in todo}
    lo = {p: max(found.depths_mm[k_of[p]] - reach[p], near) for p in todo}        # near and far: imaged depths
    hi = {p: min(found.depths_mm[k_of[p]] + reach[p], far) for p in todo}

    r = residual(op, rec)                                             # data minus prediction
    cost = float(np.vdot(r, r))
    last = None                                                       # the step before: (ds, J r, J J^T)
    for _ in range(int(steps)):
        J = slope_jacobian(op, rec.planes, fit, todo).reshape(len(todo), -1)
        b, JJ = J @ r.ravel(), J @ J.T
        ds = np.linalg.lstsq(JJ, b, rcond=None)[0]                    # (J^T J) ds = J^T (data minus prediction)
        if secant and last is not None:
            ds = ds * secant_scale(*last, b)
        ds = np.clip(ds, -REFINE_MAX_SLOPE, REFINE_MAX_SLOPE)
        planes = np.asarray(found.planes_mm, np.float64).copy()
        for p, d in zip(todo, ds):
            s_new = camera.slope_for_depth(planes[p]) + d             # slope rises with depth: clipped as the depth
            if s_new >= camera.slope_for_depth(hi[p]):                # (past the far end it may focus beyond infinity)
                planes[p] = hi[p]
            elif s_new <= camera.slope_for_depth(lo[p]):
                planes[p] = lo[p]
            else:
                planes[p] = np.clip(camera.depth_for_slope(s_new), lo[p], hi[p])
        planes = kept_apart(planes, found.planes_mm, todo, gap)
        moved = np.array([camera.slope_for_depth(planes[p]) - camera.slope_for_depth(found.planes_mm[p]) for p in todo])
        if np.abs(moved).max() < REFINE_TOL:
            break
        shift = (planes - found.planes_mm)[found.plane_of]
        trial = dataclasses.replace(found, planes_mm=planes, depths_mm=found.depths_mm + shift,
                                    slopes=np.array([camera.slope_for_depth(d) for d in found.depths_mm + shift]))
        op2, rec2 = solve(trial, start=rec) if warm else solve(trial)
        r2 = residual(op2, rec2)
        c2 = float(np.vdot(r2, r2))
        if warm and not c2 < cost:      # a warm start's few fills can keep a plane moved far at its old fit: cold
            op2, rec2 = solve(trial)
            r2 = residual(op2, rec2)
            c2 = float(np.vdot(r2, r2))
        if not c2 < cost:
            break
        last = (moved, b, JJ)
        found, op, rec, r, cost = trial, op2, rec2, r2, c2
    return found, op, rec


def secant_scale(ds, b_before, JJ, b_after) -> float:
    """How much longer the next Gauss-Newton step is taken than ``J^T J`` asks: ``1 / rho``, ``rho`` the curvature the
    last step ``ds`` met (the change of the gradient ``-J^T r`` along it) over the curvature ``J^T J`` predicted,
    clipped to [1, :data:`REFINE_SECANT_MAX`]. ``J^T J`` leaves out that the planes' emission follows their depths
    (the variable projection's full Jacobian projects ``J`` off the span of the operator, Kaufman, BIT 15 (1975)):
    where flames stand one behind another a plane's move is partly absorbed by the other's emission, the cost
    curves less than ``J^T J`` says, and each step goes only ``rho`` of the way.

    Parameters
    ----------
    ds : ndarray of shape (Q,)
        The last step's slopes' changes (lenslets per view step).
    b_before, b_after : ndarray of shape (Q,)
        ``J^T r`` before and after it.
    JJ : ndarray of shape (Q, Q)
        ``J^T J`` before it.

    Returns
    -------
    float
        >= 1; 1 where the step met as much curvature as predicted or more, or none at all (not convex along it).
    """
    predicted = float(ds @ JJ @ ds)
    met = float(ds @ (b_before - b_after))          # the gradient of cost / 2 is -J^T r
    if not (predicted > 0 and met > 0):
        return 1.0
    return float(np.clip(predicted / met, 1.0, REFINE_SECANT_MAX))


def kept_apart(planes, before, moved, gap_mm: float) -> np.ndarray:
    """The planes of one refinement step (mm, the order of ``before``) with each moved plane that would pass
    another or come within ``gap_mm`` of it (the distance within which the data barely tell planes apart,
    :func:`~lf_flame.tomo.depth.depth_tolerances`) left where it was (``before``, ascending; found depths of
    different regions may lie nearer than ``gap_mm``, :func:`~lf_flame.tomo.depth.plane_runs`). On a camera of
    little parallax per millimetre, a plane's reach spans several millimetres and Gauss-Newton moved planes one
    behind another past each other or onto one depth, which the data cannot tell apart.

    Parameters
    ----------
    planes, before : ndarray of shape (P,)
        Depths (mm) after and before the step.
    moved : sequence of int
        The planes the step may move (the others are ``before``'s).
    gap_mm : float
        >= 0.

    Returns
    -------
    ndarray of shape (P,)
    """
    planes, before = np.array(planes, np.float64), np.asarray(before, np.float64)
    moved = set(int(p) for p in moved)
    for _ in range(len(planes)):
        close = np.flatnonzero(np.diff(planes) <= gap_mm)
        back = [p for k in close for p in (k, k + 1) if p in moved and planes[p] != before[p]]
        if not back:
            break
        planes[back] = before[back]
    return planes


def refined_regions(found: FoundDepths) -> list:
    """The regions (``found.region`` labels) that hold several depths, each on a plane of its own: those whose
    planes :func:`refine_planes` moves. A plane that merged depths keeps its misfit (it is not refined), which
    the finer search of :func:`peel_and_refine` would take for a flame."""
    merged = np.bincount(found.plane_of)[found.plane_of] > 1
    return [int(r) for r in np.unique(found.region)
            if np.sum(found.region == r) > 1 and not merged[found.region == r].any()]


def peel_and_refine(found: FoundDepths, op, rec, data, fit, camera: PlenopticCamera, solve,
                    rounds: int = PEEL_ROUNDS, steps: int = REFINE_STEPS, smooth: float = 0.0):
    """The found planes' route after their first solve: the residual searched for depths the votes missed
    (:func:`~lf_flame.tomo.peel.peel_planes`, up to ``rounds`` times), the planes of flames one behind another
    refined (:func:`refine_planes`, ``steps``), and then, once, the regions that hold several depths, each on a
    plane of its own (the planes the refinement moves), searched again (:data:`REFINED_PROMINENCE`,
    :data:`REFINED_SHARE`; in a quiet light field :data:`REFINED_QUIET_PROMINENCE`, the peak's height above the
    residual's floor holding :data:`REFINED_SHARE`) and, where a depth is found, solved and refined again. In a
    noisy light field the peaks of that search short of its prominence from :data:`POSSIBLE_PROMINENCE` are reported
    in ``found.possible``.

    Parameters
    ----------
    found, op, rec, data, fit, camera, solve
        As :func:`~lf_flame.tomo.peel.peel_planes`.
    rounds : int
        >= 0; 0: no search of the residual (nor after the refinement).
    steps : int
        >= 0; 0: no refinement (nor the search after it).
    smooth : float
        The residual's smoothing before each search (lenslets, :func:`~lf_flame.tomo.peel.missed_depths`).

    Returns
    -------
    found, op, rec

    Raises
    ------
    ValueError
        ``rounds`` or ``steps`` not an integer >= 0.
    """
    from .noise_knobs import noise_regime, relative_noise
    from .solvers import Residuals
    residual = Residuals(data, fit)
    quiet = noise_regime(relative_noise(data, fit)) == "quiet"
    found, op, rec = peel_planes(found, op, rec, data, fit, camera, solve, rounds, residual, smooth)
    found, op, rec = refine_planes(found, op, rec, data, fit, camera, solve, steps, residual, warm=quiet, secant=quiet)
    several = refined_regions(found)
    if not (rounds and steps and len(several)) or rec.solver == "learned":
        return without_empty_planes(found, op, rec, solve)
    possible = None if quiet else []
    more = missed_depths(residual(op, rec), camera, found, regions=several, share=REFINED_SHARE,
                         prominence=REFINED_QUIET_PROMINENCE if quiet else REFINED_PROMINENCE,
                         excess=REFINED_SHARE if quiet else 0.0, possible=possible,
                         possible_prominence=POSSIBLE_PROMINENCE, smooth=smooth)
    if more is not None:
        op, rec = solve(more)
        found, op, rec = refine_planes(more, op, rec, data, fit, camera, solve, steps, residual, warm=quiet,
                                       secant=quiet)
    return without_empty_planes(dataclasses.replace(found, possible=possible) if possible else found, op, rec, solve)


def without_empty_planes(found: FoundDepths, op, rec, solve):
    """The found planes less those that solve to no emission at all (every sample 0), with their depths, the rest
    solved again (``solve(found, start=rec)``, started from their planes); as they are where no plane is empty, or
    every one is. A depth voted for where the planes explain nothing (a capture decoded with one view more than
    its lenslet images hold whole, 9.999 px apart: -60 mm, at the search's near end, solved to zero) is no flame.

    Parameters
    ----------
    found, op, rec, solve
        As :func:`peel_and_refine`'s.

    Returns
    -------
    found, op, rec
    """
    empty = [k for k in range(len(found.planes_mm)) if not np.any(rec.planes[k] > 0)]
    if not empty or len(empty) == len(found.planes_mm):
        return found, op, rec
    planes = np.setdiff1d(np.arange(len(found.planes_mm)), empty)
    keep = np.isin(found.plane_of, planes)
    new_index = np.full(len(found.planes_mm), -1)
    new_index[planes] = np.arange(len(planes))
    kept = dataclasses.replace(found, depths_mm=found.depths_mm[keep], slopes=found.slopes[keep],
                               uncertainty_mm=found.uncertainty_mm[keep], width_mm=found.width_mm[keep],
                               weight=found.weight[keep], region=found.region[keep], masks=found.masks[keep],
                               curves=[c for c, k in zip(found.curves, keep) if k], planes_mm=found.planes_mm[planes],
                               plane_of=new_index[found.plane_of[keep]])
    op, rec = solve(kept, start=dataclasses.replace(rec, planes=rec.planes[planes]))
    return kept, op, rec
