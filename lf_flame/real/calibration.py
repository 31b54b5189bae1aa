"""Real cameras, stage 1: lenslet-grid calibration from a white image (:func:`calibrate`,
:class:`GridCalibration`); stage 2, decoding raw images into views, is :mod:`lf_flame.real.decoding`.

A real plenoptic 1.0 camera's lenslet grid is rotated a little against the sensor,
offset, and its lenslet images are a non-integer number of pixels apart. A white
(flat-field) image shows each lenslet's image of the main-lens aperture as a bright
spot; :func:`calibrate` finds them and fits the lattice:

1. dark-frame subtraction, and checks that the image is a usable white image;
2. the lattice's two shortest vectors from the peaks of the image's autocorrelation
   (SciPy FFT, :func:`skimage.feature.peak_local_max`), refined on their multiples;
3. one spot per lenslet (:func:`skimage.feature.peak_local_max` on the smoothed
   image) and its subpixel centre: the centroid under a Gaussian window re-centred
   until it stops moving (a symmetric spot is its fixed point);
4. integer lattice indices and the lattice (pitch, rotation, origin), a similarity
   transform fitted robustly with :func:`skimage.measure.ransac` to the spots that have
   all their neighbours (an edge spot's peak is pulled inwards), over a region grown
   from the image centre so that indices stay right however many lenslets there are.

:func:`lf_flame.real.decoding.decode` then turns raw images into sub-aperture views with the
calibration. The lattice's steps are :mod:`lf_flame.real.lattice`; reading and checking the
images, :mod:`lf_flame.real.images`.

Pixel coordinates are those of :mod:`lf_flame.optics.camera`: pixel ``(i, j)`` covers rows
``[i, i + 1)`` and columns ``[j, j + 1)``; the rotation is the camera's
``grid_rotation_deg`` (positive: lenslet rows turn from the column axis towards
increasing rows). References: Dansereau, Pizarro & Williams 2013 (LFToolbox:
lenslet-grid estimation from a white image, decoding to a 4-D light field); Cho et al.
2013 (rotation and centre estimation of lenslet images).
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..optics.camera import GRID_LAYOUTS, MAX_GRID_ROTATION_DEG
from .images import _dark_subtracted
from .lattice import (_H, CalibrationError, _decoded_grid, _fit, _indices, _interior, _lattice_rc,
                      lattice_from_autocorrelation, spot_centres)

#: ``format`` tag of a calibration file, and its version.
CALIBRATION_FORMAT = "lf_flame.grid_calibration"
CALIBRATION_VERSION = 1

# ---- the calibration -----------------------------------------------------------------
@dataclass(frozen=True)
class GridCalibration:
    """A calibrated lenslet grid.

    Attributes
    ----------
    sensor_shape : (int, int)
        Rows and columns of the white image (and of every raw image it decodes).
    layout : {'square', 'hex'}
        Lattice, as :attr:`lf_flame.optics.camera.PlenopticCamera.grid_layout`.
    pitch_px : float
        Distance between neighbouring lenslet image centres (pixels).
    rotation_deg : float
        Grid rotation (degrees), as ``grid_rotation_deg`` of the camera.
    origin_px : (float, float)
        Centre (row, column) of lenslet (0, 0) of the decoded grid (pixels).
    n_rows, n_cols : int
        Lenslets of the decoded grid: every lenslet whose whole image is on the sensor.
        Hexagonal: row 0 is an unshifted row, odd rows sit half a pitch to the right.
    lenslets : ndarray of shape (K, 4), float64
        The lenslets measured and kept by the robust fit: lattice row, lattice column
        (indices of the decoded grid, may lie outside it), measured centre row, column (px).
    residual_rms_px, residual_max_px : float
        Distance between measured and fitted centres of those lenslets (pixels).
    n_found : int
        Spots found before the robust fit (``len(lenslets)`` of them kept).
    camera_id : str
        Free text naming the camera (checked by :func:`lf_flame.real.decoding.decode` when given).
    white, dark : dict or None
        ``{"path", "sha256"}`` of the white image and dark frame the calibration came
        from (the CLI's ``decode`` reloads them for normalisation), or None.
    """

    sensor_shape: tuple[int, int]
    layout: str
    pitch_px: float
    rotation_deg: float
    origin_px: tuple[float, float]
    n_rows: int
    n_cols: int
    lenslets: np.ndarray
    residual_rms_px: float
    residual_max_px: float
    n_found: int
    camera_id: str = ""
    white: dict | None = None
    dark: dict | None = None

    @property
    def matrix(self) -> np.ndarray:
        """2 × 2: lattice offsets (rows, columns; pitches) -> sensor offsets (rows, columns; px),
        as :attr:`lf_flame.optics.camera.PlenopticCamera.grid_matrix`."""
        t = math.radians(self.rotation_deg)
        return self.pitch_px * np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])

    def centres_px(self) -> np.ndarray:
        """Calibrated centre (row, column; px) of every lenslet image of the decoded grid,
        from the fitted lattice. Shape (n_rows, n_cols, 2)."""
        r, c = np.meshgrid(np.arange(self.n_rows), np.arange(self.n_cols), indexing="ij")
        return np.asarray(self.origin_px) + _lattice_rc(r, c, self.layout) @ self.matrix.T

    @property
    def offset_px(self) -> tuple[float, float]:
        """Mean lenslet centre of the decoded grid minus the centre of the sensor (rows,
        columns; px): ``grid_offset_px`` of a camera with exactly the decoded grid."""
        mid = self.centres_px().reshape(-1, 2).mean(axis=0)
        return float(mid[0] - self.sensor_shape[0] / 2), float(mid[1] - self.sensor_shape[1] / 2)

    # ---- files ---------------------------------------------------------------------------
    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["lenslets"] = np.round(self.lenslets, 4).tolist()
        d["sensor_shape"] = list(self.sensor_shape)
        d["origin_px"] = list(self.origin_px)
        d["offset_px"] = list(self.offset_px)
        return {"format": CALIBRATION_FORMAT, "version": CALIBRATION_VERSION, **d}

    def save(self, path) -> Path:
        """Write the calibration as JSON (atomically: a temporary file, then renamed)."""
        from ..config import atomic_write_text
        atomic_write_text(path, json.dumps(self.to_dict(), indent=1))
        return Path(path)

    @classmethod
    def from_dict(cls, d: dict) -> "GridCalibration":
        """Build from :meth:`to_dict`'s output; a wrong format, version or field raises ValueError."""
        if not isinstance(d, dict) or d.get("format") != CALIBRATION_FORMAT:
            raise ValueError(f"not an lf_flame lenslet-grid calibration (format {CALIBRATION_FORMAT!r} expected)")
        if d.get("version") != CALIBRATION_VERSION:
            raise ValueError(f"calibration version {d.get('version')!r} is not {CALIBRATION_VERSION}")
        names = {f.name for f in dataclasses.fields(cls)}
        missing = names - set(d) - {"camera_id", "white", "dark"}
        if missing:
            raise ValueError(f"calibration file lacks {sorted(missing)}")
        kw = {k: d[k] for k in names if k in d}
        try:
            kw["sensor_shape"] = tuple(int(v) for v in kw["sensor_shape"])
            kw["origin_px"] = tuple(float(v) for v in kw["origin_px"])
            kw["lenslets"] = np.asarray(kw["lenslets"], np.float64).reshape(-1, 4)
            for k in ("pitch_px", "rotation_deg", "residual_rms_px", "residual_max_px"):
                kw[k] = float(kw[k])
            for k in ("n_rows", "n_cols", "n_found"):
                kw[k] = int(kw[k])
        except (TypeError, ValueError) as e:
            raise ValueError(f"calibration file has a malformed field: {e}") from None
        cal = cls(**kw)
        cal.validate()
        return cal

    @classmethod
    def load(cls, path) -> "GridCalibration":
        """Read a calibration JSON file; ValueError if it is not one."""
        p = Path(path)
        if not p.is_file():
            raise FileNotFoundError(f"calibration file not found: {p}")
        try:
            d = json.loads(p.read_text())
        except (json.JSONDecodeError, UnicodeDecodeError) as e:
            raise ValueError(f"calibration file {p} is not valid JSON: {e}") from None
        return cls.from_dict(d)

    def validate(self) -> None:
        """Raise ValueError if the fields describe no possible grid."""
        vals = [self.pitch_px, self.rotation_deg, *self.origin_px]
        if not all(math.isfinite(v) for v in vals) or self.pitch_px < 2:
            raise ValueError(f"calibration has a non-finite value or a pitch below 2 px: pitch_px={self.pitch_px}, "
                             f"rotation_deg={self.rotation_deg}, origin_px={self.origin_px}")
        if self.layout not in GRID_LAYOUTS:
            raise ValueError(f"calibration layout must be one of {GRID_LAYOUTS}. Received: {self.layout!r}")
        if abs(self.rotation_deg) >= MAX_GRID_ROTATION_DEG[self.layout]:
            raise ValueError(f"calibration rotation {self.rotation_deg}° is past {MAX_GRID_ROTATION_DEG[self.layout]}°")
        if min(self.sensor_shape) < 1 or self.n_rows < 1 or self.n_cols < 1:
            raise ValueError(f"calibration has an empty sensor or grid: sensor {self.sensor_shape}, "
                             f"grid {self.n_rows} x {self.n_cols}")
        c = self.centres_px()
        if c.min() < 0 or c[..., 0].max() > self.sensor_shape[0] or c[..., 1].max() > self.sensor_shape[1]:
            raise ValueError("calibration's lenslet centres lie off its sensor")


def calibrate(white: np.ndarray, dark: np.ndarray | None = None, *, layout: str = "auto",
              residual_threshold_px: float | None = None, seed: int = 0, camera_id: str = "",
              mosaic: bool = False) -> GridCalibration:
    """Calibrate the lenslet grid from a white image.

    Parameters
    ----------
    white : ndarray of shape (rows, cols)
        White (flat-field) raw image: a uniform, diffuse target through the camera.
    dark : ndarray of shape (rows, cols) or None
        Dark frame, subtracted first.
    layout : {'auto', 'square', 'hex'}
        Lattice; ``auto`` detects it from the angle between the lattice vectors.
    residual_threshold_px : float or None
        RANSAC inlier distance (px); default ``max(0.5, pitch / 20)``.
    seed : int
        Seeds RANSAC's sampling.
    camera_id : str
        Stored in the calibration; :func:`lf_flame.real.decoding.decode` refuses a raw image of another
        camera id.
    mosaic : bool
        The white image is a colour sensor's raw mosaic (a 2 x 2 colour filter array): each of
        its four pixel phases ``[a::2, b::2]`` is divided by its own mean first, so that the
        channels' gains do not read as a lattice of two-pixel period (which a hexagonal grid's
        lattice search takes for the lenslets'). No pixel moves: the centres stay where they are.

    Returns
    -------
    GridCalibration
        Pitch (px), rotation (degrees), origin and size of the decoded grid, every kept
        lenslet's measured centre, and the fit residual (px).

    Raises
    ------
    ValueError
        Not a 2-D real image, NaN or inf, a dark frame of another shape, an unknown layout.
    CalibrationError (a ValueError)
        Not a white image (constant, mostly saturated, or too few lenslets lit), or no
        lenslet grid found (no periodic structure, no consistent lattice).
    """
    if layout not in ("auto",) + GRID_LAYOUTS:
        raise ValueError(f"layout must be 'auto' or one of {GRID_LAYOUTS}. Received: {layout!r}")
    img = _dark_subtracted("white image", white, dark)
    H, W = img.shape
    if mosaic:
        img = img.copy()
        for a in (0, 1):
            for b in (0, 1):
                level = float(img[a::2, b::2].mean())
                if level > 0:
                    img[a::2, b::2] /= level
    top = np.percentile(img, 99.5)
    if not top > 0 or np.ptp(img) <= 1e-9 * abs(top):      # relative: a white image's level is any scale
        raise CalibrationError("not a white image: it is constant (after dark subtraction)")
    if np.mean(img >= img.max()) > 0.25 and np.ptp(img) > 0:
        raise CalibrationError(f"not a white image: {100 * np.mean(img >= img.max()):.0f} % of its pixels sit at "
                               "the maximum (over-exposed; the lenslet images are clipped)")
    img = np.clip(img / top, 0, None)
    basis, found = lattice_from_autocorrelation(img, layout)
    pitch0 = float(np.mean(np.linalg.norm(basis, axis=1)))
    if pitch0 < 2 or pitch0 > min(H, W) / 3:
        raise CalibrationError(f"no lenslet grid found: lattice period {pitch0:.1f} px is not that of a lenslet grid "
                               f"on a {H} x {W} image")
    pts = spot_centres(img, pitch0)
    cell = pitch0 ** 2 * (_H if found == "hex" else 1.0)
    expected = (H - pitch0) * (W - pitch0) / cell
    if len(pts) < max(9, 0.5 * expected):
        raise CalibrationError(f"not a white image: only {len(pts)} lenslet images lit of about {expected:.0f} "
                               "expected (a scene or a dark image, or the grid is not in focus)")
    # grow the fitted region from the spot nearest the centre, so that indices stay right
    thr = residual_threshold_px if residual_threshold_px is not None else max(0.5, pitch0 / 20)
    rng = np.random.default_rng(seed)
    seed_pt = pts[np.argmin(np.hypot(pts[:, 0] - H / 2, pts[:, 1] - W / 2))]
    origin = seed_pt.copy()
    dist = np.hypot(*(pts - seed_pt).T)
    radius = 4 * pitch0
    while True:
        near = dist <= radius
        r, c = _indices(basis, origin, pts[near], found)
        inner = _interior(r, c, found)
        if inner.sum() < 3:
            raise CalibrationError("no lenslet grid found: too few lenslet images with all their neighbours")
        model, inl = _fit(r[inner], c[inner], pts[near][inner], found, thr, rng)
        P = float(model.scale)
        t = float(model.rotation)
        # the model maps lattice (x, y) to sensor (x, y): origin and the basis in (row, col)
        ox, oy = model.params[0, 2], model.params[1, 2]
        origin = np.array([oy, ox])
        M = P * np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
        basis = np.array([M @ [0, 1], M @ ([_H, 0.5] if found == "hex" else [1, 0])])
        if near.all():
            break
        radius *= 2
    meas, r, c = pts[near][inner][inl], r[inner][inl], c[inner][inl]
    r0, c0, n_rows, n_cols = _decoded_grid(found, M, origin, r, c, H, W)
    origin = origin + _lattice_rc(r0, c0, found) @ M.T
    lr, lc = r - r0, c - c0
    res = np.hypot(*(meas - (origin + _lattice_rc(lr, lc, found) @ M.T)).T)
    return GridCalibration(sensor_shape=(H, W), layout=found, pitch_px=P, rotation_deg=math.degrees(t),
                           origin_px=(float(origin[0]), float(origin[1])), n_rows=n_rows, n_cols=n_cols,
                           lenslets=np.column_stack([lr, lc, meas]),
                           residual_rms_px=float(np.sqrt(np.mean(res ** 2))), residual_max_px=float(res.max()),
                           n_found=len(pts), camera_id=str(camera_id))
