"""The plenoptic 1.0 camera: one place that defines its geometry.

Geometry (SPEC.md, worked from the paper's Sec. III-A and Fig. 5): a thin main lens
of focal length ``F`` focused on the object plane at ``z_f``; a microlens array (MLA)
at the image distance ``d = 1 / (1/F - 1/z_f)`` behind it; the sensor one lenslet
focal length behind the MLA (plenoptic 1.0, Ng 2005), so that each lenslet images
the main-lens aperture onto its ``N × N`` pixel block. The aperture is f-number
matched, ``D = d * pitch / g``, so that the lenslet images tile the sensor.

Axes: the raw sensor image has shape ``(n_rows * N, n_cols * N)`` (rows, columns),
read out rotated by 180° so the scene appears upright; object-space ``y`` points up,
``x`` to the right (mm).
"""
from __future__ import annotations

import dataclasses
import json
import math
import warnings
from dataclasses import dataclass

from .optics import ApertureStop, MicrolensArray, RayTransferMatrix, free_space, thin_lens


#: Largest tolerated relative error ``tan θ / θ - 1`` of the paraxial approximation at
#: the steepest ray (5 %, reached at 0.375 rad); beyond it the camera warns.
PARAXIAL_LIMIT = 0.05


@dataclass(frozen=True)
class PlenopticCamera:
    """A plenoptic 1.0 camera (main lens, microlens array, sensor).

    Parameters
    ----------
    main_focal_mm : float
        Main-lens focal length (mm). Paper: 150.
    focus_distance_mm : float
        Object distance of the focal plane in front of the main lens (mm), > focal
        length. Paper: 326.
    mla_pitch_mm, mla_focal_mm : float
        Lenslet pitch and focal length (mm). Paper: 0.112, 0.4.
    mla_sensor_mm : float or None
        MLA-to-sensor distance (mm); ``None`` means the lenslet focal length.
    pixels_per_lenslet : int
        ``N``, pixels under one lenslet along each axis (= number of views per axis).
    n_rows, n_cols : int
        Lenslet grid (= refocused image size). Paper preset: 180 × 90 (portrait).
    aperture_mm : float or None
        Main-lens clear aperture diameter (mm); ``None`` means f-number matched.

    Raises
    ------
    ValueError
        A non-positive or non-finite length or count, or a focal plane at or inside
        the main-lens focal length (its image would lie at infinity or be virtual).

    Warns
    -----
    UserWarning
        If the sensor is not at the lenslet focus (not a plenoptic 1.0 camera: the
        sub-aperture decomposition and slope formula assume it is), or if the steepest
        ray is past the paraxial limit :data:`PARAXIAL_LIMIT` (ray transfer matrices
        replace tan θ by θ; see :attr:`paraxial_error`).
    """

    main_focal_mm: float = 150.0
    focus_distance_mm: float = 326.0
    mla_pitch_mm: float = 0.112
    mla_focal_mm: float = 0.4
    mla_sensor_mm: float | None = None
    pixels_per_lenslet: int = 15
    n_rows: int = 180
    n_cols: int = 90
    aperture_mm: float | None = None

    def __post_init__(self):
        for name in ("main_focal_mm", "focus_distance_mm", "mla_pitch_mm", "mla_focal_mm",
                     "mla_sensor_mm", "aperture_mm"):
            v = getattr(self, name)
            if v is None and name in ("mla_sensor_mm", "aperture_mm"):
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"camera {name} must be a finite positive number (mm). Received: {name}={v!r}")
        for name in ("pixels_per_lenslet", "n_rows", "n_cols"):
            v = getattr(self, name)
            if not isinstance(v, int) or v < 1:
                raise ValueError(f"camera {name} must be a positive integer. Received: {name}={v!r}")
        if self.focus_distance_mm <= self.main_focal_mm:
            raise ValueError(
                "focal plane must lie beyond the main-lens focal length (else its image is at "
                f"infinity or virtual). Received: focus_distance_mm={self.focus_distance_mm}, "
                f"main_focal_mm={self.main_focal_mm}")
        if abs(self.sensor_distance_mm - self.mla_focal_mm) > 1e-9:
            warnings.warn(
                f"sensor at {self.sensor_distance_mm} mm behind the MLA, not at the lenslet focus "
                f"{self.mla_focal_mm} mm: this is not a plenoptic 1.0 camera and the slope formula "
                "and sub-aperture views assume one", UserWarning, stacklevel=3)
        if self.paraxial_error > PARAXIAL_LIMIT:
            warnings.warn(
                f"the steepest ray (aperture rim to sensor corner) makes {self.max_ray_angle_rad:.3f} rad with "
                f"the axis, where tan θ differs from θ by {100 * self.paraxial_error:.1f} % (limit "
                f"{100 * PARAXIAL_LIMIT:.0f} %): the ray transfer matrices are paraxial and lose accuracy here",
                UserWarning, stacklevel=3)

    # ---- derived geometry -------------------------------------------------------
    @property
    def max_ray_angle_rad(self) -> float:
        """Angle (radians) of the steepest ray: from the main-lens aperture rim to the
        farthest sensor corner across the axis, over the main-lens-to-MLA distance."""
        half_diag = 0.5 * math.hypot(self.n_rows, self.n_cols) * self.mla_pitch_mm
        return math.atan((0.5 * self.aperture_diameter_mm + half_diag) / self.mla_distance_mm)

    @property
    def paraxial_error(self) -> float:
        """Relative error ``tan θ / θ - 1`` of the small-angle approximation at
        :attr:`max_ray_angle_rad` (about θ²/3): 1.1 % (0.179 rad) for the paper's camera."""
        t = self.max_ray_angle_rad
        return math.tan(t) / t - 1.0

    @property
    def sensor_distance_mm(self) -> float:
        """MLA-to-sensor distance ``g`` (mm)."""
        return self.mla_focal_mm if self.mla_sensor_mm is None else float(self.mla_sensor_mm)

    @property
    def mla_distance_mm(self) -> float:
        """Main lens to MLA ``d = 1/(1/F - 1/z_f)`` (mm): 277.84 for the paper's camera."""
        return self.image_distance_mm(self.focus_distance_mm)

    @property
    def aperture_diameter_mm(self) -> float:
        """Main-lens aperture (mm); f-number matched ``d * pitch / g`` unless given (77.8)."""
        if self.aperture_mm is not None:
            return float(self.aperture_mm)
        return self.mla_distance_mm * self.mla_pitch_mm / self.sensor_distance_mm

    @property
    def lenslet_image_pitch_mm(self) -> float:
        """Spacing (mm) of the lenslet images on the sensor: ``pitch (1 + g/d)``.

        Each lenslet image is centred where the chief ray from the main-lens centre
        through the lenslet centre meets the sensor, so the images are spread by
        ``(d + g) / d`` (1.00144 for the paper's camera). Pixel blocks are aligned to
        these centres, as a calibrated plenoptic 1.0 camera's decoding does (Dansereau
        et al. 2013); then sub-aperture view (u, v) sees one fixed part of the main
        lens and the slope of :meth:`slope_for_depth` is exact. Aligning blocks to the
        lenslets instead would make the slope ``-(z_i - d)/(g N)`` (2.17, not 2.28, at +20 mm).
        """
        return self.mla_pitch_mm * (1.0 + self.sensor_distance_mm / self.mla_distance_mm)

    @property
    def pixel_pitch_mm(self) -> float:
        """Sensor pixel pitch (mm): lenslet image pitch / N (7.477 µm for the paper's camera)."""
        return self.lenslet_image_pitch_mm / self.pixels_per_lenslet

    @property
    def sensor_shape(self) -> tuple[int, int]:
        """Raw image shape ``(n_rows * N, n_cols * N)`` in pixels."""
        n = self.pixels_per_lenslet
        return self.n_rows * n, self.n_cols * n

    @property
    def microlens_array(self) -> MicrolensArray:
        return MicrolensArray(self.mla_pitch_mm, self.mla_focal_mm, self.n_rows, self.n_cols)

    # ---- ray transfer matrices --------------------------------------------------
    @property
    def aperture_stop(self) -> ApertureStop:
        """The main lens's clear aperture (:attr:`aperture_diameter_mm`), at the lens."""
        return ApertureStop(self.aperture_diameter_mm)

    @property
    def main_lens(self) -> RayTransferMatrix:
        return thin_lens(self.main_focal_mm)

    def object_to_mla(self, object_distance_mm: float) -> RayTransferMatrix:
        """ABCD chain from an object plane to the MLA (before its lenslets)."""
        return free_space(self.mla_distance_mm) @ self.main_lens @ free_space(object_distance_mm)

    def image_distance_mm(self, object_distance_mm: float) -> float:
        """Thin-lens image distance (mm) of an object plane ``z`` mm in front of the main lens.

        Raises
        ------
        ValueError
            If ``z <= F`` (image at infinity or virtual).
        """
        z = float(object_distance_mm)
        if not math.isfinite(z) or z <= self.main_focal_mm:
            raise ValueError(
                f"object at {z} mm is at or inside the main-lens focal length {self.main_focal_mm} mm: "
                "its image is at infinity or virtual")
        return 1.0 / (1.0 / self.main_focal_mm - 1.0 / z)

    def object_distance_mm(self, depth_offset_mm: float) -> float:
        """Object distance ``z_f + dz`` (mm); ``dz > 0`` is farther from the camera."""
        return self.focus_distance_mm + float(depth_offset_mm)

    # ---- slope <-> depth (the paper's sign convention) -------------------------
    def slope_for_depth(self, depth_offset_mm: float) -> float:
        """Refocus slope (lenslets of shift per view step) of the plane at ``dz`` mm.

        ``s = -d (1 - d / z_i) / (g N)`` with ``z_i`` the image distance of the plane
        (SPEC.md). A point of that plane appears at lenslet ``x0 + s (u - (N-1)/2)``
        in sub-aperture view ``u``. Sign: the paper's (near planes negative):
        −1.249, 0, +1.170, +2.280 for dz = −10, 0, +10, +20 mm.
        """
        d = self.mla_distance_mm
        zi = self.image_distance_mm(self.object_distance_mm(depth_offset_mm))
        return -d * (1.0 - d / zi) / (self.sensor_distance_mm * self.pixels_per_lenslet)

    def depth_for_slope(self, slope: float) -> float:
        """Inverse of :meth:`slope_for_depth`: depth offset (mm) of the plane in focus at ``slope``.

        Raises
        ------
        ValueError
            If no real object plane is in focus at that slope (image at or before the lens).
        """
        d = self.mla_distance_mm
        denom = 1.0 + float(slope) * self.sensor_distance_mm * self.pixels_per_lenslet / d
        if denom <= 0:
            raise ValueError(f"slope {slope} corresponds to no real object plane")
        zi = d / denom
        if zi <= self.main_focal_mm:
            raise ValueError(f"slope {slope} focuses at or beyond infinity (image distance {zi:.3f} mm)")
        return 1.0 / (1.0 / self.main_focal_mm - 1.0 / zi) - self.focus_distance_mm

    def object_to_lenslet(self, y_mm: float, x_mm: float, depth_offset_mm: float) -> tuple[float, float]:
        """Lenslet coordinates ``(row, col)`` (fractional, pixel-centre at +0.5) of an object point.

        The chief ray through the main-lens centre hits the MLA at ``-y d / z``; with the
        rotated read-out, row = R/2 − y d / (z pitch), col = C/2 + x d / (z pitch). This is
        where the point appears in the refocused image at its own slope.
        """
        m = self.mla_distance_mm / self.object_distance_mm(depth_offset_mm) / self.mla_pitch_mm
        return self.n_rows / 2 - y_mm * m, self.n_cols / 2 + x_mm * m

    def field_of_view_mm(self, depth_offset_mm: float = 0.0) -> tuple[float, float]:
        """Object-space field (height, width) in mm seen by the lenslet grid at ``dz``."""
        s = self.object_distance_mm(depth_offset_mm) / self.mla_distance_mm
        return self.n_rows * self.mla_pitch_mm * s, self.n_cols * self.mla_pitch_mm * s

    # ---- serialisation --------------------------------------------------------------
    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_dict(cls, d: dict) -> "PlenopticCamera":
        """Build from a dict (e.g. a dataset attribute); unknown keys raise ``ValueError``."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise ValueError(f"unknown camera fields: {sorted(unknown)}")
        return cls(**d)


#: The paper's camera (SPEC.md table): 150 mm lens focused at 326 mm, 180 × 90 lenslets.
PAPER_CAMERA = PlenopticCamera()
