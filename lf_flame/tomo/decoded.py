"""Decoded views of a user's camera as data of the exact operator, and their truth.

:func:`lf_flame.real.decoding.decode` divides each sample by the white image's: the views
are radiance relative to a white target, with the real camera's vignetting and cos⁴
taken out. The exact operator (:class:`~lf_flame.tomo.exact.ExactOperator` on
:func:`lf_flame.optics.camera_file.decoded_camera`) predicts radiance with its own
vignetting and cos⁴ in. :func:`decoded_problem` multiplies the views by the operator's
own white views (:func:`white_views`), so that they are what the operator predicts, and
says which samples to leave out of the fit. :func:`decoded_truth` puts a simulated
scene's emission on the decoded planes, which are the object's turned by the lenslet
grid's rotation and shifted by the decoded grid's offset from the axis
(:func:`lf_flame.real.own_camera.decoded_frame`).
"""
from __future__ import annotations

import math

import numpy as np

from ..simulate.layers import Scene
from .exact import ExactOperator
from .truth import depth_shares

#: Decoded samples where the model's white view is below this fraction of its largest
#: value are left out of the fit: the rim of the aperture's image, where decoding's own
#: threshold (``decode(min_white=0.05)``) and the model disagree on what is lit.
MIN_WHITE = 0.05


def white_views(op: ExactOperator) -> np.ndarray:
    """The operator's views of a white target: a plane of radiance 1 filling every pixel's rays.

    Each kernel's taps sum to what an unbounded uniform plane gives the view at the field's
    centre (aperture and cos⁴ over the pixel's rays), the same on every plane; times the
    per-pixel cos⁴ drift ``op.weights``.

    Returns
    -------
    ndarray of shape (N, N, R, C), float64
    """
    # (N, N): the same on every plane; a plane's s^2 phase kernels share its taps
    per_view = op.kernels.sum(axis=(3, 4)).mean(axis=2) * op.subsamples ** 2
    return op.to_samples(op.weights * per_view[:, :, None, None])


def decoded_problem(views, op: ExactOperator, clipped=None, *, min_white: float = MIN_WHITE):
    """Decoded (white-normalised) views as the operator's data, and the samples to leave out.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        :func:`lf_flame.real.decoding.decode`'s views, white-normalised.
    op : ExactOperator
        On the views' camera (:func:`lf_flame.real.own_camera.views_camera`).
    clipped : ndarray of bool of the views' shape, or None
        Samples from clipped raw pixels (:func:`lf_flame.real.decoding.clipped_samples`).
    min_white : float
        Samples whose model white is below this fraction of its largest value are left out
        (:data:`MIN_WHITE`).

    Returns
    -------
    data : ndarray of shape (N, N, R, C), float64
        ``views * white_views(op)``: radiance as the operator predicts it.
    leave_out : ndarray of bool of the views' shape
        Clipped or dark samples, for :func:`lf_flame.tomo.solvers.reconstruct`'s ``saturation``.

    Raises
    ------
    ValueError
        Views or a mask of another shape than the operator's, NaN or inf in the views.
    """
    v = np.asarray(views, np.float64)
    if v.shape != tuple(op.dimsd):
        raise ValueError(f"views of shape {v.shape} do not come from this camera: its views are {tuple(op.dimsd)}")
    if not np.all(np.isfinite(v)):
        raise ValueError("views contain NaN or infinite values")
    w = white_views(op)
    leave_out = w < min_white * w.max()
    if clipped is not None:
        c = np.asarray(clipped)
        if c.shape != v.shape or c.dtype != bool:
            raise ValueError(f"clipped must be boolean of the views' shape {v.shape}. Received: {c.dtype} {c.shape}")
        leave_out = leave_out | c
    return np.where(leave_out, 0.0, v * w), leave_out


def _cell_means(layer, y, x, half_mm):
    """Mean radiance of ``layer`` over axis-aligned squares of half-side ``half_mm`` centred at
    object points ``(y, x)`` (mm), exact for its piecewise-constant texture (the renderer reads
    the nearest texel): its summed-area table is bilinear within each texel, so bilinear
    interpolation of it at the squares' corners is exact. 0 outside the layer."""
    from scipy import ndimage
    tr, tc = layer.radiance.shape
    h, w = layer.size_mm
    sat = np.zeros((tr + 1, tc + 1))
    sat[1:, 1:] = np.cumsum(np.cumsum(layer.radiance.astype(np.float64), axis=0), axis=1)
    def corner(yy, xx):   # the table at object points, in texel-corner coordinates (rows from the top)
        ii = np.clip((layer.centre_mm[0] + h / 2 - yy) / h * tr, 0, tr)
        jj = np.clip((xx - layer.centre_mm[1] + w / 2) / w * tc, 0, tc)
        return ndimage.map_coordinates(sat, [ii.ravel(), jj.ravel()], order=1, mode="nearest").reshape(ii.shape)
    top, bottom, left, right = y + half_mm, y - half_mm, x - half_mm, x + half_mm
    total = corner(bottom, right) - corner(top, right) - corner(bottom, left) + corner(top, left)
    return total / ((2 * half_mm / h * tr) * (2 * half_mm / w * tc))


def decoded_truth(scene: Scene, op: ExactOperator, rotation_deg: float = 0.0, centre_lenslets=(0.0, 0.0)) -> np.ndarray:
    """A simulated scene's emission on the planes of decoded views (the truth they are scored on).

    Sample ``(i, j)`` of plane ``k`` is centred at lattice offset ``((i - (R-1)/2) / s, (j - (C-1)/2) / s)
    + centre_lenslets`` (pitches along the grid's axes, from the optical axis; ``s`` the
    operator's samples per lenslet); its object
    point (``-y`` down, ``x`` right) is that offset turned by the grid's rotation, times
    ``pitch z_k / d``. Its value is the layer's mean over the sample's square, exact for the
    piecewise-constant texture (summed-area table), the square taken unrotated: a rotation
    of ``t`` moves its corners by ``t/2`` of a sample (0.0035 at 0.4°), while it moves the
    samples far from the axis by ``t`` times their distance. A layer between two planes
    is shared between them as in :func:`lf_flame.tomo.truth.scene_truth`.

    Parameters
    ----------
    scene : Scene
    op : ExactOperator
        On the decoded views' camera.
    rotation_deg, centre_lenslets : float, (float, float)
        :class:`lf_flame.real.own_camera.DecodedFrame`'s fields. Zero: :func:`scene_truth`'s
        frame and values (to rounding).

    Returns
    -------
    ndarray of shape ``op.dims`` (P, rows, cols), float64.
    """
    truth = np.zeros(op.dims)
    s = getattr(op, "subsamples", 1)
    for L in scene.layers:
        for p, wgt in depth_shares(op.depths_mm, L.depth_offset_mm):
            truth[p] += wgt * decoded_plane_truth(L, op.camera, op.depths_mm[p], op.dims[1:], rotation_deg,
                                                  centre_lenslets, s)
    return truth


def decoded_plane_truth(layer, camera, depth_mm: float, shape, rotation_deg: float = 0.0, centre_lenslets=(0.0, 0.0),
                        subsamples: int = 1) -> np.ndarray:
    """One layer's emission on the grid of a decoded plane at ``depth_mm`` (the layer wherever it
    stands: :func:`decoded_truth`'s samples and values for one plane, without sharing it between
    planes).

    Parameters
    ----------
    layer : lf_flame.simulate.layers.Layer
    camera : PlenopticCamera
        The decoded views' camera.
    depth_mm : float
        The plane's depth (mm from the focus distance).
    shape : (int, int)
        The plane's grid (rows, cols): ``subsamples`` samples per lenslet.
    rotation_deg, centre_lenslets, subsamples
        As :func:`decoded_truth`.

    Returns
    -------
    ndarray of shape ``shape``, float64.
    """
    R, C = shape
    s = subsamples
    ar, ac = np.meshgrid((np.arange(R) - (R - 1) / 2) / s + centre_lenslets[0],
                         (np.arange(C) - (C - 1) / 2) / s + centre_lenslets[1], indexing="ij")
    t = math.radians(rotation_deg)
    q_r = math.cos(t) * ar + math.sin(t) * ac                   # sensor-frame offsets (rows, cols), pitches
    q_c = -math.sin(t) * ar + math.cos(t) * ac
    scale = camera.mla_pitch_mm * camera.object_distance_mm(depth_mm) / camera.mla_distance_mm
    return _cell_means(layer, -q_r * scale, q_c * scale, scale / (2 * s))


def fit_data(light_field, op: ExactOperator):
    """A light field's views as ``op``'s data, and what to leave out of the fit.

    Parameters
    ----------
    light_field : lf_flame.real.lightfield.LightField
        Simulated (radiance) or decoded (white-normalised) views of ``op.camera``.
    op : ExactOperator or EmissionOperator
        On the light field's camera.

    Returns
    -------
    data : ndarray of shape (N, N, R, C), float64
        Decoded views times the operator's white views (:func:`decoded_problem`); other
        views as they are.
    saturation : float, ndarray of bool or None
        :func:`lf_flame.tomo.solvers.reconstruct`'s ``saturation``: decoded views' clipped
        and dark samples, else the light field's mask or clipping level.
    """
    lf = light_field
    if lf.white_normalised:
        return decoded_problem(lf.views, op, lf.leave_out)
    return np.asarray(lf.views, np.float64), lf.fit_mask()
