"""Figures of planes in object space, shared by the commands' figures.

A plane is drawn in object-space millimetres (x right, y up, the optical axis at 0) at its
depth (:func:`plane_extent_mm`: the lenslet grid's field there, which grows with the
depth), with axes labelled in mm and a colour bar that names its units
(:func:`show_plane`, :func:`add_colorbar`); :func:`planes_figure` lays out rows of planes
(an estimate and its truth) on one colour scale; :func:`profiles_figure` draws the planes with
their measured flames (:mod:`lf_flame.measure.diagnostics`) and their profiles; :func:`signed` writes
a depth without ``-0.0``. The figures are :class:`matplotlib.figure.Figure` objects built without pyplot
(nothing global to close), returned so that tests read them; :func:`save_figure` writes
one atomically. ``lf-flame refocus``, ``temperature``, ``profiles``
(:func:`profiles_figure`) and ``reconstruct``
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
    # at most 4 intervals an axis: the ticks a small panel shows anyway, and fewer tick objects for matplotlib to
    # build at each draw (half of a reconstruction figure's drawing time with its default, 'auto')
    ax.locator_params(nbins=4)
    return im


def panel_grid(rows: int, cols: int, aspect: float, *, colorbars: int = 1, title_lines: int = 1,
               suptitle: str = "", footer: bool = False, widths_in=None, top_in: float | None = None,
               below_in: float = 0.0):
    """A figure of ``rows`` x ``cols`` image panels and ``colorbars`` colour bars at its right,
    laid out in inches (no layout engine: a constrained layout costs 0.5-1 s a figure).

    Each panel is :data:`PANEL_WIDTH_IN` wide and ``aspect`` times as tall (clipped to 0.9-5 in),
    with room above it for a title of ``title_lines`` lines and below and left for its tick
    labels and axis labels.

    Parameters
    ----------
    rows, cols : int
    aspect : float
        The planes' height over width (mm over mm, or lenslets over lenslets); with
        ``widths_in``, the panels' height over :data:`PANEL_WIDTH_IN`.
    widths_in : sequence of ``cols`` float or None
        Each column's panel width (inches); None: :data:`PANEL_WIDTH_IN` each.
    colorbars : int
        Colour bars side by side right of the panels (for :func:`add_colorbar`'s ``cax``).
    title_lines : int
    suptitle : str
        The figure's title, drawn above the panels.
    footer : bool
        Room for a legend below.
    top_in : float or None
        The margin above the panels (inches; a figure legend's room); None: as ``suptitle`` needs.
    below_in : float
        Room (inches) left under the panels for the caller's own axes (``fig.add_axes``).

    Returns
    -------
    fig : matplotlib.figure.Figure
        Its axes: the panels row by row, then the colour bars.
    axes : ndarray of shape (rows, cols) of Axes
    caxes : list of ``colorbars`` Axes
    """
    from matplotlib.figure import Figure
    widths = [PANEL_WIDTH_IN] * cols if widths_in is None else [float(v) for v in widths_in]
    h = float(np.clip(PANEL_WIDTH_IN * aspect, 0.9, 5.0))
    left, gap_x, above, below, bar = 0.65, 0.5 if widths_in is None else 0.7, 0.12 + 0.16 * title_lines, 0.5, 0.95
    top = (0.35 if suptitle else 0.1) if top_in is None else float(top_in)
    bottom = (0.35 if footer else 0.1) + float(below_in)
    x = left + np.concatenate([[0.0], np.cumsum(np.asarray(widths) + gap_x)])      # each column's left edge
    W = x[-1] - gap_x + 0.2 + colorbars * bar
    H = top + rows * (above + h + below) + bottom
    fig = Figure(figsize=(W, H))
    axes = np.empty((rows, cols), dtype=object)
    for i in range(rows):
        y0 = H - top - i * (above + h + below) - above - h
        for j in range(cols):
            axes[i, j] = fig.add_axes((x[j] / W, y0 / H, widths[j] / W, h / H))
    span = rows * (above + h + below) - above - below
    bar_h = 0.8 * span if rows == 1 else 0.45 * span
    bar_y = bottom + below + (span - bar_h) / 2
    x0 = x[-1] - gap_x + 0.2
    caxes = [fig.add_axes(((x0 + k * bar) / W, bar_y / H, 0.12 / W, bar_h / H), label="<colorbar>")   # as matplotlib
             for k in range(colorbars)]                                                     # labels its own
    if suptitle:
        fig.suptitle(suptitle, fontsize=9, y=1 - 0.08 / H, va="top")
    return fig, axes, caxes


def add_colorbar(fig, image, axes, label: str, fontsize: int = 8, shrink: float = 0.8, cax=None):
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
    cax : Axes or None
        The colour bar's own axes (:func:`panel_grid`); then ``axes`` and ``shrink`` are unused.

    Returns
    -------
    matplotlib.colorbar.Colorbar
    """
    cb = (fig.colorbar(image, cax=cax) if cax is not None else
          fig.colorbar(image, ax=axes, shrink=shrink, aspect=30))
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
    titles = [list(titles)] * R if isinstance(titles[0], str) else [list(t) for t in titles]
    fig, axes, (cax,) = panel_grid(R, P, aspect, title_lines=1 + max(t.count("\n") for row in titles for t in row),
                                   suptitle=suptitle, footer=bool(bad_label))
    cmap = matplotlib.colormaps[cmap].with_extremes(bad="0.6") if isinstance(cmap, str) else cmap
    for i, stack in enumerate(rows):
        for k in range(P):
            im = show_plane(axes[i, k], stack[k], extents_mm[k], title=titles[i][k], vmin=vmin, vmax=vmax,
                            cmap=cmap, ylabel=k == 0)
    add_colorbar(fig, im, axes, label, cax=cax)
    if bad_label:
        fig.legend(handles=[Patch(facecolor="0.6", edgecolor="0.3", label=bad_label)], loc="lower center",
                   fontsize=8, frameon=False)
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

    Raises
    ------
    IsADirectoryError
        A folder at ``path`` (before drawing; nothing temporary is left by a failed write).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_dir():       # the rename would fail after the drawing, naming the temporary file
        raise IsADirectoryError(f"cannot write the figure {path}: a folder stands there")
    tmp = path.with_name(f"{path.stem}.partial{path.suffix}")
    try:
        fig.savefig(tmp, dpi=dpi)
        tmp.replace(path)
    except BaseException:   # a full disk, Ctrl-C: nothing temporary left
        tmp.unlink(missing_ok=True)
        raise
    return path


def plot_profiles(path, cam, stack, depths, ms, objects, route, value_label: str = "radiance (a.u.)"):
    """Write :func:`profiles_figure` to ``path`` (PNG), atomically."""
    save_figure(profiles_figure(cam, stack, depths, ms, objects, route, value_label), path, dpi=100)


def profiles_figure(cam, stack, depths, ms, objects, route, value_label: str = "radiance (a.u.)"):
    """Each plane in object-space mm with the measured outline and edges (and the true ones),
    then the axial and radial profiles of the planes.

    A legend names the lines drawn on the planes (the measured region's outline, the
    measured base and tip, the true base and tip); the planes share one colour bar. A
    flagged plane (:attr:`~lf_flame.measure.diagnostics.FlameMeasurement.flags`) has a red title ending in
    ``UNTRUSTED: <flags>`` and its measured edges and profiles drawn dotted.

    Parameters
    ----------
    cam : PlenopticCamera
    stack : ndarray of shape (P, R, C)
        The planes on the camera's lenslet grid.
    depths : sequence of P float
        Depth (mm) of each plane.
    ms : sequence of P FlameMeasurement or None
        The measurements (None: no flame found).
    objects : sequence of P flame objects (or None) or None
        The truth of each plane (the flame at its depth), drawn where given.
    route : str
        Named in the axial profiles' title.
    value_label : str
        What the planes' values are, with units (the colour bar's and the profiles' axes).

    Returns
    -------
    matplotlib.figure.Figure
        Axes: the P planes, the axial profiles, the radial profiles (P > 1), the colour bar.
    """
    from matplotlib.lines import Line2D
    from .diagnostics import RADIAL_FRACTIONS, flame_truth, lenslet_to_object_mm
    P = len(stack)
    left, right, bottom, top = plane_extent_mm(cam, depths[0])
    fig, axes, (cax,) = panel_grid(1, P, (top - bottom) / (right - left), title_lines=3, top_in=0.4, below_in=3.0)
    vmax = max(float(np.max(stack)), 1e-9)
    untrusted = False
    panels = list(axes[0])
    for k, (plane, d, m) in enumerate(zip(stack, depths, ms)):
        ax = panels[k]
        im = show_plane(ax, plane, plane_extent_mm(cam, d), vmax=vmax, ylabel=k == 0)
        title = f"{signed(d, 0)} mm"
        if m is not None:
            rows, cols = np.arange(plane.shape[0]), np.arange(plane.shape[1])
            y, x = lenslet_to_object_mm(cam, rows[:, None], cols[None, :], d)
            ax.contour(np.broadcast_to(x, plane.shape), np.broadcast_to(y, plane.shape), m.mask, [0.5],
                       colors="w", linewidths=0.7)
            for yy in (m.base_y_mm, m.tip_y_mm):
                ax.axhline(yy, color="w", ls="--" if m.trusted else ":", lw=0.8)
            title += f"\nH {m.height_mm:.2f} mm"
            untrusted |= not m.trusted
        else:
            title += "\nno flame found"
        if objects and objects[k] is not None:
            t = flame_truth(objects[k])
            for yy in (t["base_y_mm"], t["tip_y_mm"]):
                ax.axhline(yy, color="c", lw=0.8)
            title += f" (true {t['height_mm']:.2f})"
        if m is not None and not m.trusted:
            title += f"\nUNTRUSTED: {', '.join(m.flags)}"
        ax.set_title(title, fontsize=9, color="k" if m is None or m.trusted else "red")
    add_colorbar(fig, im, panels, value_label, cax=cax)
    lines = [Line2D([], [], color="0.3", lw=0.9, label="measured flame region (outline)"),
             Line2D([], [], color="0.3", ls="--", lw=0.9, label="measured base and tip")]
    if untrusted:
        lines.append(Line2D([], [], color="0.3", ls=":", lw=0.9, label="measured base and tip, untrusted"))
    if objects and any(o is not None for o in objects):
        lines.append(Line2D([], [], color="c", lw=0.9, label="true base and tip"))
    fig.legend(handles=lines, loc="upper center", ncol=len(lines), fontsize=8, frameon=False)
    W, H = fig.get_size_inches()                       # the profiles in the room left under the planes
    x0, x1, y0, h = 0.75, W - 0.3, 0.55, 2.05
    half = (x1 - x0 - 0.9) / 2 if P > 1 else x1 - x0
    axa = fig.add_axes((x0 / W, y0 / H, half / W, h / H))
    axr = fig.add_axes(((x1 - half) / W, y0 / H, half / W, h / H)) if P > 1 else None
    styles = ("-", "--", ":")
    for k, (d, m) in enumerate(zip(depths, ms)):
        if m is None:
            continue
        axa.plot(m.axial_height_mm, m.axial_intensity, color=f"C{k}", ls="-" if m.trusted else ":",
                 label=f"{signed(d, 0)} mm" + ("" if m.trusted else " (untrusted)"))
        if axr is not None:
            for r in m.radial:      # styled by the fraction of the height it stands at
                j = int(np.argmin(np.abs(np.asarray(RADIAL_FRACTIONS) - r.height_mm / max(m.height_mm, 1e-9))))
                axr.plot(r.x_mm, r.intensity, color=f"C{k}", ls=styles[j % 3], lw=0.9)
    axa.set(xlabel="height above the measured base (mm)", ylabel=value_label,
            title=f"axial profiles on the centreline ({route})")
    if any(m is not None for m in ms):           # no flame found on any plane: no profile to name
        axa.legend(fontsize=7, title="plane", title_fontsize=7)
    if axr is not None:
        axr.set(xlabel="offset from the centreline (mm)", ylabel=value_label,
                title="radial profiles across the flame")
        fractions = [f"{100 * f:.0f} % of the height" for f in RADIAL_FRACTIONS]
        handles = [Line2D([], [], color=f"C{k}", label=f"{signed(d, 0)} mm") for k, (d, m) in
                   enumerate(zip(depths, ms)) if m is not None and m.radial]
        handles += [Line2D([], [], color="k", ls=styles[j % 3], lw=0.9, label=f) for j, f in enumerate(fractions)]
        axr.legend(handles=handles, fontsize=6, ncol=2)
    return fig
