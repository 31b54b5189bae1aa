"""A matrix of cameras, end to end from the command line: white image, calibration, decoding,
found depths and each plane's emission, scored against the truth in each camera's object frame.

Cameras (:data:`CAMERAS`; each a camera file written to ``<cache>/<camera>/camera.toml``):

- ``paper``: the paper's camera (15 views, 180 x 90 lenslets of 112 µm), given as its data
  config (``data_gen/paper.toml``);
- ``example``: ``examples/own_camera.toml`` (10.57 px pitch, rotated 0.4°, offset);
- ``48px``: 300 µm lenslets of 18.6 mm focal length 400 mm behind a 200 mm lens, 6.45 µm
  pixels, a 1280 x 960 sensor (the real capture's geometry; the datasheet model gives a
  48.67 px pitch, where the capture measured 48.2: its MLA sits a little farther);
- ``hex``: the example camera with a hexagonal lenslet grid;
- ``rotated``: 110 µm lenslets of 2.2 mm behind a 75 mm f/16 lens focused at 300 mm,
  9 µm pixels (12.5 px pitch), rotated -0.4° and offset, on a 1000 x 800 sensor.

For each camera, every step is an ``lf-flame`` command run in-process
(:func:`lf_flame.cli.main`, the same parser and code as the shell):
``simulate --scene white`` -> ``calibrate`` -> per scene ``simulate --scene depth --seed S``
(2-4 flames at random depths, sizes and places scaled to the camera:
:func:`lf_flame.simulate.scenes_depth.camera_depth_scene`) -> ``decode`` (its default binning: the 48 px
camera's views 3 x 3 pixels each) -> ``reconstruct``
(depths found over the camera's imaging range, admm on the exact operator of the decoded
views' camera); on the first scene also ``refocus --depth``, ``slopes`` and ``profiles`` (each
flame's height on the decoded views at the flames' depths). Noise: the noise-free render, and 14 dB of shot and read
noise on it (``experiments/depth.py``'s ``add_noise``). The render's own error (two ray seeds,
``||r1 - r2|| / (sqrt 2 ||r1||)``) is measured on the first scene.

Scored per flame by :func:`lf_flame.tomo.scoring.score_flames` on the decoded frame
(``frame=``: the truth where the decoded planes lie): depth error in mm and in slope units
(lenslets per view step, ``slope_for_depth`` of the real camera), emission error on the plane
nearest its found depth, height. Calibration: pitch (%) and rotation (degrees) against the
camera file. Time: admm's solve per lenslet-plane (µs), and each command's wall time.

Writes ``<out>/cameras.csv`` (one row per flame, camera and noise), ``cameras_runs.csv`` (one row
per command), ``cameras.md`` (the bars per camera), ``cameras.json`` (settings, own errors,
provenance) and ``cameras.png``. Usage: ``python experiments/cameras.py --out results
[--scenes 6] [--rays 1296] [--only example,hex] [--quick]``; renders and outputs are kept in
``--cache`` (default ``data/cameras``).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

EXAMPLE = tomllib.loads((ROOT / "examples" / "own_camera.toml").read_text())
#: Camera files (datasheet tables, docs/own_camera.md); None: the paper's camera (its data config).
CAMERAS = {
    "paper": None,
    "example": EXAMPLE,
    "48px": {"main_lens": {"focal_length_mm": 200.0, "mla_distance_mm": 400.0},
             "microlens_array": {"pitch_um": 300.0, "focal_length_mm": 18.6},
             "sensor": {"pixel_size_um": 6.45, "rows": 960, "cols": 1280}},
    "hex": {**EXAMPLE, "microlens_array": {**EXAMPLE["microlens_array"], "layout": "hex"}},
    "rotated": {"main_lens": {"focal_length_mm": 75.0, "f_number": 16.0, "focus_distance_mm": 300.0},
                "microlens_array": {"pitch_um": 110.0, "focal_length_mm": 2.2, "rotation_deg": -0.4,
                                    "offset_px": [1.7, -2.6]},
                "sensor": {"pixel_size_um": 9.0, "rows": 1000, "cols": 800}},
}
SEED0 = 56000
SNR_DB = 14.0
#: Rays per pixel of the scenes' renders, for an own error under 1 % on every camera (0.35-0.48 %; at 48 rays it was
#: 3.0-4.8 %, the paper camera's the largest), and of the white images that calibration and decoding take (a real
#: flat field is averaged over frames; 16 rays leave a few per cent per pixel).
RAYS, WHITE_RAYS = 1296, 256
#: The bars (noise-free; at 14 dB twice these): depth error in slope units, p90 and worst;
#: emission error on 90 % of flames.
BARS = dict(depth_p90=0.03, depth_worst=0.1, emission_p90=0.10)
#: The reconstruct routes scored: the default, and each found plane held to its regions (``--support``).
ROUTES = {"admm": (), "support": ("--support",)}


def _toml(sheet: dict) -> str:
    def value(v):
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)
    return "\n".join(f"[{t}]\n" + "\n".join(f"{k} = {value(v)}" for k, v in keys.items()) + "\n"
                     for t, keys in sheet.items())


class Runner:
    """``lf-flame`` commands in-process, each timed and recorded (its output kept for the log)."""

    def __init__(self, camera_name):
        self.camera_name, self.rows = camera_name, []

    def __call__(self, *argv, step=None):
        from lf_flame.cli import main
        out = io.StringIO()
        t = time.perf_counter()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            rc = main([str(a) for a in argv])
        dt = time.perf_counter() - t
        text = out.getvalue()
        self.rows.append(dict(camera=self.camera_name, command=argv[0], step=step or argv[0], exit_code=rc,
                              wall_s=dt, message="" if rc == 0 else text.strip().splitlines()[-1]))
        if rc != 0:
            print(f"  [{self.camera_name}] lf-flame {' '.join(map(str, argv))} -> exit {rc}: {text.strip()[-300:]}",
                  flush=True)
        return rc, text


def _noisy_copy(src: Path, dst: Path, seed: int):
    """The simulate file ``src`` with 14 dB of shot and read noise on its raw image (every other entry kept)."""
    from depth import add_noise
    z = dict(np.load(src))
    z["raw"], snr = add_noise(z["raw"], SNR_DB, seed)
    np.savez_compressed(dst, **z)
    return snr


def run_camera(name, sheet, cache: Path, seeds, rays: int) -> tuple[list, list, dict]:
    """Every step of one camera; (flame rows, command rows, facts)."""
    from lf_flame.cli._io import _raw_scene, camera_config
    from lf_flame.real.calibration import GridCalibration
    from lf_flame.measure.metrics import own_error
    from lf_flame.real.readers import read_light_field
    from lf_flame.simulate import tracer
    from lf_flame.tomo.files import load_found, load_reconstruction
    from lf_flame.tomo.scoring import score_flames
    d = cache / name
    d.mkdir(parents=True, exist_ok=True)
    cam_file = ROOT / "data_gen" / "paper.toml" if sheet is None else d / "camera.toml"
    if sheet is not None:
        cam_file.write_text(_toml(sheet))
    cam = camera_config(str(cam_file))
    run = Runner(name)
    facts = dict(camera=name, camera_file=str(cam_file.relative_to(ROOT)) if sheet is None else _toml(sheet),
                 sensor=list(cam.sensor_shape), layout=cam.grid_layout,
                 pitch_px_true=float(cam.grid_pitch_px or cam.pixels_per_lenslet),
                 rotation_deg_true=float(cam.grid_rotation_deg))
    run("simulate", "--scene", "white", "--camera", cam_file, "--rays-per-pixel", WHITE_RAYS, "--out", d / "white.npz")
    rc, _ = run("calibrate", d / "white.npz", "--out", d / "calibration.json")
    if rc:
        return [], run.rows, facts
    cal = GridCalibration.load(d / "calibration.json")
    facts.update(pitch_px=cal.pitch_px, rotation_deg=cal.rotation_deg,
                 pitch_err_pct=100 * (cal.pitch_px / facts["pitch_px_true"] - 1),
                 rotation_err_deg=cal.rotation_deg - facts["rotation_deg_true"])
    rows = []
    for i, seed in enumerate(seeds):
        raw = d / f"scene{seed}_{rays}rays.npz"
        if not raw.exists():
            run("simulate", "--scene", "depth", "--seed", seed, "--camera", cam_file, "--rays-per-pixel", rays,
                "--out", raw)
        scene = _raw_scene(raw, cam)
        if i == 0:      # the render's own error: the same scene with other rays
            facts["own_error"] = own_error(np.load(raw)["raw"], tracer.render(cam, scene, rays, seed + 1))
        for noise in ("clean", "14dB"):
            src = raw
            if noise == "14dB":
                src = d / f"scene{seed}_14dB.npz"
                if not src.exists():
                    _noisy_copy(raw, src, seed)
            views = d / f"views{seed}_{noise}.h5"
            rc, _ = run("decode", src, "--calibration", d / "calibration.json", "--out", views)
            if rc:
                continue
            if i == 0 and noise == "clean":
                o = scene.objects[0]
                run("refocus", views, "--camera", cam_file, "--calibration", d / "calibration.json", "--depth",
                    f"{o['depth_offset_mm']:.3f}", "--out", d / "refocus.npz")
                run("slopes", views, "--camera", cam_file, "--calibration", d / "calibration.json",
                    "--out-prefix", d / "slopes")
                run("profiles", views, "--camera", cam_file, "--calibration", d / "calibration.json",
                    *[x for o in scene.objects for x in ("--depth", f"{o['depth_offset_mm']:.3f}")],
                    "--out", d / "profiles")
            lf = read_light_field(views, cam, d / "calibration.json")
            for route, flags in ROUTES.items():
                rec_file = d / f"rec{seed}_{noise}_{route}.h5"
                rc, _ = run("reconstruct", views, "--camera", cam_file, "--calibration", d / "calibration.json",
                            "--out", rec_file, *flags, step=f"reconstruct ({route})")
                if rc:
                    continue
                rec = load_reconstruction(rec_file)
                df = score_flames(rec.planes, rec.depths_mm, scene, lf.camera, found=load_found(rec_file),
                                  frame=lf.frame, time_s=rec.time_s, route=route, noise=noise, seed=seed)
                df.insert(0, "camera", name)
                df["slope_err"] = [abs(cam.slope_for_depth(e) - cam.slope_for_depth(t)) if np.isfinite(e) else np.nan
                                   for e, t in zip(df.depth_mm, df.depth_mm_true)]
                P, R, C = rec.planes.shape
                df["us_per_lenslet_plane"] = 1e6 * rec.time_s / (P * R * C)
                rows.extend(df.to_dict("records"))
                print(f"  [{name}] seed {seed} {noise} {route}: " + "; ".join(
                    f"{t:+.2f} -> {e:+.2f} mm ({s:.3f} slope), {100 * r:.1f} %"
                    for t, e, s, r in zip(df.depth_mm_true, df.depth_mm, df.slope_err, df.rel_err)), flush=True)
    return rows, run.rows, facts


def summary(flames, runs, facts):
    import pandas as pd
    out = []
    for (name, route, noise), g in flames.groupby(["camera", "route", "noise"], sort=False):
        k = 1.0 if noise == "clean" else 2.0
        slope = g.slope_err.fillna(np.inf)
        err = g.rel_err.fillna(np.inf)
        f = facts[name]
        rec = runs[(runs.camera == name) & (runs.step == f"reconstruct ({route})")]
        out.append(dict(
            camera=name, route=route, noise=noise, flames=len(g), missed=int(g.depth_mm.isna().sum()),
            depth_p90_slope=float(np.quantile(slope, 0.9)), depth_worst_slope=float(slope.max()),
            depth_p90_mm=float(np.quantile(g.depth_err_mm.abs().fillna(np.inf), 0.9)),
            emission_p90=float(np.quantile(err, 0.9)), emission_worst=float(err.max()),
            share_emission_over_bar=float((err > k * BARS["emission_p90"]).mean()),
            height_err_p90_mm=float(np.quantile(g.height_err_mm.abs().dropna(), 0.9)) if g.height_err_mm.notna().any()
            else np.nan,
            pitch_err_pct=f.get("pitch_err_pct", np.nan), rotation_err_deg=f.get("rotation_err_deg", np.nan),
            own_error=f.get("own_error", np.nan),
            admm_us_per_lenslet_plane_median=float(g.us_per_lenslet_plane.median()),
            admm_us_per_lenslet_plane_p90=float(g.us_per_lenslet_plane.quantile(0.9)),
            reconstruct_wall_s_median=float(rec.wall_s.median()) if len(rec) else np.nan,
            depth_bar=bool(np.quantile(slope, 0.9) <= k * BARS["depth_p90"] and slope.max() <= k * BARS["depth_worst"]),
            emission_bar=bool(np.quantile(err, 0.9) <= k * BARS["emission_p90"])))
    tab = pd.DataFrame(out)
    paper = tab[(tab.camera == "paper") & (tab.route == "admm") & (tab.noise == "clean")].admm_us_per_lenslet_plane_median
    if len(paper):
        tab["admm_time_vs_paper"] = tab.admm_us_per_lenslet_plane_median / float(paper.iloc[0])
    return tab


def plot(flames, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(dict.fromkeys(flames.camera))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    combos = [(r, n) for r in ROUTES for n in ("clean", "14dB")]
    for j, (route, noise) in enumerate(combos):
        g = flames[(flames.noise == noise) & (flames.route == route)]
        dx = (j - (len(combos) - 1) / 2) * 0.16
        label = f"{route}, {noise}"
        for x, name in enumerate(names):
            h = g[g.camera == name]
            if route == "admm":      # the depths are the found ones, the same for every route
                axes[0].scatter(np.full(len(h), x + dx), h.slope_err, s=12, c=f"C{j}",
                                label=label if x == 0 else None)
            axes[1].scatter(np.full(len(h), x + dx), 100 * h.rel_err, s=12, c=f"C{j}",
                            marker="o" if route == "admm" else "^", label=label if x == 0 else None)
    for ax, bar, label in ((axes[0], BARS["depth_p90"], "depth error (lenslets per view step)"),
                           (axes[1], 100 * BARS["emission_p90"], "emission error per flame (%)")):
        ax.axhline(bar, color="k", lw=0.8, ls="--", label="bar (noise-free; 14 dB: 2x)")
        ax.set_xticks(range(len(names)), names)
        ax.set_ylabel(label)
        ax.set_yscale("log")
        ax.legend(fontsize=8)
    axes[0].set_title("found depth, per flame")
    axes[1].set_title("emission on its plane, per flame")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    import pandas as pd
    from lf_flame.config import atomic_write_text, provenance
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--cache", type=Path, default=ROOT / "data" / "cameras")
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--rays", type=int, default=RAYS, help="rays per pixel of the scenes' renders")
    ap.add_argument("--only", default=None, help="comma-separated camera names (default: all)")
    ap.add_argument("--quick", action="store_true", help="2 scenes, 16 rays: a check that it runs")
    ap.add_argument("--seed0", type=int, default=SEED0, help="first scene seed (validation runs: another one)")
    a = ap.parse_args(argv)
    if a.quick:
        a.scenes, a.rays = 2, 16
    names = a.only.split(",") if a.only else list(CAMERAS)
    t0 = time.perf_counter()
    flames, runs, facts = [], [], {}
    for name in names:
        print(f"camera {name}", flush=True)
        rows, cmd_rows, f = run_camera(name, CAMERAS[name], a.cache, [a.seed0 + i for i in range(a.scenes)], a.rays)
        flames += rows
        runs += cmd_rows
        facts[name] = f
    flames, runs = pd.DataFrame(flames), pd.DataFrame(runs)
    tab = summary(flames, runs, facts)
    a.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(a.out / "cameras.csv", flames.to_csv(index=False, float_format="%.5g"))
    atomic_write_text(a.out / "cameras_runs.csv", runs.to_csv(index=False, float_format="%.4g"))
    plot(flames, a.out / "cameras.png")
    cmd = "python experiments/cameras.py --out " + str(a.out) + ("" if a.scenes == 6 else f" --scenes {a.scenes}") + \
        ("" if a.rays == RAYS else f" --rays {a.rays}") + (f" --only {a.only}" if a.only else "") + \
        ("" if a.seed0 == SEED0 else f" --seed0 {a.seed0}")
    failed = runs[runs.exit_code != 0]
    md = ["# Cameras, end to end from the command line", "",
          f"`{cmd}` ({time.perf_counter() - t0:.0f} s on {provenance()['cpu_count']} cores). Per camera: its white "
          "image -> `calibrate` -> per scene `simulate --scene depth` -> `decode` -> `reconstruct` (depths found, "
          f"admm); {a.scenes} scenes of 1-4 flames at random depths, {a.rays} rays per pixel (white images "
          f"{WHITE_RAYS}), noise-free and {SNR_DB:g} dB. Bars: depth error p90 <= {BARS['depth_p90']} and worst <= "
          f"{BARS['depth_worst']} lenslets "
          f"per view step, emission error <= {100 * BARS['emission_p90']:.0f} % on 90 % of flames; at 14 dB twice "
          "these. Time: admm's solve per lenslet-plane; `admm_time_vs_paper` against the paper camera's, same run.",
          "", tab.to_markdown(index=False, floatfmt=".4g"), "",
          "## Commands", "", runs.groupby(["camera", "step"]).agg(runs=("exit_code", "size"),
                                                                failed=("exit_code", lambda s: int((s != 0).sum())),
                                                                wall_s_median=("wall_s", "median")).reset_index()
          .to_markdown(index=False, floatfmt=".3g"), ""]
    if len(failed):
        md += ["Failed commands:", ""] + [f"- {r.camera} `{r.step}`: {r.message}" for r in failed.itertuples()] + [""]
    md += ["The colour (Bayer) camera, its captures decoded with their channels apart and each plane's temperature scored against the truth: [cameras_colour.md](cameras_colour.md) (`experiments/cameras_colour.py`).", ""]
    atomic_write_text(a.out / "cameras.md", "\n".join(md))
    atomic_write_text(a.out / "cameras.json", json.dumps(dict(
        command=cmd, scenes=a.scenes, rays=a.rays, seeds=[a.seed0 + i for i in range(a.scenes)], snr_db=SNR_DB,
        bars=BARS, cameras=facts, wall_s=time.perf_counter() - t0, provenance=provenance()), indent=1, default=float))
    print(tab.to_string())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
