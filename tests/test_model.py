import numpy as np
import pytest

from lf_flame.config import ModelConfig
from lf_flame.learn.model import build_model, resolve_weights


@pytest.fixture(scope="module")
def small_model():
    import keras
    keras.utils.set_random_seed(0)
    return build_model((90, 60), (6, 4), ModelConfig(input_rows=64, input_cols=64), weights=None)


def test_layers_named_and_backbone_frozen(small_model):
    model, fx, dec = small_model
    names = [layer.name for layer in dec.layers]
    for n in ("conv1", "bn1", "lrelu1", "conv2", "bn2", "lrelu2", "gap", "dense", "reshape", "dropout", "refocused"):
        assert n in names
    assert fx.get_layer("resnet50").trainable is False
    assert all(not w.trainable for w in fx.weights)
    assert model.output.shape[1:] == (6, 4, 4)


def test_full_model_equals_cached_feature_path(small_model):
    model, fx, dec = small_model
    x = np.random.default_rng(0).random((2, 90, 60, 1)).astype(np.float32)
    full = np.asarray(model.predict_on_batch(x))
    two = np.asarray(dec.predict_on_batch(np.asarray(fx.predict_on_batch(x))))
    assert np.allclose(full, two, atol=1e-5)
    assert full.min() >= 0 and full.max() <= 1


def test_backbone_sees_0_255_scale(small_model):
    # images fed in [0, 1] are scaled to 0-255 inside the graph; a backbone fed [0, 1]
    # data with the caffe means would see nearly the same input for any two images
    _, fx, _ = small_model
    rng = np.random.default_rng(1)
    a, b = rng.random((2, 1, 90, 60, 1)).astype(np.float32)
    fa, fb = np.asarray(fx.predict_on_batch(a)), np.asarray(fx.predict_on_batch(b))
    assert np.abs(fa - fb).mean() / np.abs(fa).mean() > 0.05
    scaled = fx.get_layer("to_0_255")(a)
    assert np.isclose(float(np.max(scaled)), 255 * a.max(), rtol=1e-5)


def test_weights_resolution(tmp_path):
    assert resolve_weights("none") == (None, "random-init")
    with pytest.raises(FileNotFoundError, match="not found"):
        resolve_weights(str(tmp_path / "missing.h5"))
    f = tmp_path / "w.h5"
    f.write_bytes(b"x")
    assert resolve_weights(str(f)) == (str(f), "file:w.h5")
