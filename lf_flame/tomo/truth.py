"""The truth of a simulated scene on the reconstruction's plane grids.

Each plane's emission (its layers' radiance) resampled by area overlap onto the grid of
:func:`lf_flame.tomo.operator.plane_grid`, so a reconstruction is scored pixel for pixel.
"""
from __future__ import annotations

import numpy as np

from ..simulate.layers import Layer, Scene
from .operator import EmissionOperator


# ---- the truth on a reconstruction grid ----------------------------------------------
def _overlap(src_edges: np.ndarray, dst_edges: np.ndarray) -> np.ndarray:
    """(n_dst, n_src) fraction of each destination cell covered by each source cell
    (1-D, both edge arrays increasing)."""
    lo = np.maximum(dst_edges[:-1, None], src_edges[None, :-1])
    hi = np.minimum(dst_edges[1:, None], src_edges[None, 1:])
    return np.clip(hi - lo, 0.0, None) / np.diff(dst_edges)[:, None]


def resample_layer(layer: Layer, shape, size_mm, centre_mm=(0.0, 0.0)) -> np.ndarray:
    """A layer's radiance averaged over the cells of another grid (area-weighted, exact).

    The renderer reads a texture as piecewise constant (nearest texel), so the average
    of its texels over a cell, weighted by the area they share, is the cell's emission.

    Parameters
    ----------
    layer : Layer
        Texture (rows, cols) over ``layer.size_mm`` about ``layer.centre_mm``.
    shape : (int, int)
        Cells (rows, columns) of the grid.
    size_mm, centre_mm : (float, float)
        Height and width, and centre (y up, x right), of the grid in mm.

    Returns
    -------
    ndarray of shape ``shape``, float64: mean radiance per cell (0 outside the layer).
    """
    (tr, tc), (gr, gc) = layer.radiance.shape, shape
    # both grids' edges in mm, rows measured downward from the top so the edges increase
    src_y = np.linspace(-(layer.centre_mm[0] + layer.size_mm[0] / 2), -(layer.centre_mm[0] - layer.size_mm[0] / 2), tr + 1)
    src_x = np.linspace(layer.centre_mm[1] - layer.size_mm[1] / 2, layer.centre_mm[1] + layer.size_mm[1] / 2, tc + 1)
    dst_y = np.linspace(-(centre_mm[0] + size_mm[0] / 2), -(centre_mm[0] - size_mm[0] / 2), gr + 1)
    dst_x = np.linspace(centre_mm[1] - size_mm[1] / 2, centre_mm[1] + size_mm[1] / 2, gc + 1)
    return _overlap(src_y, dst_y) @ layer.radiance.astype(np.float64) @ _overlap(src_x, dst_x).T


def scene_truth(scene: Scene, op: EmissionOperator) -> np.ndarray:
    """The emission of ``scene`` on the operator's planes: the truth a reconstruction is scored on.

    A scene layer at one of the operator's depths gives that plane its radiance
    (:func:`resample_layer`). Layers between two planes (a volume sampled finer than the
    planes) are shared between the two nearest planes linearly in depth (each plane
    stands for the slab around it); layers outside the planes' range go to the nearest.

    Returns
    -------
    ndarray of shape ``op.dims`` (P, rows, cols), float64.
    """
    truth = np.zeros(op.dims)
    for L in scene.layers:
        for p, wgt in depth_shares(op.depths_mm, L.depth_offset_mm):
            truth[p] += wgt * resample_layer(L, op.dims[1:], op.sizes_mm[p], op.centres_mm[p])
    return truth


def depth_shares(depths_mm, depth_mm: float) -> list:
    """The planes a layer at ``depth_mm`` belongs to, with their shares: the plane at its depth
    (share 1), the two planes around it linearly in depth, or the nearest plane outside their range.

    Parameters
    ----------
    depths_mm : sequence of P float
        The planes' depths (mm), in any order.
    depth_mm : float

    Returns
    -------
    list of (plane index, share) pairs, shares summing to 1.
    """
    d = np.asarray(depths_mm, np.float64)
    order = np.argsort(d)
    ds = d[order]
    k = int(np.searchsorted(ds, depth_mm))
    if k == 0 or k == len(ds) or np.isclose(ds[min(k, len(ds) - 1)], depth_mm):
        return [(int(order[min(k, len(ds) - 1)]), 1.0)]
    f = (depth_mm - ds[k - 1]) / (ds[k] - ds[k - 1])
    return [(int(order[k - 1]), 1.0 - f), (int(order[k]), f)]


def truth_depths(scene: Scene, depths_mm) -> np.ndarray:
    """The true depth of what each plane's truth (:func:`scene_truth`) holds: the mean depth of the
    scene's layers it is the nearest plane to (a share of at least a half, :func:`depth_shares`), weighted by
    their shares and their light; of every layer given to it where none is that near.

    A plane at a found depth (``reconstruct --depths auto``) holds the layer it was found for:
    its truth is titled with that layer's depth, not the found one, nor pulled toward a flame
    between it and the next plane that gives it a sliver of its light (a flame at 0 mm between planes at
    -12.8 and +0.1 mm gave the first 1 % of its light and titled its truth -12.5 mm for a flame at -12.77).

    Parameters
    ----------
    scene : Scene
    depths_mm : sequence of P float
        The planes' depths (mm).

    Returns
    -------
    ndarray of shape (P,), float64
        mm; NaN for a plane given no light.
    """
    P = len(depths_mm)
    light, moment = np.zeros((2, P)), np.zeros((2, P))          # [0] the nearest layers', [1] every layer's
    for L in scene.layers:
        total = float(np.sum(L.radiance, dtype=np.float64)) * L.size_mm[0] * L.size_mm[1] / L.radiance.size
        for p, wgt in depth_shares(depths_mm, L.depth_offset_mm):
            for k in (0, 1) if wgt >= 0.5 else (1,):
                light[k, p] += wgt * total
                moment[k, p] += wgt * total * L.depth_offset_mm
    near = light[0] > 0
    light, moment = np.where(near, light[0], light[1]), np.where(near, moment[0], moment[1])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(light > 0, moment / np.where(light > 0, light, 1.0), np.nan)


def bin_planes(planes, subsamples: int) -> np.ndarray:
    """Planes on a grid of ``subsamples x subsamples`` samples per lenslet, averaged back to one per lenslet.

    What an :class:`~lf_flame.tomo.exact.ExactOperator` with ``subsamples > 1`` recovers,
    on the lenslet grid of the plain operator and its truth (:func:`scene_truth`), so that
    both grids are scored against the same truth: each lenslet's value is the mean of its
    samples, as each truth sample is the mean of the emission over its footprint.

    Parameters
    ----------
    planes : ndarray of shape (P, s rows, s cols)
    subsamples : int
        ``s``, >= 1 (1: returned as float64, unchanged).

    Returns
    -------
    ndarray of shape (P, rows, cols), float64

    Raises
    ------
    ValueError
        A grid that is not a whole number of ``s x s`` blocks.
    """
    x = np.asarray(planes, np.float64)
    s = int(subsamples)
    if s < 1 or x.ndim != 3 or x.shape[1] % s or x.shape[2] % s:
        raise ValueError(f"planes of shape {x.shape} are not (P, rows, cols) in whole {subsamples} x {subsamples} blocks")
    P, r, c = x.shape
    return x.reshape(P, r // s, s, c // s, s).mean(axis=(2, 4))
