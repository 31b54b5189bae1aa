"""Image-quality metrics per depth plane (paper Sec. III-D), from scikit-image.

Images are in [0, 1], so ``data_range = 1`` (the paper's MAX_I of Eq. 7).
"""
from __future__ import annotations

import numpy as np
from skimage.metrics import peak_signal_noise_ratio, structural_similarity


def _per_plane(metric, ref, pred) -> np.ndarray:
    """Apply ``metric(ref_plane, pred_plane)`` to each plane after checking the inputs."""
    ref = np.asarray(ref, np.float64)
    pred = np.asarray(pred, np.float64)
    if ref.shape != pred.shape:
        raise ValueError(f"reference {ref.shape} and prediction {pred.shape} differ in shape")
    if not (np.all(np.isfinite(ref)) and np.all(np.isfinite(pred))):
        raise ValueError("images contain NaN or inf")
    return np.array([metric(r, p) for r, p in zip(ref, pred)])


def ssim_per_plane(ref, pred) -> np.ndarray:
    """SSIM (Wang et al. 2004, skimage defaults, 7×7 window) of each plane.

    Parameters
    ----------
    ref, pred : ndarray of shape (P, rows, cols), values in [0, 1]

    Returns
    -------
    ndarray of shape (P,)
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
