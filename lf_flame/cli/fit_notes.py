"""What a solve leaves out and what to make of it, one line each: the samples left out of the fit (clipped,
defective, dark), the emission at the field's edge, the misfit, the black level, a stack's depth resolution.
"""
from __future__ import annotations

import math
import sys

import numpy as np

from .planes import _fitted_light_field


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


def edge_warning(rec, op, modelled: bool = False, stack: bool = False, skip=None):
    """Each plane's share of its emission within :data:`~lf_flame.tomo.solvers.EDGE_BAND_LENSLETS` of the field's
    edge (:func:`~lf_flame.tomo.solvers.edge_shares`), for the file; where a plane's exceeds
    :data:`~lf_flame.tomo.solvers.EDGE_SHARE_WARN` and its brightest sample there reaches
    :data:`~lf_flame.tomo.solvers.EDGE_BODY` of its brightest (:func:`~lf_flame.tomo.solvers.edge_shares`' ``peak``: its own
    flame's body, not another's stray light; planes holding less than
    :data:`~lf_flame.tomo.solvers.EDGE_PLANE_FLOOR` of the brightest plane's light left out: a few stray samples
    there are most of such a plane's light), one warning (stderr) naming those planes, or with ``modelled``
    (the axisymmetric prior's light from beyond the field) a note that it was modelled. ``stack``: a dense stack's
    planes, on which the warning also names light the solve spread over planes far from any flame. ``skip``: bool
    per plane, planes left out of the warning (given planes where no flame stands, :func:`no_flame_warning`)."""
    from ..tomo.solvers import EDGE_BAND_LENSLETS, EDGE_BODY, EDGE_PLANE_FLOOR, EDGE_SHARE_WARN, edge_shares
    s = getattr(op, "subsamples", 1)
    edge = [float(v) for v in edge_shares(rec.planes, s)]
    light = np.clip(np.asarray(rec.planes, np.float64), 0, None).sum(axis=(1, 2))
    lit = light >= EDGE_PLANE_FLOOR * light.max() if light.max() > 0 else np.zeros(len(light), bool)
    lit &= edge_shares(rec.planes, s, peak=True) >= EDGE_BODY
    if skip is not None:
        lit &= ~np.asarray(skip, bool)
    cut = [(d, e) for d, e, keep in zip(rec.depths_mm, edge, lit) if e > EDGE_SHARE_WARN and keep]
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


#: A dense stack's first or last plane holding at least this share of its brightest plane's light: the flame reaches
#: past the stack's end (:func:`stack_end_warning`). Volumes inside their stacks put 0 there with the axisymmetric
#: prior and 0.21-0.29 of the brightest without one (the volume guide's scenes, a new user's walk-through); a flame
#: 10 mm across whose axis stood 2 mm inside the stack's end put 0.98 (axisymmetric) and 1.0 (none).
STACK_END_WARN = 0.5


def resolved_spacing_mm(table, condition: float) -> float:
    """The finest plane spacing (mm) that a stack's data resolve for any feature size of its depth-resolution table
    (:meth:`DepthResolution.to_frame <lf_flame.tomo.resolution.DepthResolution.to_frame>`, at ``condition``); inf
    where none within the stack is."""
    s = np.asarray(table[f"spacing_interp_mm_{condition:g}"], np.float64)
    s = s[~np.isnan(s)]
    return float(s.min()) if len(s) else math.inf


def stack_end_warning(rec, resolved_mm: float | None = None) -> dict:
    """A dense stack's end planes' light over its brightest plane's (``{"near": ..., "far": ...}``, for the file);
    where one is at least :data:`STACK_END_WARN`, one warning (stderr): the flame reaches past that end, and the
    stack should run further; or, where the stack's data resolve no spacing finer than half its span
    (``resolved_mm``, :func:`resolved_spacing_mm`: a camera of little parallax per millimetre), that its light
    spreads along the stack whatever its length, and what gives the depth there."""
    light = np.clip(np.asarray(rec.planes, np.float64), 0, None).sum(axis=(1, 2))
    top = light.max()
    span = float(rec.depths_mm[-1] - rec.depths_mm[0])
    share = {name: float(light[k] / top) if top > 0 else 0.0 for name, k in (("near", 0), ("far", -1))}
    if resolved_mm is not None and resolved_mm > 0.5 * span and max(share.values()) >= STACK_END_WARN:
        said = "no spacing within the stack" if math.isinf(resolved_mm) else f"{resolved_mm:.3g} mm apart at best"
        print(f"warning: the stack's ends hold {100 * share['near']:.0f} % and {100 * share['far']:.0f} % of its "
              f"brightest plane's light, and this camera's data over the stack's {span:g} mm resolve {said} (the "
              "depth resolution below): without a prior the light spreads along the stack whatever its length; the "
              "axisymmetric prior (--prior axisymmetric) models a flame of revolution, and the found planes "
              "(reconstruct without --volume) a few flames", file=sys.stderr)
        return share
    for name, k, flag in (("near", 0, "--from"), ("far", -1, "--to")):
        if share[name] >= STACK_END_WARN:
            print(f"warning: the stack's {name} end ({rec.depths_mm[k]:+g} mm) holds {100 * share[name]:.0f} % of its "
                  "brightest plane's light: the flame reaches past it, and its light beyond is not recovered (the "
                  f"volume and any axis found are off); run the stack further ({flag})", file=sys.stderr)
    return share


#: :func:`misfit_warning` suggests more fills where admm's residual fell by at least this share over its last fill.
STILL_FALLING = 0.02


def misfit_warning(lf, op, rec, saturation="file", lattice=None):
    """The solve's misfit on the light field's data as it was fitted (:func:`lf_flame.tomo.solvers.data_misfit`;
    a :class:`~lf_flame.tomo.lattice.LatticeSolve` on its lattice's), for the file; where it is high
    (:func:`~lf_flame.tomo.solvers.misfit_is_high`), one warning (stderr) saying what it means, and where admm
    ran every fill of its cap with its residual still falling (by :data:`STILL_FALLING` or more over the last fill,
    or too few fills to tell), that more fills may explain more (where it had levelled off or risen, more fills had
    made a user's misfit worse: 0.585 at 2 fills, 0.719 at 20)."""
    from ..tomo.decoded import fit_data
    from ..tomo.solvers import data_misfit, misfit_is_high
    if lattice is not None:
        m = data_misfit(lattice.data, lattice.op, lattice.rec.planes, lattice.leave_out)
    else:
        data, fit = fit_data(_fitted_light_field(lf, saturation), op)
        m = data_misfit(data, op, rec.planes, fit)
    if misfit_is_high(m):
        r = np.asarray(rec.residuals, float)
        capped = rec.solver == "admm" and int(rec.settings.get("fills_run", 0)) >= int(rec.settings["iters"]) and \
            (len(r) < 2 or r[-1] < (1.0 - STILL_FALLING) * r[-2])
        print(f"warning: the planes leave {100 * m['misfit']:.0f} % of the light field unexplained beyond its noise "
              f"(relative residual {m['relative_residual']:.3f}, of which noise {m['noise_share']:.3f}): light "
              "from flames off these planes or beyond the field, or a camera file that is not this camera's"
              + ("; a colour capture levelled into one light field keeps its flames' colour variation (their red "
                 "samples differ from green's), part of this" if "monochrome" in lf.meta else "")
              + (f"; admm stopped at its fills' cap ({int(rec.settings['iters'])}) without settling: more fills "
                 "(--iters) may explain more" if capped else "") + black_level_note(lf, op), file=sys.stderr)
    return m


def solve_warnings(lf, op, rec, lattice=None, saturation="file", fitted=None, found=None) -> dict:
    """A solve's warnings, as ``reconstruct`` and ``profiles`` give them: the capture's clipped share
    (:func:`lf_flame.cli.real.overexposure_warning`, of ``fitted``: the light field as fitted, else ``lf``), the
    misfit (:func:`misfit_warning`), emission at the field's edge (:func:`edge_warning`) and, for planes the user gave,
    those where the depth search (``found``, :func:`lf_flame.cli.planes.given_planes_search`; None: not run or no
    emission found) finds no flame and the data need none (:func:`planes_without_flame`, :func:`no_flame_warning`;
    left out of the edge's warning). Returns their records: ``clipped_share``, ``edge_share``, ``misfit`` and, with
    ``found``, ``planes_without_flame``."""
    from .real import overexposure_warning
    clipped = overexposure_warning((lf if fitted is None else fitted).over_exposure())
    return dict(clipped_share=clipped, **plane_warnings(lf, op, rec, lattice, saturation, found))


def plane_warnings(lf, op, rec, lattice=None, saturation="file", found=None) -> dict:
    """What :func:`solve_warnings` says of the planes themselves, and ``temperature`` of its levelled light field's
    (:func:`lf_flame.cli.temperature_planes.fit_warnings`): the misfit (:func:`misfit_warning`), emission at the field's
    edge (:func:`edge_warning`) and, with ``found`` (planes the user gave), the planes without a flame
    (:func:`planes_without_flame`, :func:`no_flame_warning`; left out of the edge's warning). Returns ``misfit``,
    ``edge_share`` and, with ``found``, ``planes_without_flame``."""
    out = dict(misfit=misfit_warning(lf, op, rec, saturation, lattice))
    without = None if found is None else planes_without_flame(lf, rec, found, out["misfit"], saturation)
    out["edge_share"] = edge_warning(rec, op, skip=without)
    if found is not None:
        out["planes_without_flame"] = no_flame_warning(rec.planes, rec.depths_mm, found, without)
    return out


#: A plane given where the depth search finds no flame is warned of only where the data need no flame there: solved
#: again without it, the squared relative residual rises by less than this share of the fitted light field's energy.
#: On validation scenes (``experiments/depth.py``'s validation seeds, the paper camera, 64 rays per pixel, noise-free
#: and 14 dB; a ``/tmp`` probe) the planes of flames the votes miss behind others (30 column scenes: 12 of their 78
#: flames, 24 planes over both noise levels) rose by 0.0009-0.047; planes far from every flame or midway in the
#: widest gap between two (20 random-depth scenes, 31 planes, 62 over both noise levels) by at most 0.0001 noise-free
#: and 0.0005 at 14 dB but for one (0.0026: 6 mm from a flame 18 mm tall, whose misfit it took up). So no hidden flame
#: is warned of, and 61 of the 62 empty planes are (their share of the planes' light 0-3.5 %, the hidden flames'
#: 4.5-25 %).
NO_FLAME_EXPLAINED = 7e-4


def planes_without_flame(lf, rec, found, misfit, saturation="file") -> np.ndarray:
    """Which planes of a solve on planes the user gave hold no flame: the depth search (``found``) finds none within
    :data:`~lf_flame.tomo.found_planes.NEAR_PARALLAX` lenslets of parallax
    (:func:`lf_flame.tomo.found_planes.planes_without_flames`), and the data need none there: solved again without
    the plane (:func:`lf_flame.cli.planes.run_reconstruction`, the same solver at its default knobs; near planes held
    as the solve held them), the squared relative residual rises by less than :data:`NO_FLAME_EXPLAINED` over ``misfit``'s (the
    solve's :func:`~lf_flame.tomo.solvers.data_misfit` record). The votes of the search miss a flame hidden behind
    another, whose plane the data do need. Bool per plane."""
    from ..tomo.decoded import fit_data
    from ..tomo.defaults import SOLVERS
    from ..tomo.found_planes import planes_without_flames
    from ..tomo.solvers import data_misfit
    from .planes import given_planes_held, run_reconstruction
    depths = [float(d) for d in rec.depths_mm]
    without = planes_without_flames(found, lf.camera, depths)
    if rec.solver not in SOLVERS or len(depths) < 2:        # nothing to solve again (a learned one, a single plane)
        return without
    fitted = _fitted_light_field(lf, saturation) if without.any() else None
    for k in np.flatnonzero(without):
        rest = depths[:k] + depths[k + 1:]
        op, again = run_reconstruction(lf, rest, rec.solver, saturation=saturation,
                                       found_depths=given_planes_held(found, lf.camera, rest))
        data, fit = fit_data(fitted, op)
        r = data_misfit(data, op, again.planes, fit)["relative_residual"]
        without[k] = r ** 2 - misfit["relative_residual"] ** 2 < NO_FLAME_EXPLAINED
    return without


def no_flame_warning(planes, depths_mm, found, without) -> list:
    """Planes given where the depth search finds no flame (``without``, bool per plane:
    :func:`lf_flame.tomo.found_planes.planes_without_flames` of ``found``): one warning (stderr) naming them, each with
    its share of the planes' light, and the depths found; what a solve puts on such a plane is other flames' light,
    defocused (a plane given at +5 mm between flames at -5.5 and +16.5 mm held 3.7 % of the planes' light, which
    ``profiles`` had measured as a flame 15 mm tall, cut by the field's edge), unless a flame hides there behind
    another (the votes of the search do not find such flames, the solve's residual does:
    :func:`lf_flame.tomo.refine.peel_and_refine`). Returns those planes' depths (mm), for the file."""
    idx = np.flatnonzero(np.asarray(without, bool))
    if not len(idx):
        return []
    light = np.clip(np.asarray(planes, np.float64), 0, None).sum(axis=(1, 2))
    total = light.sum() or 1.0
    which = ", ".join(f"{depths_mm[k]:+.2f} mm ({100 * light[k] / total:.1f} % of the planes' light)" for k in idx)
    print(f"warning: the depth search finds no flame near the plane{'s' * (len(idx) > 1)} at {which}: what "
          f"{'they hold' if len(idx) > 1 else 'it holds'} is likely other flames' light, defocused (or a flame hidden "
          "behind another, which --depths auto also seeks in the solve's residual); it finds flames at "
          + ", ".join(f"{d:+.2f}" for d in found.depths_mm) + " mm (give those depths, or --depths auto)",
          file=sys.stderr)
    return [float(depths_mm[k]) for k in idx]


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
