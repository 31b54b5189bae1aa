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


#: Pitches, in the calibration's, of the other grids :func:`check_grid` weighs against it
#: (and the band, in periods, of its visibility test).
GRID_CHECK_PITCHES = (0.6, 1.6)
#: Harmonics :func:`check_grid` weighs: reciprocal lattice points up to this many times the
#: calibration's fundamental frequency (and at most 0.5 cycle per pixel).
GRID_CHECK_HARMONICS = 6.0
#: Percentile of the flattened log power in the weighed band that a lattice point must pass to
#: add to a grid's score (below it, it takes away): lattice points off the image's peaks cost.
GRID_CHECK_LEVEL_PERCENTILE = 90.0


def _reciprocal(layout: str, pitch_px: float, rotation_deg: float) -> np.ndarray:
    """Reciprocal basis (2, 2) of a lenslet grid, columns (row, column) in cycles per pixel:
    the dual of the lattice vectors ``a_row``, ``a_col`` of :attr:`GridCalibration.matrix`."""
    t = math.radians(rotation_deg)
    M = pitch_px * np.array([[math.cos(t), math.sin(t)], [-math.sin(t), math.cos(t)]])
    a_col = M @ [0.0, 1.0]
    a_row = M @ ([_H, 0.5] if layout == "hex" else [1.0, 0.0])
    return np.linalg.inv(np.column_stack([a_row, a_col])).T


def _rotation(rad: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 2, 2) by ``rad`` acting on (row, column) vectors."""
    c, s = np.cos(rad), np.sin(rad)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def _grids_of(bases: np.ndarray, layout: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pitch (px) and rotation (degrees, within half the layout's symmetry angle: 30° hexagonal,
    45° square) of the grids whose reciprocal bases are ``bases`` (L, 2, 2), of layouts ``layout`` (L,)."""
    v = np.linalg.inv(bases)[:, 0, :]             # the dual's first vector: a shortest lattice vector
    sym = np.where(layout == "hex", 60.0, 90.0)
    rot = (np.degrees(np.arctan2(v[:, 0], v[:, 1])) + sym / 2) % sym - sym / 2
    return np.hypot(v[:, 0], v[:, 1]), rot


def _contains(coarse: np.ndarray, fine: np.ndarray, tol: float) -> np.ndarray:
    """Whether each reciprocal lattice of ``fine`` (L, 2, 2) lies on each of ``coarse`` (K, 2, 2)
    within the resolution: both its basis vectors are integer combinations of the other's (not on
    one line), each within ``tol`` (cycles/px) times its harmonic order (its frequency over the
    coarse lattice's fundamental, at least 1: a grid one bin off at the fundamentals is ``m`` bins
    off at its ``m``-th harmonic); shape (K, L)."""
    combo = np.rint(np.linalg.solve(coarse[:, None], fine[None]))                 # (K, L, 2, 2)
    miss = np.linalg.norm(coarse[:, None] @ combo - fine[None], axis=-2)           # (K, L, 2)
    f0 = np.linalg.norm(coarse, axis=-2).min(axis=-1)[:, None, None]              # (K, 1, 1)
    order = np.maximum(1.0, np.linalg.norm(fine, axis=-2)[None] / f0)
    return (miss <= tol * order).all(axis=-1) & (np.abs(np.linalg.det(combo)) > 0.5)


def _lattice_scores(level: np.ndarray, h: int, w: int, bases: np.ndarray, f_max: float) -> np.ndarray:
    """Sum of ``level`` (a half spectrum, rows ``-h..h-1``, columns ``0..w``, on a grid
    zero-padded to twice the crop ``h`` × ``w``) over the reciprocal lattice points
    ``0 < |k| <= f_max`` of each basis of ``bases`` (L, 2, 2); shape (L,)."""
    n = int(math.ceil(1.2 * f_max / np.linalg.norm(bases, axis=1).min())) + 1
    i, j = np.meshgrid(np.arange(-n, n + 1.0), np.arange(1.0, n + 1), indexing="ij")
    m = np.column_stack([np.stack([i.ravel(), j.ravel()]),
                         np.stack([np.arange(1.0, n + 1), np.zeros(n)])])          # a half plane of indices
    k = bases @ m                                                                   # (L, 2, K)
    keep = np.hypot(k[:, 0], k[:, 1]) <= f_max
    sign = np.where(k[:, 1] < 0, -1.0, 1.0)       # k and -k have one power: the half with columns >= 0
    rr = np.rint(sign * k[:, 0] * 2 * h).astype(np.int64) + h
    cc = np.rint(sign * k[:, 1] * 2 * w).astype(np.int64)
    keep &= (rr >= 0) & (rr < 2 * h) & (cc <= w)
    v = level[np.clip(rr, 0, 2 * h - 1), np.clip(cc, 0, w)]
    return (v * keep).sum(1)


def _grid_evidence(image: np.ndarray, calibration: GridCalibration, significance: float):
    """:func:`check_grid`'s candidate grids and scores, or None where the image shows no grid:
    (reciprocal bases (L, 2, 2), layouts (L,), scores (L,), index of the calibration's, bin (cycles/px))."""
    img = np.asarray(image, np.float64)
    H, W = img.shape
    h, w = min(H, 1024), min(W, 1024)
    crop = img[(H - h) // 2:(H - h) // 2 + h, (W - w) // 2:(W - w) // 2 + w]
    crop = (crop - crop.mean()) * np.outer(np.hanning(h), np.hanning(w))
    power = np.fft.fftshift(np.abs(scipy.fft.rfft2(crop, s=(2 * h, 2 * w))) ** 2, axes=0)   # (2h, w + 1)
    fr = (np.arange(2 * h) - h)[:, None] / (2 * h)
    fc = np.arange(w + 1)[None, :] / (2 * w)
    f = np.hypot(fr, fc)                                     # cycles per pixel
    own = _reciprocal(calibration.layout, calibration.pitch_px, calibration.rotation_deg)
    f0 = float(np.linalg.norm(own, axis=0).mean())
    band = (f > f0 / GRID_CHECK_PITCHES[1]) & (f < f0 / GRID_CHECK_PITCHES[0])
    if not band.any():
        return None
    top = power[band].max()
    if not top > 0 or top < significance * np.median(power[band]):
        return None
    # log power less its mean over rings one bin wide, then the best of the 3 x 3 padded bins
    logp = np.log(np.maximum(power, top * 1e-30))
    n = min(h, w)
    ring = np.minimum((f * n).astype(np.int64), n)
    mean = np.bincount(ring.ravel(), logp.ravel()) / np.maximum(np.bincount(ring.ravel()), 1)
    level = ndimage.maximum_filter(logp - mean[ring], size=3, mode="nearest")
    f_max = min(0.5, GRID_CHECK_HARMONICS * f0)
    level -= np.percentile(level[(f >= f0 / GRID_CHECK_PITCHES[1]) & (f <= f_max)], GRID_CHECK_LEVEL_PERCENTILE)
    step = 0.5 / (f_max * n)      # a relative change of scale or rotation moving f_max half a bin

    layouts = [calibration.layout] + [x for x in ("hex", "square") if x != calibration.layout]
    scales = np.exp(np.arange(math.log(GRID_CHECK_PITCHES[0]), math.log(GRID_CHECK_PITCHES[1]), step))
    unit = [_reciprocal(x, 1.0, calibration.rotation_deg) for x in layouts]
    scan = np.stack([u / (calibration.pitch_px * s) for u in unit for s in scales])
    scan_layout = np.repeat(layouts, len(scales))
    # the grids with one of the strongest in-band peaks as a fundamental, within half a bin of it
    pk = np.where(band, power, 0.0)
    peaks = np.argwhere((pk == ndimage.maximum_filter(pk, size=5)) & (pk > 0.1 * top))
    peaks = peaks[np.argsort(pk[peaks[:, 0], peaks[:, 1]])[::-1][:4]]
    seeds, seed_layout = [], []
    for r, c in peaks:
        k = np.array([fr[r, 0], fc[0, c]])
        half = 0.5 / (float(np.linalg.norm(k)) * n)
        d = np.arange(-half, half + step / 2, step)
        S, T = np.meshgrid(np.exp(d), d, indexing="ij")
        around = _rotation(T.ravel()) / S.ravel()[:, None, None]
        for x, angle in (("hex", 60.0), ("square", 90.0)):
            seeds.append(around @ np.column_stack([k, _rotation(np.radians(angle)) @ k]))
            seed_layout += [x] * len(around)
    bases = np.concatenate([scan, own[None]] + seeds)
    layout = np.concatenate([scan_layout, [calibration.layout], seed_layout])
    return bases, layout, _lattice_scores(level, h, w, bases, f_max), len(scan), 1.0 / n


def _peak_refusal(image: np.ndarray, calibration: GridCalibration, significance: float):
    """The first test of :func:`check_grid`: its message where the power at the calibration's fundamentals
    (the best of the 3 x 3 bins about each) is under a quarter of the strongest bin of periods 0.6-1.6
    pitches, else None (also for an image that shows no grid: that bin under ``significance`` x the band's
    median)."""
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
        return None
    top = power[band].max()
    if top < significance * np.median(power[band]):
        return None
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
        return (f"the image shows a lenslet grid of period {period:.2f} px, not the calibration's "
                f"{calibration.layout} grid of pitch {calibration.pitch_px:.2f} px at "
                f"{calibration.rotation_deg:.2f}°: a calibration from another camera or set-up")
    return None


def check_grid(image: np.ndarray, calibration: GridCalibration, significance: float = 50.0,
               margin: float = 0.0) -> None:
    """Raise ValueError if ``image`` visibly shows a lenslet grid other than the calibration's.

    In the power spectrum of the image (a central crop of at most 1024 × 1024 pixels,
    Hann-windowed, zero-padded to twice its size) a lenslet grid is a set of sharp peaks on
    its reciprocal lattice: the fundamentals and their harmonics, every integer combination
    of its two reciprocal vectors. First, visibility: the strongest bin among spatial
    frequencies of periods between 0.6 and 1.6 pitches is compared with the median there;
    below ``significance`` × the median the image shows no grid (a dark raw image) and cannot
    be checked, which passes.

    Then two tests, and the image is refused only where both find another grid. The first: the
    power at the calibration's fundamental frequencies (two for a square lattice, three for a
    hexagonal one; the best of the 3 × 3 bins about each) must reach a quarter of that strongest
    bin (:func:`_peak_refusal`). It alone refused captures of flames out of focus (below), the
    second alone some of the paper camera's captures (a square grid of 15.36 px found against
    the calibration's 15.00 px, in ``make cameras``). The second weighs the whole lattice,
    not one peak. Each candidate grid scores the sum, over
    its reciprocal lattice points up to :data:`GRID_CHECK_HARMONICS` times the calibration's
    fundamental frequency (and 0.5 cycle/px), of the log power there (the best of the 3 × 3
    padded bins about the point, half a bin either way), less the mean log power of its ring
    ``|k|`` and less the :data:`GRID_CHECK_LEVEL_PERCENTILE` th percentile of that over the band:
    a point on a peak adds, a point off the peaks takes away, so that neither a grid with a
    subset of the peaks nor one with extra points scores as high as the grid itself. The
    calibration's side scores the best of its own grid and of every candidate its reciprocal
    lattice explains: one whose reciprocal vectors are integer combinations of the
    calibration's, each within one bin (1 / the crop's smaller side, cycles/px) per harmonic
    order — its grid within the window's resolution, or a grid on a subset of its peaks. The
    other candidates: both layouts at the calibration's rotation with pitches
    :data:`GRID_CHECK_PITCHES` times its own (steps moving the highest harmonic half a bin),
    and the square and hexagonal grids that have one of the four strongest in-band peaks as a
    fundamental (within half a bin of it, in pitch and rotation). The image is refused when
    the best of these scores more than ``margin`` above the calibration's side.

    Why not the strongest peak: the image's content moves it. A flame out of focus lights
    part of each lenslet image, a part that moves from lenslet to lenslet, so that its
    spectrum peaks near the fundamentals but not on them: a hexagonal camera of 10.57 px
    pitch (fundamentals of period 9.16 px) imaging two flames 0.9 mm wide showed its
    strongest peak at a period of 9.91 px, at (-0.94, -0.91) in reciprocal-lattice units,
    16 times the power at the fundamentals. That peak is on no lattice's harmonics; the
    calibration's lattice is, at every harmonic.

    Parameters
    ----------
    image : ndarray of shape (H, W)
        A raw image (dark-subtracted or not), in any units; the check is scale-free.
    calibration : GridCalibration
        Its layout, pitch (px) and rotation (degrees) are checked; its origin is not (a
        power spectrum does not see it).
    significance : float
        Strongest-to-median power ratio in the band below which no grid is visible.
    margin : float
        How much more (summed log power, nats) another grid must score to refuse the image;
        0: any grid that fits the image better than the calibration's.

    Raises
    ------
    ValueError
        The image shows another grid: another pitch, layout or rotation, beyond the window's
        resolution (another camera, or another set-up of this one). The message names the
        grid that fits best: its layout, pitch (px, to about a bin at the fundamentals) and
        rotation (degrees).
    """
    if _peak_refusal(image, calibration, significance) is None:
        return
    found = _grid_evidence(image, calibration, significance)
    if found is None:
        return
    bases, layout, scores, me, tol = found
    own = bases[me]
    # explained by the calibration: grids whose reciprocal vectors are integer combinations of its own,
    # each within a bin (its own grid within the window's resolution, or one with a subset of its peaks)
    mine = _contains(own[None], bases, tol)[0]
    mine[me] = True
    other = np.flatnonzero(~mine)
    own_score = scores[mine].max()
    if scores[other].max() > own_score + margin:
        i = other[np.argmax(scores[other])]
        pitch, rot = _grids_of(bases[i][None], layout[i:i + 1])
        raise ValueError(f"the image shows a {layout[i]} lenslet grid of pitch {pitch[0]:.2f} px at "
                         f"{rot[0]:.2f}°, not the calibration's {calibration.layout} grid of pitch "
                         f"{calibration.pitch_px:.2f} px at {calibration.rotation_deg:.2f}°: a calibration from "
                         "another camera or set-up")


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


def _prepared(raw, calibration: GridCalibration, dark, n_views, check: bool):
    """The decoders' raw image, dark subtracted and checked against the calibration's grid
    (:func:`check_grid`), the dark frame (or None) and the views per axis (default :func:`max_views`),
    each refused as :func:`decode` says."""
    img = _image("raw image", raw, calibration.sensor_shape)
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
    return img, d, int(n)


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
    if camera_id is not None and calibration.camera_id and camera_id != calibration.camera_id:
        raise ValueError(f"the calibration is of camera {calibration.camera_id!r}, not {camera_id!r}")
    img, d, n = _prepared(raw, calibration, dark, n_views, check)
    pos = view_positions(calibration, n)
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


def decode_colour(raw: np.ndarray, calibration: GridCalibration, sensor, white: np.ndarray | None = None,
                  dark: np.ndarray | None = None, *, n_views: int | None = None, min_white: float = 0.05,
                  check: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Decode a colour (Bayer) raw image into sub-aperture views that keep its channels apart.

    :func:`decode`'s bilinear resampling blends four pixels, which under a colour filter array
    are of two or three channels. Here each view sample is the one pixel nearest its position
    (:func:`view_positions`) and carries that pixel's channel: the channel map of the views, on
    which each channel is solved from its own samples
    (:func:`lf_flame.temperature.channels.channel_emission`), as on a perfect grid. The price is
    the position: up to half a pixel (half a view step) from where the decoded camera puts the
    sample. The white image divides each pixel by its own value over its channel's 99th
    percentile on the sensor, so that vignetting is removed and the channels' ratio, which the
    pyrometer reads, is the raw image's.

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
    calibration : GridCalibration
        Of a square grid.
    sensor : ColourSensor
        Its CFA pattern and phase (of pixel (0, 0) of the raw image).
    white, dark, n_views, min_white, check
        As :func:`decode`.

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        As :func:`decode`'s; 0 where the white image is dark or the pixel off the sensor.
    channels : ndarray of shape (N, N, R, C), int8
        Each sample's channel (0 R, 1 G, 2 B; :data:`lf_flame.optics.colour.CHANNELS`).

    Raises
    ------
    ValueError
        As :func:`decode`, and a hexagonal grid (its resampling onto a square one would blend
        channels again).
    """
    from ..optics.colour import cfa_channels
    calibration.validate()
    if calibration.layout == "hex":
        raise ValueError("a hexagonal colour capture cannot be decoded with its channels apart yet: the resampling "
                         "onto a square grid blends neighbouring lenslets' samples, of other channels")
    img, d, n = _prepared(raw, calibration, dark, n_views, check)
    H, W = calibration.sensor_shape
    q = np.floor(view_positions(calibration, n)).astype(np.int64)    # pixel (i, j) spans [i, i + 1) x [j, j + 1)
    on = (q[..., 0] >= 0) & (q[..., 0] < H) & (q[..., 1] >= 0) & (q[..., 1] < W)
    qr, qc = np.clip(q[..., 0], 0, H - 1), np.clip(q[..., 1], 0, W - 1)
    cfa = cfa_channels((H, W), sensor.pattern, sensor.phase)
    channels = cfa[qr, qc]
    views = np.where(on, img[qr, qc], 0.0)
    if white is not None:
        w = _image("white image", white, calibration.sensor_shape)
        if d is not None:
            w = w - d
        level = np.ones(3)
        for c in range(3):
            v = w[cfa == c]
            level[c] = np.percentile(v, 99) if v.size else 1.0
        if not np.all(level > 0):
            raise ValueError("the white image is dark in a colour channel: not this camera's white image")
        wv = np.where(on, w[qr, qc] / level[channels], 0.0)
        lit = wv > min_white
        views = np.where(lit, views / np.where(lit, wv, 1.0), 0.0)
    return np.ascontiguousarray(views.astype(np.float32)), np.ascontiguousarray(channels.astype(np.int8))


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
               channels: np.ndarray | None = None, **attrs) -> Path:
    """Write decoded views to HDF5 (dataset ``views``, (N, N, R, C) float32; the calibration
    as JSON in attribute ``calibration``), atomically: a temporary file, then renamed.
    ``clipped`` (bool, the views' shape; :func:`clipped_samples`) goes in dataset ``clipped``,
    a colour capture's ``channels`` (int8, the views' shape; :func:`decode_colour`) in dataset
    ``channels``."""
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
        if channels is not None:
            if np.shape(channels) != np.shape(views):
                raise ValueError(f"channels must have the views' shape {np.shape(views)}. Received: "
                                 f"{np.shape(channels)}")
            f.create_dataset("channels", data=np.asarray(channels, np.int8), compression="gzip", compression_opts=1)
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


def load_channels(path) -> np.ndarray | None:
    """The channel map (int8, (N, N, R, C); 0 R, 1 G, 2 B) of :func:`save_views`' file of a colour
    capture (:func:`decode_colour`), or None for a monochrome one."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        return f["channels"][...].astype(np.int8) if "channels" in f else None


def load_clipped(path) -> np.ndarray | None:
    """The ``clipped`` mask (bool, (N, N, R, C)) of :func:`save_views`' file, or None when it
    has none (decoded without a saturation level, or before decoding recorded one)."""
    import h5py
    with h5py.File(Path(path), "r") as f:
        return f["clipped"][...].astype(bool) if "clipped" in f else None
