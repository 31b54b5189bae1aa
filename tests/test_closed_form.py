"""The closed-form start's parts, each on a planted problem whose answer is known: paired
convolutions, population statistics and bn2's shift, the Gauss–Newton targets, and the
mapping of each plane's λ to its output columns."""
import h5py
import keras
import numpy as np

from lf_flame.learn.baselines import LinearDecoder, ridge_path
from lf_flame.learn.closed_form import gauss_newton_targets, layer_outputs, pair_convolutions, refine_dense, ridge_dense, set_population_statistics
from lf_flame.config import ModelConfig
from lf_flame.learn.model import build_decoder


def _sigmoid(z):
    return 1 / (1 + np.exp(-z))


def _neg_mse(gt, pred):
    return -float(np.mean((np.asarray(gt) - np.asarray(pred)) ** 2))


def _features_file(path, feats):
    with h5py.File(path, "w") as f:
        f["features"] = feats.astype(np.float16)
    return path


def _decoder(feat_shape, seed=0):
    keras.utils.set_random_seed(seed)
    return build_decoder(feat_shape, 3, 2, ModelConfig())


def _residual_of_linear_fit(x, y):
    """Relative residual of the least-squares fit of y (n, p) by [x, 1] (n, d + 1)."""
    a = np.c_[x, np.ones(len(x))]
    coef = np.linalg.lstsq(a, y, rcond=None)[0]
    return np.linalg.norm(a @ coef - y) / np.linalg.norm(y - y.mean(axis=0))


def test_paired_convolutions_keep_the_linear_decoders_map_linearly(tmp_path):
    rng = np.random.default_rng(0)
    shape = (2, 2, 8)  # (h, w, c): 8 channels, so the linear decoder's map has rank <= 8 < 128
    feats = rng.normal(size=(400, *shape)).astype(np.float16).astype(np.float32)
    y = _sigmoid(rng.normal(size=(400, 4, 3, 2))).astype(np.float32)
    lin = LinearDecoder.fit("gap", feats[:60], y[:60], feats[60:90], y[60:90], _neg_mse)
    target = lin.predict(feats[90:]).reshape(310, -1)  # the linear decoder's own output
    path = _features_file(tmp_path / "f.h5", feats)
    idx = np.arange(90, 400)

    dec = _decoder(shape)
    random_h = layer_outputs(dec, "gap", path, idx)
    assert _residual_of_linear_fit(random_h, target) > 0.02  # random convolutions lose part of it
    pair_convolutions(dec, lin)
    h = layer_outputs(dec, "gap", path, idx)
    # through both LeakyReLUs, the Dense layer's input still holds the linear decoder's
    # output exactly, as a linear function of the pooled features (differences of pairs)
    assert _residual_of_linear_fit(h, target) < 1e-3
    assert _residual_of_linear_fit(h[:, :128] - h[:, 128:], target) < 1e-3


def test_population_statistics_and_centred_pooled_features(tmp_path):
    rng = np.random.default_rng(1)
    shape = (3, 2, 8)
    feats = rng.normal(loc=0.5, size=(40, *shape)).astype(np.float32)
    path = _features_file(tmp_path / "f.h5", feats)
    train = np.arange(30)
    dec = _decoder(shape)
    set_population_statistics(dec, path, train)
    conv1 = layer_outputs(dec, "conv1", path, train).reshape(-1, 512)  # every sample and position
    bn1 = dec.get_layer("bn1")
    assert np.allclose(bn1.moving_mean.numpy(), conv1.mean(axis=0), atol=1e-4 * np.abs(conv1).max())
    assert np.allclose(bn1.moving_variance.numpy(), conv1.var(axis=0), rtol=1e-3)
    conv2 = layer_outputs(dec, "conv2", path, train).reshape(-1, 256)  # with bn1 so set
    assert np.allclose(dec.get_layer("bn2").moving_variance.numpy(), conv2.var(axis=0), rtol=1e-3)
    pooled = layer_outputs(dec, "gap", path, train)
    # bn2's shift centres the pooled features on the training split, channel by channel
    assert np.abs(pooled.mean(axis=0)).max() < 1e-3 * pooled.std(axis=0).min()
    assert np.abs(layer_outputs(dec, "gap", path, np.arange(30, 40)).mean(axis=0)).max() > 1e-3  # not on others

    dec = _decoder(shape)
    set_population_statistics(dec, path, train, center_pooled=False)
    pooled = layer_outputs(dec, "gap", path, train)
    assert np.abs(pooled.mean(axis=0)).max() > 0.1 * pooled.std(axis=0).max()  # LeakyReLU's offset remains


def test_gauss_newton_targets_are_the_linearised_logits():
    rng = np.random.default_rng(2)
    base = rng.uniform(0.2, 0.8, size=(3, 2))
    for delta in (1e-2, 1e-3):
        y = (base + delta * rng.choice([-1.0, 1.0], size=(50, 3, 2))).astype(np.float32)
        z = gauss_newton_targets(y)
        assert z.shape == y.shape and z.dtype == np.float32
        ybar = y.mean(axis=0)
        assert np.allclose(_sigmoid(gauss_newton_targets(np.broadcast_to(ybar, y.shape).copy())), ybar, atol=1e-6)
        # one Gauss-Newton step: sigma(z) = y up to second order in (y - ybar)
        assert np.abs(_sigmoid(z) - y).max() < 5 * delta ** 2
    black = np.zeros((4, 2, 2), np.float32)
    assert np.allclose(gauss_newton_targets(black), -np.log((1 - 1e-4) / 1e-4), atol=1e-4)  # -9.21
    mixed = np.stack([black[0], np.ones((2, 2), np.float32)])  # 0 and 1 about a mean of 0.5
    assert np.all(np.abs(gauss_newton_targets(mixed)) <= np.log((1 - 1e-4) / 1e-4) + 1e-5)  # clipped


def test_ridge_dense_gives_each_plane_its_own_lambda():
    """Plane 0 is an exact function of the features, plane 1 pure noise: they need opposite
    λ, and each plane's output columns (every P-th of the (r, c, plane) order) must get its own."""
    rng = np.random.default_rng(3)
    n, m, d, (R, C, P) = 200, 100, 6, (3, 2, 2)
    h = rng.normal(size=(n + m, d))
    z = np.empty((n + m, R, C, P), np.float32)
    z[..., 0] = (h @ rng.normal(size=(d, R * C))).reshape(-1, R, C)
    z[..., 1] = rng.normal(size=(n + m, R, C))
    gt_va = np.transpose(_sigmoid(z[n:]), (0, 3, 1, 2))
    scale = np.ones(d)
    w, b, rel, scores = ridge_dense(h[:n], z[:n].copy(), h[n:], gt_va, scale, _neg_mse)
    assert w.shape == (d, R * C * P) and b.shape == (R * C * P,)
    assert rel[0] <= 1e-5 and rel[1] >= 10  # the grid's smallest and (near) largest penalties
    for k in range(P):  # plane k's columns equal a ridge fitted to plane k alone with plane k's λ
        alone = ridge_path(h[:n], z[:n, ..., k].reshape(n, -1))
        wk = alone.x_train.T @ alone.dual_coef(rel[k] * alone.alpha_scale)
        assert np.allclose(w[:, k::P], wk, atol=1e-4 * max(1.0, np.abs(wk).max()))
    pred = _sigmoid(h[n:] @ w + b).reshape(m, R, C, P)
    assert np.abs(pred[..., 0] - _sigmoid(z[n:, ..., 0])).max() < 1e-3  # the exact plane recovered


def test_refine_dense_fits_the_output_space_loss():
    rng = np.random.default_rng(3)
    h = rng.normal(size=(120, 8)).astype(np.float32)
    w_true = rng.normal(scale=2.0, size=(8, 9 * 8 * 4)).astype(np.float32)  # (R, C, P) = (9, 8, 4)
    y = (1 / (1 + np.exp(-(h @ w_true)))).astype(np.float32)
    y_va = y[80:].reshape(40, 9, 8, 4)
    w0, b0 = np.zeros_like(w_true), np.zeros(w_true.shape[1], np.float32)
    w, b, info = refine_dense(h[:80], y[:80], h[80:], y_va, w0, b0, max_iter=60)
    assert min(info["refine_iterations"]) > 10 and min(info["kept_iteration"]) > 0
    z = h[80:] @ w + b
    err = np.abs(1 / (1 + np.exp(-z)) - y[80:])
    assert err.mean() < 2e-3 and err.max() < 0.1  # the known sigmoid map, recovered on unseen samples
    assert info["val_loss"] < 1e-4 < np.mean((0.5 - y[80:]) ** 2)
    same = refine_dense(h[:80], y[:80], h[80:], y_va, w0, b0, max_iter=0)
    assert np.array_equal(same[0], w0) and same[2]["kept_iteration"] == [0, 0, 0, 0]
