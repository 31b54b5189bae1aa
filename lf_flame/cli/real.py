"""Commands of real cameras: ``calibrate`` (:mod:`lf_flame.real.calibration`) and ``decode``
(:mod:`lf_flame.real.decoding`).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path


def cmd_calibrate(a):
    from ..real.calibration import CalibrationError, calibrate
    from ..real.images import file_digest, load_image
    white = load_image(a.white)
    dark = load_image(a.dark) if a.dark else None
    sensor, where = colour_sensor(a.camera, a.white)
    if sensor is not None:
        print(f"colour sensor {sensor.name}, {sensor.pattern} ({where}): the white image's four CFA phases "
              "levelled first")
    t = time.perf_counter()
    try:
        cal = calibrate(white, dark, layout=a.layout, camera_id=a.camera_id or "", mosaic=sensor is not None)
    except CalibrationError as e:
        if sensor is not None:
            raise
        raise CalibrationError(f"{e}; if this is a colour sensor's raw mosaic, give its camera file (--camera, "
                               "whose [sensor] names the cfa) so that its CFA phases are levelled first") from None
    dt = time.perf_counter() - t
    cal = dataclasses.replace(cal, white=file_digest(a.white), dark=file_digest(a.dark) if a.dark else None)
    cal.save(a.out)
    print(f"{cal.layout} grid: pitch {cal.pitch_px:.4f} px, rotation {cal.rotation_deg:+.4f}°, offset "
          f"({cal.offset_px[0]:+.2f}, {cal.offset_px[1]:+.2f}) px, {cal.n_rows} x {cal.n_cols} lenslets decoded; "
          f"fit residual {cal.residual_rms_px:.3f} px rms, {cal.residual_max_px:.3f} px max over "
          f"{len(cal.lenslets)} of {cal.n_found} lenslet images; {dt:.2f} s -> {a.out}")
    _dark_lenslets_note(cal, white, dark, sensor)


def _dark_lenslets_note(cal, white, dark, sensor) -> None:
    """A note naming the white image's dark lenslets (:func:`lf_flame.real.decoding.dark_lenslets`): dust or a defect
    that decoding's division corrects only in captures that share it."""
    import numpy as np

    from ..real.decoding import WHITE_DARK_LENSLET, dark_lenslets, white_samples
    try:
        dark_at = dark_lenslets(white_samples(cal, white, dark, sensor=sensor))
    except ValueError:                # a white image decoding refuses: decode says why
        return
    if dark_at.any():
        r, c = np.nonzero(dark_at)
        print(f"note: {int(dark_at.sum())} lenslets of the white image (rows {r.min()}-{r.max()}, columns "
              f"{c.min()}-{c.max()} of the decoded grid) hold less than {100 * WHITE_DARK_LENSLET:.0f} % of their "
              "neighbours' light: dust or a defect. Decoding divides each capture by the white image, which "
              "corrects them where the captures share it (dust on the sensor or lenslets) and brightens them where "
              "they do not (dust on the white target, or cleaned since): then clean and take the white image again")


def cmd_decode(a):
    from ..real.calibration import GridCalibration
    from ..real.images import calibration_image, load_image
    from ..real.black_level import unlit_level
    from ..real.clipping import clipped_share
    from ..real.decoding import decode_repaired
    from ..real.view_grid import on_square_grid
    from ..real.views_file import save_views
    from ._io import black_level_warning
    cal = GridCalibration.load(a.calibration)
    raw = load_image(a.raw)
    white = None if a.no_white else calibration_image(cal.white, "white", a.white)
    dark = calibration_image(cal.dark, "dark", a.dark)
    if a.camera:                    # the calibration of this camera's set-up (as every route with --camera checks)
        from ..optics.camera_file import load_camera_file
        from ..real.own_camera import check_calibration
        check_calibration(load_camera_file(a.camera), cal)
    sensor, where = colour_sensor(a.camera, a.raw)
    from ..real.images import _image
    _image(str(a.raw), raw)         # NaN or inf named before the clipping level is looked for in them
    if sensor is not None:          # a monochrome capture decoded as a colour one would read one flat temperature
        from ..temperature.mosaic import refuse_no_mosaic
        from ._io import refuse_rgb
        refuse_rgb(a.raw)
        refuse_no_mosaic(raw, a.raw, f"the camera names a colour sensor ({where}); decode a monochrome capture with a "
                                     "camera file whose [sensor] names no cfa")
        from ..temperature.mosaic import refuse_dead_site
        refuse_dead_site(raw, sensor, a.raw)
    t = time.perf_counter()
    # a hexagonal grid keeps its lattice's views (and a colour capture's channels there) beside the square grid's
    level = _saturation_level(a.saturation, raw)
    lattice, channels, k, hit, bad = decode_repaired(raw, cal, white, dark, sensor, level, n_views=a.views,
                                                       bin_views=getattr(a, "bin", None), camera_id=a.camera_id)
    views = on_square_grid(lattice, cal)
    if sensor is not None:
        print(f"colour sensor {sensor.name}, {sensor.pattern} phase {sensor.phase} ({where}): each sample from its "
              "nearest pixel, channels apart" + (" on the hexagonal lattice" if cal.layout == "hex" else ""))
    clipped = None if hit is None else on_square_grid(hit, cal)
    if cal.layout != "hex":
        lattice = hit = None
    dt = time.perf_counter() - t
    n_bad = int(bad.sum())
    extra = {"bin_views": k, "defective_pixels": n_bad}
    unlit = unlit_level(raw, white, dark)
    if unlit is not None:
        extra["unlit_level"] = unlit
    share = clipped_share(raw, level)
    if level is not None:
        extra.update(saturation=level, clipped_share=share)
    if sensor is not None:
        extra["sensor"] = json.dumps(sensor.record())
    save_views(a.out, views, cal, clipped, channels, lattice, hit, raw=str(Path(a.raw).resolve()),
               white_normalised=white is not None, **extra)
    note = "no clipping level" if level is None else (
        f"{int(clipped.sum())} samples from pixels at or above {level:g}{' or defective' if n_bad else ''}; "
        f"{100 * share:.3g} % of the lit pixels clipped")
    if n_bad:
        note = f"{note}; {defects_note(n_bad)}"
    binned = f", {k} x {k} pixels each" if k > 1 else ""
    print(f"decoded {Path(a.raw).name} into {views.shape[0]} x {views.shape[1]} views{binned} of {views.shape[2]} x "
          f"{views.shape[3]} lenslets ({note}) in {dt:.2f} s -> {a.out}")
    overexposure_warning(share)
    black_level_warning(unlit)
    if white is not None and sensor is None:
        from ..real.decoding import dim_against_white
        dim = dim_against_white(views)
        if dim:
            print(f"warning: {a.raw}: {dim}")
    from ..real.black_level import negative_note
    negative = negative_note(views, str(a.raw))
    if negative:
        print(f"warning: {negative}")
    if white is not None:
        from ..real.decoding import off_grid_note
        off = off_grid_note(raw, white, dark)
        if off:
            print(f"warning: {a.raw}: {off}")
    if a.white and white is not None:               # a white image given in place of the calibration's: unchecked
        from ..real.black_level import view_spread
        from ..real.decoding import white_samples
        spread = view_spread(white_samples(cal, white, dark, n_views=views.shape[0], bin_views=k, sensor=sensor))
        if spread is not None and spread > WHITE_SPREAD:
            print(f"warning: --white {a.white}: its lenslets' central views vary by {spread:.2g} of their level "
                  f"across the field (a white image's by little more than its vignetting, a flame's by about 1): is it "
                  "the white image? The views are divided by it")


#: ``decode --white``: a white image whose central views vary across the field by more than this share of their level
#: (:func:`lf_flame.real.black_level.view_spread`; simulated white images 0.008-0.013, a flame on a dark background
#: about 1) is warned of: a user's capture given as its own white image had been taken without a word.
WHITE_SPREAD = 0.5


def defects_note(n: int) -> str:
    """The capture's defective pixels, as the commands report them."""
    return (f"{n} defective pixels (hot or dead: standing out of their neighbours in the light field) "
            "repaired, their samples left out of the fit")


def overexposure_warning(share: float, where: str = "") -> float:
    """Where more than :data:`~lf_flame.real.clipping.CLIPPED_WARN` of a capture's lit pixels are clipped (``share``:
    :meth:`~lf_flame.real.lightfield.LightField.over_exposure`, :func:`lf_flame.real.clipping.clipped_share`), one
    warning (stderr): the brightest emission is over-exposed, its planes a lower bound there; ``where`` begins it
    (a recording's frames). Returns ``share``."""
    from ..real.clipping import CLIPPED_WARN
    if share > CLIPPED_WARN:
        print(f"warning: {where}{100 * share:.3g} % of the lit pixels are clipped: the brightest emission is "
              "over-exposed and its planes hold only a lower bound there (on the paper camera's scenes 10-27 % "
              "clipped left the flames' emission 9-30 % off, against 2-6 % below clipping: results/clipping.md); "
              "lower the exposure",
              file=sys.stderr)
    return share


def colour_sensor(camera, raw):
    """A capture's colour sensor and where it came from: the ``camera`` file's ``[sensor] cfa``, else the sensor
    ``lf-flame simulate`` stored beside the ``raw`` image; (None, "") for a monochrome capture
    (:func:`lf_flame.real.readers.capture_sensor`)."""
    from ..real.readers import capture_sensor
    from ._io import _raw_meta
    return capture_sensor(camera or None, _raw_meta(raw), str(raw))


def _saturation_level(text, raw):
    """``decode --saturation``: a level (raw units), None for 'none', or 'auto' (see its help)."""
    import numpy as np
    t = str(text).strip().lower()
    if t == "none":
        return None
    if t != "auto":
        try:
            v = float(t)
        except ValueError:
            raise ValueError(f"--saturation must be a level, 'auto' or 'none'. Received: {text!r}") from None
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"--saturation must be a positive finite level. Received: {text!r}")
        return v
    from ..real.clipping import auto_saturation
    try:
        return auto_saturation(raw)
    except ValueError as e:
        raise ValueError(f"--saturation auto: {e}") from None


def _bin_views(text: str):
    """``decode --bin``: a positive integer, or None for 'auto'."""
    if text.lower() == "auto":
        return None
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"--bin takes auto or a positive integer (pixels per view). Received: {text!r}")
    return int(text)


def add_parsers(sub) -> None:
    """Add ``calibrate`` and ``decode`` to ``sub``, the sub-parsers of :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("calibrate", help="calibrate a real camera's lenslet grid from a white image")
    s.add_argument("white", help="white (flat-field) image: PNG, TIFF, .npy or .npz")
    s.add_argument("--dark", help="dark frame, subtracted first")
    s.add_argument("--layout", choices=["auto", "square", "hex"], default="auto",
                   help="lenslet grid; auto: told by the angle between the white image's lattice vectors "
                        "(90°: square, 60°: hex)")
    s.add_argument("--camera-id", help="name of the camera, stored and checked by decode")
    s.add_argument("--camera", help="camera file (TOML): a [sensor] cfa marks the white image as a colour mosaic "
                                    "(also read from a simulated image's stored sensor)")
    s.add_argument("--out", required=True, help="calibration JSON")
    s.set_defaults(func=cmd_calibrate)

    s = sub.add_parser("decode", help="decode a real raw image into sub-aperture views with a calibration")
    s.add_argument("raw", help="raw light-field image: PNG, TIFF, .npy or .npz")
    s.add_argument("--calibration", required=True, help="JSON written by 'lf-flame calibrate'")
    s.add_argument("--white", help="white image (default: the calibration's, checked by its SHA-256)")
    s.add_argument("--dark", help="dark frame (default: the calibration's, if any)")
    s.add_argument("--no-white", action="store_true", help="no white-image normalisation")
    s.add_argument("--views", type=int, help="views per axis (default: as many as the lenslet image holds)")
    s.add_argument("--bin", default="auto", type=_bin_views,
                   help="pixels per view sample and axis, summed: views of a camera with larger pixels, as much light "
                        "and parallax, fewer views for the solvers ('auto': 1 up to 29 pixels per lenslet image, "
                        "else enough for at least 15 views, e.g. 3 for 48; 1 with --views or a colour sensor)")
    s.add_argument("--camera-id", help="refuse a calibration of another camera")
    s.add_argument("--camera", help="camera file (docs/own_camera.md): where its [sensor] names a colour filter array "
                   "(cfa), each view sample is taken from its nearest pixel and keeps that pixel's channel (the "
                   "views' channel map, which 'lf-flame temperature' reads); a raw image from 'lf-flame simulate' "
                   "with a colour sensor is decoded so without it")
    s.add_argument("--saturation", default="auto",
                   help="the sensor's clipping level in the raw image's units: the views' samples from pixels at or "
                        "above it are stored as 'clipped' (reconstruct leaves them out); auto: where the image's "
                        "pixels pile up at its largest value (a sensor clips at one level), else 1.0 when its values "
                        "are at most 1 (the simulator's), else the smallest 2**bits - 1 (bits 8, 10, 12, 14, 16) at "
                        "or above its maximum; 'none': no mask")
    s.add_argument("--out", required=True, help="HDF5 of the views (N, N, R, C)")
    s.set_defaults(func=cmd_decode)
