"""The planes of a command's light field: its input and the planes asked for (``--depth``, ``--slope``,
``--depths``), the depths found in it (:mod:`lf_flame.tomo.depth`, printed and recorded), and each plane's emission
solved on the light field's camera (:mod:`lf_flame.tomo`), with the residual's search and the refinement of found
depths; what ``reconstruct``, ``profiles``, ``sequence`` and ``temperature`` share.
"""
from __future__ import annotations

import dataclasses
import sys

import numpy as np

from ._io import _raw_objects, _recording_flames, light_field, planes_count


def reconstruct_input(a, colour: bool = False):
    """Light field, depths (mm, or "auto") and flame objects (or None) of ``reconstruct``/``temperature``
    (``colour``: a colour capture's channels kept, :func:`._io.light_field`)."""
    lf = light_field(a, colour=colour)
    stored = _raw_objects(a.raw)          # what 'lf-flame simulate' stored beside a raw image, decoded here or not
    flames = stored if stored is not None else _recording_flames(a.raw)      # or a simulated recording's frame
    return lf, planes_from_args(a, lf.camera, flames), None if lf.decoded else stored


def planes_from_args(a, cam, objects=None):
    """The planes a command's ``--depth``, ``--slope`` or ``--depths`` name on ``cam`` (mm from the focal plane), or
    "auto"; ``objects``: those ``lf-flame simulate`` stored beside the input (``--depths scene``), or None."""
    from ..simulate.scenes import PAPER_DEPTHS_MM
    given = [k for k in ("depth", "slope", "depths") if getattr(a, k, None)]
    if len(given) > 1:
        raise ValueError("give the planes one way: --depth, --slope or --depths, not " + " and ".join(
            f"--{k}" for k in given))
    spec = str(getattr(a, "depths", None) or "").strip().lower()
    if getattr(a, "depth", None):
        depths = list(a.depth)
    elif getattr(a, "slope", None):
        depths = [cam.depth_for_slope(s) for s in a.slope]
    elif spec == "scene":
        if not (objects and all("depth_offset_mm" in o for o in objects)):
            raise ValueError(f"--depths scene: {a.raw} stores no objects with depths (only what 'lf-flame simulate' "
                             "writes, .npz or .png, and a frame of a 'simulate-sequence' recording do)")
        depths = list(dict.fromkeys(float(o["depth_offset_mm"]) for o in objects))   # flames on one plane: once
    elif spec == "paper":
        depths = list(PAPER_DEPTHS_MM)
    elif spec in ("", "auto"):
        depths = "auto"
    else:
        try:
            depths = [float(v) for v in spec.split(",")]
        except ValueError:
            raise ValueError(f"--depths takes auto, scene, paper or depths in mm separated by commas. Received: "
                             f"{a.depths!r}") from None
    if depths != "auto":
        check_planes(cam, depths)
    return depths


def check_planes(cam, depths) -> None:
    """Planes given to a command: refused outside what ``cam`` refocuses or given twice
    (:func:`lf_flame.optics.depth_range.check_imaging_range`); a warning printed where two lie closer than
    :func:`lf_flame.tomo.depth.depth_tolerances`' merge depth (1.7 lenslets of parallax across the aperture, 1 mm on
    the paper's camera), whose emission the data barely share out where nothing holds each plane to its own lines of
    sight (found depths are held so, :func:`lf_flame.tomo.found_planes.near_plane_support`)."""
    from ..optics.depth_range import check_imaging_range
    from ..tomo.depth import depth_tolerances
    check_imaging_range(cam, depths)
    merge = depth_tolerances(cam, cam.pixels_per_lenslet)[1]
    d = sorted(float(v) for v in depths)
    close = [(x, y) for x, y in zip(d, d[1:]) if y - x < merge]
    if close:
        pairs = ", ".join(f"{x:+.4g} and {y:+.4g}" for x, y in close)
        metres = len(d) > 1 and max(abs(v) for v in d) < 1.0 <= merge
        print(f"warning: planes at {pairs} mm lie closer than {merge:.3g} mm, within which this camera's data barely "
              "tell planes apart: a flame's emission splits between them (give one plane there)"
              + ("; depths are millimetres from the focus distance: were these given in metres?" * metres))


def found_planes(lf, views=None, search_range=None):
    """``--depths auto``: the depths holding emission (:func:`lf_flame.tomo.depth.find_depths` over the
    camera's imaging range, clipped to ``search_range``: ``--search-range``), printed, their record for the HDF5
    (each found depth, its uncertainty, peak width, plane and region) and the
    :class:`~lf_flame.tomo.depth.FoundDepths` itself (its masks: the lenslets that voted for each depth).
    ``views``: other views of ``lf.camera`` to search (a channel sum)."""
    return search_planes(lf.views if views is None else views, lf.camera, search_range, lf.lit_views())


def search_planes(views, camera, search_range=None, views_mask=None):
    """:func:`found_planes` of views (N, N, R, C) of ``camera``, searched over its imaging range clipped to
    ``search_range`` (:func:`lf_flame.optics.depth_range.search_range_mm`), over ``views_mask``'s views (None: those
    inside the aperture's image, :func:`~lf_flame.tomo.depth.find_depths`)."""
    from ..optics.depth_range import search_range_mm
    from ..tomo.depth import find_depths
    found = find_depths(views, camera, depth_range_mm=search_range_mm(camera, search_range), views_mask=views_mask)
    if not len(found.planes_mm):
        lo, hi = found.depth_range_mm
        raise ValueError(f"--depths auto found no emission in the views focused within {lo:+.1f} .. {hi:+.1f} mm "
                         "(light whose sharpest focus lies nearer or farther is not taken, nor a dark light field); "
                         "give the planes (--depth or --depths) or --search-range")
    record = found_record(found)
    lo, hi = found.depth_range_mm
    print(f"found {len(record)} depth{'s' * (len(record) != 1)} (searched {lo:+.1f} .. {hi:+.1f} mm; --search-range "
          f"to narrow) in {found.time_s:.2f} s: " + ", ".join(
        f"{r['depth_mm']:+.2f} +- {r['uncertainty_mm']:.2f} mm" for r in record)
        + f" -> {planes_count(len(found.planes_mm))}")
    return [float(d) for d in found.planes_mm], record, found


def given_planes_search(lf, search_range=None):
    """The depth search of a light field whose planes the user gave (``--depth``/``--depths``/``--slope``), without a
    word: :func:`lf_flame.tomo.depth.find_depths` over the camera's imaging range clipped to ``search_range``
    (``--search-range``), over its lit views, or None where it finds no emission (or the views hold no light: the
    solve then says so). What the given planes are checked against (:func:`given_planes_held`,
    :func:`lf_flame.cli.fit_notes.no_flame_warning`)."""
    from ..optics.depth_range import search_range_mm
    from ..tomo.depth import find_depths
    if not np.any(np.asarray(lf.views) > 0):
        return None
    found = find_depths(lf.views, lf.camera, depth_range_mm=search_range_mm(lf.camera, search_range),
                        views_mask=lf.lit_views())
    return found if len(found.planes_mm) else None


def given_planes_held(found, camera, depths):
    """The depth search's regions (``found``, :func:`given_planes_search`) put on planes the user gave, where two of
    them lie within :data:`~lf_flame.tomo.found_planes.NEAR_PARALLAX` lenslets of parallax of each other: each found
    depth on the nearest given plane (:func:`lf_flame.tomo.found_planes.on_given_planes`), so that admm holds those
    planes to their own regions where they meet, as it holds found ones (:func:`run_reconstruction`'s
    ``found_depths``): else each flame's light splits between them. None where no two given planes are near or the
    search found no emission (the planes solved free). Chosen for colour captures' temperatures and monochrome ones'
    emission on validation scenes (``docs/decisions.md``, Finding the planes and Temperature)."""
    from ..tomo.found_planes import near_pairs, on_given_planes
    if found is None or len(depths) < 2 or not near_pairs(camera, depths).any():
        return None
    return on_given_planes(found, depths)


def solve_given(lf, depths, search_range=None, **kw):
    """Planes the user gave solved as ``reconstruct`` solves them (:func:`run_reconstruction`, keywords ``kw``),
    checked against the depth search (:func:`given_planes_search`) and, where admm solves, those near each other held
    to the regions of their flames (:func:`given_planes_held`). Returns ``(given, held, op, rec)``: the search's
    :class:`~lf_flame.tomo.depth.FoundDepths` (or None), the held planes' (None where none was held), the operator
    and the solve."""
    given = given_planes_search(lf, search_range)
    held = given_planes_held(given, lf.camera, depths)
    op, rec = run_reconstruction(lf, depths, found_depths=held, **kw)
    return given, (held if "support" in rec.settings else None), op, rec   # admm's alone hold (run_reconstruction)


def found_record(found):
    """Each found depth's record for the HDF5: depth, uncertainty, peak width (mm), plane, region, lenslets."""
    return [dict(depth_mm=float(d), uncertainty_mm=float(u), width_mm=float(w), plane_mm=float(found.planes_mm[p]),
                 region=int(r), lenslets=int(m.sum()))
            for d, u, w, p, r, m in zip(found.depths_mm, found.uncertainty_mm, found.width_mm, found.plane_of,
                                        found.region, found.masks)]


def possible_warning(found) -> list:
    """The depths the found planes' route saw in its residual and did not take (``found.possible``,
    :data:`lf_flame.tomo.refine.POSSIBLE_PROMINENCE`): one warning (stderr) per depth naming it and the planes to give
    to solve with it (``found.planes_mm`` and it); their record for the HDF5 (depth, prominence, share, region)."""
    from ..tomo.refine import REFINED_PROMINENCE
    for p in found.possible:
        planes = sorted([float(d) for d in found.planes_mm] + [p["depth_mm"]])
        print(f"warning: a flame may stand at {p['depth_mm']:+.2f} mm behind or before the others: its residual's "
              f"focus peak stands {p['prominence']:.1f} robust deviations high, short of the {REFINED_PROMINENCE:g} "
              "this noise asks (faint flames and misfits stand alike there); to solve on it give the planes: "
              + " ".join(f"--depth {d:.2f}" for d in planes), file=sys.stderr)
    return [{k: (int(v) if k == "region" else float(v)) for k, v in p.items()} for p in found.possible]


def _fitted_light_field(lf, saturation):
    """The light field with ``reconstruct``'s ``--saturation`` in place of its own ("file" or "auto": as it is, its
    level found in the image or its decoded samples' mask)."""
    if saturation in ("file", "auto"):
        return lf
    if lf.white_normalised and saturation is not None:
        raise ValueError("decoded views (decoded by 'lf-flame decode', or from a raw capture here with --calibration) "
                         "carry their clipped samples (the decoding's --saturation): "
                         "--saturation takes only 'none' for them (fit every sample)")
    return dataclasses.replace(lf, leave_out=None, lattice_leave_out=None, saturation=saturation)


def solve_found(lf, found, **kw):
    """The found planes solved (:func:`run_reconstruction` with ``found_depths``), then the residual searched for
    depths the votes missed and solved again with them (:func:`lf_flame.tomo.peel.peel_planes`), and the depths of
    flames one behind another refined by the residual and their regions searched once more
    (:func:`lf_flame.tomo.refine.peel_and_refine`), as :func:`lf_flame.tomo.found_planes.find_planes`:
    ``(found, op, rec)``. Prints the depths found in the residual and the planes after the refinement where they
    differ from those found. A colour capture's levelled light field on a hexagonal lattice has its residual smoothed
    before each search (:data:`lf_flame.tomo.peel.COLOUR_RESIDUAL_SMOOTH`)."""
    from ..tomo.decoded import fit_data
    from ..tomo.peel import COLOUR_RESIDUAL_SMOOTH
    from ..tomo.refine import peel_and_refine
    from ..tomo.solvers import fitted_pixels

    def solve(f, start=None):
        return run_reconstruction(lf, [float(d) for d in f.planes_mm], found_depths=f, start=start, **kw)

    op, rec = solve(found)
    data, fit = fit_data(_fitted_light_field(lf, kw.get("saturation", "file")), op)
    fit = fitted_pixels(data, fit)
    voted = np.array(found.planes_mm)
    found, op, rec = peel_and_refine(found, op, rec, data, fit, lf.camera, solve,
                                     smooth=COLOUR_RESIDUAL_SMOOTH if "monochrome" in lf.meta and
                                     lf.lattice_views is not None else 0.0)
    if len(found.planes_mm) != len(voted) or not np.allclose(found.planes_mm, voted):
        added = found.depths_mm[found.weight == 0]       # no votes: found in the residual
        if len(added):
            print("found in the residual (behind or before other flames): " + ", ".join(
                f"{d:+.2f} mm" for d in added) + f" -> {planes_count(len(found.planes_mm))}")
        print("planes after the residual's search and refinement: " + ", ".join(
            f"{d:+.2f}" for d in found.planes_mm) + " mm")
    return found, op, rec


def run_reconstruction(lf, depths, solver=None, iters=None, *, damp=0.0, tv=None, saturation="file",
                       rays_per_pixel=None, progress=False, subsamples=None, found_depths=None, support=False,
                       model_dir=None, start=None):
    """Build the operator of the light field's camera at ``depths``
    (:func:`lf_flame.tomo.exact.emission_operator`: exact unless ``rays_per_pixel`` is given; decoded views':
    :class:`lf_flame.tomo.lattice.LatticeOperator`, with decoding's interpolation) and
    solve (:func:`lf_flame.tomo.solvers.reconstruct`; solver None: the operator's default) on the
    light field's data (:func:`lf_flame.tomo.decoded.fit_data`: decoded views times the model's
    white views). The exact operator's grid: ``subsamples`` samples per lenslet; None: admm's
    (:func:`lf_flame.tomo.noise_knobs.admm_subsamples`), 1 for the other solvers. ``saturation``: "file" (the light field's own mask or level), a level or None.
    ``found_depths``: the :class:`~lf_flame.tomo.depth.FoundDepths` the planes were found as, or None (planes
    given). With them admm (as :func:`lf_flame.tomo.found_planes.find_planes`) holds near planes to their own regions
    where they meet (:func:`~lf_flame.tomo.found_planes.found_support`) and takes the found planes' knobs where they
    differ from its own and none were given (:func:`lf_flame.tomo.found_planes.found_planes_knobs`); ``support``: every
    plane held to its regions, with :data:`~lf_flame.tomo.found_planes.SUPPORT_KNOBS`. ``solver`` "learned": the
    reconstructor saved in ``model_dir`` (:func:`lf_flame.learn.reconstructor.reconstruction`, lenslet grid;
    None: its default folder). ``start``: a :class:`~lf_flame.tomo.solvers.Reconstruction` on as many planes a little
    apart in depth, which admm starts from (``reconstruct``'s ``start_planes``), or None. A light field without
    light (no sample fitted above 0: lsqr's planes had been NaN) is refused before the solve (ValueError)."""
    from ..tomo.decoded import fit_data
    from ..tomo.defaults import EXACT_SOLVER
    from ..tomo.exact import ExactOperator, emission_operator
    from ..tomo.noise_knobs import admm_subsamples
    from ..tomo.solvers import fitted_pixels, reconstruct
    admm = rays_per_pixel is None and (solver or EXACT_SOLVER) == "admm"
    if solver == "learned" and (rays_per_pixel is not None or support or subsamples not in (None, 1)):
        raise ValueError("the learned reconstructor runs on the exact operator's lenslet grid: it takes neither "
                         "--rays-per-pixel, --support nor --subsamples")
    if subsamples is None:
        subsamples = admm_subsamples(len(depths)) if admm else 1
    if rays_per_pixel is not None and lf.decoded:
        raise ValueError("--rays-per-pixel traces the simulated camera; decoded views are solved on their camera's "
                         "exact operator")
    if lf.interpolation is not None and rays_per_pixel is None:     # decoded views: their interpolation modelled
        from ..tomo.lattice import LatticeOperator
        op = LatticeOperator(lf.camera, depths, lf.views.shape[2:], layout="square", subsamples=subsamples,
                             interpolation=lf.interpolation)
    else:
        op = emission_operator(lf.camera, depths, rays_per_pixel=rays_per_pixel, subsamples=subsamples,
                               sample_offsets=lf.sample_offsets if lf.lattice_views is None else None)
    lf = _fitted_light_field(lf, saturation)
    data, fit = fit_data(lf, op)
    fitted = fitted_pixels(data, fit)
    if fitted.any() and not np.any(data[fitted] > 0):   # lsqr had divided 0 by 0 (NaN planes), the others gave 0
        raise ValueError(f"{lf.source or 'the light field'} holds no light: its {int(fitted.sum())} samples fitted "
                         "are all 0 (or below), there is nothing to reconstruct; check that it is the capture meant "
                         "and its exposure (a dark frame subtracted from itself, a capped lens)")
    if solver == "learned":
        from ..learn.reconstructor import DEFAULT_MODEL_DIR, LearnedReconstructor, reconstruction
        if not isinstance(op, ExactOperator):
            raise ValueError("the learned reconstructor needs the exact operator: this camera is not a perfect "
                             "lenslet grid")
        return op, reconstruction(data, op, LearnedReconstructor.load(model_dir or DEFAULT_MODEL_DIR),
                                  fitted_pixels(data, fit))
    knobs = {}
    if support and (found_depths is None or not admm):
        raise ValueError("--support holds admm's planes to the regions their depths were found in: it takes the "
                         "admm solver and found depths")
    if found_depths is not None and admm:
        from ..tomo.found_planes import SUPPORT_KNOBS, found_planes_knobs, found_support
        s = getattr(op, "subsamples", 1)
        if support:
            knobs = dict(SUPPORT_KNOBS)
        elif iters is None:
            knobs = dict(found_planes_knobs(data, fit, s) or {})
        knob_tv = knobs.pop("tv", None)
        tv = knob_tv if tv is None else tv
        mask = found_support(found_depths, lf.camera, s, support=support)
        if mask is not None:
            knobs["support"] = mask
    if start is not None and admm and start.planes.shape == tuple(op.dims):
        knobs["start_planes"] = start.planes
    rec = reconstruct(data, op, solver, iters, damp=damp, tv=tv, saturation=fit, progress=progress, unit=lf.unit,
                      **knobs)
    if found_depths is not None and admm:
        rec.settings["support"] = "regions" if support else ("near planes" if "support" in knobs else "none")
    return op, rec


def lattice_solve(lf, op, rec, found=None, support: bool = False):
    """A hexagonal camera's admm planes solved again on its lenslets' own lattice with admm's knobs and support
    (:func:`lf_flame.tomo.lattice.solve_on_lattice`): ``(rec on the square grid, LatticeSolve)``; ``(rec, None)``
    as they are for a light field without lattice views or another solver."""
    if lf.lattice_views is None or rec.solver != "admm":
        return rec, None
    from ..tomo.lattice import solve_on_lattice
    mask = None
    if found is not None and rec.settings.get("support", "none") != "none":
        from ..tomo.found_planes import found_support
        mask = found_support(found, lf.camera, getattr(op, "subsamples", 1), support=support)
    lattice = solve_on_lattice(lf, rec, op, support=mask)
    print(f"solved again on the hexagonal lattice of the lenslets ({lattice.rec.time_s:.2f} s, operator "
          f"{lattice.op.setup_s:.2f} s), resampled onto the square grid")
    return lattice.square, lattice
