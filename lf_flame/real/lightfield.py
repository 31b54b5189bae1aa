"""Light fields in: one value, whatever the camera, that every route takes.

A :class:`LightField` holds the sub-aperture views, the camera they are views of, the
samples to leave out of a fit, and, for views decoded from a capture, the real camera and
where the views' planes lie in its object space. Every reader returns one:

- a raw image of a perfect lenslet grid (what ``lf-flame simulate`` writes, with its
  camera; or any image with a camera file whose grid is perfect): split into views
  (:func:`lf_flame.refocus.shift_and_sum.raw_to_views`);
- views decoded by ``lf-flame decode`` (``VIEWS.h5``) with the camera file;
- a raw capture with its white-image calibration and the camera file: decoded here
  (:func:`lf_flame.real.decoding.decode`, the calibration's white image).

For decoded views, :attr:`LightField.camera` is the perfect-grid camera of the decoded
views (:func:`lf_flame.real.own_camera.views_camera`), on which the exact operator is
built; its planes are the real object's turned and shifted by :attr:`LightField.frame`.
So a route never asks which camera it runs on (plenoptomos' ``Lightfield`` keeps data,
camera and mask together in the same way).
"""
from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..optics.camera import PlenopticCamera, search_range_mm
from .own_camera import DecodedFrame

#: Suffixes read as a raw image by :func:`read_light_field` (besides ``VIEWS.h5``).
RAW_SUFFIXES = (".npz", ".npy", ".png", ".tif", ".tiff")


@dataclass(frozen=True, eq=False)
class LightField:
    """Sub-aperture views with the camera they are views of.

    Attributes
    ----------
    views : ndarray of shape (N, N, R, C), float32
        View row ``u``, view column ``v``, lenslet row, lenslet column; radiance units
        (simulated) or relative to the white target (decoded, ``white_normalised``).
    camera : PlenopticCamera
        A perfect lenslet grid whose views these are: slope <-> depth, the exact operator.
    source : str
        Where the views came from (a path, or a description).
    leave_out : ndarray of bool of the views' shape, or None
        Samples not to fit (decoded from clipped or defective pixels). None: none recorded.
    saturation : float or None
        The clipping level in the views' units where no mask says it (a raw image's: found in it,
        :func:`lf_flame.real.clipping.auto_saturation`; 1.0 for the simulator's); None with a
        mask, or for decoded views.
    white_normalised : bool
        Decoded views divided by the white image: the exact operator's data are the views
        times its own white views (:func:`lf_flame.tomo.decoded.decoded_problem`).
    frame : DecodedFrame or None
        Where the planes lie in the real camera's object space (decoded views); None: the
        camera's own frame.
    capture_camera : PlenopticCamera or None
        The real camera (its camera file) of decoded views.
    camera_file : str or None
        The camera file's path, when one was read.
    channels : ndarray of int8 or None
        A colour capture decoded with its channels apart
        (:func:`lf_flame.real.decoding.decode_colour`): each sample's channel (0 R, 1 G, 2 B), of
        the views' shape, or of :attr:`lattice_views`' where there are some (a hexagonal grid's
        channels stay on its lattice; its square ``views`` blend them).
    lattice_views : ndarray of shape (N, N, rows, lenslets per row), float32, or None
        A hexagonal grid's views on its own lattice, before ``views`` resampled them onto the
        square grid (``decode(..., resample=False)``): the data of
        :class:`lf_flame.tomo.lattice.LatticeOperator`, which ``lf-flame reconstruct``
        solves on. None: a square grid (or views decoded without them).
    lattice_leave_out : ndarray of bool of the lattice views' shape, or None
        Their samples from clipped pixels.
    sample_offsets : ndarray of shape (N, N, R, C, 2), float32, or None
        A colour capture's samples, each its nearest pixel: where that pixel lies from its view's
        place (view steps; :func:`lf_flame.real.view_grid.sample_offsets`), which the exact
        operator models (:class:`lf_flame.tomo.exact.ExactOperator`'s ``sample_offsets``); of
        :attr:`lattice_views`' shape where there are some. None: every sample at its view's place.
    interpolation : (ndarray of shape (2, M), int) or None
        Decoded views (bilinear, not a colour capture's nearest pixels): where their samples fell
        between pixels (:func:`lf_flame.real.view_grid.interpolation_phases`) and the pixels per
        view sample and axis, for the operator that models decoding's interpolation
        (:class:`lf_flame.tomo.lattice.LatticeOperator`).
    defective_pixels : int
        The capture's defective pixels (hot, dead: :mod:`lf_flame.real.defects`), repaired in the views and left
        out of every fit: decoded views' samples from them are in ``leave_out``, a raw image's in ``defects``.
    defects : ndarray of bool of the views' shape, or None
        A raw image's samples from defective pixels (the clipping level, or a level a command is given, adds its
        own: :meth:`fit_mask`). None: none.
    clipped_share : float or None
        A decoded capture's clipped pixels as a share of its lit ones
        (:func:`lf_flame.real.clipping.clipped_share`, of the raw image at decoding: a decoded sample mixes
        several pixels); None: a raw image's, read off its views and ``saturation`` (:meth:`over_exposure`).
    level : float or None
        A decoded capture's clipping level at decoding, in its raw image's units (which a colour capture's decoded
        views keep: each channel's white image is divided by its 99th percentile; a monochrome capture's views are
        relative to the white image, :attr:`unit`); None: not known.
    unlit_level : float or None
        A decoded capture's pixels where its white image is dark, their median over its bright pixels
        (:func:`lf_flame.real.black_level.unlit_level`, at decoding): about 0 unless a black level or stray light
        was left in (``lf-flame decode`` records it in the views file). None: not read (no white image, a raw
        image, views decoded before it was recorded).
    """

    views: np.ndarray
    camera: PlenopticCamera
    source: str = ""
    leave_out: np.ndarray | None = None
    saturation: float | None = 1.0
    white_normalised: bool = False
    frame: DecodedFrame | None = None
    capture_camera: PlenopticCamera | None = None
    camera_file: str | None = None
    meta: dict = field(default_factory=dict)
    channels: np.ndarray | None = None
    lattice_views: np.ndarray | None = None
    lattice_leave_out: np.ndarray | None = None
    interpolation: tuple | None = None
    sample_offsets: np.ndarray | None = None
    defective_pixels: int = 0
    defects: np.ndarray | None = None
    clipped_share: float | None = None
    unlit_level: float | None = None
    level: float | None = None

    def __post_init__(self):
        v = self.views
        if v.ndim != 4 or v.shape[0] != v.shape[1]:
            raise ValueError(f"{self.source}: views of shape {v.shape} are not (N, N, R, C)")
        cam = self.camera
        want = (cam.pixels_per_lenslet, cam.pixels_per_lenslet, cam.n_rows, cam.n_cols)
        if v.shape != want:
            raise ValueError(f"{self.source}: views of shape {v.shape} are not the views of its camera {want} "
                             "(N, N, rows, cols)")
        for name in ("leave_out", "defects"):
            m = getattr(self, name)
            if m is not None and (m.shape != v.shape or m.dtype != bool):
                raise ValueError(f"{self.source}: {name} must be boolean of the views' shape {v.shape}")
        lv = self.lattice_views
        if lv is not None and (lv.ndim != 4 or lv.shape[:2] != v.shape[:2] or not np.all(np.isfinite(lv))):
            raise ValueError(f"{self.source}: lattice views of shape {lv.shape} are not finite views (N, N, rows, "
                             f"cols) with the views' N = {v.shape[0]}")
        if self.lattice_leave_out is not None and (lv is None or self.lattice_leave_out.shape != lv.shape):
            raise ValueError(f"{self.source}: lattice_leave_out must have the lattice views' shape")
        mapped = v.shape if lv is None else lv.shape
        if self.sample_offsets is not None and np.shape(self.sample_offsets) != mapped + (2,):
            raise ValueError(f"{self.source}: sample_offsets must be of shape {mapped + (2,)} (the views' they map, "
                             "and 2)")

    def over_exposure(self) -> float:
        """The clipped pixels' share of the lit ones: :attr:`clipped_share` where decoding measured it, else the
        views' (a perfect grid's raw pixels) at or above :attr:`saturation`
        (:func:`lf_flame.real.clipping.clipped_share`); 0 with neither."""
        from .clipping import clipped_share
        if self.clipped_share is not None:
            return float(self.clipped_share)
        return 0.0 if self.decoded else clipped_share(self.views, self.saturation)

    @property
    def decoded(self) -> bool:
        """Views decoded from a capture (their planes are in :attr:`frame`)."""
        return self.frame is not None

    @property
    def unit(self) -> float:
        """The views' unit for the solvers (:func:`lf_flame.tomo.solvers.reconstruct`'s ``unit``): the sensor's
        clipping level in the views' units (:attr:`saturation`; a decoded capture's :attr:`level`), 1.0 where none
        is known. A mask of samples to leave out (:meth:`fit_mask`) does not carry it. Monochrome views decoded
        with a white image are that image's radiance ratio (:func:`lf_flame.real.decoding.decode` divides by the
        white image as it is), whatever units the raw and white files were in: their unit is 1.0, the white
        target's (a colour capture's views keep the raw's units: each channel's white is divided by its 99th
        percentile first; 16-bit captures had been solved with their level, 65535, as the unit of such views, and
        the weights had swamped the data: 58 % of the light field unexplained on its true planes)."""
        if self.decoded and self.white_normalised and "sensor" not in self.meta:
            return 1.0
        level = self.level if self.decoded else self.saturation
        return float(level) if level is not None else 1.0

    def fit_mask(self):
        """``reconstruct``'s ``saturation``: the mask of samples to leave out, else the level; with
        :attr:`defects`, those samples too (a mask)."""
        own = self.leave_out if self.leave_out is not None else self.saturation
        if self.defects is None:
            return own
        if own is None:
            return self.defects
        return self.defects | (own if np.ndim(own) else self.views >= own)

    def lit_views(self) -> np.ndarray:
        """The views a depth search refocuses, (N, N) bool: those inside the main lens's aperture image
        (:func:`lf_flame.refocus.shift_and_sum.lit_views`; decoded views' samples interpolated between pixels,
        ``k x k`` of them summed per sample, a colour capture's its nearest pixels)."""
        from ..refocus.shift_and_sum import lit_views
        return lit_views(self.camera, tent=0.0 if self.interpolation is None else 1.0 / self.interpolation[1])

    def depth_range_mm(self, depth_range_mm=None) -> tuple[float, float]:
        """Depths to search, mm from the focus distance (:func:`lf_flame.optics.camera.search_range_mm`)."""
        return search_range_mm(self.camera, depth_range_mm)


def from_raw(raw, camera: PlenopticCamera, source: str = "raw image", saturation: float | str | None = "auto",
             camera_file: str | None = None, meta: dict | None = None, sensor=None) -> LightField:
    """The light field of a raw image of a perfect lenslet grid, its defective pixels repaired and left out of the fit
    (:func:`lf_flame.real.defects.defective_pixels`); a colour sensor's mosaic with each sample's channel
    (``channels``: each view sample is one pixel, of that pixel's channel).

    Parameters
    ----------
    raw : ndarray of shape (R N, C N)
    camera : PlenopticCamera
        Perfect grid (whole pixels per lenslet, square, unrotated); its sensor the image's size.
    saturation : float, "auto" or None
        The sensor's clipping level in the image's units (pixels at or above it are left out of
        the fit); "auto": found in the image (:func:`lf_flame.real.clipping.auto_saturation`:
        where its pixels pile up at its largest value, else 1.0 for an image in [0, 1]); None:
        none.
    sensor : ColourSensor or None
        A colour capture's sensor (:func:`capture_sensor`): its CFA gives the channel map.

    Raises
    ------
    ValueError
        A camera whose grid is not perfect (give the white-image calibration: decode), or an
        image of another size than the camera's sensor.
    """
    from ..refocus.shift_and_sum import raw_to_views
    from .defects import defective_pixels, grid_offsets
    raw = np.asarray(raw)
    if not camera.perfect_grid:
        raise ValueError(f"{source}: the camera's lenslet images are {camera.grid_pitch:.3f} px apart"
                         f"{', rotated' if camera.grid_rotation_deg else ''}: not whole pixels on a square grid, so "
                         "the image must be decoded: give its white-image calibration (--calibration cal.json)")
    if raw.ndim != 2 or tuple(raw.shape) != tuple(camera.sensor_shape):
        raise ValueError(f"{source}: an image of shape {raw.shape} is not this camera's "
                         f"{camera.sensor_shape[0]} x {camera.sensor_shape[1]} px raw image (a crop of the sensor is "
                         "decoded with the white-image calibration of the same crop: --calibration cal.json)")
    if not np.all(np.isfinite(raw)):
        raise ValueError(f"{source}: the raw image contains NaN or infinite values")
    if isinstance(saturation, str) and saturation != "auto":
        raise ValueError(f"saturation must be a level, 'auto' or None. Received: {saturation!r}")
    n = camera.pixels_per_lenslet
    colour = sensor is not None or bool((meta or {}).get("sensor"))
    flagged, repaired = defective_pixels(raw, grid_offsets(n, colour=colour))
    n_bad = int(np.count_nonzero(flagged))
    views = raw_to_views(repaired.astype(raw.dtype) if n_bad else raw, n)
    if saturation == "auto":                            # found in the views' own values (float32: their rounding)
        from .clipping import found_level
        saturation = found_level(views)
    channels = None if sensor is None else raw_to_views(sensor.channel_map(raw.shape).astype(np.float32),
                                                        n).astype(np.int8)
    from .black_level import negative_note
    negative = negative_note(views, source)
    if negative:
        warnings.warn(negative, stacklevel=2)
    return LightField(views, camera, source, saturation=saturation, camera_file=camera_file, meta=dict(meta or {}),
                      defective_pixels=n_bad, defects=raw_to_views(flagged, n) > 0.5 if n_bad else None,
                      channels=channels)


def from_decoded(views, calibration, camera: PlenopticCamera, source: str = "decoded views", clipped=None,
                 white_normalised: bool = True, camera_file: str | None = None, channels=None,
                 meta: dict | None = None, bin_views: int = 1, lattice_views=None, lattice_clipped=None,
                 defective_pixels: int = 0, clipped_share: float | None = None,
                 unlit_level: float | None = None, level: float | None = None) -> LightField:
    """The light field of views decoded from a capture of ``camera`` with ``calibration``.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        :func:`lf_flame.real.decoding.decode`'s views.
    calibration : GridCalibration
    camera : PlenopticCamera
        The real camera (its camera file).
    clipped : ndarray of bool of the views' shape, or None
    channels : ndarray of int8 or None
        A colour capture's channel map (:func:`lf_flame.real.decoding.decode_colour`), of the
        views' shape (of ``lattice_views``' where given: a hexagonal grid's channels stay there).
    meta : dict or None
        Records kept with the views (``sensor``: a colour capture's sensor, JSON).
    bin_views : int
        Pixels per view sample and axis they were decoded with.
    lattice_views, lattice_clipped : ndarray or None
        A hexagonal grid's views on its own lattice and their clipped samples (:class:`LightField`).
    defective_pixels : int
        The capture's defective pixels, repaired before decoding (:class:`LightField`).
    clipped_share : float or None
        The capture's clipped pixels as a share of its lit ones (:class:`LightField`); None: not measured.
    unlit_level : float or None
        What the capture's unlit pixels read (:class:`LightField`); None: not read.
    level : float or None
        The capture's clipping level at decoding (:class:`LightField`); None: not known.

    Raises
    ------
    ValueError
        As :func:`lf_flame.real.own_camera.views_camera` (another sensor, layout or pitch);
        NaN or inf in the views.
    """
    from .view_grid import interpolation_phases, sample_offsets
    from .own_camera import decoded_frame, views_camera
    v = np.asarray(views, np.float32)
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{source}: the views contain NaN or infinite values")
    vcam = views_camera(camera, calibration, v.shape, bin_views)
    frame = decoded_frame(calibration, *v.shape[2:])
    mapped = v.shape if lattice_views is None else np.shape(lattice_views)
    if channels is not None and np.shape(channels) != mapped:
        raise ValueError(f"{source}: a channel map of shape {np.shape(channels)} for views of shape {mapped}")
    if white_normalised and channels is None and "sensor" not in (meta or {}):
        from .decoding import dim_against_white
        dim = dim_against_white(v)
        if dim:
            warnings.warn(f"{source}: {dim}", stacklevel=2)
    from .black_level import negative_note
    negative = negative_note(v, source)
    if negative:
        warnings.warn(negative, stacklevel=2)
    return LightField(v, vcam, source, leave_out=clipped, saturation=None, white_normalised=white_normalised,
                      frame=frame, capture_camera=camera, camera_file=camera_file, meta=dict(meta or {}),
                      channels=None if channels is None else np.asarray(channels, np.int8),
                      lattice_views=None if lattice_views is None else np.asarray(lattice_views, np.float32),
                      lattice_leave_out=lattice_clipped,
                      interpolation=None if channels is not None else
                      (interpolation_phases(calibration, v.shape[0], bin_views), int(bin_views)),
                      sample_offsets=None if channels is None else sample_offsets(calibration, v.shape[0]),
                      defective_pixels=int(defective_pixels),
                      clipped_share=None if clipped_share is None else float(clipped_share),
                      unlit_level=None if unlit_level is None else float(unlit_level),
                      level=None if level is None else float(level))


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
