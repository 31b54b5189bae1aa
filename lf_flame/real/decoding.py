"""Real cameras, stage 2: decoding of raw images into sub-aperture views with a lenslet-grid
calibration (:mod:`lf_flame.real.calibration`, stage 1).

:func:`decode` resamples every lenslet image about its calibrated centre (the fitted
lattice) into sub-aperture views (N, N, R, C), after dark subtraction and white-image
(vignetting) normalisation, with the axis order and units of :mod:`lf_flame.refocus.shift_and_sum`
(view step: one pixel; slopes: lenslets per view step); :func:`decode_colour` does so for a
colour (Bayer) capture, its channels apart. Each first checks that the raw image shows the
calibration's grid (:func:`lf_flame.real.grid_check.check_grid`). Where the samples lie (positions,
view counts, binning, the hexagonal lattice) is :mod:`lf_flame.real.view_grid`; :mod:`lf_flame.real.views_file`
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
from .view_grid import _bin, _nearest_pixels, _view_count, auto_bin, hex_to_square, view_positions, views_shape


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


def _prepared(raw, calibration: GridCalibration, dark, n_views, check: bool, bin_views: int = 1):
    """The decoders' raw image, dark subtracted and checked against the calibration's grid
    (:func:`check_grid`), the dark frame (or None) and the views per axis (:func:`~lf_flame.real.view_grid._view_count`),
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
    :func:`~lf_flame.real.view_grid.view_positions` about its calibrated centre, and divided by the white image
    resampled the same way (vignetting and cos⁴ normalisation; Dansereau et al. 2013).
    With ``bin_views`` = k each view sample sums k x k such samples, of the raw and of the white
    image alike, before the division (the views of a camera with k-times larger pixels,
    :func:`lf_flame.real.own_camera.views_camera`).
    A hexagonal grid is then resampled onto a square one (:func:`~lf_flame.real.view_grid.hex_to_square`) unless
    ``resample`` is False.

    Parameters
    ----------
    raw : ndarray of shape ``calibration.sensor_shape``
    calibration : GridCalibration
    white, dark : ndarray of the same shape, or None
        White image and dark frame (the dark frame is subtracted from both).
    n_views : int or None
        ``N``, views per axis, ``bin_views`` pixels apart; default and most
        ``max_views // bin_views`` (:func:`~lf_flame.real.view_grid.max_views`).
    bin_views : int
        Pixels per view sample and axis, >= 1 (:func:`~lf_flame.real.view_grid.auto_bin` chooses one for many-view cameras).
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
        and :func:`~lf_flame.refocus.slope_search.find_sharpest_slope` apply unchanged. With a white
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


#: A monochrome capture whose views decoded with a white image read at most this share of that image's light is
#: warned of (:func:`dim_against_white`): an 8-bit capture beside a 16-bit white image reads 1/257 of it.
DIM_AGAINST_WHITE = 1e-2


def dim_against_white(views) -> str | None:
    """Where a monochrome capture's views, decoded with a white image (its radiance ratio, :func:`decode`), read at
    most :data:`DIM_AGAINST_WHITE` of that image's light at their brightest: what to say (the files are likely in
    different units: a [0, 1] array beside a white image in 16-bit counts reads 1/65535 of it, an 8-bit capture
    beside a 16-bit white image 1/257, and its planes come out that many times too small; beside a dark frame in
    counts it reads nothing at all); else None. A flame that dim against its white target is near the sensor's
    noise anyway.

    Parameters
    ----------
    views : ndarray
        The decoded views (any shape), relative to the white image.

    Returns
    -------
    str or None
    """
    top = float(np.max(views)) if np.size(views) else 0.0
    if not top <= DIM_AGAINST_WHITE:
        return None
    return (f"its brightest view sample reads {top:.3g} of its white image's light: are the capture and the white "
            "image in the same units? (an array in [0, 1] beside a white image in 16-bit counts reads 1/65535 of it, "
            "an 8-bit capture beside a 16-bit white image 1/257, and its planes come out that much too small): give "
            "both as the camera saved them")


#: A capture whose lit pixels (above a tenth of its 99.9th percentile) fall where its white image is dark (under 5 %
#: of its 99th percentile) more than this share of them is warned of (:func:`off_grid_note`): the test suite's
#: decoded captures of every camera (square, rotated, hexagonal, colour) put at most 1.1 % of them there; a user's
#: capture transposed, turned 90° or cropped elsewhere 24-38 %, one shifted by half a lenslet 17 %.
OFF_GRID_SHARE = 0.1


def off_grid_note(raw: np.ndarray, white: np.ndarray, dark: np.ndarray | None = None) -> str | None:
    """Where a capture's light falls between its white image's lenslet images: what to say, else None.

    A lenslet image is the main lens's aperture: whatever the scene, a capture lights the pixels its white image
    lights. Where many of its lit pixels lie where the white image is dark, the two do not show the same grid at the
    same place: the capture is transposed or turned, or cropped from another part of the sensor than the white image
    (decode's grid check, a power spectrum, sees neither the grid's place nor a small turn), and its views mix
    neighbouring lenslets. A white image without dark gaps (under 5 % of its pixels dark) cannot tell: None.

    Parameters
    ----------
    raw, white : ndarray of shape (H, W)
        The capture and its white image, in any units.
    dark : ndarray of shape (H, W) or None
        The dark frame, subtracted from both.

    Returns
    -------
    str or None
    """
    r, w = np.asarray(raw, np.float64), np.asarray(white, np.float64)
    if dark is not None:
        r, w = r - dark, w - dark
    if r.shape != w.shape:
        return None
    gaps = w < 0.05 * np.percentile(w, 99)
    top = np.percentile(r, 99.9)
    if gaps.mean() < 0.05 or not top > 0:
        return None
    lit = r > 0.1 * top
    share = float(np.count_nonzero(lit & gaps) / max(np.count_nonzero(lit), 1))
    if share <= OFF_GRID_SHARE:
        return None
    return (f"{100 * share:.0f} % of its lit pixels lie where its white image is dark, between the lenslet images: "
            "is the capture transposed or turned, or cropped from another part of the sensor than the white image? "
            "Its views then mix neighbouring lenslets")


def white_samples(calibration: GridCalibration, white: np.ndarray, dark: np.ndarray | None = None, *,
                  n_views: int | None = None, bin_views: int = 1, min_white: float = 0.05, sensor=None) -> np.ndarray:
    """The white image as :func:`decode` divides a capture's views by it: the dark frame subtracted, sampled
    bilinearly at :func:`~lf_flame.real.view_grid.view_positions` and binned as the capture, and 0 where it is below ``min_white`` of
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
    _check_centred(wv)
    return np.where(wv > floor, wv, 0.0)


#: The white image's brightest view (its mean over the lenslets) may lie this share of the views per axis from the
#: central one, at least 1.5 views: the aperture's image is centred under each lenslet. A calibration whose grid lies
#: off the lenslet images (its origin edited by 5 px on the example camera's 10.57 px pitch: views 55 % off, six
#: planes found for four flames) puts it near the views' edge.
WHITE_CENTRE_SHARE = 0.25
#: ... and only where that view is brighter than the central ones by more than this share: the views' means are
#: flat-topped, and a dust spot on a white image moved the brightest of them 2.8 views out on a hexagonal grid (the
#: brightest within 0.15 % of the central ones on five cameras' white images, clean or dusty), where a grid 0.47 of
#: a pitch off the lenslet images makes it 5-96 % brighter.
WHITE_CENTRE_EXCESS = 0.02


def _check_centred(white_views: np.ndarray) -> None:
    """Refuse white-image views (N, N, R, C) whose brightest view lies more than :data:`WHITE_CENTRE_SHARE` of N
    (and 1.5 views) from the central one and is brighter than the central ones by :data:`WHITE_CENTRE_EXCESS`: the
    calibration's lenslet grid is off the white image's lenslet images."""
    m = white_views.mean(axis=(2, 3))
    n = m.shape[0]
    i, j = np.unravel_index(int(np.argmax(m)), m.shape)
    off = math.hypot(i - (n - 1) / 2, j - (n - 1) / 2)
    centre = float(m[(n - 1) // 2:n // 2 + 1, (n - 1) // 2:n // 2 + 1].mean())
    if off > max(1.5, WHITE_CENTRE_SHARE * n) and m[i, j] > (1 + WHITE_CENTRE_EXCESS) * centre:
        raise ValueError(f"the white image's brightest view is ({i}, {j}) of {n} x {n}, {off:.1f} views from the "
                         "central one: the calibration's lenslet grid lies off the lenslet images (its origin edited, "
                         "or the grid moved since it was calibrated: calibrate again with this set-up's white image)")


#: A lenslet of the white image holding less than this share of the light of the 5 x 5 lenslets about it (their
#: median) is dark: dust or a defect (five cameras' simulated white images: at least 0.986 of it; a dust spot
#: dimming the sensor to 0.4: 0.40-0.60).
WHITE_DARK_LENSLET = 0.8


def dark_lenslets(white_views: np.ndarray) -> np.ndarray:
    """The white image's dark lenslets: those holding less than :data:`WHITE_DARK_LENSLET` of the median light of the
    5 x 5 lenslets about them, at least 2 lenslets in from the rim of where the white image is lit.

    Parameters
    ----------
    white_views : ndarray of shape (N, N, R, C)
        The white image as decoding divides by it (:func:`white_samples`).

    Returns
    -------
    ndarray of bool, shape (R, C)
    """
    from scipy import ndimage
    light = np.asarray(white_views, np.float64).sum(axis=(0, 1))
    inner = ndimage.binary_erosion(light > 0.2 * np.percentile(light, 90), iterations=2)
    return inner & (light < WHITE_DARK_LENSLET * ndimage.median_filter(light, size=5, mode="nearest"))


def decode_colour(raw: np.ndarray, calibration: GridCalibration, sensor, white: np.ndarray | None = None,
                  dark: np.ndarray | None = None, *, n_views: int | None = None, min_white: float = 0.05,
                  check: bool = True, white_views: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Decode a colour (Bayer) raw image into sub-aperture views that keep its channels apart.

    :func:`decode`'s bilinear resampling blends four pixels, which under a colour filter array
    are of two or three channels. Here each view sample is the one pixel nearest its position
    (:func:`~lf_flame.real.view_grid.view_positions`) and carries that pixel's channel: the channel map of the views, on
    which each channel is solved from its own samples
    (:func:`lf_flame.temperature.channels.channel_emission`), as on a perfect grid. The price is
    the position: up to half a pixel (half a view step) from where the decoded camera puts the
    sample, which :func:`~lf_flame.real.view_grid.sample_offsets` gives and the exact operator models
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


def decode_capture_views(raw: np.ndarray, calibration: GridCalibration, white: np.ndarray | None = None,
                         dark: np.ndarray | None = None, sensor=None, *, n_views: int | None = None,
                         bin_views: int | None = None, camera_id: str | None = None, check: bool = True,
                         white_views: np.ndarray | None = None):
    """A capture decoded as ``lf-flame decode`` decodes it: :func:`decode` (its bilinear samples, binned by
    ``bin_views``, None: :func:`~lf_flame.real.view_grid.auto_bin`), or for a colour ``sensor``'s capture :func:`decode_colour` (each sample
    its nearest pixel, its channel with it, one pixel per sample); a hexagonal grid's views on its own lattice.
    ``check``, ``white_views``: as :func:`decode` (a recording's later frames unchecked, its first checked; its
    white image's samples computed once: :func:`white_samples`, with the ``sensor`` of a colour capture).

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32
        On the calibration's grid (``resample=False``: :func:`~lf_flame.real.view_grid.on_square_grid` puts a hexagonal grid's on the
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
        samples it is interpolated from is (:func:`~lf_flame.real.view_grid.hex_to_square`).

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
