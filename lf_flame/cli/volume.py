"""The ``reconstruct`` command: each plane's emission from one light field
(:mod:`lf_flame.tomo`), written to HDF5 with a figure. Without planes given (``--depths auto``)
the depths holding emission are found first (:mod:`lf_flame.tomo.depth`).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from ._io import (AUTO_LEVEL, RAW_FORMATS, _level_or_none, _raw_objects, _raw_scene, add_camera_args, add_figure_arg,
                  add_search_arg, light_field, positive_int)
from ..simulate.scenes import PAPER_DEPTHS_MM
from ..tomo.defaults import (ADMM_KNOBS, ADMM_QUIET, ADMM_SUBSAMPLES, ADMM_TV, DEFAULT_ITERS, DEFAULT_SOLVER,
                              DEFAULT_TV, EXACT_SOLVER, SOLVERS, SUBSAMPLES_MAX_PLANES, VOLUME_L1,
                              VOLUME_MAX_PLANES, VOLUME_PRIOR, VOLUME_PRIORS, VOLUME_STEP_MM, VOLUME_TV)


def reconstruct_input(a, colour: bool = False):
    """Light field, depths (mm, or "auto") and flame objects (or None) of ``reconstruct``/``temperature``
    (``colour``: a colour capture's channels kept, :func:`._io.light_field`)."""
    lf = light_field(a, colour=colour)
    stored = _raw_objects(a.raw)          # what 'lf-flame simulate' stored beside a raw image, decoded here or not
    return lf, planes_from_args(a, lf.camera, stored), None if lf.decoded else stored


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
                             "writes, .npz or .png, does)")
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
        from ..optics.camera import check_imaging_range
        check_imaging_range(cam, depths)
    return depths


def found_planes(lf, views=None, search_range=None):
    """``--depths auto``: the depths holding emission (:func:`lf_flame.tomo.depth.find_depths` over the
    camera's imaging range, clipped to ``search_range``: ``--search-range``), printed, their record for the HDF5
    (each found depth, its uncertainty, peak width, plane and region) and the
    :class:`~lf_flame.tomo.depth.FoundDepths` itself (its masks: the lenslets that voted for each depth).
    ``views``: other views of ``lf.camera`` to search (a channel sum)."""
    return search_planes(lf.views if views is None else views, lf.camera, search_range, lf.lit_views())


def search_planes(views, camera, search_range=None, views_mask=None):
    """:func:`found_planes` of views (N, N, R, C) of ``camera``, searched over its imaging range clipped to
    ``search_range`` (:func:`lf_flame.optics.camera.search_range_mm`), over ``views_mask``'s views (None: those
    inside the aperture's image, :func:`~lf_flame.tomo.depth.find_depths`)."""
    from ..optics.camera import search_range_mm
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
        + f" -> {len(found.planes_mm)} planes")
    return [float(d) for d in found.planes_mm], record, found


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
        raise ValueError("decoded views carry their clipped samples ('lf-flame decode --saturation'): "
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
                f"{d:+.2f} mm" for d in added) + f" -> {len(found.planes_mm)} planes")
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
    apart in depth, which admm starts from (``reconstruct``'s ``start_planes``), or None."""
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
    rec = reconstruct(data, op, solver, iters, damp=damp, tv=tv, saturation=fit, progress=progress, **knobs)
    if found_depths is not None and admm:
        rec.settings["support"] = "regions" if support else ("near planes" if "support" in knobs else "none")
    return op, rec


def saturation_note(rec, lf=None) -> str:
    """What the fit left out: the count of saturated pixels (``reconstruct``'s settings; of the light field ``lf``
    where its defective pixels' samples make the fit's mask, :func:`defects_note` counting those)."""
    level, n = rec.settings.get("saturation"), rec.settings.get("n_saturated", 0)
    if lf is not None and lf.defects is not None:
        level = lf.saturation
        n = 0 if level is None else int(np.count_nonzero(lf.views >= level))
    if level is None:
        return "saturation: none given, every pixel fitted" + ("" if lf is None or lf.defects is None else
                                                              " but the defective ones")
    if rec.solver == "adjoint":   # no fit: the adjoint carries every pixel back as it is
        return f"{n} saturated pixels (at or above {level:g}), used as they are by the adjoint"
    return f"{n} saturated pixels (at or above {level:g}) left out of the fit"


def left_out_notes(lf, rec, lattice=None) -> list:
    """What the fit of the light field ``lf`` left out, one line each: its saturated pixels (:func:`saturation_note`),
    or a decoded capture's samples (:func:`decoded_note`), and its defective pixels where it has some."""
    from .real import defects_note
    notes = [decoded_note(lf, rec, lattice) if lf.decoded or lf.leave_out is not None else saturation_note(rec, lf)]
    return notes + ([defects_note(lf.defective_pixels)] if lf.defective_pixels else [])


def resolution_note(table, condition: float, span_mm: float) -> str:
    """The stack's depth resolution in one line: per feature size (``table``: :meth:`DepthResolution.to_frame
    <lf_flame.tomo.resolution.DepthResolution.to_frame>`) the spacing resolved at ``condition``, "> span" where
    none in the stack is, and where the feature is finer than the planes' samples (not mapped), that."""
    apart = ["finer than the planes' samples" if np.isnan(s) else f"> {span_mm:g} mm apart" if np.isinf(s) else
             f"{s:.2g} mm apart" for s in table[f"spacing_interp_mm_{condition:g}"]]
    return (f"depth resolution of this stack for the data alone (condition <= {condition:g}; the prior adds what the "
            "data lack): " + ", ".join(f"{f:g} mm features {s}" for f, s in zip(table.feature_mm, apart)))


def decoded_note(lf, rec, lattice=None) -> str:
    """What the fit of decoded views (or of a raw colour mosaic, levelled) left out: the count and share of the
    samples (of the hexagonal lattice's views where ``lattice``, a :class:`~lf_flame.tomo.lattice.LatticeSolve`,
    solved them) and why."""
    rec = rec if lattice is None else lattice.rec   # on the lattice: its axial cells that hold a lenslet
    n, total = int(rec.settings.get("n_saturated", 0)), int(rec.settings.get("n_samples", lf.views.size))
    why = ("clipped, or dark: outside the aperture's image" if lf.decoded else "clipped") + (
        "; a colour camera's blue samples, which the levelled light field leaves out" if "monochrome" in lf.meta else "")
    return f"{n} of {total} samples ({100 * n / total:.0f} %) left out of the fit ({why})"


def edge_warning(rec, op, modelled: bool = False, stack: bool = False):
    """Each plane's share of its emission within :data:`~lf_flame.tomo.solvers.EDGE_BAND_LENSLETS` of the field's
    edge (:func:`~lf_flame.tomo.solvers.edge_shares`), for the file; where a plane's exceeds
    :data:`~lf_flame.tomo.solvers.EDGE_SHARE_WARN`, one warning (stderr) naming those planes, or with ``modelled``
    (the axisymmetric prior's light from beyond the field) a note that it was modelled. ``stack``: a dense stack's
    planes, on which the warning also names light the solve spread over planes far from any flame."""
    from ..tomo.solvers import EDGE_BAND_LENSLETS, EDGE_SHARE_WARN, edge_shares
    edge = [float(v) for v in edge_shares(rec.planes, getattr(op, "subsamples", 1))]
    cut = [(d, e) for d, e in zip(rec.depths_mm, edge) if e > EDGE_SHARE_WARN]
    if cut:
        which = ", ".join(f"{d:+.2f} mm ({100 * e:.1f} %)" for d, e in cut[:4]) + (
            f" and {len(cut) - 4} more" if len(cut) > 4 else "")
        lead = f"the emission reaches the field's edge (share within {EDGE_BAND_LENSLETS} lenslets of it: {which})"
        if modelled:
            print(f"{lead}: the axisymmetric prior modelled its light from beyond the field; the volume holds the "
                  "field's part")
        else:
            print(f"warning: {lead}: the flame is cut by the field of view, and the light that falls outside the "
                  "views is not recovered" + ("; or, on planes far from the flame, the solve spread light there"
                                              if stack else ""),
                  file=sys.stderr)
    return edge


def misfit_warning(lf, op, rec, saturation="file", lattice=None):
    """The solve's misfit on the light field's data as it was fitted (:func:`lf_flame.tomo.solvers.data_misfit`;
    a :class:`~lf_flame.tomo.lattice.LatticeSolve` on its lattice's), for the file; where it is high
    (:func:`~lf_flame.tomo.solvers.misfit_is_high`), one warning (stderr) saying what it means, and where admm
    ran every fill of its cap, that more fills may explain more."""
    from ..tomo.decoded import fit_data
    from ..tomo.solvers import data_misfit, misfit_is_high
    if lattice is not None:
        m = data_misfit(lattice.data, lattice.op, lattice.rec.planes, lattice.leave_out)
    else:
        data, fit = fit_data(_fitted_light_field(lf, saturation), op)
        m = data_misfit(data, op, rec.planes, fit)
    if misfit_is_high(m):
        capped = rec.solver == "admm" and int(rec.settings.get("fills_run", 0)) >= int(rec.settings["iters"])
        print(f"warning: the planes leave {100 * m['misfit']:.0f} % of the light field unexplained beyond its noise "
              f"(relative residual {m['relative_residual']:.3f}, of which noise {m['noise_share']:.3f}): light "
              "from flames off these planes or beyond the field, or a camera file that is not this camera's"
              + ("; a colour capture levelled into one light field keeps its flames' colour variation (their red "
                 "samples differ from green's), part of this" if "monochrome" in lf.meta else "")
              + (f"; admm stopped at its fills' cap ({int(rec.settings['iters'])}) without settling: more fills "
                 "(--iters) may explain more" if capped else "") + black_level_note(lf, op), file=sys.stderr)
    return m


def black_level_note(lf, op) -> str:
    """Where the samples no light reaches (outside the aperture's image: the operator's white views dark) read more
    than :data:`~lf_flame.real.black_level.BLACK_LEVEL_SHARE` of the light field's peak (their median), the misfit
    warning's hint: a black level (the sensor's offset) or stray light not subtracted, which no plane of emission
    explains. "" otherwise, for decoded views (their dark samples are left out, and decoding reads the capture's own
    unlit pixels: :func:`lf_flame.cli._io.black_level_warning`) and for operators without kernels."""
    if lf.decoded or not hasattr(op, "kernels"):
        return ""
    from ..real.black_level import BLACK_LEVEL_SHARE
    from ..tomo.decoded import white_views
    white = white_views(op)
    unlit = white <= 1e-6 * white.max()
    views = np.asarray(lf.views)
    peak = float(np.percentile(views, 99.9))
    if np.count_nonzero(unlit) < 100 or not peak > 0:
        return ""
    level = float(np.median(views[unlit]))
    if level <= BLACK_LEVEL_SHARE * peak:
        return ""
    return (f"; the samples no light reaches (outside the aperture's image) read {level:.3g}, {100 * level / peak:.1f} "
            "% of the light field's peak: a black level or stray light not subtracted (subtract the dark frame)")


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


def cmd_reconstruct(a):
    from ..tomo.files import iterations_note, plot_reconstruction, save_reconstruction
    from ..tomo.truth import truth_depths
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    if getattr(a, "volume", False):
        return volume_reconstruct(a)
    given = [f"--{k}" for k, n in (("from", "near"), ("to", "far"), ("step", "step"), ("l1", "l1")) if getattr(a, n, None) is not None]
    if given:
        raise ValueError(" and ".join(given) + " go with --volume")
    lf, depths, objects = reconstruct_input(a)
    t_route = time.perf_counter()
    cam, views = lf.camera, lf.views
    extra, arrays, voters = {}, None, None
    if getattr(a, "support", False) and depths != "auto":
        raise ValueError("--support holds each plane to the regions its depth was found in: it goes with the found "
                         "depths (--depths auto, the default), not with planes given")
    if depths == "auto":
        _, _, voters = found_planes(lf, search_range=a.search_range)   # their record once solved (below)
        extra = dict(depths_from="auto", support=bool(getattr(a, "support", False)))
    if "monochrome" in lf.meta:                        # a colour capture's channels levelled
        extra["monochrome"] = lf.meta["monochrome"]
        print(f"colour capture: {lf.meta['monochrome']}")
    if lf.decoded:
        operator = "exact" if lf.interpolation is None else "exact, with decoding's interpolation" + (
            ", on the hexagonal lattice" if lf.lattice_views is not None else "")
        extra.update(own_camera=lf.capture_camera.to_json(), frame=lf.frame.to_dict(), operator=operator,
                     n_clipped=0 if lf.leave_out is None else int(lf.leave_out.sum()))
        if lf.camera_file:
            extra["camera_file"] = lf.camera_file
    kw = dict(solver=a.solver, iters=a.iters, damp=a.damp, tv=a.tv, saturation=getattr(a, "saturation", "file"),
              rays_per_pixel=a.rays_per_pixel, progress=True, subsamples=getattr(a, "subsamples", None),
              model_dir=getattr(a, "model", None))
    if voters is None:
        op, rec = run_reconstruction(lf, depths, **kw)
    else:
        voters, op, rec = solve_found(lf, voters, support=bool(getattr(a, "support", False)), **kw)
        depths = [float(d) for d in voters.planes_mm]      # after the residual's search and the refinement
        extra["found_depths"] = found_record(voters)
        arrays = dict(found_masks=np.asarray(voters.masks, bool), found_regions=voters.labels)
        extra["possible_depths"] = possible_warning(voters)
    fitted = _fitted_light_field(lf, kw["saturation"])
    rec, lattice = lattice_solve(fitted, op, rec, voters,
                                 bool(getattr(a, "support", False)))
    if rec.settings.get("support") == "near planes":
        from ..tomo.found_planes import NEAR_PARALLAX
        print(f"planes within {NEAR_PARALLAX:g} lenslets of parallax of each other are held to the regions their "
              "depths were found in, where they meet (the data barely tell such planes apart)")
    print("\n".join(left_out_notes(fitted, rec, lattice)))
    from .real import overexposure_warning
    extra["clipped_share"] = overexposure_warning(fitted.over_exposure())
    extra["edge_share"] = edge_warning(rec, op)
    extra["misfit"] = misfit_warning(lf, op, rec, kw["saturation"], lattice)
    extra["route_time_s"] = route_s = time.perf_counter() - t_route     # the depth search (if any), every solve
    out = Path(a.out)
    save_reconstruction(out, rec, arrays, source=str(a.raw), camera=cam.to_json(), **extra)
    sub, truth, fig = getattr(op, "subsamples", 1), None, _figure_path(a)
    if fig is not None:
        refocused = focal_stack(views, [cam.slope_for_depth(d) for d in depths],
                                aperture_mask(cam.pixels_per_lenslet, "circular"))
        refocused = np.repeat(np.repeat(refocused, sub, axis=1), sub, axis=2)      # on the planes' grid
        scene, truth = _scene_truth(a.raw, lf, op)
        plot_reconstruction(fig, rec, refocused, truth, truth_depths_mm=None if scene is None else
                            truth_depths(scene, rec.depths_mm))
    res = f"{extra['misfit']['relative_residual']:.4f}"     # of the planes written (a solver's last is older)
    grid = f", {sub} x {sub} samples per lenslet" if sub > 1 else ""
    m = rec.settings.get("sub_views")
    grid += f", each sample at its own pixel ({m} x {m} sub-views per view)" if m else ""
    print(f"reconstructed {len(depths)} planes ({rec.solver}, {iterations_note(rec)}{grid}) in {route_s:.2f} s "
          f"(its last solve {rec.time_s:.2f} s);"
          f" relative residual {res} -> {out}" + ("" if fig is None else f", {fig}")
          + ("" if truth is None else " (with the scene's truth)"))


def _scene_truth(raw, lf, op):
    """The scene ``lf-flame simulate`` rendered into ``raw``, rebuilt for the camera it was drawn for, and its
    emission on ``op``'s planes: for decoded views carried into the decoded frame
    (:func:`lf_flame.tomo.decoded.decoded_truth`), else :func:`lf_flame.tomo.truth.scene_truth`; (None, None) where no
    scene is stored."""
    from ..tomo.decoded import decoded_truth
    from ..tomo.truth import scene_truth
    scene = _raw_scene(raw, lf.capture_camera if lf.decoded else lf.camera)
    if scene is None:
        return None, None
    return scene, (decoded_truth(scene, op, lf.frame.rotation_deg, lf.frame.centre_lenslets) if lf.decoded else
                   scene_truth(scene, op))


def _figure_path(a):
    """The figure beside ``--out`` (.png), or None with ``--no-figure``."""
    return Path(a.out).with_suffix(".png") if getattr(a, "figure", True) else None


def volume_reconstruct(a):
    """``reconstruct RAW --volume --from MM --to MM [--step MM] [--prior P]``: a dense stack with a prior
    (:func:`lf_flame.tomo.volume.solve_volume`) -> HDF5 (the planes, their depths, the prior's settings, the
    stack's depth resolution; for the axisymmetric prior ``extra/emission_r_y`` with ``extra/radii_mm`` and
    ``extra/heights_mm``) and the figure (maxima, side view, slice and depth profile; with the truth where the
    scene is known)."""
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    from ..tomo.files import plot_reconstruction, save_reconstruction
    from ..tomo.volume import solve_volume
    other = [f"--{k.replace('_', '-')}" for k in ("depth", "depths", "slope", "solver", "iters", "subsamples",
                                                  "rays_per_pixel")
             if getattr(a, k, None) not in (None, False)]
    if other:
        raise ValueError(f"--volume solves its own stack (--from, --to, --step) with admm or the axisymmetric "
                         f"prior on the exact operator of the light field's camera; drop {', '.join(other)}")
    if a.near is None or a.far is None:
        raise ValueError("--volume needs the stack's ends: --from MM and --to MM (mm from the focal plane, > 0 "
                         "farther; 'lf-flame reconstruct RAW' without --volume finds the flames' depths)")
    lf, _, _ = reconstruct_input(a)
    cam, views = lf.camera, lf.views
    lo, hi = lf.depth_range_mm()
    if not (lo <= a.near and a.far <= hi):
        raise ValueError(f"--from {a.near:g} --to {a.far:g}: this camera refocuses {lo:+.3g} .. {hi:+.3g} mm from its "
                         "focus distance")
    level = getattr(a, "saturation", "file")
    step = VOLUME_STEP_MM if a.step is None else a.step
    rec, extra = solve_volume(views, cam, a.near, a.far, step, a.prior,
                              saturation=_fitted_light_field(lf, level).fit_mask(),
                              tv=a.tv, l1=a.l1, progress=True, white_normalised=lf.white_normalised,
                              interpolation=lf.interpolation)
    res, axi, op = extra["resolution"], extra["axisymmetric"], extra["operator"]
    table = res.to_frame()
    arrays = {} if axi is None else dict(emission_r_y=axi.emission, radii_mm=axi.radii_mm, heights_mm=axi.heights_mm)
    out = Path(a.out)
    edge = edge_warning(rec, op, modelled=axi is not None and axi.beyond_field, stack=axi is None)
    misfit = misfit_warning(lf, op, rec, level)
    save_reconstruction(out, rec, arrays, source=str(a.raw), camera=cam.to_json(), volume=True,
                        depth_resolution=table.to_dict("list"), edge_share=edge, misfit=misfit,
                        operator="exact" if lf.interpolation is None else "exact, with decoding's interpolation")
    _, truth = _scene_truth(a.raw, lf, op)
    fig = _figure_path(a)
    if fig is not None:
        refocused = focal_stack(views, [cam.slope_for_depth(d) for d in rec.depths_mm],
                                aperture_mask(cam.pixels_per_lenslet, "circular"))
        plot_reconstruction(fig, rec, refocused, truth, title=f"volume, prior {a.prior}: {len(rec.depths_mm)} "
                            f"planes every {step:g} mm, {rec.time_s:.1f} s")
    axis = "" if axi is None else f"; axis at x {axi.axis_x_mm:+.2f} mm, depth {axi.axis_z_mm:+.2f} mm"
    score = "" if truth is None else (f"; against the scene's truth: 3-D relative error "
                                      f"{np.linalg.norm(rec.planes - truth) / np.linalg.norm(truth):.3f}")
    print(f"volume of {len(rec.depths_mm)} planes from {rec.depths_mm[0]:+g} to {rec.depths_mm[-1]:+g} mm every "
          f"{step:g} mm, prior "
          f"{a.prior} ({rec.solver}), solved in {rec.time_s:.1f} s{axis}{score} -> {out}"
          + ("" if fig is None else f", {fig}"))
    print(resolution_note(table, res.conditions[0], float(rec.depths_mm[-1] - rec.depths_mm[0])))


def _subsamples(text: str):
    """``--subsamples``: 1 or 2, or None for 'auto'."""
    if text.lower() == "auto":
        return None
    if text not in ("1", "2"):
        raise argparse.ArgumentTypeError(f"--subsamples takes auto, 1 or 2. Received: {text!r}")
    return int(text)


def _admm_fills(subsamples: int) -> str:
    """admm's cap on its fills on a grid of ``subsamples``, by the noise (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`)."""
    quiet, noisy = (ADMM_KNOBS[subsamples, k]["fills"] for k in ("quiet", "noisy"))
    return f"{quiet}" if quiet == noisy else f"{quiet} (quiet) or {noisy} (noisy)"


#: What admm's iterations are by default (``reconstruct --help``): its fills of the missing data, a cap by the
#: data's noise and the planes' grid, stopped sooner once they converge; ``reconstruct`` prints how many ran.
ADMM_FILLS_HELP = (f"admm: its fills of the missing data, by the data's noise and the grid: at most "
                   f"{_admm_fills(ADMM_SUBSAMPLES)} on the {ADMM_SUBSAMPLES} x {ADMM_SUBSAMPLES} grid, "
                   f"{_admm_fills(1)} on the lenslet grid, stopping sooner once they converge (the output says how "
                   "many ran); --iters N runs all N")


def add_parsers(sub) -> None:
    """Add ``reconstruct`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("reconstruct", help="each plane's emission from one light field (3-D reconstruction with "
                       "the simulator as the forward operator) -> HDF5 and a figure")
    s.add_argument("raw", help=RAW_FORMATS + ", or views .h5 from 'lf-flame decode'")
    s.add_argument("--depth", type=float, action="append",
                   help="plane depth (mm from the focal plane; repeatable). Default: --depths auto")
    s.add_argument("--depths", default=None,
                   help="the planes: 'auto' (the default when neither --depth nor --slope is given) finds the depths "
                        "that hold emission from the views (depth from focus per region, several per region where "
                        "flames stand one behind another; lf_flame.tomo.depth) and solves on them, with admm unless "
                        "--solver says otherwise, writing each found depth and its uncertainty into the HDF5; "
                        "'scene': the depths of the objects that 'lf-flame simulate' stored (.npz or .png); 'paper': "
                        "the paper's four planes, " + ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) + " mm; or "
                        "depths in mm separated by commas")
    s.add_argument("--slope", type=float, action="append", help="plane slope instead of a depth (repeatable)")
    s.add_argument("--solver", choices=list(SOLVERS) + ["learned"],
                   help=f"the default is the one chosen on validation renders: {EXACT_SOLVER} on the exact operator, "
                        f"{DEFAULT_SOLVER} on a traced one (--rays-per-pixel); adjoint: plain refocusing through "
                        f"the operator's rays; learned: a trained network on a one-pass Wiener start (lenslet grid; "
                        f"--model; make train-reconstructor) (default: {EXACT_SOLVER}, traced: {DEFAULT_SOLVER})")
    s.add_argument("--model", default=None,
                   help="--solver learned: the folder of a reconstructor trained for this camera (default: "
                        "models/reconstructor/paper, make train-reconstructor)")
    s.add_argument("--iters", type=positive_int, help="iterations, >= 1 (default: the solver's, chosen on validation "
                   "renders: " + ", ".join(f"{k} {v}" for k, v in DEFAULT_ITERS.items() if k not in ("adjoint", "admm"))
                   + "; " + ADMM_FILLS_HELP + "; adjoint: none)")
    s.add_argument("--damp", type=float, default=0.0, help="LSQR damping (Tikhonov)")
    s.add_argument("--tv", type=float, default=None, help=f"TV weight of pd-tv (default: {DEFAULT_TV}) or of admm "
                   f"(default by the light field's noise and the grid: on {ADMM_SUBSAMPLES} x {ADMM_SUBSAMPLES} samples "
                   f"per lenslet {ADMM_KNOBS[ADMM_SUBSAMPLES, 'quiet']['tv']} on quiet data, "
                   f"{ADMM_KNOBS[ADMM_SUBSAMPLES, 'noisy']['tv']} on noisy; on the lenslet grid "
                   f"{ADMM_QUIET['tv']} and {ADMM_TV})")
    s.add_argument("--subsamples", type=_subsamples, default=None,
                   help="samples per lenslet and axis of the planes' grid on the exact operator: 1 (the lenslet grid) "
                        "or 2 (detail finer than a lenslet, seen off focus in the views' parallax; 4x the unknowns). "
                        f"Default 'auto': {ADMM_SUBSAMPLES} for admm on at most {SUBSAMPLES_MAX_PLANES} planes, else 1")
    s.add_argument("--support", action="store_true",
                   help="hold every found plane's emission to the regions its depth was found in (admm, found "
                        "depths). Without it only planes within 3 lenslets of parallax of each other are held so, where "
                        "they meet (their emission would otherwise split between them); docs/own_camera.md")
    s.add_argument("--saturation", type=_level_or_none, default=argparse.SUPPRESS,
                   help="the sensor's clipping level in the views' units: pixels at or above it are left out of the "
                        "fit ('none': fit every pixel; default auto: " + AUTO_LEVEL + "). Decoded views take only "
                        "'none' (fit every sample): they carry their clipped samples ('lf-flame decode "
                        "--saturation')")
    add_camera_args(s)
    s.add_argument("--rays-per-pixel", type=int, default=None,
                   help="rays per pixel of a traced forward operator (the reference; default: the exact operator "
                        "where the camera is a perfect lenslet grid, else 4 rays)")
    s.add_argument("--volume", action="store_true",
                   help="a volume: a dense stack every --step mm from --from to --to (mm from the focal plane) on the "
                        "exact operator's lenslet grid, with a prior (--prior), and the depth resolution the stack "
                        "carries for the data alone (lf_flame.tomo.volume)")
    s.add_argument("--from", dest="near", type=float, help="--volume: the nearest plane (mm)")
    s.add_argument("--to", dest="far", type=float, help="--volume: the farthest plane (mm)")
    s.add_argument("--step", type=float, default=None, help=f"--volume: plane spacing (mm; at most "
                   f"{VOLUME_MAX_PLANES} planes; default {VOLUME_STEP_MM:g}: finer than a flame, whatever the camera)")
    s.add_argument("--prior", choices=list(VOLUME_PRIORS), default=VOLUME_PRIOR,
                   help=f"--volume: none (admm by the data's noise), tv (admm with TV per plane, weight --tv, "
                        f"default {VOLUME_TV['quiet']:g} on quiet data, {VOLUME_TV['noisy']:g} on noisy), sparse (admm "
                        f"with an l1 weight, --l1, default {VOLUME_L1['quiet']:g} of the weight that zeroes every "
                        f"plane), axisymmetric (a laminar flame's e(r, y) about a vertical axis found from the data: "
                        f"for laminar flames)")
    s.add_argument("--l1", type=float, default=None, help="--volume --prior sparse: the l1 weight in [0, 1)")
    s.add_argument("--out", required=True, help="volume.h5 (planes, depths, mm per sample, settings, residuals); "
                                               "the figure goes beside it as .png")
    add_figure_arg(s, "each plane beside its refocused plane and, for a simulated scene, the truth")
    add_search_arg(s)
    s.set_defaults(func=cmd_reconstruct)
