"""Numba kernel of :mod:`lf_flame.real.defects`: each pixel against its neighbours in its lenslet image and in the
lenslets around. Arrays and scalars only; :func:`lf_flame.real.defects.defective_pixels` validates its inputs."""
import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def outlier_pixels(img, offsets, n_near, margin, spread, flagged, repaired):
    """Flag and repair the pixels that stand out of their neighbours: of every neighbour in the lenslets around,
    and of all but one in their own lenslet image (two defects side by side there hide each other otherwise).

    ``img`` (H, W) float32 or float64; ``offsets`` (K, 2) int64: the neighbours' (row, column) offsets, the first
    ``n_near`` in the pixel's lenslet image, the others under the lenslets around. A pixel is flagged where it
    stands above the larger of those two references (or below the smaller of the lowest) by more than ``margin``
    (image units) plus ``spread`` times the neighbours' own spread (their third highest less their third lowest:
    noise and texture). Writes ``flagged`` (H, W) bool and ``repaired`` (H, W, the image's dtype): the image with
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
            # a defect stands out of all its neighbours but one by the margin at least: most pixels are ruled out
            # after a few neighbours (two within the margin above it and two below)
            n_up = n_down = 0
            for k in range(K):
                rr = r + offsets[k, 0]
                cc = c + offsets[k, 1]
                if 0 <= rr < H and 0 <= cc < W:
                    v = img[rr, cc]
                    n_up += v >= x - margin
                    n_down += v <= x + margin
                    if n_up >= 2 and n_down >= 2:
                        break
            if n_up >= 2 and n_down >= 2:
                continue
            n = 0
            a_hi1 = a_hi2 = s_hi = -np.inf
            a_lo1 = a_lo2 = s_lo = np.inf
            for k in range(K):
                rr = r + offsets[k, 0]
                cc = c + offsets[k, 1]
                if 0 <= rr < H and 0 <= cc < W:
                    v = img[rr, cc]
                    vals[n] = v
                    n += 1
                    if k < n_near:
                        if v > a_hi1:
                            a_hi1, a_hi2 = v, a_hi1
                        elif v > a_hi2:
                            a_hi2 = v
                        if v < a_lo1:
                            a_lo1, a_lo2 = v, a_lo1
                        elif v < a_lo2:
                            a_lo2 = v
                    else:
                        s_hi = max(s_hi, v)
                        s_lo = min(s_lo, v)
            if n < 4:
                continue
            srt = np.sort(vals[:n])
            tol = margin + spread * (srt[n - 3] - srt[2])
            if x - max(a_hi2, s_hi) > tol or min(a_lo2, s_lo) - x > tol:
                flagged[r, c] = True
                repaired[r, c] = np.median(vals[:n])
