"""Two-colour pyrometry: a blackbody calibration and the ratio of two channels to temperature.

A channel's recorded signal is ``g_c ∫ S_c(λ) ε(λ) B(λ, T) dλ``
(:func:`lf_flame.optics.colour.band_integrals`). The ratio of two channels,
``R = (g_a / g_b) · I_a(T) / I_b(T)``, depends on temperature alone once the gain ratio
``g_a / g_b`` is known; images of a blackbody furnace at known temperatures give it
(:func:`fit_calibration`), and a lookup of the band-integrated ratio over T inverts it
(:func:`ratio_to_temperature`) — not the monochromatic Wien formula
(:func:`wien_temperature`), whose difference is reported by ``make temperature``.

A calibration is bound to the camera it was made with (sensitivities' name, CFA pattern
and phase, channels): :func:`load_calibration` refuses one from another camera or CFA, or
one whose ratio is not strictly monotonic in T (no unique temperature).
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..optics.colour import ALPHA_SOOT, CHANNELS, ColourSensor, band_integrals

#: temperatures (K) the lookup covers, and its step
T_RANGE_K = (1000.0, 3200.0)
T_STEP_K = 1.0
#: Blackbodies at two or more temperatures whose measured log ratio changes by less than this share of the model's
#: change are refused (:func:`fit_calibration`): one image given for two temperatures.
FLAT_RATIO = 0.1
#: pixels below this fraction of their plane's peak emission get no temperature
MIN_FRACTION = 0.1
C2_M_K = 1.438777e-2   # second radiation constant, m K (CODATA 2018)


@dataclass(frozen=True)
class TemperatureCalibration:
    """A two-colour calibration.

    Attributes
    ----------
    sensor_name, pattern : str
    phase : (int, int)
        The camera it was made with (:class:`~lf_flame.optics.colour.ColourSensor`).
    channels : (str, str)
        Numerator and denominator channels of the ratio, e.g. ``("R", "G")``.
    gain_ratio : float
        Recorded ratio over the model's band-integrated ratio (``g_a / g_b``).
    fit_temperatures_k : tuple of float
        The blackbody temperatures fitted (K).
    fit_residuals_k : tuple of float
        Each fitted image's temperature error after the fit (K).
    """

    sensor_name: str
    pattern: str
    phase: tuple
    channels: tuple
    gain_ratio: float
    fit_temperatures_k: tuple
    fit_residuals_k: tuple

    def check_sensor(self, sensor: ColourSensor) -> None:
        """Raise ValueError unless ``sensor`` is the camera (sensitivities, CFA, phase) of this calibration: its
        sensitivities and the channels its CFA puts on the sensor's first 2 x 2 pixels (a pattern and a phase that lay
        them out alike, RGGB at phase (0, 1) and GRBG at (0, 0), are the same sensor)."""
        from ..optics.colour import same_cfa_layout
        mine = (self.sensor_name, self.pattern, tuple(self.phase))
        theirs = (sensor.name, sensor.pattern, tuple(sensor.phase))
        if mine[0] != theirs[0] or not same_cfa_layout(*mine[1:], *theirs[1:]):
            raise ValueError(f"this temperature calibration was made for sensor {mine[0]!r}, CFA {mine[1]} phase "
                             f"{mine[2]}; the images are from sensor {theirs[0]!r}, CFA {theirs[1]} phase {theirs[2]}: "
                             "calibrate this camera with its own blackbody images")


def _channel_index(channels) -> tuple[int, int]:
    if len(channels) != 2 or any(c not in CHANNELS for c in channels) or channels[0] == channels[1]:
        raise ValueError(f"channels must be two different of {CHANNELS}. Received: {channels!r}")
    return CHANNELS.index(channels[0]), CHANNELS.index(channels[1])


def model_ratio(sensor: ColourSensor, temperature_k, channels=("R", "G"), alpha: float = ALPHA_SOOT) -> np.ndarray:
    """Band-integrated ratio ``I_a(T) / I_b(T)`` of the sensor's sensitivities, no gains
    (shape of ``temperature_k``)."""
    a, b = _channel_index(channels)
    s = band_integrals(sensor, temperature_k, alpha)
    return s[..., a] / s[..., b]


def blackbody_ratio(raw: np.ndarray, sensor: ColourSensor, pixels_per_lenslet: int, channels=("R", "G"),
                    radius: float = 0.4, centre_fraction: float = 0.5) -> float:
    """Ratio of two channels' mean signal in a raw image of a uniform (blackbody) target.

    The mean of each channel's pixels over the central ``centre_fraction`` of the sensor
    (each axis) among the pixels within ``radius`` x N of their lenslet image's centre
    (inside the aperture disc; chosen by position, not by value, so noise does not bias the
    choice). With an odd number N of pixels per lenslet the CFA's phase alternates from
    lenslet to lenslet, so both channels sample every position under the lenslets alike and
    the vignetting cancels in the ratio.

    Parameters
    ----------
    raw : ndarray of shape (R * N, C * N)
    sensor : ColourSensor
    pixels_per_lenslet : int
        ``N`` (a perfect lenslet grid).
    channels : (str, str)
    radius, centre_fraction : float

    Returns
    -------
    float: mean of channel a over mean of channel b.

    Raises
    ------
    ValueError
        A raw image that is not 2-D, finite and a grid of N x N lenslet images, or a
        channel with no pixel or no signal.
    """
    raw = np.asarray(raw, float)
    n = int(pixels_per_lenslet)
    if raw.ndim != 2 or not np.all(np.isfinite(raw)) or n < 1 or raw.shape[0] % n or raw.shape[1] % n:
        raise ValueError(f"raw must be a finite 2-D grid of {n} x {n} lenslet images. Received shape {raw.shape}")
    a, b = _channel_index(channels)
    chan = sensor.channel_map(raw.shape)
    H, W = raw.shape
    i, j = np.mgrid[0:H, 0:W]
    c0 = (n - 1) / 2
    disc = (i % n - c0) ** 2 + (j % n - c0) ** 2 <= (radius * n) ** 2
    mh, mw = int(H * (1 - centre_fraction) / 2), int(W * (1 - centre_fraction) / 2)
    box = (i >= mh) & (i < H - mh) & (j >= mw) & (j < W - mw)
    return _channel_means_ratio(raw, box & disc, chan, (a, b), "pixel", "image")


def _channel_means_ratio(values, where, chan, pair, what: str, of: str) -> float:
    """Mean of ``values`` over ``where`` and channel ``pair[0]`` over the same for ``pair[1]``; ValueError where a
    channel has no lit ``what`` (a pixel, a sample) in the blackbody's ``of``."""
    means = []
    for c in pair:
        v = values[where & (chan == c)]
        if v.size == 0 or not v.mean() > 0:
            raise ValueError(f"no lit {what} of channel {CHANNELS[c]} in the blackbody {of}")
        means.append(float(v.mean()))
    return means[0] / means[1]


def views_blackbody_ratio(views: np.ndarray, chan: np.ndarray, channels=("R", "G"), radius: float = 0.4,
                          centre_fraction: float = 0.5) -> float:
    """:func:`blackbody_ratio` of a blackbody's decoded views (a colour capture decoded with its channels
    apart, :func:`lf_flame.real.decoding.decode_colour`).

    The mean of each channel's samples over the central ``centre_fraction`` of the lenslets (each
    axis) and the views within ``radius`` x N of the central view, where they hold light.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    chan : ndarray of int of the views' shape
        Each sample's channel (0 R, 1 G, 2 B).
    channels : (str, str)
    radius, centre_fraction : float

    Returns
    -------
    float: mean of channel a over mean of channel b.

    Raises
    ------
    ValueError
        Views not (N, N, R, C), a channel map of another shape, or a channel with no lit sample.
    """
    v = np.asarray(views, float)
    if v.ndim != 4 or v.shape[0] != v.shape[1] or np.shape(chan) != v.shape:
        raise ValueError(f"views (N, N, R, C) and a channel map of their shape are needed. Received {v.shape} and "
                         f"{np.shape(chan)}")
    a, b = _channel_index(channels)
    N, _, R, C = v.shape
    u = np.arange(N) - (N - 1) / 2
    disc = (u[:, None] ** 2 + u[None, :] ** 2 <= (radius * N) ** 2)[:, :, None, None]
    mr, mc = int(R * (1 - centre_fraction) / 2), int(C * (1 - centre_fraction) / 2)
    box = np.zeros((R, C), bool)
    box[mr:R - mr, mc:C - mc] = True
    return _channel_means_ratio(v, disc & box & (v > 0), np.asarray(chan), (a, b), "sample", "views")


def fit_calibration(sensor: ColourSensor, temperatures_k, ratios, channels=("R", "G")) -> TemperatureCalibration:
    """The gain ratio from blackbody images at known temperatures.

    ``log(gain_ratio)`` is the mean of ``log(ratio / model_ratio(T, alpha=0))`` over the
    images (least squares in log), the model being the sensor's band-integrated
    blackbody ratio (:func:`model_ratio`; unit emissivity).

    Parameters
    ----------
    sensor : ColourSensor
        The camera's model: sensitivities, CFA, phase (its gains are not used: unknown).
    temperatures_k : sequence of float, K
    ratios : sequence of float
        Measured channel ratios (:func:`blackbody_ratio`), one per temperature.
    channels : (str, str)

    Returns
    -------
    TemperatureCalibration, with each fitted image's temperature residual (K).

    Raises
    ------
    ValueError
        Fewer than one image, lengths that differ, non-positive ratios or temperatures, temperatures outside
        :data:`T_RANGE_K`; images at two or more temperatures whose ratio barely moves (under :data:`FLAT_RATIO` of
        the model's change: one image given twice); images at
        two or more temperatures whose ratio moves with temperature against the model's (whatever
        the channels' gains, a blackbody's ratio of a longer- over a shorter-wavelength band falls
        as it heats): the temperatures given in another order than the images, or the samples of those
        channels not the sensor's (a colour filter array read at the wrong phase, red and blue swapped, or
        the wrong pattern); a fitted image whose ratio then reads outside :data:`T_RANGE_K` (the images do not follow
        the sensor's model).
    """
    t = np.asarray(temperatures_k, float)
    r = np.asarray(ratios, float)
    if t.ndim != 1 or t.shape != r.shape or t.size < 1:
        raise ValueError(f"one ratio per temperature is needed. Received: {t.shape} and {r.shape}")
    if np.any(~np.isfinite(r)) or np.any(r <= 0) or np.any(t <= 0):
        raise ValueError("ratios and temperatures must be finite and > 0")
    out = [v for v in t if not T_RANGE_K[0] <= v <= T_RANGE_K[1]]
    if out:
        raise ValueError(f"blackbodies at {', '.join(f'{v:g} K' for v in out)} lie outside the {T_RANGE_K[0]:g}-"
                         f"{T_RANGE_K[1]:g} K this pyrometer reads (T_RANGE_K): their fit could not be checked against "
                         "the temperatures given; calibrate with blackbodies inside it")
    model = model_ratio(sensor, t, channels, alpha=0.0)
    if np.ptp(t) > 0:                   # the log ratio's slope in T, measured against the model's: the same sign
        slope, want = (np.polyfit(t, np.log(v), 1)[0] for v in (r, model))
        if abs(slope) < FLAT_RATIO * abs(want):
            raise ValueError(f"the measured {channels[0]}/{channels[1]} ratio barely moves across the blackbodies' "
                             f"temperatures ({', '.join(f'{v:g} K' for v in t)}: {100 * abs(slope / want):.2g} % of "
                             f"the change sensor {sensor.name!r} gives): the same image given for two temperatures?")
        if slope * want < 0:
            raise ValueError(f"the measured {channels[0]}/{channels[1]} ratio {'rises' if slope > 0 else 'falls'} with "
                             f"the blackbody's temperature where sensor {sensor.name!r}'s "
                             f"{'falls' if want < 0 else 'rises'}: either the temperatures given are not the images' "
                             f"(each image takes the temperature in the same place: here {', '.join(f'{v:g} K' for v in t)})"
                             f", or these images' {channels[0]} and {channels[1]} "
                             f"samples are not those channels' pixels. Check the colour filter array: pattern "
                             f"{sensor.pattern}, phase {tuple(int(p) for p in sensor.phase)} (the camera file's cfa "
                             "and cfa_phase, or --cfa and --cfa-phase)")
    g = float(np.exp(np.mean(np.log(r / model))))
    cal = TemperatureCalibration(sensor.name, sensor.pattern, tuple(int(p) for p in sensor.phase), tuple(channels),
                                 g, tuple(float(x) for x in t), ())
    res = ratio_to_temperature(r, cal, sensor, alpha=0.0) - t
    if not np.all(np.isfinite(res)):      # a fitted image's ratio outside the table: no temperature reads it back
        raise ValueError(f"after the fit the blackbodies at {', '.join(f'{v:g} K' for v in t[~np.isfinite(res)])} read "
                         f"outside the {T_RANGE_K[0]:g}-{T_RANGE_K[1]:g} K the pyrometer reads: these images do not "
                         f"follow sensor {sensor.name!r}'s model (its sensitivities, the channels' pixels) with the "
                         f"temperatures given ({', '.join(f'{v:g} K' for v in t)})")
    return TemperatureCalibration(**{**asdict(cal), "fit_residuals_k": tuple(float(x) for x in res)})


def lookup_table(cal: TemperatureCalibration, sensor: ColourSensor, alpha: float = ALPHA_SOOT):
    """``(T, recorded ratio)`` over :data:`T_RANGE_K` every :data:`T_STEP_K`: the inverse's table.

    Raises
    ------
    ValueError
        A sensor that is not the calibration's, a gain ratio that is not positive and
        finite, or a ratio that is not strictly monotonic over the range (no unique
        temperature for a ratio).
    """
    cal.check_sensor(sensor)
    if not (math.isfinite(cal.gain_ratio) and cal.gain_ratio > 0):
        raise ValueError(f"the calibration's gain ratio must be positive and finite. Received: {cal.gain_ratio!r}")
    t = np.arange(T_RANGE_K[0], T_RANGE_K[1] + T_STEP_K / 2, T_STEP_K)
    r = cal.gain_ratio * model_ratio(sensor, t, cal.channels, alpha)
    d = np.diff(r)
    if not (np.all(d > 0) or np.all(d < 0)):
        raise ValueError(f"the ratio {cal.channels[0]}/{cal.channels[1]} of sensor {sensor.name!r} is not strictly "
                         f"monotonic over {T_RANGE_K} K: it cannot be inverted to a temperature")
    return t, r


def ratio_to_temperature(ratio, cal: TemperatureCalibration, sensor: ColourSensor,
                         alpha: float = ALPHA_SOOT) -> np.ndarray:
    """Temperature (K) of each recorded channel ratio, by the band-integrated lookup.

    Linear interpolation in the table of :func:`lookup_table` (1 K steps); a ratio outside
    the table's range, or not finite and positive, gives NaN.

    Parameters
    ----------
    ratio : ndarray of any shape
        Recorded ratio of the calibration's channels (gains included).
    cal : TemperatureCalibration
    sensor : ColourSensor
    alpha : float
        Emissivity exponent of the source: 0 for a blackbody, :data:`ALPHA_SOOT` for soot.

    Returns
    -------
    ndarray of the shape of ``ratio``, K (NaN where no temperature).

    Raises
    ------
    ValueError
        The errors of :func:`lookup_table`.
    """
    t, r = lookup_table(cal, sensor, alpha)
    if r[-1] < r[0]:
        t, r = t[::-1], r[::-1]
    x = np.asarray(ratio, float)
    ok = np.isfinite(x) & (x >= r[0]) & (x <= r[-1])
    out = np.full(x.shape, np.nan)
    out[ok] = np.interp(x[ok], r, t)
    return out


def bright_pixels(emission, min_fraction: float = MIN_FRACTION) -> np.ndarray:
    """Pixels of each plane at or above ``min_fraction`` of that plane's peak, and with light (above 0): those
    :func:`temperature_planes` gives a temperature when their ratio has one. A plane with no light has none (an
    all-zero plane's pixels had all been bright, each reported as a bright pixel masked).

    Parameters
    ----------
    emission : ndarray of shape (P, rows, cols)
        Summed emission of the two channels.
    min_fraction : float

    Returns
    -------
    ndarray of bool of shape (P, rows, cols)
    """
    tot = np.asarray(emission, float)
    return (tot >= min_fraction * tot.reshape(len(tot), -1).max(axis=1)[:, None, None]) & (tot > 0)


def temperature_planes(emission_a, emission_b, cal: TemperatureCalibration, sensor: ColourSensor,
                       alpha: float = ALPHA_SOOT, min_fraction: float = MIN_FRACTION):
    """Each plane's temperature map from two channels' emission, with the pixels masked.

    Parameters
    ----------
    emission_a, emission_b : ndarray of shape (P, rows, cols)
        Emission of the calibration's numerator and denominator channels per plane
        (reconstructed or refocused; recorded units).
    cal, sensor, alpha
        As :func:`ratio_to_temperature`.
    min_fraction : float
        A pixel whose summed emission ``a + b`` is below this fraction of its plane's peak
        gets no temperature (masked), nor does one whose ratio has no temperature.

    Returns
    -------
    temperature : ndarray (P, rows, cols), K, NaN where masked
    valid : ndarray (P, rows, cols), bool
    n_masked : ndarray (P,), int: pixels above the emission threshold left without a
        temperature (ratio out of the table), per plane.

    Raises
    ------
    ValueError
        Shapes that differ or are not 3-D, NaN or inf in either stack (named with its planes: one such pixel had
        left its whole plane without a temperature, unreported), ``min_fraction`` outside [0, 1), and the errors
        of :func:`lookup_table`.
    """
    a, b = np.asarray(emission_a, float), np.asarray(emission_b, float)
    if a.shape != b.shape or a.ndim != 3:
        raise ValueError(f"two (P, rows, cols) emission stacks are needed. Received: {a.shape} and {b.shape}")
    for name, e in (("emission_a", a), ("emission_b", b)):
        bad = (~np.isfinite(e)).reshape(len(e), -1).sum(axis=1)
        if bad.any():
            where = ", ".join(f"plane {k} ({n} px)" for k, n in enumerate(bad) if n)
            raise ValueError(f"{name} holds NaN or inf in {where}: a temperature needs both channels' emission "
                             "finite (a solve that diverged, or views holding NaN: repair them and solve again)")
    if not (0 <= min_fraction < 1):
        raise ValueError(f"min_fraction must be in [0, 1). Received: {min_fraction}")
    bright = bright_pixels(a + b, min_fraction)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bright & (b > 0) & (a > 0), a / b, np.nan)
    temp = ratio_to_temperature(ratio, cal, sensor, alpha)
    valid = bright & np.isfinite(temp)
    return np.where(valid, temp, np.nan), valid, (bright & ~valid).reshape(len(a), -1).sum(axis=1)


def wien_temperature(ratio, cal: TemperatureCalibration, sensor: ColourSensor, alpha: float = ALPHA_SOOT):
    """The monochromatic (Wien) two-colour temperature of a recorded ratio, K.

    Each channel as one wavelength, its sensitivity's centroid ``λ_c = ∫ λ S_c / ∫ S_c``:
    ``1/T = ((5 + alpha) ln(λ_b/λ_a) - ln(R / g) + ln(s_a / s_b)) / (c2 (1/λ_a - 1/λ_b))``
    with ``s_c = ∫ S_c dλ`` the band's width (so a band integral is ``s_c`` times the
    spectrum at ``λ_c``). For comparison with :func:`ratio_to_temperature` only.
    """
    a, b = _channel_index(cal.channels)
    wl, s = sensor.wavelengths_nm * 1e-9, sensor.sensitivities
    lam = [np.trapezoid(wl * s[:, c], wl) / np.trapezoid(s[:, c], wl) for c in (a, b)]
    width = [np.trapezoid(s[:, c], wl) for c in (a, b)]
    la, lb = lam
    g = np.log(np.asarray(ratio, float) / cal.gain_ratio) - math.log(width[0] / width[1])
    # R/g = (lb/la)^(5+alpha) exp(-c2/T (1/la - 1/lb)) · width ratio
    inv_t = ((5 + alpha) * math.log(lb / la) - g) / (C2_M_K * (1 / la - 1 / lb))
    return 1.0 / inv_t


def write_calibration(path, cal: TemperatureCalibration) -> Path:
    """Write ``cal`` as JSON atomically (``PATH.partial`` beside it, then renamed; removed if the
    write fails), with the permissions of any file this process creates (its umask), as
    :func:`lf_flame.config.atomic_write_text` writes (``temperature`` does not import ``config``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".partial")
    try:
        with open(tmp, "w") as f:
            json.dump(dict(asdict(cal), kind="lf_flame two-colour temperature calibration"), f, indent=2)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def load_calibration(path, sensor: ColourSensor | None = None) -> TemperatureCalibration:
    """Read a calibration written by :func:`write_calibration`.

    With ``sensor``, refuse (ValueError) a calibration made with another camera or CFA
    (:meth:`TemperatureCalibration.check_sensor`) or whose ratio is not strictly monotonic
    (:func:`lookup_table`). Raises ValueError for a file that is not such a calibration.
    """
    try:
        d = json.loads(Path(path).read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path} is not an lf_flame temperature calibration (not JSON: {e})") from None
    if not isinstance(d, dict) or d.pop("kind", None) != "lf_flame two-colour temperature calibration":
        raise ValueError(f"{path} is not an lf_flame temperature calibration")
    try:
        cal = TemperatureCalibration(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})
    except TypeError as e:
        raise ValueError(f"{path}: malformed temperature calibration ({e})") from None
    try:
        numbers = [float(cal.gain_ratio), *map(float, cal.fit_temperatures_k), *map(float, cal.fit_residuals_k)]
        ok = all(isinstance(v, (int, float)) and not isinstance(v, bool)
                 for v in (cal.gain_ratio, *cal.fit_temperatures_k, *cal.fit_residuals_k))
    except (TypeError, ValueError):
        ok = False
    if not (ok and all(math.isfinite(v) for v in numbers) and cal.gain_ratio > 0):
        raise ValueError(f"{path}: malformed temperature calibration (gain_ratio must be a positive number, the fit's "
                         f"temperatures and residuals numbers; edited since?). Received: gain_ratio={cal.gain_ratio!r}")
    _channel_index(cal.channels)
    if sensor is not None:
        lookup_table(cal, sensor)
    return cal
