"""Why do the paper's epochs (Adam 1e-4, batch 2, MSE) lower validation SSIM after the
closed-form start? One epoch from the same start under each candidate cause switched off.

The start is the 'closed-form' recipe's (``lf-flame train`` with no epochs, in
``--start-dir``); then, for each variant, the start is loaded and trained for ``--epochs``
epochs at the paper's settings, and validation MSE, SSIM and PSNR are logged per epoch:

- ``dense+refocused, dropout``: what ``make tables`` trained before;
- ``dense, dropout``: the output 3×3 convolution kept as the identity;
- ``dense+refocused, no dropout`` and ``dense, no dropout``: dropout off (rate 0).

Usage::

    python experiments/studies/learning_causes.py --dataset data/paper/varied/shapes.h5 \\
        --experiment-config experiments/paper.toml --start-dir models/causes/varied/shapes \\
        --epochs 1 --out results/paper/learning_causes.csv

Appends one row per variant and epoch (epoch 0 = the start) to ``--out`` (CSV).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time
from pathlib import Path

import keras
import numpy as np
import pandas as pd

from lf_flame.config import load_experiment_config, provenance
from lf_flame.learn.dataset import LightFieldDataset
from lf_flame.learn.features import FeatureBatches, compute_features, predict_features
from lf_flame.learn.training import train, validation_scores

VARIANTS = {
    "dense+refocused, dropout": (("dense", "refocused"), True),
    "dense, dropout": (("dense",), True),
    "dense+refocused, no dropout": (("dense", "refocused"), False),
    "dense, no dropout": (("dense",), False),
}


def val_scores(decoder, feats, ds) -> dict:
    """Validation MSE, SSIM and PSNR (dB), means over samples and planes."""
    idx = np.sort(ds.splits["val"])
    mse = float(np.mean((np.clip(predict_features(decoder, feats, idx), 0, 1) - ds.gt(idx)) ** 2))
    return dict(val_mse=mse, **validation_scores(decoder, feats, ds, idx))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", required=True)
    ap.add_argument("--experiment-config", required=True)
    ap.add_argument("--start-dir", required=True, help="folder of the closed-form start (made if missing)")
    ap.add_argument("--epochs", type=int, default=1)
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    model_cfg, train_cfg = load_experiment_config(a.experiment_config)
    ds = LightFieldDataset(a.dataset)
    start_dir = Path(a.start_dir)
    if not (start_dir / "train_info.json").exists():  # the start only: no epochs
        train(a.dataset, start_dir, model_cfg, dataclasses.replace(train_cfg, max_epochs={ds.scene: 0}))
    feats, _ = compute_features(ds, model_cfg, model_cfg.weights, seed=train_cfg.seed)
    rows = []
    for name in a.variants:
        layers, dropout = VARIANTS[name]
        keras.utils.set_random_seed(train_cfg.seed)
        dec = keras.models.load_model(start_dir / "decoder_last.keras")
        for layer in dec.layers:
            layer.trainable = layer.name in layers
            if layer.name == "dropout" and not dropout:
                layer.rate = 0.0
        dec.compile(optimizer=keras.optimizers.Adam(train_cfg.learning_rate), loss="mse")
        rows.append(dict(variant=name, epoch=0, **val_scores(dec, feats, ds)))
        print(rows[-1], flush=True)
        for e in range(a.epochs):
            data = FeatureBatches(feats, ds, ds.splits["train"], train_cfg.batch_size, True, train_cfg.seed, e)
            t = time.perf_counter()
            h = dec.fit(data, epochs=1, verbose=0)
            rows.append(dict(variant=name, epoch=e + 1, loss=float(h.history["loss"][-1]),
                             epoch_s=time.perf_counter() - t, **val_scores(dec, feats, ds)))
            print(rows[-1], flush=True)
    df = pd.DataFrame(rows)
    df.insert(0, "dataset", f"{ds.config.regime}/{ds.scene}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, mode="a", header=not out.exists(), index=False)
    prov = out.with_suffix(".json")
    prov.write_text(json.dumps(dict(experiment_config=a.experiment_config, seed=train_cfg.seed,
                                    provenance=provenance()), indent=2))


if __name__ == "__main__":
    main()
