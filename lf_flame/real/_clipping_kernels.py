"""Numba kernel of :mod:`lf_flame.real.clipping`: an image's two largest values and how many pixels hold each, in
one pass (:func:`lf_flame.real.clipping.clipping_pile`, once per frame of a recording). Arrays only; the caller
gives a flat array."""
import numpy as np
from numba import njit


@njit(cache=True)
def top_two(a):
    """``(top, n_top, second, n_second)`` of the flat array ``a`` (any real type; NaN skipped): its largest value
    and the count of elements equal to it, the largest value below it and its count (``-inf``, 0 where none)."""
    top, n_top, second, n_second = -np.inf, 0, -np.inf, 0
    for i in range(a.size):
        v = np.float64(a[i])
        if v >= second:
            if v > top:
                second, n_second = top, n_top
                top, n_top = v, 1
            elif v == top:
                n_top += 1
            elif v > second:
                second, n_second = v, 1
            else:
                n_second += 1
    return top, n_top, second, n_second
