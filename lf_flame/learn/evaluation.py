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

from ..config import atomic_write_text, provenance, read_json  # noqa: E402
from .dataset import LightFieldDataset  # noqa: E402
from ..measure.metrics import psnr_per_plane, ssim_per_plane  # noqa: E402
from ..simulate.scenes import PAPER_DEPTHS_MM, SHAPE_AT_DEPTH  # noqa: E402

#: The paper's Table I (shapes) and Table II (flames), per depth +20, +10, 0, −10 mm.
#: Table II's last column is printed "-20 mm"; the scene has no such plane (SPEC.md).
PAPER_TABLES = {
    "shapes": {"ssim": (0.96, 0.96, 0.97, 0.96), "psnr": (45.05, 43.73, 45.31, 47.87)},
    "flame": {"ssim": (0.91, 0.94, 0.96, 0.95), "psnr": (41.64, 39.416, 40.06, 41.87)},
}
PAPER_SLOPES = dict(zip(SHAPE_AT_DEPTH, (2.10, 1.15, 0.00, -1.25)))
TABLE_NAMES = {"shapes": "Table I (multi-shape)", "flame": "Table II (flame)"}


#: Routes scored beside each other, in table order; the network is the paper's model.
ROUTES = ("network", "mean image", "linear decoder (GAP-pooled)", "linear decoder (un-pooled)")
_SHORT = {"network": "network", "mean image": "mean image", "linear decoder (GAP-pooled)": "linear GAP",
          "linear decoder (un-pooled)": "linear un-pooled"}


def score(gt: np.ndarray, pred: np.ndarray, **labels) -> list[dict]:
    """SSIM and PSNR of every plane of every sample: the one scoring function of every route.

    Parameters
    ----------
    gt, pred : ndarray of shape (n, 4, R, C), values in [0, 1]
        Ground truth and prediction (clipped to [0, 1] here, as an image would be).
    **labels
        Columns added to every row (route, split, ...); ``sample`` may be a list of n ids.

    Returns
    -------
    list of dict rows: labels, sample, depth_mm, ssim, psnr_db.
    """
    samples = labels.pop("sample", range(len(gt)))
    rows = []
    for i, g, p in zip(samples, gt, pred):
        p = np.clip(p, 0.0, 1.0)
        for k, (s, q) in enumerate(zip(ssim_per_plane(g, p), psnr_per_plane(g, p))):
            rows.append(dict(labels, sample=int(i), depth_mm=PAPER_DEPTHS_MM[k], ssim=s, psnr_db=q))
    return rows


def route_predictions(baselines: dict, features: np.ndarray, decoder) -> dict:
    """Each route's planes (n, 4, R, C) for backbone features (n, h, w, 2048): the network
    and the yardsticks of :func:`lf_flame.learn.baselines.load_baselines`."""
    x = np.asarray(features, np.float32)
    out = {"network": np.transpose(np.asarray(decoder.predict_on_batch(x)), (0, 3, 1, 2))}
    out.update({route: base.predict(x) for route, base in baselines.items()})
    return out


#: Name of the second held-out set's split in tables and metrics.
HELDOUT2 = "held-out 2"


def _backbone_features(full_model, raw, indices, batch: int = 4) -> np.ndarray:
    """The backbone features of the raw images ``raw(idx)`` (a function of a list of indices -> (k, H, W)) through
    a saved full model's frozen feature extractor, ``batch`` at a time: (len(indices), h, w, 2048)."""
    fx = full_model.get_layer("feature_extractor")
    idx = list(indices)
    return np.concatenate([np.asarray(fx.predict_on_batch(np.asarray(raw(idx[s:s + batch]))[..., None]))
                           for s in range(0, len(idx), batch)])


def evaluate(dataset_path, model_dir, results_dir, n_heldout: int = 0, heldout_seed: int | None = None) -> pd.DataFrame:
    """Score the network and its yardsticks per plane on the test split and on a second
    held-out set.

    Routes (:data:`ROUTES`): the trained network, the training split's mean image, and the
    GAP-pooled and un-pooled linear decoders, all from the same frozen backbone features
    and scored by :func:`score`. The second held-out set (split :data:`HELDOUT2`) is
    ``n_heldout`` samples drawn and rendered like the dataset's, but from the stream of
    ``heldout_seed``, which neither the dataset nor any choice made on its validation
    split used (:meth:`LightFieldDataset.heldout_sample`); its seed is written into the
    table and ``eval_<scene>.json``.

    Writes ``metrics_<scene>.csv`` (per route, split, sample and plane), ``table_<scene>.csv``
    and ``.md`` (mean ± sd per route and plane; the paper's values on the paper regime),
    ``fig_<scene>.png``, ``learning_<scene>.{csv,png}`` and ``eval_<scene>.json``.

    Returns
    -------
    DataFrame of the table (one row per split, route and depth).

    Raises
    ------
    ValueError
        The dataset is not the one the model was trained on (another camera, scene kind or content digest), or
        ``n_heldout`` without a ``heldout_seed`` (or with the dataset's own seed).
    """
    from .baselines import load_baselines
    from .features import cache_mismatch
    from .model_files import load_decoder, load_full_model

    ds = LightFieldDataset(dataset_path)
    model_dir, results_dir = Path(model_dir), Path(results_dir)
    dec, info = load_decoder(model_dir)
    if info["dataset_camera"] != ds.attrs["camera"]:
        raise ValueError(f"{dataset_path} was rendered with another camera than the model in {model_dir} "
                         "was trained on")
    if info.get("scene", ds.scene) != ds.scene:
        raise ValueError(f"{dataset_path} holds {ds.scene} scenes but the model in {model_dir} was trained on "
                         f"{info['scene']} scenes: evaluate it on its own kind of dataset")
    trained_on = info.get("dataset_digest") or info.get("start", {}).get("dataset_digest")
    if trained_on is not None and trained_on != ds.digest:
        raise ValueError(f"{dataset_path} is not the dataset the model in {model_dir} was trained on (digest "
                         f"{ds.digest[:12]} here, {trained_on[:12]} at training; re-rendered or another): its test "
                         "split may hold training samples; evaluate on the training dataset, or train on this one")
    baselines = load_baselines(model_dir)
    test = np.sort(ds.splits["test"])
    why = cache_mismatch(info["feature_cache"], ds.digest, info["train_config"]["seed"], info["backbone_weights"],
                         ds.n, info.get("backend"))
    if why is None:
        import h5py
        with h5py.File(info["feature_cache"], "r") as f:
            feats = f["features"][test]
    else:       # a cache another run overwrote (or deleted): this dataset through the model's own backbone
        print(f"{why}: the test split's features computed with the backbone saved in {model_dir}")
        feats = _backbone_features(load_full_model(model_dir)[0], ds.raw, test)
    preds = route_predictions(baselines, feats, dec)
    gt_test = ds.gt(test)
    rows = []
    for route in ROUTES:
        rows += score(gt_test, preds[route], route=route, split="test", sample=test)
    if n_heldout:
        if heldout_seed is None:
            raise ValueError("a second held-out set needs its own seed (heldout_seed)")
        raws, gts = zip(*(ds.heldout_sample(j, heldout_seed) for j in range(n_heldout)))
        feats = _backbone_features(load_full_model(model_dir)[0], lambda idx: np.stack([raws[i] for i in idx]),
                                   np.arange(n_heldout))
        held = route_predictions(baselines, feats, dec)
        for route in ROUTES:
            rows += score(np.stack(gts), held[route], route=route, split=HELDOUT2, sample=np.arange(n_heldout))
    per = pd.DataFrame(rows)
    results_dir.mkdir(parents=True, exist_ok=True)
    per.to_csv(results_dir / f"metrics_{ds.scene}.csv", index=False)
    table = summarise(per, ds.scene, ds.config.regime)
    table.to_csv(results_dir / f"table_{ds.scene}.csv", index=False)
    atomic_write_text(results_dir / f"table_{ds.scene}.md",
                      table_markdown(table, ds.scene, ds.config.regime, info, heldout_seed))
    figure(ds, test[0], preds, results_dir / f"fig_{ds.scene}.png")
    learning_curves(model_dir / "history.csv", results_dir, ds.scene, info.get("baselines", {}))
    atomic_write_text(results_dir / f"eval_{ds.scene}.json", json.dumps(
        dict(train_info=info, n_test=len(test), n_heldout=n_heldout, heldout_seed=heldout_seed,
             dataset_seed=ds.config.seed, dataset_attrs={k: str(v) for k, v in ds.attrs.items()},
             provenance=provenance()), indent=2))
    return table


def summarise(per: pd.DataFrame, scene: str, regime: str) -> pd.DataFrame:
    """Mean and sd per split, route and plane of :func:`score` rows, with the paper's values
    on the paper regime (NaN on the varied one: the paper has no such table)."""
    g = per.groupby(["split", "route", "depth_mm"], sort=False)
    table = g.agg(ssim_mean=("ssim", "mean"), ssim_sd=("ssim", "std"), psnr_db_mean=("psnr_db", "mean"),
                  psnr_db_sd=("psnr_db", "std"), n=("ssim", "size")).reset_index()
    objects = dict(zip(PAPER_DEPTHS_MM, SHAPE_AT_DEPTH if scene == "shapes" else ["flame"] * 4))
    table.insert(3, "object", table.depth_mm.map(objects))
    paper = PAPER_TABLES[scene]
    on_paper = regime == "paper"
    table["ssim_paper"] = table.depth_mm.map(dict(zip(PAPER_DEPTHS_MM, paper["ssim"]))) if on_paper else np.nan
    table["psnr_db_paper"] = table.depth_mm.map(dict(zip(PAPER_DEPTHS_MM, paper["psnr"]))) if on_paper else np.nan
    table.insert(0, "regime", regime)
    return table


def below_the_mean_image(table: pd.DataFrame) -> list[str]:
    """One sentence per split of :func:`summarise`'s table naming the planes where the network's mean SSIM or PSNR
    is below the mean image's (the training split's mean, one constant image per plane): there it does worse than
    an image that ignores the light field. Empty where it beats it on every plane (or a route is missing)."""
    out = []
    for split in table.split.unique():
        t = table[table.split == split]
        net, mean = (t[t.route == r].set_index("depth_mm") for r in ("network", "mean image"))
        worse = []
        for dz in net.index.intersection(mean.index):
            what = [f"{unit} {net.loc[dz, col]:.{d}f} < {mean.loc[dz, col]:.{d}f}"
                    for col, unit, d in (("ssim_mean", "SSIM", 4), ("psnr_db_mean", "PSNR (dB)", 2))
                    if net.loc[dz, col] < mean.loc[dz, col]]
            if what:
                worse.append(f"{dz:+.0f} mm ({', '.join(what)})")
        if worse:
            out.append(f"The network scores below the mean image (a constant image per plane) on the {split} split at "
                       + "; ".join(worse) + ": on " + ("this plane" if len(worse) == 1 else "these planes")
                       + " it does worse than an image that ignores the light field.")
    return out


def table_markdown(table: pd.DataFrame, scene: str, regime: str, info: dict, heldout_seed: int | None = None) -> str:
    """Markdown: per split, SSIM and PSNR of every route per plane (mean ± sd), and the paper's; where the network
    scores below the mean image, a sentence saying so (:func:`below_the_mean_image`)."""
    on_paper = regime == "paper"
    routes = [r for r in ROUTES if r in set(table.route)]
    head = [_SHORT[r] for r in routes] + (["paper"] if on_paper else [])
    lines = [f"### {TABLE_NAMES[scene]}, {regime} regime" + (": ours vs paper" if on_paper else ""), ""]
    for split in table.split.unique():
        t = table[table.split == split]
        n = int(t.n.iloc[0])
        for metric, unit, fmt in (("ssim", "SSIM", "{:.3f}"), ("psnr_db", "PSNR (dB)", "{:.2f}")):
            lines += [f"{unit}, {split} split ({n} samples)" if split == "test" else
                      f"{unit}, second held-out set: {n} samples drawn with seed {heldout_seed} "
                      "(not the dataset's; never used in training or selection)", "",
                      "| depth (mm) | object | " + " | ".join(head) + " |",
                      "|---:|---|" + "---:|" * len(head)]
            for dz in PAPER_DEPTHS_MM:
                rr = t[t.depth_mm == dz].set_index("route")
                cells = [(fmt + " ± " + fmt).format(rr.loc[r, f"{metric}_mean"], rr.loc[r, f"{metric}_sd"])
                         for r in routes]
                if on_paper:
                    cells.append(fmt.format(rr[f"{metric}_paper"].iloc[0]))
                lines.append(f"| {dz:+.0f} | {rr.object.iloc[0]} | " + " | ".join(cells) + " |")
            lines.append("")
    lines += [f"Backbone weights: **{info['backbone_weights']}**; recipe {info['train_config']['recipe']}; "
              f"epochs run: {info['epochs_run']} (paper: {info['paper_epochs']}), best epoch {info['best_epoch']} "
              f"(validation SSIM {info['start_val_ssim']:.4f} at the start, {info['best_val_ssim']:.4f} at best); "
              f"training wall time {info['training_wall_time_s']:.0f} s on {info['provenance']['cpu_count']} "
              "CPU cores.", ""]
    lines += [f"**{line}**\n" for line in below_the_mean_image(table)]
    return "\n".join(lines)


def figure(ds: LightFieldDataset, index: int, preds: dict, path) -> None:
    """Raw light field, ground truth and each route's planes for one test sample (like the
    paper's Figs. 7/8). ``preds``: route -> (n_test, 4, R, C), the sample being the first."""
    gt = ds.gt(int(index))
    raw = ds.raw(int(index))
    routes = [r for r in ROUTES if r in preds]
    fig, ax = plt.subplots(1 + len(routes), 5, figsize=(11, 2.7 * (1 + len(routes))),
                           gridspec_kw=dict(width_ratios=[1.3, 1, 1, 1, 1]), squeeze=False)
    ax[0, 0].imshow(raw, cmap="gray", vmin=0, vmax=1)
    ax[0, 0].set_title("raw light field")
    n = ds.camera.pixels_per_lenslet
    lenslets = raw[:raw.shape[0] // n * n, :raw.shape[1] // n * n].reshape(raw.shape[0] // n, n, -1, n).sum(axis=(1, 3))
    r, c = np.unravel_index(np.argmax(lenslets), lenslets.shape)  # 6×6 lenslets about the brightest
    r0 = int(np.clip(r - 3, 0, lenslets.shape[0] - 6)) * n
    c0 = int(np.clip(c - 3, 0, lenslets.shape[1] - 6)) * n
    ax[1, 0].imshow(raw[r0:r0 + 6 * n, c0:c0 + 6 * n], cmap="gray", vmin=0, vmax=1)
    ax[1, 0].set_title("raw, 6×6 lenslets (brightest)", fontsize=9)
    for k, dz in enumerate(PAPER_DEPTHS_MM):
        ax[0, k + 1].imshow(gt[k], cmap="gray", vmin=0, vmax=1)
        ax[0, k + 1].set_title(f"ground truth {dz:+.0f} mm", fontsize=9)
        for j, route in enumerate(routes, start=1):
            p = np.clip(preds[route][0, k], 0, 1)
            ax[j, k + 1].imshow(p, cmap="gray", vmin=0, vmax=1)
            ax[j, k + 1].set_title(f"{_SHORT[route]}, SSIM {ssim_per_plane(gt[k:k + 1], p[None])[0]:.3f}", fontsize=8)
    for a in ax.ravel():
        a.set_xticks([])
        a.set_yticks([])
    for a in ax[2:, 0]:
        a.set_visible(False)
    fig.suptitle(f"{ds.scene} ({ds.config.regime} regime): test sample {index}")
    fig.tight_layout()
    tmp = Path(str(path) + ".partial.png")
    fig.savefig(tmp, dpi=90)
    plt.close(fig)
    tmp.replace(path)


def learning_curves(history_csv, results_dir, scene: str, baselines: dict | None = None) -> None:
    """Copy the training history to ``results_dir`` (``learning_<scene>.csv``) and plot it
    against the epoch (``learning_<scene>.png``; epoch 0 is the start): MSE (training, with
    dropout during the epochs and without at the start; validation), validation SSIM with
    each yardstick's (mean of the planes) as a labelled line, and validation PSNR."""
    from matplotlib.ticker import MaxNLocator
    h = pd.read_csv(history_csv)
    h.to_csv(Path(results_dir) / f"learning_{scene}.csv", index=False)
    panels = [("MSE", ("loss", "training MSE (epochs: with dropout)"), ("val_loss", "validation MSE")),
              ("validation SSIM", ("val_ssim", "network"),), ("validation PSNR (dB)", ("val_psnr_db", "network"),)]
    panels = [p for p in panels if all(c in h for c, _ in p[1:])]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.9), squeeze=False)
    for ax, (ylabel, *curves) in zip(axes[0], panels):
        for k, (col, label) in enumerate(curves):
            ax.plot(h["epoch"], h[col], ".-", color=f"C{k}", label=label)
        if ylabel == "MSE":
            ax.set_yscale("log")
        if ylabel == "validation SSIM":
            for k, (route, v) in enumerate((baselines or {}).items()):
                y = float(np.mean(v["val_ssim"]))
                ax.axhline(y, color=f"C{k + 3}", ls="--", lw=1, label=f"{_SHORT.get(route, route)}: {y:.3f}")
        ax.set(xlabel="epoch (0 = closed-form start)", ylabel=ylabel)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=1, frameon=False)
    wall = h["wall_time_s"].iloc[-1] / 60
    fig.suptitle(f"{scene}: learning curves ({len(h) - 1} epochs after the start; {wall:.1f} min in all, "
                 "the start included)", fontsize=10)
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
        ax.plot(s.slopes, s.scores / peak if peak > 0 else s.scores, label=f"{label}: {round(s.slope, 3) + 0.0:.3f}")
    ax.set_xlabel("slope (lenslets per view)")
    ax.set_ylabel(f"sharpness ({metric}, normalised)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def read_gnu_time(path) -> dict:
    """Wall time (s) and peak resident memory (GiB) from the ``/usr/bin/time -v`` reports of a file, one per run
    (``time -a`` appends each run's: a training target resumed after a kill, or run again with nothing left to
    train, adds its own run to the first's).

    Returns
    -------
    dict
        ``wall_s``: the runs' wall times summed; ``peak_rss_gib``: the largest run's peak; ``runs``: the reports
        read (a run killed with its ``time`` wrote none: its time is missing from the sum).

    Raises
    ------
    ValueError
        The file holds no complete report (not a GNU time ``-v`` report).
    """
    runs, cur = [], {}
    for line in Path(path).read_text().splitlines():
        key, _, val = line.strip().rpartition(": ")
        if key == "Maximum resident set size (kbytes)":
            cur["peak_rss_gib"] = int(val) / 2**20
        elif key.startswith("Elapsed (wall clock) time"):
            parts = [float(v) for v in val.split(":")]
            cur["wall_s"] = sum(v * 60 ** k for k, v in enumerate(reversed(parts)))
        if len(cur) == 2:
            runs.append(cur)
            cur = {}
    if not runs:
        raise ValueError(f"{path} is not a '/usr/bin/time -v' report")
    return dict(wall_s=sum(r["wall_s"] for r in runs), peak_rss_gib=max(r["peak_rss_gib"] for r in runs),
                runs=len(runs))


def provenance_section(results_dir, tables) -> list[str]:
    """Markdown lines: where each collected table came from, from its ``REGIME/eval_SCENE.json`` (:func:`evaluate`):
    the dataset (digest, seed, samples, camera), the training run (seed, backbone weights, epochs, wall time) and
    the evaluation (commit, date, versions); a note where the tables were evaluated at different commits or a table
    has no record. ``tables``: the (regime, scene) pairs collected."""
    rows, commits, missing = [], set(), []
    for regime, scene in tables:
        path = Path(results_dir) / regime / f"eval_{scene}.json"
        if not path.exists():
            missing.append(f"{regime}/table_{scene}.md")
            continue
        e = read_json(path, "record of an evaluation (evaluate again)")
        info, attrs, prov = e["train_info"], e.get("dataset_attrs", {}), e.get("provenance", {})
        cam = json.loads(attrs.get("camera", "{}"))
        n = json.loads(attrs.get("dataset_config", "{}")).get("n_samples", {}).get(scene, "?")
        v = prov.get("versions", {})
        commits.add(prov.get("git_commit"))
        rows.append(f"| {regime} {scene} | `{info.get('dataset')}` ({str(attrs.get('digest', '?'))[:12]}) | "
                    f"{e.get('dataset_seed')}, {n} | {cam.get('n_rows')} x {cam.get('n_cols')} lenslets, "
                    f"{cam.get('pixels_per_lenslet')} px, focus {cam.get('focus_distance_mm')} mm | "
                    f"{info.get('train_config', {}).get('seed')} | {info.get('backbone_weights')} | "
                    f"{info.get('epochs_run')} ({info.get('training_wall_time_s', float('nan')):.0f} s) | "
                    f"{prov.get('git_commit')}, {str(prov.get('date', ''))[:10]} | lf_flame {v.get('lf_flame')}, "
                    f"keras {v.get('keras')}, tensorflow {v.get('tensorflow-cpu')}, numpy {v.get('numpy')} |")
    lines = ["### Provenance", "", "| table | dataset (digest) | dataset seed, samples | camera | training seed | "
             "backbone weights | epochs (training wall time) | evaluated at (commit, date) | versions |",
             "|---|---|---|---|---:|---|---|---|---|"] + rows + [""]
    if len(commits) > 1:
        lines += [f"**The tables were evaluated at different commits ({', '.join(sorted(map(str, commits)))}): "
                  "they may come from different code.**", ""]
    if missing:
        lines += [f"**No evaluation record (eval_*.json) beside {', '.join(missing)}: its provenance is "
                  "unknown.**", ""]
    return lines


def write_tables(results_dir, stage_times: dict | None = None, make_targets: dict | None = None) -> str:
    """Collect both tables, their provenance (:func:`provenance_section`), slopes, stage wall times and, per make
    target, wall time and peak memory (:func:`read_gnu_time`) into ``tables.md``; return its text.

    Raises
    ------
    FileNotFoundError
        When ``results_dir`` holds no evaluated table (``REGIME/table_SCENE.md``): an empty page
        would look like a finished reproduction.
    """
    from ..simulate.scenes import REGIMES
    results_dir = Path(results_dir)
    parts = ["# Results", ""]
    tables = [(regime, scene) for regime in REGIMES for scene in ("shapes", "flame")
              if (results_dir / regime / f"table_{scene}.md").exists()]
    if not tables:
        raise FileNotFoundError(f"no table to collect: none of {results_dir}/{{{','.join(REGIMES)}}}/"
                                "table_{shapes,flame}.md exists (written by 'lf-flame evaluate')")
    for regime, scene in tables:
        parts += [(results_dir / regime / f"table_{scene}.md").read_text(), f"![{scene}]({regime}/fig_{scene}.png)",
                  f"![{scene} learning]({regime}/learning_{scene}.png)", ""]
    parts += provenance_section(results_dir, tables)
    sp = results_dir / "slopes.csv"
    if sp.exists():
        parts += ["### Sharpest slopes (slope search on the nominal scene)", "",
                  pd.read_csv(sp).to_markdown(index=False), ""]
    if stage_times:
        parts += ["### Wall time per stage", "", "| stage | seconds |", "|---|---:|"]
        parts += [f"| {k} | {v:.0f} |" for k, v in stage_times.items()] + [""]
    if make_targets:
        parts += ["### Training targets, measured with `/usr/bin/time -v`", "",
                  "Every run of the target (resumed after a kill, or run again): wall times summed, the largest peak.",
                  "", "| make target | runs | wall time (min) | peak memory (GiB) |", "|---|---:|---:|---:|"]
        parts += [f"| {k} | {v.get('runs', 1)} | {v['wall_s'] / 60:.1f} | {v['peak_rss_gib']:.2f} |"
                  for k, v in make_targets.items()]
        parts += [""]
    text = "\n".join(parts)
    atomic_write_text(results_dir / "tables.md", text)
    return text
