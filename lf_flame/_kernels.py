"""Numba kernels. Private: they take only arrays and scalars and trust their inputs;
the public, validating API is in :mod:`lf_flame.simulate` and :mod:`lf_flame.refocus`.

Randomness is a counter-based hash (SplitMix64) of (seed, pixel, sample, dimension), so
every pixel's samples are fixed by the seed alone: results are bit-identical whatever
the number of threads, and threads never share state.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_INV53 = 1.0 / 9007199254740992.0


@njit(inline="always", cache=True)
def _uniform(key):
    """SplitMix64 finaliser of a uint64 key -> float64 uniform in [0, 1)."""
    z = key * _GOLDEN + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    z = z ^ (z >> np.uint64(31))
    return np.float64(z >> np.uint64(11)) * _INV53


@njit(inline="always", cache=True)
def _back(m, y, t):
    """Apply a 2x2 ray transfer matrix ``m`` to ``(y, t)``."""
    return m[0, 0] * y + m[0, 1] * t, m[1, 0] * y + m[1, 1] * t


@njit(parallel=True, cache=True)
def render_backward(n_rows, n_cols, n_pix, mla_pitch, pixel_pitch, gap, lenslet_inv, mla_to_lens, lens_inv,
                    aperture_radius, use_cos4, layer_z, layer_top, layer_left, layer_h, layer_w,
                    radiance, alpha, occlusion, rays_per_pixel, seed, out):
    """Backward-trace ``rays_per_pixel`` rays per sensor pixel into a layered scene.

    Each ray starts at a random point of its pixel, passes through a random point of
    the pixel's own lenslet (stratified on an m x m grid when rays_per_pixel = m^2),
    is traced back through the lenslet, to the main lens (aperture test, cos^4
    weight of the ray between lens and MLA), through it, and to each layer plane,
    nearest first, compositing ``sum_k T_k L_k`` with ``T_{k+1} = T_k (1 - alpha_k)``
    when ``occlusion`` (else ``T = 1``: additive emission).

    Matrices (2x2, float64) trace backwards: ``gap`` sensor -> MLA (its B is -g),
    ``lenslet_inv`` the inverse lenslet lens, ``mla_to_lens`` MLA -> main lens,
    ``lens_inv`` the inverse main lens. ``out`` (n_rows*n_pix, n_cols*n_pix) float32
    receives the mean radiance per pixel. Pixel pitch ``pixel_pitch`` (mm) may exceed
    ``mla_pitch / n_pix``: lenslet images are centred on the chief rays from the
    main-lens centre, so pixel block r is centred at y_c (1 + g / d). Read-out rotated by 180 degrees: pixel
    row i sits at sensor height (i + 1/2 - H/2) * pitch/N, column j at
    (W/2 - j - 1/2) * pitch/N, so the scene appears upright.
    """
    H = n_rows * n_pix
    W = n_cols * n_pix
    pp = pixel_pitch
    n_layers = layer_z.shape[0]
    tr_n = radiance.shape[1]
    tc_n = radiance.shape[2]
    m = int(np.sqrt(rays_per_pixel) + 0.5)
    stratified = m * m == rays_per_pixel
    r2 = aperture_radius * aperture_radius
    base = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019)
    for i in prange(H):
        r = i // n_pix
        yc_l = (r + 0.5 - n_rows * 0.5) * mla_pitch
        yc_p = (i + 0.5 - H * 0.5) * pp
        for j in range(W):
            c = j // n_pix
            xc_l = (n_cols * 0.5 - c - 0.5) * mla_pitch
            xc_p = (W * 0.5 - j - 0.5) * pp
            key0 = base + np.uint64((i * W + j) * rays_per_pixel * 4)
            acc = 0.0
            for k in range(rays_per_pixel):
                key = key0 + np.uint64(4 * k)
                ys = yc_p + (_uniform(key) - 0.5) * pp
                xs = xc_p + (0.5 - _uniform(key + np.uint64(1))) * pp
                if stratified:
                    a = ((k // m) + _uniform(key + np.uint64(2))) / m
                    b = ((k % m) + _uniform(key + np.uint64(3))) / m
                else:
                    a = _uniform(key + np.uint64(2))
                    b = _uniform(key + np.uint64(3))
                yl = yc_l + (a - 0.5) * mla_pitch
                xl = xc_l + (0.5 - b) * mla_pitch
                # sensor -> MLA: the angle that joins the two points, then the lenslet
                ty = (yl - gap[0, 0] * ys) / gap[0, 1]
                tx = (xl - gap[0, 0] * xs) / gap[0, 1]
                _, ty = _back(gap, ys, ty)
                _, tx = _back(gap, xs, tx)
                _, ty = _back(lenslet_inv, yl - yc_l, ty)
                _, tx = _back(lenslet_inv, xl - xc_l, tx)
                ym, ty = _back(mla_to_lens, yl, ty)
                xm, tx = _back(mla_to_lens, xl, tx)
                if aperture_radius > 0.0 and ym * ym + xm * xm > r2:
                    continue
                w = 1.0
                if use_cos4:
                    t2 = 1.0 + ty * ty + tx * tx
                    w = 1.0 / (t2 * t2)
                ym, ty = _back(lens_inv, ym, ty)
                xm, tx = _back(lens_inv, xm, tx)
                trans = 1.0
                val = 0.0
                for li in range(n_layers):
                    yo = ym - layer_z[li] * ty
                    xo = xm - layer_z[li] * tx
                    fr = (layer_top[li] - yo) / layer_h[li] * tr_n
                    fc = (xo - layer_left[li]) / layer_w[li] * tc_n
                    if fr < 0.0 or fc < 0.0 or fr >= tr_n or fc >= tc_n:
                        continue
                    ir = int(fr)
                    ic = int(fc)
                    val += trans * radiance[li, ir, ic]
                    if occlusion:
                        trans *= 1.0 - alpha[li, ir, ic]
                        if trans <= 0.0:
                            break
                acc += w * val
            out[i, j] = acc / rays_per_pixel


@njit(parallel=True, cache=True)
def shift_sum_stack(views, shifts_r, shifts_c, mask, out):
    """Bilinear shift-and-sum of sub-aperture views into a focal stack.

    ``views`` (U, V, R, C) float32; ``shifts_r`` (S, U), ``shifts_c`` (S, V) float64:
    view (u, v) of plane s is sampled at (r + shifts_r[s, u], c + shifts_c[s, v]);
    ``mask`` (U, V) bool selects views. Each output pixel is the mean over the views
    whose sample point lies inside the image (so borders do not darken); pixels with
    none get 0. Accumulates in float64. ``out`` (S, R, C) float32.
    """
    U, V, R, C = views.shape
    S = shifts_r.shape[0]
    for sr in prange(S * R):
        s = sr // R
        r = sr % R
        acc = np.zeros(C, dtype=np.float64)
        cnt = np.zeros(C, dtype=np.float64)
        for u in range(U):
            y = r + shifts_r[s, u]
            r0 = int(np.floor(y))
            fr = y - r0
            if r0 < 0 or r0 > R - 1 or (fr > 0.0 and r0 > R - 2):
                continue
            r1 = r0 + 1 if fr > 0.0 else r0
            for v in range(V):
                if not mask[u, v]:
                    continue
                x = shifts_c[s, v]
                c0 = int(np.floor(x))
                fc = x - c0
                lo = max(0, -c0)
                hi = min(C, C - 1 - c0 + (0 if fc > 0.0 else 1))
                a = views[u, v, r0]
                b = views[u, v, r1]
                w00 = (1.0 - fr) * (1.0 - fc)
                w01 = (1.0 - fr) * fc
                w10 = fr * (1.0 - fc)
                w11 = fr * fc
                if fc > 0.0:
                    for cc in range(lo, hi):
                        k = cc + c0
                        acc[cc] += w00 * a[k] + w01 * a[k + 1] + w10 * b[k] + w11 * b[k + 1]
                        cnt[cc] += 1.0
                else:
                    for cc in range(lo, hi):
                        k = cc + c0
                        acc[cc] += (1.0 - fr) * a[k] + fr * b[k]
                        cnt[cc] += 1.0
        for cc in range(C):
            out[s, r, cc] = acc[cc] / cnt[cc] if cnt[cc] > 0.0 else 0.0
