"""What accuracy costs in time (``make tradeoff``): one run, side by side, on this machine.

Writes ``<out>/tradeoff.csv`` (one row per route or knob setting), ``tradeoff_pareto.png``
(latency against SSIM of the refocusing routes, Pareto front marked), ``tradeoff_knobs.png``
(rays per pixel, slope-search grid, training time), ``tradeoff.md`` (tables and the
statements drawn from them) and ``tradeoff.json`` (provenance).

Sections (column ``section``):

- ``refocusing``: raw flame light field (the dataset's, as the model sees it) -> 4 planes
  at the dataset's slopes, for each route: shift-and-sum with whole-lenslet (nearest) and
  bilinear shifts, Fourier slice (4-D FFT included: it is paid per light field), and the
  trained model (backbone + decoder) at two backbone input sizes, with TensorFlow and, in
  a subprocess, JAX. Latency: median, 10th and 90th percentile of ``repeats`` calls after a
  warm-up, on one light field. Accuracy: SSIM/PSNR per plane (scikit-image), mean over the
  test split, against the **reference**: bilinear shift-and-sum at the same slopes of the
  same scene rendered noise-free at ``ref_rays_per_pixel``; and, in physical terms, the
  flame height measured on each route's planes (:mod:`lf_flame.measure.diagnostics`) against the
  simulation's true height: mean absolute error in mm per plane (``height_err_mm_*``) and
  the number of planes where no flame could be measured (``height_failed``).
- ``simulator: rays per pixel`` and ``simulator: effects``: rows of
  ``experiments/bench_sim.py`` (image RMSE against a high-sample render, and time).
- ``slope search``: grid steps against the largest slope error (analytic slopes of the
  nominal shapes scene) and time per object.
- ``training``: validation SSIM against epochs and wall time, from the learning curves.
- ``reconstruction``: every 3-D reconstruction solver at every iteration count of ``make
  reconstruct``'s validation curves: time against the worst plane's emission error.
- ``depth`` and ``volume``: the routes to flames at unknown depths (``make depth``) and to
  volumes (``make volume``), read from their own results: time per light field against the
  per-flame emission error and the 3-D error.
- ``emission``: the learned reconstructor, its start, admm started from it, admm and
  shift-and-sum on the same scored renders (``make train-reconstructor``, ``learned.csv``).

Usage: ``python experiments/tradeoff.py --preset paper|quick --data-dir D --model-dir M --out O``;
``python experiments/tradeoff.py --plot-only --out O`` measures nothing and redraws the
figures from ``O/tradeoff.csv``; ``--reconstruction-only`` measures nothing either and refreshes
the ``reconstruction``, ``depth``, ``volume`` and ``emission`` sections (rows, figure
``tradeoff_reconstruct.png``, ``tradeoff_emission.png``, tables) from their results in ``O`` (``make reconstruct`` and
``make train-reconstructor`` run it).
The second, smaller backbone input size is trained here if its model folder is missing
(settings in the ``[tradeoff]`` table of ``experiments/<preset>.toml``).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_sim  # noqa: E402
from bench_refocus import _times  # noqa: E402

from lf_flame.simulate import scenes  # noqa: E402
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.config import atomic_write_text, load_experiment_config, load_toml, provenance
from lf_flame.learn.dataset import GT_MASK, LightFieldDataset, SCENES, sample_rng  # noqa: E402
from lf_flame.measure.scoring import error_table, score_stacks  # noqa: E402
from lf_flame.measure.metrics import psnr_per_plane, ssim_per_plane  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, raw_to_views, refocus  # noqa: E402
from lf_flame.refocus.slope_search import find_sharpest_slope  # noqa: E402
from lf_flame.simulate.scenes import PAPER_DEPTHS_MM  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PLANES = [f"{d:+.0f}mm" for d in PAPER_DEPTHS_MM]


def reference_stacks(ds: LightFieldDataset, indices, rays_per_pixel: int) -> np.ndarray:
    """Reference 4-plane stacks (k, 4, R, C): each sample's scene rendered noise-free at
    ``rays_per_pixel``, refocused bilinearly at the dataset's slopes (ground-truth views)."""
    cfg = ds.config
    cam, n = ds.camera, ds.camera.pixels_per_lenslet
    out = []
    for i in indices:
        sc = SCENES[ds.scene](cam, sample_rng(cfg, ds.scene, int(i)), regime=cfg.regime)
        sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, full_well_e=None, read_noise_e=None,
                                                                 bit_depth=None))
        raw = simulate.render(cam, sc, rays_per_pixel, seed=99)
        out.append(np.clip(refocus(raw, ds.slopes, n, aperture_mask(n, GT_MASK)), 0, 1))
    return np.stack(out)


def _accuracy(preds, refs) -> dict:
    ssim = np.mean([ssim_per_plane(r, np.clip(p, 0, 1)) for p, r in zip(preds, refs)], axis=0)
    psnr = np.mean([psnr_per_plane(r, np.clip(p, 0, 1)) for p, r in zip(preds, refs)], axis=0)
    row = {f"ssim_{k}": float(v) for k, v in zip(PLANES, ssim)}
    row.update({f"psnr_db_{k}": float(v) for k, v in zip(PLANES, psnr)})
    row.update(ssim_mean=float(ssim.mean()), psnr_db_mean=float(psnr.mean()))
    return row


def _height_accuracy(preds, truth) -> dict:
    """Mean absolute flame-height error (mm) per plane of ``preds`` (k, 4, R, C) against
    ``truth = (camera, objects of each sample)``, and its tail over all planes (share off by
    more than 1 mm, 90th percentile, worst; planes flagged untrusted); planes with no
    measurable flame are counted in ``height_failed`` and left out."""
    camera, objects = truth
    scores = score_stacks(np.clip(np.asarray(preds), 0, 1), camera, objects)
    t = error_table(scores)
    row = {f"height_err_mm_{d:+.0f}mm": float(v) for d, v in zip(t.depth_mm, t.height_err_mm)}
    ok = t.height_err_mm.notna()
    row.update(height_err_mm_mean=float(t.height_err_mm[ok].mean()) if ok.any() else float("nan"),
               height_failed=int(t.n_failed.sum()))
    a = error_table(scores.assign(planes="all"), ("planes",)).iloc[0]   # the tail over every plane
    row.update(height_share_over_1mm=float(a.share_over_1mm), height_err_mm_p90=float(a.height_err_mm_p90),
               height_err_mm_max=float(a.height_err_mm_max), height_flagged=int(a.n_flagged))
    return row


def _route_row(route, setting, fn, raws, refs, repeats, backend="numpy/numba", truth=None) -> dict:
    t = _times(lambda: fn(raws[0]), repeats)
    row = dict(section="refocusing", route=route, setting=setting, backend=backend,
               latency_ms_median=t[0], latency_ms_p10=t[1], latency_ms_p90=t[2],
               throughput_lf_per_s=1e3 / t[0], n_samples=len(refs))
    preds = [fn(r) for r in raws]
    row.update(_accuracy(preds, refs))
    if truth is not None:
        row.update(_height_accuracy(preds, truth))
    return row


def classical_rows(ds, raws, refs, repeats, truth=None) -> list[dict]:
    n, slopes = ds.camera.pixels_per_lenslet, ds.slopes
    mask = aperture_mask(n, GT_MASK)
    routes = [("shift-sum", "nearest (whole lenslets)", dict(interpolation="nearest")),
              ("shift-sum", "bilinear", {}),
              ("Fourier slice", "4-D FFT + 4 slices", dict(method="fourier"))]
    return [_route_row(r, s, lambda raw, kw=kw: refocus(raw, slopes, n, mask, **kw), raws, refs, repeats,
                       truth=truth) for r, s, kw in routes]


def model_rows(model_dirs, raws, refs, repeats, baselines: bool = True, truth=None) -> list[dict]:
    """The trained models (full: backbone + decoder) on the current Keras backend and, with
    ``baselines``, the yardsticks saved beside each (mean image; linear decoders, which run
    the same backbone)."""
    import keras
    from lf_flame.learn.baselines import load_baselines
    from lf_flame.learn.model_files import load_full_model
    rows = []
    for d in model_dirs:
        model, info = load_full_model(d)
        fx = model.get_layer("feature_extractor")
        size = f"{info['model_config']['input_rows']}x{info['model_config']['input_cols']}"

        def fn(raw, model=model):
            return np.transpose(np.asarray(model.predict_on_batch(raw[None, ..., None]))[0], (2, 0, 1))
        rows.append(_route_row("model", f"backbone input {size}, {info['epochs_run']} epochs, "
                               f"{info['backbone_weights']}", fn, raws, refs, repeats, backend=keras.backend.backend(),
                               truth=truth))
        for route, base in (load_baselines(d) if baselines else {}).items():
            if route == "mean image":
                if any(r["route"] == route for r in rows):
                    continue  # every model of the map is trained on the same split: one mean image
                rows.append(_route_row(route, "training split's mean ground truth", lambda raw, m=base.mean: m, raws,
                                       refs, repeats, truth=truth))
                continue

            def lin_fn(raw, lin=base, fx=fx):
                return lin.predict(np.asarray(fx.predict_on_batch(raw[None, ..., None])))[0]
            rows.append(_route_row(route, f"backbone input {size}, {info['backbone_weights']}", lin_fn, raws, refs,
                                   repeats, backend=keras.backend.backend(), truth=truth))
    return rows


def jax_model_rows(model_dirs, raws, refs, repeats, tmp: Path, truth=None) -> list[dict]:
    """:func:`model_rows` with ``KERAS_BACKEND=jax`` in a subprocess (a backend is fixed at import)."""
    extra = {} if truth is None else dict(camera=truth[0].to_json(), objects=json.dumps(truth[1], default=float))
    np.savez(tmp / "tradeoff_inputs.npz", raws=np.stack(raws), refs=refs, **extra)
    r = subprocess.run([sys.executable, __file__, "--models-only", str(tmp / "tradeoff_inputs.npz"),
                        "--repeats", str(repeats), *map(str, model_dirs)],
                       env=dict(os.environ, KERAS_BACKEND="jax", TF_CPP_MIN_LOG_LEVEL="3"),
                       capture_output=True, text=True)
    (tmp / "tradeoff_inputs.npz").unlink()
    if r.returncode != 0:
        print(f"JAX rows skipped: {r.stderr.strip().splitlines()[-1] if r.stderr.strip() else r.returncode}")
        return []
    return json.loads(r.stdout.strip().splitlines()[-1])


def simulator_rows(quick: bool) -> list[dict]:
    df = bench_sim.run(quick, sections=("effects", "sampling"))  # the sections this map keeps
    rows = []
    for r in df.itertuples():
        sampling = r.section == "sampling"
        rows.append(dict(section=f"simulator: {'rays per pixel' if sampling else 'effects'}",
                         route=r.scene, setting=f"{r.rays_per_pixel} rays/pixel" if sampling else r.setting,
                         rays_per_pixel=r.rays_per_pixel, latency_ms_median=r.ms_median,
                         image_rmse=r.rmse if sampling else np.nan))
    return rows


def slope_search_rows(rays_per_pixel: int, grids, camera=PAPER_CAMERA) -> list[dict]:
    sc = scenes.shapes_scene(camera, np.random.default_rng(0), vary=False)
    views = raw_to_views(simulate.render(camera, sc, rays_per_pixel, seed=0), camera.pixels_per_lenslet)
    mask = aperture_mask(camera.pixels_per_lenslet, GT_MASK)
    rows = []
    for coarse, fine in grids:
        errs, ts = [], []
        for o in sc.objects:
            t = time.perf_counter()
            s = find_sharpest_slope(views, o["roi"], mask=mask, coarse_step=coarse, fine_step=fine)
            ts.append(time.perf_counter() - t)
            errs.append(abs(s.slope - camera.slope_for_depth(o["depth_offset_mm"])))
        rows.append(dict(section="slope search", route="Fourier-scored, tenengrad",
                         setting=f"coarse {coarse}, fine {fine}", coarse_step=coarse, fine_step=fine,
                         latency_ms_median=1e3 * float(np.median(ts)), slope_error_max=float(max(errs)),
                         slope_error_mean=float(np.mean(errs))))
    return rows


def training_rows(model_dirs) -> list[dict]:
    rows = []
    for d in model_dirs:
        info = json.loads((Path(d) / "train_info.json").read_text())
        size = f"{info['model_config']['input_rows']}x{info['model_config']['input_cols']}"
        for r in pd.read_csv(Path(d) / "history.csv").itertuples():
            rows.append(dict(section="training", route=f"{info['scene']} model, input {size}",
                             setting="start" if r.epoch == 0 else f"epoch {r.epoch}", epochs=r.epoch,
                             train_wall_s=r.wall_time_s,
                             val_ssim=r.val_ssim, val_loss=r.val_loss))
    return rows


def reconstruction_rows(folder: Path) -> list[dict]:
    """Every solver at every iteration count of ``make reconstruct``'s validation curves
    (``folder/reconstruct_iters.csv``, written there by ``experiments/reconstruct.py``): time
    against the worst plane's relative emission error, per scene and noise level; [] when
    the curves are missing. Time: median and 90th percentile over the validation renders."""
    f = folder / "reconstruct_iters.csv"
    if not f.exists():
        return []
    c = pd.read_csv(f)
    per_render = c.groupby(["scene", "snr_db", "solver", "knobs", "iters", "seed"], sort=False).agg(
        rel_err=("rel_err", "max"), time_s=("time_s", "first")).reset_index()
    rows = []
    for (scene, snr, solver, knobs, iters), g in per_render.groupby(["scene", "snr_db", "solver", "knobs", "iters"],
                                                                   sort=False):
        knobs = knobs if knobs != "{}" else ""
        rows.append(dict(section="reconstruction", route=f"reconstruct-{solver}", knobs=knobs,
                         setting=f"{iters} it. {knobs}".strip(), scene=scene,
                         noise="noise-free" if np.isinf(snr) else f"{snr:g} dB", iters=int(iters),
                         latency_ms_median=1e3 * float(g.time_s.median()),
                         latency_ms_p90=1e3 * float(g.time_s.quantile(0.9)),
                         worst_plane_rel_err=float(g.rel_err.max()), mean_worst_plane_rel_err=float(g.rel_err.mean()),
                         n_samples=len(g)))
    return rows


def depth_volume_rows(folder: Path) -> list[dict]:
    """The routes to flames at unknown depths and to volumes, from their own runs in ``folder``
    (``depth.csv`` of ``make depth``, ``volume.csv`` / ``volume_nonaxi.csv`` of ``make volume``; [] for each
    missing): per route and noise, time per light field (median, p90) against the error (per flame's emission:
    median, p90; per volume: the 3-D error, median and worst over scenes, and the depth centroid's error)."""
    rows = []
    f = folder / "depth.csv"
    if f.exists():
        d = pd.read_csv(f)
        d = d[d.kind == "random"]
        for (route, noise), g in d.groupby(["route", "noise"], sort=False):
            t = g.groupby(["seed"]).time_s.first()
            rows.append(dict(section="depth", route=route, noise="noise-free" if noise == "clean" else noise,
                             scene="random depths", latency_ms_median=1e3 * float(t.median()),
                             latency_ms_p90=1e3 * float(t.quantile(0.9)), error_median=float(g.rel_err.median()),
                             error_tail=float(g.rel_err.quantile(0.9)),
                             depth_err_mm_p90=float(g.depth_err_mm.abs().fillna(np.inf).quantile(0.9)),
                             n_samples=len(g)))
    for name in ("volume.csv", "volume_nonaxi.csv"):
        f = folder / name
        if not f.exists():
            continue
        v = pd.read_csv(f)
        if "split" in v:                                     # the scored volumes only, not those the weights were chosen on
            v = v[v.split == "test"]
        for (route, noise), g in v.groupby(["route", "noise"], sort=False):
            rows.append(dict(section="volume", route=route, noise=noise, scene=name.removesuffix(".csv"),
                             latency_ms_median=1e3 * float(g.time_s.median()),
                             latency_ms_p90=1e3 * float(g.time_s.quantile(0.9)), error_median=float(g.rel_3d.median()),
                             error_tail=float(g.rel_3d.max()), centroid_mm_mean=float(g.centroid_mean_mm.mean()),
                             n_samples=len(g)))
    return rows


def emission_rows(folder: Path) -> list[dict]:
    """Each plane's emission by every route of ``make train-reconstructor`` (``folder/learned.csv``: the learned
    reconstructor, its Wiener start, admm started from it, admm, shift-and-sum, on the same traced scored
    renders; [] when missing): per route, scene and noise, the worst plane per render (median and worst over
    renders) against the time per light field (median; p90: the largest of the renders' own)."""
    f = folder / "learned.csv"
    if not f.exists():
        return []
    c = pd.read_csv(f)
    per = c.groupby(["route", "scene", "noise", "seed"], sort=False).agg(
        worst=("rel_err", "max"), t=("time_s", "first"), t90=("time_p90_s", "first")).reset_index()
    return [dict(section="emission", route=route, scene=scene, noise="noise-free" if noise == "clean" else "14 dB",
                 latency_ms_median=1e3 * float(g.t.median()), latency_ms_p90=1e3 * float(g.t90.max()),
                 error_median=float(g.worst.median()), error_tail=float(g.worst.max()), n_samples=len(g))
            for (route, scene, noise), g in per.groupby(["route", "scene", "noise"], sort=False)]


def plot_reconstruction(df: pd.DataFrame, out: Path) -> None:
    """``tradeoff_reconstruct.png``: worst-plane emission error against time, one line per
    solver and knob setting through its iteration counts, one panel per scene and noise."""
    rec = df[df.section == "reconstruction"]
    panels = list(rec.groupby(["scene", "noise"], sort=False))
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 4.2), squeeze=False, sharey=True)
    for ax, ((scene, noise), g) in zip(axes[0], panels):
        for (route, knobs), h in g.groupby([g.route, g.knobs.fillna("")], sort=False):
            ax.plot(h.latency_ms_median / 1e3, h.worst_plane_rel_err, "o-", ms=3,
                    label=f"{route.replace('reconstruct-', '')} {knobs}".strip())
        ax.set_yscale("log")
        ax.set_xlabel("time (s, median over renders)")
        ax.set_title(f"{scene}, {noise}")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel("worst plane relative error")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle("3-D reconstruction: error against time, iterations along each line (validation renders)")
    fig.tight_layout()
    fig.savefig(out / "tradeoff_reconstruct.png", dpi=110)
    plt.close(fig)


def plot_emission(df: pd.DataFrame, out: Path) -> None:
    """``tradeoff_emission.png``: each route of ``make train-reconstructor`` (learned, its start, admm from it,
    admm, shift-and-sum) as a point, worst-plane error (worst render) against time per light field (median, the
    bar to the p90), one panel per scene and noise, on the same traced scored renders."""
    em = df[df.section == "emission"]
    panels = list(em.groupby(["scene", "noise"], sort=False))
    cols = (len(panels) + 1) // 2
    fig, axes = plt.subplots(2, cols, figsize=(3.6 * cols, 7.2), squeeze=False, sharey=True, sharex=True)
    markers = dict(zip(em.route.unique(), "osD^vx"))
    for ax, ((scene, noise), g) in zip(axes.ravel(), panels):
        for r in g.itertuples():
            t, t90 = r.latency_ms_median / 1e3, r.latency_ms_p90 / 1e3
            ax.errorbar(t, r.error_tail, xerr=[[0], [max(t90 - t, 0)]], fmt=markers[r.route], ms=6, label=r.route)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(f"{scene}, {noise}", fontsize=9)
        ax.grid(alpha=0.3, which="both")
    for ax in axes[1]:
        ax.set_xlabel("time per light field (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("worst plane relative error")
    for ax in axes.ravel()[len(panels):]:
        ax.axis("off")
    axes[0, -1].legend(fontsize=7)
    fig.suptitle("Each plane's emission: learned and solved, error against time (traced scored renders)")
    fig.tight_layout()
    fig.savefig(out / "tradeoff_emission.png", dpi=100)
    plt.close(fig)


def pareto(df: pd.DataFrame) -> pd.Series:
    """True for the routes that no other route beats in both latency and mean SSIM."""
    lat, acc = df.latency_ms_median.values, df.ssim_mean.values
    return pd.Series([not np.any((lat <= lat[i]) & (acc >= acc[i]) & ((lat < lat[i]) | (acc > acc[i])))
                      for i in range(len(df))], index=df.index)


def _routes(df: pd.DataFrame) -> pd.DataFrame:
    """The refocusing rows, with a ``pareto`` column. The mean image ignores its input (a
    yardstick, not a way to refocus), so it is never on the front."""
    ref = df[df.section == "refocusing"].copy()
    looks = ref.route != "mean image"
    ref["pareto"] = pareto(ref[looks]).reindex(ref.index, fill_value=False)
    return ref


def _label(r) -> str:
    return f"{r.route} {r.setting.split(',')[0]}" + ("" if r.backend == "numpy/numba" else f" [{r.backend}]")


#: colour per route family, in the plots (the mean image is a grey reference line)
_ROUTE_COLOURS = {"shift-sum": "C0", "Fourier slice": "C1", "model": "C2", "linear decoder (GAP-pooled)": "C3",
                  "linear decoder (un-pooled)": "C4"}


def _input_px(setting: str) -> int | None:
    """Pixels of the backbone input a row's setting names (``backbone input RxC``), or None."""
    m = re.search(r"backbone input (\d+)x(\d+)", setting)
    return int(m[1]) * int(m[2]) if m else None


def _marker(r, largest_input: int | None) -> dict:
    """Marker of one refocusing row: colour by route, squares for whole-lenslet shifts and
    for backbone inputs smaller than ``largest_input``, hollow for the JAX backend."""
    colour = _ROUTE_COLOURS.get(r.route, "C5")
    px = _input_px(r.setting)
    small = r.setting.startswith("nearest") or (px is not None and largest_input is not None and px < largest_input)
    return dict(marker="s" if small else "o", ms=7, color=colour, mec=colour,
                mfc="none" if r.backend == "jax" else colour, mew=1.5, ls="none")


def _log_ms_axis(ax, lo: float, hi: float) -> None:
    """A log latency axis from ``lo`` to ``hi`` ms, ticks at 1-2-5 steps labelled plainly."""
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullFormatter
    ax.set_xscale("log")
    ax.set_xlim(lo, hi)
    ticks = [m * 10.0 ** e for e in range(int(np.floor(np.log10(lo))), int(np.ceil(np.log10(hi))) + 1)
             for m in (1, 2, 5)]
    if sum(lo <= t <= hi for t in ticks) < 3:    # less than a decade: denser ticks
        ticks = [m * 10.0 ** e for e in range(int(np.floor(np.log10(lo))), int(np.ceil(np.log10(hi))) + 1)
                 for m in (1, 1.5, 2, 3, 4, 5, 7)]
    ax.xaxis.set_major_locator(FixedLocator([t for t in ticks if lo <= t <= hi]))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())


def plot(df: pd.DataFrame, out: Path) -> None:
    """``tradeoff_pareto.png`` (refocusing routes: latency against SSIM and against flame
    height error) and ``tradeoff_knobs.png`` (simulator, slope search, training) from the
    rows of ``tradeoff.csv``."""
    ref = _routes(df)
    # the routes that compute something from the light field, in the legend's order
    order = {r: k for k, r in enumerate(_ROUTE_COLOURS)}
    looks = ref[ref.route != "mean image"].assign(
        _o=lambda d: d.route.map(order).fillna(len(order)), _jax=lambda d: d.backend == "jax",
        _px=lambda d: -d.setting.map(_input_px).fillna(0)).sort_values(["_o", "_jax", "_px"], kind="stable")
    mean = ref[ref.route == "mean image"]
    # x-range: the computing routes' p10-p90, with room on either side (the mean image's
    # latency is that of returning a constant: a reference line, not a point)
    lo, hi = looks.latency_ms_p10.min() / 1.6, looks.latency_ms_p90.max() * 1.6
    sizes = [px for px in map(_input_px, looks.setting) if px is not None]
    largest = max(sizes) if sizes else None
    fig, (ax, axh) = plt.subplots(1, 2, figsize=(13, 5.6))
    handles = []
    for r in looks.itertuples():
        m = _marker(r, largest)
        ax.errorbar(r.latency_ms_median, r.ssim_mean, xerr=[[r.latency_ms_median - r.latency_ms_p10],
                                                             [r.latency_ms_p90 - r.latency_ms_median]],
                    capsize=3, elinewidth=1, **m)
        handles.append(Line2D([], [], **m, label=_label(r) + (" (Pareto front)" if r.pareto else "")))
        axh.plot(r.latency_ms_median, r.height_err_mm_mean, **m)
    front = looks[looks.pareto].sort_values("latency_ms_median")
    handles.append(ax.plot(front.latency_ms_median, front.ssim_mean, "k--", lw=1, label="SSIM Pareto front")[0])
    for a, col in ((ax, "ssim_mean"), (axh, "height_err_mm_mean")):
        for r in mean.itertuples():
            a.axhline(getattr(r, col), color="0.45", ls=":", lw=1.5)
            a.annotate(f"mean image: {getattr(r, col):.3g} (ignores its input, {r.latency_ms_median:.1g} ms)",
                       (0.01, getattr(r, col)), xycoords=("axes fraction", "data"), xytext=(0, 3),
                       textcoords="offset points", fontsize=7.5, color="0.3", va="bottom")
        a.axvline(1e3 / 30, color="0.7", lw=1, zorder=0)
        a.annotate("real time: 33 ms (30 light fields/s)", (1e3 / 30, 0.5), xycoords=("data", "axes fraction"),
                   xytext=(-3, 0), textcoords="offset points", fontsize=7, color="0.4", rotation=90,
                   ha="right", va="center")
        _log_ms_axis(a, lo, hi)
    if len(mean):   # room above the mean image's line for its label
        for a, col in ((ax, "ssim_mean"), (axh, "height_err_mm_mean")):
            vals = ref[col].dropna()
            pad = 0.06 * (vals.max() - vals.min())
            a.set_ylim(vals.min() - pad, vals.max() + 2 * pad if a is axh else vals.max() + pad)
    ax.set_xlabel("latency per light field, 4 planes (ms, median and p10-p90; log)")
    ax.set_ylabel("SSIM vs reference (mean of 4 planes)")
    ax.set_title("accuracy of the planes", fontsize=10)
    axh.set_xlabel("latency per light field, 4 planes (ms, median; log)")
    axh.set_ylabel("flame height error (mm, mean abs., mean of 4 planes)")
    axh.set_title("flame height vs the simulation's truth (lower is better)", fontsize=10)
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False,
               title="colour: route; square: whole-lenslet shifts or the smaller backbone input; hollow: JAX",
               title_fontsize=8)
    rows = int(np.ceil(len(handles) / 3))
    fig.tight_layout(rect=(0, 0.035 * rows + 0.05, 1, 1))
    fig.savefig(out / "tradeoff_pareto.png", dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 3, figsize=(14, 4.2))
    sim = df[df.section == "simulator: rays per pixel"]
    for scene, g in sim.groupby("route"):
        g = g.sort_values("rays_per_pixel")
        ax[0].loglog(g.latency_ms_median, g.image_rmse, "o-", label=scene)
        for r in g.itertuples():
            ax[0].annotate(f"{r.rays_per_pixel:.0f}", (r.latency_ms_median, r.image_rmse), fontsize=7,
                           xytext=(4, 3), textcoords="offset points")
    if len(sim):
        _log_ms_axis(ax[0], sim.latency_ms_median.min() / 1.3, sim.latency_ms_median.max() * 1.4)
    ax[0].set(xlabel="render time (ms; log)", ylabel="image RMSE vs high-sample render (log)",
              title="simulator: rays per pixel (labels)")
    ax[0].legend(fontsize=8, loc="upper right")
    ss = df[df.section == "slope search"]       # in grid order, coarse to fine
    ax[1].loglog(ss.latency_ms_median, ss.slope_error_max, "o-", label="largest error")
    ax[1].loglog(ss.latency_ms_median, ss.slope_error_mean, "s--", label="mean error")
    for r in ss.itertuples():
        ax[1].annotate(f"{r.coarse_step:g}/{r.fine_step:g}", (r.latency_ms_median, r.slope_error_max), fontsize=7,
                       xytext=(4, 3), textcoords="offset points")
    if len(ss):
        _log_ms_axis(ax[1], ss.latency_ms_median.min() / 1.2, ss.latency_ms_median.max() * 1.5)
    ax[1].set(xlabel="time per object (ms; log)", ylabel="slope error (lenslets per view; log)",
              title="slope search: coarse/fine grid step (labels)")
    ax[1].legend(fontsize=8, loc="best")
    tr = df[df.section == "training"]
    for route, g in tr.groupby("route"):
        ax[2].plot(g.train_wall_s / 60, g.val_ssim, ".-", label=route)
    ax[2].set(xlabel="training wall time (min)", ylabel="validation SSIM (vs dataset GT)", title="training")
    ax[2].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(out / "tradeoff_knobs.png", dpi=100)
    plt.close(fig)
    if (df.section == "reconstruction").any():
        plot_reconstruction(df, out)
    if (df.section == "emission").any():
        plot_emission(df, out)


def summary(df: pd.DataFrame, prov: dict, n_test: int, ref_rpp: int, gt_heights: dict | None = None) -> str:
    ref = _routes(df)
    cols = ["route", "setting", "backend", "latency_ms_median", "latency_ms_p10", "latency_ms_p90",
            "throughput_lf_per_s", *[f"ssim_{p}" for p in PLANES], "ssim_mean", "psnr_db_mean",
            *[f"height_err_mm_{p}" for p in PLANES], "height_err_mm_mean", "height_share_over_1mm",
            "height_err_mm_p90", "height_err_mm_max", "height_flagged", "height_failed", "pareto"]
    fastest = ref.loc[ref[ref.route != "mean image"].latency_ms_median.idxmin()]
    best = ref.loc[ref.ssim_mean.idxmax()]
    models = ref[ref.route == "model"]
    lines = ["# What accuracy costs: speed-accuracy map", "",
             f"Generated by `make tradeoff` (`experiments/tradeoff.py`) on {prov['cpu_count']} CPU cores "
             f"({prov['processor']}), {prov['date']}, commit {prov['git_commit']}; Keras "
             f"{prov['versions'].get('keras')}, TensorFlow {prov['versions'].get('tensorflow-cpu') or prov['versions'].get('tensorflow')}, "
             f"JAX {prov['versions'].get('jax', 'not installed')}. No GPU.", "",
             f"## Refocusing routes: raw flame light field -> 4 planes ({n_test} test light fields)", "",
             f"Reference: bilinear shift-and-sum at the same slopes of the same scenes rendered noise-free at "
             f"{ref_rpp} rays/pixel. Latency: median (p10-p90) of repeated calls after a warm-up. "
             "Height error: flame height measured on the route's planes (`lf_flame.measure.diagnostics`) against the "
             "simulation's true height, mean absolute error in mm per plane, and its tail over all planes: the "
             "share off by more than 1 mm, the 90th percentile and the worst; `height_flagged`: planes whose "
             "height the method cannot trust (`FlameMeasurement.flags`); `height_failed`: planes where no "
             "flame could be measured (left out).", "",
             ref[[c for c in cols if c in ref]].to_markdown(index=False, floatfmt=".4g"), "",
             "![Pareto](tradeoff_pareto.png)", "",
             f"- Fastest: **{_label(fastest)}**, {fastest.latency_ms_median:.3g} ms, SSIM {fastest.ssim_mean:.3f}.",
             f"- Most accurate: **{_label(best)}**, SSIM {best.ssim_mean:.3f} at {best.latency_ms_median:.3g} ms.",
             f"- Pareto front: {', '.join(_label(r) for r in ref[ref.pareto].itertuples())}.",
             "- Flame height error (mm, mean over the planes) beside latency: " + "; ".join(
                 f"{_label(r)}: {r.height_err_mm_mean:.2f} mm at {r.latency_ms_median:.3g} ms"
                 + (f" ({r.height_failed:.0f} planes unmeasurable)" if r.height_failed else "")
                 for r in ref.sort_values("height_err_mm_mean").itertuples()) + "."]
    if gt_heights:
        lines.append("- The dataset's own ground-truth planes of the same light fields: height error "
                     + ", ".join(f"{gt_heights[f'height_err_mm_{p}']:.2f}" for p in PLANES)
                     + f" mm ({', '.join(PLANES)}): what the measurement itself costs.")
    if len(models):
        m = models.loc[models.latency_ms_median.idxmin()]
        bil = ref[(ref.route == "shift-sum") & (ref.setting == "bilinear")].iloc[0]
        lines.append(f"- Real time (30 light fields/s, 33 ms): the fastest model ({_label(m)}) takes "
                     f"{m.latency_ms_median:.3g} ms ({m.throughput_lf_per_s:.3g} light fields/s), "
                     f"{'within' if m.latency_ms_median <= 33.3 else 'outside'} it; bilinear shift-and-sum "
                     f"takes {bil.latency_ms_median:.3g} ms ({bil.throughput_lf_per_s:.3g}/s), "
                     f"{m.latency_ms_median / bil.latency_ms_median:.3g}x faster than the model, "
                     f"at SSIM {bil.ssim_mean:.3f} against the model's {m.ssim_mean:.3f}.")
    learned = ref[ref.route.isin(["model", "mean image", "linear decoder (GAP-pooled)", "linear decoder (un-pooled)"])
                  & (ref.backend != "jax")]
    if len(learned):
        lines.append("- The learned routes beside their yardsticks (same backbone, same light fields): " + "; ".join(
            f"{_label(r)}: SSIM {r.ssim_mean:.3f}, {r.psnr_db_mean:.1f} dB, "
            f"height error {r.height_err_mm_mean:.2f} mm, {r.latency_ms_median:.3g} ms"
            for r in learned.itertuples()) + ".")
    for sec, cols in (("simulator: rays per pixel", ["route", "rays_per_pixel", "latency_ms_median", "image_rmse"]),
                      ("simulator: effects", ["setting", "latency_ms_median"]),
                      ("slope search", ["setting", "latency_ms_median", "slope_error_max", "slope_error_mean"])):
        lines += ["", f"## {sec[0].upper() + sec[1:]}", "", df[df.section == sec][cols].to_markdown(
            index=False, floatfmt=".4g")]
    tr = df[df.section == "training"]
    lines += ["", "## Training: validation SSIM against time", ""]
    for route, g in tr.groupby("route"):
        b = g.loc[g.val_ssim.idxmax()]
        lines.append(f"- {route}: best validation SSIM {b.val_ssim:.3f} at epoch {b.epochs:.0f} "
                     f"({b.train_wall_s / 60:.1f} min); last {g.val_ssim.iloc[-1]:.3f} at epoch "
                     f"{g.epochs.iloc[-1]:.0f} ({g.train_wall_s.iloc[-1] / 60:.1f} min).")
    lines += ["", "![knobs](tradeoff_knobs.png)", ""]
    rec = df[df.section == "reconstruction"]
    if len(rec):
        rec = rec.assign(solver=(rec.route.str.replace("reconstruct-", "") + " " + rec.knobs.fillna("")).str.strip(),
                         s_per_it=rec.latency_ms_median / 1e3 / rec.iters)
        err = rec.pivot_table(index=["scene", "noise", "solver"], columns="iters", values="worst_plane_rel_err",
                              sort=False)
        per_it = rec.groupby(["scene", "noise", "solver"], sort=False).s_per_it.median()
        err.columns = [f"{int(c)} it." for c in err.columns]
        lines += ["## 3-D reconstruction: worst-plane emission error against iterations and time", "",
                  "From `make reconstruct`'s validation curves (`reconstruct_iters.csv`: the renders the "
                  "iterations and weights are chosen on; the scored renders are in `reconstruct.md`). "
                  "Worst plane's relative error ‖x̂ − x‖/‖x‖ over the renders; `s/it.`: seconds per "
                  "iteration (median), so a setting's time is iterations x s/it.", "",
                  err.assign(**{"s/it.": per_it}).reset_index().to_markdown(index=False, floatfmt=".3g"), "",
                  "![reconstruction](tradeoff_reconstruct.png)", ""]
    dv = df[df.section.isin(["depth", "volume"])]
    if len(dv):
        lines += ["## Flames at unknown depths and volumes: error against time per light field", "",
                  "From `make depth` (`depth.csv`: per flame of the random-depth scenes, its emission error on the "
                  "plane at its found depth; `depth_err_mm_p90`: the depth error's 90th percentile, a missed flame "
                  "counted as infinite) and `make volume` (`volume*.csv`: the 3-D relative error per scene, scored "
                  "volumes only; `centroid_mm_mean`: the per-line-of-sight depth centroid's error, mean over "
                  "scenes). `error_tail`: the 90th percentile over flames (depth), the worst scene (volume). "
                  "Time: the whole route per light field (depth search, "
                  "operator, solve), median and 90th percentile.", "",
                  dv.reindex(columns=["section", "scene", "route", "noise", "latency_ms_median", "latency_ms_p90",
                                      "error_median", "error_tail", "depth_err_mm_p90", "centroid_mm_mean",
                                      "n_samples"]).to_markdown(index=False, floatfmt=".3g"), ""]   # a run may lack one
    em = df[df.section == "emission"]
    if len(em):
        lines += ["## Each plane's emission, learned and solved: error against time per light field", "",
                  "From `make train-reconstructor` (`learned.csv`: traced scored renders; `error_median` and "
                  "`error_tail`: the worst plane per render, median and worst over renders). Time per light field, "
                  "median and 90th percentile, the operator and the network built.", "",
                  em[["scene", "noise", "route", "latency_ms_median", "latency_ms_p90", "error_median", "error_tail",
                      "n_samples"]].to_markdown(index=False, floatfmt=".3g"), "",
                  "![emission](tradeoff_emission.png)", ""]
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--preset", choices=["paper", "quick"], default="paper")
    p.add_argument("--data-dir")
    p.add_argument("--model-dir")
    p.add_argument("--out")
    p.add_argument("--models-only", help=argparse.SUPPRESS)  # JAX subprocess: inputs .npz
    p.add_argument("--repeats", type=int, default=20, help="timed calls per route after the warm-up")
    p.add_argument("--plot-only", action="store_true",
                   help="measure nothing: redraw the two figures in --out from the tradeoff.csv there")
    p.add_argument("--reconstruction-only", action="store_true",
                   help="measure nothing: replace the reconstruction, depth, volume and emission rows of --out's "
                        "tradeoff.csv with those of its reconstruct_iters.csv (make reconstruct), depth.csv (make "
                        "depth), volume*.csv (make volume) and learned.csv (make train-reconstructor), redraw the "
                        "figures and rewrite tradeoff.md")
    p.add_argument("dirs", nargs="*", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.models_only:
        z = np.load(a.models_only)
        truth = None
        if "camera" in z:
            from lf_flame.optics.camera import PlenopticCamera
            truth = (PlenopticCamera.from_dict(json.loads(str(z["camera"]))), json.loads(str(z["objects"])))
        print(json.dumps(model_rows(a.dirs, list(z["raws"]), z["refs"], a.repeats, baselines=False, truth=truth)))
        return 0
    if a.plot_only:
        if not a.out:
            p.error("--plot-only needs --out (the folder with tradeoff.csv)")
        out = Path(a.out)
        plot(pd.read_csv(out / "tradeoff.csv"), out)
        print(f"-> {out / 'tradeoff_pareto.png'}, {out / 'tradeoff_knobs.png'}")
        return 0

    if a.reconstruction_only:
        out = Path(a.out)
        old = pd.read_csv(out / "tradeoff.csv")
        df = pd.concat([old[~old.section.isin(["reconstruction", "depth", "volume", "emission"])],
                        pd.DataFrame(reconstruction_rows(out) + depth_volume_rows(out) + emission_rows(out))],
                       ignore_index=True)
        atomic_write_text(out / "tradeoff.csv", df.to_csv(index=False))
        plot(df, out)
        j = json.loads((out / "tradeoff.json").read_text())
        atomic_write_text(out / "tradeoff.md", summary(df, j["provenance"], len(j["test_indices"]),
                                                       j["tradeoff_config"]["ref_rays_per_pixel"],
                                                       j.get("ground_truth_height_err_mm")))
        print(f"{int((df.section == 'reconstruction').sum())} reconstruction rows, "
              f"{int(df.section.isin(['depth', 'volume']).sum())} depth and volume rows -> {out / 'tradeoff.md'}")
        return 0

    t0 = time.perf_counter()
    ecfg = ROOT / "experiments" / f"{a.preset}.toml"
    tcfg = load_toml(ecfg)["tradeoff"]
    quick = a.preset == "quick"
    out, models = Path(a.out), Path(a.model_dir)
    out.mkdir(parents=True, exist_ok=True)
    flame = Path(a.data_dir) / "flame.h5"
    ds = LightFieldDataset(flame)

    # the second backbone input size, trained here under the same settings and its own budget
    small = models / f"flame-{tcfg['small_input']}"
    if not (small / "train_info.json").exists():
        from lf_flame.learn.training import train
        mcfg, trc = load_experiment_config(ecfg)
        rows_, cols_ = (int(v) for v in tcfg["small_input"].split("x"))
        train(flame, small, dataclasses.replace(mcfg, input_rows=rows_, input_cols=cols_),
              dataclasses.replace(trc, time_budget_s={"flame": tcfg["small_budget_s"]}), progress=not quick)
    model_dirs = [models / "flame", small]

    test = np.sort(ds.splits["test"])[: tcfg["n_test"]]
    print(f"reference stacks of {len(test)} test light fields at {tcfg['ref_rays_per_pixel']} rays/pixel")
    refs = reference_stacks(ds, test, tcfg["ref_rays_per_pixel"])
    raws = [ds.raw(int(i)) for i in test]
    truth = (ds.camera, [ds.params(int(i)) for i in test])
    gt_heights = _height_accuracy(ds.gt(list(test)), truth)  # the dataset's own ground-truth planes
    rows = classical_rows(ds, raws, refs, a.repeats, truth)
    rows += model_rows(model_dirs, raws, refs, a.repeats, truth=truth)
    import importlib.util
    if importlib.util.find_spec("jax") is not None:
        rows += jax_model_rows(model_dirs, raws, refs, a.repeats, out, truth)
    print("simulator knobs")
    rows += simulator_rows(quick)
    print("slope search grids")
    rows += slope_search_rows(tcfg["calibration_rays_per_pixel"], [tuple(g) for g in tcfg["slope_grids"]],
                              ds.camera if quick else PAPER_CAMERA)
    shapes = [models / "shapes"] if (models / "shapes" / "train_info.json").exists() else []
    rows += training_rows(model_dirs + shapes)
    rows += reconstruction_rows(out) + depth_volume_rows(out) + emission_rows(out)
    df = pd.DataFrame(rows)
    prov = provenance()
    tmp = out / "tradeoff.csv.partial"
    df.to_csv(tmp, index=False)
    os.replace(tmp, out / "tradeoff.csv")
    plot(df, out)
    atomic_write_text(out / "tradeoff.md", summary(df, prov, len(test), tcfg["ref_rays_per_pixel"], gt_heights))
    atomic_write_text(out / "tradeoff.json", json.dumps(dict(
        preset=a.preset, tradeoff_config=tcfg, repeats=a.repeats, dataset=str(flame), test_indices=test.tolist(),
        ground_truth_height_err_mm=gt_heights,
        models=[str(d) for d in model_dirs], wall_time_s=time.perf_counter() - t0, provenance=prov), indent=2))
    print((out / "tradeoff.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
