"""The depths a camera can refocus: its imaging range (:func:`imaging_range_mm`), which every depth search
covers unless narrowed (:func:`search_range_mm`), and outside which planes are refused (:func:`check_imaging_range`;
a plane given twice, :func:`check_planes_once`).
"""
from __future__ import annotations

import math

from .camera import PlenopticCamera


#: The largest |slope| (lenslets per view step) searched unless told: beyond it a point's image
#: moves more than this many lenslets between neighbouring views and every view sees it blurred
#: over as many lenslets (the paper's planes reach 2.28).
MAX_SEARCH_SLOPE = 3.0
#: The nearest depth searched is where the object distance is this multiple of the main lens's
#: focal length (nearer, the image runs off to infinity).
NEAR_LIMIT = 1.05
#: The farthest depth a camera refocuses (:func:`imaging_range_mm`) is at most this many times its focus distance
#: from it, where the slope still changes with depth.
IMAGING_FAR_FOCUS = 10.0


def imaging_range_mm(camera: PlenopticCamera, max_slope: float = MAX_SEARCH_SLOPE) -> tuple[float, float]:
    """Depths (mm from the focus distance) a camera can refocus: slopes within ``max_slope``,
    object distances beyond :data:`NEAR_LIMIT` focal lengths (and finite), or, for a camera focused
    nearer than that (a microscope objective's magnification), beyond halfway from the focal length to
    the focus distance.

    Parameters
    ----------
    camera : PlenopticCamera
    max_slope : float
        Largest |slope|, lenslets per view step, > 0.

    Returns
    -------
    (near, far) : float, float
        mm, negative nearer the camera. ``far`` is capped at 10 focus distances.

    Notes
    -----
    ``slope(z) = -d (1 - d / z_i) / (g N)`` (``PlenopticCamera.slope_for_depth``) rises
    monotonically from minus infinity at the main lens's focal length ``F`` to
    ``d (d - F) / (F g N)`` at infinity; the range is where ``|slope| <= max_slope``, found by
    bisection on each side of the focus distance.
    """
    if not (math.isfinite(max_slope) and max_slope > 0):
        raise ValueError(f"max_slope must be positive and finite. Received: {max_slope!r}")
    z_f = camera.focus_distance_mm
    near_mm = min(NEAR_LIMIT * camera.main_focal_mm, (camera.main_focal_mm + z_f) / 2) - z_f
    far_mm = IMAGING_FAR_FOCUS * z_f

    def slope(d):
        return camera.slope_for_depth(d)

    def edge(a, b, target):     # bisection for slope(d) = target between a (inside) and b (outside)
        for _ in range(80):
            m = 0.5 * (a + b)
            if abs(slope(m)) <= abs(target):
                a = m
            else:
                b = m
        return a
    lo = near_mm if abs(slope(near_mm)) <= max_slope else edge(0.0, near_mm, max_slope)
    hi = far_mm if abs(slope(far_mm)) <= max_slope else edge(0.0, far_mm, max_slope)
    return float(lo), float(hi)


def search_range_mm(camera: PlenopticCamera, depth_range_mm=None) -> tuple[float, float]:
    """Depths to search (mm from the focus distance, > 0 farther): the camera's imaging range
    (:func:`imaging_range_mm`), clipped to ``depth_range_mm`` (low, high) when given.

    Raises
    ------
    ValueError
        ``depth_range_mm`` not two finite depths, low < high, or wholly outside the imaging range.
    """
    lo, hi = imaging_range_mm(camera)
    if depth_range_mm is None:
        return lo, hi
    a, b = (float(d) for d in depth_range_mm)
    if not (math.isfinite(a) and math.isfinite(b) and b > a):
        raise ValueError(f"a depth range is two finite depths, low < high. Received: {depth_range_mm!r}")
    if b <= lo or a >= hi:
        raise ValueError(f"depths {a:+g} .. {b:+g} mm lie outside what this camera can refocus "
                         f"({lo:+.4g} .. {hi:+.4g} mm from its focus distance)")
    return max(a, lo), min(b, hi)


def check_planes_once(depths_mm) -> None:
    """Refuse a plane given twice: two identical planes, whose emission the data cannot share out.

    Parameters
    ----------
    depths_mm : sequence of float
        Plane depths, mm from the focus distance.

    Raises
    ------
    ValueError
        Naming the depths given more than once.
    """
    seen = [float(d) for d in depths_mm]
    twice = sorted({d for d in seen if seen.count(d) > 1})
    if twice:
        raise ValueError(f"planes at {', '.join(f'{d:+g}' for d in twice)} mm are given more than once: give each "
                         "plane once")


def check_imaging_range(camera: PlenopticCamera, depths_mm) -> None:
    """Refuse planes the camera cannot refocus: depths outside :func:`imaging_range_mm`; and a plane given twice.

    Parameters
    ----------
    camera : PlenopticCamera
    depths_mm : sequence of float
        Plane depths, mm from the focus distance (> 0 farther).

    Raises
    ------
    ValueError
        Naming the depths outside the range and the range, or the depth given twice (solved as two identical
        planes, whose emission the data cannot share out).
    """
    check_planes_once(depths_mm)
    lo, hi = imaging_range_mm(camera)
    far = [float(d) for d in depths_mm if not lo <= d <= hi]
    if far:
        raise ValueError(f"planes at {', '.join(f'{d:+g}' for d in far)} mm lie outside what this camera can "
                         f"refocus ({lo:+.4g} .. {hi:+.4g} mm from its focus distance: |slope| <= "
                         f"{MAX_SEARCH_SLOPE:g} lenslets per view, and no farther than {IMAGING_FAR_FOCUS:g} times "
                         "the focus distance)")
