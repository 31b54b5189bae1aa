"""Commands of the learning stage: ``dataset`` (:mod:`lf_flame.learn.dataset`), ``train``
(:mod:`lf_flame.learn.training`), ``predict`` (a trained network or its yardsticks), ``evaluate``
and ``tables`` (:mod:`lf_flame.learn.evaluation`).
"""
from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np

from ..routes import LEARNED_ROUTES
from ._io import _load_raw, _write_stack


def cmd_dataset(a):
    from ..config import load_data_config
    from ..learn.dataset import generate
    cam, cfg = load_data_config(a.data_config)
    if a.regime:
        cfg = dataclasses.replace(cfg, regime=a.regime)
    slopes = json.loads(Path(a.slopes).read_text())["slopes"]
    shard = None
    if a.shard:
        try:
            shard = tuple(int(v) for v in a.shard.split("/"))
        except ValueError:
            raise SystemExit(f"--shard must look like i/N (e.g. 2/4). Received: {a.shard!r}") from None
    p = generate(a.out, cam, cfg, a.scene, slopes, progress=not a.quiet, shard=shard, scheduler=a.scheduler,
                 workers=a.workers)
    print(f"dataset -> {p}")


def cmd_train(a):
    from ..config import load_experiment_config
    from ..learn.training import train
    mcfg, tcfg = load_experiment_config(a.experiment_config)
    if a.input_size:
        try:
            rows, cols = (int(v) for v in a.input_size.lower().split("x"))
        except ValueError:
            raise SystemExit(f"--input-size must look like ROWSxCOLS (e.g. 224x112). Received: {a.input_size!r}")
        mcfg = dataclasses.replace(mcfg, input_rows=rows, input_cols=cols)
    if a.time_budget_s is not None:
        tcfg = dataclasses.replace(tcfg, time_budget_s={k: a.time_budget_s for k in tcfg.time_budget_s})
    info = train(a.dataset, a.out, mcfg, tcfg, progress=not a.quiet)
    print(f"trained {info['epochs_run']} epochs in {info['training_wall_time_s']:.0f} s "
          f"(best validation SSIM {info['best_val_ssim']:.4f} at epoch {info['best_epoch']}, backbone {info['backbone_weights']}) -> {a.out}")


def _learned_runner(raw, cam, raw_name, model_dir, route):
    """The function ``x (1, rows, cols, 1) -> stack (4, R, C)`` of a learned route, with the
    model's info; checks that the raw image fits the model."""
    from ..optics.camera import PlenopticCamera
    from ..learn.model_files import load_full_model
    model, info = load_full_model(model_dir)
    if tuple(raw.shape) != tuple(info["raw_shape"]):
        raise ValueError(f"raw image {raw.shape} does not match the model's sensor {tuple(info['raw_shape'])}")
    if cam is not None and cam != PlenopticCamera.from_dict(json.loads(info["dataset_camera"])):
        raise ValueError(f"{raw_name} was rendered with another camera than the model was trained on")
    if not np.all(np.isfinite(raw)):
        raise ValueError(f"{raw_name} contains NaN or inf")
    if route == "network":
        def run(x):
            return np.transpose(np.asarray(model.predict_on_batch(x))[0], (2, 0, 1))
    else:
        from ..learn.baselines import load_baselines
        base = load_baselines(model_dir)[LEARNED_ROUTES[route]]
        fx = model.get_layer("feature_extractor")

        def run(x):
            return base.predict(np.asarray(fx.predict_on_batch(x)))[0]
    return run, info


def cmd_predict(a):
    raw, cam = _load_raw(a.raw)
    run, info = _learned_runner(raw, cam, a.raw, a.model_dir, a.route)
    x = raw.astype(np.float32)[None, ..., None]
    run(x)  # warm-up: graph tracing
    times = []
    for _ in range(max(1, a.repeat)):
        t = time.perf_counter()
        stack = run(x)
        times.append(time.perf_counter() - t)
    print(f"{a.route}: predicted 4 planes {stack.shape[1:]} in {1e3 * np.median(times):.1f} ms per light field "
          f"(median of {len(times)} after a warm-up; backbone input {info['model_config']['input_rows']}x"
          f"{info['model_config']['input_cols']}, weights {info['backbone_weights']}, "
          f"keras backend {__import__('keras').backend.backend()})")
    _write_stack(a.out, stack, latency_s=np.asarray(times))


def cmd_evaluate(a):
    from ..learn.evaluation import evaluate
    table = evaluate(a.dataset, a.model_dir, a.results, n_heldout=a.heldout, heldout_seed=a.heldout_seed)
    print(table.to_string(index=False))


def cmd_tables(a):
    import h5py
    from ..learn.evaluation import read_gnu_time, write_tables
    from ..simulate.scenes import REGIMES
    times, targets = {}, {}
    sl = Path(a.data_dir) / "slopes.json"
    if sl.exists():
        times["slope search"] = json.loads(sl.read_text())["wall_time_s"]
    for regime in REGIMES:
        for scene in ("shapes", "flame"):
            d = Path(a.data_dir) / regime / f"{scene}.h5"
            if d.exists():
                with h5py.File(d, "r") as f:
                    times[f"dataset {regime} {scene}"] = float(f.attrs.get("wall_time_s_last_run", float("nan")))
            info = Path(a.model_dir) / regime / scene / "train_info.json"
            if info.exists():
                i = json.loads(info.read_text())
                with h5py.File(i["feature_cache"], "r") as f:  # when they were computed, maybe by an earlier run
                    times[f"backbone features {regime} {scene}"] = float(f.attrs["wall_time_s"])
                times[f"training {regime} {scene} (start + {i['epochs_run']} epochs)"] = i["training_wall_time_s"]
            tv = Path(a.model_dir) / regime / scene / "time_v.txt"
            if tv.exists():
                targets[f"train {regime} {scene}"] = read_gnu_time(tv)
    print(write_tables(a.results, times, targets))
