"""Sharpness metrics and the slope search: the slope (lenslets per view step) at which a region of a light field
refocuses sharpest (:func:`find_sharpest_slope`), by the refocusing of :mod:`.shift_and_sum` (its convention).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from skimage import filters

from .shift_and_sum import METHODS, FourierSlice, _check_finite, _margin, focal_stack


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


#: A region whose sharpness (:data:`SHARPNESS`) stays below this share of its mean light squared (normvar: of its
#: mean light) at every slope has no focus to find (:func:`find_sharpest_slope`): a constant image's tenengrad peaks
#: at about 4e-8 of it (Fourier round-off); the paper's flames and shapes (4 rays per pixel) peak at 0.30-1.45 and
#: stay above 1.4e-3 at every slope.
FLAT_SHARPNESS = 1e-6
#: :func:`find_sharpest_slope` searches slopes (lenslets per view step) up to this magnitude on any grid (its default
#: range's), and further only as far as the outermost views stay within the grid (``max(R, C) / (N - 1)``): beyond,
#: a slope moves their light past the whole grid (and its Fourier slice's padding grows with it: -1000 .. 1000 asked
#: for 44 GiB).
DEFAULT_REACH = 3.0
#: The fewest views per axis a slope search, and the depth search (:data:`lf_flame.tomo.depth.MIN_VIEWS`), takes:
#: fewer hold no parallax to tell depths apart (one view none, two the focus curves of a single shift; every flame of
#: a new user's 2-view camera came back at the searched range's end).
MIN_SEARCH_VIEWS = 3
#: A region whose sharpness varies by less than this share of its largest over the slopes searched has no focus to
#: find (:func:`find_sharpest_slope`): light that no slope moves (a hot pixel in the centre view: 0.24 % with the
#: Fourier slice's round-off, 0 by shift-and-sum, where its peak had fallen at the grid's end, slope +3.0025 or -3.0).
#: The paper's shapes (4 rays per pixel) and a small camera's flames vary by 98-99.9 %, views of noise by 89-93 %.
FLAT_SPREAD = 0.01
#: A region where one view holds more than this share of the light of the views searched has no parallax to measure
#: (:func:`find_sharpest_slope`): a hot pixel or a reflection that one view sees, which had a sharpest slope wherever
#: its interpolation happened to be sharpest (-3.0 or +2.95 for a pixel of an outer view). Lit views each hold about
#: one share in as many as there are (1/69 of a circular aperture of 9 x 9 views).
ONE_VIEW_SHARE = 0.5


def find_sharpest_slope(views: np.ndarray, roi, *, metric: str = "tenengrad", method: str = "fourier",
                        lo: float = -3.0, hi: float = 3.0, coarse_step: float = 0.05, fine_step: float = 0.005,
                        mask=None) -> SlopeSearch:
    """Slope at which the region ``roi`` is sharpest: coarse grid, then a finer grid.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    roi : (row0, row1, col0, col1)
        Region of interest in lenslets (half-open).
    metric : {'laplacian', 'tenengrad', 'normvar'}
    method : {'fourier', 'shift-sum'}
        Refocusing used to score each slope. ``fourier`` (default) interpolates the
        views band-limited, so every slope is equally sharp but for focus. Bilinear
        ``shift-sum`` blurs a view by an amount that depends on the fraction of its
        shift, so the metrics favour slopes whose shifts are whole lenslets: at -15 mm
        it picks -2.00 for an analytic -1.90 (``results/slopes_depths.csv``).
        ``fourier`` works on the ROI with a margin of the largest shift, so its cost
        does not grow with the image.
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
        Unknown metric or method, fewer than :data:`MIN_SEARCH_VIEWS` views per axis, an empty ROI or one
        outside the views' grid, a bad grid (or one reaching
        past ``max(R, C) / (N - 1)``, where the outermost views shift past the whole grid, and past the default's
        :data:`DEFAULT_REACH`), NaN/inf in the
        views, a region as sharp at every slope (no light or no structure, or light that no slope moves:
        :data:`FLAT_SHARPNESS`, :data:`FLAT_SPREAD`), or one whose light one view holds (:data:`ONE_VIEW_SHARE`):
        no focus to find.
    """
    if metric not in SHARPNESS:
        raise ValueError(f"metric must be one of {sorted(SHARPNESS)}. Received: metric={metric!r}")
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}. Received: {method!r}")
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo and coarse_step > 0 and fine_step > 0):
        raise ValueError(f"a slope grid needs finite ends lo < hi and steps > 0 (lenslets per view step). Received "
                         f"lo={lo}, hi={hi}, coarse_step={coarse_step}, fine_step={fine_step}")
    r0, r1, c0, c1 = (int(v) for v in roi)
    if r1 - r0 < 3 or c1 - c0 < 3:
        raise ValueError(f"region of interest {roi} is smaller than 3x3 lenslets")
    fn = SHARPNESS[metric]
    views = np.asarray(views)
    _check_finite("views", views)
    n, _, R, C = views.shape
    if n < MIN_SEARCH_VIEWS:
        raise ValueError(f"a slope search needs at least {MIN_SEARCH_VIEWS} views per axis; the light field has {n} x "
                         f"{n}, too few for a focus to stand out of (give the planes as slopes: refocus --slope)")
    limit = max(max(R, C) / max(n - 1, 1), DEFAULT_REACH)
    if max(abs(lo), abs(hi)) > limit:
        raise ValueError(f"slopes {lo:+g} .. {hi:+g} reach past +-{limit:.3g} lenslets per view step, where the "
                         f"outermost views shift past the whole grid ({R} x {C} lenslets, {n} views): search within it")
    if not (0 <= r0 and r1 <= R and 0 <= c0 and c1 <= C):
        raise ValueError(f"region of interest {tuple(roi)} lies outside the views' grid of {R} x {C} lenslets")
    light = np.abs(views[:, :, r0:r1, c0:c1]).sum(axis=(2, 3), dtype=np.float64)
    if mask is not None:
        light = np.where(np.asarray(mask, bool), light, 0.0)
    if light.sum() > 0 and light.max() > ONE_VIEW_SHARE * light.sum():
        u, v = np.unravel_index(int(np.argmax(light)), light.shape)
        raise ValueError(f"the light of the region {tuple(roi)} comes from one view, ({u}, {v}), alone "
                         f"({100 * light.max() / light.sum():.0f} % of it): a hot pixel or a reflection that one view "
                         "sees has no parallax, no focus to find (repair the pixel, or search another region: --roi)")
    max_slope = max(abs(lo), abs(hi)) + coarse_step
    if method == "fourier":
        pad = _margin(max_slope, n)
        a0, b0 = max(0, r0 - pad), max(0, c0 - pad)
        fourier = FourierSlice(views[:, :, a0:min(R, r1 + pad), b0:min(C, c1 + pad)], max_slope, mask)
        r0, r1, c0, c1 = r0 - a0, r1 - a0, c0 - b0, c1 - b0

    def scores(slopes):
        if method == "fourier":
            stack = fourier.stack(slopes)
        else:
            stack = focal_stack(views, slopes, mask, check_finite=False)
        return np.array([fn(im) for im in stack[:, r0:r1, c0:c1]])

    coarse = np.arange(lo, hi + coarse_step / 2, coarse_step)
    coarse[-1] = min(coarse[-1], hi)          # its last step had passed hi by up to half a step (3.0375 for 3)
    sc = scores(coarse)
    # the metrics go as the light's square (normvar: as the light): a constant image's are round-off, 1e-7 of that
    level = float(np.mean(np.abs(views[..., roi[0]:roi[1], roi[2]:roi[3]]), dtype=np.float64))   # float32 overflows
    if not (np.all(np.isfinite(sc)) and sc.max() > FLAT_SHARPNESS * (level if metric == "normvar" else level ** 2)):
        raise ValueError(f"the region {tuple(roi)} is as sharp at every slope (no light, or no structure in it): "
                         "it has no focus to find")
    if sc.max() - sc.min() <= FLAT_SPREAD * sc.max():
        raise ValueError(f"the region {tuple(roi)} is as sharp at every slope (its sharpness varies by "
                         f"{100 * (sc.max() - sc.min()) / sc.max():.2g} % from {lo:+.4g} to {hi:+.4g}): no slope moves "
                         "its light (a hot pixel of the centre view, or light the views all see alike), so it has no "
                         "focus to find (repair the pixel, or search another region: --roi)")
    best = coarse[int(np.argmax(sc))]
    fine = np.arange(best - coarse_step, best + coarse_step + fine_step / 2, fine_step)
    fine = fine[(fine >= lo - fine_step / 2) & (fine <= hi + fine_step / 2)]      # the grid asked for, not beyond
    fine = np.clip(fine, lo, hi)                                                  # nor half a fine step past it
    sf = scores(fine)
    slopes = np.concatenate([coarse, fine])
    allsc = np.concatenate([sc, sf])
    order = np.argsort(slopes, kind="stable")
    return SlopeSearch(float(fine[int(np.argmax(sf))]), slopes[order], allsc[order])
