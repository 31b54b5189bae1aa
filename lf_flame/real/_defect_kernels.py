"""Numba kernel of :mod:`lf_flame.real.defects`: each pixel against its neighbours in its lenslet image and in the
lenslets around. Arrays and scalars only; :func:`lf_flame.real.defects.defective_pixels` validates its inputs."""
import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def outlier_pixels(img, offsets, margin, spread, flagged, repaired):
    """Flag and repair the pixels that stand out of all but two of their neighbours.

    ``img`` (H, W) float64; ``offsets`` (K, 2) int64: the neighbours' (row, column) offsets. A pixel is flagged
    where it stands above the third highest of its neighbours inside the image (or below the third lowest) by
    more than ``margin`` (image units) plus ``spread`` times the neighbours' own spread (the third highest less
    the third lowest: noise and texture). Writes ``flagged`` (H, W) bool and ``repaired`` (H, W) float64: the image with
    each flagged pixel replaced by the median of its neighbours. A pixel with fewer than 4 neighbours inside the
    image is left as it is.
    """
    H, W = img.shape
    K = offsets.shape[0]
    for r in prange(H):
        vals = np.empty(K)
        for c in range(W):
            x = img[r, c]
            repaired[r, c] = x
            flagged[r, c] = False
            # a defect stands out of all but two neighbours by the margin at least: most pixels are ruled out
            # after a few neighbours (three within the margin above it and three below)
            n_up = n_down = 0
            for k in range(K):
                rr = r + offsets[k, 0]
                cc = c + offsets[k, 1]
                if 0 <= rr < H and 0 <= cc < W:
                    v = img[rr, cc]
                    n_up += v >= x - margin
                    n_down += v <= x + margin
                    if n_up >= 3 and n_down >= 3:
                        break
            if n_up >= 3 and n_down >= 3:
                continue
            n = 0
            for k in range(K):
                rr = r + offsets[k, 0]
                cc = c + offsets[k, 1]
                if 0 <= rr < H and 0 <= cc < W:
                    vals[n] = img[rr, cc]
                    n += 1
            if n < 4:
                continue
            hi1 = hi2 = hi3 = -np.inf
            lo1 = lo2 = lo3 = np.inf
            for k in range(n):
                v = vals[k]
                if v > hi1:
                    hi1, hi2, hi3 = v, hi1, hi2
                elif v > hi2:
                    hi2, hi3 = v, hi2
                elif v > hi3:
                    hi3 = v
                if v < lo1:
                    lo1, lo2, lo3 = v, lo1, lo2
                elif v < lo2:
                    lo2, lo3 = v, lo2
                elif v < lo3:
                    lo3 = v
            tol = margin + spread * (hi3 - lo3)
            if x - hi3 > tol or lo3 - x > tol:
                flagged[r, c] = True
                repaired[r, c] = np.median(vals[:n])
