"""Real cameras, decoding's guard: does a raw image show the lenslet grid of its calibration?

:func:`check_grid` refuses a raw image of another camera (another pitch, layout or rotation)
before :mod:`lf_flame.real.decoding` resamples it onto the calibration's grid, from the
image's power spectrum: its strongest peak in the band of the grid's fundamentals, and the
whole reciprocal lattice. Pixel coordinates and the grid rotation are those of
:mod:`lf_flame.real.calibration`.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.fft
from scipy import ndimage

from .calibration import GridCalibration
from .lattice import _H


#: Pitches, in the calibration's, of the other grids :func:`check_grid` weighs against it
#: (and the band, in periods, of its visibility test).
GRID_CHECK_PITCHES = (0.6, 1.6)
#: Harmonics :func:`check_grid` weighs: reciprocal lattice points up to this many times the
#: calibration's fundamental frequency (and at most 0.5 cycle per pixel).
GRID_CHECK_HARMONICS = 6.0
#: Lenslet images' worth of lit pixels (above a tenth of the brightest lenslet image's level, :func:`lit_lenslets`)
#: under which an image cannot show its grid and :func:`check_grid` passes it: a point of light lit 1.3-2.4
#: lenslet images and its few peaks took other grids for the calibration's (refused captures of the calibrated
#: camera of a new user's, 8-13 px pitches); scenes of flames light 200-600, a white image thousands.
GRID_CHECK_MIN_LIT = 16.0
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


def lit_lenslets(image: np.ndarray, pitch_px: float) -> float:
    """How many lenslet images' worth of pixels an image lights: its pixels above a tenth of the level of its
    brightest lenslet image's worth of pixels (the ``pitch_px ** 2``-th brightest), over ``pitch_px ** 2``.

    Parameters
    ----------
    image : ndarray of shape (H, W)
        A raw image, dark-subtracted (any units).
    pitch_px : float
        The lenslet images' pitch, px.

    Returns
    -------
    float
        Lenslet images (0 for an image that is nowhere positive).
    """
    flat = np.asarray(image, np.float64).ravel()
    k = int(min(max(round(pitch_px ** 2), 1), flat.size))
    top = np.partition(flat, -k)[-k]
    return float(np.count_nonzero(flat > 0.1 * top) / pitch_px ** 2) if top > 0 else 0.0


def check_grid(image: np.ndarray, calibration: GridCalibration, significance: float = 50.0,
               margin: float = 0.0) -> None:
    """Raise ValueError if ``image`` visibly shows a lenslet grid other than the calibration's.

    In the power spectrum of the image (a central crop of at most 1024 × 1024 pixels,
    Hann-windowed, zero-padded to twice its size) a lenslet grid is a set of sharp peaks on
    its reciprocal lattice: the fundamentals and their harmonics, every integer combination
    of its two reciprocal vectors. First, visibility: the strongest bin among spatial
    frequencies of periods between 0.6 and 1.6 pitches is compared with the median there;
    below ``significance`` × the median the image shows no grid (a dark raw image) and cannot
    be checked, which passes; so does an image that lights fewer than :data:`GRID_CHECK_MIN_LIT`
    lenslet images (:func:`lit_lenslets`: a point of light, whose few lenslet images' peaks fit
    other grids as well).

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
    if lit_lenslets(image, calibration.pitch_px) < GRID_CHECK_MIN_LIT:
        return
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
