"""Image-quality metrics per depth plane (paper Sec. III-D), from scikit-image, and a render's own error.

Images are in [0, 1], so ``data_range = 1`` (the paper's MAX_I of Eq. 7).
"""
from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity


def _checked_pair(first, second, names=("reference", "prediction"), what="images"):
    """Two arrays of one shape, finite, as float64; ValueError naming ``names`` and ``what`` otherwise."""
    a = np.asarray(first, np.float64)
    b = np.asarray(second, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"{names[0]} {a.shape} and {names[1]} {b.shape} differ in shape")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError(f"{what} contain NaN or inf")
    return a, b


def _per_plane(metric, ref, pred) -> np.ndarray:
    """Apply ``metric(ref_plane, pred_plane)`` to each plane after checking the inputs: stacks (P, rows, cols) of
    floats (one 2-D image had been scored row by row; a uint8 image against the data range 1, -9.5 dB for two
    near-identical ones)."""
    for name, x in (("reference", ref), ("prediction", pred)):
        x = np.asarray(x)
        if x.ndim != 3:
            raise ValueError(f"{name} must be a stack of planes (P, rows, cols); one image is x[None]. Received "
                             f"shape {x.shape}")
        if np.issubdtype(x.dtype, np.integer):
            raise ValueError(f"{name} holds integers ({x.dtype}): scale the planes to [0, 1] (the metrics' data range)")
    ref, pred = _checked_pair(ref, pred)
    return np.array([metric(r, p) for r, p in zip(ref, pred)])


def ssim_per_plane(ref, pred) -> np.ndarray:
    """SSIM (Wang et al. 2004, skimage defaults, 7×7 window) of each plane.

    Parameters
    ----------
    ref, pred : ndarray of shape (P, rows, cols), values in [0, 1]

    Returns
    -------
    ndarray of shape (P,)

    Raises
    ------
    ValueError
        Stacks of other shapes than (P, rows, cols) or unlike each other, integer images, NaN or inf.
    """
    return _per_plane(lambda r, p: structural_similarity(r, p, data_range=1.0), ref, pred)


def psnr_per_plane(ref, pred) -> np.ndarray:
    """PSNR in dB (paper Eq. 7, MAX = 1) of each plane; ``inf`` for identical planes.

    Parameters
    ----------
    ref, pred : ndarray of shape (P, rows, cols), values in [0, 1]

    Returns
    -------
    ndarray of shape (P,)
    """
    return _per_plane(lambda r, p: np.inf if np.array_equal(r, p) else peak_signal_noise_ratio(r, p, data_range=1.0),
                      ref, pred)


def mean_ssim(ref, pred) -> float:
    """Mean SSIM over a stack of images: the validation score of one plane.

    Parameters
    ----------
    ref, pred : ndarray of shape (n, rows, cols), values in [0, 1]
    """
    return float(np.mean(ssim_per_plane(ref, pred)))


def own_error(first, second) -> float:
    """A Monte-Carlo render's own error, from two renders of one scene with independent rays.

    Each render is the exact image plus an independent error of the same size, so their difference
    holds both: ``||first - second|| / (sqrt(2) ||first||)`` estimates one render's error relative to
    its image (the ray noise that the project's tables state beside every scored render).

    Parameters
    ----------
    first, second : ndarray of the same shape
        The two renders (any axes: raw images, views, channels).

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Shapes that differ, values not finite, or a first render without light.
    """
    a, b = _checked_pair(first, second, ("first render", "second render"), "renders")
    norm = np.linalg.norm(a)
    if norm == 0:
        raise ValueError("the first render holds no light")
    return float(np.linalg.norm(a - b) / (np.sqrt(2) * norm))
