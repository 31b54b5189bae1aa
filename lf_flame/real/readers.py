"""Light fields in: the readers of every input, each returning one :class:`~lf_flame.real.lightfield.LightField`.

:func:`read_light_field` reads a simulated raw image with its camera, views decoded by ``lf-flame decode`` with the
camera file, or a raw capture with its white-image calibration and camera file, decoded here
(:func:`decode_capture`); :func:`capture_sensor` gives a colour capture's sensor, and :func:`stored_camera_warning`
says where a file's stored camera differs from the one given.
"""
from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from ..optics.camera import PlenopticCamera
from .lightfield import LightField, from_decoded, from_raw

#: Suffixes read as a raw image by :func:`read_light_field` (besides ``VIEWS.h5``).
RAW_SUFFIXES = (".npz", ".npy", ".png", ".tif", ".tiff")


def read_light_field(path, camera=None, calibration=None, *, views: int | None = None,
                     bin_views: int | None = None, raw_reader=None, formats: str = "") -> LightField:
    """Read a light field: ``VIEWS.h5`` from ``lf-flame decode``, or a raw image.

    Parameters
    ----------
    path : str or Path
        ``VIEWS.h5``; or a raw image (:data:`RAW_SUFFIXES`).
    camera : str, Path, PlenopticCamera or None
        A camera file (:func:`lf_flame.optics.camera_file.load_camera_file`) or camera.
        None: the camera stored in the file (``lf-flame simulate``'s), else, for a raw image,
        the paper's camera; decoded views need one.
    calibration : str, Path, GridCalibration or None
        The white-image calibration: a raw capture of a camera whose grid is not perfect is
        decoded with it (its white image, checked by its SHA-256), a colour capture's (the camera
        file's ``[sensor] cfa``, else the sensor the image stores) with its channels apart as
        ``lf-flame decode --camera`` decodes it; decoded views are checked against it.
    views : int or None
        Views per axis when decoding here (default: as many as the lenslet image holds).
    bin_views : int or None
        Pixels per view sample and axis when decoding here; None: ``lf-flame decode``'s default
        (:func:`lf_flame.real.view_grid.auto_bin`; 1 where ``views`` is given).
    raw_reader : callable or None
        ``raw_reader(path) -> (raw, stored camera or None, meta dict)``; None: the
        command line's reader (:func:`lf_flame.cli._io` formats) is not imported here, so
        raw images are read as .npy/.npz (``raw``) or images by scikit-image.
    formats : str
        What the caller reads as a raw image, added to the refusal of an .h5 file that holds
        no decoded views.

    Returns
    -------
    LightField

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        Decoded views without a camera file; a calibration of another grid than the views';
        a raw image of a non-perfect grid without a calibration; the readers' errors.
    """
    from ..optics.camera_file import load_camera_file
    from .calibration import GridCalibration
    src = str(path)
    cam = camera if (camera is None or isinstance(camera, PlenopticCamera)) else load_camera_file(camera)
    cam_file = None if camera is None or isinstance(camera, PlenopticCamera) else str(Path(camera).resolve())
    cal = calibration if (calibration is None or isinstance(calibration, GridCalibration)) else \
        GridCalibration.load(calibration)
    p = Path(src)
    if p.suffix.lower() == ".h5" and ".h5:" not in src:
        from ..config import DamagedFileError
        from .views_file import load_channels, load_clipped, load_lattice, load_views
        try:
            v, vcal = load_views(p)
        except DamagedFileError:
            raise
        except ValueError as e:
            raise ValueError(f"{e}. Reads views .h5 from 'lf-flame decode'" + (f", or a raw image: {formats}"
                                                                               if formats else "")) from None
        if cal is not None and not same_grid(cal, vcal):
            raise ValueError(f"{src} was decoded with another calibration than the one given")
        if cam is None:
            raise ValueError(f"{src} holds decoded views: give the camera they come from (--camera cam.toml, "
                             "docs/own_camera.md)")
        import h5py
        with h5py.File(p, "r") as f:
            white = bool(f.attrs.get("white_normalised", True))
            meta = {"sensor": str(f.attrs["sensor"])} if "sensor" in f.attrs else {}
            k = int(f.attrs.get("bin_views", 1))
            share = float(f.attrs["clipped_share"]) if "clipped_share" in f.attrs else None
            unlit = float(f.attrs["unlit_level"]) if "unlit_level" in f.attrs else None
            level = float(f.attrs["saturation"]) if "saturation" in f.attrs else None
        return from_decoded(v, vcal, cam, src, load_clipped(p), white, cam_file, load_channels(p), meta, k,
                            *load_lattice(p), clipped_share=share, unlit_level=unlit, level=level)
    raw, stored, meta = (raw_reader or _read_raw)(p)
    stored_camera_warning(cam, stored, src)
    cam = cam or stored
    assumed = cam is None
    if assumed:
        from ..optics.camera import PAPER_CAMERA
        cam = PAPER_CAMERA
    if cal is None:
        return from_raw(raw, cam, src, camera_file=cam_file, meta=meta, sensor=capture_sensor(camera, meta, src)[0])
    images = None
    if ".h5:" in src:          # a frame of an HDF5 stack (FILE.h5:INDEX): the white and dark in its frames' units
        from .images import calibration_image_path, decoding_images
        images = decoding_images(calibration_image_path(cal.white, "white"), calibration_image_path(cal.dark, "dark"))
    elif p.suffix.lower() not in (".npz", ".npy"):    # an image file: in the units of the calibration's white and dark
        from .images import load_image
        raw = load_image(p)
    try:
        return _decode_here(raw, src, cam, cal, views, cam_file, bin_views, capture_sensor(camera, meta)[0],
                            images=images)
    except ValueError as e:
        if assumed:                      # say which camera was taken, the likeliest cause
            raise ValueError(f"{e} (no camera file given, and {src} stores none: the paper's camera was taken; "
                             "give the capture's --camera cam.toml)") from None
        raise


def camera_differences(a: PlenopticCamera, b: PlenopticCamera, rel: float = 1e-6) -> list:
    """The fields (``PlenopticCamera.to_dict`` names) in which two cameras differ, numbers beyond ``rel``."""
    import math
    da, db = a.to_dict(), b.to_dict()
    out = []
    for k in sorted(set(da) | set(db)):
        x, y = da.get(k), db.get(k)
        same = (x == y) or (isinstance(x, (int, float)) and isinstance(y, (int, float))
                            and math.isclose(x, y, rel_tol=rel, abs_tol=1e-12))
        if not same:
            out.append(f"{k} {x} against {y}")
    return out


def stored_camera_warning(given, stored, source: str) -> None:
    """Where a file records the camera it was simulated with (``stored``) and another is ``given`` (a camera file),
    a warning naming the fields that differ: the given camera is the one used, and a wrong one moves every depth
    (a focus distance 50 mm off moved a recording's flames by 12-40 mm, with no other sign)."""
    if given is None or stored is None:
        return
    diff = camera_differences(given, stored)
    if diff:
        import warnings
        warnings.warn(f"{source} records the camera it was rendered with, and the camera given differs ("
                      + "; ".join(diff[:4]) + (f"; {len(diff) - 4} more" if len(diff) > 4 else "")
                      + "): the camera given is used", stacklevel=3)


def decode_capture(raw, camera: PlenopticCamera, calibration, sensor=None, source: str = "raw capture",
                   images=None) -> LightField:
    """The light field of one raw capture (a recording's frame) decoded with its calibration, as
    :func:`read_light_field` decodes a raw image file: every view the lenslet image holds, binned as
    ``lf-flame decode`` bins by default, a colour ``sensor``'s capture one pixel per sample, its channels apart.

    Parameters
    ----------
    raw : ndarray of shape (rows, cols)
        In the units of the white and dark images (``images``, else the calibration's files as read).
    camera : PlenopticCamera
        The real camera (:func:`lf_flame.optics.camera_file.load_camera_file`).
    calibration : GridCalibration
    sensor : ColourSensor or None
        A colour capture's sensor (:func:`lf_flame.optics.camera_file.load_colour_sensor`).
    source : str
        Names the capture in messages.
    images : (white, dark) or None
        The white image and dark frame (rows, cols) in the raw's units (a recording's frames':
        :func:`lf_flame.real.images.frame_image`), either None (no white normalisation, no dark
        subtracted); None: the calibration's, read from their files
        (:func:`lf_flame.real.images.calibration_image`).

    Returns
    -------
    LightField

    Raises
    ------
    ValueError
        As :func:`read_light_field` refuses a raw capture.
    """
    return _decode_here(np.asarray(raw, np.float64), source, camera, calibration, None, None, None, sensor, images)


def capture_sensor(camera, meta, source: str = "the image") -> tuple:
    """A raw capture's colour sensor and where it came from: the camera file's ``[sensor] cfa``, else the record
    ``lf-flame simulate`` stored beside the image (``meta["sensor"]``); ``(None, "")`` for a monochrome one, and for
    an image ``lf-flame simulate`` or ``simulate-sequence`` rendered without colour (its record names a ``scene`` or
    a ``sequence`` and no ``sensor``: a monochrome scene's render, whatever CFA the camera file names). A camera
    file's CFA that lays other channels on the pixels than the one the image records is warned of (the camera
    file's is used; :func:`lf_flame.optics.colour.same_cfa_layout`).

    Parameters
    ----------
    camera : str, Path, PlenopticCamera or None
        The camera file (a camera object names no sensor).
    meta : dict or None
        What the image stores beside the raw data (JSON strings).
    source : str
        The image, named in ``where``.

    Returns
    -------
    (ColourSensor or None, str)
    """
    from ..optics.camera_file import load_colour_sensor
    from ..optics.colour import library_sensor
    meta = meta or {}
    if not meta.get("sensor") and ("scene" in meta or "sequence" in meta):
        return None, ""
    if camera is not None and not isinstance(camera, PlenopticCamera):
        sensor = load_colour_sensor(camera)
        if sensor is not None:
            from ..optics.colour import same_cfa_layout
            from ..config import stored_json
            stored = stored_json(meta["sensor"], source, "sensor") if meta.get("sensor") else None
            if stored and not same_cfa_layout(stored["pattern"], stored["phase"], sensor.pattern, sensor.phase):
                import warnings
                warnings.warn(f"{source} records its colour filter array as {stored['pattern']} phase "
                              f"{tuple(stored['phase'])}, the camera file {camera} names {sensor.pattern} phase "
                              f"{tuple(sensor.phase)}: the camera file's is used", stacklevel=2)
            return sensor, f"{camera} [sensor]"
    rec = meta.get("sensor")
    if not rec:
        return None, ""
    from ..config import stored_json
    r = stored_json(rec, source, "sensor")
    return library_sensor(r["name"], r["pattern"], tuple(r["phase"])), f"stored in {source}"


def _decode_here(raw, src, cam, cal, n_views, cam_file, bin_views=None, sensor=None, images=None) -> LightField:
    """A raw capture decoded with its calibration's white (and dark) image, as ``lf-flame decode`` decodes it:
    ``bin_views`` None: binned by default (:func:`lf_flame.real.view_grid.auto_bin`, one pixel per view where
    ``n_views`` is given); a colour ``sensor``'s capture one pixel per sample, its channels apart
    (:func:`lf_flame.real.decoding.decode_colour`); ``images``: as :func:`decode_capture`'s."""
    from .images import calibration_image
    from .black_level import unlit_level
    from .clipping import clipped_share, found_level
    from .decoding import decode_repaired
    from .view_grid import on_square_grid
    white, dark = (calibration_image(cal.white, "white"), calibration_image(cal.dark, "dark")) if images is None \
        else images
    level = found_level(raw)
    lattice, channels, k, hit, bad = decode_repaired(raw, cal, white, dark, sensor, level, n_views=n_views,
                                                       bin_views=bin_views)
    if white is not None:
        from .decoding import off_grid_note
        off = off_grid_note(raw, white, dark)
        if off:
            warnings.warn(f"{src}: {off}", stacklevel=2)
    meta = {} if sensor is None else {"sensor": json.dumps(dict(name=sensor.name, pattern=sensor.pattern,
                                                                phase=list(sensor.phase)))}
    hexagonal = cal.layout == "hex"
    return from_decoded(on_square_grid(lattice, cal), cal, cam, src, None if hit is None else on_square_grid(hit, cal),
                        white is not None, cam_file, channels, meta, bin_views=k,
                        lattice_views=lattice if hexagonal else None, lattice_clipped=hit if hexagonal else None,
                        defective_pixels=int(bad.sum()), clipped_share=clipped_share(raw, level),
                        unlit_level=unlit_level(raw, white, dark), level=level)


def _read_raw(p: Path):
    """A raw image, the camera stored beside it (or None) and its other records (JSON strings)."""
    if not p.is_file():
        raise FileNotFoundError(f"raw image file not found: {p}")
    from ..config import reading
    meta, stored = {}, None
    if p.suffix.lower() == ".npz":
        with reading(p, ".npz file"), np.load(p) as z:
            if "raw" not in z:
                raise ValueError(f"{p} holds no raw image (its arrays: {', '.join(z.files)})")
            raw = z["raw"]
            meta = {k: str(z[k]) for k in z.files if k != "raw" and z[k].dtype.kind == "U"}
    elif p.suffix.lower() == ".npy":
        with reading(p, ".npy file"):
            raw = np.load(p)
    else:
        from .images import load_image
        raw = load_image(p)
    if "camera" in meta:
        from ..config import stored_json
        stored = PlenopticCamera.from_dict(stored_json(meta["camera"], p, "camera"))
    return np.asarray(raw, np.float64), stored, meta


def same_grid(c1, c2) -> bool:
    """Two calibrations of one lenslet grid (the fitted lattice and the decoded grid)."""
    return (c1.layout == c2.layout and tuple(c1.sensor_shape) == tuple(c2.sensor_shape)
            and (c1.n_rows, c1.n_cols) == (c2.n_rows, c2.n_cols)
            and np.allclose([c1.pitch_px, c1.rotation_deg, *c1.origin_px],
                            [c2.pitch_px, c2.rotation_deg, *c2.origin_px], rtol=0, atol=1e-9))
