"""The ``temperature`` command: each plane's temperature map from one colour light field, written to HDF5 with
a figure (:mod:`.temperature_planes`); a recording's frames in :mod:`.temperature_recording`, the blackbody
calibration (``calibrate-temperature``) in :mod:`.temperature_calibration`.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from ._io import RAW_FORMATS, planes_count
from .options import AUTO_LEVEL, _level_or_none, add_figure_arg, add_search_arg, fraction, finite
from .temperature_planes import (_auto_depths, fit_warnings, given_planes_found, _level_record, _plane_lines,
                                 furnace_note, _plane_temperatures, _record, _refuse_monochrome, _sensor, _sensor_args,
                                 temperature_figure)


def cmd_temperature(a):
    """``temperature RAW --calibration bb.json [--depths ...|auto] --out T.h5``; a recording (an HDF5 stack, a
    multi-page TIFF, a folder of frames): each frame's planes, :func:`lf_flame.cli.temperature_recording.temperature_recording`."""
    import time

    import h5py

    from ..config import provenance
    from ..measure.figures import save_figure
    from ..temperature.pyrometry import load_calibration
    from .planes import reconstruct_input
    src = str(a.raw)
    from .temperature_recording import recording_source, temperature_recording
    recording = recording_source(src)
    mosaic = None                                       # a raw mosaic (a recording's frames: each in its turn)
    if recording is None and not (src.endswith(".h5") and ".h5:" not in src):
        mosaic = _refuse_monochrome(src)
    if recording is None:
        furnace_note(src, a.alpha)
    cal = load_calibration(a.calibration)
    sensor, where = _sensor(src, a, cal)
    cal.check_sensor(sensor)
    cal = load_calibration(a.calibration, sensor)      # also refuses a ratio with no unique temperature
    from .temperature_calibration import calibration_warnings
    for line in calibration_warnings(cal):
        print(f"warning: {a.calibration}: {line}", file=sys.stderr)
    if mosaic is not None:
        from ..temperature.mosaic import refuse_dead_site
        refuse_dead_site(mosaic, sensor, src)
    print(f"sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where}); calibration "
          f"{cal.channels[0]}/{cal.channels[1]}, gain ratio {cal.gain_ratio:.5f}")
    from ..temperature.channels import CFA_ROUTES, ROUTE_P90_K
    if a.route != CFA_ROUTES[0]:
        (q, qn), (d, dn) = ROUTE_P90_K[a.route], ROUTE_P90_K[CFA_ROUTES[0]]
        print(f"note: --route {a.route} is quicker and less accurate than the default {CFA_ROUTES[0]}: on the paper "
              f"camera's flames its worst plane's p90 error is {q} K noise-free and {qn} K at 14 dB, the default's {d} "
              f"and {dn} K (results/temperature.md): report the default's temperatures", file=sys.stderr)
    if recording is not None:
        return temperature_recording(a, *recording, cal, sensor, where)
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
    if a.route == "refocus-cfa" and lf.lattice_views is not None:       # before the depth search
        from ..temperature.channels import HEX_REFOCUS_REFUSED
        raise ValueError(HEX_REFOCUS_REFUSED)
    extra, found = {}, None
    if depths == "auto":                                # reconstruct's planes: the levelled channels' found route
        depths, found, extra = _auto_depths(a, lf)
    elif a.route != "refocus-cfa":                      # planes given: are they where the flames are?
        given, found = given_planes_found(a, lf, depths)    # near ones held to the regions of their flames
        extra = fit_warnings(a, lf, depths, found=found, given=given)
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
    print("\n".join(_plane_lines(a, depths, r, cal)))
    masked, reported = int(np.sum(r["n_masked"])), int(valid.sum())
    if masked > reported:
        print(f"warning: {masked} of the planes' {masked + reported} bright pixels have a {cal.channels[0]}/"
              f"{cal.channels[1]} ratio no temperature of the table gives: the channels are likely misread (the colour "
              "filter array's pattern or phase: an image cropped by an odd number of pixels moves the phase) or the "
              "calibration is another camera's", file=sys.stderr)
    print(f"temperature of {planes_count(len(depths))} ({a.route}: {settings_text(r['chosen'])}) in {wall:.1f} s -> "
          f"{out}" + (f", {fig}" if fig else ""))


def settings_text(settings: dict) -> str:
    """A route's settings (nested dicts of names and values) as one line: 'regime noisy, knobs fills 25 lam 0.01'."""
    def text(v):
        if isinstance(v, dict):
            return " ".join(f"{k} {text(x)}" for k, x in v.items())
        return f"{v:.3g}" if isinstance(v, float) else str(v)
    return ", ".join(f"{k} {text(v)}" for k, v in settings.items())


def add_parsers(sub) -> None:
    """Add ``temperature`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
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
    s.add_argument("--depth", type=finite, action="append", help="plane depth (mm from the focal plane; repeatable). "
                   "Default: --depths auto")
    s.add_argument("--depths", default=None, help="'auto' (default): the planes 'lf-flame reconstruct' finds in the "
                   "capture (its red and green samples levelled into one light field, depths found, the solve's "
                   "residual searched, flames one behind another refined); 'scene', 'paper', or depths in mm "
                   "separated by commas (as 'lf-flame reconstruct')")
    s.add_argument("--slope", type=finite, action="append", help="plane slope instead of a depth (repeatable)")
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
    s.add_argument("--alpha", type=finite, default=1.39, help="emissivity exponent of the source, eps ~ lambda^-alpha "
                   "(soot: 1.39, Hottel & Broughton; 0: a blackbody)")
    s.add_argument("--saturation", type=_level_or_none, default="auto", help="the sensor's clipping level of a raw "
                   "image: pixels at or above it are left out of the fit ('none': fit every pixel; default "
                   + "auto: " + AUTO_LEVEL + ")")
    _sensor_args(s, True)
    s.add_argument("--out", required=True, help="T.h5: temperature_k, valid, dim (plane, row, col), emission, "
                   "depths_mm, counts, provenance; the figure goes beside it as .png. A recording's: temperature_k and "
                   "valid (frame, plane, row, col), depths_mm, times_s, and T.csv (per frame and plane: median, p10, "
                   "p90 K)")
    s.add_argument("--fps", type=finite, help="a recording's frame rate, frames/s (default: its file's)")
    add_figure_arg(s, "each plane's temperature map in mm, one colour bar in K")
    add_search_arg(s)
    s.set_defaults(func=cmd_temperature)
