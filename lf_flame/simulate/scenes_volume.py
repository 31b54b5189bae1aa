"""Axisymmetric volumetric flames (issue 36, step 2): a luminous sheath, a filled core, or a mix, about any vertical axis.

:func:`lf_flame.simulate.scenes.volume_flame_scene` draws the sheath on the optical axis;
:func:`axisymmetric_flame_scene` draws the same sheath, a filled core or a blend of both,
with its axis at any lateral position and depth, sampled as thin layers.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import PlenopticCamera
from .scenes import FLAME_EFFECTS, Scene, _axisymmetric_layers, _roi


def axisymmetric_flame_scene(camera: PlenopticCamera, rng: np.random.Generator | None = None, *,
                             centre_depth_mm: float = 0.0, centre_x_mm: float = 0.0, diameter_mm: float = 10.0,
                             height_mm: float | None = None, core: float = 0.0, n_layers: int = 32,
                             texels_per_lenslet: float = 3.0) -> Scene:
    """An axisymmetric emitting volume (a laminar flame) about a vertical axis, sampled as thin layers.

    Emission density ``e(r, y) = env(eta) [(1 - core) exp(-(r - R)^2 / (2 s^2)) + core exp(-r^2 / (2 (R/2 + s)^2))]``:
    the luminous sheath of :func:`~lf_flame.simulate.scenes.volume_flame_scene` (radius
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
                                                               height_mm, core, n_layers, texels_per_lenslet)
    obj = dict(name="volume", depth_offset_mm=float(centre_depth_mm), centre_x_mm=float(centre_x_mm),
               diameter_mm=float(diameter_mm), height_mm=H, base_y_mm=base_y, core=float(core),
               layer_depths_mm=[float(v) for v in dzs], layer_thickness_mm=thick, peak_emission=peak,
               roi=_roi(camera, centre_depth_mm, base_y, base_y + H, centre_x_mm - diameter_mm / 2,
                        centre_x_mm + diameter_mm / 2))
    return Scene("axisymmetric", layers, FLAME_EFFECTS, (obj,))
