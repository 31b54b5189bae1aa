"""Commands of real cameras: ``calibrate`` (:mod:`lf_flame.real.calibration`) and ``decode``
(:mod:`lf_flame.real.decoding`).
"""
from __future__ import annotations

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
    sensor, where = colour_sensor(a.camera, a.raw)
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
        extra["sensor"] = json.dumps(dict(name=sensor.name, pattern=sensor.pattern, phase=list(sensor.phase)))
    save_views(a.out, views, cal, clipped, channels, lattice, hit, raw=str(Path(a.raw).resolve()),
               white_normalised=white is not None, **extra)
    note = "no clipping level" if level is None else (
        f"{int(clipped.sum())} samples from pixels at or above {level:g}{' or defective' if n_bad else ''}; "
        f"{100 * share:.2g} % of the lit pixels clipped")
    if n_bad:
        note = f"{note}; {defects_note(n_bad)}"
    binned = f", {k} x {k} pixels each" if k > 1 else ""
    print(f"decoded {Path(a.raw).name} into {views.shape[0]} x {views.shape[1]} views{binned} of {views.shape[2]} x "
          f"{views.shape[3]} lenslets ({note}) in {dt:.2f} s -> {a.out}")
    overexposure_warning(share)
    black_level_warning(unlit)


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
        print(f"warning: {where}{100 * share:.2g} % of the lit pixels are clipped: the brightest emission is "
              "over-exposed and its planes hold only a lower bound there (on the paper camera's scenes 10-27 % "
              "clipped left the flames' emission 9-30 % off, against 2-6 % below clipping: results/clipping.md); "
              "lower the exposure",
              file=sys.stderr)
    return share


def colour_sensor(camera, raw):
    """A capture's colour sensor and where it came from: the ``camera`` file's ``[sensor] cfa``, else the sensor
    ``lf-flame simulate`` stored beside the ``raw`` image; (None, "") for a monochrome capture
    (:func:`lf_flame.real.lightfield.capture_sensor`)."""
    from ..real.lightfield import capture_sensor
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
