"""Scenes as data: planar layers with radiance textures, and the effects each scene needs.

The one place that defines the paper's two scenes (multi-shape, Fig. 5; flame, Fig. 6)
and the point source (the camera's PSF); what a scene is made of (its layers and effects):
:mod:`.layers`. Every sample is drawn from a seeded ``numpy.random.Generator``; how and why each
parameter varies is in the docstrings and ``docs/scenes.md``.
"""
from __future__ import annotations

import math
import numpy as np

from ..optics.camera import PAPER_CAMERA, PlenopticCamera
from .layers import Effects, Layer, Scene

#: Depth offsets (mm) of the paper's four planes, in the order of its tables.
PAPER_DEPTHS_MM = (20.0, 10.0, 0.0, -10.0)
#: The shape at each depth (paper Sec. III-A).
SHAPE_AT_DEPTH = ("rectangle", "triangle", "circle", "square")
#: Paper Sec. III-B: mean flame heights range 14.47–29.48 mm across depths and the
#: standard deviations 1.41–1.48 mm; the paper does not say which depth has which, so
#: the means and deviations are spread linearly, tallest at the farthest plane.
FLAME_HEIGHT_MEAN_MM = (29.48, 24.48, 19.47, 14.47)
FLAME_HEIGHT_SD_MM = (1.48, 1.457, 1.433, 1.41)

#: How much a scene varies from sample to sample (``docs/scenes.md``):
#: ``"paper"`` varies only what the paper states (the flames' heights; the shapes get the
#: same small relative spread), ``"varied"`` also position, size, rotation, radiance and
#: flicker (the generalisation test).
REGIMES = ("paper", "varied")
#: Relative spread (sd / mean, ~0.070) of the shapes' size and position in the ``"paper"``
#: regime: the mean over the four depths of the flames' height coefficient of variation
#: ``FLAME_HEIGHT_SD_MM[k] / FLAME_HEIGHT_MEAN_MM[k]``, so both scenes vary alike.
PAPER_RELATIVE_SD = sum(sd / m for sd, m in zip(FLAME_HEIGHT_SD_MM, FLAME_HEIGHT_MEAN_MM)) / len(FLAME_HEIGHT_MEAN_MM)


# ---------------------------------------------------------------------------------
def _layer_grid(camera: PlenopticCamera, dz: float, texels_per_lenslet: float, margin: float):
    """Texture grid covering the field at depth ``dz`` (mm), enlarged by ``margin``; ValueError for
    ``texels_per_lenslet`` not finite and > 0."""
    if not (math.isfinite(texels_per_lenslet) and texels_per_lenslet > 0):
        raise ValueError(f"texels_per_lenslet must be a finite number > 0. Received: {texels_per_lenslet!r}")
    h, w = camera.field_of_view_mm(dz)
    h, w = h * margin, w * margin
    rows = int(math.ceil(camera.n_rows * margin * texels_per_lenslet))
    cols = int(math.ceil(camera.n_cols * margin * texels_per_lenslet))
    y = (0.5 - (np.arange(rows) + 0.5) / rows) * h      # texel centres, y up
    x = ((np.arange(cols) + 0.5) / cols - 0.5) * w
    return y[:, None], x[None, :], (h, w), h / rows


def _polygon_coverage(y, x, verts, texel):
    """Anti-aliased coverage of a convex polygon (vertices counter-clockwise in (x, y))."""
    d = np.full(np.broadcast(y, x).shape, -np.inf)
    n = len(verts)
    for k in range(n):
        (x0, y0), (x1, y1) = verts[k], verts[(k + 1) % n]
        ex, ey = x1 - x0, y1 - y0
        L = math.hypot(ex, ey)
        # outward normal of a counter-clockwise edge is (ey, -ex)
        d = np.maximum(d, ((x - x0) * ey - (y - y0) * ex) / L)
    return np.clip(0.5 - d / texel, 0.0, 1.0)


def _shape_vertices(kind, cy, cx, size, angle):
    if kind == "rectangle":
        hw, hh = 0.5 * size / 1.6, 0.5 * size            # portrait rectangle, aspect 1.6
        pts = [(-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh)]
    elif kind == "square":
        s = 0.5 * size * 0.8
        pts = [(-s, -s), (s, -s), (s, s), (-s, s)]
    elif kind == "triangle":
        r = 0.55 * size
        pts = [(r * math.cos(math.radians(a)), r * math.sin(math.radians(a))) for a in (210.0, 330.0, 90.0)]
    else:
        raise ValueError(f"unknown polygon shape {kind!r}")
    ca, sa = math.cos(angle), math.sin(angle)
    return [(cx + px * ca - py * sa, cy + px * sa + py * ca) for px, py in pts]


def _roi(camera, dz, y0, y1, x0, x1, margin_lenslets=3.0):
    """Box (row0, row1, col0, col1) in lenslets of an object-space box at depth dz."""
    ra, ca = camera.object_to_lenslet(y1, x0, dz)
    rb, cb = camera.object_to_lenslet(y0, x1, dz)
    r0 = max(0, int(math.floor(min(ra, rb) - margin_lenslets)))
    r1 = min(camera.n_rows, int(math.ceil(max(ra, rb) + margin_lenslets)))
    c0 = max(0, int(math.floor(min(ca, cb) - margin_lenslets)))
    c1 = min(camera.n_cols, int(math.ceil(max(ca, cb) + margin_lenslets)))
    return (r0, r1, c0, c1)


def _check_regime(regime) -> None:
    """Raise ValueError unless ``regime`` is one of :data:`REGIMES`."""
    if regime not in REGIMES:
        raise ValueError(f"regime must be one of {REGIMES}. Received: regime={regime!r}")


def _shape_params(kind: str, ch: float, cw: float, rng: np.random.Generator, vary: bool, regime: str):
    """Draw one shape's parameters in focal-plane millimetres (before scaling to its depth).

    Parameters
    ----------
    kind : str
        One of :data:`SHAPE_AT_DEPTH`.
    ch, cw : float
        Height and width of the shape's cell at the focal plane, mm.
    rng : numpy.random.Generator
        Source of the draws (none is drawn when ``vary`` is False).
    vary : bool
        False: the nominal template, whatever ``regime`` says.
    regime : str
        One of :data:`REGIMES` (see :func:`shapes_scene`).

    Returns
    -------
    dy, dx : float
        Offset of the centre from the cell's centre (y up, x right), mm.
    size : float
        Size of the shape, mm.
    angle : float
        Rotation, radians (counter-clockwise).
    level : float
        Radiance (1 saturates the sensor).
    """
    nominal = 0.6 * min(ch, cw)
    if not vary:
        return 0.0, 0.0, nominal, 0.0, 1.0
    if regime == "paper":
        size = nominal * rng.normal(1.0, PAPER_RELATIVE_SD)
        dy = rng.normal(0.0, PAPER_RELATIVE_SD * nominal)
        dx = rng.normal(0.0, PAPER_RELATIVE_SD * nominal)
        return dy, dx, size, 0.0, 1.0
    # "varied": the draws and their order are those of the scenes before regimes existed,
    # so a seed gives the same sample as it did then.
    dy = rng.uniform(-0.12, 0.12) * ch
    dx = rng.uniform(-0.12, 0.12) * cw
    size = rng.uniform(0.45, 0.75) * min(ch, cw)
    angle = 0.0 if kind == "circle" else math.radians(rng.uniform(-20, 20))
    level = rng.uniform(0.5, 1.0)
    return dy, dx, size, angle, level


def shapes_scene(camera: PlenopticCamera, rng: np.random.Generator, *,
                 texels_per_lenslet: float = 3.0, vary: bool = True, depths_mm=PAPER_DEPTHS_MM,
                 regime: str = "varied") -> Scene:
    """The paper's multi-shape scene (Fig. 5): rectangle +20, triangle +10, circle 0, square −10 mm.

    Layout: the field at the focal plane is split 2 × 2 (rectangle top-left, triangle
    top-right, circle bottom-left, square bottom-right), each cell scaled with its
    depth so every shape is seen in its own cell and the slope search has a region of
    interest per object. The nominal template: centred in its cell, size 60 % of the
    cell's smaller side, upright, radiance 1. What varies per sample depends on
    ``regime`` (sizes and offsets below are in focal-plane mm, scaled with the depth):

    - ``"paper"``: the template with the flames' relative spread
      (:data:`PAPER_RELATIVE_SD`, ~7 %): size × Normal(1, PAPER_RELATIVE_SD), centre
      offsets in y and x ~ Normal(0, PAPER_RELATIVE_SD × template size). No rotation,
      radiance 1. The paper states no variation of its shapes.
    - ``"varied"``: centre jitter ±12 % of the cell, size 45–75 % of the cell's
      smaller side, rotation ±20° (polygons), radiance 0.5–1.0, all uniform. Why: the
      network must learn refocusing, not one template (the generalisation test).

    Effects: opaque objects (occlusion), aperture and cos⁴ of the paper's Eq. 1;
    noise-free like the paper's simulation.

    Parameters
    ----------
    camera : PlenopticCamera
        The camera whose field the scene fills.
    rng : numpy.random.Generator
        Source of every random draw.
    texels_per_lenslet : float
        Texture resolution, texels per lenslet footprint.
    vary : bool
        False: the nominal scene (every shape its template), used by the slope search;
        it wins over ``regime`` and draws nothing from ``rng``.
    depths_mm : sequence of four float
        Depth offsets (mm, same order as :data:`SHAPE_AT_DEPTH`), e.g. to check the
        slope search away from the paper's planes.
    regime : str
        One of :data:`REGIMES`: ``"paper"`` or ``"varied"`` (default).

    Returns
    -------
    Scene
        Four layers ordered as ``depths_mm``; each object records its drawn parameters
        (mm, degrees) and ``regime`` (``"nominal"`` when ``vary`` is False).

    Raises
    ------
    ValueError
        If ``depths_mm`` does not hold four depths or ``regime`` is not in :data:`REGIMES`.
    """
    _check_regime(regime)
    if len(depths_mm) != len(SHAPE_AT_DEPTH):
        raise ValueError(f"depths_mm must hold {len(SHAPE_AT_DEPTH)} depths. Received: {depths_mm}")
    h0, w0 = camera.field_of_view_mm(0.0)
    cells = {"rectangle": (h0 / 4, -w0 / 4), "triangle": (h0 / 4, w0 / 4),
             "circle": (-h0 / 4, -w0 / 4), "square": (-h0 / 4, w0 / 4)}
    ch, cw = h0 / 2, w0 / 2
    layers, objects = [], []
    for dz, kind in zip(depths_mm, SHAPE_AT_DEPTH):
        scale = camera.object_distance_mm(dz) / camera.focus_distance_mm
        dy, dx, size, angle, level = _shape_params(kind, ch, cw, rng, vary, regime)
        cy, cx = cells[kind]
        cy, cx, size = (cy + dy) * scale, (cx + dx) * scale, size * scale
        y, x, (h, w), texel = _layer_grid(camera, dz, texels_per_lenslet, 1.2)
        if kind == "circle":
            cov = np.clip(0.5 - (np.hypot(y - cy, x - cx) - 0.5 * size) / texel, 0.0, 1.0)
        else:
            cov = _polygon_coverage(y, x, _shape_vertices(kind, cy, cx, size, angle), texel)
        cov = cov.astype(np.float32)
        layers.append(Layer(radiance=(level * cov).astype(np.float32), alpha=cov, depth_offset_mm=dz,
                            centre_mm=(0.0, 0.0), size_mm=(h, w)))
        half = 0.6 * size
        objects.append(dict(name=kind, depth_offset_mm=dz, centre_y_mm=cy, centre_x_mm=cx, size_mm=size,
                            angle_deg=math.degrees(angle), radiance=level, regime=regime if vary else "nominal",
                            roi=_roi(camera, dz, cy - half, cy + half, cx - half, cx + half)))
    return Scene("shapes", tuple(layers), Effects(aperture=True, cos4=True, occlusion=True), tuple(objects))


def flame_luminosity(eta, xi):
    """Projected luminosity of a laminar jet diffusion flame, normalised coordinates.

    ``eta`` = height / flame height in [0, 1], ``xi`` = lateral offset / local flame
    half-width. The flame is a thin luminous sheath of relative thickness 0.35 around a
    dark core (a Burke–Schumann flame sheet, Burke & Schumann 1928, thickened by soot);
    its line-of-sight projection is ``sqrt(1 - xi²) - sqrt((0.65)² - xi²)``. Axial
    luminosity rises from the dim blue base, peaks near 40 % of the height, and fades
    at the tip where soot burns out: ``sin(pi eta^0.75)``. Peak normalised to 1.

    Returns
    -------
    ndarray broadcast from ``eta`` and ``xi``, values in [0, 1].
    """
    eta = np.asarray(eta, dtype=np.float64)
    xi = np.abs(np.asarray(xi, dtype=np.float64))
    inner = 0.65
    proj = np.sqrt(np.clip(1.0 - xi ** 2, 0, None)) - np.sqrt(np.clip(inner ** 2 - xi ** 2, 0, None))
    proj /= math.sqrt(1 - inner ** 2)  # its maximum, at xi = inner
    axial = np.where((eta >= 0) & (eta <= 1), np.sin(np.pi * np.clip(eta, 0, 1) ** 0.75), 0.0)
    return np.clip(proj * axial, 0.0, 1.0)


def _flame_params(k: int, w0: float, rng: np.random.Generator, vary: bool, regime: str):
    """Draw the parameters of the flame at depth index ``k``.

    Parameters
    ----------
    k : int
        Index into :data:`PAPER_DEPTHS_MM`.
    w0 : float
        Width of the field at the focal plane, mm.
    rng : numpy.random.Generator
        Source of the draws (none is drawn when ``vary`` is False).
    vary : bool
        False: the nominal flame (mean height, no jitter, radiance 1, no sway).
    regime : str
        One of :data:`REGIMES` (see :func:`flame_scene`).

    Returns
    -------
    height : float
        Template height, mm (before ``template_scale``).
    jitter : float
        Lateral offset at the focal plane, mm.
    level : float
        Peak radiance.
    sway : float
        Sway amplitude as a fraction of the height.
    phase : float
        Sway phase, radians.
    """
    if not vary:
        return FLAME_HEIGHT_MEAN_MM[k], 0.0, 1.0, 0.0, 0.0
    height = rng.normal(FLAME_HEIGHT_MEAN_MM[k], FLAME_HEIGHT_SD_MM[k])
    if regime == "paper":
        return height, 0.0, 1.0, 0.0, 0.0
    # "varied": the draws and their order are those of the scenes before regimes existed.
    return (height, rng.uniform(-0.04, 0.04) * w0, rng.uniform(0.6, 1.0),
            rng.uniform(0.0, 0.06), rng.uniform(0.0, 2 * math.pi))


#: :func:`flame_scene`'s scale of the paper's flame heights on the paper's camera: the tallest flame (mean + 3 sd)
#: fills 90 % of the field at +20 mm.
TEMPLATE_SCALE = 0.64


def camera_template_scale(camera: PlenopticCamera) -> float:
    """:data:`TEMPLATE_SCALE` times ``camera``'s field height at its focus distance over the paper camera's
    (dimensionless): the paper's flames fill any camera's field as they fill the paper's (the paper's camera:
    :data:`TEMPLATE_SCALE` itself)."""
    return TEMPLATE_SCALE * camera.field_of_view_mm(0.0)[0] / PAPER_CAMERA.field_of_view_mm(0.0)[0]


def flame_scene(camera: PlenopticCamera, rng: np.random.Generator, *, template_scale: float | None = None,
                texels_per_lenslet: float = 3.0, vary: bool = True, regime: str = "varied",
                depths_mm=PAPER_DEPTHS_MM) -> Scene:
    """The paper's flame scene (Fig. 6): four flames, one at each of the four depths.

    The paper's 180 × 90-lenslet grid sees only about 23.7 × 11.8 mm at the focal plane
    (SPEC.md), smaller than its 30 mm flames, so templates are scaled by
    ``template_scale`` (0.64 on the paper's camera, :data:`TEMPLATE_SCALE`: the tallest flame, mean + 3 sd, fills
    90 % of the field at +20 mm; another camera's field in proportion) — the paper's optics are kept. Flames stand
    side by side (farthest left), bases near the bottom of the field. Half-width at the base 7 % of the height,
    narrowing as ``sqrt(1 - eta)``. What varies per sample depends on ``regime``:

    - ``"paper"``: only the height, as the paper states (Sec. III-B): the flame at
      depth k is Normal(:data:`FLAME_HEIGHT_MEAN_MM` [k], :data:`FLAME_HEIGHT_SD_MM` [k])
      template mm tall. Fixed lateral position, peak radiance 1, no flicker.
    - ``"varied"``: the height as above, lateral jitter ±4 % of the field width, peak
      radiance 0.6–1.0, and flicker: a sway of the centreline
      ``a eta² sin(2 pi eta / 0.6 + phi)``, ``a`` up to 6 % of the height, random phase
      (the generalisation test).

    Effects: optically thin flames add their emission (no occlusion); aperture and
    cos⁴ of Eq. 1; noise-free.

    Parameters
    ----------
    camera : PlenopticCamera
        The camera whose field the scene fills.
    rng : numpy.random.Generator
        Source of every random draw.
    template_scale : float or None
        Object-space scale of the paper's flame heights (dimensionless); None: :func:`camera_template_scale`, so that
        the flames fill ``camera``'s field as they fill the paper's (:data:`TEMPLATE_SCALE` on the paper's camera).
    texels_per_lenslet : float
        Texture resolution, texels per lenslet footprint.
    vary : bool
        False: the nominal scene (mean heights, no jitter, radiance 1, no sway); it wins
        over ``regime`` and draws nothing from ``rng``.
    regime : str
        One of :data:`REGIMES`: ``"paper"`` or ``"varied"`` (default).
    depths_mm : sequence of four float
        Depth offsets (mm) of the flames, farthest-left first; flame ``k`` keeps the
        height statistics of :data:`FLAME_HEIGHT_MEAN_MM` [k] whatever its depth. Default
        :data:`PAPER_DEPTHS_MM`; other depths test the diagnostics away from the paper's planes.

    Returns
    -------
    Scene
        Four layers ordered as ``depths_mm``; each object records its drawn
        parameters (template and object-space heights, centre and base in mm, radiance,
        sway, phase) and ``regime`` (``"nominal"`` when ``vary`` is False).

    Raises
    ------
    ValueError
        If ``regime`` is not in :data:`REGIMES` or ``depths_mm`` does not hold four depths.
    """
    _check_regime(regime)
    if len(depths_mm) != len(FLAME_HEIGHT_MEAN_MM):
        raise ValueError(f"depths_mm must hold {len(FLAME_HEIGHT_MEAN_MM)} depths. Received: {depths_mm}")
    h0, w0 = camera.field_of_view_mm(0.0)
    if template_scale is None:
        template_scale = camera_template_scale(camera)
    layers, objects = [], []
    for k, dz in enumerate(depths_mm):
        dz = float(dz)
        scale = camera.object_distance_mm(dz) / camera.focus_distance_mm
        height, jitter, level, sway, phase = _flame_params(k, w0, rng, vary, regime)
        cx = ((k + 0.5) / 4 - 0.5) * w0 * 0.9 * scale + jitter * scale
        layer, obj = _flame_layer(camera, dz, max(height, 1.0) * template_scale * scale, cx, -0.45 * h0 * scale,
                                  level, sway, phase, texels_per_lenslet)
        layers.append(layer)
        obj.update(height_template_mm=height, regime=regime if vary else "nominal")
        objects.append({k: obj[k] for k in _FLAME_KEYS})   # the datasets' order (their digest reads it)
    return Scene("flame", tuple(layers), FLAME_EFFECTS, tuple(objects))


_FLAME_KEYS = ("name", "depth_offset_mm", "height_template_mm", "height_mm", "centre_x_mm", "base_y_mm", "radiance",
               "sway", "phase", "regime", "roi")
#: Optically thin flames: they add their emission (no occlusion); aperture and cos⁴ of Eq. 1; noise-free.
FLAME_EFFECTS = Effects(aperture=True, cos4=True, occlusion=False)


def flame_centreline(cx, H, eta, sway, phase):
    """Lateral position (mm) of a flame's centreline at normalised heights ``eta``: ``cx`` swayed by
    ``sway H eta² sin(2 pi eta / 0.6 + phase)``, a wave travelling up the flame (``phase`` falls
    with time, :class:`lf_flame.simulate.scenes_time.FlameSequence`); ``cx`` itself where ``sway`` is 0."""
    return cx + sway * H * eta ** 2 * np.sin(2 * math.pi * eta / 0.6 + phase)


def _flame_layer(camera, dz, H, cx, base_y, level, sway, phase, texels_per_lenslet, half_width_mm=None):
    """One flame of height ``H`` (mm), centre ``cx`` and base ``base_y`` (mm) at depth ``dz``,
    its base's half-width ``half_width_mm`` (None: 0.07 H): its layer (the field x 1.2) and its
    object record (see :func:`flame_scene`)."""
    y, x, (h, w), texel = _layer_grid(camera, dz, texels_per_lenslet, 1.2)
    eta = (y - base_y) / H
    hw0 = 0.07 * H if half_width_mm is None else half_width_mm
    half_w = hw0 * np.sqrt(np.clip(1.0 - eta, 0.0, 1.0)) + 1e-9
    lum = (level * flame_luminosity(eta, (x - flame_centreline(cx, H, eta, sway, phase)) / half_w)).astype(np.float32)
    hw = hw0 + sway * H
    obj = dict(name=f"flame_{dz:+.0f}mm", depth_offset_mm=dz, height_mm=H, centre_x_mm=cx, base_y_mm=base_y,
               radiance=level, sway=sway, phase=phase, roi=_roi(camera, dz, base_y, base_y + H, cx - hw, cx + hw))
    return Layer(radiance=lum, alpha=None, depth_offset_mm=dz, centre_mm=(0.0, 0.0), size_mm=(h, w)), obj


def overlap_scene(camera: PlenopticCamera, rng: np.random.Generator, *, depths_mm=(20.0, 5.0, -10.0),
                  texels_per_lenslet: float = 3.0, vary: bool = True) -> Scene:
    """Flames standing one behind another in the same columns: the hard case of refocusing.

    The farthest flame is the tallest and brightest; each nearer one is shorter and
    dimmer, down to a short dim flame in front of a tall bright one (the case of
    ``docs/diagnostics.md``, where a refocused plane's dim flame merges with its bright
    neighbour's blur). Nominal (``vary`` False): heights 90 % of the field at the
    farthest depth falling linearly to 45 % of it at the nearest, radiance 1.0 falling to
    0.4, all centred on the optical axis. ``vary``: heights and radiance x U(0.9, 1.1),
    lateral offset U(−0.5, 0.5) mm per flame, sway up to 4 % of the height.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator
    depths_mm : sequence of 2 to 4 distinct float
        Depth offsets (mm from the focal plane), any order.
    texels_per_lenslet : float
    vary : bool

    Returns
    -------
    Scene
        One layer and one flame object per depth (keys as :func:`flame_scene`'s), farthest first.

    Raises
    ------
    ValueError
        Fewer than 2 or more than 4 depths, repeated or non-finite depths, a depth the
        camera cannot image.
    """
    d = sorted((float(v) for v in depths_mm), reverse=True)
    if not 2 <= len(d) <= 4 or len(set(d)) != len(d) or not all(math.isfinite(v) for v in d):
        raise ValueError(f"depths_mm must hold 2 to 4 distinct finite depths. Received: {depths_mm!r}")
    h0, _ = camera.field_of_view_mm(0.0)
    layers, objects = [], []
    for k, dz in enumerate(d):
        camera.image_distance_mm(camera.object_distance_mm(dz))   # raises for a depth it cannot image
        scale = camera.object_distance_mm(dz) / camera.focus_distance_mm
        f = k / (len(d) - 1)
        height, level = 0.9 - 0.45 * f, 1.0 - 0.6 * f
        cx, sway, phase = 0.0, 0.0, 0.0
        if vary:
            height, level = height * rng.uniform(0.9, 1.1), level * rng.uniform(0.9, 1.1)
            cx, sway, phase = rng.uniform(-0.5, 0.5), rng.uniform(0.0, 0.04), rng.uniform(0.0, 2 * math.pi)
        layer, obj = _flame_layer(camera, dz, height * h0 * scale, cx * scale, -0.45 * h0 * scale, min(level, 1.0),
                                  sway, phase, texels_per_lenslet)
        layers.append(layer)
        objects.append(obj)
    return Scene("overlap", tuple(layers), FLAME_EFFECTS, tuple(objects))


def point_scene(camera: PlenopticCamera, depth_offset_mm: float = 0.0, y_mm: float = 0.0, x_mm: float = 0.0,
                size_mm: float | None = None, radiance: float = 1.0) -> Scene:
    """A point source (the camera's PSF): one small square emitter at ``(y, x)`` mm, depth ``dz``.

    ``size_mm`` defaults to half a lenslet's footprint at that depth, so the in-focus
    point stays inside one lenslet. Backward tracing finds a small source only with
    enough rays per pixel (a pixel's ray bundle is ~0.4 mm wide at 20 mm defocus): use
    >= 64 for a defocused point. Effects: aperture only (a PSF of the optics).
    """
    if size_mm is None:
        size_mm = 0.5 * camera.mla_pitch_mm * camera.object_distance_mm(depth_offset_mm) / camera.mla_distance_mm
    tex = np.full((1, 1), radiance, dtype=np.float32)
    layer = Layer(radiance=tex, alpha=None, depth_offset_mm=float(depth_offset_mm), centre_mm=(y_mm, x_mm),
                  size_mm=(size_mm, size_mm))
    obj = dict(name="point", depth_offset_mm=float(depth_offset_mm), centre_y_mm=y_mm, centre_x_mm=x_mm,
               size_mm=size_mm, roi=_roi(camera, depth_offset_mm, y_mm, y_mm, x_mm, x_mm))
    return Scene("point", (layer,), Effects(aperture=True, cos4=False, occlusion=False), (obj,))


def white_scene(camera: PlenopticCamera, radiance: float = 1.0, cos4: bool = True) -> Scene:
    """A white (flat-field) target: one plane of constant ``radiance`` filling three times
    the field of view at the focal plane, as a diffuser in front of the lens gives.

    Its raw image is the grid of lenslet images of the main-lens aperture (discs, dimmed
    towards the corners by cos⁴ when ``cos4``), the input of
    :func:`lf_flame.real.calibration.calibrate`. Effects: aperture (and cos⁴), no occlusion.
    """
    h, w = camera.field_of_view_mm(0.0)
    layer = Layer(radiance=np.full((2, 2), radiance, np.float32), alpha=None, depth_offset_mm=0.0,
                  centre_mm=(0.0, 0.0), size_mm=(3 * h, 3 * w))
    return Scene("white", (layer,), Effects(aperture=True, cos4=bool(cos4), occlusion=False))


SCENES = {"shapes": shapes_scene, "flame": flame_scene}
