"""What the views tell of an axisymmetric flame before any fit: its axis's lateral position, and whether its
light reaches the field's edge (a flame cut by it; :mod:`lf_flame.tomo.axisymmetric` then fits the light from
beyond the field).

- :func:`axis_x_from_views`: the central view (a pinhole image) sees every depth's plane sample ``c`` in its
  column ``c``: the lit columns' centroid is the axis's column, or, where they reach the view's edge, the
  column about which they are most nearly mirror-symmetric.
- :func:`reaches_edge`: which edges the slope-0 image's light reaches.
"""
from __future__ import annotations

import numpy as np

from .revolve import frame_at

#: Weight of the one-sided light in :func:`_mirror_centre`'s cost. Chosen on validation sheaths (``experiments/volume.py
#: --set edge``'s ``EDGE_VAL`` scenes, in a ``/tmp`` probe at 100 rays per pixel): at 14 dB the sheath 11.5 % outside
#: the field has two mirror centres of symmetric cost 0.000, its axis (87 % of the light both sides) and its right limb
#: (28 %), and without the term the limb won (5.25 mm for an axis at 3.5 mm); 0.02 moved the sheath 28.5 % outside
#: 0.1 mm inward, 0.005 found both within 0.05 mm.
MIRROR_ONE_SIDED = 0.005
#: Light in the outermost column or row of the views summed over the aperture (the slope-0 image), as a share of
#: its brightest column's or row's, above which the light reaches that edge of the field (:func:`reaches_edge`): a
#: flame cut by it, whose light from beyond the field :func:`~lf_flame.tomo.axisymmetric.solve_axisymmetric` then
#: models (:func:`~lf_flame.tomo.revolve.wide_operator`).
EDGE_SHARE = 0.05


def reaches_edge(views) -> tuple:
    """Which edges of the field a light field's light reaches (a flame cut by the field's edge).

    The views summed over the aperture (the slope-0 image, which holds the light that
    parallax brings in from beyond the field), less its dark floor (its 5th percentile: the
    mean of clipped noise), are summed along rows and along columns; an edge is reached where
    the outermost column or row holds more than :data:`EDGE_SHARE` of the brightest one.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)

    Returns
    -------
    (bool, bool, bool, bool)
        Top, bottom, left, right.
    """
    img = np.clip(np.asarray(views, np.float64), 0.0, None).sum(axis=(0, 1))
    img = img - np.percentile(img, 5)
    rows, cols = img.sum(axis=1), img.sum(axis=0)
    top_r, top_c = EDGE_SHARE * rows.max(), EDGE_SHARE * cols.max()
    return (bool(rows[0] > top_r), bool(rows[-1] > top_r), bool(cols[0] > top_c), bool(cols[-1] > top_c))


def lit_profile(views):
    """The central view's column sums (clipped at 0), those below 5 % of the largest set to 0: its lit columns.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)

    Returns
    -------
    ndarray of shape (C,), float64
    """
    c = views.shape[0] // 2
    prof = np.clip(np.asarray(views[c, c], np.float64), 0.0, None).sum(axis=0)
    return np.where(prof > 0.05 * prof.max(), prof, 0.0) if prof.max() > 0 else prof


def _mirror_centre(prof):
    """Column (fractional, every 0.1) about which ``prof`` is most nearly mirror-symmetric over the columns both
    sides hold: the lowest ``sum (p - q)^2 / sum (p^2 + q^2)`` there (``q`` the mirror image) plus
    :data:`MIRROR_ONE_SIDED` x the share of the light whose mirror falls beyond the view, so that a limb's own
    symmetry near the edge does not pass for the flame's."""
    C = len(prof)
    cols = np.arange(C)
    lit = np.flatnonzero(prof > 0)
    best, best_cost = None, np.inf
    for c0 in np.arange(lit[0], lit[-1] + 1e-9, 0.1):
        both = (cols >= 2 * c0 - (C - 1)) & (cols <= 2 * c0)
        p = prof[both]
        q = np.interp(2 * c0 - cols[both], cols, prof)
        energy = float(np.sum(p * p + q * q))
        if not energy > 0:
            continue
        cost = float(np.sum((p - q) ** 2)) / energy + MIRROR_ONE_SIDED * (1.0 - p.sum() / prof.sum())
        if cost < best_cost:
            best, best_cost = float(c0), cost
    return best


def axis_x_from_views(views, op, axis_z_mm: float, fit=None) -> float:
    """Lateral position (mm) of a vertical axis of symmetry: the central view's column centroid at depth ``axis_z_mm``.

    The central sub-aperture view is a pinhole image: its column ``c`` sees the plane
    sample ``c`` at every depth, so the centroid column of an axisymmetric flame's image is
    its axis's, and the axis's position is that column's on the grid at the axis's depth.
    Where the lit columns reach the view's edge (a flame cut by the field's edge) the
    centroid is pulled inward: the axis is then the column about which the lit profile is
    most nearly mirror-symmetric over the columns both sides hold.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    op : ExactOperator
    axis_z_mm : float
    fit : ndarray of bool or None
        Pixels to use (saturated ones still count: they bound the light from below).

    Returns
    -------
    float
        x0 in mm (x right, 0 on the optical axis).

    Raises
    ------
    ValueError
        A central view without light.
    """
    prof = lit_profile(views)
    if not prof.sum() > 0:
        raise ValueError("the central view holds no light: no axis to find")
    cbar = float(np.sum(np.arange(len(prof)) * prof) / prof.sum())
    if prof[0] > 0 or prof[-1] > 0:
        cbar = _mirror_centre(prof)
    _, w = frame_at(op, axis_z_mm)
    gc = op.dims[2]
    return ((cbar + 0.5) / gc - 0.5) * w
