"""The paper's Keras functional model (Sec. II-C, Fig. 4): one place that defines it.

Raw light field (R·N, C·N, 1) in [0, 1]
→ ``feature_extractor``: resize to the backbone input size (a config value), ×255,
  grey → 3 channels, ImageNet 'caffe' mean subtraction (as
  ``keras.applications.resnet50.preprocess_input`` does on 0–255 data), frozen
  ResNet-50 (``include_top=False``, called with ``training=False``)
→ ``decoder``: Conv2D 512 3×3 → BN → LeakyReLU → Conv2D 256 3×3 → BN → LeakyReLU →
  GAP → Dense(R·C·4) → Reshape (R, C, 4) → Conv2D 4 3×3, sigmoid, with Dropout 0.3 on the
  pooled vector or on the pixel map (``ModelConfig.dropout_at``).

Backend-agnostic Keras 3 (no ``tf.*``), so it runs on TensorFlow or JAX.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

import keras
from keras import layers

from ..config import ModelConfig

#: ImageNet BGR means of ResNet-50's 'caffe' preprocessing.
CAFFE_MEAN = (103.939, 116.779, 123.68)
NOTOP_FILE = "resnet50_weights_tf_dim_ordering_tf_kernels_notop.h5"


def resolve_weights(spec: str):
    """Turn a weights spec into ``(keras_weights_argument, label)``.

    Parameters
    ----------
    spec : str
        'imagenet', 'auto', 'none', or a path to a Keras ResNet-50 no-top ``.h5`` file.

    Returns
    -------
    (arg, label) : the ``weights=`` argument for ``keras.applications.ResNet50`` and a
        label recorded with every result ('imagenet', 'file:<path>', 'random-init').

    Raises
    ------
    FileNotFoundError
        A path that does not exist.
    RuntimeError
        'imagenet' when the weights can be neither found in the Keras cache nor downloaded.
    """
    s = str(spec)
    if s.lower() == "none":
        return None, "random-init"
    if s.lower() in ("imagenet", "auto"):
        cached = Path(os.environ.get("KERAS_HOME", Path.home() / ".keras")) / "models" / NOTOP_FILE
        if cached.is_file():
            return "imagenet", "imagenet"
        try:  # the real loader: Keras downloads (and md5-checks) into its cache
            keras.applications.ResNet50(include_top=False, weights="imagenet", input_shape=(64, 64, 3))
            return "imagenet", "imagenet"
        except Exception as e:  # Keras raises a bare Exception("URL fetch failure ...")
            if s.lower() == "imagenet":
                raise RuntimeError(f"ImageNet weights for ResNet-50 are not obtainable ({e}); "
                                   f"put {NOTOP_FILE} in ~/.keras/models or pass a file path") from None
            msg = (f"ImageNet weights for ResNet-50 are not obtainable offline ({type(e).__name__}); "
                   "falling back to a randomly initialised, frozen backbone (recorded as 'random-init')")
            warnings.warn(msg, RuntimeWarning, stacklevel=2)
            print(f"WARNING: {msg}")
            return None, "random-init"
    p = Path(s)
    if not p.is_file():
        raise FileNotFoundError(f"backbone weights file not found: {p}")
    return str(p), f"file:{p.name}"


def build_feature_extractor(raw_shape, cfg: ModelConfig, weights=None) -> keras.Model:
    """Raw image (rows, cols, 1) -> frozen ResNet-50 features (rows/32, cols/32, 2048).

    ``weights`` is the already-resolved argument of :func:`resolve_weights`.
    """
    inp = keras.Input((*raw_shape, 1), name="raw_light_field")
    x = layers.Resizing(cfg.input_rows, cfg.input_cols, interpolation="bilinear", antialias=True,
                        name="resize_to_backbone")(inp)
    x = layers.Rescaling(255.0, name="to_0_255")(x)
    x = layers.Concatenate(axis=-1, name="grey_to_bgr")([x, x, x])
    x = layers.Normalization(mean=list(CAFFE_MEAN), variance=[1.0, 1.0, 1.0], name="caffe_mean")(x)
    backbone = keras.applications.ResNet50(include_top=False, weights=weights,
                                           input_shape=(cfg.input_rows, cfg.input_cols, 3))
    backbone.trainable = False
    feats = backbone(x, training=False)
    return keras.Model(inp, feats, name="feature_extractor")


#: Where the paper's Dropout(0.3) may sit (Sec. II-C lists it without saying where):
#: 'pixels' on the (R, C, 4) map right before the sigmoid convolution (the layer order as
#: printed), 'gap' on the 256-d pooled vector before the Dense layer (where Keras heads
#: put it). docs/deviations.md has the figures of each.
DROPOUT_PLACES = ("pixels", "gap")


def build_decoder(feature_shape, out_rows: int, out_cols: int, cfg: ModelConfig, n_planes: int = 4) -> keras.Model:
    """The paper's decoder: features (h, w, 2048) -> refocused images (out_rows, out_cols, 4) in [0, 1].

    Conv2D 512 3×3 → BN → LeakyReLU → Conv2D 256 3×3 → BN → LeakyReLU → GAP → Dense(R·C·4)
    → Reshape (R, C, 4) → Conv2D 4 3×3, sigmoid (Sec. II-C), with Dropout(``cfg.dropout``)
    where ``cfg.dropout_at`` says (:data:`DROPOUT_PLACES`).

    Raises
    ------
    ValueError
        ``cfg.dropout_at`` is not one of :data:`DROPOUT_PLACES`.
    """
    if cfg.dropout_at not in DROPOUT_PLACES:
        raise ValueError(f"dropout_at must be one of {DROPOUT_PLACES}. Received: dropout_at={cfg.dropout_at!r}")
    inp = keras.Input(tuple(feature_shape), name="backbone_features")
    x = layers.Conv2D(512, 3, padding="same", name="conv1")(inp)
    x = layers.BatchNormalization(name="bn1")(x)
    x = layers.LeakyReLU(name="lrelu1")(x)
    x = layers.Conv2D(256, 3, padding="same", name="conv2")(x)
    x = layers.BatchNormalization(name="bn2")(x)
    x = layers.LeakyReLU(name="lrelu2")(x)
    x = layers.GlobalAveragePooling2D(name="gap")(x)
    if cfg.dropout_at == "gap":
        x = layers.Dropout(cfg.dropout, name="dropout")(x)
    x = layers.Dense(out_rows * out_cols * n_planes, name="dense")(x)
    x = layers.Reshape((out_rows, out_cols, n_planes), name="reshape")(x)
    if cfg.dropout_at == "pixels":
        x = layers.Dropout(cfg.dropout, name="dropout")(x)
    out = layers.Conv2D(n_planes, 3, padding="same", activation="sigmoid", name="refocused")(x)
    return keras.Model(inp, out, name="decoder")


def build_model(raw_shape, out_shape, cfg: ModelConfig, weights=None):
    """The full model and its two parts.

    Parameters
    ----------
    raw_shape : (int, int)
        Raw image (rows, cols), e.g. (2700, 1350).
    out_shape : (int, int)
        Refocused image (rows, cols) = lenslet grid, e.g. (180, 90).
    cfg : ModelConfig
    weights : resolved backbone weights (:func:`resolve_weights`).

    Returns
    -------
    (model, feature_extractor, decoder) : keras.Model
        ``model`` maps (batch, rows, cols, 1) raw images to (batch, R, C, 4) refocused images.
    """
    fx = build_feature_extractor(raw_shape, cfg, weights)
    dec = build_decoder(fx.output.shape[1:], *out_shape, cfg)
    return compose(fx, dec), fx, dec


def compose(feature_extractor: keras.Model, decoder: keras.Model) -> keras.Model:
    """The full model ``decoder(feature_extractor(raw))``, sharing both parts' layers.

    Raises
    ------
    ValueError
        The decoder expects features of another shape than the extractor gives.
    """
    got, want = tuple(feature_extractor.output.shape[1:]), tuple(decoder.input_shape[1:])
    if got != want:
        raise ValueError(f"the decoder expects backbone features {want} but the feature extractor gives {got} "
                         "(another backbone input size or camera)")
    inp = keras.Input(feature_extractor.input_shape[1:], name="raw_light_field")
    return keras.Model(inp, decoder(feature_extractor(inp)), name="lf_refocus")
