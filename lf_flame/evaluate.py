"""Evaluation: SSIM/PSNR per depth plane on the test split, Tables I and II beside the
paper's values, and figures like the paper's Figs. 7 and 8. One place for evaluation.
"""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from .config import atomic_write_text, provenance  # noqa: E402
from .dataset import LightFieldDataset  # noqa: E402
from .metrics import psnr_per_plane, ssim_per_plane  # noqa: E402
from .scenes import PAPER_DEPTHS_MM, SHAPE_AT_DEPTH  # noqa: E402

#: The paper's Table I (shapes) and Table II (flames), per depth +20, +10, 0, −10 mm.
#: Table II's last column is printed "-20 mm"; the scene has no such plane (SPEC.md).
PAPER_TABLES = {
    "shapes": {"ssim": (0.96, 0.96, 0.97, 0.96), "psnr": (45.05, 43.73, 45.31, 47.87)},
    "flame": {"ssim": (0.91, 0.94, 0.96, 0.95), "psnr": (41.64, 39.416, 40.06, 41.87)},
}
PAPER_SLOPES = dict(zip(SHAPE_AT_DEPTH, (2.10, 1.15, 0.00, -1.25)))
TABLE_NAMES = {"shapes": "Table I (multi-shape)", "flame": "Table II (flame)"}


def evaluate(dataset_path, model_dir, results_dir) -> pd.DataFrame:
    """Score the trained decoder on the test split and write the table and figure.

    Writes ``metrics_<scene>.csv`` (per test sample and plane), ``table_<scene>.csv``
    and ``.md`` (mean ± sd per plane beside the paper), ``fig_<scene>.png``.

    Returns
    -------
    DataFrame of the table.
    """
    from .train import load_decoder, predict_features

    ds = LightFieldDataset(dataset_path)
    model_dir, results_dir = Path(model_dir), Path(results_dir)
    dec, info = load_decoder(model_dir)
    if info["dataset_camera"] != ds.attrs["camera"]:
        raise ValueError(f"{dataset_path} was rendered with another camera than the model in {model_dir} "
                         "was trained on")
    test = np.sort(ds.splits["test"])
    pred = predict_features(dec, info["feature_cache"], test)
    rows = []
    for i, p in zip(test, pred):
        gt = ds.gt(int(i))
        for k, (s, q) in enumerate(zip(ssim_per_plane(gt, p), psnr_per_plane(gt, p))):
            rows.append(dict(sample=int(i), depth_mm=PAPER_DEPTHS_MM[k], ssim=s, psnr_db=q))
    per = pd.DataFrame(rows)
    results_dir.mkdir(parents=True, exist_ok=True)
    per.to_csv(results_dir / f"metrics_{ds.scene}.csv", index=False)
    g = per.groupby("depth_mm", sort=False)
    paper = PAPER_TABLES[ds.scene]
    table = pd.DataFrame({
        "depth_mm": PAPER_DEPTHS_MM,
        "object": list(SHAPE_AT_DEPTH) if ds.scene == "shapes" else ["flame"] * 4,
        "ssim_mean": g["ssim"].mean().values, "ssim_sd": g["ssim"].std().values, "ssim_paper": paper["ssim"],
        "psnr_db_mean": g["psnr_db"].mean().values, "psnr_db_sd": g["psnr_db"].std().values,
        "psnr_db_paper": paper["psnr"],
        "n_test": g.size().values,
    })
    table.to_csv(results_dir / f"table_{ds.scene}.csv", index=False)
    md = table_markdown(table, ds.scene, info)
    atomic_write_text(results_dir / f"table_{ds.scene}.md", md)
    figure(ds, test[0], pred[0], results_dir / f"fig_{ds.scene}.png")
    learning_curves(model_dir / "history.csv", results_dir, ds.scene)
    atomic_write_text(results_dir / f"eval_{ds.scene}.json", json.dumps(
        dict(train_info=info, n_test=len(test), dataset_attrs={k: str(v) for k, v in ds.attrs.items()},
             provenance=provenance()), indent=2))
    return table


def table_markdown(table: pd.DataFrame, scene: str, info: dict) -> str:
    """Markdown of a table with ours (mean ± sd over the test split) beside the paper."""
    lines = [f"### {TABLE_NAMES[scene]}: ours vs paper", "",
             "| depth (mm) | object | SSIM ours | SSIM paper | PSNR ours (dB) | PSNR paper (dB) |",
             "|---:|---|---:|---:|---:|---:|"]
    for r in table.itertuples():
        lines.append(f"| {r.depth_mm:+.0f} | {r.object} | {r.ssim_mean:.3f} ± {r.ssim_sd:.3f} | {r.ssim_paper:.2f} "
                     f"| {r.psnr_db_mean:.2f} ± {r.psnr_db_sd:.2f} | {r.psnr_db_paper:.2f} |")
    lines += ["", f"Test samples: {int(table.n_test.iloc[0])}; backbone weights: **{info['backbone_weights']}**; "
              f"epochs run: {info['epochs_run']} (paper: {info['paper_epochs']}), best epoch {info['best_epoch']}; "
              f"training wall time {info['training_wall_time_s']:.0f} s on "
              f"{info['provenance']['cpu_count']} CPU cores.", ""]
    return "\n".join(lines)


def figure(ds: LightFieldDataset, index: int, pred: np.ndarray, path) -> None:
    """Raw light field, ground truth and prediction per plane (like the paper's Figs. 7/8)."""
    gt = ds.gt(int(index))
    raw = ds.raw(int(index))
    fig, ax = plt.subplots(2, 5, figsize=(11, 5.4), gridspec_kw=dict(width_ratios=[1.3, 1, 1, 1, 1]))
    ax[0, 0].imshow(raw, cmap="gray", vmin=0, vmax=1)
    ax[0, 0].set_title("raw light field")
    n = ds.camera.pixels_per_lenslet
    r0, c0 = raw.shape[0] // 2 - 3 * n, raw.shape[1] // 2 - 3 * n
    ax[1, 0].imshow(raw[r0:r0 + 6 * n, c0:c0 + 6 * n], cmap="gray", vmin=0, vmax=1)
    ax[1, 0].set_title("raw, 6×6 lenslets")
    for k, dz in enumerate(PAPER_DEPTHS_MM):
        ax[0, k + 1].imshow(gt[k], cmap="gray", vmin=0, vmax=1)
        ax[0, k + 1].set_title(f"ground truth {dz:+.0f} mm")
        ax[1, k + 1].imshow(pred[k], cmap="gray", vmin=0, vmax=1)
        s = ssim_per_plane(gt[k:k + 1], pred[k:k + 1])[0]
        ax[1, k + 1].set_title(f"model, SSIM {s:.3f}")
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    fig.suptitle(f"{ds.scene}: test sample {index}")
    fig.tight_layout()
    tmp = Path(str(path) + ".partial.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    tmp.replace(path)


def learning_curves(history_csv, results_dir, scene: str) -> None:
    """Copy the training history to ``results_dir`` and plot loss and validation SSIM
    against epoch and wall time (``learning_<scene>.csv`` / ``.png``)."""
    h = pd.read_csv(history_csv)
    h.to_csv(Path(results_dir) / f"learning_{scene}.csv", index=False)
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.6))
    for a, x, label in ((ax[0], h["epoch"] + 1, "epoch"), (ax[1], h["wall_time_s"] / 60, "wall time (min)")):
        a.semilogy(x, h["loss"], label="train MSE")
        a.semilogy(x, h["val_loss"], label="validation MSE")
        a.set_xlabel(label)
        a.set_ylabel("MSE")
        b = a.twinx()
        b.plot(x, h["val_ssim"], "g.-", label="validation SSIM")
        b.set_ylabel("SSIM")
        a.legend(loc="upper center", fontsize=8)
        b.legend(loc="center right", fontsize=8)
    fig.suptitle(f"{scene}: learning curves")
    fig.tight_layout()
    fig.savefig(Path(results_dir) / f"learning_{scene}.png", dpi=100)
    plt.close(fig)


def write_slopes(camera, slopes, searches, objects, results_dir) -> pd.DataFrame:
    """Write the slope search results beside the paper's and the analytic slopes, with a plot."""
    results_dir = Path(results_dir)
    results_dir.mkdir(parents=True, exist_ok=True)
    df = pd.DataFrame({
        "object": [o["name"] for o in objects],
        "depth_mm": [o["depth_offset_mm"] for o in objects],
        "slope_found": np.round(slopes, 4),
        "slope_analytic": [round(camera.slope_for_depth(o["depth_offset_mm"]), 4) for o in objects],
        "slope_paper": [PAPER_SLOPES[o["name"]] for o in objects],
    })
    df["found_minus_analytic"] = (df.slope_found - df.slope_analytic).round(4)
    df.to_csv(results_dir / "slopes.csv", index=False)
    plot_slope_curves([f"{o['name']} ({o['depth_offset_mm']:+.0f} mm)" for o in objects], searches,
                      results_dir / "slopes.png")
    return df


def plot_slope_curves(labels, searches, path, metric: str = "tenengrad") -> None:
    """Plot each object's sharpness against slope (normalised to its peak) into ``path`` (PNG)."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for label, s in zip(labels, searches):
        peak = s.scores.max()
        ax.plot(s.slopes, s.scores / peak if peak > 0 else s.scores, label=f"{label}: {s.slope:.3f}")
    ax.set_xlabel("slope (lenslets per view)")
    ax.set_ylabel(f"sharpness ({metric}, normalised)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def read_gnu_time(path) -> dict:
    """Wall time (s) and peak resident memory (GiB) from a ``/usr/bin/time -v`` report.

    Raises
    ------
    ValueError
        The file lacks either line (not a GNU time ``-v`` report).
    """
    text = Path(path).read_text()
    out = {}
    for line in text.splitlines():
        key, _, val = line.strip().rpartition(": ")
        if key == "Maximum resident set size (kbytes)":
            out["peak_rss_gib"] = int(val) / 2**20
        elif key.startswith("Elapsed (wall clock) time"):
            parts = [float(v) for v in val.split(":")]
            out["wall_s"] = sum(v * 60 ** k for k, v in enumerate(reversed(parts)))
    if len(out) != 2:
        raise ValueError(f"{path} is not a '/usr/bin/time -v' report")
    return out


def write_tables(results_dir, stage_times: dict | None = None, make_targets: dict | None = None) -> str:
    """Collect both tables, slopes, stage wall times and, per make target, wall time and
    peak memory (:func:`read_gnu_time`) into ``tables.md``; return its text."""
    results_dir = Path(results_dir)
    parts = ["# Results", ""]
    for scene in ("shapes", "flame"):
        p = results_dir / f"table_{scene}.md"
        if p.exists():
            parts += [p.read_text(), f"![{scene}](fig_{scene}.png)", f"![{scene} learning](learning_{scene}.png)", ""]
    sp = results_dir / "slopes.csv"
    if sp.exists():
        parts += ["### Sharpest slopes (slope search on the nominal scene)", "",
                  pd.read_csv(sp).to_markdown(index=False), ""]
    if stage_times:
        parts += ["### Wall time per stage", "", "| stage | seconds |", "|---|---:|"]
        parts += [f"| {k} | {v:.0f} |" for k, v in stage_times.items()] + [""]
    if make_targets:
        parts += ["### Training targets, measured with `/usr/bin/time -v`", "",
                  "| make target | wall time (min) | peak memory (GiB) |", "|---|---:|---:|"]
        parts += [f"| {k} | {v['wall_s'] / 60:.1f} | {v['peak_rss_gib']:.2f} |" for k, v in make_targets.items()]
        parts += [""]
    text = "\n".join(parts)
    atomic_write_text(results_dir / "tables.md", text)
    return text
