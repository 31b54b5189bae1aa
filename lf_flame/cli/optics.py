"""Commands of the simulated camera: ``simulate`` (:mod:`lf_flame.simulate.tracer`), ``refocus``
and ``slopes`` (:mod:`lf_flame.refocus.shift_and_sum`; without a raw image, the nominal scene's slope
calibration of a data config).
"""
from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from ._io import (COLOUR_SCENES, RAW_FORMATS, _raw_objects, _save_image, _write_stack, camera_config, colour_scene,
                  light_field, planes_count, render_sensor, save_npz, simulated_scene)
from .options import add_camera_args, add_search_arg, count, finite
from ..simulate.scenes import PAPER_DEPTHS_MM
from ..simulate.layers import MAX_BIT_DEPTH




def cmd_simulate(a):
    from ..simulate import tracer as simulate
    from ..optics.camera import PAPER_CAMERA
    cam = camera_config(a.data_config) if a.data_config else PAPER_CAMERA
    placed = [f"--{k}" for k in ("depth", "x", "y") if getattr(a, k) is not None]
    allowed = {"point": ("--depth", "--x", "--y"), "volume": ("--depth", "--x")}.get(a.scene, ())
    if any(k not in allowed for k in placed):     # they had been ignored in silence
        raise ValueError(f"{' and '.join(k for k in placed if k not in allowed)} place"
                         f"{'s' * (sum(k not in allowed for k in placed) == 1)} a point (--depth, --x, --y) or a "
                         f"volume's axis (--depth, --x), not the {a.scene} scene's objects, which it draws itself "
                         "(--seed varies them)")
    a.depth, a.x, a.y = (0.0 if v is None else v for v in (a.depth, a.x, a.y))
    record = dict(kind=a.scene, seed=a.seed, nominal=a.nominal, depth_mm=a.depth, y_mm=a.y, x_mm=a.x)
    if a.depth is not None and not cam.focus_distance_mm + a.depth > 0:
        raise ValueError(f"--depth {a.depth:+g} mm puts the object {cam.focus_distance_mm + a.depth:.4g} mm from the "
                         f"main lens, at or behind it: depths are mm from the focus distance "
                         f"({cam.focus_distance_mm:.4g} mm), more than {-cam.focus_distance_mm:+.4g} mm")
    if a.scene == "furnace" and a.temperature is None:
        raise ValueError("--scene furnace needs its blackbody temperature: give --temperature K")
    # the colour sensor the camera file names ([sensor] cfa): a colour camera's white image is a mosaic too
    from ..optics.camera_file import load_colour_sensor
    named = load_colour_sensor(a.data_config) if a.data_config else None
    sensor = named if a.scene in COLOUR_SCENES + ("white",) else None
    colour = a.scene in COLOUR_SCENES or sensor is not None
    if named is not None and not colour:
        print(f"{a.data_config} names a colour sensor ({named.pattern}); scene {a.scene!r} is rendered monochrome "
              f"and recorded so (the colour scenes: {', '.join(COLOUR_SCENES)}, white)")
    if colour:
        sensor, where = render_sensor(sensor, a.data_config)
        record.update(sensor=sensor.record())
        if a.scene == "furnace":
            record["temperature_k"] = float(a.temperature)
        sc, chans, sensor = colour_scene(record, cam)
        print(f"colour sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where})")
    else:
        sc = simulated_scene(record, cam)
    if a.crosstalk or a.bit_depth:
        import dataclasses
        sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, crosstalk=a.crosstalk or
                                                                 sc.effects.crosstalk, bit_depth=a.bit_depth))
    t = time.perf_counter()
    if colour:
        from ..simulate.colour import render_colour
        raw = render_colour(cam, sc, chans, sensor, a.rays_per_pixel, a.seed)
    else:
        raw = simulate.render(cam, sc, a.rays_per_pixel, a.seed)
    dt = time.perf_counter() - t
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    meta = dict(camera=cam.to_json(), objects=json.dumps(sc.objects, default=float), scene=json.dumps(record))
    if colour:
        meta["sensor"] = json.dumps(record["sensor"])
    if out.suffix == ".png":
        _save_image(out, raw, {f"lf_flame.{k}": v for k, v in meta.items()}, bits=16)
    else:
        extra = {}
        if a.views:
            from ..refocus.shift_and_sum import raw_to_views
            extra["views"] = raw_to_views(raw, cam.pixels_per_lenslet)
        out = save_npz(out, raw=raw, **meta, **extra)
    name = f"furnace at {a.temperature:g} K" if a.scene == "furnace" else sc.name    # a blackbody filling the field
    # drawn or carried to this camera's depths: how many (a small field holds fewer) and where
    if a.scene in ("depth", "colour-depth", "flame", "colour-flame"):
        depths = [float(o["depth_offset_mm"]) for o in sc.objects]
        name += (f" ({len(depths)} flame{'s' * (len(depths) != 1)} at "
                 + ", ".join(f"{d:+.2f}" for d in depths) + " mm)")
    cut = ""
    if a.scene not in ("white", "furnace"):                   # those fill the field and more, by design
        from ..simulate.layers import light_outside_field
        share = light_outside_field(sc, cam)
        cut = f"; {100 * share:.1f} % of its light lies outside the field of view" if share >= 0.001 else ""
    print(f"rendered {name} {raw.shape} at {a.rays_per_pixel} rays/pixel in {dt:.2f} s -> {out}{cut}")
    if a.scene not in ("white", "furnace"):
        _render_warnings(cam, sc, raw)


def _render_warnings(cam, sc, raw) -> None:
    """``simulate``'s warnings of a scene the camera cannot show: objects at depths it does not refocus
    (:func:`lf_flame.optics.depth_range.imaging_range_mm`), a render with no light on the sensor; and a note of the
    pixels that clip the sensor (at the simulator's level, 1)."""
    from ..optics.depth_range import imaging_range_mm
    lo, hi = imaging_range_mm(cam)
    far = sorted({float(o["depth_offset_mm"]) for o in sc.objects if "depth_offset_mm" in o
                  and not lo <= float(o["depth_offset_mm"]) <= hi})
    if far:
        print(f"warning: objects at {', '.join(f'{d:+.4g}' for d in far)} mm lie outside what this camera refocuses "
              f"({lo:+.4g} .. {hi:+.4g} mm from its focus distance): their light spreads over the sensor, and no "
              "command brings them into focus")
    if not np.any(np.asarray(raw) > 0):
        print("warning: the render holds no light: the scene's rays miss the sensor")
    n = int(np.count_nonzero(np.asarray(raw) >= 1.0))
    if n:
        print(f"note: {n} pixels ({100 * n / np.asarray(raw).size:.2g} %) clip the sensor (at 1): reconstruct, "
              "profiles and temperature leave their samples out of the fit")


def views_and_camera(a):
    """The views of a command's input, their camera (:func:`._io.light_field`), the views a depth search
    refocuses (:meth:`lf_flame.real.lightfield.LightField.lit_views`) and, for decoded views, where their planes
    lie in the capture's object space (:class:`lf_flame.real.own_camera.DecodedFrame`, else None); decoded views
    without ``--camera`` come with None for the last three (slopes only, no depths)."""
    src = str(a.raw)
    if src.endswith(".h5") and ".h5:" not in src and not getattr(a, "camera", None):
        from ..real.views_file import load_views
        return load_views(src)[0], None, None, None
    lf = light_field(a)
    from .profiles import structure_warning
    from .real import overexposure_warning
    overexposure_warning(lf.over_exposure())     # as decode and reconstruct warn of it
    structure_warning(lf.views, src, "the planes and slopes found in it are no flame's")
    return lf.views, lf.camera, lf.lit_views(), lf.frame


def cmd_refocus(a):
    from ..refocus.shift_and_sum import aperture_mask, refocus_views
    if a.slope and a.depth:
        raise ValueError("give the planes as --slope (lenslets per view) or as --depth (mm), not both")
    views, cam, lit, _ = views_and_camera(a)
    if not (a.slope or a.depth):         # the depths found in the views, as reconstruct finds them
        if cam is None:
            raise ValueError(f"give the planes (--slope), or the camera of {a.raw} (--camera cam.toml) to find them")
        from .planes import search_planes
        a.depth = search_planes(views, cam, a.search_range, lit)[0]
    if a.depth:
        if cam is None:
            raise ValueError(f"--depth needs the camera of {a.raw}: give --camera cam.toml (or use --slope)")
        from ..optics.depth_range import check_imaging_range
        check_imaging_range(cam, a.depth)            # as every route that takes planes
        slopes = [cam.slope_for_depth(d) for d in a.depth]
    else:
        from ..optics.depth_range import MAX_SEARCH_SLOPE
        slopes = list(a.slope)
        far = [s for s in slopes if not abs(s) <= MAX_SEARCH_SLOPE]
        if far:
            raise ValueError(f"planes at slopes {', '.join(f'{s:+g}' for s in far)} lie outside what a camera can "
                             f"refocus (|slope| <= {MAX_SEARCH_SLOPE:g} lenslets per view)")
    n = views.shape[0]
    times = []
    for _ in range(2):    # the first call loads the kernels (Numba's cache) and plans: the second is the refocusing's
        t = time.perf_counter()
        stack = refocus_views(views, slopes, aperture_mask(n, a.aperture), method=a.method,
                              interpolation=a.interpolation)
        times.append(1e3 * (time.perf_counter() - t))
    shown = ", ".join(f"{round(s, 9) + 0.0:+.4g}" for s in slopes)          # + 0.0: no "-0" at the focal plane
    print(f"refocused {planes_count(len(slopes))} ({a.method}) at slopes {shown} in {times[1]:.2f} ms (a second "
          f"call; the first, with the kernels' start-up, {times[0]:.0f} ms)")
    depths = a.depth
    if depths is None and cam is not None:        # planes given by slope: their depths where the camera refocuses
        try:
            depths = [cam.depth_for_slope(v) for v in slopes]
        except ValueError:                        # a slope focusing at or beyond infinity: no depth to record
            depths = None
    extra = {} if depths is None else {"depths_mm": np.asarray(depths, float)}
    if Path(a.out).suffix.lower() in FIGURE_SUFFIXES:
        from ..measure.figures import save_figure
        print(f"-> {save_figure(refocus_figure(stack, slopes, cam, method=a.method), a.out)}")
    else:
        _write_stack(a.out, stack, slopes=np.asarray(slopes), **extra)


#: ``refocus --out`` suffixes written as a figure (anything else: the stack as .npz).
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def refocus_figure(stack, slopes, camera=None, *, method: str = ""):
    """``refocus``'s figure: one panel per plane, in object-space mm at its depth, on one colour scale.

    Parameters
    ----------
    stack : ndarray of shape (P, rows, cols)
        Refocused planes (the raw image's units), one sample per lenslet.
    slopes : sequence of P float
        Each plane's slope (lenslets per view).
    camera : PlenopticCamera or None
        The planes' camera: each panel's depth (mm) and its field in mm
        (:func:`lf_flame.measure.figures.plane_extent_mm`). None (views without a camera), or a
        camera whose lenslet grid is not the planes': titles give the slope alone, axes in lenslets.
    method : str
        The refocusing method, named in the figure's title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..measure.figures import plane_extent_mm, planes_figure, signed
    stack = np.asarray(stack)
    if camera is not None and (camera.n_rows, camera.n_cols) != stack.shape[1:]:
        camera = None
    titles, extents = [], []
    for s in slopes:
        try:
            d = None if camera is None else camera.depth_for_slope(s)
        except ValueError:                                       # a slope that focuses no real plane
            d = None
        titles.append(f"slope {signed(s, 3)} lenslets/view" + ("" if d is None else f"\ndepth {signed(d)} mm"))
        extents.append(None if d is None else plane_extent_mm(camera, d))
    return planes_figure([stack], extents, titles, "refocused radiance (a.u.: the raw image's units)",
                         suptitle=f"refocused ({method})" if method else "")


def cmd_slopes(a):
    if a.raw is None:
        return _calibrate_slopes(a)
    given = [f"--{k.replace('_', '-')}" for k in ("out", "data_config", "results") if getattr(a, k, None)]
    if given:       # they had been ignored without a word: the files went beside RAW
        raise ValueError(f"{' and '.join(given)} belong{'s' * (len(given) == 1)} to the calibration mode (no RAW); "
                         "a light field's curves go to --out-prefix PREFIX (default: beside RAW)")
    import pandas as pd
    from ..learn.evaluation import plot_slope_curves
    from ..refocus.shift_and_sum import aperture_mask
    from ..refocus.slope_search import find_sharpest_slope
    views, cam, lit, frame = views_and_camera(a)
    from ..optics.depth_range import MAX_SEARCH_SLOPE, imaging_range_mm
    lo, hi = a.lo, a.hi
    far = [f"--{k} {v:g}" for k, v in (("lo", lo), ("hi", hi)) if v is not None and not abs(v) <= MAX_SEARCH_SLOPE]
    if far:       # a wider grid had held every refocused plane at once: 24 GB for -100 ... 100, killed
        raise ValueError(f"{', '.join(far)}: slopes beyond {MAX_SEARCH_SLOPE:g} lenslets per view lie outside what a "
                         "camera can refocus (refocus and reconstruct refuse them too)")
    if lo is None or hi is None:
        if cam is None:
            s_lo, s_hi = -MAX_SEARCH_SLOPE, MAX_SEARCH_SLOPE
        else:
            s_lo, s_hi = sorted(cam.slope_for_depth(d) for d in imaging_range_mm(cam))
        lo, hi = (s_lo if lo is None else lo), (s_hi if hi is None else hi)
    if a.roi:
        objects = [dict(name=f"roi{i}", roi=tuple(r)) for i, r in enumerate(a.roi)]
    else:
        stored = _raw_objects(a.raw)
        if stored and frame is not None:      # a simulated capture decoded here: its regions in the decoded frame
            stored = _decoded_objects(stored, _raw_camera(a.raw), cam, frame, views.shape[2:])
        objects = (stored or (_emission_regions(views, cam, lit) if cam is not None else None)
                   or [dict(name="image", roi=(0, views.shape[2], 0, views.shape[3]))])
    # the circular aperture: the views inside the main lens's aperture image where the camera is known
    mask = lit if a.aperture == "circular" and lit is not None else aperture_mask(views.shape[0], a.aperture)
    # the grid's steps move the outermost view as on the paper's 15 views (0.05 and 0.005 lenslets per view)
    scale = 14.0 / max(views.shape[0] - 1, 1)
    t = time.perf_counter()
    searches = [find_sharpest_slope(views, o["roi"], metric=a.metric, method=a.method, lo=lo, hi=hi, mask=mask,
                                    coarse_step=0.05 * scale, fine_step=0.005 * scale)
                for o in objects]
    rows = []
    for o, s in zip(objects, searches):
        row = dict(object=o["name"], roi=" ".join(str(int(x)) for x in o["roi"]), slope=round(s.slope, 6) + 0.0)
        if cam is not None:  # decoded views without --camera: no optics, no depth
            try:
                row["depth_mm"] = round(cam.depth_for_slope(s.slope), 3)
            except ValueError:
                row["depth_mm"] = float("nan")
        if "depth_offset_mm" in o:
            row["true_depth_mm"] = o["depth_offset_mm"]
            row["analytic_slope"] = round(cam.slope_for_depth(o["depth_offset_mm"]), 4) + 0.0    # no -0
        rows.append(row)
    df = pd.DataFrame(rows)
    print(df.to_string(index=False))
    print(f"searched {len(objects)} regions ({a.method}, {a.metric}) in {time.perf_counter() - t:.2f} s")
    stem = Path(a.raw.split(".h5:")[0]).with_suffix("")
    out = Path(a.out_prefix or stem)
    if a.out_prefix and (a.out_prefix.endswith(("/", "\\")) or out.is_dir()):   # a folder: the files go in it
        out = out / stem.name
    out.parent.mkdir(parents=True, exist_ok=True)
    from ..config import atomic_write_text
    atomic_write_text(f"{out}.slopes.csv", df.to_csv(index=False))
    plot_slope_curves([o["name"] for o in objects], searches, f"{out}.slopes.png", a.metric)
    print(f"-> {out}.slopes.csv, {out}.slopes.png")


def _raw_camera(path):
    """The camera that ``lf-flame simulate`` stored beside a raw image (the one its objects' ``roi`` are on)."""
    from ..optics.camera import PlenopticCamera
    from ._io import _raw_meta
    meta = _raw_meta(path)
    return PlenopticCamera.from_dict(json.loads(meta["camera"])) if "camera" in meta else None


def _decoded_objects(objects, stored_cam, cam, frame, shape):
    """A simulated capture's objects with their regions carried from the simulated camera's lenslet grid
    (``stored_cam``, where ``simulate`` drew each ``roi``) onto the grid of the views decoded from it (``cam``,
    ``frame``, ``shape``: :meth:`lf_flame.real.own_camera.DecodedFrame.object_to_lenslet`): each box's corners
    taken to object space at the object's depth and back, the box around them clipped to the decoded grid. None
    where they cannot be carried (no stored camera, an object without a depth, a box wholly off the decoded grid):
    the regions are then those found in the views, said in a note."""
    why = None
    if stored_cam is None:
        why = "the file stores no camera for them"
    elif not all("depth_offset_mm" in o and "roi" in o for o in objects):
        why = "they have no depths"
    out = []
    for o in objects if why is None else ():
        z = float(o["depth_offset_mm"])
        m = stored_cam.mla_distance_mm / stored_cam.object_distance_mm(z) / stored_cam.mla_pitch_mm
        r0, r1, c0, c1 = (float(v) for v in o["roi"])
        corners = [frame.object_to_lenslet(cam, shape, (stored_cam.n_rows / 2 - r) / m, (c - stored_cam.n_cols / 2) / m,
                                           z) for r in (r0, r1) for c in (c0, c1)]
        rows, cols = [p[0] for p in corners], [p[1] for p in corners]
        roi = (max(0, int(math.floor(min(rows) + 1e-6))), min(shape[0], int(math.ceil(max(rows) - 1e-6))),
               max(0, int(math.floor(min(cols) + 1e-6))), min(shape[1], int(math.ceil(max(cols) - 1e-6))))
        if roi[0] >= roi[1] or roi[2] >= roi[3]:
            why = f"{o.get('name', 'an object')}'s lies off the decoded views' grid"
            break
        out.append({**o, "roi": roi})
    if why is not None:
        print(f"note: the regions of the objects the file stores cannot be carried into the decoded views ({why}): "
              "searching the regions found in the views instead (--roi to give regions)")
        return None
    return out


def _emission_regions(views, cam, views_mask=None):
    """The flames the depth search finds (:func:`lf_flame.tomo.depth.find_depths`, ``reconstruct``'s search, over
    ``views_mask``'s views): one object per found depth, the bounding box of the lenslets that voted for it as
    ``roi`` (lenslets)."""
    from ..tomo.depth import find_depths
    found = find_depths(views, cam, views_mask=views_mask)
    objects = []
    for k, m in enumerate(found.masks):
        rows, cols = np.nonzero(m)
        objects.append(dict(name=f"found{k}", roi=(int(rows.min()), int(rows.max()) + 1, int(cols.min()),
                                                   int(cols.max()) + 1)))
    return objects


def _calibrate_slopes(a):
    from ..config import atomic_write_text, load_data_config
    from ..learn.dataset import calibrate_slopes
    from ..learn.evaluation import write_slopes
    if not (a.data_config and a.out and a.results):
        raise SystemExit("error: give RAW, or --data-config, --out and --results to calibrate the nominal scene")
    given = [f"--{k}" for k in ("lo", "hi") if getattr(a, k, None) is not None]
    if given:       # they had been ignored without a word
        raise ValueError(f"{' and '.join(given)} go with RAW: the calibration searches -3 .. 3 lenslets per view, "
                         "widened to a lenslet per view beyond the shapes' analytic slopes")
    cam, cfg = load_data_config(a.data_config)
    t = time.perf_counter()
    slopes, searches, objects = calibrate_slopes(cam, cfg.calibration_rays_per_pixel)
    df = write_slopes(cam, slopes, searches, objects, a.results)
    print(df.to_string(index=False))
    atomic_write_text(a.out, json.dumps({"slopes": slopes, "wall_time_s": time.perf_counter() - t,
                                         "camera": json.loads(cam.to_json())}))


def _bit_depth(text: str) -> int:
    """``--bit-depth``: an integer from 1 to :data:`~lf_flame.simulate.layers.MAX_BIT_DEPTH`."""
    try:
        bits = int(text)
    except ValueError:
        bits = 0
    if not 1 <= bits <= MAX_BIT_DEPTH:
        raise argparse.ArgumentTypeError(f"--bit-depth takes an integer from 1 to {MAX_BIT_DEPTH}. Received: {text!r}")
    return bits


def add_parsers(sub) -> None:
    """Add ``simulate``, ``refocus`` and ``slopes`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("simulate", help="render a raw light-field image of a scene")
    s.add_argument("--scene", choices=["shapes", "flame", "point", "volume", "depth", "white", "colour-flame",
                                       "colour-depth", "furnace"], required=True,
                   help="shapes: the paper's four shapes (rectangle, triangle, circle, square); flame: four "
                        "flames; both at the paper's depths " + ", ".join(f"{d:+g}" for d in PAPER_DEPTHS_MM) +
                        " mm (on another camera carried to its depths as far apart in parallax, and the flames "
                        "scaled to its field); point: one point of light (--depth, --y, --x); volume: a volumetric laminar flame "
                        "(a luminous sheath 10 mm across, at most 85 %% of the field, about a vertical axis at --depth "
                        "and --x, default 0 and 0, in 32 layers; moved sideways, it is cut by the field's edge where "
                        "it reaches past it; 'reconstruct --volume'); depth: 2-4 flames at random "
                        "depths, sizes and places (--seed), scaled to the camera (its depth of field and lenslet "
                        "footprint; fewer, down to one, where a small field has no room for them: the printout "
                        "says how many and where); white: a flat field, the white image that 'lf-flame calibrate' takes; seen "
                        "by a colour (Bayer) sensor, for 'lf-flame temperature': colour-flame: the four flames with "
                        "their temperature fields; colour-depth: the depth scene's flames, each with a drawn "
                        "temperature; furnace: a blackbody at --temperature filling the field, for "
                        "'lf-flame calibrate-temperature'. The colour sensor is the camera file's [sensor] cfa "
                        "(docs/own_camera.md), else colour-science's Nikon 5100 behind an RGGB CFA")
    s.add_argument("--out", required=True, help=".npz (raw, camera, objects, scene[, views]) or .png (the raw "
                   "image in 16 bits, clipped at 1, with the camera, objects and scene in its text); both read by "
                   "the commands that take a raw image")
    s.add_argument("--seed", type=count, default=0, help="seed of the scene's random variation and of the rays")
    s.add_argument("--rays-per-pixel", type=int, default=16, help="rays traced per sensor pixel (fewer: faster, "
                   "noisier)")
    s.add_argument("--data-config", "--camera", dest="data_config", help="camera file (the datasheet tables of "
                   "docs/own_camera.md) or a TOML with a [camera] table (default: the paper's camera); the scene's "
                   "depths are mm from its focus distance")
    s.add_argument("--nominal", action="store_true", help="the nominal scene (no random variation)")
    s.add_argument("--views", action="store_true", help="also store sub-aperture views (N, N, R, C)")
    s.add_argument("--crosstalk", action="store_true", help="add crosstalk through neighbouring lenslets")
    s.add_argument("--bit-depth", type=_bit_depth, help="quantise the raw image to this many bits, 1-32 (default: "
                   "not quantised)")
    s.add_argument("--temperature", type=finite, help="furnace scene: the blackbody's temperature (K)")
    s.add_argument("--depth", type=finite, default=None, help="point and volume scenes: depth offset (mm; "
                   "default 0)")
    s.add_argument("--y", type=finite, default=None, help="point scene: height (mm; default 0)")
    s.add_argument("--x", type=finite, default=None, help="point and volume scenes: lateral position (mm, x "
                   "right; a volume's axis; default 0)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("refocus", help="refocus a raw image (or decoded views) at one or more slopes")
    s.add_argument("raw", help=RAW_FORMATS + ", or VIEWS.h5 from decode")
    s.add_argument("--slope", type=finite, action="append", help="lenslets per view (repeatable)")
    s.add_argument("--depth", type=finite, action="append", help="instead of --slope: plane depth, mm from the "
                   "camera's focus distance (> 0 farther; repeatable); neither: the depths found in the views, as "
                   "'reconstruct' finds them")
    add_camera_args(s)
    s.add_argument("--method", choices=["shift-sum", "fourier"], default="shift-sum",
                   help="shift-and-sum of the views, or the Fourier slice")
    s.add_argument("--interpolation", choices=["bilinear", "nearest"], default="bilinear",
                   help="shift-sum only: bilinear, or whole-lenslet shifts")
    s.add_argument("--aperture", choices=["square", "circular"], default="circular",
                   help="views summed: all, or those inside the main lens's circular aperture")
    s.add_argument("--out", required=True, help=".npz (the planes as 'stack', with 'slopes' and, where the camera "
                   "is known, 'depths_mm'), or "
                   ".png/.pdf/.svg: a figure of the planes in object-space mm at their depths, one colour bar")
    add_search_arg(s)
    s.set_defaults(func=cmd_refocus)

    s = sub.add_parser("slopes", help="sharpest slope of each object of a raw image (table and plot of the "
                       "sharpness curves); without RAW, calibrate the nominal scene of a data config")
    s.add_argument("raw", nargs="?", help=RAW_FORMATS + " (a simulated .npz: its objects' ROIs are used), "
                   "or VIEWS.h5 from decode")
    s.add_argument("--roi", type=int, nargs=4, action="append", metavar=("ROW0", "ROW1", "COL0", "COL1"),
                   help="region in lenslets (repeatable; default: the stored objects, else per depth the depth "
                   "search finds the bounding box of the lenslets that vote for it, else the whole image)")
    s.add_argument("--metric", choices=["tenengrad", "laplacian", "normvar"], default="tenengrad",
                   help="sharpness of a refocused region")
    s.add_argument("--method", choices=["fourier", "shift-sum"], default="fourier", help="refocusing of the search")
    s.add_argument("--lo", type=finite, help="lowest slope searched, lenslets per view (default: the camera's "
                   "imaging range, |slope| <= 3 and object distances beyond 1.05 focal lengths)")
    s.add_argument("--hi", type=finite, help="highest slope searched, lenslets per view (default: as --lo)")
    add_camera_args(s)
    s.add_argument("--aperture", choices=["square", "circular"], default="circular",
                   help="views summed: all, or those inside the main lens's circular aperture")
    s.add_argument("--out-prefix", help="write PREFIX.slopes.csv and PREFIX.slopes.png (default: beside RAW; a "
                                        "folder, or a path ending in /: in it, named after RAW)")
    s.add_argument("--data-config", help="calibration mode: data config TOML")
    s.add_argument("--out", help="calibration mode: JSON of the slopes used for ground truth")
    s.add_argument("--results", help="calibration mode: folder for slopes.csv and slopes.png")
    s.set_defaults(func=cmd_slopes)
