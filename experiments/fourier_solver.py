"""The 'admm' solver on the exact operator beside pd-tv on the Monte-Carlo operator.

Stages (``--stage``, default all), each writing ``<out>/fourier_solver_<stage>.csv`` and a
section of ``<out>/fourier_solver.md`` (``fourier_solver.json``: settings, own errors,
wall times, provenance):

- **renders**: the light fields scored here, rendered by the ray tracer (never by the
  operator that inverts them) at ``--rays`` rays per pixel, and each render's *own error*:
  its distance from the exact light field of its scene, estimated as
  ``||r_1 - r_2|| / (sqrt 2 ||r_1||)`` from a second render with another seed (the two
  differ by Monte-Carlo noise alone); with shot and read noise at 14 dB on top (measured
  SNR). Kept in ``--cache`` (default ``data/fourier_solver``) and reused.
- **tune**: the admm knobs (TV weight, fills read off one run by its callback) on the
  validation renders (``VAL_SEEDS``), per noise level: the score is the worst plane of the
  worst noise-free render for the quiet knobs, of the worst render at 14 dB for the noisy
  ones, and the renders' relative noise is measured for the split between them
  (``lf_flame.tomo.defaults.ADMM_QUIET_NOISE``); on both planes' grids, the lenslet grid and
  2 x 2 samples per lenslet (``ExactOperator(subsamples=2)``, scored binned back to the
  lenslets, against the same truth), the finer grid taken per noise level where it beats the
  lenslet grid by ``FINE_GAIN``; pd-tv (40 it., TV 0.3, 4-ray operator) on the same renders
  for the record. Every knob with every start (``STARTS``; the coarse one on the 2 x 2 grid,
  its lenslet-grid solve at the package's lenslet knobs); the start by time among those
  within 10 % of the best score (:func:`choose`).
- **coarse**: the coarse start's lenslet-grid solve: its start and fills cap (``COARSE_VARIANTS``)
  tried ahead of the chosen quiet 2 x 2 knobs on the noise-free validation renders, the rows
  added to an existing ``fourier_solver_tune.csv`` (the same knobs' earlier coarse rows
  replaced), then the same choice, each variant a start of its own; **choose**: the choice
  alone, from that file.
- **score**: admm at the package's defaults (its grid, knobs by the data's noise) and on the
  lenslet grid, pd-tv and shift-and-sum (``focal_stack``) on the scored
  renders (``TEST_SEEDS``) of the paper, varied and overlap scenes, noise-free and at
  14 dB, through :func:`lf_flame.tomo.scoring.score_planes`.
- **time**: in one run, the median and 90th percentile of ``--repeats`` 4-plane admm solves
  per scene kind (operator and per-frequency matrices built: their setup timed apart; the
  fills that ran), pd-tv solves and ``focal_stack`` calls on the paper's scene.
- **dense**: stacks of P = 4, 16, 41, 81 planes (every 0.5 mm over 40 mm for 81) on a
  volumetric flame: setup time (the first in the process, and the same setup again, its
  memory's first touch paid) and memory of the operator and of its per-frequency
  matrices, one admm solve's time.

Timings are taken on a shared 2-core machine: compare rows of one run only.

Usage: ``python experiments/fourier_solver.py --out results [--stage all] [--rays 400] [--tests 2]``.
"""
from __future__ import annotations

import argparse
import itertools
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import reconstruct as R  # noqa: E402  (the scenes, seeds and noise of make reconstruct)

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack, raw_to_views  # noqa: E402
from lf_flame.routes import measure_settings  # noqa: E402
from lf_flame.simulate import tracer  # noqa: E402
from lf_flame.simulate.scenes_volume import volume_flame_scene  # noqa: E402
from lf_flame.tomo import defaults, fourier, fourier_system, noise_knobs  # noqa: E402
from lf_flame.tomo.exact import ExactOperator  # noqa: E402
from lf_flame.tomo.operator import EmissionOperator  # noqa: E402
from lf_flame.tomo.scoring import score_planes  # noqa: E402
from lf_flame.tomo.solvers import reconstruct  # noqa: E402
from lf_flame.tomo.truth import bin_planes, scene_truth  # noqa: E402

KINDS = ("paper", "varied", "overlap")
SNR_DB = 14.0
#: the admm knobs tried on the validation renders (fills 1..MAX_FILLS read off each run); the
#: gradient weight, momentum and steps per fill are those a wider grid chose (lam 0.01-0.1,
#: momentum 0.4-0.6, 5 or 10 steps: commit 6c031f5's results/fourier_solver_tune.csv)
#: l1 (a fraction of lambda_max, :func:`lf_flame.tomo.fourier.solve_admm`): a probe on these renders at 14 dB
#: (2 x 2 grid, lam 0.01, TV 0.1) took the worst plane from 11.4 % to 7.9-8.1 % at 0.001-0.002; 0.01 and
#: above empty the planes for the first fills
GRID = dict(lam=(0.03,), tv=(0.0, 0.1, 0.3, 1.0), momentum=(0.6,), inner=(5,), l1=(0.0, 0.001))
#: the same on the 2 x 2 grid per lenslet (``ExactOperator(subsamples=2)``): four times the unknowns
#: want a weaker gradient weight (a probe: lam 0.003 at 2.0-2.6 % where 0.03 stops at 3.4 %; lam 0.001,
#: tried until commit 689b9aa, was never better than 0.003 at either noise level)
GRID_FINE = dict(lam=(0.01, 0.003), tv=(0.0, 0.1, 0.3), momentum=(0.6,), inner=(5,), l1=(0.0, 0.001, 0.002))
#: the finer grid is taken for a noise level only where it beats the lenslet grid's best by this factor
FINE_GAIN = 0.9
MAX_FILLS = 16
#: where the first fill predicts the missing data from (``solve_admm``'s ``start``), tried with every knob
STARTS = ("zero", "refocused", "coarse")
KNOBS = ["start", "lam", "tv", "momentum", "inner", "l1", "coarse_start", "coarse_fills"]
#: the coarse start's lenslet-grid solve (``defaults.COARSE_KNOBS``): its start and fills cap tried ahead of the
#: 2 x 2 grid's chosen quiet knobs (``--stage coarse``); the rows of the other starts carry "-" and 0
COARSE_VARIANTS = tuple((start, fills) for start in ("zero", "refocused") for fills in (1, 2, 4))
#: the stopping tolerances tried on the chosen knobs (``solve_admm``'s ``tol``: relative change of the planes over a
#: fill); the largest that keeps the validation score within 10 % of the best is taken, 0 (every fill) if none
TOLS = (0.0, 0.002, 0.005, 0.01, 0.02, 0.03, 0.05)
#: the knobs are chosen per noise level: 'quiet' on the noise-free renders, 'noisy' on those at 14 dB
REGIMES = {"clean": "quiet", "14dB": "noisy"}
DENSE_P = (4, 16, 41, 81)
PRECISION = "float32"   # the solver's: its rounding (1e-7) is far below any render's own error


def render_set(cam, kind, seed, rays, cache: Path):
    """(scene, views clean, views at 14 dB, own error, measured SNR) of one render, cached."""
    scene = R.build_scene(kind, cam, seed)
    return (scene,) + R.cached_render(cam, scene, rays, seed, cache / f"{kind}_{seed}_{rays}.npz", SNR_DB)


def worst_plane(x, truth):
    return float(R.rel_errors(x, truth).max())


def coarse_knobs(regime, start=None, fills=None):
    """The coarse start's lenslet-grid knobs: the package's for the noise level, ``start`` and ``fills`` replaced."""
    kn = dict(defaults.COARSE_KNOBS[regime])
    kn.update({k: v for k, v in (("start", start), ("fills", fills)) if v is not None})
    return kn


def tune(cam, rays, cache, starts=STARTS, grids=(1, 2), pd_tv=True, coarse_variants=None, fine=None, noises=None):
    """Validation rows: every knob of the grids' GRID / GRID_FINE with every start, worst plane per fill.

    ``coarse_variants``: the coarse start's (start, fills cap) pairs tried (None: the package's); ``fine``: the
    2 x 2 grid's knobs (lam, tv, momentum, inner, l1) alone instead of GRID_FINE's; ``noises``: those run (None:
    both)."""
    rows = []
    for kind, seed in itertools.product(KINDS, R.VAL_SEEDS):
        scene, clean, noisy, own, snr = render_set(cam, kind, seed, rays, cache)
        depths = R.planes_of(kind, scene)
        ops = {1: ExactOperator(cam, depths, precision=PRECISION),
               2: ExactOperator(cam, depths, precision=PRECISION, subsamples=2)}
        mc = EmissionOperator(cam, depths, rays_per_pixel=R.RAYS_OP) if pd_tv else None
        truth = scene_truth(scene, ops[1])
        for noise, views in (("clean", clean), ("14dB", noisy)):
            if noises is not None and noise not in noises:
                continue
            labels = dict(scene=kind, seed=seed, noise=noise, own_error=own,
                          noise_level=noise_knobs.relative_noise(views, views < 1.0))
            if pd_tv:
                t0 = time.perf_counter()
                rec = reconstruct(views, mc, "pd-tv")
                rows.append(dict(labels, route="pd-tv", fills=np.nan, worst=worst_plane(rec.planes, truth),
                                 time_s=time.perf_counter() - t0))
            for sub, grid in ((1, GRID), (2, GRID_FINE)):
                if sub not in grids:
                    continue
                op = ops[sub]
                knobs = [fine] if fine is not None and sub == 2 else itertools.product(*grid.values())
                for start, (lam, tv, mom, inner, l1) in itertools.product(starts, knobs):
                    if start == "coarse" and sub == 1:
                        continue
                    default = coarse_knobs(REGIMES[noise])
                    for cs, cf in (coarse_variants or [(default["start"], default["fills"])]) \
                            if start == "coarse" else [("-", 0)]:
                        prev = []

                        def cb(j, x):
                            change = np.linalg.norm(x - prev[0]) / max(np.linalg.norm(x), 1e-30) if prev else np.nan
                            prev[:] = [x.copy()]
                            rows.append(dict(labels, route="admm", subsamples=sub, start=start, lam=lam, tv=tv,
                                             momentum=mom, inner=inner, l1=l1, coarse_start=cs, coarse_fills=cf,
                                             fills=j, change=change,
                                             worst=worst_plane(bin_planes(x.reshape(op.dims), sub), truth)))
                        fourier.solve_admm(views, op, views < 1.0, fills=MAX_FILLS, inner=inner, lam=lam, tv=tv,
                                           momentum=mom, l1=l1, start=start, callback=cb,
                                           coarse_knobs=coarse_knobs(REGIMES[noise], cs, cf) if cf else None)
        print(f"  tune {kind} {seed} done", flush=True)
    return pd.DataFrame(rows)


def choose(df, cam, rays, cache):
    """The knobs per noise level and grid from the validation rows.

    Per start: the fewest fills within 10 % of that start's best score, then the best of those, and the largest
    tolerance that keeps the stopped runs within 10 % of the best (:func:`stopping`). Among the starts whose
    stopped score is within 10 % of the best start's, the fastest: the median over the validation renders of
    the stopped solve's time (:func:`time_starts`), since a start's cost is not its fills (the refocused start
    adds an ``H`` and an ``H^H``, the coarse one a solve on the lenslet grid); starts within 10 % of the
    fastest time count as as fast (this machine's run-to-run noise), the best stopped score among them."""
    best = {}
    for noise, regime in REGIMES.items():
        for sub in (1, 2):
            admm = df[(df.route == "admm") & (df.noise == noise) & (df.subsamples == sub)]
            cands = []
            for _, runs in admm.groupby(["start", "coarse_start", "coarse_fills"]):
                score = runs.groupby(KNOBS + ["fills"]).worst.max().reset_index()
                # the fewest fills within 10 % of the best score, then the best of those
                ok = score[score.worst <= 1.1 * score.worst.min()].sort_values(["fills", "inner", "worst"])
                b = ok.iloc[0].to_dict()
                b["tol"], b["fills_run_mean"], b["worst_stopped"] = stopping(runs, b, 1.1 * score.worst.min())
                cands.append(b)
            floor = min(b["worst_stopped"] for b in cands)
            cands = [b for b in cands if b["worst_stopped"] <= 1.1 * floor]
            for b, t in zip(cands, time_starts(cam, rays, cache, noise, sub, cands) if len(cands) > 1
                            else [np.nan]):
                b["time_s"] = t
            timed = {start_label(c): (c["time_s"], c["worst_stopped"]) for c in cands}
            if len(cands) > 1:   # within 10 % of the fastest counts as as fast (this machine's noise): the best score
                fastest = min(c["time_s"] for c in cands)
                cands = [c for c in cands if c["time_s"] <= 1.1 * fastest]
            b = best[f"{regime}_{sub}"] = min(cands, key=lambda c: c["worst_stopped"])
            b["starts_timed"] = timed
        best[f"{regime}_subsamples"] = 2 if best[f"{regime}_2"]["worst"] < FINE_GAIN * best[f"{regime}_1"]["worst"] else 1
    return best


def start_label(knobs):
    """``start``, the coarse one with its lenslet-grid start and fills cap: ``coarse (zero, 2)``."""
    return knobs["start"] + (f" ({knobs['coarse_start']}, {int(knobs['coarse_fills'])})"
                             if knobs["start"] == "coarse" else "")


def time_starts(cam, rays, cache, noise, sub, candidates, repeats=3):
    """Per candidate knobs, the median over the validation renders of the stopped admm solve's time (each render's
    operator built once for all candidates; per-frequency factors and the coarse start's lenslet-grid operator
    built by a first run; the fastest of ``repeats``)."""
    times = [[] for _ in candidates]
    for kind, seed in itertools.product(KINDS, R.VAL_SEEDS):
        scene, clean, noisy, _, _ = render_set(cam, kind, seed, rays, cache)
        views = clean if noise == "clean" else noisy
        op = ExactOperator(cam, R.planes_of(kind, scene), precision=PRECISION, subsamples=sub)
        for knobs, out in zip(candidates, times):
            def run():
                fourier.solve_admm(views, op, views < 1.0, fills=int(knobs["fills"]), inner=int(knobs["inner"]),
                                   lam=knobs["lam"], tv=knobs["tv"], momentum=knobs["momentum"], l1=knobs["l1"],
                                   start=knobs["start"], tol=knobs["tol"],
                                   coarse_knobs=coarse_knobs(REGIMES[noise], knobs["coarse_start"],
                                                             int(knobs["coarse_fills"]))
                                   if knobs["start"] == "coarse" else None)
            run()
            t = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                run()
                t.append(time.perf_counter() - t0)
            out.append(min(t))
    return [float(np.median(t)) for t in times]


def stopping(admm, chosen, bar):
    """The largest of TOLS whose stopped runs (after the first fill >= 2 whose relative change of the planes is at
    most tol, else at the chosen fills) keep every render's worst plane within ``bar``: (tol, mean fills run, score)."""
    runs = admm[np.logical_and.reduce([admm[k] == chosen[k] for k in KNOBS]) & (admm.fills <= chosen["fills"])]
    for tol in sorted(TOLS, reverse=True):
        stops = [g.loc[g.fills >= 2].pipe(lambda h: h[(h.change <= tol) | (h.fills == chosen["fills"])]).iloc[0]
                 for _, g in runs.sort_values("fills").groupby(["scene", "seed"])]
        worst = max(r.worst for r in stops)
        if worst <= bar or tol == 0:
            return float(tol), float(np.mean([r.fills for r in stops])), float(worst)


def score(cam, rays, cache, n_tests):
    rows, own_errors = [], {}
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    for kind, seed in itertools.product(KINDS, R.TEST_SEEDS[:n_tests]):
        scene, clean, noisy, own, snr = render_set(cam, kind, seed, rays, cache)
        own_errors[f"{kind}_{seed}"] = own
        depths = R.planes_of(kind, scene)
        op = ExactOperator(cam, depths, precision=PRECISION)
        mc = EmissionOperator(cam, depths, rays_per_pixel=R.RAYS_OP)
        truth = scene_truth(scene, op)
        fine = ExactOperator(cam, depths, precision=PRECISION, subsamples=2)
        for noise, views in (("clean", clean), ("14dB", noisy)):
            labels = dict(scene=kind, seed=seed, noise=noise, snr_measured_db=snr if noise != "clean" else np.inf,
                          own_error=own)
            t0 = time.perf_counter()
            fs = focal_stack(views, [cam.slope_for_depth(d) for d in depths], mask)
            rows.append(score_planes(fs, truth, cam, depths, scene.objects, time_s=time.perf_counter() - t0,
                                     route="refocus-shift-sum", **labels))
            rec = reconstruct(views, mc, "pd-tv")
            rows.append(score_planes(rec.planes, truth, cam, depths, scene.objects, time_s=rec.time_s,
                                     route="reconstruct-pd-tv (4-ray operator)",
                                     measure=measure_settings("reconstruct-pd-tv"), **labels))
            # its defaults: the grid and the knobs of the data's noise level (as lf-flame reconstruct)
            for name, o in (("reconstruct-admm (exact operator)", fine if noise_knobs.admm_subsamples(len(depths)) == 2 else op),
                            ("reconstruct-admm (exact operator, lenslet grid)", op)):
                rec = reconstruct(views, o, "admm")
                rows.append(score_planes(bin_planes(rec.planes, o.subsamples), truth, cam, depths, scene.objects,
                                         time_s=rec.time_s, route=name, measure=measure_settings("reconstruct-admm"),
                                         noise_level=rec.settings["noise"], fills=rec.settings["iters"],
                                         fills_run=rec.settings["fills_run"], start=rec.settings["start"],
                                         tol=rec.settings["tol"],
                                         admm_tv=rec.settings["tv"], admm_lam=rec.settings["lam"],
                                         admm_l1=rec.settings["l1"], subsamples=o.subsamples, **labels))
        print(f"  score {kind} {seed} done", flush=True)
    return pd.concat(rows, ignore_index=True), own_errors


def timing(cam, rays, cache, repeats):
    """Per scene kind, admm at its defaults (2 x 2 grid) and on the lenslet grid, noise-free and at 14 dB (their
    stopping makes the time depend on the scene); on the paper's scene pd-tv and ``focal_stack``, in one run."""
    rows = []
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    for kind in KINDS:
        scene, clean, noisy, _, _ = render_set(cam, kind, R.TEST_SEEDS[0], rays, cache)
        depths = R.planes_of(kind, scene)
        t0 = time.perf_counter()
        op = ExactOperator(cam, depths, precision=PRECISION)
        op_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        fine = ExactOperator(cam, depths, precision=PRECISION, subsamples=2)
        fine_s = time.perf_counter() - t0
        runs = {"reconstruct-admm (exact operator), noise-free": (lambda: reconstruct(clean, fine, "admm"), fine_s),
                "reconstruct-admm (exact operator), 14 dB": (lambda: reconstruct(noisy, fine, "admm"), fine_s),
                "reconstruct-admm (exact operator, lenslet grid), noise-free": (lambda: reconstruct(clean, op, "admm"),
                                                                                op_s),
                "reconstruct-admm (exact operator, lenslet grid), 14 dB": (lambda: reconstruct(noisy, op, "admm"), op_s)}
        if kind == "paper":
            t0 = time.perf_counter()
            mc = EmissionOperator(cam, depths, rays_per_pixel=R.RAYS_OP)
            mc.matvec(np.zeros(mc.shape[1]))   # the ray record is made on first use
            slopes = [cam.slope_for_depth(d) for d in depths]
            runs["reconstruct-pd-tv (4-ray operator)"] = (lambda: reconstruct(clean, mc, "pd-tv"),
                                                          time.perf_counter() - t0)
            runs["refocus-shift-sum (focal_stack)"] = (lambda: focal_stack(clean, slopes, mask), 0.0)
        for name, (f, setup) in runs.items():
            rec = f()   # warm-up (Numba, threads; admm's per-frequency factors for its knobs, setup)
            fills = np.nan
            if "admm" in name:
                setup += rec.settings["system_s"]
                fills = rec.settings["fills_run"]
            t = []
            for _ in range(repeats if "pd-tv" not in name else max(3, repeats // 4)):
                t1 = time.perf_counter()
                f()
                t.append(time.perf_counter() - t1)
            rows.append(dict(route=name, scene=kind, median_s=float(np.median(t)), p90_s=float(np.percentile(t, 90)),
                             worst_s=float(np.max(t)), n=len(t), setup_s=setup, fills_run=fills))
        print(f"  time {kind} done", flush=True)
    df = pd.DataFrame(rows)
    base = df[df.route == "reconstruct-pd-tv (4-ray operator)"].median_s.iloc[0]
    df["x_faster_than_pd_tv"] = base / df.median_s
    return df


def dense(cam, plane_counts=DENSE_P):
    rng = np.random.default_rng(R.TEST_SEEDS[0])
    scene = volume_flame_scene(cam, rng)
    views = raw_to_views(tracer.render(cam, scene, 16, R.TEST_SEEDS[0]), cam.pixels_per_lenslet)
    rows = []
    for P in plane_counts:
        depths = list(np.linspace(-15.0, 25.0, P))
        t0 = time.perf_counter()
        op = ExactOperator(cam, depths, precision=PRECISION)
        op_s = time.perf_counter() - t0
        rec = reconstruct(views, op, "admm")   # the 16-ray render is quiet: 8 fills, no TV
        system = fourier_system.admm_system(op, rec.settings["lam"], rec.settings["tv"])   # the one it built
        solve_s = rec.time_s - rec.settings["system_s"]
        # the same setup again in this process: its memory's first touch is then paid (a virtual machine backs a
        # guest's fresh pages on first touch, at a cost that varies from run to run)
        row = dict(planes=P, spacing_mm=40.0 / (P - 1), operator_setup_s=op_s, system_setup_s=system.setup_s,
                   setup_s=op_s + system.setup_s, operator_mb=op.nbytes / 2 ** 20, system_mb=system.nbytes / 2 ** 20,
                   solve_s=solve_s)
        lam, rho = system.lam, system.rho
        del op, system                                             # the system holds the operator's spectra
        t0 = time.perf_counter()
        again = ExactOperator(cam, depths, precision=PRECISION)
        row["setup_again_s"] = time.perf_counter() - t0 + fourier_system.FourierSystem(again, lam, rho).setup_s
        del again
        rows.append(dict(row, peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024))
        print(f"  dense P={P}: setup {row['setup_s']:.1f} s (again {row['setup_again_s']:.1f} s), "
              f"solve {solve_s:.2f} s", flush=True)
    return pd.DataFrame(rows)


def summary(df):
    d = df.assign(key=df.scene + " " + df.noise)
    worst = d.groupby(["route", "scene", "noise", "seed"]).rel_err.max().reset_index()
    return worst.groupby(["route", "scene", "noise"]).rel_err.agg(
        worst_plane_mean="mean", worst_plane_max="max").reset_index()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results"))
    ap.add_argument("--cache", type=Path, default=Path("data/fourier_solver"))
    ap.add_argument("--stage", choices=("all", "tune", "coarse", "choose", "score", "time", "dense"), default="all",
                    help="coarse: the coarse start's lenslet-grid variants (start, fills cap) at the chosen quiet "
                         "2 x 2 knobs added to fourier_solver_tune.csv, then the choice again (tune: every "
                         "start); choose: the choice again from that file")
    ap.add_argument("--rays", type=int, default=400, help="rays per pixel of the scored renders")
    ap.add_argument("--tests", type=int, default=2, help="scored renders per scene kind")
    ap.add_argument("--repeats", type=int, default=12)
    ap.add_argument("--planes", type=int, nargs="+", default=list(DENSE_P), help="plane counts of the dense stage")
    a = ap.parse_args(argv)
    cam = PAPER_CAMERA
    a.out.mkdir(parents=True, exist_ok=True)
    meta_path = a.out / "fourier_solver.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    meta.update(rays=a.rays, precision=PRECISION, grid=GRID, grid_fine=GRID_FINE, fine_gain=FINE_GAIN, starts=STARTS,
                tols=TOLS,
                max_fills=MAX_FILLS, val_seeds=R.VAL_SEEDS,
                test_seeds=R.TEST_SEEDS[:a.tests], snr_db=SNR_DB, provenance=provenance())
    t_all = time.perf_counter()
    stages = ("tune", "score", "time", "dense") if a.stage == "all" else (a.stage,)
    if {"tune", "coarse", "choose"} & set(stages):
        if "tune" in stages:
            df = tune(cam, a.rays, a.cache)
        elif "choose" in stages:
            df = pd.read_csv(a.out / "fourier_solver_tune.csv")
        else:   # the coarse start's variants at the chosen quiet 2 x 2 knobs, noise-free
            old = pd.read_csv(a.out / "fourier_solver_tune.csv")
            q = meta["chosen"]["quiet_2"]
            fine = tuple(q[k] for k in ("lam", "tv", "momentum", "inner", "l1"))
            new = tune(cam, a.rays, a.cache, starts=("coarse",), grids=(2,), pd_tv=False,
                       coarse_variants=COARSE_VARIANTS, fine=fine, noises=("clean",))
            same = np.logical_and.reduce([old[k] == new[k].iloc[0] for k in ("start", "noise", "subsamples", "lam",
                                                                            "tv", "momentum", "inner", "l1")])
            df = pd.concat([old[~same], new], ignore_index=True)
        if "choose" not in stages:
            atomic_write_text(a.out / "fourier_solver_tune.csv", df.to_csv(index=False))
        best = choose(df, cam, a.rays, a.cache)
        meta["chosen"] = {key: int(b) if isinstance(b, int) else
                          {k: (v if k in ("start", "coarse_start", "starts_timed") else
                               float(v) if k not in ("inner", "fills", "coarse_fills")
                               else int(v)) for k, v in b.items()} for key, b in best.items()}
        meta["noise_levels"] = df.groupby("noise").noise_level.agg(["min", "max"]).to_dict("index")
        meta["pd_tv_validation_worst"] = df[df.route == "pd-tv"].groupby("noise").worst.max().to_dict()
        print("chosen", meta["chosen"], "noise levels", meta["noise_levels"], "pd-tv validation worst",
              meta["pd_tv_validation_worst"])
    if "chosen" in meta:   # what the package's defaults hold against what was chosen
        c = meta["chosen"]
        meta["defaults_hold_the_choice"] = bool(
            all(tuple(c[f"{regime}_{sub}"].get(k, 0.0) for k in ("fills", "tv", "lam", "l1", "start", "tol"))
                == tuple(defaults.ADMM_KNOBS[sub, regime][k] for k in ("fills", "tv", "lam", "l1", "start", "tol"))
                and c[f"{regime}_subsamples"] == defaults.ADMM_SUBSAMPLES
                and (c[f"{regime}_2"]["start"] != "coarse" or (c[f"{regime}_2"]["coarse_start"],
                                                               c[f"{regime}_2"]["coarse_fills"])
                     == tuple(defaults.COARSE_KNOBS[regime][k] for k in ("start", "fills")))
                for regime in ("quiet", "noisy") for sub in (1, 2))
            and meta["noise_levels"]["clean"]["max"] < defaults.ADMM_QUIET_NOISE < meta["noise_levels"]["14dB"]["min"])
    if "score" in stages:
        df, own = score(cam, a.rays, a.cache, a.tests)
        df.to_csv(a.out / "fourier_solver_score.csv", index=False)
        meta["own_errors"] = own
    if "time" in stages:
        timing(cam, a.rays, a.cache, a.repeats).to_csv(a.out / "fourier_solver_time.csv", index=False)
    if "dense" in stages:
        dense(cam, a.planes).to_csv(a.out / "fourier_solver_dense.csv", index=False)
    meta.setdefault("wall_s", {})[a.stage] = time.perf_counter() - t_all
    atomic_write_text(meta_path, json.dumps(meta, indent=2, default=str))
    write_md(a.out, meta)


def write_md(out: Path, meta):
    parts = ["# The admm solver on the exact operator (`python experiments/fourier_solver.py`)", "",
             f"Renders: ray tracer at {meta['rays']} rays per pixel; their own error against the exact light field "
             f"(two seeds): " + (", ".join(f"{k} {100 * v:.2f} %" for k, v in meta.get("own_errors", {}).items())
                                 or "see the json") + f". Noise: shot + read at {meta['snr_db']:g} dB (measured).",
             f"Chosen on validation renders, per noise level: {meta.get('chosen')}; the renders' relative noise "
             f"(`lf_flame.tomo.noise_knobs.relative_noise`): {meta.get('noise_levels')}; the package's defaults "
             f"hold the choice: {meta.get('defaults_hold_the_choice')}. pd-tv's worst validation plane: "
             f"{meta.get('pd_tv_validation_worst')}.", ""]
    p = out / "fourier_solver_score.csv"
    if p.exists():
        parts += ["## Worst plane per render (relative L2 error), scored renders", "",
                  summary(pd.read_csv(p)).to_markdown(index=False, floatfmt=".3f"), ""]
    p = out / "fourier_solver_time.csv"
    if p.exists():
        parts += ["## Time of one 4-plane solve (one run; setup apart)", "",
                  pd.read_csv(p).to_markdown(index=False, floatfmt=".3f"), ""]
    p = out / "fourier_solver_dense.csv"
    if p.exists():
        parts += ["## Dense stacks (volumetric flame, 16-ray render; float32)", "",
                  pd.read_csv(p).to_markdown(index=False, floatfmt=".2f"), ""]
    parts += [f"Provenance: {json.dumps(meta['provenance'])[:400]} ...", ""]
    atomic_write_text(out / "fourier_solver.md", "\n".join(parts))


if __name__ == "__main__":
    main()
