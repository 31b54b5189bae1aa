"""admm's knobs by the light field's noise: the noise estimate, the noise level and the planes' grid.

The knobs of :func:`lf_flame.tomo.fourier.solve_admm` were chosen on validation renders per
planes' grid and noise level (:data:`~lf_flame.tomo.defaults.ADMM_KNOBS`); this module measures a
light field's noise (:func:`relative_noise`), names its level (:func:`noise_regime`) and picks
the knobs not given (:func:`admm_knobs`) and the grid (:func:`admm_subsamples`).
"""
from __future__ import annotations

import math

import numpy as np

from .defaults import ADMM_KNOBS, ADMM_QUIET_NOISE, ADMM_START, ADMM_SUBSAMPLES, SUBSAMPLES_MAX_PLANES


#: Immerkaer's mask: the difference of two Laplacians, blind to a plane's first and second
#: derivatives, whose response to white noise of deviation sigma has deviation 6 sigma.
_IMMERKAER = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])


def relative_noise(views, fit=None) -> float:
    """The light field's noise: its standard deviation over the views' 99.9th percentile.

    Per central view (the 3 x 3 around the optical axis, lit in any camera), Immerkaer's
    estimate ``sqrt(pi / 2) mean|I * M| / 6`` (J. Immerkaer, "Fast noise variance
    estimation", Comput. Vis. Image Underst. 64 (1996)) over the pixels whose 3 x 3
    neighbourhood is fitted; the median over those views. Smooth emission (flames) barely
    moves it; sharp edges raise it.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    fit : ndarray of bool of shape (N, N, R, C) or None
        The pixels to use (False: saturated); None: all.

    Returns
    -------
    float
        0 for central views without light.
    """
    import scipy.ndimage
    c = views.shape[0] // 2
    sl = (slice(max(c - 1, 0), c + 2),) * 2
    v = np.asarray(views[sl], np.float64)
    flat = v.reshape((-1,) + v.shape[2:])
    ok = np.ones(flat.shape, bool) if fit is None else np.asarray(fit, bool)[sl].reshape(flat.shape)
    peak = float(np.percentile(flat, 99.9))
    if not peak > 0:
        return 0.0
    r = np.abs(scipy.ndimage.convolve(flat, _IMMERKAER[None], mode="nearest"))
    ok = scipy.ndimage.binary_erosion(ok, np.ones((1, 3, 3), bool), border_value=1)
    sig = [r[i][ok[i]].mean() for i in range(len(flat)) if ok[i].any()]
    return float(math.sqrt(math.pi / 2) * np.median(sig) / 6 / peak) if sig else 0.0


def noise_norm(views, fit=None) -> float:
    """The norm of the light field's noise over its fitted samples, ``sqrt(sum sigma_i^2)``, in the views' units.

    Per view, Immerkaer's mask (blind to a plane's first and second derivatives; white noise of
    deviation sigma gives a response of variance ``36 sigma^2``) over the samples whose 3 x 3
    neighbourhood is fitted, ``sum (I * M)^2 / 36`` scaled to every fitted sample: the mean of the
    noise's variance, where :func:`relative_noise`'s mean absolute response gives a typical
    deviation (shot noise varies with the light: the mean of the variance is the larger, and the
    one a residual's norm holds). On simulated flames at 14 dB it reads 89-95 % of the noise that
    was added (the rest is clipping's offset at 0, which the mask does not see); without noise it
    reads a render's ray noise (1.5-1.8 % of the light at 100 rays per pixel).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    fit : ndarray of bool of the views' shape or None
        The samples that count (False: clipped); None: all.

    Returns
    -------
    float
    """
    import scipy.ndimage
    v = np.asarray(views, np.float64)
    flat = v.reshape((-1,) + v.shape[-2:])
    f = np.ones(flat.shape, bool) if fit is None else np.asarray(fit, bool).reshape(flat.shape)
    ok = scipy.ndimage.binary_erosion(f, np.ones((1, 3, 3), bool), border_value=1)
    if not ok.any():
        return 0.0
    r = scipy.ndimage.convolve(flat, _IMMERKAER[None], mode="nearest")[ok]
    return float(math.sqrt(float(np.sum(r * r)) / 36.0 * f.sum() / ok.sum()))


def admm_knobs(views, fit, fills=None, tv=None, lam=None, subsamples: int = 1, l1=None, start=None, tol=None) -> dict:
    """admm's knobs for these views: those given, the others by their noise.

    The knobs not given come from :data:`~lf_flame.tomo.defaults.ADMM_KNOBS` for the
    planes' grid (``subsamples``) and the light field's noise level (quiet below
    :data:`~lf_flame.tomo.defaults.ADMM_QUIET_NOISE`). The noise is measured when any of
    ``fills``, ``tv``, ``lam``, ``l1`` is not given; otherwise ``start`` not given is
    :data:`~lf_flame.tomo.defaults.ADMM_START`. ``tol`` not given is the grid's and noise
    level's where ``fills`` was not given, else 0 (the fills given all run).

    Returns
    -------
    dict
        ``fills`` (int), ``tv``, ``lam``, ``l1`` (float), ``start`` (str), ``tol`` (float) and
        ``noise``: :func:`relative_noise` of the views (NaN when not measured).

    Raises
    ------
    ValueError
        A grid the knobs were not chosen for.
    """
    if (subsamples, "quiet") not in ADMM_KNOBS:
        raise ValueError(f"admm's knobs were chosen for subsamples in {sorted({k for k, _ in ADMM_KNOBS})}; give "
                         f"fills, tv, lam and l1 for subsamples={subsamples!r}")
    given = dict(fills=fills, tv=tv, lam=lam, l1=l1)
    noise = math.nan if None not in given.values() else relative_noise(views, fit)
    chosen = ADMM_KNOBS[subsamples, noise_regime(noise)] if math.isfinite(noise) else {}
    out = {k: chosen[k] if v is None else v for k, v in given.items()}
    out = dict(fills=int(out["fills"]), tv=float(out["tv"]), lam=float(out["lam"]), l1=float(out["l1"]))
    out["start"] = str(chosen.get("start", ADMM_START) if start is None else start)
    out["tol"] = float((chosen["tol"] if fills is None else 0.0) if tol is None else tol)
    out["noise"] = noise
    return out


def noise_regime(noise: float) -> str:
    """``"quiet"`` below :data:`~lf_flame.tomo.defaults.ADMM_QUIET_NOISE` of relative noise, else ``"noisy"``."""
    return "quiet" if noise < ADMM_QUIET_NOISE else "noisy"


def admm_subsamples(n_planes: int) -> int:
    """The planes' grid (samples per lenslet and axis) of the routes that build their operator:
    :data:`~lf_flame.tomo.defaults.ADMM_SUBSAMPLES`, or 1 for stacks of more than
    :data:`~lf_flame.tomo.defaults.SUBSAMPLES_MAX_PLANES` planes (the per-frequency matrices
    grow as ``(P s^2)^2``: dense stacks stay on the lenslet grid)."""
    return 1 if n_planes > SUBSAMPLES_MAX_PLANES else ADMM_SUBSAMPLES
