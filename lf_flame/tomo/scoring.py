"""Scores of reconstructed planes against the truth: relative error, SSIM, PSNR, diagnostics; per flame
at unknown depths, the depth error, emission error and share of emission near the true depth."""
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


def _flame_truth(layer, camera, depth_mm, shape, frame=None):
    """A flame's emission on the grid of a plane at ``depth_mm`` (:func:`resample_layer`; decoded
    views' planes, ``frame`` given: :func:`~lf_flame.tomo.decoded.decoded_plane_truth`)."""
    if frame is not None:
        from .decoded import decoded_plane_truth
        return decoded_plane_truth(layer, camera, depth_mm, shape, frame.rotation_deg, frame.centre_lenslets)
    from .operator import plane_grid
    from .truth import resample_layer
    return resample_layer(layer, shape, plane_grid(camera, depth_mm))


def score_flames(planes, depths_mm, scene, camera: PlenopticCamera, *, found=None, emission: bool = True,
                 near_mm: float = 1.0, time_s=float("nan"), frame=None, **labels):
    """The one scoring function of every route to flames at unknown depths, per flame.

    Each flame of ``scene`` (layer ``k`` is flame ``k``, :mod:`lf_flame.simulate.scenes_depth`) is
    scored in its region ``M`` (its true emission above 2 % of its peak on its own plane,
    dilated by 2 samples):

    - **depth**: with ``found``, the found depth whose footprint meets ``M`` nearest the
      flame's true depth, each found depth given to at most one flame of the same lines of
      sight (greedy, nearest first: flames whose regions ``M`` meet; flames side by side may
      share a depth found over both, as a camera whose depth resolution is coarser than their
      separation finds them); none: the flame is missed (NaN). Without ``found`` (fixed planes), the plane
      holding most of the route's non-negative emission in ``M``.
    - **emission error**: ``||x_p - t_p|| / ||t_p||`` in ``M`` on the plane ``p`` nearest
      that depth, ``t_p`` the flame's truth resampled onto that plane's grid.
    - **share within ±near_mm**: the route's non-negative emission in ``M`` on planes
      within ``near_mm`` of the flame's true depth, over that on all planes but those
      within ``near_mm`` of another flame whose region meets ``M`` (its own light).
    - **height**: the flame measured on that plane
      (:func:`~lf_flame.measure.diagnostics.measure_flame` in the flame's ``roi`` columns and,
      with ``found``, within the region its depth was found in and outside the footprints of
      the other found depths on the same plane, each dilated by 2 samples: two flames merged
      onto one plane may share columns, and the route's own segmentation tells them apart;
      its own footprint is not used, as the lenslets that voted for a flame in front of
      another cover only where it is the sharper one), at the plane's depth; planes of
      emission with
      :data:`~lf_flame.measure.diagnostics.EMISSION_MEASURE`, refocused images with the
      defaults) against the scene's ``height_mm``. A plane the diagnostics find empty: NaN
      and the failure's message.

    Parameters
    ----------
    planes : ndarray of shape (P, R, C)
        A route's emission (or refocused images, ``emission=False``) on each plane.
    depths_mm : sequence of P float
        The planes' depths (mm).
    scene : Scene
        Its layers are the flames, ``scene.objects[k]["depth_offset_mm"]`` their depths.
    camera : PlenopticCamera
    found : sequence of (depth_mm, mask (R, C) bool[, region (R, C) bool]) or None
        A route's depths, their lateral footprints (the lenslets that voted for them) and,
        optionally, the regions they were found in
        (:class:`~lf_flame.tomo.depth.FoundDepths`' ``labels == region``).
    emission : bool
        False for refocused images: the share is not defined (NaN).
    near_mm : float
    time_s : float
        The route's wall time for the light field.
    frame : lf_flame.real.own_camera.DecodedFrame or None
        For planes of decoded views (``camera`` their camera): where they lie in the scene's
        object space (:func:`~lf_flame.tomo.decoded.decoded_plane_truth`); each flame's height
        is then measured in the columns of its truth's region, 3 lenslets either side, as the
        scene's ``roi`` counts lenslets of the camera that rendered it.
    **labels
        Columns added to every row.

    Returns
    -------
    DataFrame, one row per flame: labels, ``flame``, ``depth_mm_true``, ``height_mm``,
    ``depth_mm`` (found; NaN: missed), ``depth_err_mm`` (signed), ``plane_mm``,
    ``rel_err``, ``share_near``, ``height_mm_found``, ``height_err_mm`` (signed; NaN: missed
    or not measured), ``height_flags`` (the measurement's flags, ``;``-joined), ``height_failure``,
    ``time_s``.

    Raises
    ------
    ValueError
        Planes not (P, R, C) of the camera's lenslet grid (or ``(P, s R, s C)``, an
        :class:`~lf_flame.tomo.exact.ExactOperator`'s with ``subsamples = s``: averaged to the
        lenslets, :func:`~lf_flame.tomo.truth.bin_planes`), or not as many depths as planes; a scene whose
        layers and objects differ in number.
    """
    import pandas as pd
    from scipy import ndimage
    from ..measure.diagnostics import EMISSION_MEASURE, EmptyPlaneError, measure_flame
    from .truth import bin_planes
    x = np.asarray(planes, np.float64)
    d = np.asarray(depths_mm, np.float64)
    sub = x.shape[1] // camera.n_rows if x.ndim == 3 else 0
    if sub > 1 and x.shape[1:] == (sub * camera.n_rows, sub * camera.n_cols):
        x = bin_planes(x, sub)                     # a finer grid, scored on the lenslets
    if x.ndim != 3 or x.shape[1:] != (camera.n_rows, camera.n_cols) or len(d) != len(x):
        raise ValueError(f"planes {x.shape} must be (P, {camera.n_rows}, {camera.n_cols}) (or s times as many rows "
                         f"and columns) with P = {len(d)} depths")
    if len(scene.layers) != len(scene.objects):
        raise ValueError(f"scene has {len(scene.layers)} layers but {len(scene.objects)} objects: one per flame")
    shape = x.shape[1:]
    xp = np.clip(x, 0.0, None)
    true_d = [float(o["depth_offset_mm"]) for o in scene.objects]
    regions = []
    for L, dz in zip(scene.layers, true_d):
        t = _flame_truth(L, camera, dz, shape, frame)
        regions.append(ndimage.binary_dilation(t > 0.02 * t.max(), iterations=2))
    est = [np.nan] * len(true_d)
    footprint = [None] * len(true_d)
    if found is not None:
        pairs = sorted((abs(f[0] - true_d[k]), k, j) for j, f in enumerate(found)
                       for k in range(len(true_d)) if np.any(np.asarray(f[1], bool) & regions[k]))
        on_plane = [int(np.argmin(np.abs(d - f[0]))) for f in found]
        used_f, holders = set(), [[] for _ in found]
        for _, k, j in pairs:
            if k not in used_f and not any(np.any(regions[k] & regions[h]) for h in holders[j]):
                est[k] = float(found[j][0])
                foot = np.ones(shape, bool)
                if len(found[j]) > 2:    # the region the depth was found in
                    foot = ndimage.binary_dilation(np.asarray(found[j][2], bool), iterations=2)
                others = [np.asarray(found[g][1], bool) for g in range(len(found))
                          if g != j and on_plane[g] == on_plane[j]]
                if others:       # flames merged onto one plane: the others' voters are not this flame
                    foot &= ~ndimage.binary_dilation(np.any(others, axis=0), iterations=2)
                footprint[k] = foot
                used_f.add(k)
                holders[j].append(k)
    else:
        for k, M in enumerate(regions):
            est[k] = float(d[int(np.argmax(xp[:, M].sum(axis=1)))])
    rows = []
    for k, (L, dz, M) in enumerate(zip(scene.layers, true_d, regions)):
        row = dict(labels, flame=k, depth_mm_true=dz, height_mm=float(scene.objects[k].get("height_mm", np.nan)),
                   depth_mm=est[k], depth_err_mm=est[k] - dz, plane_mm=np.nan, rel_err=np.nan, share_near=np.nan,
                   height_mm_found=np.nan, height_err_mm=np.nan, height_flags="", height_failure="", time_s=time_s)
        if np.isfinite(est[k]):
            p = int(np.argmin(np.abs(d - est[k])))
            t = _flame_truth(L, camera, float(d[p]), shape, frame)
            row.update(plane_mm=float(d[p]), rel_err=float(np.linalg.norm((x[p] - t)[M]) / np.linalg.norm(t[M])))
            try:
                plane = xp[p] if footprint[k] is None else xp[p] * footprint[k]
                cols = tuple(scene.objects[k]["roi"][2:4])
                on = np.flatnonzero(M.any(axis=0))
                if frame is not None and on.size:
                    cols = (max(int(on[0]) - 3, 0), min(int(on[-1]) + 4, shape[1]))
                m = measure_flame(plane, camera, float(d[p]), columns=cols,
                                  **(EMISSION_MEASURE if emission else {}))
                row.update(height_mm_found=m.height_mm, height_err_mm=m.height_mm - row["height_mm"],
                           height_flags=";".join(m.flags))
            except EmptyPlaneError as e:
                row["height_failure"] = str(e)
        if emission:
            others = [true_d[g] for g in range(len(true_d)) if g != k and np.any(regions[g] & M)]
            keep = np.array([not any(abs(dp - o) <= near_mm for o in others) for dp in d])
            light = xp[:, M].sum(axis=1)
            den = light[keep].sum()
            row["share_near"] = float(light[np.abs(d - dz) <= near_mm].sum() / den) if den > 0 else 0.0
        rows.append(row)
    return pd.DataFrame(rows)
