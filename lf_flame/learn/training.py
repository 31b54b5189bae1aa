"""Training: the paper's decoder on cached backbone features (batch 2, Adam 1e-4, MSE).

Stage: after the feature cache (:mod:`lf_flame.learn.features`), the yardsticks
(:mod:`lf_flame.learn.baselines`) and, by the 'closed-form' recipe, the start
(:mod:`lf_flame.learn.closed_form`); the files written are read back by
:mod:`lf_flame.learn.model_files`. Decoder + backbone compose into the full model for inference
(:func:`lf_flame.learn.model.compose`).

Keras callbacks do the bookkeeping: ModelCheckpoint (best validation SSIM; the last full
decoder for resume), CSVLogger (learning curves, appended on resume), EarlyStopping on the
validation SSIM, plus a wall-time budget and a callback computing validation SSIM and PSNR.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import h5py
import keras
import numpy as np
import pandas as pd

from .baselines import BASELINE_FILES, fit_baselines
from .closed_form import closed_form_start, freeze_for_probe
from ..config import ModelConfig, TrainConfig, atomic_write_text, provenance, read_json, to_json
from .dataset import LightFieldDataset
from .features import FeatureBatches, compute_features, predict_features
from ..measure.metrics import psnr_per_plane, ssim_per_plane
from .model import build_decoder
from .model_files import save_random_backbone


def validation_scores(decoder, features_path, ds: LightFieldDataset, indices) -> dict:
    """The decoder's ``val_ssim`` and ``val_psnr_db`` (dB): means over the samples
    ``indices`` and the planes, from cached features; what the learning curves log.

    Parameters
    ----------
    decoder : keras.Model, features (h, w, 2048) -> planes (R, C, 4)
    features_path : the dataset's feature cache
    ds : the dataset (ground truth)
    indices : sample indices (read in sorted order)
    """
    pred = np.clip(predict_features(decoder, features_path, indices), 0, 1)
    gt = ds.gt(np.sort(np.asarray(indices)))
    return dict(val_ssim=float(np.mean([ssim_per_plane(g, p) for g, p in zip(gt, pred)])),
                val_psnr_db=float(np.mean([psnr_per_plane(g, p) for g, p in zip(gt, pred)])))


class _WallClock(keras.callbacks.Callback):
    """Adds validation SSIM and PSNR (dB; means over samples and planes) and cumulative wall
    time to the epoch logs, and stops at the time budget: after an epoch, training stops
    when one more epoch as long as the longest so far would end past ``budget_s``. The
    first epoch always runs, so a start that already spent the budget is followed by one
    epoch (which may end past it)."""

    def __init__(self, val_data, budget_s: float, start_offset_s: float = 0.0):
        super().__init__()
        self.val_data, self.budget_s, self.offset = val_data, budget_s, start_offset_s
        self.t0 = self.t_epoch = time.perf_counter()
        self.longest = 0.0

    def on_epoch_begin(self, epoch, logs=None):
        self.t_epoch = time.perf_counter()

    def on_epoch_end(self, epoch, logs=None):
        logs.update(validation_scores(self.model, *self.val_data))
        now = time.perf_counter()
        logs["wall_time_s"] = self.offset + now - self.t0
        self.longest = max(self.longest, now - self.t_epoch)
        if logs["wall_time_s"] + self.longest > self.budget_s:
            print(f"time budget of {self.budget_s:.0f} s: stopping after epoch {epoch + 1} "
                  f"({logs['wall_time_s']:.0f} s trained, epochs take up to {self.longest:.0f} s)")
            self.model.stop_training = True


class _ResumeCheckpoint(keras.callbacks.Callback):
    """Saves the whole decoder (weights and optimizer state) atomically after every epoch,
    then ``train_state.json`` naming the epoch it holds; a killed run resumes from it."""

    def __init__(self, model_path: Path, state_path: Path, weights_label: str):
        super().__init__()
        self.model_path, self.state_path, self.label = model_path, state_path, weights_label

    def on_epoch_end(self, epoch, logs=None):
        tmp = self.model_path.with_name("partial." + self.model_path.name)
        self.model.save(tmp)
        os.replace(tmp, self.model_path)
        atomic_write_text(self.state_path, json.dumps(dict(epoch=epoch, wall_time_s=logs["wall_time_s"],
                                                           backbone_weights=self.label)))


class _LabelWeightsFile(keras.callbacks.Callback):
    """Writes the backbone weights label into the best-weights HDF5 checkpoint's attributes."""

    def __init__(self, path: Path, weights_label: str):
        super().__init__()
        self.path, self.label = path, weights_label

    def on_epoch_end(self, epoch, logs=None):
        if self.path.exists():
            with h5py.File(self.path, "a") as f:
                if f.attrs.get("backbone_weights") != self.label:
                    f.attrs["backbone_weights"] = self.label


def _epochs_since_best(val_ssims) -> int:
    """Epochs run after the one with the highest validation SSIM (0 if the last was best)."""
    return len(val_ssims) - 1 - int(np.argmax(val_ssims))


class _ResumableEarlyStopping(keras.callbacks.EarlyStopping):
    """EarlyStopping that, on resume, counts the epochs without improvement already run."""

    def __init__(self, past_ssims, **kw):
        super().__init__(monitor="val_ssim", mode="max", **kw)
        self.past = list(past_ssims)

    def on_train_begin(self, logs=None):
        super().on_train_begin(logs)
        if self.past:
            self.best = float(np.max(self.past))
            self.wait = _epochs_since_best(self.past)


#: The settings that make a training run what it is (:func:`run_settings`): a run started with others is not
#: resumed. ``max_epochs``, ``time_budget_s`` and ``patience`` only say how long it goes on, and may change.
RUN_TRAIN_KEYS = ("recipe", "refine_iterations", "batch_size", "learning_rate", "seed", "train_layers")


def run_settings(model_cfg: ModelConfig, train_cfg: TrainConfig) -> dict:
    """The settings recorded in ``start.json`` that a resumed run must share: the model's (input size, backbone
    weights) and :data:`RUN_TRAIN_KEYS` of the training's, as JSON values."""
    return json.loads(json.dumps(dict(model=json.loads(to_json(model_cfg)),
                                      **{k: getattr(train_cfg, k) for k in RUN_TRAIN_KEYS})))


def _resume_state(out: Path, dataset_digest: str, run: dict | None = None):
    """(initial_epoch, wall time already trained, past val SSIMs) from a previous run in ``out``.

    The history is cut back to the epoch that the last complete checkpoint holds, so an
    epoch logged by a run killed before its checkpoint was written is trained again. A run
    started on another dataset (``start.json``'s digest differs) or with other settings (``run``,
    :func:`run_settings`, where ``start.json`` records them) is not resumed: training starts again, with a
    message naming what differs.
    """
    state_path, hist_path, start_path = out / "train_state.json", out / "history.csv", out / "start.json"
    old = read_json(start_path, "record of a training start") if start_path.exists() else None
    why = None
    if old is not None and old.get("dataset_digest") != dataset_digest:
        why = "a run on another dataset"
    elif old is not None and run is not None and "run" in old and old["run"] != run:
        differ = [k for k in sorted(set(old["run"]) | set(run)) if old["run"].get(k) != run.get(k)]
        why = "a run of other settings (" + ", ".join(
            f"{k} {json.dumps(old['run'].get(k))} there, {json.dumps(run.get(k))} now" for k in differ) + ")"
    if why:
        print(f"{out} holds {why}: training from the start")
        for p in (state_path, start_path):
            p.unlink(missing_ok=True)
    if not (state_path.exists() and (out / "decoder_last.keras").exists() and hist_path.exists()):
        for p in (hist_path, state_path):
            p.unlink(missing_ok=True)
        return 0, 0.0, []
    state = read_json(state_path, "resume state")
    h = pd.read_csv(hist_path)
    h = h[h["epoch"] <= state["epoch"]]
    if len(h) != state["epoch"] + 1:
        raise ValueError(f"{hist_path} lacks epochs that {state_path} says were trained; "
                         f"delete {out} to train from scratch")
    atomic_write_text(hist_path, h.to_csv(index=False))
    return state["epoch"] + 1, float(state["wall_time_s"]), h["val_ssim"].tolist()


def _start(ds, feats_path, model_cfg: ModelConfig, train_cfg: TrainConfig, label, train_data, val_data, out: Path):
    """Build and initialise the decoder by the recipe, compile it, and write the start as
    epoch 0 of the history, the best and the last checkpoint (so a resume begins at epoch 1)."""
    t0 = time.perf_counter()
    with h5py.File(feats_path, "r") as f:
        fshape = f["features"].shape[1:]
    decoder = build_decoder(fshape, ds.camera.n_rows, ds.camera.n_cols, model_cfg)
    start = dict(recipe=train_cfg.recipe, dataset_digest=ds.digest, run=run_settings(model_cfg, train_cfg))
    if train_cfg.recipe == "closed-form":
        from .baselines import LinearDecoder
        gap = LinearDecoder.load(out / BASELINE_FILES["linear decoder (GAP-pooled)"])
        start.update(closed_form_start(decoder, feats_path, ds, model_cfg,
                                       max_iter=int(train_cfg.refine_iterations[ds.scene]), linear=gap))
        freeze_for_probe(decoder, train_cfg.train_layers)
        logs = dict(loss=start["loss"], val_loss=start["val_loss"])  # the network's output is σ(dense) here
    decoder.compile(optimizer=keras.optimizers.Adam(train_cfg.learning_rate), loss="mse")
    decoder.optimizer.build(decoder.trainable_variables)  # its (empty) state is saved with the start
    if train_cfg.recipe == "paper":
        logs = dict(loss=float(decoder.evaluate(train_data, verbose=0)),
                    val_loss=float(decoder.evaluate(val_data, verbose=0)))
    wall = _WallClock((feats_path, ds, ds.splits["val"]), float("inf"))
    wall.set_model(decoder)
    wall.t0 -= time.perf_counter() - t0  # the start's own time counts as training time
    wall.on_epoch_end(0, logs)
    start["wall_time_s"] = logs["wall_time_s"]
    atomic_write_text(out / "start.json", json.dumps(start, indent=2))
    # in the column order of keras.callbacks.CSVLogger (epoch, then sorted keys), which appends to it
    row = dict(epoch=0, **{k: logs[k] for k in sorted(logs)})
    atomic_write_text(out / "history.csv", pd.DataFrame([row]).to_csv(index=False))
    decoder.save_weights(out / "decoder_best.weights.h5")
    _LabelWeightsFile(out / "decoder_best.weights.h5", label).on_epoch_end(0)
    resume = _ResumeCheckpoint(out / "decoder_last.keras", out / "train_state.json", label)
    resume.set_model(decoder)
    resume.on_epoch_end(0, logs)
    print(f"start ({train_cfg.recipe}): validation SSIM {logs['val_ssim']:.4f} in {logs['wall_time_s']:.0f} s")
    return start, decoder


def train(dataset_path, out_dir, model_cfg: ModelConfig, train_cfg: TrainConfig, progress: bool = True) -> dict:
    """Train the decoder on a dataset's cached features; resumable.

    Writes to ``out_dir``: ``decoder_best.weights.h5`` (highest validation SSIM; its HDF5
    attribute ``backbone_weights`` names the backbone), ``backbone.weights.h5`` (only for a
    random-init backbone), ``decoder_last.keras`` and
    ``train_state.json`` (for resume), ``history.csv`` (loss, val_loss, val_psnr_db,
    val_ssim, wall_time_s per epoch; epoch 0 is the start) and, last, ``train_info.json`` (configs, weights used, epochs,
    wall time, provenance). A run started again in the same folder continues from the last
    complete epoch with the same split, data order and optimizer state. ``train_info.json`` is removed once the
    features are computed, before any file of the folder is rewritten: a run stopped before its end leaves none,
    not the record of an earlier run beside its weights.

    Returns
    -------
    dict : the content of ``train_info.json``.

    Raises
    ------
    ValueError
        A resume state that does not match the history in ``out_dir``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ds = LightFieldDataset(dataset_path)
    t_start = time.perf_counter()
    feats_path, label = compute_features(ds, model_cfg, model_cfg.weights, progress=progress, seed=train_cfg.seed)
    # this run rewrites the folder's files: the record of the last finished run goes until this one has finished
    (out / "train_info.json").unlink(missing_ok=True)
    if label == "random-init":
        save_random_backbone(ds, model_cfg, train_cfg.seed, out)
    t_feat = time.perf_counter() - t_start
    baselines = fit_baselines(feats_path, ds, out)
    keras.utils.set_random_seed(train_cfg.seed)
    hist_path, last_path, best_path = out / "history.csv", out / "decoder_last.keras", out / "decoder_best.weights.h5"
    initial_epoch, offset, past = _resume_state(out, ds.digest, run_settings(model_cfg, train_cfg))
    bs = train_cfg.batch_size
    val_data = FeatureBatches(feats_path, ds, ds.splits["val"], bs, False, train_cfg.seed)
    if initial_epoch:
        decoder = keras.models.load_model(last_path)
        start = read_json(out / "start.json", "record of a training start")
        print(f"resuming from epoch {initial_epoch} ({offset:.0f} s already trained)")
    else:
        train_eval = FeatureBatches(feats_path, ds, ds.splits["train"], bs, False, train_cfg.seed)
        start, decoder = _start(ds, feats_path, model_cfg, train_cfg, label, train_eval, val_data, out)
        initial_epoch, offset, past = _resume_state(out, ds.digest, run_settings(model_cfg, train_cfg))
    # epoch 0 of the history is the start; training epoch k (1 .. max_epochs) shuffles with (seed, k - 1)
    train_data = FeatureBatches(feats_path, ds, ds.splits["train"], bs, True, train_cfg.seed, initial_epoch - 1)
    scene = ds.scene
    max_epochs = int(train_cfg.max_epochs[scene])
    budget = float(train_cfg.time_budget_s[scene])
    callbacks = [
        _WallClock((feats_path, ds, ds.splits["val"]), budget, offset),
        keras.callbacks.ModelCheckpoint(str(best_path), monitor="val_ssim", mode="max", save_best_only=True,
                                        save_weights_only=True, initial_value_threshold=max(past)),
        _LabelWeightsFile(best_path, label),
        keras.callbacks.CSVLogger(str(hist_path), append=True),
        _ResumeCheckpoint(last_path, out / "train_state.json", label),
        _ResumableEarlyStopping(past, patience=train_cfg.patience),
    ]
    stopped_early = _epochs_since_best(past) >= train_cfg.patience
    if initial_epoch <= max_epochs and offset < budget and not stopped_early:
        decoder.fit(train_data, validation_data=val_data, epochs=max_epochs + 1, initial_epoch=initial_epoch,
                    callbacks=callbacks, verbose=2 if progress else 0)
    h = pd.read_csv(hist_path)
    info = dict(dataset=str(dataset_path), dataset_digest=ds.digest, scene=scene, backbone_weights=label,
                model_config=json.loads(to_json(model_cfg)), train_config=json.loads(to_json(train_cfg)),
                raw_shape=list(ds.camera.sensor_shape), output_shape=[ds.camera.n_rows, ds.camera.n_cols],
                feature_shape=list(decoder.input_shape[1:]), dataset_camera=ds.attrs["camera"],
                epochs_run=int(len(h)) - 1, paper_epochs=int({"shapes": 5000, "flame": 1000}[scene]),
                best_epoch=int(h["epoch"].iloc[int(h["val_ssim"].idxmax())]),
                best_val_ssim=float(h["val_ssim"].max()), start_val_ssim=float(h["val_ssim"].iloc[0]),
                best_val_loss=float(h["val_loss"].min()), training_wall_time_s=float(h["wall_time_s"].iloc[-1]),
                start=start, baselines=baselines,
                feature_cache=str(Path(feats_path).resolve()), backend=keras.backend.backend(),
                feature_wall_time_s=t_feat, provenance=provenance())
    atomic_write_text(out / "train_info.json", json.dumps(info, indent=2))
    return info
