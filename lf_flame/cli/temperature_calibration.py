"""The ``calibrate-temperature`` command: the gain ratio of two colour channels from raw images (or decoded views)
of a blackbody at known temperatures (:mod:`lf_flame.temperature.pyrometry`), written as JSON."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._io import RAW_FORMATS, _load_raw, refuse_rgb
from .options import finite
from .temperature_planes import _sensor, _sensor_args


def _channels(text: str):
    ch = tuple(c.strip().upper() for c in str(text).split(","))
    from ..optics.colour import CHANNELS
    if len(ch) != 2 or any(c not in CHANNELS for c in ch) or ch[0] == ch[1]:
        raise ValueError(f"--channels takes two different channels of {', '.join(CHANNELS)} as A,B. Received: {text!r}")
    return ch


#: Blackbody images with more than this share of their lit samples clipped are refused: a clipped channel's mean reads
#: low, and so does the gain ratio (a new user's images with 63 % of their red pixels clipped gave 0.834 against 1.000,
#: with residuals of 0.00 K, and flames read 225-249 K low). A few clipped samples cost nothing that counts: 1 % of
#: them clipped 30 % short moves the ratio by 0.3 %, a temperature near 2,000 K by about 0.5 K (Wien: dT / T = (lambda
#: T / c2) dr / r); the example camera's simulated furnace at 2,400 K clips 0.1 % of its samples (shot noise at 4 rays
#: per pixel).
BLACKBODY_CLIPPED_MAX = 0.01
#: A fit leaving a residual beyond this (K) is warned of: a blackbody's --temperature wrong (1,800 K given for a
#: 2,000 K image left +130 K; the fit of correct images leaves a few K at most), or its image not a blackbody's.
RESIDUAL_WARN_K = 20.0
#: A blackbody image whose two channels' ratio over the field's centre (a fifth of each axis) or its outer part (nine
#: tenths) differs from the ratio over its central half by more than this share is refused: a blackbody's ratio is the
#: same everywhere (the furnaces of a new user's three cameras, simulated: within 0.2 %), a flame's is not (2-9 % on
#: the same cameras; a flame image given as a one-temperature blackbody had been taken, its gain ratio 0.71).
BLACKBODY_SPREAD = 0.02


def _clipped_blackbody(share: float, path) -> None:
    """Refuse a blackbody image with more than :data:`BLACKBODY_CLIPPED_MAX` of its lit samples clipped."""
    if share > BLACKBODY_CLIPPED_MAX:
        raise ValueError(f"{path}: {100 * share:.3g} % of its lit samples are clipped: a clipped channel's mean "
                         "reads low and the gain ratio with it (every temperature then off by up to hundreds of K); "
                         "image the blackbody with a shorter exposure")


def cmd_calibrate_temperature(a):
    """``calibrate-temperature BB... --temperature T... --out bb.json``."""
    from ..temperature.pyrometry import blackbody_ratio, fit_calibration, write_calibration
    from ..optics.camera import PAPER_CAMERA
    temps = list(a.temperature or [])
    if len(temps) != len(a.images):
        raise ValueError(f"one --temperature per blackbody image is needed: {len(a.images)} images, {len(temps)} "
                         "temperatures")
    channels = _channels(a.channels)
    ratios, sensor0, mosaics = [], None, []
    own = None
    if a.camera:                                  # the images' camera (a perfect grid's raw images need no decoding)
        from ..optics.camera_file import load_camera_file
        own = load_camera_file(a.camera)
    missing = [str(p) for p in a.images if not Path(p).is_file()]
    if missing:                                   # before any image's sensor is read (a missing one's is the default)
        raise FileNotFoundError(f"blackbody image file not found: {', '.join(missing)}")
    for path, t in zip(a.images, temps):
        refuse_rgb(path)
        raw, cam = (None, None) if str(path).endswith(".h5") else _load_raw(path)
        cam = own or cam
        sensor, where = _sensor(path, a)
        if sensor0 is not None and (sensor.name, sensor.pattern, sensor.phase) != (
                sensor0.name, sensor0.pattern, sensor0.phase):
            raise ValueError(f"{path} is from sensor {sensor.name!r} {sensor.pattern} phase {sensor.phase}, the first "
                             f"image from {sensor0.name!r} {sensor0.pattern} phase {sensor0.phase}: one camera per "
                             "calibration")
        sensor0 = sensor
        if str(path).endswith(".h5"):                                 # a colour capture decoded with its channels
            from ..real.views_file import load_channels, load_clipped, load_lattice, load_views
            from ..temperature.pyrometry import views_blackbody_ratio
            (v, hit), chan = load_lattice(path), load_channels(path)  # a hexagonal grid's channels: on its lattice
            if v is None:
                v, hit = load_views(path)[0], load_clipped(path)
            if chan is None:
                raise ValueError(f"{path}: decoded views without their colour channels ('lf-flame decode --camera "
                                 "cam.toml' keeps them apart)")
            if hit is not None:
                _clipped_blackbody(float(hit.sum()) / max(int(np.count_nonzero(v > 0)), 1), path)
            r = views_blackbody_ratio(v, chan, channels)
            _check_even(path, r, lambda cf: views_blackbody_ratio(v, chan, channels, centre_fraction=cf), channels)
        else:
            if cam is not None and not cam.perfect_grid:
                raise ValueError(f"{path} is a raw image of a camera whose lenslet grid is not a perfect one (rotated, "
                                 "hexagonal, or lenslet images no whole number of pixels apart): decode it first "
                                 "('lf-flame decode IMAGE --calibration cal.json --camera cam.toml --out VIEWS.h5') "
                                 "and give the VIEWS.h5")
            from ..real.clipping import auto_saturation, clipped_share
            _clipped_blackbody(clipped_share(raw, auto_saturation(raw)), path)
            from ..temperature.mosaic import refuse_no_mosaic
            refuse_no_mosaic(raw, path, "a blackbody image of a colour camera has one")
            mosaics.append((raw, path))
            n = (cam or PAPER_CAMERA).pixels_per_lenslet
            try:
                r = blackbody_ratio(raw, sensor, n, channels)
            except ValueError as e:
                if cam is not None:
                    raise
                raise ValueError(f"{e} ({path} stores no camera: it was taken as the paper camera's raw image; a raw "
                                 "image of your own camera is decoded first: 'lf-flame decode IMAGE --calibration "
                                 "cal.json --camera cam.toml --out VIEWS.h5', and the VIEWS.h5 given)") from None
            _check_even(path, r, lambda cf: blackbody_ratio(raw, sensor, n, channels, centre_fraction=cf), channels)
        ratios.append(r)
        print(f"{path}: {t:g} K, {channels[0]}/{channels[1]} = {r:.5f} (sensor {sensor.name}, {sensor.pattern} "
              f"phase {sensor.phase}: {where})")
    try:
        cal = fit_calibration(sensor0, temps, ratios, channels)
    except ValueError as err:           # a colour filter array read at the wrong phase: say which phase fits
        raise ValueError(f"{err}{_fitting_phases(a.images, temps, sensor0, channels, own)}") from None
    from ..temperature.mosaic import refuse_dead_site
    for raw, path in mosaics:           # at the phase that fits (a wrong phase is named above): a site dead or dimmed
        refuse_dead_site(raw, sensor0, path)
    out = write_calibration(a.out, cal)
    print(f"gain ratio {cal.gain_ratio:.5f}; fit residuals " + ", ".join(f"{x:+.2f}" for x in cal.fit_residuals_k)
          + f" K -> {out}")
    for line in calibration_warnings(cal):
        print(f"warning: {line}", file=sys.stderr)


def calibration_warnings(cal) -> list:
    """What a temperature calibration cannot vouch for, as sentences (``calibrate-temperature`` warns of them when it
    fits, ``temperature`` each time it reads the calibration): blackbodies at one temperature (a ratio that moves
    against the sensor's, a colour filter array read at the wrong phase or red and blue swapped, cannot be seen, nor a
    wrong --temperature), a fit residual beyond :data:`RESIDUAL_WARN_K`."""
    out, temps = [], cal.fit_temperatures_k
    if len(set(temps)) < 2:
        out.append(f"the calibration's blackbodies are at one temperature ({temps[0]:g} K): they fit the gain ratio, "
                   "but cannot check that the ratio moves with temperature as the sensor's does (its colour filter "
                   "array's pattern and phase; a wrong --temperature moves every reading): give two or more "
                   "temperatures for that check")
    worst = max(abs(x) for x in cal.fit_residuals_k)
    if worst > RESIDUAL_WARN_K:
        out.append(f"the calibration's fit leaves a residual of {worst:.0f} K: one blackbody's --temperature may be "
                   "wrong, or its image not a blackbody's filling the field (the temperatures given in the images' "
                   "order: " + ", ".join(f"{t:g}" for t in temps) + " K)")
    return out


def _check_even(path, r, ratio, channels) -> None:
    """Refuse a blackbody image whose channel ratio over the field's centre or outer part (``ratio(centre_fraction)``)
    differs from ``r``, its ratio over the central half, by more than :data:`BLACKBODY_SPREAD`."""
    spread = max(abs(ratio(cf) / r - 1) for cf in (0.2, 0.9))
    if spread > BLACKBODY_SPREAD:
        raise ValueError(f"{path}: its {channels[0]}/{channels[1]} ratio differs by {100 * spread:.1f} % between the "
                         f"field's centre, its central half and its outer part (a blackbody's is the same everywhere, "
                         f"{100 * BLACKBODY_SPREAD:g} % tolerated): not a blackbody filling the field evenly")


def _fitting_phases(images, temps, sensor, channels, camera=None) -> str:
    """For raw blackbody images refused by :func:`~lf_flame.temperature.pyrometry.fit_calibration`: the other CFA
    phases of the same pattern under which they fit, with their largest residual (K), as a sentence ('' for
    decoded views, whose channels were fixed when decoded, or where none fits)."""
    import dataclasses

    from ..optics.camera import PAPER_CAMERA
    from ..temperature.pyrometry import blackbody_ratio, fit_calibration
    if any(str(p).endswith(".h5") for p in images):
        return ""
    raws = [(raw, camera or cam) for raw, cam in (_load_raw(p) for p in images)]
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


def add_parsers(sub) -> None:
    """Add ``calibrate-temperature`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("calibrate-temperature", help="two-colour temperature calibration (the channels' gain "
                       "ratio) from raw images of a blackbody (furnace) at known temperatures -> JSON")
    s.add_argument("images", nargs="+", help="raw colour images of a blackbody filling the field: " + RAW_FORMATS
                   + "; a camera whose lenslet grid is not perfect (rotated, hexagonal, a pitch of no whole number of "
                   "pixels): its images decoded with their channels apart ('lf-flame decode --camera cam.toml')")
    s.add_argument("--temperature", type=finite, action="append", help="each image's temperature, K, in the images' "
                   "order (repeatable; one per image)")
    s.add_argument("--channels", default="R,G", help="numerator and denominator channels of the ratio")
    s.add_argument("--camera", help="camera file (docs/own_camera.md) of raw images that store none: its grid and "
                   "its [sensor] cfa")
    _sensor_args(s, False)
    s.add_argument("--out", required=True, help="calibration JSON (read by 'lf-flame temperature')")
    s.set_defaults(func=cmd_calibrate_temperature)
