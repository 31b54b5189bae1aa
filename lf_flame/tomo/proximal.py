"""The solvers of :func:`lf_flame.tomo.solvers.reconstruct` that run on PyLops and PyProximal.

Damped LSQR (PyLops; Sun, Hossain, Xu et al., Opt. Commun. 390 (2017)), FISTA with
non-negativity (PyProximal's proximal gradient; Beck & Teboulle, SIAM J. Imaging Sci. 2 (2009))
and primal-dual with TV and non-negativity (PyProximal; Chambolle & Pock, J. Math. Imaging Vis.
40 (2011); Viganò et al., Opt. Express (2018), plenoptomos). :func:`~lf_flame.tomo.solvers.reconstruct`
imports this module only when one of them is asked for: PyLops's import (SciPy's signal and
stats modules, about a second) stays off the default route, admm on the exact operator.

Each solver takes the fitted problem of :func:`~lf_flame.tomo.solvers.reconstruct` (``p.op``
the operator, ``p.y`` the views flat, ``p.fit`` the fitted samples, ``p.n_sat`` the samples
left out, ``p.yw`` the views with those zeroed, ``p.norm`` ``||y||``), its settings (updated
with the solver's step or damping), the per-iteration counter ``step(x)`` and its knobs, and
returns ``(x, residuals)``: the planes flat and the relative residual per iteration.
"""
from __future__ import annotations

import math

import numpy as np
import pylops
import pyproximal
from pylops.optimization.basic import lsqr
from pyproximal.optimization.primal import ProximalGradient
from pyproximal.optimization.primaldual import PrimalDual

#: "pd-tv" records its residual at the first, every this many and the last iteration (NaN
#: between): each record costs one more ``A``, a third of an iteration.
PD_RESIDUAL_EVERY = 5


def fitted_operator(p):
    """``W A`` as a PyLops operator: the operator with the samples left out of the fit zeroed
    (``W`` the 0/1 diagonal of ``p.fit``; ``A`` itself when none is)."""
    A = pylops.aslinearoperator(p.op)
    return A if p.n_sat == 0 else pylops.Diagonal(p.fit.astype(np.float64)) @ A


class _TrackedL2(pyproximal.L2):
    """``1/2 ||A x - b||^2`` that records the relative residual at every gradient it gives."""

    def __init__(self, Op, b):
        super().__init__(Op=Op, b=b)
        self.history, self._norm = [], float(np.linalg.norm(b)) or 1.0

    def grad(self, x):
        r = self.Op.matvec(x) - self.b
        self.history.append(float(np.linalg.norm(r)) / self._norm)
        return self.Op.rmatvec(r)


def solve_lsqr(p, settings: dict, step, iters: int, damp: float):
    """``"lsqr"``: damped LSQR: ``(x, residuals)``, LSQR's own ``||A x - y||`` estimates."""
    settings["damp"] = damp
    out = lsqr(fitted_operator(p), p.yw, np.zeros(p.op.shape[1]), damp=damp, niter=iters, calc_var=False,
               callback=step)
    return np.ravel(out[0]), np.asarray(out[-1])[1:] / p.norm   # LSQR's own ||A x - y|| estimate per iteration


def solve_fista(p, settings: dict, step, iters: int, lipschitz: float):
    """``"fista"``: accelerated proximal gradient with ``x >= 0``, step ``1 / lipschitz``
    (:func:`~lf_flame.tomo.solvers.lipschitz_bound`): ``(x, residuals)``."""
    settings["step"] = tau = 1.0 / lipschitz
    f = _TrackedL2(fitted_operator(p), p.yw)
    x = ProximalGradient(f, pyproximal.Box(lower=0.0), np.zeros(p.op.shape[1]), tau=tau, niter=iters,
                         acceleration="fista", callback=step)
    return x, f.history


def solve_pd_tv(p, settings: dict, step, iters: int, tv: float, lipschitz: float):
    """``"pd-tv"``: primal-dual with TV per plane and ``x >= 0`` (``lipschitz``: the bound of
    ``||A||^2``, :func:`~lf_flame.tomo.solvers.lipschitz_bound`): ``(x, residuals)``, the
    residual recorded every :data:`PD_RESIDUAL_EVERY` iterations (NaN between)."""
    op, n, residuals, A = p.op, p.op.shape[1], [], fitted_operator(p)
    # the gradient block scaled by c to the norm of A (||c grad||^2 <= 8 c^2 = ||A||^2 bound):
    # with one step for both blocks, an unscaled TV term would move ~sqrt(||A||^2 / 8) times slower
    c = math.sqrt(lipschitz / 8.0)
    grad = pylops.VStack([c * pylops.FirstDerivative(op.dims, axis=a, edge=True, kind="forward") for a in (1, 2)])
    K = pylops.VStack([A, grad])
    tau = mu = 0.99 / math.sqrt(2.0 * lipschitz)
    g = pyproximal.VStack([pyproximal.L2(b=p.yw), pyproximal.L21(ndim=2, sigma=tv / c)], nn=[op.shape[0], 2 * n])
    settings.update(tv=tv, step=tau)

    def track(xk):  # the primal-dual iteration exposes no residual: one more A, so only now and then
        k = step.count + 1
        residuals.append(float(np.linalg.norm(A.matvec(xk) - p.yw)) / p.norm
                         if k == 1 or k % PD_RESIDUAL_EVERY == 0 or k == iters else math.nan)
        step(xk)
    x = PrimalDual(pyproximal.Box(lower=0.0), g, K, np.zeros(n), tau=tau, mu=mu, niter=iters, callback=track)
    return x, residuals
