"""End-to-end: the quick preset's configs through the real CLI, as `make tables PRESET=quick` runs it."""
import json
from pathlib import Path

import pandas as pd
import pytest

from lf_flame.cli import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_quick_pipeline_end_to_end(tmp_path):
    dcfg, ecfg = str(ROOT / "data_gen/quick.toml"), str(ROOT / "experiments/quick.toml")
    data, models, res = tmp_path / "data", tmp_path / "models", tmp_path / "results"
    assert main(["slopes", "--data-config", dcfg, "--out", str(data / "slopes.json"), "--results", str(res)]) == 0
    slopes = pd.read_csv(res / "slopes.csv")
    assert (slopes.found_minus_analytic.abs() <= 0.05).all()
    for scene in ("shapes", "flame"):
        h5 = str(data / f"{scene}.h5")
        assert main(["dataset", "--data-config", dcfg, "--scene", scene, "--slopes", str(data / "slopes.json"),
                     "--out", h5, "--quiet"]) == 0
        assert main(["train", "--dataset", h5, "--experiment-config", ecfg, "--out", str(models / scene),
                     "--quiet"]) == 0
        assert main(["evaluate", "--dataset", h5, "--model-dir", str(models / scene), "--results", str(res)]) == 0
        info = json.loads((models / scene / "train_info.json").read_text())
        assert info["backbone_weights"] in ("imagenet", "random-init")
        hist = pd.read_csv(models / scene / "history.csv")
        assert {"loss", "val_loss", "val_ssim", "wall_time_s"} <= set(hist.columns) and len(hist) >= 1
        table = pd.read_csv(res / f"table_{scene}.csv")
        assert table[["ssim_mean", "psnr_db_mean"]].notna().all().all() and len(table) == 4
        assert (res / f"fig_{scene}.png").stat().st_size > 10_000
        assert len(pd.read_csv(res / f"learning_{scene}.csv")) == len(hist)
    # a second train call resumes from the saved state and runs no further epochs
    n_before = len(pd.read_csv(models / "flame" / "history.csv"))
    assert main(["train", "--dataset", str(data / "flame.h5"), "--experiment-config", ecfg,
                 "--out", str(models / "flame"), "--quiet"]) == 0
    assert len(pd.read_csv(models / "flame" / "history.csv")) == n_before
    assert main(["tables", "--results", str(res), "--data-dir", str(data), "--model-dir", str(models)]) == 0
    text = (res / "tables.md").read_text()
    assert "Table I" in text and "Table II" in text and ("random-init" in text or "imagenet" in text)


def test_cli_errors_are_clear(tmp_path, capsys):
    assert main(["evaluate", "--dataset", str(tmp_path / "none.h5"), "--model-dir", str(tmp_path),
                 "--results", str(tmp_path)]) == 2
    assert "not found" in capsys.readouterr().err
