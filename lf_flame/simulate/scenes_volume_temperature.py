"""A colour axisymmetric volumetric flame with a temperature field, for temperature per voxel.

:func:`lf_flame.simulate.scenes_volume.axisymmetric_flame_scene` gives the soot (its emission
density ``e(r, y)``, a luminous sheath, a filled core or a blend, about any vertical axis,
sampled as thin layers); :func:`axisymmetric_temperature_field` gives each point a
temperature ``T(r, y)``, hottest on the sheath and cooling along the height
(:func:`lf_flame.simulate.scenes_temperature.flame_temperature` in the sheath's normalised
coordinates); each layer's emission in channel ``c`` is, as in
:mod:`lf_flame.simulate.scenes_temperature`,
``exposure · g_c · soot · ∫ S_c(λ) (λ/λ0)^-1.39 B(λ, T) dλ``. The truth per voxel is the
per-channel emission (:func:`lf_flame.temperature.channels.colour_truth`-like, on a dense stack) and
the temperature; on the axisymmetric model's ``(r, y)`` nodes it is
:func:`axisymmetric_node_truth`.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.colour import ALPHA_SOOT, ColourSensor, band_integrals
from .scenes import _layer_grid
from .layers import Scene
from .scenes_temperature import FLAME_BASE_K, SHEATH_XI, ColourFlameScene, flame_temperature
from .scenes_volume import axisymmetric_flame_scene, sheath_density


def _geometry(obj):
    try:
        return (float(obj["diameter_mm"]), float(obj["height_mm"]), float(obj["base_y_mm"]), float(obj["core"]))
    except (KeyError, TypeError) as exc:
        raise ValueError(f"an axisymmetric volume object (diameter_mm, height_mm, base_y_mm, core) is needed: {exc}") \
            from None


def axisymmetric_temperature_field(r_mm, y_mm, obj: dict, peak_k: float, base_k: float = FLAME_BASE_K):
    """Temperature (K) of an axisymmetric flame at distance ``r_mm`` from its axis and height ``y_mm``.

    With ``eta = (y - base_y) / H`` and the sheath's radius ``R(eta) = 0.4 D sqrt(1 - eta)``
    (the luminous sheath of :func:`~lf_flame.simulate.scenes_volume.axisymmetric_flame_scene`,
    thickness ``s = 0.08 D``), the normalised radius is ``xi = 0.82 r / max(R, s)``, so the
    hottest point of :func:`~lf_flame.simulate.scenes_temperature.flame_temperature`
    (``xi = 0.82``) lies on the sheath: ``T = base + (peak - base) (0.5 + 0.5 exp(-((xi -
    0.82) / 0.25)^2)) (1 - 0.4 eta)``. Hottest in the annular reaction zone low in the flame,
    cooling towards the axis, outwards and along the height (the shape reported for laminar
    ethylene diffusion flames: Santoro, Semerjian & Dobbins, Combust. Flame 51 (1983)
    203-218; a model, not a fit). At ``peak`` 2,100 K it spans about 1,680-2,100 K where the
    soot emits.

    Parameters
    ----------
    r_mm, y_mm : array_like, broadcastable
        Distance from the axis (mm, >= 0) and height (mm, y up, 0 on the optical axis).
    obj : dict
        The scene's volume object (``diameter_mm``, ``height_mm``, ``base_y_mm``).
    peak_k, base_k : float
        Sheath (hottest) and base temperatures, K, ``0 < base_k < peak_k``.

    Returns
    -------
    ndarray broadcast from ``r_mm`` and ``y_mm``, K.

    Raises
    ------
    ValueError
        A negative or non-finite radius, an object without the geometry, and the errors of
        :func:`~lf_flame.simulate.scenes_temperature.flame_temperature`.
    """
    D, H, base_y, _ = _geometry(obj)
    r = np.asarray(r_mm, float)
    if not np.all(np.isfinite(r)) or np.any(r < 0):
        raise ValueError("r_mm must be finite and >= 0")
    eta = (np.asarray(y_mm, float) - base_y) / H
    R = 0.4 * D * np.sqrt(np.clip(1.0 - eta, 0.0, 1.0))
    xi = SHEATH_XI * r / np.maximum(R, 0.08 * D)
    return flame_temperature(eta, xi, float(peak_k), float(base_k))


def axisymmetric_density(r_mm, y_mm, obj: dict) -> np.ndarray:
    """The soot emission density ``e(r, y)`` of the volume (relative, the generator's formula before its scaling).

    :func:`~lf_flame.simulate.scenes_volume.sheath_density` at ``eta = (y - base_y) / H`` (as
    :func:`~lf_flame.simulate.scenes_volume.axisymmetric_flame_scene` draws it); multiply by the
    object's ``peak_emission`` for the layers' units per mm of depth.

    Returns
    -------
    ndarray broadcast from ``r_mm`` and ``y_mm``.
    """
    D, H, base_y, core = _geometry(obj)
    return sheath_density(np.asarray(r_mm, float), (np.asarray(y_mm, float) - base_y) / H, D, core)


#: Temperature step (K) of the band-integral table the layers are interpolated from (log-linear; its
#: relative error, about (step^2 / 8) d^2 ln I / dT^2 < 1e-6, is far below the renders' own error).
TABLE_STEP_K = 0.25


def _band_table(sensor, temps, alpha):
    """``band_integrals(sensor, temps, alpha, gains=True)`` (..., 3) by log-linear interpolation in a table
    over the temperatures' range every :data:`TABLE_STEP_K` (the direct integral of millions of texels takes minutes)."""
    t = np.asarray(temps, float)
    lo, hi = float(t.min()), float(t.max())
    grid = np.arange(lo, hi + 2 * TABLE_STEP_K, TABLE_STEP_K)
    logi = np.log(band_integrals(sensor, grid, alpha, gains=True))
    return np.stack([np.exp(np.interp(t, grid, logi[:, c])) for c in range(3)], axis=-1)


def colour_axisymmetric_scene(camera: PlenopticCamera, sensor: ColourSensor, rng: np.random.Generator | None = None, *,
                              peak_k: float = 2100.0, base_k: float = FLAME_BASE_K, alpha: float = ALPHA_SOOT,
                              peak: float = 0.8, centre_depth_mm: float = 0.0, centre_x_mm: float = 0.0,
                              diameter_mm: float = 10.0, height_mm: float | None = None, core: float = 0.0,
                              n_layers: int = 32, texels_per_lenslet: float = 3.0) -> ColourFlameScene:
    """An axisymmetric volumetric flame with soot and a temperature field, seen by a colour sensor.

    The soot is the emission of
    :func:`~lf_flame.simulate.scenes_volume.axisymmetric_flame_scene` (same keywords; each
    layer's radiance is the density times the layer's thickness), the temperature
    :func:`axisymmetric_temperature_field` at each texel's distance from the axis; channel
    ``c`` of a layer is ``exposure · g_c · soot · ∫ S_c (λ/λ0)^-alpha B(λ, T) dλ``
    (:func:`lf_flame.optics.colour.band_integrals`), the exposure bringing the brightest
    line of sight (the layers' texels summed, as the generator scales the monochrome
    volume) of any channel to ``peak``.

    Parameters
    ----------
    camera : PlenopticCamera
    sensor : ColourSensor
        Its sensitivities and gains make the channels' emission.
    rng : numpy.random.Generator or None
        Jitters the height by ±10 % (as the monochrome generator).
    peak_k, base_k : float
        Sheath and base temperatures, K (``0 < base_k < peak_k``).
    alpha : float
        Soot emissivity exponent (:data:`~lf_flame.optics.colour.ALPHA_SOOT`, Hottel & Broughton 1932).
    peak : float
        Brightest line of sight of any channel, in (0, 1] (1 saturates).
    centre_depth_mm, centre_x_mm, diameter_mm, height_mm, core, n_layers, texels_per_lenslet
        As :func:`~lf_flame.simulate.scenes_volume.axisymmetric_flame_scene`.

    Returns
    -------
    ColourFlameScene
        ``scene.name == "colour_axisymmetric"``; ``channel_radiance``, ``temperature_k`` and
        ``soot`` per layer (nearest first); the object gains ``peak_k``, ``base_k``,
        ``alpha`` and ``exposure``.

    Raises
    ------
    ValueError
        ``peak`` outside (0, 1], ``peak_k`` not above ``base_k``, and the errors of
        :func:`~lf_flame.simulate.scenes_volume.axisymmetric_flame_scene`.
    """
    if not (0 < peak <= 1):
        raise ValueError(f"peak must be in (0, 1]. Received: {peak!r}")
    if not (0 < base_k < peak_k and math.isfinite(peak_k)):
        raise ValueError(f"need 0 < base_k < peak_k. Received: base_k={base_k!r}, peak_k={peak_k!r}")
    mono = axisymmetric_flame_scene(camera, rng, centre_depth_mm=centre_depth_mm, centre_x_mm=centre_x_mm,
                                    diameter_mm=diameter_mm, height_mm=height_mm, core=core, n_layers=n_layers,
                                    texels_per_lenslet=texels_per_lenslet)
    obj = mono.objects[0]
    temps, soots = [], []
    for L in mono.layers:
        y, x, _, _ = _layer_grid(camera, L.depth_offset_mm, texels_per_lenslet, 1.2)
        r = np.hypot(x - centre_x_mm, L.depth_offset_mm - centre_depth_mm)
        temps.append(np.broadcast_to(axisymmetric_temperature_field(r, y, obj, peak_k, base_k), L.radiance.shape).copy())
        soots.append(np.asarray(L.radiance, float))
    bands = _band_table(sensor, np.stack(temps), alpha)                     # (layers, rows, cols, 3)
    rad = [s[None] * np.moveaxis(b, -1, 0) for s, b in zip(soots, bands)]
    exposure = peak / max(float(np.max(sum(rad))), 1e-300)
    chans = tuple((c * exposure).astype(np.float32) for c in rad)
    layers = tuple(dataclasses.replace(L, radiance=c[1]) for L, c in zip(mono.layers, chans))
    o = dict(obj, peak_k=float(peak_k), base_k=float(base_k), alpha=float(alpha), exposure=exposure)
    return ColourFlameScene(Scene("colour_axisymmetric", layers, mono.effects, (o,)), chans, tuple(temps),
                            tuple(soots), exposure)


def axisymmetric_node_truth(scene: ColourFlameScene, sensor: ColourSensor, radii_mm, heights_mm):
    """The truth on an axisymmetric model's ``(y, r)`` nodes: temperature and per-channel emission density.

    Parameters
    ----------
    scene : ColourFlameScene
        From :func:`colour_axisymmetric_scene`.
    sensor : ColourSensor
        The sensor the scene was made with (its gains).
    radii_mm : ndarray of shape (n_r,)
        Distances from the axis (mm, >= 0), e.g. ``AxisymmetricVolume.radii_mm``.
    heights_mm : ndarray of shape (rows,)
        Heights (mm, y up), e.g. ``AxisymmetricVolume.heights_mm``.

    Returns
    -------
    temperature : ndarray of shape (rows, n_r), K
    emission : ndarray of shape (3, rows, n_r)
        Channels R, G, B, recorded units per mm of depth (the layers' radiance over their
        thickness; times a plane spacing: the planes' units).

    Raises
    ------
    ValueError
        A scene not made by :func:`colour_axisymmetric_scene`, radii negative or not 1-D.
    """
    if scene.scene.name != "colour_axisymmetric":
        raise ValueError(f"a colour_axisymmetric scene is needed. Received: {scene.scene.name!r}")
    o = scene.scene.objects[0]
    r = np.asarray(radii_mm, float)
    y = np.asarray(heights_mm, float)
    if r.ndim != 1 or y.ndim != 1:
        raise ValueError(f"radii_mm and heights_mm must be 1-D. Received: {r.shape}, {y.shape}")
    T = axisymmetric_temperature_field(r[None, :], y[:, None], o, o["peak_k"], o["base_k"])
    dens = axisymmetric_density(r[None, :], y[:, None], o) * o["peak_emission"]
    em = dens[None] * np.moveaxis(band_integrals(sensor, T, o["alpha"], gains=True), -1, 0) * o["exposure"]
    return T, em


def axisymmetric_voxel_truth(scene: ColourFlameScene, sensor: ColourSensor, op):
    """The truth at the centre of each voxel of a stack of planes: temperature and per-channel emission density.

    Each voxel's centre (its plane's depth, its row's height and its column's lateral
    position on the plane's grid) gives its distance from the axis; the temperature and the
    emission are the analytic fields there (:func:`axisymmetric_temperature_field`,
    :func:`axisymmetric_density`): what an axisymmetric model sampled at the voxels holds, where
    :func:`lf_flame.tomo.truth.scene_truth` gives each plane the thin layers around it (a slab
    average, emission-weighted in temperature).

    Parameters
    ----------
    scene : ColourFlameScene
        From :func:`colour_axisymmetric_scene`.
    sensor : ColourSensor
        The sensor the scene was made with.
    op : object with ``dims`` (P, rows, cols), ``depths_mm``, ``sizes_mm`` and ``centres_mm``
        The planes (e.g. an :class:`lf_flame.tomo.exact.ExactOperator`).

    Returns
    -------
    temperature : ndarray of shape (P, rows, cols), K
    emission : ndarray of shape (3, P, rows, cols)
        Channels R, G, B, recorded units per mm of depth (as :func:`axisymmetric_node_truth`).

    Raises
    ------
    ValueError
        A scene not made by :func:`colour_axisymmetric_scene`.
    """
    if scene.scene.name != "colour_axisymmetric":
        raise ValueError(f"a colour_axisymmetric scene is needed. Received: {scene.scene.name!r}")
    o = scene.scene.objects[0]
    P, gr, gc = op.dims
    T = np.zeros((P, gr, gc))
    em = np.zeros((3, P, gr, gc))
    for p in range(P):
        h, w = op.sizes_mm[p]
        cy, cx = op.centres_mm[p]
        y = cy + (0.5 - (np.arange(gr) + 0.5) / gr) * h
        x = cx + ((np.arange(gc) + 0.5) / gc - 0.5) * w
        r = np.hypot(x - o["centre_x_mm"], op.depths_mm[p] - o["depth_offset_mm"])[None, :]
        T[p] = axisymmetric_temperature_field(r, y[:, None], o, o["peak_k"], o["base_k"])
        dens = axisymmetric_density(r, y[:, None], o) * o["peak_emission"] * o["exposure"]
        em[:, p] = dens[None] * np.moveaxis(band_integrals(sensor, T[p], o["alpha"], gains=True), -1, 0)
    return T, em
