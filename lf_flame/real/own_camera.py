"""Real cameras, stage 3: the camera that decoded views come from.

A camera file (:mod:`lf_flame.optics.camera_file`) says what the optics are; the
white-image calibration (:mod:`.calibration`) where the lenslet grid lies; decoding
(:mod:`.decoding`) what views were cut from it. :func:`views_camera` checks that they
describe one camera and returns the perfect-grid camera of the decoded views
(:func:`lf_flame.optics.camera_file.decoded_camera`), on which
:class:`lf_flame.tomo.exact.ExactOperator` is built; :func:`decoded_frame` says where its
planes lie in the real camera's object space (turned by the grid's rotation, shifted by
the decoded grid's offset from the optical axis).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.camera_file import decoded_camera
from .calibration import GridCalibration
from .lattice import _H

#: Relative difference between the lenslet image pitch a camera file implies
#: (``pitch (1 + g/d) / pixel``) and the calibrated one above which :func:`views_camera`
#: warns (1 %: 0.1 px on a 10-px pitch), and above which it refuses (5 %): the file's optics
#: (often the main lens's distance) are not the set-up the white image was taken with. Real
#: captures' stated optics differ from their calibrated pitch by 0.10-1.79 % (README, "Real
#: light fields").
PITCH_WARN, PITCH_TOLERANCE = 0.01, 0.05


@dataclass(frozen=True)
class DecodedFrame:
    """Where the decoded views' planes lie in the real camera's object space.

    Attributes
    ----------
    rotation_deg : float
        The lenslet grid's rotation (the calibration's): the decoded planes' rows and
        columns are the object's turned by it (sign of ``grid_rotation_deg``).
    centre_lenslets : (float, float)
        The decoded grid's centre minus the optical axis (taken at the sensor's centre),
        in lenslet pitches along the grid's rows and columns.
    """

    rotation_deg: float
    centre_lenslets: tuple[float, float]

    def to_dict(self) -> dict:
        return {"rotation_deg": self.rotation_deg, "centre_lenslets": list(self.centre_lenslets)}

    def object_to_lenslet(self, camera: PlenopticCamera, shape, y_mm: float, x_mm: float,
                          depth_offset_mm: float) -> tuple[float, float]:
        """Where an object point lies on the decoded planes: the inverse of
        :func:`lf_flame.tomo.decoded.decoded_plane_truth`'s map from a sample to its object point.

        Parameters
        ----------
        camera : PlenopticCamera
            The decoded views' camera.
        shape : (int, int)
            The decoded views' lenslet grid (``views.shape[2:]``).
        y_mm, x_mm : float
            The object point (``y`` up, ``x`` right), mm from the optical axis.
        depth_offset_mm : float
            Its depth, mm from the focus distance.

        Returns
        -------
        (float, float)
            Lenslet coordinates ``(row, col)`` of the decoded grid, fractional, a lenslet's centre at +0.5 (as
            :meth:`lf_flame.optics.camera.PlenopticCamera.object_to_lenslet` gives them on a perfect grid).
        """
        scale = camera.mla_pitch_mm * camera.object_distance_mm(depth_offset_mm) / camera.mla_distance_mm
        q_r, q_c = -y_mm / scale, x_mm / scale                      # sensor-frame offsets, pitches
        t = math.radians(self.rotation_deg)
        a_r = math.cos(t) * q_r - math.sin(t) * q_c                 # along the grid's rows and columns
        a_c = math.sin(t) * q_r + math.cos(t) * q_c
        R, C = shape
        return a_r - self.centre_lenslets[0] + R / 2, a_c - self.centre_lenslets[1] + C / 2


def decoded_frame(calibration: GridCalibration, n_rows: int, n_cols: int) -> DecodedFrame:
    """The decoded grid's rotation and its centre's offset from the optical axis.

    Parameters
    ----------
    calibration : GridCalibration
    n_rows, n_cols : int
        The decoded views' lenslet grid (``views.shape[2:]``): the calibration's, or for a
        hexagonal grid the square lattice of :func:`lf_flame.real.view_grid.hex_to_square`.

    Returns
    -------
    DecodedFrame

    Raises
    ------
    ValueError
        A grid size that the calibration does not decode to.
    """
    calibration.validate()
    if calibration.layout == "hex":
        expect = (int(math.floor((calibration.n_rows - 1) * _H)) + 1, calibration.n_cols - 1)
        mid = np.array([(n_rows - 1) / 2, 0.5 + (n_cols - 1) / 2])   # hex_to_square's lattice, pitches
    else:
        expect = (calibration.n_rows, calibration.n_cols)
        mid = np.array([(n_rows - 1) / 2, (n_cols - 1) / 2])
    if (n_rows, n_cols) != expect:
        raise ValueError(f"views of {n_rows} x {n_cols} lenslets were not decoded with this calibration "
                         f"({calibration.layout} grid decoding to {expect[0]} x {expect[1]})")
    centre_px = np.asarray(calibration.origin_px) + calibration.matrix @ mid
    axis_px = np.asarray(calibration.sensor_shape, np.float64) / 2
    lat = np.linalg.solve(calibration.matrix, centre_px - axis_px)       # pitches along the grid's axes
    return DecodedFrame(float(calibration.rotation_deg), (float(lat[0]), float(lat[1])))


def views_camera(camera: PlenopticCamera, calibration: GridCalibration, views_shape,
                 bin_views: int = 1) -> PlenopticCamera:
    """The perfect-grid camera of views decoded from ``camera`` with ``calibration``.

    Parameters
    ----------
    camera : PlenopticCamera
        The real camera (:func:`lf_flame.optics.camera_file.load_camera_file`).
    calibration : GridCalibration
        The white-image calibration the views were decoded with.
    views_shape : (N, N, R, C)
    bin_views : int
        Pixels per view sample and axis (:func:`lf_flame.real.decoding.decode`'s ``bin_views``).

    Returns
    -------
    PlenopticCamera
        :func:`lf_flame.optics.camera_file.decoded_camera` of ``(N k, R, C)`` (``k`` = ``bin_views``)
        with ``N`` pixels per lenslet: its pixel is ``k`` of the decoded camera's, at the same
        distance behind the lenslets. What it leaves out is stated there.

    Raises
    ------
    ValueError
        Images larger than the camera's sensor, another layout than the camera's, a calibrated pitch more than
        :data:`PITCH_TOLERANCE` away from the camera's, views of another shape than the
        calibration decodes to, or the errors of ``decoded_camera``.

    Warns
    -----
    UserWarning
        A calibrated pitch more than :data:`PITCH_WARN` away from the camera's; images smaller
        than the camera's sensor (a centred crop: a datasheet gives the whole sensor, a capture
        file often less).
    """
    shape = tuple(int(v) for v in views_shape)
    if len(shape) != 4 or shape[0] != shape[1]:
        raise ValueError(f"views of shape {shape} are not (N, N, R, C)")
    check_calibration(camera, calibration)
    decoded_frame(calibration, shape[2], shape[3])                      # views of this calibration
    if isinstance(bin_views, bool) or int(bin_views) != bin_views or bin_views < 1:
        raise ValueError(f"bin_views must be an integer >= 1. Received: {bin_views!r}")
    k = int(bin_views)
    return replace(decoded_camera(camera, shape[0] * k, shape[2], shape[3]), pixels_per_lenslet=shape[0])


def decoded_views_camera(camera: PlenopticCamera, calibration: GridCalibration,
                         colour: bool = False) -> tuple[PlenopticCamera, int]:
    """The camera of the views that ``lf-flame decode`` decodes ``camera``'s captures to with ``calibration`` by
    default, before any is decoded (a recording's frames, a learned reconstructor trained for those views).

    Parameters
    ----------
    camera : PlenopticCamera
        The real camera (:func:`lf_flame.optics.camera_file.load_camera_file`).
    calibration : GridCalibration
    colour : bool
        A colour camera's captures: no pixels binned (each sample keeps its own channel).

    Returns
    -------
    (PlenopticCamera, int)
        :func:`views_camera` of the views' shape (:func:`lf_flame.real.view_grid.views_shape`), and the pixels
        binned per view sample and axis (:func:`lf_flame.real.view_grid.auto_bin`; 1 for ``colour``).

    Raises
    ------
    ValueError
        As :func:`views_camera`.
    """
    from .view_grid import auto_bin, views_shape
    k = 1 if colour else auto_bin(calibration)
    return views_camera(camera, calibration, views_shape(calibration, None, k), k), k


def check_calibration(camera: PlenopticCamera, calibration: GridCalibration) -> None:
    """Refuse a white-image calibration of another set-up than ``camera``'s (:func:`views_camera`'s checks of the
    sensor, the grid's layout and its pitch).

    Raises
    ------
    ValueError
        Images larger than the camera's sensor, another layout than the camera's, a calibrated pitch more than
        :data:`PITCH_TOLERANCE` away from the camera's.

    Warns
    -----
    UserWarning
        A calibrated pitch more than :data:`PITCH_WARN` away from the camera's; images smaller than its sensor.
    """
    (H, W), (Hc, Wc) = calibration.sensor_shape, camera.sensor_shape
    if (H, W) != (Hc, Wc):
        if not (H <= Hc and W <= Wc):
            raise ValueError(f"the white-image calibration's images are {H} x {W} px, larger than the camera's {Hc} x "
                             f"{Wc} px sensor: another camera")
        warnings.warn(f"the images are {H} x {W} px of the camera's {Hc} x {Wc} px sensor: taken as its centred "
                      "crop (the optical axis at the image's centre, as the file's offset_px counts it)", UserWarning,
                      stacklevel=3)
    if calibration.layout != camera.grid_layout:
        raise ValueError(f"the calibration found a {calibration.layout} lenslet grid, the camera file says "
                         f"{camera.grid_layout}")
    off = abs(calibration.pitch_px / camera.grid_pitch - 1)
    msg = (f"the calibrated lenslet images are {calibration.pitch_px:.3f} px apart, the camera's optics give "
           f"{camera.grid_pitch:.3f} px (pitch (1 + g/d) / pixel, {100 * off:.2f} % off): check the camera file's "
           "distances and pixel size against this set-up, and that the calibration's white image is of this set-up "
           "(another camera's calibration decodes every lenslet image off its place)")
    if off > PITCH_TOLERANCE:
        raise ValueError(msg + f" ({100 * PITCH_TOLERANCE:g} % tolerated)")
    if off > PITCH_WARN:
        warnings.warn(msg + "; the views' angles are taken from the file", UserWarning, stacklevel=3)


def nominal_views_camera(camera: PlenopticCamera) -> PlenopticCamera:
    """The perfect-grid camera of the views that decoding would cut from ``camera`` as its file
    states it (no calibration: the lenslet images at the optics' pitch, every view they hold, each
    lenslet of the file's grid; a hexagonal grid's square lattice, :func:`lf_flame.real.view_grid.hex_to_square`);
    ``camera`` itself where its grid is perfect already. For what needs the camera before any capture
    (``lf-flame resolution``); a capture's views take :func:`views_camera` of their calibration.

    Parameters
    ----------
    camera : PlenopticCamera
        :func:`lf_flame.optics.camera_file.load_camera_file`'s.

    Returns
    -------
    PlenopticCamera

    Raises
    ------
    ValueError
        The errors of :func:`lf_flame.optics.camera_file.decoded_camera`.
    """
    from .view_grid import _square_grid, views_for_pitch
    if camera.perfect_grid:
        return camera
    n = views_for_pitch(camera.grid_pitch)
    R, C = ((camera.n_rows, camera.n_cols) if camera.grid_layout == "square" else
            _square_grid(camera.n_rows, camera.n_cols))
    return replace(decoded_camera(camera, n, R, C), pixels_per_lenslet=n)
