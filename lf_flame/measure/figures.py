"""Figures of planes in object space, shared by the commands' figures.

A plane is drawn in object-space millimetres (x right, y up, the optical axis at 0) at its
depth (:func:`plane_extent_mm`: the lenslet grid's field there, which grows with the
depth), with axes labelled in mm and a colour bar that names its units
(:func:`show_plane`, :func:`add_colorbar`); :func:`planes_figure` lays out rows of planes
(an estimate and its truth) on one colour scale; :func:`signed` writes a depth without
``-0.0``. The figures are :class:`matplotlib.figure.Figure` objects built without pyplot
(nothing global to close), returned so that tests read them; :func:`save_figure` writes
one atomically. ``lf-flame refocus``, ``temperature``, ``profiles``
(:func:`lf_flame.measure.diagnostics.profiles_figure`) and ``reconstruct``
(:func:`lf_flame.tomo.files.reconstruction_figure`) draw their planes with these.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..optics.camera import PlenopticCamera

#: Width (inches) of one plane's panel; its height follows the plane's aspect.
PANEL_WIDTH_IN = 2.4


def signed(value: float, digits: int = 1) -> str:
    """A number with its sign, rounded, never ``-0.0``: ``+20.0``, ``-9.5``, ``+0.0`` (a depth in mm, a slope).

    Parameters
    ----------
    value : float
    digits : int
        Digits after the decimal point.

    Returns
    -------
    str
        The number alone (no unit).
    """
    v = round(float(value), digits) + 0.0     # -0.0 + 0.0 is +0.0
    return f"{v:+.{digits}f}"


def plane_extent_mm(camera: PlenopticCamera, depth_offset_mm: float) -> tuple:
    """The object-space field of the camera's lenslet grid at a depth, as imshow's ``extent``.

    Parameters
    ----------
    camera : PlenopticCamera
    depth_offset_mm : float
        The plane's depth, mm from the focal plane (> 0 farther).

    Returns
    -------
    (left, right, bottom, top) : tuple of float
        mm, x right and y up, the optical axis at 0
        (:func:`lf_flame.measure.diagnostics.lenslet_to_object_mm` of the grid's outer edges).
        A plane on a finer grid over the same lenslets (``s`` samples per lenslet) has the same extent.
    """
    from .diagnostics import lenslet_to_object_mm
    (top, bottom), (left, right) = lenslet_to_object_mm(camera, [-0.5, camera.n_rows - 0.5],
                                                        [-0.5, camera.n_cols - 0.5], depth_offset_mm)
    return float(left), float(right), float(bottom), float(top)


def show_plane(ax, plane, extent_mm=None, *, title: str = "", vmin=0.0, vmax=None, cmap="inferno",
               fontsize: int = 8, ylabel: bool = True):
    """Draw one plane on ``ax`` in object-space mm, its axes labelled.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    plane : array_like of shape (rows, cols)
        Rows down (row 0 at the top of the field), columns right; NaN or masked values take
        the colour map's "bad" colour.
    extent_mm : (left, right, bottom, top) or None
        The plane's field in mm (:func:`plane_extent_mm`); None: axes in lenslets (no camera known).
    title : str
    vmin, vmax : float or None
        The colour scale (None: the plane's range).
    cmap : str or matplotlib.colors.Colormap
    fontsize : int
        Of the title and labels (tick labels one smaller).
    ylabel : bool
        Label the y axis (False for panels right of the first).

    Returns
    -------
    matplotlib.image.AxesImage
        For :func:`add_colorbar`.
    """
    im = ax.imshow(np.ma.masked_invalid(np.asarray(plane, np.float64)), cmap=cmap, vmin=vmin, vmax=vmax,
                   extent=extent_mm, interpolation="nearest")
    mm = extent_mm is not None
    ax.set_xlabel("x (mm)" if mm else "column (lenslet)", fontsize=fontsize)
    if ylabel:
        ax.set_ylabel("y (mm)" if mm else "row (lenslet)", fontsize=fontsize)
    if title:
        ax.set_title(title, fontsize=fontsize)
    ax.tick_params(labelsize=fontsize - 1)
    return im


def add_colorbar(fig, image, axes, label: str, fontsize: int = 8, shrink: float = 0.8):
    """A colour bar for ``image`` beside ``axes``, labelled with its quantity and units.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    image : matplotlib.image.AxesImage
        What :func:`show_plane` returned (its colour map and scale).
    axes : Axes or sequence of Axes
        The panels it serves (space is taken from them).
    label : str
        Quantity and units, e.g. ``"temperature (K)"``.
    fontsize : int
    shrink : float
        Its length, a fraction of the panels' height (its width follows: a 30th of its length).

    Returns
    -------
    matplotlib.colorbar.Colorbar
    """
    cb = fig.colorbar(image, ax=axes, shrink=shrink, aspect=30)
    cb.set_label(label, fontsize=fontsize)
    cb.ax.tick_params(labelsize=fontsize - 1)
    return cb


def planes_figure(rows, extents_mm, titles, label: str, *, vmin=0.0, vmax=None, cmap="inferno",
                  bad_label: str | None = None, suptitle: str = ""):
    """Rows of planes side by side (one column per plane) on one colour scale with one colour bar.

    Parameters
    ----------
    rows : sequence of R array_like of shape (P, rows, cols)
        E.g. an estimate, then its truth. NaN values are "bad": grey, named by ``bad_label``.
    extents_mm : sequence of P (left, right, bottom, top) or None
        Each column's field in mm (:func:`plane_extent_mm`); None: axes in lenslets.
    titles : sequence of P str, or R sequences of P str
        Each panel's title (its depth ...): the same for every row, or one sequence per row.
    label : str
        The colour bar's quantity and units.
    vmin, vmax : float or None
        The colour scale (None: the finite values' range over every row).
    cmap : str
    bad_label : str or None
        When given, NaN pixels are drawn grey and a legend entry (a grey patch) says what they are.
    suptitle : str

    Returns
    -------
    matplotlib.figure.Figure
        Axes: the R x P panels row by row, then the colour bar's.
    """
    import matplotlib
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch
    rows = [np.asarray(r, np.float64) for r in rows]
    R, P = len(rows), len(rows[0])
    finite = np.concatenate([r[np.isfinite(r)] for r in rows])
    if vmax is None:
        vmax = float(finite.max()) if finite.size else 1.0
    if vmin is None:
        vmin = float(finite.min()) if finite.size else 0.0
    vmax = max(vmax, vmin + 1e-12)
    extents_mm = list(extents_mm) if extents_mm is not None else [None] * P
    aspect = rows[0].shape[1] / rows[0].shape[2]
    if extents_mm[0] is not None:
        left, right, bottom, top = extents_mm[0]
        aspect = (top - bottom) / (right - left)
    panel_h = float(np.clip(0.8 * PANEL_WIDTH_IN * aspect, 1.4, 5.0)) + 0.9   # the image, its title and x label
    fig = Figure(figsize=(PANEL_WIDTH_IN * P + 1.4, panel_h * R + (0.6 if suptitle or bad_label else 0.2)),
                 layout="constrained")
    axes = fig.subplots(R, P, squeeze=False)
    cmap = matplotlib.colormaps[cmap].with_extremes(bad="0.6") if isinstance(cmap, str) else cmap
    titles = [list(titles)] * R if isinstance(titles[0], str) else [list(t) for t in titles]
    for i, stack in enumerate(rows):
        for k in range(P):
            im = show_plane(axes[i, k], stack[k], extents_mm[k], title=titles[i][k], vmin=vmin, vmax=vmax,
                            cmap=cmap, ylabel=k == 0)
    add_colorbar(fig, im, axes, label)
    if bad_label:
        fig.legend(handles=[Patch(facecolor="0.6", edgecolor="0.3", label=bad_label)], loc="outside lower center",
                   fontsize=8, frameon=False)
    if suptitle:
        fig.suptitle(suptitle, fontsize=9)
    return fig


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Write a figure, atomically (a temporary file beside it, then renamed).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or Path
        The image to write; its suffix picks the format (PNG ...).
    dpi : int

    Returns
    -------
    Path
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.stem}.partial{path.suffix}")
    fig.savefig(tmp, dpi=dpi)
    tmp.replace(path)
    return path
