"""A colour (Bayer) light field's samples: each one's channel, and the channels as one monochrome light field.

A colour plenoptic camera records one channel per pixel (the colour filter array). Split
into sub-aperture views, each view sample keeps the channel of the pixel it came from
(:func:`channel_views`); :func:`channel_subviews` takes one channel's samples of each view
as a regular image and :func:`cfa_blind` names the planes a 2 x 2 CFA shows in one phase
only. For the routes that solve or refocus emission, :func:`levelled_views` and
:func:`monochrome_light_field` level the red and green samples into one light field (each over
its channel's mean), and :func:`channel_sum_views` interpolates the channels per view into one
without the CFA's checkerboard, for depth from focus. Each channel's emission on planes:
:mod:`lf_flame.temperature.channels`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..optics.colour import ColourSensor
from ..refocus.shift_and_sum import raw_to_views


#: Relative spread of a raw image's four 2 x 2 phase means (over its lit pixels) below which it holds no colour
#: filter mosaic: a monochrome sensor's phases differ by noise alone; a Bayer mosaic of flame light by tens of %.
MOSAIC_SPREAD = 0.01


def refuse_no_mosaic(raw, source: str, hint: str = "a monochrome light field has no two colour channels to take a "
                                                   "ratio of") -> None:
    """Refuse a raw image whose four 2 x 2 pixel phases have the same mean over its lit pixels (those above 0.1 of
    its maximum; within :data:`MOSAIC_SPREAD`): a monochrome sensor's, read as a colour one.

    Parameters
    ----------
    raw : ndarray of shape (rows, cols)
        Pixels, any units.
    source : str
        Its name in the message.
    hint : str
        What the refusal means for the command (the message's end).

    Raises
    ------
    ValueError
        No mosaic, naming ``source``.
    """
    raw = np.asarray(raw, np.float64)
    lit = raw > 0.1 * float(raw.max()) if raw.max() > 0 else np.zeros(raw.shape, bool)
    means = []
    for i in (0, 1):
        for j in (0, 1):
            m = lit[i::2, j::2]
            means.append(float(raw[i::2, j::2][m].mean()) if m.any() else np.nan)
    means = np.asarray(means)
    if np.all(np.isfinite(means)) and np.ptp(means) <= MOSAIC_SPREAD * means.mean():
        raise ValueError(f"{source} holds no colour filter mosaic (its four 2 x 2 pixel phases have the same mean, "
                         f"within {100 * MOSAIC_SPREAD:g} %): {hint}")


#: A colour channel's sites of the 2 x 2 filter tile (an RGGB sensor's two greens) whose means over the lit tiles
#: differ by more than this factor: one of them is dead, or the tile's phase is not the sensor's. A sensor's two
#: greens differ by a few per cent; a flame's red and blue pixels (a phase off by one) by several times.
SITE_RATIO = 2.0


def refuse_dead_site(raw, sensor: ColourSensor, source: str) -> None:
    """Refuse a raw colour mosaic whose sites of one colour disagree: a channel's pixels at one place of the 2 x 2
    tile dark (or far dimmer) where its pixels at the other read light. Its ratio would be read as a temperature
    (an RGGB capture whose greens at one site read nothing: about 1,080 K for flames at 1,800-2,050 K).

    Parameters
    ----------
    raw : ndarray of shape (rows, cols)
        Pixels, any units.
    sensor : ColourSensor
        Its CFA pattern and phase.
    source : str
        Its name in the message.

    Raises
    ------
    ValueError
        Two sites of one channel whose means over the lit tiles (those whose brightest pixel is above 0.1 of the
        image's maximum) differ by more than :data:`SITE_RATIO`, naming the channel, the sites and their means.
    """
    raw = np.asarray(raw, np.float64)
    r, c = (raw.shape[0] // 2) * 2, (raw.shape[1] // 2) * 2
    tiles = raw[:r, :c].reshape(r // 2, 2, c // 2, 2)
    top = float(raw.max())
    if not top > 0:
        return
    lit = tiles.max(axis=(1, 3)) > 0.1 * top
    chan = sensor.channel_map((2, 2))
    for ch in np.unique(chan):
        sites = [(int(i), int(j)) for i, j in zip(*np.nonzero(chan == ch))]
        if len(sites) < 2:
            continue
        means = [float(tiles[:, i, :, j][lit].mean()) for i, j in sites]
        if max(means) > SITE_RATIO * min(means):
            name = "RGB"[int(ch)]
            said = ", ".join(f"{m:.4g} at tile row {i}, column {j}" for (i, j), m in zip(sites, means))
            raise ValueError(f"{source}: its {name} pixels disagree ({said}, over the lit 2 x 2 tiles): one site of "
                             f"the {name} channel is dead or dimmed, or the CFA's phase {tuple(sensor.phase)} is not "
                             "the sensor's; two-colour pyrometry would read that as a temperature")


def channel_views(shape, sensor: ColourSensor, pixels_per_lenslet: int) -> np.ndarray:
    """Channel index (0 R, 1 G, 2 B) of each view sample of a raw image of ``shape``.

    Parameters
    ----------
    shape : (int, int)
        The raw image's rows and columns, ``(R * N, C * N)``.
    sensor : ColourSensor
        Its CFA pattern and phase.
    pixels_per_lenslet : int
        ``N``.

    Returns
    -------
    ndarray of shape (N, N, R, C), int8: views' axes as
    :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.

    Raises
    ------
    ValueError
        A shape that is not a grid of N x N lenslet images.
    """
    n = int(pixels_per_lenslet)
    if len(shape) != 2 or n < 1 or shape[0] % n or shape[1] % n:
        raise ValueError(f"a raw image of {n} x {n} lenslet images is needed. Received shape {tuple(shape)}")
    return raw_to_views(sensor.channel_map(shape).astype(np.float32), n).astype(np.int8)


def channel_subviews(views: np.ndarray, chan: np.ndarray, channel: int) -> np.ndarray:
    """One channel's samples of each view as a regular image: every other lenslet, at the phase holding it.

    With a 2 x 2 CFA a view's samples of one channel lie on every other lenslet row and
    column (odd pixels per lenslet) or on all of them (even): per view, the one of the four
    phases ``views[u, v, a::2, b::2]`` holding most of the channel's samples.

    Parameters
    ----------
    views, chan : ndarray of shape (N, N, R, C)
    channel : int

    Returns
    -------
    ndarray of shape (N, N, R // 2, C // 2), float64
    """
    N, _, R, C = views.shape
    out = np.zeros((N, N, R // 2, C // 2))
    phases = [(a, b) for a in (0, 1) for b in (0, 1)]
    for u in range(N):
        for v in range(N):
            a, b = max(phases, key=lambda ab: np.count_nonzero(chan[u, v, ab[0]::2, ab[1]::2] == channel))
            out[u, v] = views[u, v, a::2, b::2][:R // 2, :C // 2]
    return out


def cfa_blind(slopes, pixels_per_lenslet: int) -> np.ndarray:
    """Planes whose points a 2 x 2 CFA shows in one phase only: no ratio there for half the lenslets.

    With an odd number ``N`` of pixels per lenslet, the CFA's phase along an axis alternates
    from lenslet to lenslet, so view ``u`` of lenslet ``k`` holds phase ``(k + u) mod 2``. A
    point of a plane of slope ``s`` at lenslet ``y`` lies in lenslet ``y + s u`` of view ``u``,
    at phase ``(y + (s + 1) u) mod 2``: at an odd-integer slope that is ``y``'s alone, and
    the points on every other lenslet row (column) have no sample of that phase in any view
    (no red sample, in the RGGB pattern). Within ``2 / (N - 1)`` of an odd integer the views'
    spread of ``s u`` stays under two lenslets and most of them still see one phase only.
    With ``N`` even, each view holds one phase at every lenslet and no plane is blind.

    Parameters
    ----------
    slopes : sequence of float, lenslets per view
    pixels_per_lenslet : int

    Returns
    -------
    ndarray of bool, shape (len(slopes),)
    """
    s = np.asarray(slopes, float)
    n = int(pixels_per_lenslet)
    if n % 2 == 0 or n < 3:
        return np.zeros(s.shape, bool)
    odd = 2 * np.floor(s / 2) + 1                       # the nearest odd integer
    return np.abs(s - odd) < 2.0 / (n - 1)


def channel_sum_views(views: np.ndarray, chan: np.ndarray, channels=(0, 1), sigma: float = 0.7) -> np.ndarray:
    """One monochrome light field from a colour one, without the CFA's checkerboard: for depth from focus.

    Per channel of ``channels``, its samples are interpolated over each view's lenslets by
    normalised convolution (a Gaussian of ``sigma`` lenslets: ``G(v m) / G(m)``), scaled by
    the channel's mean sample, and the channels present at a sample averaged. With an odd
    number of pixels per lenslet every view holds every channel on alternate lenslets; with
    an even number a view holds one channel, which is then that view's value.

    Parameters
    ----------
    views, chan : ndarray of shape (N, N, R, C)
    channels : sequence of int
    sigma : float, lenslets

    Returns
    -------
    ndarray of shape (N, N, R, C), float32, about 1 where the channels are at their mean.

    Raises
    ------
    ValueError
        Shapes that differ, or a channel with no signal.
    """
    from scipy.ndimage import gaussian_filter
    v = np.asarray(views, np.float64)
    if np.shape(chan) != v.shape:
        raise ValueError(f"channel map of shape {np.shape(chan)} for views of shape {v.shape}")
    num = np.zeros_like(v)
    cnt = np.zeros_like(v)
    for c in channels:
        m = np.asarray(chan) == c
        mean = float(v[m].mean()) if m.any() else 0.0
        if not mean > 0:
            raise ValueError(f"channel {c} has no signal")
        a = gaussian_filter(v * m, (0, 0, sigma, sigma))
        b = gaussian_filter(m.astype(np.float64), (0, 0, sigma, sigma))
        has = b > 1e-3
        num += np.where(has, a / np.maximum(b, 1e-3), 0.0) / mean
        cnt += has
    return (num / np.maximum(cnt, 1)).astype(np.float32)


def levelled_views(views: np.ndarray, chan: np.ndarray, channels=(0, 1)):
    """A colour light field's samples as one monochrome light field (:func:`monochrome_light_field`).

    Parameters
    ----------
    views, chan : ndarray of shape (N, N, R, C)
        The samples and each one's channel (0 R, 1 G, 2 B; a hexagonal grid's on its lattice rows).
    channels : sequence of int
        The channels kept; the last one's mean sets the units.

    Returns
    -------
    levelled : ndarray of shape (N, N, R, C), float32
        Each kept channel's samples times (last channel's mean / its mean); the other samples
        :func:`channel_sum_views`' interpolation in the same units.
    other : ndarray of bool of shape (N, N, R, C)
        The samples of the channels not kept (to leave out of a fit).
    gains : list of float
        Each kept channel's factor; all 1 where a kept channel has no signal (its mean not above 0:
        a dark frame of a recording), whose samples are kept as they are and the others set to 0.
    """
    src = np.asarray(views, np.float64)
    chan = np.asarray(chan)
    other = ~np.isin(chan, channels)
    means = [float(src[chan == c].mean()) if np.any(chan == c) else 0.0 for c in channels]
    if not all(m > 0 for m in means):                       # a dark frame: nothing to level
        return np.where(other, 0.0, src).astype(np.float32), other, [1.0] * len(channels)
    fill = channel_sum_views(src, chan, channels)
    gains = [means[-1] / m for m in means]
    out = fill * means[-1]
    for c, g in zip(channels, gains):
        own = chan == c
        out[own] = src[own] * g
    return out.astype(np.float32), other, gains


def monochrome_light_field(lf, channels=(0, 1)):
    """A colour capture as one monochrome light field, for the routes that solve or refocus emission.

    A Bayer mosaic read as one light field is a checkerboard of the channels' levels: depth from
    focus takes it for texture and the exact operator cannot fit it (on the example camera's
    colour flames: 6 planes found for 2 flames, relative residual 0.41). Here each sample of
    ``channels`` is divided by its channel's mean over the light field and multiplied by the
    last channel's (green by default: the views are in its units), so that where the flame's
    colour is uniform the channels agree; the other channels' samples (blue: a flame's faintest)
    are left out of the fit and hold :func:`channel_sum_views`' interpolation (for refocusing
    and the depth search) (:func:`levelled_views`). Where the colour varies across the flame
    (temperature), the levelled channels differ by that variation.

    Parameters
    ----------
    lf : lf_flame.real.lightfield.LightField
        With :attr:`~lf_flame.real.lightfield.LightField.channels` (decoded with the channels apart,
        a hexagonal grid's on its lattice; or a perfect grid's raw mosaic, whose pixels at or above its
        clipping level join the samples left out). A light field without them is returned as it is.
    channels : sequence of int
        The channels kept (0 R, 1 G, 2 B).

    Returns
    -------
    LightField
        Without channels; ``leave_out`` (``lattice_leave_out``) holds the other channels' samples
        and those already left out; ``meta["monochrome"]`` says how it was made.
    """
    from ..real.view_grid import hex_to_square
    if lf.channels is None:
        return lf
    lattice = lf.lattice_views is not None
    out, other, gains = levelled_views(lf.lattice_views if lattice else lf.views, lf.channels, channels)
    note = (f"channels {list(channels)} levelled by their means (x {[round(g, 4) for g in gains]}), "
            "the others left out of the fit")
    meta = {**lf.meta, "monochrome": note}
    if not lattice:
        leave = other if lf.leave_out is None else other | lf.leave_out
        if not lf.white_normalised and lf.saturation is not None:   # a raw mosaic: its clipped pixels too
            leave = leave | (lf.views >= lf.saturation)
        return dataclasses.replace(lf, views=out, leave_out=leave, channels=None, meta=meta)
    lattice_leave = other if lf.lattice_leave_out is None else other | lf.lattice_leave_out
    square_leave = hex_to_square(lattice_leave.astype(np.float32)) > 1e-6       # any of its three samples
    if lf.leave_out is not None:
        square_leave |= lf.leave_out
    return dataclasses.replace(lf, views=np.ascontiguousarray(hex_to_square(out)), leave_out=square_leave,
                               channels=None, lattice_views=out, lattice_leave_out=lattice_leave, meta=meta)
