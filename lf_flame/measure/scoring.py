"""Flame diagnostics scored against the simulation's truth: per plane, per sample, and their tail.

The scoring half of the diagnostics (:mod:`lf_flame.measure.diagnostics` measures a plane and
holds the truth of a flame object, :func:`~lf_flame.measure.diagnostics.flame_truth`): a stack measured against its objects
(:func:`measure_stack`), the errors of many stacks (:func:`score_stacks`) and their
means and tails per group (:func:`error_table`: share of planes off by more than 1 mm,
90th percentile, worst; over all planes and over the trusted ones).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from ..optics.camera import PlenopticCamera
from .diagnostics import EmptyPlaneError, flame_truth, measure_flame


def measure_stack(stack, camera: PlenopticCamera, objects, **kw) -> list:
    """Measure each plane of a focal stack against its flame object.

    Parameters
    ----------
    stack : ndarray of shape (P, R, C)
        Refocused planes, plane ``k`` focused on ``objects[k]``'s depth.
    camera : PlenopticCamera
    objects : sequence of P dict
        Flame objects (:func:`flame_truth`): each gives the plane's depth and column band.
    **kw
        Passed to :func:`measure_flame`.

    Returns
    -------
    list of P :class:`FlameMeasurement`, or the :class:`EmptyPlaneError` raised for a
    plane with nothing to measure (an empty prediction, say).

    Raises
    ------
    ValueError
        A stack of the wrong shape, NaN or inf, an object that is not a flame's.
    """
    stack = np.asarray(stack)
    if stack.ndim != 3 or len(stack) != len(objects):
        raise ValueError(f"stack must have shape ({len(objects)}, R, C), one plane per object. "
                         f"Received: shape {stack.shape}")
    out = []
    for plane, obj in zip(stack, objects):
        t = flame_truth(obj)
        try:
            out.append(measure_flame(plane, camera, t["depth_offset_mm"], columns=t["columns"], **kw))
        except EmptyPlaneError as e:
            out.append(e)
    return out


def score_stacks(stacks, camera: PlenopticCamera, objects_list, samples=None, *, measure=None,
                 **labels) -> pd.DataFrame:
    """Measured against true flame geometry, per plane of each sample.

    Parameters
    ----------
    stacks : ndarray of shape (n, P, R, C)
        Refocused stacks (ground truth or any route's prediction).
    camera : PlenopticCamera
    objects_list : sequence of n sequences of P flame objects
        Each sample's scene objects (``LightFieldDataset.params(i)``).
    samples : sequence of n ids or None
        Sample ids for the ``sample`` column (default 0 .. n-1).
    measure : dict or None
        Keyword arguments of :func:`measure_flame` (:func:`lf_flame.routes.measure_settings` of the route).
    **labels
        Columns added to every row (route, regime, ...).

    Returns
    -------
    DataFrame, one row per sample and plane: labels, ``sample``, ``depth_mm``, the true
    ``height_mm_true``, ``base_y_mm_true``, ``tip_y_mm_true``, ``centre_x_mm_true``, the
    measured :meth:`FlameMeasurement.summary` values, the absolute errors
    ``height_err_mm``, ``base_err_mm``, ``tip_err_mm``, ``centre_x_err_mm`` (|measured −
    true|, centre against the centroid), ``flags`` (:attr:`FlameMeasurement.flags` joined
    by ``;``, empty when trusted) and ``failure`` (the reason a plane could not be
    measured, else empty; its errors are NaN and its flags empty).

    Raises
    ------
    ValueError
        Stacks and objects of different lengths; as :func:`measure_stack`.
    """
    if len(stacks) != len(objects_list):
        raise ValueError(f"{len(stacks)} stacks but {len(objects_list)} object lists")
    samples = range(len(stacks)) if samples is None else samples
    rows = []
    for i, stack, objects in zip(samples, stacks, objects_list):
        for obj, m in zip(objects, measure_stack(stack, camera, objects, **(measure or {}))):
            t = flame_truth(obj)
            row = dict(labels, sample=int(i), depth_mm=t["depth_offset_mm"],
                       **{f"{k}_true": v for k, v in t.items() if k not in ("columns", "depth_offset_mm")})
            if isinstance(m, EmptyPlaneError):
                row.update(failure=str(m), flags="", height_err_mm=math.nan, base_err_mm=math.nan, tip_err_mm=math.nan,
                           centre_x_err_mm=math.nan)
            else:
                row.update(m.summary(), failure="", height_err_mm=abs(m.height_mm - t["height_mm"]),
                           base_err_mm=abs(m.base_y_mm - t["base_y_mm"]), tip_err_mm=abs(m.tip_y_mm - t["tip_y_mm"]),
                           centre_x_err_mm=abs(m.centroid_x_mm - t["centre_x_mm"]))
            rows.append(row)
    return pd.DataFrame(rows)


def _tail(err: pd.Series) -> pd.Series:
    """Tail of absolute errors (NaN left out): share over 1 mm, 90th percentile, worst."""
    err = err.dropna()
    if err.empty:
        return pd.Series(dict(share_over_1mm=math.nan, p90=math.nan, max=math.nan))
    return pd.Series(dict(share_over_1mm=float((err > 1.0).mean()), p90=float(err.quantile(0.9)),
                          max=float(err.max())))


def error_table(scores: pd.DataFrame, by=("depth_mm",)) -> pd.DataFrame:
    """Mean absolute errors and their tail (mm) per group of :func:`score_stacks` rows
    (default: per plane).

    Returns
    -------
    DataFrame with ``by`` columns, ``n`` (planes), ``n_failed`` (not measurable; left out
    of every statistic), ``n_flagged`` (measured but flagged, :attr:`FlameMeasurement.flags`),
    the mean absolute ``height_err_mm``, ``base_err_mm``, ``tip_err_mm``,
    ``centre_x_err_mm``, the mean signed height error ``height_bias_mm`` (measured −
    true), and the height error's tail: ``share_over_1mm`` (fraction of measured planes
    off by more than 1 mm), ``height_err_mm_p90`` (90th percentile), ``height_err_mm_max``
    (worst); and the same three over the trusted planes only (suffix ``_trusted``). The
    means are over all measured planes, flagged ones included (as before the flags).
    """
    flags = scores["flags"].fillna("") if "flags" in scores else pd.Series("", index=scores.index)
    df = scores.assign(height_bias=scores.get("height_mm", np.nan) - scores.height_mm_true,
                       flagged=(flags != "") & (scores.failure == ""),
                       height_err_trusted=scores.height_err_mm.where(flags == ""))
    g = df.groupby(list(by), sort=False)
    tail = g.height_err_mm.apply(_tail).unstack()
    tail_t = g.height_err_trusted.apply(_tail).unstack()
    return pd.DataFrame(dict(
        n=g.size(), n_failed=g.failure.apply(lambda f: int((f != "").sum())), n_flagged=g.flagged.sum().astype(int),
        height_err_mm=g.height_err_mm.mean(), height_err_mm_max=tail["max"],
        height_bias_mm=g.height_bias.mean(), base_err_mm=g.base_err_mm.mean(), tip_err_mm=g.tip_err_mm.mean(),
        centre_x_err_mm=g.centre_x_err_mm.mean(), share_over_1mm=tail.share_over_1mm, height_err_mm_p90=tail.p90,
        share_over_1mm_trusted=tail_t.share_over_1mm, height_err_mm_p90_trusted=tail_t.p90,
        height_err_mm_max_trusted=tail_t["max"])).reset_index()
