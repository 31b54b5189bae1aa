"""A sensor's defective pixels (hot, warm, stuck or dead) in a raw light-field capture: found, repaired, left out.

A hot pixel is one bright sample in one view. Refocused, it is sharp only where the views' shifts happen to be
whole pixels, so depth from focus reads it as a flame of its own: on the paper's camera, with 1 pixel in 10,000
defective (half hot, at 0.3-1 of the clipping level, half dead) ``lf-flame reconstruct``'s route found a
spurious depth on 2 of 6 random-depth scenes, with 1 in 1,000 1-11 on every scene (``experiments/defects.py``).
Sensors ship with such pixels (and grow more), and a dark frame only removes those that are hot at the frame's
exposure.

What tells a defect from light. A plenoptic 1.0 camera images each object point through many pixels: a pixel's
neighbours in its lenslet image are the neighbouring views of the same lenslet, and the pixel at the same place
under the neighbouring lenslets is the same view of the neighbouring lenslets. Light that reaches one pixel
reaches some of those 16 (a flame is wider than a lenslet's footprint, and blurs across the views); a defect
reaches none. A pixel is flagged when it stands out of every neighbour under the lenslets around and of all but
one in its own lenslet image (two defects side by side on the sensor are both found) by more than ``margin``
times the image's light range plus ``spread`` times the neighbours' own spread (their third highest less their
third lowest: noise and texture). A thin bright structure keeps a lit neighbour under a lenslet around, and is
not taken.
PlenoptiCam flags pixels against their 3 x 3 median on the raw mosaic (its ``CfaHotPixels``); the lenslets'
neighbours are what a light field adds. A point of light smaller than a lenslet's footprint and far from focus
(a spark) is seen so too, and would be flagged: this project's emitters are flames.

Repaired pixels take the median of their neighbours (the views refocused and searched for depths); the routes
that fit the data leave them out, as they leave out clipped pixels (a raw image's
:attr:`~lf_flame.real.lightfield.LightField.defects`; a decoded capture's clipped samples,
:func:`lf_flame.real.decoding.decode_repaired`).
"""
from __future__ import annotations

import math

import numpy as np

from . import _defect_kernels

#: A defect stands this share of the image's light range (its 99.9th percentile less its median), plus
#: :data:`DEFECT_SPREAD` times its neighbours' spread, above its neighbours (module notes). With
#: :data:`DEFECT_SPREAD`, chosen on the renders of ``experiments/fourier_solver.py``, 16-ray random-depth scenes
#: and the colour camera's validation captures (``experiments/defects.py``, ``docs/decisions.md``): no pixel of a
#: monochrome noise-free render taken; at 14 dB 1-73 of 3.6 million (noise as far above its neighbours as a warm
#: pixel, left out of the fit with them).
DEFECT_MARGIN = 0.1
#: The neighbours' spread (third highest less third lowest) a defect stands out of besides the margin: noise
#: and texture raise it, so that a noisy pixel is not taken for a defect.
DEFECT_SPREAD = 1.5


def lenslet_offsets(matrix, layout: str = "square", step: int = 1) -> np.ndarray:
    """The 16 neighbours of a pixel (row, column offsets, px): 8 in its lenslet image, 8 at its place under the
    lenslets around.

    Parameters
    ----------
    matrix : array_like of shape (2, 2)
        Lattice steps (rows, columns; pitches) -> sensor offsets (rows, columns; px), as
        :attr:`lf_flame.real.calibration.GridCalibration.matrix` (``pixels_per_lenslet`` times the identity
        for a perfect grid).
    layout : {"square", "hex"}
        ``hex``: rows of lenslets half a pitch apart in columns, ``sqrt(3) / 2`` pitches apart in rows.
    step : int
        Pixels between two pixels of one colour along rows and columns: 1 for a monochrome sensor, 2 for a Bayer
        mosaic (the offsets are then rounded to even pixels, so a pixel meets pixels of its own colour; a lattice
        step that rounds more than half a pixel off its place is taken twice, where that lands nearer).

    Returns
    -------
    ndarray of shape (16, 2), int64

    Raises
    ------
    ValueError
        A matrix that is not 2 x 2 and finite, an unknown layout, a step below 1, or lenslets so close that a
        neighbouring lenslet's pixel falls in the pixel's own 3 x 3 neighbourhood.
    """
    m = np.asarray(matrix, np.float64)
    if m.shape != (2, 2) or not np.all(np.isfinite(m)):
        raise ValueError(f"matrix must be a finite 2 x 2 array. Received: {matrix!r}")
    if layout not in ("square", "hex"):
        raise ValueError(f"layout must be 'square' or 'hex'. Received: {layout!r}")
    if int(step) != step or step < 1:
        raise ValueError(f"step must be a positive integer. Received: {step!r}")
    step = int(step)
    col = m @ np.array([0.0, 1.0])
    if layout == "square":
        row = m @ np.array([1.0, 0.0])
        lattice = [col, row, col + row, col - row]
    else:
        h = math.sqrt(3) / 2
        up, down = m @ np.array([h, 0.5]), m @ np.array([h, -0.5])
        lattice = [col, up, down, up + down]
    near = [(dy * step, dx * step) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
    far = []
    for v in lattice:
        if max(abs(float(v[0])), abs(float(v[1]))) < 1.5 * step:
            raise ValueError(f"lenslet images {np.hypot(*v):.2f} px apart are too close to find defective pixels")
        # the lattice step (or its double) whose pixel of the same colour lies nearest its place: rounded to even
        # pixels a Bayer mosaic's step of 10.96 px lands 0.96 px off, in another view, and the lit pixels at the
        # rim of a lenslet's aperture image stood out of dark neighbours and were taken for defects; twice the step
        # lands 0.08 px off
        q = np.rint(v / step).astype(np.int64) * step
        if np.max(np.abs(q - v)) > 0.5:
            q2 = np.rint(2 * v / step).astype(np.int64) * step
            q = q2 if np.max(np.abs(q2 - 2 * v)) < np.max(np.abs(q - v)) else q
        far += [(int(q[0]), int(q[1])), (-int(q[0]), -int(q[1]))]
    return np.array(near + far, np.int64)


def defective_pixels(raw, offsets, *, margin: float = DEFECT_MARGIN, spread: float = DEFECT_SPREAD,
                     level: float | None = None):
    """Defective pixels of a raw light-field image, and the image with each replaced by its neighbours' median.

    Parameters
    ----------
    raw : ndarray of shape (H, W)
        The raw image (any units; dark-subtracted or not).
    offsets : ndarray of shape (K, 2), int
        The neighbours (:func:`lenslet_offsets`).
    margin : float
        In (0, 1): how far a defect stands out of its neighbours, in the image's light range (module notes).
    spread : float
        >= 0: and how many times its neighbours' spread besides.
    level : float or None
        The light range (the raw image's units); None: its 99.9th percentile less its median (of every pixel
        ``step`` rows and columns apart, about 10^5 of them).

    Returns
    -------
    flagged : ndarray of bool of shape (H, W)
    repaired : ndarray of shape (H, W)
        float32 for a float32 image, else float64.

    Raises
    ------
    ValueError
        A raw image that is not 2-D or not finite, offsets that are not (K, 2) integers with K >= 4, or a margin
        or level out of range.
    """
    img = np.asarray(raw)
    img = np.ascontiguousarray(img, img.dtype if img.dtype in (np.float32, np.float64) else np.float64)
    if img.ndim != 2:
        raise ValueError(f"raw must be a 2-D image. Received shape {img.shape}")
    if not np.all(np.isfinite(img)):
        raise ValueError("raw contains NaN or infinite values")
    off = np.asarray(offsets)
    if off.ndim != 2 or off.shape[1] != 2 or len(off) < 4 or not np.issubdtype(off.dtype, np.integer):
        raise ValueError(f"offsets must be (K, 2) integers, K >= 4. Received shape {off.shape}, {off.dtype}")
    if not (math.isfinite(margin) and 0 < margin < 1):
        raise ValueError(f"margin must be in (0, 1). Received: {margin!r}")
    if not (math.isfinite(spread) and spread >= 0):
        raise ValueError(f"spread must be finite and >= 0. Received: {spread!r}")
    if level is None:                                  # on about 10^5 pixels: the same within a percent, 30x faster
        step = max(1, int(math.sqrt(img.size / 1e5)))
        hi, mid = np.percentile(img[::step, ::step], [99.9, 50.0])
        level = float(hi - mid)
    if not (math.isfinite(level) and level >= 0):
        raise ValueError(f"level must be finite and >= 0. Received: {level!r}")
    flagged = np.zeros(img.shape, bool)
    repaired = np.empty_like(img)
    if level == 0:                                     # no light: nothing stands out of it
        return flagged, img.copy()
    _defect_kernels.outlier_pixels(img, np.ascontiguousarray(off, np.int64), min(8, len(off)), margin * level,
                                   float(spread), flagged, repaired)
    return flagged, repaired


def repair_pixels(raw, flagged, offsets) -> np.ndarray:
    """``raw`` with the ``flagged`` pixels replaced by the median of their neighbours that are not flagged (those
    inside the image): a defect map found once (a sensor's defects are the same in every frame,
    :func:`defective_pixels`) applied to another frame.

    Parameters
    ----------
    raw : ndarray of shape (H, W)
    flagged : ndarray of bool of shape (H, W)
    offsets : ndarray of shape (K, 2), int

    Returns
    -------
    ndarray of shape (H, W), float64 (a copy)

    Raises
    ------
    ValueError
        A mask of another shape.
    """
    img = np.array(raw, np.float64)
    if np.shape(flagged) != img.shape:
        raise ValueError(f"the defect map's shape {np.shape(flagged)} is not the frame's {img.shape}")
    r, c = np.nonzero(flagged)
    if not len(r):
        return img
    rr, cc = r[:, None] + np.asarray(offsets)[None, :, 0], c[:, None] + np.asarray(offsets)[None, :, 1]
    inside = (rr >= 0) & (rr < img.shape[0]) & (cc >= 0) & (cc < img.shape[1])
    rr, cc = np.clip(rr, 0, img.shape[0] - 1), np.clip(cc, 0, img.shape[1] - 1)
    vals = np.where(inside & ~np.asarray(flagged)[rr, cc], img[rr, cc], np.nan)
    med = np.nanmedian(np.where(np.isnan(vals).all(axis=1, keepdims=True), 0.0, vals), axis=1)
    img[r, c] = med
    return img


def capture_defects(raw, offsets, *, dark=None, flagged=None):
    """A raw capture's defective pixels (:func:`defective_pixels`) and the capture with them repaired, as decoding
    takes it; or, with ``flagged`` (a map found in an earlier frame of the same sensor), that map applied.

    Parameters
    ----------
    raw : ndarray of shape (H, W)
        As read (before dark subtraction).
    offsets : ndarray of shape (K, 2), int
        The neighbours on the capture's lenslet grid (:func:`lenslet_offsets`; :func:`grid_offsets` for a
        calibrated one).
    dark : ndarray of the raw image's shape or None
        The dark frame decoding subtracts: the defects are found in ``raw - dark`` (a pixel hot in both is no
        defect of the capture), and repaired so that ``repaired - dark`` holds its neighbours' median.
    flagged : ndarray of bool of the raw image's shape, or None
        The defects, known: only repaired.

    Returns
    -------
    flagged : ndarray of bool of the raw image's shape
    repaired : ndarray of the raw image's shape, float64

    Raises
    ------
    ValueError
        As :func:`defective_pixels`; a dark frame or map of another shape.
    """
    img = np.asarray(raw, np.float64)
    d = 0.0 if dark is None else np.asarray(dark, np.float64)
    if np.shape(d) not in ((), img.shape):
        raise ValueError(f"the dark frame's shape {np.shape(d)} is not the raw image's {img.shape}")
    if flagged is None:
        flagged, fixed = defective_pixels(img - d, offsets)
    elif np.shape(flagged) != img.shape:
        raise ValueError(f"the defect map's shape {np.shape(flagged)} is not the raw image's {img.shape}")
    else:
        flagged, fixed = np.asarray(flagged, bool), None
    if not flagged.any():                              # nothing to repair: the capture as it is
        return flagged, img
    if fixed is None:
        fixed = repair_pixels(img - d, flagged, offsets)
    return flagged, np.where(flagged, fixed + d, img)


def grid_offsets(grid, colour: bool = False) -> np.ndarray:
    """:func:`lenslet_offsets` of a capture's lenslet grid.

    Parameters
    ----------
    grid : GridCalibration or int
        A calibrated grid (:class:`~lf_flame.real.calibration.GridCalibration`), or a perfect grid's pixels per
        lenslet.
    colour : bool
        A Bayer mosaic's (each pixel against pixels of its own colour).

    Returns
    -------
    ndarray of shape (16, 2), int64
    """
    if isinstance(grid, (int, np.integer)):
        return lenslet_offsets(int(grid) * np.eye(2), "square", 2 if colour else 1)
    return lenslet_offsets(grid.matrix, grid.layout, 2 if colour else 1)
