"""The ``reconstruct`` command: each plane's emission from one light field
(:mod:`lf_flame.tomo`), written to HDF5 with a figure. Without planes given (``--depths auto``)
the depths holding emission are found first (:mod:`lf_flame.tomo.depth`).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from ._io import RAW_FORMATS, _raw_scene, planes_count
from .options import AUTO_LEVEL, finite, _level_or_none, add_camera_args, add_figure_arg, add_search_arg, positive_int
from .fit_notes import (edge_warning, left_out_notes, misfit_warning, resolution_note, resolved_spacing_mm,
                        solve_warnings, stack_end_warning)
from .planes import (_fitted_light_field, found_planes, found_record, lattice_solve, possible_warning,
                     reconstruct_input, solve_found, solve_given)
from ..simulate.scenes import PAPER_DEPTHS_MM
from ..tomo.defaults import (ADMM_KNOBS, ADMM_QUIET, ADMM_SUBSAMPLES, ADMM_TV, DEFAULT_ITERS, DEFAULT_SOLVER,
                              DEFAULT_TV, EXACT_SOLVER, SOLVERS, SUBSAMPLES_MAX_PLANES, VOLUME_L1,
                              VOLUME_MAX_PLANES, VOLUME_PRIOR, VOLUME_PRIORS, VOLUME_STEP_MM, VOLUME_TV)


#: The solver options each solver of ``reconstruct`` uses (``--iters``, ``--damp``, ``--tv``; ``--saturation`` the
#: learned route does not, its network taking every pixel as it is).
SOLVER_OPTIONS = {"adjoint": (), "lsqr": ("iters", "damp", "saturation"), "fista": ("iters", "saturation"),
                  "pd-tv": ("iters", "tv", "saturation"), "rl": ("iters", "saturation"),
                  "admm": ("iters", "tv", "saturation"), "learned": ()}


def refuse_unused(a) -> None:
    """Refuse ``reconstruct``'s solver options that its solver (``--solver``, or the default: admm, pd-tv on a traced
    operator) does not use (:data:`SOLVER_OPTIONS`): they had been taken and printed without changing a pixel
    (``--solver adjoint --iters 50``, ``--damp 5`` with admm, ``--tv 3`` with rl).

    Raises
    ------
    ValueError
        Naming the options and the solver.
    """
    solver = a.solver or ("pd-tv" if a.rays_per_pixel else "admm")
    given = {"iters": a.iters is not None, "damp": bool(a.damp), "tv": a.tv is not None,
             "saturation": getattr(a, "saturation", "auto") != "auto"}
    unused = [f"--{k}" for k, g in given.items() if g and k not in SOLVER_OPTIONS[solver]]
    if unused:
        uses = ", ".join(f"--{k}" for k in SOLVER_OPTIONS[solver] if k != "saturation") or "none of them"
        raise ValueError(f"{' and '.join(unused)} {'is' if len(unused) == 1 else 'are'} not used by the {solver} "
                         f"solver (it takes {uses}): drop {'it' if len(unused) == 1 else 'them'}, or choose a solver "
                         "that uses it (--solver)")


def cmd_reconstruct(a):
    from ..tomo.files import iterations_note, plot_reconstruction, save_reconstruction
    from ..tomo.truth import truth_depths
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    if getattr(a, "volume", False):
        return volume_reconstruct(a)
    given = [f"--{k}" for k, n in (("from", "near"), ("to", "far"), ("step", "step"), ("l1", "l1")) if getattr(a, n, None) is not None]
    if given:
        raise ValueError(" and ".join(given) + " go with --volume")
    refuse_unused(a)
    lf, depths, objects = reconstruct_input(a)
    t_route = time.perf_counter()
    cam, views = lf.camera, lf.views
    extra, arrays, voters, held, given = {}, None, None, None, None
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
        extra.update(decoded_record(lf), operator=operator)
    kw = dict(solver=a.solver, iters=a.iters, damp=a.damp, tv=a.tv, saturation=getattr(a, "saturation", "file"),
              rays_per_pixel=a.rays_per_pixel, progress=True, subsamples=getattr(a, "subsamples", None),
              model_dir=getattr(a, "model", None))
    if voters is None:                                   # planes given: the depth search tells where the flames are
        given, held, op, rec = solve_given(lf, depths, a.search_range, **kw)
        if held is not None:
            extra["given_planes_held"] = found_record(held)
    else:
        voters, op, rec = solve_found(lf, voters, support=bool(getattr(a, "support", False)), **kw)
        depths = [float(d) for d in voters.planes_mm]      # after the residual's search and the refinement
        extra["found_depths"] = found_record(voters)
        arrays = dict(found_masks=np.asarray(voters.masks, bool), found_regions=voters.labels)
        extra["possible_depths"] = possible_warning(voters)
    fitted = _fitted_light_field(lf, kw["saturation"])
    rec, lattice = lattice_solve(fitted, op, rec, voters if voters is not None else held,
                                 bool(getattr(a, "support", False)))
    if rec.settings.get("support") == "near planes":
        from ..tomo.found_planes import NEAR_PARALLAX
        print(f"planes within {NEAR_PARALLAX:g} lenslets of parallax of each other are held to the regions their "
              "depths were found in, where they meet (the data barely tell such planes apart)")
    print("\n".join(left_out_notes(fitted, rec, lattice)))
    extra.update(solve_warnings(lf, op, rec, lattice, kw["saturation"], fitted, found=given))
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
    print(f"reconstructed {planes_count(len(depths))} ({rec.solver}, {iterations_note(rec)}{grid}) in {route_s:.2f} s "
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


def decoded_record(lf) -> dict:
    """What a file of decoded views' planes records of the real camera: its camera, the decoded frame (the planes'
    rotation and offset in the real object space: positions are in that frame), the clipped samples and the camera
    file; {} for a light field that is not decoded."""
    if not lf.decoded:
        return {}
    out = dict(own_camera=lf.capture_camera.to_json(), frame=lf.frame.to_dict(),
               n_clipped=0 if lf.leave_out is None else int(lf.leave_out.sum()))
    return {**out, "camera_file": lf.camera_file} if lf.camera_file else out


def _outside_stack_note(scene, depths_mm, step: float) -> str:
    """Where the scene's light lies beyond the stack (more than half a step past its ends), the share of it, for the
    score's line: the truth puts that light on the end planes (:func:`lf_flame.tomo.truth.depth_shares`), so the score
    is of a truth redrawn to fit the stack (a stack 15 mm from the flame had scored 0.756, as one over it 0.765)."""
    light = np.array([float(np.sum(layer.radiance, dtype=np.float64)) for layer in scene.layers])
    out = np.array([not (min(depths_mm) - step / 2 <= layer.depth_offset_mm <= max(depths_mm) + step / 2)
                    for layer in scene.layers])
    share = float(light[out].sum() / light.sum()) if light.sum() > 0 else 0.0
    return "" if share == 0 else (f" ({100 * share:.0f} % of the scene's light lies beyond the stack: scored on its end "
                                  "planes, as if there)")


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
        raise ValueError(f"--from {a.near:g} --to {a.far:g}: this camera refocuses {lo:+.4g} .. {hi:+.4g} mm from its "
                         "focus distance")
    fitted = _fitted_light_field(lf, getattr(a, "saturation", "file"))
    step = VOLUME_STEP_MM if a.step is None else a.step
    rec, extra = solve_volume(views, cam, a.near, a.far, step, a.prior, saturation=fitted.fit_mask(), unit=fitted.unit,
                              tv=a.tv, l1=a.l1, progress=True, white_normalised=lf.white_normalised,
                              interpolation=lf.interpolation)
    res, axi, op = extra["resolution"], extra["axisymmetric"], extra["operator"]
    table = res.to_frame()
    arrays = {} if axi is None else dict(emission_r_y=axi.emission, radii_mm=axi.radii_mm, heights_mm=axi.heights_mm)
    out = Path(a.out)
    edge = edge_warning(rec, op, modelled=axi is not None and axi.beyond_field, stack=axi is None)
    ends = stack_end_warning(rec, resolved_spacing_mm(table, res.conditions[0]))
    misfit = misfit_warning(lf, op, rec, getattr(a, "saturation", "file"))
    save_reconstruction(out, rec, arrays, source=str(a.raw), camera=cam.to_json(), volume=True,
                        depth_resolution=table.to_dict("list"), edge_share=edge, stack_end_share=ends, misfit=misfit,
                        operator="exact" if lf.interpolation is None else "exact, with decoding's interpolation",
                        **decoded_record(lf))
    scene, truth = _scene_truth(a.raw, lf, op)
    fig = _figure_path(a)
    if fig is not None:
        refocused = focal_stack(views, [cam.slope_for_depth(d) for d in rec.depths_mm],
                                aperture_mask(cam.pixels_per_lenslet, "circular"))
        plot_reconstruction(fig, rec, refocused, truth, title=f"volume, prior {a.prior}: {len(rec.depths_mm)} "
                            f"planes every {step:g} mm, {rec.time_s:.1f} s")
    axis = "" if axi is None else f"; axis at x {axi.axis_x_mm:+.2f} mm, depth {axi.axis_z_mm:+.2f} mm"
    score = "" if truth is None else (f"; against the scene's truth: 3-D relative error "
                                      f"{np.linalg.norm(rec.planes - truth) / np.linalg.norm(truth):.3f}"
                                      + _outside_stack_note(scene, rec.depths_mm, step))
    print(f"volume of {len(rec.depths_mm)} planes from {rec.depths_mm[0]:+g} to {rec.depths_mm[-1]:+g} mm every "
          f"{step:g} mm, prior "
          f"{a.prior} ({rec.solver}), solved in {rec.time_s:.1f} s{axis}{score} -> {out}"
          + ("" if fig is None else f", {fig}"))
    print(resolution_note(table, res.conditions[0], float(rec.depths_mm[-1] - rec.depths_mm[0])))
    if axi is not None:
        axis_depth_warning(axi)


def axis_depth_warning(axi) -> None:
    """Where the axisymmetric prior searched its axis's depth about a found depth less certain than the search is
    wide (:attr:`lf_flame.tomo.axisymmetric.AxisymmetricVolume.start_uncertainty_mm`): one warning (stderr) that the
    axis depth is known no better than that uncertainty."""
    from ..tomo.axisymmetric import SEARCH_HALF_WIDTH_MM
    u = axi.start_uncertainty_mm
    if u > SEARCH_HALF_WIDTH_MM:
        print(f"warning: the axis's depth {axi.axis_z_mm:+.2f} mm was searched within {SEARCH_HALF_WIDTH_MM:g} mm of "
              f"the flame's found depth, itself uncertain by +-{u:.2g} mm on this camera: the axis depth is known no "
              "better than that (the residual's minima there follow the planes' spacing, not the flame)",
              file=sys.stderr)


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
    s.add_argument("--depth", type=finite, action="append",
                   help="plane depth (mm from the focal plane; repeatable). Default: --depths auto")
    s.add_argument("--depths", default=None,
                   help="the planes: 'auto' (the default when neither --depth nor --slope is given) finds the depths "
                        "that hold emission from the views (depth from focus per region, several per region where "
                        "flames stand one behind another; lf_flame.tomo.depth) and solves on them, with admm unless "
                        "--solver says otherwise, writing each found depth and its uncertainty into the HDF5; "
                        "'scene': the depths of the objects that 'lf-flame simulate' stored (.npz or .png); 'paper': "
                        "the paper's four planes, " + ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) + " mm; or "
                        "depths in mm separated by commas")
    s.add_argument("--slope", type=finite, action="append", help="plane slope instead of a depth (repeatable)")
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
    s.add_argument("--damp", type=finite, default=0.0, help="LSQR damping (Tikhonov)")
    s.add_argument("--tv", type=finite, default=None, help=f"TV weight of pd-tv (default: {DEFAULT_TV}) or of admm "
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
    s.add_argument("--from", dest="near", type=finite, help="--volume: the nearest plane (mm)")
    s.add_argument("--to", dest="far", type=finite, help="--volume: the farthest plane (mm)")
    s.add_argument("--step", type=finite, default=None, help=f"--volume: plane spacing (mm; at most "
                   f"{VOLUME_MAX_PLANES} planes; default {VOLUME_STEP_MM:g}: finer than a flame, whatever the camera)")
    s.add_argument("--prior", choices=list(VOLUME_PRIORS), default=VOLUME_PRIOR,
                   help=f"--volume: none (admm by the data's noise), tv (admm with TV per plane, weight --tv, "
                        f"default {VOLUME_TV['quiet']:g} on quiet data, {VOLUME_TV['noisy']:g} on noisy), sparse (admm "
                        f"with an l1 weight, --l1, default {VOLUME_L1['quiet']:g} of the weight that zeroes every "
                        f"plane), axisymmetric (a laminar flame's e(r, y) about a vertical axis found from the data: "
                        f"for laminar flames)")
    s.add_argument("--l1", type=finite, default=None, help="--volume --prior sparse: the l1 weight in [0, 1)")
    s.add_argument("--out", required=True, help="volume.h5 (planes, depths, mm per sample, settings, residuals); "
                                               "the figure goes beside it as .png")
    add_figure_arg(s, "each plane beside its refocused plane and, for a simulated scene, the truth")
    add_search_arg(s)
    s.set_defaults(func=cmd_reconstruct)
