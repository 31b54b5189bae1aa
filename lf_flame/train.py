"""Training: backbone feature cache, then the decoder at the paper's settings.

The backbone is frozen and inputs are not augmented, so its features are computed once
per dataset, input size and weights, cached as float16 in HDF5, and the decoder is
trained on them (batch 2, Adam 1e-4, MSE). Decoder + backbone compose into the full
model for inference (:func:`lf_flame.model.build_model`).

Keras callbacks do the bookkeeping: ModelCheckpoint (best weights, last full decoder for
resume), CSVLogger (learning curves, appended on resume), EarlyStopping on the
validation loss, plus a wall-time budget and a validation-SSIM callback.
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

import h5py
import keras
import numpy as np
import pandas as pd
from tqdm import tqdm

from .config import ModelConfig, TrainConfig, atomic_write_text, provenance, to_json
from .dataset import LightFieldDataset
from .metrics import ssim_per_plane
from .model import build_decoder, build_feature_extractor, resolve_weights


def feature_cache_path(dataset_path, cfg: ModelConfig, weights_label: str) -> Path:
    """Where the features of a dataset for an input size and weights are cached."""
    p = Path(dataset_path)
    tag = weights_label.replace(":", "-").replace("/", "_")
    return p.with_name(f"{p.stem}.features_{cfg.input_rows}x{cfg.input_cols}_{tag}.h5")


def compute_features(ds: LightFieldDataset, cfg: ModelConfig, weights_spec: str, batch: int = 4,
                     progress: bool = True, seed: int = 0) -> tuple[Path, str]:
    """Compute (or reuse) the frozen backbone features of every sample of ``ds``.

    Returns
    -------
    (path, weights_label) : the cache file, holding ``features`` (n, h, w, 2048) float16
        and attributes naming the dataset, input size and weights; and the weights used.
    """
    weights, label = resolve_weights(weights_spec)  # may build (and fail to load) a model
    path = feature_cache_path(ds.path, cfg, label)
    if path.exists():
        with h5py.File(path, "r") as f:
            if (f.attrs.get("dataset_camera") == ds.attrs["camera"] and f["features"].shape[0] == ds.n
                    and int(f.attrs.get("seed", -1)) == seed):
                return path, label
        path.unlink()
    # seeded right before the build, as _save_random_backbone does: the same random draw
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
        f.attrs.update(dataset=str(ds.path), dataset_camera=ds.attrs["camera"], weights=label, seed=seed,
                       model_config=to_json(cfg), wall_time_s=time.perf_counter() - t0)
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


def _layer_outputs(decoder, name: str, features_path, indices, batch: int = 16) -> np.ndarray:
    """Inference-mode output of the decoder's layer ``name`` for cached features of ``indices``."""
    sub = keras.Model(decoder.input, decoder.get_layer(name).output)
    out = []
    with h5py.File(features_path, "r") as f:
        for s in range(0, len(indices), batch):
            idx = np.sort(np.asarray(indices[s:s + batch]))
            out.append(keras.ops.convert_to_numpy(sub(f["features"][idx].astype(np.float32), training=False)))
    return np.concatenate(out)


def set_population_statistics(decoder, features_path, indices, center_pooled: bool = True) -> None:
    """Set both batch-norm layers' moving mean and variance from the training split.

    bn1 gets the per-channel statistics of conv1's output over every training sample and
    position; then bn2 those of conv2's output with bn1 so set (inference mode). With the
    layers frozen (``trainable = False``, which Keras 3 runs in inference mode) a sample's
    pooled features no longer depend on its batch partner, as they do with batch
    statistics from batches of 2 (``../shared/NOTES.md``; Detectron2's FrozenBatchNorm).

    ``center_pooled``: also set bn2's shift β per channel (bisection) so that the pooled
    features ``GAP(LeakyReLU(bn2(·)))`` average to zero over the training split. Dropout
    on the pooled vector then perturbs only how a sample differs from the others, not a
    large common offset that every output pixel (the background's −9.2 logits included)
    depends on.
    """
    for bn, conv in (("bn1", "conv1"), ("bn2", "conv2")):
        a = _layer_outputs(decoder, conv, features_path, indices)
        layer = decoder.get_layer(bn)
        a = a.reshape(-1, a.shape[-1])
        mean, var = a.mean(axis=0, dtype=np.float64), a.var(axis=0, dtype=np.float64)
        layer.moving_mean.assign(mean.astype(np.float32))
        layer.moving_variance.assign(var.astype(np.float32))
    if center_pooled:
        slope = float(decoder.get_layer("lrelu2").negative_slope)
        u = ((a - mean) / np.sqrt(var + layer.epsilon)).astype(np.float32) * np.asarray(layer.gamma)
        lo, hi = np.full(u.shape[1], -20.0, np.float32), np.full(u.shape[1], 20.0, np.float32)
        for _ in range(40):  # mean of LeakyReLU(u + beta) rises with beta
            mid = 0.5 * (lo + hi)
            v = u + mid
            pos = np.where(v > 0, v, slope * v).mean(axis=0) > 0
            hi, lo = np.where(pos, mid, hi), np.where(pos, lo, mid)
        layer.beta.assign(0.5 * (lo + hi))


def refine_dense(h_tr, y_tr, h_va, y_va, w, b, max_iter: int, patience: int | None = None):
    """Refine the Dense layer on the output-space MSE of the training split, from ``(w, b)``.

    The Gauss–Newton start fits linearised logits; this minimises the loss the network
    trains on, ``mean ||σ(h W + b) − y||²``, over the whole training split at once with
    L-BFGS (``scipy.optimize.minimize``), the pooled features ``h`` fixed. The loss is a
    sum of independent terms, one per plane (each output column has its own weights), so
    each plane is refined on its own: a quarter of the variables per L-BFGS run, which
    bounds the memory of its history (``maxcor`` pairs of vectors), and its own stopping.
    Every iteration is scored on the validation split, and each plane keeps the iteration
    that scored best there (iteration 0 is the start): early stopping per plane is the
    regularisation, chosen on validation. A plane stops after ``max_iter`` iterations, or
    ``patience`` iterations without improving. No patience by default: the first L-BFGS
    steps overshoot, and validation SSIM dips below its iteration-2 value for some 15
    iterations before it climbs past it (paper preset, shapes: 0.958 at iteration 2,
    0.945-0.955 at 5-16, 0.964 at 40).

    Parameters
    ----------
    h_tr, h_va : ndarray (n, 256), (m, 256)
        Pooled features of the training and validation splits.
    y_tr : ndarray (n, R·C·P)
        Training targets in the Dense layer's (r, c, plane) order.
    y_va : ndarray (m, R, C, P)
    w, b : ndarray (256, R·C·P), (R·C·P,)
        The start.
    max_iter : int
        L-BFGS iterations per plane (0: return the start).
    patience : int, optional
        Stop a plane after this many iterations without a better validation SSIM.

    Returns
    -------
    (w, b, info) : the refined layer (float32); info holds, per plane, the iterations run,
        the iteration kept and its validation SSIM, and the training and validation MSE.
    """
    h_tr, h_va = np.asarray(h_tr, np.float32), np.asarray(h_va, np.float32)
    w, b = np.array(w, np.float32), np.array(b, np.float32)
    n_planes = y_va.shape[-1]
    info = dict(refine_iterations=[], kept_iteration=[], val_ssim=[])
    sq_err = 0.0
    for k in range(n_planes):  # the plane's columns are k, k + P, k + 2P, ... of the (r, c, plane) order
        wk, bk, its, kept, score, sse = _refine_plane(h_tr, y_tr[:, k::n_planes], h_va, y_va[..., k],
                                                      w[:, k::n_planes], b[k::n_planes], max_iter, patience)
        w[:, k::n_planes], b[k::n_planes] = wk, bk
        sq_err += sse
        for key, v in zip(info, (its, kept, score)):
            info[key].append(v)
    z_va = h_va @ w + b
    info.update(loss=sq_err / np.size(y_tr), val_loss=float(np.mean((_sigmoid(z_va) - y_va.reshape(len(y_va), -1)) ** 2)))
    return w, b, info


def _sigmoid(z):
    return 1 / (1 + np.exp(-z))


def _refine_plane(h_tr, y_tr, h_va, gt_va, w, b, max_iter, patience):
    """:func:`refine_dense` for one plane: ``w`` (d, q), ``b`` (q,), ``y_tr`` (n, q),
    ``gt_va`` (m, R, C) with q = R·C. Returns (w, b, iterations, kept iteration, its
    validation SSIM, its training sum of squared errors)."""
    from scipy.optimize import minimize

    from .metrics import mean_ssim
    d, q = w.shape
    n = len(h_tr)

    def unpack(x):
        x = np.asarray(x, np.float32)
        return x[:d * q].reshape(d, q), x[d * q:]

    def val_score(x):
        wk, bk = unpack(x)
        return mean_ssim(gt_va, _sigmoid(h_va @ wk + bk).reshape(gt_va.shape))

    def sse(x):
        wk, bk = unpack(x)
        s = _sigmoid(h_tr @ wk + bk)
        r = s - y_tr
        return s, r, float((r ** 2).sum())

    def loss(x):
        s, r, e = sse(x)
        g = (2.0 / n) * r * s * (1 - s)
        return e / n, np.concatenate([(h_tr.T @ g).ravel(), g.sum(axis=0)]).astype(np.float64)

    x0 = np.concatenate([w.ravel(), b])
    best = dict(x=x0, score=val_score(x0), it=0)
    it = [0]

    def track(x):
        it[0] += 1
        score = val_score(x)
        if score > best["score"]:
            best.update(x=np.asarray(x, np.float32), score=score, it=it[0])
        if patience is not None and it[0] - best["it"] >= patience:
            raise StopIteration  # SciPy >= 1.11 ends the minimisation here

    if max_iter:
        minimize(loss, x0.astype(np.float64), jac=True, method="L-BFGS-B", callback=track,
                 options=dict(maxiter=int(max_iter)))
    wk, bk = unpack(best["x"])
    return wk, bk, int(it[0]), int(best["it"]), float(best["score"]), sse(best["x"])[2]


def pair_convolutions(decoder, linear) -> None:
    """Set conv1 and conv2 (centre taps) so that the pooled features keep, linearly, the
    leading feature directions of the GAP-pooled linear decoder.

    The directions: the GAP-pooled ridge's weights ``W`` (2,048 × R·C·4) mapped through the
    principal axes of its fitted values on the training split (SVD), i.e. the feature
    combinations that make its largest output modes (reduced-rank regression, Izenman
    1975). conv1's 512 filters are 256 such directions and their negatives; conv2's first
    128 filters take each pair's difference and its last 128 the negated difference.
    Since LeakyReLU(u) − LeakyReLU(−u) = (1 + slope) u and batch normalisation treats a
    pair alike, the leading 128 directions reach bn2 unchanged (up to scale); after bn2's
    LeakyReLU the Dense layer can form them back as differences of pooled features.
    Random convolutions keep less of them (docs/deviations.md has the figures).

    Parameters
    ----------
    decoder : keras.Model from :func:`lf_flame.model.build_decoder` (modified in place)
    linear : :class:`lf_flame.baselines.LinearDecoder` with ``pooling == 'gap'``
    """
    w = linear.x_train.T @ linear.dual_coef                       # primal weights (c, R·C·P)
    vt = np.linalg.svd(linear.x_train @ w, full_matrices=False)[2]
    c1, c2 = decoder.get_layer("conv1"), decoder.get_layer("conv2")
    n1, n2 = c1.filters // 2, c2.filters // 2
    d = w @ vt[:n1].T
    d = np.pad(d / (np.linalg.norm(d, axis=0) + 1e-12), ((0, 0), (0, n1 - d.shape[1])))
    k1 = np.zeros(c1.kernel.shape, np.float32)
    k1[1, 1, :, :n1], k1[1, 1, :, n1:2 * n1] = d, -d
    k2 = np.zeros(c2.kernel.shape, np.float32)
    j = np.arange(n2)
    k2[1, 1, j, j], k2[1, 1, n1 + j, j], k2[1, 1, j, n2 + j], k2[1, 1, n1 + j, n2 + j] = 1, -1, -1, 1
    c1.set_weights([k1, np.zeros(c1.filters, np.float32)])
    c2.set_weights([k2, np.zeros(c2.filters, np.float32)])


def closed_form_start(decoder, features_path, ds: LightFieldDataset, cfg: ModelConfig, eps: float = 1e-4,
                      max_iter: int = 0, linear=None) -> dict:
    """The 'closed-form' recipe's initialisation of the decoder, in place; seconds to minutes.

    0. With ``linear`` (the GAP-pooled :class:`~lf_flame.baselines.LinearDecoder`), the
       convolutions are set by :func:`pair_convolutions`; without, they keep their
       random initialisation.
    1. Batch-norm statistics from the training split (:func:`set_population_statistics`).
    2. The output convolution starts as the identity (centre tap 1 on its own plane, bias 0),
       so the Dense layer's output is the logit of the prediction.
    3. The Dense layer is solved by ridge regression (:func:`lf_flame.baselines.ridge_path`)
       from the network's own pooled 256-d features ``h`` to the targets' logits linearised
       about the training mean image ȳ (one Gauss–Newton step from it):
       ``z = logit(ȳ) + (y − ȳ) / (ȳ (1 − ȳ))``, clipped to ``±logit(1 − eps)``, with ȳ
       clipped to [eps, 1 − eps]. The background, exactly 0 in every target, gets logit
       −9.2 (prediction 1e-4, which costs SSIM nothing; NOTES.md). λ is chosen per plane on
       the validation split by SSIM, λ = ∞ (the mean image itself) among the candidates, so
       the start is never worse than the mean image on the validation planes.
       With ``cfg.dropout_at == 'gap'``, each pooled feature is scaled by the dropout
       penalty's ``sqrt(p/(1−p) Σₙ hₙᵢ²)`` before the (isotropic) ridge: dropout on a
       linear layer's input acts as that diagonal L2 penalty (Wager, Wang & Liang 2013,
       "Dropout training as adaptive regularization"), the penalty that training with
       dropout adds.
    4. The Dense layer is refined on the output-space MSE (:func:`refine_dense`,
       ``max_iter`` L-BFGS iterations, each plane kept at its best validation iteration).

    Returns
    -------
    dict : ``relative_alpha`` (the λ chosen per plane, relative to the mean Gram
        eigenvalue; ``inf`` = mean image), ``gauss_newton_val_ssim`` (per plane, before the
        refinement) and :func:`refine_dense`'s record: ``val_ssim`` per plane at the start,
        ``kept_iteration``, ``loss`` and ``val_loss`` (MSE).
    """
    from .baselines import RELATIVE_ALPHAS, choose_alpha_per_plane, ridge_path
    from .metrics import mean_ssim
    tr, va = np.sort(ds.splits["train"]), np.sort(ds.splits["val"])
    if linear is not None:
        pair_convolutions(decoder, linear)
    set_population_statistics(decoder, features_path, tr)
    h_tr = _layer_outputs(decoder, "gap", features_path, tr).astype(np.float64)
    h_va = _layer_outputs(decoder, "gap", features_path, va).astype(np.float64)
    if cfg.dropout_at == "gap":
        p = cfg.dropout
        scale = np.sqrt(p / (1 - p) * (h_tr ** 2).sum(axis=0)) + 1e-12
    else:
        scale = np.ones(h_tr.shape[1])
    y = np.ascontiguousarray(np.transpose(ds.gt(tr), (0, 2, 3, 1)))  # (n, R, C, P): the Dense layout
    n_planes = y.shape[-1]
    ybar = np.clip(y.mean(axis=0, dtype=np.float64), eps, 1 - eps).astype(np.float32)
    lim = float(np.log((1 - eps) / eps))
    z = y - ybar  # float32 and in place from here: n × R·C·P values (bounds the peak memory)
    z /= ybar * (1 - ybar)
    z += np.log(ybar / (1 - ybar))
    path = ridge_path(h_tr / scale, np.clip(z, -lim, lim, out=z).reshape(len(z), -1))
    del z
    kq = path.kernel(h_va / scale) @ path.eigvecs
    rel = np.array([*RELATIVE_ALPHAS, np.inf])

    def predict(alpha):
        zv = path.predict(kq, alpha).reshape(len(va), *y.shape[1:])
        return np.transpose(1 / (1 + np.exp(-zv)), (0, 3, 1, 2))

    alphas, scores = choose_alpha_per_plane(predict, path.alpha_scale * rel, ds.gt(va), mean_ssim)
    coef = path.dual_coef(np.tile(alphas, int(np.prod(y.shape[1:-1]))))  # columns are (r, c, plane)
    w = (path.x_train.T @ coef) / scale[:, None].astype(np.float32)     # (256, R·C·P)
    b = path.y_mean - (path.x_mean * scale.astype(np.float32)) @ w
    relative_alpha = [float(a / path.alpha_scale) for a in alphas]
    del path, kq, coef
    w, b, refined = refine_dense(h_tr, y.reshape(len(y), -1), h_va, np.transpose(ds.gt(va), (0, 2, 3, 1)),
                                 w, b, max_iter)
    decoder.get_layer("dense").set_weights([w, b])
    k = np.zeros(decoder.get_layer("refocused").kernel.shape, np.float32)
    k[1, 1, np.arange(n_planes), np.arange(n_planes)] = 1.0
    decoder.get_layer("refocused").set_weights([k, np.zeros(n_planes, np.float32)])
    return dict(relative_alpha=relative_alpha, gauss_newton_val_ssim=scores.tolist(), **refined)


#: Layers that the 'closed-form' recipe trains (a linear probe of the decoder's head).
PROBE_LAYERS = ("dense", "refocused")


def freeze_for_probe(decoder) -> None:
    """Freeze every decoder layer but :data:`PROBE_LAYERS`: the convolutions keep their
    weights, and the batch-norm layers (frozen, so Keras 3 runs them in inference mode)
    their population statistics, in training as in inference."""
    for layer in decoder.layers:
        layer.trainable = layer.name in PROBE_LAYERS


class _WallClock(keras.callbacks.Callback):
    """Adds validation SSIM and cumulative wall time to the epoch logs, and stops before the
    time budget: after an epoch, training stops when one more epoch as long as the longest
    so far would end past ``budget_s``."""

    def __init__(self, val_data, budget_s: float, start_offset_s: float = 0.0):
        super().__init__()
        self.val_data, self.budget_s, self.offset = val_data, budget_s, start_offset_s
        self.t0 = self.t_epoch = time.perf_counter()
        self.longest = 0.0

    def on_epoch_begin(self, epoch, logs=None):
        self.t_epoch = time.perf_counter()

    def on_epoch_end(self, epoch, logs=None):
        feats_path, ds, idx = self.val_data
        pred = predict_features(self.model, feats_path, idx)
        logs["val_ssim"] = float(np.mean([ssim_per_plane(ds.gt(int(i)), p) for i, p in zip(np.sort(idx), pred)]))
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


def _resume_state(out: Path):
    """(initial_epoch, wall time already trained, past val SSIMs) from a previous run in ``out``.

    The history is cut back to the epoch that the last complete checkpoint holds, so an
    epoch logged by a run killed before its checkpoint was written is trained again.
    """
    state_path, hist_path = out / "train_state.json", out / "history.csv"
    if not (state_path.exists() and (out / "decoder_last.keras").exists() and hist_path.exists()):
        for p in (hist_path, state_path):
            p.unlink(missing_ok=True)
        return 0, 0.0, []
    state = json.loads(state_path.read_text())
    h = pd.read_csv(hist_path)
    h = h[h["epoch"] <= state["epoch"]]
    if len(h) != state["epoch"] + 1:
        raise ValueError(f"{hist_path} lacks epochs that {state_path} says were trained; "
                         f"delete {out} to train from scratch")
    atomic_write_text(hist_path, h.to_csv(index=False))
    return state["epoch"] + 1, float(state["wall_time_s"]), h["val_ssim"].tolist()


def load_decoder(model_dir):
    """The trained decoder of ``model_dir`` and its ``train_info`` dict.

    Raises
    ------
    FileNotFoundError
        ``train_info.json`` or the weights file is missing.
    """
    model_dir = Path(model_dir)
    info_path, weights_path = model_dir / "train_info.json", model_dir / "decoder_best.weights.h5"
    for p in (info_path, weights_path):
        if not p.is_file():
            raise FileNotFoundError(f"trained model file not found: {p} (run 'lf-flame train' first)")
    info = json.loads(info_path.read_text())
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


def _save_random_backbone(ds: LightFieldDataset, cfg: ModelConfig, seed: int, out: Path) -> None:
    """Save the random-init backbone that made the feature cache (same seed, same draw)."""
    path = out / "backbone.weights.h5"
    if not path.exists():
        keras.utils.set_random_seed(seed)
        tmp = out / "partial.backbone.weights.h5"
        build_feature_extractor(ds.camera.sensor_shape, cfg, None).save_weights(tmp)
        os.replace(tmp, path)


def _features(features_path, indices) -> np.ndarray:
    with h5py.File(features_path, "r") as f:
        return f["features"][np.sort(np.asarray(indices))]


#: The baselines' files in a model folder, by route.
BASELINE_FILES = {"mean image": "mean_image.h5", "linear decoder (GAP-pooled)": "linear_gap.h5",
                  "linear decoder (un-pooled)": "linear_unpooled.h5"}


def load_baselines(model_dir) -> dict:
    """The yardsticks saved beside a trained network: route -> MeanImage or LinearDecoder.

    Raises
    ------
    FileNotFoundError, ValueError
        A baseline file is missing, corrupt or of another route.
    """
    from .baselines import LinearDecoder, MeanImage
    return {route: (MeanImage if route == "mean image" else LinearDecoder).load(Path(model_dir) / name)
            for route, name in BASELINE_FILES.items()}


def fit_baselines(features_path, ds: LightFieldDataset, out: Path) -> dict:
    """Fit the mean image and both linear decoders on the training split (λ per plane chosen
    on the validation split) and save them in ``out`` (:data:`BASELINE_FILES`), unless done.

    Returns
    -------
    dict : route -> validation SSIM per plane (list of 4) and fit time (s).
    """
    from .baselines import LinearDecoder, MeanImage
    from .metrics import mean_ssim
    info_path = out / "baselines.json"
    if info_path.exists() and all((out / f).exists() for f in BASELINE_FILES.values()):
        return json.loads(info_path.read_text())
    tr, va = np.sort(ds.splits["train"]), np.sort(ds.splits["val"])
    gt_tr, gt_va = ds.gt(tr), ds.gt(va)
    info = {}
    t = time.perf_counter()
    mean = MeanImage.fit(gt_tr)
    mean.save(out / BASELINE_FILES[mean.route])
    info[mean.route] = dict(val_ssim=[mean_ssim(gt_va[:, k], mean.predict(va)[:, k]) for k in range(gt_va.shape[1])],
                            fit_s=time.perf_counter() - t)
    f_tr, f_va = _features(features_path, tr), _features(features_path, va)
    for pooling in ("gap", "none"):
        t = time.perf_counter()
        dec = LinearDecoder.fit(pooling, f_tr, gt_tr, f_va, gt_va, mean_ssim)
        dec.save(out / BASELINE_FILES[dec.route])
        info[dec.route] = dict(val_ssim=dec.val_scores.tolist(), alphas=dec.alphas.tolist(),
                               fit_s=time.perf_counter() - t)
        print(f"{dec.route}: validation SSIM {np.round(dec.val_scores, 3).tolist()} "
              f"({info[dec.route]['fit_s']:.0f} s)")
    atomic_write_text(info_path, json.dumps(info, indent=2))
    return info


def _start(ds, feats_path, model_cfg: ModelConfig, train_cfg: TrainConfig, label, train_data, val_data, out: Path):
    """Build and initialise the decoder by the recipe, compile it, and write the start as
    epoch 0 of the history, the best and the last checkpoint (so a resume begins at epoch 1)."""
    t0 = time.perf_counter()
    with h5py.File(feats_path, "r") as f:
        fshape = f["features"].shape[1:]
    decoder = build_decoder(fshape, ds.camera.n_rows, ds.camera.n_cols, model_cfg)
    start = dict(recipe=train_cfg.recipe)
    if train_cfg.recipe == "closed-form":
        from .baselines import LinearDecoder
        gap = LinearDecoder.load(out / BASELINE_FILES["linear decoder (GAP-pooled)"])
        start.update(closed_form_start(decoder, feats_path, ds, model_cfg,
                                       max_iter=int(train_cfg.refine_iterations[ds.scene]), linear=gap))
        freeze_for_probe(decoder)
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
    atomic_write_text(out / "history.csv", pd.DataFrame([dict(epoch=0, **logs)]).to_csv(index=False))
    decoder.save_weights(out / "decoder_best.weights.h5")
    _LabelWeightsFile(out / "decoder_best.weights.h5", label).on_epoch_end(0)
    resume = _ResumeCheckpoint(out / "decoder_last.keras", out / "train_state.json", label)
    resume.set_model(decoder)
    resume.on_epoch_end(0, logs)
    print(f"start ({train_cfg.recipe}): validation SSIM {logs['val_ssim']:.4f} in {logs['wall_time_s']:.0f} s")
    return start, decoder


def train(dataset_path, out_dir, model_cfg: ModelConfig, train_cfg: TrainConfig, progress: bool = True) -> dict:
    """Train the decoder on a dataset's cached features; resumable.

    Writes to ``out_dir``: ``decoder_best.weights.h5`` (lowest validation loss; its HDF5
    attribute ``backbone_weights`` names the backbone), ``backbone.weights.h5`` (only for a
    random-init backbone), ``decoder_last.keras`` and
    ``train_state.json`` (for resume), ``history.csv`` (loss, val_loss, val_ssim,
    wall_time_s per epoch) and, last, ``train_info.json`` (configs, weights used, epochs,
    wall time, provenance). A run started again in the same folder continues from the last
    complete epoch with the same split, data order and optimizer state.

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
    if label == "random-init":
        _save_random_backbone(ds, model_cfg, train_cfg.seed, out)
    t_feat = time.perf_counter() - t_start
    baselines = fit_baselines(feats_path, ds, out)
    keras.utils.set_random_seed(train_cfg.seed)
    hist_path, last_path, best_path = out / "history.csv", out / "decoder_last.keras", out / "decoder_best.weights.h5"
    initial_epoch, offset, past = _resume_state(out)
    bs = train_cfg.batch_size
    val_data = FeatureBatches(feats_path, ds, ds.splits["val"], bs, False, train_cfg.seed)
    if initial_epoch:
        decoder = keras.models.load_model(last_path)
        start = json.loads((out / "start.json").read_text())
        print(f"resuming from epoch {initial_epoch} ({offset:.0f} s already trained)")
    else:
        train_eval = FeatureBatches(feats_path, ds, ds.splits["train"], bs, False, train_cfg.seed)
        start, decoder = _start(ds, feats_path, model_cfg, train_cfg, label, train_eval, val_data, out)
        initial_epoch, offset, past = _resume_state(out)
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
    info = dict(dataset=str(dataset_path), scene=scene, backbone_weights=label,
                model_config=json.loads(to_json(model_cfg)), train_config=json.loads(to_json(train_cfg)),
                raw_shape=list(ds.camera.sensor_shape), output_shape=[ds.camera.n_rows, ds.camera.n_cols],
                feature_shape=list(decoder.input_shape[1:]), dataset_camera=ds.attrs["camera"],
                epochs_run=int(len(h)) - 1, paper_epochs=int({"shapes": 5000, "flame": 1000}[scene]),
                best_epoch=int(h["epoch"].iloc[int(h["val_ssim"].idxmax())]),
                best_val_ssim=float(h["val_ssim"].max()), start_val_ssim=float(h["val_ssim"].iloc[0]),
                best_val_loss=float(h["val_loss"].min()), training_wall_time_s=float(h["wall_time_s"].iloc[-1]),
                start=start, baselines=baselines,
                feature_cache=str(feats_path), feature_wall_time_s=t_feat, provenance=provenance())
    atomic_write_text(out / "train_info.json", json.dumps(info, indent=2))
    return info
