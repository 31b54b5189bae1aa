"""The network's yardsticks: the mean image and the closed-form linear decoders."""
import numpy as np
import pytest

from lf_flame.learn.baselines import LinearDecoder, MeanImage, pool_features, ridge_path


def _neg_mse(gt, pred):
    return -float(np.mean((np.asarray(gt) - np.asarray(pred)) ** 2))


def _linear_problem(rng, n, feat_shape, pooling, out_shape=(4, 3, 2)):
    """Features (n, h, w, c) and targets exactly linear in their design rows, inside (0, 1)."""
    f = rng.normal(size=(n, *feat_shape)).astype(np.float16).astype(np.float32)
    x = pool_features(f, pooling)
    w = rng.normal(scale=0.05 / np.sqrt(x.shape[1]), size=(x.shape[1], int(np.prod(out_shape))))
    y = 0.5 + x @ w
    assert 0 < y.min() and y.max() < 1
    return f, y.reshape(n, *out_shape).astype(np.float32)


@pytest.mark.parametrize("pooling, feat_shape", [("gap", (3, 2, 6)), ("none", (2, 2, 3))])
def test_linear_decoder_recovers_a_known_linear_map(pooling, feat_shape):
    rng = np.random.default_rng(0)
    f, y = _linear_problem(rng, 240, feat_shape, pooling)
    tr, va, te = slice(0, 160), slice(160, 200), slice(200, 240)
    dec = LinearDecoder.fit(pooling, f[tr], y[tr], f[va], y[va], _neg_mse)
    pred = dec.predict(f[te])
    assert pred.shape == y[te].shape
    assert np.abs(pred - y[te]).max() < 1e-4 * np.abs(y[te] - 0.5).max() + 1e-6
    # the smallest penalties of the grid win on noise-free linear data
    assert np.all(dec.alphas <= 1e-3 * ridge_path(pool_features(f[tr], pooling), y[tr].reshape(160, -1)).alpha_scale)


def test_linear_decoder_chooses_a_larger_penalty_for_noisy_targets():
    rng = np.random.default_rng(1)
    f, y = _linear_problem(rng, 120, (2, 2, 40), "gap")
    noisy = np.clip(y + rng.normal(scale=0.05, size=y.shape), 0, 1).astype(np.float32)
    clean = LinearDecoder.fit("gap", f[:60], y[:60], f[60:90], y[60:90], _neg_mse)
    rough = LinearDecoder.fit("gap", f[:60], noisy[:60], f[60:90], y[60:90], _neg_mse)
    assert np.all(rough.alphas > clean.alphas)


def test_baselines_save_and_load(tmp_path):
    rng = np.random.default_rng(2)
    f, y = _linear_problem(rng, 40, (2, 2, 3), "none")
    dec = LinearDecoder.fit("none", f[:30], y[:30], f[30:], y[30:], _neg_mse)
    dec.save(tmp_path / "lin.h5")
    back = LinearDecoder.load(tmp_path / "lin.h5")
    assert back.pooling == "none" and back.route == "linear decoder (un-pooled)"
    assert np.allclose(back.predict(f), dec.predict(f), atol=1e-6)
    mean = MeanImage.fit(y[:30])
    assert np.allclose(mean.predict(f[:3]), y[:30].mean(axis=0))
    mean.save(tmp_path / "mean.h5")
    assert np.array_equal(MeanImage.load(tmp_path / "mean.h5").mean, mean.mean)
    with pytest.raises(ValueError, match="not a 'linear decoder'"):
        LinearDecoder.load(tmp_path / "mean.h5")
    with pytest.raises(FileNotFoundError, match="baseline file not found"):
        MeanImage.load(tmp_path / "none.h5")
    (tmp_path / "bad.h5").write_bytes(b"not hdf5")
    with pytest.raises(ValueError, match="truncated or corrupt"):
        MeanImage.load(tmp_path / "bad.h5")


def test_bad_inputs_are_refused():
    f = np.zeros((4, 2, 2, 3), np.float32)
    with pytest.raises(ValueError, match="pooling must be"):
        pool_features(f, "max")
    with pytest.raises(ValueError, match=r"\(n, h, w, c\)"):
        pool_features(f[0], "gap")
    f[1, 0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        pool_features(f, "gap")
    with pytest.raises(ValueError, match="one target row each"):
        ridge_path(np.zeros((4, 3)), np.zeros((5, 2)))
    with pytest.raises(ValueError, match="finite"):
        MeanImage.fit(np.full((2, 4, 3, 3), np.nan))
