"""Light fields in: one value, whatever the camera, that every route takes.

A :class:`LightField` holds the sub-aperture views, the camera they are views of, the
samples to leave out of a fit, and, for views decoded from a capture, the real camera and
where the views' planes lie in its object space; :func:`from_raw` and :func:`from_decoded` make one. Every reader
(:mod:`lf_flame.real.readers`) returns one:

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

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.depth_range import search_range_mm
from .own_camera import DecodedFrame



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
        """Depths to search, mm from the focus distance (:func:`lf_flame.optics.depth_range.search_range_mm`)."""
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
        A colour capture's sensor (:func:`lf_flame.real.readers.capture_sensor`): its CFA gives the channel map.

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
