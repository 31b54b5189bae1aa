"""Real cameras, decoding's geometry: where each view sample lies on the sensor, with a lenslet-grid calibration
(:mod:`lf_flame.real.calibration`).

:func:`view_positions` places view ``(u, v)`` of lenslet ``(r, c)`` about the lenslet's calibrated centre along
the grid's rotated axes; :func:`max_views` and :func:`views_shape` give how many views a lenslet image holds and
the decoded views' shape, :func:`auto_bin` the pixels per view sample of a many-view camera, :func:`hex_to_square`
a hexagonal grid's views on a square lattice, and :func:`interpolation_phases` and :func:`sample_offsets` where
the samples fall between pixels, which the exact operator of decoded views models. :mod:`lf_flame.real.decoding`
samples the images there.

Pixel coordinates and the grid rotation are those of :mod:`lf_flame.real.calibration`.
"""
from __future__ import annotations

import math

import numpy as np

from ..optics.camera import views_for_pitch
from .calibration import GridCalibration
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
    """Where each decoded sample falls between the pixels :func:`~lf_flame.real.decoding.decode` interpolates it from.

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
        As :func:`~lf_flame.real.decoding.decode`.

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
    """The shape (N, N, R, C) of :func:`~lf_flame.real.decoding.decode`'s views (a hexagonal grid's on the square lattice),
    refused as :func:`~lf_flame.real.decoding.decode` refuses ``n_views`` and ``bin_views``."""
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
    """:func:`~lf_flame.real.decoding.decode`'s (or :func:`~lf_flame.real.decoding.clipped_samples`') output with ``resample=False`` as it is with
    resampling: a hexagonal grid's views (a boolean mask: any of its three samples) on the square
    grid (:func:`hex_to_square`), a square grid's as they are."""
    if calibration.layout != "hex":
        return a
    if a.dtype == bool:
        return np.ascontiguousarray(hex_to_square(a.astype(np.float32)) > 1e-6)
    return np.ascontiguousarray(hex_to_square(a))


def max_views(calibration) -> int:
    """Views per axis a lenslet image holds: ``floor(pitch_px + PITCH_SNAP_PX)``
    (:func:`lf_flame.optics.camera.views_for_pitch`).

    Parameters
    ----------
    calibration : GridCalibration

    Returns
    -------
    int
        One pixel apart along each axis: 10 for a 10.57 px pitch, 15 for a calibrated 14.9997.
    """
    return views_for_pitch(calibration.pitch_px)




def _view_count(calibration: GridCalibration, n_views, bin_views=1) -> int:
    """Views per axis (default: as many ``bin_views``-pixel views as the lenslet image holds), refused as
    :func:`~lf_flame.real.decoding.decode` says."""
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


def sample_offsets(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """Where the pixel :func:`~lf_flame.real.decoding.decode_colour` reads for each view sample lies from the sample's place.

    The pixel's centre less the view's position (:func:`view_positions`), turned into the grid's
    axes and in view steps (one pixel: :func:`~lf_flame.real.decoding.decode`'s view step), each within about half a
    step: what the exact operator models for such samples
    (:class:`lf_flame.tomo.exact.ExactOperator`'s ``sample_offsets``). On a grid whose pitch is
    not a whole number of pixels it runs through every value from lenslet to lenslet; its
    effect on a sample grows with the plane's slope (a point at ``s`` lenslets per view step is
    seen ``s`` times the offset lenslets away).

    Parameters
    ----------
    calibration : GridCalibration
        Square or hexagonal (whose samples :func:`~lf_flame.real.decoding.decode_colour` keeps on its lattice, as here).
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


def _nearest_pixels(calibration: GridCalibration, n_views: int) -> np.ndarray:
    """The pixel holding each view sample's position (row, column; (N, N, R, C, 2) int64): pixel
    ``(i, j)`` spans ``[i, i + 1) x [j, j + 1)``."""
    return np.floor(view_positions(calibration, n_views)).astype(np.int64)
