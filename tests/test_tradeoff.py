"""`make tradeoff PRESET=quick`: the speed-accuracy map of the real pipeline at tiny sizes."""
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("make") is None or not (ROOT / ".venv/bin/lf-flame").exists(),
                    reason="needs make and the project's .venv (make install)")
def test_make_tradeoff_quick():
    # 3 timed calls per route instead of 20: the latency columns are still a median and a 10-90 % spread
    r = subprocess.run(["make", "tradeoff", "PRESET=quick", "REPEATS=3"], cwd=ROOT, capture_output=True, text=True,
                       timeout=1200)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    out = ROOT / "results/quick"
    df = pd.read_csv(out / "tradeoff.csv")
    assert {"refocusing", "simulator: rays per pixel", "simulator: effects", "slope search",
            "training"} <= set(df.section)
    ref = df[df.section == "refocusing"]
    routes = set(zip(ref.route, ref.setting.str.split(",").str[0]))
    assert {("shift-sum", "nearest (whole lenslets)"), ("shift-sum", "bilinear"),
            ("Fourier slice", "4-D FFT + 4 slices")} <= routes
    assert len(ref[ref.route == "model"].setting.str.split(",").str[0].unique()) >= 2  # two input sizes
    cols = ["latency_ms_median", "latency_ms_p10", "latency_ms_p90", "ssim_mean", "psnr_db_mean"]
    assert np.isfinite(ref[cols].values).all() and (ref.latency_ms_p10 <= ref.latency_ms_p90).all()
    # every route's flame-height error in mm, from lf_flame.measure.diagnostics against the scenes' truth
    hcols = [c for c in ref.columns if c.startswith("height_err_mm_")]
    assert len(hcols) == 7 and ref.height_failed.notna().all()     # 4 planes, mean, p90, worst
    assert (ref.height_share_over_1mm.between(0, 1) & (ref.height_err_mm_p90 <= ref.height_err_mm_max)).all()
    measured = ref[ref.height_failed == 0]
    assert np.isfinite(measured[hcols].values).all() and (measured[hcols].values >= 0).all()
    classical = ref[ref.route.isin(["shift-sum", "Fourier slice"])]
    assert (classical.height_failed == 0).all() and (classical.height_err_mm_mean < 1.0).all()
    assert "height error" in (out / "tradeoff.md").read_text()
    # the reference is bilinear shift-and-sum of a cleaner render: that route must score best
    assert ref.loc[ref.ssim_mean.idxmax(), "setting"] == "bilinear"
    sim = df[df.section == "simulator: rays per pixel"]
    for _, g in sim.groupby("route"):
        assert g.sort_values("rays_per_pixel").image_rmse.is_monotonic_decreasing
    for png in ("tradeoff_pareto.png", "tradeoff_knobs.png"):
        assert (out / png).stat().st_size > 10_000
    meta = json.loads((out / "tradeoff.json").read_text())
    assert meta["repeats"] == 3
    assert {"versions", "cpu_count", "date", "numba_threads", "omp_wait_policy",
            "malloc_tuned"} <= set(meta["provenance"])
    assert "Pareto front" in (out / "tradeoff.md").read_text()


def test_plot_only_redraws_the_figures_from_the_committed_csv(tmp_path):
    """``--plot-only`` measures nothing: it reads ``<out>/tradeoff.csv`` and writes the PNGs only
    (the reconstruction's, from the rows of ``make reconstruct``'s curves, and the emission routes', from
    ``make train-reconstructor``'s, among them)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("tradeoff_script", ROOT / "experiments" / "tradeoff.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    shutil.copy(ROOT / "results" / "tradeoff.csv", tmp_path / "tradeoff.csv")
    assert mod.main(["--plot-only", "--out", str(tmp_path)]) == 0
    pngs = ["tradeoff_emission.png", "tradeoff_knobs.png", "tradeoff_pareto.png", "tradeoff_reconstruct.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tradeoff.csv"] + pngs
    for png in pngs:
        assert (tmp_path / png).stat().st_size > 10_000


def test_reconstruction_only_brings_the_depth_and_volume_routes(tmp_path):
    """``--reconstruction-only`` measures nothing: it takes the depth and volume routes' time and error from
    ``make depth``'s and ``make volume``'s files beside ``tradeoff.csv`` (here the committed ones)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("tradeoff_script", ROOT / "experiments" / "tradeoff.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for name in ("tradeoff.csv", "tradeoff.json", "reconstruct_iters.csv", "depth.csv", "volume.csv",
                 "volume_nonaxi.csv"):
        shutil.copy(ROOT / "results" / name, tmp_path / name)
    assert mod.main(["--reconstruction-only", "--out", str(tmp_path)]) == 0
    df = pd.read_csv(tmp_path / "tradeoff.csv")
    depth = pd.read_csv(tmp_path / "depth.csv")
    dv = df[df.section == "depth"].set_index(["route", "noise"])
    auto = depth[(depth.kind == "random") & (depth.route == "auto") & (depth.noise == "clean")]
    assert dv.loc[("auto", "noise-free"), "error_median"] == pytest.approx(auto.rel_err.median())
    assert dv.loc[("auto", "noise-free"), "latency_ms_median"] == pytest.approx(
        1e3 * auto.groupby("seed").time_s.first().median())
    vol = df[df.section == "volume"]
    assert set(vol[vol.scene == "volume"].route) == set(pd.read_csv(tmp_path / "volume.csv").route)
    assert (vol.error_median > 0).all() and (vol.centroid_mm_mean > 0).all()
    nonaxi = pd.read_csv(tmp_path / "volume_nonaxi.csv")
    scored = nonaxi[nonaxi.split == "test"]
    assert (vol.scene == "volume_nonaxi").sum() == scored.groupby(["route", "noise"]).ngroups
    assert vol[vol.scene == "volume_nonaxi"].n_samples.sum() == len(scored)     # the validation volumes left out
    assert "## Flames at unknown depths and volumes" in (tmp_path / "tradeoff.md").read_text()
