"""What a scene is made of: planar layers of radiance (:class:`Layer`), the physical effects the scene asks the
simulator for (:class:`Effects`), and the two together with a record of each object (:class:`Scene`); the share
of a scene's light outside a camera's field (:func:`light_outside_field`). The scenes themselves:
:mod:`lf_flame.simulate.scenes` and its siblings.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..optics.camera import PlenopticCamera


@dataclass(frozen=True)
class Effects:
    """Physical effects a scene asks the simulator for. Off costs nothing.

    Attributes
    ----------
    aperture : bool
        Main-lens aperture function A(u, v) of the paper's Eq. 1: rays outside the
        circular clear aperture are lost, which vignettes the corners of each
        lenslet image. Off: an unbounded lens.
    cos4 : bool
        The cos⁴θ fall-off of Eq. 1, θ the angle of the ray between main lens and MLA.
    occlusion : bool
        Opaque layers hide what lies behind them (front-to-back alpha compositing);
        off: optically thin layers whose emission adds up (flames).
    crosstalk : bool
        Light may reach a pixel through the neighbouring lenslets as well as its own
        (rays sampled over the 3 × 3 lenslets around the pixel's own; the main-lens
        aperture decides which pass). Zero for an f-number-matched camera, whose
        lenslet images just tile the sensor; on when the main lens is faster than the
        lenslets and their images overlap. Off: each pixel sees its own lenslet only.
    read_noise_e, full_well_e : float or None
        Sensor noise: Poisson shot noise for a full well of ``full_well_e`` electrons at
        radiance 1 and Gaussian read noise of ``read_noise_e`` electrons. None: noise-free.
    bit_depth : int or None
        Quantise the raw image to this many bits (1 to :data:`MAX_BIT_DEPTH`); None keeps float32.

    Raises
    ------
    ValueError
        A full well that is not finite and positive, a read noise that is not finite and >= 0 or is given
        without a full well (electrons need the full well to become radiance), a bit depth that is not a whole
        number from 1 to :data:`MAX_BIT_DEPTH`.
    """

    aperture: bool = True
    cos4: bool = True
    occlusion: bool = True
    crosstalk: bool = False
    full_well_e: float | None = None
    read_noise_e: float | None = None
    bit_depth: int | None = None

    def __post_init__(self):
        fw, rn, bits = self.full_well_e, self.read_noise_e, self.bit_depth
        if fw is not None and not (_real(fw) and math.isfinite(fw) and fw > 0):
            raise ValueError(f"full_well_e must be a finite number of electrons > 0, or None (noise-free). "
                             f"Received: {fw!r}")
        if rn is not None and not (_real(rn) and math.isfinite(rn) and rn >= 0):
            raise ValueError(f"read_noise_e must be a finite number of electrons >= 0, or None. Received: {rn!r}")
        if rn and fw is None:
            raise ValueError(f"read_noise_e={rn!r} needs full_well_e (the electrons at radiance 1) to become "
                             "radiance: give both, or neither for a noise-free sensor")
        if bits is not None and not (_real(bits) and float(bits).is_integer() and 1 <= bits <= MAX_BIT_DEPTH):
            raise ValueError(f"bit_depth must be a whole number of bits from 1 to {MAX_BIT_DEPTH}, or None (float32). "
                             f"Received: {bits!r}")


#: The most bits :class:`Effects` quantises to (``--bit-depth``'s range; past 24 a float32 raw image is unchanged).
MAX_BIT_DEPTH = 32


def _real(x) -> bool:
    """A real number (Python's or NumPy's), not a bool."""
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


@dataclass(frozen=True)
class Layer:
    """A planar layer of a scene.

    Attributes
    ----------
    radiance : ndarray of shape (rows, cols), float32
        Emitted radiance, >= 0, in units where 1 saturates the sensor. Row 0 is the top.
    alpha : ndarray of shape (rows, cols), float32, or None
        Opacity in [0, 1] (used when the scene's effects ask for occlusion); None: 0.
    depth_offset_mm : float
        Distance beyond the focal plane (mm), positive = farther from the camera.
    centre_mm : (float, float)
        Object-space centre (y up, x right) of the texture, mm.
    size_mm : (float, float)
        Height and width covered by the texture, mm.
    """

    radiance: np.ndarray
    alpha: np.ndarray | None
    depth_offset_mm: float
    centre_mm: tuple[float, float]
    size_mm: tuple[float, float]


@dataclass(frozen=True)
class Scene:
    """Layers, the effects they need, and a record of each object for search and provenance.

    ``objects`` holds one dict per object: name, depth_offset_mm, the parameters drawn,
    and ``roi`` = (row0, row1, col0, col1) in lenslets, its box in the refocused image.
    """

    name: str
    layers: tuple[Layer, ...]
    effects: Effects
    objects: tuple[dict, ...] = field(default_factory=tuple)


def light_outside_field(scene: Scene, camera: PlenopticCamera) -> float:
    """The share of a scene's emitted light (its layers' radiance summed over their texels) that lies outside the
    camera's field of view at each layer's depth (:meth:`~lf_flame.optics.camera.PlenopticCamera.field_of_view_mm`,
    centred on the axis): how far a flame is cut by the field's edge. 0 for a scene without light."""
    total = outside = 0.0
    for layer in scene.layers:
        rad = np.asarray(layer.radiance, np.float64)
        (h, w), (cy, cx) = layer.size_mm, layer.centre_mm
        fh, fw = camera.field_of_view_mm(layer.depth_offset_mm)
        y = cy + (0.5 - (np.arange(rad.shape[0]) + 0.5) / rad.shape[0]) * h      # texel centres, y up
        x = cx + ((np.arange(rad.shape[1]) + 0.5) / rad.shape[1] - 0.5) * w
        inside = (np.abs(y)[:, None] <= fh / 2) & (np.abs(x)[None, :] <= fw / 2)
        total += float(rad.sum())
        outside += float(rad[~inside].sum())
    return outside / total if total > 0 else 0.0
