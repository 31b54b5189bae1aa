"""The learned reconstructor (``make train-reconstructor``): trained on exact-operator light fields, scored on traced renders.

Stages (``--stage``, default all):

- **data**: training and validation samples (:func:`lf_flame.learn.reconstructor.training_samples`:
  the ``depth`` and ``four-flames`` families at random depths, exact operator, noise-free or
  10-24 dB) from seeds ``TRAIN_SEED`` and ``VAL_SEED``, kept in ``--cache`` (.npz, written to a
  temporary file and renamed; a run finds them there).
- **train**: the network, its epoch chosen on the validation samples; saved with its config,
  camera, seeds and record in ``--models`` (``reconstructor.json`` + weights); the score stage adds
  its scores to that record.
- **score**: on traced renders at ``--rays`` per pixel (the ray tracer, never the operator that made
  the training data; ``experiments/fourier_solver.py``'s cache and seeds), noise-free and at 14 dB:
  the paper's, varied and overlap scenes (the overlap family and the paper's fixed depths are
  left out of training) and random-depth scenes (the training family, traced), each route scored
  by :func:`lf_flame.tomo.scoring.score_planes` on the same truth: ``learned``, its Wiener start
  alone (negatives clipped), admm at its defaults, admm started from the learned planes (in
  place of its coarse start, its knobs by the noise as ever), shift-and-sum; with each route's
  time per light field: median and p90 of ``--repeats`` calls (a quarter as many, at least 2,
  for the admm routes) after a warm-up call (graphs, FFT plans, per-frequency factors).

Writes ``learned.csv`` (one row per route, render, noise and plane), ``learned.md`` and
``learned.json`` (config, seeds, provenance, wall time) in ``--out``. Timings come from a
shared 2-core machine: compare rows of one run.

Usage: ``python experiments/learned.py --out results [--scenes 240] [--tests 3] [--epochs 30] [--camera FILE
[--calibration cal.json] --models DIR]`` (``--quick``: a tiny run for the tests; ``--camera``: train for another
camera, scored on its random-depth scenes; a real lenslet grid's with ``--calibration``: for its decoded views'
camera).
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fourier_solver as FS  # noqa: E402  (its traced renders and seeds)
import reconstruct as R  # noqa: E402

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.learn import reconstructor as L  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.optics.camera_file import load_camera_file  # noqa: E402
from lf_flame.real.calibration import GridCalibration  # noqa: E402
from lf_flame.real.own_camera import decoded_views_camera  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack  # noqa: E402
from lf_flame.routes import measure_settings  # noqa: E402
from lf_flame.simulate.scenes_depth import camera_depth_scene  # noqa: E402
from lf_flame.tomo import fourier  # noqa: E402
from lf_flame.tomo.exact import ExactOperator  # noqa: E402
from lf_flame.tomo.scoring import score_planes  # noqa: E402
from lf_flame.tomo.solvers import reconstruct  # noqa: E402
from lf_flame.tomo.truth import bin_planes, scene_truth  # noqa: E402

TRAIN_SEED, VAL_SEED = 1_100_000, 1_200_000
#: scored families: the paper's fixed scenes and the overlap family are left out of training
KINDS = ("paper", "varied", "overlap", "depth")


def cached_samples(cam, n, seed, cfg, cache: Path, name: str):
    """:func:`~lf_flame.learn.reconstructor.training_samples` kept in ``cache`` under a name that holds
    everything they depend on (count, seed, families, noise, camera)."""
    key = json.dumps([n, seed, L.TRAIN_FAMILIES, cfg.snr_db, cfg.clean_share, L.READ_NOISE_E, cam.to_dict()],
                     sort_keys=True, default=str)
    path = cache / f"{name}_{n}_{seed}_{hashlib.blake2b(key.encode(), digest_size=6).hexdigest()}.npz"
    if not path.exists():
        x, y = L.training_samples(cam, n, seed, cfg)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".partial.npz")
        np.savez(tmp, x=x, y=y)
        tmp.rename(path)
    f = np.load(path)
    return f["x"], f["y"]


def camera_tag(cam) -> str:
    """'' for the paper's camera, else a short digest of the camera (the caches' names)."""
    if cam == PAPER_CAMERA:
        return ""
    return hashlib.blake2b(json.dumps(cam.to_dict(), sort_keys=True).encode(), digest_size=4).hexdigest() + "_"


def traced_set(cam, kind, seed, rays, cache):
    """(scene, views clean, views at 14 dB, own error) of one traced render, cached."""
    if kind != "depth":
        scene, clean, noisy, own, _ = FS.render_set(cam, kind, seed, rays, cache)
        return scene, clean, noisy, own
    scene = camera_depth_scene(cam, np.random.default_rng(seed))
    path = cache / f"{camera_tag(cam)}depth_{seed}_{rays}.npz"
    clean, noisy, own, _ = R.cached_render(cam, scene, rays, seed, path, FS.SNR_DB)
    return scene, clean, noisy, own


def timed(f, repeats):
    """``f()`` after a warm-up call (graphs, FFT plans, per-frequency factors): (its result, median and p90 s)."""
    f()
    t, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = f()
        t.append(time.perf_counter() - t0)
    return out, float(np.median(t)), float(np.percentile(t, 90))


def score(cam, model, rays, cache, seeds, repeats, kinds=KINDS):
    rows = []
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    emission = measure_settings("reconstruct-admm")
    for kind, seed in itertools.product(kinds, seeds):
        scene, clean, noisy, own = traced_set(cam, kind, seed, rays, cache)
        depths = L.scene_depths(scene)
        fine = ExactOperator(cam, depths, precision=FS.PRECISION, subsamples=2)
        op, _ = fourier.coarse_operator(fine)
        truth = scene_truth(scene, op)
        slopes = [cam.slope_for_depth(d) for d in depths]
        for noise, views in (("clean", clean), ("14dB", noisy)):
            routes = {
                "learned": (lambda: model.planes(views, op), repeats, emission),
                "learned start + admm (2 x 2 grid)": (lambda: reconstruct(views, fine, "admm",
                                                                          start_planes=model.planes(views, op)),
                                                      max(2, repeats // 4), emission),
                "admm (2 x 2 grid)": (lambda: reconstruct(views, fine, "admm"), max(2, repeats // 4), emission),
                "wiener start": (lambda: np.clip(fourier.wiener_start(views, op, views < 1.0)[0], 0, None), repeats,
                                 emission),
                "shift-and-sum": (lambda: focal_stack(views, slopes, mask), repeats, None)}
            for route, (f, n, measure) in routes.items():
                out, med, p90 = timed(f, n)
                extra = {}
                if not isinstance(out, np.ndarray):
                    out, extra = bin_planes(out.planes, 2), dict(fills_run=out.settings["fills_run"])
                rows.append(score_planes(out, truth, cam, depths, scene.objects, time_s=med, time_p90_s=p90,
                                         route=route, measure=measure, scene=kind, seed=seed, noise=noise,
                                         own_error=own, in_training=kind == "depth", **extra))
        print(f"  score {kind} {seed} done", flush=True)
    return pd.concat(rows, ignore_index=True)


def summary(df):
    """Per route, scene and noise: the worst plane per render (mean and max over renders) and the time per light
    field (median of the renders' medians, the largest p90)."""
    worst = df.groupby(["route", "scene", "noise", "seed"]).agg(worst=("rel_err", "max"), t=("time_s", "first"),
                                                                t90=("time_p90_s", "first"))
    return worst.groupby(["route", "scene", "noise"]).agg(
        worst_plane_mean=("worst", "mean"), worst_plane_max=("worst", "max"), n=("worst", "size"),
        time_median_s=("t", "median"), time_p90_s=("t90", "max")).reset_index()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=Path("results"))
    ap.add_argument("--camera", type=Path, default=None,
                    help="a camera file (lf_flame.optics.camera_file) to train for; default the paper's camera. "
                         "Its scored renders are the random-depth family alone (the paper's scenes are its camera's)")
    ap.add_argument("--calibration", type=Path, default=None,
                    help="with --camera of a lenslet grid that is not perfect (rotated, offset, a pitch of no whole "
                         "number of pixels, hexagonal: every real one): its white-image calibration ('lf-flame "
                         "calibrate'); the network is trained for the views that decoding with it gives")
    ap.add_argument("--models", type=Path, default=Path("models/reconstructor/paper"))
    ap.add_argument("--cache", type=Path, default=Path("data/learned"))
    ap.add_argument("--render-cache", type=Path, default=Path("data/fourier_solver"))
    ap.add_argument("--stage", choices=("all", "data", "train", "score"), default="all")
    ap.add_argument("--scenes", type=int, default=240, help="training scenes (4 light fields each)")
    ap.add_argument("--val-scenes", type=int, default=25)
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--base-channels", type=int, default=16)
    ap.add_argument("--tests", type=int, default=3)
    ap.add_argument("--rays", type=int, default=400)
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--quick", action="store_true", help="a tiny run: 2 scenes, 1 epoch, 1 test, 16 rays")
    a = ap.parse_args(argv)
    if a.quick:
        a.scenes, a.val_scenes, a.epochs, a.tests, a.rays, a.repeats = 2, 1, 1, 1, 16, 2
    cam = PAPER_CAMERA if a.camera is None else load_camera_file(a.camera)
    if not cam.perfect_grid:        # a real grid: the network sees its decoded views, whose camera the calibration's
        if a.calibration is None:
            ap.error(f"{a.camera} describes a lenslet grid that is not perfect: give its white-image calibration "
                     "(--calibration cal.json, or CALIBRATION=cal.json to make): the network is trained for the "
                     "views decoding gives")
        cam = decoded_views_camera(cam, GridCalibration.load(a.calibration))[0]
    elif a.calibration is not None:
        ap.error(f"--calibration is for a camera whose lenslet grid is not perfect; "
                 f"{a.camera or 'the paper camera'} is decoded without one")
    cfg = L.ReconstructorConfig(epochs=a.epochs, base_channels=a.base_channels)
    t_start = time.perf_counter()
    if a.stage in ("all", "data", "train"):
        train = cached_samples(cam, a.scenes, TRAIN_SEED, cfg, a.cache, "train")
        val = cached_samples(cam, a.val_scenes, VAL_SEED, cfg, a.cache, "val")
        if a.stage != "data":
            model = L.train(cam, train, val, cfg)
            model.record.update(train_seed=TRAIN_SEED, train_scenes=a.scenes, val_seed=VAL_SEED,
                                val_scenes=a.val_scenes, families=list(L.TRAIN_FAMILIES), provenance=provenance())
            model.save(a.models)
            print(f"trained: best epoch {model.record['best_epoch']} of {model.record['epochs_run']}, "
                  f"{model.record['train_s']:.0f} s -> {a.models}", flush=True)
    if a.stage in ("all", "score"):
        model = L.LearnedReconstructor.load(a.models)
        df = score(cam, model, a.rays, a.render_cache, R.TEST_SEEDS[:a.tests], a.repeats,
                   KINDS if a.camera is None else ("depth",))
        a.out.mkdir(parents=True, exist_ok=True)
        df.to_csv(a.out / "learned.csv", index=False)
        s = summary(df)
        model.record.update(scores=s.to_dict("records"), scores_file=str(a.out / "learned.csv"))
        model.save(a.models)                                      # the weights, their config and their scores together
        meta = dict(config=dataclasses.asdict(model.config), record=model.record, rays=a.rays,
                    test_seeds=list(R.TEST_SEEDS[:a.tests]), own_errors=df.groupby(["scene", "seed"]).own_error.first()
                    .reset_index().to_dict("records"), wall_s=time.perf_counter() - t_start, provenance=provenance())
        atomic_write_text(a.out / "learned.json", json.dumps(meta, indent=1, default=str))
        md = ["# The learned reconstructor (`python experiments/learned.py`)", "",
              f"Trained on {model.record.get('train_scenes')} scenes x 4 light fields of the families "
              f"{', '.join(model.record.get('families', []))} (exact operator, 2 x 2 samples per lenslet, noise-free or "
              f"{cfg.snr_db[0]:g}-{cfg.snr_db[1]:g} dB); epoch {model.record.get('best_epoch')} of "
              f"{model.record.get('epochs_run')} kept on the validation samples; training "
              f"{model.record.get('train_s', float('nan')):.0f} s. Scored on traced renders at {a.rays} rays per pixel "
              "(own error in learned.json); 'depth' is the training family, the others are left out of training.", "",
              "## Worst plane of the worst render (relative L2 error)", "",
              s.pivot_table(index=["scene", "noise"], columns="route", values="worst_plane_max").to_markdown(
                  floatfmt=".3f"), "",
              "## Every figure", "", s.to_markdown(index=False, floatfmt=".3f"), ""]
        atomic_write_text(a.out / "learned.md", "\n".join(md))
        print(s.to_string())


if __name__ == "__main__":
    main()
