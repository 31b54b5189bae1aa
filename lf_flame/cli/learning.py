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
from ._io import RAW_FORMATS, _load_raw, _write_stack
from .options import count, positive_int, finite


def cmd_dataset(a):
    from ..config import load_data_config
    from ..learn.dataset import generate
    cam, cfg = load_data_config(a.data_config)
    if a.regime:
        cfg = dataclasses.replace(cfg, regime=a.regime)
    try:
        record = json.loads(Path(a.slopes).read_text())
        slopes = record["slopes"]
    except (ValueError, KeyError, TypeError):
        raise ValueError(f"{a.slopes} is not a slopes file of 'lf-flame slopes --data-config' (JSON with the "
                         "'slopes' of the data config's four depths)") from None
    if "camera" in record:               # the slopes of the camera they were found on (older files record none)
        from ..optics.camera import PlenopticCamera
        from ..real.readers import camera_differences
        diff = camera_differences(PlenopticCamera.from_dict(record["camera"]), cam)
        if diff:
            raise ValueError(f"{a.slopes} holds the slopes of another camera than {a.data_config}'s ("
                             + "; ".join(diff[:3]) + "): its ground truth would be refocused off the objects' "
                             f"planes; find this camera's with 'lf-flame slopes --data-config {a.data_config}'")
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
    from ..learn import evaluation
    table = evaluation.evaluate(a.dataset, a.model_dir, a.results, n_heldout=a.heldout, heldout_seed=a.heldout_seed)
    print(table.to_string(index=False))
    for line in evaluation.below_the_mean_image(table):
        print(line)


def cmd_tables(a):
    import h5py
    from ..config import read_json
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
                    times[f"dataset {regime} {scene}"] = float(       # every run's (older files: the last run's)
                        f.attrs.get("wall_time_s", f.attrs.get("wall_time_s_last_run", float("nan"))))
            info = Path(a.model_dir) / regime / scene / "train_info.json"
            if info.exists():
                i = read_json(info, "record of a training run (train it again)")
                try:       # when they were computed, maybe by an earlier run; a cache deleted since: no time
                    with h5py.File(i["feature_cache"], "r") as f:
                        times[f"backbone features {regime} {scene}"] = float(f.attrs["wall_time_s"])
                except OSError:
                    print(f"note: {i['feature_cache']} is gone: the backbone features' time of {regime} {scene} "
                          "is left out")
                times[f"training {regime} {scene} (start + {i['epochs_run']} epochs)"] = i["training_wall_time_s"]
            tv = Path(a.model_dir) / regime / scene / "time_v.txt"
            if tv.exists():
                try:
                    targets[f"train {regime} {scene}"] = read_gnu_time(tv)
                except ValueError:      # a run killed with its timer: no report was written
                    print(f"note: {tv} holds no complete GNU time report (its runs were killed): the training "
                          f"target's time and memory of {regime} {scene} are left out")
    print(write_tables(a.results, times, targets))


def add_parsers(sub) -> None:
    """Add ``dataset``, ``train``, ``predict``, ``evaluate`` and ``tables`` to ``sub``, the sub-parsers of
    :func:`lf_flame.cli.build_parser`."""
    s = sub.add_parser("dataset", help="generate (or resume) a dataset in HDF5")
    s.add_argument("--data-config", required=True, help="data config TOML (camera, sizes, seed, regime)")
    s.add_argument("--scene", choices=["shapes", "flame"], required=True, help="the paper's shapes or four flames")
    s.add_argument("--slopes", required=True, help="JSON written by 'lf-flame slopes'")
    s.add_argument("--regime", choices=["paper", "varied"],
                   help="scene variation (docs/scenes.md) instead of the data config's")
    s.add_argument("--out", required=True, help="dataset HDF5 (resumed when it exists)")
    s.add_argument("--shard", help="i/N: render only shard i of N (1 <= i <= N) beside --out; an unsharded "
                                   "run imports finished shards and renders the rest")
    s.add_argument("--scheduler", help="render on the Dask cluster at this address (tcp://...) or scheduler file")
    s.add_argument("--workers", type=positive_int, help="render on a local Dask cluster of this many worker "
                   "processes (>= 1)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_dataset)

    s = sub.add_parser("train", help="train the decoder on cached backbone features (resumable)")
    s.add_argument("--dataset", required=True, help="dataset HDF5 written by 'lf-flame dataset'")
    s.add_argument("--experiment-config", required=True, help="experiment config TOML (model and training)")
    s.add_argument("--out", required=True, help="model folder")
    s.set_defaults(out_is_folder=True)
    s.add_argument("--input-size", help="ROWSxCOLS: backbone input size instead of the config's")
    s.add_argument("--time-budget-s", type=finite, help="training time budget (s) instead of the config's")
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("predict", help="the trained model's 4 refocused planes of a raw image, with its latency")
    s.add_argument("raw", help=RAW_FORMATS)
    s.add_argument("--model-dir", required=True, help="folder written by 'lf-flame train'")
    s.add_argument("--out", required=True, help=".npz (stack (4, R, C), latency_s) or .png (planes side by side)")
    s.add_argument("--repeat", type=int, default=5, help="timed calls after the warm-up")
    s.add_argument("--route", choices=list(LEARNED_ROUTES), default="network",
                   help="the trained network, or one of its yardsticks saved beside it")
    s.set_defaults(func=cmd_predict)

    s = sub.add_parser("evaluate", help="SSIM/PSNR per plane on the test split, table and figure")
    s.add_argument("--dataset", required=True, help="dataset HDF5 written by 'lf-flame dataset'")
    s.add_argument("--model-dir", required=True, help="folder written by 'lf-flame train'")
    s.add_argument("--results", required=True, help="folder for the table (CSV) and figure")
    s.add_argument("--heldout", type=count, default=0,
                   help="also score a second held-out set of this many samples, drawn with --heldout-seed")
    s.add_argument("--heldout-seed", type=int, default=None,
                   help="seed of the second held-out set: needed with --heldout, not the dataset's seed")
    s.set_defaults(func=cmd_evaluate)

    s = sub.add_parser("tables", help="collect Tables I and II, slopes and stage times into tables.md")
    s.add_argument("--results", required=True, help="results folder: reads the evaluations, writes tables.md")
    s.add_argument("--data-dir", required=True, help="folder of the datasets and slopes.json")
    s.add_argument("--model-dir", required=True, help="folder of the trained models")
    s.set_defaults(func=cmd_tables)
