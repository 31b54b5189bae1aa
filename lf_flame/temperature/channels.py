"""Each colour channel's emission on planes from one colour (Bayer) light field.

A colour plenoptic camera records one channel per pixel (the colour filter array). Split
into sub-aperture views, each view sample keeps the channel of the pixel it came from
(:func:`lf_flame.temperature.mosaic.channel_views`), so each channel's data are its own samples and the others are
missing. Routes from those samples to each plane's emission in two channels, whose ratio
:func:`lf_flame.temperature.pyrometry.temperature_planes` turns into temperature:

- ``admm-cfa-matched`` (the default): the two channels' resolution matched. Each channel's
  reconstruction from its own samples (``admm-cfa``, on the 2 x 2 grid per lenslet of
  :data:`MATCHED_SUBSAMPLES`) is imaged again by the operator and reconstructed from the
  *other* channel's samples (:func:`matched_channels`), so that both channels pass through
  both sampling patterns and their errors largely cancel in the ratio: the colour
  counterpart of matching two images' point-spread functions before a colour ratio in
  multi-band photometry. Binned to the lenslets; the admm knobs of :data:`MATCHED_KNOBS` by
  the light field's noise (:func:`cfa_noise`), the ratio filtered by
  :data:`MATCHED_RATIO_FILTER` for that noise (:func:`lf_flame.temperature.ratio.filter_ratio`);
- ``admm-cfa``: the exact operator's admm (:func:`lf_flame.tomo.solvers.reconstruct`) on
  each channel's own samples, the other channels' samples left out of the fit as missing
  data (the ``saturation`` mask), as are clipped samples (:func:`admm_channel`);
- ``admm-cfa-smooth``: the same, both channels smoothed by a Gaussian of
  :data:`SMOOTH_SIGMA` lenslets before the ratio;
- ``refocus-cfa``: each channel's samples refocused by shift-and-sum at the planes' slopes,
  the mean over the views that hold that channel (:func:`refocus_channel`): the focal-stack
  ratio baseline.

Each sample's channel and the channels as one monochrome light field (for reconstruct and the
depth search): :mod:`lf_flame.temperature.mosaic`. :func:`colour_truth` puts a colour scene's
per-channel truth on the planes' grids.
``experiments/temperature.py`` measures the routes; ``lf-flame temperature`` runs them.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..optics.colour import CHANNELS
from ..refocus.shift_and_sum import aperture_mask, focal_stack
from ..tomo.noise_knobs import relative_noise
from ..tomo.solvers import reconstruct
from ..tomo.truth import bin_planes, resample_layer
from .mosaic import channel_subviews
from .ratio import SMOOTH_SIGMA, filter_ratio, smooth_planes

#: The routes from a colour light field to two channels' emission per plane (the first: the default).
CFA_ROUTES = ("admm-cfa-matched", "admm-cfa", "admm-cfa-smooth", "refocus-cfa")
#: Each route's worst plane's p90 temperature error (K) on the paper camera's colour flames, noise-free and at 14 dB
#: (``results/temperature.md``, ``make temperature``): what ``lf-flame temperature`` quotes when another route than
#: the default is asked for.
ROUTE_P90_K = {"admm-cfa-matched": (26, 76), "admm-cfa": (283, 454), "admm-cfa-smooth": (84, 146),
               "refocus-cfa": (191, 199)}
#: admm on each channel's samples: converged by 25 fills on the nominal scene (12-300 tried,
#: ``experiments/temperature.py``); lam and tv as measured there, no sparsity weight.
CFA_FILLS, CFA_LAM, CFA_TV, CFA_L1 = 25, 0.01, 0.0, 0.0
#: ``admm-cfa-matched``: its planes' grid (samples per lenslet and axis) and the Gaussian
#: (lenslets) both channels were smoothed by when the light field is noisy, before the guided
#: ratio filter (:data:`MATCHED_RATIO_FILTER`) replaced it; the experiments compare the two.
#: Chosen on validation scenes (seeds 937500-1, 400 rays, ``results/temperature_grid.md``):
#: worst-plane p90 38 K noise-free unsmoothed (67 K smoothed by 0.7), 98 K at 14 dB smoothed by
#: 0.7 (253 K unsmoothed); on the lenslet grid 56 K noise-free (89 K at 14 dB: the one setting
#: where the lenslet grid is better).
MATCHED_SUBSAMPLES, MATCHED_SIGMA_NOISY = 2, 0.7
#: ``admm-cfa-matched``'s admm knobs (all four solves) by the light field's noise regime
#: (:func:`cfa_noise` against :data:`MATCHED_QUIET_NOISE`). Quiet: the missing data's fills converge
#: slowly (three quarters of the red samples are missing), and the lenslet-scale aliasing of
#: the ratio fades only after some hundreds of fills: chosen on validation scenes (seeds
#: 937500-1, ``results/temperature_fills.md``) for the smallest worst-plane p90, about 90 s a
#: scene on 2 cores against 8 s for 25 fills. Noisy: 25 fills (stopping early regularises the
#: noise) and the ``admm-cfa`` weights, the ratio filtered by :data:`MATCHED_RATIO_FILTER`. Very
#: noisy (from :data:`MATCHED_WIDE_NOISE`): a three times larger gradient weight, chosen with the
#: ratio filter on four validation scenes at 14 dB (seeds 937500-3, ``results/temperature_noisy.md``:
#: worst-plane p90 62 K against 64 K for lam 0.01 and 67 K for lam 0.1, each with its best filter); at
#: 17-26 dB lam 0.01 stays best (TV 0.03 was no level's best in a first run, commit 0be9b8c).
MATCHED_KNOBS = {"quiet": dict(fills=300, lam=0.003, tv=0.0, l1=0.0),
                 "noisy": dict(fills=CFA_FILLS, lam=CFA_LAM, tv=CFA_TV, l1=CFA_L1),
                 "very noisy": dict(fills=CFA_FILLS, lam=0.03, tv=CFA_TV, l1=CFA_L1)}
#: The relative noise (:func:`cfa_noise`) below which ``admm-cfa-matched`` takes the quiet knobs: lower
#: than the monochrome ``ADMM_QUIET_NOISE`` (0.005), as the quiet knobs' many fills fit the noise. Chosen on
#: the validation scenes (``experiments/studies/temperature_snr.py --validation``, each knob set with its
#: :data:`MATCHED_RATIO_FILTER`): the quiet knobs' worst-plane p90 beat the noisy knobs' from 30 dB
#: (noise up to 0.0033; 32.6 against 39.3 K with the contour filter) and lost at 26 dB (noise from 0.0047;
#: 38.8 against 38.0 K) and below; 0.004 splits them (their geometric mean 0.0039). (With the guided filter
#: alone: 32.6 against 34.6 K, 38.8 against 37.6 K; with the Gaussian: 65 against 68 K at 30 dB, 98 against
#: 67 K at 26 dB.)
MATCHED_QUIET_NOISE = 0.004
#: ``admm-cfa-matched``'s filter of the two channels' ratio by the light field's noise regime (in
#: place of a Gaussian on both channels, which blurs the temperature across the luminous sheath),
#: :func:`lf_flame.temperature.ratio.filter_ratio`: when noisy, the channels averaged along the brightness contours over
#: ``contour`` lenslets (``contour_ratio``), then a guided filter (``guided_ratio``) of the log
#: ratio, the log of the summed emission as its guide, of ``radius`` lenslets and regularisation
#: ``eps``. Noise-free: chosen on validation scenes (``experiments/studies/temperature_ratio_filter.py``) as the
#: smaller of the flames' p90 over 30 K and the two-flames-behind p90 over 50 K (their bars), as the
#: filter trades the in-focus plane's detail for the CFA's aliasing on the planes out of focus.
#: Noisy: chosen with the admm knobs on four validation scenes (``experiments/studies/temperature_noisy.py``,
#: seeds 937500-3): the smallest mean over the regime's levels (17, 20, 26 dB) of the worst-plane p90,
#: 44 K against 57 K with the guided filter alone (17 dB: 52 against 75 K; 26 dB: 38 against 38 K);
#: very noisy (14 dB): the smallest worst-plane p90, 62 K against 77 K with the guided filter of
#: radius 2 alone. The guided filter alone lowers the hot sheath where it is wide enough for the
#: noise; the contours' average does not.
MATCHED_RATIO_FILTER = {"quiet": dict(radius=1, eps=0.001), "noisy": dict(radius=1, eps=0.1, contour=5.0),
                        "very noisy": dict(radius=1, eps=0.1, contour=8.0)}
#: ``admm-cfa-matched``'s knobs and ratio filter for decoded colour captures (``lf-flame temperature`` of
#: views decoded with their channels apart, :func:`lf_flame.real.decoding.decode_colour`), in place of the
#: noise regimes: the views differ from the operator's prediction by more than their noise (each sample the
#: nearest pixel of a lenslet image's mosaic), and :func:`cfa_noise` misreads a non-integer pitch's mosaic as
#: noise. Chosen on the example camera's validation scenes (``experiments/cameras_colour.py --seed0 58100
#: --scenes 6``, 11 planes; a ``/tmp`` probe of lam 0.003-1 and the filter's radius 1-2, eps 0.01-0.1, contour
#: 0-12): worst-plane p90 median / worst 108.7 / 150 K noise-free and 108.8 / 175 K at 14 dB, against
#: 126 / 298 K and 125 / 343 K with the very noisy regime's (which every decoded capture read), better on 9
#: of 11 planes at each noise level.
DECODED_KNOBS = dict(fills=CFA_FILLS, lam=0.1, tv=CFA_TV, l1=CFA_L1)
DECODED_RATIO_FILTER = dict(radius=1, eps=0.1)
#: The same for a square grid's captures with each sample modelled at its own pixel (``sample_offsets``, on
#: :data:`DECODED_OFFSET_BINS` sub-views per view and axis), whose fills have most of each sub-view to fill. Chosen
#: on the same validation scenes (``/tmp`` probes of ``experiments/cameras_colour.py --seed0 58100``; worst-plane
#: p90 median / worst, noise-free then 14 dB): 2 sub-views, lam 0.01 and 60 fills 89 / 116 and 110 / 173 K in
#: 2.9 s a capture, against 109 / 150 and 109 / 175 K in 0.7 s for the whole views with :data:`DECODED_KNOBS`;
#: 3 sub-views at lam 0.01: 90 / 154 and 113 / 150 K (60 fills), 91 / 124 and 114 / 146 K (100 fills, 9.2 s);
#: lam 0.003 at 100-200 fills 82-83 / 117-126 K noise-free but 116 / 220 K at 14 dB; lam 0.03 or 0.1 at 25-100
#: fills 112-143 K medians. A hexagonal grid's lattice keeps its whole views here: with these knobs and its
#: samples' offsets its validation worst planes rose (268 -> 415 K noise-free, 325 -> 356 K at 14 dB).
DECODED_OFFSET_KNOBS = dict(fills=60, lam=0.01, tv=CFA_TV, l1=CFA_L1)
DECODED_OFFSET_BINS = 2
#: The relative noise (:func:`cfa_noise`) from which the very noisy knobs and ratio filter are taken:
#: the geometric mean of the validation scenes' noise at 17 dB (up to 0.0150, the noisy ones best)
#: and at 14 dB (from 0.0194, the very noisy ones best).
MATCHED_WIDE_NOISE = 0.017


def admm_channel(views: np.ndarray, op, fit: np.ndarray, *, fills: int = CFA_FILLS, lam: float = CFA_LAM,
                 tv: float = CFA_TV, l1: float = CFA_L1, support=None) -> np.ndarray:
    """One channel's emission per plane by admm on its own samples.

    The views are scaled by the largest fitted sample (so admm's ``lam`` does not depend on
    exposure), solved with the samples outside ``fit`` left out, and scaled back.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The colour light field (every channel's samples).
    op : lf_flame.tomo.exact.ExactOperator
        The planes' operator (``op.dims`` = (P, rows, cols)).
    fit : ndarray of shape (N, N, R, C), bool
        The samples of this channel that are fitted (its own, not clipped).
    fills, lam, tv, l1
        admm's iterations and weights (:func:`lf_flame.tomo.solvers.reconstruct`).
    support : ndarray of bool of shape ``op.dims`` (P, rows, cols), or None
        Where each plane may hold emission (found planes near each other held to their own regions:
        :func:`lf_flame.tomo.found_planes.found_support`); None: everywhere.

    Returns
    -------
    ndarray of shape (P, rows, cols): the channel's emission, the views' units.

    Raises
    ------
    ValueError
        ``fit`` not of the views' shape, or no fitted sample with signal.
    """
    fit = np.asarray(fit, bool)
    if fit.shape != views.shape:
        raise ValueError(f"fit mask of shape {fit.shape} for views of shape {views.shape}")
    s = float(views[fit].max()) if fit.any() else 0.0
    if not s > 0:
        raise ValueError("this channel has no sample with signal to fit")
    rec = reconstruct(views / s, op, "admm", fills, lam=lam, tv=tv, l1=l1, saturation=~fit, support=support)
    return rec.planes.reshape(op.dims) * s


def matched_channels(views: np.ndarray, op, fits, support=None, **knobs):
    """Two channels' emission per plane with their resolution matched: each through both sampling patterns.

    Channel ``i`` is reconstructed from its own samples (:func:`admm_channel` with
    ``fits[i]``), imaged again by ``op`` onto every pixel, and reconstructed from the
    other channel's samples (``fits[1 - i]``). Both results have been through both
    channels' sampling and the same solver, so where the two channels share their
    geometry (one flame, a smooth colour ratio) their errors are alike and cancel in the
    ratio. Four admm solves.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The colour light field.
    op : lf_flame.tomo.exact.ExactOperator
        The planes' operator.
    fits : (ndarray, ndarray) of shape (N, N, R, C), bool
        Each channel's fitted samples (its own, not clipped).
    support : ndarray of bool of shape ``op.dims``, or None
        Where each plane may hold emission, in all four solves (:func:`admm_channel`).
    **knobs
        admm's ``fills``, ``lam``, ``tv``, ``l1`` (:func:`admm_channel`), the same in all four solves.

    Returns
    -------
    (a, b) : two ndarrays of shape ``op.dims``, the views' units.

    Raises
    ------
    ValueError
        Not two fit masks, or the errors of :func:`admm_channel`.
    """
    if len(fits) != 2:
        raise ValueError(f"two channels' fit masks are needed. Received {len(fits)}")
    own = [admm_channel(views, op, f, support=support, **knobs) for f in fits]
    return tuple(admm_channel(op.matvec(x.ravel()).reshape(views.shape), op, fits[1 - i], support=support, **knobs)
                 for i, x in enumerate(own))


def matched_regime(noise: float) -> str:
    """``admm-cfa-matched``'s noise regime for a relative noise (:func:`cfa_noise`): ``"quiet"``
    below :data:`MATCHED_QUIET_NOISE`, ``"noisy"`` below :data:`MATCHED_WIDE_NOISE`, else
    ``"very noisy"``; it picks :data:`MATCHED_KNOBS` and :data:`MATCHED_RATIO_FILTER`."""
    return "quiet" if noise < MATCHED_QUIET_NOISE else "noisy" if noise < MATCHED_WIDE_NOISE else "very noisy"


def cfa_noise(views: np.ndarray, chan: np.ndarray, channels) -> float:
    """A colour light field's relative noise: the largest of ``channels``' (:func:`lf_flame.tomo.noise_knobs.relative_noise`
    of :func:`~lf_flame.temperature.mosaic.channel_subviews`, each channel's samples only, so the CFA's pattern is not taken for noise)."""
    return max(relative_noise(channel_subviews(views, chan, c)) for c in channels)


#: Why ``refocus-cfa`` is refused on a hexagonal grid (:func:`route_operator`, and ``lf-flame temperature`` before its
#: depth search).
HEX_REFOCUS_REFUSED = ("refocus-cfa refocuses a square grid's views; a hexagonal grid's colour channels are solved on "
                       "its lattice: choose an admm route")


def route_operator(camera, depths_mm, route: str, hexagonal=None, sample_offsets=None):
    """The planes' operator a route of :data:`CFA_ROUTES` solves on: None for ``refocus-cfa``; the
    :data:`MATCHED_SUBSAMPLES` grid for ``admm-cfa-matched``; the lenslet grid otherwise (float32).
    ``sample_offsets``: a decoded square colour capture's
    (:attr:`lf_flame.real.lightfield.LightField.sample_offsets`), each sample modelled at its own pixel on
    at most :data:`DECODED_OFFSET_BINS` sub-views per view and axis, as the planes need
    (:func:`lf_flame.tomo.exact.offset_bins_for`; :class:`lf_flame.tomo.exact.ExactOperator`); not with ``hexagonal``
    (:data:`DECODED_OFFSET_KNOBS`).

    ``hexagonal``: a decoded hexagonal grid's light field (:class:`lf_flame.real.lightfield.LightField`
    with lattice views), whose channels are solved on its lattice
    (:func:`lf_flame.tomo.lattice.hexagonal_operator`); ``refocus-cfa`` is refused there (shift-and-sum
    needs the square grid, where the resampled views blend channels)."""
    from ..tomo.exact import ExactOperator, offset_bins_for
    if route not in CFA_ROUTES:
        raise ValueError(f"unknown route {route!r}; one of {CFA_ROUTES}")
    subsamples = MATCHED_SUBSAMPLES if route == "admm-cfa-matched" else 1
    if hexagonal is not None:
        if route == "refocus-cfa":
            raise ValueError(HEX_REFOCUS_REFUSED)
        from ..tomo.lattice import hexagonal_operator
        if sample_offsets is not None:
            raise ValueError("a hexagonal grid's colour channels are solved on its whole lattice views (the samples' "
                             "offsets are not modelled there)")
        return hexagonal_operator(hexagonal, depths_mm, precision="float32", subsamples=subsamples,
                                  sample_offsets=None)
    if route == "refocus-cfa":
        return None
    return ExactOperator(camera, depths_mm, precision="float32", subsamples=subsamples, sample_offsets=sample_offsets,
                         offset_bins=offset_bins_for(camera, depths_mm, DECODED_OFFSET_BINS))


def refocus_channel(views: np.ndarray, own: np.ndarray, slopes, mask: np.ndarray) -> np.ndarray:
    """One channel refocused at ``slopes``: per pixel the mean over the views holding that channel there.

    Shift-and-sum of ``views * own`` over shift-and-sum of ``own`` (bilinear,
    :func:`lf_flame.refocus.shift_and_sum.focal_stack`); 0 where no view holds the channel.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    own : ndarray of shape (N, N, R, C), bool: the channel's samples
    slopes : sequence of float, lenslets per view
    mask : ndarray of shape (N, N), bool: the views summed (the aperture)

    Returns
    -------
    ndarray of shape (len(slopes), R, C)
    """
    m = np.asarray(own, bool)
    num = focal_stack(views * m, slopes, mask)
    den = focal_stack(m.astype(np.float32), slopes, mask)
    return np.where(den > 0, num / np.maximum(den, 1e-12), 0.0)


def channel_emission(route: str, views: np.ndarray, chan: np.ndarray, channels, *, op=None, slopes=None,
                     saturation: float | None = 1.0, sigma: float | None = None, knobs: dict | None = None,
                     ratio_filter: dict | None = None, info: dict | None = None, support=None):
    """Two channels' emission per plane from a colour light field by one of :data:`CFA_ROUTES`.

    Parameters
    ----------
    route : str
        One of :data:`CFA_ROUTES`.
    views : ndarray of shape (N, N, R, C)
        The colour light field (:func:`lf_flame.refocus.shift_and_sum.raw_to_views` of the raw mosaic).
    chan : ndarray of shape (N, N, R, C), int
        Each sample's channel (:func:`channel_views`).
    channels : (int, int)
        Channel indices (0 R, 1 G, 2 B) of the ratio's numerator and denominator.
    op : ExactOperator
        The planes' operator (admm routes; :func:`route_operator` builds the route's own).
        On a grid finer than the lenslets the emission is binned to them.
    slopes : sequence of float
        The planes' slopes, lenslets per view (``refocus-cfa``).
    saturation : float, ndarray of bool of the views' shape, or None
        Clipping level: admm leaves samples at or above it out of the fit; or the samples to
        leave out (True; decoded views, :func:`lf_flame.tomo.decoded.fit_data`); None: none.
    sigma : float or None
        ``admm-cfa-matched``'s Gaussian on both channels, lenslets; None: 0 (none).
    knobs : dict or None
        ``admm-cfa-matched``'s admm ``fills``, ``lam``, ``tv``, ``l1``; None:
        :data:`MATCHED_KNOBS` by the light field's noise (:func:`cfa_noise`; texture finer
        than two lenslets also reads as noise there).
    ratio_filter : dict or None
        ``admm-cfa-matched``'s :func:`~lf_flame.temperature.ratio.filter_ratio` ``radius``, ``eps`` and
        ``contour`` (an empty dict: none); None: :data:`MATCHED_RATIO_FILTER` by the light field's
        noise (the very noisy one from :data:`MATCHED_WIDE_NOISE`).
    info : dict or None
        Filled with what the route chose: ``noise`` (measured where ``knobs`` or ``ratio_filter``
        is None), ``regime``, ``knobs``, ``sigma`` and ``ratio_filter`` (``admm-cfa-matched``),
        ``subsamples`` (admm routes).
    support : ndarray of bool of shape ``op.dims``, or None
        admm routes: where each plane may hold emission (:func:`admm_channel`); None: everywhere.

    Returns
    -------
    (a, b) : two ndarrays of shape (P, R, C): the channels' emission on the lenslet grid, the views' units.

    Raises
    ------
    ValueError
        An unknown route, a missing ``op``/``slopes``, a channel mask of another shape, channels not two
        different indices of :data:`~lf_flame.optics.colour.CHANNELS` or one the map holds no sample of, and
        the errors of :func:`admm_channel`.
    """
    if route not in CFA_ROUTES:
        raise ValueError(f"unknown route {route!r}; one of {CFA_ROUTES}")
    chan = np.asarray(chan)
    if chan.shape != views.shape:
        raise ValueError(f"channel map of shape {chan.shape} for views of shape {views.shape}")
    if len(channels) != 2 or len({int(c) for c in channels}) != 2 or not all(0 <= int(c) < len(CHANNELS)
                                                                             for c in channels):
        raise ValueError(f"channels must be two different channel indices of {len(CHANNELS)} (0 R, 1 G, 2 B). "
                         f"Received: {tuple(channels)!r}")
    absent = [CHANNELS[int(c)] for c in channels if not np.any(chan == int(c))]
    if absent:
        raise ValueError(f"the channel map holds no sample of {', '.join(absent)}: a ratio of channels needs a colour "
                         "(Bayer) light field's map (lf_flame.temperature.mosaic.channel_views)")
    if route == "refocus-cfa":
        if slopes is None:
            raise ValueError("refocus-cfa needs the planes' slopes")
        mask = aperture_mask(views.shape[0], "circular")
        return tuple(refocus_channel(views, chan == c, slopes, mask) for c in channels)
    if op is None:
        raise ValueError(f"{route} needs the planes' operator")
    info = {} if info is None else info
    ok = (np.ones(views.shape, bool) if saturation is None else ~np.asarray(saturation, bool)
          if np.ndim(saturation) else views < saturation)
    fits = [(chan == c) & ok for c in channels]
    for c, f in zip(channels, fits):
        if not (f.any() and views[f].max() > 0):
            raise ValueError(f"the {CHANNELS[c]} channel has no sample with signal to fit (its pixels dark, clipped "
                             "or absent from the capture): two-colour pyrometry needs light in both channels")
    if route == "admm-cfa-matched":
        sigma = 0.0 if sigma is None else sigma
        if ratio_filter is None or knobs is None:
            info["noise"] = cfa_noise(views, chan, channels)
            info["regime"] = matched_regime(info["noise"])
            knobs = MATCHED_KNOBS[info["regime"]] if knobs is None else knobs
            if ratio_filter is None:
                ratio_filter = MATCHED_RATIO_FILTER[info["regime"]]
        info.update(knobs=dict(knobs), sigma=sigma, ratio_filter=dict(ratio_filter))
        rec = matched_channels(views, op, fits, support=support, **knobs)
    else:
        rec = [admm_channel(views, op, f, support=support) for f in fits]
        sigma = SMOOTH_SIGMA if route == "admm-cfa-smooth" else 0.0
        ratio_filter = {}
    rec = [bin_planes(r, op.subsamples) for r in rec]
    info["subsamples"] = op.subsamples
    if sigma:
        rec = [smooth_planes(r, sigma) for r in rec]
    if ratio_filter:
        rec = filter_ratio(rec[0], rec[1], **ratio_filter)
    return rec[0], rec[1]


def colour_truth(channel_radiance, layers, op) -> np.ndarray:
    """A colour scene's emission per channel on the planes' grids.

    Parameters
    ----------
    channel_radiance : sequence of ndarray of shape (3, rows, cols)
        Per layer, channels R, G, B (:class:`lf_flame.simulate.scenes_temperature.ColourFlameScene`).
    layers : sequence of Layer
        The scene's layers, one per plane of ``op`` in its order.
    op : ExactOperator
        Its ``dims``, ``sizes_mm`` and ``centres_mm`` give the grids.

    Returns
    -------
    ndarray of shape (3, P, rows, cols): the area-weighted truth
    (:func:`lf_flame.tomo.truth.resample_layer`).

    Raises
    ------
    ValueError
        Not one layer per plane.
    """
    if len(layers) != op.dims[0] or len(channel_radiance) != len(layers):
        raise ValueError(f"one layer and channel radiance per plane is needed: {op.dims[0]} planes, {len(layers)} "
                         f"layers, {len(channel_radiance)} radiances")
    truth = np.zeros((3,) + tuple(op.dims))
    for k, L in enumerate(layers):
        for c in range(3):
            truth[c, k] = resample_layer(dataclasses.replace(L, radiance=channel_radiance[k][c]), op.dims[1:],
                                         op.sizes_mm[k], op.centres_mm[k])
    return truth


