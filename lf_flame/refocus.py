"""Sub-aperture views, shift-and-sum refocusing, sharpness metrics and the slope search.

Convention (the paper's): a point of the plane at slope ``s`` appears at lenslet
``x0 + s (u - c)`` in sub-aperture view ``u``, ``c = (N - 1) / 2``; refocusing at ``s``
samples view ``(u, v)`` at ``(r + s (u - c), col + s (v - c))`` and averages (the
paper's Eq. 2, Ng 2005 Eq. 4.1, with the 1/α magnification dropped as is usual for
sub-aperture shift-and-sum). Slopes are in lenslets per view step.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage import filters

from . import _kernels


def _check_finite(name, a):
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN or inf")


def raw_to_views(raw: np.ndarray, pixels_per_lenslet: int) -> np.ndarray:
    """Split a raw plenoptic image into sub-aperture views.

    Parameters
    ----------
    raw : ndarray of shape (R * N, C * N)
        Raw sensor image, rows and columns.
    pixels_per_lenslet : int
        ``N``.

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32, C-contiguous
        ``views[u, v, r, c] = raw[r * N + u, c * N + v]``: (u, v) the pixel under
        each lenslet (view row, view column), (r, c) the lenslet.

    Raises
    ------
    ValueError
        If the raw shape is not a multiple of N, or it holds NaN or inf.
    """
    raw = np.asarray(raw)
    n = int(pixels_per_lenslet)
    if raw.ndim != 2 or n < 1 or raw.shape[0] % n or raw.shape[1] % n:
        raise ValueError(f"raw image of shape {raw.shape} is not a grid of {n}x{n}-pixel lenslet images")
    _check_finite("raw image", raw)
    R, C = raw.shape[0] // n, raw.shape[1] // n
    return np.ascontiguousarray(raw.reshape(R, n, C, n).transpose(1, 3, 0, 2), dtype=np.float32)


def views_to_raw(views: np.ndarray) -> np.ndarray:
    """Inverse of :func:`raw_to_views`: (N, N, R, C) -> (R * N, C * N)."""
    U, V, R, C = views.shape
    return np.ascontiguousarray(views.transpose(2, 0, 3, 1).reshape(R * U, C * V))


def aperture_mask(n: int, shape: str = "square") -> np.ndarray:
    """Views to use: ``square`` (all N × N) or ``circular`` (inside the inscribed circle).

    Returns
    -------
    mask : ndarray of shape (N, N), bool
    """
    if shape == "square":
        return np.ones((n, n), bool)
    if shape == "circular":
        c = (n - 1) / 2
        u = np.arange(n) - c
        return u[:, None] ** 2 + u[None, :] ** 2 <= (n / 2) ** 2
    raise ValueError(f"aperture shape must be 'square' or 'circular'. Received: {shape!r}")


def focal_stack(views: np.ndarray, slopes, mask: np.ndarray | None = None) -> np.ndarray:
    """Shift-and-sum refocusing at several slopes in one pass (paper Eq. 2).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`raw_to_views`).
    slopes : sequence of float, length S
        Slopes in lenslets per view step (paper's sign: near planes negative).
    mask : ndarray of shape (N, N), bool, optional
        Views to use (:func:`aperture_mask`); default all.

    Returns
    -------
    stack : ndarray of shape (S, R, C), float32
        Mean of the bilinearly shifted views that cover each pixel (borders are not
        darkened by views that shift out of the image; a pixel no view covers is 0).

    Raises
    ------
    ValueError
        NaN/inf in views or slopes, or a mask of the wrong shape.
    """
    views = np.ascontiguousarray(views, dtype=np.float32)
    if views.ndim != 4 or views.shape[0] != views.shape[1]:
        raise ValueError(f"views must have shape (N, N, R, C). Received: {views.shape}")
    slopes = np.atleast_1d(np.asarray(slopes, dtype=np.float64))
    _check_finite("slopes", slopes)
    _check_finite("views", views)
    n = views.shape[0]
    mask = aperture_mask(n) if mask is None else np.asarray(mask, bool)
    if mask.shape != (n, n):
        raise ValueError(f"mask must have shape {(n, n)}. Received: {mask.shape}")
    offs = np.arange(n) - (n - 1) / 2
    shifts = slopes[:, None] * offs[None, :]
    out = np.empty((len(slopes),) + views.shape[2:], np.float32)
    _kernels.shift_sum_stack(views, shifts, shifts, mask, out)
    return out


def refocus(raw: np.ndarray, slopes, pixels_per_lenslet: int, mask=None) -> np.ndarray:
    """Refocus a raw image at ``slopes``: (R·N, C·N) -> (S, R, C) float32. See :func:`focal_stack`."""
    return focal_stack(raw_to_views(raw, pixels_per_lenslet), slopes, mask)


# ---- sharpness -------------------------------------------------------------------
def variance_of_laplacian(img: np.ndarray) -> float:
    """Variance of the Laplacian (Pech-Pacheco et al. 2000); 0 for a constant image."""
    return float(np.var(ndimage.laplace(np.asarray(img, np.float64))))


def tenengrad(img: np.ndarray) -> float:
    """Mean squared Sobel gradient magnitude (Tenengrad, Krotkov 1987)."""
    return float(np.mean(filters.sobel(np.asarray(img, np.float64)) ** 2))


def normalized_variance(img: np.ndarray) -> float:
    """Intensity variance divided by the mean (Groen et al. 1985); 0 if the mean is 0."""
    img = np.asarray(img, np.float64)
    m = img.mean()
    return float(img.var() / m) if m > 0 else 0.0


SHARPNESS = {"laplacian": variance_of_laplacian, "tenengrad": tenengrad, "normvar": normalized_variance}


@dataclass(frozen=True)
class SlopeSearch:
    """Result of :func:`find_sharpest_slope`: best slope, and the metric curve."""

    slope: float
    slopes: np.ndarray
    scores: np.ndarray


def find_sharpest_slope(views: np.ndarray, roi, *, metric: str = "tenengrad", lo: float = -3.0,
                        hi: float = 3.0, coarse_step: float = 0.05, fine_step: float = 0.005,
                        mask=None) -> SlopeSearch:
    """Slope at which the region ``roi`` is sharpest: coarse grid, then a finer grid.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    roi : (row0, row1, col0, col1)
        Region of interest in lenslets (half-open).
    metric : {'laplacian', 'tenengrad', 'normvar'}
    lo, hi, coarse_step, fine_step : float
        Coarse grid ``lo..hi`` by ``coarse_step``; the fine grid spans ± one coarse
        step around the coarse maximum by ``fine_step``.

    Returns
    -------
    SlopeSearch
        ``slope``, and ``slopes``/``scores`` of both grids merged, sorted by slope.

    Raises
    ------
    ValueError
        Unknown metric, an empty ROI, or a bad grid.
    """
    if metric not in SHARPNESS:
        raise ValueError(f"metric must be one of {sorted(SHARPNESS)}. Received: metric={metric!r}")
    if not (hi > lo and coarse_step > 0 and fine_step > 0):
        raise ValueError(f"bad slope grid lo={lo}, hi={hi}, coarse_step={coarse_step}, fine_step={fine_step}")
    r0, r1, c0, c1 = (int(v) for v in roi)
    if r1 - r0 < 3 or c1 - c0 < 3:
        raise ValueError(f"region of interest {roi} is smaller than 3x3 lenslets")
    fn = SHARPNESS[metric]

    def scores(slopes):
        stack = focal_stack(views, slopes, mask)[:, r0:r1, c0:c1]
        return np.array([fn(im) for im in stack])

    coarse = np.arange(lo, hi + coarse_step / 2, coarse_step)
    sc = scores(coarse)
    best = coarse[int(np.argmax(sc))]
    fine = np.arange(best - coarse_step, best + coarse_step + fine_step / 2, fine_step)
    sf = scores(fine)
    slopes = np.concatenate([coarse, fine])
    allsc = np.concatenate([sc, sf])
    order = np.argsort(slopes, kind="stable")
    return SlopeSearch(float(fine[int(np.argmax(sf))]), slopes[order], allsc[order])
