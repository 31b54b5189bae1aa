"""Real cameras, stage 2: decoding of raw images into sub-aperture views with a lenslet-grid
calibration (:mod:`lf_flame.real.calibration`, stage 1).

:func:`decode` resamples every lenslet image about its calibrated centre (the fitted
lattice) into sub-aperture views (N, N, R, C), after dark subtraction and white-image
(vignetting) normalisation, with the axis order and units of :mod:`lf_flame.refocus.shift_and_sum`
(view step: one pixel; slopes: lenslets per view step). :func:`check_grid` refuses a raw
image of another camera; :func:`save_views` and :func:`load_views` are the file of
decoded views that ``lf-flame decode`` writes.

Pixel coordinates and the grid rotation are those of :mod:`lf_flame.real.calibration`.
Reference: Dansereau, Pizarro & Williams 2013 (LFToolbox: decoding to a 4-D light field).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import scipy.fft
from scipy import ndimage

from .calibration import GridCalibration
from .images import _image
from .lattice import _H


def check_grid(image: np.ndarray, calibration: GridCalibration, significance: float = 50.0) -> None:
    """Raise ValueError if ``image`` visibly shows a lenslet grid other than the calibration's.

    In the power spectrum of the image (a central crop of at most 1024 × 1024 pixels,
    Hann-windowed) a lenslet grid is a set of sharp peaks at its reciprocal lattice. The
    strongest bin among spatial frequencies of periods between 0.6 and 1.6 pitches is
    compared with the median there: below ``significance`` × the median the image shows
    no grid (a dark raw image) and cannot be checked, which passes. Otherwise the power
    at the calibration's fundamental frequencies (two for a square lattice, three for a
    hexagonal one; the best of the 3 × 3 bins about each)
    must reach a quarter of that strongest bin, else the grid is another one: another
    camera, or another set-up of this one.
    """
    img = np.asarray(image, np.float64)
    H, W = img.shape
    h, w = min(H, 1024), min(W, 1024)
    crop = img[(H - h) // 2:(H - h) // 2 + h, (W - w) // 2:(W - w) // 2 + w]
    crop = (crop - crop.mean()) * np.outer(np.hanning(h), np.hanning(w))
    power = np.fft.fftshift(np.abs(scipy.fft.fft2(crop)) ** 2)
    fr = (np.arange(h) - h // 2)[:, None] / h
    fc = (np.arange(w) - w // 2)[None, :] / w
    f = np.hypot(fr, fc)                                     # cycles per pixel
    M = calibration.matrix
    a_col = M @ [0.0, 1.0]
    a_row = M @ ([_H, 0.5] if calibration.layout == "hex" else [1.0, 0.0])
    recip = np.linalg.inv(np.column_stack([a_row, a_col])).T   # columns: reciprocal vectors (row, col), cycles/px
    f0 = float(np.linalg.norm(recip, axis=0).mean())
    band = (f > f0 / 1.6) & (f < f0 / 0.6)
    if not band.any():
        return
    top = power[band].max()
    if top < significance * np.median(power[band]):
        return
    at = 0.0
    fundamentals = [recip[:, 0], recip[:, 1]]
    if calibration.layout == "hex":         # a hexagonal lattice has three: the third is their sum or difference
        fundamentals.append(min(recip[:, 0] + recip[:, 1], recip[:, 0] - recip[:, 1], key=np.linalg.norm))
    for k in fundamentals:
        rr = int(round(k[0] * h)) + h // 2
        cc = int(round(k[1] * w)) + w // 2
        if 1 <= rr < h - 1 and 1 <= cc < w - 1:
            at = max(at, power[rr - 1:rr + 2, cc - 1:cc + 2].max())
    if at < 0.25 * top:
        peak = np.unravel_index(np.argmax(np.where(band, power, 0)), power.shape)
        period = 1 / max(float(f[peak]), 1e-12)
        raise ValueError(f"the image shows a lenslet grid of period {period:.2f} px, not the calibration's "
                         f"{calibration.layout} grid of pitch {calibration.pitch_px:.2f} px at "
                         f"{calibration.rotation_deg:.2f}°: a calibration from another camera or set-up")


def view_positions(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """Sensor positions (row, column; px) sampled for view ``(u, v)`` of lenslet ``(r, c)``:
    the lenslet's calibrated centre plus ``(u - (N-1)/2, v - (N-1)/2)`` pixels along the
    grid's rotated axes. Shape (N, N, R, C, 2), R × C the calibration's (hexagonal) grid."""
    off = np.arange(n_views) - (n_views - 1) / 2
    du = np.stack(np.meshgrid(off, off, indexing="ij"), axis=-1)              # (N, N, 2)
    rot = calibration.matrix / calibration.pitch_px
    return calibration.centres_px()[None, None] + (du @ rot.T)[:, :, None, None]


def _sample(img, pos):
    """Bilinear samples of ``img`` at pixel-coordinate positions ``pos`` (..., 2); 0 off the image."""
    coords = np.moveaxis(pos, -1, 0).reshape(2, -1) - 0.5      # pixel (i, j) is centred at (i + ½, j + ½)
    return ndimage.map_coordinates(img, coords, order=1, mode="constant", cval=0.0).reshape(pos.shape[:-1])


def hex_to_square(views: np.ndarray) -> np.ndarray:
    """Resample views on a hexagonal lenslet lattice onto a square one of the same pitch.

    ``views`` (N, N, R, C) on the calibration's hexagonal grid (row 0 unshifted, odd rows
    half a pitch right, rows ``sqrt(3)/2`` pitches apart). The square lattice has rows one
    pitch apart, ``floor((R - 1) sqrt(3)/2) + 1`` of them, and ``C - 1`` columns from
    half a pitch right of lenslet (0, 0), where every row has lenslets on both sides.
    Each value is the barycentric (linear) interpolation in the lattice triangle about it.

    Returns
    -------
    views : ndarray of shape (N, N, R', C'), float32
    """
    N, _, R, C = views.shape
    rows = int(math.floor((R - 1) * _H)) + 1
    cols = C - 1
    if rows < 1 or cols < 1:
        raise ValueError(f"a hexagonal grid of {R} x {C} lenslets is too small to resample")
    y, x = np.meshgrid(np.arange(rows, dtype=np.float64), 0.5 + np.arange(cols), indexing="ij")
    j = y / _H                        # lattice row, fractional
    i = x - j / 2                     # skew column: site (i, j) sits at x = i + j/2
    i0, j0 = np.floor(i), np.floor(j)
    fi, fj = i - i0, j - j0
    lower = fi + fj < 1
    verts = [(np.where(lower, i0, i0 + 1), np.where(lower, j0, j0 + 1), np.where(lower, 1 - fi - fj, fi + fj - 1)),
             (i0 + 1, j0, np.where(lower, fi, 1 - fj)),
             (i0, j0 + 1, np.where(lower, fj, 1 - fi))]
    out = np.zeros((N, N, rows, cols), np.float32)
    for vi, vj, w in verts:
        r = np.clip(vj, 0, R - 1).astype(int)
        c = np.clip(vi + np.floor(vj / 2), 0, C - 1).astype(int)
        out += (w[None, None] * views[:, :, r, c]).astype(np.float32)
    return out


def max_views(calibration) -> int:
    """Views per axis a lenslet image holds: ``floor(pitch_px + PITCH_SNAP_PX)``
    (:data:`lf_flame.optics.camera_file.PITCH_SNAP_PX`).

    Parameters
    ----------
    calibration : GridCalibration

    Returns
    -------
    int
        One pixel apart along each axis: 10 for a 10.57 px pitch, 15 for a calibrated 14.9997.
    """
    from ..optics.camera_file import PITCH_SNAP_PX
    return int(math.floor(calibration.pitch_px + PITCH_SNAP_PX))


def decode(raw: np.ndarray, calibration: GridCalibration, white: np.ndarray | None = None,
           dark: np.ndarray | None = None, *, n_views: int | None = None, min_white: float = 0.05,
           camera_id: str | None = None, check: bool = True) -> np.ndarray:
    """Decode a raw plenoptic image into sub-aperture views with its grid calibration.

    Dark subtraction, then every lenslet image is resampled (bilinearly) at
    :func:`view_positions` about its calibrated centre, and divided by the white image
    resampled the same way (vignetting and cos⁴ normalisation; Dansereau et al. 2013).
    A hexagonal grid is then resampled onto a square one (:func:`hex_to_square`).

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
    calibration : GridCalibration
    white, dark : ndarray of the same shape, or None
        White image and dark frame (the dark frame is subtracted from both).
    n_views : int or None
        ``N``, views per axis, one pixel apart; default and most :func:`max_views`.
    min_white : float
        Samples where the white image is below this fraction of its 99th percentile
        (outside the lenslet image, between lenslets) are set to 0.
    camera_id : str or None
        If given and the calibration names a camera, they must agree.
    check : bool
        Check that the raw image shows the calibration's grid (:func:`check_grid`).

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        ``views[u, v, r, c]``: view (u, v) of lenslet (r, c), as
        :func:`lf_flame.refocus.shift_and_sum.raw_to_views` (view step one pixel, lenslet step one pitch),
        so that :func:`~lf_flame.refocus.shift_and_sum.focal_stack`, :class:`~lf_flame.refocus.shift_and_sum.FourierSlice`
        and :func:`~lf_flame.refocus.shift_and_sum.find_sharpest_slope` apply unchanged. With a white
        image: radiance relative to the white target's; without: dark-subtracted counts.

    Raises
    ------
    ValueError
        A raw, white or dark image of another shape than the calibration's sensor, NaN or
        inf, ``n_views`` out of range, another camera id, or a raw image whose visible
        lenslet grid is not the calibration's.
    """
    calibration.validate()
    img = _image("raw image", raw, calibration.sensor_shape)
    if camera_id is not None and calibration.camera_id and camera_id != calibration.camera_id:
        raise ValueError(f"the calibration is of camera {calibration.camera_id!r}, not {camera_id!r}")
    d = None if dark is None else _image("dark frame", dark, calibration.sensor_shape)
    if d is not None:
        img = img - d
    if check:
        check_grid(img, calibration)
    n_max = max_views(calibration)
    n = n_max if n_views is None else n_views
    if int(n) != n or not 1 <= n <= n_max:
        raise ValueError(f"n_views must be an integer in [1, {n_max}] (the pitch is {calibration.pitch_px:.2f} px). "
                         f"Received: n_views={n_views!r}")
    pos = view_positions(calibration, int(n))
    views = _sample(img, pos)
    if white is not None:
        w = _image("white image", white, calibration.sensor_shape)
        if d is not None:
            w = w - d
        wv = _sample(w, pos)
        floor = min_white * np.percentile(wv, 99)
        if not floor > 0:
            raise ValueError("the white image is dark where the lenslet images are: not this calibration's white image")
        lit = wv > floor
        views = np.where(lit, views / np.where(lit, wv, 1.0), 0.0)
    views = views.astype(np.float32)
    if calibration.layout == "hex":
        views = hex_to_square(views)
    return np.ascontiguousarray(views)


def clipped_samples(raw: np.ndarray, calibration: GridCalibration, saturation: float, *,
                    n_views: int | None = None) -> np.ndarray:
    """Which decoded samples come from clipped raw pixels: the clipping level in the views' units.

    A sample of :func:`decode` is a bilinear mix of up to four raw pixels; it holds only a
    lower bound of its light when any of them (with a non-zero weight) is at or above the
    sensor's clipping level. After white-image division no single level marks such
    samples (a clipped pixel under a bright white reads 1 / white), so the mask is what
    carries the level into the views (:func:`lf_flame.tomo.solvers.reconstruct` leaves
    them out of the fit).

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
        The raw image as read, before dark subtraction (clipping happens in the sensor).
    calibration : GridCalibration
    saturation : float
        The sensor's clipping level in the raw image's units (1.0 for the simulator's
        images; ``2**bits - 1`` for integer counts).
    n_views : int or None
        As :func:`decode`.

    Returns
    -------
    clipped : ndarray of bool, the shape of :func:`decode`'s views (N, N, R, C)
        Hexagonal grids: a square-lattice sample is clipped when any of the three samples
        it is interpolated from is (:func:`hex_to_square`).

    Raises
    ------
    ValueError
        A raw image of another shape, NaN or inf, a level that is not a positive finite
        number, ``n_views`` out of range.
    """
    calibration.validate()
    img = _image("raw image", raw, calibration.sensor_shape)
    if isinstance(saturation, bool) or not isinstance(saturation, (int, float, np.floating)) or \
            not (math.isfinite(saturation) and saturation > 0):
        raise ValueError(f"saturation must be a positive finite level (raw units). Received: {saturation!r}")
    n_max = max_views(calibration)
    n = n_max if n_views is None else n_views
    if int(n) != n or not 1 <= n <= n_max:
        raise ValueError(f"n_views must be an integer in [1, {n_max}]. Received: n_views={n_views!r}")
    hit = _sample((img >= saturation).astype(np.float64), view_positions(calibration, int(n)))
    if calibration.layout == "hex":
        hit = hex_to_square(hit)
    return np.ascontiguousarray(hit > 1e-6)


def save_views(path, views: np.ndarray, calibration: GridCalibration, clipped: np.ndarray | None = None,
               **attrs) -> Path:
    """Write decoded views to HDF5 (dataset ``views``, (N, N, R, C) float32; the calibration
    as JSON in attribute ``calibration``), atomically: a temporary file, then renamed.
    ``clipped`` (bool, the views' shape; :func:`clipped_samples`) goes in dataset ``clipped``."""
    import os

    import h5py
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".partial")
    from ..config import removed_on_error
    with removed_on_error(tmp), h5py.File(tmp, "w") as f:
        f.create_dataset("views", data=np.asarray(views, np.float32), compression="gzip", compression_opts=1)
        if clipped is not None:
            if np.shape(clipped) != np.shape(views) or np.asarray(clipped).dtype != bool:
                raise ValueError(f"clipped must be boolean of the views' shape {np.shape(views)}. Received: "
                                 f"{np.asarray(clipped).dtype} of shape {np.shape(clipped)}")
            f.create_dataset("clipped", data=np.asarray(clipped), compression="gzip", compression_opts=1)
        f.attrs["format"] = "lf_flame.decoded_views"
        f.attrs["calibration"] = json.dumps(calibration.to_dict())
        for k, v in attrs.items():
            f.attrs[k] = v
    os.replace(tmp, p)
    return p


def load_views(path) -> tuple[np.ndarray, GridCalibration]:
    """Read :func:`save_views`' file: views (N, N, R, C) float32 and the calibration."""
    import h5py
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"views file not found: {p}")
    from ..config import reading
    with reading(p, "HDF5 file"), h5py.File(p, "r") as f:
        if f.attrs.get("format") != "lf_flame.decoded_views" or "views" not in f:
            raise ValueError(f"{p} is not a file of decoded views written by 'lf-flame decode'")
        views = f["views"][...]
        cal = GridCalibration.from_dict(json.loads(f.attrs["calibration"]))
    if views.ndim != 4 or views.shape[0] != views.shape[1]:
        raise ValueError(f"{p}: views of shape {views.shape}, not (N, N, R, C)")
    return views, cal


def load_clipped(path) -> np.ndarray | None:
    """The ``clipped`` mask (bool, (N, N, R, C)) of :func:`save_views`' file, or None when it
    has none (decoded without a saturation level, or before decoding recorded one)."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        return f["clipped"][...].astype(bool) if "clipped" in f else None
