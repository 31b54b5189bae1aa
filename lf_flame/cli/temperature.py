"""The temperature commands: ``calibrate-temperature`` (a blackbody calibration of
two colour channels from furnace images) and ``temperature`` (each plane's temperature map from
one colour light field, :mod:`lf_flame.temperature.channels` and :mod:`lf_flame.temperature.pyrometry`),
written to HDF5 with a figure.

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
    raw, _ = _load_raw(path)
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


def cmd_temperature(a):
    """``temperature RAW --calibration bb.json [--depths ...|auto] --out T.h5``."""
    import time

    import h5py

    from ..config import provenance
    from ..measure.figures import save_figure
    from ..temperature.pyrometry import bright_pixels, load_calibration, temperature_planes
    from ..optics.colour import CHANNELS
    from ..temperature.channels import (DECODED_KNOBS, DECODED_OFFSET_KNOBS, DECODED_RATIO_FILTER, channel_emission,
                                        route_operator)
    from ..temperature.mosaic import cfa_blind, channel_views, monochrome_light_field
    from .volume import found_planes, found_record, possible_warning, reconstruct_input, solve_found
    from ..tomo.decoded import fit_data
    src = str(a.raw)
    if not (src.endswith(".h5") and ".h5:" not in src):
        _refuse_monochrome(src)
    cal = load_calibration(a.calibration)
    sensor, where = _sensor(src, a, cal)
    cal.check_sensor(sensor)
    cal = load_calibration(a.calibration, sensor)      # also refuses a ratio with no unique temperature
    print(f"sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where}); calibration "
          f"{cal.channels[0]}/{cal.channels[1]}, gain ratio {cal.gain_ratio:.5f}")
    t0 = time.perf_counter()
    import argparse
    # --calibration is the blackbody calibration here; the lenslet grid's is --grid-calibration
    try:
        lf, depths, _ = reconstruct_input(argparse.Namespace(**{**vars(a), "calibration": a.grid_calibration}),
                                          colour=True)
    except ValueError as e:              # the light field's refusals name the grid's calibration by its flag here
        raise ValueError(str(e).replace("--calibration", "--grid-calibration")) from None
    cam, views = lf.camera, lf.views
    n = cam.pixels_per_lenslet
    if lf.decoded and lf.channels is None:
        raise ValueError(f"{src}: decoded views without their colour channels (a monochrome capture, or a colour one "
                         "decoded without its camera file): 'lf-flame decode RAW --camera cam.toml' keeps them apart "
                         "where the file's [sensor] names its cfa")
    chan = lf.channels if lf.decoded else channel_views((views.shape[2] * n, views.shape[3] * n), sensor, n)
    ch = tuple(CHANNELS.index(c) for c in cal.channels)
    hexagonal = lf if lf.lattice_views is not None and lf.channels is not None else None
    extra, found = {}, None
    if depths == "auto":                                # reconstruct's planes: the levelled channels' found route
        mono = monochrome_light_field(lf)
        _, _, found = found_planes(mono, search_range=a.search_range)
        found, _, _ = solve_found(mono, found)
        depths = [float(d) for d in found.planes_mm]
        extra = dict(depths_from="auto (as reconstruct: the channels levelled, depths found, the residual searched, "
                                 "refined)", found_depths=found_record(found), possible_depths=possible_warning(found))
    chosen, knobs, ratio_filter = {}, None, None
    slopes = [cam.slope_for_depth(d) for d in depths]
    op = route_operator(cam, depths, a.route, hexagonal, lf.sample_offsets if hexagonal is None else None)
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
        from ..tomo.found_planes import found_support
        support = found_support(found, cam, op.subsamples)
        if support is not None and hexagonal is not None:
            support = op.from_square(support)
        chosen["support"] = "none" if support is None else "near planes"
    emission = channel_emission(a.route, data, chan, ch, op=op, slopes=slopes, saturation=sat, info=chosen,
                                knobs=knobs, ratio_filter=ratio_filter, support=support)
    if hexagonal is not None:                           # the lattice's planes on the decoded square grid
        emission = tuple(op.to_square(e, cam.n_rows, cam.n_cols) for e in emission)
        chosen["lattice"] = "hexagonal"
    temp, valid, n_masked = temperature_planes(emission[0], emission[1], cal, sensor, a.alpha, a.min_fraction)
    dim = ~bright_pixels(emission[0] + emission[1], a.min_fraction)
    blind = cfa_blind(slopes, n)
    n_dim = dim.reshape(len(dim), -1).sum(axis=1)
    sample = np.array([np.asarray(cam.field_of_view_mm(d)) / (cam.n_rows, cam.n_cols) for d in depths])
    wall = time.perf_counter() - t0
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".part")
    from ..config import removed_on_error
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f["temperature_k"] = temp.astype(np.float32)
        f["temperature_k"].attrs.update(units="K", masked="NaN: no temperature (see valid, dim)")
        f["valid"] = valid
        f["dim"] = dim
        f["emission"] = np.stack(emission).astype(np.float32)
        f["emission"].attrs["channels"] = json.dumps(list(cal.channels))
        f["depths_mm"] = np.asarray(depths, float)
        f["sample_mm"] = sample
        f["n_masked"] = np.asarray(n_masked, np.int64)
        f["n_dim"] = np.asarray(n_dim, np.int64)
        f["cfa_blind"] = blind
        f["cfa_blind"].attrs["meaning"] = ("plane at a slope near an odd integer: half its lenslets have no sample of "
                                           "a CFA phase in any view (lf_flame.temperature.mosaic.cfa_blind)")
        attrs = dict(kind="lf_flame temperature", source=src, calibration=json.dumps(
            dict(path=str(a.calibration), **{k: getattr(cal, k) for k in cal.__dataclass_fields__})),
                     sensor=json.dumps(dict(name=sensor.name, pattern=sensor.pattern, phase=list(sensor.phase),
                                            where=where)),
                     route=a.route, route_settings=json.dumps(chosen), alpha=float(a.alpha),
                     min_fraction=float(a.min_fraction),
                     saturation=_level_record(a.saturation, lf), camera=cam.to_json(),
                     time_s=wall, provenance=json.dumps(provenance()),
                     axes="temperature_k, valid, dim: (plane, lenslet row, lenslet col); emission: (channel, plane, "
                          "row, col); sample_mm: (plane, [height, width]) mm per lenslet sample",
                     **{k: json.dumps(v, default=float) for k, v in extra.items()})
        for k, v in attrs.items():
            f.attrs[k] = v
    tmp.replace(out)
    fig = out.with_suffix(".png") if a.figure else None
    if fig is not None:
        save_figure(temperature_figure(temp, depths, valid, cam), fig)
    for k, d in enumerate(depths):
        v = temp[k][valid[k]]
        stats = (f"median {np.median(v):.0f} K, p10-p90 {np.percentile(v, 10):.0f}-{np.percentile(v, 90):.0f} K"
                 if v.size else "no temperature")
        print(f"plane {k} ({d:+.2f} mm): {int(valid[k].sum())} px with a temperature, {stats}; {int(n_masked[k])} "
              f"bright px masked (ratio out of the table), {int(n_dim[k])} px below {a.min_fraction:g} of the peak"
              + (f"; WARNING: slope {slopes[k]:+.3f} near an odd integer, half its lenslets have no red "
                 "sample in any view (cfa_blind): its temperature is interpolation there" if blind[k] else ""))
    print(f"temperature of {len(depths)} planes ({a.route} {chosen}) in {wall:.1f} s -> {out}"
          + (f", {fig}" if fig else ""))


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
                   "capture decoded with its channels apart ('lf-flame decode --camera cam.toml') with --camera")
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
                   "depths_mm, counts, provenance; the figure goes beside it as .png")
    add_figure_arg(s, "each plane's temperature map in mm, one colour bar in K")
    add_search_arg(s)
    s.set_defaults(func=cmd_temperature)
