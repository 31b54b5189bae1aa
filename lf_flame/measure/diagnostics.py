"""Flame diagnostics per depth plane: where the flame is, its size in mm and its profiles.

The one place for diagnostics. A refocused plane ``(R, C)`` is in lenslets;
:func:`lenslet_size_mm` turns lenslets into object-space millimetres at the plane's depth
(the main lens's magnification ``d / z`` changes with the depth, see
:meth:`~lf_flame.optics.camera.PlenopticCamera.object_to_lenslet`). :func:`measure_flame`
segments the in-focus flame with scikit-image and measures it;
:func:`lf_flame.measure.scoring.score_stacks` compares measurements with the
simulation's truth (the flame scene's ``objects``);
:func:`lf_flame.measure.figures.profiles_figure` draws them (the figure of ``lf-flame profiles``,
:func:`lf_flame.measure.figures.plot_profiles` writes it).

How the other planes' out-of-focus flames bias each measurement, and what is done about
it (``docs/diagnostics.md`` has the measured figures):

- **Which flame.** A refocused plane holds its own flame in focus plus the three other
  flames blurred by discs of ``|Δslope| · N`` lenslets (17 lenslets for 10 mm apart with
  the paper's camera), which can be brighter than a dim in-focus flame. The search is
  restricted to the flame's column band (the burner's lateral position, known in an
  experiment; the scene's ``roi`` columns in a simulation; its rows, which hold the true
  height, are never used). Within it, of the regions above the segmentation threshold,
  the **sharpest** one (largest mean Sobel gradient, scikit-image ``filters.sobel``) is
  the in-focus flame: blur removes gradients, so a blurred neighbour loses even when it
  is brighter (sharpness = mean gradient / mean value, so brightness does not count).
  Where the dim in-focus flame and a brighter blur merge into one region above the
  threshold, there is nothing to choose and the measurement includes the blur. On a
  plane of *emission* (:data:`EMISSION_MEASURE`) the region holding the most light is
  the flame: no neighbour's blur lies there, only the solve's artefacts.
- **Segmentation threshold** at :data:`SEGMENT_FRACTION` (30 %) of the brightest pixel in
  the band, ``measure.label`` + ``measure.regionprops``. Blurred light of neighbours
  adds to the flame's own; a low threshold lets the region merge with a neighbour's blur
  (the tip then jumps to the taller neighbour's), a high one eats the flame's dim base
  and tip. Widths, centroid and integrated intensity are taken on this region, so they
  are those of the flame above 30 % of its peak, plus whatever blurred light lies inside
  it (a bias upward of the integrated intensity, of a few per cent where neighbours
  overlap).
- **Height** is not the region's extent: the flame's luminosity fades to zero at both its
  base and its tip (soot burn-out), so any threshold shortens it (by 0.7-1.3 mm at 10 %
  of the peak on the paper preset's ground truth). The base and the tip are each found
  by extrapolating the flame's edge to zero intensity along the axial peak profile (the
  brightest pixel of the flame in each row): a straight line is fitted to the rows
  between :data:`EDGE_FIT_RANGE` (20 % and 60 %) of the profile's maximum and its zero
  crossing is the edge. Blurred light below 20 % of the peak does not enter the fit. The
  walk from the peak row to each end follows the flame's own columns (it cannot jump
  sideways to blur the region touches elsewhere) and goes on past the region only while
  the profile keeps falling as fast as the flame's edge does (:data:`TAIL_FALL`), not
  along the slow tail of a neighbour's blur. Biases that remain (measured,
  ``docs/diagnostics.md``): the line undershoots the base by 3-4 % of the height (the
  luminosity rises concavely from the base); at the tip the error depends on the blurred
  neighbours (about −2 % of the height with the paper's layout, near 0 elsewhere), so
  on the paper's planes the two partly cancel. Where a short in-focus flame merges, above
  the threshold, with a brighter blur of a taller neighbour, the tip follows the blur
  (errors of 1-3 mm seen).
- **Flags** (:attr:`FlameMeasurement.flags`, :attr:`FlameMeasurement.trusted`): the
  cases above where the height cannot be trusted are detected and flagged, never
  returned silently. ``"merged"``: the edge walk ran on light from outside the column
  band (its brightest lenslet on the band's inner border in some row: the region is a
  sliver of a neighbour's blur at the border, or merged with it), or the tip's fitted
  rows stand on other flames' light: the lower of the two lenslets
  :data:`PEDESTAL_GAP` beside the flame, averaged over the fitted rows, over the fitted
  slope, is the distance (mm) a pedestal of that level moves the extrapolated tip up;
  above :data:`TIP_PEDESTAL_MM` the tip is not trusted. Only the tip: at the base every
  flame of the scene stands on the same row, the neighbours' blur fades with the flame
  and did not move the base (measured, ``docs/diagnostics.md``). ``"cut"``: the region
  or an edge walk reaches the plane's border. ``"no-edge"``: an edge walk ended with the
  region, above the fitted range. Widths, centroid and integrated intensity of a
  trusted plane may still include blur where the region touches a neighbour's blur
  below the tip (they are not flagged). Measured on 200 fresh scenes per regime
  (``experiments/studies/flame_tail.py``, ``docs/diagnostics.md``).
- **Axial and radial profiles** are samples of the plane, out-of-focus light included:
  they are biased upward wherever a neighbour's blur overlaps, most near the base, where
  all flames stand at the same image row.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy import ndimage
from skimage import filters, measure

from ..optics.camera import PlenopticCamera

#: Segmentation threshold, a fraction of the brightest pixel of the flame's column band.
SEGMENT_FRACTION = 0.3
#: Fractions of the axial peak profile's maximum between which the base and tip edges are
#: fitted by a straight line and extrapolated to zero.
EDGE_FIT_RANGE = (0.2, 0.6)
#: Past the segmented region, the edge walk goes on while the profile falls per row at
#: least this fraction of its mean fall per row inside the region's part of the fit.
TAIL_FALL = 0.25
#: The light beside the flame is read this many lenslets outside the walk's run (past the
#: in-focus flame's own edge) to measure the pedestal other flames' blur puts under an edge.
PEDESTAL_GAP = 3
#: A tip whose fitted rows stand on a pedestal worth more than this many mm of edge shift
#: (pedestal / slope of the fit) is flagged "merged" (threshold from ``experiments/studies/flame_tail.py``).
TIP_PEDESTAL_MM = 0.35
#: Flags a :class:`FlameMeasurement` may carry: measurements the method cannot trust.
FLAGS = ("merged", "cut", "no-edge")
#: Regions smaller than this many lenslets are noise, not a flame.
MIN_AREA_LENSLETS = 10
#: Default heights of the radial profiles, fractions of the measured height above the base.
RADIAL_FRACTIONS = (0.25, 0.5, 0.75)
#: How a flame is measured on a plane of *emission* (a reconstructed plane,
#: :mod:`lf_flame.tomo`, or the truth on its grid): no other plane's defocused light
#: lies on it, so the threshold and the fitted part of each edge go lower, where the
#: luminosity's curvature biases the extrapolated edge less. On the true emission of 240
#: validation scenes the defaults above measure flames 0.28 mm too tall on average (the base
#: undershot), worst 0.99 mm; these 0.06 mm, worst 0.65 mm (a flame cut by the field,
#: flagged). Chosen by the lowest worst trusted height error over those scenes and the chosen
#: solver's validation reconstructions (``python experiments/reconstruct.py --stage edges``,
#: ``results/reconstruct_edges.csv``).
#: On such a plane the flame is the region that holds the most light (``pick="brightest"``), not the sharpest: what
#: other flames leave there is the solve's artefact, and where the data are few (a camera of 6-7 views, a recording
#: solved on the lenslet grid) it is speckled, so the sharpest region above 5 % was another flame's ghost (a user's
#: 6-view camera: each plane measured at its neighbour's place, heights 3-4 mm off).
EMISSION_MEASURE = dict(segment_fraction=0.05, edge_fit_range=(0.05, 0.5), pick="brightest")
#: How :func:`measure_flame` chooses among a band's regions above the threshold.
PICKS = ("sharpest", "brightest")
#: :func:`separate_flame_bands`: the least light a region of a plane of emission holds to count as a flame of its
#: own, a fraction of the light of the plane's region holding the most.
SEPARATE_SHARE = 0.1


class EmptyPlaneError(ValueError):
    """A plane holds no flame to measure (no light, or no region large enough)."""


def lenslet_size_mm(camera: PlenopticCamera, depth_offset_mm: float) -> float:
    """Object-space size (mm) of one lenslet of a plane refocused at depth ``dz``.

    The refocused image has one pixel per lenslet; a lenslet of pitch ``p`` sees
    ``p z / d`` mm of the plane at object distance ``z = z_f + dz`` (chief ray through the
    main-lens centre, :meth:`~lf_flame.optics.camera.PlenopticCamera.object_to_lenslet`): 0.1314 mm
    at the focal plane of the paper's camera, 0.1394 mm at +20 mm, 0.1273 mm at −10 mm.

    Raises
    ------
    ValueError
        If the plane lies at or inside the main lens's focal length.
    """
    z = camera.object_distance_mm(depth_offset_mm)
    camera.image_distance_mm(z)  # raises for an impossible plane
    return camera.mla_pitch_mm * z / camera.mla_distance_mm


def lenslet_to_object_mm(camera: PlenopticCamera, rows, cols, depth_offset_mm: float):
    """Object-space ``(y, x)`` (mm; y up, x right) of refocused-image pixels ``(rows, cols)``.

    The inverse of :meth:`~lf_flame.optics.camera.PlenopticCamera.object_to_lenslet`: pixel
    index ``i`` has its centre at lenslet coordinate ``i + 0.5``.

    Parameters
    ----------
    rows, cols : array_like
        Pixel indices (may be fractional) of the refocused image, rows down, columns right.
    depth_offset_mm : float
        Depth of the plane (mm from the focal plane, > 0 farther).

    Returns
    -------
    y_mm, x_mm : ndarray, broadcast from ``rows`` and ``cols``.
    """
    s = lenslet_size_mm(camera, depth_offset_mm)
    r0, c0 = camera.object_to_lenslet(0.0, 0.0, depth_offset_mm)
    return (r0 - (np.asarray(rows, np.float64) + 0.5)) * s, (np.asarray(cols, np.float64) + 0.5 - c0) * s


@dataclass(frozen=True)
class RadialProfile:
    """Intensity across the flame at one height.

    Attributes
    ----------
    height_mm : float
        Height above the measured base (mm).
    x_mm : ndarray of shape (n,)
        Lateral offset from the flame's centreline (mm, right positive), one per column
        of the column band.
    intensity : ndarray of shape (n,)
        The plane's value there (bilinear between rows), same scale as the plane.
    """

    height_mm: float
    x_mm: np.ndarray
    intensity: np.ndarray


@dataclass(frozen=True)
class FlameMeasurement:
    """What :func:`measure_flame` finds in one plane. Lengths in object-space mm.

    Attributes
    ----------
    depth_offset_mm, lenslet_mm : float
        The plane's depth and the object-space size of one of its lenslets.
    height_mm : float
        ``tip_y_mm - base_y_mm``.
    base_y_mm, tip_y_mm : float
        Heights (y up, mm, from the optical axis) of the base and the tip: the axial
        edges extrapolated to zero intensity (module docstring).
    base_width_mm : float
        Width of the segmented region at 10 % of the height above the base (the
        luminous sheath is dark right at the base).
    max_width_mm, max_width_y_mm : float
        Largest width of the region and the height (y, mm) of that row.
    centroid_y_mm, centroid_x_mm : float
        Intensity-weighted centroid of the region.
    integrated_intensity : float
        Sum of the plane over the region times the lenslet area (intensity · mm²).
    peak_intensity, threshold : float
        Brightest value of the region and the segmentation threshold (plane's scale).
    mask : ndarray of shape (R, C), bool
        The segmented region (rows, columns of the plane).
    axial_height_mm, axial_intensity : ndarray of shape (n,)
        Axial profile: the plane along the centreline (the region's intensity-weighted
        centre column in each row, bilinear), against height above the base (mm), in the
        region's row order: the top row (the tip) first, the heights descending.
    radial : tuple of RadialProfile
        Radial profiles at the requested heights.
    flags : tuple of str
        Why the height (and the base and tip) cannot be trusted, from :data:`FLAGS`;
        empty when it can (module docstring, "Flags"):

        - ``"merged"``: an edge walk ran on other flames' light: the brightest lenslet of
          a walked row lies on an inner border of the column band (light from outside the
          band), or the tip's fitted rows stand on a pedestal of light worth more than
          :data:`TIP_PEDESTAL_MM` of edge shift (``tip_pedestal_mm``);
        - ``"cut"``: the region reaches the plane's first or last row or column, or an
          edge walk reached the plane's end: the true tip or base may lie outside;
        - ``"no-edge"``: an edge walk stopped where the region ends, above the fitted
          range (the threshold, set by brighter light in the band, cut the flame before
          its edge faded), so that edge is the threshold's, not the flame's.
    tip_pedestal_mm : float
        The light beside the flame in the tip's fitted rows divided by the fitted slope
        (mm): how far a pedestal of that level moves the extrapolated tip upward. NaN
        when the tip was not fitted (too few rows, or not falling).
    """

    depth_offset_mm: float
    lenslet_mm: float
    height_mm: float
    base_y_mm: float
    tip_y_mm: float
    base_width_mm: float
    max_width_mm: float
    max_width_y_mm: float
    centroid_y_mm: float
    centroid_x_mm: float
    integrated_intensity: float
    peak_intensity: float
    threshold: float
    mask: np.ndarray = field(repr=False)
    axial_height_mm: np.ndarray = field(repr=False)
    axial_intensity: np.ndarray = field(repr=False)
    radial: tuple = field(repr=False, default=())
    flags: tuple[str, ...] = ()
    tip_pedestal_mm: float = math.nan

    @property
    def trusted(self) -> bool:
        """True when no flag is raised (:attr:`flags` is empty)."""
        return not self.flags

    def summary(self) -> dict:
        """The scalar measurements as a dict (one CSV row); ``flags`` joined by ``;``
        (empty string when trusted)."""
        row = {k: float(getattr(self, k)) for k in (
            "depth_offset_mm", "lenslet_mm", "height_mm", "base_y_mm", "tip_y_mm", "base_width_mm", "max_width_mm",
            "max_width_y_mm", "centroid_y_mm", "centroid_x_mm", "integrated_intensity", "peak_intensity",
            "threshold", "tip_pedestal_mm")}
        row["flags"] = ";".join(self.flags)
        return row


def _check_plane(plane, camera: PlenopticCamera) -> np.ndarray:
    a = np.asarray(plane)
    if a.shape != (camera.n_rows, camera.n_cols):
        raise ValueError(f"plane must have the camera's lenslet grid shape {(camera.n_rows, camera.n_cols)} "
                         f"(rows, columns). Received: shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise ValueError(f"plane must hold real numbers. Received: dtype {a.dtype}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"plane contains {int(np.sum(~np.isfinite(a)))} NaN or infinite values")
    return a


def _check_columns(columns, n_cols: int) -> tuple[int, int]:
    if columns is None:
        return 0, n_cols
    try:
        c0, c1 = (int(v) for v in columns)
    except (TypeError, ValueError):
        raise ValueError(f"columns must be (col0, col1). Received: columns={columns!r}") from None
    if not 0 <= c0 < c1 <= n_cols:
        raise ValueError(f"columns must satisfy 0 <= col0 < col1 <= {n_cols}. Received: columns={columns!r}")
    return c0, c1


class _Edge(NamedTuple):
    """What :func:`_edge` finds at one end of the flame."""

    y_mm: float  #: the edge's height (y, mm)
    #: in some row of the walk the profile's brightest lenslet lies on a border of the
    #: band that is not the plane's edge: the walk ran on light from outside the band
    on_band_border: bool
    #: the light beside the flame in the fitted rows (mean over them of the lower of the
    #: two lenslets :data:`PEDESTAL_GAP` outside the row's run) over the fitted line's
    #: slope (intensity per mm): how far a pedestal of that level moves the extrapolated
    #: zero outward, in mm; NaN when no line was fitted
    pedestal_mm: float
    #: the walk reached the plane's first or last row, or the edge was clipped to it
    at_plane_end: bool
    #: the edge was fitted, or the profile fell below ``lo`` (a hard edge); False: the
    #: walk stopped at the region's end above the fitted range, so the edge returned is
    #: where the segmentation threshold cut the flame, not the flame's edge
    found: bool


def _edge(img, mask, y, start, step, lo, hi, band) -> _Edge:
    """Walk the axial peak profile from row ``start`` in direction ``step`` (-1 up, +1
    down) to the flame's edge, extrapolated to zero (see module docstring).

    The walk follows the flame: in each row it looks only at the columns of the previous
    row's run widened by one lenslet on each side (within the region while the region
    lasts), so it cannot jump to blurred light that the region touches elsewhere. Past
    the region's end it goes on only while the profile keeps falling at least
    :data:`TAIL_FALL` times as fast as it fell inside the region: the flame's own fading
    edge does, the slowly varying blur of other planes does not. ``lo`` and ``hi`` are
    fractions of the profile at ``start``; ``band`` is the column band ``(c0, c1)``.
    What the walk saw on the way is returned with the edge (:class:`_Edge`), for the flags.
    """
    c0, c1 = band
    n_rows, n_cols = img.shape
    borders = [c for c, inner in ((c0, c0 > 0), (c1 - 1, c1 < n_cols)) if inner]
    cols = np.flatnonzero(mask[start])
    a, b = cols[0], cols[-1]
    ref = img[start, a:b + 1].max()
    lo, hi = lo * ref, hi * ref
    pts, beside, falls, prev, i, last, on_border, below = [], [], [], np.inf, start, start, False, False
    while 0 <= i < n_rows:
        lo_c, hi_c = max(a - 1, 0), min(b + 2, n_cols)
        inside = np.flatnonzero(mask[i, lo_c:hi_c]) + lo_c
        if inside.size:
            a, b = inside[0], inside[-1]
        v = img[i, a:b + 1].max()
        if v < lo:
            below = True
            break
        if not inside.size and not (falls and prev - v >= TAIL_FALL * np.mean(falls)):
            break
        on_border |= a + int(np.argmax(img[i, a:b + 1])) in borders
        if v <= hi:
            if pts and inside.size:
                falls.append(prev - v)
            pts.append((y[i], v))
            beside.append(min(img[i, max(a - PEDESTAL_GAP, 0)], img[i, min(b + PEDESTAL_GAP, n_cols - 1)]))
        prev, last, i = v, i, i + step
    half = 0.5 * (y[0] - y[1])
    at_end = last in (0, n_rows - 1)
    outer = float(y[last] - step * half)  # the outer edge of the last row above ``lo``
    if len(pts) < 2:  # too steep to fit (a hard edge), or the region ended above the fitted range
        return _Edge(outer, on_border, math.nan, at_end, below)
    slope, intercept = np.polyfit(*np.asarray(pts).T, 1)
    if slope * step <= 0:  # not falling outward (a blurred, flat prediction): no edge to extrapolate
        return _Edge(outer, on_border, math.nan, at_end, below)
    pedestal = float(np.mean(beside) / abs(slope))
    # between the peak row and the plane's top (bottom) edge
    limit = y[0] + half if step < 0 else y[-1] - half
    edge = -intercept / slope
    if step * (edge - limit) < 0:  # beyond the plane's edge: clipped
        return _Edge(float(limit), on_border, pedestal, True, True)
    return _Edge(float(max(edge, y[start]) if step < 0 else min(edge, y[start])), on_border, pedestal, at_end, True)


def measure_flame(plane, camera: PlenopticCamera, depth_offset_mm: float, *, columns=None,
                  segment_fraction: float = SEGMENT_FRACTION, edge_fit_range=EDGE_FIT_RANGE,
                  radial_heights_mm=None, pick: str = "sharpest") -> FlameMeasurement:
    """Segment the in-focus flame of a refocused plane and measure it in object-space mm.

    Parameters
    ----------
    plane : ndarray of shape (R, C)
        A refocused image (rows, columns; one pixel per lenslet), e.g. one plane of the
        ground truth or of any refocusing route, non-negative radiance (any scale).
    camera : PlenopticCamera
        The camera (lenslet grid and optics) that took the light field.
    depth_offset_mm : float
        Depth of the plane the image is focused on (mm from the focal plane).
    columns : (col0, col1) or None
        Column band ``[col0, col1)`` (lenslets) where the flame stands, e.g. a scene
        object's ``roi[2:4]``; None: the whole plane.
    segment_fraction : float in (0, 1)
        Segmentation threshold, fraction of the band's brightest pixel.
    edge_fit_range : (lo, hi), 0 < lo < hi <= 1
        Fractions of the axial peak profile's maximum fitted for the base and tip edges.
    radial_heights_mm : sequence of float or None
        Heights above the measured base (mm) of the radial profiles; None: 25, 50 and
        75 % of the measured height. Heights outside the plane are skipped.
    pick : {"sharpest", "brightest"}
        Which region above the threshold is the flame: the sharpest (largest mean Sobel gradient over mean value:
        a refocused plane, where blurred neighbours can be brighter) or the one holding the most light (a plane of
        emission, :data:`EMISSION_MEASURE`).

    Returns
    -------
    FlameMeasurement

    Raises
    ------
    ValueError
        A plane of the wrong shape (not the camera's ``(n_rows, n_cols)``), with NaN or
        inf; a bad band or fraction; an impossible depth.
    EmptyPlaneError
        (a ValueError) An empty plane: no positive value in the band, or no region of at
        least :data:`MIN_AREA_LENSLETS` lenslets above the threshold.

    Notes
    -----
    The method and its biases are in the module docstring and ``docs/diagnostics.md``.
    Flame edges by extrapolating the intensity edge to zero: the "tangent" construction
    used for edge positions of blurred profiles (e.g. knife-edge methods); segmentation
    by thresholding and connected components, scikit-image ``measure.label``.
    """
    img = _check_plane(plane, camera)
    c0, c1 = _check_columns(columns, camera.n_cols)
    if not 0.0 < segment_fraction < 1.0:
        raise ValueError(f"segment_fraction must lie in (0, 1). Received: {segment_fraction!r}")
    lo, hi = (float(v) for v in edge_fit_range)
    if not 0.0 < lo < hi <= 1.0:
        raise ValueError(f"edge_fit_range must be (lo, hi) with 0 < lo < hi <= 1. Received: {edge_fit_range!r}")
    if pick not in PICKS:
        raise ValueError(f"pick must be one of {PICKS}. Received: {pick!r}")
    s = lenslet_size_mm(camera, depth_offset_mm)
    band = np.zeros_like(img)
    band[:, c0:c1] = img[:, c0:c1]
    peak = float(band.max())
    if peak <= 0.0:
        raise EmptyPlaneError(f"plane is empty: no light in columns [{c0}, {c1}) (maximum {peak})")
    threshold = segment_fraction * peak
    labels = measure.label(band >= threshold)
    # sharpness of each region: mean Sobel gradient over mean value (brightness-free)
    regions = [r for r in measure.regionprops(labels, intensity_image=np.dstack([filters.sobel(img), img]))
               if r.area >= MIN_AREA_LENSLETS]
    if not regions:
        raise EmptyPlaneError(f"no region of {MIN_AREA_LENSLETS} lenslets or more above {segment_fraction:.0%} of "
                              f"the peak {peak:.4g} in columns [{c0}, {c1}): the plane holds light, but is empty of "
                              "flames that large (a smaller one is not measured)")
    if pick == "sharpest":
        best = max(regions, key=lambda r: r.intensity_mean[0] / r.intensity_mean[1])
    else:
        best = max(regions, key=lambda r: r.intensity_mean[1] * r.area)
    mask = labels == best.label

    rows_idx = np.arange(img.shape[0])
    y, _ = lenslet_to_object_mm(camera, rows_idx, 0, depth_offset_mm)
    profile = np.where(mask, img, 0.0).max(axis=1)
    start = int(np.argmax(profile))
    tip_edge = _edge(img, mask, y, start, -1, lo, hi, (c0, c1))
    base_edge = _edge(img, mask, y, start, +1, lo, hi, (c0, c1))
    tip, base = tip_edge.y_mm, base_edge.y_mm
    height = tip - base
    flags = []
    if tip_edge.on_band_border or base_edge.on_band_border or tip_edge.pedestal_mm > TIP_PEDESTAL_MM:
        flags.append("merged")
    if tip_edge.at_plane_end or base_edge.at_plane_end or any(e.any() for e in (mask[0], mask[-1], mask[:, 0],
                                                                                 mask[:, -1])):
        flags.append("cut")
    if not (tip_edge.found and base_edge.found):
        flags.append("no-edge")

    props = measure.regionprops(mask.astype(np.uint8), intensity_image=img)[0]
    cy, cx = lenslet_to_object_mm(camera, *props.centroid_weighted, depth_offset_mm)
    rows = np.flatnonzero(mask.any(axis=1))
    first = np.array([np.flatnonzero(mask[r])[0] for r in rows])
    last = np.array([np.flatnonzero(mask[r])[-1] for r in rows])
    widths = (last - first + 1) * s
    k = int(np.argmax(widths))
    row_base = np.interp(base + 0.1 * height, y[rows][::-1], rows[::-1].astype(float))
    base_width = float(widths[int(np.argmin(np.abs(rows - row_base)))])

    # centreline: intensity-weighted centre column of the region in each row
    w = np.where(mask, img, 0.0)[rows]
    centre_col = (w * np.arange(img.shape[1])).sum(axis=1) / w.sum(axis=1)
    axial = ndimage.map_coordinates(img, [rows.astype(float), centre_col], order=1, mode="nearest")
    radial = []
    if radial_heights_mm is None:
        radial_heights_mm = [f * height for f in RADIAL_FRACTIONS]
    cols = np.arange(c0, c1, dtype=float)
    for h in radial_heights_mm:
        r = (camera.object_to_lenslet(base + float(h), 0.0, depth_offset_mm)[0] - 0.5)
        if not 0 <= r <= img.shape[0] - 1:
            continue
        cc = float(np.interp(r, rows, centre_col))
        vals = ndimage.map_coordinates(img, [np.full_like(cols, r), cols], order=1, mode="nearest")
        radial.append(RadialProfile(float(h), (cols - cc) * s, vals))
    return FlameMeasurement(
        depth_offset_mm=float(depth_offset_mm), lenslet_mm=s, height_mm=height, base_y_mm=base, tip_y_mm=tip,
        base_width_mm=base_width, max_width_mm=float(widths[k]), max_width_y_mm=float(y[rows[k]]),
        centroid_y_mm=float(cy), centroid_x_mm=float(cx), integrated_intensity=float(img[mask].sum() * s * s),
        peak_intensity=float(img[mask].max()), threshold=threshold, mask=mask,
        axial_height_mm=y[rows] - base, axial_intensity=axial, radial=tuple(radial), flags=tuple(flags),
        tip_pedestal_mm=tip_edge.pedestal_mm)


def separate_flame_bands(plane, camera: PlenopticCamera, *, segment_fraction: float = EMISSION_MEASURE[
                             "segment_fraction"], share: float = SEPARATE_SHARE) -> list:
    """The column bands of the flames that stand apart on one plane of emission, read from the plane itself.

    Where a plane's flames were not found apart (planes given by depth, not found by
    :func:`lf_flame.tomo.depth.find_depths`, whose regions tell them apart), two flames side by side on it are two
    regions above the segmentation threshold; :func:`measure_flame` on the whole plane measures one of them. Here
    each region of at least :data:`MIN_AREA_LENSLETS` lenslets above ``segment_fraction`` of the plane's brightest
    lenslet that holds at least ``share`` of the light of the region holding the most is a flame; where two or more
    such regions' columns do not overlap, each band reaches halfway to its neighbour's (the bands of
    ``lf-flame profiles``' found planes, by columns). On a plane of *emission* only: on a refocused plane other
    flames' defocused light forms such regions too.

    Parameters
    ----------
    plane : ndarray of shape (R, C)
        A plane of emission on the camera's lenslet grid (row 0 the top).
    camera : PlenopticCamera
    segment_fraction : float
        In (0, 1): the threshold, a fraction of the plane's brightest lenslet (:data:`EMISSION_MEASURE`'s).
    share : float
        In (0, 1]: the least light a region holds, a fraction of the light of the region holding the most
        (:data:`SEPARATE_SHARE`).

    Returns
    -------
    list of (int, int) or [None]
        The bands ``[c0, c1)`` (lenslet columns, left to right, covering every column), or ``[None]`` (the whole
        plane: one flame, flames whose columns overlap, or a plane without light).

    Raises
    ------
    ValueError
        A plane of another shape than the camera's lenslet grid, not finite; ``segment_fraction`` or ``share``
        outside its range.
    """
    img = _check_plane(plane, camera)
    if not (0.0 < segment_fraction < 1.0 and 0.0 < share <= 1.0):
        raise ValueError(f"segment_fraction must lie in (0, 1) and share in (0, 1]. Received: {segment_fraction!r}, "
                         f"{share!r}")
    peak = float(img.max())
    if not peak > 0.0:
        return [None]
    labels = measure.label(img >= segment_fraction * peak)
    regions = [r for r in measure.regionprops(labels, intensity_image=img) if r.area >= MIN_AREA_LENSLETS]
    light = [r.intensity_mean * r.area for r in regions]
    spans = sorted((r.bbox[1], r.bbox[3]) for r, q in zip(regions, light) if q >= share * max(light, default=0.0))
    merged = []
    for c0, c1 in spans:                                   # overlapping columns: one band (one behind another)
        if merged and c0 < merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], c1))
        else:
            merged.append((c0, c1))
    if len(merged) < 2:
        return [None]
    edges = [0] + [(a[1] + b[0]) // 2 for a, b in zip(merged, merged[1:])] + [int(camera.n_cols)]
    return list(zip(edges[:-1], edges[1:]))


def flame_truth(obj: dict) -> dict:
    """The simulation's truth of one flame object (:func:`lf_flame.simulate.scenes.flame_scene`).

    Returns
    -------
    dict with ``depth_offset_mm``, ``height_mm``, ``base_y_mm``, ``tip_y_mm`` and
    ``centre_x_mm`` (object space, mm) and ``columns`` (the object's ``roi`` columns).

    Raises
    ------
    ValueError
        If ``obj`` is not a flame object (lacks a height, base or centre).
    """
    missing = [k for k in ("depth_offset_mm", "height_mm", "base_y_mm", "centre_x_mm", "roi") if k not in obj]
    if missing:
        raise ValueError(f"not a flame object: lacks {missing}. Received: {obj.get('name', obj)!r}")
    return dict(depth_offset_mm=float(obj["depth_offset_mm"]), height_mm=float(obj["height_mm"]),
                base_y_mm=float(obj["base_y_mm"]), tip_y_mm=float(obj["base_y_mm"]) + float(obj["height_mm"]),
                centre_x_mm=float(obj["centre_x_mm"]), columns=(int(obj["roi"][2]), int(obj["roi"][3])))
