"""Where a sensor clips, found in the image, and how much of a capture clipped.

A sensor clips at one value, so a clipped image's pixels pile up at its largest value (:func:`clipping_pile`),
whatever the file's type and scaling; without a pile the level follows from the image's range
(:func:`auto_saturation`). Every reader takes the level from here (:mod:`.lightfield`, decoding on the fly,
``lf-flame decode``, each frame of a recording), and the share of the lit pixels at or above it
(:func:`clipped_share`) says when a capture is over-exposed (:data:`CLIPPED_WARN`).
"""
from __future__ import annotations

import numpy as np

#: A sensor clips at one level, so a clipped image's pixels pile up at its largest value: at least this many
#: pixels hold exactly that value ...
PILE_MIN_PIXELS = 8
#: ... and this many times as many as hold the next value below it (an image that does not clip has few pixels
#: at its largest value, about as many as at the next).
PILE_RATIO = 4
#: ... and stands at least this many of the image's quantisation steps (the least gap between two of its values) above
#: zero: a dim image of an even field (a blackbody's) quantised to a few counts piles up at its top count too, 10 steps
#: up (a new user's 12-bit furnace images at 10 counts of 4095 were taken as 79 % clipped and the advice was a shorter
#: exposure), where a clipping sensor's pile stands hundreds of steps up (8 bits: 255).
PILE_MIN_STEPS = 32
#: The quantisation step is read from at most this many of the image's values (evenly strided): enough to hold an
#: image's neighbouring levels, and a few milliseconds where a pile is found (a clipped recording: every frame).
STEP_SAMPLES = 65_536


def clipping_pile(raw: np.ndarray) -> float | None:
    """The level where a raw image's pixels pile up at its largest value (a sensor clips there), or None.

    Such a pile marks the clipping level whatever the file's type: a 12-bit sensor's counts
    stored in 16 bits (clipping at 4095, or at 65520 when the counts are shifted to the top
    bits), a sensor whose full well is reached below its converter's top, an image scaled
    to [0, 1] by its type's range.

    Parameters
    ----------
    raw : ndarray
        The raw image (any shape), as read.

    Returns
    -------
    float or None
        The image's largest value where at least :data:`PILE_MIN_PIXELS` pixels hold exactly
        it and :data:`PILE_RATIO` times as many as hold the next value below, at least :data:`PILE_MIN_STEPS`
        quantisation steps above zero; None otherwise (no pile, an image of one value, none above 0, or a dim
        image quantised to a few steps).
    """
    from ._clipping_kernels import top_two
    flat = np.ravel(np.asarray(raw), order="K")
    top, n_top, _, n_next = top_two(flat)                  # one pass (a view where it can)
    if n_top < PILE_MIN_PIXELS or top <= 0 or n_next == 0 or n_top < PILE_RATIO * n_next:
        return None
    values = np.unique(flat[::max(1, flat.size // STEP_SAMPLES)])
    values = values[np.isfinite(values)]
    step = float(np.diff(values).min()) if values.size > 1 else float(top)
    return float(top) if top >= PILE_MIN_STEPS * step else None


def auto_saturation(raw: np.ndarray) -> float:
    """The clipping level of a raw image whose level is not given: where its pixels pile up at its
    largest value (:func:`clipping_pile`), else 1.0 for images whose values are at most 1 (the
    simulator's; integer files scaled by their type's range), else the smallest ``2**bits - 1``
    (bits 8, 10, 12, 14, 16) at or above its maximum (integer counts read unscaled,
    :func:`lf_flame.real.images.load_image`).

    Raises
    ------
    ValueError
        An image past 16-bit counts with no pile at its top.
    """
    pile = clipping_pile(raw)
    if pile is not None:
        return pile
    top = float(np.max(raw))
    if top <= 1.0:
        return 1.0
    for bits in (8, 10, 12, 14, 16):
        if top <= 2 ** bits - 1:
            return float(2 ** bits - 1)
    raise ValueError(f"the raw image reaches {top:g}, past 16-bit counts: give its clipping level")


#: A pixel is lit above this share of the clipping level (:func:`clipped_share`).
LIT_SHARE = 0.05
#: Clipped pixels more than this share of the lit ones (above :data:`LIT_SHARE` of the clipping level): the
#: capture is over-exposed, and ``decode``, ``reconstruct`` and ``sequence`` warn
#: (:func:`lf_flame.cli.real.overexposure_warning`).
#: On six scenes of the paper's camera (``make clipping``, results/clipping.md) 0.6-2.9 % clipped left the flames'
#: emission within 0.6 points (median per scene) of the same scenes below clipping, and 6.2 % (one scene) too; 9.7-27 %
#: left it 8.7-30 % off (worst flame 38 %), against 2-6 % (worst 11 %) below clipping.
#: ``experiments/fourier_solver.py``'s overlap render, 5.2 % clipped, is solved to 2 %.
CLIPPED_WARN = 0.08


def clipped_share(raw, level: float | None) -> float:
    """The clipped pixels' share of the lit ones: pixels at or above ``level`` over those at or above
    :data:`LIT_SHARE` of it (the over-exposure that ``lf-flame reconstruct`` warns of).

    Parameters
    ----------
    raw : ndarray
        A raw image, or a perfect grid's views (the same pixels), in ``level``'s units.
    level : float or None
        The clipping level; None: no level (0).

    Returns
    -------
    float
        In [0, 1]; 0 with no lit pixel.
    """
    if level is None:
        return 0.0
    a = np.asarray(raw)
    lit = int(np.count_nonzero(a >= LIT_SHARE * level))
    return int(np.count_nonzero(a >= level)) / lit if lit else 0.0


def found_level(raw) -> float | None:
    """A raw image's clipping level found in it (:func:`auto_saturation`); None past 16-bit
    counts with no pile at its top (no level known).

    Parameters
    ----------
    raw : ndarray
        A raw image or its views (the same pixels' values), any shape.

    Returns
    -------
    float or None
    """
    try:
        return auto_saturation(raw)
    except ValueError:
        return None
