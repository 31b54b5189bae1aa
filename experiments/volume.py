"""Axisymmetric volumetric flames on a dense stack (issue 36, step 2): the axisymmetric prior beside the baselines.

Scenes: axisymmetric flames (``volume_flame_scene``: the sheath on the optical axis; and
:func:`lf_flame.simulate.scenes_volume.axisymmetric_flame_scene`: sheaths and filled cores
about axes off the optical axis, at other depths and diameters), 32 layers each, rendered by
the ray tracer (never by the operator) at ``--rays`` rays per pixel; each render's own error
``||r1 - r2|| / (sqrt 2 ||r1||)`` from a second seed; noise-free and at 14 dB (shot and read
noise, ``experiments/reconstruct.py``'s ``noisy``). Renders cached in ``--cache``.

One dense stack (``--planes`` planes every ``--step`` mm about 0) holds every scene; the truth
is :func:`lf_flame.tomo.truth.scene_truth` on it. Routes on the same renders:

- ``axisymmetric``: :func:`lf_flame.tomo.axisymmetric.solve_axisymmetric`, the axis found
  (x0 from the central view, z0 searched on the residual from find_depths' start);
- ``admm``: the dense stack by ``reconstruct(views, op, "admm")`` (no axisymmetric prior);
- ``shift-and-sum``: ``focal_stack`` at every plane's slope, scaled by the least-squares
  factor against the truth (optimistic for it).

Metrics on the dense grid: 3-D relative L2 error; projection error (the planes summed along
depth against the truth's, relative L2); per line of sight (a grid sample whose truth, summed
over depth, holds >= 5 % of the largest) the depth centroid's error, mean / p90 / worst (mm).

Usage: ``python experiments/volume.py --out results [--quick]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reconstruct as R  # noqa: E402  (the 14 dB noise of make reconstruct)

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack  # noqa: E402
from lf_flame.simulate.scenes import volume_flame_scene  # noqa: E402
from lf_flame.simulate.scenes_volume import axisymmetric_flame_scene  # noqa: E402
from lf_flame.tomo.axisymmetric import solve_axisymmetric  # noqa: E402
from lf_flame.tomo.exact import ExactOperator  # noqa: E402
from lf_flame.tomo.solvers import reconstruct  # noqa: E402
from lf_flame.tomo.truth import scene_truth  # noqa: E402

SNR_DB = 14.0
N_LAYERS = 32
#: (name, seed, generator keywords): the sheath on the optical axis, then off-axis sheaths and cores
SCENES = (
    ("sheath D10 on axis", 501, dict(kind="sheath_axis", centre_depth_mm=0.0, diameter_mm=10.0)),
    ("sheath D8 x+0.8 z+2.3", 502, dict(centre_depth_mm=2.3, centre_x_mm=0.8, diameter_mm=8.0, core=0.0)),
    ("core D7 x-0.6 z-3.1", 503, dict(centre_depth_mm=-3.1, centre_x_mm=-0.6, diameter_mm=7.0, core=1.0)),
    ("sheath+core D6 x+0.4 z+1.2", 504, dict(centre_depth_mm=1.2, centre_x_mm=0.4, diameter_mm=6.0, core=0.5)),
)


def build_scene(cam, seed, kw):
    kw = dict(kw)
    rng = np.random.default_rng(seed)
    if kw.pop("kind", None) == "sheath_axis":
        return volume_flame_scene(cam, rng, n_layers=N_LAYERS, **kw)
    return axisymmetric_flame_scene(cam, rng, n_layers=N_LAYERS, **kw)


def render_set(cam, name, seed, kw, rays, cache: Path):
    scene = build_scene(cam, seed, kw)
    t0 = time.perf_counter()
    out = R.cached_render(cam, scene, rays, seed, cache / f"volume_{seed}_{rays}.npz", SNR_DB)
    return (scene,) + out + (time.perf_counter() - t0,)


def metrics(x, truth, depths):
    rel = float(np.linalg.norm(x - truth) / np.linalg.norm(truth))
    pt, px = truth.sum(axis=0), x.sum(axis=0)
    proj = float(np.linalg.norm(px - pt) / np.linalg.norm(pt))
    z = np.asarray(depths)[:, None, None]
    los = pt >= 0.05 * pt.max()
    ct = (z * truth).sum(axis=0)[los] / pt[los]
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = (z * x).sum(axis=0)[los] / px[los]
    err = np.abs(np.where(np.isfinite(cx), cx - ct, np.nan))
    e = err[np.isfinite(err)]
    return dict(rel_3d=rel, projection=proj, centroid_mean_mm=float(e.mean()) if len(e) else np.nan,
                centroid_p90_mm=float(np.percentile(e, 90)) if len(e) else np.nan,
                centroid_worst_mm=float(e.max()) if len(e) else np.nan, lines_unlit=int((~np.isfinite(err)).sum()),
                lines=int(los.sum()))


def run(a):
    cam = PAPER_CAMERA
    scenes = SCENES[:1] if a.quick else SCENES
    depths = list(np.round((np.arange(a.planes) - (a.planes - 1) / 2) * a.step, 6))
    t0 = time.perf_counter()
    op = ExactOperator(cam, depths, precision="float32")
    op_s = time.perf_counter() - t0
    slopes = [cam.slope_for_depth(d) for d in depths]
    mask = aperture_mask(cam.pixels_per_lenslet)
    rows, renders, figs = [], [], {}
    for name, seed, kw in scenes:
        scene, clean, noisy, own, snr, render_s = render_set(cam, name, seed, kw, a.rays, a.cache)
        obj = scene.objects[0]
        truth = scene_truth(scene, op)
        renders.append(dict(scene=name, seed=seed, own_error=own, snr_db=snr, render_or_load_s=render_s))
        print(f"{name}: own error {own:.4f}, SNR {snr:.2f} dB", flush=True)
        for noise, views in (("noise-free", clean), ("14 dB", noisy)):
            lab = dict(scene=name, seed=seed, noise=noise, own_error=own, true_x_mm=obj.get("centre_x_mm", 0.0),
                       true_z_mm=obj["depth_offset_mm"])
            t = time.perf_counter()
            res = solve_axisymmetric(views, op, views < 1.0, camera=cam)
            rows.append(dict(lab, route="axisymmetric", time_s=time.perf_counter() - t, axis_x_mm=res.axis_x_mm,
                             axis_z_mm=res.axis_z_mm, residual=res.residual, **metrics(res.volume, truth, depths)))
            t = time.perf_counter()
            rec = reconstruct(views, op, "admm")
            rows.append(dict(lab, route="admm (dense, no prior)", time_s=time.perf_counter() - t,
                             **metrics(rec.planes, truth, depths)))
            t = time.perf_counter()
            fs = focal_stack(views, slopes, mask).astype(np.float64)
            scale = float((fs * truth).sum() / max((fs * fs).sum(), 1e-30))
            rows.append(dict(lab, route="shift-and-sum (scaled)", time_s=time.perf_counter() - t,
                             **metrics(fs * scale, truth, depths)))
            if noise == "noise-free" and not figs:
                figs = dict(name=name, truth=truth, axi=res.volume, admm=rec.planes, x=res.axis_x_mm)
            print("  " + noise + ": " + ", ".join(f"{r['route']} {r['rel_3d']:.3f}" for r in rows[-3:]), flush=True)
    return pd.DataFrame(rows), renders, figs, op_s, depths


def figure(figs, depths, op, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    t = figs["truth"]
    row = int(np.argmax(t.sum(axis=(0, 2))))                      # the brightest row: an x-z slice
    p = int(np.argmax(t.sum(axis=(1, 2))))
    fig, ax = plt.subplots(2, 3, figsize=(11, 6))
    vmax = t.max()
    for j, (lab, x) in enumerate((("truth", t), ("axisymmetric", figs["axi"]), ("admm, no prior", figs["admm"]))):
        ax[0, j].imshow(x[:, row, :], aspect="auto", vmin=0, vmax=vmax, cmap="inferno",
                        extent=(0, x.shape[2], depths[-1], depths[0]))
        ax[0, j].set_title(f"{lab}: x-z slice, row {row}")
        ax[0, j].set_xlabel("column (lenslets)")
        ax[0, j].set_ylabel("depth (mm)")
        ax[1, j].imshow(x[p], vmin=0, vmax=vmax, cmap="inferno")
        ax[1, j].set_title(f"{lab}: plane {depths[p]:+.1f} mm")
    fig.suptitle(f"{figs['name']} (noise-free)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=Path("data/volume"))
    ap.add_argument("--rays", type=int, default=200)
    ap.add_argument("--planes", type=int, default=41)
    ap.add_argument("--step", type=float, default=0.5)
    ap.add_argument("--quick", action="store_true", help="one scene, 16 rays, 21 planes every 1 mm (a smoke test)")
    a = ap.parse_args(argv)
    if a.quick:
        a.rays, a.planes, a.step = 16, 21, 1.0
    t0 = time.perf_counter()
    df, renders, figs, op_s, depths = run(a)
    wall = time.perf_counter() - t0
    a.out.mkdir(parents=True, exist_ok=True)
    stem = "volume_quick" if a.quick else "volume"
    df.to_csv(a.out / f"{stem}.csv", index=False)
    figure(figs, depths, None, a.out / f"{stem}.png")
    g = df.groupby(["route", "noise"], sort=False)
    summ = g.agg(rel_3d_median=("rel_3d", "median"), rel_3d_worst=("rel_3d", "max"),
                 projection_median=("projection", "median"), centroid_mean_mm=("centroid_mean_mm", "mean"),
                 centroid_p90_mm_worst=("centroid_p90_mm", "max"), time_s_median=("time_s", "median")).reset_index()
    ax = df[df.route == "axisymmetric"]
    own = [r["own_error"] for r in renders]
    cmd = "python experiments/volume.py --out " + str(a.out) + (" --quick" if a.quick else "")
    lines = [f"# Axisymmetric volumes (issue 36, step 2)", "",
             f"`{cmd}` ({wall / 60:.1f} min wall on this 2-core machine). {len(renders)} scenes, "
             f"{N_LAYERS} layers each, traced at {a.rays} rays per pixel: own error "
             f"{min(own) * 100:.2f}–{max(own) * 100:.2f} % (two seeds); 14 dB measured "
             f"{min(r['snr_db'] for r in renders):.2f}–{max(r['snr_db'] for r in renders):.2f} dB. "
             f"Dense stack: {a.planes} planes every {a.step} mm from {depths[0]:+g} to {depths[-1]:+g} mm "
             f"(exact operator, float32, setup {op_s:.1f} s). Truth: scene_truth on the same planes.", "",
             "Per route and noise: 3-D relative L2 error (median / worst over scenes), projection error "
             "(median), per-line-of-sight depth-centroid error (mean over scenes of each scene's mean; worst "
             "scene's p90), time per light field (median).", "",
             "| route | noise | 3-D error median / worst | projection median | centroid mean / p90 worst (mm) | "
             "time (s) |", "|---|---|---|---|---|---|"]
    for _, r in summ.iterrows():
        lines.append(f"| {r.route} | {r.noise} | {r.rel_3d_median:.3f} / {r.rel_3d_worst:.3f} | "
                     f"{r.projection_median:.3f} | {r.centroid_mean_mm:.2f} / {r.centroid_p90_mm_worst:.2f} | "
                     f"{r.time_s_median:.1f} |")
    lines += ["", "Per scene (axisymmetric route): axis found against the truth.", "",
              "| scene | noise | 3-D error | x0 found / true (mm) | z0 found / true (mm) | residual |",
              "|---|---|---|---|---|---|"]
    for _, r in ax.iterrows():
        lines.append(f"| {r.scene} | {r.noise} | {r.rel_3d:.3f} | {r.axis_x_mm:+.3f} / {r.true_x_mm:+.2f} | "
                     f"{r.axis_z_mm:+.3f} / {r.true_z_mm:+.2f} | {r.residual:.4f} |")
    lines += ["", "Shift-and-sum is scaled by its least-squares factor against the truth (optimistic for it). "
              "Full rows: " + f"[{stem}.csv]({stem}.csv); figure [{stem}.png]({stem}.png).", ""]
    atomic_write_text(a.out / f"{stem}.md", "\n".join(lines))
    meta = dict(command=cmd, rays=a.rays, planes=a.planes, step_mm=a.step, snr_db=SNR_DB, n_layers=N_LAYERS,
                scenes=[dict(name=n, seed=s, **k) for n, s, k in (SCENES[:1] if a.quick else SCENES)],
                renders=renders, wall_s=wall, operator_setup_s=op_s, provenance=provenance())
    atomic_write_text(a.out / f"{stem}.json", json.dumps(meta, indent=1, default=str))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
