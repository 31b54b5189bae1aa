"""Trained models on disk: the decoder and its backbone, loaded for inference.

Stage: after training (:mod:`lf_flame.learn.training` writes the files), for evaluation
(:mod:`lf_flame.learn.evaluation`), ``lf-flame predict`` and the trade-off map.
"""
from __future__ import annotations

import os
from pathlib import Path

import h5py
import keras

from ..config import ModelConfig, read_json
from .dataset import LightFieldDataset
from .model import build_decoder, build_feature_extractor, resolve_weights


def load_decoder(model_dir):
    """The trained decoder of ``model_dir`` and its ``train_info`` dict.

    Raises
    ------
    FileNotFoundError
        ``train_info.json`` or the weights file is missing.
    ValueError
        ``train_info.json`` is empty, truncated or damaged (:func:`lf_flame.config.read_json`).
    """
    model_dir = Path(model_dir)
    info_path, weights_path = model_dir / "train_info.json", model_dir / "decoder_best.weights.h5"
    for p in (info_path, weights_path):
        if not p.is_file():
            raise FileNotFoundError(f"trained model file not found: {p} (run 'lf-flame train' first)")
    info = read_json(info_path, "record of a training run (train it again)")
    cfg = ModelConfig(**info["model_config"])
    dec = build_decoder(info["feature_shape"], *info["output_shape"], cfg)
    dec.load_weights(weights_path)
    return dec, info


def load_full_model(model_dir):
    """Backbone + trained decoder as one model: raw (batch, rows, cols, 1) -> (batch, R, C, 4).

    The backbone is rebuilt with the weights recorded at training: ImageNet or the weights
    file, or for a random-init backbone the draw saved in ``backbone.weights.h5`` (the one
    that made the cached features), so any Keras backend gives the same model.

    Returns
    -------
    (model, info)

    Raises
    ------
    FileNotFoundError
        A missing model file, or backbone weights file recorded at training.
    ValueError
        The backbone weights found are not those the model was trained with.
    """
    from .model import compose
    dec, info = load_decoder(model_dir)
    cfg = ModelConfig(**info["model_config"])
    label = info["backbone_weights"]
    if label == "random-init":  # the saved draw: Keras backends draw different random weights
        fx = build_feature_extractor(info["raw_shape"], cfg, None)
        fx.load_weights(_backbone_file(model_dir))
    else:
        weights, got = resolve_weights("imagenet" if label == "imagenet" else cfg.weights)
        if got != label:
            raise ValueError(f"the model was trained on backbone weights {label!r} but {got!r} were found")
        fx = build_feature_extractor(info["raw_shape"], cfg, weights)
    return compose(fx, dec), info


def _backbone_file(model_dir) -> Path:
    p = Path(model_dir) / "backbone.weights.h5"
    if not p.is_file():
        raise FileNotFoundError(f"random-init backbone weights not found: {p} (written by 'lf-flame train')")
    return p


def backbone_key(ds: LightFieldDataset, cfg: ModelConfig, seed: int) -> dict:
    """What makes a random-init backbone's draw (:func:`save_random_backbone`): the seed, the input size, the
    sensor's shape and the Keras backend that drew it."""
    return dict(seed=int(seed), input_size=f"{cfg.input_rows}x{cfg.input_cols}",
                sensor_shape="x".join(str(v) for v in ds.camera.sensor_shape), backend=keras.backend.backend())


def save_random_backbone(ds: LightFieldDataset, cfg: ModelConfig, seed: int, out: Path) -> None:
    """Save the random-init backbone that made the feature cache (same seed, same draw).

    The file's attributes record its :func:`backbone_key`; one saved by another run (another seed, input size,
    sensor or backend, or none recorded) is drawn and written again, with a message: it would not be the backbone
    of this run's features."""
    path = out / "backbone.weights.h5"
    key = backbone_key(ds, cfg, seed)
    if path.exists():
        try:
            with h5py.File(path, "r") as f:
                old = {k: f.attrs.get(k) for k in key}
        except OSError:
            old = {}
        old = {k: int(v) if k == "seed" and v is not None else v for k, v in old.items()}
        if old == key:
            return
        differ = [f"{k} {old.get(k)} there, {key[k]} now" for k in key if old.get(k) != key[k]]
        print(f"{path} holds another backbone draw ({', '.join(differ)}): writing this run's")
    keras.utils.set_random_seed(seed)
    tmp = out / "partial.backbone.weights.h5"
    build_feature_extractor(ds.camera.sensor_shape, cfg, None).save_weights(tmp)
    with h5py.File(tmp, "a") as f:
        f.attrs.update(key)
    os.replace(tmp, path)
