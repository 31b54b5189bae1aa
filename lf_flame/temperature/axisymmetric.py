"""Temperature per voxel of an axisymmetric flame from one colour (Bayer) light field.

An axisymmetric flame's emission ``e(r, y)`` has ``rows x n_r`` unknowns
(:class:`lf_flame.tomo.revolve.RevolveOperator`), far fewer than one colour channel's own
samples (a quarter of the views' samples for R, half for G under a Bayer CFA), so each
channel's ``e_c(r, y)`` is solved on its own samples alone
(:func:`lf_flame.tomo.axisymmetric.solve_axisymmetric` with ``fit`` = that channel's
unsaturated samples; the others are missing data): nothing is demosaiced. The two channels'
samples still differ, and so do their errors; the matched second pass (step 2) evens them out.
:func:`axisymmetric_temperature`:

1. the axis, once: :func:`~lf_flame.tomo.axisymmetric.solve_axisymmetric`'s search on the
   channels' sum (:func:`lf_flame.temperature.mosaic.channel_sum_views`, the CFA's checkerboard
   interpolated away), unless given; both channels' solves get the same axis, radius and
   radial nodes;
2. ``e_a(r, y)`` and ``e_b(r, y)`` of the calibration's two channels, each on its own samples,
   then (``matched``, the default) each imaged again and solved on the other channel's samples
   so that both carry both sampling patterns' errors (:func:`lf_flame.temperature.channels.matched_channels`);
3. the ratio ``e_a / e_b`` to temperature by the calibration's band-integrated lookup
   (:func:`lf_flame.temperature.pyrometry.ratio_to_temperature`) on the ``(r, y)`` nodes and on
   every voxel of the dense stack (the revolved emissions' ratio); nodes or voxels whose
   ``e_a + e_b`` is below :data:`~lf_flame.temperature.pyrometry.MIN_FRACTION` of its peak, or
   whose ratio has no temperature, are masked and counted (:func:`volume_temperature`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..optics.colour import ALPHA_SOOT, CHANNELS, ColourSensor
from ..tomo.axisymmetric import solve_axisymmetric
from .mosaic import channel_sum_views
from .pyrometry import MIN_FRACTION, TemperatureCalibration, temperature_planes

#: Fills of the missing data and FISTA steps per fill of each channel's solve. A channel's own samples
#: are a quarter (R) or half (G) of the views', the rest filled from the prediction: each fill shrinks the
#: fill's bias by about the missing share, so R needs many fills (small camera, noise-free, 16 rays:
#: solve_axisymmetric's 8 x 100 left the voxels' median temperature error at 149 K, 30 x 25 at 27 K,
#: 60 x 15 at 27 K; tests/test_temperature_volume.py's scene).
COLOUR_FILLS, COLOUR_INNER = 30, 25
#: ... and the smoothness weight of each channel's solve: ``solve_axisymmetric``'s weight when the results in
#: ``results/temperature_volume.md`` were measured (its noise-dependent ``AXI_LAM`` was chosen later, on
#: monochrome volumes, not on colour ones).
COLOUR_LAM = 1e-3


def volume_temperature(emission_a, emission_b, cal: TemperatureCalibration, sensor: ColourSensor,
                       alpha: float = ALPHA_SOOT, min_fraction: float = MIN_FRACTION):
    """Temperature of each sample of two channels' emission (any shape), masked against the whole array's peak.

    :func:`lf_flame.temperature.pyrometry.temperature_planes` with the whole array as one plane: a
    sample is bright when ``a + b`` is at least ``min_fraction`` of the largest ``a + b`` of the
    whole array (the volume or the ``(r, y)`` nodes), not of its own plane.

    Parameters
    ----------
    emission_a, emission_b : ndarray, same shape
        The calibration's numerator and denominator channels (recorded units, any scale common to both).
    cal : TemperatureCalibration
    sensor : ColourSensor
        The calibration's camera (sensitivities; no gains).
    alpha : float
        Emissivity exponent (soot: :data:`~lf_flame.optics.colour.ALPHA_SOOT`).
    min_fraction : float
        In [0, 1).

    Returns
    -------
    temperature : ndarray, K, NaN where masked
    valid : ndarray of bool
    n_masked : int
        Bright samples without a temperature (ratio not positive or out of the lookup's range).

    Raises
    ------
    ValueError
        Shapes that differ, no positive emission, and the errors of
        :func:`~lf_flame.temperature.pyrometry.temperature_planes` (``min_fraction`` outside [0, 1)).
    """
    a, b = np.asarray(emission_a, float), np.asarray(emission_b, float)
    if a.shape != b.shape:
        raise ValueError(f"the two channels' emission must have one shape. Received: {a.shape} and {b.shape}")
    if not (a.size and float(np.max(a + b)) > 0):
        raise ValueError("no positive emission: no temperature")
    # the whole array as one plane of temperature_planes: its peak is the array's
    temp, valid, n_masked = temperature_planes(a.reshape(1, 1, -1), b.reshape(1, 1, -1), cal, sensor, alpha,
                                               min_fraction)
    return temp.reshape(a.shape), valid.reshape(a.shape), int(n_masked[0])


@dataclass
class AxisymmetricTemperature:
    """What :func:`axisymmetric_temperature` returns.

    Attributes
    ----------
    temperature : ndarray of shape (rows, n_r), K
        On the nodes (``heights_mm`` x ``radii_mm``), NaN where masked.
    valid : ndarray of shape (rows, n_r), bool
    n_masked : int
        Nodes above the emission threshold left without a temperature.
    temperature_volume : ndarray of shape (P, rows, cols), K
        Per voxel of the operator's planes, NaN where masked.
    valid_volume : ndarray of shape (P, rows, cols), bool
    n_masked_volume : int
    emission : ndarray of shape (2, rows, n_r)
        ``e_a``, ``e_b`` on the nodes (the planes' units).
    volume : ndarray of shape (2, P, rows, cols)
        The two channels revolved onto the planes.
    radii_mm, heights_mm : ndarray
    axis_x_mm, axis_z_mm : float
    channels : (int, int)
        The channel indices (0 R, 1 G, 2 B) of ``a`` and ``b``.
    residuals : (float, float)
        Each channel's data residual of its last solve (on its own samples; matched: on the
        other channel's).
    time_s : float
        Wall time (axis, the solves, temperature).
    own_samples : AxisymmetricTemperature or None
        Matched: the same from each channel's own samples alone (the first pass, its
        ``time_s`` up to the end of it); None when not matched.
    """

    temperature: np.ndarray
    valid: np.ndarray
    n_masked: int
    temperature_volume: np.ndarray
    valid_volume: np.ndarray
    n_masked_volume: int
    emission: np.ndarray
    volume: np.ndarray
    radii_mm: np.ndarray
    heights_mm: np.ndarray
    axis_x_mm: float
    axis_z_mm: float
    channels: tuple
    residuals: tuple
    time_s: float
    own_samples: "AxisymmetricTemperature | None" = None


def axisymmetric_temperature(views, op, chan, cal: TemperatureCalibration, sensor: ColourSensor, *,
                             axis_x_mm: float | None = None, axis_z_mm: float | None = None,
                             r_max_mm: float | None = None, dr_mm: float | None = None,
                             saturation: float | None = 1.0, alpha: float = ALPHA_SOOT,
                             min_fraction: float = MIN_FRACTION, lam: float = COLOUR_LAM, fills: int = COLOUR_FILLS,
                             inner: int = COLOUR_INNER, matched: bool = True, camera=None,
                             **search) -> AxisymmetricTemperature:
    """Two-colour temperature ``T(r, y)`` and per voxel of an axisymmetric flame from one colour light field.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The colour light field (:func:`lf_flame.refocus.shift_and_sum.raw_to_views` of the raw mosaic).
    op : ExactOperator
        The dense stack (``subsamples=1``) the volume is returned on.
    chan : ndarray of shape (N, N, R, C), int
        Each sample's channel (:func:`lf_flame.temperature.mosaic.channel_views`).
    cal : TemperatureCalibration
        Its ``channels`` (e.g. ``("R", "G")``) are the ratio's numerator and denominator.
    sensor : ColourSensor
        The calibration's camera (checked against ``cal``).
    axis_x_mm, axis_z_mm : float or None
        The axis (mm); None: found on the channels' sum (both must be given to skip the search).
    r_max_mm, dr_mm : float or None
        Radial extent and node spacing (:class:`~lf_flame.tomo.revolve.RevolveOperator`);
        None: ``r_max_mm`` as the axis search sets it on the channels' sum, ``dr_mm`` one lateral sample.
    saturation : float or None
        Samples at or above it are left out of the fits (None: none).
    alpha, min_fraction
        As :func:`volume_temperature`.
    lam, fills, inner
        Each channel's solve (:func:`~lf_flame.tomo.axisymmetric.solve_axisymmetric`;
        defaults :data:`COLOUR_LAM`, :data:`COLOUR_FILLS`, :data:`COLOUR_INNER`).
    matched : bool
        Match the channels' resolution as :func:`lf_flame.temperature.channels.matched_channels`:
        each channel's volume imaged again by ``op`` and solved on the other channel's
        samples (twice the solves). False: each channel from its own samples alone. On the
        small camera of ``tests/test_temperature_volume.py`` (noise-free, 32 rays) matching
        took the voxels' p90 from 106 to 62 K (sheath and core) and from 61 to 51 K (sheath);
        ``results/temperature_volume.md`` scores both routes.
    camera : PlenopticCamera or None
        For the axis search's start (:func:`~lf_flame.tomo.depth.find_depths`).
    **search
        Further keywords of the axis search (``search_half_width_mm``, ``start_z_mm``, ...).

    Returns
    -------
    AxisymmetricTemperature

    Raises
    ------
    ValueError
        A channel map not of the views' shape, a calibration of another camera, a channel
        with no unsaturated sample, only one of ``axis_x_mm``/``axis_z_mm`` given, and the
        errors of :func:`~lf_flame.tomo.axisymmetric.solve_axisymmetric` and
        :func:`volume_temperature`.
    """
    t0 = time.perf_counter()
    v = np.asarray(views, np.float64)
    chan = np.asarray(chan)
    if chan.shape != v.shape:
        raise ValueError(f"channel map of shape {chan.shape} for views of shape {v.shape}")
    cal.check_sensor(sensor)
    ia, ib = (CHANNELS.index(c) for c in cal.channels)
    if (axis_x_mm is None) != (axis_z_mm is None):
        raise ValueError("give both axis_x_mm and axis_z_mm, or neither (the axis is then found)")
    ok = np.ones(v.shape, bool) if saturation is None else v < saturation
    fits = [(chan == c) & ok for c in (ia, ib)]
    for c, f in zip((ia, ib), fits):
        if not f.any():
            raise ValueError(f"channel {CHANNELS[c]} has no unsaturated sample to fit")
    if axis_x_mm is None or r_max_mm is None:
        summed = channel_sum_views(v, chan, (ia, ib)).astype(np.float64)
        top = float(summed[ok].max()) if ok.any() else 1.0
        found = solve_axisymmetric(summed / top, op, ok, axis_x_mm=axis_x_mm, axis_z_mm=axis_z_mm, r_max_mm=r_max_mm,
                                   dr_mm=dr_mm, lam=lam, fills=1, inner=1, camera=camera, **search)
        axis_x_mm, axis_z_mm = found.axis_x_mm, found.axis_z_mm
        r_max_mm = float(found.radii_mm[-1])
        dr_mm = float(found.radii_mm[1] - found.radii_mm[0])
    def result(sols, own_samples=None):
        em = np.stack([s.emission for s in sols])
        vol = np.stack([s.volume for s in sols])
        T, valid, n_masked = volume_temperature(em[0], em[1], cal, sensor, alpha, min_fraction)
        Tv, valid_v, n_masked_v = volume_temperature(vol[0], vol[1], cal, sensor, alpha, min_fraction)
        return AxisymmetricTemperature(temperature=T, valid=valid, n_masked=n_masked, temperature_volume=Tv,
                                       valid_volume=valid_v, n_masked_volume=n_masked_v, emission=em, volume=vol,
                                       radii_mm=sols[0].radii_mm, heights_mm=sols[0].heights_mm,
                                       axis_x_mm=float(axis_x_mm), axis_z_mm=float(axis_z_mm), channels=(ia, ib),
                                       residuals=(sols[0].residual, sols[1].residual),
                                       time_s=time.perf_counter() - t0, own_samples=own_samples)

    sols = [solve_axisymmetric(v, op, f, axis_x_mm=axis_x_mm, axis_z_mm=axis_z_mm, r_max_mm=r_max_mm, dr_mm=dr_mm,
                               lam=lam, fills=fills, inner=inner, camera=camera) for f in fits]
    if not matched:
        return result(sols)
    own = result(sols)
    return result([solve_axisymmetric(op.matvec(s.volume.ravel()).reshape(v.shape), op, fits[1 - i],
                                      axis_x_mm=axis_x_mm, axis_z_mm=axis_z_mm, r_max_mm=r_max_mm, dr_mm=dr_mm,
                                      lam=lam, fills=fills, inner=inner, camera=camera) for i, s in enumerate(sols)],
                  own_samples=own)
