"""The paper's four flames with a temperature field and soot: colour scenes for pyrometry.

Each flame of :func:`lf_flame.simulate.scenes.flame_scene` (same heights, positions and
luminous profile) gets a temperature per texel and a soot column, and its emission in each
colour channel is ``exposure · g_c · soot · ∫ S_c(λ) (λ/λ0)^-1.39 B(λ, T) dλ``
(:func:`lf_flame.optics.colour.band_integrals`). Layers stay planar (a flame is a sheet of
projected emission at its depth, as in the monochrome scenes), so the truth of a plane is its
temperature map and its emission per channel.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..optics.camera import PlenopticCamera
from ..optics.colour import ALPHA_SOOT, ColourSensor, band_integrals
from .scenes import PAPER_DEPTHS_MM, _layer_grid, flame_centreline, flame_luminosity, flame_scene
from .layers import Scene
from .scenes_time import FlameSequence

#: Sheath (hottest) temperature of each of the paper's four flames, K, in the order of
#: :data:`~lf_flame.simulate.scenes.PAPER_DEPTHS_MM`: each flame its own field, within the
#: 1,500-2,100 K of laminar hydrocarbon diffusion flames' soot.
FLAME_PEAK_K = (2100.0, 1950.0, 2050.0, 1850.0)
#: The temperature the field falls towards in the cool core and the tip, K.
FLAME_BASE_K = 1500.0
#: Relative position (of the local half-width) and width of the hot sheath.
SHEATH_XI, SHEATH_WIDTH = 0.82, 0.25
#: Fraction of the sheath's excess temperature lost from base to tip (radiative cooling).
TIP_COOLING = 0.4


def flame_temperature(eta, xi, peak_k: float, base_k: float = FLAME_BASE_K):
    """Temperature (K) of a laminar diffusion flame in normalised coordinates.

    ``eta`` = height / flame height, ``xi`` = lateral offset / local half-width (as
    :func:`lf_flame.simulate.scenes.flame_luminosity`). Hottest on the luminous sheath
    (``|xi|`` = :data:`SHEATH_XI`, the middle of the luminous annulus 0.65-1), cooler in the
    fuel-rich core and towards the tip:

        T = base + (peak - base) · (0.5 + 0.5 exp(-((|xi| - 0.82) / 0.25)²)) · (1 - 0.4 eta)

    A model of the shape that measurements of laminar ethylene diffusion flames report (soot
    hottest in the annular reaction zone low in the flame, cooling along the height as soot
    radiates: Santoro, Semerjian & Dobbins, Combust. Flame 51 (1983) 203-218), with the
    1,500-2,100 K of laminar hydrocarbon diffusion flames' soot; it is not a fit to data. At ``peak`` 2,100 K it spans
    about 1,680-2,100 K over the flame.

    Returns
    -------
    ndarray broadcast from ``eta`` and ``xi``, K.

    Raises
    ------
    ValueError
        ``peak_k`` not above ``base_k`` or either not positive.
    """
    if not (0 < base_k < peak_k):
        raise ValueError(f"need 0 < base_k < peak_k. Received: base_k={base_k}, peak_k={peak_k}")
    eta = np.clip(np.asarray(eta, float), 0.0, 1.0)
    xi = np.abs(np.asarray(xi, float))
    radial = 0.5 + 0.5 * np.exp(-((xi - SHEATH_XI) / SHEATH_WIDTH) ** 2)
    return base_k + (peak_k - base_k) * radial * (1.0 - TIP_COOLING * eta)


@dataclass(frozen=True)
class ColourFlameScene:
    """Flames with temperature: the geometry, and per layer the truth.

    Attributes
    ----------
    scene : Scene
        Layers (geometry; their radiance is the green channel's) and effects.
    channel_radiance : tuple of ndarray of shape (3, rows, cols), float32
        Per layer, the recorded emission of channels R, G, B (gains and exposure included;
        1 saturates the sensor).
    temperature_k : tuple of ndarray of shape (rows, cols), float64
        Per layer, the temperature of each texel (K; meaningful where soot > 0).
    soot : tuple of ndarray of shape (rows, cols), float64
        Per layer, the soot column (relative, peak 1).
    exposure : float
        The scale that brings the brightest texel of any channel to ``peak``.
    """

    scene: Scene
    channel_radiance: tuple
    temperature_k: tuple
    soot: tuple
    exposure: float


def colour_flame_scene(camera: PlenopticCamera, sensor: ColourSensor, rng: np.random.Generator | None = None, *,
                       peaks_k=FLAME_PEAK_K, base_k: float = FLAME_BASE_K, alpha: float = ALPHA_SOOT,
                       peak: float = 0.8, depths_mm=PAPER_DEPTHS_MM, texels_per_lenslet: float = 3.0,
                       regime: str = "paper", template_scale: float | None = None) -> ColourFlameScene:
    """The paper's four flames, each with its own temperature field, seen by a colour sensor.

    Geometry and soot are those of :func:`lf_flame.simulate.scenes.flame_scene` (``rng``
    None: the nominal flames; else drawn in ``regime``, which must have no sway); flame
    ``k`` has temperature :func:`flame_temperature` with sheath ``peaks_k[k]``.

    Parameters
    ----------
    camera : PlenopticCamera
    sensor : ColourSensor
        Its sensitivities and gains make the channels' emission.
    rng : numpy.random.Generator or None
    peaks_k : sequence of four float, K
    base_k : float, K
    alpha : float
        Soot emissivity exponent (:data:`~lf_flame.optics.colour.ALPHA_SOOT`).
    peak : float
        Emission of the brightest texel of any channel (exposure; 1 saturates).
    depths_mm : sequence of four float
    texels_per_lenslet : float
    regime : str
        ``"paper"`` (heights only vary) is the one supported with ``rng``.
    template_scale : float or None
        The flames' heights' scale (:func:`~lf_flame.simulate.scenes.flame_scene`; None: the camera's field's).

    Returns
    -------
    ColourFlameScene

    Raises
    ------
    ValueError
        Not four peak temperatures, a peak below ``base_k``, ``peak`` not in (0, 1], or a
        regime with sway.
    """
    if len(peaks_k) != len(depths_mm):
        raise ValueError(f"one peak temperature per flame is needed: {len(depths_mm)} flames, {len(peaks_k)} given")
    if not (0 < peak <= 1):
        raise ValueError(f"peak must be in (0, 1]. Received: {peak}")
    if rng is not None and regime != "paper":
        raise ValueError(f"colour flames support regime 'paper' (no sway). Received: {regime!r}")
    mono = flame_scene(camera, rng if rng is not None else np.random.default_rng(0), vary=rng is not None,
                       regime=regime, depths_mm=depths_mm, texels_per_lenslet=texels_per_lenslet,
                       template_scale=template_scale)
    temps, soots = [], []
    for L, obj, pk in zip(mono.layers, mono.objects, peaks_k):
        eta, xi = _flame_coordinates(camera, L, obj, texels_per_lenslet)
        soot = obj["radiance"] * flame_luminosity(eta, xi)
        temps.append(np.broadcast_to(flame_temperature(eta, xi, float(pk), base_k), soot.shape).copy())
        soots.append(soot)
    return _in_colour(mono, "colour_flame", temps, soots, sensor, alpha, peak, peaks_k, base_k)


#: Sheath temperatures (K) drawn for :func:`colour_depth_scene`'s flames: the span of :data:`FLAME_PEAK_K`, widened.
DEPTH_PEAK_RANGE_K = (1800.0, 2200.0)


def colour_depth_scene(camera: PlenopticCamera, sensor: ColourSensor, rng: np.random.Generator, *,
                       base_k: float = FLAME_BASE_K, alpha: float = ALPHA_SOOT, peak: float = 0.8,
                       texels_per_lenslet: float = 3.0) -> ColourFlameScene:
    """Flames at random depths of any camera, each with its own temperature field, seen by a colour sensor.

    The geometry and soot of :func:`lf_flame.simulate.scenes_depth.camera_depth_scene` (2-4
    flames scaled to the camera's depth of field and lenslet footprint); flame ``k`` has
    :func:`flame_temperature` with a sheath temperature drawn uniformly from
    :data:`DEPTH_PEAK_RANGE_K` (after the geometry, from the same ``rng``).

    Parameters
    ----------
    camera : PlenopticCamera
    sensor : ColourSensor
    rng : numpy.random.Generator
    base_k, alpha, peak, texels_per_lenslet : as :func:`colour_flame_scene`

    Returns
    -------
    ColourFlameScene
        Its objects carry ``peak_k`` and ``base_k``.

    Raises
    ------
    ValueError
        ``peak`` not in (0, 1], or the errors of :func:`~lf_flame.simulate.scenes_depth.camera_depth_scene`.
    """
    from .scenes_depth import camera_depth_scene
    if not (0 < peak <= 1):
        raise ValueError(f"peak must be in (0, 1]. Received: {peak}")
    mono = camera_depth_scene(camera, rng, texels_per_lenslet=texels_per_lenslet)
    peaks_k = rng.uniform(*DEPTH_PEAK_RANGE_K, size=len(mono.layers))
    temps, soots = _layer_temperatures(camera, mono, peaks_k, base_k, texels_per_lenslet)
    return _in_colour(mono, "colour_depth", temps, soots, sensor, alpha, peak, peaks_k, base_k)


def _flame_coordinates(camera: PlenopticCamera, layer, obj: dict, texels_per_lenslet: float):
    """A flame layer's normalised coordinates (eta, xi) per texel, as its luminosity was drawn
    (:func:`lf_flame.simulate.scenes._flame_layer`): height over the flame's height, and lateral offset
    from the (swayed) centreline over the local half-width (``half_width_mm`` at the base, 0.07 H
    where the object does not record it)."""
    y, x, _, _ = _layer_grid(camera, layer.depth_offset_mm, texels_per_lenslet, 1.2)
    H = obj["height_mm"]
    eta = (y - obj["base_y_mm"]) / H
    half_w = obj.get("half_width_mm", 0.07 * H) * np.sqrt(np.clip(1.0 - eta, 0.0, 1.0)) + 1e-9
    centre = flame_centreline(obj["centre_x_mm"], H, eta, obj.get("sway", 0.0), obj.get("phase", 0.0))
    return eta, (x - centre) / half_w


def _layer_temperatures(camera: PlenopticCamera, mono: Scene, peaks_k, base_k: float, texels_per_lenslet: float):
    """Each flame layer of ``mono`` as soot (its luminosity) with :func:`flame_temperature` of sheath
    ``peaks_k[k]`` in its own coordinates (:func:`_flame_coordinates`): (temps, soots), float64 per layer."""
    temps, soots = [], []
    for L, obj, pk in zip(mono.layers, mono.objects, peaks_k):
        eta, xi = _flame_coordinates(camera, L, obj, texels_per_lenslet)
        soot = np.asarray(L.radiance, float)
        temps.append(np.broadcast_to(flame_temperature(eta, xi, float(pk), base_k), soot.shape).copy())
        soots.append(soot)
    return temps, soots


def _in_colour(mono: Scene, name, temps, soots, sensor, alpha, peak, peaks_k, base_k,
               exposure: float | None = None) -> ColourFlameScene:
    """A monochrome scene's layers as soot with temperature: each channel's emission, one exposure
    (None: the one that brings the brightest texel of any channel to ``peak``)."""
    rad = [s[None] * np.moveaxis(band_integrals(sensor, t, alpha, gains=True), -1, 0) for s, t in zip(soots, temps)]
    if exposure is None:
        exposure = peak / max(float(r.max()) for r in rad)
    chans = tuple((r * exposure).astype(np.float32) for r in rad)
    layers = tuple(dataclasses.replace(L, radiance=c[1]) for L, c in zip(mono.layers, chans))
    objects = tuple(dict(o, peak_k=float(pk), base_k=float(base_k)) for o, pk in zip(mono.objects, peaks_k))
    return ColourFlameScene(Scene(name, layers, mono.effects, objects), chans, tuple(temps), tuple(soots), exposure)


#: Amplitude (K) of each flame's sheath temperature oscillation in a recording
#: (:func:`colour_flicker_frame`): at the flame's flicker frequency, in antiphase with its height. A
#: model for colour recordings (a stretched flame loses more heat), not a fit to data.
FLICKER_K = 40.0


def colour_flicker_frame(seq: FlameSequence, camera: PlenopticCamera, sensor: ColourSensor, frame: int, *,
                         peaks_k=FLAME_PEAK_K, flicker_k: float = FLICKER_K, base_k: float = FLAME_BASE_K,
                         alpha: float = ALPHA_SOOT, exposure: float | None = None,
                         peak: float = 0.8) -> ColourFlameScene:
    """One frame of a recording of flickering flames with temperature, seen by a colour sensor.

    The geometry and soot of ``seq.scene(camera, frame)`` (:class:`~lf_flame.simulate.scenes_time.FlameSequence`:
    heights that flicker, centrelines that sway); flame ``k``'s temperature is :func:`flame_temperature`
    in its coordinates of that frame, with the sheath at

        T_sheath(t) = peaks_k[k] - flicker_k sin(2 pi f_k t + phase_k)

    (``f_k`` and ``phase_k`` the flame's flicker frequency and phase: hottest when the flame is
    shortest). Each object records its sheath temperature of the frame as ``peak_k``: the truth of
    the recording's temperature over time.

    Parameters
    ----------
    seq : FlameSequence
    camera : PlenopticCamera
    sensor : ColourSensor
    frame : int
        In ``[0, seq.n_frames)``.
    peaks_k : sequence of float, K
        Each flame's mean sheath temperature, in ``seq.flames``' order.
    flicker_k : float, K
        Amplitude of the sheath temperature's oscillation (>= 0).
    base_k, alpha
        As :func:`colour_flame_scene`.
    exposure : float or None
        The recording's exposure (a camera's is fixed over a recording: give frame 0's
        ``exposure`` to the others); None: this frame's, bringing its brightest texel of any channel
        to ``peak``.
    peak : float
        In (0, 1]; used where ``exposure`` is None.

    Returns
    -------
    ColourFlameScene
        ``scene.name == "colour_flicker"``, one layer per flame.

    Raises
    ------
    ValueError
        Not one peak temperature per flame, ``flicker_k`` negative or not finite, a sheath
        temperature that falls to ``base_k``, ``peak`` outside (0, 1] or an exposure not
        positive, and the errors of :meth:`FlameSequence.scene` (a frame outside the recording).
    """
    if len(peaks_k) != len(seq.flames):
        raise ValueError(f"one peak temperature per flame is needed: {len(seq.flames)} flames, {len(peaks_k)} given")
    if not (np.isfinite(flicker_k) and flicker_k >= 0):
        raise ValueError(f"flicker_k must be finite and >= 0 (K). Received: {flicker_k!r}")
    if not (0 < peak <= 1) or not (exposure is None or (np.isfinite(exposure) and exposure > 0)):
        raise ValueError(f"peak must be in (0, 1] and the exposure positive. Received: peak={peak}, "
                         f"exposure={exposure!r}")
    mono = seq.scene(camera, frame)
    sheath = sheath_temperatures(seq, frame, peaks_k, flicker_k)
    if min(sheath) <= base_k:
        raise ValueError(f"the sheath temperatures {sheath} K must stay above base_k {base_k} K: lower flicker_k")
    temps, soots = _layer_temperatures(camera, mono, sheath, base_k, seq.texels_per_lenslet)
    return _in_colour(mono, "colour_flicker", temps, soots, sensor, alpha, peak, sheath, base_k, exposure)


def flicker_peaks(n_flames: int) -> tuple:
    """Each flame's mean sheath temperature (K) of a recording of ``n_flames`` flickering in colour: the paper's
    flames' (:data:`FLAME_PEAK_K`, farthest first), taken again from the first for a fifth flame and on."""
    return tuple(FLAME_PEAK_K[k % len(FLAME_PEAK_K)] for k in range(int(n_flames)))


def sheath_temperatures(seq: FlameSequence, frame: int, peaks_k=FLAME_PEAK_K, flicker_k: float = FLICKER_K) -> list:
    """Each flame's sheath temperature (K) in frame ``frame`` of ``seq``, as :func:`colour_flicker_frame` draws it:
    ``peaks_k[k] - flicker_k sin(2 pi f_k t + phase_k)`` at ``t = frame / seq.fps`` s (``seq.flames``' order)."""
    t = int(frame) / float(seq.fps)
    return [float(pk) - flicker_k * np.sin(2 * np.pi * f.freq_hz * t + f.phase) for pk, f in zip(peaks_k, seq.flames)]


#: Sheath temperatures (K) of the far and the near flame of :func:`colour_behind_scene`.
BEHIND_PEAK_K = (2050.0, 1800.0)


def colour_behind_scene(camera: PlenopticCamera, sensor: ColourSensor, rng: np.random.Generator,
                        separation_mm: float, *, peaks_k=BEHIND_PEAK_K, base_k: float = FLAME_BASE_K,
                        alpha: float = ALPHA_SOOT, peak: float = 0.8, texels_per_lenslet: float = 3.0,
                        depth_range=None) -> ColourFlameScene:
    """Two flames in the same columns, one behind the other, each with its own temperature field.

    The geometry and soot of :func:`lf_flame.simulate.scenes_depth.behind_scene` (far flame
    first; ``rng`` draws depths, heights, radiance and lateral offsets), each flame's
    temperature :func:`flame_temperature` with sheath ``peaks_k`` (far, near) in its own
    normalised coordinates (base half-width as drawn there), emission per channel as
    :func:`colour_flame_scene`'s.

    Parameters
    ----------
    camera : PlenopticCamera
    sensor : ColourSensor
    rng : numpy.random.Generator
    separation_mm : float
        Depth between the flames, mm (as :func:`~lf_flame.simulate.scenes_depth.behind_scene`).
    peaks_k : (float, float), K
        Sheath temperature of the far and the near flame.
    base_k, alpha, peak, texels_per_lenslet
        As :func:`colour_flame_scene`.
    depth_range : (float, float) or None
        Depths the pair is drawn in (None: behind_scene's default).

    Returns
    -------
    ColourFlameScene
        ``scene.name == "colour_behind"``, two layers, far first.

    Raises
    ------
    ValueError
        Not two peak temperatures, a peak not above ``base_k``, ``peak`` outside (0, 1], and
        the errors of ``behind_scene``.
    """
    from .scenes_depth import DEPTH_RANGE_MM, behind_scene
    if len(peaks_k) != 2:
        raise ValueError(f"two peak temperatures (far, near) are needed. Received: {peaks_k!r}")
    if not (0 < peak <= 1):
        raise ValueError(f"peak must be in (0, 1]. Received: {peak}")
    mono = behind_scene(camera, rng, separation_mm, depth_range=depth_range or DEPTH_RANGE_MM,
                        texels_per_lenslet=texels_per_lenslet)
    temps, soots = _layer_temperatures(camera, mono, peaks_k, base_k, texels_per_lenslet)
    return _in_colour(mono, "colour_behind", temps, soots, sensor, alpha, peak, peaks_k, base_k)


def blackbody_channels(sensor: ColourSensor, temperature_k: float, peak: float = 0.8) -> np.ndarray:
    """Recorded emission (3,) of channels R, G, B of a blackbody (unit emissivity) at
    ``temperature_k`` K, gains included, scaled so the brightest channel is ``peak`` (an
    exposure set for the furnace, the same for all channels)."""
    s = band_integrals(sensor, float(temperature_k), alpha=0.0, gains=True)
    return s * (peak / s.max())


def white_target_scene(camera: PlenopticCamera, sensor: ColourSensor, peak: float = 1.0):
    """The white (flat-field) target of :func:`lf_flame.simulate.scenes.white_scene` seen by a colour sensor:
    ``(scene, channel_radiance)`` for :func:`lf_flame.simulate.colour.render_colour`, each channel's signal
    the integral of its sensitivity (an equal-energy spectrum), gains included, the brightest at ``peak``:
    the white image of a Bayer camera is a mosaic too."""
    from .scenes import white_scene
    s = np.trapezoid(np.asarray(sensor.sensitivities, float), np.asarray(sensor.wavelengths_nm, float), axis=0)
    s = s * np.asarray(sensor.gains, float)
    scene = white_scene(camera, 1.0)
    ch = (s * (peak / s.max())).astype(np.float32)
    return scene, [np.broadcast_to(ch[:, None, None], (3,) + scene.layers[0].radiance.shape).astype(np.float32)]


def furnace_scene(camera: PlenopticCamera, sensor: ColourSensor, temperature_k: float, peak: float = 0.8,
                  effects=None):
    """A blackbody furnace's opening filling the field at the focal plane (a flat-field target).

    Returns ``(scene, channel_radiance)`` for :func:`lf_flame.simulate.colour.render_colour`:
    one uniform layer three times the field at depth 0 (as
    :func:`lf_flame.simulate.scenes.white_scene`) and its (3, 2, 2) channel emission
    (:func:`blackbody_channels`). ``effects`` (default: aperture and cos⁴, noise-free)
    replaces the scene's effects.
    """
    from .scenes import white_scene

    ch = blackbody_channels(sensor, temperature_k, peak)
    scene = white_scene(camera, 1.0)
    if effects is not None:
        scene = dataclasses.replace(scene, effects=effects)
    return scene, [np.broadcast_to(ch[:, None, None], (3,) + scene.layers[0].radiance.shape).astype(np.float32)]
