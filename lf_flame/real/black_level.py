"""What a capture's pixels read where no light reaches them: a black level (or stray light) not subtracted.

A sensor adds an offset to every pixel, its black level (tens of counts of a 10- to 16-bit sensor), and a dark
frame taken with the lens capped holds it. Left in, it is light that no plane of emission explains, and decoding,
which divides by the white image (which carries its own), bends the dim samples' values. Where the white image is
dark (between the lenslet images, beyond the main lens's image) a capture without it reads about zero:
:func:`unlit_level` reads it there, and the commands warn above :data:`BLACK_LEVEL_SHARE`
(:func:`lf_flame.cli._io.black_level_warning`).

On napari-LF's three microscopy captures (``make real-data``; their dark frames' median 107, 101 and 3 counts) the
unlit pixels read 3.7, 2.0 and 1.8 % of the capture's bright pixels without the dark frame, and -2.3, 0.9 and
0.5 % with it subtracted; a simulated capture reads 0.
"""
from __future__ import annotations

import numpy as np

#: A pixel is unlit where the white image reads within this share of its range (1st to 99th percentile) above its
#: 1st percentile.
UNLIT_SHARE = 0.05
#: Fewer unlit pixels than this, or a white image whose range is less than :data:`MIN_WHITE_CONTRAST` of its 99th
#: percentile (lit everywhere: no gaps between lenslet images): no level is read.
MIN_UNLIT_PIXELS = 100
MIN_WHITE_CONTRAST = 0.5
#: Pixels read per axis: every this many (:func:`unlit_level`).
SUBSAMPLE = 3
#: The unlit pixels' median above this share of a capture's bright pixels (its 99.9th percentile): a black level
#: or stray light not subtracted.
BLACK_LEVEL_SHARE = 0.01


def unlit_level(raw, white, dark=None) -> float | None:
    """The median of a capture's unlit pixels (where its white image is dark) over its bright pixels' level.

    Every :data:`SUBSAMPLE`-th pixel per axis is read.

    Parameters
    ----------
    raw, white : ndarray of shape (H, W)
        The capture and its white image, as read (:func:`lf_flame.real.images.load_image`).
    dark : ndarray of shape (H, W) or None
        The dark frame decoding subtracts from both.

    Returns
    -------
    float or None
        ``median(raw - dark over the unlit pixels) / percentile(raw - dark, 99.9)``: about 0 for a capture
        without a black level (negative where the dark frame reads more than the capture); None without a white
        image, with fewer than :data:`MIN_UNLIT_PIXELS` unlit pixels or a white image of too little contrast
        (:data:`MIN_WHITE_CONTRAST`), a capture of another shape than its white image, or no bright pixel.
    """
    if white is None:
        return None
    r, w = np.asarray(raw), np.asarray(white)
    if w.ndim != 2 or r.shape != w.shape:
        return None
    # every third pixel per axis (a ninth of the time, 4 ms on a megapixel; 3 is prime to a colour mosaic's period)
    r, w = r[::SUBSAMPLE, ::SUBSAMPLE].astype(np.float64), w[::SUBSAMPLE, ::SUBSAMPLE].astype(np.float64)
    if dark is not None:
        d = np.asarray(dark)[::SUBSAMPLE, ::SUBSAMPLE]
        r, w = r - d, w - d
    floor, top = np.percentile(w, [1, 99])
    if not top - floor >= MIN_WHITE_CONTRAST * top > 0:
        return None
    unlit = w <= floor + UNLIT_SHARE * (top - floor)
    bright = float(np.percentile(r, 99.9))
    if np.count_nonzero(unlit) < MIN_UNLIT_PIXELS or not bright > 0:
        return None
    return float(np.median(r[unlit])) / bright


#: A light field whose central views vary across their lenslets by less than this share of their level (the median
#: over the 3 x 3 views about the centre of (95th - 5th percentile) / 95th percentile, :func:`view_spread`) holds no
#: structure: a uniform frame (a glare, a blank or washed-out capture), no flame. A simulated flame's views read 1
#: (their 5th percentile dark); a frame set to one value throughout reads 0, simulated white images 0.008-0.013,
#: flames under a haze of 0.3 of their peak 0.76 (a recording's frame of glare had been measured as flames 5.2 mm tall
#: on three of four planes, its intensities 11 times the others' in the spectra).
FLAT_SPREAD = 0.1


def view_spread(views) -> float | None:
    """How much a light field's central views vary across their lenslets, for their level: the median over the 3 x 3
    views about the centre (always inside the aperture's image) of (95th - 5th percentile) / 95th percentile of each
    view's samples (every second lenslet per axis: about 1 ms a frame of the paper's camera, which every frame of a
    recording pays). Below :data:`FLAT_SPREAD` the light field holds no structure.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)

    Returns
    -------
    float or None
        0 for views each uniform, about 1 for a flame on a dark background; None for central views without light or
        not finite.
    """
    v = np.asarray(views)
    if v.ndim != 4:
        return None
    c = v.shape[0] // 2
    v = np.asarray(v[max(c - 1, 0):c + 2, max(c - 1, 0):c + 2, ::2, ::2], np.float64)
    v = v.reshape(v.shape[0] * v.shape[1], -1)
    if not np.all(np.isfinite(v)):
        return None
    hi, lo = np.percentile(v, [95, 5], axis=1)
    if not hi.max() > 0:
        return None
    lit = hi > 0
    return float(np.median((hi[lit] - lo[lit]) / hi[lit]))


#: Samples below minus this share of a light field's bright level (its 99.9th percentile) are warned of
#: (:func:`negative_note`): a capture's noise after its dark frame reads a few hundredths of its level below zero at
#: most; far below are a dark frame brighter than the capture, or corrupt pixels (a user's block of pixels at -1 had
#: been decoded into views at -0.5, and the residual's search took it for three flames).
NEGATIVE_SHARE = 0.1


def negative_note(views, source: str) -> str | None:
    """Where a light field's samples (views or a raw image, dark-subtracted) read below minus :data:`NEGATIVE_SHARE`
    of their 99.9th percentile: one line saying how many and what it means, else None.

    Parameters
    ----------
    views : ndarray
        The samples (any shape).
    source : str
        The file, named in the line.

    Returns
    -------
    str or None
    """
    v = np.asarray(views)
    if not v.size or not float(v.min()) < 0:      # no sample below zero: no percentile taken (every read pays this)
        return None
    level = float(np.percentile(v, 99.9))
    n = int(np.count_nonzero(v < -NEGATIVE_SHARE * level)) if level > 0 else 0
    if not n:
        return None
    return (f"{source}: {n} samples read below -{NEGATIVE_SHARE:g} of its level (down to {float(v.min()):.3g} "
            f"against {level:.3g}): a dark frame brighter than the capture, or corrupt pixels; no emission explains "
            "them (the fit treats them as data)")
