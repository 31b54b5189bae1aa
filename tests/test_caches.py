"""Caches computed from a dataset (backbone features, the yardsticks, a training run) are
tied to the exact dataset by its content digest and rebuilt when it changes."""
import dataclasses
import json

import h5py
import numpy as np
import pytest

from lf_flame.learn import dataset as D
from lf_flame.learn.baselines import MeanImage, fit_baselines
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.config import DatasetConfig, ModelConfig, TrainConfig
from lf_flame.learn.features import compute_features
from lf_flame.learn.training import train

CAM = PlenopticCamera(n_rows=20, n_cols=10)
CFG = DatasetConfig(n_samples={"shapes": 6, "flame": 12}, rays_per_pixel=1, seed=3, regime="paper")
SLOPES = [CAM.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)]
MODEL = ModelConfig(input_rows=64, input_cols=32, weights="none")


def test_digest_names_the_content(tmp_path):
    a = D.generate(tmp_path / "a.h5", CAM, CFG, "flame", SLOPES, progress=False)
    b = D.generate(tmp_path / "b.h5", CAM, CFG, "flame", SLOPES, progress=False)
    c = D.generate(tmp_path / "c.h5", CAM, dataclasses.replace(CFG, rays_per_pixel=2), "flame", SLOPES,
                   progress=False)
    da, db, dc = (D.LightFieldDataset(p).digest for p in (a, b, c))
    assert da == db != dc  # the same settings render the same file; other rays per pixel another
    with h5py.File(a, "r") as f:
        assert f.attrs["digest"] == D.content_digest(f)  # written at generation
    with h5py.File(b, "a") as f:  # one ground-truth value changed
        f["gt"][0, 0, 0, 0] += 0.5
    with pytest.raises(ValueError, match="was changed since it was written"):   # its digest no longer holds
        D.LightFieldDataset(b)
    with h5py.File(b, "a") as f:
        del f.attrs["digest"]  # (a file made before digests: computed on reading)
    assert D.LightFieldDataset(b).digest != da
    with h5py.File(a, "a") as f:  # a test image's planes reversed: scored against the wrong truth, had it been read
        f["gt"][int(f["split/test"][0])] = f["gt"][int(f["split/test"][0])][::-1]
    with pytest.raises(ValueError, match="was changed since it was written"):
        D.check_dataset(a)


def test_features_baselines_and_training_are_rebuilt_for_a_regenerated_dataset(tmp_path, capsys):
    path, out = tmp_path / "flame.h5", tmp_path / "model"
    out.mkdir()
    D.generate(path, CAM, CFG, "flame", SLOPES, progress=False)
    ds = D.LightFieldDataset(path)
    feats, _ = compute_features(ds, MODEL, "none", progress=False, seed=7)
    fit_baselines(feats, ds, out)
    with h5py.File(feats) as f:
        before = f["features"][:]
    stamp = feats.stat().st_mtime_ns
    assert compute_features(ds, MODEL, "none", progress=False, seed=7)[0] == feats
    assert feats.stat().st_mtime_ns == stamp  # the same dataset: the cache is reused
    capsys.readouterr()

    # the same path, the other regime, same camera, seed and sample count
    D.generate(path, CAM, dataclasses.replace(CFG, regime="varied"), "flame", SLOPES, progress=False)
    new = D.LightFieldDataset(path)
    assert new.digest != ds.digest and new.n == ds.n and new.attrs["camera"] == ds.attrs["camera"]
    feats2, _ = compute_features(new, MODEL, "none", progress=False, seed=7)
    assert "computing it again" in capsys.readouterr().out
    with h5py.File(feats2) as f:
        assert f.attrs["dataset_digest"] == new.digest
        assert not np.array_equal(f["features"][:], before)
    fit_baselines(feats2, new, out)
    assert "fitting them again" in capsys.readouterr().out
    assert json.loads((out / "baselines.json").read_text())["dataset_digest"] == new.digest
    mean = MeanImage.load(out / "mean_image.h5").mean
    assert np.allclose(mean, new.gt(np.sort(new.splits["train"])).mean(axis=0), atol=1e-6)


def test_a_training_run_is_not_resumed_on_another_dataset(tmp_path, capsys):
    path, out = tmp_path / "flame.h5", tmp_path / "model"
    D.generate(path, CAM, CFG, "flame", SLOPES, progress=False)
    tcfg = TrainConfig(max_epochs={"flame": 1}, time_budget_s={"flame": 600}, refine_iterations={"flame": 2})
    train(path, out, MODEL, tcfg, progress=False)
    assert json.loads((out / "start.json").read_text())["dataset_digest"] == D.LightFieldDataset(path).digest
    D.generate(path, CAM, dataclasses.replace(CFG, regime="varied"), "flame", SLOPES, progress=False)
    capsys.readouterr()
    info = train(path, out, MODEL, tcfg, progress=False)
    assert "holds a run on another dataset" in capsys.readouterr().out
    new = D.LightFieldDataset(path).digest
    assert json.loads((out / "start.json").read_text())["dataset_digest"] == new
    assert info["epochs_run"] == 1 and json.loads((out / "baselines.json").read_text())["dataset_digest"] == new


def test_a_retrain_with_another_seed_and_input_size_rewrites_the_backbone_and_refits_the_yardsticks(tmp_path,
                                                                                                    capsys):
    """train into a folder of a random-init run (seed 7, 64 x 32 input) with seed 8 and a 64 x 64 input: the saved
    backbone and the yardsticks must be this run's. They were kept (the backbone written only if absent, the
    yardsticks reused whenever the dataset's digest matched): held-out SSIM 0.03-0.13 where a clean folder gave
    0.90-0.94, and after an input-size change evaluate's broadcast error on the un-pooled decoder."""
    from lf_flame.learn.baselines import LinearDecoder, pool_features
    from lf_flame.learn.features import load_features
    from lf_flame.learn.model_files import load_full_model
    path, out = tmp_path / "flame.h5", tmp_path / "model"
    D.generate(path, CAM, CFG, "flame", SLOPES, progress=False)
    ds = D.LightFieldDataset(path)
    tcfg = TrainConfig(max_epochs={"flame": 0}, time_budget_s={"flame": 600}, refine_iterations={"flame": 0})
    train(path, out, MODEL, tcfg, progress=False)
    capsys.readouterr()
    info = train(path, out, dataclasses.replace(MODEL, input_cols=64), dataclasses.replace(tcfg, seed=8),
                 progress=False)
    printed = capsys.readouterr().out
    assert "holds another backbone draw (seed 7 there, 8 now, input_size 64x32 there, 64x64 now)" in printed
    assert "fitting them again" in printed
    fx = load_full_model(out)[0].get_layer("feature_extractor")      # the draw that made this run's features
    with h5py.File(info["feature_cache"]) as f:
        cached = f["features"][:2].astype(np.float32)
    got = np.asarray(fx.predict_on_batch(ds.raw([0, 1])[..., None]))
    assert got.shape == cached.shape and np.abs(got - cached).max() <= 2e-3 * np.abs(cached).max()
    unpooled = LinearDecoder.load(out / "linear_unpooled.h5")             # fitted on this run's features
    want = pool_features(load_features(info["feature_cache"], np.sort(ds.splits["train"])), "none").mean(axis=0)
    assert unpooled.x_mean.shape == want.shape and np.allclose(unpooled.x_mean, want, atol=1e-3)
    assert json.loads((out / "baselines.json").read_text())["features"]["seed"] == 8


def _fake_features(path, ds, seed=7):
    """A small feature cache of ``ds`` (random (n, 2, 1, 8) features) with the attributes compute_features writes."""
    with h5py.File(path, "w") as f:
        f["features"] = np.random.default_rng(seed).normal(size=(ds.n, 2, 1, 8)).astype(np.float16)
        f.attrs.update(dataset_digest=ds.digest, weights="random-init", seed=seed, backend="tensorflow",
                       model_config=json.dumps(dict(input_rows=64, input_cols=32)))
    return path


def test_an_interrupted_yardstick_fit_is_not_reused(tmp_path, monkeypatch):
    """Yardsticks fitted on dataset A, then a fit on dataset B killed after the mean image: baselines.json still
    recorded A while mean_image.h5 was B's, and a run on A reused that mixed set silently. The record is removed
    before the files are rewritten (and written last): the next run on A fits them again."""
    from lf_flame.learn import baselines as B
    out = tmp_path / "model"
    a = D.LightFieldDataset(D.generate(tmp_path / "a.h5", CAM, CFG, "flame", SLOPES, progress=False))
    b = D.LightFieldDataset(D.generate(tmp_path / "b.h5", CAM, dataclasses.replace(CFG, regime="varied"), "flame",
                                       SLOPES, progress=False))
    fa, fb = _fake_features(tmp_path / "fa.h5", a), _fake_features(tmp_path / "fb.h5", b)
    fit_baselines(fa, a, out)

    def killed(*args, **kw):
        raise KeyboardInterrupt
    with monkeypatch.context() as m:
        m.setattr(B.LinearDecoder, "fit", killed)
        with pytest.raises(KeyboardInterrupt):
            fit_baselines(fb, b, out)
    assert not (out / "baselines.json").exists()
    fit_baselines(fa, a, out)
    mean = MeanImage.load(out / "mean_image.h5").mean
    assert np.allclose(mean, a.gt(np.sort(a.splits["train"])).mean(axis=0), atol=1e-6)


def test_a_damaged_yardstick_record_is_fitted_again(tmp_path, capsys):
    """A truncated baselines.json ended training in json's "Unterminated string ..." naming no file: it is said,
    naming the file, and the yardsticks are fitted again."""
    out = tmp_path / "model"
    a = D.LightFieldDataset(D.generate(tmp_path / "a.h5", CAM, CFG, "flame", SLOPES, progress=False))
    fa = _fake_features(tmp_path / "fa.h5", a)
    fit_baselines(fa, a, out)
    record = out / "baselines.json"
    record.write_text(record.read_text()[:50])
    capsys.readouterr()
    fit_baselines(fa, a, out)
    assert f"{record} is not a readable record of the yardsticks: it is truncated or damaged" in capsys.readouterr().out
    assert json.loads(record.read_text())["dataset_digest"] == a.digest
