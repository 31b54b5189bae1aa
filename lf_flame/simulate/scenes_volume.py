"""Volumetric flames: axisymmetric (a luminous sheath, a filled core, or a mix, about any
vertical axis) and non-axisymmetric (a leaning sheath with a brighter lobe inside).

:func:`volume_flame_scene` draws the sheath on the optical axis;
:func:`axisymmetric_flame_scene` draws the same sheath, a filled core or a blend of both,
with its axis at any lateral position and depth; :func:`nonaxisymmetric_flame_scene` the sheath
about an axis leaning in depth with a Gaussian lobe on one side; all sampled as thin layers, their
density :func:`sheath_density`.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import PlenopticCamera
from .scenes import FLAME_EFFECTS, _layer_grid, _roi
from .layers import Layer, Scene


def sheath_density(r_mm, eta, diameter_mm: float, core: float = 0.0):
    """Relative emission density of a laminar flame's luminous sheath blended with a filled core.

    ``env(eta) [(1 - core) exp(-(r - R)^2 / (2 s^2)) + core exp(-r^2 / (2 (R/2 + s)^2))]``: the
    sheath (Burke & Schumann 1928) of radius ``R(eta) = 0.4 D sqrt(1 - eta)`` and thickness
    ``s = 0.08 D``, ``env(eta) = sin(pi eta^0.75)`` on ``0 <= eta <= 1`` (0 outside); the core
    (``core`` in [0, 1]) of half the sheath's radius. The density of every volume generator
    (:func:`volume_flame_scene`, :func:`axisymmetric_flame_scene`,
    :func:`nonaxisymmetric_flame_scene`'s sheath,
    :func:`lf_flame.simulate.scenes_volume_temperature.axisymmetric_density`).

    Parameters
    ----------
    r_mm : array_like
        Distance from the axis (mm).
    eta : array_like, broadcastable with ``r_mm``
        Height above the base over the flame height.
    diameter_mm : float
        ``D`` (mm).
    core : float

    Returns
    -------
    ndarray broadcast from ``r_mm`` and ``eta``.
    """
    s = 0.08 * diameter_mm
    R = 0.4 * diameter_mm * np.sqrt(np.clip(1.0 - eta, 0.0, 1.0))
    env = np.where((eta >= 0) & (eta <= 1), np.sin(np.pi * np.clip(eta, 0, 1) ** 0.75), 0.0)
    shape = np.exp(-(r_mm - R) ** 2 / (2 * s ** 2))
    shape = (1.0 - core) * shape + core * np.exp(-r_mm ** 2 / (2 * (R / 2 + s) ** 2)) if core else shape
    return env * shape


def _axisymmetric_layers(camera, rng, centre_depth_mm, centre_x_mm, diameter_mm, height_mm, core, n_layers,
                         texels_per_lenslet, field_margin=1.2):
    """:func:`volume_flame_scene`'s sheath blended with a filled core (``core`` in [0, 1]) about the axis at
    ``(centre_x_mm, centre_depth_mm)``: (layers, height, base y, layer depths, thickness, peak per mm)."""
    if int(n_layers) < 2 or not diameter_mm > 0:
        raise ValueError(f"need n_layers >= 2 and diameter_mm > 0. Received: {n_layers}, {diameter_mm}")
    h0, _ = camera.field_of_view_mm(0.0)
    H = (0.8 * h0 if height_mm is None else float(height_mm)) * (rng.uniform(0.9, 1.1) if rng is not None else 1.0)
    dzs = centre_depth_mm + (np.arange(n_layers) + 0.5) / n_layers * diameter_mm - diameter_mm / 2
    thick, base_y, raw = diameter_mm / n_layers, -0.45 * h0, []
    for dz in dzs:
        camera.image_distance_mm(camera.object_distance_mm(dz))
        y, x, (h, w), _ = _layer_grid(camera, dz, texels_per_lenslet, field_margin)
        r = np.sqrt((x - centre_x_mm) ** 2 + (dz - centre_depth_mm) ** 2)
        raw.append((dz, h, w, sheath_density(r, (y - base_y) / H, diameter_mm, core)))
    peak = 0.9 / (thick * max(float(np.max(sum(e for *_, e in raw))), 1e-12))   # brightest line of sight -> 0.9
    layers = tuple(Layer((e * peak * thick).astype(np.float32), None, float(dz), (0.0, 0.0), (h, w))
                   for dz, h, w, e in raw)
    return layers, H, base_y, dzs, thick, peak


def volume_flame_scene(camera: PlenopticCamera, rng: np.random.Generator | None = None, *,
                       centre_depth_mm: float = 0.0, diameter_mm: float = 10.0, height_mm: float | None = None,
                       n_layers: int = 24, texels_per_lenslet: float = 3.0, centre_x_mm: float = 0.0,
                       field_margin: float = 1.2) -> Scene:
    """An axisymmetric emitting volume (a laminar diffusion flame) sampled as thin layers.

    Emission density ``e(r, y) = env(eta) exp(-(r - R(eta))^2 / (2 s^2))``: a luminous
    sheath (Burke & Schumann 1928) of radius ``R(eta) = 0.4 D sqrt(1 - eta)`` and
    thickness ``s = 0.08 D`` around the axis (``r`` from the axis, in x and depth), with
    ``env(eta) = sin(pi eta^0.75)`` along the height (``eta`` = height above the base /
    flame height). Layer ``k`` stands for the slab ``centre ± D/2`` cut in ``n_layers``
    equal parts, at the slab's middle, with radiance ``e`` times the slab thickness (its
    emission integrated through the slab), scaled so the brightest line of sight
    carries 0.9 (no saturation). ``rng``, if given, jitters the height by ±10 %.
    ``centre_x_mm`` moves the axis sideways (mm, x right; a flame cut by the field's edge where it
    reaches past it, its whole width drawn with ``field_margin``: each layer's extent as a multiple of
    the field of view at its depth, about ``2 (|centre_x_mm| + 0.9 diameter_mm) / width``; the default
    1.2 clips a flame that reaches farther).

    Returns
    -------
    Scene
        ``n_layers`` layers nearest first; one object ``name="volume"`` with the centre
        depth and lateral position, diameter, height, base, ``layer_depths_mm``, ``layer_thickness_mm``
        and the ``peak_emission`` (per mm of depth) of the scaled density.

    Raises
    ------
    ValueError
        Fewer than 2 layers, a non-positive diameter, a non-finite axis, a slab the camera cannot image.
    """
    sc = axisymmetric_flame_scene(camera, rng, centre_depth_mm=centre_depth_mm, centre_x_mm=centre_x_mm,
                                  diameter_mm=diameter_mm, height_mm=height_mm, core=0.0, n_layers=n_layers,
                                  texels_per_lenslet=texels_per_lenslet, field_margin=field_margin)
    obj = {k: v for k, v in sc.objects[0].items() if k != "core"}      # the sheath alone
    return Scene("volume", sc.layers, sc.effects, (obj,))


def axisymmetric_flame_scene(camera: PlenopticCamera, rng: np.random.Generator | None = None, *,
                             centre_depth_mm: float = 0.0, centre_x_mm: float = 0.0, diameter_mm: float = 10.0,
                             height_mm: float | None = None, core: float = 0.0, n_layers: int = 32,
                             texels_per_lenslet: float = 3.0, field_margin: float = 1.2) -> Scene:
    """An axisymmetric emitting volume (a laminar flame) about a vertical axis, sampled as thin layers.

    Emission density ``e(r, y) = env(eta) [(1 - core) exp(-(r - R)^2 / (2 s^2)) + core exp(-r^2 / (2 (R/2 + s)^2))]``:
    the luminous sheath of :func:`volume_flame_scene` (radius
    ``R(eta) = 0.4 D sqrt(1 - eta)``, thickness ``s = 0.08 D``; Burke & Schumann 1928) blended
    with a filled core (soot across the whole cross-section, as in a sooting laminar flame's
    upper part) of half the sheath's radius; ``env(eta) = sin(pi eta^0.75)``, ``eta`` the
    height above the base over the flame height, ``r`` the distance from the axis at
    ``(x, depth) = (centre_x_mm, centre_depth_mm)``. Layer ``k`` stands for the slab
    ``centre ± D/2`` cut in ``n_layers`` equal parts, at its middle, with radiance ``e`` times
    the slab's thickness; scaled so the brightest line of sight carries 0.9 (no saturation).
    ``rng``, if given, jitters the height by ±10 %.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator or None
    centre_depth_mm, centre_x_mm : float
        The axis: depth (mm from the focal plane, positive farther) and lateral position (mm, x right).
    diameter_mm : float
        ``D`` (mm), > 0.
    height_mm : float or None
        Flame height (mm); None: 0.8 x the field's height at the focal plane.
    core : float
        In [0, 1]: 0 the sheath alone, 1 the filled core alone.
    n_layers : int
        Layers (>= 2).
    texels_per_lenslet : float
    field_margin : float
        Each layer's extent as a multiple of the field of view at its depth: the default
        1.2 clips a flame that reaches farther; a flame cut by the field's edge needs its
        whole width drawn, about ``2 (|centre_x_mm| + 0.9 diameter_mm) / width``.

    Returns
    -------
    Scene
        ``n_layers`` layers nearest first; one object ``name="volume"`` with the axis
        (``depth_offset_mm``, ``centre_x_mm``), diameter, height, base, core, ``layer_depths_mm``,
        ``layer_thickness_mm`` and the ``peak_emission`` (per mm of depth) of the scaled density.

    Raises
    ------
    ValueError
        Fewer than 2 layers, a non-positive diameter, a core outside [0, 1], a non-finite
        axis, a slab the camera cannot image.
    """
    if not 0.0 <= core <= 1.0:
        raise ValueError(f"core must lie in [0, 1]. Received: {core!r}")
    if not (math.isfinite(centre_depth_mm) and math.isfinite(centre_x_mm)):
        raise ValueError(f"the axis must be finite. Received: depth {centre_depth_mm!r}, x {centre_x_mm!r}")
    layers, H, base_y, dzs, thick, peak = _axisymmetric_layers(camera, rng, centre_depth_mm, centre_x_mm, diameter_mm,
                                                               height_mm, core, n_layers, texels_per_lenslet,
                                                               field_margin)
    obj = dict(name="volume", depth_offset_mm=float(centre_depth_mm), centre_x_mm=float(centre_x_mm),
               diameter_mm=float(diameter_mm), height_mm=H, base_y_mm=base_y, core=float(core),
               layer_depths_mm=[float(v) for v in dzs], layer_thickness_mm=thick, peak_emission=peak,
               roi=_roi(camera, centre_depth_mm, base_y, base_y + H, centre_x_mm - diameter_mm / 2,
                        centre_x_mm + diameter_mm / 2))
    return Scene("axisymmetric", layers, FLAME_EFFECTS, (obj,))


def nonaxisymmetric_flame_scene(camera: PlenopticCamera, rng: np.random.Generator | None = None, *,
                                centre_depth_mm: float = 0.0, centre_x_mm: float = 0.0, diameter_mm: float = 10.0,
                                height_mm: float | None = None, tilt_deg: float = 10.0,
                                lobe: tuple[float, float, float] = (1.5, 0.25, 0.5), n_layers: int = 32,
                                texels_per_lenslet: float = 3.0) -> Scene:
    """A volumetric flame that is not axisymmetric: a leaning sheath with a brighter lobe inside, as thin layers.

    Emission density ``e(x, y, z) = env(eta) exp(-(r - R(eta))^2 / (2 s^2)) + a exp(-|p - p_l|^2 / (2 s_l^2))``:
    the luminous sheath of :func:`volume_flame_scene` (radius
    ``R(eta) = 0.4 D sqrt(1 - eta)``, thickness ``s = 0.08 D``, ``env(eta) = sin(pi eta^0.75)``;
    Burke & Schumann 1928) about an axis that leans in depth, ``r`` the distance in (x, depth)
    from ``(centre_x_mm, centre_depth_mm + tan(tilt) (y - y_mid))`` (``y_mid`` the flame's
    mid-height; a flame leaning towards or away from the camera, as in a cross-draught), plus a
    Gaussian lobe (a pocket of hotter soot on one side) of peak ``a`` (relative to the sheath's
    peak 1), width ``s_l = 0.12 D``, centred on the axis at height fraction ``eta_l`` and offset
    from it in depth by ``f_z D``. ``eta`` is the height above the base over the flame height.
    Layer ``k`` stands for the slab ``centre ± (D/2 + |tan tilt| H/2)`` (the flame's true depth
    range) cut in ``n_layers`` equal parts, at its middle, with radiance ``e`` times the slab's
    thickness; scaled so the brightest line of sight carries 0.9 (no saturation). The density
    is cut at the slab. ``rng``, if given, jitters the height by ±10 %, the tilt by ±1° and
    the lobe's peak by ±15 %.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator or None
    centre_depth_mm, centre_x_mm : float
        The axis at mid-height: depth (mm from the focal plane, positive farther) and lateral
        position (mm, x right).
    diameter_mm : float
        ``D`` (mm), > 0.
    height_mm : float or None
        Flame height ``H`` (mm), > 0; None: 0.8 x the field's height at the focal plane.
    tilt_deg : float
        The axis's lean in the y-depth plane (degrees, in (-45, 45)): positive moves higher rows farther.
    lobe : (float, float, float)
        ``(a, f_z, eta_l)``: peak (>= 0; 0 no lobe), depth offset from the axis as a fraction of
        ``D`` (in [-0.5, 0.5]) and height fraction (in [0, 1]).
    n_layers : int
        Layers (>= 2).
    texels_per_lenslet : float

    Returns
    -------
    Scene
        ``n_layers`` layers nearest first; one object ``name="volume"`` with the axis at mid-height
        (``depth_offset_mm``, ``centre_x_mm``), diameter, height, base, tilt, lobe,
        ``layer_depths_mm``, ``layer_thickness_mm``, ``depth_range_mm`` (the slab, mm) and the
        ``peak_emission`` (per mm of depth) of the scaled density.

    Raises
    ------
    ValueError
        Fewer than 2 layers, a non-positive diameter or height, a tilt outside (-45, 45), a
        lobe out of its ranges, a non-finite axis, a slab the camera cannot image.
    """
    if int(n_layers) < 2 or not diameter_mm > 0:
        raise ValueError(f"need n_layers >= 2 and diameter_mm > 0. Received: {n_layers}, {diameter_mm}")
    if not (math.isfinite(centre_depth_mm) and math.isfinite(centre_x_mm)):
        raise ValueError(f"the axis must be finite. Received: depth {centre_depth_mm!r}, x {centre_x_mm!r}")
    if not -45.0 < tilt_deg < 45.0:
        raise ValueError(f"tilt_deg must lie in (-45, 45). Received: {tilt_deg!r}")
    if height_mm is not None and not height_mm > 0:
        raise ValueError(f"height_mm must be > 0. Received: {height_mm!r}")
    if len(lobe) != 3:
        raise ValueError(f"lobe must be (peak, depth offset fraction, height fraction). Received: {lobe!r}")
    amp, fz, eta_l = (float(v) for v in lobe)
    if not (amp >= 0 and -0.5 <= fz <= 0.5 and 0.0 <= eta_l <= 1.0):
        raise ValueError(f"lobe peak must be >= 0, its depth offset in [-0.5, 0.5], its height in [0, 1]. "
                         f"Received: {lobe!r}")
    h0, _ = camera.field_of_view_mm(0.0)
    jit = rng.uniform(-1.0, 1.0, 3) if rng is not None else np.zeros(3)
    H = (0.8 * h0 if height_mm is None else float(height_mm)) * (1.0 + 0.1 * jit[0])
    tilt = float(tilt_deg + jit[1])
    amp *= 1.0 + 0.15 * float(jit[2])
    D, base_y = float(diameter_mm), -0.45 * h0
    half = D / 2 + abs(math.tan(math.radians(tilt))) * H / 2
    dzs = centre_depth_mm + (np.arange(n_layers) + 0.5) / n_layers * 2 * half - half
    thick, sl, y_mid, raw = 2 * half / n_layers, 0.12 * D, base_y + H / 2, []
    for dz in dzs:
        camera.image_distance_mm(camera.object_distance_mm(dz))
        y, x, (h, w), _ = _layer_grid(camera, dz, texels_per_lenslet, 1.2)
        za = centre_depth_mm + math.tan(math.radians(tilt)) * (y - y_mid)        # the leaning axis, per row
        r = np.sqrt((x - centre_x_mm) ** 2 + (dz - za) ** 2)
        yl = base_y + eta_l * H
        zl = centre_depth_mm + math.tan(math.radians(tilt)) * (yl - y_mid) + fz * D
        blob = amp * np.exp(-((x - centre_x_mm) ** 2 + (y - yl) ** 2 + (dz - zl) ** 2) / (2 * sl ** 2))
        raw.append((dz, h, w, sheath_density(r, (y - base_y) / H, D) + blob))
    peak = 0.9 / (thick * max(float(np.max(sum(e for *_, e in raw))), 1e-12))   # brightest line of sight -> 0.9
    layers = tuple(Layer((e * peak * thick).astype(np.float32), None, float(dz), (0.0, 0.0), (h, w))
                   for dz, h, w, e in raw)
    obj = dict(name="volume", depth_offset_mm=float(centre_depth_mm), centre_x_mm=float(centre_x_mm),
               diameter_mm=D, height_mm=float(H), base_y_mm=base_y, tilt_deg=tilt, lobe=(float(amp), fz, eta_l),
               layer_depths_mm=[float(v) for v in dzs], layer_thickness_mm=thick,
               depth_range_mm=(float(centre_depth_mm - half), float(centre_depth_mm + half)), peak_emission=float(peak),
               roi=_roi(camera, centre_depth_mm, base_y, base_y + H, centre_x_mm - D / 2, centre_x_mm + D / 2))
    return Scene("nonaxisymmetric", layers, FLAME_EFFECTS, (obj,))
