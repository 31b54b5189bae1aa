"""The honest yardsticks of the network: the mean image and closed-form linear decoders.

- :class:`MeanImage`: the training split's mean ground truth, one constant image per plane.
  A network that does not beat it has learned nothing about the light field.
- :class:`LinearDecoder`: ridge regression from the same frozen backbone features the
  network sees to the 4 refocused planes, GAP-pooled (2,048 values) or un-pooled
  (h × w × 2,048). Solved in closed form in the dual (kernel) form, since there are far
  fewer training samples (≤ 1,280) than features or output pixels (4 × 180 × 90):
  ``A = (K + λ I)⁻¹ (Y − ȳ)`` with ``K = (Φ − φ̄)(Φ − φ̄)ᵀ`` (Hastie, Tibshirani &
  Friedman, *Elements of Statistical Learning*, 2nd ed., Sec. 3.4.1 and 5.8); one
  eigendecomposition of K (``scipy.linalg.eigh``) gives every λ of the search. λ is
  chosen per plane on the validation split.

:func:`ridge_path` is the solver, shared with the network's closed-form start
(:mod:`lf_flame.learn.closed_form`). Everything here is NumPy/SciPy: no Keras.

Stage: fitted on the cached backbone features (:mod:`lf_flame.learn.features`) by
:func:`fit_baselines` before the network trains, saved beside it and loaded by
:func:`load_baselines` wherever the network is scored.
"""
from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from scipy.linalg import eigh

from ..config import atomic_write_text, read_json
from .features import load_features

#: Candidate regularisations, relative to the mean eigenvalue of the Gram matrix.
RELATIVE_ALPHAS = tuple(10.0 ** np.arange(-6.0, 3.01, 0.5))
#: Features per block when forming Gram matrices (bounds the float32 temporaries).
_BLOCK = 64


def pool_features(features: np.ndarray, pooling: str) -> np.ndarray:
    """Backbone features (n, h, w, c) -> design rows (n, d), float32.

    Parameters
    ----------
    features : ndarray of shape (n, h, w, c)
        Frozen ResNet-50 features, any float dtype.
    pooling : {'gap', 'none'}
        'gap': global average over (h, w), d = c; 'none': flattened, d = h·w·c.

    Raises
    ------
    ValueError
        Unknown pooling, features not 4-D, or not finite.
    """
    f = np.asarray(features)
    if f.ndim != 4:
        raise ValueError(f"features must be (n, h, w, c). Received shape {f.shape}")
    if pooling == "gap":
        out = f.astype(np.float32).mean(axis=(1, 2))
    elif pooling == "none":
        out = f.reshape(len(f), -1).astype(np.float32)
    else:
        raise ValueError(f"pooling must be 'gap' or 'none'. Received: pooling={pooling!r}")
    if not np.all(np.isfinite(out)):
        raise ValueError("features contain NaN or inf")
    return out


def _gram(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b.T`` in float64, accumulated over blocks of rows of ``a``."""
    out = np.empty((len(a), len(b)), np.float64)
    for s in range(0, len(a), _BLOCK):
        out[s:s + _BLOCK] = a[s:s + _BLOCK] @ b.T
    return out


@dataclass
class RidgePath:
    """Dual ridge regression for every λ at once (see the module docstring).

    Attributes
    ----------
    x_mean : ndarray (d,)
        Training mean of the design rows (subtracted).
    y_mean : ndarray (p,)
        Training mean of the targets (the intercept).
    eigvals : ndarray (n,)
        Eigenvalues of the centred training Gram matrix, ascending.
    eigvecs : ndarray (n, n)
    qty : ndarray (n, p)
        ``eigvecsᵀ (Y − ȳ)``.
    x_train : ndarray (n, d)
        Centred training design rows (kept for predictions in the dual).
    """

    x_mean: np.ndarray
    y_mean: np.ndarray
    eigvals: np.ndarray
    eigvecs: np.ndarray
    qty: np.ndarray
    x_train: np.ndarray

    @property
    def alpha_scale(self) -> float:
        """Mean eigenvalue of the Gram matrix: the unit of :data:`RELATIVE_ALPHAS`."""
        return float(max(self.eigvals.mean(), 1e-30))

    def kernel(self, x: np.ndarray) -> np.ndarray:
        """Centred cross-Gram ``(x − x̄) x_trainᵀ`` (m, n) of new design rows ``x`` (m, d)."""
        return _gram(np.asarray(x, np.float32) - self.x_mean, self.x_train)

    def _weights(self, alpha) -> np.ndarray:
        """``1 / (eigval + λ)`` (n, 1) for one λ, or (n, p) for one λ per target column."""
        return (1.0 / (self.eigvals[:, None] + np.asarray(alpha, np.float64).reshape(1, -1))).astype(np.float32)

    def dual_coef(self, alpha) -> np.ndarray:
        """Dual coefficients A (n, p) for one λ, or one λ per target column ((p,) array)."""
        return self.eigvecs.astype(np.float32) @ (self._weights(alpha) * self.qty)

    def predict(self, kq: np.ndarray, alpha) -> np.ndarray:
        """Predictions (m, p) for one λ from ``kq = kernel(x) @ eigvecs`` (m, n), which is
        computed once for a whole λ search: each λ then costs one (m, n) × (n, p) product."""
        return (kq.astype(np.float32) * self._weights(alpha)[:, 0]) @ self.qty + self.y_mean


def ridge_path(x: np.ndarray, y: np.ndarray, overwrite_x: bool = False) -> RidgePath:
    """Prepare dual ridge regression of ``y`` on ``x`` for any λ.

    Parameters
    ----------
    x : ndarray of shape (n, d)
        Design rows (e.g. :func:`pool_features`); centred here.
    y : ndarray of shape (n, p)
        Targets; an intercept (their mean) is fitted, not penalised. Float32 (the
        eigenvectors' projection of them too); means accumulate in float64.
    overwrite_x : bool
        Centre a float32 ``x`` in place (no copy of the design matrix, which is 1 GB for
        the un-pooled features of 1,280 samples); ``x`` is then the path's ``x_train``.

    Raises
    ------
    ValueError
        Mismatched sample counts, fewer than 2 samples, or NaN/inf.
    """
    x = np.asarray(x, np.float32)
    y = np.asarray(y, np.float32).reshape(len(y), -1)
    if len(x) != len(y) or len(x) < 2:
        raise ValueError(f"need >= 2 samples with one target row each. Received x {x.shape}, y {y.shape}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise ValueError("ridge inputs contain NaN or inf")
    x_mean = x.mean(axis=0, dtype=np.float64).astype(np.float32)
    xc = np.subtract(x, x_mean, out=x if overwrite_x else None)
    y_mean = y.mean(axis=0, dtype=np.float64).astype(np.float32)
    lam, q = eigh(_gram(xc, xc))
    lam = np.clip(lam, 0.0, None)
    return RidgePath(x_mean, y_mean, lam, q, q.T.astype(np.float32) @ (y - y_mean), xc)


class MeanImage:
    """The training split's mean ground truth: one constant image per plane.

    Parameters
    ----------
    mean : ndarray of shape (P, R, C), values in [0, 1]
    """

    route = "mean image"

    def __init__(self, mean: np.ndarray):
        self.mean = np.asarray(mean, np.float32)

    @classmethod
    def fit(cls, gt: np.ndarray) -> "MeanImage":
        """From training ground truth (n, P, R, C)."""
        gt = np.asarray(gt, np.float64)
        if gt.ndim != 4 or not np.all(np.isfinite(gt)):
            raise ValueError(f"ground truth must be finite (n, P, R, C). Received shape {gt.shape}")
        return cls(gt.mean(axis=0))

    def predict(self, features: np.ndarray) -> np.ndarray:
        """The mean image (n, P, R, C) for each of ``len(features)`` samples (inputs unused)."""
        return np.broadcast_to(self.mean, (len(features), *self.mean.shape)).copy()

    def save(self, path) -> None:
        """Write ``mean`` to an HDF5 file (via a temporary file and rename)."""
        _save_h5(path, dict(mean=self.mean), dict(route=self.route))

    @classmethod
    def load(cls, path) -> "MeanImage":
        with _open_h5(path, cls.route) as f:
            return cls(f["mean"][:])


class LinearDecoder:
    """Closed-form ridge regression from frozen backbone features to the refocused planes.

    Parameters
    ----------
    pooling : {'gap', 'none'}
        Design rows from :func:`pool_features`.
    x_mean, x_train, dual_coef, y_mean : ndarrays
        The fitted dual solution: prediction ``((φ(f) − x_mean) x_trainᵀ) dual_coef + y_mean``.
    out_shape : (P, R, C)
    alphas : ndarray (P,)
        The λ chosen per plane on the validation split.
    """

    def __init__(self, pooling, x_mean, x_train, dual_coef, y_mean, out_shape, alphas):
        self.pooling = pooling
        self.x_mean, self.x_train = np.asarray(x_mean, np.float32), np.asarray(x_train, np.float32)
        self.dual_coef, self.y_mean = np.asarray(dual_coef, np.float32), np.asarray(y_mean, np.float32)
        self.out_shape, self.alphas = tuple(int(v) for v in out_shape), np.asarray(alphas, np.float64)

    @property
    def route(self) -> str:
        return f"linear decoder ({'GAP-pooled' if self.pooling == 'gap' else 'un-pooled'})"

    @classmethod
    def fit(cls, pooling: str, feats_train, gt_train, feats_val, gt_val, score_plane) -> "LinearDecoder":
        """Fit on the training split; choose λ per plane on the validation split.

        Parameters
        ----------
        pooling : {'gap', 'none'}
        feats_train, feats_val : ndarray (n, h, w, c)
            Frozen backbone features.
        gt_train, gt_val : ndarray (n, P, R, C)
            Ground-truth planes in [0, 1].
        score_plane : callable(gt (m, R, C), pred (m, R, C)) -> float
            Validation score of one plane, higher is better (the evaluation's SSIM).

        Returns
        -------
        LinearDecoder, with ``alphas`` (absolute λ per plane) and ``val_scores`` (P,).
        """
        gt_train, gt_val = np.asarray(gt_train), np.asarray(gt_val)
        out_shape = gt_train.shape[1:]
        path = ridge_path(pool_features(feats_train, pooling), gt_train.reshape(len(gt_train), -1), overwrite_x=True)
        kq = path.kernel(pool_features(feats_val, pooling)) @ path.eigvecs
        alphas, scores = choose_alpha_per_plane(
            lambda a: np.clip(path.predict(kq, a), 0, 1).reshape(len(kq), *out_shape),
            path.alpha_scale * np.asarray(RELATIVE_ALPHAS), gt_val, score_plane)
        per_col = np.repeat(alphas, int(np.prod(out_shape[1:])))
        dec = cls(pooling, path.x_mean, path.x_train, path.dual_coef(per_col), path.y_mean, out_shape, alphas)
        dec.val_scores = scores
        return dec

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Refocused planes (n, P, R, C), clipped to [0, 1], of backbone features (n, h, w, c)."""
        k = _gram(pool_features(features, self.pooling) - self.x_mean, self.x_train)
        return np.clip(k @ self.dual_coef + self.y_mean, 0.0, 1.0).reshape(len(k), *self.out_shape)

    def save(self, path) -> None:
        """Write the dual solution to HDF5 (via a temporary file and rename)."""
        # un-pooled rows are cached float16 features: stored uncentred, float16 holds them exactly
        rows = self.x_train + self.x_mean
        _save_h5(path, dict(x_mean=self.x_mean, x_rows=rows.astype(np.float16) if self.pooling == "none" else rows,
                            dual_coef=self.dual_coef, y_mean=self.y_mean, alphas=self.alphas),
                 dict(route="linear decoder", pooling=self.pooling, out_shape=list(self.out_shape)))

    @classmethod
    def load(cls, path) -> "LinearDecoder":
        with _open_h5(path, "linear decoder") as f:
            x_mean = f["x_mean"][:]
            return cls(f.attrs["pooling"], x_mean, f["x_rows"][:].astype(np.float32) - x_mean, f["dual_coef"][:], f["y_mean"][:],
                       f.attrs["out_shape"], f["alphas"][:])


def choose_alpha_per_plane(predict, alphas, gt_val, score_plane):
    """The λ of ``alphas`` that scores best on each plane of the validation split.

    Parameters
    ----------
    predict : callable(alpha) -> ndarray (m, P, R, C)
        Validation predictions for one λ.
    alphas : sequence of float
    gt_val : ndarray (m, P, R, C)
    score_plane : callable(gt (m, R, C), pred (m, R, C)) -> float, higher is better

    Returns
    -------
    (best_alpha (P,), best_score (P,))
    """
    gt_val = np.asarray(gt_val)
    n_planes = gt_val.shape[1]
    best_a, best_s = np.full(n_planes, np.nan), np.full(n_planes, -np.inf)
    for a in alphas:
        pred = predict(a)
        for k in range(n_planes):
            s = score_plane(gt_val[:, k], pred[:, k])
            if s > best_s[k]:
                best_a[k], best_s[k] = a, s
    return best_a, best_s


def _save_h5(path, arrays: dict, attrs: dict) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name("partial." + path.name)
    with h5py.File(tmp, "w") as f:
        for k, v in arrays.items():
            f.create_dataset(k, data=v)
        f.attrs.update(attrs)
    os.replace(tmp, path)


def _open_h5(path, route: str):
    """Open a saved baseline, checking it is one of ``route``.

    Raises
    ------
    FileNotFoundError
        No such file.
    ValueError
        A corrupt file or one of another route.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"baseline file not found: {path} (written by 'lf-flame train')")
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise ValueError(f"baseline file {path} is truncated or corrupt: {e}") from None
    if f.attrs.get("route") != route:
        got = f.attrs.get("route")
        f.close()
        raise ValueError(f"{path} holds a {got!r}, not a {route!r}")
    return f


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
    return {route: (MeanImage if route == "mean image" else LinearDecoder).load(Path(model_dir) / name)
            for route, name in BASELINE_FILES.items()}


def features_key(features_path) -> dict:
    """What makes a feature cache's features, from its attributes (:func:`lf_flame.learn.features.compute_features`):
    the dataset's digest, the backbone weights, the input size, the seed and, for a random-init backbone, the Keras
    backend that drew it. Yardsticks fitted on features of another key are not those of these features."""
    with h5py.File(features_path, "r") as f:
        a = dict(f.attrs)
    size = json.loads(a.get("model_config", "{}"))
    key = dict(dataset_digest=str(a.get("dataset_digest")), weights=str(a.get("weights")),
               input_size=f"{size.get('input_rows')}x{size.get('input_cols')}", seed=int(a.get("seed", -1)))
    if "random" in key["weights"]:
        key["backend"] = str(a.get("backend"))
    return key


def fit_baselines(features_path, ds, out: Path) -> dict:
    """Fit the mean image and both linear decoders on the training split (λ per plane chosen
    on the validation split) and save them in ``out`` (:data:`BASELINE_FILES`), unless done
    for these very features.

    Parameters
    ----------
    features_path : path of the dataset's feature cache (:func:`lf_flame.learn.features.compute_features`)
    ds : :class:`lf_flame.learn.dataset.LightFieldDataset`
    out : folder of the model

    Returns
    -------
    dict : route -> validation SSIM per plane (list of 4) and fit time (s).

    ``baselines.json`` holds that dict under ``routes``, under ``dataset_digest`` the
    :func:`lf_flame.learn.dataset.content_digest` of the dataset they were fitted on and under ``features`` the
    :func:`features_key` of the features. Yardsticks saved for another dataset or other features (another
    digest, backbone, input size or seed; or none recorded) are fitted again, with a message. The record is
    removed before the files are rewritten and written last, so a fit interrupted half-way leaves no record and
    is fitted again, never reused as a set of two datasets' yardsticks.
    """
    from ..measure.metrics import mean_ssim
    info_path = out / "baselines.json"
    key = features_key(features_path)
    if info_path.exists() and all((out / f).exists() for f in BASELINE_FILES.values()):
        try:
            old = read_json(info_path, "record of the yardsticks")
        except ValueError as e:                                    # a damaged record: as if none
            print(f"{e}: fitting them again")
        else:
            if old.get("dataset_digest") != ds.digest:
                print(f"{out}: the yardsticks were fitted on another dataset than {ds.path} "
                      f"(digest {str(old.get('dataset_digest'))[:12]} != {ds.digest[:12]}); fitting them again")
            elif old.get("features") != key:
                was = old.get("features") or {}
                differ = [f"{k} {was.get(k)} there, {key[k]} now" for k in key if was.get(k) != key[k]]
                print(f"{out}: the yardsticks were fitted on other backbone features ({', '.join(differ)}); "
                      "fitting them again")
            else:
                return old["routes"]
    info_path.unlink(missing_ok=True)       # the files are rewritten one by one: no record until all are
    tr, va = np.sort(ds.splits["train"]), np.sort(ds.splits["val"])
    gt_tr, gt_va = ds.gt(tr), ds.gt(va)
    info = {}
    t = time.perf_counter()
    mean = MeanImage.fit(gt_tr)
    mean.save(out / BASELINE_FILES[mean.route])
    info[mean.route] = dict(val_ssim=[mean_ssim(gt_va[:, k], mean.predict(va)[:, k]) for k in range(gt_va.shape[1])],
                            fit_s=time.perf_counter() - t)
    f_tr, f_va = load_features(features_path, tr), load_features(features_path, va)
    for pooling in ("gap", "none"):
        t = time.perf_counter()
        dec = LinearDecoder.fit(pooling, f_tr, gt_tr, f_va, gt_va, mean_ssim)
        dec.save(out / BASELINE_FILES[dec.route])
        info[dec.route] = dict(val_ssim=dec.val_scores.tolist(), alphas=dec.alphas.tolist(),
                               fit_s=time.perf_counter() - t)
        print(f"{dec.route}: validation SSIM {np.round(dec.val_scores, 3).tolist()} "
              f"({info[dec.route]['fit_s']:.0f} s)")
    atomic_write_text(info_path, json.dumps(dict(dataset_digest=ds.digest, features=key, routes=info), indent=2))
    return info
