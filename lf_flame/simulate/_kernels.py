"""Numba kernels of the simulation stage, serving :mod:`lf_flame.simulate.tracer`. Private: they
take only arrays and scalars and trust their inputs; the public, validating API is in
:mod:`lf_flame.simulate.tracer`.

Kernels: random numbers (:func:`_uniform`), backward ray tracing on the perfect grid
(:func:`_chain`, :func:`trace_rays`, :func:`axis_coefficients`, :func:`render_backward`),
forward tracing (:func:`render_forward`, the measured alternative of ``make bench-sim``)
and rendering through a lenslet grid of any geometry (:func:`_nearest_site`,
:func:`render_points`). They stay in one module because they share :func:`_uniform` and
the R_d sequence: Numba's cache (``cache=True``) is invalidated by a change of the
kernel's own file only, not of a file it calls into.

Randomness is a counter-based hash (SplitMix64) of (seed, pixel, dimension), so every
pixel's samples are fixed by the seed alone: results are bit-identical whatever the
number of threads, and threads never share state.
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


# R_d low-discrepancy sequence in 4-D (Roberts 2018, "The unreasonable effectiveness
# of quasirandom sequences"): alpha_k = phi_4^-k, phi_4 the real root of x^5 = x + 1.
_PHI4 = 1.1673039782614187
_R4 = np.array([_PHI4 ** -1, _PHI4 ** -2, _PHI4 ** -3, _PHI4 ** -4])


@njit(inline="always", cache=True)
def _chain(y_s, y_l, y_c, gap, lenslet_inv, mla_to_lens, lens_inv):
    """Trace one axis of one ray backwards, sensor -> object space.

    The ray joins sensor height ``y_s`` to MLA height ``y_l`` (mm) and is refracted by the
    lenslet centred at ``y_c``. ``gap`` (sensor -> MLA, B = -g), ``lenslet_inv`` (inverse
    lenslet), ``mla_to_lens`` (MLA -> main lens) and ``lens_inv`` (inverse main lens) are
    2x2 ray transfer matrices. Returns ``(y_m, t_m, y_o, t_o)``: height (mm) and angle
    (rad, paraxial: tan) between MLA and main lens, then height and angle leaving the
    main lens into object space.
    Linear and homogeneous in ``(y_s, y_l, y_c)``.
    """
    t = (y_l - gap[0, 0] * y_s) / gap[0, 1]
    t = gap[1, 0] * y_s + gap[1, 1] * t
    t = lenslet_inv[1, 0] * (y_l - y_c) + lenslet_inv[1, 1] * t
    y_m = mla_to_lens[0, 0] * y_l + mla_to_lens[0, 1] * t
    t_m = mla_to_lens[1, 0] * y_l + mla_to_lens[1, 1] * t
    y_o = lens_inv[0, 0] * y_m + lens_inv[0, 1] * t_m
    t_o = lens_inv[1, 0] * y_m + lens_inv[1, 1] * t_m
    return y_m, t_m, y_o, t_o


@njit(cache=True)
def trace_rays(y_s, y_l, y_c, gap, lenslet_inv, mla_to_lens, lens_inv):
    """:func:`_chain` over arrays of rays (1-D, float64): returns its four arrays."""
    n = y_s.shape[0]
    out = np.empty((4, n))
    for k in range(n):
        out[0, k], out[1, k], out[2, k], out[3, k] = _chain(y_s[k], y_l[k], y_c[k], gap, lenslet_inv, mla_to_lens, lens_inv)
    return out


@njit(cache=True)
def axis_coefficients(n_lenslets, n_pix, mla_pitch, pixel_pitch, sign, gap, lenslet_inv, mla_to_lens,
                      lens_inv, layer_z, tex_offset, tex_scale):
    """Affine coefficients of every traced quantity, per pixel along one sensor axis.

    The backward chain is linear, so for pixel ``i`` (lenslet ``i // N``) every quantity
    is ``K[q, 0, i] + K[q, 1, i] du + K[q, 2, i] da + K[q, 3, i] o`` in the ray's
    sample coordinates: ``du`` in [-1/2, 1/2) across the pixel, ``da`` across the
    lenslet (pitches from its centre) and ``o`` the lenslet step (crosstalk, else 0).
    Quantities ``q``: 0 height at the main lens (mm), 1 angle between MLA and main lens,
    ``2 + l`` texture coordinate of layer ``l`` (texels: ``tex_offset[l] +
    tex_scale[l] * y_object``; object distance ``layer_z[l]`` mm). ``sign`` is +1 for
    rows (y up) and -1 for columns (read-out rotated by 180°). Returns K, float64,
    shape (2 + n_layers, 4, n_lenslets * n_pix).
    """
    n = n_lenslets * n_pix
    n_layers = layer_z.shape[0]
    K = np.zeros((2 + n_layers, 4, n))
    unit = np.zeros((4, 3))          # (y_s, y_l, y_c) of the constant term and of du, da, o
    unit[1, 0] = pixel_pitch
    unit[2, 1] = mla_pitch
    unit[3, 2] = mla_pitch
    for i in range(n):
        unit[0, 0] = sign * (i + 0.5 - n * 0.5) * pixel_pitch
        unit[0, 1] = sign * (i // n_pix + 0.5 - n_lenslets * 0.5) * mla_pitch
        unit[0, 2] = unit[0, 1]
        for c in range(4):
            y_m, t_m, y_o, t_o = _chain(unit[c, 0], unit[c, 1], unit[c, 2], gap, lenslet_inv, mla_to_lens,
                                        lens_inv)
            K[0, c, i] = y_m
            K[1, c, i] = t_m
            for li in range(n_layers):
                K[2 + li, c, i] = tex_scale[li] * (y_o - layer_z[li] * t_o) + (tex_offset[li] if c == 0 else 0.0)
    return K


@njit(parallel=True, cache=True, fastmath={'contract'})
def render_backward(ky, kx, n_pix, radiance, alpha, layer_box, occlusion, aperture_radius, use_cos4, lenslet_span,
                    rays_per_pixel, seed, out, adjoint, y_adj, grad, record, tab_texel, tab_weight):
    """Backward-trace ``rays_per_pixel`` rays per sensor pixel into a stack of layers.

    Every ray of pixel (i, j) has four sample coordinates: its start in the pixel
    (``du`` per axis) and its point on the lenslet plane (``da`` per axis, spanning
    ``lenslet_span`` pitches: 1 = the pixel's own lenslet, 3 = crosstalk through the
    neighbours, whose lenslet step ``o`` is ``floor(da + 1/2)``, higher y / lower
    column on a border). Samples are a 4-D R_d sequence rotated by a per-pixel random
    shift (randomised quasi-Monte Carlo, unbiased; Cranley & Patterson 1976), the shift
    a SplitMix64 hash of (seed, pixel): bit-identical at any thread count.
    Every traced quantity is affine in the samples, with coefficients ``ky`` (rows) and
    ``kx`` (columns) from :func:`axis_coefficients`. A ray is lost outside the main-lens
    aperture (``aperture_radius`` mm; <= 0: none) or through a lenslet beyond the array;
    it is weighted by cos^4 of its angle between MLA and main lens when ``use_cos4``;
    then the layers (nearest first, nearest-texel lookup in ``radiance`` and ``alpha``,
    shape (n_layers, rows, cols) float32) are composited front to back
    (``sum_k T_k L_k``, ``T_{k+1} = T_k (1 - alpha_k)``) when ``occlusion``, else summed
    (optically thin emitters). ``out`` (H, W) float32 receives the irradiance estimate:
    the mean over the rays times ``lenslet_span**2`` (the sampled area in lenslets).

    ``adjoint`` False renders (``y_adj`` and ``grad`` unused: pass (1, 1) arrays).
    ``adjoint`` True runs the transpose of the same linear map (``occlusion`` must be
    False: only then is the image linear in ``radiance`` alone): every ray of pixel
    (i, j) adds ``y_adj[i, j]`` (H, W) float64 times its weight to the texel it reads,
    in ``grad`` (n_blocks, n_layers * rows * cols) float64, zeroed by the caller, one
    row per parallel block of sensor rows (summed by the caller; a fixed block count
    keeps the sum bit-identical at any thread count). Forward and adjoint are one
    compiled function, so both compute every texel index with the same instructions:
    the adjoint is exact, not an approximation (``lf_flame.tomo``). ``out`` and
    ``radiance`` are not read then (``radiance`` gives the texture shape).

    ``record`` True (``adjoint`` False, every layer's box its whole texture) renders
    nothing and writes the map itself, ray by ray: ``tab_weight`` (H, W, rays_per_pixel)
    float32 receives each ray's weight times the area it stands for (0 for a lost ray),
    ``tab_texel`` (H, W, rays_per_pixel, n_layers) int32, filled with -1 by the caller,
    the flat index (into ``grad``'s layout) of the texel each ray reads on each layer,
    left -1 where it misses the layer. Otherwise pass (1, 1, 1, 1) and (1, 1, 1) arrays.
    """
    ky = ky.astype(np.float32)
    kx = kx.astype(np.float32)
    H = ky.shape[2]
    W = kx.shape[2]
    n_rows = H // n_pix
    n_cols = W // n_pix
    n_layers = radiance.shape[0]
    tr = radiance.shape[1]
    tc = np.int32(radiance.shape[2])
    tr_max = np.float32(tr - 1.0)
    tc_max = np.float32(tc - 1.0)
    trf = np.float32(tr)
    tcf = np.float32(tc)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    half = np.float32(0.5)
    rad = radiance.reshape(n_layers * tr * tc)
    alp = alpha.reshape(alpha.size)
    r2 = np.float32(aperture_radius * aperture_radius)
    span = np.float32(lenslet_span)
    half_span = np.float32(0.5 * lenslet_span)
    crosstalk = lenslet_span > 1
    scale = lenslet_span * lenslet_span / rays_per_pixel    # each ray stands for span^2 / rpp of the area
    base = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019)
    # bounding-box culling: columns whose rays can reach layer li's content (texels
    # layer_box[li] = row0, row1, col0, col1) are col_lo[li] <= j < col_hi[li]
    col_lo = np.zeros(n_layers, np.int64)
    col_hi = np.zeros(n_layers, np.int64)
    for li in range(n_layers):
        first, last = W, -1
        for j in range(W):
            reach = abs(kx[2 + li, 1, j]) * half + abs(kx[2 + li, 2, j]) * half_span
            if crosstalk:
                reach += abs(kx[2 + li, 3, j])
            if kx[2 + li, 0, j] + reach >= layer_box[li, 2] and kx[2 + li, 0, j] - reach < layer_box[li, 3]:
                first = min(first, j)
                last = j
        col_lo[li] = first
        col_hi[li] = last + 1
    n_blocks = grad.shape[0] if adjoint else min(H, 64)
    for b in prange(n_blocks):
        g = grad[b] if adjoint else grad[0]
        gw = np.zeros(W)
        rot = np.empty((4, W), np.float32)
        du_y = np.empty(W, np.float32)
        du_x = np.empty(W, np.float32)
        da_y = np.empty(W, np.float32)
        da_x = np.empty(W, np.float32)
        o_y = np.zeros(W, np.float32)
        o_x = np.zeros(W, np.float32)
        wgt = np.empty(W, np.float32)
        val = np.empty(W, np.float32)
        trans = np.empty(W, np.float32)
        acc = np.empty(W)
        inside = np.empty(W, np.float32)
        texv = np.empty(W, np.float32)
        texa = np.empty(W, np.float32)
        texel = np.empty(W, np.int32)
        for i in range(b * H // n_blocks, (b + 1) * H // n_blocks):
            row_lenslet = i // n_pix
            for j in range(W):
                key = base + np.uint64((i * W + j) * 4)
                rot[0, j] = np.float32(_uniform(key))
                rot[1, j] = np.float32(_uniform(key + np.uint64(1)))
                rot[2, j] = np.float32(_uniform(key + np.uint64(2)))
                rot[3, j] = np.float32(_uniform(key + np.uint64(3)))
                acc[j] = 0.0
            for k in range(rays_per_pixel):
                q0 = np.float32((0.5 + (k + 1) * _R4[0]) % 1.0)
                q1 = np.float32((0.5 + (k + 1) * _R4[1]) % 1.0)
                q2 = np.float32((0.5 + (k + 1) * _R4[2]) % 1.0)
                q3 = np.float32((0.5 + (k + 1) * _R4[3]) % 1.0)
                for j in range(W):
                    u = q0 + rot[0, j]
                    du_y[j] = (u - one if u >= one else u) - half
                    u = q1 + rot[1, j]
                    du_x[j] = (u - one if u >= one else u) - half
                    u = q2 + rot[2, j]
                    da_y[j] = (u - one if u >= one else u) * span - half_span
                    u = q3 + rot[3, j]
                    da_x[j] = (u - one if u >= one else u) * span - half_span
                    wgt[j] = one
                    val[j] = zero
                    trans[j] = one
                if crosstalk:
                    for j in range(W):
                        o_y[j] = np.floor(da_y[j] + half)
                        o_x[j] = np.floor(da_x[j] + half)
                        r_l = row_lenslet + o_y[j]
                        c_l = j // n_pix - o_x[j]
                        if r_l < 0 or r_l >= n_rows or c_l < 0 or c_l >= n_cols:
                            wgt[j] = zero
                if aperture_radius > 0.0:
                    a0, a1, a2, a3 = ky[0, 0, i], ky[0, 1, i], ky[0, 2, i], ky[0, 3, i]
                    for j in range(W):
                        ym = a0 + a1 * du_y[j] + a2 * da_y[j] + a3 * o_y[j]
                        xm = kx[0, 0, j] + kx[0, 1, j] * du_x[j] + kx[0, 2, j] * da_x[j] + kx[0, 3, j] * o_x[j]
                        if ym * ym + xm * xm > r2:
                            wgt[j] = zero
                if use_cos4:
                    a0, a1, a2, a3 = ky[1, 0, i], ky[1, 1, i], ky[1, 2, i], ky[1, 3, i]
                    for j in range(W):
                        ty = a0 + a1 * du_y[j] + a2 * da_y[j] + a3 * o_y[j]
                        tx = kx[1, 0, j] + kx[1, 1, j] * du_x[j] + kx[1, 2, j] * da_x[j] + kx[1, 3, j] * o_x[j]
                        t2 = one + ty * ty + tx * tx
                        wgt[j] *= one / (t2 * t2)
                if record:
                    for j in range(W):
                        tab_weight[i, j, k] = wgt[j] * np.float32(scale)
                if adjoint:
                    for j in range(W):
                        gw[j] = wgt[j] * y_adj[i, j] * scale
                for li in range(n_layers):
                    q = 2 + li
                    a0, a1, a2, a3 = ky[q, 0, i], ky[q, 1, i], ky[q, 2, i], ky[q, 3, i]
                    reach = abs(a1) * half + abs(a2) * half_span + (abs(a3) if crosstalk else zero)
                    j0, j1 = col_lo[li], col_hi[li]
                    if a0 + reach < layer_box[li, 0] or a0 - reach >= layer_box[li, 1] or j1 <= j0:
                        continue                     # no ray of this row meets the layer's content
                    off = np.int32(li * tr * tc)
                    # 0-based loops over slices vectorise (offset indices do not)
                    n = j1 - j0
                    dyy, dxx, ayy, axx = du_y[j0:j1], du_x[j0:j1], da_y[j0:j1], da_x[j0:j1]
                    c0, c1, c2 = kx[q, 0, j0:j1], kx[q, 1, j0:j1], kx[q, 2, j0:j1]
                    if crosstalk:
                        oyy, oxx, c3 = o_y[j0:j1], o_x[j0:j1], kx[q, 3, j0:j1]
                        for j in range(n):
                            fr = a0 + a1 * dyy[j] + a2 * ayy[j] + a3 * oyy[j]
                            fc = c0[j] + c1[j] * dxx[j] + c2[j] * axx[j] + c3[j] * oxx[j]
                            inside[j] = one if (fr >= zero) & (fr < trf) & (fc >= zero) & (fc < tcf) else zero
                            texel[j] = off + np.int32(min(max(fr, zero), tr_max)) * tc + np.int32(min(max(fc, zero), tc_max))
                    else:
                        for j in range(n):
                            fr = a0 + a1 * dyy[j] + a2 * ayy[j]
                            fc = c0[j] + c1[j] * dxx[j] + c2[j] * axx[j]
                            inside[j] = one if (fr >= zero) & (fr < trf) & (fc >= zero) & (fc < tcf) else zero
                            texel[j] = off + np.int32(min(max(fr, zero), tr_max)) * tc + np.int32(min(max(fc, zero), tc_max))
                    if record:
                        for j in range(n):
                            if inside[j] > zero:
                                tab_texel[i, j0 + j, k, li] = texel[j]
                        continue
                    if adjoint:
                        gg = gw[j0:j1]
                        for j in range(n):
                            g[texel[j]] += inside[j] * gg[j]
                        continue
                    vv = val[j0:j1]
                    for j in range(n):
                        texv[j] = rad[texel[j]]
                    if occlusion:
                        tt = trans[j0:j1]
                        for j in range(n):
                            texa[j] = alp[texel[j]]
                        for j in range(n):
                            t = tt[j] * inside[j]
                            vv[j] += t * texv[j]
                            tt[j] -= t * texa[j]
                    else:
                        for j in range(n):
                            vv[j] += inside[j] * texv[j]
                if not (adjoint or record):
                    for j in range(W):
                        acc[j] += wgt[j] * val[j]
            if not (adjoint or record):
                for j in range(W):
                    out[i, j] = acc[j] * scale


@njit(parallel=True, cache=True)
def render_forward(z, main_f, mla_d, gap, mla_pitch, mla_f, pixel_pitch, n_rows, n_cols, n_pix, aperture_radius,
                   texture, top, left, height, width, n_rays, seed, n_chunks):
    """Forward-trace ``n_rays`` rays from one additive layer to the sensor (the measured alternative).

    Each ray starts at a uniform point of the layer rectangle (``top``/``left`` corner,
    ``height`` x ``width`` mm, object distance ``z`` mm) with the radiance of its texel,
    aims at a uniform point of the main-lens aperture disc, and is traced through the
    main lens (focal ``main_f``), to the MLA (``mla_d``), through the lenslet it hits
    (``floor`` rule), to the sensor (``gap``), then binned into its pixel (scatter). Each
    of ``n_chunks`` parallel chunks bins into its own image, summed at the end.
    Returns the irradiance image (H, W) float64 in the units of :func:`render_backward`
    (flux x g^2 / (pixel area x lenslet area)); no cos^4, no occlusion.
    """
    H = n_rows * n_pix
    W = n_cols * n_pix
    tr, tc = texture.shape
    imgs = np.zeros((n_chunks, H, W))
    base = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019)
    for ch in prange(n_chunks):
        img = imgs[ch]
        for k in range(ch * n_rays // n_chunks, (ch + 1) * n_rays // n_chunks):
            key = base + np.uint64(4 * k)
            u0 = _uniform(key)
            u1 = _uniform(key + np.uint64(1))
            lum = texture[int(u0 * tr), int(u1 * tc)]
            if lum == 0.0:
                continue
            rho = aperture_radius * np.sqrt(_uniform(key + np.uint64(2)))
            phi = 2.0 * np.pi * _uniform(key + np.uint64(3))
            ym = rho * np.cos(phi)
            xm = rho * np.sin(phi)
            ty = (ym - (top - u0 * height)) / z - ym / main_f
            tx = (xm - (left + u1 * width)) / z - xm / main_f
            yl = ym + mla_d * ty
            xl = xm + mla_d * tx
            r = int(np.floor(yl / mla_pitch + n_rows * 0.5))
            c = int(np.floor(n_cols * 0.5 - xl / mla_pitch))
            if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
                continue
            ty -= (yl - (r + 0.5 - n_rows * 0.5) * mla_pitch) / mla_f
            tx -= (xl - (n_cols * 0.5 - c - 0.5) * mla_pitch) / mla_f
            i = int(np.floor((yl + gap * ty) / pixel_pitch + H * 0.5))
            j = int(np.floor(W * 0.5 - (xl + gap * tx) / pixel_pitch))
            if 0 <= i < H and 0 <= j < W:
                img[i, j] += lum
    out = imgs.sum(axis=0)
    scale = (height * width * np.pi * aperture_radius ** 2 / (z * z * n_rays)
             * gap * gap / (pixel_pitch * pixel_pitch * mla_pitch * mla_pitch))
    return out * scale


@njit(inline="always", cache=True)
def _nearest_site(q0, q1, hexagonal, n_rows, n_cols):
    """Lattice site (row, column) nearest to the lattice offsets ``(q0, q1)`` (pitches,
    rows and columns about the grid centre; as :meth:`PlenopticCamera.lattice_offsets`);
    (-1, -1) outside the grid."""
    if not hexagonal:
        r = np.rint(q0 + (n_rows - 1) * 0.5)
        c = np.rint(q1 + (n_cols - 1) * 0.5)
    else:
        h = np.sqrt(3.0) / 2.0
        shift = -0.25 if n_rows > 1 else 0.0
        rf = np.floor(q0 / h + (n_rows - 1) * 0.5)
        best = np.inf
        r = 0.0
        c = 0.0
        for cand in (rf, rf + 1.0):
            odd = cand - 2.0 * np.floor(cand * 0.5)
            cc = np.rint(q1 + (n_cols - 1) * 0.5 - 0.5 * odd - shift)
            dy = (cand - (n_rows - 1) * 0.5) * h - q0
            dx = cc - (n_cols - 1) * 0.5 + 0.5 * odd + shift - q1
            d2 = dy * dy + dx * dx
            if d2 < best:
                best = d2
                r = cand
                c = cc
    if r < 0 or r >= n_rows or c < 0 or c >= n_cols:
        return -1, -1
    return int(r), int(c)


@njit(parallel=True, cache=True)
def render_points(pts, keys, height, width, pixel_pitch, grid_centre, grid_inv, lens_mm, lens_mat, hexagonal,
                  ay, ax, radiance, alpha, occlusion, aperture_radius, use_cos4, rays_per_pixel, seed, out):
    """Backward-trace pixel-sized sample areas through a lenslet grid of any geometry.

    The general-grid twin of :func:`render_backward` (same ray samples, same chain),
    for lenslet grids that are rotated, offset, of non-integer pitch or hexagonal: the
    chain is no longer separable by sensor row and column, so each ray finds its own
    lenslet. Area ``m`` is a pixel centred at ``pts[m]`` = (row, column) in sensor
    pixel coordinates (sensor ``height`` x ``width`` pixels of ``pixel_pitch`` mm; y =
    (row - H/2) pitch, x = -(column - W/2) pitch: the read-out is rotated by 180°). A
    ray's sensor point lies in the cell (Voronoi region) of the lenslet image whose
    centre is nearest (:func:`_nearest_site` of ``grid_inv @ (point - grid_centre)``;
    no crosstalk), and the ray passes through that lenslet, centred at ``lens_mm[r, c]``
    = (y, x) mm on the MLA, at a uniform point of its cell: local coordinates in
    [-1/2, 1/2)^2 (a hexagonal cell: a point of the lattice's rhombic fundamental domain
    moved into the hexagon by a lattice vector, which preserves the uniform measure),
    mapped to mm by ``lens_mat`` (2, 2; the grid rotation times the lenslet pitch).
    ``ay``, ``ax`` (2 + n_layers, 4) float64: every traced quantity along y (x) is
    ``a[q, 0] y_s + a[q, 1] y_l + a[q, 2] y_c + a[q, 3]`` (the backward ABCD chain is
    linear; q as in :func:`axis_coefficients`). ``keys`` (M,) int64 index the per-area
    random shift of the R_d sequence exactly as pixel ``i * W + j`` does in
    :func:`render_backward`, so a perfect grid traces that kernel's rays. ``out`` (M,)
    float32 receives the irradiance estimate (float64 arithmetic).
    """
    M = pts.shape[0]
    n_rows = lens_mm.shape[0]
    n_cols = lens_mm.shape[1]
    n_layers = radiance.shape[0]
    tr = radiance.shape[1]
    tc = radiance.shape[2]
    r2 = aperture_radius * aperture_radius
    base = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019)
    one = np.float32(1.0)
    half = np.float32(0.5)
    h3 = np.sqrt(3.0) / 2.0
    n_chunks = min(M, 256)
    for b in prange(n_chunks):
        rot = np.empty(4, np.float32)
        s = np.empty(4, np.float32)
        for m in range(b * M // n_chunks, (b + 1) * M // n_chunks):
            key = base + np.uint64(keys[m] * 4)
            for d in range(4):
                rot[d] = np.float32(_uniform(key + np.uint64(d)))
            acc = 0.0
            for k in range(rays_per_pixel):
                for d in range(4):
                    u = np.float32((0.5 + (k + 1) * _R4[d]) % 1.0) + rot[d]
                    s[d] = (u - one if u >= one else u) - half
                pr = pts[m, 0] + np.float64(s[0])
                pc = pts[m, 1] - np.float64(s[1])  # x = -(column - W/2) pitch: x + s pitch is column - s
                q0 = grid_inv[0, 0] * (pr - grid_centre[0]) + grid_inv[0, 1] * (pc - grid_centre[1])
                q1 = grid_inv[1, 0] * (pr - grid_centre[0]) + grid_inv[1, 1] * (pc - grid_centre[1])
                lr, lc = _nearest_site(q0, q1, hexagonal, n_rows, n_cols)
                if lr < 0:
                    continue
                ys = (pts[m, 0] - 0.5 * height) * pixel_pitch + np.float64(s[0]) * pixel_pitch
                xs = -(pts[m, 1] - 0.5 * width) * pixel_pitch + np.float64(s[1]) * pixel_pitch
                a_y = np.float64(s[2])
                a_x = np.float64(s[3])
                if hexagonal:  # rhombus (1, 0), (1/2, sqrt 3 / 2) in (column, row) -> hexagon
                    pcol = a_y + 0.5 * a_x
                    prow = h3 * a_x
                    bc, br, bd = 0.0, 0.0, pcol * pcol + prow * prow
                    for vc, vr in ((1.0, 0.0), (-1.0, 0.0), (0.5, h3), (-0.5, -h3), (-0.5, h3), (0.5, -h3)):
                        dd = (pcol - vc) ** 2 + (prow - vr) ** 2
                        if dd < bd:
                            bc, br, bd = vc, vr, dd
                    a_y = prow - br
                    a_x = pcol - bc
                yc = lens_mm[lr, lc, 0]
                xc = lens_mm[lr, lc, 1]
                yl = yc + lens_mat[0, 0] * a_y + lens_mat[0, 1] * a_x
                xl = xc + lens_mat[1, 0] * a_y + lens_mat[1, 1] * a_x
                w = 1.0
                if aperture_radius > 0.0:
                    ym = ay[0, 0] * ys + ay[0, 1] * yl + ay[0, 2] * yc + ay[0, 3]
                    xm = ax[0, 0] * xs + ax[0, 1] * xl + ax[0, 2] * xc + ax[0, 3]
                    if ym * ym + xm * xm > r2:
                        continue
                if use_cos4:
                    ty = ay[1, 0] * ys + ay[1, 1] * yl + ay[1, 2] * yc + ay[1, 3]
                    tx = ax[1, 0] * xs + ax[1, 1] * xl + ax[1, 2] * xc + ax[1, 3]
                    t2 = 1.0 + ty * ty + tx * tx
                    w = 1.0 / (t2 * t2)
                val = 0.0
                trans = 1.0
                for li in range(n_layers):
                    q = 2 + li
                    fr = ay[q, 0] * ys + ay[q, 1] * yl + ay[q, 2] * yc + ay[q, 3]
                    fc = ax[q, 0] * xs + ax[q, 1] * xl + ax[q, 2] * xc + ax[q, 3]
                    if fr < 0.0 or fr >= tr or fc < 0.0 or fc >= tc:
                        continue
                    ir = int(fr)
                    ic = int(fc)
                    val += trans * radiance[li, ir, ic]
                    if occlusion:
                        trans -= trans * alpha[li, ir, ic]
                acc += w * val
            out[m] = acc / rays_per_pixel
