"""Real cameras, stage 2: decoding of raw images into sub-aperture views with a lenslet-grid
calibration (:mod:`lf_flame.real.calibration`, stage 1).

:func:`decode` resamples every lenslet image about its calibrated centre (the fitted
lattice) into sub-aperture views (N, N, R, C), after dark subtraction and white-image
(vignetting) normalisation, with the axis order and units of :mod:`lf_flame.refocus.shift_and_sum`
(view step: one pixel; slopes: lenslets per view step); :func:`decode_colour` does so for a
colour (Bayer) capture, its channels apart. Each first checks that the raw image shows the
calibration's grid (:func:`lf_flame.real.grid_check.check_grid`); :mod:`lf_flame.real.views_file`
is the file of decoded views that ``lf-flame decode`` writes.

Pixel coordinates and the grid rotation are those of :mod:`lf_flame.real.calibration`.
Reference: Dansereau, Pizarro & Williams 2013 (LFToolbox: decoding to a 4-D light field).
"""
from __future__ import annotations

import math

import numpy as np

from ._decoding_kernels import bilinear
from .calibration import GridCalibration
from .grid_check import check_grid
from .images import _image
from .lattice import _H


def view_positions(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """Sensor positions (row, column; px) sampled for view ``(u, v)`` of lenslet ``(r, c)``:
    the lenslet's calibrated centre plus ``(u - (N-1)/2, v - (N-1)/2)`` pixels along the
    grid's rotated axes. Shape (N, N, R, C, 2), R × C the calibration's (hexagonal) grid.

    Read-only, and the same array for the same grid and ``N`` as the call before (a recording's frames are all
    decoded at one grid's positions: 5-10 ms a frame of a 99 x 98-lenslet camera, twice)."""
    key = (calibration.layout, calibration.pitch_px, calibration.rotation_deg, tuple(calibration.origin_px),
           calibration.n_rows, calibration.n_cols, int(n_views))
    pos = _LAST_POSITIONS.get(key)
    if pos is None:
        pos = calibration.centres_px()[None, None] + _view_offsets(calibration, n_views)[:, :, None, None]
        pos.setflags(write=False)
        _LAST_POSITIONS.clear()
        _LAST_POSITIONS[key] = pos
    return pos


#: :func:`view_positions`' last grid and its positions.
_LAST_POSITIONS: dict = {}


def _view_offsets(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """Each view's offset (row, column; px) from its lenslet's centre: (N, N, 2)."""
    off = np.arange(n_views) - (n_views - 1) / 2
    du = np.stack(np.meshgrid(off, off, indexing="ij"), axis=-1)              # (N, N, 2)
    rot = calibration.matrix / calibration.pitch_px
    return du @ rot.T


#: The most samples :func:`interpolation_phases` keeps (an even spread): the operator draws 2^14 per view and plane.
MAX_PHASES = 2 ** 16


def interpolation_phases(calibration: GridCalibration, n_views: int, bin_views: int = 1) -> np.ndarray:
    """Where each decoded sample falls between the pixels :func:`decode` interpolates it from.

    Bilinear sampling at a position ``f`` of the way from one pixel's centre to the next reads
    the first with weight ``1 - f`` and the second with ``f``: on average over the lenslets,
    whose centres fall anywhere between pixels on a grid of non-integer pitch, a blur of the
    lenslet images (a triangle of half-width one pixel for phases spread evenly), and none on
    a grid whose centres sit on pixel centres. The exact operator of decoded views models it
    from these phases (:func:`lf_flame.tomo.lattice.lattice_kernels`).

    Parameters
    ----------
    calibration : GridCalibration
    n_views, bin_views : int
        As :func:`decode`.

    Returns
    -------
    ndarray of shape (2, M), float64
        Per sensor axis (rows, columns), the phases ``f`` in [0, 1) of the samples of every view of
        every lenslet (``M = (N bin_views)^2 R C``), or of an even spread of at most
        :data:`MAX_PHASES` of them.
    """
    centres = calibration.centres_px().reshape(-1, 2)
    offsets = _view_offsets(calibration, int(n_views) * int(bin_views)).reshape(-1, 2)
    total = len(offsets) * len(centres)             # view_positions' samples, flattened (view, lenslet)
    view, lenslet = np.divmod(np.arange(0, total, -(-total // MAX_PHASES)), len(centres))
    pos = centres[lenslet] + offsets[view] - 0.5                                 # pixel (i, j) centred at (i + ½, j + ½)
    return (pos - np.floor(pos)).T


def _sample(img, pos):
    """Bilinear samples of ``img`` (H, W), or of each of a stack (K, H, W), at pixel-coordinate positions ``pos``
    (..., 2); 0 off the image (:func:`~lf_flame.real._decoding_kernels.bilinear`): shape ``pos.shape[:-1]``, or
    (K,) + that, float64."""
    images = np.ascontiguousarray(img, np.float64)
    stack = images.reshape((-1,) + images.shape[-2:])
    positions = np.ascontiguousarray(np.reshape(pos, (-1, 2)), np.float64)    # a view of view_positions' array
    out = np.empty((len(stack), len(positions)))
    bilinear(stack, positions, out)
    return out.reshape(images.shape[:-2] + pos.shape[:-1])


#: Views per axis that :func:`auto_bin` bins a many-view camera down to (at least): the paper camera's 15.
BIN_TARGET_VIEWS = 15


def auto_bin(calibration: GridCalibration, n_views: int | None = None) -> int:
    """Pixels per axis summed into one view sample by default (``decode --bin auto``):
    ``max(1, max_views // BIN_TARGET_VIEWS)``, so a lenslet image of 48 pixels gives 16 views of
    3 x 3 pixels, and one of up to 29 pixels keeps a view per pixel; 1 where the views' count
    ``n_views`` is given.

    Binning keeps every pixel's light and the aperture's full parallax; it coarsens the angular
    sampling. On the 48 px camera of ``experiments/cameras.py`` (validation scenes 57000-57005,
    a ``/tmp`` probe) 3 x 3 binning left the found depths (p90 0.0032 against 0.0033 lenslets per
    view step) and the emission (p90 7.3 % against 7.4 % noise-free) as they were, and cut admm's
    time per lenslet-plane 3-5x: the exact operator's work grows with the views' count.
    """
    return 1 if n_views is not None else max(1, max_views(calibration) // BIN_TARGET_VIEWS)


def _bin(a: np.ndarray, k: int) -> np.ndarray:
    """Sums of ``k x k`` blocks of views: (N k, N k, R, C) -> (N, N, R, C)."""
    if k == 1:
        return a
    n = a.shape[0] // k
    return a.reshape(n, k, n, k, *a.shape[2:]).sum(axis=(1, 3))


def _square_grid(R: int, C: int) -> tuple[int, int]:
    """The square lattice :func:`hex_to_square` resamples a hexagonal grid of R x C lenslets onto."""
    return int(math.floor((R - 1) * _H)) + 1, C - 1


def views_shape(calibration: GridCalibration, n_views: int | None = None, bin_views: int = 1) -> tuple:
    """The shape (N, N, R, C) of :func:`decode`'s views (a hexagonal grid's on the square lattice),
    refused as :func:`decode` refuses ``n_views`` and ``bin_views``."""
    n = _view_count(calibration, n_views, bin_views)
    R, C = calibration.n_rows, calibration.n_cols
    return (n, n) + (_square_grid(R, C) if calibration.layout == "hex" else (R, C))


def hex_to_square(views: np.ndarray) -> np.ndarray:
    """Resample views on a hexagonal lenslet lattice onto a square one of the same pitch.

    ``views`` (N, N, R, C) on the calibration's hexagonal grid (row 0 unshifted, odd rows
    half a pitch right, rows ``sqrt(3)/2`` pitches apart). The square lattice has rows one
    pitch apart, ``floor((R - 1) sqrt(3)/2) + 1`` of them, and ``C - 1`` columns from
    half a pitch right of lenslet (0, 0), where every row has lenslets on both sides.
    Each value is the barycentric (linear) interpolation in the lattice triangle about it.

    Returns
    -------
    views : ndarray of shape (N, N, R', C'), float32
    """
    N, _, R, C = views.shape
    rows, cols = _square_grid(R, C)
    if rows < 1 or cols < 1:
        raise ValueError(f"a hexagonal grid of {R} x {C} lenslets is too small to resample")
    y, x = np.meshgrid(np.arange(rows, dtype=np.float64), 0.5 + np.arange(cols), indexing="ij")
    j = y / _H                        # lattice row, fractional
    i = x - j / 2                     # skew column: site (i, j) sits at x = i + j/2
    i0, j0 = np.floor(i), np.floor(j)
    fi, fj = i - i0, j - j0
    lower = fi + fj < 1
    verts = [(np.where(lower, i0, i0 + 1), np.where(lower, j0, j0 + 1), np.where(lower, 1 - fi - fj, fi + fj - 1)),
             (i0 + 1, j0, np.where(lower, fi, 1 - fj)),
             (i0, j0 + 1, np.where(lower, fj, 1 - fi))]
    out = np.zeros((N, N, rows, cols), np.float32)
    for vi, vj, w in verts:
        r = np.clip(vj, 0, R - 1).astype(int)
        c = np.clip(vi + np.floor(vj / 2), 0, C - 1).astype(int)
        out += (w[None, None] * views[:, :, r, c]).astype(np.float32)
    return out


def on_square_grid(a: np.ndarray, calibration: GridCalibration) -> np.ndarray:
    """:func:`decode`'s (or :func:`clipped_samples`') output with ``resample=False`` as it is with
    resampling: a hexagonal grid's views (a boolean mask: any of its three samples) on the square
    grid (:func:`hex_to_square`), a square grid's as they are."""
    if calibration.layout != "hex":
        return a
    if a.dtype == bool:
        return np.ascontiguousarray(hex_to_square(a.astype(np.float32)) > 1e-6)
    return np.ascontiguousarray(hex_to_square(a))


def max_views(calibration) -> int:
    """Views per axis a lenslet image holds: ``floor(pitch_px + PITCH_SNAP_PX)``
    (:data:`lf_flame.optics.camera_file.PITCH_SNAP_PX`).

    Parameters
    ----------
    calibration : GridCalibration

    Returns
    -------
    int
        One pixel apart along each axis: 10 for a 10.57 px pitch, 15 for a calibrated 14.9997.
    """
    return views_for_pitch(calibration.pitch_px)


def views_for_pitch(pitch_px: float) -> int:
    """Views per axis a lenslet image ``pitch_px`` pixels wide holds (:func:`max_views`)."""
    from ..optics.camera_file import PITCH_SNAP_PX
    return int(math.floor(pitch_px + PITCH_SNAP_PX))


def _view_count(calibration: GridCalibration, n_views, bin_views=1) -> int:
    """Views per axis (default: as many ``bin_views``-pixel views as the lenslet image holds), refused as
    :func:`decode` says."""
    n_max = max_views(calibration)
    if isinstance(bin_views, bool) or int(bin_views) != bin_views or not 1 <= bin_views <= n_max:
        raise ValueError(f"bin_views must be an integer in [1, {n_max}] (pixels per view sample and axis). "
                         f"Received: bin_views={bin_views!r}")
    k = int(bin_views)
    n = n_max // k if n_views is None else n_views
    if int(n) != n or not 1 <= n * k <= n_max:
        raise ValueError(f"n_views must be an integer in [1, {n_max // k}] (the pitch is {calibration.pitch_px:.2f} px"
                         + (f", {k} pixels per view" if k > 1 else "") + f"). Received: n_views={n_views!r}")
    return int(n)


def _prepared(raw, calibration: GridCalibration, dark, n_views, check: bool, bin_views: int = 1):
    """The decoders' raw image, dark subtracted and checked against the calibration's grid
    (:func:`check_grid`), the dark frame (or None) and the views per axis (:func:`_view_count`),
    each refused as :func:`decode` says."""
    img = _image("raw image", raw, calibration.sensor_shape)
    d = None if dark is None else _image("dark frame", dark, calibration.sensor_shape)
    if d is not None:
        img = img - d
    if check:
        check_grid(img, calibration)
    return img, d, _view_count(calibration, n_views, bin_views)


def decode(raw: np.ndarray, calibration: GridCalibration, white: np.ndarray | None = None,
           dark: np.ndarray | None = None, *, n_views: int | None = None, min_white: float = 0.05,
           camera_id: str | None = None, check: bool = True, bin_views: int = 1, resample: bool = True,
           white_views: np.ndarray | None = None) -> np.ndarray:
    """Decode a raw plenoptic image into sub-aperture views with its grid calibration.

    Dark subtraction, then every lenslet image is resampled (bilinearly) at
    :func:`view_positions` about its calibrated centre, and divided by the white image
    resampled the same way (vignetting and cos⁴ normalisation; Dansereau et al. 2013).
    With ``bin_views`` = k each view sample sums k x k such samples, of the raw and of the white
    image alike, before the division (the views of a camera with k-times larger pixels,
    :func:`lf_flame.real.own_camera.views_camera`).
    A hexagonal grid is then resampled onto a square one (:func:`hex_to_square`) unless
    ``resample`` is False.

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
    calibration : GridCalibration
    white, dark : ndarray of the same shape, or None
        White image and dark frame (the dark frame is subtracted from both).
    n_views : int or None
        ``N``, views per axis, ``bin_views`` pixels apart; default and most
        ``max_views // bin_views`` (:func:`max_views`).
    bin_views : int
        Pixels per view sample and axis, >= 1 (:func:`auto_bin` chooses one for many-view cameras).
    min_white : float
        Samples where the white image is below this fraction of its 99th percentile
        (outside the lenslet image, between lenslets) are set to 0.
    camera_id : str or None
        If given and the calibration names a camera, they must agree.
    check : bool
        Check that the raw image shows the calibration's grid (:func:`check_grid`).
    resample : bool
        False: a hexagonal grid's views stay on its own lattice (the calibration's R x C
        lenslets, odd rows half a pitch right), the data of
        :class:`lf_flame.tomo.lattice.LatticeOperator`.
    white_views : ndarray of shape (N, N, R, C) or None
        The white image as it divides the views (:func:`white_samples`, at the same ``n_views``,
        ``bin_views`` and ``min_white``), in place of ``white``: computed once, it decodes every
        frame of a recording.

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        ``views[u, v, r, c]``: view (u, v) of lenslet (r, c), as
        :func:`lf_flame.refocus.shift_and_sum.raw_to_views` (view step one pixel, lenslet step one pitch),
        so that :func:`~lf_flame.refocus.shift_and_sum.focal_stack`, :class:`~lf_flame.refocus.shift_and_sum.FourierSlice`
        and :func:`~lf_flame.refocus.shift_and_sum.find_sharpest_slope` apply unchanged. With a white
        image: radiance relative to the white target's; without: dark-subtracted counts.

    Raises
    ------
    ValueError
        A raw, white or dark image of another shape than the calibration's sensor, NaN or
        inf, ``n_views`` or ``bin_views`` out of range, another camera id, or a raw image whose
        visible lenslet grid is not the calibration's; ``white`` and ``white_views`` both given,
        or ``white_views`` of another shape than the views.
    """
    calibration.validate()
    if camera_id is not None and calibration.camera_id and camera_id != calibration.camera_id:
        raise ValueError(f"the calibration is of camera {calibration.camera_id!r}, not {camera_id!r}")
    if white is not None and white_views is not None:
        raise ValueError("give the white image or its samples (white_views), not both")
    img, d, n = _prepared(raw, calibration, dark, n_views, check, bin_views)
    k = int(bin_views)
    views = _bin(_sample(img, view_positions(calibration, n * k)), k)
    if white is not None:
        white_views = white_samples(calibration, white, d, n_views=n, bin_views=k, min_white=min_white)
    if white_views is not None:
        if np.shape(white_views) != views.shape:
            raise ValueError(f"white_views of shape {np.shape(white_views)} are not the views' {views.shape}")
        lit = white_views > 0
        views = np.where(lit, views / np.where(lit, white_views, 1.0), 0.0)
    views = views.astype(np.float32)
    if calibration.layout == "hex" and resample:
        views = hex_to_square(views)
    return np.ascontiguousarray(views)


def white_samples(calibration: GridCalibration, white: np.ndarray, dark: np.ndarray | None = None, *,
                  n_views: int | None = None, bin_views: int = 1, min_white: float = 0.05, sensor=None) -> np.ndarray:
    """The white image as :func:`decode` divides a capture's views by it: the dark frame subtracted, sampled
    bilinearly at :func:`view_positions` and binned as the capture, and 0 where it is below ``min_white`` of
    its 99th percentile (outside the lenslet images, between lenslets), where the views are set to 0. With a
    colour ``sensor``, as :func:`decode_colour` divides by it: each sample its nearest pixel, over that pixel's
    channel's 99th percentile on the sensor, and 0 where that is ``min_white`` or less.

    Parameters
    ----------
    calibration, white, dark, n_views, bin_views, min_white
        As :func:`decode`.
    sensor : ColourSensor or None
        A colour capture's (:func:`decode_colour`; ``bin_views`` 1).

    Returns
    -------
    ndarray of shape (N, N, R, C), float64
        On the calibration's grid (a hexagonal grid's lattice).

    Raises
    ------
    ValueError
        A white image or dark frame of another shape than the calibration's sensor, NaN or inf, ``n_views`` or
        ``bin_views`` out of range, or a white image dark where the lenslet images are (or in a colour channel).
    """
    w = _image("white image", white, calibration.sensor_shape)
    if dark is not None:
        w = w - _image("dark frame", dark, calibration.sensor_shape)
    if sensor is not None:
        if bin_views != 1:
            raise ValueError("a colour capture is decoded one pixel per sample, its channels apart: bin_views 1")
        wv = _colour_white(w, _colour_pixels(calibration, sensor, _view_count(calibration, n_views, 1)))
        return np.where(wv > min_white, wv, 0.0)
    n, k = _view_count(calibration, n_views, bin_views), int(bin_views)
    wv = _bin(_sample(w, view_positions(calibration, n * k)), k)
    floor = min_white * np.percentile(wv, 99)
    if not floor > 0:
        raise ValueError("the white image is dark where the lenslet images are: not this calibration's white image")
    return np.where(wv > floor, wv, 0.0)


def decode_colour(raw: np.ndarray, calibration: GridCalibration, sensor, white: np.ndarray | None = None,
                  dark: np.ndarray | None = None, *, n_views: int | None = None, min_white: float = 0.05,
                  check: bool = True, white_views: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decode a colour (Bayer) raw image into sub-aperture views that keep its channels apart.

    :func:`decode`'s bilinear resampling blends four pixels, which under a colour filter array
    are of two or three channels. Here each view sample is the one pixel nearest its position
    (:func:`view_positions`) and carries that pixel's channel: the channel map of the views, on
    which each channel is solved from its own samples
    (:func:`lf_flame.temperature.channels.channel_emission`), as on a perfect grid. The price is
    the position: up to half a pixel (half a view step) from where the decoded camera puts the
    sample, which :func:`sample_offsets` gives and the exact operator models
    (:attr:`lf_flame.real.lightfield.LightField.sample_offsets`). The white image divides each pixel by its own value over its channel's 99th
    percentile on the sensor, so that vignetting is removed and the channels' ratio, which the
    pyrometer reads, is the raw image's.

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
    calibration : GridCalibration
        Square or hexagonal. A hexagonal grid's views stay on its own lattice (rows of lenslets,
        odd rows half a pitch right, as :func:`decode` with ``resample=False``): resampling them
        onto a square grid would blend neighbouring lenslets' samples, of other channels. They
        are solved there (:class:`lf_flame.tomo.lattice.LatticeOperator`).
    sensor : ColourSensor
        Its CFA pattern and phase (of pixel (0, 0) of the raw image).
    white, dark, n_views, min_white, check
        As :func:`decode`.
    white_views : ndarray of shape (N, N, R, C) or None
        The white image as it divides the views (:func:`white_samples` with this ``sensor``, at the same
        ``n_views`` and ``min_white``), in place of ``white``: computed once, it decodes every frame of a
        recording.

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        As :func:`decode`'s (a hexagonal grid's: on its lattice, the calibration's rows); 0 where the
        white image is dark or the pixel off the sensor.
    channels : ndarray of shape (N, N, R, C), int8
        Each sample's channel (0 R, 1 G, 2 B; :data:`lf_flame.optics.colour.CHANNELS`).

    Raises
    ------
    ValueError
        As :func:`decode`.
    """
    calibration.validate()
    if white is not None and white_views is not None:
        raise ValueError("give the white image or its samples (white_views), not both")
    img, d, n = _prepared(raw, calibration, dark, n_views, check)
    pixels = _colour_pixels(calibration, sensor, n)
    qr, qc, on, cfa = pixels
    channels = cfa[qr, qc]
    views = np.where(on, img[qr, qc], 0.0)
    if white is not None:
        w = _image("white image", white, calibration.sensor_shape)
        wv = _colour_white(w if d is None else w - d, pixels)
        white_views = np.where(wv > min_white, wv, 0.0)
    if white_views is not None:
        if np.shape(white_views) != views.shape:
            raise ValueError(f"white_views of shape {np.shape(white_views)} are not the views' {views.shape}")
        lit = white_views > 0
        views = np.where(lit, views / np.where(lit, white_views, 1.0), 0.0)
    return np.ascontiguousarray(views.astype(np.float32)), np.ascontiguousarray(channels.astype(np.int8))


def _colour_pixels(calibration: GridCalibration, sensor, n_views: int):
    """The pixel each view sample reads (row, column; (N, N, R, C) int64, clipped to the sensor), whether it lies on
    the sensor, and the sensor's channel map (:func:`lf_flame.optics.colour.cfa_channels`)."""
    from ..optics.colour import cfa_channels
    H, W = calibration.sensor_shape
    q = _nearest_pixels(calibration, n_views)
    on = (q[..., 0] >= 0) & (q[..., 0] < H) & (q[..., 1] >= 0) & (q[..., 1] < W)
    return (np.clip(q[..., 0], 0, H - 1), np.clip(q[..., 1], 0, W - 1), on,
            cfa_channels((H, W), sensor.pattern, sensor.phase))


def _colour_white(w: np.ndarray, pixels) -> np.ndarray:
    """A dark-subtracted white image ``w`` at each view sample's pixel over its channel's 99th percentile on the
    sensor (0 off the sensor; ``pixels``: :func:`_colour_pixels`): :func:`decode_colour`'s divisor before
    ``min_white``."""
    qr, qc, on, cfa = pixels
    level = np.ones(3)
    for c in range(3):
        v = w[cfa == c]
        level[c] = np.percentile(v, 99) if v.size else 1.0
    if not np.all(level > 0):
        raise ValueError("the white image is dark in a colour channel: not this camera's white image")
    return np.where(on, w[qr, qc] / level[cfa[qr, qc]], 0.0)


def _nearest_pixels(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """The pixel holding each view sample's position (row, column; (N, N, R, C, 2) int64): pixel
    ``(i, j)`` spans ``[i, i + 1) x [j, j + 1)``."""
    return np.floor(view_positions(calibration, n_views)).astype(np.int64)


def decode_capture_views(raw: np.ndarray, calibration: GridCalibration, white: np.ndarray | None = None,
                         dark: np.ndarray | None = None, sensor=None, *, n_views: int | None = None,
                         bin_views: int | None = None, camera_id: str | None = None, check: bool = True,
                         white_views: np.ndarray | None = None):
    """A capture decoded as ``lf-flame decode`` decodes it: :func:`decode` (its bilinear samples, binned by
    ``bin_views``, None: :func:`auto_bin`), or for a colour ``sensor``'s capture :func:`decode_colour` (each sample
    its nearest pixel, its channel with it, one pixel per sample); a hexagonal grid's views on its own lattice.
    ``check``, ``white_views``: as :func:`decode` (a recording's later frames unchecked, its first checked; its
    white image's samples computed once: :func:`white_samples`, with the ``sensor`` of a colour capture).

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        On the calibration's grid (``resample=False``: :func:`on_square_grid` puts a hexagonal grid's on the
        square one).
    channels : ndarray of int8 of the views' shape, or None
        A colour capture's channel map.
    bin_views : int
        Pixels per view sample and axis.

    Raises
    ------
    ValueError
        As :func:`decode` and :func:`decode_colour`; a colour capture with ``bin_views`` other than 1 or None, or
        ``camera_id`` other than the calibration's.
    """
    if sensor is None:
        k = auto_bin(calibration, n_views) if bin_views is None else bin_views
        return decode(raw, calibration, white, dark, n_views=n_views, camera_id=camera_id, bin_views=k,
                      resample=False, check=check, white_views=white_views), None, k
    if bin_views not in (None, 1):
        raise ValueError("a colour capture is decoded one pixel per sample, its channels apart: bin_views 1 (--bin 1 "
                         "or auto)")
    if camera_id is not None and calibration.camera_id and camera_id != calibration.camera_id:
        raise ValueError(f"the calibration is of camera {calibration.camera_id!r}, not {camera_id!r}")
    views, channels = decode_colour(raw, calibration, sensor, white, dark, n_views=n_views, check=check,
                                    white_views=white_views)
    return views, channels, 1


def decode_repaired(raw: np.ndarray, calibration: GridCalibration, white: np.ndarray | None = None,
                    dark: np.ndarray | None = None, sensor=None, saturation: float | None = None, *,
                    n_views: int | None = None, bin_views: int | None = None, camera_id: str | None = None,
                    defects: np.ndarray | None = None, check: bool = True, white_views: np.ndarray | None = None):
    """A capture decoded as :func:`decode_capture_views` decodes it, its defective pixels repaired first
    (:func:`lf_flame.real.defects.capture_defects`), and the samples to leave out of a fit: those from pixels at or
    above ``saturation`` (:func:`clipped_samples`) or defective.

    ``defects``: the sensor's defect map (bool, the raw image's shape), found in an earlier frame (a recording's):
    applied, not searched for again. None: found in this capture. ``check``: check that the capture shows the
    calibration's grid (:func:`decode`; False for a recording's frames after its first). ``white_views``: the white
    image's samples (:func:`white_samples`, a recording's, computed once) in place of ``white``.

    Returns
    -------
    views, channels, bin_views
        As :func:`decode_capture_views` (``resample=False``: a hexagonal grid's on its lattice).
    leave_out : ndarray of bool of the views' shape, or None
        None where no level is given and no pixel is defective.
    defects : ndarray of bool of the raw image's shape
        The capture's defective pixels.

    Raises
    ------
    ValueError
        As :func:`decode_capture_views` and :func:`clipped_samples`.
    """
    from .defects import capture_defects, grid_offsets
    img = _image("raw image", raw, calibration.sensor_shape)
    flagged, repaired = capture_defects(img, grid_offsets(calibration, sensor is not None), flagged=defects,
                                        dark=None if dark is None else _image("dark frame", dark, img.shape))
    views, channels, k = decode_capture_views(repaired, calibration, white, dark, sensor, n_views=n_views,
                                              bin_views=bin_views, camera_id=camera_id, check=check,
                                              white_views=white_views)
    leave_out = None if saturation is None and not flagged.any() else clipped_samples(
        img, calibration, saturation, n_views=n_views, bin_views=k, resample=False, defects=flagged)
    return views, channels, k, leave_out, flagged


def sample_offsets(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """Where the pixel :func:`decode_colour` reads for each view sample lies from the sample's place.

    The pixel's centre less the view's position (:func:`view_positions`), turned into the grid's
    axes and in view steps (one pixel: :func:`decode`'s view step), each within about half a
    step: what the exact operator models for such samples
    (:class:`lf_flame.tomo.exact.ExactOperator`'s ``sample_offsets``). On a grid whose pitch is
    not a whole number of pixels it runs through every value from lenslet to lenslet; its
    effect on a sample grows with the plane's slope (a point at ``s`` lenslets per view step is
    seen ``s`` times the offset lenslets away).

    Parameters
    ----------
    calibration : GridCalibration
        Square or hexagonal (whose samples :func:`decode_colour` keeps on its lattice, as here).
    n_views : int
        ``N``, as decoded.

    Returns
    -------
    ndarray of shape (N, N, R, C, 2), float32
        (along the grid's rows, along its columns), view steps.
    """
    pos = view_positions(calibration, int(n_views))
    rot = calibration.matrix / calibration.pitch_px                  # grid axes -> sensor (rows of view_positions)
    off = (_nearest_pixels(calibration, int(n_views)) + 0.5 - pos) @ np.linalg.inv(rot.T)
    return np.ascontiguousarray(off, np.float32)


def clipped_samples(raw: np.ndarray, calibration: GridCalibration, saturation: float | None, *,
                    n_views: int | None = None, bin_views: int = 1, resample: bool = True,
                    defects: np.ndarray | None = None) -> np.ndarray:
    """Which decoded samples come from clipped raw pixels: the clipping level in the views' units.

    A sample of :func:`decode` is a bilinear mix of up to four raw pixels; it holds only a
    lower bound of its light when any of them (with a non-zero weight) is at or above the
    sensor's clipping level. After white-image division no single level marks such
    samples (a clipped pixel under a bright white reads 1 / white), so the mask is what
    carries the level into the views (:func:`lf_flame.tomo.solvers.reconstruct` leaves
    them out of the fit).

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
        The raw image as read, before dark subtraction (clipping happens in the sensor).
    calibration : GridCalibration
    saturation : float or None
        The sensor's clipping level in the raw image's units (1.0 for the simulator's
        images; ``2**bits - 1`` for integer counts); None: no level (only ``defects``).
    n_views, bin_views, resample : int or None, int, bool
        As :func:`decode` (a binned sample is clipped when any of its pixels is).
    defects : ndarray of bool of the raw image's shape, or None
        Pixels whose samples are left out as the clipped ones are (defective pixels,
        :func:`lf_flame.real.defects.capture_defects`).

    Returns
    -------
    clipped : ndarray of bool, the shape of :func:`decode`'s views (N, N, R, C)
        Hexagonal grids resampled: a square-lattice sample is clipped when any of the three
        samples it is interpolated from is (:func:`hex_to_square`).

    Raises
    ------
    ValueError
        A raw image of another shape, NaN or inf, a level that is not a positive finite
        number, ``n_views`` out of range.
    """
    calibration.validate()
    img = _image("raw image", raw, calibration.sensor_shape)
    if saturation is None and defects is None:
        raise ValueError("give a saturation level, defects, or both")
    if saturation is not None and (isinstance(saturation, bool) or
                                   not isinstance(saturation, (int, float, np.floating)) or
                                   not (math.isfinite(saturation) and saturation > 0)):
        raise ValueError(f"saturation must be a positive finite level (raw units). Received: {saturation!r}")
    bad = np.zeros(img.shape, bool) if saturation is None else img >= saturation
    if defects is not None:
        if np.shape(defects) != img.shape:
            raise ValueError(f"defects of shape {np.shape(defects)} are not the raw image's {img.shape}")
        bad |= np.asarray(defects, bool)
    n, k = _view_count(calibration, n_views, bin_views), int(bin_views)
    if not bad.any():                      # no sample is (most frames of a well exposed recording): none sampled
        return np.zeros(views_shape(calibration, n, k) if resample else (n, n, calibration.n_rows,
                                                                          calibration.n_cols), bool)
    hit = _bin(_sample(bad.astype(np.float64), view_positions(calibration, n * k)), k)
    if calibration.layout == "hex" and resample:
        hit = hex_to_square(hit)
    return np.ascontiguousarray(hit > 1e-6)
