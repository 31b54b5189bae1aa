"""The ``reconstruct`` command: each plane's emission from one light field
(:mod:`lf_flame.tomo`), written to HDF5 with a figure.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ._io import _load_views, _raw_objects, _raw_scene


def reconstruct_input(a):
    """Camera, views, depths (mm) and flame objects (or None) of ``reconstruct``/``profiles``."""
    from ..optics.camera import PAPER_CAMERA
    from ..simulate.scenes import PAPER_DEPTHS_MM
    views, cam = _load_views(a.raw)
    cam = cam or PAPER_CAMERA
    if views.shape[2:] != (cam.n_rows, cam.n_cols):
        raise ValueError(f"{a.raw}: views of {views.shape[2]} x {views.shape[3]} lenslets, but the camera (the "
                         f"paper's when the file stores none: PNG, TIFF, .npy, decoded views) has {cam.n_rows} x "
                         f"{cam.n_cols}; give the .npz that 'lf-flame simulate' writes, which stores its camera")
    objects = _raw_objects(a.raw)
    if getattr(a, "depth", None) and getattr(a, "slope", None):
        raise ValueError("give the planes as --depth or as --slope, not both")
    if getattr(a, "depth", None):
        depths = list(a.depth)
    elif getattr(a, "slope", None):
        depths = [cam.depth_for_slope(s) for s in a.slope]
    elif objects and all("depth_offset_mm" in o for o in objects):
        depths = [float(o["depth_offset_mm"]) for o in objects]
    else:
        depths = list(PAPER_DEPTHS_MM)
    return cam, views, depths, objects


def run_reconstruction(cam, views, depths, solver, iters=None, *, damp=0.0, tv=None, saturation=1.0,
                       rays_per_pixel=None, progress=False):
    """Build the operator of ``cam`` at ``depths`` (:func:`lf_flame.tomo.exact.emission_operator`:
    exact unless ``rays_per_pixel`` is given or the camera needs tracing) and solve
    (:func:`lf_flame.tomo.solvers.reconstruct`)."""
    from ..tomo.exact import emission_operator
    from ..tomo.solvers import reconstruct
    op = emission_operator(cam, depths, rays_per_pixel=rays_per_pixel)
    return op, reconstruct(views, op, solver, iters, damp=damp, tv=tv, saturation=saturation, progress=progress)


def saturation_note(rec) -> str:
    """What the fit left out: the count of saturated pixels (``reconstruct``'s settings)."""
    level, n = rec.settings.get("saturation"), rec.settings.get("n_saturated", 0)
    if level is None:
        return "saturation: none given, every pixel fitted"
    if rec.solver == "adjoint":   # no fit: the adjoint carries every pixel back as it is
        return f"{n} saturated pixels (at or above {level:g}), used as they are by the adjoint"
    return f"{n} saturated pixels (at or above {level:g}) left out of the fit"


def cmd_reconstruct(a):
    from ..tomo.files import plot_reconstruction, save_reconstruction
    from ..tomo.truth import scene_truth
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    cam, views, depths, objects = reconstruct_input(a)
    op, rec = run_reconstruction(cam, views, depths, a.solver, a.iters, damp=a.damp, tv=a.tv,
                                 saturation=a.saturation, rays_per_pixel=a.rays_per_pixel, progress=True)
    print(saturation_note(rec))
    out = Path(a.out)
    save_reconstruction(out, rec, source=str(a.raw), camera=cam.to_json())
    n = cam.pixels_per_lenslet
    refocused = focal_stack(views, [cam.slope_for_depth(d) for d in depths], aperture_mask(n, "circular"))
    scene = _raw_scene(a.raw, cam)
    truth = None if scene is None else scene_truth(scene, op)
    fig = out.with_suffix(".png")
    plot_reconstruction(fig, rec, refocused, truth)
    res = f"{rec.residuals[-1]:.4f}" if len(rec.residuals) else "-"
    print(f"reconstructed {len(depths)} planes ({a.solver}, {rec.settings['iters']} iterations) in {rec.time_s:.2f} s;"
          f" relative residual {res} -> {out}, {fig}" + ("" if truth is None else " (with the scene's truth)"))
