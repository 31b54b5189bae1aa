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

Lenslet grid: by default perfect (``N`` whole pixels per lenslet image, no rotation,
no offset), as the simulator has always rendered. A real camera's grid is not: the MLA
is rotated a little against the sensor, offset, and its images are a non-integer number
of pixels apart, on a square or hexagonal lattice. The ``grid_*`` fields describe such a
grid (:meth:`PlenopticCamera.lenslet_image_centres_px`); :mod:`lf_flame.simulate.tracer`
renders through it and :mod:`lf_flame.real.calibration` recovers it from a white image.
Pixel coordinates: pixel ``(i, j)`` covers rows ``[i, i + 1)`` and columns ``[j, j + 1)``.

The depths a camera can refocus, and the planes it refuses: :mod:`lf_flame.optics.depth_range`.
"""
from __future__ import annotations

import dataclasses
import json
import math
import warnings
from dataclasses import dataclass

from .matrices import ApertureStop, MicrolensArray, RayTransferMatrix, free_space, thin_lens


#: Lenslet lattices: square, or hexagonal with rows of lenslets along the columns,
#: ``sqrt(3)/2`` pitches apart and odd rows shifted by half a pitch.
GRID_LAYOUTS = ("square", "hex")

#: Largest grid rotation (degrees) per layout: beyond it the same lattice is described
#: by a smaller angle (a square lattice repeats every 90°, a hexagonal one every 60°).
MAX_GRID_ROTATION_DEG = {"square": 45.0, "hex": 30.0}
#: A pitch this close below a whole number of pixels holds that number of views: a calibration
#: measures the pitch within a few hundredths of a percent (14.9997 px for 15).
PITCH_SNAP_PX = 0.02


def views_for_pitch(pitch_px: float) -> int:
    """Views per axis a lenslet image ``pitch_px`` pixels wide holds, one pixel apart: ``floor(pitch_px +
    PITCH_SNAP_PX)``, the count decoding takes (:func:`lf_flame.real.view_grid.max_views`) and a camera file's
    ``pixels_per_lenslet`` (:func:`lf_flame.optics.camera_file.camera_from_datasheet`). ValueError for a pitch
    that is not a finite number of at least one pixel."""
    try:
        p = float(pitch_px)
    except (TypeError, ValueError):
        p = math.nan
    if isinstance(pitch_px, bool) or not (math.isfinite(p) and p >= 1):
        raise ValueError(f"a lenslet image's pitch must be a finite number of pixels >= 1. Received: {pitch_px!r}")
    return int(math.floor(p + PITCH_SNAP_PX))

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
    grid_pitch_px : float or None
        Spacing of the lenslet images on the sensor in pixels (non-integer allowed);
        ``None``: exactly ``N`` (the perfect grid). ``N`` is then the number of views per
        axis decoded under each lenslet image (``1 <= N <= grid_pitch_px``).
    grid_rotation_deg : float
        Rotation of the lenslet grid against the sensor (degrees; positive turns the
        lenslet rows from the column axis towards increasing rows), below
        :data:`MAX_GRID_ROTATION_DEG` in magnitude.
    grid_offset_px : (float, float)
        Offset (rows, columns) in pixels of the grid's centre from the sensor's centre.
    grid_layout : {'square', 'hex'}
        Lattice of the lenslets (:data:`GRID_LAYOUTS`).
    sensor_rows, sensor_cols : int or None
        Sensor size in pixels for a non-perfect grid; ``None``: the smallest that holds
        the rotated grid plus one pitch.

    Raises
    ------
    ValueError
        A non-positive or non-finite length or count, or a focal plane at or inside
        the main-lens focal length (its image would lie at infinity or be virtual);
        a grid pitch below 2 pixels or below ``N``, a rotation past
        :data:`MAX_GRID_ROTATION_DEG`, an unknown layout, grid fields other than the
        pitch given without a pitch, or a lenslet image centre off the sensor.

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
    grid_pitch_px: float | None = None
    grid_rotation_deg: float = 0.0
    grid_offset_px: tuple[float, float] = (0.0, 0.0)
    grid_layout: str = "square"
    sensor_rows: int | None = None
    sensor_cols: int | None = None

    def __post_init__(self):
        for f in dataclasses.fields(self):      # NumPy numbers (an HDF5 attribute's) as Python's
            v = getattr(self, f.name)
            if type(v).__module__ == "numpy" and getattr(v, "ndim", None) == 0:
                object.__setattr__(self, f.name, v.item())
        for name in ("main_focal_mm", "focus_distance_mm", "mla_pitch_mm", "mla_focal_mm",
                     "mla_sensor_mm", "aperture_mm"):
            v = getattr(self, name)
            if v is None and name in ("mla_sensor_mm", "aperture_mm"):
                continue
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"camera {name} must be a finite positive number (mm). Received: {name}={v!r}")
        for name in ("pixels_per_lenslet", "n_rows", "n_cols"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"camera {name} must be a positive integer. Received: {name}={v!r}")
        if self.focus_distance_mm <= self.main_focal_mm:
            raise ValueError(
                "focal plane must lie beyond the main-lens focal length (else its image is at "
                f"infinity or virtual). Received: focus_distance_mm={self.focus_distance_mm}, "
                f"main_focal_mm={self.main_focal_mm}")
        self._check_grid()
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

    def _check_grid(self):
        off = self.grid_offset_px
        try:
            off = (float(off[0]), float(off[1])) if len(off) == 2 else None
        except (TypeError, ValueError):
            off = None
        if off is None or not all(math.isfinite(v) for v in off):
            raise ValueError(f"camera grid_offset_px must be two finite numbers (rows, columns; pixels). "
                             f"Received: grid_offset_px={self.grid_offset_px!r}")
        object.__setattr__(self, "grid_offset_px", off)  # a JSON list becomes the tuple
        if self.grid_layout not in GRID_LAYOUTS:
            raise ValueError(f"camera grid_layout must be one of {GRID_LAYOUTS}. Received: {self.grid_layout!r}")
        rot = self.grid_rotation_deg
        if not isinstance(rot, (int, float)) or not math.isfinite(rot):
            raise ValueError(f"camera grid_rotation_deg must be a finite number (degrees). Received: {rot!r}")
        for name in ("sensor_rows", "sensor_cols"):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, int) or isinstance(v, bool) or v < 1):
                raise ValueError(f"camera {name} must be a positive integer. Received: {name}={v!r}")
        p = self.grid_pitch_px
        if p is None:
            given = [n for n, v, d in (("grid_rotation_deg", rot, 0.0), ("grid_offset_px", off, (0.0, 0.0)),
                                       ("grid_layout", self.grid_layout, "square"),
                                       ("sensor_rows", self.sensor_rows, None),
                                       ("sensor_cols", self.sensor_cols, None)) if v != d]
            if given:
                raise ValueError(f"camera {', '.join(given)} describe a non-perfect lenslet grid: give its "
                                 "grid_pitch_px (pixels between lenslet images) too")
            return
        if not isinstance(p, (int, float)) or not math.isfinite(p) or p < 2:
            raise ValueError(f"camera grid_pitch_px must be a finite number >= 2 (pixels). Received: {p!r}")
        if self.pixels_per_lenslet > views_for_pitch(p):
            raise ValueError(f"camera pixels_per_lenslet={self.pixels_per_lenslet} views do not fit under a "
                             f"lenslet image of grid_pitch_px={p} pixels")
        limit = MAX_GRID_ROTATION_DEG[self.grid_layout]
        if abs(rot) >= limit:
            raise ValueError(f"camera grid_rotation_deg must be below {limit}° in magnitude for a "
                             f"{self.grid_layout} grid (the lattice repeats). Received: {rot}")
        c = self.lenslet_image_centres_px()
        H, W = self.sensor_shape
        if c[..., 0].min() < 0 or c[..., 1].min() < 0 or c[..., 0].max() > H or c[..., 1].max() > W:
            raise ValueError(f"lenslet grid ({self.n_rows} x {self.n_cols}, pitch {p} px, rotation {rot}°, "
                             f"offset {off} px) does not fit on the {H} x {W}-pixel sensor: lenslet image "
                             f"centres span rows {c[..., 0].min():.1f}..{c[..., 0].max():.1f}, "
                             f"columns {c[..., 1].min():.1f}..{c[..., 1].max():.1f}")

    # ---- lenslet grid (pixels) --------------------------------------------------
    @property
    def perfect_grid(self) -> bool:
        """True for the default grid: ``N`` whole pixels per lenslet, no rotation, no offset."""
        return self.grid_pitch_px is None

    @property
    def grid_pitch(self) -> float:
        """Spacing of the lenslet images on the sensor (pixels): :attr:`grid_pitch_px` or ``N``."""
        return float(self.pixels_per_lenslet if self.grid_pitch_px is None else self.grid_pitch_px)

    def lattice_offsets(self) -> "np.ndarray":
        """Unrotated lattice positions (rows, columns) of the lenslets about the grid centre.

        In pitches: square ``(r - (R-1)/2, c - (C-1)/2)``; hexagonal rows ``sqrt(3)/2``
        apart, odd rows shifted by ``+1/2`` and every row by ``-1/4`` (so that the
        lattice stays centred). Returns an array of shape (R, C, 2), float64.
        """
        import numpy as np
        r = np.arange(self.n_rows, dtype=np.float64)[:, None] * np.ones(self.n_cols)
        c = np.arange(self.n_cols, dtype=np.float64)[None, :] * np.ones((self.n_rows, 1))
        if self.grid_layout == "hex":
            odd = (np.arange(self.n_rows) % 2)[:, None]
            shift = -0.25 if self.n_rows > 1 else 0.0
            return np.stack([(r - (self.n_rows - 1) / 2) * math.sqrt(3) / 2,
                             c - (self.n_cols - 1) / 2 + 0.5 * odd + shift], axis=-1)
        return np.stack([r - (self.n_rows - 1) / 2, c - (self.n_cols - 1) / 2], axis=-1)

    @property
    def grid_matrix(self) -> "np.ndarray":
        """2 × 2 matrix (pixels per pitch) taking lattice offsets (rows, columns) to sensor
        offsets (rows, columns): the rotation by :attr:`grid_rotation_deg` times the pitch."""
        import numpy as np
        t = math.radians(self.grid_rotation_deg)
        return self.grid_pitch * np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])

    @property
    def grid_centre_px(self) -> tuple[float, float]:
        """Centre (row, column) of the lenslet grid on the sensor (pixels)."""
        H, W = self.sensor_shape
        return H / 2 + self.grid_offset_px[0], W / 2 + self.grid_offset_px[1]

    def lenslet_image_centres_px(self) -> "np.ndarray":
        """Centre (row, column) of every lenslet's image on the sensor (pixels).

        Where the chief ray through the main-lens centre and the lenslet centre meets
        the sensor (:attr:`lenslet_image_pitch_mm`). Perfect grid: ``((r + 1/2) N,
        (c + 1/2) N)``. Returns an array of shape (R, C, 2), float64.
        """
        import numpy as np
        return np.asarray(self.grid_centre_px) + self.lattice_offsets() @ self.grid_matrix.T

    def nearest_lenslet(self, points_px) -> tuple["np.ndarray", "np.ndarray"]:
        """The lenslet whose image centre is nearest to each point (its Voronoi cell).

        Parameters
        ----------
        points_px : array_like of shape (M, 2)
            Points (row, column) in sensor pixel coordinates.

        Returns
        -------
        rows, cols : ndarray of shape (M,), int64
            Lenslet indices; -1 for both where the nearest lattice site is outside the grid.
        """
        import numpy as np
        p = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        q = (p - self.grid_centre_px) @ np.linalg.inv(self.grid_matrix).T     # lattice offsets (pitches)
        if self.grid_layout == "square":
            r = np.rint(q[:, 0] + (self.n_rows - 1) / 2)
            c = np.rint(q[:, 1] + (self.n_cols - 1) / 2)
        else:  # hexagonal: the nearest of the sites in the two nearest lattice rows
            h = math.sqrt(3) / 2
            shift = -0.25 if self.n_rows > 1 else 0.0
            rf = q[:, 0] / h + (self.n_rows - 1) / 2
            best = np.full(len(p), np.inf)
            r = np.zeros(len(p))
            c = np.zeros(len(p))
            for cand in (np.floor(rf), np.floor(rf) + 1):
                odd = np.mod(cand, 2)
                cc = np.rint(q[:, 1] + (self.n_cols - 1) / 2 - 0.5 * odd - shift)
                d2 = ((cand - (self.n_rows - 1) / 2) * h - q[:, 0]) ** 2 + \
                    (cc - (self.n_cols - 1) / 2 + 0.5 * odd + shift - q[:, 1]) ** 2
                better = d2 < best
                best = np.where(better, d2, best)
                r = np.where(better, cand, r)
                c = np.where(better, cc, c)
        r, c = r.astype(np.int64), c.astype(np.int64)
        out = (r < 0) | (r >= self.n_rows) | (c < 0) | (c >= self.n_cols)
        r[out] = -1
        c[out] = -1
        return r, c

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
        """Sensor pixel pitch (mm): lenslet image pitch / N (7.477 µm for the paper's camera),
        / :attr:`grid_pitch_px` for a non-perfect grid."""
        if self.grid_pitch_px is not None:
            return self.lenslet_image_pitch_mm / self.grid_pitch_px
        return self.lenslet_image_pitch_mm / self.pixels_per_lenslet

    @property
    def sensor_shape(self) -> tuple[int, int]:
        """Raw image shape ``(n_rows * N, n_cols * N)`` in pixels; for a non-perfect grid
        ``(sensor_rows, sensor_cols)``, by default the bounding box of the rotated grid's
        lenslet image centres plus one pitch, rounded up."""
        n = self.pixels_per_lenslet
        if self.grid_pitch_px is None:
            return self.n_rows * n, self.n_cols * n
        if self.sensor_rows is not None and self.sensor_cols is not None:
            return self.sensor_rows, self.sensor_cols
        import numpy as np
        ext = np.abs(self.lattice_offsets() @ self.grid_matrix.T).max(axis=(0, 1)) * 2 + self.grid_pitch
        rows = self.sensor_rows if self.sensor_rows is not None else int(math.ceil(ext[0] - 1e-9))
        cols = self.sensor_cols if self.sensor_cols is not None else int(math.ceil(ext[1] - 1e-9))
        return rows, cols

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
                f"object at {z:.6g} mm is at or inside the main-lens focal length {self.main_focal_mm:g} mm: "
                "its image is at infinity or virtual")
        return 1.0 / (1.0 / self.main_focal_mm - 1.0 / z)

    def object_distance_mm(self, depth_offset_mm: float) -> float:
        """Object distance ``z_f + dz`` (mm); ``dz > 0`` is farther from the camera.

        Raises
        ------
        ValueError
            A depth that is not finite, or one at or behind the main lens (``z_f + dz <= 0``).
        """
        dz = float(depth_offset_mm)
        if not math.isfinite(dz):
            raise ValueError(f"a depth must be a finite number of mm from the focus distance. Received: {dz!r}")
        if self.focus_distance_mm + dz <= 0:
            raise ValueError(f"a plane at {dz:+g} mm from the focus distance ({self.focus_distance_mm:g} mm) lies "
                             "at or behind the main lens")
        return self.focus_distance_mm + dz

    # ---- slope <-> depth (the paper's sign convention) -------------------------
    def slope_for_depth(self, depth_offset_mm: float) -> float:
        """Refocus slope (lenslets of shift per view step) of the plane at ``dz`` mm.

        ``s = -d (1 - d / z_i) / (g N)`` with ``z_i`` the image distance of the plane
        (SPEC.md). A point of that plane appears at lenslet ``x0 + s (u - (N-1)/2)``
        in sub-aperture view ``u``. Sign: the paper's (near planes negative):
        −1.249, 0, +1.175, +2.281 for dz = −10, 0, +10, +20 mm on the paper's camera.
        """
        d = self.mla_distance_mm
        zi = self.image_distance_mm(self.object_distance_mm(depth_offset_mm))
        return -d * (1.0 - d / zi) / (self.sensor_distance_mm * self._view_steps)

    @property
    def _view_steps(self):
        """Pixels per lenslet image pitch: ``N`` (an int, as always) or :attr:`grid_pitch_px`.
        A view step is one pixel, so slopes scale with it."""
        return self.pixels_per_lenslet if self.grid_pitch_px is None else self.grid_pitch_px

    def depth_for_slope(self, slope: float) -> float:
        """Inverse of :meth:`slope_for_depth`: depth offset (mm) of the plane in focus at ``slope``.

        Raises
        ------
        ValueError
            If no real object plane is in focus at that slope (image at or before the lens).
        """
        d = self.mla_distance_mm
        denom = 1.0 + float(slope) * self.sensor_distance_mm * self._view_steps / d
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
        """Object-space field (height, width) in mm seen by the lenslet grid at ``dz``: its rows and columns of
        lenslets times their spacing, a pitch (a hexagonal lattice's rows ``sqrt(3)/2`` pitches apart, where the
        height was once taken a pitch per row and scenes drawn to it stood past the sensor's edge)."""
        s = self.object_distance_mm(depth_offset_mm) / self.mla_distance_mm
        row = math.sqrt(3) / 2 if self.grid_layout == "hex" else 1.0
        return self.n_rows * row * self.mla_pitch_mm * s, self.n_cols * self.mla_pitch_mm * s

    # ---- serialisation --------------------------------------------------------------
    def to_dict(self) -> dict:
        """The fields as a dict; the grid fields only where they differ from the perfect
        grid's defaults, so that a perfect-grid camera serialises as it always has."""
        d = dataclasses.asdict(self)
        for f in dataclasses.fields(self):
            if f.name.startswith(("grid_", "sensor_r", "sensor_c")) and d[f.name] == f.default:
                del d[f.name]
        if "grid_offset_px" in d:
            d["grid_offset_px"] = list(d["grid_offset_px"])
        return d

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
