"""Backbone feature cache: the frozen ResNet-50's features of every sample of a dataset,
computed once per dataset, input size and weights, and batches read from it.

Stage: between the dataset (:mod:`lf_flame.learn.dataset`) and the decoder's training
(:mod:`lf_flame.learn.training`), the yardsticks (:mod:`lf_flame.learn.baselines`) and the closed-form
start (:mod:`lf_flame.learn.closed_form`). The backbone is frozen and inputs are not augmented,
so a cache is exact; it is tied to the dataset's content digest
(:func:`lf_flame.learn.dataset.content_digest`) and rebuilt when the dataset changes.
"""
from __future__ import annotations

import math
import os
import time
from pathlib import Path

import h5py
import keras
import numpy as np
from tqdm import tqdm

from ..config import ModelConfig, to_json
from .dataset import LightFieldDataset
from .model import build_feature_extractor, resolve_weights


def feature_cache_path(dataset_path, cfg: ModelConfig, weights_label: str) -> Path:
    """Where the features of a dataset for an input size and weights are cached."""
    p = Path(dataset_path)
    tag = weights_label.replace(":", "-").replace("/", "_")
    return p.with_name(f"{p.stem}.features_{cfg.input_rows}x{cfg.input_cols}_{tag}.h5")


def cache_mismatch(path, digest: str, seed: int, label: str, n: int, backend: str | None = None) -> str | None:
    """Why the feature cache at ``path`` is not the features of a dataset (``digest``, ``n`` samples) through a
    backbone (weights ``label``, drawn with ``seed``; a random draw also by the Keras ``backend`` that drew it), or
    None where it is. A random-init backbone's draw differs by seed and by backend; pretrained weights by neither
    (the seed is checked as recorded all the same)."""
    try:
        with h5py.File(path, "r") as f:
            got = dict(digest=f.attrs.get("dataset_digest"), seed=int(f.attrs.get("seed", -1)),
                       weights=f.attrs.get("weights"), n=f["features"].shape[0], backend=f.attrs.get("backend"))
    except (OSError, KeyError):
        return f"feature cache {path} is missing or unreadable"
    want = dict(digest=digest, seed=int(seed), weights=label, n=int(n),
                backend=backend if "random" in str(label) else got["backend"])
    differ = [k for k in want if got[k] != want[k]]
    if not differ:
        return None
    return (f"feature cache {path} holds other features (" + ", ".join(
        f"{k} {str(got[k])[:12]} there, {str(want[k])[:12]} wanted" for k in differ) + ")")


def compute_features(ds: LightFieldDataset, cfg: ModelConfig, weights_spec: str, batch: int = 4,
                     progress: bool = True, seed: int = 0) -> tuple[Path, str]:
    """Compute (or reuse) the frozen backbone features of every sample of ``ds``.

    A cache is reused only if it was computed from this very dataset (the same
    :attr:`~lf_flame.learn.dataset.LightFieldDataset.digest`), with the same backbone weights,
    input size and seed (a random-init backbone's also by the same Keras backend: :func:`cache_mismatch`);
    otherwise it is computed again, with a message naming what differs, and replaces the old file only
    once complete.

    Parameters
    ----------
    ds : the dataset
    cfg : the model settings (backbone input size)
    weights_spec : 'auto', 'imagenet', 'none' or a file (:func:`lf_flame.learn.model.resolve_weights`)
    batch : light fields per backbone call
    seed : seeds the random-init backbone's draw

    Returns
    -------
    (path, weights_label) : the cache file, holding ``features`` (n, h, w, 2048) float16
        and attributes naming the dataset (path, camera, ``dataset_digest``), input size,
        weights and seed; and the weights used.

    Raises
    ------
    FloatingPointError
        Features that are not finite in float16.
    """
    weights, label = resolve_weights(weights_spec)  # may build (and fail to load) a model
    path = feature_cache_path(ds.path, cfg, label)
    if path.exists():
        why = cache_mismatch(path, ds.digest, seed, label, ds.n, keras.backend.backend())
        if why is None:
            return path, label
        print(f"{why}: computing it again")
    # seeded right before the build, as model_files.save_random_backbone does: the same random draw
    keras.utils.set_random_seed(seed)
    fx = build_feature_extractor(ds.camera.sensor_shape, cfg, weights)
    tmp = path.with_name(path.name + ".partial")
    t0 = time.perf_counter()
    with h5py.File(tmp, "w") as f:
        shape = tuple(fx.output.shape[1:])
        d = f.create_dataset("features", (ds.n, *shape), np.float16, chunks=(1, *shape))
        for s in tqdm(range(0, ds.n, batch), desc="backbone features", disable=not progress):
            idx = list(range(s, min(ds.n, s + batch)))
            feats = np.asarray(fx.predict_on_batch(ds.raw(idx)[..., None]))
            if not np.all(np.isfinite(feats)) or np.abs(feats).max() > 6e4:
                raise FloatingPointError("backbone features are not finite in float16")
            d[s:s + len(idx)] = feats.astype(np.float16)
        f.attrs.update(dataset=str(ds.path), dataset_camera=ds.attrs["camera"], dataset_digest=ds.digest,
                       weights=label, seed=seed, backend=keras.backend.backend(), model_config=to_json(cfg),
                       wall_time_s=time.perf_counter() - t0)
    os.replace(tmp, path)
    return path, label


class FeatureBatches(keras.utils.PyDataset):
    """Batches of (cached features, ground truth (R, C, 4)) read from disk, never all in memory.

    Shuffled each epoch by a generator seeded with (seed, epoch) when ``shuffle``, so a run
    resumed at ``start_epoch`` sees the same order as one never stopped.
    """

    def __init__(self, features_path, ds: LightFieldDataset, indices, batch_size: int, shuffle: bool, seed: int,
                 start_epoch: int = 0):
        super().__init__()
        self.features_path, self.ds = str(features_path), ds
        self.indices = np.asarray(indices)
        self.batch_size, self.shuffle, self.seed = batch_size, shuffle, seed
        self.epoch = start_epoch
        self._order = self.indices.copy()
        self._f = None
        self.on_epoch_end()

    def __len__(self):
        return math.ceil(len(self.indices) / self.batch_size)

    def on_epoch_end(self):
        if self.shuffle:
            self._order = np.random.default_rng([self.seed, self.epoch]).permutation(self.indices)
        self.epoch += 1

    def __getitem__(self, k):
        if self._f is None:
            self._f = h5py.File(self.features_path, "r")
        idx = np.sort(self._order[k * self.batch_size:(k + 1) * self.batch_size])
        x = self._f["features"][idx].astype(np.float32)
        y = np.transpose(self.ds.gt(idx), (0, 2, 3, 1))
        return x, y


def predict_features(decoder, features_path, indices, batch: int = 8) -> np.ndarray:
    """Decoder predictions (k, 4, R, C) for cached features of ``indices``."""
    out = []
    with h5py.File(features_path, "r") as f:
        for s in range(0, len(indices), batch):
            idx = np.sort(np.asarray(indices[s:s + batch]))
            out.append(np.asarray(decoder.predict_on_batch(f["features"][idx].astype(np.float32))))
    return np.transpose(np.concatenate(out), (0, 3, 1, 2))


def layer_outputs(decoder, name: str, features_path, indices, batch: int = 16) -> np.ndarray:
    """Inference-mode output of the decoder's layer ``name`` for cached features of ``indices``."""
    sub = keras.Model(decoder.input, decoder.get_layer(name).output)
    out = []
    with h5py.File(features_path, "r") as f:
        for s in range(0, len(indices), batch):
            idx = np.sort(np.asarray(indices[s:s + batch]))
            out.append(keras.ops.convert_to_numpy(sub(f["features"][idx].astype(np.float32), training=False)))
    return np.concatenate(out)


def load_features(features_path, indices) -> np.ndarray:
    """Cached features (k, h, w, 2048) float16 of ``indices`` (in sorted order)."""
    with h5py.File(features_path, "r") as f:
        return f["features"][np.sort(np.asarray(indices))]
