"""Scenes of flames at depths nobody gave: random continuous depths, flames behind one another.

:func:`random_depth_scene` draws 2-4 flame-like emitters at continuous random depths
(never on a grid), random heights and lateral positions; :func:`behind_scene` stands two
flames in the same columns a given distance apart in depth; :func:`column_scene` stands two
or three flames of varied size and brightness in one column band, 3-15 mm apart. Each flame is one layer of
:func:`lf_flame.simulate.scenes.flame_luminosity` (a luminous sheath about a dark core), so
the truth of flame ``k`` is ``scene.layers[k]`` at ``scene.objects[k]["depth_offset_mm"]``.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import PlenopticCamera
from .scenes import FLAME_EFFECTS, PAPER_DEPTHS_MM, _flame_layer, _roi, camera_template_scale
from .layers import Scene

#: Depth range (mm from the focal plane) of the paper camera's usable slopes (about -1.9 .. +2.8).
DEPTH_RANGE_MM = (-15.0, 25.0)
#: Flame heights (mm) drawn log-uniformly, capped at 85 % of the field's height at the flame's depth.
HEIGHT_RANGE_MM = (2.0, 25.0)
#: Smallest half-width of a flame's base (mm): 7-12 % of its height, but never below this
#: (about 3 lenslet footprints at the focal plane of the paper camera), so a flame is resolved.
MIN_HALF_WIDTH_MM = 0.4
#: The paper camera's :data:`DEPTH_RANGE_MM` in slopes (lenslets per view step) and its lenslet
#: footprint at the focus distance (mm): :func:`camera_depth_scene` scales both to another camera.
PAPER_SLOPE_RANGE = (-1.9035, 2.8110)
PAPER_FOOTPRINT_MM = 0.131413
#: :func:`camera_depth_ranges` keeps depths within this share of the focus distance (the paper's
#: -15 .. +25 mm are -4.6 .. +7.7 % of its 326 mm).
MAX_DEPTH_SHARE = 0.25


def _flame(camera, dz, H, half_w0, cx, base_y, level, texels_per_lenslet, name):
    """One upright flame layer (:func:`~lf_flame.simulate.scenes._flame_layer`, no sway) and its
    object record, named ``name``, with its base's half-width."""
    layer, obj = _flame_layer(camera, float(dz), float(H), float(cx), float(base_y), float(level), 0.0, 0.0,
                              texels_per_lenslet, half_width_mm=float(half_w0))
    obj.update(name=name, half_width_mm=float(half_w0))
    return layer, obj


def _check(camera, depth_range, n_flames):
    lo, hi = (float(v) for v in depth_range)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ValueError(f"depth_range must be two finite depths, low < high. Received: {depth_range!r}")
    for d in (lo, hi):
        camera.image_distance_mm(camera.object_distance_mm(d))   # raises for a depth the camera cannot image
    if n_flames is not None and not (isinstance(n_flames, (int, np.integer)) and 1 <= n_flames <= 4):
        raise ValueError(f"n_flames must be an integer from 1 to 4 (or None: 2-4 drawn). Received: {n_flames!r}")
    return lo, hi


def random_depth_scene(camera: PlenopticCamera, rng: np.random.Generator, *, n_flames: int | None = None,
                       depth_range=DEPTH_RANGE_MM, height_range=HEIGHT_RANGE_MM,
                       texels_per_lenslet: float = 3.0, max_tries: int = 500,
                       min_half_width_mm: float = MIN_HALF_WIDTH_MM) -> Scene:
    """Flames at continuous random depths, heights and lateral positions, each in its own part of the image.

    Per flame: depth ``U(depth_range)`` (continuous: never on a grid); height
    log-uniform in ``height_range`` capped at 85 % of the field's height at that depth (and
    its low end at half that cap);
    half-width of the base ``U(0.07, 0.12)`` of the height, at least
    :data:`MIN_HALF_WIDTH_MM`; base and centre uniform over the field (the flame inside
    the central 90 %); peak radiance ``U(0.5, 1.0)``. A flame whose box (in lenslets,
    with a 3-lenslet margin) meets an earlier one's is drawn again, so the flames stand
    apart in the image: flames in the same columns are :func:`behind_scene`.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator
        Source of every draw (the scene's own seed).
    n_flames : int or None
        1-4; None draws 2-4.
    depth_range : (float, float)
        Depths (mm from the focal plane, positive farther) the flames are drawn in.
    height_range : (float, float)
        Heights (mm), positive, low < high.
    texels_per_lenslet : float
    max_tries : int
        Draws per flame before giving up.
    min_half_width_mm : float
        Smallest half-width of a flame's base (mm).

    Returns
    -------
    Scene
        ``name="depth"``, one layer and one object per flame (``depth_offset_mm``,
        ``height_mm``, ``half_width_mm``, ``centre_x_mm``, ``base_y_mm``, ``radiance``,
        ``roi`` = (row0, row1, col0, col1) lenslets), in drawing order.

    Raises
    ------
    ValueError
        A bad depth or height range, a depth the camera cannot image, a bad ``n_flames``,
        or no room for the flames after ``max_tries`` draws.
    """
    lo, hi = _check(camera, depth_range, n_flames)
    h_lo, h_hi = (float(v) for v in height_range)
    if not (math.isfinite(h_lo) and math.isfinite(h_hi) and 0 < h_lo < h_hi):
        raise ValueError(f"height_range must be two positive heights, low < high. Received: {height_range!r}")
    n = int(rng.integers(2, 5)) if n_flames is None else int(n_flames)
    layers, objects, boxes = [], [], []
    for k in range(n):
        for _ in range(max_tries):
            dz = float(rng.uniform(lo, hi))
            fh, fw = camera.field_of_view_mm(dz)
            h_top = min(h_hi, 0.85 * fh)
            H = float(math.exp(rng.uniform(math.log(min(h_lo, 0.5 * h_top)), math.log(h_top))))
            hw = max(float(rng.uniform(0.07, 0.12)) * H, min_half_width_mm)
            if hw > 0.45 * fw:       # numpy's 'high - low < 0' had said so
                raise ValueError(f"the camera's field, {fw:.3g} mm wide at {dz:+.3g} mm ({camera.n_cols} lenslets), "
                                 f"is too narrow for a flame of its smallest half-width ({min_half_width_mm:g} mm): "
                                 "this scene needs more lenslets")
            base = float(rng.uniform(-0.45 * fh, 0.45 * fh - H))
            cx = float(rng.uniform(-0.45 * fw + hw, 0.45 * fw - hw))
            level = float(rng.uniform(0.5, 1.0))
            roi = _roi(camera, dz, base, base + H, cx - hw, cx + hw)
            if all(roi[1] <= b[0] or b[1] <= roi[0] or roi[3] <= b[2] or b[3] <= roi[2] for b in boxes):
                break
        else:
            raise ValueError(f"no room for flame {k + 1} of {n} after {max_tries} draws")
        boxes.append(roi)
        layer, obj = _flame(camera, dz, H, hw, cx, base, level, texels_per_lenslet, f"flame_{k}")
        layers.append(layer)
        objects.append(obj)
    return Scene("depth", tuple(layers), FLAME_EFFECTS, tuple(objects))


def _parallax_scale(camera: PlenopticCamera) -> float:
    """:func:`camera_depth_ranges`' factor from the paper camera's slopes to ``camera``'s: ``min(14 / (N - 1),
    min(R, C) / 90)`` (``N`` views, ``R x C`` lenslets), 1 on the paper's camera."""
    n, R, C = camera.pixels_per_lenslet, camera.n_rows, camera.n_cols
    return min(14.0 / max(n - 1, 1), min(R, C) / 90.0)


def carried_depths(camera: PlenopticCamera, paper_depths_mm) -> tuple:
    """Depths on the paper's camera carried to ``camera`` as :func:`camera_depth_ranges` carries its range: each
    depth's slope on the paper's camera times the same factor, the depth of that slope on ``camera``, so that a
    scene's flames lie as far apart in parallax on any camera; where one would fall outside the
    :func:`camera_depth_ranges` range, every slope shrinks by one factor until it fits (the flames keep their
    order and their spacing's proportions).

    Parameters
    ----------
    camera : PlenopticCamera
    paper_depths_mm : sequence of float
        mm from the paper camera's focus distance, > 0 farther.

    Returns
    -------
    tuple of float
        mm from ``camera``'s focus distance (to 1e-6 mm: the paper's camera keeps the depths given).
    """
    from ..optics.camera import PAPER_CAMERA
    lo, hi = camera_depth_ranges(camera)["depth_range"]
    scale = _parallax_scale(camera)
    s_lo, s_hi = camera.slope_for_depth(lo), camera.slope_for_depth(hi)
    slopes = np.array([PAPER_CAMERA.slope_for_depth(float(d)) * scale for d in paper_depths_mm])
    fit = min([1.0] + [s_hi / s for s in slopes if s > s_hi] + [s_lo / s for s in slopes if s < s_lo])
    return tuple(round(float(np.clip(camera.depth_for_slope(fit * s), lo, hi)), 6) + 0.0 for s in slopes)


def paper_layout(camera: PlenopticCamera) -> dict:
    """The paper's four-plane scenes (``shapes``, ``flame``, ``colour-flame``) on ``camera``: ``depths_mm``, the
    paper's +20, +10, 0, -10 mm carried to it as far apart in parallax (:func:`carried_depths`), and the flames'
    ``template_scale`` (:func:`lf_flame.simulate.scenes.camera_template_scale`): on a camera of a smaller field the
    paper's 8-21 mm flames stood past its edges. The paper's camera keeps its own."""
    return dict(depths_mm=carried_depths(camera, PAPER_DEPTHS_MM), template_scale=camera_template_scale(camera))


def camera_depth_ranges(camera: PlenopticCamera) -> dict:
    """:func:`random_depth_scene`'s ranges for any camera: the paper camera's, scaled.

    - depths: the slopes of :data:`PAPER_SLOPE_RANGE` times ``min(14 / (N - 1), min(R, C) / 90)``
      (``N`` views, ``R x C`` lenslets), so that a flame's parallax across the aperture takes
      the same share of the field as on the paper's camera (never more parallax than its 15
      views give); a far slope beyond 80 % of the slope at infinity is clipped there, and the
      depths to within :data:`MAX_DEPTH_SHARE` of the focus distance (a camera of many views
      and few lenslets images far deeper than it resolves: its flames stay near focus);
    - heights and the smallest half-width: the paper's in lenslet footprints at the focus
      distance (``pitch z_f / d``): 2-25 mm and 0.4 mm are 15.2-190 and 3.04 footprints.

    On the paper camera: depths -15.0 .. +25.0 mm, heights 2-25 mm, half-width 0.4 mm.

    Parameters
    ----------
    camera : PlenopticCamera

    Returns
    -------
    dict
        ``depth_range`` (near, far) mm from the focus distance, ``height_range`` (mm),
        ``min_half_width_mm`` (mm): :func:`random_depth_scene`'s keyword arguments.
    """
    scale = _parallax_scale(camera)
    s_inf = camera.slope_for_depth(1e6 * camera.focus_distance_mm)
    lo_s, hi_s = (v * scale for v in PAPER_SLOPE_RANGE)
    if s_inf > 0:
        hi_s = min(hi_s, 0.8 * s_inf)
    foot = camera.mla_pitch_mm * camera.focus_distance_mm / camera.mla_distance_mm / PAPER_FOOTPRINT_MM
    reach = MAX_DEPTH_SHARE * camera.focus_distance_mm
    return dict(depth_range=(max(camera.depth_for_slope(lo_s), -reach), min(camera.depth_for_slope(hi_s), reach)),
                height_range=tuple(v * foot for v in HEIGHT_RANGE_MM), min_half_width_mm=MIN_HALF_WIDTH_MM * foot)


def camera_depth_scene(camera: PlenopticCamera, rng: np.random.Generator, *, n_flames: int | None = None,
                       texels_per_lenslet: float = 3.0) -> Scene:
    """:func:`random_depth_scene` with :func:`camera_depth_ranges`: flames at random depths that any
    camera can image and resolve (``lf-flame simulate --scene depth``). Without ``n_flames``,
    2-4 are drawn, and one fewer (down to one) while a small field has no room for them.

    Raises
    ------
    ValueError
        As :func:`random_depth_scene`.
    """
    ranges = camera_depth_ranges(camera)
    if n_flames is not None:
        return random_depth_scene(camera, rng, n_flames=n_flames, texels_per_lenslet=texels_per_lenslet, **ranges)
    n = int(rng.integers(2, 5))
    while True:
        try:
            return random_depth_scene(camera, rng, n_flames=n, texels_per_lenslet=texels_per_lenslet, **ranges)
        except ValueError as e:
            if n == 1 or not str(e).startswith("no room"):
                raise
            n -= 1


def behind_scene(camera: PlenopticCamera, rng: np.random.Generator, separation_mm: float, *,
                 depth_range=DEPTH_RANGE_MM, texels_per_lenslet: float = 3.0) -> Scene:
    """Two flames in the same columns, ``separation_mm`` apart in depth (one behind the other).

    The far flame: depth ``U(lo, hi - separation)`` + separation, height ``U(0.5, 0.8)`` of
    the field's height, radiance ``U(0.7, 1.0)``; the near flame: ``U(0.4, 0.7)`` of the far
    one's height, radiance ``U(0.5, 1.0)``. Both centred on the same column (lateral
    offset ``U(-0.3, 0.3)`` mm between them), bases near the bottom of the field;
    half-widths 8 % of the height, at least :data:`MIN_HALF_WIDTH_MM`.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator
    separation_mm : float
        Depth between the two flames (mm), positive and below the range's span.
    depth_range : (float, float)
    texels_per_lenslet : float

    Returns
    -------
    Scene
        ``name="behind"``, the far flame first (objects as :func:`random_depth_scene`'s).

    Raises
    ------
    ValueError
        A separation that is not positive or does not fit in ``depth_range``; a bad range.
    """
    lo, hi = _check(camera, depth_range, None)
    sep = float(separation_mm)
    if not (math.isfinite(sep) and 0 < sep < hi - lo):
        raise ValueError(f"separation_mm must be positive and below the depth range's span {hi - lo:g} mm. "
                         f"Received: {separation_mm!r}")
    near = float(rng.uniform(lo, hi - sep))
    far = near + sep
    cx = float(rng.uniform(-0.15, 0.15)) * camera.field_of_view_mm(0.0)[1]
    layers, objects = [], []
    fh = camera.field_of_view_mm(far)[0]
    H_far = float(rng.uniform(0.5, 0.8)) * fh
    H_near = float(rng.uniform(0.4, 0.7)) * H_far
    spec = ((far, H_far, float(rng.uniform(0.7, 1.0)), cx), (near, H_near, float(rng.uniform(0.5, 1.0)),
                                                               cx + float(rng.uniform(-0.3, 0.3))))
    for k, (dz, H, level, x) in enumerate(spec):
        base = -0.42 * camera.field_of_view_mm(dz)[0]
        layer, obj = _flame(camera, dz, H, max(0.08 * H, MIN_HALF_WIDTH_MM), x, base, level, texels_per_lenslet,
                            ("far", "near")[k])
        layers.append(layer)
        objects.append(obj)
    return Scene("behind", tuple(layers), FLAME_EFFECTS, tuple(objects))


#: :func:`column_scene`: depths between neighbouring flames of a column (mm), their brightness ratio to the first
#: flame (log-uniform), and the share of scenes with a flame within :data:`NEAR_FOCUS_MM` of the focal plane.
COLUMN_SEPARATION_MM = (3.0, 15.0)
COLUMN_RATIO = (0.3, 3.0)
NEAR_FOCUS_SHARE = 1.0 / 3.0
NEAR_FOCUS_MM = 3.0


def column_scene(camera: PlenopticCamera, rng: np.random.Generator, *, n_flames: int | None = None,
                 depth_range=DEPTH_RANGE_MM, texels_per_lenslet: float = 3.0) -> Scene:
    """Two or three flames in one column band, one behind another, of varied size and brightness.

    Depths: in a share :data:`NEAR_FOCUS_SHARE` of scenes one flame stands within
    :data:`NEAR_FOCUS_MM` of the focal plane; the others follow at separations
    ``U(COLUMN_SEPARATION_MM)`` on either side, all within ``depth_range`` (drawn again
    otherwise). Per flame: height ``U(0.3, 0.8)`` of the field's height at its depth, half-width
    ``U(0.06, 0.12)`` of the height (at least :data:`MIN_HALF_WIDTH_MM`), lateral offset
    ``U(-0.4, 0.4)`` mm from the band's centre, base ``U(-0.45, -0.3)`` of the field's height;
    brightness relative to the first flame log-uniform in :data:`COLUMN_RATIO`, the brightest at
    a peak radiance ``U(0.6, 1.0)``.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator
    n_flames : int or None
        2 or 3; None: drawn.
    depth_range : (float, float)
        mm from the focal plane; it must hold the flames' separations.
    texels_per_lenslet : float

    Returns
    -------
    Scene
        ``name="column"``, objects as :func:`random_depth_scene`'s, ordered by depth.

    Raises
    ------
    ValueError
        A bad ``n_flames`` or range, or a range too short for the separations.
    """
    lo, hi = _check(camera, depth_range, None)
    n = int(rng.integers(2, 4)) if n_flames is None else n_flames
    if n not in (2, 3):
        raise ValueError(f"n_flames must be 2 or 3 (or None: drawn). Received: {n_flames!r}")
    s_lo, s_hi = COLUMN_SEPARATION_MM
    if hi - lo < (n - 1) * s_hi:
        raise ValueError(f"depth_range {depth_range!r} is too short for {n} flames up to {s_hi:g} mm apart")
    near_focus = bool(rng.random() < NEAR_FOCUS_SHARE) and lo < 0 < hi
    for _ in range(1000):
        seps = rng.uniform(s_lo, s_hi, n - 1)
        if near_focus:
            first = float(rng.uniform(-NEAR_FOCUS_MM, NEAR_FOCUS_MM))
            k = int(rng.integers(0, n))                      # which flame stands near focus
            depths = first + np.concatenate([[0.0], np.cumsum(seps)]) - np.concatenate([[0.0], np.cumsum(seps)])[k]
        else:
            depths = float(rng.uniform(lo, hi)) + np.concatenate([[0.0], np.cumsum(seps)])
        if depths.min() >= lo and depths.max() <= hi:
            break
    else:
        raise ValueError(f"no depths for {n} flames within {depth_range!r}")
    ratios = np.exp(rng.uniform(np.log(COLUMN_RATIO[0]), np.log(COLUMN_RATIO[1]), n))
    ratios[0] = 1.0
    levels = ratios / ratios.max() * float(rng.uniform(0.6, 1.0))
    cx = float(rng.uniform(-0.15, 0.15)) * camera.field_of_view_mm(0.0)[1]
    layers, objects = [], []
    for k in np.argsort(depths):
        dz = float(depths[k])
        fh = camera.field_of_view_mm(dz)[0]
        H = float(rng.uniform(0.3, 0.8)) * fh
        hw = max(float(rng.uniform(0.06, 0.12)) * H, MIN_HALF_WIDTH_MM)
        layer, obj = _flame(camera, dz, H, hw, cx + float(rng.uniform(-0.4, 0.4)), float(rng.uniform(-0.45, -0.3)) * fh,
                            float(levels[k]), texels_per_lenslet, f"flame_{len(layers)}")
        layers.append(layer)
        objects.append(obj)
    return Scene("column", tuple(layers), FLAME_EFFECTS, tuple(objects))
