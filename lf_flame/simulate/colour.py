"""Colour raw images: a plenoptic camera with a colour filter array.

The camera's optics are achromatic ray transfer matrices, so the light of one colour channel
follows the same rays as any other: a colour raw image is the monochrome render of each
channel's band-integrated emission (same rays, same seed), mosaicked by the colour filter
array, with the sensor's noise applied once to the mosaic (:func:`render_colour`). The
monochrome path (:func:`lf_flame.simulate.tracer.render`) is untouched: a scene renders in
colour only when it is given a :class:`~lf_flame.optics.colour.ColourSensor` and per-channel
emission.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.colour import ColourSensor, mosaic
from .layers import Scene
from .tracer import apply_sensor, render


def render_colour(camera: PlenopticCamera, scene: Scene, channel_radiance, sensor: ColourSensor,
                  rays_per_pixel: int = 16, seed: int = 0) -> np.ndarray:
    """Render the raw mosaic of a colour plenoptic camera.

    Each channel's emission is rendered as a monochrome scene (the scene's layers with
    their radiance replaced, same rays and seed, no sensor model), the three images are
    mosaicked by the CFA (:func:`mosaic`) and the scene's sensor effects (shot and read
    noise, saturation, quantisation: :func:`lf_flame.simulate.tracer.apply_sensor`) are
    applied once to the mosaic.

    Parameters
    ----------
    camera : PlenopticCamera
    scene : Scene
        Geometry and effects; its layers' own radiance is not used.
    channel_radiance : sequence of ndarray of shape (3, rows, cols)
        Per layer (the scene's order), the recorded radiance of channels R, G, B
        (gains included, units where 1 saturates the sensor), >= 0.
    sensor : ColourSensor
    rays_per_pixel, seed : int
        As :func:`lf_flame.simulate.tracer.render`.

    Returns
    -------
    raw : ndarray of shape (n_rows * N, n_cols * N), float32

    Raises
    ------
    ValueError
        A channel radiance per layer missing or of the wrong shape, or the errors of
        :func:`lf_flame.simulate.tracer.render`.
    """
    if len(channel_radiance) != len(scene.layers):
        raise ValueError(f"one (3, rows, cols) channel radiance per layer is needed: {len(scene.layers)} layers, "
                         f"{len(channel_radiance)} given")
    for L, cr in zip(scene.layers, channel_radiance):
        if np.shape(cr) != (3,) + L.radiance.shape:
            raise ValueError(f"channel radiance of shape {np.shape(cr)} for a layer of shape {L.radiance.shape}; "
                             f"(3, rows, cols) is needed")
    imgs = []
    for c in range(3):
        layers = tuple(dataclasses.replace(L, radiance=np.asarray(cr[c], np.float32))
                       for L, cr in zip(scene.layers, channel_radiance))
        imgs.append(render(camera, dataclasses.replace(scene, layers=layers), rays_per_pixel, seed, sensor=False))
    raw = mosaic(np.stack(imgs), sensor)
    return apply_sensor(raw, scene.effects, seed)
