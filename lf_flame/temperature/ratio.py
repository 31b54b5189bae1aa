"""Filters of two colour channels' ratio per plane, before it becomes temperature.

Two channels' emission reconstructed per plane (:mod:`lf_flame.temperature.channels`) carry noise and
sampling artefacts that do not cancel in their ratio, and two-colour pyrometry turns a 1 % error
in the ratio into about 12 K. These filters smooth the ratio, not the emission, so that the
temperature keeps the flame's structure:

- :func:`smooth_planes`: a Gaussian on each plane (``admm-cfa-smooth``'s, on both channels);
- :func:`guided_filter` and :func:`guided_ratio`: the log ratio smoothed by a guided filter
  with the log of the summed emission as its guide (He, Sun & Tang, TPAMI 2013);
- :func:`contour_ratio`: each channel averaged along the contours of the summed emission (their
  direction by :func:`contour_direction`, the structure tensor's orientation), the ratio that of the
  averages;
- :func:`filter_ratio`: the matched route's filter (``MATCHED_RATIO_FILTER``), the contours'
  average and then the guided filter.

Each returns the two channels as the smoothed sum split by the filtered ratio, so that which
pixels are bright enough for a temperature is decided on the sum.
"""
from __future__ import annotations

import numpy as np

from .pyrometry import MIN_FRACTION, bright_pixels

#: Gaussian (lenslets) of ``admm-cfa-smooth``.
SMOOTH_SIGMA = 0.7


def smooth_planes(planes: np.ndarray, sigma: float = SMOOTH_SIGMA) -> np.ndarray:
    """Each plane of (P, rows, cols) smoothed by a Gaussian of ``sigma`` samples (lenslets)."""
    from scipy.ndimage import gaussian_filter
    return np.stack([gaussian_filter(p, sigma) for p in planes])


def guided_filter(p: np.ndarray, guide: np.ndarray, mask: np.ndarray, radius: int, eps: float) -> np.ndarray:
    """Guided filter of an image over the pixels of a mask.

    He, Sun & Tang, "Guided image filtering", IEEE TPAMI 35 (2013) 1397, Algorithm 1: in
    each ``(2 radius + 1)``-square window the output is a linear function ``a I + b`` of the
    guide ``I``, fitted to ``p`` by least squares with ``a`` damped by ``eps``; the windows'
    ``a`` and ``b`` are averaged. Every window mean is taken over the mask's pixels only
    (normalised convolution, Knutsson & Westin 1993), so pixels outside it neither enter nor
    bias the fit.

    Parameters
    ----------
    p, guide : ndarray of shape (rows, cols)
        The image filtered and its guide (any units; ``eps`` is in the guide's units squared).
    mask : ndarray of shape (rows, cols), bool
    radius : int, pixels
    eps : float, > 0

    Returns
    -------
    ndarray of shape (rows, cols): filtered on the mask; ``p`` elsewhere.

    Raises
    ------
    ValueError
        Shapes that differ, a radius below 1 or ``eps`` not positive.
    """
    from scipy.ndimage import uniform_filter
    p, guide, m = np.asarray(p, float), np.asarray(guide, float), np.asarray(mask, bool)
    if not (p.shape == guide.shape == m.shape and p.ndim == 2):
        raise ValueError(f"image, guide and mask of one 2-D shape are needed. Received {p.shape}, {guide.shape}, "
                         f"{m.shape}")
    if int(radius) < 1 or not eps > 0:
        raise ValueError(f"radius >= 1 and eps > 0 are needed. Received radius {radius}, eps {eps}")
    w = m.astype(float)
    n = np.maximum(uniform_filter(w, 2 * int(radius) + 1, mode="constant"), 1e-12)

    def mean(x):
        return uniform_filter(np.where(m, x, 0.0), 2 * int(radius) + 1, mode="constant") / n

    i, q = np.where(m, guide, 0.0), np.where(m, p, 0.0)
    mi, mq = mean(i), mean(q)
    a = (mean(i * q) - mi * mq) / (mean(i * i) - mi ** 2 + eps)
    b = mq - a * mi
    return np.where(m, mean(a) * i + mean(b), p)


def _sum_and_share(a, b, guide_sigma, min_fraction):
    """(a, b, s, m, frac) of :func:`guided_ratio` and :func:`contour_ratio`: the channels as floats, their
    sum ``s`` smoothed by ``guide_sigma`` (clipped at 0), the pixels whose ratio is filtered ``m`` and
    ``a``'s share of the sum ``frac`` (0.5 where both are 0)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape or a.ndim != 3:
        raise ValueError(f"two (P, rows, cols) emission stacks are needed. Received {a.shape} and {b.shape}")
    s = np.maximum(smooth_planes(a + b, guide_sigma) if guide_sigma > 0 else a + b, 0.0)
    m = bright_pixels(s, min_fraction) & (a > 0) & (b > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(a + b > 0, np.clip(a / (a + b), 0.0, 1.0), 0.5)
    return a, b, s, m, frac


def _split(s, frac, a, b):
    """The smoothed sum ``s`` split by ``a``'s share ``frac`` into the two channels, both 0 where neither channel
    holds emission (``a + b <= 0``): the sum's smoothing spreads light there, but no ratio was measured (a share of
    0.5 would read ratio 1, one temperature of the calibration's, wherever the mask reaches such pixels)."""
    s = np.where(a + b > 0, s, 0.0)
    return s * frac, s * (1.0 - frac)


def contour_direction(plane: np.ndarray, orient_sigma: float = 1.0, tensor_sigma: float = 1.5):
    """The direction along the brightness contours at each pixel of one plane.

    The structure tensor's orientation (scikit-image ``structure_tensor``; Bigün & Granlund,
    ICCV 1987) of the log of ``plane`` (floored at 1e-6 of its peak) smoothed by a Gaussian of
    ``orient_sigma``, over a window of ``tensor_sigma``: the contour is perpendicular to the
    dominant gradient.

    Parameters
    ----------
    plane : ndarray of shape (rows, cols), non-negative with a positive peak
    orient_sigma, tensor_sigma : float, pixels

    Returns
    -------
    (dr, dc) : two ndarrays of shape (rows, cols): the unit vector along the contour (rows, cols).
    """
    from scipy.ndimage import gaussian_filter
    from skimage.feature import structure_tensor
    log_s = np.log(np.maximum(plane, 1e-6 * plane.max()))
    arr, arc, acc = structure_tensor(gaussian_filter(log_s, orient_sigma), sigma=tensor_sigma, order="rc")
    theta = 0.5 * np.arctan2(2 * arc, acc - arr)                     # the gradient's angle from the columns' axis
    return np.cos(theta), -np.sin(theta)


def contour_ratio(a: np.ndarray, b: np.ndarray, length: float, guide_sigma: float = 0.5,
                  min_fraction: float = MIN_FRACTION, support_fraction: float = MIN_FRACTION / 2,
                  orient_sigma: float = 1.0, tensor_sigma: float = 1.5):
    """Two channels' emission per plane with their ratio averaged along the brightness contours.

    A flame's temperature changes fast across its luminous sheath and slowly along it. Here
    each channel is averaged along the local contour of the summed emission (the line
    through the pixel perpendicular to the brightness gradient), by a Gaussian of ``length``
    lenslets sampled every half lenslet (bilinear, scipy ``map_coordinates``), and the ratio
    is that of the two averages: noise is averaged along the sheath without flattening the
    temperature's profile across it (a filter isotropic in space lowers the hot sheath). The
    direction is the structure tensor's (scikit-image ``structure_tensor``; Bigün & Granlund,
    ICCV 1987; the orientation of coherence-enhancing diffusion, Weickert, IJCV 31 (1999)) of
    the log of the smoothed sum. Averaging the channels rather than their log ratio keeps
    the ratio free of the bias a mean of logs of noisy values carries. Pixels whose smoothed
    sum is at least ``support_fraction`` of the plane's peak enter the averages; those at
    ``min_fraction`` or above get the averaged ratio. The channels returned are the smoothed
    sum split by the ratio, as :func:`guided_ratio` returns them.

    Parameters
    ----------
    a, b : ndarray of shape (P, rows, cols)
        The ratio's numerator and denominator channels' emission (lenslet grid).
    length : float, lenslets
        The Gaussian's standard deviation along the contour (> 0); samples reach two of them.
    guide_sigma : float, lenslets
        The Gaussian on the sum (0: none).
    min_fraction : float
        As :func:`lf_flame.temperature.pyrometry.temperature_planes`.
    support_fraction : float
        Below ``min_fraction``, so that a contour's samples near that threshold are not cut off
        (validation scenes 937500 and 937502 at 14 dB, a ``/tmp`` probe: the dim -10 mm plane's p90
        49 and 58 K against 54 and 63 K with the threshold itself).
    orient_sigma, tensor_sigma : float, lenslets
        The Gaussian on the log sum before its gradient, and the structure tensor's window.

    Returns
    -------
    (a, b) : two ndarrays of shape (P, rows, cols), with ``a / b`` the averaged ratio and
    ``a + b`` the smoothed sum (clipped at 0; 0 where neither channel holds emission).

    Raises
    ------
    ValueError
        Shapes that differ or are not 3-D, or a length that is not positive.
    """
    from scipy.ndimage import map_coordinates
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"a positive length along the contours (lenslets) is needed. Received {length!r}")
    a, b, s, _, frac = _sum_and_share(a, b, guide_sigma, min_fraction)
    m, out = bright_pixels(s, support_fraction), bright_pixels(s, min_fraction)
    rows, cols = np.mgrid[0:a.shape[1], 0:a.shape[2]].astype(float)
    n = int(np.ceil(4 * length))
    steps = np.arange(-n, n + 1) / 2.0                               # every half lenslet, to 2 lengths
    weights = np.exp(-0.5 * (steps / length) ** 2)
    for k in range(len(a)):
        if not m[k].any():
            continue
        dr, dc = contour_direction(s[k], orient_sigma, tensor_sigma)
        na, nb = np.zeros_like(s[k]), np.zeros_like(s[k])
        ak, bk = np.where(m[k], a[k], 0.0), np.where(m[k], b[k], 0.0)
        for t, w in zip(steps, weights):
            at = [rows + t * dr, cols + t * dc]
            na += w * map_coordinates(ak, at, order=1, mode="constant")
            nb += w * map_coordinates(bk, at, order=1, mode="constant")
        ok = out[k] & (na > 0) & (nb > 0)
        frac[k] = np.where(ok, na / np.where(ok, na + nb, 1.0), frac[k])
    return _split(s, frac, a, b)


def guided_ratio(a: np.ndarray, b: np.ndarray, radius: int, eps: float, guide_sigma: float = 0.5,
                 min_fraction: float = MIN_FRACTION):
    """Two channels' emission per plane with their ratio smoothed by a guided filter.

    The two channels are split into their summed emission ``s = a + b``, smoothed by a
    Gaussian of ``guide_sigma`` lenslets, and the ratio ``a / b``. The log ratio of each
    plane (where both channels are positive and ``s`` is at least ``min_fraction`` of the
    plane's peak ``s``) is filtered by :func:`guided_filter` with ``ln s``, relative to the
    plane's peak, as its guide: where temperature follows brightness (the hot, luminous
    sheath) the ratio keeps its edges, and it is averaged where it does not. Elsewhere the
    ratio is kept as it is. The channels returned are ``s`` split by the ratio, so that
    which pixels are bright enough for a temperature is decided on the smoothed sum, not on
    a noise peak (a noisy plane's peak raises its ``min_fraction`` threshold).

    Parameters
    ----------
    a, b : ndarray of shape (P, rows, cols)
        The ratio's numerator and denominator channels' emission (lenslet grid).
    radius : int, lenslets
    eps : float
        Regularisation, in the guide's units (log emission) squared.
    guide_sigma : float, lenslets
        0: the sum is not smoothed (``a + b`` is returned unchanged).
    min_fraction : float
        As :func:`lf_flame.temperature.pyrometry.temperature_planes`.

    Returns
    -------
    (a, b) : two ndarrays of shape (P, rows, cols), with ``a / b`` the filtered ratio and
    ``a + b`` the smoothed sum (clipped at 0; 0 where neither channel holds emission).

    Raises
    ------
    ValueError
        Shapes that differ or are not 3-D, and the errors of :func:`guided_filter`.
    """
    a, b, s, m, frac = _sum_and_share(a, b, guide_sigma, min_fraction)
    with np.errstate(divide="ignore"):
        guide = np.log(s)
    for k in range(len(a)):
        if not m[k].any():
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            lr = np.where(m[k], np.log(a[k] / b[k]), 0.0)
        g = np.where(m[k], guide[k] - guide[k][m[k]].max(), 0.0)
        frac[k] = np.where(m[k], 1.0 / (1.0 + np.exp(-guided_filter(lr, g, m[k], radius, eps))), frac[k])
    return _split(s, frac, a, b)


def filter_ratio(a: np.ndarray, b: np.ndarray, radius: int, eps: float, contour: float = 0.0):
    """The matched route's ratio filter (:data:`MATCHED_RATIO_FILTER`): :func:`contour_ratio` along ``contour``
    lenslets (when > 0), then :func:`guided_ratio` of ``radius`` and ``eps`` (each smooths the sum by its
    0.5-lenslet Gaussian). Shapes, units and errors as theirs."""
    if contour:
        a, b = contour_ratio(a, b, contour)
    return guided_ratio(a, b, radius, eps)
