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
calibration; this module also reads the images (:func:`load_image`) and checks them.

Pixel coordinates are those of :mod:`lf_flame.optics.camera`: pixel ``(i, j)`` covers rows
``[i, i + 1)`` and columns ``[j, j + 1)``; the rotation is the camera's
``grid_rotation_deg`` (positive: lenslet rows turn from the column axis towards
increasing rows). References: Dansereau, Pizarro & Williams 2013 (LFToolbox:
lenslet-grid estimation from a white image, decoding to a 4-D light field); Cho et al.
2013 (rotation and centre estimation of lenslet images).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.fft
from scipy import ndimage
from skimage import feature, measure, transform

from ..optics.camera import GRID_LAYOUTS, MAX_GRID_ROTATION_DEG

#: ``format`` tag of a calibration file, and its version.
CALIBRATION_FORMAT = "lf_flame.grid_calibration"
CALIBRATION_VERSION = 1

_H = math.sqrt(3) / 2


class CalibrationError(ValueError):
    """The white image cannot be calibrated (not a white image, no lenslet grid found)."""


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


# ---- input checks ----------------------------------------------------------------------
def load_image(path) -> np.ndarray:
    """Read a white, dark or raw image: .npy, .npz (key ``raw``, else its only array), or any
    image file scikit-image reads (PNG, TIFF; 8 or 16 bit). Colour is averaged to gray.

    Returns
    -------
    image : ndarray of shape (rows, cols), float64 (the file's values, unscaled)
    """
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"image file not found: {p}")
    from ..config import reading
    if p.suffix == ".npy":
        with reading(p, ".npy file"):
            a = np.load(p)
    elif p.suffix == ".npz":
        with reading(p, ".npz file"), np.load(p) as z:
            keys = list(z.keys())
            if "raw" in keys:
                a = z["raw"]
            elif len(keys) == 1:
                a = z[keys[0]]
            else:
                raise ValueError(f"{p}: .npz with keys {keys}; expected 'raw' or a single array")
    else:
        from skimage import io
        try:
            a = io.imread(p)
        except Exception as e:  # the readers raise many kinds
            raise ValueError(f"{p} is not a readable image: {e}") from None
    a = np.asarray(a)
    if a.ndim == 3 and a.shape[-1] in (3, 4):
        a = a[..., :3].mean(axis=-1)
    return a.astype(np.float64)


def file_digest(path) -> dict:
    """``{"path": absolute path, "sha256": hex digest}`` of a file."""
    p = Path(path).resolve()
    return {"path": str(p), "sha256": hashlib.sha256(p.read_bytes()).hexdigest()}


def _image(name, a, shape=None) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 2 or min(a.shape) < 1:
        raise ValueError(f"{name} must be a 2-D image (rows, columns). Received shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise ValueError(f"{name} must be real-valued. Received dtype {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf ({int(np.sum(~np.isfinite(a)))} pixels)")
    if shape is not None and a.shape != tuple(shape):
        raise ValueError(f"{name} has shape {a.shape}, not the {tuple(shape)} of the calibration's sensor")
    return a


def _dark_subtracted(name, image, dark):
    img = _image(name, image)
    if dark is not None:
        img = img - _image("dark frame", dark, img.shape)
    return img


# ---- the lattice from the autocorrelation -------------------------------------------------
def _autocorrelation(img: np.ndarray, size: int = 1024) -> np.ndarray:
    """Normalised autocorrelation (zero lag = 1, at the centre) of a central crop of at
    most ``size`` × ``size`` pixels, high-passed (minus a Gaussian blur of σ = 1/20 of
    the image's smaller side: the shading across the field, not the lenslet grid) and
    Hann-windowed against the crop's edges; zero-padded, so not circular."""
    H, W = img.shape
    h, w = min(H, size), min(W, size)
    crop = img[(H - h) // 2:(H - h) // 2 + h, (W - w) // 2:(W - w) // 2 + w]
    crop = crop - ndimage.gaussian_filter(crop, max(4.0, min(H, W) / 20), mode="nearest")
    crop = (crop - crop.mean()) * np.outer(np.hanning(h), np.hanning(w))
    f = scipy.fft.rfft2(crop, s=(2 * h, 2 * w))          # zero-padded: no wrap-around
    ac = scipy.fft.irfft2(np.abs(f) ** 2, s=(2 * h, 2 * w))
    ac = np.fft.fftshift(ac)
    if ac.max() <= 0:
        raise CalibrationError("no lenslet grid found: the white image is constant")
    return ac / ac[h, w]


def _refine_peak(ac, p):
    """Subpixel maximum of ``ac`` near integer ``p`` (row, column): a parabola per axis."""
    r, c = int(p[0]), int(p[1])
    if not (1 <= r < ac.shape[0] - 1 and 1 <= c < ac.shape[1] - 1):
        return np.array([r, c], np.float64)
    out = []
    for a, b, m in ((ac[r - 1, c], ac[r + 1, c], ac[r, c]), (ac[r, c - 1], ac[r, c + 1], ac[r, c])):
        den = a - 2 * m + b
        off = 0.5 * (a - b) / den if den < 0 else 0.0
        out.append(off if abs(off) <= 0.5 else 0.0)     # not a maximum there: keep the integer peak
    return np.array([r + out[0], c + out[1]])


def lattice_from_autocorrelation(img: np.ndarray, layout: str = "auto") -> tuple[np.ndarray, str]:
    """The lattice's two basis vectors from the autocorrelation of a white image.

    The autocorrelation of a periodic image peaks on its lattice. The shortest lag with a
    strong peak is one lattice vector; the shortest one not parallel to it is the other
    (at about 90°: square lattice, about 60°: hexagonal). Each is refined on its largest
    multiple inside a quarter of the crop (a subpixel parabola there, divided by the
    multiple). Returned as ``a_col``, the one nearest the column axis, and ``a_row`` (square:
    at +90°, towards increasing rows; hexagonal: at +60°, so that going one lattice row
    down moves half a pitch right).

    Returns
    -------
    basis : ndarray of shape (2, 2)
        ``basis[0] = a_col``, ``basis[1] = a_row``, each (rows, columns) in pixels.
    layout : {'square', 'hex'}

    Raises
    ------
    CalibrationError
        No periodic structure, or lattice vectors at neither 90° nor 60°.
    """
    ac = _autocorrelation(img)
    centre = np.array(ac.shape) // 2
    peaks = feature.peak_local_max(ac, min_distance=2, threshold_abs=0.1, exclude_border=2)
    lag = peaks - centre
    dist = np.hypot(lag[:, 0], lag[:, 1])
    keep = dist >= 3
    peaks, lag, dist = peaks[keep], lag[keep], dist[keep]
    if len(peaks) < 4:
        raise CalibrationError("no lenslet grid found: the white image's autocorrelation has no periodic peaks")
    strength = ac[peaks[:, 0], peaks[:, 1]]
    strong = strength >= 0.3 * strength.max()
    lag, dist = lag[strong], dist[strong]
    order = np.argsort(dist)
    lag, dist = lag[order].astype(np.float64), dist[order]
    a1 = lag[0]
    ang = np.degrees(np.arccos(np.clip(np.abs(lag @ a1) / (dist * dist[0]), 0, 1)))
    others = np.flatnonzero(ang > 30)
    if others.size == 0:
        raise CalibrationError("no lenslet grid found: the autocorrelation's peaks lie on one line")
    a2 = lag[others[0]]
    if dist[others[0]] > 1.3 * dist[0]:
        raise CalibrationError(f"no lenslet grid found: lattice vectors of {dist[0]:.1f} and "
                               f"{dist[others[0]]:.1f} px are not of one pitch")
    angle = float(np.degrees(np.arccos(abs(a1 @ a2) / (np.linalg.norm(a1) * np.linalg.norm(a2)))))
    found = "square" if abs(angle - 90) < 10 else "hex" if abs(angle - 60) < 10 else None
    if found is None:
        raise CalibrationError(f"no lenslet grid found: lattice vectors {angle:.1f}° apart, neither a square (90°) "
                               "nor a hexagonal (60°) grid")
    if layout != "auto" and layout != found:
        raise CalibrationError(f"the white image shows a {found} lenslet grid, not the {layout} one asked for")
    # refine each vector on its largest multiple that stays well inside the crop
    span = 0.25 * min(ac.shape) / 2
    basis = []
    for a in (a1, a2):
        k = max(1, int(span // np.linalg.norm(a)))
        p = _refine_peak(ac, np.rint(centre + k * a))
        for _ in range(2):  # climb to the local maximum, then refine
            r, c = int(round(p[0])), int(round(p[1]))
            win = ac[r - 2:r + 3, c - 2:c + 3]
            dr, dc = np.unravel_index(np.argmax(win), win.shape)
            p = _refine_peak(ac, (r - 2 + dr, c - 2 + dc))
        basis.append((p - centre) / k)
    cands = [b * s for b in basis for s in (1, -1)]
    if found == "hex":
        cands += [s * (basis[0] - basis[1]) for s in (1, -1)] + [s * (basis[0] + basis[1]) for s in (1, -1)]
        cands = [v for v in cands if np.linalg.norm(v) < 1.2 * np.linalg.norm(basis[0])]
    # a_col: the vector nearest the +column direction; a_row: +90° (square) or +60° (hex) from it
    a_col = min(cands, key=lambda v: abs(math.atan2(v[0], v[1])))
    want = 90.0 if found == "square" else 60.0
    a_row = min(cands, key=lambda v: abs(math.degrees(math.atan2(v[0], v[1]) - math.atan2(a_col[0], a_col[1]))
                                         - want))
    return np.array([a_col, a_row]), found


# ---- spots and their centres ---------------------------------------------------------------
def spot_centres(img: np.ndarray, pitch: float, threshold: float = 0.3) -> np.ndarray:
    """Subpixel centres of the lenslet images (spots) of a white image.

    First the spots' shading is flattened: the image is divided by half its local maximum
    (a maximum filter over 1.5 pitches, at least ``threshold`` × its 99th percentile) and clipped at 1, so
    that each spot becomes its shape, its edge at half its brightness, with no
    cos⁴ or vignetting gradient across it (an intensity centroid moves with such a
    gradient: towards the optical axis, a bias on the pitch). Then it is smoothed by a
    Gaussian (σ = pitch / 4), which turns each spot into a smooth peak centred where the
    spot is (a symmetric spot under a symmetric kernel);
    one spot per local maximum (:func:`skimage.feature.peak_local_max`, at least 0.3
    pitch apart, above ``threshold`` × the 99th percentile, at least half a pitch from
    the border); its centre is the vertex of a quadratic fitted by least squares to the
    logarithm of the smoothed image on the 5 × 5 pixels about the maximum (exact for a
    Gaussian peak).

    Returns
    -------
    centres : ndarray of shape (K, 2), float64
        (row, column) in pixel coordinates (pixel ``(i, j)`` is centred at ``(i + ½, j + ½)``).
    """
    level = ndimage.maximum_filter(img, size=max(3, int(1.5 * pitch)))
    level = np.maximum(level, threshold * np.percentile(level, 99))   # unlit regions stay dark
    shape = np.clip(img / (0.5 * level), 0, 1)
    smooth = ndimage.gaussian_filter(shape, pitch / 4)
    level = 0.3 * np.percentile(smooth, 99)
    pk = feature.peak_local_max(smooth, min_distance=max(1, int(0.3 * pitch)), threshold_abs=level,
                                exclude_border=max(2, int(math.ceil(pitch / 2))))
    if len(pk) == 0:
        return np.zeros((0, 2))
    off = np.arange(-2, 3)
    dr, dc = np.meshgrid(off, off, indexing="ij")
    A = np.column_stack([np.ones(25), dr.ravel(), dc.ravel(), dr.ravel() ** 2, dr.ravel() * dc.ravel(),
                         dc.ravel() ** 2])
    patch = smooth[pk[:, 0, None] + dr.ravel(), pk[:, 1, None] + dc.ravel()]            # (K, 25)
    coef = np.linalg.lstsq(A, np.log(np.maximum(patch, 1e-12 * level)).T, rcond=None)[0]   # (6, K)
    _, b1, b2, a11, a12, a22 = coef
    det = 4 * a11 * a22 - a12 ** 2
    ok = (det > 0) & (a11 < 0)                       # a maximum
    sr = np.where(ok, (-2 * a22 * b1 + a12 * b2) / np.where(ok, det, 1), 0.0)
    sc = np.where(ok, (-2 * a11 * b2 + a12 * b1) / np.where(ok, det, 1), 0.0)
    ok &= (np.abs(sr) <= 1) & (np.abs(sc) <= 1)
    return np.column_stack([pk[ok, 0] + 0.5 + sr[ok], pk[ok, 1] + 0.5 + sc[ok]])


# ---- the robust lattice fit -------------------------------------------------------------------
def _indices(cal_basis, origin, pts, layout):
    """Nearest lattice indices (row, column) of points under basis (a_col, a_row) and origin."""
    B = np.column_stack([cal_basis[1], cal_basis[0]])      # (row, col) <- (lattice row, lattice col) in "skew" coords
    q = np.linalg.solve(B, (pts - origin).T).T              # q[:, 0] rows, q[:, 1] skew columns
    r = np.rint(q[:, 0])
    if layout == "hex":   # a_row moves half a pitch right: column = skew column + row / 2, rounded down for odd rows
        c = np.rint(q[:, 1] + r / 2 - 0.5 * np.mod(r, 2))
    else:
        c = np.rint(q[:, 1])
    return r, c


def _lattice_xy(r, c, layout):
    """Lattice offsets as (x, y) = (columns, rows) in pitches, for scikit-image's transforms."""
    if layout == "hex":
        return np.column_stack([c + 0.5 * np.mod(r, 2), r * _H])
    return np.column_stack([c, r])


def _fit(r, c, pts, layout, threshold, rng):
    """RANSAC similarity transform lattice (x, y) -> measured (x, y); inlier mask."""
    src = _lattice_xy(r, c, layout)
    dst = pts[:, ::-1]
    model, inl = measure.ransac((src, dst), transform.SimilarityTransform, min_samples=3,
                                residual_threshold=threshold, max_trials=200, rng=rng)
    if model is None or inl is None or inl.sum() < 3:
        raise CalibrationError("no lenslet grid found: no consistent lattice through the spots")
    model = transform.SimilarityTransform.from_estimate(src[inl], dst[inl])   # least squares on the inliers
    if not model:
        raise CalibrationError("no lenslet grid found: the lattice fit is degenerate")
    return model, inl


def calibrate(white: np.ndarray, dark: np.ndarray | None = None, *, layout: str = "auto",
              residual_threshold_px: float | None = None, seed: int = 0, camera_id: str = "") -> GridCalibration:
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
    top = np.percentile(img, 99.5)
    if not top > 0 or np.ptp(img) <= 1e-9 * max(1.0, abs(top)):
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


def _interior(r, c, layout) -> np.ndarray:
    """Mask of the lenslets whose nearest neighbours (4 square, 6 hexagonal) were all found.

    A spot on the edge of the lit area has a bright neighbour on one side only, which
    pulls its smoothed peak inwards (by up to a pixel when spots touch): the fit uses
    interior spots only."""
    have = set(zip(r.astype(int).tolist(), c.astype(int).tolist()))
    out = np.ones(len(r), bool)
    for k, (a, b) in enumerate(zip(r.astype(int).tolist(), c.astype(int).tolist())):
        if layout == "hex":   # odd rows sit half a pitch right
            d = 0 if a % 2 else -1
            nb = [(a, b - 1), (a, b + 1), (a - 1, b + d), (a - 1, b + d + 1), (a + 1, b + d), (a + 1, b + d + 1)]
        else:
            nb = [(a - 1, b), (a + 1, b), (a, b - 1), (a, b + 1)]
        out[k] = all(n in have for n in nb)
    return out


def _lattice_rc(r, c, layout):
    """Lattice offsets (rows, columns; pitches) of indices ``r``, ``c`` from lenslet (0, 0)."""
    r = np.asarray(r, np.float64)
    c = np.asarray(c, np.float64)
    if layout == "hex":
        return np.stack([r * _H, c + 0.5 * np.mod(r, 2)], axis=-1)
    return np.stack([r, c], axis=-1)


def _decoded_grid(layout, M, origin, r, c, H, W):
    """First row, first column and size of the largest index rectangle within the measured
    lenslets' index range whose lenslet images lie wholly on the sensor (centres half a
    pitch from every edge). Hexagonal: the first row is even (unshifted)."""
    half = 0.5 * float(np.linalg.norm(M[:, 0]))
    r0, r1, c0, c1 = int(r.min()), int(r.max()), int(c.min()), int(c.max())
    step = 2 if layout == "hex" else 1
    if layout == "hex" and r0 % 2:
        r0 += 1
    while r0 <= r1 and c0 <= c1:
        rr, cc = np.meshgrid(np.arange(r0, r1 + 1), np.arange(c0, c1 + 1), indexing="ij")
        cen = origin + _lattice_rc(rr, cc, layout) @ M.T
        bad = (cen[..., 0] < half) | (cen[..., 0] > H - half) | (cen[..., 1] < half) | (cen[..., 1] > W - half)
        if not bad.any():
            return r0, c0, r1 - r0 + 1, c1 - c0 + 1
        k = int(np.argmax([bad[0].sum(), bad[-1].sum(), bad[:, 0].sum(), bad[:, -1].sum()]))
        if k == 0:
            r0 += step
        elif k == 1:
            r1 -= 1
        elif k == 2:
            c0 += 1
        else:
            c1 -= 1
    raise CalibrationError("no lenslet grid found: no whole lenslet image lies on the sensor")


def calibration_image(info, kind: str, override=None):
    """The white or dark image a calibration names (``GridCalibration.white``/``.dark``), checked
    against its SHA-256; ``override``: a path read instead, unchecked. None when neither is given.

    Raises
    ------
    FileNotFoundError
        The named image is gone (give it again as ``--white``/``--dark``).
    ValueError
        The named image has changed since the calibration.
    """
    if override:
        return load_image(override)
    if not info:
        return None
    p = Path(info["path"])
    if not p.is_file():
        raise FileNotFoundError(f"the calibration's {kind} image {p} is gone; give it with --{kind}")
    if file_digest(p)["sha256"] != info["sha256"]:
        raise ValueError(f"the calibration's {kind} image {p} has changed since the calibration")
    return load_image(p)

