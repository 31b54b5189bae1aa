"""The matched route's filter of the channels' ratio by noise level, on validation scenes.

``admm-cfa-matched`` (:func:`lf_flame.temperature.channels.matched_channels`, binned to the lenslets) on the
paper's four flames drawn with the validation seeds of ``temperature_grid.py`` (not the scored
937000-937001), noise-free (the quiet knobs) and with the mosaic's shot and read noise at each SNR of
:data:`SNRS_DB` (the noisy knobs; ``temperature.add_noise``), the two channels' emission filtered by:
none; a Gaussian of ``MATCHED_SIGMA_NOISY`` lenslets on both (the route's filter before this
experiment); or a guided filter of their log ratio (:func:`lf_flame.temperature.ratio.guided_ratio`) of each
radius and eps of :data:`GUIDED`. Scored as ``temperature.md`` (per plane over the pixels >= 10 % of
the plane's true peak R+G emission), beside the share of those pixels each leaves without a
temperature. Also noise-free, two flames one behind another (``colour_behind_scene``, validation
seeds :data:`BEHIND_SEEDS`, not the scored 937200-937203), scored over the mixed pixels as
``temperature_behind.md``. Per noisy level: the filter with the smallest worst-plane p90 is chosen;
noise-free, the one with the smallest larger of the flames' worst-plane p90 over 30 K and the behind
scenes' over 50 K (their bars), the behind planes the CFA leaves blind apart
(:func:`lf_flame.temperature.mosaic.cfa_blind`: at a slope near +-1 lenslet per view, half the lenslets hold
no red sample in any view, a ratio no filter restores); ``MATCHED_RATIO_FILTER`` and
``MATCHED_WIDE_NOISE`` are checked against the choices, the relative noise ``cfa_noise`` measures
beside each level. Writes ``<out>/temperature_ratio_filter.{csv,md}``.

Usage: ``python experiments/studies/temperature_ratio_filter.py --out results [--rays 400]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # experiments/, studies/
import temperature as E  # noqa: E402
from temperature_grid import SEEDS  # noqa: E402

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.refocus.shift_and_sum import raw_to_views  # noqa: E402
from lf_flame.simulate.scenes_temperature import colour_behind_scene  # noqa: E402
from lf_flame.temperature.channels import (MATCHED_KNOBS, MATCHED_QUIET_NOISE, MATCHED_RATIO_FILTER,  # noqa: E402
                                           MATCHED_SIGMA_NOISY, MATCHED_WIDE_NOISE, cfa_noise, matched_channels,
                                           matched_regime, route_operator)
from lf_flame.temperature.mosaic import cfa_blind  # noqa: E402
from lf_flame.temperature.ratio import guided_ratio, smooth_planes  # noqa: E402
from lf_flame.tomo.truth import bin_planes  # noqa: E402

SNRS_DB = (14.0, 17.0, 20.0, 26.0, 30.0)
GUIDED = ((1, 0.001), (1, 0.003), (1, 0.01), (1, 0.03), (1, 0.1), (2, 0.03), (2, 0.1), (2, 0.3))
BEHIND_SEEDS = ((937600, 10.0), (937601, 20.0), (937602, 10.0), (937603, 20.0))


def filters():
    """name -> (a, b) -> (a, b): every filter measured."""
    out = {"none": lambda a, b: (a, b),
           f"gaussian {MATCHED_SIGMA_NOISY}": lambda a, b: (smooth_planes(a, MATCHED_SIGMA_NOISY),
                                                            smooth_planes(b, MATCHED_SIGMA_NOISY))}
    for r, eps in GUIDED:
        out[E.ratio_filter_label(dict(radius=r, eps=eps))] = lambda a, b, r=r, eps=eps: guided_ratio(a, b, r, eps)
    return out


def route_filter(noise: float) -> str:
    """The filter name the route takes at a measured noise."""
    return E.ratio_filter_label(MATCHED_RATIO_FILTER[matched_regime(noise)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--rays", type=int, default=400)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cam, sensor, model, cal = E.setup(args.out)
    rows = []
    for seed, cs, r, Tt, vt, chan, op in E.flame_scenes(SEEDS, args.rays, cam, sensor, model, cal):
        for snr in (np.inf,) + SNRS_DB:
            raw = r["clean"] if snr == np.inf else E.add_noise(r["clean"], cs.scene.effects, seed, snr)[0]
            views = raw_to_views(raw, cam.pixels_per_lenslet)
            noise = cfa_noise(views, chan, (0, 1))
            knobs = MATCHED_KNOBS["quiet" if snr == np.inf else "noisy"]
            t1 = time.perf_counter()
            a, b = (bin_planes(x, op.subsamples) for x in
                    matched_channels(views, op, [(chan == c) & (views < 1) for c in (0, 1)], **knobs))
            dt = time.perf_counter() - t1
            for name, f in filters().items():
                rows += E.score("admm-cfa-matched", "clean" if snr == np.inf else f"{snr:g}dB", seed, *f(a, b), Tt,
                                vt, cal, model, snr_db=snr, filter=name, measured_noise=noise, fills=knobs["fills"],
                                time_s=dt)
            print(f"seed {seed} {snr:g} dB (noise {noise:.4f}): {dt:.0f} s", flush=True)
    for seed, sep in BEHIND_SEEDS:
        cs = colour_behind_scene(cam, sensor, np.random.default_rng(seed), sep)
        depths, r, Tt, vt, chan = E.scene_case(cam, cs, sensor, args.rays, seed, cal, model)
        op = route_operator(cam, depths, "admm-cfa-matched")
        views = raw_to_views(r["clean"], cam.pixels_per_lenslet)
        noise = cfa_noise(views, chan, (0, 1))
        t1 = time.perf_counter()
        a, b = (bin_planes(x, op.subsamples) for x in matched_channels(
            views, op, [(chan == c) & (views < 1) for c in (0, 1)], **MATCHED_KNOBS["quiet"]))
        dt = time.perf_counter() - t1
        slopes = [cam.slope_for_depth(d) for d in depths]
        blind = cfa_blind(slopes, cam.pixels_per_lenslet)
        for name, f in filters().items():
            rows += [dict(x, kind="behind", slope=slopes[x["plane"]],
                          blind=bool(blind[x["plane"]]))
                     for x in E.score("admm-cfa-matched", "clean", seed, *f(a, b), Tt, vt & vt[::-1], cal, model,
                                      snr_db=np.inf, filter=name, measured_noise=noise,
                                      fills=MATCHED_KNOBS["quiet"]["fills"], time_s=dt)]
        print(f"behind {seed} ({sep:g} mm, slopes {[round(x, 3) for x in slopes]}): {dt:.0f} s", flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(args.out / "temperature_ratio_filter.csv", index=False)
    bh = df[df.kind == "behind"]
    bw = bh[~bh.blind.astype(bool)].groupby("filter").p90_k.max()
    blind = bh[bh.blind.astype(bool)].groupby("filter").p90_k.max()
    df = df[df.kind == "flame"]
    g = df.groupby(["snr_db", "filter"]).agg(noise=("measured_noise", "max"), p90_worst_plane=("p90_k", "max"),
                                             p90_median_plane=("p90_k", "median"), worst=("worst_k", "max"),
                                             masked=("n_masked", "sum"), truth=("n_truth", "sum"))
    g["masked_pct"] = 100.0 * g.masked / g.truth
    g = g.drop(columns=["masked", "truth"])
    w = g.p90_worst_plane.unstack("filter")
    noise = df.groupby("snr_db").measured_noise.agg(["min", "max"])
    picks = pd.DataFrame(dict(noise_min=noise["min"], noise_max=noise["max"], best=w.idxmin(axis=1),
                              best_p90=w.min(axis=1),
                              route=[route_filter(n) for n in noise["max"]],
                              route_p90=[w.loc[s].get(route_filter(noise.loc[s, 'max']), np.nan) for s in w.index]))
    clean = pd.DataFrame(dict(flames_p90=w.loc[np.inf], behind_mixed_p90=bw, behind_blind_plane_p90=blind))
    clean["larger_over_bar"] = np.maximum(clean.flames_p90 / 30.0, clean.behind_mixed_p90 / 50.0)
    picks.loc[np.inf, "best"] = clean.larger_over_bar.idxmin()
    picks.loc[np.inf, "best_p90"] = clean.flames_p90[clean.larger_over_bar.idxmin()]
    picks["route_low_noise"] = [route_filter(n) for n in noise["min"]]
    held = all(a == b for a, b in zip(picks.route, picks.route_low_noise))
    prov = provenance()
    atomic_write_text(args.out / "temperature_ratio_filter.md", "\n".join([
        "# The matched route's filter of the channels' ratio by noise level, validation scenes", "",
        f"Command: `python experiments/studies/temperature_ratio_filter.py --out {args.out} --rays {args.rays}`; wall time "
        f"{time.perf_counter() - t0:.0f} s; commit {prov.get('git_commit')}; seeds {SEEDS} (validation, not the "
        f"scored ones); `admm-cfa-matched` binned to the lenslets, noise-free with the quiet knobs "
        f"{MATCHED_KNOBS['quiet']}, noisy with {MATCHED_KNOBS['noisy']}; shot + 2 e- read noise on the mosaic, "
        "the SNR measured over the image; `noise`: `cfa_noise` (the route's measure).", "",
        "Worst-plane p90 |T error| (K) over both scenes, per SNR (inf: noise-free) and filter:", "",
        w.to_markdown(floatfmt=".1f"), "",
        "Share of the truth pixels (>= 10 % of the true peak) left without a temperature (%): a filter that "
        "masks more reports fewer of the dim, hard pixels, so its p90 is read beside this:", "",
        g.masked_pct.unstack("filter").to_markdown(floatfmt=".1f"), "",
        "The best filter per level, and the one the route takes by the measured noise (`MATCHED_QUIET_NOISE` "
        f"{MATCHED_QUIET_NOISE}, `MATCHED_WIDE_NOISE` {MATCHED_WIDE_NOISE}, `MATCHED_RATIO_FILTER` "
        f"{MATCHED_RATIO_FILTER}) with its p90 here:", "",
        picks.to_markdown(floatfmt=".4g"), "",
        "Noise-free: the flames' worst-plane p90 beside the behind scenes' (mixed pixels; the planes `cfa_blind` "
        "flags apart, as `behind_blind_plane_p90`), and the larger of each over its bar:", "",
        clean.to_markdown(floatfmt=".3g"), "",
        f"Both scenes of each level take the same filter: **{'yes' if held else 'no'}**.", "",
        "All settings (median-plane p90 and worst pixel too):", "",
        g.reset_index().to_markdown(index=False, floatfmt=".4g"), ""]))
    print((args.out / "temperature_ratio_filter.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
