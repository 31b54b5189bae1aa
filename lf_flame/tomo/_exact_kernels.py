"""Numba kernels of :mod:`lf_flame.tomo.exact`: the exact operator's kernels by quadrature, and the map applied by
its taps.

Deterministic quadrature of the tracer's ray chain over a pixel (``du``: closed-form area
and centroid of a rectangle on the main lens inside the aperture disc) and a lenslet
position (``da``: Gauss-Legendre on the smooth pieces between texel-boundary crossings).
Arrays and scalars only; :class:`lf_flame.tomo.exact.ExactOperator` validates its inputs.
"""
import math

import numpy as np
from numba import njit, prange


# ---- quadrature of the kernels -----------------------------------------------------
@njit(inline="always", cache=True)
def _half_disc(y, r):
    """Area of the disc of radius ``r`` (centred at 0) above the line ``Y = y``."""
    if y >= r:
        return 0.0
    if y <= -r:
        return math.pi * r * r
    return r * r * math.acos(y / r) - y * math.sqrt(r * r - y * y)


@njit(inline="always", cache=True)
def _half_moment(y, r):
    """First moment (along Y) of the disc above ``Y = y``: ``2/3 (r^2 - y^2)^(3/2)``."""
    if abs(y) >= r:
        return 0.0
    return 2.0 / 3.0 * (r * r - y * y) ** 1.5


@njit(inline="always", cache=True)
def _arc(x, r):
    """``int_0^x sqrt(r^2 - X^2) dX`` for ``0 <= x <= r``."""
    return 0.5 * (x * math.sqrt(max(r * r - x * x, 0.0)) + r * r * math.asin(min(x / r, 1.0)))


#: Entries of :func:`_edge_terms`: the parts of a corner's area and moments that depend on one edge alone.
N_EDGE_TERMS = 9


@njit(inline="always", cache=True)
def _edge_terms(e, r, t):
    """Into ``t`` (:data:`N_EDGE_TERMS`,): the terms of :func:`_corner` that depend on the edge ``e`` alone (mm,
    either axis), each by the expression :func:`_corner` would evaluate it with (so a corner from them is the
    same to the bit): ``a = |e|``, ``_arc(a)``, ``(r^2 - a^2)^(3/2)``, ``r^2 - a^2``, ``s = sqrt(r^2 - a^2)``,
    ``_arc(s)`` (0 for the last three where ``a >= r``: no corner reads them there), the half discs above
    ``e`` and ``-e`` and the half moment above ``e`` (the same as above ``-e``)."""
    a = abs(e)
    d = r * r - a * a
    t[0] = a
    t[1] = _arc(a, r)
    t[2] = d ** 1.5 if d > 0.0 else 0.0
    t[3] = d
    sx = math.sqrt(d) if d > 0.0 else 0.0
    t[4] = sx
    t[5] = _arc(sx, r)
    t[6] = _half_disc(e, r)
    t[7] = _half_disc(-e, r)
    t[8] = _half_moment(e, r)


@njit(inline="always", cache=True)
def _corner_pos(tx, ty, r):
    """Area and first moments (X, Y) of the disc within ``X >= x, Y >= y``, ``x, y >= 0`` the edges of
    :func:`_edge_terms` ``tx`` and ``ty``."""
    x, y = tx[0], ty[0]
    if x * x + y * y >= r * r:
        return 0.0, 0.0, 0.0
    sx = ty[4]
    area = ty[5] - tx[1] - y * (sx - x)
    mx = (tx[2] - y ** 3) / 3.0 - 0.5 * y * (sx * sx - x * x)
    my = 0.5 * (ty[3] * (sx - x) - (sx ** 3 - x ** 3) / 3.0)
    return area, mx, my


@njit(inline="always", cache=True)
def _corner(x, y, tx, ty, r):
    """Area and first moments (X, Y) of the disc within ``X >= x, Y >= y`` (any signs; ``tx``, ``ty`` their
    :func:`_edge_terms`), by the disc's mirror symmetries."""
    a, mx, my = _corner_pos(tx, ty, r)
    if x >= 0.0 and y >= 0.0:
        return a, mx, my
    if x < 0.0 and y >= 0.0:
        return ty[6] - a, mx, ty[8] - my
    if x >= 0.0:
        return tx[6] - a, tx[8] - mx, my
    return math.pi * r * r - tx[7] - ty[7] + a, tx[8] - mx, ty[8] - my


@njit(inline="always", cache=True)
def _clip_by_terms(y0, y1, x0, x1, ty0, ty1, tx0, tx1, r):
    """The part of the rectangle ``[y0, y1] x [x0, x1]`` (mm, ``y`` along Y) inside the aperture disc of radius
    ``r``: its fraction of the rectangle's area and the offset of its centroid from the rectangle's centre
    (dy, dx), from its corners' areas and moments in closed form (:func:`_corner`), its edges' terms given
    (:func:`_edge_terms`: ``ty0, ty1, tx0, tx1``, kept by :func:`kernel_quadrature` for the pairs that share
    them). A rectangle wholly inside the disc (or no disc) is the caller's: fraction 1, no offset."""
    ny = 0.0 if y0 <= 0.0 <= y1 else min(y0 * y0, y1 * y1)
    nx = 0.0 if x0 <= 0.0 <= x1 else min(x0 * x0, x1 * x1)
    if ny + nx >= r * r:
        return 0.0, 0.0, 0.0
    a00, x00, y00 = _corner(x0, y0, tx0, ty0, r)
    a10, x10, y10 = _corner(x1, y0, tx1, ty0, r)
    a01, x01, y01 = _corner(x0, y1, tx0, ty1, r)
    a11, x11, y11 = _corner(x1, y1, tx1, ty1, r)
    area = a00 - a10 - a01 + a11
    if area <= 0.0:
        return 0.0, 0.0, 0.0
    mx = (x00 - x10 - x01 + x11) / area - 0.5 * (x0 + x1)
    my = (y00 - y10 - y01 + y11) / area - 0.5 * (y0 + y1)
    return min(area / ((y1 - y0) * (x1 - x0)), 1.0), my, mx


@njit(cache=True)
def _axis_points(c, A, B, a0, a1, a2, t0, t1, t2, m0, n_taps, xg, wg, tap, wt, lo_mm, hi_mm, angle, slope, var):
    """Quadrature points of one axis of one view and plane; returns how many were written.

    Texel coordinate ``c + A du + B da``, main-lens height ``a0 + a1 du + a2 da`` (mm,
    ``a1 != 0``), angle ``t0 + t1 du + t2 da`` (rad), ``du, da`` in [-1/2, 1/2]. ``da`` is
    split where a texel boundary meets ``du = +-1/2`` and each piece integrated by
    Gauss-Legendre (``xg, wg`` on [-1, 1]); ``du`` exactly: for each ``da`` node and tap
    ``m0 + m`` the point holds the tap ``m``, the weight (``da`` weight x the length of the
    ``du`` interval reading that tap), that interval's main-lens heights (mm), its angle
    at the interval's middle, the angle's slope per mm of height and its variance over
    the interval.
    """
    bp = np.empty(4 + 2 * (n_taps + 2))
    bp[0] = -0.5
    bp[1] = 0.5
    nb = 2
    if B != 0.0:
        for s in (-0.5 * A, 0.5 * A):
            v0 = c + s - 0.5 * abs(B)
            v1 = c + s + 0.5 * abs(B)
            for j in range(int(math.floor(v0)) + 1, int(math.ceil(v1))):
                da = (j - c - s) / B
                if -0.5 < da < 0.5 and nb < bp.shape[0]:
                    bp[nb] = da
                    nb += 1
    bps = np.sort(bp[:nb])
    n = 0
    for seg in range(nb - 1):
        d0, d1 = bps[seg], bps[seg + 1]
        if d1 <= d0:
            continue
        half, mid = 0.5 * (d1 - d0), 0.5 * (d1 + d0)
        for g in range(xg.shape[0]):
            da = mid + half * xg[g]
            w = half * wg[g]
            base = c + B * da
            for m in range(n_taps):
                mm = m0 + m
                if A > 0.0:
                    lo, hi = (mm - base) / A, (mm + 1 - base) / A
                elif A < 0.0:
                    lo, hi = (mm + 1 - base) / A, (mm - base) / A
                elif math.floor(base) == mm:
                    lo, hi = -0.5, 0.5
                else:
                    continue
                lo = max(lo, -0.5)
                hi = min(hi, 0.5)
                if hi <= lo:
                    continue
                e0 = a0 + a1 * lo + a2 * da
                e1 = a0 + a1 * hi + a2 * da
                tap[n] = m
                wt[n] = w * (hi - lo)
                lo_mm[n] = min(e0, e1)
                hi_mm[n] = max(e0, e1)
                angle[n] = t0 + t1 * 0.5 * (lo + hi) + t2 * da
                slope[n] = t1 / a1
                var[n] = (t1 * (hi - lo)) ** 2 / 12.0
                n += 1
    return n


@njit(parallel=True, cache=True)
def kernel_quadrature(cy, ay, ty, m0y, cx, ax, tx, n0x, n_taps_y, n_taps_x, radius, use_cos4, xg, wg, h, moments):
    """Kernels ``h`` (Nu, Nv, P, n_taps_y, n_taps_x) and, per view, the moments of its rays'
    angles (``moments`` (Nu, Nv, 6): mass, mean ty, mean tx, var ty, cov, var tx).

    ``cy`` (Nu, P, 3): texel coefficients (constant, du, da) of each view row ``u`` and
    plane; ``ay``, ``ty`` (Nu, 3): main-lens height and angle coefficients (angle at the
    reference lenslet); ``m0y`` (Nu, P) int64: first tap; ``cx``... the same along x.
    ``radius`` of the aperture (mm; <= 0: none). Each pair of points (one per axis) is a
    rectangle of main-lens heights: its part inside the aperture exactly (area and
    centroid in closed form), cos^4 over it to second order about its centroid.
    """
    Nu, P = cy.shape[0], cy.shape[1]
    Nv = cx.shape[0]
    n_g = xg.shape[0]
    cap_y = n_g * (3 + 2 * (n_taps_y + 2)) * n_taps_y
    cap_x = n_g * (3 + 2 * (n_taps_x + 2)) * n_taps_x
    r2 = radius * radius
    for uv in prange(Nu * Nv):
        u = uv // Nv
        v = uv % Nv
        tp_y = np.empty(cap_y, np.int64)
        w_y = np.empty(cap_y)
        l_y = np.empty(cap_y)
        u_y = np.empty(cap_y)
        a_y = np.empty(cap_y)
        s_y = np.empty(cap_y)
        v_y = np.empty(cap_y)
        tp_x = np.empty(cap_x, np.int64)
        w_x = np.empty(cap_x)
        l_x = np.empty(cap_x)
        u_x = np.empty(cap_x)
        a_x = np.empty(cap_x)
        s_x = np.empty(cap_x)
        v_x = np.empty(cap_x)
        e_x = np.empty(cap_x)
        t_y0 = np.empty((cap_y, N_EDGE_TERMS))   # each point's edges' terms, where a rectangle crosses the rim
        t_y1 = np.empty((cap_y, N_EDGE_TERMS))
        t_x0 = np.empty((cap_x, N_EDGE_TERMS))
        t_x1 = np.empty((cap_x, N_EDGE_TERMS))
        for k in range(P):
            ny = _axis_points(cy[u, k, 0], cy[u, k, 1], cy[u, k, 2], ay[u, 0], ay[u, 1], ay[u, 2],
                              ty[u, 0], ty[u, 1], ty[u, 2], m0y[u, k], n_taps_y, xg, wg, tp_y, w_y, l_y, u_y, a_y,
                              s_y, v_y)
            nx = _axis_points(cx[v, k, 0], cx[v, k, 1], cx[v, k, 2], ax[v, 0], ax[v, 1], ax[v, 2],
                              tx[v, 0], tx[v, 1], tx[v, 2], n0x[v, k], n_taps_x, xg, wg, tp_x, w_x, l_x, u_x, a_x,
                              s_x, v_x)
            s0 = sy = sx = syy = sxy = sxx = 0.0
            for q in range(nx):
                e_x[q] = max(l_x[q] * l_x[q], u_x[q] * u_x[q])
            hk = h[u, v, k]
            x_terms = False
            for p in range(ny):
                e_y = max(l_y[p] * l_y[p], u_y[p] * u_y[p])
                wyp, ayp, syp, vyp = w_y[p], a_y[p], s_y[p], v_y[p]
                row = hk[tp_y[p]]
                y_terms = False
                for q in range(nx):
                    if radius <= 0.0 or e_y + e_x[q] <= r2:     # inside the disc (or no disc): all of it
                        frac, dy, dx = 1.0, 0.0, 0.0
                    else:                                       # clipped, each edge's terms once
                        if not x_terms:
                            for j in range(nx):
                                _edge_terms(l_x[j], radius, t_x0[j])
                                _edge_terms(u_x[j], radius, t_x1[j])
                            x_terms = True
                        if not y_terms:
                            _edge_terms(l_y[p], radius, t_y0[p])
                            _edge_terms(u_y[p], radius, t_y1[p])
                            y_terms = True
                        frac, dy, dx = _clip_by_terms(l_y[p], u_y[p], l_x[q], u_x[q], t_y0[p], t_y1[p], t_x0[q],
                                                      t_x1[q], radius)
                    mu = wyp * w_x[q] * frac
                    if mu == 0.0:
                        continue
                    t_y = ayp + syp * dy
                    t_x = a_x[q] + s_x[q] * dx
                    f = 1.0
                    if use_cos4:
                        t2 = 1.0 + t_y * t_y + t_x * t_x
                        f = 1.0 / (t2 * t2) + 0.5 * (
                            (-4.0 / t2 ** 3 + 24.0 * t_y * t_y / t2 ** 4) * vyp
                            + (-4.0 / t2 ** 3 + 24.0 * t_x * t_x / t2 ** 4) * v_x[q])
                    row[tp_x[q]] += mu * f
                    if k == 0:
                        s0 += mu
                        sy += mu * t_y
                        sx += mu * t_x
                        syy += mu * (t_y * t_y + vyp)
                        sxy += mu * t_y * t_x
                        sxx += mu * (t_x * t_x + v_x[q])
            if k == 0 and s0 > 0.0:
                my, mx = sy / s0, sx / s0
                moments[u, v, 0] = s0
                moments[u, v, 1] = my
                moments[u, v, 2] = mx
                moments[u, v, 3] = syy / s0 - my * my
                moments[u, v, 4] = sxy / s0 - my * mx
                moments[u, v, 5] = sxx / s0 - mx * mx


# ---- the per-pixel cos^4 drift ---------------------------------------------------------
@njit(cache=True)
def cos4_mean(ty, tx, var_y, cov, var_x):
    """Mean of ``1 / (1 + ty^2 + tx^2)^2`` over angles of mean (ty, tx) and that covariance
    (second-order expansion: ``f + (f_yy var_y + 2 f_xy cov + f_xx var_x) / 2`` with ``i = 1 / (1 + ty^2 + tx^2)``,
    ``f = i^2``, ``f_yy = -4 i^3 + 24 ty^2 i^4``, ``f_xy = 24 ty tx i^4``; the powers formed once)."""
    i = 1.0 / (1.0 + ty * ty + tx * tx)
    i2 = i * i
    quad = ty * ty * var_y + 2.0 * ty * tx * cov + tx * tx * var_x
    return i2 * (1.0 - 2.0 * i * (var_y + var_x) + 12.0 * i2 * quad)


@njit(parallel=True, cache=True)
def cos4_weights(moments, ry, rx, out):
    """Each pixel's mean cos^4 over its view's centre's (:func:`cos4_mean`), ``out`` (Nu, Nv, R, C): 0 in a view
    no ray reaches. ``moments`` (Nu, Nv, 6) as :func:`kernel_quadrature`'s; ``ry`` (Nu, R) and ``rx`` (Nv, C): the
    angle shift of each row and column of lenslets from the centre's. Threads over views."""
    Nu, Nv = moments.shape[0], moments.shape[1]
    R, C = ry.shape[1], rx.shape[1]
    for uv in prange(Nu * Nv):
        u, v = uv // Nv, uv % Nv
        my, mx, vy, cv, vx = moments[u, v, 1], moments[u, v, 2], moments[u, v, 3], moments[u, v, 4], moments[u, v, 5]
        if not moments[u, v, 0] > 0:
            out[u, v] = 0.0
            continue
        centre = cos4_mean(my, mx, vy, cv, vx)
        if not centre > 0:
            centre = 1.0
        for r in range(R):
            ty = my + ry[u, r]
            for c in range(C):
                out[u, v, r, c] = cos4_mean(ty, mx + rx[v, c], vy, cv, vx) / centre


# ---- the map applied by its taps (small kernels: no FFT) ----------------------------------
# Four output rows at a time from the seven input rows that four tap rows reach: each pass over a row's columns
# loads seven input rows and four accumulators for sixteen products; unsigned column counters, so that Numba
# emits no negative-index wrap and the column loops vectorise.
@njit(parallel=True, cache=True, fastmath={'contract'})
def taps_forward(h, oy, ox, x, first, out, dest):
    """``out[dest[v], r, c] = sum_{p, ty, tx} h[v, p, ty, tx] x[first[v] + p, (r + oy[v, p] + ty) % Lr,
    (c + ox[v, p] + tx) % Lc]``: planes of ``x`` (S, Lr, Lc) to the views ``out`` (V', Lr, Lc) on the canvas, as the
    operator's spectra give them by FFT (a circular correlation with each view's taps at their origins). ``h``
    (V, P, Ty, Tx) with ``Ty`` a multiple of 4 (zero rows padded); ``oy``, ``ox`` (V, P), ``first`` and ``dest`` (V,)
    int64. Threads over views and blocks of rows."""
    V, P, Ty, Tx = h.shape
    S, Lr, Lc = x.shape
    src = x
    if Tx > 1 or np.any(ox != 0):
        src = np.empty((S, Lr, 2 * Lc), x.dtype)                 # each row twice: a shifted row is one slice
        for p in range(S):
            for r in range(Lr):
                for j in range(2 * Lc):
                    src[p, r, j] = x[p, r, j % Lc]
    n = np.uint64(Lc)
    blocks = (Lr + 3) // 4
    for vb in prange(V * blocks):
        v = vb // blocks
        r = (vb - v * blocks) * 4
        acc = np.zeros((4, Lc), x.dtype)
        q0, q1, q2, q3 = acc[0], acc[1], acc[2], acc[3]
        for p in range(P):
            xp = src[first[v] + p]
            for t in range(0, Ty, 4):
                b = r + oy[v, p] + t
                x0, x1, x2, x3 = xp[b % Lr], xp[(b + 1) % Lr], xp[(b + 2) % Lr], xp[(b + 3) % Lr]
                x4, x5, x6 = xp[(b + 4) % Lr], xp[(b + 5) % Lr], xp[(b + 6) % Lr]
                for tx in range(Tx):
                    a0, a1, a2, a3 = h[v, p, t, tx], h[v, p, t + 1, tx], h[v, p, t + 2, tx], h[v, p, t + 3, tx]
                    if a0 == 0 and a1 == 0 and a2 == 0 and a3 == 0:
                        continue
                    c0 = (ox[v, p] + tx) % Lc
                    s0, s1, s2, s3, s4, s5, s6 = x0[c0:], x1[c0:], x2[c0:], x3[c0:], x4[c0:], x5[c0:], x6[c0:]
                    for c in range(n):
                        e0, e1, e2, e3, e4, e5, e6 = s0[c], s1[c], s2[c], s3[c], s4[c], s5[c], s6[c]
                        q0[c] += a0 * e0 + a1 * e1 + a2 * e2 + a3 * e3
                        q1[c] += a0 * e1 + a1 * e2 + a2 * e3 + a3 * e4
                        q2[c] += a0 * e2 + a1 * e3 + a2 * e4 + a3 * e5
                        q3[c] += a0 * e3 + a1 * e4 + a2 * e5 + a3 * e6
        o = out[dest[v]]
        for k in range(min(4, Lr - r)):
            for c in range(n):
                o[r + k, c] = acc[k, c]


@njit(inline="always", cache=True)
def _adjoint_rows(hv, oyv, oxv, zv, q0, q1, q2, q3, r, Lr, Lc, n):
    """Add one view's ``H^H`` of plane rows ``r .. r + 3`` into ``q0 .. q3`` (rows of length ``2 Lc`` where a tap
    shifts columns): ``hv`` (Ty, Tx) its taps, ``oyv`` and ``oxv`` their origins, ``zv`` (Lr, Lc) the view."""
    Ty, Tx = hv.shape
    for t in range(0, Ty, 4):
        # output row r + j, tap row t + k reads input row b + j - k: rows b - 3 .. b + 3
        b = r - oyv - t
        z0, z1, z2, z3 = zv[(b - 3) % Lr], zv[(b - 2) % Lr], zv[(b - 1) % Lr], zv[b % Lr]
        z4, z5, z6 = zv[(b + 1) % Lr], zv[(b + 2) % Lr], zv[(b + 3) % Lr]
        for tx in range(Tx):
            a0, a1, a2, a3 = hv[t, tx], hv[t + 1, tx], hv[t + 2, tx], hv[t + 3, tx]
            if a0 == 0 and a1 == 0 and a2 == 0 and a3 == 0:
                continue
            o = (oxv + tx) % Lc
            d0, d1, d2, d3 = q0[o:], q1[o:], q2[o:], q3[o:]
            for c in range(n):
                e0, e1, e2, e3, e4, e5, e6 = z0[c], z1[c], z2[c], z3[c], z4[c], z5[c], z6[c]
                d0[c] += a0 * e3 + a1 * e2 + a2 * e1 + a3 * e0
                d1[c] += a0 * e4 + a1 * e3 + a2 * e2 + a3 * e1
                d2[c] += a0 * e5 + a1 * e4 + a2 * e3 + a3 * e2
                d3[c] += a0 * e6 + a1 * e5 + a2 * e4 + a3 * e3


@njit(parallel=True, cache=True, fastmath={'contract'})
def taps_adjoint(h, oy, ox, z, rows, out, n_threads):
    """The transpose of :func:`taps_forward` from the planes ``x`` to the views ``z[rows]`` (``first`` 0): the views
    ``z`` (V', Lr, Lc) to the planes ``out`` (P, Lr, Lc) on the canvas, ``out[p, r, c] = sum_{v, ty, tx}
    h[v, p, ty, tx] z[rows[v], (r - oy[v, p] - ty) % Lr, (c - ox[v, p] - tx) % Lc]``. Each of ``n_threads`` threads
    sums its share of the views into planes of its own (each view read once, the planes in cache), each row twice as
    long so that a shifted row is one slice; the halves and the threads' planes are added at the end."""
    V, P, Ty, Tx = h.shape
    Lr, Lc = out.shape[1], out.shape[2]
    n = np.uint64(Lc)
    part = np.zeros((n_threads, P, (Lr + 3) // 4 * 4, 2 * Lc), z.dtype)
    for t_id in prange(n_threads):
        acc = part[t_id]
        for v in range(t_id * V // n_threads, (t_id + 1) * V // n_threads):
            for p in range(P):
                for r in range(0, Lr, 4):
                    _adjoint_rows(h[v, p], oy[v, p], ox[v, p], z[rows[v]], acc[p, r], acc[p, r + 1], acc[p, r + 2],
                                  acc[p, r + 3], r, Lr, Lc, n)
    for pr in prange(P * Lr):
        p = pr // Lr
        r = pr - p * Lr
        o = out[p, r]
        for c in range(n):
            s = part[0, p, r, c] + part[0, p, r, c + Lc]
            for t_id in range(1, n_threads):
                s += part[t_id, p, r, c] + part[t_id, p, r, c + Lc]
            o[c] = s


# ---- separable taps: a column filter shared by a column of views, then each view's row filter ----------
@njit(parallel=True, cache=True, fastmath={'contract'})
def taps_adjoint_columns(a, oy, z, rows, start, out):
    """The row filters' transpose, summed per column of views: ``out[c P + p, r, :] = sum_{v in column c, ty}
    a[v, p, ty] z[rows[v], (r - oy[v, p] - ty) % Lr, :]`` with the views of column ``c`` at ``start[c] .. start[c +
    1] - 1`` of ``a`` (V, P, Ty) (``Ty`` a multiple of 4), ``oy`` (V, P) and ``rows`` (V,). ``out`` (C P, Lr', Lc)
    with ``Lr'`` the rows rounded up to a multiple of 4 (the last rows spare). Threads over columns, planes and
    blocks of rows (each writes its own rows)."""
    V, P, Ty = a.shape
    Lr, Lc = z.shape[1], z.shape[2]
    n = np.uint64(Lc)
    C = start.shape[0] - 1
    blocks = (Lr + 3) // 4
    for cpb in prange(C * P * blocks):
        cp = cpb // blocks
        r = (cpb - cp * blocks) * 4
        c, p = cp // P, cp % P
        q0, q1, q2, q3 = out[cp, r], out[cp, r + 1], out[cp, r + 2], out[cp, r + 3]
        for j in range(n):
            q0[j], q1[j], q2[j], q3[j] = 0, 0, 0, 0
        for v in range(start[c], start[c + 1]):
            _adjoint_rows(a[v, p].reshape((Ty, 1)), oy[v, p], 0, z[rows[v]], q0, q1, q2, q3, r, Lr, Lc, n)


@njit(parallel=True, cache=True, fastmath={'contract'})
def column_sums(w, idx, shift, src, out, accumulate):
    """``out[m, r, j] (+)= sum_k w[m, k] src[idx[m, k], r, (j + shift[m, k]) % Lc]`` for ``r < Lr`` (``out``'s
    rows), a row's list ending at its first zero weight: ``w`` (M, K), ``idx`` and ``shift`` (M, K) int64, ``src``
    (S, Lr', Lc) with ``Lr' >= Lr``; ``out`` (M, Lr, Lc) overwritten, or added to with ``accumulate``. Threads over
    rows of ``out``."""
    M, K = w.shape
    Lr, Lc = out.shape[1], out.shape[2]
    for mr in prange(M * Lr):
        m = mr // Lr
        r = mr - m * Lr
        o = out[m, r]
        if not accumulate:
            for j in range(Lc):
                o[j] = 0
        for k in range(K):
            wk = w[m, k]
            if wk == 0:
                break
            s = src[idx[m, k], r]
            c = shift[m, k] % Lc
            e = np.uint64(Lc - c)
            s1 = s[c:]
            for j in range(e):
                o[j] += wk * s1[j]
            o2 = o[e:]
            for j in range(np.uint64(c)):
                o2[j] += wk * s[j]
