"""A learned reconstructor: each plane's emission from one light field, by a small U-Net on a physics start.

The paper trains a network to refocus; what is expensive here is each plane's *emission*
(:mod:`lf_flame.tomo`). This module learns it on top of a cheap start that carries the optics,
so that the network learns the prior and the corrections, not the camera:

1. **The physics start** (:func:`lf_flame.tomo.fourier.wiener_start`): one per-frequency
   Tikhonov solve of the exact operator and the normalised back-projection (refocused stack),
   on the lenslet grid.
2. **The network** (:func:`build_network`): a 2-D U-Net (Ronneberger et al., MICCAI 2015)
   shared by the planes. Each plane is one sample of channels ``[Wiener_k, refocused_k,
   mean of the other planes' Wiener, defocus_k]`` (defocus: the plane's parallax across the
   aperture, ``slope (N - 1) / 10`` lenslets, a constant map), scaled by the stack's light;
   its output is a correction added to ``Wiener_k``, kept non-negative. Shared over planes, it
   takes any number of planes at any depths.
3. **Training data** (:func:`training_samples`): scenes of the project's generators at random
   depths that the camera images (:data:`TRAIN_FAMILIES`: flames apart, the four-flame scene,
   two flames one behind the other), their truth on a grid of 2 x 2 samples per
   lenslet, light fields by the exact operator on that grid (:class:`~lf_flame.tomo.exact.ExactOperator`,
   no rays: thousands of samples cost minutes), the sensor's shot and read noise at a random
   SNR (or none) and its clipping. Each operator serves four samples (the scene, mirrored, its
   planes' contents permuted, both), since its setup costs more than a light field.

Scored, as every route, on traced renders (never by the operator that made the training data)
and on scene families left out of training: ``experiments/learned.py``.
"""
from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from pathlib import Path

import numpy as np

#: Scene families the reconstructor is trained on (:func:`training_scene`); the three-flame overlap
#: scene (:func:`~lf_flame.simulate.scenes.overlap_scene`) and the paper's fixed scenes are left out, to
#: score it on families it never saw.
TRAIN_FAMILIES = ("depth", "four-flames", "behind")
#: Channels of each plane's input (:func:`plane_inputs`).
CHANNELS = ("wiener", "refocused", "others", "defocus")
#: Read noise (electrons) of the training data's sensor, as ``experiments/reconstruct.py``'s renders.
READ_NOISE_E = 2.0
WEIGHTS_FILE = "reconstructor.weights.h5"
CONFIG_FILE = "reconstructor.json"


@dataclasses.dataclass(frozen=True)
class ReconstructorConfig:
    """What a learned reconstructor is, and how it is trained.

    Attributes
    ----------
    base_channels : int
        Feature maps of the U-Net's first level (doubled per level down).
    levels : int
        Pooling steps of the U-Net (the planes are zero-padded to a multiple of ``2**levels``).
    snr_db : (float, float)
        Range of the training data's SNR (dB, uniform); a share ``clean_share`` is noise-free.
    clean_share : float
    epochs, batch_size, learning_rate, patience :
        Adam on the relative squared error per plane (:func:`train`); the epoch kept is the best
        on the validation samples (``patience`` epochs without gain stop it).
    seed : int
    """
    base_channels: int = 16
    levels: int = 2
    snr_db: tuple = (10.0, 24.0)
    clean_share: float = 0.3
    epochs: int = 40
    batch_size: int = 8
    learning_rate: float = 1e-3
    patience: int = 6
    seed: int = 0


# ---- the data --------------------------------------------------------------------------------
def sensor_noise(views, snr_db, rng: np.random.Generator, read_e: float = READ_NOISE_E):
    """Shot and read noise at a given SNR on views whose clipping level is 1, then the clipping.

    The full well ``fw`` (electrons at level 1) solves ``sum(s) / fw + n read^2 / fw^2 =
    sum(s^2) / 10^(snr / 10)`` (the SNR of ``experiments/reconstruct.py``); each pixel
    reads ``(Poisson(s fw) + Normal(0, read)) / fw``, clipped to [0, 1]; since the clipping
    removes noise, the full well shrinks (up to 3 times) until the measured SNR against the
    clipped clean views is within 0.2 dB.

    Parameters
    ----------
    views : ndarray (any shape), radiance units (1: the sensor's clipping level)
    snr_db : float or None
        None: noise-free (only the clipping).
    rng : numpy.random.Generator
    read_e : float
        Read noise, electrons.

    Returns
    -------
    ndarray of the views' shape, float32
    """
    s = np.clip(np.asarray(views, np.float64), 0, None)
    if snr_db is None:
        return np.minimum(s, 1.0).astype(np.float32)
    a, b, c = s.size * read_e ** 2, s.sum(), -np.sum(s ** 2) / 10 ** (snr_db / 10)
    fw = 2 * a / (-b + math.sqrt(b * b - 4 * a * c))
    power = np.sum(s ** 2)
    for _ in range(4):        # clipping removes noise: shrink the full well until the SNR is measured
        out = np.clip((rng.poisson(s * fw) + rng.normal(0.0, read_e, s.shape)) / fw, 0.0, 1.0)
        snr = 10 * math.log10(power / max(np.sum((out - np.minimum(s, 1.0)) ** 2), 1e-300))
        if abs(snr - snr_db) < 0.2:
            break
        fw *= 10 ** ((snr_db - snr) / 10)
    return out.astype(np.float32)


def training_scene(camera, rng: np.random.Generator, family: str):
    """One training scene: ``"depth"`` (1-4 flames at random depths, heights and places, each in its own
    columns), ``"four-flames"`` (the paper's four-flame scene, varied regime, at four random depths) or
    ``"behind"`` (two flames in the same columns, 5-50 % of the depth range apart), in the camera's
    depth range (:func:`lf_flame.simulate.scenes_depth.camera_depth_ranges`)."""
    from ..simulate.scenes import flame_scene
    from ..simulate.scenes_depth import behind_scene, camera_depth_ranges, camera_depth_scene
    if family == "depth":
        return camera_depth_scene(camera, rng)
    if family == "behind":
        lo, hi = camera_depth_ranges(camera)["depth_range"]
        return behind_scene(camera, rng, float(rng.uniform(0.05, 0.5)) * (hi - lo), depth_range=(lo, hi))
    if family == "four-flames":
        lo, hi = camera_depth_ranges(camera)["depth_range"]
        while True:
            d = np.sort(rng.uniform(lo, hi, 4))[::-1]
            if np.min(-np.diff(d)) > 0.05 * (hi - lo):
                return flame_scene(camera, rng, regime="varied", depths_mm=tuple(float(v) for v in d))
    raise ValueError(f"family must be one of {TRAIN_FAMILIES}. Received: {family!r}")


def scene_depths(scene) -> list:
    """The depths (mm) of a scene's flames: the planes a reconstruction is asked for."""
    return [float(o["depth_offset_mm"]) for o in scene.objects]


def exact_light_field(scene, fine, rng, snr_db):
    """A scene's light field by the exact operator ``fine`` (2 x 2 samples per lenslet), with noise and
    clipping (:func:`sensor_noise`). Returns (views (N, N, R, C) float32, fitted pixels (bool, same shape))."""
    from ..tomo.truth import scene_truth
    clean = fine.matvec(scene_truth(scene, fine).ravel()).reshape(fine.dimsd)
    views = sensor_noise(clean, snr_db, rng)
    return views, views < 1.0


def plane_inputs(views, op, fit=None):
    """Each plane's input to the network (:data:`CHANNELS`), from one light field.

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    op : ExactOperator
        The planes (any grid; the inputs are on the lenslet grid).
    fit : ndarray of bool of shape (N, N, R, C) or None

    Returns
    -------
    inputs : ndarray of shape (P, rows', cols', 4), float32
        Zero-padded to a multiple of 8 per axis (rows first).
    scale : float
        The stack's light the inputs were divided by (the 99.9th percentile of the refocused stack).
    wiener : ndarray of shape (P, rows, cols)
        The start (:func:`lf_flame.tomo.fourier.wiener_start`), unscaled.
    """
    from ..tomo.fourier import wiener_start
    wiener, refocused = wiener_start(views, op, fit)
    P, rows, cols = wiener.shape
    scale = float(np.percentile(refocused, 99.9))
    scale = scale if scale > 0 else 1.0
    n = op.camera.pixels_per_lenslet
    x = np.zeros((P, -(-rows // 8) * 8, -(-cols // 8) * 8, len(CHANNELS)), np.float32)
    x[:, :rows, :cols, 0] = wiener / scale
    x[:, :rows, :cols, 1] = refocused / scale
    if P > 1:
        x[:, :rows, :cols, 2] = (wiener.sum(axis=0) - wiener) / ((P - 1) * scale)
    for k, d in enumerate(op.depths_mm):
        x[k, :rows, :cols, 3] = op.camera.slope_for_depth(d) * (n - 1) / 10.0
    return x, scale, wiener


def training_samples(camera, n_scenes: int, seed: int, config: ReconstructorConfig = ReconstructorConfig(),
                     families=TRAIN_FAMILIES, progress: bool = True, first: int = 0, workers: int | None = None):
    """Planes and their truth for training, from ``n_scenes`` scenes (four samples each).

    Parameters
    ----------
    camera : PlenopticCamera
        A perfect lenslet grid (the exact operator's).
    n_scenes : int
    seed : int
        Scene ``i`` draws from ``numpy.random.default_rng([seed, i])``; its family cycles through ``families``.
    config : ReconstructorConfig
        The noise range.
    families : sequence of str
    progress : bool
        A tqdm bar.
    first : int
        Index of the first scene (a share of a larger set: ``first .. first + n_scenes - 1``).
    workers : int or None
        Threads of the operators' FFTs (None: all cores).

    Returns
    -------
    x : ndarray of shape (S, rows', cols', 4), float32
        One row per plane (S = the planes of the 4 n_scenes light fields).
    y : ndarray of shape (S, rows', cols', 1), float32
        The truth on the lenslet grid, divided by its light field's ``scale``.
    """
    from tqdm.auto import tqdm
    from ..tomo.exact import ExactOperator
    from ..tomo.fourier import coarse_operator
    from ..tomo.truth import scene_truth
    xs, ys = [], []
    for i in tqdm(range(first, first + n_scenes), desc="reconstructor samples", disable=not progress):
        rng = np.random.default_rng([seed, i])
        scene = training_scene(camera, rng, families[i % len(families)])
        fine = ExactOperator(camera, scene_depths(scene), precision="float32", subsamples=2, workers=workers)
        op, _ = coarse_operator(fine)
        truth = scene_truth(scene, op)
        truth2 = scene_truth(scene, fine)
        for variant in range(4):
            t2, t = truth2, truth
            if variant & 1:                                         # mirrored left-right
                t2, t = t2[:, :, ::-1], t[:, :, ::-1]
            if variant & 2:                                         # the planes' contents permuted
                perm = rng.permutation(len(t))
                t2, t = t2[perm], t[perm]
            snr = None if rng.random() < config.clean_share else float(rng.uniform(*config.snr_db))
            views = sensor_noise(fine.matvec(np.ascontiguousarray(t2).ravel()).reshape(fine.dimsd), snr, rng)
            x, scale, _ = plane_inputs(views, op, views < 1.0)
            y = np.zeros(x.shape[:3] + (1,), np.float32)
            y[:, :t.shape[1], :t.shape[2], 0] = t / scale
            xs.append(x)
            ys.append(y)
    return np.concatenate(xs), np.concatenate(ys)


# ---- the network -----------------------------------------------------------------------------
def build_network(config: ReconstructorConfig = ReconstructorConfig()):
    """The U-Net: ``(None, rows', cols', 4)`` planes' inputs to ``(None, rows', cols', 1)`` emission.

    Two 3 x 3 convolutions (ReLU) per level, max-pooling down, nearest upsampling and skip
    concatenation up, a 1 x 1 convolution to a correction added to the Wiener channel, ReLU
    (emission is non-negative). ``rows'`` and ``cols'`` must be multiples of ``2**levels``.
    """
    import keras
    from keras import layers

    def block(x, ch):
        x = layers.Conv2D(ch, 3, padding="same", activation="relu")(x)
        return layers.Conv2D(ch, 3, padding="same", activation="relu")(x)

    inp = keras.Input((None, None, len(CHANNELS)))
    x, skips = inp, []
    for level in range(config.levels):
        x = block(x, config.base_channels * 2 ** level)
        skips.append(x)
        x = layers.MaxPooling2D()(x)
    x = block(x, config.base_channels * 2 ** config.levels)
    for level in reversed(range(config.levels)):
        x = layers.Concatenate()([layers.UpSampling2D()(x), skips[level]])
        x = block(x, config.base_channels * 2 ** level)
    correction = layers.Conv2D(1, 1, kernel_initializer="zeros")(x)
    wiener = layers.Lambda(lambda t: t[..., :1], output_shape=(None, None, 1))(inp)
    out = layers.ReLU()(layers.Add()([wiener, correction]))
    return keras.Model(inp, out, name="reconstructor")


def plane_mse(y_true, y_pred):
    """Mean squared error per plane (a Keras loss of shape (batch,), which the sample weights scale)."""
    from keras import ops
    return ops.mean(ops.square(y_true - y_pred), axis=(1, 2, 3))


def relative_weights(y) -> np.ndarray:
    """Per plane, ``1 / ||truth||^2`` scaled to mean 1 (so the loss is the relative squared error); planes
    without light take the mean weight."""
    sq = np.square(y, dtype=np.float64).sum(axis=(1, 2, 3))
    w = np.where(sq > 0, 1.0 / np.where(sq > 0, sq, 1.0), 0.0)
    w[sq <= 0] = w[sq > 0].mean() if np.any(sq > 0) else 1.0
    return (w / w.mean()).astype(np.float32)


# ---- the reconstructor -------------------------------------------------------------------------
class LearnedReconstructor:
    """A trained network and the camera it was trained for.

    Parameters
    ----------
    network : keras.Model
    camera : PlenopticCamera
    config : ReconstructorConfig
    record : dict
        Training provenance and scores (saved with the weights).
    """

    def __init__(self, network, camera, config: ReconstructorConfig, record: dict | None = None):
        self.network, self.camera, self.config, self.record = network, camera, config, dict(record or {})
        self._predict = None

    def planes(self, views, op, fit=None) -> np.ndarray:
        """Each plane's emission on the lenslet grid.

        Parameters
        ----------
        views : ndarray of shape (N, N, R, C)
            Radiance units (1: the clipping level).
        op : ExactOperator
            This reconstructor's camera, any planes.
        fit : ndarray of bool or None
            The pixels to use (None: those below 1, the clipping level).

        Returns
        -------
        ndarray of shape (P, rows, cols), float64

        Raises
        ------
        ValueError
            An operator of another camera than the one trained for, or views with NaN or inf.
        """
        if op.camera.to_dict() != self.camera.to_dict():
            raise ValueError("the reconstructor was trained for another camera than the operator's: train one for "
                             "this camera (make train-reconstructor CAMERA=camera-file, with CALIBRATION=cal.json "
                             "where its lenslet grid is not perfect)")
        views = np.asarray(views)
        if not np.all(np.isfinite(views)):
            raise ValueError("the views hold NaN or infinite values")
        x, scale, _ = plane_inputs(views, op, views < 1.0 if fit is None else fit)
        if self._predict is None:
            import tensorflow as tf
            self._predict = tf.function(lambda t: self.network(t, training=False), reduce_retracing=True)
        out = np.asarray(self._predict(x))[..., 0]
        _, rows, cols = op.phase_dims
        return out[:, :rows, :cols].astype(np.float64) * scale

    def save(self, folder) -> Path:
        """Weights and config (with the camera and the record) into ``folder``, each written to a temporary
        file and renamed."""
        from ..config import atomic_write_text
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / (WEIGHTS_FILE + ".partial.weights.h5")
        self.network.save_weights(tmp)
        os.replace(tmp, folder / WEIGHTS_FILE)
        record = {k: v for k, v in self.record.items() if k != "folder"}        # where it was loaded from
        atomic_write_text(folder / CONFIG_FILE, json.dumps(dict(config=dataclasses.asdict(self.config),
                                                                camera=self.camera.to_dict(), record=record),
                                                           indent=1, default=str))
        return folder

    @classmethod
    def load(cls, folder) -> "LearnedReconstructor":
        """A reconstructor saved by :meth:`save`.

        Raises
        ------
        FileNotFoundError
            No reconstructor in ``folder`` (train one: ``make train-reconstructor``).
        ValueError
            A config file that is not one of a reconstructor.
        """
        from ..optics.camera import PlenopticCamera
        folder = Path(folder)
        if not (folder / CONFIG_FILE).is_file() or not (folder / WEIGHTS_FILE).is_file():
            raise FileNotFoundError(f"no trained reconstructor in {folder} ({CONFIG_FILE} and {WEIGHTS_FILE}): "
                                    "train one with make train-reconstructor")
        try:
            meta = json.loads((folder / CONFIG_FILE).read_text())
            cfg = ReconstructorConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in meta["config"].items()})
            camera = PlenopticCamera.from_dict(meta["camera"])
        except (KeyError, TypeError, json.JSONDecodeError) as e:
            raise ValueError(f"{folder / CONFIG_FILE} is not a reconstructor's config: {e}") from e
        net = build_network(cfg)
        net.load_weights(folder / WEIGHTS_FILE)
        return cls(net, camera, cfg, dict(meta.get("record") or {}, folder=str(folder)))


def train(camera, train_data, val_data, config: ReconstructorConfig = ReconstructorConfig(), *,
          verbose: int = 2, checkpoint=None) -> LearnedReconstructor:
    """Train a reconstructor on samples of :func:`training_samples`.

    Adam on the relative squared error per plane (:func:`relative_weights`), its rate halved after 2
    epochs without gain on ``val_data`` (Keras ``ReduceLROnPlateau``); the epoch kept is the best on
    ``val_data`` (``EarlyStopping`` with ``restore_best_weights``).

    Parameters
    ----------
    camera : PlenopticCamera
    train_data, val_data : (x, y)
        From :func:`training_samples` with disjoint seeds.
    config : ReconstructorConfig
    verbose : int
        Keras's.
    checkpoint : path or None
        A weights file kept at the best epoch so far (a long run can be looked at while it runs).

    Returns
    -------
    LearnedReconstructor
        ``record``: epochs run, the best epoch, the losses per epoch, wall time.
    """
    import keras
    keras.utils.set_random_seed(config.seed)
    (x, y), (xv, yv) = train_data, val_data
    net = build_network(config)
    net.compile(optimizer=keras.optimizers.Adam(config.learning_rate), loss=plane_mse)
    calls = [keras.callbacks.EarlyStopping(patience=config.patience, restore_best_weights=True),
             keras.callbacks.ReduceLROnPlateau(factor=0.5, patience=2)]
    if checkpoint is not None:
        calls.append(keras.callbacks.ModelCheckpoint(str(checkpoint), save_best_only=True, save_weights_only=True))
    t0 = time.perf_counter()
    hist = net.fit(x, y, sample_weight=relative_weights(y), validation_data=(xv, yv, relative_weights(yv)),
                   epochs=config.epochs, batch_size=config.batch_size, callbacks=calls, verbose=verbose, shuffle=True)
    loss = hist.history["val_loss"]
    record = dict(epochs_run=len(loss), best_epoch=int(np.argmin(loss)) + 1, val_loss=[float(v) for v in loss],
                  loss=[float(v) for v in hist.history["loss"]], train_planes=int(len(x)), val_planes=int(len(xv)),
                  train_s=time.perf_counter() - t0)
    return LearnedReconstructor(net, camera, config, record)


#: Where ``make train-reconstructor`` saves the paper camera's reconstructor (``lf-flame reconstruct --solver learned``'s default).
DEFAULT_MODEL_DIR = Path(__file__).resolve().parents[2] / "models" / "reconstructor" / "paper"


def reconstruction(views, op, model: LearnedReconstructor, fit=None):
    """A learned reconstruction as the solvers' record (:class:`~lf_flame.tomo.solvers.Reconstruction`).

    Parameters
    ----------
    views : ndarray of shape (N, N, R, C)
    op : ExactOperator
        On the lenslet grid (``subsamples`` 1): the planes are returned on it.
    model : LearnedReconstructor
    fit : ndarray of bool or None
        The pixels to use (None: those below the clipping level 1).

    Returns
    -------
    Reconstruction
        ``solver`` ``"learned"``; ``settings``: the model's folder record, ``iters`` 0, the count of pixels
        left out; ``residuals``: the relative data residual over the fitted pixels (one more ``A``, not
        timed); ``time_s``: the start and the network.

    Raises
    ------
    ValueError
        An operator on a finer grid than the lenslets, or as :meth:`LearnedReconstructor.planes`.
    """
    from ..tomo.solvers import Reconstruction
    if getattr(op, "subsamples", None) != 1:
        raise ValueError("the learned reconstructor gives planes on the lenslet grid: its operator must be the exact "
                         "one with subsamples 1")
    views = np.asarray(views, np.float64)
    fit = views < 1.0 if fit is None else np.asarray(fit, bool)
    t0 = time.perf_counter()
    x = model.planes(views, op, fit)
    time_s = time.perf_counter() - t0
    r = (op.matvec(x.ravel()).reshape(views.shape) - views)[fit]
    sample = tuple((h / op.dims[1], w / op.dims[2]) for h, w in op.sizes_mm)
    settings = dict(iters=0, model=model.record.get("folder"), n_saturated=int((~fit).sum()), saturation=1.0,
                    train_scenes=model.record.get("train_scenes"), best_epoch=model.record.get("best_epoch"))
    return Reconstruction(x, op.depths_mm, sample, "learned", settings,
                          np.array([np.linalg.norm(r) / max(np.linalg.norm(views[fit]), 1e-300)]), time_s)
