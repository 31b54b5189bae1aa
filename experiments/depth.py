"""Find the planes: flames at random depths, found and reconstructed, beside the baselines.

Scenes (:mod:`lf_flame.simulate.scenes_depth`, seeds ``SEED0 + i``, never used elsewhere):
``--scenes`` scenes of 2-4 flames at continuous random depths in -15..+25 mm, 2-25 mm
tall, at random lateral positions (apart in the image); ``--behind`` scenes per separation
of two flames in the same columns 5 mm and 10 mm apart in depth. Each rendered by the ray
tracer at ``--rays`` rays per pixel (never by an operator that inverts it); the render's
*own error* (distance from the exact light field, ``||r1 - r2|| / (sqrt 2 ||r1||)`` from a
second render with another seed) measured on the first ``OWN_ERROR_SCENES`` scenes. At
14 dB: shot and read noise (2 e-) drawn on the noise-free raw image with the full well
that gives 14 dB (measured), clipped at 1 as the sensor does.

Routes, on the same renders, each scored by :func:`lf_flame.tomo.scoring.score_flames`:

- ``auto``: :func:`lf_flame.tomo.found_planes.find_planes` (depth from focus per region, then
  admm on the exact operator of the found planes); its time is the depth search, the
  operator's build and the solve.
- ``fixed-paper-planes``: admm on the exact operator of the paper's planes (+20, +10, 0,
  -10 mm; the operator built once, its build not timed); a flame's depth is the plane
  holding most of its emission.
- ``shift-sum-slope-search``: per flame, :func:`lf_flame.refocus.slope_search.find_sharpest_slope`
  on the flame's true box (the object's ``roi``: given, as the slope search is), the
  refocused image at that slope its "emission" (share not defined).

Writes ``<out>/depth.csv`` (one row per flame, route, noise), ``depth.md`` (the bars),
``depth.json`` (settings, own errors, wall time, provenance), ``depth.png`` (depth errors);
with ``--variant V`` (other knobs of the auto route's solve) ``depth_V.*``.

Usage: ``python experiments/depth.py --out results [--quick] [--scenes 100] [--behind 5] [--rays 150]``
(each scene's rows are kept in ``--cache``, default ``data/depth``: a rerun resumes).
``--tune [N]``: the found planes' admm knobs at 14 dB (``TUNE_KNOBS``) on N validation scenes
(``SEED_VAL``), ``depth_tune.{csv,md}``; the package holds the choice in
``lf_flame.tomo.found_planes.FOUND_PLANES_KNOBS``.
``--columns [N]``: N scenes of two or three flames in one column band (``column_scene``, ``SEED_COLUMNS``;
with ``--validation`` other seeds, ``SEED_COLUMNS_VAL``), the same routes, ``depth_columns.{csv,md}``.
``--bias [N]``: the depth finder's bias near focus: N single flames at depths U(-5, 5) mm
(``SEED_BIAS``), noise-free and at 14 dB, the error of the depth found with the most votes per
depth band, ``depth_bias.{csv,md}`` (the bar: |bias| <= 0.05 mm and p90 |error| <= 0.15 mm
within +-3 mm of focus).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text, provenance
from lf_flame.measure.metrics import own_error
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack, raw_to_views
from lf_flame.refocus.slope_search import find_sharpest_slope  # noqa: E402
from lf_flame.simulate import tracer
from lf_flame.simulate.scenes import PAPER_DEPTHS_MM
from lf_flame.simulate.scenes_depth import behind_scene, column_scene, random_depth_scene
from lf_flame.tomo.found_planes import find_planes
from lf_flame.tomo.exact import emission_operator
from lf_flame.tomo.scoring import score_flames
from lf_flame.tomo.solvers import reconstruct

SEED0 = 3_600_000          # random-depth scenes: SEED0 + i; behind scenes: SEED0 + 50_000 + i
SEED_VAL = 3_900_000       # --tune's validation scenes: SEED_VAL + i (never scored)
SEED_BIAS = 3_680_000      # --bias: single flames near focus, SEED_BIAS + i
SEED_COLUMNS = 3_700_000   # --columns: two or three flames in one column band, SEED_COLUMNS + i
SEED_COLUMNS_VAL = 3_950_000   # their validation scenes (--columns N --validation; never scored)
BIAS_RANGE_MM = (-5.0, 5.0)
BIAS_BANDS_MM = (-5.0, -3.0, -1.0, 1.0, 3.0, 5.0)
#: --tune: the found planes' admm knobs tried at 14 dB (the others by the noise, as reconstruct takes them); the
#: lowest 90th percentile of the validation flames' emission error is taken (the bar's statistic)
TUNE_KNOBS = {"tv 0.1, lam 0.01 (admm's)": dict(tv=0.1, lam=0.01), "tv 0, lam 0.01": dict(tv=0.0, lam=0.01),
              "tv 0, lam 0.003": dict(tv=0.0, lam=0.003), "tv 0, lam 0.001": dict(tv=0.0, lam=0.001),
              "tv 0.03, lam 0.003": dict(tv=0.03, lam=0.003)}
SNR_DB = 14.0
READ_E = 2.0
OWN_ERROR_SCENES = 3
SEPARATIONS_MM = (5.0, 10.0)
#: The version of score_flames the cached rows were scored by (rows of another are scored again):
#: "heights-region", heights measured in the flame's columns, within the region its depth was found in and outside
#: the footprints of the other depths merged onto its plane. Earlier runs: the column band alone (3 of 295 flames
#: off by > 1 mm, each sharing its columns with a flame merged onto its plane); within the flame's own footprint
#: (0 of 295, but 3 of 20 near flames of the behind scenes off by about 2 mm: their voters cover only where they
#: are the sharper one); outside the others' footprints alone (1 of 295: the merged flame's tip beyond its voters).
#: "heights-region-box": the slope search's flames also measured within their boxes (the regions it is given), as
#: before "heights-region", which measured them in their columns alone (3 % off by > 1 mm: other flames' blur).
#: "side-by-side": a found depth may be each one's of flames side by side (regions apart), not of flames in the same
#: lines of sight.
SCORE_VERSION = "side-by-side"
#: The auto route the cached rows were solved by (rows of another are solved again): "near-peel", found planes near
#: in parallax held to their regions (``NEAR_PARALLAX``) and depths missed by the votes found in the residual
#: (``peel_planes``). "near-peel-prominence": the residual's peak judged by its prominence over the curve's spread
#: (``RESIDUAL_PROMINENCE``), not by its ratio to the median. "...-refine": the depths of flames one behind another
#: refined by Gauss-Newton on the residual (``refine_planes``); "-unmerged": planes that merged several depths left;
#: "-search-own-planes": their regions searched once more after the refinement where each depth has a plane of its
#: own (``peel_and_refine``); "-quiet-excess": in a quiet light field that search asks a lower prominence of a peak
#: whose height above the residual's floor holds ``REFINED_SHARE`` (``REFINED_QUIET_PROMINENCE``); "-possible": the
#: rows record the depths that search saw and did not take (``FoundDepths.possible``; the route's planes unchanged).
#: "-camera-range": the depths searched are the camera's imaging range (``imaging_range_mm``), not -15 .. +25 mm.
#: "-warm": a quiet light field's refinement solves start from the planes of the step before (``refine_planes``).
#: "-parallax-merge": found depths share a plane only within ``MERGE_PARALLAX`` lenslets of parallax (``plane_runs``).
#: "-secant": a quiet light field's refinement steps lengthened by the curvature the step before met (``secant_scale``).
ROUTE_VERSION = ("near-peel-prominence-refine-unmerged-search-own-planes-quiet-excess-possible-camera-range-warm"
                 "-parallax-merge-secant")


def add_noise(raw, snr_db, seed):
    """Shot + read noise with the full well that gives ``snr_db`` (measured, within 0.2 dB) over ``raw``, clipped
    to [0, 1] as the sensor clips; (noisy, measured SNR)."""
    s = raw.astype(np.float64)
    a, b, c = s.size * READ_E ** 2, s.sum(), -np.sum(s ** 2) / 10 ** (snr_db / 10)
    fw = 1.0 / ((-b + np.sqrt(b * b - 4 * a * c)) / (2 * a))
    for _ in range(6):   # clipping at 0 and 1 removes noise: shrink the full well until the SNR is measured
        rng = np.random.default_rng(seed)
        noisy = np.clip((rng.poisson(s * fw) + rng.normal(0.0, READ_E, s.shape)) / fw, 0.0, 1.0)
        snr = float(10 * np.log10(np.sum(s ** 2) / np.sum((noisy - s) ** 2)))
        if abs(snr - snr_db) < 0.2:
            break
        fw /= 10 ** ((snr - snr_db) / 10)
    return noisy.astype(np.float32), snr


#: ``--variant``: the knobs of the auto route's solve (:func:`lf_flame.tomo.found_planes.find_planes`)
VARIANTS = {"default": {}, "support": dict(support=True, solve=dict(lam=0.01, tv=0.0))}


def found_flames(found):
    """``score_flames``' ``found`` of the auto route: each found depth, its voters and the region it was found in."""
    return list(zip(found.depths_mm, found.masks, found.labels[None] == found.region[:, None, None]))


def routes(cam, scene, views, fixed_op, mask, labels, variant="default"):
    rows = []
    t0 = time.perf_counter()
    found, _, rec = find_planes(views, cam, **VARIANTS[variant])
    t_auto = time.perf_counter() - t0
    rows.append(score_flames(rec.planes, found.planes_mm, scene, cam, found=found_flames(found),
                             time_s=t_auto, route="auto", find_s=found.time_s, solve_s=rec.time_s,
                             n_found=len(found.depths_mm), n_planes=len(found.planes_mm),
                             possible_mm=json.dumps([round(p["depth_mm"], 3) for p in found.possible]), **labels))
    # each flame's found uncertainty beside its error (matched as score_flames matches)
    df = rows[-1]
    unc = []
    for d in df.depth_mm:
        j = np.flatnonzero(found.depths_mm == d)
        unc.append(float(found.uncertainty_mm[j[0]]) if len(j) else np.nan)
    df["uncertainty_mm"] = unc
    t0 = time.perf_counter()
    r4 = reconstruct(views.astype(np.float64), fixed_op, "admm")
    rows.append(score_flames(r4.planes, PAPER_DEPTHS_MM, scene, cam, time_s=time.perf_counter() - t0,
                             route="fixed-paper-planes", **labels))
    t0 = time.perf_counter()
    slopes, masks = [], []
    for o in scene.objects:
        slopes.append(find_sharpest_slope(views, o["roi"], mask=mask).slope)
        m = np.zeros(views.shape[2:], bool)
        r0, r1, c0, c1 = o["roi"]
        m[r0:r1, c0:c1] = True
        masks.append(m)
    fs = focal_stack(views, slopes, mask)
    depths = [cam.depth_for_slope(s) for s in slopes]
    # each flame's box is the region its depth was found in (the slope search is given it)
    rows.append(score_flames(fs, depths, scene, cam, found=list(zip(depths, masks, masks)), emission=False,
                             time_s=time.perf_counter() - t0, route="shift-sum-slope-search", **labels))
    return rows


def run(cam, n_scenes, n_behind, rays, cache: Path, variant="default", n_columns=0, columns_seed0=SEED_COLUMNS):
    """Every job's rows (cached per scene in ``cache``: a rerun resumes) and the renders' own errors. Jobs: the behind
    scenes, ``n_scenes`` random-depth scenes, or (``n_columns``) only that many column scenes."""
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    fixed_op = emission_operator(cam, list(PAPER_DEPTHS_MM))
    if n_columns:
        jobs = [("column", columns_seed0 + i, None) for i in range(n_columns)]
    else:
        jobs = [("behind", SEED0 + 50_000 + 100 * int(sep) + i, sep) for sep in SEPARATIONS_MM
                for i in range(n_behind)]
        jobs += [("random", SEED0 + i, None) for i in range(n_scenes)]
    rows, own = [], {}
    cache.mkdir(parents=True, exist_ok=True)
    for i, (kind, seed, sep) in enumerate(jobs):
        rng = np.random.default_rng(seed)
        scene = {"random": lambda: random_depth_scene(cam, rng), "behind": lambda: behind_scene(cam, rng, sep),
                 "column": lambda: column_scene(cam, rng)}[kind]()
        part = cache / f"{kind}_{seed}_{rays}{'' if variant == 'default' else '_' + variant}.csv"
        if part.exists():
            cached = pd.read_csv(part)
            if "route_version" in cached and (cached.score_version == SCORE_VERSION).all() and \
                    (cached.route_version == ROUTE_VERSION).all():
                rows.append(cached)
                continue
        raw = tracer.render(cam, scene, rays, seed)
        if i < OWN_ERROR_SCENES:
            other = tracer.render(cam, scene, rays, seed + 7)
            own[f"{kind}_{seed}"] = own_error(raw, other)
        noisy, snr = add_noise(raw, SNR_DB, seed)
        out = []
        for noise, r in (("clean", raw), ("14dB", noisy)):
            views = raw_to_views(r, cam.pixels_per_lenslet)
            out += routes(cam, scene, views, fixed_op, mask,
                          dict(kind=kind, seed=seed, separation_mm=sep if sep else np.nan, noise=noise,
                               snr_db=snr if noise != "clean" else np.inf), variant)
        df = pd.concat(out, ignore_index=True)
        df["score_version"], df["route_version"] = SCORE_VERSION, ROUTE_VERSION
        df.to_csv(part, index=False)
        rows.append(df)
        print(f"  {i + 1}/{len(jobs)} {kind} {seed}: auto depth errors "
              f"{np.round(df[(df.route == 'auto') & (df.noise == 'clean')].depth_err_mm.values, 3)}", flush=True)
    return pd.concat(rows, ignore_index=True), own


def tune(cam, n_scenes, rays, out: Path):
    """The found planes' knobs at 14 dB on validation scenes (``SEED_VAL``): every ``TUNE_KNOBS`` candidate through
    :func:`find_planes` (``solve=``), and the package's defaults (noise-free and at 14 dB) for reference; writes
    ``depth_tune.{csv,md}``."""
    t_all = time.perf_counter()
    rows = []
    for i in range(n_scenes):
        seed = SEED_VAL + i
        scene = random_depth_scene(cam, np.random.default_rng(seed))
        raw = tracer.render(cam, scene, rays, seed)
        noisy, snr = add_noise(raw, SNR_DB, seed)
        for noise, r in (("clean", raw), ("14dB", noisy)):
            views = raw_to_views(r, cam.pixels_per_lenslet)
            for name, solve in [("package defaults", None)] + (list(TUNE_KNOBS.items()) if noise == "14dB" else []):
                t0 = time.perf_counter()
                found, _, rec = find_planes(views, cam, solve=solve)
                rows.append(score_flames(rec.planes, found.planes_mm, scene, cam, found=found_flames(found),
                                         time_s=time.perf_counter() - t0, route=name, noise=noise, seed=seed,
                                         snr_db=snr, knobs=str(solve)))
        print(f"  tune {i + 1}/{n_scenes}", flush=True)
    df = pd.concat(rows, ignore_index=True)
    tab = df.groupby(["noise", "route"], sort=False).rel_err.agg(
        flames="size", median="median", p90=lambda e: e.quantile(0.9), worst="max").reset_index()
    cand = tab[(tab.noise == "14dB") & tab.route.isin(list(TUNE_KNOBS))]
    chosen = cand.loc[cand.p90.idxmin(), "route"]
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "depth_tune.csv", index=False)
    L = ["# The found planes' admm knobs at 14 dB, on validation scenes", "",
         f"`python experiments/depth.py --tune --out {out}` ({(time.perf_counter() - t_all) / 60:.1f} min); "
         f"{n_scenes} random-depth scenes (seeds {SEED_VAL}-{SEED_VAL + n_scenes - 1}, never scored), renders at "
         f"{rays} rays per pixel, 14 dB shot + read noise. Each candidate through `find_planes(views, camera, "
         "solve=knobs)` (the other admm knobs by the noise); per-flame emission error (`score_flames`). Chosen: the "
         f"lowest 90th percentile at 14 dB: **{chosen}** ({TUNE_KNOBS[chosen]}). `package defaults`: the route as "
         "committed (`FOUND_PLANES_KNOBS`).", "",
         tab.to_markdown(index=False, floatfmt=".4f"), "",
         f"Provenance: {json.dumps(provenance())[:300]} ...", ""]
    atomic_write_text(out / "depth_tune.md", "\n".join(L))
    print("\n".join(L))


def bars(df: pd.DataFrame) -> pd.DataFrame:
    """The issue's bars per route and noise, on the random-depth scenes and the behind scenes."""
    out = []
    for (route, noise), g in df.groupby(["route", "noise"], sort=False):
        rnd, beh = g[g.kind == "random"], g[g.kind == "behind"]
        err = rnd.depth_err_mm.abs()
        missed = int(err.isna().sum())
        e = err.fillna(np.inf)
        b5 = beh[beh.separation_mm == 5.0]
        pairs5 = b5.groupby("seed").apply(lambda s: bool((s.rel_err <= 0.15).all() and s.depth_err_mm.notna().all()),
                                          include_groups=False)
        out.append(dict(route=route, noise=noise, flames=len(rnd), missed=missed,
                        depth_err_median_mm=float(e.median()), depth_err_p90_mm=float(e.quantile(0.9)),
                        depth_err_worst_mm=float(e.max()),
                        rel_err_median=float(rnd.rel_err.median()), rel_err_p90=float(rnd.rel_err.quantile(0.9)),
                        rel_err_worst=float(rnd.rel_err.max()),
                        frac_rel_err_le_10pct=float((rnd.rel_err <= 0.10).mean()),
                        share_near_median=float(rnd.share_near.median()),
                        share_near_p10=float(rnd.share_near.quantile(0.1)),
                        frac_share_ge_90pct=float((rnd.share_near >= 0.9).mean()),
                        height_err_median_mm=float(rnd.height_err_mm.abs().median()),
                        height_err_p90_mm=float(rnd.height_err_mm.abs().fillna(np.inf).quantile(0.9)),
                        # missed or not measured counts as off
                        frac_height_off_gt_1mm=float((rnd.height_err_mm.abs().fillna(np.inf) > 1.0).mean()),
                        behind5_pairs=len(pairs5), behind5_both_found_le_15pct=int(pairs5.sum()),
                        behind10_depth_err_worst_mm=float(beh[beh.separation_mm == 10.0].depth_err_mm.abs().max()),
                        behind_rel_err_worst=float(beh.rel_err.max()) if len(beh) else np.nan,
                        time_median_s=float(g.groupby("seed").time_s.first().median()),
                        time_p90_s=float(g.groupby("seed").time_s.first().quantile(0.9))))
    return pd.DataFrame(out)


def write_report(out: Path, df, tb, own, settings, wall, prov, stem="depth"):
    auto = df[df.route == "auto"]
    per = auto.groupby(["seed", "noise"]).first()
    cov = auto.dropna(subset=["depth_err_mm", "uncertainty_mm"])
    lines = ["# Find the planes: flames at random depths", "",
             f"Auto route's solve: variant `{settings['variant']}` {settings['auto_knobs']} "
             "(`lf_flame.tomo.found_planes.find_planes`).", "",
             f"`python experiments/depth.py {settings['argv']}`; {settings['n_scenes']} random-depth scenes "
             f"({int((df.kind == 'random').sum() / 6)} flames), {settings['n_behind']} behind scenes per separation "
             f"{list(SEPARATIONS_MM)} mm; paper camera; renders at {settings['rays']} rays per pixel, own error "
             + ", ".join(f"{k} {100 * v:.2f} %" for k, v in own.items()) + f"; 14 dB shot + read noise. "
             f"Wall time {wall / 60:.1f} min (shared 2-core machine).", "",
             "## Bars (random-depth scenes; behind columns: the two-flame scenes)", "",
             tb.to_markdown(index=False, floatfmt=".3g"), "",
             "Bars: depth error p90 <= 0.3 mm, worst <= 1 mm; emission error <= 10 % on 90 % of flames; "
             ">= 90 % of each flame's emission within +-1 mm; heights on the found planes (measure_flame, emission "
             "settings, in the flame's columns and found region, outside the footprints of other depths merged onto its plane): <= 1 % of flames off by > 1 mm (missed or unmeasured counted off); "
             "two flames 5 mm apart both found, each <= 15 %; "
             "14 dB within 2x the noise-free errors; goal <= 1 s per light field.", "",
             "## Time of the auto route per light field (s)", "",
             f"depth search: median {per.find_s.median():.2f}, p90 {per.find_s.quantile(0.9):.2f}, worst "
             f"{per.find_s.max():.2f}; admm solve: median {per.solve_s.median():.2f}; whole (search, operator build, "
             f"solve): median {per.time_s.median():.2f}, p90 {per.time_s.quantile(0.9):.2f}, worst "
             f"{per.time_s.max():.2f}. Fixed planes' admm alone (operator prebuilt): median "
             f"{df[df.route == 'fixed-paper-planes'].groupby(['seed', 'noise']).time_s.first().median():.2f}.", "",
             "## Found uncertainty against the error (auto)", "",
             f"|error| <= uncertainty for {100 * float((cov.depth_err_mm.abs() <= cov.uncertainty_mm).mean()):.0f} % "
             f"of flames, <= 2x for {100 * float((cov.depth_err_mm.abs() <= 2 * cov.uncertainty_mm).mean()):.0f} %; "
             f"uncertainty median {cov.uncertainty_mm.median():.3f} mm.", "",
             "## Worst flames of the auto route", "",
             auto.reindex(auto.depth_err_mm.abs().sort_values(ascending=False, na_position="first").index).head(8)[
                 ["kind", "seed", "noise", "flame", "depth_mm_true", "height_mm", "depth_err_mm", "rel_err",
                  "share_near", "uncertainty_mm", "height_err_mm"]].to_markdown(index=False, floatfmt=".3g"), "",
             "## Worst heights of the auto route", "",
             auto.reindex(auto.height_err_mm.abs().sort_values(ascending=False, na_position="first").index).head(5)[
                 ["kind", "seed", "noise", "flame", "depth_mm_true", "height_mm", "height_err_mm", "height_flags",
                  "height_failure", "depth_err_mm", "rel_err"]].to_markdown(index=False, floatfmt=".3g"), ""]
    atomic_write_text(out / f"{stem}.md", "\n".join(lines))
    atomic_write_text(out / f"{stem}.json", json.dumps(dict(settings=settings, own_error=own, wall_s=wall,
                                                          provenance=prov), indent=1, default=str))


def plot(out: Path, df, stem="depth"):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for route, g in df[df.kind == "random"].groupby("route"):
        for noise, mk in (("clean", "o"), ("14dB", "x")):
            h = g[g.noise == noise]
            ax[0].plot(h.depth_mm_true, h.depth_err_mm, mk, ms=3, label=f"{route} {noise}")
            ax[1].plot(h.depth_mm_true, h.rel_err, mk, ms=3, label=f"{route} {noise}")
    ax[0].set(xlabel="true depth (mm)", ylabel="depth error (mm)", ylim=(-3, 3))
    ax[1].set(xlabel="true depth (mm)", ylabel="emission error (relative)", yscale="log")
    ax[0].axhspan(-0.3, 0.3, color="g", alpha=0.1)
    ax[1].axhline(0.1, color="g", lw=0.8)
    ax[1].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(out / f"{stem}.png", dpi=110)
    plt.close(fig)


def possible_reports(per) -> dict:
    """The depths the auto route saw and did not take (``possible_mm``), per light field of ``per`` (rows grouped by
    seed): the missed flames within 1 mm of one, and those with no missed flame within 1 mm."""
    hits = false = 0
    for _, f in per:
        seen = json.loads(f.possible_mm.iloc[0]) if isinstance(f.possible_mm.iloc[0], str) else []
        missed = f.depth_mm_true[f.depth_mm.isna()].values
        hits += sum(any(abs(p - m) <= 1.0 for p in seen) for m in missed)
        false += sum(not any(abs(p - m) <= 1.0 for m in missed) for p in seen)
    return dict(missed_reported=hits, false_reports=false)


def column_bars(df: pd.DataFrame) -> pd.DataFrame:
    """The column scenes' bars per route and noise: flames found, depth error (missed: inf), emission error,
    flames near focus, and the closest pairs."""
    out = []
    for (route, noise), g in df.groupby(["route", "noise"], sort=False):
        e = g.depth_err_mm.abs().fillna(np.inf)
        near = g[g.depth_mm_true.abs() <= 3.0]
        per = g.groupby("seed")
        sep = per.depth_mm_true.apply(lambda d: float(np.diff(np.sort(d.values)).min()))
        ok = per.apply(lambda s: bool(s.depth_err_mm.notna().all() and (s.rel_err <= 0.15).all()), include_groups=False)
        close = sep[sep <= 5.0].index
        reported = possible_reports(per) if "possible_mm" in g else {}
        out.append(dict(route=route, noise=noise, scenes=len(sep), flames=len(g), found=float(g.depth_mm.notna().mean()),
                        depth_err_p90_mm=float(e.quantile(0.9)), depth_err_worst_mm=float(e.max()),
                        rel_err_median=float(g.rel_err.median()), rel_err_p90=float(g.rel_err.fillna(np.inf).quantile(0.9)),
                        frac_rel_err_le_15pct=float((g.rel_err <= 0.15).mean()),
                        near_focus_flames=len(near),
                        near_focus_depth_err_p90_mm=float(near.depth_err_mm.abs().fillna(np.inf).quantile(0.9))
                        if len(near) else np.nan,
                        scenes_all_found_le_15pct=float(ok.mean()),
                        close_scenes=len(close), close_all_found_le_15pct=float(ok[close].mean()) if len(close) else np.nan,
                        time_median_s=float(per.time_s.first().median()), **reported))
    return pd.DataFrame(out)


def columns_report(out: Path, df, own, settings, wall, stem="depth_columns"):
    tb = column_bars(df)
    auto = df[df.route == "auto"]
    worst = auto.assign(err=auto.depth_err_mm.abs().fillna(np.inf)).sort_values(["err", "rel_err"], ascending=False)
    lines = ["# Flames one behind another: two or three per column band", "",
             f"`python experiments/depth.py {settings['argv']}`: {settings['n_columns']} column scenes "
             f"(`column_scene`, seeds {settings['seed0']}-{settings['seed0'] + settings['n_columns'] - 1}): 2-3 flames "
             "in one column band 3-15 mm apart, brightness ratios 0.3-3, heights 0.3-0.8 of the field, a flame within "
             f"3 mm of focus in a third of the scenes; paper camera; renders at {settings['rays']} rays per pixel "
             "(own error " + ", ".join(f"{k} {100 * v:.2f} %" for k, v in own.items()) + "), noise-free and "
             f"{SNR_DB:g} dB. Routes and scoring as `make depth` (`score_flames`: one found depth per flame; a flame "
             f"without one is missed). Wall time {wall / 60:.1f} min.", "",
             "Bars (noise-free; 14 dB within 2x): >= 95 % of flames found; depth error p90 <= 0.3 mm, worst <= 1 mm "
             "(missed: infinite); emission <= 15 % on 90 % of flames. Goal: pairs 3 mm apart both found, each "
             "<= 15 %, in 90 % of cases (`close_*`: scenes whose nearest two flames are <= 5 mm apart). "
             "`missed_reported`: missed flames within 1 mm of a depth the auto route reports as possible (seen in its "
             "residual short of the prominence the noise asks: `lf-flame reconstruct` warns), `false_reports`: "
             "reported depths with no missed flame within 1 mm.", "",
             tb.to_markdown(index=False, floatfmt=".3g"), "",
             "## Worst flames of the auto route", "",
             worst.head(12)[["seed", "noise", "flame", "depth_mm_true", "height_mm", "depth_mm", "depth_err_mm",
                             "rel_err", "share_near"]].to_markdown(index=False, floatfmt=".3g"), "",
             "Provenance: `" + json.dumps(provenance()) + "`", ""]
    atomic_write_text(out / f"{stem}.md", "\n".join(lines))
    return tb


def bias(cam, n_scenes, rays, out: Path):
    """``--bias``: single flames at depths U(BIAS_RANGE_MM), the depth found with the most votes against the
    truth, noise-free and at 14 dB, per depth band; depth_bias.{csv,md}."""
    from lf_flame.tomo.depth import find_depths
    t0 = time.perf_counter()
    rows = []
    for i in range(n_scenes):
        seed = SEED_BIAS + i
        scene = random_depth_scene(cam, np.random.default_rng(seed), n_flames=1, depth_range=BIAS_RANGE_MM)
        raw = tracer.render(cam, scene, rays, seed)
        true = float(scene.objects[0]["depth_offset_mm"])
        for noise, r in (("clean", raw), ("14dB", add_noise(raw, SNR_DB, seed)[0])):
            f = find_depths(raw_to_views(r, cam.pixels_per_lenslet), cam)
            k = int(np.argmax(f.weight)) if len(f.depths_mm) else -1
            found = float(f.depths_mm[k]) if k >= 0 else np.nan
            rows.append(dict(seed=seed, noise=noise, depth_mm_true=true, height_mm=scene.objects[0]["height_mm"],
                             depth_mm=found, err_mm=found - true, n_found=len(f.depths_mm)))
        print(f"  {i + 1}/{n_scenes} {true:+.2f} mm: errors {rows[-2]['err_mm']:+.4f} / {rows[-1]['err_mm']:+.4f} mm",
              flush=True)
    df = pd.DataFrame(rows)
    df["band_mm"] = pd.cut(df.depth_mm_true, BIAS_BANDS_MM)
    near = df[df.depth_mm_true.abs() <= 3.0]
    stats = lambda g: pd.Series(dict(flames=len(g), missed=int(g.depth_mm.isna().sum()), bias_mm=g.err_mm.mean(),
                                     p90_abs_mm=g.err_mm.abs().quantile(0.9), worst_abs_mm=g.err_mm.abs().max()))
    tb = df.groupby(["noise", "band_mm"], sort=True, observed=True).apply(stats).reset_index()
    tb["band_mm"] = tb.band_mm.astype(str)
    tn = near.groupby("noise", sort=False).apply(stats).reset_index()
    tn.insert(1, "band_mm", "within +-3 mm")
    tb = pd.concat([tb, tn], ignore_index=True)
    out.mkdir(parents=True, exist_ok=True)
    df.to_csv(out / "depth_bias.csv", index=False)
    wall = time.perf_counter() - t0
    atomic_write_text(out / "depth_bias.md", "\n".join([
        "# The depth finder's bias near focus", "",
        f"`python experiments/depth.py --out {out} --bias {n_scenes} --rays {rays}`: {n_scenes} single flames (seeds "
        f"{SEED_BIAS}-{SEED_BIAS + n_scenes - 1}, `random_depth_scene(n_flames=1)`) at depths U{BIAS_RANGE_MM} mm, "
        f"paper camera, renders at {rays} rays per pixel, noise-free and {SNR_DB:g} dB shot + read noise; "
        "`find_depths`' depth with the most votes against the truth (error = found - true). "
        f"Wall time {wall / 60:.1f} min.", "",
        "Bar: within +-3 mm of focus, |bias| <= 0.05 mm and p90 |error| <= 0.15 mm.", "",
        tb.to_markdown(index=False, floatfmt=".4g"), "",
        "Provenance: `" + json.dumps(provenance()) + "`", ""]))
    print(tb.to_string())
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--quick", action="store_true", help="6 random scenes, 1 behind scene per separation, 100 rays")
    ap.add_argument("--scenes", type=int, default=100)
    ap.add_argument("--behind", type=int, default=5)
    ap.add_argument("--rays", type=int, default=150)
    ap.add_argument("--cache", default="data/depth")
    ap.add_argument("--tune", type=int, nargs="?", const=20, default=0, metavar="N",
                    help="choose the found planes' knobs at 14 dB on N validation scenes (default 20): "
                         "depth_tune.{csv,md}")
    ap.add_argument("--columns", type=int, nargs="?", const=40, default=0, metavar="N",
                    help="N column scenes (default 40): flames one behind another -> depth_columns.{csv,md}")
    ap.add_argument("--validation", action="store_true",
                    help="with --columns: the validation scenes (other seeds, never scored) -> depth_columns_val.*")
    ap.add_argument("--bias", type=int, nargs="?", const=60, default=0, metavar="N",
                    help="the depth finder's bias near focus on N single flames (default 60): depth_bias.{csv,md}")
    ap.add_argument("--variant", choices=list(VARIANTS), default="default",
                    help="knobs of the auto route's solve; not 'default': files depth_VARIANT.*")
    a = ap.parse_args(argv)
    if a.quick:
        a.scenes, a.behind, a.rays = 6, 1, 100
    out = Path(a.out)
    if a.tune:
        return tune(PAPER_CAMERA, a.tune, a.rays, out)
    if a.bias:
        return bias(PAPER_CAMERA, a.bias, a.rays, out)
    if a.columns:
        t0 = time.perf_counter()
        seed0 = SEED_COLUMNS_VAL if a.validation else SEED_COLUMNS
        df, own = run(PAPER_CAMERA, 0, 0, a.rays, Path(a.cache), a.variant, n_columns=a.columns, columns_seed0=seed0)
        stem = "depth_columns" + ("_val" if a.validation else "") + ("" if a.variant == "default" else f"_{a.variant}")
        out.mkdir(parents=True, exist_ok=True)
        df.to_csv(out / f"{stem}.csv", index=False)
        settings = dict(argv=" ".join(argv if argv is not None else __import__("sys").argv[1:]), n_columns=a.columns,
                        seed0=seed0, rays=a.rays)
        print(columns_report(out, df, own, settings, time.perf_counter() - t0, stem).to_string())
        return 0
    t0 = time.perf_counter()
    df, own = run(PAPER_CAMERA, a.scenes, a.behind, a.rays, Path(a.cache), a.variant)
    wall = time.perf_counter() - t0
    tb = bars(df)
    out.mkdir(parents=True, exist_ok=True)
    stem = "depth" if a.variant == "default" else f"depth_{a.variant}"
    df.to_csv(out / f"{stem}.csv", index=False)
    settings = dict(argv=" ".join(argv if argv is not None else __import__("sys").argv[1:]), n_scenes=a.scenes,
                    n_behind=a.behind, rays=a.rays, seed0=SEED0, snr_db=SNR_DB, read_e=READ_E,
                    variant=a.variant, auto_knobs=VARIANTS[a.variant])
    write_report(out, df, tb, own, settings, wall, provenance(), stem)
    plot(out, df, stem)
    print(tb.to_string())


if __name__ == "__main__":
    main()
