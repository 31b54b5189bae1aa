"""The temperature commands: ``calibrate-temperature`` (a blackbody calibration of
two colour channels from furnace images) and ``temperature`` (each plane's temperature map from
one colour light field, or from each frame of a recording, :mod:`lf_flame.temperature.channels` and
:mod:`lf_flame.temperature.pyrometry`), written to HDF5 with a figure.

The colour sensor of an image (sensitivities, CFA pattern and phase) is, in order: the
``--sensor``/``--cfa``/``--cfa-phase`` options, the ``sensor`` record stored beside the raw
image (``.npz`` key or PNG text ``lf_flame.sensor``), the calibration's (``temperature``
only, said so), else colour-science's Nikon 5100 behind an RGGB CFA of phase (0, 0).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from ._io import (AUTO_LEVEL, RAW_FORMATS, _level_or_none, _load_raw, _raw_meta, add_figure_arg, add_search_arg,
                  fraction)

#: what the ``temperature`` HDF5 holds (its datasets)
TEMPERATURE_DATASETS = ("temperature_k", "valid", "dim", "emission", "depths_mm", "sample_mm", "n_masked", "n_dim")


def _sensor(path, a, cal=None):
    """The colour sensor of the image at ``path`` and a phrase saying where it came from."""
    from ..optics.colour import DEFAULT_SENSITIVITIES, library_sensor
    meta = _raw_meta(path)
    if str(path).endswith(".h5") and Path(path).is_file():          # decoded views: the sensor decode stored
        import h5py
        with h5py.File(path, "r") as f:
            meta = {"sensor": str(f.attrs["sensor"])} if "sensor" in f.attrs else {}
    rec = json.loads(meta["sensor"]) if "sensor" in meta else {}
    given = {k: v for k, v in (("name", a.sensor), ("pattern", a.cfa),
                               ("phase", None if a.cfa_phase is None else tuple(a.cfa_phase))) if v is not None}
    if rec:
        where = f"stored in {path}"
    elif cal is not None:
        rec = dict(name=cal.sensor_name, pattern=cal.pattern, phase=tuple(cal.phase))
        where = f"{path} records none: the calibration's"
    else:
        rec = dict(name=DEFAULT_SENSITIVITIES, pattern="RGGB", phase=(0, 0))
        where = f"{path} records none: the default"
    if given:
        where = "given" + ("" if len(given) == 3 else f" ({', '.join(given)}; the rest {where})")
    rec = {**rec, **given}
    return library_sensor(rec["name"], rec["pattern"], tuple(rec["phase"])), where


def _channels(text: str):
    ch = tuple(c.strip().upper() for c in str(text).split(","))
    from ..optics.colour import CHANNELS
    if len(ch) != 2 or any(c not in CHANNELS for c in ch) or ch[0] == ch[1]:
        raise ValueError(f"--channels takes two different channels of {', '.join(CHANNELS)} as A,B. Received: {text!r}")
    return ch


#: Relative spread of a raw image's four 2 x 2 phase means (over its lit pixels) below which it holds no colour
#: filter mosaic: a monochrome sensor's phases differ by noise alone; a Bayer mosaic of flame light by tens of %.
MOSAIC_SPREAD = 0.01


def _refuse_monochrome(path):
    """Refuse a light field without colour channels: one ``lf-flame simulate`` rendered monochrome
    (its record holds a camera and no sensor), or an image whose four 2 x 2 pixel phases have the
    same mean over its lit pixels (within :data:`MOSAIC_SPREAD`): no mosaic to take a ratio of."""
    meta = _raw_meta(path)
    if "camera" in meta and "sensor" not in meta:
        raise ValueError(f"{path} is a monochrome light field (rendered without a colour sensor): two-colour "
                         "pyrometry needs a colour (Bayer) capture")
    _refuse_no_mosaic(_load_raw(path)[0], path)


def _refuse_no_mosaic(raw, path):
    """Refuse a raw image (named ``path``) whose four 2 x 2 pixel phases have the same mean over its lit pixels
    (within :data:`MOSAIC_SPREAD`): a monochrome sensor's."""
    lit = raw > 0.1 * float(raw.max()) if raw.max() > 0 else np.zeros(raw.shape, bool)
    means = []
    for i in (0, 1):
        for j in (0, 1):
            m = lit[i::2, j::2]
            means.append(float(raw[i::2, j::2][m].mean()) if m.any() else np.nan)
    means = np.asarray(means)
    if np.all(np.isfinite(means)) and np.ptp(means) <= MOSAIC_SPREAD * means.mean():
        raise ValueError(f"{path} holds no colour filter mosaic (its four 2 x 2 pixel phases have the same mean, "
                         f"within {100 * MOSAIC_SPREAD:g} %): a monochrome light field has no two colour channels "
                         "to take a ratio of")


def cmd_calibrate_temperature(a):
    """``calibrate-temperature BB... --temperature T... --out bb.json``."""
    from ..temperature.pyrometry import blackbody_ratio, fit_calibration, write_calibration
    from ..optics.camera import PAPER_CAMERA
    temps = list(a.temperature or [])
    if len(temps) != len(a.images):
        raise ValueError(f"one --temperature per blackbody image is needed: {len(a.images)} images, {len(temps)} "
                         "temperatures")
    channels = _channels(a.channels)
    ratios, sensor0 = [], None
    for path, t in zip(a.images, temps):
        raw, cam = (None, None) if str(path).endswith(".h5") else _load_raw(path)
        sensor, where = _sensor(path, a)
        if sensor0 is not None and (sensor.name, sensor.pattern, sensor.phase) != (
                sensor0.name, sensor0.pattern, sensor0.phase):
            raise ValueError(f"{path} is from sensor {sensor.name!r} {sensor.pattern} phase {sensor.phase}, the first "
                             f"image from {sensor0.name!r} {sensor0.pattern} phase {sensor0.phase}: one camera per "
                             "calibration")
        sensor0 = sensor
        if str(path).endswith(".h5"):                                 # a colour capture decoded with its channels
            from ..real.views_file import load_channels, load_lattice, load_views
            from ..temperature.pyrometry import views_blackbody_ratio
            v, chan = load_lattice(path)[0], load_channels(path)      # a hexagonal grid's channels: on its lattice
            if v is None:
                v = load_views(path)[0]
            if chan is None:
                raise ValueError(f"{path}: decoded views without their colour channels ('lf-flame decode --camera "
                                 "cam.toml' keeps them apart)")
            r = views_blackbody_ratio(v, chan, channels)
        else:
            if cam is not None and not cam.perfect_grid:
                raise ValueError(f"{path} is a raw image of a camera whose lenslet grid is not a perfect one (rotated, "
                                 "hexagonal, or lenslet images no whole number of pixels apart): decode it first "
                                 "('lf-flame decode IMAGE --calibration cal.json --camera cam.toml --out VIEWS.h5') "
                                 "and give the VIEWS.h5")
            r = blackbody_ratio(raw, sensor, (cam or PAPER_CAMERA).pixels_per_lenslet, channels)
        ratios.append(r)
        print(f"{path}: {t:g} K, {channels[0]}/{channels[1]} = {r:.5f} (sensor {sensor.name}, {sensor.pattern} "
              f"phase {sensor.phase}: {where})")
    try:
        cal = fit_calibration(sensor0, temps, ratios, channels)
    except ValueError as err:           # a colour filter array read at the wrong phase: say which phase fits
        raise ValueError(f"{err}{_fitting_phases(a.images, temps, sensor0, channels)}") from None
    out = write_calibration(a.out, cal)
    print(f"gain ratio {cal.gain_ratio:.5f}; fit residuals " + ", ".join(f"{x:+.2f}" for x in cal.fit_residuals_k)
          + f" K -> {out}")


def _fitting_phases(images, temps, sensor, channels) -> str:
    """For raw blackbody images refused by :func:`~lf_flame.temperature.pyrometry.fit_calibration`: the other CFA
    phases of the same pattern under which they fit, with their largest residual (K), as a sentence ('' for
    decoded views, whose channels were fixed when decoded, or where none fits)."""
    import dataclasses

    from ..optics.camera import PAPER_CAMERA
    from ..temperature.pyrometry import blackbody_ratio, fit_calibration
    if any(str(p).endswith(".h5") for p in images):
        return ""
    raws = [_load_raw(p) for p in images]
    fits = []
    for phase in ((0, 0), (0, 1), (1, 0), (1, 1)):
        if phase == tuple(sensor.phase):
            continue
        other = dataclasses.replace(sensor, phase=phase)
        try:
            cal = fit_calibration(other, temps, [blackbody_ratio(raw, other, (cam or PAPER_CAMERA).pixels_per_lenslet,
                                                                 channels) for raw, cam in raws], channels)
        except ValueError:
            continue
        fits.append(f"{phase} (residuals within {max(abs(x) for x in cal.fit_residuals_k):.1f} K)")
    return f". These images fit at phase {' and '.join(fits)}" if fits else ""


#: What the temperature figure's grey area is (its legend entry).
NO_TEMPERATURE = "no temperature: dim, or a ratio outside the calibration"


def temperature_figure(temperature_k, depths_mm, valid, camera=None, truth_k=None):
    """``temperature``'s figure: each plane's temperature map in object-space mm, one colour bar in K.

    Pixels without a temperature (NaN) are grey, named by a legend entry (:data:`NO_TEMPERATURE`).
    With a truth, its maps form a second row on the same colour scale.

    Parameters
    ----------
    temperature_k : ndarray of shape (P, rows, cols)
        Temperature (K), NaN where none was estimated.
    depths_mm : sequence of P float
        The planes' depths (mm from the focal plane).
    valid : ndarray of bool, shape (P, rows, cols)
        Where a temperature was estimated (counted in the titles).
    camera : PlenopticCamera or None
        The planes' camera: axes in mm (:func:`lf_flame.measure.figures.plane_extent_mm`); None: lenslets.
    truth_k : ndarray of shape (P, rows, cols) or None
        The true temperature (K) on the same planes, NaN where the scene has none.

    Returns
    -------
    matplotlib.figure.Figure
        Axes: the panels row by row (estimate, then truth), then the colour bar's.
    """
    from ..measure.figures import plane_extent_mm, planes_figure, signed
    t = np.asarray(temperature_k, float)
    rows = [t] if truth_k is None else [t, np.asarray(truth_k, float)]
    finite = np.concatenate([r[np.isfinite(r)] for r in rows])
    lo, hi = np.percentile(finite, [1, 99]) if finite.size else (1500.0, 2500.0)
    extents = None if camera is None else [plane_extent_mm(camera, d) for d in depths_mm]
    titles = [[f"estimate {signed(d)} mm\n{int(np.sum(v))} px with T" for d, v in zip(depths_mm, valid)],
              [f"truth {signed(d)} mm" for d in depths_mm]][:len(rows)]
    return planes_figure(rows, extents, titles, "temperature (K)", vmin=float(lo), vmax=float(max(hi, lo + 1)),
                         bad_label=NO_TEMPERATURE)


def _level_record(saturation, lf) -> str | float:
    """What ``--saturation`` the file records: the level used (found in a raw image where 'auto'), or what a decoded
    capture's clipped samples came from."""
    if lf.decoded:
        return "decoded: the views' clipped samples"
    level = lf.saturation if saturation == "auto" else saturation
    return "none" if level is None else float(level)


def _plane_temperatures(a, lf, depths, found, cal, sensor, cache=None) -> dict:
    """Each plane's temperature of one colour light field ``lf`` on ``depths`` (``found``: the
    :class:`~lf_flame.tomo.depth.FoundDepths` they came from, or None) by ``a.route``: the channels' emission
    (:func:`lf_flame.temperature.channels.channel_emission`) and their ratio through ``cal``
    (:func:`lf_flame.temperature.pyrometry.temperature_planes`). ``cache``: a dict that keeps what the next light field
    of the same camera and planes (a recording's frames) shares: the route's operator, a raw mosaic's channel map and
    the found planes' support.

    Returns
    -------
    dict
        ``temp`` (P, R, C) K, NaN where none; ``valid``, ``dim`` (P, R, C) bool; ``n_masked``, ``n_dim`` (P,);
        ``emission`` (2, P, R, C); ``chosen`` (the route's settings); ``slopes``, ``blind`` (P,); ``sample`` (P, 2) mm.
    """
    from ..measure.diagnostics import lenslet_size_mm
    from ..optics.colour import CHANNELS
    from ..temperature.pyrometry import bright_pixels, temperature_planes
    from ..temperature.channels import (DECODED_KNOBS, DECODED_OFFSET_KNOBS, DECODED_RATIO_FILTER, channel_emission,
                                        route_operator)
    from ..temperature.mosaic import cfa_blind, channel_views
    from ..tomo.decoded import fit_data
    cam, views = lf.camera, lf.views
    n = cam.pixels_per_lenslet
    cache = {} if cache is None else cache
    if not lf.decoded and "chan" not in cache:
        cache["chan"] = channel_views((views.shape[2] * n, views.shape[3] * n), sensor, n)
    chan = lf.channels if lf.decoded else cache["chan"]
    ch = tuple(CHANNELS.index(c) for c in cal.channels)
    hexagonal = lf if lf.lattice_views is not None and lf.channels is not None else None
    chosen, knobs, ratio_filter = {}, None, None
    slopes = [cam.slope_for_depth(d) for d in depths]
    if "op" not in cache:
        cache["op"] = route_operator(cam, depths, a.route, hexagonal, lf.sample_offsets if hexagonal is None else None)
    op = cache["op"]
    if getattr(op, "offset_bins", None):                # each sample at its own pixel: recorded with the route
        chosen["sub_views"] = op.offset_bins
    if not lf.decoded:                                  # the level given, and the image's defective pixels
        given = lf if a.saturation == "auto" else dataclasses.replace(lf, saturation=a.saturation)
        data, sat = views, given.fit_mask()
    elif op is None:                                    # refocus-cfa: the decoded views as they are
        data, sat = views, None
    elif hexagonal is not None:                         # the lattice's views (axial), its channels with them
        from ..tomo.lattice import lattice_problem, to_axial
        data, sat = lattice_problem(lf, op)
        chan = np.where(op.inside, to_axial(chan)[0], -1).astype(np.int8)
    else:                                               # the operator's data: views times its white views
        data, sat = fit_data(lf, op)
    if lf.decoded and a.route == "admm-cfa-matched":    # a decoded capture's knobs, not its noise's
        knobs, ratio_filter = DECODED_OFFSET_KNOBS if op.offset_bins else DECODED_KNOBS, DECODED_RATIO_FILTER
        chosen["regime"] = "decoded"
    support = None
    if found is not None and op is not None:
        # found planes near each other held to their own regions where they meet, as reconstruct holds them (a
        # hexagonal grid's taken from the decoded square grid to its lattice)
        if "support" not in cache:
            from ..tomo.found_planes import found_support
            support = found_support(found, cam, op.subsamples)
            cache["support"] = op.from_square(support) if support is not None and hexagonal is not None else support
        support = cache["support"]
        chosen["support"] = "none" if support is None else "near planes"
    emission = channel_emission(a.route, data, chan, ch, op=op, slopes=slopes, saturation=sat, info=chosen,
                                knobs=knobs, ratio_filter=ratio_filter, support=support)
    if hexagonal is not None:                           # the lattice's planes on the decoded square grid
        emission = tuple(op.to_square(e, cam.n_rows, cam.n_cols) for e in emission)
        chosen["lattice"] = "hexagonal"
    temp, valid, n_masked = temperature_planes(emission[0], emission[1], cal, sensor, a.alpha, a.min_fraction)
    dim = ~bright_pixels(emission[0] + emission[1], a.min_fraction)
    return dict(temp=temp, valid=valid, n_masked=n_masked, dim=dim, n_dim=dim.reshape(len(dim), -1).sum(axis=1),
                emission=emission, chosen=chosen, slopes=slopes, blind=cfa_blind(slopes, n),
                sample=np.array([[lenslet_size_mm(cam, d)] * 2 for d in depths]))


def _auto_depths(a, lf):
    """``--depths auto``: reconstruct's planes of the colour light field ``lf`` (its channels levelled, the depths
    found, the residual searched, refined): (depths, found, the record's extra attributes)."""
    from ..temperature.mosaic import monochrome_light_field
    from .volume import found_planes, found_record, possible_warning, solve_found
    mono = monochrome_light_field(lf)
    _, _, found = found_planes(mono, search_range=a.search_range)
    found, _, _ = solve_found(mono, found)
    extra = dict(depths_from="auto (as reconstruct: the channels levelled, depths found, the residual searched, "
                             "refined)", found_depths=found_record(found), possible_depths=possible_warning(found))
    return [float(d) for d in found.planes_mm], found, extra


def _plane_lines(a, depths, r) -> list:
    """The printout's line per plane: its pixels with a temperature, their median and p10-p90, and the pixels left
    without one (:func:`_plane_temperatures`' ``r``)."""
    lines = []
    for k, d in enumerate(depths):
        v = r["temp"][k][r["valid"][k]]
        stats = (f"median {np.median(v):.0f} K, p10-p90 {np.percentile(v, 10):.0f}-{np.percentile(v, 90):.0f} K"
                 if v.size else "no temperature")
        lines.append(f"plane {k} ({d:+.2f} mm): {int(r['valid'][k].sum())} px with a temperature, {stats}; "
                     f"{int(r['n_masked'][k])} bright px masked (ratio out of the table), {int(r['n_dim'][k])} px "
                     f"below {a.min_fraction:g} of the peak"
                     + (f"; WARNING: slope {r['slopes'][k]:+.3f} near an odd integer, half its lenslets have no red "
                        "sample in any view (cfa_blind): its temperature is interpolation there" if r["blind"][k]
                        else ""))
    return lines


def cmd_temperature(a):
    """``temperature RAW --calibration bb.json [--depths ...|auto] --out T.h5``; a recording (an HDF5 stack, a
    multi-page TIFF, a folder of frames): each frame's planes, :func:`_temperature_recording`."""
    import time

    import h5py

    from ..config import provenance
    from ..measure.figures import save_figure
    from ..temperature.pyrometry import load_calibration
    from .volume import reconstruct_input
    src = str(a.raw)
    recording = _recording(src)
    if recording is None and not (src.endswith(".h5") and ".h5:" not in src):
        _refuse_monochrome(src)
    cal = load_calibration(a.calibration)
    sensor, where = _sensor(src, a, cal)
    cal.check_sensor(sensor)
    cal = load_calibration(a.calibration, sensor)      # also refuses a ratio with no unique temperature
    print(f"sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where}); calibration "
          f"{cal.channels[0]}/{cal.channels[1]}, gain ratio {cal.gain_ratio:.5f}")
    if recording is not None:
        return _temperature_recording(a, *recording, cal, sensor, where)
    if getattr(a, "fps", None) is not None:
        raise ValueError("--fps goes with a recording (an HDF5 stack of frames, a multi-page TIFF or a folder)")
    t0 = time.perf_counter()
    import argparse
    # --calibration is the blackbody calibration here; the lenslet grid's is --grid-calibration
    try:
        lf, depths, _ = reconstruct_input(argparse.Namespace(**{**vars(a), "calibration": a.grid_calibration}),
                                          colour=True)
    except ValueError as e:              # the light field's refusals name the grid's calibration by its flag here
        raise ValueError(str(e).replace("--calibration", "--grid-calibration")) from None
    if lf.decoded and lf.channels is None:
        raise ValueError(f"{src}: decoded views without their colour channels (a monochrome capture, or a colour one "
                         "decoded without its camera file): 'lf-flame decode RAW --camera cam.toml' keeps them apart "
                         "where the file's [sensor] names its cfa")
    extra, found = {}, None
    if depths == "auto":                                # reconstruct's planes: the levelled channels' found route
        depths, found, extra = _auto_depths(a, lf)
    r = _plane_temperatures(a, lf, depths, found, cal, sensor)
    cam, temp, valid = lf.camera, r["temp"], r["valid"]
    wall = time.perf_counter() - t0
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    from ..config import removed_on_error
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f["temperature_k"] = temp.astype(np.float32)
        f["temperature_k"].attrs.update(units="K", masked="NaN: no temperature (see valid, dim)")
        f["valid"] = valid
        f["dim"] = r["dim"]
        f["emission"] = np.stack(r["emission"]).astype(np.float32)
        f["emission"].attrs["channels"] = json.dumps(list(cal.channels))
        f["depths_mm"] = np.asarray(depths, float)
        f["sample_mm"] = r["sample"]
        f["n_masked"] = np.asarray(r["n_masked"], np.int64)
        f["n_dim"] = np.asarray(r["n_dim"], np.int64)
        f["cfa_blind"] = r["blind"]
        f["cfa_blind"].attrs["meaning"] = ("plane at a slope near an odd integer: half its lenslets have no sample of "
                                           "a CFA phase in any view (lf_flame.temperature.mosaic.cfa_blind)")
        attrs = dict(kind="lf_flame temperature", source=src, **_record(a, cal, sensor, where, r["chosen"]),
                     saturation=_level_record(a.saturation, lf), camera=cam.to_json(), time_s=wall,
                     provenance=json.dumps(provenance()),
                     axes="temperature_k, valid, dim: (plane, lenslet row, lenslet col); emission: (channel, plane, "
                          "row, col); sample_mm: (plane, [height, width]) mm per lenslet sample",
                     **{k: json.dumps(v, default=float) for k, v in extra.items()})
        for k, v in attrs.items():
            f.attrs[k] = v
    tmp.replace(out)
    fig = out.with_suffix(".png") if a.figure else None
    if fig is not None:
        save_figure(temperature_figure(temp, depths, valid, cam), fig)
    print("\n".join(_plane_lines(a, depths, r)))
    print(f"temperature of {len(depths)} planes ({a.route} {r['chosen']}) in {wall:.1f} s -> {out}"
          + (f", {fig}" if fig else ""))


def _recording(src):
    """``(source, attrs)`` of the recording at ``src`` (:func:`lf_flame.recordings.sources.open_source`: a folder of
    frames, an HDF5 file holding a ``frames`` stack, a TIFF of more than one page), else None (one capture)."""
    p = Path(src)
    suffix = p.suffix.lower()
    if p.is_file() and suffix == ".h5":
        import h5py

        from ..config import reading
        with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
            if "frames" not in f:
                return None
    elif not (p.is_dir() or (p.is_file() and suffix in (".tif", ".tiff"))):
        return None
    from ..recordings.sources import open_source
    source, attrs = open_source(p)
    return None if suffix in (".tif", ".tiff") and source.n_frames < 2 else (source, attrs)


def _temperature_recording(a, source, attrs, cal, sensor, where):
    """``temperature RECORDING``: each frame's planes' temperature (:func:`_plane_temperatures`, the route's operator
    built once), on the planes given or found in the first frame, each frame decoded with ``--grid-calibration``
    where the camera's grid is not a perfect one. Writes ``--out`` (HDF5: ``temperature_k`` and ``valid`` (frame,
    plane, row, col), ``depths_mm``, ``times_s``), its ``.csv`` (per frame and plane: the pixels with a
    temperature, their median, p10 and p90, K) and figure (each plane's median over time); prints each plane's
    dominant frequency of its median temperature (:func:`lf_flame.recordings.flicker.spectra`)."""
    import time

    import h5py
    import pandas as pd
    from tqdm.auto import tqdm

    from ..config import atomic_write_text, provenance, removed_on_error
    from ..optics.camera import PAPER_CAMERA, PlenopticCamera
    from ..real.lightfield import decode_capture, from_raw
    from ..recordings.flicker import peaks, spectra
    from ..recordings.sources import source_frame_rate
    from .volume import planes_from_args
    src, t0 = str(a.raw), time.perf_counter()
    if "sequence" in attrs and "sensor" not in attrs:
        raise ValueError(f"{src} is a monochrome recording (rendered without a colour sensor): two-colour pyrometry "
                         "needs a colour (Bayer) recording")
    if a.camera:
        from ..optics.camera_file import load_camera_file
        cam, cam_file = load_camera_file(a.camera), str(Path(a.camera).resolve())
    else:
        cam, cam_file = (PlenopticCamera.from_dict(json.loads(attrs["camera"])) if "camera" in attrs
                         else PAPER_CAMERA), None
    grid = images = None
    if a.grid_calibration:
        from ..real.calibration import GridCalibration
        from ..real.images import calibration_image_path
        from ..recordings.sources import decoding_images
        grid = GridCalibration.load(a.grid_calibration)
        images = decoding_images(calibration_image_path(grid.white, "white"),     # in the frames' units
                                 calibration_image_path(grid.dark, "dark"))
    fps = source_frame_rate(source, attrs, a.fps)
    depths, found, extra, cache, rows, temps, valids = None, None, {}, {}, [], [], []
    for i, raw in enumerate(tqdm(source.frames(0, source.n_frames), total=source.n_frames, desc="temperature",
                                 unit="frame", disable=None)):
        raw = np.asarray(raw, np.float64)
        name = f"{src} frame {i}"
        try:
            lf = (from_raw(raw, cam, name, camera_file=cam_file, sensor=sensor) if grid is None else
                  decode_capture(raw, cam, grid, sensor, name, images))
        except ValueError as e:
            raise ValueError(str(e).replace("--calibration", "--grid-calibration")) from None
        if depths is None:                                  # the planes: given, or found in the first frame
            _refuse_no_mosaic(raw, name)
            stored = json.loads(attrs["sequence"]).get("flames") if "sequence" in attrs else None  # a simulated one
            depths = planes_from_args(a, lf.camera, stored)
            if depths == "auto":
                depths, found, extra = _auto_depths(a, lf)
        r = _plane_temperatures(a, lf, depths, found, cal, sensor, cache)
        temps.append(r["temp"].astype(np.float32))
        valids.append(r["valid"])
        for k, d in enumerate(depths):
            v = r["temp"][k][r["valid"][k]]
            q = np.percentile(v, [10, 50, 90]) if v.size else (np.nan,) * 3
            rows.append(dict(frame=i, time_s=i / fps, plane=k, depth_mm=d, n_px=int(v.size), median_k=float(q[1]),
                             p10_k=float(q[0]), p90_k=float(q[2])))
    df = pd.DataFrame(rows)
    wall = time.perf_counter() - t0
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f["temperature_k"] = np.stack(temps)
        f["temperature_k"].attrs.update(units="K", masked="NaN: no temperature (see valid)")
        f["valid"] = np.stack(valids)
        f["depths_mm"] = np.asarray(depths, float)
        f["times_s"] = np.arange(len(temps)) / fps
        attrs_out = dict(kind="lf_flame temperature recording", source=src, fps=float(fps),
                         **_record(a, cal, sensor, where, r["chosen"]), saturation=_level_record(a.saturation, lf),
                         camera=lf.camera.to_json(), time_s=wall,
                         provenance=json.dumps(provenance()),
                         axes="temperature_k, valid: (frame, plane, lenslet row, lenslet col)",
                         **{k: json.dumps(v, default=float) for k, v in extra.items()})
        for k, v in attrs_out.items():
            f.attrs[k] = v
    tmp.replace(out)
    atomic_write_text(out.with_suffix(".csv"), df.to_csv(index=False))
    fig = out.with_suffix(".png") if a.figure else None
    if fig is not None:
        from ..measure.figures import save_figure
        save_figure(_recording_figure(df), fig)
    if len(temps) > 1:
        pk = peaks(spectra(df, fps, signals=("median_k",)))
        print(pk[["plane", "depth_mm", "bin_hz", "dominant_hz", "amplitude"]].to_string(
            index=False, float_format=lambda v: f"{v:.3g}"))
    med = df.groupby("plane").median_k
    for k, d in enumerate(depths):
        print(f"plane {k} ({d:+.2f} mm): median temperature over the frames {med.median()[k]:.0f} K "
              f"(frames' medians {med.min()[k]:.0f}-{med.max()[k]:.0f} K)")
    print(f"temperature of {len(depths)} planes in {len(temps)} frames ({a.route}) in {wall:.1f} s "
          f"({len(temps) / wall:.2f} frames/s) -> {out}, {out.with_suffix('.csv')}" + (f", {fig}" if fig else ""))


def _recording_figure(df):
    """Each plane's median temperature over a recording's frames, its p10-p90 band shaded."""
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for (k, d), g in df.groupby(["plane", "depth_mm"], sort=True):
        line, = ax.plot(g.time_s, g.median_k, label=f"plane {k} ({d:+.1f} mm)")
        ax.fill_between(g.time_s, g.p10_k, g.p90_k, color=line.get_color(), alpha=0.2)
    ax.set(xlabel="time (s)", ylabel="temperature (K): median, p10-p90")
    ax.legend(fontsize="small")
    fig.tight_layout()
    return fig


def _record(a, cal, sensor, where, chosen) -> dict:
    """What a temperature file records of its calibration, sensor and route (HDF5 attributes)."""
    return dict(calibration=json.dumps(dict(path=str(a.calibration),
                                            **{k: getattr(cal, k) for k in cal.__dataclass_fields__})),
                sensor=json.dumps(dict(sensor.record(), where=where)),
                route=a.route, route_settings=json.dumps(chosen), alpha=float(a.alpha),
                min_fraction=float(a.min_fraction))


def _sensor_args(s, calibration_default):
    s.add_argument("--sensor", help="camera sensitivities (a name of colour-science's MSDS_CAMERA_SENSITIVITIES, "
                   "e.g. 'Nikon 5100 (NPL)'); default: the image's stored sensor record"
                   + (", else the calibration's" if calibration_default else "") + ", else Nikon 5100 (NPL)")
    s.add_argument("--cfa", choices=["RGGB", "BGGR", "GRBG", "GBRG"], help="colour filter array (default: as "
                   "--sensor)")
    s.add_argument("--cfa-phase", type=int, nargs=2, metavar=("ROW", "COL"),
                   help="tile row and column (0 or 1) of pixel (0, 0) (default: as --sensor, else 0 0)")


def add_parsers(sub) -> None:
    """Add ``calibrate-temperature`` and ``temperature`` to ``sub``, the sub-parsers of
    :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("calibrate-temperature", help="two-colour temperature calibration (the channels' gain "
                       "ratio) from raw images of a blackbody (furnace) at known temperatures -> JSON")
    s.add_argument("images", nargs="+", help="raw colour images of a blackbody filling the field: " + RAW_FORMATS
                   + "; a camera whose lenslet grid is not perfect (rotated, hexagonal, a pitch of no whole number of "
                   "pixels): its images decoded with their channels apart ('lf-flame decode --camera cam.toml')")
    s.add_argument("--temperature", type=float, action="append", help="each image's temperature, K, in the images' "
                   "order (repeatable; one per image)")
    s.add_argument("--channels", default="R,G", help="numerator and denominator channels of the ratio")
    _sensor_args(s, False)
    s.add_argument("--out", required=True, help="calibration JSON (read by 'lf-flame temperature')")
    s.set_defaults(func=cmd_calibrate_temperature)

    s = sub.add_parser("temperature", help="each plane's temperature map (K) from one colour light field by "
                       "two-colour pyrometry -> HDF5 and a figure")
    s.add_argument("raw", help="raw colour image (the CFA's mosaic): " + RAW_FORMATS + "; or VIEWS.h5 of a colour "
                   "capture decoded with its channels apart ('lf-flame decode --camera cam.toml') with --camera; or a "
                   "recording of raw colour frames (an HDF5 file with a 'frames' stack (T, H, W), a multi-page TIFF, "
                   "a folder of frames): each frame's planes, on the planes given or found in its first frame")
    s.add_argument("--calibration", required=True, help="JSON of 'lf-flame calibrate-temperature'; refused when "
                   "made for another sensor or CFA")
    s.add_argument("--camera", help="camera file (docs/own_camera.md) of decoded views (VIEWS.h5), or of a raw image "
                   "that stores none")
    s.add_argument("--grid-calibration", help="the white-image calibration JSON of 'lf-flame calibrate' (--calibration "
                   "is the blackbody's here): a raw capture is decoded with it, its channels apart, as 'lf-flame "
                   "decode --camera' decodes it")
    s.add_argument("--depth", type=float, action="append", help="plane depth (mm from the focal plane; repeatable). "
                   "Default: --depths auto")
    s.add_argument("--depths", default=None, help="'auto' (default): the planes 'lf-flame reconstruct' finds in the "
                   "capture (its red and green samples levelled into one light field, depths found, the solve's "
                   "residual searched, flames one behind another refined); 'scene', 'paper', or depths in mm "
                   "separated by commas (as 'lf-flame reconstruct')")
    s.add_argument("--slope", type=float, action="append", help="plane slope instead of a depth (repeatable)")
    s.add_argument("--route", choices=["admm-cfa-matched", "admm-cfa", "admm-cfa-smooth", "refocus-cfa"],
                   default="admm-cfa-matched",
                   help="each channel's emission: the exact operator's admm on its own pixels (the CFA as a "
                        "missing-data mask) on a 2 x 2 grid per lenslet, re-imaged and solved again on the other "
                        "channel's pixels so that both channels' resolution matches, its settings and ratio "
                        "filter by the light field's noise (decoded captures: their own); admm on its own pixels "
                        "alone, unsmoothed or smoothed by 0.7 lenslet; or each channel's pixels refocused (a "
                        "square grid's only) (results/temperature.md)")
    s.add_argument("--min-fraction", type=fraction, default=0.1, help="pixels whose two channels' emission is below "
                   "this fraction (0 to 1) of their plane's peak get no temperature (counted as dim)")
    s.add_argument("--alpha", type=float, default=1.39, help="emissivity exponent of the source, eps ~ lambda^-alpha "
                   "(soot: 1.39, Hottel & Broughton; 0: a blackbody)")
    s.add_argument("--saturation", type=_level_or_none, default="auto", help="the sensor's clipping level of a raw "
                   "image: pixels at or above it are left out of the fit ('none': fit every pixel; default "
                   + "auto: " + AUTO_LEVEL + ")")
    _sensor_args(s, True)
    s.add_argument("--out", required=True, help="T.h5: temperature_k, valid, dim (plane, row, col), emission, "
                   "depths_mm, counts, provenance; the figure goes beside it as .png. A recording's: temperature_k and "
                   "valid (frame, plane, row, col), depths_mm, times_s, and T.csv (per frame and plane: median, p10, "
                   "p90 K)")
    s.add_argument("--fps", type=float, help="a recording's frame rate, frames/s (default: its file's)")
    add_figure_arg(s, "each plane's temperature map in mm, one colour bar in K")
    add_search_arg(s)
    s.set_defaults(func=cmd_temperature)
