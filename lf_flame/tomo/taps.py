"""The exact operator applied by its taps: direct sums over each view's small kernel, split where it separates.

A view's kernel on a plane (:mod:`lf_flame.tomo.quadrature`) is the overlap of its pixel's footprint with the
plane's samples along rows times the same along columns, unless the aperture's circle clips the view: away from the
aperture's rim it is the outer product of a row filter (the view's, its row of views') and a column filter shared by
its whole column of views. There the map is applied in two passes, each plane filtered along its rows once per
column of views and then along its columns once per view, instead of the whole kernel per view; the clipped views
keep their whole kernels. Both passes are circular correlations on the canvas, as the spectra apply them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from . import _exact_kernels

#: A view's kernels count as separable where the outer product of their row sums and their column's filter is within
#: this share of their largest tap, per precision. The unclipped views' kernels separate but for their cos^4 across
#: the taps (about 1e-5 of the largest tap), the clipped ones' not to 1e-4. In float32, 1e-5: on the paper camera's
#: operators (lenslet and 2 x 2 grid, planes at +-2 to +-10 mm; a ``/tmp`` probe) 137-145 of 201 views separate and
#: the taps apply the map within 1.3-2.4e-6 of float64's largest view sample, closer than the float32 spectra's FFT
#: route (6-11e-6). In float64 (A^T the transpose of A to float64 rounding) only what separates to its rounding.
SEPARABLE_TOLERANCE = {"float32": 1e-5, "float64": 1e-13}


@dataclass(frozen=True)
class TapPlan:
    """The lit views' taps as :func:`separable_taps` splits them (every array contiguous, in one precision)."""
    #: Views whose kernels do not separate: their taps (V_d, P, Ty, Tx), origins (V_d, P) and rows among the views.
    h: np.ndarray
    oy: np.ndarray
    ox: np.ndarray
    rows: np.ndarray
    #: Views whose kernels separate, sorted by column of views: row filters (V_s, P, Ty), their origins (V_s, P), rows
    #: among the views (V_s,), where each column's views start among them (C + 1,) and each view's first plane among
    #: the column-filtered planes (V_s,), ``c P`` for column ``c``.
    a: np.ndarray
    oy_s: np.ndarray
    rows_s: np.ndarray
    start: np.ndarray
    first: np.ndarray
    #: The column filters as lists (weights, source, column shift), each ending at its first zero weight: per column
    #: and plane (C P, K) for ``H``, per plane (P, K') for ``H^H``.
    forward_columns: tuple
    adjoint_columns: tuple
    n_views: int
    n_planes: int
    per_view: float

    def forward(self, x: np.ndarray) -> np.ndarray:
        """``H`` on the canvas: the phase planes ``x`` (P, Lr, Lc) to the lit views (V', Lr, Lc)."""
        out = np.empty((self.n_views,) + x.shape[1:], x.dtype)
        if len(self.rows_s):
            filtered = np.empty(((len(self.start) - 1) * self.n_planes,) + x.shape[1:], x.dtype)
            _exact_kernels.column_sums(*self.forward_columns, x, filtered, False)
            _exact_kernels.taps_forward(np.ascontiguousarray(self.a[..., None]), self.oy_s, np.zeros_like(self.oy_s),
                                        filtered, self.first, out, self.rows_s)
        if len(self.rows):
            _exact_kernels.taps_forward(self.h, self.oy, self.ox, x, np.zeros_like(self.rows), out, self.rows)
        return out

    def adjoint(self, z: np.ndarray) -> np.ndarray:
        """``H^H`` on the canvas: the lit views ``z`` (V', Lr, Lc) to the phase planes (P, Lr, Lc)."""
        P, (Lr, Lc) = self.n_planes, z.shape[1:]
        out = np.zeros((P, Lr, Lc), z.dtype)
        if len(self.rows):
            _exact_kernels.taps_adjoint(self.h, self.oy, self.ox, z, self.rows, out, numba.get_num_threads())
        if len(self.rows_s):
            filtered = np.empty(((len(self.start) - 1) * P, -(-Lr // 4) * 4, Lc), z.dtype)
            _exact_kernels.taps_adjoint_columns(self.a, self.oy_s, z, self.rows_s, self.start, filtered)
            _exact_kernels.column_sums(*self.adjoint_columns, filtered, out, True)
        return out


def _lists(entries, dtype) -> tuple:
    """Lists of (weight, source, shift) as arrays (M, K), each padded with zero weights."""
    K = max([len(e) for e in entries] + [1])
    w = np.zeros((len(entries), K), dtype)
    idx, shift = np.zeros((len(entries), K), np.int64), np.zeros((len(entries), K), np.int64)
    for m, e in enumerate(entries):
        if e:
            w[m, :len(e)], idx[m, :len(e)], shift[m, :len(e)] = np.asarray(e).T
    return w, idx, shift


def separable_taps(h, origin_y, origin_x, view_column, dtype, tolerance: float) -> TapPlan:
    """Split the lit views' taps into those that separate into a row filter and their column's filter, and the rest.

    Parameters
    ----------
    h : ndarray of shape (V, P, Ty, Tx)
        Each lit view's taps on each phase plane (tap ``(m, n)`` reads the plane ``m`` rows and ``n`` columns from the
        view's origin).
    origin_y, origin_x : ndarray of shape (V, P), int
        The taps' origins along rows and columns; ``origin_x`` is the same for the views of one column.
    view_column : ndarray of shape (V,), int
        Each view's column in the grid of views.
    dtype : numpy dtype
        The operator's real precision.
    tolerance : float
        A view separates where, on every plane, the outer product of its taps' row sums with its column's filter
        is within ``tolerance`` of its largest tap (:data:`SEPARABLE_TOLERANCE`). A column's filter is the column sums,
        normalised, of its view nearest the middle of the column (the aperture's centre, no clipping).

    Returns
    -------
    TapPlan
        With rows of taps padded to a multiple of four, and :attr:`TapPlan.per_view` the taps summed per view.
    """
    h = np.asarray(h, np.float64)
    V, P, ty, Tx = h.shape
    Ty = -(-ty // 4) * 4
    origin_y, origin_x = np.asarray(origin_y, np.int64), np.asarray(origin_x, np.int64)
    columns, column = np.unique(np.asarray(view_column), return_inverse=True)
    rows_sum = h.sum(axis=3)                                                  # (V, P, ty)
    total = rows_sum.sum(axis=2)
    filters = np.zeros((len(columns), P, Tx))
    separable = np.zeros(V, bool)
    for c in range(len(columns)):
        views = np.flatnonzero(column == c)
        ref = views[len(views) // 2]
        filters[c] = h[ref].sum(axis=1) / np.where(total[ref] > 0, total[ref], 1)[:, None]
        err = np.abs(rows_sum[views, :, :, None] * filters[c][None, :, None, :] - h[views]).max(axis=(2, 3))
        separable[views] = (err <= tolerance * np.abs(h[views]).max(axis=(2, 3))).all(axis=1)
    direct = np.flatnonzero(~separable)
    sep = np.flatnonzero(separable)
    sep = sep[np.argsort(column[sep], kind="stable")]
    taps = np.zeros((len(direct), P, Ty, Tx), dtype)
    taps[:, :, :ty] = h[direct]
    a = np.zeros((len(sep), P, Ty), dtype)
    a[:, :, :ty] = rows_sum[sep]
    used = np.unique(column[sep])                                             # columns with separable views
    start = np.searchsorted(column[sep], np.arange(len(columns) + 1)).astype(np.int64)
    ox = {c: origin_x[np.flatnonzero(column == c)[0]] for c in used}
    fwd = [[(filters[c, p, t], p, ox[c][p] + t) for t in range(Tx) if filters[c, p, t] != 0] if c in ox else []
           for c in range(len(columns)) for p in range(P)]
    adj = [[(filters[c, p, t], c * P + p, -(ox[c][p] + t)) for c in used for t in range(Tx) if filters[c, p, t] != 0]
           for p in range(P)]
    groups = (taps.reshape(len(direct), P, Ty // 4, 4, Tx) != 0).any(axis=3).sum()
    groups += (a.reshape(len(sep), P, Ty // 4, 4) != 0).any(axis=3).sum()
    per_view = float(groups * 4 + sum(len(e) for e in fwd)) / max(V, 1)
    return TapPlan(h=taps, oy=np.ascontiguousarray(origin_y[direct]), ox=np.ascontiguousarray(origin_x[direct]),
                   rows=direct.astype(np.int64), a=a, oy_s=np.ascontiguousarray(origin_y[sep]),
                   rows_s=sep.astype(np.int64), start=start, first=(column[sep] * P).astype(np.int64),
                   forward_columns=_lists(fwd, dtype), adjoint_columns=_lists(adj, dtype), n_views=V, n_planes=P,
                   per_view=per_view)
