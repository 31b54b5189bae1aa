"""Numba kernels of the refocusing stage, serving :mod:`lf_flame.refocus.shift_and_sum`. Private: they
take only arrays and scalars and trust their inputs; the public, validating API is in
:mod:`lf_flame.refocus.shift_and_sum`.

Kernels: the finite check of large inputs (:func:`max_exponent`, behind
``refocus._check_finite``), shift-and-sum of a focal stack (:func:`shift_sum_stack`) and
the Fourier slice resampling of the 4-D spectrum (:func:`fourier_slice`).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def max_exponent(bits, exponent_mask):
    """Largest ``bits & exponent_mask`` over a flat array of IEEE floats viewed as
    unsigned integers (uint32 for float32, uint64 for float64): it equals
    ``exponent_mask`` exactly when some element is NaN or inf. One parallel read with no
    array the size of the input (``np.isfinite(a).all()`` also writes a boolean one)."""
    chunk = 1 << 16
    n_chunks = (bits.size + chunk - 1) // chunk
    best = np.zeros(n_chunks, bits.dtype)
    for i in prange(n_chunks):
        best[i] = _max_masked(bits[i * chunk:min(bits.size, (i + 1) * chunk)], exponent_mask)
    return _max_masked(best, exponent_mask)


@njit(cache=True)
def _max_masked(bits, exponent_mask):
    """Serial part of :func:`max_exponent`: 64 running maxima, one per lane, so that
    the loop vectorises (a single running maximum is a chain)."""
    n = bits.size // 64 * 64
    lanes = np.zeros(64, bits.dtype)
    for i in range(0, n, 64):
        for j in range(64):
            lanes[j] = max(lanes[j], bits[i + j] & exponent_mask)
    m = lanes.max()
    for i in range(n, bits.size):
        m = max(m, bits[i] & exponent_mask)
    return m


@njit(cache=True)
def _shift_taps(shifts, n):
    """Split shifts (S, K) into integer part, fraction and the output range they cover.

    A sample at ``i + shift`` (``i`` an output index) is inside an axis of ``n`` samples
    when ``0 <= i + shift <= n - 1``; returns ``k = floor(shift)``, ``f = shift - k``
    (float32) and the half-open output range ``[lo, hi)`` of such ``i`` (empty: lo = hi).
    """
    S, K = shifts.shape
    k = np.empty((S, K), np.int64)
    f = np.empty((S, K), np.float32)
    lo = np.empty((S, K), np.int64)
    hi = np.empty((S, K), np.int64)
    for s in range(S):
        for j in range(K):
            x = shifts[s, j]
            k0 = int(np.floor(x))
            fr = x - k0
            k[s, j] = k0
            f[s, j] = fr
            a = max(0, -k0)
            b = min(n, n - 1 - k0 + (0 if fr > 0.0 else 1))
            lo[s, j] = a
            hi[s, j] = max(a, b)
    return k, f, lo, hi


@njit(cache=True)
def _cover(mask, lo, hi, n):
    """``cover[s, u, c]``: views of view row u whose column sample is inside at column c.

    A running sum over a difference array (+1 at ``lo``, -1 at ``hi``). Serial on
    purpose: array statements in a ``parallel=True`` function become parallel loops,
    each one a dispatch to the thread pool."""
    S, V = lo.shape
    U = mask.shape[0]
    cover = np.zeros((S, U, n), np.float32)
    step = np.zeros(n + 1, np.int64)
    for s in range(S):
        for u in range(U):
            step[:] = 0
            for v in range(V):
                if mask[u, v] and lo[s, v] < hi[s, v]:
                    step[lo[s, v]] += 1
                    step[hi[s, v]] -= 1
            k = 0
            for c in range(n):
                k += step[c]
                cover[s, u, c] = k
    return cover


@njit(inline="always", cache=True)
def _add_shifted_cols(acc, ra, y, y0, col, k, f, lo, hi, r0, r1, C):
    """Rows r0 .. r1 of the plane's sum ``acc`` (row ra first) += the view-column sum
    (row r at ``y[y0 + r * C]``) shifted by k + f columns, in one flat loop; a column c
    whose sample runs off the view (c outside [lo, hi)) is selected out; ``col[p]`` is
    p % C (at least n of them). ``y`` has a margin of at least C + 1 on each side, so
    the flat reads never leave it."""
    n = (r1 - r0) * C
    p0 = y0 + r0 * C + k
    a = y[p0:p0 + n]
    b = y[p0 + 1:p0 + 1 + n]
    cc = col[:n]  # every row starts at a multiple of C
    dst = acc[(r0 - ra) * C:(r0 - ra) * C + n]
    lo32 = np.int32(lo)  # int32 like ``col``: the compare vectorises with the float32 lanes
    hi32 = np.int32(hi)
    if f > 0.0:
        g = np.float32(1.0) - f
        for p in range(n):
            dst[p] += g * a[p] + f * b[p] if (cc[p] >= lo32) & (cc[p] < hi32) else np.float32(0.0)
    else:
        for p in range(n):
            dst[p] += a[p] if (cc[p] >= lo32) & (cc[p] < hi32) else np.float32(0.0)


@njit(inline="always", cache=True)
def _add_shifted_rows(ys, sa, views, u, v, k, f, r0, r1, C):
    """Rows r0 .. r1 of the sum ``ys`` (row sa first) += view (u, v) shifted by k + f rows."""
    if r0 >= r1:
        return
    n = (r1 - r0) * C
    t = ys[(r0 - sa) * C:(r0 - sa) * C + n]
    src = (r0 + k) * C
    a = views[u, v, src:src + n]
    if f > 0.0:
        b = views[u, v, src + C:src + C + n]
        f0 = np.float32(1.0) - f
        for p in range(n):
            t[p] += f0 * a[p] + f * b[p]
    else:
        for p in range(n):
            t[p] += a[p]


_SUB_ROWS = 16  # rows of the float32 view-column sums kept in L1 cache at once


@njit(parallel=True, cache=True, fastmath={'contract'})
def shift_sum_stack(views, n_rows, shifts_r, shifts_c, mask, out, rows_per_task):
    """Shift-and-sum a focal stack of S planes in one pass over the light field.

    ``views`` (U, V, R * C) float32, each view flattened row-major (R = ``n_rows``);
    ``shifts_r`` (S, U), ``shifts_c`` (S, V) float64: view (u, v) of plane s is sampled
    at (r + shifts_r[s, u], c + shifts_c[s, v]), bilinearly (a whole-pixel shift reads
    one sample: the integer path does no interpolation); ``mask`` (U, V) bool selects
    views. Each output pixel is the mean over the views whose sample point lies inside
    the image (borders do not darken); pixels with none get 0. ``out`` (S, R, C) float32.

    Bilinear interpolation is separable, the row shift depends only on u and the column
    shift only on v. So for each view column v, the U views are shifted along rows and
    summed first: a shift by whole rows is a shift of the flattened view, one long loop
    per view (two views per loop where their rows agree, to halve the read-modify-write
    of the sum). That sum is then shifted along columns and added to the plane, again as
    one flat loop over a block of rows (:func:`_add_shifted_cols`). Sums are float32 but
    two-level, like a pairwise sum: no float32 sum has more than U (then V) terms, so a
    15 x 15 light field loses no light (relative error < (U + V) 2^-24).

    Tasks are blocks of ``rows_per_task`` output rows (the result does not depend on
    it); a task goes through view column v for all planes while that column's rows are
    in L2 cache, ``_SUB_ROWS`` rows at a time so that the sums stay in L1.

    Returns True if every output pixel is finite (each task checks its own rows while
    they are in its cache: cheaper than a second pass over ``out`` afterwards).
    """
    R = n_rows
    C = views.shape[2] // R
    kr, fr, rlo, rhi = _shift_taps(shifts_r, R)
    kc, fc, clo, chi = _shift_taps(shifts_c, C)
    cover = _cover(mask, clo, chi, C)
    n_tasks = (R + rows_per_task - 1) // rows_per_task
    finite = np.empty(n_tasks, np.bool_)
    for task in prange(n_tasks):
        ra = task * rows_per_task
        finite[task] = _stack_rows(views, mask, kr, fr, rlo, rhi, kc, fc, clo, chi, cover, ra,
                                   min(R, ra + rows_per_task) - ra, out)
    all_finite = True
    for task in range(n_tasks):
        all_finite = all_finite and finite[task]
    return all_finite


@njit(cache=True, fastmath={'contract'})
def _stack_rows(views, mask, kr, fr, rlo, rhi, kc, fc, clo, chi, cover, ra, nb, out):
    """Rows ``ra .. ra + nb`` of every plane of :func:`shift_sum_stack` (one task; serial,
    see :func:`_cover`); returns True if they are all finite."""
    U, V, RC = views.shape
    S, R, C = out.shape
    acc = np.zeros((S, nb * C), np.float32)
    m = (C + 16) // 16 * 16  # margin >= C + 1 (64-byte aligned): the column pass reads up to C + 1 beyond the rows
    y = np.zeros((S, _SUB_ROWS * C + 2 * m), np.float32)
    col = np.empty(_SUB_ROWS * C, np.int32)  # column of each flat sample of a sub-block
    for p in range(_SUB_ROWS * C):
        col[p] = p % C
    for v in range(V):
        for sa in range(ra, ra + nb, _SUB_ROWS):
            sb = min(ra + nb, sa + _SUB_ROWS)
            for s in range(S):
                if clo[s, v] >= chi[s, v]:
                    continue
                ys = y[s, m:m + _SUB_ROWS * C]
                ys[:(sb - sa) * C] = 0.0
                r_any0 = sb
                r_any1 = sa
                for u in range(0, U, 2):  # fixed pairs (u, u + 1): the sums do not depend on the blocks
                    w = min(u + 1, U - 1)
                    u0, u1 = max(sa, rlo[s, u]), min(sb, rhi[s, u])
                    w0, w1 = max(sa, rlo[s, w]), min(sb, rhi[s, w])
                    use_u = mask[u, v] and u0 < u1
                    use_w = w != u and mask[w, v] and w0 < w1
                    r_any0 = min(r_any0, u0 if use_u else sb, w0 if use_w else sb)
                    r_any1 = max(r_any1, u1 if use_u else sa, w1 if use_w else sa)
                    if use_u and use_w and fr[s, u] > 0.0 and fr[s, w] > 0.0 and max(u0, w0) < min(u1, w1):
                        b0, b1 = max(u0, w0), min(u1, w1)  # rows both reach: one loop for the two views
                        n = (b1 - b0) * C
                        t = ys[(b0 - sa) * C:(b0 - sa) * C + n]
                        p1 = (b0 + kr[s, u]) * C
                        p2 = (b0 + kr[s, w]) * C
                        a1 = views[u, v, p1:p1 + n]
                        c1 = views[u, v, p1 + C:p1 + C + n]
                        a2 = views[w, v, p2:p2 + n]
                        c2 = views[w, v, p2 + C:p2 + C + n]
                        f1 = fr[s, u]
                        f2 = fr[s, w]
                        g1 = np.float32(1.0) - f1
                        g2 = np.float32(1.0) - f2
                        for p in range(n):
                            t[p] += (g1 * a1[p] + f1 * c1[p]) + (g2 * a2[p] + f2 * c2[p])
                        for x, x0, x1 in ((u, u0, u1), (w, w0, w1)):
                            _add_shifted_rows(ys, sa, views, x, v, kr[s, x], fr[s, x], x0, b0, C)
                            _add_shifted_rows(ys, sa, views, x, v, kr[s, x], fr[s, x], b1, x1, C)
                    else:
                        if use_u:
                            _add_shifted_rows(ys, sa, views, u, v, kr[s, u], fr[s, u], u0, u1, C)
                        if use_w:
                            _add_shifted_rows(ys, sa, views, w, v, kr[s, w], fr[s, w], w0, w1, C)
                if r_any0 < r_any1:
                    _add_shifted_cols(acc[s], ra, y[s], m - sa * C, col, kc[s, v], fc[s, v], clo[s, v], chi[s, v],
                                      r_any0, r_any1, C)
    # normalise by the number of views that reach each pixel; the count of a row only
    # changes at a row where some view row u starts or stops reaching the image
    cnt = np.zeros(C, np.float32)
    probe = np.zeros(C, np.float32)  # x * 0 is 0 for finite x, NaN for NaN or inf (no fastmath flag folds it)
    for s in range(S):
        for r in range(ra, ra + nb):
            changed = r == ra
            for u in range(U):
                changed = changed or r == rlo[s, u] or r == rhi[s, u]
            if changed:
                cnt[:] = 0.0
                for u in range(U):
                    if rlo[s, u] <= r < rhi[s, u]:
                        cu = cover[s, u]
                        for c in range(C):
                            cnt[c] += cu[c]
            o = out[s, r]
            a = acc[s, (r - ra) * C:(r - ra + 1) * C]
            for c in range(C):
                o[c] = a[c] / cnt[c] if cnt[c] > 0.0 else 0.0
                probe[c] += o[c] * np.float32(0.0)  # per column: vectorises, unlike one running sum
    return np.all(probe == 0.0)


@njit(parallel=True, cache=True)
def fourier_slice(spectrum, j_r, w_r, j_c, w_c, out):
    """Resample the 4-D light-field spectrum on the 2-D slices of a focal stack (Ng 2005).

    ``spectrum`` (Kr, Kc, M, M) complex64: for each spatial frequency (kr, kc) of the
    padded views, the M-point DFT over the angular axes (u', v'). Plane s takes, at
    (kr, kc), the separable interpolation ``sum_a sum_b w_r[s, kr, a] w_c[s, kc, b]
    spectrum[kr, kc, (j_r[s, kr] + a) % M, (j_c[s, kc] + b) % M]`` (``j_*`` int64 first
    tap, ``w_*`` (S, K, W) float64 kernel weights). ``out`` (S, Kr, Kc) complex64.
    """
    S, Kr, W = w_r.shape
    Kc = w_c.shape[1]
    M = spectrum.shape[2]
    # every slope at one spatial frequency in turn: its (M, M) block stays in cache (slope by slope over the
    # whole spectrum, each block was fetched again from memory: 3-4x the time, the same sums)
    # (the rows' wrapped taps once per spatial row, the columns' by subtraction instead of a modulo: 1.3x)
    for kr in prange(Kr):
        ju = np.empty((S, W), np.int64)
        for s in range(S):
            for a in range(W):
                ju[s, a] = (j_r[s, kr] + a) % M
        for kc in range(Kc):
            for s in range(S):
                jc = j_c[s, kc] % M
                re = im = 0.0
                for a in range(W):
                    u = ju[s, a]
                    row_re = row_im = 0.0
                    for b in range(W):
                        col = jc + b
                        while col >= M:                      # (more than once only where M < W)
                            col -= M
                        z = spectrum[kr, kc, u, col]
                        wb = w_c[s, kc, b]
                        row_re += wb * z.real
                        row_im += wb * z.imag
                    re += w_r[s, kr, a] * row_re
                    im += w_r[s, kr, a] * row_im
                out[s, kr, kc] = complex(re, im)


@njit(parallel=True, cache=True)
def angular_grid(spec, iu, iv, out):
    """Place the lit views' spatial spectra on the angular grid of :func:`fourier_slice`.

    ``spec`` (V, Kr, Kc) complex64: view ``k``'s spectrum, to slot ``(iu[k], iv[k])`` (int64) of
    ``out`` (Kr, Kc, M, M) complex64, every other slot 0 (the grid's zero padding and the unlit views).
    """
    V, Kr, Kc = spec.shape
    M = out.shape[2]
    for kr in prange(Kr):
        for kc in range(Kc):
            for a in range(M):
                for b in range(M):
                    out[kr, kc, a, b] = 0
            for k in range(V):
                out[kr, kc, iu[k], iv[k]] = spec[k, kr, kc]
