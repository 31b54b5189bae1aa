"""The depth search's focus curves (:mod:`lf_flame.tomo.depth`, :mod:`lf_flame.tomo.peel`): the views refocused
band-limited over a slope grid and each lenslet's focus energy there (Tenengrad, Laplacian; the Numba kernels of
:mod:`lf_flame.tomo._focus_kernels`), the grid's depths, and a curve's peaks, their sub-step positions and widths.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import PlenopticCamera
from ..refocus.shift_and_sum import FourierSlice, aperture_mask


def _grid_depths(camera: PlenopticCamera, slopes) -> np.ndarray:
    """Each slope's depth (mm), NaN for a slope the camera does not focus at (beyond infinity, or
    nearer than its main lens's focal length): the search grid runs a step past its range's ends."""
    out = np.full(len(slopes), np.nan)
    for k, s in enumerate(slopes):
        try:
            out[k] = camera.depth_for_slope(float(s))
        except ValueError:
            pass
    return out


def _peak_fit(curve, i):
    """Sub-step position (in grid steps) of the maximum near index ``i``: parabola through
    the log of the curve at ``i - 1, i, i + 1`` (a Gaussian peak); ``i`` at the grid's ends."""
    if i <= 0 or i >= len(curve) - 1:
        return float(i)
    y = np.log(np.maximum(curve[i - 1:i + 2], 1e-300))
    den = y[0] - 2 * y[1] + y[2]
    if not den < 0:
        return float(i)
    return float(i + np.clip(0.5 * (y[0] - y[2]) / den, -0.5, 0.5))


def find_peaks(x, distance: float, height: float) -> np.ndarray:
    """The peaks of a curve at least ``height`` high, the highest kept first where two lie within ``distance``.

    ``scipy.signal.find_peaks(x, distance=distance, height=height)[0]``, by SciPy's own steps
    (``scipy/signal/_peak_finding_utils.pyx``): every strict local maximum, a plateau at its
    middle (the left one of two), none at the ends; those at least ``height`` high; then,
    from the highest down (``np.argsort``'s order), each kept peak removes every other
    within ``ceil(distance)`` samples. Written here because importing ``scipy.signal``
    (SciPy 1.17 parses its functions' docstrings on import, and it imports ``scipy.stats``)
    cost every depth search 0.4-0.7 s on this project's machine, more than the search;
    ``tests/test_depth.py`` pins it to SciPy's on random curves with ties and plateaus.

    Parameters
    ----------
    x : ndarray of shape (n,)
    distance : float
        The least distance (samples, >= 1) between two peaks.
    height : float
        The least height of a peak.

    Returns
    -------
    ndarray of int of shape (k,)
        The peaks' indices, ascending.
    """
    x = np.asarray(x, np.float64)
    found, i, n = [], 1, len(x)
    while i < n - 1:
        if x[i - 1] < x[i]:
            ahead = i + 1
            while ahead < n - 1 and x[ahead] == x[i]:
                ahead += 1
            if x[ahead] < x[i]:
                found.append((i + ahead - 1) // 2)
                i = ahead
        i += 1
    peaks = np.asarray(found, np.intp)
    peaks = peaks[x[peaks] >= height]
    keep, reach = np.ones(len(peaks), bool), math.ceil(distance)
    for j in np.argsort(x[peaks])[::-1]:
        if keep[j]:
            gone = np.abs(peaks - peaks[j]) < reach
            gone[j] = False
            keep &= ~gone
    return peaks[keep]


def _local_max(curve, i, reach):
    """Index of the curve's largest value within ``reach`` steps of ``i``."""
    a, b = max(0, i - reach), min(len(curve), i + reach + 1)
    return a + int(np.argmax(curve[a:b]))


def _half_width(curve, i):
    """Half width at half maximum (grid steps) of the peak at ``i`` (above the curve's minimum)."""
    base = float(curve.min())
    half = base + 0.5 * (float(curve[i]) - base)
    lo = i
    while lo > 0 and curve[lo] > half:
        lo -= 1
    hi = i
    while hi < len(curve) - 1 and curve[hi] > half:
        hi += 1
    return 0.5 * (hi - lo)


def _focus_energy(views, slopes, sigma, laplacian=False, mask=None):
    """The views refocused band-limited at ``slopes`` (:class:`FourierSlice`, over ``mask``'s views; None: the
    inscribed circle's); per slope and lenslet the Tenengrad energy (squared Sobel gradient), and with ``laplacian``
    the squared Laplacian, each smoothed over ``sigma`` lenslets: (S, R, C) float64 arrays."""
    from ._focus_kernels import focus_measures
    if mask is None:
        mask = aperture_mask(views.shape[0], "circular")
    stack = FourierSlice(views, float(np.max(np.abs(slopes))) + 1e-9, mask).stack(slopes).astype(np.float64)
    ten = np.empty_like(stack)
    lap = np.empty_like(stack) if laplacian else np.empty((0, 0, 0))
    focus_measures(stack, _gaussian_taps(sigma), bool(laplacian), ten, lap)
    return (ten, lap) if laplacian else ten


def _gaussian_taps(sigma: float, truncate: float = 4.0) -> np.ndarray:
    """The taps of ``scipy.ndimage.gaussian_filter(x, sigma, truncate=truncate)`` along one axis (``sigma`` > 0,
    lenslets), as it builds them: ``2 r + 1`` of them, ``r = int(truncate sigma + 1/2)``, summing to 1 (float64;
    one tap of 1 where ``r`` is 0, as SciPy's for such a ``sigma``)."""
    r = int(truncate * float(sigma) + 0.5)
    if r == 0:
        return np.ones(1)
    x = np.arange(-r, r + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x ** 2)
    return (phi / phi.sum())[::-1].copy()
