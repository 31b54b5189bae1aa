"""Two-colour temperature per voxel of axisymmetric volumetric flames from one colour light field.

Writes ``<out>/temperature_volume.{csv,md,json,png}``.

- **Camera, sensor, calibration**: as ``experiments/temperature.py`` (the paper's camera, RGGB
  phase (0, 0), Nikon 5100 sensitivities, gains ``GAINS`` unknown to the pyrometer; the R/G gain
  ratio fitted on blackbody furnace renders at ``FIT_K`` by its ``calibrate``, written to
  ``--cache``, not over ``results/temperature_calibration.json``).
- **Volumes** (:data:`VOLUMES`): :func:`lf_flame.simulate.scenes_volume_temperature.colour_axisymmetric_scene`
  (soot: the sheath / core / blend of ``axisymmetric_flame_scene``, 32 layers; ``T(r, y)``
  hottest on the sheath, cooling with height), different axes, diameters, peak temperatures;
  each channel traced at ``--rays`` rays per pixel, the mosaic clipped (noise-free) and at
  14 dB (``experiments/temperature.py``'s ``add_noise``); the own error from the G channel
  traced again with a second seed. Renders cached in ``--cache``.
- **Dense stack**: ``--planes`` planes every ``--step`` mm about 0 (ExactOperator, float32).
  Truth per voxel: each channel's ``scene_truth`` on it, R/G -> T by the calibration's lookup;
  on the ``(r, y)`` nodes: ``axisymmetric_node_truth`` (the analytic field).
- **Routes**: ``axisymmetric`` (:func:`lf_flame.temperature.axisymmetric.axisymmetric_temperature`:
  the axis found once on the channels' sum, each channel solved on its own unsaturated
  samples, the ratio to T on nodes and voxels: the first pass of the matched call, its
  ``own_samples``); ``axisymmetric-matched`` (``matched=True``: each channel's volume then
  imaged again and solved on the other channel's samples; its time includes the first pass);
  ``refocus-cfa`` (each channel's samples
  refocused at every plane's slope, the ratio per voxel: the focal-stack baseline).
- **Scores**: |T - T_true| over the voxels (and nodes) whose true R+G emission is >= 10 % of the
  volume's peak: median, p90, worst over those the route reports; share masked (bright truth
  voxels the route leaves without a temperature).

Usage: ``python experiments/temperature_volume.py --out results [--quick]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import temperature as TE  # noqa: E402  (calibration, 14 dB noise of make temperature)

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.measure.metrics import own_error  # noqa: E402
from lf_flame.temperature import pyrometry as P  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.optics.colour import library_sensor, mosaic  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, raw_to_views  # noqa: E402
from lf_flame.simulate import tracer  # noqa: E402
from lf_flame.simulate.scenes_volume_temperature import (axisymmetric_node_truth, axisymmetric_voxel_truth,  # noqa: E402
                                                         colour_axisymmetric_scene)
from lf_flame.temperature.axisymmetric import (COLOUR_FILLS, COLOUR_INNER, axisymmetric_temperature,  # noqa: E402
                                              volume_temperature)  # noqa: E402
from lf_flame.temperature.channels import refocus_channel  # noqa: E402
from lf_flame.temperature.mosaic import channel_views  # noqa: E402
from lf_flame.tomo.exact import ExactOperator  # noqa: E402
from lf_flame.tomo.truth import scene_truth  # noqa: E402

N_LAYERS = 32
#: smoothness of each channel's solve (relative, solve_axisymmetric); swept on volumes 0-1 with the true axis
#: (centre truth, p90): at 14 dB 1e-3 237/288 K, 0.01 179/214 K, 0.1 96/102 K, 1 117/72 K, 10 168 K (volume 0);
#: noise-free, volume 1: 1e-3 74 K, 0.1 21 K. Chosen on the volumes scored (not held out).
LAM = 0.1
SEED0 = 937500
#: (name, generator keywords): different axes, diameters, peak temperatures, sheath / core
VOLUMES = (
    ("sheath D8 x+0.8 z+2.3, 2100 K", dict(centre_depth_mm=2.3, centre_x_mm=0.8, diameter_mm=8.0, core=0.0,
                                           peak_k=2100.0)),
    ("core D7 x-0.6 z-3.1, 1900 K", dict(centre_depth_mm=-3.1, centre_x_mm=-0.6, diameter_mm=7.0, core=1.0,
                                         peak_k=1900.0)),
    ("sheath+core D6 x+0.4 z+1.2, 2000 K", dict(centre_depth_mm=1.2, centre_x_mm=0.4, diameter_mm=6.0, core=0.5,
                                                peak_k=2000.0)),
)


def channel_scene(cs, c):
    return dataclasses.replace(cs.scene, layers=tuple(dataclasses.replace(L, radiance=cs.channel_radiance[k][c])
                                                      for k, L in enumerate(cs.scene.layers)))


def render(cam, cs, sensor, rays, seed, path: Path):
    """Clean (clipped) and 14 dB mosaics, the own error (G traced again, seed + 7), SNR; cached in ``path``."""
    t0 = time.perf_counter()
    if not path.exists():
        chans = np.stack([tracer.render(cam, channel_scene(cs, c), rays, seed, sensor=False) for c in range(3)])
        other = tracer.render(cam, channel_scene(cs, 1), rays, seed + 7, sensor=False)
        own = own_error(chans[1], other)
        clean = tracer.apply_sensor(mosaic(chans, sensor), cs.scene.effects, seed)
        noisy, fw = TE.add_noise(clean, cs.scene.effects, seed)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".partial.npz")
        np.savez_compressed(tmp, clean=clean, noisy=noisy, own=own, fw=fw)
        tmp.rename(path)
    f = np.load(path)
    clean, noisy = f["clean"], f["noisy"]
    snr = float(10 * np.log10(np.sum(clean.astype(float) ** 2) / np.sum((noisy - clean.astype(float)) ** 2)))
    snr_c = TE.snr_per_channel(clean, noisy, sensor.channel_map(clean.shape))
    return dict(clean=clean, noisy=noisy, own=float(f["own"]), fw=float(f["fw"]), snr=snr, snr_c=snr_c,
                render_or_load_s=time.perf_counter() - t0)


def errors(T, valid, Tt, vt):
    sel = vt & valid
    e = np.abs(T - Tt)[sel]
    n = int(vt.sum())
    return dict(n_truth=n, n_reported=int(sel.sum()), share_masked=float((vt & ~valid).sum() / max(n, 1)),
                median_k=float(np.median(e)) if e.size else np.nan,
                p90_k=float(np.percentile(e, 90)) if e.size else np.nan, worst_k=float(e.max()) if e.size else np.nan)


def run(a, log, write=None):
    cam = PAPER_CAMERA
    sensor = library_sensor(gains=TE.GAINS)
    model = library_sensor()
    a.cache.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cal, bb = TE.calibrate(cam, sensor, model, a.cal_rays, TE.SEED0, a.cache)
    cal_s = time.perf_counter() - t0
    log(f"calibration: gain ratio {cal.gain_ratio:.5f} (true {TE.GAINS[0] / TE.GAINS[1]:.5f}), checks "
        f"{[round(r['error_k'], 2) for r in bb]} K ({cal_s:.0f} s)")
    depths = list(np.round((np.arange(a.planes) - (a.planes - 1) / 2) * a.step, 6))
    t0 = time.perf_counter()
    op = ExactOperator(cam, depths, precision="float32")
    op_s = time.perf_counter() - t0
    slopes = [cam.slope_for_depth(d) for d in depths]
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    rows, info, fig = [], [], None
    for i, (name, kw) in enumerate(VOLUMES[:a.volumes]):
        seed = SEED0 + i
        cs = colour_axisymmetric_scene(cam, sensor, np.random.default_rng(seed), n_layers=N_LAYERS, **kw)
        obj = cs.scene.objects[0]
        r = render(cam, cs, sensor, a.rays, seed, a.cache / f"tvol_{seed}_{a.rays}.npz")
        info.append(dict(volume=name, seed=seed, **kw, height_mm=obj["height_mm"], own_error=r["own"],
                         full_well_e=r["fw"], snr_db=r["snr"], snr_db_per_channel=r["snr_c"],
                         render_or_load_s=r["render_or_load_s"]))
        log(f"{name}: own error {r['own']:.4f}, 14 dB measured {r['snr']:.2f} dB {r['snr_c']}")
        tr = [scene_truth(channel_scene(cs, c), op) for c in (0, 1)]
        Tt, vt, _ = volume_temperature(tr[0], tr[1], cal, model, min_fraction=0.0)
        vt = (tr[0] + tr[1]) >= P.MIN_FRACTION * float((tr[0] + tr[1]).max())
        Tc, ec = axisymmetric_voxel_truth(cs, sensor, op)
        vc = (ec[0] + ec[1]) >= P.MIN_FRACTION * float((ec[0] + ec[1]).max())
        chan = channel_views(r["clean"].shape, sensor, cam.pixels_per_lenslet)
        for noise, raw in (("noise-free", r["clean"]), (f"{TE.SNR_DB:g} dB", r["noisy"])):
            views = raw_to_views(raw, cam.pixels_per_lenslet)
            lab = dict(volume=name, noise=noise, own_error=r["own"], snr_db=r["snr"] if noise != "noise-free" else np.inf,
                       true_x_mm=kw["centre_x_mm"], true_z_mm=kw["centre_depth_mm"])
            res_m = axisymmetric_temperature(views, op, chan, cal, model, camera=cam, matched=True,
                                             lam=a.lam if noise == "noise-free" else a.lam_noisy)
            res, dt = res_m.own_samples, res_m.own_samples.time_s
            Tn, en = axisymmetric_node_truth(cs, sensor, res.radii_mm, res.heights_mm)
            bn = (en[0] + en[1]) >= P.MIN_FRACTION * float((en[0] + en[1]).max())
            ex = dict(axis_x_mm=res.axis_x_mm, axis_z_mm=res.axis_z_mm)
            for route, x in (("axisymmetric", res), ("axisymmetric-matched", res_m)):
                ex = dict(ex, time_s=x.time_s)
                rows.append(dict(lab, route=route, grid="voxels (slab truth)", **ex,
                                 **errors(x.temperature_volume, x.valid_volume, Tt, vt)))
                rows.append(dict(lab, route=route, grid="voxels (centre truth)", **ex,
                                 **errors(x.temperature_volume, x.valid_volume, Tc, vc)))
                rows.append(dict(lab, route=route, grid="(r, y) nodes", **ex,
                                 **errors(x.temperature, x.valid, Tn, bn)))
            t = time.perf_counter()
            fs = [refocus_channel(views, chan == c, slopes, mask) for c in (0, 1)]
            Tf, vf, _ = volume_temperature(fs[0], fs[1], cal, model)
            dt_f = time.perf_counter() - t
            rows.append(dict(lab, route="refocus-cfa (focal stack ratio)", grid="voxels (slab truth)", time_s=dt_f,
                             **errors(Tf, vf, Tt, vt)))
            rows.append(dict(lab, route="refocus-cfa (focal stack ratio)", grid="voxels (centre truth)", time_s=dt_f,
                             **errors(Tf, vf, Tc, vc)))
            log("  " + noise + ": " + "; ".join(f"{x['route']} {x['grid']} median {x['median_k']:.1f} p90 "
                                                  f"{x['p90_k']:.1f} worst {x['worst_k']:.1f} K, masked "
                                                  f"{x['share_masked']:.3f}" for x in rows[-8:])
                + f" (axis {res.axis_x_mm:+.3f}, {res.axis_z_mm:+.3f} mm; {dt:.0f} s)")
            if fig is None:
                fig = dict(name=name, Tt=Tt, vt=vt, Ta=res.temperature_volume, Tf=Tf, Tn=np.where(bn, Tn, np.nan),
                           Tr=res.temperature, radii=res.radii_mm, heights=res.heights_mm, depths=depths)
        if write is not None:                                        # partial results after each volume
            write(pd.DataFrame(rows), info, fig, dict(calibration=dataclasses.asdict(cal), blackbody_checks=bb,
                                                      calibration_s=cal_s, operator_setup_s=op_s, depths_mm=depths))
    return pd.DataFrame(rows), info, fig, dict(calibration=dataclasses.asdict(cal), blackbody_checks=bb,
                                               calibration_s=cal_s, operator_setup_s=op_s, depths_mm=depths)


def figure(f, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    row = int(np.argmax(f["vt"].sum(axis=(0, 2))))
    fig, ax = plt.subplots(1, 5, figsize=(19, 4.4))
    lo, hi = np.nanmin(np.where(f["vt"], f["Tt"], np.nan)), np.nanmax(np.where(f["vt"], f["Tt"], np.nan))
    d = f["depths"]
    for j, (lab, T) in enumerate((("truth", np.where(f["vt"], f["Tt"], np.nan)), ("axisymmetric", f["Ta"]),
                                  ("refocus-cfa", f["Tf"]))):
        im = ax[j].imshow(T[:, row, :], aspect="auto", vmin=lo, vmax=hi, cmap="inferno",
                          extent=(0, T.shape[2], d[-1], d[0]))
        ax[j].set_title(f"{lab}: T, x-z, row {row}", fontsize=9)
        ax[j].set_xlabel("column (lenslets)")
        ax[j].set_ylabel("depth (mm)")
    ext = (f["radii"][0], f["radii"][-1], f["heights"][-1], f["heights"][0])
    for j, (lab, T) in enumerate((("truth T(r, y)", f["Tn"]), ("axisymmetric T(r, y)", f["Tr"]))):
        im = ax[3 + j].imshow(T, aspect="auto", vmin=lo, vmax=hi, cmap="inferno", extent=ext)
        ax[3 + j].set_title(lab, fontsize=9)
        ax[3 + j].set_xlabel("r (mm)")
        ax[3 + j].set_ylabel("y (mm)")
    fig.colorbar(im, ax=ax, label="K", shrink=0.8)
    fig.suptitle(f"{f['name']} (noise-free); masked: white", y=0.99)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=Path("data/temperature_volume"))
    ap.add_argument("--rays", type=int, default=32, help="rays per pixel of each channel's render")
    ap.add_argument("--cal-rays", type=int, default=32, help="rays per pixel of the blackbody renders")
    ap.add_argument("--planes", type=int, default=41)
    ap.add_argument("--step", type=float, default=0.5)
    ap.add_argument("--volumes", type=int, default=len(VOLUMES))
    ap.add_argument("--lam", type=float, default=LAM, help="smoothness of each channel's solve, noise-free")
    ap.add_argument("--lam-noisy", type=float, default=LAM, help="... and at 14 dB")
    ap.add_argument("--quick", action="store_true", help="one volume, 8 rays, 21 planes every 1 mm (a smoke test)")
    a = ap.parse_args(argv)
    if a.quick:
        a.rays, a.cal_rays, a.planes, a.step, a.volumes = 8, 8, 21, 1.0, 1

    def log(msg):
        print(msg, flush=True)

    t0 = time.perf_counter()

    def partial(df, info, fig, meta):
        write(a, df, info, fig, meta, time.perf_counter() - t0, partial=True)

    df, info, fig, meta = run(a, log, partial)
    write(a, df, info, fig, meta, time.perf_counter() - t0)


def write(a, df, info, fig, meta, wall, partial=False):
    a.out.mkdir(parents=True, exist_ok=True)
    stem = "temperature_volume_quick" if a.quick else "temperature_volume"
    df.to_csv(a.out / f"{stem}.csv", index=False)
    figure(fig, a.out / f"{stem}.png")
    cmd = (f"python experiments/temperature_volume.py --out {a.out}" + (" --quick" if a.quick else "")
           + (f" --lam {a.lam:g}" if a.lam != LAM else "") + (f" --lam-noisy {a.lam_noisy:g}" if a.lam_noisy != LAM else ""))
    cols = ["volume", "noise", "route", "grid", "n_truth", "share_masked", "median_k", "p90_k", "worst_k", "time_s"]
    g = df.groupby(["route", "grid", "noise"], sort=False).agg(
        median_of_medians=("median_k", "median"), p90_worst_volume=("p90_k", "max"), worst=("worst_k", "max"),
        share_masked_max=("share_masked", "max")).reset_index()
    bb = meta["blackbody_checks"]
    lines = ["# Two-colour temperature per voxel of axisymmetric flames", "",
             f"`{cmd}` ({wall / 60:.1f} min wall on this 2-core machine); commit {provenance().get('git_commit')}."
             + (f" PARTIAL: {len(info)} of {a.volumes} volumes done." if partial else ""),
             f"Camera: the paper's, RGGB phase (0, 0), Nikon 5100 (NPL), gains {TE.GAINS}; calibration fitted on "
             f"furnace renders at {TE.FIT_K} K ({a.cal_rays} rays/pixel): gain ratio "
             f"{meta['calibration']['gain_ratio']:.5f} (true {TE.GAINS[0] / TE.GAINS[1]:.5f}); checks at "
             f"{TE.CHECK_K} K: worst {max(abs(x['error_k']) for x in bb):.2f} K.",
             f"Volumes: `colour_axisymmetric_scene`, {N_LAYERS} layers, traced per channel at {a.rays} rays/pixel; "
             f"own error (G, two seeds) {[round(x['own_error'], 4) for x in info]}; 14 dB measured "
             f"{[round(x['snr_db'], 2) for x in info]} dB, per channel "
             f"{[{k: round(v, 2) for k, v in x['snr_db_per_channel'].items()} for x in info]}.",
             f"Dense stack: {a.planes} planes every {a.step} mm, {meta['depths_mm'][0]:+g} to "
             f"{meta['depths_mm'][-1]:+g} mm (ExactOperator float32). Each channel's solve: smoothness lam {a.lam:g} "
             f"noise-free, {a.lam_noisy:g} at 14 dB (relative, `solve_axisymmetric`), {COLOUR_FILLS} fills x "
             f"{COLOUR_INNER} steps. Scored over the voxels (nodes) with >= 10 % of "
             "the volume's peak true R+G emission; `share_masked`: of those, the share the route leaves without a "
             "temperature (its own R+G below 10 % of its peak, or ratio out of the lookup). Truth per voxel: `slab` = "
             "each channel's `scene_truth` (the 32 thin layers shared between the two nearest planes, linearly in "
             "depth), R/G -> T; `centre` = the analytic T and emission at the voxel's centre "
             "(`axisymmetric_voxel_truth`, what the axisymmetric model samples); nodes: `axisymmetric_node_truth`.",
             "",
             "## Summary (over volumes: median of medians, worst volume's p90, worst voxel)", "",
             g.to_markdown(index=False, floatfmt=".2f"), "", "## Per volume", "",
             df[cols].to_markdown(index=False, floatfmt=".2f"), ""]
    axr = df[df.route.str.startswith("axisymmetric")]
    for (route, grid, noise), r in axr.groupby(["route", "grid", "noise"], sort=False):
        p90 = float(r.p90_k.max())
        lines.append(f"- {route}, {grid}, {noise}: worst volume's p90 {p90:.1f} K (Goal 50 K) -> "
                     f"**{'met' if p90 <= 50 else 'NOT met'}**")
    ax = axr[(axr.grid == "voxels (slab truth)") & (axr.route == "axisymmetric")]
    lines += ["", "Axis found (x0, z0) against the truth: " + "; ".join(
        f"{r.volume} {r.noise}: {r.axis_x_mm:+.3f}/{r.true_x_mm:+.2f}, {r.axis_z_mm:+.3f}/{r.true_z_mm:+.2f} mm"
        for r in ax.itertuples()), "", f"Figure: [{stem}.png]({stem}.png); rows: [{stem}.csv]({stem}.csv).", ""]
    atomic_write_text(a.out / f"{stem}.md", "\n".join(lines))
    atomic_write_text(a.out / f"{stem}.json", json.dumps(dict(
        command=cmd, lam=a.lam, lam_noisy=a.lam_noisy, rays=a.rays, cal_rays=a.cal_rays, planes=a.planes, step_mm=a.step, n_layers=N_LAYERS,
        volumes=info, wall_s=wall, partial=partial, provenance=provenance(), **meta), indent=1, default=str))
    if not partial:
        print("\n".join(lines))


if __name__ == "__main__":
    main()
