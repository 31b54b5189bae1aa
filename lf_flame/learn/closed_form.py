"""The 'closed-form' recipe: the paper's decoder initialised in closed form before any epoch.

Stage: the start of training (:mod:`lf_flame.learn.training`), on the cached backbone features
(:mod:`lf_flame.learn.features`). Population statistics for both batch-norm layers, the
convolutions paired to the GAP-pooled linear decoder's leading directions, the Dense layer
solved by ridge regression on linearised logits (one Gauss–Newton step) and refined by
L-BFGS on the output-space MSE, one run per plane; then which layers the epochs train.
``docs/deviations.md`` has the figures of each choice.
"""
from __future__ import annotations

import numpy as np
from scipy.special import expit  # σ, without overflow for large negative logits

from ..config import ModelConfig
from .dataset import LightFieldDataset
from .features import layer_outputs


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
        a = layer_outputs(decoder, conv, features_path, indices)
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
    info.update(loss=sq_err / np.size(y_tr), val_loss=float(np.mean((expit(z_va) - y_va.reshape(len(y_va), -1)) ** 2)))
    return w, b, info


def _refine_plane(h_tr, y_tr, h_va, gt_va, w, b, max_iter, patience):
    """:func:`refine_dense` for one plane: ``w`` (d, q), ``b`` (q,), ``y_tr`` (n, q),
    ``gt_va`` (m, R, C) with q = R·C. Returns (w, b, iterations, kept iteration, its
    validation SSIM, its training sum of squared errors)."""
    from scipy.optimize import minimize

    from ..measure.metrics import mean_ssim
    d, q = w.shape
    n = len(h_tr)

    def unpack(x):
        x = np.asarray(x, np.float32)
        return x[:d * q].reshape(d, q), x[d * q:]

    def val_score(x):
        wk, bk = unpack(x)
        return mean_ssim(gt_va, expit(h_va @ wk + bk).reshape(gt_va.shape))

    def sse(x):
        wk, bk = unpack(x)
        s = expit(h_tr @ wk + bk)
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
    decoder : keras.Model from :func:`lf_flame.learn.model.build_decoder` (modified in place)
    linear : :class:`lf_flame.learn.baselines.LinearDecoder` with ``pooling == 'gap'``
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

    0. With ``linear`` (the GAP-pooled :class:`~lf_flame.learn.baselines.LinearDecoder`), the
       convolutions are set by :func:`pair_convolutions`; without, they keep their
       random initialisation.
    1. Batch-norm statistics from the training split (:func:`set_population_statistics`).
    2. The output convolution starts as the identity (centre tap 1 on its own plane, bias 0),
       so the Dense layer's output is the logit of the prediction.
    3. The Dense layer is solved by ridge regression (:func:`lf_flame.learn.baselines.ridge_path`)
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
    from ..measure.metrics import mean_ssim
    tr, va = np.sort(ds.splits["train"]), np.sort(ds.splits["val"])
    if linear is not None:
        pair_convolutions(decoder, linear)
    set_population_statistics(decoder, features_path, tr)
    h_tr = layer_outputs(decoder, "gap", features_path, tr).astype(np.float64)
    h_va = layer_outputs(decoder, "gap", features_path, va).astype(np.float64)
    if cfg.dropout_at == "gap":
        p = cfg.dropout
        scale = np.sqrt(p / (1 - p) * (h_tr ** 2).sum(axis=0)) + 1e-12
    else:
        scale = np.ones(h_tr.shape[1])
    y = np.ascontiguousarray(np.transpose(ds.gt(tr), (0, 2, 3, 1)))  # (n, R, C, P): the Dense layout
    n_planes = y.shape[-1]
    gt_va = ds.gt(va)
    w, b, relative_alpha, scores = ridge_dense(h_tr, gauss_newton_targets(y, eps), h_va, gt_va, scale, mean_ssim)
    w, b, refined = refine_dense(h_tr, y.reshape(len(y), -1), h_va, np.transpose(gt_va, (0, 2, 3, 1)),
                                 w, b, max_iter)
    decoder.get_layer("dense").set_weights([w, b])
    k = np.zeros(decoder.get_layer("refocused").kernel.shape, np.float32)
    k[1, 1, np.arange(n_planes), np.arange(n_planes)] = 1.0
    decoder.get_layer("refocused").set_weights([k, np.zeros(n_planes, np.float32)])
    return dict(relative_alpha=relative_alpha, gauss_newton_val_ssim=scores.tolist(), **refined)


def gauss_newton_targets(y: np.ndarray, eps: float = 1e-4) -> np.ndarray:
    """The targets' logits linearised about their mean image: one Gauss–Newton step of the
    sigmoid from the mean, ``z = logit(ȳ) + (y − ȳ) / (ȳ (1 − ȳ))``.

    ȳ (the mean over samples, per pixel and plane) is clipped to [eps, 1 − eps] and ``z``
    to ``±logit(1 − eps)``, so a background that is 0 in every target gets logit
    −logit(1 − eps) (−9.21 for eps = 1e-4) and ``σ(z) = y`` to first order in ``y − ȳ``.

    Parameters
    ----------
    y : ndarray of shape (n, ...) float32, values in [0, 1]
        Targets, samples first (the Dense layout (n, R, C, P) in the recipe).
    eps : float

    Returns
    -------
    z : ndarray, the shape of ``y``, float32 (computed in place in a new array: the peak
        memory is one copy of ``y``)
    """
    ybar = np.clip(y.mean(axis=0, dtype=np.float64), eps, 1 - eps).astype(np.float32)
    lim = float(np.log((1 - eps) / eps))
    z = np.subtract(y, ybar, dtype=np.float32)
    z /= ybar * (1 - ybar)
    z += np.log(ybar / (1 - ybar))
    return np.clip(z, -lim, lim, out=z)


def ridge_dense(h_tr, z_tr, h_va, gt_va, scale, score_plane):
    """The Dense layer by ridge regression from pooled features to logits, λ per plane.

    Solves ``z ≈ (h / scale) W' + b`` in the dual (:func:`lf_flame.learn.baselines.ridge_path`)
    for every λ of :data:`~lf_flame.learn.baselines.RELATIVE_ALPHAS` and λ = ∞ (the intercept
    alone, i.e. the targets' mean logit), chooses λ per plane by ``score_plane`` of
    ``σ(z)`` on the validation split, and returns the weights in the unscaled features
    (``W = W' / scale``). The columns of ``z`` are in the Dense layer's (r, c, plane) order,
    so plane k's λ goes to columns k, k + P, k + 2P, ...

    Parameters
    ----------
    h_tr, h_va : ndarray (n, d), (m, d)
        Pooled features of the training and validation splits.
    z_tr : ndarray (n, R, C, P) float32
        Training targets as logits (:func:`gauss_newton_targets`); this function keeps no
        reference to it after the solve (the caller may pass it without holding it).
    gt_va : ndarray (m, P, R, C)
        Validation targets in [0, 1].
    scale : ndarray (d,)
        Per-feature scaling before the isotropic ridge (the dropout penalty's).
    score_plane : callable(gt (m, R, C), pred (m, R, C)) -> float, higher is better

    Returns
    -------
    (w (d, R·C·P) float32, b (R·C·P,) float32, relative_alpha (list of P floats, λ relative
    to the mean Gram eigenvalue; inf = the mean logit alone), scores (P,) on validation)
    """
    from .baselines import RELATIVE_ALPHAS, choose_alpha_per_plane, ridge_path
    shape = z_tr.shape[1:]
    path = ridge_path(h_tr / scale, z_tr.reshape(len(z_tr), -1))
    del z_tr
    kq = path.kernel(h_va / scale) @ path.eigvecs

    def predict(alpha):
        zv = path.predict(kq, alpha).reshape(len(h_va), *shape)
        return np.transpose(expit(zv), (0, 3, 1, 2))

    rel = np.array([*RELATIVE_ALPHAS, np.inf])
    alphas, scores = choose_alpha_per_plane(predict, path.alpha_scale * rel, gt_va, score_plane)
    coef = path.dual_coef(np.tile(alphas, int(np.prod(shape[:-1]))))  # columns are (r, c, plane)
    w = (path.x_train.T @ coef) / scale[:, None].astype(np.float32)
    b = path.y_mean - (path.x_mean * scale.astype(np.float32)) @ w
    return w, b, [float(a / path.alpha_scale) for a in alphas], scores


#: Decoder layers that the 'closed-form' recipe's epochs may train (a probe of the head).
PROBE_LAYERS = ("dense", "refocused")


def freeze_for_probe(decoder, layers=("dense",)) -> None:
    """Freeze every decoder layer but ``layers`` (a subset of :data:`PROBE_LAYERS`): the
    convolutions keep their weights, and the batch-norm layers (frozen, so Keras 3 runs them
    in inference mode) their population statistics, in training as in inference.

    By default only the Dense layer trains; the output 3×3 convolution stays the identity
    the start set. Trained at the paper's settings it lowers validation SSIM (varied shapes:
    0.848 → 0.826 in one epoch, validation MSE 0.002427 → 0.002386; with the Dense layer
    alone 0.848 → 0.848, MSE → 0.002420; ``experiments/studies/learning_causes.py``).

    Raises
    ------
    ValueError
        ``layers`` names a layer outside :data:`PROBE_LAYERS`.
    """
    if not set(layers) <= set(PROBE_LAYERS):
        raise ValueError(f"train_layers must be among {PROBE_LAYERS}. Received: {tuple(layers)}")
    for layer in decoder.layers:
        layer.trainable = layer.name in layers
