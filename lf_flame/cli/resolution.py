"""The ``resolution`` command: the camera's depth-resolution map (:mod:`lf_flame.tomo.resolution`),
printed as a table and optionally written as CSV, Markdown and a figure.
"""
from __future__ import annotations

import time
from pathlib import Path
from ..tomo.resolution import AXES, CONDITIONS
from .options import finite


def wider_than_field(camera, feature_mm, axis: str) -> str | None:
    """A note naming the feature sizes whose period (twice the size) is longer than ``camera``'s field at its
    focal plane along the map's frequency (``axis``: rows, y; columns, x; diagonal, the shorter side), or None."""
    from ..measure.diagnostics import lenslet_size_mm
    n = {"rows": camera.n_rows, "columns": camera.n_cols}.get(axis, min(camera.n_rows, camera.n_cols))
    field = n * lenslet_size_mm(camera, 0.0)
    wide = [f for f in feature_mm if 2 * f > field]
    if not wide:
        return None
    return (f"note: features of {', '.join(f'{f:g}' for f in wide)} mm have a period longer than the field along the "
            f"{axis} ({field:.3g} mm at the focal plane, {n} lenslets): their rows say what the optics resolve, "
            "not what this field can hold")


def cmd_resolution(a):
    """Print the smallest resolvable plane spacing against feature size for the paper's camera
    or the camera file of ``--camera`` (its datasheet tables or a ``[camera]`` table,
    :func:`lf_flame.optics.camera_file.load_camera_file`); with ``--out PREFIX`` also write
    PREFIX.csv, PREFIX.md (table, settings, provenance) and PREFIX.png."""
    from ..config import atomic_write_text, provenance, to_json
    from ..optics.camera import PAPER_CAMERA
    from ..optics.camera_file import load_camera_file
    from ..real.own_camera import nominal_views_camera
    from ..tomo.resolution import depth_resolution, plot_depth_resolution, stack_depths, stack_settings
    t0 = time.perf_counter()
    camera = load_camera_file(a.camera) if a.camera else PAPER_CAMERA
    views = nominal_views_camera(camera)         # a real grid: the camera of its decoded views
    # the defaults: the paper camera's stack carried to this camera
    a.near, a.far, a.spacing, a.feature = stack_settings(views, a.near, a.far, a.spacing, a.feature)
    stack_depths(a.near, a.far, a.spacing)          # refuse a bad stack before computing anything
    res = depth_resolution(views, near_mm=a.near, far_mm=a.far, spacing_mm=a.spacing, feature_mm=a.feature,
                           conditions=a.condition, axis=a.axis)
    wall = time.perf_counter() - t0
    where = f"camera of {a.camera}" if a.camera else "the paper's camera"
    if views is not camera:
        where += (f" (its decoded views: {views.pixels_per_lenslet} x {views.pixels_per_lenslet} views of "
                  f"{views.n_rows} x {views.n_cols} lenslets at the optics' pitch, no calibration)")
    head = (f"Depth resolution of {where}: {res.depths_mm.size} planes every {a.spacing:g} mm from "
            f"{res.depths_mm[0]:+g} to {res.depths_mm[-1]:+g} mm, frequency along the {a.axis}; for each plane "
            "spacing, the condition number of the two "
            f"planes' normal block, median (worst) over positions across the stack. Data alone: no border, "
            f"no prior (optimistic).")
    print(head)
    print(res.markdown())
    wide = wider_than_field(views, a.feature, a.axis)
    if wide:
        print(wide)
    print(f"kernels {res.setup_s:.1f} s, map {res.map_s:.1f} s, wall {wall:.1f} s")
    if a.out:
        out = Path(a.out)
        atomic_write_text(out.with_name(out.name + ".csv"), res.to_frame().to_csv(index=False))
        settings = dict(camera=a.camera or "paper", near_mm=a.near, far_mm=a.far, spacing_mm=a.spacing,
                        feature_mm=list(a.feature), conditions=list(a.condition), axis=a.axis)
        atomic_write_text(out.with_name(out.name + ".md"),
                          f"# Depth resolution\n\n{head}\n\n{res.markdown()}\n" + (f"\n{wide}\n\n" if wide else "") +
                          f"Command: `lf-flame resolution` {to_json(settings)}\n\nCamera: `{to_json(views)}`\n\n"
                          f"Wall time {wall:.1f} s (kernels {res.setup_s:.1f} s, map {res.map_s:.1f} s).\n\n"
                          f"Provenance: `{to_json(provenance())}`\n")
        plot_depth_resolution(out.with_name(out.name + ".png"), res)
        print(f"wrote {out}.csv, {out}.md, {out}.png")


def add_parsers(sub) -> None:
    """Add ``resolution`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("resolution", help="the camera's depth-resolution map: the smallest plane spacing that "
                       "the light field resolves against feature size, at stated condition numbers (from the exact "
                       "operator's per-frequency normal matrices of a dense stack)")
    s.add_argument("--camera", help="camera file: the datasheet tables of docs/own_camera.md, or a [camera] table "
                   "(default: the paper's camera)")
    s.add_argument("--near", type=finite, help="nearest plane of the stack, mm from the focal plane (> 0 farther; "
                   "default: the paper camera's -15 mm carried to this camera at equal parallax across the aperture, "
                   "within what it refocuses)")
    s.add_argument("--far", type=finite, help="farthest plane, mm (default: the paper camera's +25 mm, carried so)")
    s.add_argument("--spacing", type=finite, help="the stack's plane spacing, mm (default: about 80 steps from --near "
                   "to --far, rounded to two digits, the last plane at or below --far; 0.5 mm on the paper's camera)")
    s.add_argument("--condition", type=finite, nargs="+", default=list(CONDITIONS),
                   help="condition numbers of the two planes' normal block (>= 1)")
    s.add_argument("--feature", type=finite, nargs="+", help="feature sizes, half a period, mm (default: the paper "
                   "camera's 0.33-6.6 mm, 2.5 to 50 of its lenslets at the focal plane, in this camera's lenslets)")
    s.add_argument("--axis", choices=list(AXES), default="rows", help="direction of the lateral frequency")
    s.add_argument("--out", help="PREFIX: also write PREFIX.csv, PREFIX.md and PREFIX.png (default: print only)")
    s.set_defaults(out_is_prefix=True)
    s.set_defaults(func=cmd_resolution)
