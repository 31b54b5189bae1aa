"""Flame geometry measured on a dataset's ground-truth planes, scored against the simulation's truth.

Writes ``<out>/heights_gt.csv`` (per plane: mean absolute errors in mm of the height, base,
tip and centre over the split; :func:`lf_flame.measure.scoring.error_table`) and
``<out>/heights_gt_samples.csv`` (every sample and plane: measured and true values).

Usage: ``python experiments/flame_heights.py --dataset data/paper/paper/flame.h5 --out results/paper/paper``
(``make heights`` runs it for both regimes).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from lf_flame.config import atomic_write_text
from lf_flame.learn.dataset import LightFieldDataset
from lf_flame.measure.scoring import error_table, score_stacks


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--dataset", required=True, help="flame dataset (.h5)")
    p.add_argument("--split", choices=["train", "val", "test"], default="test")
    p.add_argument("--out", required=True, help="folder for heights_gt.csv and heights_gt_samples.csv")
    a = p.parse_args(argv)
    ds = LightFieldDataset(a.dataset)
    if ds.scene != "flame":
        raise SystemExit(f"error: {a.dataset} holds the {ds.scene!r} scene, not flames")
    idx = np.sort(ds.splits[a.split])
    regime = ds.config.regime
    per = score_stacks(ds.gt(list(idx)), ds.camera, [ds.params(int(i)) for i in idx], samples=idx,
                       route="ground truth", regime=regime, split=a.split)
    table = error_table(per, by=("route", "regime", "split", "depth_mm"))
    out = Path(a.out)
    atomic_write_text(out / "heights_gt.csv", table.to_csv(index=False, float_format="%.4g"))
    atomic_write_text(out / "heights_gt_samples.csv", per.to_csv(index=False, float_format="%.5g"))
    print(table.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"-> {out / 'heights_gt.csv'}, {out / 'heights_gt_samples.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
