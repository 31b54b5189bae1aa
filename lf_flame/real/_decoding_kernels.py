"""Numba kernel of :mod:`lf_flame.real.decoding`: bilinear samples of images at sensor positions, the decoders'
resampling of every lenslet image. Arrays only; :func:`lf_flame.real.decoding.decode` validates its inputs."""
import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def bilinear(images, positions, out):
    """Write ``out[k, m]``: image ``k`` of ``images`` (K, H, W) sampled bilinearly at ``positions[m]`` (M, 2: row,
    column; px, pixel (i, j) centred at (i + ½, j + ½)), 0 where the position lies beyond the first or last pixel
    centre of either axis: ``scipy.ndimage.map_coordinates(image, positions.T - 0.5, order=1, mode="constant",
    cval=0)`` for each image, with the weights computed once per position for all K images."""
    K, H, W = images.shape
    for m in prange(positions.shape[0]):
        r, c = positions[m, 0] - 0.5, positions[m, 1] - 0.5
        if not (0.0 <= r <= H - 1 and 0.0 <= c <= W - 1):
            for k in range(K):
                out[k, m] = 0.0
            continue
        r0, c0 = int(np.floor(r)), int(np.floor(c))
        fr, fc = r - r0, c - c0
        r1, c1 = min(r0 + 1, H - 1), min(c0 + 1, W - 1)
        for k in range(K):
            top = (1.0 - fc) * images[k, r0, c0] + fc * images[k, r0, c1]
            bottom = (1.0 - fc) * images[k, r1, c0] + fc * images[k, r1, c1]
            out[k, m] = (1.0 - fr) * top + fr * bottom
