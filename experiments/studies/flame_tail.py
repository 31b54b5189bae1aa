"""The diagnostics' tail: how often shift-and-sum flame heights are off by more than 1 mm,
and whether :attr:`lf_flame.measure.diagnostics.FlameMeasurement.flags` catches those planes.

For each regime, draws ``n`` fresh flame scenes (:func:`lf_flame.simulate.scenes.flame_scene` with
``numpy.random.default_rng(seed0 + i)``; seeds no other file of the project uses), renders
each at 4 rays per pixel (:func:`lf_flame.simulate.tracer.render`, seed ``seed0 + i``), refocuses
it by shift-and-sum (:func:`lf_flame.refocus.shift_and_sum.focal_stack`, bilinear, ``--aperture`` views)
at the analytic slopes of the four flames' depths, and scores every plane against the
simulation's truth (:func:`lf_flame.measure.scoring.score_stacks`).

Writes ``<out>.csv`` (one row per scene and plane: truth, measurement, errors, the tip's
pedestal and the flags) and ``<out>.md``: per regime and depth, and over all depths, the
tail of the height error (share of planes off by more than 1 mm, 90th percentile, worst)
over all planes and over the trusted ones only, and the detector's confusion (how many
planes off by more than 1 mm are flagged, how many good planes, off by less than 0.5 mm).

Usage: ``python experiments/studies/flame_tail.py [--n 200] [--seed0 910000] [--regimes varied paper]
[--aperture square] [--out results/flame_tail]``
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

from lf_flame.measure import diagnostics
from lf_flame.refocus import shift_and_sum as refocus
from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.config import atomic_write_text
from lf_flame.measure.scoring import error_table, score_stacks

RAYS_PER_PIXEL = 4
#: Columns kept in the CSV (one row per scene and plane).
CSV_COLUMNS = ("regime", "seed", "depth_mm", "height_mm_true", "height_mm", "height_err_mm", "base_err_mm",
               "tip_err_mm", "centre_x_err_mm", "tip_pedestal_mm", "flags", "failure")
#: An error below this (mm) makes a plane "good" in the confusion table.
GOOD_MM = 0.5


def score_regime(regime: str, n: int, seed0: int, aperture: str, camera=PAPER_CAMERA) -> pd.DataFrame:
    """Render, refocus and score ``n`` scenes of ``regime``.

    Returns
    -------
    DataFrame, one row per scene and plane (:func:`lf_flame.measure.scoring.score_stacks`'s
    columns plus ``regime`` and ``seed``).
    """
    mask = refocus.aperture_mask(camera.pixels_per_lenslet, aperture)
    frames = []
    for seed in tqdm(range(seed0, seed0 + n), desc=regime, unit="scene"):
        sc = scenes.flame_scene(camera, np.random.default_rng(seed), regime=regime)
        raw = simulate.render(camera, sc, RAYS_PER_PIXEL, seed)
        views = refocus.raw_to_views(raw, camera.pixels_per_lenslet)
        stack = refocus.focal_stack(views, [camera.slope_for_depth(o["depth_offset_mm"]) for o in sc.objects], mask)
        frames.append(score_stacks(stack[None], camera, [sc.objects], samples=[seed], regime=regime))
    return pd.concat(frames, ignore_index=True).rename(columns={"sample": "seed"})


def tail_table(scores: pd.DataFrame) -> pd.DataFrame:
    """:func:`error_table` per regime and depth, plus one row per regime over all depths
    (``depth_mm`` "all"), with the median absolute height error."""
    per_depth = error_table(scores, by=("regime", "depth_mm"))
    per_depth["height_err_mm_median"] = scores.groupby(["regime", "depth_mm"], sort=False).height_err_mm.median().values
    overall = error_table(scores, by=("regime",))
    overall["height_err_mm_median"] = scores.groupby("regime", sort=False).height_err_mm.median().values
    overall.insert(1, "depth_mm", "all")
    t = pd.concat([per_depth.astype({"depth_mm": object}), overall], ignore_index=True)
    return t.sort_values("regime", kind="stable", key=lambda r: r.map({g: i for i, g in enumerate(scores.regime.unique())}))


def confusion(scores: pd.DataFrame) -> pd.DataFrame:
    """Per regime: planes off by > 1 mm, by 0.5-1 mm and by < 0.5 mm (:data:`GOOD_MM`),
    how many of each are flagged, and how many planes carry each flag (DataFrame.flags is
    pandas' own attribute: the column is read as ``["flags"]``)."""
    rows = []
    for regime, g in scores.groupby("regime", sort=False):
        ok = g[g.failure == ""]
        e, f = ok.height_err_mm, ok["flags"] != ""
        bad, good = e > 1.0, e < GOOD_MM
        mid = ~bad & ~good
        rows.append({"regime": regime, "planes": len(g), "failed": len(g) - len(ok),
                     "off > 1 mm": int(bad.sum()), "flagged (> 1 mm)": int((bad & f).sum()),
                     f"off {GOOD_MM}-1 mm": int(mid.sum()), f"flagged ({GOOD_MM}-1 mm)": int((mid & f).sum()),
                     f"off < {GOOD_MM} mm": int(good.sum()), f"flagged (< {GOOD_MM} mm)": int((good & f).sum()),
                     **{f'"{k}"': int(ok["flags"].str.split(";").apply(lambda fl, k=k: k in fl).sum())
                        for k in diagnostics.FLAGS}})
    return pd.DataFrame(rows)


def pedestal_table(scores: pd.DataFrame) -> pd.DataFrame:
    """The tip pedestal (mm) on good planes and on planes off by > 1 mm, per regime: what
    the threshold :data:`lf_flame.measure.diagnostics.TIP_PEDESTAL_MM` separates."""
    ok = scores[scores.failure == ""]
    rows = []
    for regime, g in ok.groupby("regime", sort=False):
        for name, sel in ((f"good (< {GOOD_MM} mm)", g.height_err_mm < GOOD_MM), ("off > 1 mm", g.height_err_mm > 1.0)):
            p = g.tip_pedestal_mm[sel]
            rows.append(dict(regime=regime, planes=name, n=int(sel.sum()), n_no_fit=int(p.isna().sum()),
                             median=p.median(), p99=p.quantile(0.99), min=p.min(), max=p.max(),
                             over_threshold=int((p > diagnostics.TIP_PEDESTAL_MM).sum())))
    return pd.DataFrame(rows)


def _md(df: pd.DataFrame) -> str:
    def cell(v):
        if isinstance(v, float):
            return "" if np.isnan(v) else f"{v:.3g}"
        return str(v)
    lines = ["| " + " | ".join(df.columns) + " |", "|" + " --- |" * len(df.columns)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join(lines)


def report(scores: pd.DataFrame, command: str) -> str:
    t = tail_table(scores)
    t = t.assign(share_over_1mm=100 * t.share_over_1mm, share_over_1mm_trusted=100 * t.share_over_1mm_trusted)
    cols = {"regime": "regime", "depth_mm": "plane (mm)", "n": "planes", "n_failed": "failed",
            "n_flagged": "flagged", "height_err_mm_median": "median", "share_over_1mm": "% > 1 mm",
            "height_err_mm_p90": "p90", "height_err_mm_max": "worst", "share_over_1mm_trusted": "% > 1 mm trusted",
            "height_err_mm_p90_trusted": "p90 trusted", "height_err_mm_max_trusted": "worst trusted"}
    return "\n\n".join([
        "# Flame heights on shift-and-sum planes: the tail and the flags",
        f"`{command}`",
        ("Absolute height error (mm) against the simulation's truth, per plane and over all "
         "planes; *trusted*: the planes without flags (`FlameMeasurement.flags`). Shares in %."),
        _md(t[list(cols)].rename(columns=cols)),
        (f"## Detector's confusion\n\nPlanes by height error, and how many of each the flags catch "
         f"({', '.join(f'`{k}`' for k in diagnostics.FLAGS)}; a plane may carry several)."),
        _md(confusion(scores)),
        (f"## Tip pedestal (mm)\n\nThe light beside the flame in the tip's fitted rows over the fitted slope; "
         f"`merged` above {diagnostics.TIP_PEDESTAL_MM} mm (`TIP_PEDESTAL_MM`). No fit: too few rows fitted."),
        _md(pedestal_table(scores)),
    ]) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=200, help="scenes per regime")
    p.add_argument("--seed0", type=int, default=910000, help="first scene seed (scene i: seed0 + i)")
    p.add_argument("--regimes", nargs="+", choices=scenes.REGIMES, default=["varied", "paper"])
    p.add_argument("--aperture", choices=["square", "circular"], default="square",
                   help="views summed by shift-and-sum (square: all)")
    p.add_argument("--out", default="results/flame_tail", help="prefix of the .csv and .md written")
    a = p.parse_args(argv)
    if a.n < 1:
        p.error(f"--n must be at least 1. Received: {a.n}")
    scores = pd.concat([score_regime(r, a.n, a.seed0, a.aperture) for r in a.regimes], ignore_index=True)
    out = Path(a.out)
    command = "python experiments/studies/flame_tail.py " + " ".join(argv if argv is not None else sys.argv[1:])
    atomic_write_text(f"{out}.csv", scores[list(CSV_COLUMNS)].to_csv(index=False, float_format="%.4g"))
    atomic_write_text(f"{out}.md", report(scores, command.strip()))
    print(report(scores, command.strip()))
    print(f"-> {out}.csv, {out}.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
