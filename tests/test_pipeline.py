"""End-to-end: the quick preset's configs through the real CLI, as `make tables PRESET=quick` runs it."""
import json
import os
import re
from pathlib import Path

import pandas as pd
import pytest

from lf_flame.cli import main
from lf_flame.learn.model import NOTOP_FILE

ROOT = Path(__file__).resolve().parents[1]
#: training without a wall-time budget: a loaded machine must not change how many epochs run
NO_BUDGET = ("--time-budget-s", "1e9")
#: the quick preset's training, shortened for this test: one epoch (each writes both checkpoints,
#: 0.25 GB), and the closed-form start's L-BFGS refinement of the flames' Dense layer kept but
#: 5 iterations per plane (the shapes' start is the Gauss-Newton solve alone); the network still
#: beats the mean image by >= 0.019 SSIM per plane on the flames and >= 0.029 on the shapes
TEST_TRAIN = {"max_epochs": "{ shapes = 1, flame = 1 }", "refine_iterations": "{ shapes = 0, flame = 5 }"}


def _test_experiment_config(path) -> str:
    """``experiments/quick.toml`` with :data:`TEST_TRAIN`'s values in its ``[train]`` table."""
    text = (ROOT / "experiments/quick.toml").read_text()
    for key, value in TEST_TRAIN.items():
        text, n = re.subn(rf"^{key} = .*$", f"{key} = {value}", text, flags=re.M)
        assert n == 1, f"experiments/quick.toml has no single '{key} = ...' line"
    path.write_text(text)
    return str(path)


@pytest.mark.slow
# offline (CI), the backbone falls back to a saved random draw and says so; the test checks that record below
@pytest.mark.filterwarnings("ignore:ImageNet weights for ResNet-50 are not obtainable offline:RuntimeWarning")
def test_quick_pipeline_end_to_end(tmp_path):
    """The quick preset's configs, its training shortened (:data:`TEST_TRAIN`). Training runs
    without its wall-time budget (``--time-budget-s``), so a loaded machine cannot cut it
    short: every run trains the configured epoch, and the resumed run none."""
    dcfg, ecfg = str(ROOT / "data_gen/quick.toml"), _test_experiment_config(tmp_path / "experiment.toml")
    data, models, res = tmp_path / "data", tmp_path / "models", tmp_path / "results"
    assert main(["slopes", "--data-config", dcfg, "--out", str(data / "slopes.json"), "--results", str(res)]) == 0
    slopes = pd.read_csv(res / "slopes.csv")
    assert (slopes.found_minus_analytic.abs() <= 0.05).all()
    # the shapes on the paper regime, the flames on the varied one (as make lays them out)
    for regime, scene in (("paper", "shapes"), ("varied", "flame")):
        h5, m, r = str(data / regime / f"{scene}.h5"), models / regime / scene, res / regime
        assert main(["dataset", "--data-config", dcfg, "--regime", regime, "--scene", scene, "--slopes",
                     str(data / "slopes.json"), "--out", h5, "--quiet"]) == 0
        assert main(["train", "--dataset", h5, "--experiment-config", ecfg, "--out", str(m), "--quiet",
                     *NO_BUDGET]) == 0
        assert main(["evaluate", "--dataset", h5, "--model-dir", str(m), "--results", str(r), "--heldout", "4",
                     "--heldout-seed", "99"]) == 0
        info = json.loads((m / "train_info.json").read_text())
        # weights "auto": ImageNet's if Keras has (or could download) them, else a saved random draw
        label = _expected_backbone()
        assert info["backbone_weights"] == label
        assert (m / "backbone.weights.h5").is_file() == (label == "random-init")
        hist = pd.read_csv(m / "history.csv")
        assert {"loss", "val_loss", "val_ssim", "wall_time_s"} <= set(hist.columns)
        assert info["epochs_run"] == 1 and list(hist.epoch) == [0, 1]   # the start, then 1 epoch
        assert info["start"]["refine_iterations"] == [0 if scene == "shapes" else 5] * 4
        table = pd.read_csv(r / f"table_{scene}.csv")
        assert table[["ssim_mean", "psnr_db_mean"]].notna().all().all()
        assert set(table.route) == {"network", "mean image", "linear decoder (GAP-pooled)",
                                    "linear decoder (un-pooled)"}
        assert set(table.split) == {"test", "held-out 2"} and len(table) == 4 * 4 * 2
        assert json.loads((r / f"eval_{scene}.json").read_text())["heldout_seed"] == 99
        assert table.ssim_paper.notna().all() == (regime == "paper")
        assert (r / f"fig_{scene}.png").stat().st_size > 10_000
        assert len(pd.read_csv(r / f"learning_{scene}.csv")) == len(hist)
        _network_beats_the_mean_image(table)
    # a second train call resumes from the saved state and runs no further epochs
    flame = models / "varied" / "flame"
    n_before = len(pd.read_csv(flame / "history.csv"))
    assert main(["train", "--dataset", str(data / "varied" / "flame.h5"), "--experiment-config", ecfg,
                 "--out", str(flame), "--quiet", *NO_BUDGET]) == 0
    assert len(pd.read_csv(flame / "history.csv")) == n_before
    assert main(["tables", "--results", str(res), "--data-dir", str(data), "--model-dir", str(models)]) == 0
    text = (res / "tables.md").read_text()
    assert "Table I" in text and "Table II" in text and f"Backbone weights: **{_expected_backbone()}**" in text
    assert "mean image" in text and "linear GAP" in text


def _expected_backbone():
    """The label weights "auto" must give here: ImageNet's when the no-top file is in Keras's
    cache (put there by hand or by Keras's download), else "random-init"."""
    cache = Path(os.environ.get("KERAS_HOME", Path.home() / ".keras")) / "models" / NOTOP_FILE
    return "imagenet" if cache.is_file() else "random-init"


def _network_beats_the_mean_image(table):
    """The trained network against the mean image saved beside it, per plane, on the samples
    that chose nothing (the test split and the second held-out set), by a margin: fails for
    an untrained network and for one that predicts the mean image."""
    for split in ("test", "held-out 2"):
        t = table[table.split == split].pivot(index="depth_mm", columns="route", values="ssim_mean")
        margin = t["network"] - t["mean image"]
        assert (margin > 0.01).all(), f"{split}: network - mean image SSIM per plane {margin.round(4).tolist()}"


def test_cli_errors_are_clear(tmp_path, capsys):
    assert main(["evaluate", "--dataset", str(tmp_path / "none.h5"), "--model-dir", str(tmp_path),
                 "--results", str(tmp_path)]) == 2
    assert "not found" in capsys.readouterr().err
