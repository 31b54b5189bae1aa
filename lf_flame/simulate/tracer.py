"""Render raw plenoptic sensor images of layered scenes (validating API over the kernels).

Backward tracing (sensor -> object), chosen after measuring both ideas
(``make bench-sim``, ``results/bench_sim.md``): every pixel launches its own rays
through its own lenslet (or its 3 x 3 neighbourhood with crosstalk), so pixels are
independent: no scatter, no atomic adds, no ray lost or counted twice at a lenslet
border, bit-identical under any number of threads. Occlusion is a front-to-back
composite along each ray, which forward tracing cannot do without a visibility pass.
On one flame layer of the paper's camera, forward tracing (object -> lens aperture ->
MLA -> sensor, binned by scatter) needed 16 rays per pixel for the image error that
backward tracing reaches with 1, and ran 3-6x fewer rays per second.

Speed comes from linearity: along each sensor axis every traced quantity (height on
the main lens, angle, texture coordinate of each layer) is an affine function of the
ray's sample coordinates, so the kernel evaluates precomputed coefficients
(:func:`trace_coefficients`) in float32, vectorised over a sensor row, and skips
layers a row's rays cannot reach (:func:`content_box`; exact). The plain NumPy
version of the same chain, :func:`render_reference`, is the tests' reference.
"""
from __future__ import annotations

import math

import numpy as np

from . import _kernels as _simulate_kernels
from ..optics.camera import PlenopticCamera
from ..optics.matrices import RayTransferMatrix, free_space
from .layers import Scene


_UNUSED = np.zeros((1, 1))  # the kernel's adjoint buffers, when rendering
#: the kernel's ray-table outputs (texel, weight), when not recording the map
NO_TABLE = (np.full((1, 1, 1, 1), -1, np.int32), np.zeros((1, 1, 1), np.float32))


def _stack_layers(camera: PlenopticCamera, scene: Scene):
    if not scene.layers:
        raise ValueError(f"scene {scene.name!r} has no layers")
    order = sorted(range(len(scene.layers)), key=lambda k: scene.layers[k].depth_offset_mm)
    layers = [scene.layers[k] for k in order]
    shape = layers[0].radiance.shape
    z = np.array([camera.object_distance_mm(L.depth_offset_mm) for L in layers])
    for L, z_l in zip(layers, z):
        if not math.isfinite(z_l) or z_l <= 0:
            raise ValueError(f"layer at depth offset {L.depth_offset_mm} mm lies behind the camera "
                             f"(object distance {z_l} mm <= 0)")
        if L.radiance.shape != shape or L.radiance.ndim != 2:
            raise ValueError(f"all layer textures must share one 2-D shape; got {L.radiance.shape} and {shape}")
        if not np.all(np.isfinite(L.radiance)) or np.any(L.radiance < 0):
            raise ValueError(f"layer at {L.depth_offset_mm} mm has NaN, inf or negative radiance")
        if L.alpha is not None and (L.alpha.shape != shape or not np.all((L.alpha >= 0) & (L.alpha <= 1))):
            raise ValueError(f"layer at {L.depth_offset_mm} mm has alpha outside [0, 1] or of the wrong shape")
        if min(L.size_mm) <= 0:
            raise ValueError(f"layer size must be positive. Received: size_mm={L.size_mm}")
    rad = np.ascontiguousarray(np.stack([L.radiance for L in layers]), dtype=np.float32)
    if scene.effects.occlusion:
        alpha = np.ascontiguousarray(np.stack([np.zeros(shape, np.float32) if L.alpha is None else L.alpha
                                               for L in layers]), dtype=np.float32)
    else:
        alpha = np.zeros((1, 1, 1), np.float32)  # never read
    return layers, z, rad, alpha


def content_box(radiance: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Per-layer bounding box (row0, row1, col0, col1), in texels, of non-zero radiance or alpha.

    ``radiance`` (n_layers, rows, cols); ``alpha`` the same shape, or (1, 1, 1) when
    unused. A layer with no content gets an empty box (row1 = row0). The kernel skips
    rays that cannot reach a layer's box: exact, since those rays would add 0.
    """
    box = np.zeros((radiance.shape[0], 4), np.int64)
    for li in range(radiance.shape[0]):
        mask = radiance[li] > 0
        if alpha.shape == radiance.shape:
            mask |= alpha[li] > 0
        rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        if rows.size:
            box[li] = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    return box


def _layer_frames(layers):
    """Top edge, left edge, height and width (mm) of each layer's texture, as arrays."""
    top = np.array([L.centre_mm[0] + L.size_mm[0] / 2 for L in layers])
    left = np.array([L.centre_mm[1] - L.size_mm[1] / 2 for L in layers])
    h = np.array([L.size_mm[0] for L in layers])
    w = np.array([L.size_mm[1] for L in layers])
    return top, left, h, w


def backward_chain(camera: PlenopticCamera) -> tuple[RayTransferMatrix, ...]:
    """The camera's ray transfer matrices in backward order (sensor -> object space).

    ``(gap, lenslet_inv, mla_to_lens, lens_inv)``: free space ``-g`` (sensor -> MLA),
    the inverse lenslet (in its own frame), free space ``-d`` (MLA -> main lens) and
    the inverse main lens. Each object layer then adds free space ``-z``.
    """
    return (free_space(-camera.sensor_distance_mm), camera.microlens_array.lens.inverse(),
            free_space(-camera.mla_distance_mm), camera.main_lens.inverse())


def trace_coefficients(camera: PlenopticCamera, layers, z) -> tuple[np.ndarray, np.ndarray]:
    """Per-row and per-column affine coefficients of the backward ABCD chain.

    See :func:`lf_flame.simulate._kernels.axis_coefficients`; returns ``(ky, kx)`` of shapes
    (2 + n_layers, 4, n_rows * N) and (2 + n_layers, 4, n_cols * N), float64.
    """
    tr, tc = layers[0].radiance.shape
    top, left, h, w = _layer_frames(layers)
    chain = tuple(m.matrix for m in backward_chain(camera))
    n, p, pp = camera.pixels_per_lenslet, camera.mla_pitch_mm, camera.pixel_pitch_mm
    ky = _simulate_kernels.axis_coefficients(camera.n_rows, n, p, pp, 1.0, *chain, z, top * tr / h, -tr / h)
    kx = _simulate_kernels.axis_coefficients(camera.n_cols, n, p, pp, -1.0, *chain, z, -left * tc / w, tc / w)
    return ky, kx


def render(camera: PlenopticCamera, scene: Scene, rays_per_pixel: int = 16, seed: int = 0, *,
           sensor: bool = True) -> np.ndarray:
    """Render the raw sensor image of ``scene`` seen by ``camera``.

    Parameters
    ----------
    camera : PlenopticCamera
    scene : Scene
        Layers (any order; traced nearest first) and the effects to simulate.
    rays_per_pixel : int
        Rays per sensor pixel (>= 1): a 4-D low-discrepancy (R_d) sequence over the
        pixel area and the lenslet aperture, randomly shifted per pixel (unbiased
        randomised quasi-Monte Carlo). Error against ray count: ``make bench-sim``.
    seed : int
        Seeds the ray samples and the sensor noise; same seed, bit-identical image.
    sensor : bool
        Apply the sensor model (:func:`apply_sensor`: noise, clipping, quantisation); False
        returns the noise-free mean radiance, unclipped (a colour render's channels,
        :func:`lf_flame.simulate.colour.render_colour`, get the sensor once, on the mosaic).

    Returns
    -------
    raw : ndarray of shape (n_rows * N, n_cols * N), float32
        Mean radiance per pixel (rows, columns; read-out rotated so the scene is
        upright), clipped to [0, 1] (sensor saturation), quantised if the scene's
        effects give a bit depth.

    Raises
    ------
    ValueError
        Bad ray count or seed, layers behind the camera, NaN/negative radiance,
        crosstalk asked of a non-perfect grid.

    Notes
    -----
    A non-perfect lenslet grid (rotated, offset, non-integer pitch or hexagonal; see
    :class:`~lf_flame.optics.camera.PlenopticCamera`) is rendered by :func:`render_points`,
    each pixel through the lenslet whose image centre is nearest (its Voronoi cell,
    :meth:`~lf_flame.optics.camera.PlenopticCamera.nearest_lenslet`); the raw image then has
    the camera's :attr:`~lf_flame.optics.camera.PlenopticCamera.sensor_shape`.
    """
    _validate_sampling(rays_per_pixel, seed)
    fx = scene.effects
    if not camera.perfect_grid:
        H, W = camera.sensor_shape
        i, j = np.mgrid[0:H, 0:W]
        pts = np.stack([i.ravel() + 0.5, j.ravel() + 0.5], axis=-1)
        out = render_points(camera, scene, pts, (i * W + j).ravel(), rays_per_pixel, seed).reshape(H, W)
        return apply_sensor(out, fx, seed) if sensor else out
    layers, z, rad, alpha = _stack_layers(camera, scene)
    ky, kx = trace_coefficients(camera, layers, z)
    out = np.empty(camera.sensor_shape, dtype=np.float32)
    _simulate_kernels.render_backward(ky, kx, camera.pixels_per_lenslet, rad, alpha, content_box(rad, alpha),
                             bool(fx.occlusion), camera.aperture_diameter_mm / 2 if fx.aperture else -1.0,
                             bool(fx.cos4), 3 if fx.crosstalk else 1, int(rays_per_pixel), int(seed), out,
                             False, _UNUSED, _UNUSED, False, *NO_TABLE)
    return apply_sensor(out, fx, seed) if sensor else out


def _axis_basis(camera: PlenopticCamera, z, tex_offset, tex_scale) -> np.ndarray:
    """Coefficients (2 + n_layers, 4) of each traced quantity along one axis as
    ``a[q, 0] y_s + a[q, 1] y_l + a[q, 2] y_c + a[q, 3]`` (quantities q as in
    :func:`lf_flame.simulate._kernels.axis_coefficients`): the backward chain traced on unit
    sensor, lenslet-plane and lenslet-centre heights (it is linear and homogeneous)."""
    chain = tuple(m.matrix for m in backward_chain(camera))
    e = np.eye(3)
    y_m, t_m, y_o, t_o = _simulate_kernels.trace_rays(e[0], e[1], e[2], *chain)
    a = np.zeros((2 + len(z), 4))
    a[0, :3], a[1, :3] = y_m, t_m
    for li in range(len(z)):
        a[2 + li, :3] = tex_scale[li] * (y_o - z[li] * t_o)
        a[2 + li, 3] = tex_offset[li]
    return a


def render_points(camera: PlenopticCamera, scene: Scene, points_px: np.ndarray, keys: np.ndarray,
                  rays_per_pixel: int = 16, seed: int = 0) -> np.ndarray:
    """Mean radiance of pixel-sized areas of the sensor, for any lenslet grid.

    The general-grid renderer behind :func:`render` and :func:`render_views`
    (kernel :func:`lf_flame.simulate._kernels.render_points`): the same backward ABCD chain and
    ray samples as the perfect-grid kernel; each ray passes through the lenslet whose
    image cell (:meth:`~lf_flame.optics.camera.PlenopticCamera.nearest_lenslet`) holds its
    point of the sensor.

    Parameters
    ----------
    camera : PlenopticCamera
    scene : Scene
    points_px : ndarray of shape (M, 2)
        Centres (row, column) of the areas in sensor pixel coordinates (pixel ``(i, j)``
        covers ``[i, i + 1) x [j, j + 1)``); each area is one pixel, axis-aligned.
    keys : ndarray of shape (M,), int
        Index of each area's random shift (pixel ``(i, j)`` of the sensor uses ``i * W + j``).

    Returns
    -------
    values : ndarray of shape (M,), float32
        Noise-free mean radiance, in the units of :func:`render` (before the sensor model).

    Raises
    ------
    ValueError
        Shapes that disagree, non-finite points, crosstalk (not modelled for a general
        grid), or the errors of :func:`render`.
    """
    _validate_sampling(rays_per_pixel, seed)
    fx = scene.effects
    if fx.crosstalk:
        raise ValueError("crosstalk is modelled for the perfect lenslet grid only; turn it off for a rotated, "
                         "offset, non-integer-pitch or hexagonal grid")
    pts = np.asarray(points_px, dtype=np.float64)
    keys = np.asarray(keys).reshape(-1)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(keys) != len(pts):
        raise ValueError(f"points_px must have shape (M, 2) and keys shape (M,). Received: {pts.shape}, {keys.shape}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points_px contains NaN or inf")
    layers, z, rad, alpha = _stack_layers(camera, scene)
    tr, tc = rad.shape[1:]
    top, left, h, w = _layer_frames(layers)
    ay = _axis_basis(camera, z, top * tr / h, -tr / h)
    ax = _axis_basis(camera, z, -left * tc / w, tc / w)
    H, W = camera.sensor_shape
    pp = camera.pixel_pitch_mm
    to_mla = pp * camera.mla_pitch_mm / camera.lenslet_image_pitch_mm  # chief ray: image centre -> lenslet centre
    c = camera.lenslet_image_centres_px()
    lens_mm = np.ascontiguousarray(np.stack([(c[..., 0] - H / 2) * to_mla, -(c[..., 1] - W / 2) * to_mla], -1))
    t = math.radians(camera.grid_rotation_deg)
    lens_mat = camera.mla_pitch_mm * np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])
    out = np.empty(len(pts), np.float32)
    _simulate_kernels.render_points(np.ascontiguousarray(pts), keys.astype(np.int64), H, W, pp,
                           np.asarray(camera.grid_centre_px, np.float64), np.linalg.inv(camera.grid_matrix), lens_mm,
                           lens_mat, camera.grid_layout == "hex", ay, ax, rad,
                           alpha if fx.occlusion else np.zeros((1, 1, 1), np.float32), bool(fx.occlusion),
                           camera.aperture_diameter_mm / 2 if fx.aperture else -1.0, bool(fx.cos4),
                           int(rays_per_pixel), int(seed), out)
    return out


def render_views(camera: PlenopticCamera, scene: Scene, rays_per_pixel: int = 16, seed: int = 0) -> np.ndarray:
    """Render the sub-aperture views directly, without a raw image (the decoder's reference).

    View ``(u, v)`` of lenslet ``(r, c)`` is the pixel-sized area centred ``(u - (N-1)/2,
    v - (N-1)/2)`` pixels from the lenslet's image centre along the grid's (rotated)
    axes (rays through the lenslet whose cell holds their sensor point, as for
    :func:`render`): the area that :func:`lf_flame.real.decoding.decode`
    resamples from the raw image. Each area takes the random ray shifts of the sensor
    pixel it lies on, so for the perfect grid these are the sensor's own pixels:
    ``raw_to_views(render(...))`` before the sensor's response (not clipped at 1, no noise), equal
    to float rounding on all but about one sample in 10,000 (311 of 3.6 M on the paper camera's
    nominal flames at 16 rays per pixel differ, by up to 3 % of the peak).

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        Noise-free mean radiance (no sensor model), axes as in
        :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    """
    n, R, C = camera.pixels_per_lenslet, camera.n_rows, camera.n_cols
    off = np.arange(n) - (n - 1) / 2
    du = np.stack(np.meshgrid(off, off, indexing="ij"), axis=-1)          # (N, N, 2) along the grid axes
    rot = camera.grid_matrix / camera.grid_pitch
    pts = camera.lenslet_image_centres_px()[None, None] + (du @ rot.T)[:, :, None, None]   # (N, N, R, C, 2)
    pts = pts.reshape(-1, 2)
    H, W = camera.sensor_shape
    # the random shift of the sensor pixel under each area: the perfect grid's views are its raw pixels
    keys = np.clip(np.floor(pts[:, 0]), 0, H - 1) * W + np.clip(np.floor(pts[:, 1]), 0, W - 1)
    out = render_points(camera, scene, pts, keys.astype(np.int64), rays_per_pixel, seed)
    return out.reshape(n, n, R, C)


def _validate_sampling(rays_per_pixel, seed):
    if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
               for v in (rays_per_pixel, seed)):
        raise ValueError(f"rays_per_pixel and seed must be whole numbers. Received: rays_per_pixel={rays_per_pixel!r}, "
                         f"seed={seed!r}")
    if int(rays_per_pixel) != rays_per_pixel or rays_per_pixel < 1:
        raise ValueError(f"rays_per_pixel must be a positive integer. Received: rays_per_pixel={rays_per_pixel!r}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a non-negative integer. Received: seed={seed!r}")


def _uniform_np(key: np.ndarray) -> np.ndarray:
    """NumPy twin of the kernel's SplitMix64 hash: uint64 keys -> float64 in [0, 1)."""
    g, m1, m2 = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
    z = key * g + g
    z = (z ^ (z >> np.uint64(30))) * m1
    z = (z ^ (z >> np.uint64(27))) * m2
    z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) / 9007199254740992.0


def render_reference(camera: PlenopticCamera, scene: Scene, rays_per_pixel: int = 16, seed: int = 0,
                     rows_per_chunk: int = 45) -> np.ndarray:
    """Plain NumPy rendering of the same backward ABCD chain as :func:`render` (slow).

    Every ray is traced explicitly through :func:`backward_chain` with
    :meth:`RayTransferMatrix.apply` in float64, with the same samples as the kernel
    (same hash, same low-discrepancy sequence), vectorised over ``rows_per_chunk``
    sensor rows at a time. It is the kernel's reference in the tests and the NumPy
    baseline of ``make bench-sim``; it has no content culling and no sensor model
    (returns the noise-free mean radiance, float32, shape of :attr:`sensor_shape`).
    """
    _validate_sampling(rays_per_pixel, seed)
    fx = scene.effects
    layers, z, rad, alpha = _stack_layers(camera, scene)
    gap, lenslet_inv, mla_to_lens, lens_inv = backward_chain(camera)
    n, p, pp = camera.pixels_per_lenslet, camera.mla_pitch_mm, camera.pixel_pitch_mm
    H, W = camera.sensor_shape
    tr, tc = rad.shape[1:]
    top, left, h, w = _layer_frames(layers)
    span = 3 if fx.crosstalk else 1
    r4 = _simulate_kernels._R4
    out = np.empty((H, W), np.float32)
    j = np.arange(W)
    x_pix = -(j + 0.5 - W / 2) * pp
    x_len = -(j // n + 0.5 - camera.n_cols / 2) * p
    for i0 in range(0, H, rows_per_chunk):
        i = np.arange(i0, min(H, i0 + rows_per_chunk))[:, None]
        y_pix = (i + 0.5 - H / 2) * pp
        y_len = (i // n + 0.5 - camera.n_rows / 2) * p
        with np.errstate(over="ignore"):
            key = np.uint64(seed) * np.uint64(0x632BE59BD9B4E019) + ((i * W + j) * 4).astype(np.uint64)
        rot = [_uniform_np(key + np.uint64(d)).astype(np.float32) for d in range(4)]
        acc = np.zeros((len(i), W))
        for k in range(rays_per_pixel):
            u = []
            for d in range(4):
                v = np.float32((0.5 + (k + 1) * r4[d]) % 1.0) + rot[d]
                u.append(np.where(v >= 1, v - np.float32(1), v))
            du_y, du_x = u[0] - np.float32(0.5), u[1] - np.float32(0.5)
            da_y = u[2] * np.float32(span) - np.float32(span / 2)
            da_x = u[3] * np.float32(span) - np.float32(span / 2)
            o_y, o_x = np.floor(da_y + np.float32(0.5)), np.floor(da_x + np.float32(0.5))
            weight = np.ones_like(acc)
            if fx.crosstalk:
                r_l, c_l = i // n + o_y, j // n - o_x
                weight[(r_l < 0) | (r_l >= camera.n_rows) | (c_l < 0) | (c_l >= camera.n_cols)] = 0.0
            rays = []
            for s_pix, s_len, du, da, o in ((y_pix, y_len, du_y, da_y, o_y), (x_pix, x_len, du_x, da_x, o_x)):
                y_s, y_l, y_c = s_pix + du * pp, s_len + da * p, s_len + o * p
                _, t = gap.apply(y_s, (y_l - gap.A * y_s) / gap.B)
                _, t = lenslet_inv.apply(y_l - y_c, t)
                y_m, t_m = mla_to_lens.apply(y_l, t)
                y_o, t_o = lens_inv.apply(y_m, t_m)
                rays.append((y_m, t_m, y_o, t_o))
            (ym, tmy, yo, toy), (xm, tmx, xo, tox) = rays
            if fx.aperture:
                weight[~camera.aperture_stop.passes(ym, xm)] = 0.0
            if fx.cos4:
                weight /= (1.0 + tmy ** 2 + tmx ** 2) ** 2
            val = np.zeros_like(acc)
            trans = np.ones_like(acc)
            for li in range(len(layers)):
                fr = (top[li] - (yo - z[li] * toy)) / h[li] * tr
                fc = ((xo - z[li] * tox) - left[li]) / w[li] * tc
                inside = (fr >= 0) & (fr < tr) & (fc >= 0) & (fc < tc)
                ir = np.clip(fr, 0, tr - 1).astype(np.int64)
                ic = np.clip(fc, 0, tc - 1).astype(np.int64)
                t = trans * inside
                val += t * rad[li, ir, ic]
                if fx.occlusion:
                    trans = trans - t * alpha[li, ir, ic]
            acc += weight * val
        out[i0:i0 + len(i)] = acc * (span * span / rays_per_pixel)
    return out


def apply_sensor(raw: np.ndarray, effects, seed: int) -> np.ndarray:
    """Sensor response: shot and read noise (seeded), saturation at 1, quantisation.

    Each step runs only if the effects ask for it. ``raw`` (any shape, float32) is
    modified in place and returned.
    """
    if effects.full_well_e is not None:
        rng = np.random.default_rng([int(seed), 0x5E4])
        electrons = rng.poisson(np.clip(raw, 0, None) * effects.full_well_e).astype(np.float32)
        if effects.read_noise_e:
            electrons += rng.normal(0.0, effects.read_noise_e, raw.shape).astype(np.float32)
        raw[...] = electrons / effects.full_well_e
    np.clip(raw, 0.0, 1.0, out=raw)
    if effects.bit_depth is not None:
        levels = 2 ** int(effects.bit_depth) - 1
        raw[...] = np.round(raw * levels) / levels
    return raw
