"""The ``reconstruct`` command: each plane's emission from one light field
(:mod:`lf_flame.tomo`), written to HDF5 with a figure. Without planes given (``--depths auto``)
the depths holding emission are found first (:mod:`lf_flame.tomo.depth`).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ._io import _load_views, _raw_objects, _raw_scene

#: ``reconstruct --camera``: the solver and iterations on a user's camera's exact operator.
#: FISTA's worst plane on the decoded views of ``examples/own_camera.toml`` is flat from 75
#: iterations on (7.9 %); at the 30 of the traced operator's default its in-focus plane is
#: still 7.9 % off, 1.9 % at 100 (``results/own_camera.md``, ``docs/own_camera.md``).
OWN_CAMERA_SOLVER = "fista"
OWN_CAMERA_ITERS = {"fista": 100}


def reconstruct_input(a):
    """Camera, views, depths (mm) and flame objects (or None) of ``reconstruct``/``profiles``."""
    from ..optics.camera import PAPER_CAMERA
    from ..simulate.scenes import PAPER_DEPTHS_MM
    views, cam = _load_views(a.raw)
    cam = cam or PAPER_CAMERA
    if views.shape[2:] != (cam.n_rows, cam.n_cols):
        raise ValueError(f"{a.raw}: views of {views.shape[2]} x {views.shape[3]} lenslets, but the camera (the "
                         f"paper's when the file stores none: PNG, TIFF, .npy, decoded views) has {cam.n_rows} x "
                         f"{cam.n_cols}; give the .npz that 'lf-flame simulate' writes, which stores its camera, or, "
                         "for views decoded by 'lf-flame decode', their camera file (--camera cam.toml)")
    objects = _raw_objects(a.raw)
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
        depths = [float(o["depth_offset_mm"]) for o in objects]
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
    return cam, views, depths, objects


def found_planes(cam, views):
    """``--depths auto``: the depths holding emission (:func:`lf_flame.tomo.depth.find_depths`), printed,
    and their record for the HDF5 (each found depth, its uncertainty, peak width, plane and region)."""
    from ..tomo.depth import find_depths
    found = find_depths(views, cam)
    if not len(found.planes_mm):
        raise ValueError("--depths auto found no emission in the views; give the planes (--depth or --depths)")
    record = [dict(depth_mm=float(d), uncertainty_mm=float(u), width_mm=float(w), plane_mm=float(found.planes_mm[p]),
                   region=int(r), lenslets=int(m.sum()))
              for d, u, w, p, r, m in zip(found.depths_mm, found.uncertainty_mm, found.width_mm, found.plane_of,
                                          found.region, found.masks)]
    print(f"found {len(record)} depths in {found.time_s:.2f} s: " + ", ".join(
        f"{r['depth_mm']:+.2f} +- {r['uncertainty_mm']:.2f} mm" for r in record)
        + f" -> {len(found.planes_mm)} planes")
    return [float(d) for d in found.planes_mm], record


def run_reconstruction(cam, views, depths, solver=None, iters=None, *, damp=0.0, tv=None, saturation=1.0,
                       rays_per_pixel=None, progress=False, subsamples=None):
    """Build the operator of ``cam`` at ``depths`` (:func:`lf_flame.tomo.exact.emission_operator`:
    exact unless ``rays_per_pixel`` is given or the camera needs tracing) and solve
    (:func:`lf_flame.tomo.solvers.reconstruct`; solver None: the operator's default). The
    exact operator's grid: ``subsamples`` samples per lenslet; None: admm's
    (:func:`lf_flame.tomo.fourier.admm_subsamples`), 1 for the other solvers."""
    from ..tomo.defaults import EXACT_SOLVER
    from ..tomo.exact import emission_operator
    from ..tomo.fourier import admm_subsamples
    from ..tomo.solvers import reconstruct
    if subsamples is None:
        admm = rays_per_pixel is None and (solver or EXACT_SOLVER) == "admm"
        subsamples = admm_subsamples(len(depths)) if admm else 1
    op = emission_operator(cam, depths, rays_per_pixel=rays_per_pixel, subsamples=subsamples)
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
    if getattr(a, "volume", False):
        return volume_reconstruct(a)
    given = [f"--{k}" for k, n in (("from", "near"), ("to", "far"), ("l1", "l1")) if getattr(a, n, None) is not None]
    if given:
        raise ValueError(" and ".join(given) + " go with --volume")
    if getattr(a, "camera", None):
        return own_camera_reconstruct(a)
    if getattr(a, "calibration", None):
        raise ValueError("--calibration goes with --camera (views decoded from your own camera)")
    cam, views, depths, objects = reconstruct_input(a)
    extra = {}
    if depths == "auto":
        depths, found = found_planes(cam, views)
        extra = dict(depths_from="auto", found_depths=found)
    op, rec = run_reconstruction(cam, views, depths, a.solver, a.iters, damp=a.damp, tv=a.tv,
                                 saturation=getattr(a, "saturation", 1.0), rays_per_pixel=a.rays_per_pixel,
                                 progress=True, subsamples=getattr(a, "subsamples", None))
    print(saturation_note(rec))
    out = Path(a.out)
    save_reconstruction(out, rec, source=str(a.raw), camera=cam.to_json(), **extra)
    n = cam.pixels_per_lenslet
    refocused = focal_stack(views, [cam.slope_for_depth(d) for d in depths], aperture_mask(n, "circular"))
    sub = getattr(op, "subsamples", 1)
    refocused = np.repeat(np.repeat(refocused, sub, axis=1), sub, axis=2)      # on the planes' grid
    scene = _raw_scene(a.raw, cam)
    truth = None if scene is None else scene_truth(scene, op)
    fig = out.with_suffix(".png")
    plot_reconstruction(fig, rec, refocused, truth)
    res = f"{rec.residuals[-1]:.4f}" if len(rec.residuals) else "-"
    grid = f", {sub} x {sub} samples per lenslet" if sub > 1 else ""
    print(f"reconstructed {len(depths)} planes ({rec.solver}, {rec.settings['iters']} iterations{grid}) in "
          f"{rec.time_s:.2f} s;"
          f" relative residual {res} -> {out}, {fig}" + ("" if truth is None else " (with the scene's truth)"))


def _same_grid(c1, c2) -> bool:
    """Two calibrations of one lenslet grid (the fitted lattice and the decoded grid)."""
    return (c1.layout == c2.layout and tuple(c1.sensor_shape) == tuple(c2.sensor_shape)
            and (c1.n_rows, c1.n_cols) == (c2.n_rows, c2.n_cols)
            and np.allclose([c1.pitch_px, c1.rotation_deg, *c1.origin_px],
                            [c2.pitch_px, c2.rotation_deg, *c2.origin_px], rtol=0, atol=1e-9))


def own_camera_reconstruct(a):
    """``reconstruct VIEWS.h5 --camera cam.toml [--calibration cal.json]``: the exact operator of the
    decoded views' camera (:func:`lf_flame.real.own_camera.views_camera`), the views as its data with
    their clipped samples left out (:func:`lf_flame.tomo.decoded.decoded_problem`), then the solver."""
    from ..optics.camera_file import load_camera_file
    from ..real.calibration import GridCalibration
    from ..real.decoding import load_clipped, load_views
    from ..real.own_camera import decoded_frame, views_camera
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    from ..tomo.decoded import decoded_problem
    from ..tomo.exact import ExactOperator
    from ..tomo.files import plot_reconstruction, save_reconstruction
    from ..tomo.solvers import reconstruct
    src = str(a.raw)
    if not src.endswith(".h5") or ".h5:" in src:
        raise ValueError(f"--camera reconstructs views decoded by 'lf-flame decode' (VIEWS.h5), not {src}")
    views, cal = load_views(src)
    if a.calibration and not _same_grid(GridCalibration.load(a.calibration), cal):
        raise ValueError(f"{src} was decoded with another calibration than {a.calibration}")
    cam = load_camera_file(a.camera)
    vcam = views_camera(cam, cal, views.shape)
    frame = decoded_frame(cal, *views.shape[2:])
    if getattr(a, "depth", None) and getattr(a, "slope", None):
        raise ValueError("give the planes as --depth or as --slope, not both")
    if getattr(a, "depths", None):
        raise ValueError("with --camera give the planes as --depth or --slope (--depths is for simulated light fields)")
    if getattr(a, "depth", None):
        depths = list(a.depth)
    elif getattr(a, "slope", None):
        depths = [vcam.depth_for_slope(s) for s in a.slope]
    else:
        raise ValueError("with --camera give the planes (--depth mm from the focus distance, or --slope): the "
                         "paper's depths belong to its camera")
    level = getattr(a, "saturation", "file")
    if level not in ("file", None):
        raise ValueError("with --camera, --saturation takes only 'none' (fit every sample): decoded views carry "
                         "their clipped samples (give the sensor's level to 'lf-flame decode --saturation')")
    clipped = None if level is None else load_clipped(src)
    solver = a.solver or OWN_CAMERA_SOLVER
    iters = a.iters if a.iters is not None else OWN_CAMERA_ITERS.get(solver)   # None: the solver's default
    op = ExactOperator(vcam, depths)
    data, leave = decoded_problem(views, op, clipped)
    rec = reconstruct(data, op, solver, iters, damp=a.damp, tv=a.tv, saturation=leave, progress=True)
    n_clip = 0 if clipped is None else int(clipped.sum())
    print(("no clipped samples recorded (decoded without a level, or 'none')" if clipped is None else
           f"{n_clip} samples from clipped pixels") + f"; {int(leave.sum())} samples left out of the fit (clipped, "
          f"or outside the aperture's image){' but used by the adjoint' if solver == 'adjoint' else ''}")
    out = Path(a.out)
    save_reconstruction(out, rec, source=src, camera=vcam.to_json(), own_camera=cam.to_json(),
                        camera_file=str(Path(a.camera).resolve()), frame=frame.to_dict(), operator="exact",
                        n_clipped=n_clip)
    refocused = focal_stack(views, [vcam.slope_for_depth(d) for d in depths], aperture_mask(vcam.pixels_per_lenslet,
                                                                                           "circular"))
    fig = out.with_suffix(".png")
    plot_reconstruction(fig, rec, refocused, None)
    res = f"{rec.residuals[-1]:.4f}" if len(rec.residuals) else "-"
    print(f"reconstructed {len(depths)} planes of {src} with its camera's exact operator ({solver}, "
          f"{rec.settings['iters']} iterations) in {rec.time_s:.2f} s; relative residual {res} -> {out}, {fig}")


def volume_reconstruct(a):
    """``reconstruct RAW --volume --from MM --to MM [--step MM] [--prior P]``: a dense stack with a prior
    (:func:`lf_flame.tomo.volume.solve_volume`) -> HDF5 (the planes, their depths, the prior's settings, the
    stack's depth resolution; for the axisymmetric prior ``extra/emission_r_y`` with ``extra/radii_mm`` and
    ``extra/heights_mm``) and the figure (maxima, side view, slice and depth profile; with the truth where the
    scene is known)."""
    from ..refocus.shift_and_sum import aperture_mask, focal_stack
    from ..tomo.files import plot_reconstruction, save_reconstruction
    from ..tomo.truth import scene_truth
    from ..tomo.volume import solve_volume
    other = [f"--{k.replace('_', '-')}" for k in ("depth", "depths", "slope", "solver", "iters", "subsamples",
                                                  "rays_per_pixel", "camera", "calibration")
             if getattr(a, k, None) not in (None, False)]
    if other:
        raise ValueError(f"--volume solves its own stack (--from, --to, --step) with admm or the axisymmetric "
                         f"prior on the exact operator of a simulated light field; drop {', '.join(other)}")
    if a.near is None or a.far is None:
        raise ValueError("--volume needs the stack's ends: --from MM and --to MM (mm from the focal plane, > 0 "
                         "farther; 'lf-flame reconstruct RAW' without --volume finds the flames' depths)")
    cam, views, _, _ = reconstruct_input(a)
    rec, extra = solve_volume(views, cam, a.near, a.far, a.step, a.prior, saturation=getattr(a, "saturation", 1.0),
                              tv=a.tv, l1=a.l1, progress=True)
    res, axi, op = extra["resolution"], extra["axisymmetric"], extra["operator"]
    table = res.to_frame()
    arrays = {} if axi is None else dict(emission_r_y=axi.emission, radii_mm=axi.radii_mm, heights_mm=axi.heights_mm)
    out = Path(a.out)
    save_reconstruction(out, rec, arrays, source=str(a.raw), camera=cam.to_json(), volume=True,
                        depth_resolution=table.to_dict("list"))
    scene = _raw_scene(a.raw, cam)
    truth = None if scene is None else scene_truth(scene, op)
    refocused = focal_stack(views, [cam.slope_for_depth(d) for d in rec.depths_mm],
                            aperture_mask(cam.pixels_per_lenslet, "circular"))
    fig = out.with_suffix(".png")
    plot_reconstruction(fig, rec, refocused, truth, title=f"volume, prior {a.prior}: {len(rec.depths_mm)} planes "
                        f"every {a.step:g} mm, {rec.time_s:.1f} s")
    axis = "" if axi is None else f"; axis at x {axi.axis_x_mm:+.2f} mm, depth {axi.axis_z_mm:+.2f} mm"
    score = "" if truth is None else (f"; against the scene's truth: 3-D relative error "
                                      f"{np.linalg.norm(rec.planes - truth) / np.linalg.norm(truth):.3f}")
    print(f"volume of {len(rec.depths_mm)} planes from {rec.depths_mm[0]:+g} to {rec.depths_mm[-1]:+g} mm, prior "
          f"{a.prior} ({rec.solver}), solved in {rec.time_s:.1f} s{axis}{score} -> {out}, {fig}")
    c = res.conditions[0]
    span = float(rec.depths_mm[-1] - rec.depths_mm[0])
    apart = [f"> {span:g}" if np.isinf(s) else f"{s:.2g}" for s in table[f"spacing_interp_mm_{c:g}"]]
    print(f"depth resolution of this stack for the data alone (condition <= {c:g}; the prior adds what the data "
          "lack): " + ", ".join(f"{f:g} mm features {s} mm apart" for f, s in zip(table.feature_mm, apart)))
