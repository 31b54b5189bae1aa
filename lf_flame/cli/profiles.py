"""The ``profiles`` command: flame diagnostics per plane (:mod:`lf_flame.measure.diagnostics`) of a
stack refocused by any route; its figure is :func:`lf_flame.measure.diagnostics.plot_profiles`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ._io import _load_raw, _raw_objects
from ..routes import parse_route
from .learning import _learned_runner


def _profiles_input(a):
    """Camera, 4-plane stack, depths, slopes and flame objects (or None) for ``profiles``."""
    from ..optics.camera import PAPER_CAMERA
    from ..refocus.shift_and_sum import aperture_mask, refocus
    from ..simulate.scenes import PAPER_DEPTHS_MM
    s = str(a.raw)
    gt, objects, slopes = None, None, None
    if ".h5:" in s:
        from ..learn.dataset import LightFieldDataset
        f, i = s.rsplit(":", 1)
        ds = LightFieldDataset(f)
        raw, cam = ds.raw(int(i)), ds.camera
        gt, objects, slopes = ds.gt(int(i)), ds.params(int(i)), ds.slopes
    else:
        raw, cam = _load_raw(a.raw)
        objects = _raw_objects(a.raw)
    if getattr(a, "camera", None):
        from ..optics.camera_file import load_camera_file
        cam = load_camera_file(a.camera)
    cam = cam or PAPER_CAMERA
    if objects is not None and not all("height_mm" in o for o in objects):
        raise ValueError(f"{a.raw} does not hold a flame scene (its objects have no flame heights)")
    depths = [float(o["depth_offset_mm"]) for o in objects] if objects else list(PAPER_DEPTHS_MM)
    if a.slope:
        slopes = a.slope
    elif slopes is None:
        slopes = [cam.slope_for_depth(d) for d in depths]
    if len(slopes) != len(depths):
        raise ValueError(f"need {len(depths)} slopes, one per plane. Received: {slopes}")
    n = cam.pixels_per_lenslet
    route = parse_route(a.route)
    if route.kind == "stored":
        if gt is None:
            raise ValueError("--route ground-truth needs a dataset sample DATASET.h5:INDEX")
        stack = gt
    elif route.kind == "learned":
        if not a.model_dir:
            raise ValueError(f"--route {a.route} needs --model-dir")
        run, _ = _learned_runner(raw, cam, a.raw, a.model_dir, route.solver)
        stack = run(raw.astype(np.float32)[None, ..., None])
    elif route.tomographic:
        from ..real.lightfield import from_raw
        from .volume import run_reconstruction, saturation_note
        rec = run_reconstruction(from_raw(raw, cam, str(a.raw)), depths, route.solver)[1]
        print(saturation_note(rec))
        stack = rec.planes
    else:
        stack = refocus(raw, slopes, n, aperture_mask(n, "circular"), **route.options)
    return cam, np.asarray(stack), depths, list(slopes), objects


def cmd_profiles(a):
    import pandas as pd
    from ..config import atomic_write_text
    from ..measure.diagnostics import EmptyPlaneError, flame_truth, measure_flame, plot_profiles
    from ..routes import measure_settings
    from ..measure.scoring import score_stacks
    kw = measure_settings(a.route)
    cam, stack, depths, slopes, objects = _profiles_input(a)
    if objects:
        sample = int(str(a.raw).rsplit(":", 1)[1]) if ".h5:" in str(a.raw) else 0
        df = score_stacks(stack[None], cam, [objects], samples=[sample], measure=kw, route=a.route)
        df.insert(0, "plane", range(len(df)))
        ms = []
        for plane, o in zip(stack, objects):
            try:
                ms.append(measure_flame(plane, cam, o["depth_offset_mm"], columns=flame_truth(o)["columns"], **kw))
            except EmptyPlaneError:
                ms.append(None)
    else:
        ms, rows = [], []
        for k, (plane, d) in enumerate(zip(stack, depths)):
            try:
                m = measure_flame(plane, cam, d, **kw)
                rows.append(dict(plane=k, route=a.route, depth_mm=d, **m.summary(), failure=""))
            except EmptyPlaneError as e:
                m = None
                rows.append(dict(plane=k, route=a.route, depth_mm=d, failure=str(e)))
            ms.append(m)
        df = pd.DataFrame(rows)
    df.insert(3, "slope", slopes)
    out = Path(a.out)
    atomic_write_text(f"{out}.csv", df.to_csv(index=False, float_format="%.5g"))
    axial = pd.DataFrame([dict(plane=k, depth_mm=d, height_mm=h, intensity=v)
                          for k, (m, d) in enumerate(zip(ms, depths)) if m is not None
                          for h, v in zip(m.axial_height_mm, m.axial_intensity)])
    atomic_write_text(f"{out}.axial.csv", axial.to_csv(index=False, float_format="%.5g"))
    plot_profiles(f"{out}.png", cam, stack, depths, ms, objects, a.route)
    cols = [c for c in ("depth_mm", "height_mm", "height_mm_true", "height_err_mm", "max_width_mm",
                        "centroid_x_mm", "integrated_intensity", "flags", "failure") if c in df]
    print(df[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"-> {out}.csv, {out}.axial.csv, {out}.png")
