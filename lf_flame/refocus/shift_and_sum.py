"""Sub-aperture views and refocusing (shift-and-sum, Fourier slice); the slope search is :mod:`.slope_search`.

Convention (the paper's): a point of the plane at slope ``s`` appears at lenslet
``x0 + s (u - c)`` in sub-aperture view ``u``, ``c = (N - 1) / 2``; refocusing at ``s``
samples view ``(u, v)`` at ``(r + s (u - c), col + s (v - c))`` and averages (the
paper's Eq. 2, Ng 2005 Eq. 4.1, with the 1/α magnification dropped as is usual for
sub-aperture shift-and-sum). Slopes are in lenslets per view step; slope <-> depth (mm)
is :meth:`lf_flame.optics.camera.PlenopticCamera.slope_for_depth` and ``depth_for_slope``.
"""
from __future__ import annotations

import math

import numba
import numpy as np
import scipy.fft

from . import _kernels as _refocus_kernels


_EXPONENT_BITS = {np.dtype(np.float32): (np.uint32, 0x7F800000), np.dtype(np.float64): (np.uint64, 0x7FF0000000000000)}

#: Views whose largest magnitude passes this are refocused by the Fourier slice scaled down by a power of two (exact:
#: no bit of the result changes) and scaled back: its float32 spectrum sums every sample of the light field, and
#: views of 1e34 had overflowed it into inf (1e37: NaN), written as the refocused planes.
FOURIER_SCALE_ABOVE = 2.0 ** 64
#: The largest float32, in which views and refocused planes are held.
FLOAT32_MAX = float(np.finfo(np.float32).max)


def _overflow(what: str, peak: float) -> ValueError:
    """The refusal of values past :data:`FLOAT32_MAX`, naming the way out."""
    return ValueError(f"{what} overflows float32 (its values reach {peak:.3g}; float32, in which views and refocused "
                      f"planes are held, ends at {FLOAT32_MAX:.3g}): scale the data down, e.g. divide it by its "
                      "largest value")


def _check_finite(name, a):
    """Raise ValueError if the array ``a`` holds NaN or inf (large float32/float64 arrays:
    one parallel read; below 2^16 elements NumPy, as a parallel launch costs more)."""
    a = np.asarray(a)
    if a.dtype in _EXPONENT_BITS and a.size >= 1 << 16:
        utype, exponent = _EXPONENT_BITS[a.dtype]
        bits = np.ascontiguousarray(a).reshape(-1).view(utype)
        finite = _refocus_kernels.max_exponent(bits, utype(exponent)) != exponent
    else:
        finite = bool(np.all(np.isfinite(a)))
    if not finite:
        raise ValueError(f"{name} contains NaN or inf")


def raw_to_views(raw: np.ndarray, pixels_per_lenslet: int) -> np.ndarray:
    """Split a raw plenoptic image into sub-aperture views.

    Parameters
    ----------
    raw : ndarray of shape (R * N, C * N)
        Raw sensor image, rows and columns.
    pixels_per_lenslet : int
        ``N``.

    Returns
    -------
    views : ndarray of shape (N, N, R, C), float32, C-contiguous
        ``views[u, v, r, c] = raw[r * N + u, c * N + v]``: (u, v) the pixel under
        each lenslet (view row, view column), (r, c) the lenslet.

    Raises
    ------
    ValueError
        If the raw shape is not a multiple of N, it holds NaN or inf, or values past float32's largest (a float64
        image's: its views would be inf).
    """
    raw = np.asarray(raw)
    n = int(pixels_per_lenslet)
    if raw.ndim != 2 or n < 1 or raw.shape[0] % n or raw.shape[1] % n:
        raise ValueError(f"raw image of shape {raw.shape} is not a grid of {n}x{n}-pixel lenslet images")
    _check_finite("raw image", raw)
    R, C = raw.shape[0] // n, raw.shape[1] // n
    with np.errstate(over="ignore"):        # a float64 image past float32's largest: refused below
        views = np.ascontiguousarray(raw.reshape(R, n, C, n).transpose(1, 3, 0, 2), dtype=np.float32)
    if raw.dtype.kind == "f" and raw.dtype.itemsize > 4:      # finite before the cast: inf after it is an overflow
        try:
            _check_finite("views", views)
        except ValueError:
            raise _overflow("the raw image", float(np.max(np.abs(raw)))) from None
    return views


def views_to_raw(views: np.ndarray) -> np.ndarray:
    """Inverse of :func:`raw_to_views`: (N, N, R, C) -> (R * N, C * N); ValueError for another shape."""
    views = np.asarray(views)
    if views.ndim != 4 or views.shape[0] != views.shape[1]:
        raise ValueError(f"views must have shape (N, N, R, C). Received: {views.shape}")
    U, V, R, C = views.shape
    return np.ascontiguousarray(views.transpose(2, 0, 3, 1).reshape(R * U, C * V))


def aperture_mask(n: int, shape: str = "square") -> np.ndarray:
    """Views to use: ``square`` (all N × N) or ``circular`` (inside the inscribed circle).

    Returns
    -------
    mask : ndarray of shape (N, N), bool

    Raises
    ------
    ValueError
        ``n`` not a whole number >= 1, an unknown shape.
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n, the views per axis, must be a whole number >= 1. Received: {n!r}")
    n = int(n)
    if shape == "square":
        return np.ones((n, n), bool)
    if shape == "circular":
        c = (n - 1) / 2
        u = np.arange(n) - c
        return u[:, None] ** 2 + u[None, :] ** 2 <= (n / 2) ** 2
    raise ValueError(f"aperture shape must be 'square' or 'circular'. Received: {shape!r}")


#: The share of a view sample's footprint that must lie inside the main lens's aperture image for the view to take
#: part in a depth search (:func:`lit_views`). A partly lit sample's light comes from its lit part, nearer the
#: aperture's centre than the view's place: its parallax is smaller than its place says, and the sharpest slope
#: falls short (a new user's camera at f/4, its aperture image 10.3 of its 12.0 px lenslet images: depths found
#: 5-9 % nearer the focal plane, e.g. +45.5 for +50 mm; with this share +49.0). Under the smallest share of the
#: paper camera's inscribed-circle views (0.71) and of the example camera's decoded views (0.65-0.7 at its corners,
#: whose loss split a flame of a noisy recording in two): both keep the inscribed circle's views.
LIT_VIEW_SHARE = 0.65


def lit_views(camera, *, tent: float = 0.0, share: float = LIT_VIEW_SHARE) -> np.ndarray:
    """The views of ``camera`` (its ``pixels_per_lenslet`` per axis) inside the inscribed circle
    (:func:`aperture_mask`) whose sample lies at least ``share`` inside the main lens's aperture image.

    The aperture image behind each lenslet is a disc of radius ``(A / 2) g / (d s)`` view steps about the
    lenslet image's centre (``A`` the aperture's diameter, ``d`` the main lens to lenslet distance, ``g`` the
    lenslets to sensor, ``s`` the pixel; a decoded capture's camera keeps ``g / s``,
    :func:`lf_flame.optics.camera_file.decoded_camera`). A sample's footprint is its pixel, one view step square,
    or a decoded capture's bilinear sample's: its pixels weighed by a tent of half-width ``tent`` view steps, at a
    phase that varies from lenslet to lenslet (:func:`lf_flame.real.decoding.decode`), on average the pixel's box
    spread by the tent (one pixel per view: the quadratic B-spline). Its share inside the disc is taken on a 64-point
    grid per step.

    Parameters
    ----------
    camera : PlenopticCamera
        The views' camera (for decoded views, :func:`lf_flame.real.own_camera.views_camera`).
    tent : float
        The bilinear interpolation's half-width in view steps, >= 0: a decoded capture's ``1 / k`` for ``k x k``
        pixels summed per view sample (:func:`lf_flame.real.decoding.decode`'s ``bin_views``); 0: raw pixels (a
        perfect grid's views, a colour capture's nearest pixels).
    share : float
        In (0, 1].

    Returns
    -------
    ndarray of shape (N, N), bool
        For a camera whose aperture image fills its lenslet images, the inscribed circle's views.

    Raises
    ------
    ValueError
        ``share`` outside (0, 1], ``tent`` negative or not finite.
    """
    if not 0 < share <= 1 or not (math.isfinite(tent) and tent >= 0):
        raise ValueError(f"share must be in (0, 1] and tent finite and >= 0. Received: share={share!r}, tent={tent!r}")
    n = int(camera.pixels_per_lenslet)
    rho = camera.aperture_diameter_mm / 2 * camera.sensor_distance_mm / (camera.mla_distance_mm * camera.pixel_pitch_mm)
    step = 1.0 / 64
    half = 0.5 + tent
    t = np.arange(-half + step / 2, half, step)           # the footprint's points along one axis (view steps)
    w = np.ones_like(t)
    if tent > 0:                                           # the pixel's box spread by the tent
        tau = np.arange(-tent + step / 2, tent, step)
        w = (np.abs(t[:, None] - tau[None, :]) <= 0.5) @ (1.0 - np.abs(tau) / tent)
    u = _view_offsets(n)
    y = (u[:, None] + t[None, :]) ** 2                  # (N, T): squared offsets of the footprint's points, per axis
    inside = (y[:, None, :, None] + y[None, :, None, :] <= rho ** 2)          # (N, N, T, T)
    lit = np.einsum("uvab,a,b->uv", inside, w, w) / w.sum() ** 2
    return aperture_mask(n, "circular") & (lit >= share)


INTERPOLATIONS = ("bilinear", "nearest")
METHODS = ("shift-sum", "fourier")


def _view_offsets(n: int) -> np.ndarray:
    """``u - (N - 1) / 2`` for u = 0 .. N - 1: view positions about the central view."""
    return np.arange(n) - (n - 1) / 2


def _margin(max_slope: float, n: int) -> int:
    """Lenslets of padding that cover the largest view shift ``max_slope (N - 1) / 2``, plus 2."""
    return int(np.ceil(max_slope * (n - 1) / 2)) + 2


def _check_stack_args(views, slopes, mask, check_finite):
    views = np.ascontiguousarray(views, dtype=np.float32)
    if views.ndim != 4 or views.shape[0] != views.shape[1]:
        raise ValueError(f"views must have shape (N, N, R, C). Received: {views.shape}")
    slopes = np.atleast_1d(np.asarray(slopes, dtype=np.float64))
    if slopes.ndim != 1 or slopes.size == 0:
        raise ValueError(f"slopes must be a non-empty 1-D sequence. Received shape {slopes.shape}")
    _check_finite("slopes", slopes)
    if check_finite:
        _check_finite("views", views)
    n = views.shape[0]
    mask = aperture_mask(n) if mask is None else np.asarray(mask, bool)
    if mask.shape != (n, n):
        raise ValueError(f"mask must have shape {(n, n)}. Received: {mask.shape}")
    return views, slopes, mask


def focal_stack(views: np.ndarray, slopes, mask: np.ndarray | None = None, *, interpolation: str = "bilinear",
                check_finite: bool = True) -> np.ndarray:
    """Shift-and-sum refocusing at several slopes in one pass over the light field (paper Eq. 2).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        Sub-aperture views (:func:`raw_to_views`), float32 (other types are converted).
    slopes : sequence of float, length S
        Slopes in lenslets per view step (paper's sign: near planes negative).
    mask : ndarray of shape (N, N), bool, optional
        Views to use (:func:`aperture_mask`); default all.
    interpolation : {'bilinear', 'nearest'}
        ``bilinear`` samples each view at ``slope * (u - c)`` exactly; ``nearest`` rounds
        every shift to whole lenslets (the integer path: no interpolation, faster, and
        identical to ``bilinear`` where the shifts are whole, e.g. integer slopes).
    check_finite : bool
        Check that ``views`` holds no NaN or inf (one extra read of the light field;
        pass False for views already checked, as :func:`raw_to_views` does).

    Returns
    -------
    stack : ndarray of shape (S, R, C), float32
        Mean of the shifted views that cover each pixel (borders are not darkened by
        views that shift out of the image; a pixel no view covers is 0).

    Raises
    ------
    ValueError
        NaN/inf in views or slopes, a bad shape, or an unknown interpolation.

    Notes
    -----
    The sums are float32: views so bright that a sum of them passes float32's largest (1e37 over 81 views) are
    refocused once more scaled down by a power of two (exact) and the planes scaled back, where they had been
    refused as views holding NaN or inf.
    """
    views, slopes, mask = _check_stack_args(views, slopes, mask, check_finite)
    if interpolation not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}. Received: {interpolation!r}")
    n, _, R, C = views.shape
    shifts = slopes[:, None] * _view_offsets(n)[None, :]
    if interpolation == "nearest":
        shifts = np.floor(shifts + 0.5)
    out = np.empty((len(slopes), R, C), np.float32)
    rows_per_task = -(-R // numba.get_num_threads())
    if _refocus_kernels.shift_sum_stack(views.reshape(n, n, R * C), R, shifts, shifts, mask, out, rows_per_task):
        return out
    if not check_finite:
        _check_finite("views", views)                   # NaN or inf in the views: said so
    peak = float(np.max(np.abs(views)))                 # finite views: a sum overflowed float32
    k = math.frexp(peak)[1]
    if not _refocus_kernels.shift_sum_stack(np.ldexp(views, -k).reshape(n, n, R * C), R, shifts, shifts, mask, out,
                                            rows_per_task):
        raise _overflow("refocusing the views", peak)
    with np.errstate(over="ignore"):
        out = np.ldexp(out, k)
    if not np.all(np.isfinite(out)):
        raise _overflow("refocusing the views", peak)
    return out


def _band_limited_box(shifts: np.ndarray, length: int, padded: int) -> np.ndarray:
    """(S, N, length): the image support (1 on ``0..length-1``, 0 to ``padded``) shifted by
    ``shifts`` (S, N) with the periodic band-limited interpolation of the Fourier method.

    Its sum over the views is the Fourier method's count of views reaching a pixel, so
    a constant light field stays constant up to the border, as with shift-and-sum.
    """
    box = np.zeros(padded)
    box[:length] = 1.0
    k = np.fft.rfftfreq(padded)
    phase = np.exp(2j * np.pi * k[None, None, :] * shifts[:, :, None])
    return np.fft.irfft(np.fft.rfft(box)[None, None, :] * phase, n=padded, axis=-1)[..., :length]


#: The largest view count (bytes) :func:`_slice_count` keeps: a stack of the paper camera's 121 slopes holds 18 MB.
SLICE_COUNT_KEEP_BYTES = 64 << 20
_SLICE_COUNTS: dict = {}


def _slice_count(n: int, shape: tuple, canvas: tuple, slopes: np.ndarray, mask: np.ndarray):
    """:meth:`FourierSlice.stack`'s count of the views reaching each pixel, (S, R, C) float64 (at least 0.5), and
    where it reaches 0.5 (bool): the same for every light field of one shape, mask and slopes (the depth search
    and its residual's searches refocus at the same slopes), so the last two up to
    :data:`SLICE_COUNT_KEEP_BYTES` are kept, read-only."""
    key = (n, shape, canvas, slopes.tobytes(), mask.tobytes())
    if key in _SLICE_COUNTS:
        return _SLICE_COUNTS[key]
    shifts = slopes[:, None] * _view_offsets(n)[None, :]
    count = np.einsum("sur,uv,svc->src", _band_limited_box(shifts, shape[0], canvas[0]), mask.astype(np.float64),
                      _band_limited_box(shifts, shape[1], canvas[1]), optimize=True)
    reached = count >= 0.5
    count = np.maximum(count, 0.5)
    if count.nbytes + reached.nbytes <= SLICE_COUNT_KEEP_BYTES:
        count.flags.writeable = reached.flags.writeable = False
        while len(_SLICE_COUNTS) >= 2:
            del _SLICE_COUNTS[next(iter(_SLICE_COUNTS))]
        _SLICE_COUNTS[key] = count, reached
    return count, reached


class FourierSlice:
    """Fourier-slice refocusing (Ng 2005, "Fourier slice photography"): the 2-D spectrum
    of the image refocused at slope ``s`` is the slice of the light field's 4-D
    spectrum at angular frequency ``-s`` x spatial frequency.

    The 4-D FFT is computed once (views zero-padded 2x along u and v, and along r and c
    by the largest shift so that no shifted view wraps round); each plane then costs a
    resampling of the spectrum on its slice and one inverse 2-D FFT. The resampling
    kernel is a separable Kaiser-Bessel of 4 taps per angular axis at 2x oversampling
    (Jackson et al. 1991; beta from Beatty et al. 2005), with the views divided
    beforehand by the kernel's Fourier transform (roll-off correction). Each pixel is
    then divided by the number of views that reach it, as in :func:`focal_stack`.
    Interpolation along r and c is therefore band-limited (sinc), not bilinear.
    An even number of views (decoded from lenslet images of any pitch) has view offsets
    ``u - (N - 1)/2`` at half-integers: the views are placed on the whole offsets
    ``u - N/2``, which refocuses the image shifted by ``slope / 2``, and each plane is moved
    back by that shift as a phase ramp on its spectrum (band-limited, exact).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    max_slope : float
        Largest |slope| this object will refocus at (sets the spatial padding), > 0.
    mask : ndarray of shape (N, N), bool, optional

    Raises
    ------
    ValueError
        NaN/inf in views, bad shapes, or ``max_slope`` not positive and finite.

    Notes
    -----
    The spectrum is complex64 and sums every sample of the light field: views brighter than
    :data:`FOURIER_SCALE_ABOVE` are transformed scaled down by a power of two (exact) and each plane is scaled
    back in :meth:`stack`, which refuses a plane that float32 cannot hold.
    """

    KERNEL_WIDTH = 4
    OVERSAMPLE = 2

    def __init__(self, views: np.ndarray, max_slope: float, mask: np.ndarray | None = None):
        views, _, mask = _check_stack_args(views, [0.0], mask, True)
        if not (np.isfinite(max_slope) and max_slope > 0):
            raise ValueError(f"max_slope must be positive and finite. Received: {max_slope}")
        n, _, R, C = views.shape
        self.n, self.shape, self.mask, self.max_slope = n, (R, C), mask, float(max_slope)
        W, alpha = self.KERNEL_WIDTH, self.OVERSAMPLE
        self.M = M = int(2 * np.ceil(alpha * n / 2))
        self.beta = np.pi * np.sqrt((W / alpha) ** 2 * (alpha - 0.5) ** 2 - 0.8)
        # the angular grid's samples: whole view offsets; an even count's offsets are half-integers,
        # taken half a view lower (u - N/2) and the refocused image moved back by slope / 2 in stack()
        self.half = 0.5 * (1 - n % 2)
        pad = _margin(max_slope, n) + int(np.ceil(self.half * max_slope))
        self.R2, self.C2 = scipy.fft.next_fast_len(R + pad), scipy.fft.next_fast_len(C + pad, real=True)
        off = _view_offsets(n) - self.half
        roll = self._kernel_ft(off)
        idx = np.rint(off).astype(np.int64) % M  # view offset u' at index u' mod M
        weight = (mask / (roll[:, None] * roll[None, :])).astype(np.float32)
        # the lit views' spatial spectra (zero-padded to the canvas), placed on the M x M angular grid (the other
        # slots, the unlit views' among them, are 0) with the angular axes last, then their angular DFT along
        # those contiguous axes
        lu, lv = np.nonzero(mask)
        lit = views[lu, lv]
        self.peak = float(np.max(np.abs(lit))) if lit.size else 0.0
        # very bright views scaled down by a power of two (exact) so that the spectrum's sums stay finite
        self.exponent = math.frexp(self.peak)[1] if self.peak > FOURIER_SCALE_ABOVE else 0
        if self.exponent:
            lit = np.ldexp(lit, -self.exponent)
        spec = scipy.fft.rfftn(lit * weight[lu, lv, None, None], s=(self.R2, self.C2), axes=(1, 2), workers=-1)
        grid = np.empty((self.R2, spec.shape[2], M, M), np.complex64)
        _refocus_kernels.angular_grid(spec, idx[lu], idx[lv], grid)
        self.spectrum = scipy.fft.fftn(grid, axes=(2, 3), workers=-1, overwrite_x=True)

    def _kernel(self, t):
        """Kaiser-Bessel kernel at offsets ``t`` (grid units), zero outside ``|t| <= W/2``."""
        x = 2.0 * np.asarray(t, np.float64) / self.KERNEL_WIDTH
        inside = np.abs(x) <= 1
        return np.where(inside, np.i0(self.beta * np.sqrt(np.clip(1 - x * x, 0, None))), 0.0)

    def _kernel_ft(self, u):
        """Fourier transform of the kernel at view offset ``u`` (cycles ``u / M``), by quadrature."""
        t = np.linspace(-self.KERNEL_WIDTH / 2, self.KERNEL_WIDTH / 2, 4001)
        k = self._kernel(t)
        return np.trapezoid(k[None, :] * np.cos(2 * np.pi * np.outer(u, t) / self.M), t, axis=1)

    def _taps(self, theta):
        """First tap and kernel weights for angular frequencies ``theta`` (cycles per view)."""
        p = theta * self.M
        j0 = np.floor(p - self.KERNEL_WIDTH / 2).astype(np.int64) + 1
        w = self._kernel(p[..., None] - (j0[..., None] + np.arange(self.KERNEL_WIDTH)))
        return j0, w

    def stack(self, slopes) -> np.ndarray:
        """Refocus at ``slopes`` (length S): (S, R, C) float32, as :func:`focal_stack`.

        Raises
        ------
        ValueError
            A slope that is not finite or exceeds ``max_slope``; planes past float32's largest (views near it).
        """
        slopes = np.atleast_1d(np.asarray(slopes, np.float64))
        _check_finite("slopes", slopes)
        if np.any(np.abs(slopes) > self.max_slope + 1e-12):
            raise ValueError(f"slopes {slopes} exceed max_slope={self.max_slope} of this FourierSlice")
        R, C = self.shape
        fr = np.fft.fftfreq(self.R2)
        fc = np.fft.rfftfreq(self.C2)
        j_r, w_r = self._taps(-slopes[:, None] * fr[None, :])
        j_c, w_c = self._taps(-slopes[:, None] * fc[None, :])
        spec = np.empty((len(slopes), self.R2, len(fc)), np.complex64)
        _refocus_kernels.fourier_slice(self.spectrum, j_r, w_r, j_c, w_c, spec)
        if self.half:   # views placed at offsets u - c - 1/2 give the image at r - s/2: shift it back, band-limited
            spec *= np.exp(2j * np.pi * self.half * slopes[:, None, None] * (fr[None, :, None] + fc[None, None, :]))
        img = scipy.fft.irfft2(spec, s=(self.R2, self.C2), workers=-1)[:, :R, :C]
        count, reached = _slice_count(self.n, self.shape, (self.R2, self.C2), slopes, self.mask)
        out = np.divide(img, count, out=np.zeros(img.shape), where=reached)
        if not self.exponent:
            return out.astype(np.float32)
        with np.errstate(over="ignore"):
            out = np.ldexp(out, self.exponent).astype(np.float32)     # scaled back
        if not np.all(np.isfinite(out)):
            raise _overflow("refocusing the views (Fourier slice)", self.peak)
        return out


def refocus(raw: np.ndarray, slopes, pixels_per_lenslet: int, mask=None, *, method: str = "shift-sum",
            interpolation: str = "bilinear") -> np.ndarray:
    """Refocus a raw image at ``slopes``: (R·N, C·N) -> (S, R, C) float32.

    ``method`` is ``shift-sum`` (:func:`focal_stack`, with ``interpolation``) or
    ``fourier`` (:class:`FourierSlice`). Raises ValueError for an unknown method and as
    :func:`raw_to_views` and the method do.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}. Received: {method!r}")
    return refocus_views(raw_to_views(raw, pixels_per_lenslet), slopes, mask, method=method,
                         interpolation=interpolation, check_finite=False)


def refocus_views(views: np.ndarray, slopes, mask=None, *, method: str = "shift-sum",
                  interpolation: str = "bilinear", check_finite: bool = True) -> np.ndarray:
    """Refocus sub-aperture views (N, N, R, C) at ``slopes``: -> (S, R, C) float32.

    As :func:`refocus`, for views already split (e.g. decoded from a real camera's raw
    image by :func:`lf_flame.real.decoding.decode`).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}. Received: {method!r}")
    if check_finite:
        _check_finite("views", views)
    if method == "fourier":
        slopes = np.atleast_1d(np.asarray(slopes, np.float64))
        if slopes.ndim != 1 or slopes.size == 0:
            raise ValueError(f"slopes must be a non-empty 1-D sequence. Received shape {slopes.shape}")
        _check_finite("slopes", slopes)
        return FourierSlice(views, max(float(np.max(np.abs(slopes))), 1e-3), mask).stack(slopes)
    return focal_stack(views, slopes, mask, interpolation=interpolation, check_finite=False)
