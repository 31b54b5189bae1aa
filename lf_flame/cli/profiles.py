"""The ``profiles`` command: flame diagnostics per plane (:mod:`lf_flame.measure.diagnostics`) of the
planes of any route (default :data:`PROFILES_ROUTE`, admm's reconstruction); its figure is
:func:`lf_flame.measure.figures.profiles_figure`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ._io import RAW_FORMATS, _load_raw, _raw_objects
from .options import add_camera_args, add_figure_arg, add_search_arg, finite
from ..routes import parse_route
from .learning import _learned_runner
from ..routes import LEARNED_ROUTES
from ..tomo.defaults import SOLVERS

#: ``profiles``' default route: admm's planes of emission (``lf-flame reconstruct``'s default solver).
#: Every route on ``lf-flame simulate --scene flame`` at seeds 0, 1, 2 (12 flames, 16 rays per pixel):
#: reconstruct-admm measured every height within 0.21 mm of the truth (mean 0.09 mm, none flagged;
#: pd-tv 0.14 mm at 2.6 times admm's time, fista 0.22, rl 0.37, lsqr 6.4); the refocused planes
#: (shift-sum, fourier, shift-sum-nearest, reconstruct-adjoint) measured seed 0's +20 mm flame
#: 12.8-13.7 mm short, its region merged with the blur of the flames in front of it (flagged).
PROFILES_ROUTE = "reconstruct-admm"


def _profiles_input(a):
    """Camera, 4-plane stack, depths, slopes, flame objects (or None), the found depths (a
    :class:`~lf_flame.tomo.depth.FoundDepths` where the planes were found, else None), whether the light field is
    uniform (:func:`structure_warning`) and the depths of the given planes where the depth search finds no flame
    (:func:`solved_planes`) for ``profiles``."""
    from ..optics.camera import PAPER_CAMERA
    from ..real.lightfield import from_raw
    from ..refocus.shift_and_sum import aperture_mask, refocus
    from ..simulate.scenes import PAPER_DEPTHS_MM
    from .planes import found_planes
    s = str(a.raw)
    if _decoded(a):
        return _decoded_profiles_input(a)
    gt, objects, slopes = None, None, None
    if ".h5:" in s:
        from ..learn.dataset import LightFieldDataset
        f, i = s.rsplit(":", 1)
        ds = LightFieldDataset(f)
        raw, cam = ds.raw(int(i)), ds.camera
        gt, objects, slopes = ds.gt(int(i)), ds.params(int(i)), ds.slopes
    else:
        raw, cam = _load_raw(a.raw)
        objects = _flame_objects(a.raw)
    if getattr(a, "camera", None):
        from ..optics.camera_file import load_camera_file
        cam = load_camera_file(a.camera)
    cam = cam or PAPER_CAMERA
    given = _given_depths(a)
    depths = given or _scene_depths(a, objects)
    if depths and not given:
        print("planes at the depths of the flames the file stores (" + ", ".join(f"{d:+.2f}" for d in depths)
              + " mm: the scene's truth, not found; --depths auto to find them, --depth to give others)")
    if not depths and a.slope:
        depths = [cam.depth_for_slope(v) for v in a.slope]
    elif not depths and slopes is not None:       # a dataset sample: the paper's planes
        depths = list(PAPER_DEPTHS_MM)
    if given or slopes is None:                   # the dataset's slopes go with its own planes only
        slopes = [cam.slope_for_depth(d) for d in depths] if depths else None
    route = parse_route(a.route)
    search = getattr(a, "search_range", None)
    found, flat, without = None, None, []
    if np.shape(raw) == tuple(cam.sensor_shape) and cam.perfect_grid:
        from ..refocus.shift_and_sum import raw_to_views
        flat = structure_warning(raw_to_views(np.asarray(raw, np.float32), cam.pixels_per_lenslet), a.raw)
    if route.tomographic:
        depths, stack, found, without = solved_planes(from_raw(raw, cam, str(a.raw)), depths, route.solver, search)
    elif not depths:
        depths, _, found = found_planes(from_raw(raw, cam, str(a.raw)), search_range=search)
    if a.slope:
        slopes = a.slope
    elif slopes is None:                          # the planes found
        slopes = [cam.slope_for_depth(d) for d in depths]
    if len(slopes) != len(depths):
        raise ValueError(f"need {len(depths)} slopes, one per plane. Received: {slopes}")
    n = cam.pixels_per_lenslet
    if route.kind == "stored":
        if gt is None:
            raise ValueError("--route ground-truth needs a dataset sample DATASET.h5:INDEX")
        stack = gt
    elif route.kind == "learned":
        if not a.model_dir:
            raise ValueError(f"--route {a.route} needs --model-dir")
        run, _ = _learned_runner(raw, cam, a.raw, a.model_dir, route.solver)
        stack = run(raw.astype(np.float32)[None, ..., None])
    elif not route.tomographic:
        stack = refocus(raw, slopes, n, aperture_mask(n, "circular"), **route.options)
    return cam, np.asarray(stack), depths, list(slopes), objects, found, flat, without


#: The flag ``profiles`` adds to every plane's measurement of a light field without structure
#: (:func:`structure_warning`).
NO_STRUCTURE_FLAG = "no-structure"
#: The flag of ``profiles``' rows on a plane given (the user's, or the scene's) where the depth search finds no flame
#: and the data need none (:func:`lf_flame.cli.fit_notes.planes_without_flame`): what is measured there is other
#: flames' light, defocused.
NO_FLAME_FLAG = "no-flame-found"


def structure_warning(views, source, found: str = f"what is measured on its planes is none (flagged "
                                                  f"{NO_STRUCTURE_FLAG})") -> bool:
    """Where a light field's views carry no structure (:func:`lf_flame.real.black_level.view_spread` under
    :data:`~lf_flame.real.black_level.FLAT_SPREAD`: a uniform light field, a glare, a blank or washed-out capture),
    one warning (stderr) that what is ``found`` in it is no flame (``profiles``: its measurements are flagged
    :data:`NO_STRUCTURE_FLAG`), and True; else False."""
    import sys
    from ..real.black_level import FLAT_SPREAD, view_spread
    spread = view_spread(views)
    if spread is None or spread >= FLAT_SPREAD:
        return False
    print(f"warning: {source}'s views carry no structure (each varies by {spread:.2g} of its level across its "
          f"lenslets, under {FLAT_SPREAD:g}): a uniform light field (a glare, a blank or washed-out capture) holds no "
          f"flame, and {found}; check the capture and its exposure",
          file=sys.stderr)
    return True


def _decoded(a) -> bool:
    """``profiles`` of decoded views: ``VIEWS.h5``, or a raw capture with ``--calibration``."""
    s = str(a.raw)
    return bool(getattr(a, "calibration", None)) or (s.endswith(".h5") and ".h5:" not in s)


def _given_depths(a):
    """``--depth``'s planes (refused beside ``--slope``), or None."""
    if not getattr(a, "depth", None):
        return None
    if a.slope:
        raise ValueError("give the planes as --depth or as --slope, not both")
    return [float(d) for d in a.depth]


#: What ``profiles`` reads of each flame a file stores (its objects): a record without one is refused.
FLAME_KEYS = ("height_mm", "depth_offset_mm")


def _flame_objects(path):
    """The flames ``lf-flame simulate`` stored beside the raw image (:func:`lf_flame.cli._io._raw_objects`), or None.

    Raises
    ------
    ValueError
        Objects that are not flames (no flame heights), or a flame that lacks its depth (``depth_offset_mm``):
        naming the file, the flame and what it lacks.
    """
    objects = _raw_objects(path)
    if objects is None:
        return None
    if not isinstance(objects, list) or not all(isinstance(o, dict) and "height_mm" in o for o in objects):
        raise ValueError(f"{path} does not hold a flame scene (its objects have no flame heights)")
    for i, o in enumerate(objects):
        missing = [k for k in FLAME_KEYS if k not in o]
        if missing:
            raise ValueError(f"{path}: its stored flame {i} (record 'objects') lacks {', '.join(missing)}: the file "
                             "is damaged; simulate it again, or save its raw image alone (.npy) and give --depth")
    return objects


def _object_depths(objects):
    """The flames' depths (mm), or None without flames."""
    return [float(o["depth_offset_mm"]) for o in objects] if objects else None


def _scene_depths(a, objects):
    """The stored flames' depths where ``profiles`` takes them for its planes (``--depths scene``, the default for a
    file that stores its flames), else None: ``--depths auto``, or a ``--search-range`` given (a search asked for:
    it had been ignored in silence on a file that stores its flames)."""
    choice = getattr(a, "depths", None)
    if choice == "auto" or (choice is None and getattr(a, "search_range", None)):
        return None
    if choice == "scene" and not objects:
        raise ValueError(f"--depths scene: {a.raw} stores no flames (give --depth, or --depths auto)")
    return _object_depths(objects)


def _decoded_profiles_input(a):
    """:func:`_profiles_input` of decoded views (``VIEWS.h5``, or a raw capture with ``--calibration``):
    the planes of the decoded views' camera (:func:`lf_flame.cli._io.light_field`), solved as ``reconstruct``
    solves them (a hexagonal grid's admm planes once more on its lattice) or refocused."""
    from ..refocus.shift_and_sum import aperture_mask, refocus_views
    from ._io import light_field
    from .planes import check_planes, found_planes
    lf = light_field(a)
    cam = lf.camera
    flat = structure_warning(lf.views, a.raw)
    objects = None if str(a.raw).endswith(".h5") else _flame_objects(a.raw)
    depths = _given_depths(a) or ([cam.depth_for_slope(v) for v in a.slope] if a.slope else
                                  _scene_depths(a, objects))
    route = parse_route(a.route)
    if route.kind in ("stored", "learned"):
        raise ValueError(f"--route {a.route} takes the paper camera's raw images or dataset samples, not decoded views")
    if depths:
        check_planes(cam, depths)
    search = getattr(a, "search_range", None)
    found, without = None, []
    if route.tomographic:
        depths, stack, found, without = solved_planes(lf, depths, route.solver, search)
    elif not depths:
        depths, _, found = found_planes(lf, search_range=search)
    slopes = [cam.slope_for_depth(d) for d in depths]
    if not route.tomographic:
        stack = refocus_views(lf.views, slopes, aperture_mask(cam.pixels_per_lenslet, "circular"), **route.options)
    return cam, np.asarray(stack), depths, slopes, objects, found, flat, without


def solved_planes(lf, depths, solver, search_range=None):
    """Each plane's emission as ``lf-flame reconstruct`` solves it, averaged to the lenslets
    (:func:`lf_flame.tomo.truth.bin_planes`): ``(depths, stack)``, stack (P, rows, cols).

    ``depths`` (mm from the focal plane) given (by the user, or the scene's stored flames'): solved on them
    (:func:`lf_flame.cli.planes.run_reconstruction`), checked against the depth search as ``reconstruct`` checks them
    (:func:`lf_flame.cli.planes.given_planes_search`: planes near each other held to the regions of their flames,
    planes where it finds no flame warned of).
    None or empty: found as ``reconstruct --depths auto`` finds them, within ``search_range`` (mm): the votes, then
    the residual's search and the refinement, near planes held to their regions
    (:func:`lf_flame.cli.planes.solve_found`); the votes' depths alone leave those out. A hexagonal grid's admm
    planes are solved once more on its lattice (:func:`lf_flame.cli.planes.lattice_solve`). Returns
    ``(depths, stack, found, without)``, ``found`` the :class:`~lf_flame.tomo.depth.FoundDepths` (None for given
    depths), ``without`` the depths of the given planes where the search finds no flame."""
    from ..tomo.truth import bin_planes
    from .planes import found_planes, lattice_solve, solve_found, solve_given
    from .fit_notes import left_out_notes, solve_warnings
    found = given = held = None
    if depths:
        given, held, op, rec = solve_given(lf, depths, search_range, solver=solver)
    else:
        found, op, rec = solve_found(lf, found_planes(lf, search_range=search_range)[2], solver=solver)
        depths = [float(d) for d in found.planes_mm]
    rec, lattice = lattice_solve(lf, op, rec, found if held is None else held)
    print("\n".join(left_out_notes(lf, rec, lattice)))
    record = solve_warnings(lf, op, rec, lattice, found=given)  # the planes measured are what reconstruct warns of
    return list(depths), bin_planes(rec.planes, getattr(op, "subsamples", 1)), found, \
        record.get("planes_without_flame", [])


def flame_bands(found, plane: int, n_cols: int) -> list:
    """The column bands ``[c0, c1)`` (lenslets) of the separate flames found on one plane: where depths found in two
    or more regions (:class:`~lf_flame.tomo.depth.FoundDepths`' ``region`` and ``labels``) share the plane (their
    depths merged onto it, ``plane_of``) and the regions' columns do not overlap, each region's band reaches halfway
    to its neighbour's; else ``[None]``, the whole plane (one flame, or flames one behind another)."""
    if found is None:
        return [None]
    labs = sorted({int(found.region[j]) for j in np.flatnonzero(np.asarray(found.plane_of) == plane)})
    spans = sorted((int(c[0]), int(c[-1]) + 1) for c in
                   (np.flatnonzero((found.labels == lab).any(axis=0)) for lab in labs) if len(c))
    if len(spans) < 2 or any(b[0] < a[1] for a, b in zip(spans, spans[1:])):
        return [None]
    edges = [0] + [(a[1] + b[0]) // 2 for a, b in zip(spans, spans[1:])] + [int(n_cols)]
    return list(zip(edges[:-1], edges[1:]))


def profiles_table(a):
    """What ``profiles`` measures, before anything is written: the planes of ``a.route`` and
    each plane's flame diagnostics.

    Parameters
    ----------
    a : argparse.Namespace
        ``profiles``' arguments: ``raw``, ``route``, ``slope``, ``camera``, ``model_dir``.

    Returns
    -------
    cam : PlenopticCamera
    stack : ndarray of shape (P, rows, cols)
        The planes on the camera's lenslet grid (a reconstruction on a finer grid, admm's,
        averaged to the lenslets: :func:`lf_flame.tomo.truth.bin_planes`).
    depths : list of P float
        The planes' depths (mm from the focal plane).
    measurements : list of P FlameMeasurement or None
        None where no flame was found.
    objects : list of P (dict or None) or None
        When the input stores its flames (the truth): the flame standing at each plane's depth, None where none does
        (:func:`plane_flames`).
    table : pandas.DataFrame
        On the planes of the stored flames (the default where the input stores them): one row per flame, as
        :func:`lf_flame.measure.scoring.score_stacks` scores them (``plane``, ``route``, ``sample``, ``slope``,
        ``depth_mm``, the truth, the measurement's summary, ``failure`` and the ``*_err_mm`` columns; no ``flame``).
        Else one row per plane and flame: ``plane``, ``flame`` (0, 1 ... where flames found apart share a plane,
        :func:`flame_bands`, or stand apart on a plane of emission given by depth,
        :func:`lf_flame.measure.diagnostics.separate_flame_bands`; ``measurements`` holds each plane's
        brightest), ``route``, ``depth_mm``, ``slope``, the measurement's summary (mm and the plane's units), and
        with the truth ``height_mm_true``, ``height_err_mm`` (|measured - true|, mm, each row paired with its own
        flame: :func:`row_flames`) ...; ``failure``. ``docs/files.md`` explains every column.
    """
    import pandas as pd
    from ..measure.diagnostics import EmptyPlaneError, flame_truth, measure_flame, separate_flame_bands
    from ..routes import measure_settings, parse_route
    from ..measure.scoring import score_stacks
    kw = measure_settings(a.route)
    cam, stack, depths, slopes, objects, found, flat, without = _profiles_input(a)
    truth = plane_flames(cam, depths, objects)
    if objects and not _decoded(a) and truth == list(objects):      # the scene's own planes, in its order
        sample = int(str(a.raw).rsplit(":", 1)[1]) if ".h5:" in str(a.raw) else 0
        df = score_stacks(stack[None], cam, [objects], samples=[sample], measure=kw, route=a.route)
        df.insert(0, "plane", range(len(df)))
        ms = []
        for plane, o in zip(stack, objects):
            try:
                ms.append(measure_flame(plane, cam, o["depth_offset_mm"], columns=flame_truth(o)["columns"], **kw))
            except EmptyPlaneError:
                ms.append(None)
    else:
        ms, rows = [], []
        apart = parse_route(a.route).emission and found is None      # planes given: their flames told apart here
        for k, (plane, d) in enumerate(zip(stack, depths)):
            kept = []
            bands = separate_flame_bands(plane, cam, segment_fraction=kw["segment_fraction"]) if apart else \
                flame_bands(found, k, cam.n_cols)
            for i, band in enumerate(bands):
                try:
                    m = measure_flame(plane, cam, d, columns=band, **kw)
                    rows.append(dict(plane=k, flame=i, route=a.route, depth_mm=d, **m.summary(), failure=""))
                    kept.append(m)
                except EmptyPlaneError as e:
                    rows.append(dict(plane=k, flame=i, route=a.route, depth_mm=d, failure=str(e)))
            ms.append(max(kept, key=lambda m: m.integrated_intensity) if kept else None)
        df = pd.DataFrame(rows)
        if any(o is not None for o in truth) and "height_mm" in df:   # the heights of the flames at the planes' depths
            paired = row_flames(cam, depths, objects, truth, df)
            df.insert(df.columns.get_loc("height_mm") + 1, "height_mm_true",
                      [np.nan if o is None else float(o["height_mm"]) for o in paired])
            # |measured - true|, as score_stacks gives it on the simulated camera's route
            df.insert(df.columns.get_loc("height_mm_true") + 1, "height_err_mm", (df.height_mm - df.height_mm_true).abs())
    df.insert(3 + ("flame" in df), "slope", [slopes[k] for k in df.plane])
    if "flags" in df:                   # what was measured is no flame: a uniform light field, a plane without flame
        if flat:
            _add_flag(df, df["flags"].notna().to_numpy(), NO_STRUCTURE_FLAG)
        if len(without):
            _add_flag(df, np.isclose(df.depth_mm.to_numpy(float)[:, None], np.asarray(without)[None]).any(axis=1),
                      NO_FLAME_FLAG)
    return cam, stack, depths, ms, truth if objects else None, df


def _add_flag(df, rows, flag: str) -> None:
    """Add ``flag`` to the ``flags`` of ``df``'s ``rows`` (bool per row), ``;``-joined after those they hold."""
    df.loc[rows, "flags"] = [";".join([f for f in str(v).split(";") if f and f != "nan"] + [flag])
                             for v in df["flags"][rows]]


def plane_flames(cam, depths, objects) -> list:
    """The flame (its object) standing at each plane's depth, or None: each flame goes to the plane nearest its depth
    within the camera's merge tolerance (:func:`lf_flame.tomo.depth.depth_tolerances`, 1 mm on the paper's camera),
    nearest pairs first, one plane per flame.

    Parameters
    ----------
    cam : PlenopticCamera
    depths : sequence of P float
        The planes' depths (mm from the focal plane).
    objects : sequence of dict or None
        The scene's flames (``depth_offset_mm``, ``height_mm`` ...).

    Returns
    -------
    list of P dict or None
    """
    from ..tomo.depth import depth_tolerances
    out = [None] * len(depths)
    if not objects:
        return out
    tol = depth_tolerances(cam, cam.pixels_per_lenslet)[1]
    pairs = sorted((abs(float(o["depth_offset_mm"]) - d), k, i) for k, d in enumerate(depths)
                   for i, o in enumerate(objects))
    used = set()
    for gap, k, i in pairs:
        if gap <= tol and out[k] is None and i not in used:
            out[k] = objects[i]
            used.add(i)
    return out


def row_flames(cam, depths, objects, truth, df) -> list:
    """The flame (its object) each row of ``profiles``' table measured, or None: the flames standing at a plane's
    depth (within the camera's merge tolerance, as :func:`plane_flames` pairs them) go to that plane's rows nearest
    them across the field (``centroid_x_mm``), nearest pairs first, one row per flame; a plane's only row takes its
    flame of :func:`plane_flames` (``truth``) where it measured none. Two flames side by side on one plane are each
    paired with their own row, and a row of light that no flame at that depth explains (another flame's, put on a
    plane it does not stand on) with none.

    Parameters
    ----------
    cam : PlenopticCamera
    depths : sequence of P float
        The planes' depths (mm from the focal plane).
    objects : sequence of dict
        The scene's flames (``depth_offset_mm``, ``height_mm``, ``centre_x_mm`` ...).
    truth : list of P dict or None
        :func:`plane_flames` of the same planes.
    df : pandas.DataFrame
        The table's rows: ``plane`` and, where measured, ``centroid_x_mm``.

    Returns
    -------
    list of dict or None, one per row
    """
    from ..tomo.depth import depth_tolerances
    tol = depth_tolerances(cam, cam.pixels_per_lenslet)[1]
    x = df["centroid_x_mm"].to_numpy(float) if "centroid_x_mm" in df else np.full(len(df), np.nan)
    planes = df.plane.to_numpy()
    out = [None] * len(df)
    for k in np.unique(planes):
        rows = np.flatnonzero(planes == k)
        if len(rows) == 1 and not np.isfinite(x[rows[0]]):
            out[rows[0]] = truth[k]
            continue
        near = [o for o in objects if abs(float(o["depth_offset_mm"]) - depths[k]) <= tol and "centre_x_mm" in o]
        pairs = sorted((abs(float(o["centre_x_mm"]) - x[r]), int(r), i) for r in rows if np.isfinite(x[r])
                       for i, o in enumerate(near))
        used = set()
        for _, r, i in pairs:
            if out[r] is None and i not in used:
                out[r] = near[i]
                used.add(i)
    return out


def value_label(route) -> str:
    """What the planes of ``route`` hold, with units: the label of ``profiles``' colour bar and profiles."""
    from ..routes import parse_route
    r = parse_route(route)
    if r.emission:
        return "emission (a.u.)"
    return "refocused radiance (a.u.)" if r.kind == "refocus" else "radiance (a.u.)"


def cmd_profiles(a):
    import pandas as pd
    from ..config import atomic_write_text
    cam, stack, depths, ms, objects, df = profiles_table(a)
    out = Path(a.out)
    atomic_write_text(f"{out}.csv", df.to_csv(index=False, float_format="%.5g"))
    axial = pd.DataFrame([dict(plane=k, depth_mm=d, height_mm=h, intensity=v)
                          for k, (m, d) in enumerate(zip(ms, depths)) if m is not None
                          for h, v in zip(m.axial_height_mm, m.axial_intensity)])
    atomic_write_text(f"{out}.axial.csv", axial.to_csv(index=False, float_format="%.5g"))
    if a.figure:
        from ..measure.figures import plot_profiles
        plot_profiles(f"{out}.png", cam, stack, depths, ms, objects, a.route, value_label(a.route))
    several = "flame" in df and bool((df.flame > 0).any())          # flames found apart on one plane: say which
    cols = [c for c in ("depth_mm", *(("flame",) if several else ()), "height_mm", "height_mm_true", "height_err_mm",
                        "max_width_mm", "centroid_x_mm", "integrated_intensity", "flags", "failure") if c in df]
    print(df[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"-> {out}.csv, {out}.axial.csv" + (f", {out}.png" if a.figure else ""))


def add_parsers(sub) -> None:
    """Add ``profiles`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("profiles", help="flame diagnostics per plane: height, widths, centroid, intensity, "
                       "axial and radial profiles in object-space mm (CSV and figure)")
    s.add_argument("raw", help=RAW_FORMATS + ", or views .h5 from 'lf-flame decode' (the truth is marked when the "
                   "flames' objects are known: 'simulate --scene flame' .npz, dataset samples)")
    s.add_argument("--route", choices=["ground-truth", "shift-sum", "shift-sum-nearest", "fourier",
                                       *LEARNED_ROUTES, *(f"reconstruct-{k}" for k in SOLVERS)],
                   default=PROFILES_ROUTE, help="how the planes are made. reconstruct-SOLVER: each plane's emission "
                   "(lf-flame reconstruct, the solver's default iterations; admm's finer grid averaged to the "
                   "lenslets); the default, reconstruct-admm, measured every flame height of 'simulate --scene "
                   "flame' (seeds 0-2) within 0.21 mm, where refocused planes carry the other flames' blur (shift-"
                   "sum: the +20 mm flame of seed 0 measured 13 mm short, flagged untrusted). shift-sum, "
                   "shift-sum-nearest, fourier: refocused planes (faster; reconstruct-adjoint is plain refocusing "
                   "too); ground-truth: a dataset's stored planes; learned routes need --model-dir")
    s.add_argument("--model-dir", help="folder written by 'lf-flame train' (learned routes)")
    s.add_argument("--slope", type=finite, action="append",
                   help="refocusing routes: one per plane (repeatable); default: the dataset's, else the analytic "
                   "slopes of the depths")
    s.add_argument("--depth", type=finite, action="append",
                   help="a plane's depth, mm from the focus distance (repeatable; default: the flames' when RAW "
                        "stores them, a dataset sample's the paper's four, else the depths found in the views, as "
                        "'reconstruct --depths auto' finds them)")
    s.add_argument("--depths", choices=("auto", "scene"), default=None,
                   help="the planes where no --depth or --slope is given: 'auto' finds them in the views as "
                        "'reconstruct --depths auto' does (within --search-range), the flames RAW stores still "
                        "scored beside them; 'scene' the stored flames' depths (the default where RAW stores them, "
                        "unless --search-range is given)")
    add_camera_args(s)
    s.add_argument("--out", required=True, help="PREFIX: writes PREFIX.csv (one row per plane and flame), "
                                               "PREFIX.axial.csv and PREFIX.png")
    s.set_defaults(out_is_prefix=True)
    add_figure_arg(s, "each plane with its height, widths and profiles marked")
    add_search_arg(s)
    s.set_defaults(func=cmd_profiles)
