"""A colour (Bayer) camera end to end from the command line: each plane's temperature of flames at
random depths, from its raw captures, against the truth in its decoded frame; and each flame's
emission as ``reconstruct`` gives it.

The camera is ``examples/colour_camera.toml``: ``examples/own_camera.toml`` (10.57 px lenslet images, rotated
0.4°, offset) with an RGGB colour filter array in its ``[sensor]`` table (or another datasheet file, ``--camera``,
given that CFA where it names none); ``--grid hex`` gives it a hexagonal lenslet grid (a Lytro-like camera:
its channels are decoded and solved on the grid's own lattice). Every step is an ``lf-flame`` command run in-process
(:func:`lf_flame.cli.main`): ``simulate --scene white`` -> ``calibrate``; blackbodies at
:data:`FIT_K` (``simulate --scene furnace``) -> ``decode --camera`` (each view sample from its
nearest pixel, channels apart) -> ``calibrate-temperature``; per scene ``simulate --scene
colour-depth --seed S`` (2-4 flames at random depths, each with its own sheath temperature) ->
``decode --camera`` -> ``temperature --depth`` at the flames' true (merged within 1 mm) depths (the
temperature, not the depth finding, is scored there) and ``reconstruct`` (depths found; each flame's
emission scored against its green channel, :func:`emission_rows`). Noise: the noise-free render, and
14 dB of shot and read noise on it (``experiments/temperature.py``'s ``add_noise``).

The truth: per plane, each channel's emission of its flame on the decoded plane's lenslet grid
(:func:`lf_flame.tomo.decoded.decoded_plane_truth` in the light field's decoded frame), R over G
through the same calibration's lookup (:func:`lf_flame.temperature.pyrometry.temperature_planes`),
as ``experiments/temperature.py`` scores the paper camera. Per plane: |T - T_true| median, p90 and
worst over the pixels that both report. The bar (noise-free): each plane's p90 within 50 K.

Writes ``<out>/cameras_colour.{csv,md,json,png}`` and ``cameras_colour_emission.csv`` (``--grid hex``:
``cameras_colour_hex*``; the figure: the first scene's planes, noise-free, above their truth). Usage:
``python experiments/cameras_colour.py --out results [--grid square|hex] [--camera FILE] [--route R]
[--scenes 6] [--rays 1024] [--white-rays 256] [--quick]``; renders in ``--cache`` (default ``data/cameras_colour``,
``data/cameras_colour_hex``).
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from lf_flame.cli import main as lf_flame  # noqa: E402
from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.measure.metrics import own_error  # noqa: E402

#: Blackbody temperatures (K) of the calibration.
FIT_K = (1600, 2000, 2400)
#: Flames whose depths lie within this (mm) share one plane, as found planes do
#: (:data:`lf_flame.tomo.depth.MERGE_MM`): two planes closer than that split one flame's light.
MERGE_MM = 1.0
#: Scored scenes' seeds (never used to choose anything).
SEED0 = 58000
SNR_DB = 14.0
BAR_P90_K = 50.0
#: A flame's body: where the truth's two channels' light is above this fraction of its plane's peak (its edges
#: are the rest of the pixels with a temperature).
BODY_FRACTION = 0.3
#: A yardstick per plane: the truth's two channels each blurred by a Gaussian of this many lenslets, its temperature
#: against the truth's (``blur_p90_k``), over the pixels that both report. A route that resolves each channel no
#: finer than this on the decoded planes' lenslet grid scores about so: how much of a plane's error its flames'
#: structure at the lenslets' scale asks for.
BLUR_LENSLETS = 0.5
#: Rays per pixel of the scored renders, whose own error (:func:`render_own_error`) is then under 1 % (0.74 % on the
#: scored scenes' first; on validation seed 58101 48 rays give 7.9 %, 400 give 1.6 %), and of the white image that
#: decoding divides every sample by (16 rays: 3.7 % ray noise per pixel where it is above half its peak, 14 % above
#: 5 %; a real flat field is averaged over frames).
RAYS, WHITE_RAYS = 1024, 256


def run(*argv) -> str:
    """One ``lf-flame`` command in-process; its standard output, or RuntimeError with its error."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = lf_flame([str(a) for a in argv])
    if rc != 0:
        raise RuntimeError(f"lf-flame {' '.join(map(str, argv))} -> exit {rc}: {err.getvalue().strip()}")
    return out.getvalue()


def camera_file(cache: Path, grid: str = "square", sheet: Path | None = None) -> Path:
    """The example colour camera (``examples/colour_camera.toml``: the example camera with an RGGB CFA), or the
    datasheet file ``sheet`` with an RGGB CFA where it names none, with a ``grid`` (square or hex) lenslet layout,
    written to ``cache``."""
    text = Path(sheet or ROOT / "examples" / "colour_camera.toml").read_text()
    if "cfa" not in text:
        text += 'cfa = "RGGB"\n'
    p = cache / "camera.toml"
    p.write_text(text.replace('layout = "square"', f'layout = "{grid}"'))
    return p


def render_own_error(path: Path, cam: Path, rays: int, seed: int) -> float:
    """The render's own error: ``||r1 - r2|| / (sqrt(2) ||r1||)`` of the raw image of ``path`` (an ``lf-flame simulate``
    colour render of seed ``seed``) and the same scene rendered with other rays (seed + 1), as ``make cameras``
    states it for its monochrome renders."""
    from lf_flame.cli._io import camera_config, colour_scene
    from lf_flame.simulate.colour import render_colour
    z, capture = np.load(path), camera_config(str(cam))
    scene, chans, sensor = colour_scene(json.loads(str(z["scene"])), capture)
    return own_error(z["raw"], render_colour(capture, scene, chans, sensor, rays, seed + 1))


def noisy_copy(path: Path, seed: int) -> Path:
    """The raw image of ``path`` (an ``lf-flame simulate`` .npz) with shot and read noise at :data:`SNR_DB`."""
    from temperature import add_noise
    from lf_flame.simulate.scenes import FLAME_EFFECTS
    out = path.with_name(path.stem + "_14dB.npz")
    if not out.exists():
        z = dict(np.load(path))
        z["raw"] = add_noise(z["raw"], FLAME_EFFECTS, seed, SNR_DB)[0].astype(np.float32)
        tmp = out.with_suffix(".partial.npz")
        np.savez_compressed(tmp, **z)
        tmp.rename(out)
    return out


def merged_planes(depths) -> list:
    """The flames' depths, those within :data:`MERGE_MM` of a neighbour merged into their mean."""
    groups = []
    for d in sorted(depths):
        if groups and d - groups[-1][-1] < MERGE_MM:
            groups[-1].append(d)
        else:
            groups.append([d])
    return [float(np.mean(g)) for g in groups]


def channel_truth(scene_npz: Path, lf, depths) -> np.ndarray:
    """The red and green channels' emission (2, P, rows, cols) of a colour scene's flames, each on the plane nearest
    its depth, on the decoded planes' lenslet grid."""
    from lf_flame.cli._io import colour_scene
    from lf_flame.tomo.decoded import decoded_plane_truth
    scene, chans, _ = colour_scene(json.loads(str(np.load(scene_npz)["scene"])), lf.capture_camera)
    truth = np.zeros((2, len(depths), lf.camera.n_rows, lf.camera.n_cols))
    for L, ch in zip(scene.layers, chans):
        k = int(np.argmin([abs(d - L.depth_offset_mm) for d in depths]))
        for c in (0, 1):
            truth[c, k] += decoded_plane_truth(dataclasses.replace(L, radiance=ch[c]), lf.camera, depths[k],
                                               truth.shape[2:], lf.frame.rotation_deg, lf.frame.centre_lenslets)
    return truth


def truth_temperature(scene_npz: Path, lf, depths, cal, model):
    """Each plane's true temperature (K), where it has one, its flames' bodies (:data:`BODY_FRACTION`), and the
    temperature of the truth's channels blurred by :data:`BLUR_LENSLETS` (and where it has one), on the decoded
    planes' lenslet grid."""
    from lf_flame.temperature.pyrometry import temperature_planes
    from lf_flame.temperature.ratio import smooth_planes
    truth = channel_truth(scene_npz, lf, depths)
    Tt, vt, _ = temperature_planes(truth[0], truth[1], cal, model)
    Tb, vb, _ = temperature_planes(*(smooth_planes(t, BLUR_LENSLETS) for t in truth), cal, model)
    light = truth.sum(axis=0)
    body = light > BODY_FRACTION * light.reshape(len(light), -1).max(axis=1)[:, None, None]
    return Tt, vt, body, np.where(vb, Tb, np.nan)


def emission_rows(scene_npz: Path, views: Path, cam: Path, noise: str, seed: int) -> list:
    """``reconstruct`` (its default: depths found, admm) of one decoded colour capture, whose channels it levels into
    one monochrome light field; each flame scored by :func:`lf_flame.tomo.scoring.score_flames` against its green
    channel's emission (the levelled views' units) in the decoded frame."""
    import h5py

    from lf_flame.cli._io import camera_config, colour_scene
    from lf_flame.real.readers import read_light_field
    from lf_flame.tomo.files import load_found, load_reconstruction
    from lf_flame.tomo.scoring import score_flames
    rec_file = views.with_name(views.stem + "_rec.h5")
    t0 = time.perf_counter()
    run("reconstruct", views, "--camera", cam, "--out", rec_file)
    wall = time.perf_counter() - t0
    lf = read_light_field(views, cam)
    capture = camera_config(str(cam))
    scene, chans, _ = colour_scene(json.loads(str(np.load(scene_npz)["scene"])), capture)
    green = dataclasses.replace(scene, layers=tuple(dataclasses.replace(L, radiance=ch[1])
                                                    for L, ch in zip(scene.layers, chans)))
    rec = load_reconstruction(rec_file)
    df = score_flames(rec.planes, rec.depths_mm, green, lf.camera, found=load_found(rec_file), frame=lf.frame,
                      time_s=rec.time_s, noise=noise, seed=seed)
    df["slope_err"] = [abs(capture.slope_for_depth(e) - capture.slope_for_depth(t)) if np.isfinite(e) else np.nan
                       for e, t in zip(df.depth_mm, df.depth_mm_true)]     # lenslets per view step, as make cameras
    df["planes"] = len(rec.depths_mm)
    with h5py.File(rec_file) as f:                  # the written planes' (admm's last fill's is an older prediction)
        df["relative_residual"] = json.loads(f.attrs["misfit"])["relative_residual"]
    df["reconstruct_wall_s"] = wall
    return df.to_dict("records")


def offsets_figure(scene_npz: Path, views: Path, cam: Path, depths, path: Path):
    """One noise-free capture's green emission per plane solved at the flames' true planes twice, each sample at
    its own pixel (the route's default) and at its view's place, beside the truth in the decoded frame: the figure
    of the docs, and each plane's relative error in its titles."""
    import matplotlib.pyplot as plt

    from lf_flame.cli.planes import run_reconstruction
    from lf_flame.measure.figures import save_figure
    from lf_flame.real.readers import read_light_field
    from lf_flame.temperature.mosaic import monochrome_light_field
    from lf_flame.tomo.truth import bin_planes
    lf = monochrome_light_field(read_light_field(views, cam))
    truth = channel_truth(scene_npz, lf, depths)[1]                      # green
    solved = {}
    for label, field in (("samples at their pixels", lf),
                         ("samples at their views' places", dataclasses.replace(lf, sample_offsets=None))):
        op, rec = run_reconstruction(field, list(depths))
        solved[label] = bin_planes(rec.planes, op.subsamples)
    fig, axes = plt.subplots(len(depths), 3, figsize=(7.5, 3.2 * len(depths)), squeeze=False, layout="constrained")
    for k, d in enumerate(depths):
        top = float(truth[k].max())
        for j, (label, planes) in enumerate([("truth", truth)] + list(solved.items())):
            err = "" if j == 0 else f", {100 * np.linalg.norm(planes[k] - truth[k]) / np.linalg.norm(truth[k]):.1f} % off"
            im = axes[k, j].imshow(planes[k], cmap="inferno", vmin=0, vmax=top)
            axes[k, j].set_title(f"{label}\n{d:+.1f} mm{err}", fontsize=8)
            axes[k, j].set_xticks([])
            axes[k, j].set_yticks([])
        fig.colorbar(im, ax=axes[k, :], shrink=0.8, label="green emission (views' units)")
    save_figure(fig, path)
    plt.close(fig)


def main(argv=None):
    import h5py

    from lf_flame.optics.camera_file import load_colour_sensor
    from lf_flame.real.readers import read_light_field
    from lf_flame.temperature.pyrometry import load_calibration
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--cache", help="renders (default data/cameras_colour, data/cameras_colour_hex)")
    ap.add_argument("--grid", choices=("square", "hex"), default="square", help="the lenslet grid's layout")
    ap.add_argument("--route", help="temperature's --route (default: its default)")
    ap.add_argument("--camera", help="another datasheet camera file (default: examples/colour_camera.toml)")
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--rays", type=int, default=RAYS, help="rays per pixel of the scenes' renders")
    ap.add_argument("--white-rays", type=int, default=WHITE_RAYS, help="rays per pixel of the white image")
    ap.add_argument("--quick", action="store_true", help="2 scenes at 16 rays")
    ap.add_argument("--seed0", type=int, default=SEED0, help="first scene's seed (other seeds: validation)")
    a = ap.parse_args(argv)
    if a.quick:
        a.scenes, a.rays, a.white_rays = 2, 16, 16
    name = "cameras_colour" + ("_hex" if a.grid == "hex" else "")
    out, cache = Path(a.out), Path(a.cache or f"data/{name}")
    out.mkdir(parents=True, exist_ok=True)
    cache.mkdir(parents=True, exist_ok=True)
    t_all = time.perf_counter()
    cam = camera_file(cache, a.grid, a.camera)
    model = load_colour_sensor(cam)
    run("simulate", "--camera", cam, "--scene", "white", "--rays-per-pixel", a.white_rays, "--out", cache / "white.npz")
    run("calibrate", cache / "white.npz", "--out", cache / "cal.json")
    views = []
    for t in FIT_K:
        run("simulate", "--camera", cam, "--scene", "furnace", "--temperature", t, "--rays-per-pixel", 8,
            "--out", cache / f"bb{t}.npz")
        run("decode", cache / f"bb{t}.npz", "--calibration", cache / "cal.json", "--camera", cam,
            "--out", cache / f"bb{t}.h5")
        views.append(cache / f"bb{t}.h5")
    run("calibrate-temperature", *views, *[x for t in FIT_K for x in ("--temperature", t)],
        "--out", cache / "bb.json")
    cal = load_calibration(cache / "bb.json", model)
    rows, flames = [], []
    for i in range(a.scenes):
        seed = a.seed0 + i
        clean = cache / f"scene{seed}_{a.rays}rays.npz"
        if not clean.exists():
            run("simulate", "--camera", cam, "--scene", "colour-depth", "--seed", seed, "--rays-per-pixel", a.rays,
                "--out", clean)
        if i == 0:
            own = render_own_error(clean, cam, a.rays, seed)
        objects = json.loads(str(np.load(clean)["objects"]))
        depths = merged_planes([float(o["depth_offset_mm"]) for o in objects])
        for noise, raw in (("clean", clean), (f"{SNR_DB:g}dB", noisy_copy(clean, seed))):
            v = raw.with_suffix(".h5")
            run("decode", raw, "--calibration", cache / "cal.json", "--camera", cam, "--out", v)
            t0 = time.perf_counter()
            run("temperature", v, "--camera", cam, "--calibration", cache / "bb.json",
                *(("--route", a.route) if a.route else ()),
                *[x for d in depths for x in ("--depth", d)], "--out", v.with_name(v.stem + "_T.h5"))
            wall = time.perf_counter() - t0
            with h5py.File(v.with_name(v.stem + "_T.h5")) as f:
                T, valid = f["temperature_k"][...], f["valid"][...]
            flames.extend(emission_rows(clean, v, cam, noise, seed))
            if i == 0 and noise == "clean" and a.grid == "square":   # a hexagonal grid solves on its lattice
                offsets_figure(clean, v, cam, depths, out / f"{name}_offsets.png")
            if noise == "clean":   # the truth in the decoded frame, the same for both renders (one calibration)
                lf = read_light_field(v, cam)
                Tt, vt, body, Tb = truth_temperature(clean, lf, depths, cal, model)
                if i == 0:         # the first scene's planes beside their truth: the figure of the docs
                    from lf_flame.cli.temperature_planes import temperature_figure
                    from lf_flame.measure.figures import save_figure
                    save_figure(temperature_figure(T, depths, valid, lf.camera,
                                                   truth_k=np.where(vt, Tt, np.nan)), out / f"{name}.png")
            for k, d in enumerate(depths):
                sel = valid[k] & vt[k]
                err = np.abs(T[k] - Tt[k])[sel]
                body_err = np.abs(T[k] - Tt[k])[sel & body[k]]
                blur_err = np.abs(Tb[k] - Tt[k])[sel & np.isfinite(Tb[k])]
                rows.append(dict(seed=seed, noise=noise, plane=k, depth_mm=d, flames=len(objects),
                                 n_truth=int(vt[k].sum()), n_reported=int(sel.sum()),
                                 n_without_truth=int((valid[k] & ~vt[k]).sum()), n_valid=int(valid[k].sum()),
                                 median_k=float(np.median(err)) if err.size else np.nan,
                                 p90_k=float(np.percentile(err, 90)) if err.size else np.nan,
                                 worst_k=float(err.max()) if err.size else np.nan,
                                 signed_median_k=float(np.median((T[k] - Tt[k])[sel])) if err.size else np.nan,
                                 body_p90_k=float(np.percentile(body_err, 90)) if body_err.size else np.nan,
                                 blur_p90_k=float(np.percentile(blur_err, 90)) if blur_err.size else np.nan,
                                 temperature_wall_s=wall))
            print(f"  seed {seed} {noise}: " + "; ".join(f"{r['depth_mm']:+.1f} mm p90 {r['p90_k']:.0f} K"
                                                        for r in rows[-len(depths):]), flush=True)
    df = pd.DataFrame(rows)
    atomic_write_text(out / f"{name}.csv", df.to_csv(index=False, float_format="%.6g"))
    g = df.groupby("noise", sort=False).agg(planes=("p90_k", "size"), p90_median=("p90_k", "median"),
                                            p90_worst_plane=("p90_k", "max"), worst=("worst_k", "max"),
                                            body_p90_median=("body_p90_k", "median"),
                                            blur_p90_median=("blur_p90_k", "median"),
                                            blur_p90_worst_plane=("blur_p90_k", "max"),
                                            signed_median_range=("signed_median_k",
                                                                 lambda v: f"{v.min():+.0f} .. {v.max():+.0f}"),
                                            share_reported=("n_reported", "sum"), truth=("n_truth", "sum"),
                                            share_without_truth=("n_without_truth", "sum"), valid=("n_valid", "sum"),
                                            temperature_wall_s=("temperature_wall_s", "median"))
    g["share_reported"] = g.share_reported / g.truth
    g["share_without_truth"] = g.share_without_truth / g.valid
    g = g.drop(columns=["truth", "valid"]).reset_index()
    g["bar"] = [f"p90 <= {BAR_P90_K:g} K: {'met' if v <= BAR_P90_K else 'not met'}" if n == "clean" else
                f"p90 <= {2 * BAR_P90_K:g} K: {'met' if v <= 2 * BAR_P90_K else 'not met'}"
                for n, v in zip(g.noise, g.p90_worst_plane)]
    fl = pd.DataFrame(flames)
    atomic_write_text(out / f"{name}_emission.csv", fl.to_csv(index=False, float_format="%.6g"))
    missed = lambda v: int(np.isnan(v).sum())
    em = fl.groupby("noise", sort=False).agg(flames=("rel_err", "size"), missed=("depth_mm", missed),
                                             depth_err_p90_mm=("depth_err_mm",
                                                               lambda v: np.nanpercentile(np.abs(v), 90)),
                                             depth_err_worst_mm=("depth_err_mm", lambda v: np.nanmax(np.abs(v))),
                                             slope_err_p90=("slope_err", lambda v: np.nanpercentile(v, 90)),
                                             rel_err_median=("rel_err", "median"),
                                             rel_err_p90=("rel_err", lambda v: np.nanpercentile(v, 90)),
                                             rel_err_worst=("rel_err", "max"),
                                             relative_residual_median=("relative_residual", "median"),
                                             reconstruct_wall_s=("reconstruct_wall_s", "median")).reset_index()
    wall = time.perf_counter() - t_all
    flags = ((" --quick" if a.quick else "") + (" --grid hex" if a.grid == "hex" else "")
             + (f" --route {a.route}" if a.route else "") + (f" --camera {a.camera}" if a.camera else ""))
    md = ["# A colour camera end to end: each plane's temperature from raw captures", "",
          f"`python experiments/cameras_colour.py --out {a.out}{flags}` ({wall:.0f} s on 2 cores). "
          + (f"The camera of {a.camera}" if a.camera else "The example camera (10.57 px lenslet images, rotated 0.4°")
          + f"{', on a hexagonal grid' if a.grid == 'hex' else ''}{'' if a.camera else ')'} with an "
          "RGGB CFA: white image -> `calibrate`; blackbodies at "
          f"{', '.join(map(str, FIT_K))} K -> `decode --camera` (each view sample from its nearest pixel, channels "
          f"apart) -> `calibrate-temperature`; per scene `simulate --scene colour-depth` ({a.scenes} scenes from seed "
          f"{a.seed0}, {a.rays} rays per pixel, own error {100 * own:.2f} %; the white image at {a.white_rays}) "
          "-> `decode --camera` -> `temperature --depth` at the flames' true "
          "depths; noise-free and at 14 dB. Scored per plane against the truth on the decoded planes (each "
          "channel's emission in the decoded frame, R over G through the same calibration): |T - T_true| over the "
          "pixels that both report (`body_p90`: those where the truth's light is above "
          f"{BODY_FRACTION:g} of its plane's peak; `signed_median`: the estimate less the truth; "
          "`share_reported`: the truth's pixels that the route reports; `share_without_truth`: the route's pixels "
          "where the truth has no temperature, not scored: the flames' blurred edges, or another plane's flame read "
          "on this one at temperatures of its own). A yardstick beside "
          f"the route: `blur_p90`, the truth's two channels each blurred by a Gaussian of {BLUR_LENSLETS:g} lenslet, "
          "scored the same way: what resolving each channel no finer than that on the decoded planes' lenslet grid "
          "costs these flames.", "",
          g.to_markdown(index=False, floatfmt=".3g"), "", "Per plane:", "",
          df.to_markdown(index=False, floatfmt=".3g"), "",
          "## Emission of the same captures", "",
          f"`reconstruct` as a user runs it (depths found, admm; {name}_emission.csv, one row per flame): the "
          "decoded colour views levelled into one monochrome light field (red and green samples each divided by "
          "their channel's mean and put in green's units, blue left out: "
          "`lf_flame.temperature.mosaic.monochrome_light_field`), scored per flame by `score_flames` against its "
          "green channel's emission in the decoded frame (a flame whose colour varies is not one grey image: "
          "its red samples differ from green's by that variation). Each sample is modelled at its own pixel, up to "
          "half a view step from its view's place, where the planes' parallax calls for it "
          "(`lf_flame.tomo.exact.offset_bins_for`)"
          + ("." if a.grid == "hex" else f"; {name}_offsets.png: the first scene's planes solved noise-free at the "
             "flames' true depths so and with every sample at its view's place, beside the truth."), "",
          em.to_markdown(index=False, floatfmt=".3g"), ""]
    atomic_write_text(out / f"{name}.md", "\n".join(md))
    atomic_write_text(out / f"{name}.json", json.dumps(dict(
        grid=a.grid, scenes=a.scenes, rays=a.rays, white_rays=a.white_rays, own_error=own, seed0=a.seed0,
        fit_k=FIT_K, snr_db=SNR_DB, calibration=dataclasses.asdict(cal) if dataclasses.is_dataclass(cal) else str(cal),
        wall_s=wall, provenance=provenance()), indent=1, default=float))
    print(g.to_string())


if __name__ == "__main__":
    main()
