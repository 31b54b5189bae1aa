"""Volumes: a dense stack of planes from one light field, with a prior that fits flames.

A dense stack is not depth-resolved for whole flames by the data alone
(:mod:`lf_flame.tomo.resolution`: on the paper's camera two planes 20 mm apart are not told
apart for features of 6.6 mm at condition 10). What resolves them is a prior.
:func:`solve_volume` solves a stack every ``step`` mm over ``[near, far]`` with one of
:data:`~lf_flame.tomo.defaults.VOLUME_PRIORS` on the exact operator (lenslet grid, float32):

- ``"none"``: admm, its knobs by the light field's noise (:func:`lf_flame.tomo.solvers.reconstruct`);
- ``"tv"``: admm with isotropic TV per plane (lateral) of weight
  :data:`~lf_flame.tomo.defaults.VOLUME_TV` (by the light field's noise);
- ``"sparse"``: admm with the ``l1`` sparsity weight :data:`~lf_flame.tomo.defaults.VOLUME_L1`
  (a fraction of ``lambda_max``, :func:`lf_flame.tomo.fourier.solve_admm`; by the noise): the
  emission gathers on fewer planes per line of sight;
- ``"axisymmetric"``: a laminar flame's emission ``e(r, y)`` about a vertical axis found
  from the data (:func:`lf_flame.tomo.axisymmetric.solve_axisymmetric`).

Each volume states the depth resolution its stack carries for the data alone
(:func:`lf_flame.tomo.resolution.depth_resolution` over the same stack).
"""
from __future__ import annotations

import time

import numpy as np

from .defaults import VOLUME_L1, VOLUME_MAX_PLANES, VOLUME_PRIOR, VOLUME_PRIORS, VOLUME_TV


def volume_depths(near_mm: float, far_mm: float, step_mm: float) -> np.ndarray:
    """Depths (mm from the focal plane, > 0 farther) of a volume's stack every ``step_mm`` from
    ``near_mm`` to ``far_mm`` (:func:`lf_flame.tomo.resolution.stack_depths`).

    Raises
    ------
    ValueError
        Non-finite values, ``step_mm <= 0``, ``near_mm >= far_mm``, or more than
        :data:`~lf_flame.tomo.defaults.VOLUME_MAX_PLANES` planes (the per-frequency matrices
        grow as ``P^2``: 81 planes peak at 3.0 GB on the paper's camera, ``results/fourier_solver.md``).
    """
    from .resolution import stack_depths
    d = stack_depths(near_mm, far_mm, step_mm)
    if len(d) > VOLUME_MAX_PLANES:
        raise ValueError(f"{len(d)} planes from {near_mm:g} to {far_mm:g} mm every {step_mm:g} mm: a volume takes at "
                         f"most {VOLUME_MAX_PLANES} (memory grows as the planes squared); give a larger step or a "
                         "shorter range")
    if len(d) < 2:
        raise ValueError(f"a volume needs at least 2 planes: {near_mm:g} to {far_mm:g} mm every {step_mm:g} mm "
                         "gives 1")
    return d


def solve_volume(views, camera, near_mm: float, far_mm: float, step_mm: float, prior: str = VOLUME_PRIOR, *,
                 saturation=1.0, tv: float | None = None, l1: float | None = None, resolution: bool = True,
                 white_normalised: bool = False, interpolation=None, progress: bool = False, unit: float | None = None):
    """The emission on a dense stack from one light field, with a prior (module docstring).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
        The light field (radiance units), :func:`lf_flame.refocus.shift_and_sum.raw_to_views`.
    camera : PlenopticCamera
        A perfect lenslet grid (the exact operator's).
    near_mm, far_mm, step_mm : float
        The stack: planes every ``step_mm`` from ``near_mm`` to ``far_mm`` (mm from the focal
        plane, > 0 farther; :func:`volume_depths`).
    prior : str
        One of :data:`~lf_flame.tomo.defaults.VOLUME_PRIORS`.
    saturation : float, ndarray of bool of the views' shape, or None
        The clipping level (views' units): pixels at or above it are left out of the fit; a mask
        of the samples to leave out (decoded views' clipped samples); None: all fitted.
    unit : float or None
        The views' unit with a mask (:func:`~lf_flame.tomo.solvers.reconstruct`'s ``unit``); None: as there.
    white_normalised : bool
        Views decoded from a capture (divided by the white image): taken as the operator's
        data times its white views, the aperture image's dark rim left out
        (:func:`lf_flame.tomo.decoded.decoded_problem`).
    interpolation : (ndarray of shape (2, M), int) or None
        Decoded views' interpolation phases and pixels per sample
        (:attr:`lf_flame.real.lightfield.LightField.interpolation`): the stack's operator models decoding's
        interpolation
        (:class:`~lf_flame.tomo.lattice.LatticeOperator` on the square grid, as ``lf-flame reconstruct``'s
        planes). None: the exact operator of a perfect grid.
    tv, l1 : float or None
        The ``"tv"`` and ``"sparse"`` priors' weights; None: :data:`~lf_flame.tomo.defaults.VOLUME_TV`,
        :data:`~lf_flame.tomo.defaults.VOLUME_L1` for the light field's noise level
        (:func:`lf_flame.tomo.noise_knobs.relative_noise`). Refused with another prior.
    resolution : bool
        Also map the stack's depth resolution (about 2 s on the paper's camera).
    progress : bool
        A tqdm bar over admm's fills.

    Returns
    -------
    rec : Reconstruction
        ``planes`` (P, R, C) on the stack (float64, non-negative); ``solver`` is ``"admm"`` or
        ``"axisymmetric"``; ``settings`` hold the prior, its weights and, for the
        axisymmetric prior, the axis (mm), the residual, the search and ``beyond_field``
        (whether the flame's light from beyond the field was modelled).
    extra : dict
        ``"axisymmetric"``: the :class:`~lf_flame.tomo.axisymmetric.AxisymmetricVolume`
        (None for the other priors); ``"resolution"``: the
        :class:`~lf_flame.tomo.resolution.DepthResolution` of the stack (None unless asked);
        ``"operator"``: the stack's :class:`~lf_flame.tomo.exact.ExactOperator` (a
        :class:`~lf_flame.tomo.lattice.LatticeOperator` with ``interpolation``).

    Raises
    ------
    ValueError
        An unknown prior, a weight given to a prior that has none, a bad stack
        (:func:`volume_depths`), views not of the camera, or the solvers' own refusals.
    """
    from .exact import ExactOperator
    from .solvers import Reconstruction, reconstruct
    if prior not in VOLUME_PRIORS:
        raise ValueError(f"prior must be one of {VOLUME_PRIORS}. Received: {prior!r}")
    if (tv is not None and prior != "tv") or (l1 is not None and prior != "sparse"):
        raise ValueError(f"a TV weight goes with the 'tv' prior and an l1 weight with 'sparse'; the prior is {prior!r}")
    depths = volume_depths(near_mm, far_mm, step_mm)
    t0 = time.perf_counter()
    if interpolation is None:
        op = ExactOperator(camera, list(depths), precision="float32")
    else:
        from .lattice import LatticeOperator
        op = LatticeOperator(camera, list(depths), np.shape(views)[2:], layout="square", interpolation=interpolation)
    setup_s = time.perf_counter() - t0
    if white_normalised:                                   # decoded views: the operator's data, dark rims left out
        from .decoded import decoded_problem
        views, saturation = decoded_problem(views, op, saturation if np.ndim(saturation) else None)

    def fitted(v):
        if np.ndim(saturation):
            return ~np.asarray(saturation)
        return np.ones(v.shape, bool) if saturation is None else v < float(saturation)
    axi = None
    if prior == "axisymmetric":
        from .axisymmetric import solve_axisymmetric
        from .operator import check_views
        v = check_views(views, op)
        fit = fitted(v)
        axi = solve_axisymmetric(v, op, fit, camera=camera)
        sample = tuple((h / op.dims[1], w / op.dims[2]) for h, w in op.sizes_mm)
        rec = Reconstruction(axi.volume, tuple(float(d) for d in depths), sample, "axisymmetric",
                             dict(prior=prior, axis_x_mm=axi.axis_x_mm, axis_z_mm=axi.axis_z_mm, lam=axi.lam,
                                  beyond_field=axi.beyond_field, start_uncertainty_mm=axi.start_uncertainty_mm,
                                  saturation="mask" if np.ndim(saturation) else saturation, n_saturated=int((~fit).sum()),
                                  search=[list(s) for s in axi.search]),
                             np.array([axi.residual]), axi.time_s)
    else:
        knobs = {"l1": 0.0}                        # sparsity only where the prior says so
        if prior in ("tv", "sparse"):
            key, weight, table = ("tv", tv, VOLUME_TV) if prior == "tv" else ("l1", l1, VOLUME_L1)
            if weight is None:                                            # the weight by the noise
                from .noise_knobs import noise_regime, relative_noise
                from .operator import check_views
                v = check_views(views, op)
                weight = table[noise_regime(relative_noise(v, fitted(v)))]
            knobs[key] = weight
        rec = reconstruct(views, op, "admm", saturation=saturation, progress=progress, unit=unit, **knobs)
        rec.settings["prior"] = prior
    rec.settings.update(setup_s=setup_s, near_mm=float(near_mm), far_mm=float(far_mm), step_mm=float(step_mm))
    res = None
    if resolution:
        from .resolution import depth_resolution
        res = depth_resolution(camera, near_mm=float(depths[0]), far_mm=float(depths[-1]), spacing_mm=float(step_mm))
    return rec, dict(axisymmetric=axi, resolution=res, operator=op)
