"""What the matched route's accuracy costs in time, its admm knobs on validation scenes.

``admm-cfa-matched`` (:func:`lf_flame.temperature.channels.matched_channels`, the 2 x 2 grid per lenslet,
binned to the lenslets) on the paper's four flames drawn with the validation seeds of
``temperature_grid.py`` (distinct from the scored 937000-937001), at ``--rays`` rays per pixel:

- noise-free: fills :data:`FILLS` x gradient weights :data:`LAMS`, unsmoothed;
- at 14 dB: fills :data:`FILLS_NOISY` at the noisy knobs' weight, smoothed by
  ``MATCHED_SIGMA_NOISY`` (as the route does when the light field is noisy).

Per setting: the worst plane's p90 |T error| over both scenes (as ``temperature.md``), the median
plane's, the worst pixel, and the wall time of the four solves per scene (median over scenes).
The quiet knobs chosen: the smallest noise-free worst-plane p90 (ties within 1 K: fewer fills);
``MATCHED_KNOBS["quiet"]`` is checked against the choice. Writes ``<out>/temperature_fills.{csv,md}``.

Usage: ``python experiments/studies/temperature_fills.py --out results [--rays 400]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # experiments/, studies/
import temperature as E  # noqa: E402
from temperature_grid import SEEDS  # noqa: E402

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.refocus.shift_and_sum import raw_to_views  # noqa: E402
from lf_flame.temperature.channels import MATCHED_KNOBS, MATCHED_SIGMA_NOISY, matched_channels  # noqa: E402
from lf_flame.temperature.ratio import smooth_planes  # noqa: E402
from lf_flame.tomo.truth import bin_planes  # noqa: E402

FILLS, LAMS = (25, 100, 300), (0.003, 0.005, 0.01)
FILLS_NOISY = (25, 100)


def settings():
    """(noise, knobs, sigma) of every setting measured."""
    noisy = MATCHED_KNOBS["noisy"]
    out = [("clean", dict(noisy, fills=f, lam=lam), 0.0) for lam in LAMS for f in FILLS]
    return out + [("14dB", dict(noisy, fills=f), MATCHED_SIGMA_NOISY) for f in FILLS_NOISY]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--rays", type=int, default=400)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cam, sensor, model, cal = E.setup(args.out)
    rows, own = [], {}
    for seed, cs, r, Tt, vt, chan, op in E.flame_scenes(SEEDS, args.rays, cam, sensor, model, cal):
        own[seed] = r["own"]
        for noise, knobs, sigma in settings():
            views = raw_to_views(r["clean" if noise == "clean" else "noisy"], cam.pixels_per_lenslet)
            t1 = time.perf_counter()
            rec = matched_channels(views, op, [(chan == c) & (views < 1) for c in (0, 1)], **knobs)
            a, b = (smooth_planes(bin_planes(x, op.subsamples), sigma) if sigma else bin_planes(x, op.subsamples)
                    for x in rec)
            dt = time.perf_counter() - t1
            rows += E.score("admm-cfa-matched", noise, seed, a, b, Tt, vt, cal, model, time_s=dt, sigma=sigma,
                            **knobs)
            print(f"seed {seed} {noise} fills {knobs['fills']} lam {knobs['lam']}: {dt:.1f} s, p90 per plane "
                  f"{[round(x['p90_k']) for x in rows[-len(Tt):]]}", flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(args.out / "temperature_fills.csv", index=False)
    g = df.groupby(["noise", "fills", "lam"]).agg(
        p90_worst_plane=("p90_k", "max"), p90_median_plane=("p90_k", "median"), worst=("worst_k", "max"),
        time_s=("time_s", "median")).reset_index()
    clean = g[g.noise == "clean"].sort_values(["p90_worst_plane", "fills"])
    best = clean.p90_worst_plane.min()
    pick = clean[clean.p90_worst_plane <= best + 1.0].sort_values("fills").iloc[0]
    held = (int(pick.fills), float(pick.lam)) == (MATCHED_KNOBS["quiet"]["fills"], MATCHED_KNOBS["quiet"]["lam"])
    prov = provenance()
    atomic_write_text(args.out / "temperature_fills.md", "\n".join([
        "# The matched route's accuracy against its time: admm fills and weight, validation scenes", "",
        f"Command: `python experiments/studies/temperature_fills.py --out {args.out} --rays {args.rays}`; wall time "
        f"{time.perf_counter() - t0:.0f} s; commit {prov.get('git_commit')}; seeds {SEEDS} (validation, not the scored "
        f"ones); own error of the renders {[round(v, 4) for v in own.values()]}; `admm-cfa-matched` on the 2 x 2 "
        f"grid, binned to the lenslets; 14 dB smoothed by {MATCHED_SIGMA_NOISY} lenslets; tv 0, l1 0.", "",
        "p90 |T error| (K) of the worst and the median plane over both scenes, the worst pixel, and the seconds of "
        "the four admm solves per scene (median of the scenes; this machine, 2 cores):", "",
        g.to_markdown(index=False, floatfmt=".3g"), "",
        f"Quiet knobs chosen (smallest noise-free worst-plane p90, ties within 1 K to fewer fills): fills "
        f"{int(pick.fills)}, lam {pick.lam:g} ({pick.p90_worst_plane:.1f} K, {pick.time_s:.0f} s a scene); "
        f"`MATCHED_KNOBS['quiet']` = {MATCHED_KNOBS['quiet']} -> **{'holds' if held else 'differs from'}** the choice.",
        ""]))
    print((args.out / "temperature_fills.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
