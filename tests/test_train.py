"""Training: resume after a real kill, time budget, cached features vs the full model,
predict, and a tiny fit on each Keras backend."""
import importlib.util
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pytest

from lf_flame.cli import main

ROOT = Path(__file__).resolve().parents[1]
LF = [sys.executable, "-m", "lf_flame.cli"]

EXPERIMENT = """
[model]
input_rows = 64
input_cols = 32
weights = "none"
[train]
batch_size = 2
learning_rate = 1e-4
max_epochs = {{ shapes = {epochs}, flame = {epochs} }}
refine_iterations = {{ shapes = {refine}, flame = {refine} }}
time_budget_s = {{ shapes = {budget}, flame = {budget} }}
patience = 50
seed = 7
"""


def _experiment(path, epochs=6, budget=600, refine=5):
    path.write_text(EXPERIMENT.format(epochs=epochs, budget=budget, refine=refine))
    return str(path)


@pytest.fixture(scope="module")
def flame_h5(tmp_path_factory):
    d = tmp_path_factory.mktemp("data")
    (d / "slopes.json").write_text(json.dumps({"slopes": [2.28, 1.17, 0.0, -1.25]}))
    h5 = d / "flame.h5"
    assert main(["dataset", "--data-config", str(ROOT / "data_gen/quick.toml"), "--scene", "flame",
                 "--slopes", str(d / "slopes.json"), "--out", str(h5), "--quiet"]) == 0
    return h5


@pytest.fixture(scope="module")
def trained(flame_h5, tmp_path_factory):
    """A model trained 1 epoch on ``flame_h5`` by the CLI (the experiment above: the closed-form
    start refined by 5 L-BFGS iterations per plane), shared by the tests that only read a
    trained model folder (a test that edits it works on a copy)."""
    d = tmp_path_factory.mktemp("trained")
    out = d / "model"
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", _experiment(d / "exp.toml", epochs=1),
                 "--out", str(out), "--quiet"]) == 0
    return out


def _epochs(model_dir):
    return pd.read_csv(model_dir / "history.csv")["epoch"].tolist()


def _runs_here(backend) -> bool:
    """Whether this process's Keras runs on ``backend`` (fixed at import): a run on it needs
    no new process (one costs some 10 s of imports)."""
    import keras
    return keras.backend.backend() == backend


def test_killed_training_resumes_from_last_checkpoint(flame_h5, tmp_path, capsys):
    """3 epochs in a process killed once two are logged, then resumed by a new run (here, in
    the test's process: it reads only the files the killed one left); the start without the
    L-BFGS refinement (resuming never recomputes the start)."""
    cfg, out = _experiment(tmp_path / "exp.toml", epochs=3, refine=0), tmp_path / "model"
    env = dict(os.environ, TF_CPP_MIN_LOG_LEVEL="3")
    proc = subprocess.Popen(LF + ["train", "--dataset", str(flame_h5), "--experiment-config", cfg,
                                  "--out", str(out), "--quiet"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    hist, t0 = out / "history.csv", time.monotonic()
    while proc.poll() is None and time.monotonic() - t0 < 300:  # kill once the start and two epochs are logged
        if hist.exists() and len(hist.read_text().splitlines()) >= 4:
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.01)
    assert proc.wait() == -signal.SIGKILL, "training ended before it could be killed"
    killed_at = json.loads((out / "train_state.json").read_text())["epoch"]
    # epoch 2 was logged, so epoch 1's checkpoint is complete: a resume that restarted the
    # optimizer would count fewer iterations than 3 epochs' (checked below)
    assert 1 <= killed_at < 3 and not (out / "train_info.json").exists()

    capsys.readouterr()
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", cfg, "--out", str(out), "--quiet"]) == 0
    assert f"resuming from epoch {killed_at + 1}" in capsys.readouterr().out
    info = json.loads((out / "train_info.json").read_text())
    assert _epochs(out) == list(range(4))  # the start (0), then each epoch once, none lost, none repeated
    assert info["epochs_run"] == 3
    import keras
    last = keras.models.load_model(out / "decoder_last.keras")
    steps = int(np.ceil(len(h5py.File(flame_h5)["split/train"]) / 2))
    assert int(last.optimizer.iterations) == 3 * steps  # the optimizer state was resumed, not restarted
    with h5py.File(out / "decoder_best.weights.h5") as f:
        assert f.attrs["backbone_weights"] == "random-init"


def test_time_budget_stops_training(flame_h5, tmp_path):
    # the closed-form start alone (without its L-BFGS refinement) spends the budget: the
    # history holds only the start (epoch 0)
    out = tmp_path / "model"
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config",
                 _experiment(tmp_path / "exp.toml", epochs=50, budget=0.01, refine=0), "--out", str(out),
                 "--quiet"]) == 0
    assert _epochs(out) == [0]
    # started again, it trains no further: the budget is spent
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", str(tmp_path / "exp.toml"),
                 "--out", str(out), "--quiet"]) == 0
    assert _epochs(out) == [0]


def test_predict_full_model_equals_cached_feature_path(flame_h5, trained, tmp_path, capsys):
    from lf_flame.learn.features import predict_features
    from lf_flame.learn.model_files import load_decoder
    out = trained
    i = 3
    assert main(["predict", f"{flame_h5}:{i}", "--model-dir", str(out), "--out", str(tmp_path / "p.npz"),
                 "--repeat", "2"]) == 0
    assert "ms per light field" in capsys.readouterr().out
    full = np.load(tmp_path / "p.npz")["stack"]
    dec, info = load_decoder(out)
    cached = predict_features(dec, info["feature_cache"], [i])[0]
    assert full.shape == cached.shape == (4, 180, 90)
    # the full model rebuilds the random-init backbone from the recorded seed; the cache is
    # float16, so the two agree to float16 rounding, far below the spread of the outputs
    assert np.abs(full - cached).max() < 2e-3 < full.std()


def test_predict_rejects_mismatched_input(flame_h5, trained, tmp_path, capsys):
    out = trained
    np.save(tmp_path / "small.npy", np.zeros((30, 45), np.float32))
    assert main(["predict", str(tmp_path / "small.npy"), "--model-dir", str(out), "--out",
                 str(tmp_path / "p.npz")]) == 2
    assert "does not match the model's sensor" in capsys.readouterr().err
    assert main(["predict", f"{flame_h5}:0", "--model-dir", str(tmp_path / "nothing"), "--out",
                 str(tmp_path / "p.npz")]) == 2
    assert "not found" in capsys.readouterr().err
    for index in ("999", "abc"):        # a sample past the dataset's end (an IndexError's traceback), or no number
        assert main(["predict", f"{flame_h5}:{index}", "--model-dir", str(out), "--out", str(tmp_path / "p.npz")]) == 2
        assert f"{flame_h5}:{index}: a dataset of" in capsys.readouterr().err
    assert main(["predict", f"{flame_h5}:0", "--model-dir", str(out), "--out", str(tmp_path / "p.txt")]) == 0
    assert f"-> {tmp_path / 'p.txt.npz'}" in capsys.readouterr().out and (tmp_path / "p.txt.npz").exists()


FIT = """
import numpy as np, keras
from lf_flame.config import ModelConfig
from lf_flame.learn.model import build_model
keras.utils.set_random_seed(0)
model, fx, dec = build_model((90, 60), (6, 4), ModelConfig(input_rows=64, input_cols=64), weights=None)
model.compile(optimizer=keras.optimizers.Adam(1e-3), loss="mse")
x = np.random.default_rng(0).random((4, 90, 60, 1)).astype("float32")
y = np.full((4, 6, 4, 4), 0.25, "float32")
h = model.fit(x, y, batch_size=2, epochs=3, verbose=0).history["loss"]
assert all(np.isfinite(h)) and h[-1] < h[0], h
assert not any(w.trainable for w in fx.weights)
print(keras.backend.backend(), h)
"""


@pytest.mark.parametrize("backend", [
    "tensorflow",
    pytest.param("jax", marks=[pytest.mark.jax, pytest.mark.skipif(importlib.util.find_spec("jax") is None,
                                                                    reason="jax is not installed")]),
])
def test_tiny_fit_on_each_keras_backend(backend, capsys):
    if _runs_here(backend):
        exec(FIT, {})
        out = capsys.readouterr().out
    else:
        r = subprocess.run([sys.executable, "-c", FIT], env=dict(os.environ, KERAS_BACKEND=backend,
                                                                 TF_CPP_MIN_LOG_LEVEL="3"),
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        out = r.stdout
    assert out.startswith(backend)


@pytest.mark.skipif(not Path("/usr/bin/time").exists(), reason="GNU time is not installed")
def test_gnu_time_report_parsed(tmp_path):
    from lf_flame.learn.evaluation import read_gnu_time
    report = tmp_path / "time_v.txt"
    subprocess.run(["/usr/bin/time", "-v", "-o", str(report), sys.executable, "-c",
                    "import numpy, time; a = numpy.ones(50 * 2**20, numpy.uint8); time.sleep(0.2)"], check=True)
    got = read_gnu_time(report)
    assert 0.2 <= got["wall_s"] < 30 and 0.045 < got["peak_rss_gib"] < 2  # 50 MiB array held
    assert got["runs"] == 1
    # a second run appended (a target resumed): the times add up, the peak is the larger run's
    subprocess.run(["/usr/bin/time", "-v", "-a", "-o", str(report), sys.executable, "-c",
                    "import time; time.sleep(0.3)"], check=True)
    both = read_gnu_time(report)
    assert both["runs"] == 2 and both["wall_s"] >= got["wall_s"] + 0.3 and both["peak_rss_gib"] == got["peak_rss_gib"]
    (tmp_path / "bad.txt").write_text("Command being timed: x\n")
    with pytest.raises(ValueError, match="not a '/usr/bin/time -v' report"):
        read_gnu_time(tmp_path / "bad.txt")


def test_model_refuses_a_dataset_from_another_camera(flame_h5, trained, tmp_path, capsys):
    out = tmp_path / "model"
    shutil.copytree(trained, out)  # edited below: a copy of the shared model
    info = json.loads((out / "train_info.json").read_text())
    from lf_flame.optics.camera import PlenopticCamera
    info["dataset_camera"] = PlenopticCamera(mla_pitch_mm=0.1).to_json()  # as if trained on another camera
    (out / "train_info.json").write_text(json.dumps(info))
    assert main(["evaluate", "--dataset", str(flame_h5), "--model-dir", str(out), "--results", str(tmp_path)]) == 2
    assert "another camera" in capsys.readouterr().err
    assert main(["predict", f"{flame_h5}:0", "--model-dir", str(out), "--out", str(tmp_path / "p.npz")]) == 2
    assert "another camera" in capsys.readouterr().err


@pytest.mark.jax
@pytest.mark.skipif(importlib.util.find_spec("jax") is None, reason="jax is not installed")
def test_jax_backend_predicts_what_tensorflow_predicts(flame_h5, trained, tmp_path, capsys):
    out = trained
    stacks = {}
    for backend in ("tensorflow", "jax"):
        args = ["predict", f"{flame_h5}:2", "--model-dir", str(out), "--out", str(tmp_path / f"{backend}.npz"),
                "--repeat", "1"]
        if _runs_here(backend):
            capsys.readouterr()
            assert main(args) == 0
            stdout = capsys.readouterr().out
        else:
            r = subprocess.run(LF + args, env=dict(os.environ, KERAS_BACKEND=backend, TF_CPP_MIN_LOG_LEVEL="3"),
                               capture_output=True, text=True, timeout=300)
            assert r.returncode == 0, r.stderr[-2000:]
            stdout = r.stdout
        assert f"keras backend {backend}" in stdout
        stacks[backend] = np.load(tmp_path / f"{backend}.npz")["stack"]
    # the random-init backbone is loaded from the saved draw, not re-drawn by each backend
    assert np.abs(stacks["tensorflow"] - stacks["jax"]).max() < 1e-4


def test_saved_random_backbone_is_the_one_that_made_the_features(flame_h5, tmp_path, monkeypatch):
    # offline, weights "auto" first tries to build ResNet-50 with ImageNet weights, which
    # draws random numbers before failing; the backbone saved with the model must still be
    # the draw that computed the cached features
    import keras

    import lf_flame.learn.features as F
    from lf_flame.config import ModelConfig, TrainConfig
    from lf_flame.learn.model_files import load_full_model
    from lf_flame.learn.training import train
    real = F.resolve_weights

    def auto_offline(spec):
        keras.layers.Dense(64).build((None, 64))  # a draw, as the failed ImageNet build makes
        return real("none")

    monkeypatch.setattr(F, "resolve_weights", auto_offline)
    out = tmp_path / "model"
    # the start alone (no epoch): the features and the saved backbone are what is checked
    train(flame_h5, out, ModelConfig(input_rows=64, input_cols=32, weights="auto"),
          TrainConfig(max_epochs={"flame": 0}, time_budget_s={"flame": 600}, refine_iterations={"flame": 0}, seed=11),
          progress=False)
    model, info = load_full_model(out)
    fx = model.get_layer("feature_extractor")
    with h5py.File(info["feature_cache"]) as f:
        cached = f["features"][0].astype(np.float32)
    from lf_flame.learn.dataset import LightFieldDataset
    got = np.asarray(fx.predict_on_batch(LightFieldDataset(flame_h5).raw([0])[..., None]))[0]
    assert np.abs(got - cached).max() <= 2e-3 * np.abs(cached).max()


def _pooled_with_partners(decoder, feats):
    """Sample 0's pooled features (the Dense layer's input) in training mode, batched with
    sample 1 and with sample 2."""
    import keras
    gap = keras.Model(decoder.input, decoder.get_layer("gap").output)
    return tuple(keras.ops.convert_to_numpy(gap(feats[[0, k]], training=True))[0] for k in (1, 2))


def test_pooled_features_do_not_depend_on_the_batch_partner():
    import keras
    from lf_flame.config import ModelConfig
    from lf_flame.learn.model import build_decoder
    from lf_flame.learn.closed_form import freeze_for_probe
    feats = np.random.default_rng(0).normal(size=(3, 4, 2, 16)).astype("float32")
    keras.utils.set_random_seed(0)
    dec = build_decoder((4, 2, 16), 6, 4, ModelConfig())
    a, b = _pooled_with_partners(dec, feats)  # the paper's recipe: batch statistics of 2 samples
    assert np.abs(a - b).max() > 0.1 * np.abs(a).max()
    freeze_for_probe(dec)  # the closed-form recipe: population statistics
    a, b = _pooled_with_partners(dec, feats)
    assert np.allclose(a, b, atol=1e-6)
    inference = keras.ops.convert_to_numpy(keras.Model(dec.input, dec.get_layer("gap").output)(feats[[0]]))[0]
    assert np.allclose(a, inference, atol=1e-6)  # and training sees what inference sees


def test_paper_recipe_stays_reproducible_and_fails(flame_h5, tmp_path):
    """recipe = 'paper' (random init, batch statistics of 2, dropout on the pixel map) is kept
    as a named option for its failure: after an epoch it does not reach the mean image."""
    exp = tmp_path / "exp.toml"
    exp.write_text(EXPERIMENT.format(epochs=1, budget=600, refine=5).replace("[train]", '[train]\nrecipe = "paper"')
                   .replace("[model]", '[model]\ndropout_at = "pixels"'))
    out = tmp_path / "model"
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", str(exp), "--out", str(out),
                 "--quiet"]) == 0
    info = json.loads((out / "train_info.json").read_text())
    assert info["train_config"]["recipe"] == "paper" and info["model_config"]["dropout_at"] == "pixels"
    assert set(info["start"]) == {"recipe", "dataset_digest", "run", "wall_time_s"}
    assert _epochs(out) == [0, 1]
    import keras
    last = keras.models.load_model(out / "decoder_last.keras")
    assert last.get_layer("bn1").trainable and last.get_layer("conv1").trainable
    h = pd.read_csv(out / "history.csv")
    mean_val = np.mean(info["baselines"]["mean image"]["val_ssim"])
    assert h.val_ssim.max() < mean_val - 0.1, (h.val_ssim.tolist(), mean_val)


def test_closed_form_start_beats_the_mean_image_and_the_best_epoch_is_kept(flame_h5, trained):
    from lf_flame.learn.baselines import load_baselines
    from lf_flame.learn.dataset import LightFieldDataset
    from lf_flame.learn.features import load_features, predict_features
    from lf_flame.measure.metrics import ssim_per_plane
    from lf_flame.learn.model_files import load_decoder
    out = trained
    info = json.loads((out / "train_info.json").read_text())
    h = pd.read_csv(out / "history.csv")
    assert h.val_ssim.iloc[0] == pytest.approx(info["start_val_ssim"], abs=1e-12)
    # the start was solved on the pooled features in NumPy: the Keras network scores the same
    assert np.mean(info["start"]["val_ssim"]) == pytest.approx(h.val_ssim.iloc[0], abs=2e-3)
    assert info["start"]["val_loss"] == pytest.approx(h.val_loss.iloc[0]) and np.isfinite(h.loss.iloc[0])
    # the output-space refinement keeps, per plane, nothing worse than the Gauss-Newton start
    # (up to rounding: the start's score is recomputed from its primal float32 weights)
    assert np.all(np.array(info["start"]["val_ssim"]) >= np.array(info["start"]["gauss_newton_val_ssim"]) - 1e-6)
    dec, _ = load_decoder(out)  # the best checkpoint: what evaluate and predict use
    assert dec.get_layer("bn1").moving_variance.numpy().mean() != 1.0  # population statistics, not the init
    ds = LightFieldDataset(flame_h5)
    test = np.sort(ds.splits["test"])
    # on samples that chose nothing (the test split), the network beats the mean image by a margin
    net = predict_features(dec, info["feature_cache"], test)
    mean = load_baselines(out)["mean image"].predict(load_features(info["feature_cache"], test))
    margin = [np.mean(ssim_per_plane(g, p)) - np.mean(ssim_per_plane(g, q))
              for g, p, q in zip(ds.gt(test), net, mean)]
    assert min(margin) > 0.02, margin


def test_the_checkpoint_kept_is_the_best_epoch(flame_h5, tmp_path):
    """Without the L-BFGS refinement the Dense layer's epochs improve the start a little
    (about 1e-5 validation SSIM per epoch on the quick flames): the weights kept must be
    the epoch with the best validation SSIM, recomputed from them, not the start."""
    from lf_flame.learn.dataset import LightFieldDataset
    from lf_flame.learn.features import predict_features
    from lf_flame.measure.metrics import ssim_per_plane
    from lf_flame.learn.model_files import load_decoder
    exp = tmp_path / "exp.toml"
    exp.write_text(EXPERIMENT.format(epochs=2, budget=600, refine=0))
    out = tmp_path / "model"
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", str(exp), "--out", str(out),
                 "--quiet"]) == 0
    h = pd.read_csv(out / "history.csv")
    best = int(h.val_ssim.idxmax())
    assert best > 0, h.val_ssim.tolist()  # an epoch beat the start
    dec, info = load_decoder(out)
    assert info["best_epoch"] == best
    ds = LightFieldDataset(flame_h5)
    val = np.sort(ds.splits["val"])
    kept = np.mean([ssim_per_plane(g, p) for g, p in zip(ds.gt(val), predict_features(dec, info["feature_cache"], val))])
    assert kept == pytest.approx(h.val_ssim.iloc[best], abs=1e-9) and kept > h.val_ssim.iloc[0] + 1e-7


def test_a_models_scores_stay_its_own_when_another_run_overwrites_the_feature_cache(flame_h5, tmp_path, capsys):
    """Two models trained on one dataset with random-init backbones of other seeds share the feature cache's name: the
    second run rewrites it. The first model's evaluate then scores the second backbone's features through its own
    decoder (SSIM 0.88 -> 0.50 in a new user's run) unless it checks the cache; it does, and computes the test split's
    features with its own saved backbone, so its table stays what it was (to the cache's float16 rounding). The cache's
    path is recorded absolute (evaluate from another folder read a path relative to where train ran)."""
    data = tmp_path / "flame.h5"
    shutil.copy(flame_h5, data)
    exp7 = _experiment(tmp_path / "e7.toml", epochs=1, refine=1)
    exp8 = tmp_path / "e8.toml"
    exp8.write_text(Path(exp7).read_text().replace("seed = 7", "seed = 8"))
    for exp, out in ((exp7, "m7"), (str(exp8), "m8")):
        assert main(["train", "--dataset", str(data), "--experiment-config", exp, "--out", str(tmp_path / out),
                     "--quiet"]) == 0
        if out == "m7":
            assert main(["evaluate", "--dataset", str(data), "--model-dir", str(tmp_path / "m7"),
                         "--results", str(tmp_path / "before")]) == 0
    assert Path(json.loads((tmp_path / "m7" / "train_info.json").read_text())["feature_cache"]).is_absolute()
    capsys.readouterr()
    assert main(["evaluate", "--dataset", str(data), "--model-dir", str(tmp_path / "m7"),
                 "--results", str(tmp_path / "after")]) == 0
    assert "seed 8 there, 7 wanted" in capsys.readouterr().out
    before, after = (pd.read_csv(tmp_path / r / "metrics_flame.csv") for r in ("before", "after"))
    assert np.abs(before.ssim - after.ssim).max() < 2e-3, (before.ssim.describe(), after.ssim.describe())


def test_tables_leave_out_the_time_of_a_feature_cache_deleted_since(tmp_path, capsys):
    """tables reads the backbone features' time from their cache; a cache deleted since (it is rebuilt by make) leaves
    that time out with a note, where h5py's 'unable to open file' stopped the tables."""
    model = tmp_path / "models" / "paper" / "flame"
    model.mkdir(parents=True)
    (model / "train_info.json").write_text(json.dumps(dict(feature_cache=str(tmp_path / "gone.h5"), epochs_run=1,
                                                           training_wall_time_s=1.0)))
    (tmp_path / "res" / "paper").mkdir(parents=True)
    (tmp_path / "res" / "paper" / "table_flame.md").write_text("| plane | SSIM |\n|---|---|\n| 1 | 0.9 |\n")
    (model / "time_v.txt").write_text("")                  # its timer killed with the training run: no report
    assert main(["tables", "--results", str(tmp_path / "res"), "--data-dir", str(tmp_path / "data"),
                 "--model-dir", str(tmp_path / "models")]) == 0
    out = capsys.readouterr().out
    assert f"note: {tmp_path / 'gone.h5'} is gone" in out and "holds no complete GNU time report" in out


def test_tables_with_no_table_to_collect_are_refused(tmp_path, capsys):
    """tables with no evaluated table (evaluate not run, or the wrong --results) is refused naming the files it
    looked for, where it exited 0 with a page of headings only, as if the reproduction had finished."""
    assert main(["tables", "--results", str(tmp_path / "res"), "--data-dir", str(tmp_path / "data"),
                 "--model-dir", str(tmp_path / "models")]) == 2
    assert "no table to collect" in capsys.readouterr().err
    assert not (tmp_path / "res" / "tables.md").exists()


def test_a_model_folder_of_other_settings_trains_from_the_start(flame_h5, tmp_path, capsys):
    """train into a folder that holds a run: more epochs resume it; another learning rate (or recipe, seed, input
    size) starts again, naming what differs. It had resumed the old run and recorded the new settings beside it (a
    new user's closed-form start labelled 'recipe paper', lr 0.01; a 32 x 32 input resumed on 64 x 32 features)."""
    exp1 = _experiment(tmp_path / "e1.toml", epochs=1, refine=1)
    exp2 = _experiment(tmp_path / "e2.toml", epochs=2, refine=1)
    lr = tmp_path / "lr.toml"
    lr.write_text(Path(exp2).read_text().replace("learning_rate = 1e-4", "learning_rate = 1e-2"))
    out = str(tmp_path / "m")
    for exp in (exp1, exp2):
        assert main(["train", "--dataset", str(flame_h5), "--experiment-config", exp, "--out", out, "--quiet"]) == 0
    assert "resuming from epoch 2" in capsys.readouterr().out           # only how long it goes on changed
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", str(lr), "--out", out, "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "holds a run of other settings (learning_rate 0.0001 there, 0.01 now): training from the start" in printed
    assert "resuming" not in printed
    assert json.loads((tmp_path / "m" / "start.json").read_text())["run"]["learning_rate"] == 0.01


def test_settings_out_of_range_are_refused_naming_them(tmp_path, capsys):
    """A two-way split (it had given a 1-sample test split), a negative time budget and a learning rate of 0 (both
    accepted) are refused naming the setting; 0 epochs (the closed-form start only) is still taken."""
    from lf_flame.config import DatasetConfig, TrainConfig
    with pytest.raises(ValueError, match=r"split takes three fractions .* Received: \(0.8, 0.2\)"):
        DatasetConfig(n_samples={"flame": 10}, split=(0.8, 0.2))
    with pytest.raises(ValueError, match=r"learning_rate must be > 0"):
        TrainConfig(learning_rate=0.0)
    with pytest.raises(ValueError, match=r"max_epochs must be >= 0"):
        TrainConfig(max_epochs={"flame": -1})
    assert TrainConfig(max_epochs={"flame": 0}).max_epochs == {"flame": 0}     # the closed-form start only
    assert main(["train", "--dataset", str(tmp_path / "d.h5"), "--experiment-config", "experiments/quick.toml",
                 "--out", str(tmp_path / "m"), "--time-budget-s", "-5"]) == 2
    assert "time_budget_s must be > 0 for each scene" in capsys.readouterr().err


def test_config_and_slopes_files_of_the_wrong_kind_are_refused_naming_them(tmp_path, capsys):
    """An experiment config given as a data config, n_samples that is not a table of counts, and a JSON without
    slopes given to dataset: refused in one line naming the file (they had ended in TypeError, AttributeError and
    KeyError tracebacks)."""
    bad = tmp_path / "bad.toml"
    bad.write_text('[dataset]\nn_samples = "many"\n')
    slopes = tmp_path / "s.json"
    slopes.write_text('{"a": 1}')
    for cfg, sl, text in (("experiments/quick.toml", str(slopes), "[dataset]: missing ['n_samples']"),
                          (str(bad), str(slopes), "n_samples must be a table of whole numbers"),
                          ("data_gen/quick.toml", str(slopes), "is not a slopes file")):
        assert main(["dataset", "--data-config", cfg, "--scene", "flame", "--slopes", sl,
                     "--out", str(tmp_path / "d.h5")]) == 2
        assert text in capsys.readouterr().err


def test_an_interrupted_retrain_leaves_no_record_of_the_old_run(flame_h5, trained, tmp_path, capsys, monkeypatch):
    """A retrain (another learning rate: from the start) killed in its start left the old run's train_info.json
    beside the new weights, and evaluate reported the old run's epochs and SSIM. The record goes when a run starts
    rewriting the folder: evaluate then asks for training."""
    import lf_flame.learn.training as T
    out = tmp_path / "model"
    shutil.copytree(trained, out)
    lr = tmp_path / "lr.toml"
    lr.write_text(Path(_experiment(lr, epochs=1)).read_text().replace("learning_rate = 1e-4", "learning_rate = 1e-2"))

    def killed(*args, **kw):
        raise KeyboardInterrupt
    monkeypatch.setattr(T, "_start", killed)
    assert main(["train", "--dataset", str(flame_h5), "--experiment-config", str(lr), "--out", str(out),
                 "--quiet"]) != 0
    assert "interrupted" in capsys.readouterr().err
    assert not (out / "train_info.json").exists()
    capsys.readouterr()
    assert main(["evaluate", "--dataset", str(flame_h5), "--model-dir", str(out), "--results", str(tmp_path)]) == 2
    assert "run 'lf-flame train' first" in capsys.readouterr().err


def test_evaluate_refuses_a_dataset_the_model_was_not_trained_on(flame_h5, trained, tmp_path, capsys):
    """A shapes model evaluated on flames wrote 'Table II (flame)', and a dataset re-rendered larger at the training
    one's path leaked training samples into its test split: evaluate checked only the camera. Another scene kind
    and another content digest are refused, naming them."""
    out = tmp_path / "model"
    shutil.copytree(trained, out)  # edited below: a copy of the shared model
    info = json.loads((out / "train_info.json").read_text())
    assert info["dataset_digest"] == info["start"]["dataset_digest"]
    for edit, text in ((dict(scene="shapes"), "holds flame scenes but the model"),
                       (dict(dataset_digest="0" * 64), "is not the dataset the model")):
        (out / "train_info.json").write_text(json.dumps(dict(info, **edit)))
        assert main(["evaluate", "--dataset", str(flame_h5), "--model-dir", str(out),
                     "--results", str(tmp_path / "res")]) == 2
        assert text in capsys.readouterr().err
        assert not (tmp_path / "res").exists()


def test_a_network_below_the_mean_image_is_said_to_be(tmp_path, capsys, monkeypatch):
    """Where the network scores below the mean image (a constant image) on a plane, evaluate's output and table
    say so in words, naming the plane and the scores; nothing had said it (a table of numbers only)."""
    from lf_flame.learn import evaluation as E
    rows = [dict(route=route, split="test", sample=i, depth_mm=dz, ssim=s, psnr_db=q)
            for i in range(2) for route in E.ROUTES for dz in E.PAPER_DEPTHS_MM
            for s, q in [(0.5 if route == "network" and dz == 20.0 else 0.9 if route == "network" else 0.6,
                          35.0 if route == "network" and dz == -10.0 else 40.0 if route == "network" else 38.0)]]
    table = E.summarise(pd.DataFrame(rows), "flame", "varied")
    info = dict(backbone_weights="random-init", train_config=dict(recipe="closed-form"), epochs_run=1,
                paper_epochs=1000, best_epoch=1, start_val_ssim=0.5, best_val_ssim=0.6, training_wall_time_s=1.0,
                provenance=dict(cpu_count=2))
    said = ("The network scores below the mean image (a constant image per plane) on the test split at +20 mm "
            "(SSIM 0.5000 < 0.6000); -10 mm (PSNR (dB) 35.00 < 38.00)")
    assert said in E.table_markdown(table, "flame", "varied", info)
    monkeypatch.setattr(E, "evaluate", lambda *args, **kw: table)
    assert main(["evaluate", "--dataset", "d.h5", "--model-dir", "m", "--results", str(tmp_path)]) == 0
    assert said in capsys.readouterr().out
    beaten = E.summarise(pd.DataFrame([dict(r, ssim=0.9, psnr_db=40.0) if r["route"] == "network" else r
                                       for r in rows]), "flame", "varied")
    assert E.below_the_mean_image(beaten) == [] and "below the mean image" not in E.table_markdown(
        beaten, "flame", "varied", info)


def test_config_values_that_fail_late_are_refused_at_load_naming_them(tmp_path, capsys):
    """Values that passed the config checks and failed late, or not at all: a split of 3 samples with an empty
    training split (dataset wrote it, train crashed leaving NaN files), a NaN fraction (min() with NaN first passed),
    a negative seed (failed after rendering, leaving a .partial), a dropout of NaN or 1.5 (refused by Keras only after
    the features were computed) and a negative refine_iterations (taken silently). Refused when the config is read,
    naming the key; nothing written."""
    from lf_flame.config import DatasetConfig, ModelConfig, TrainConfig
    for kw, text in ((dict(n_samples={"flame": 3}, split=(0.1, 0.1, 0.8)), "leaves an empty split (train, validation, "
                                                                             "test: 0, 1, 2)"),
                     (dict(n_samples={"flame": 10}, split=(float("nan"), 0.5, 0.5)), "split fractions must be"),
                     (dict(n_samples={"flame": 10}, seed=-5), "seed must be a whole number >= 0")):
        with pytest.raises(ValueError, match=re.escape(text)):
            DatasetConfig(**kw)
    assert DatasetConfig(n_samples={"flame": 3}).n_samples == {"flame": 3}    # 1 sample in each split
    for cls, kw, text in ((ModelConfig, dict(dropout=float("nan")), "dropout must be a fraction >= 0 and < 1"),
                          (ModelConfig, dict(dropout=1.5), "dropout must be a fraction"),
                          (TrainConfig, dict(refine_iterations={"flame": -3}), "refine_iterations must be a whole"),
                          (TrainConfig, dict(seed=-5), "seed must be a whole number >= 0")):
        with pytest.raises(ValueError, match=re.escape(text)):
            cls(**kw)
    data = tmp_path / "d.toml"
    data.write_text((ROOT / "data_gen/quick.toml").read_text().replace("flame = 40", "flame = 3")
                    .replace("split = [0.8, 0.1, 0.1]", "split = [0.1, 0.1, 0.8]"))
    (tmp_path / "slopes.json").write_text(json.dumps({"slopes": [2.28, 1.17, 0.0, -1.25]}))
    assert main(["dataset", "--data-config", str(data), "--scene", "flame", "--slopes", str(tmp_path / "slopes.json"),
                 "--out", str(tmp_path / "d.h5"), "--quiet"]) == 2
    assert "leaves an empty split" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.toml", "slopes.json"]


def test_a_truncated_training_record_is_refused_naming_it(trained, flame_h5, tmp_path, capsys):
    """A train_info.json cut short gave "error: Unterminated string ..." naming no file (evaluate, predict,
    tables): the message now names the file and says it is truncated or damaged."""
    out = tmp_path / "models" / "paper" / "flame"
    shutil.copytree(trained, out)
    path = out / "train_info.json"
    path.write_text(path.read_text()[:300])
    (tmp_path / "res" / "paper").mkdir(parents=True)
    (tmp_path / "res" / "paper" / "table_flame.md").write_text("| plane | SSIM |\n|---|---|\n| 1 | 0.9 |\n")
    for argv in (["evaluate", "--dataset", str(flame_h5), "--model-dir", str(out), "--results", str(tmp_path / "r")],
                 ["predict", f"{flame_h5}:0", "--model-dir", str(out), "--out", str(tmp_path / "p.npz")],
                 ["tables", "--results", str(tmp_path / "res"), "--data-dir", str(tmp_path / "data"),
                  "--model-dir", str(tmp_path / "models")]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert f"{path} is not a readable record of a training run (train it again): it is truncated or damaged" \
               in err, err


def test_tables_carry_each_tables_provenance(tmp_path, capsys):
    """tables.md names where each table came from (dataset digest and seed, camera, training seed, backbone
    weights, epochs, the evaluation's commit and versions; from eval_SCENE.json), and says so where the tables were
    evaluated at different commits or a table has no record: it carried none of it, so a 3-epoch model's table sat
    beside another run's stage times without a word."""
    res = tmp_path / "res"
    cam = json.dumps(dict(n_rows=48, n_cols=24, pixels_per_lenslet=15, focus_distance_mm=326.0))
    for regime, scene, commit in (("paper", "shapes", "aaaaaaa"), ("paper", "flame", "bbbbbbb"),
                                  ("varied", "flame", None)):
        (res / regime).mkdir(parents=True, exist_ok=True)
        (res / regime / f"table_{scene}.md").write_text("| plane | SSIM |\n|---|---|\n| 1 | 0.9 |\n")
        if commit:
            (res / regime / f"eval_{scene}.json").write_text(json.dumps(dict(
                train_info=dict(dataset=f"d/{scene}.h5", train_config=dict(seed=7), backbone_weights="random-init",
                                epochs_run=3, training_wall_time_s=8.0),
                dataset_seed=2025, dataset_attrs=dict(digest="0123456789abcdef", camera=cam,
                                                      dataset_config=json.dumps(dict(n_samples={scene: 12}))),
                provenance=dict(git_commit=commit, date="2026-11-29T00:00:00", versions={"lf_flame": "0.1.0"}))))
    assert main(["tables", "--results", str(res), "--data-dir", str(tmp_path / "data"), "--model-dir",
                 str(tmp_path / "models")]) == 0
    text = (res / "tables.md").read_text()
    assert "### Provenance" in text
    assert "| paper shapes | `d/shapes.h5` (0123456789ab) | 2025, 12 | 48 x 24 lenslets" in text
    assert "random-init | 3 (8 s) | aaaaaaa, 2026-11-29" in text
    assert "evaluated at different commits (aaaaaaa, bbbbbbb)" in text and "beside varied/table_flame.md" in text
