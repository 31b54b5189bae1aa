"""Real cameras: the lenslet lattice of a white image, the steps of
:func:`lf_flame.real.calibration.calibrate`: the lattice's two shortest vectors from the
image's autocorrelation, one spot per lenslet and its subpixel centre, and a robust fit of
the lattice through the spots (indices, similarity transform, the whole lenslet images on
the sensor). Coordinates as :mod:`lf_flame.real.calibration` states them.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.fft
from scipy import ndimage
from skimage import feature, measure, transform

#: Row spacing of a hexagonal lattice, in pitches.
_H = math.sqrt(3) / 2


class CalibrationError(ValueError):
    """The white image cannot be calibrated (not a white image, no lenslet grid found)."""


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
