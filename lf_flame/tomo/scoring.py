"""Scores of reconstructed planes against the truth: relative error, SSIM, PSNR, diagnostics."""
from __future__ import annotations

import numpy as np

from ..optics.camera import PlenopticCamera


# ---- scoring ---------------------------------------------------------------------------
def score_planes(planes, truth, camera: PlenopticCamera, depths_mm, objects=None, *, time_s=float("nan"),
                 measure=None, **labels):
    """The one scoring function of every route to the emission, per plane.

    Parameters
    ----------
    planes, truth : ndarray of shape (P, R, C)
        A route's planes (reconstructed, or refocused: the baseline) and the true emission
        on the same grid (:func:`scene_truth`), radiance units.
    camera : PlenopticCamera
    depths_mm : sequence of P float
    objects : sequence of P flame objects or None
        Each plane's flame (:func:`lf_flame.measure.diagnostics.flame_truth`): its height is then
        measured on the plane (:func:`lf_flame.measure.diagnostics.measure_flame`) and compared.
    time_s : float
        The route's wall time for the whole stack.
    measure : dict or None
        Keyword arguments of :func:`~lf_flame.measure.diagnostics.measure_flame`: planes of emission
        are measured with :data:`~lf_flame.measure.diagnostics.EMISSION_MEASURE`, refocused planes
        with the defaults (:func:`~lf_flame.routes.measure_settings` of the route).
    **labels
        Columns added to every row (route, scene, noise ...).

    Returns
    -------
    DataFrame, one row per plane: labels, ``plane``, ``depth_mm``, ``rel_err`` (||x̂ − x|| /
    ||x||), ``ssim``, ``psnr_db`` (data range 1, :mod:`lf_flame.measure.metrics`), and with
    objects ``height_mm``, ``height_mm_true``, ``height_err_mm``, ``flags`` (why a
    measurement is not to be trusted) and ``failure``; ``time_s``.
    """
    import pandas as pd

    from ..measure.metrics import psnr_per_plane, ssim_per_plane
    from ..measure.scoring import score_stacks
    planes, truth = np.asarray(planes, np.float64), np.asarray(truth, np.float64)
    if planes.shape != truth.shape or planes.ndim != 3 or len(depths_mm) != len(planes):
        raise ValueError(f"planes {planes.shape}, truth {truth.shape} and {len(depths_mm)} depths do not match")
    rel = np.linalg.norm((planes - truth).reshape(len(planes), -1), axis=1) / np.maximum(
        np.linalg.norm(truth.reshape(len(truth), -1), axis=1), 1e-300)
    df = pd.DataFrame(dict(labels, plane=range(len(planes)), depth_mm=[float(d) for d in depths_mm], rel_err=rel,
                           ssim=ssim_per_plane(truth, planes), psnr_db=psnr_per_plane(truth, planes)))
    if objects is not None:
        h = score_stacks(np.clip(planes, 0, None)[None], camera, [list(objects)], measure=measure)
        keep = [c for c in ("height_mm", "height_mm_true", "height_err_mm", "flags", "failure") if c in h]
        df = pd.concat([df, h[keep].reset_index(drop=True)], axis=1)
    df["time_s"] = time_s
    return df
