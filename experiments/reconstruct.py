"""Each plane's emission from one light field, scored against the truth (``make reconstruct``).

Writes to ``--out`` (default ``results``):

- ``reconstruct.csv``: one row per route, scene, noise level, render and plane
  (:func:`lf_flame.tomo.scoring`: relative L2 error, SSIM, PSNR, flame height
  error and its flags, time). Routes: ``refocus-adjoint`` (``A^T y / A^T 1``, plain
  refocusing through the operator's rays: the baseline row), ``refocus-shift-sum``
  (:func:`lf_flame.refocus.shift_and_sum.focal_stack`, bilinear) and every solver at the iterations
  chosen on validation renders.
- ``reconstruct_iters.csv``: error against iterations and time of every solver, on the
  validation renders (the choice, and the speed-accuracy rows of ``make tradeoff``).
- ``reconstruct_tail.csv``: the flame height error of every plane of ``--tail`` fresh
  varied-regime flame scenes (4 rays per pixel, analytic slopes), shift-and-sum beside
  the chosen solver.
- ``reconstruct.md`` (tables) and ``reconstruct.json`` (provenance, timing of one
  operator pair beside one 4-plane ``focal_stack``); figures ``reconstruct_*.png``.

Scenes (``lf_flame.simulate.scenes``): the paper's four flames in both regimes, the overlap scene
(flames one behind another), the volumetric flame; each noise-free and with shot + read
noise at ``--snr-db`` (14 dB: the LSQR-LMBC paper's). Seeds: validation renders
``VAL_SEEDS``, scored renders ``TEST_SEEDS``, the tail ``TAIL_SEED0 + i``: three
disjoint streams that no dataset file uses.

Usage: ``python experiments/reconstruct.py --out results [--tests 3] [--tail 200] [--stage all|main|tail]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from tqdm import tqdm  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_refocus import _times  # noqa: E402

from lf_flame.simulate import scenes  # noqa: E402
from lf_flame.simulate.scenes_volume import volume_flame_scene  # noqa: E402
from lf_flame.simulate import tracer as simulate
from lf_flame.measure.metrics import own_error  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.measure.diagnostics import EMISSION_MEASURE  # noqa: E402
from lf_flame.routes import measure_settings  # noqa: E402
from lf_flame.measure.scoring import error_table, score_stacks  # noqa: E402
from lf_flame.tomo.solvers import DEFAULT_SOLVER, SOLVERS, reconstruct
from lf_flame.tomo.operator import EmissionOperator
from lf_flame.tomo.truth import scene_truth
from lf_flame.tomo.scoring import score_planes
from lf_flame.tomo.files import plot_reconstruction  # noqa: E402
from lf_flame.refocus.shift_and_sum import aperture_mask, focal_stack, raw_to_views  # noqa: E402

VAL_SEEDS = (920001, 920002)
TEST_SEEDS = (930001, 930002, 930003, 930004, 930005)
TAIL_SEED0 = 940000
RAYS_DATA = 16          # rays per pixel of the rendered light fields (the datasets')
RAYS_OP = 4             # rays per pixel of the operator
#: every solver's knobs tried on the validation renders (iterations are read off one run)
CANDIDATES = {"fista": [{}], "lsqr": [dict(damp=0.0)], "rl": [{}], "pd-tv": [dict(tv=0.1), dict(tv=0.3), dict(tv=1.0)]}
MAX_ITERS = 60
CHECKPOINTS = (5, 10, 15, 20, 30, 40, 50, 60)
#: how flames are measured on planes of emission: the candidates tried (``--stage edges``), each region picked as
#: ``EMISSION_MEASURE`` picks it (the one holding the most light)
EDGE_CANDIDATES = [dict(segment_fraction=s, edge_fit_range=(lo, hi), pick=EMISSION_MEASURE["pick"]) for s, lo, hi in (
    (0.3, 0.2, 0.6), (0.2, 0.1, 0.5), (0.1, 0.1, 0.5), (0.1, 0.1, 0.4), (0.1, 0.05, 0.4), (0.1, 0.05, 0.3),
    (0.05, 0.05, 0.5))]
#: validation scenes whose true emission the candidates are measured on (no render needed)
EDGE_SEED0 = 960000


def build_scene(kind: str, cam, seed: int):
    rng = np.random.default_rng(seed)
    if kind in ("paper", "varied"):
        return scenes.flame_scene(cam, rng, regime=kind)
    if kind == "overlap":
        return scenes.overlap_scene(cam, rng)
    if kind == "volume":
        return volume_flame_scene(cam, rng)
    raise ValueError(kind)


def planes_of(kind: str, scene) -> list:
    """Depths (mm) of the reconstruction planes: the flames' own, or 5 planes through a volume
    (evenly from its first layer to its last, 2.4 mm apart: none on a layer)."""
    if kind == "volume":
        d = [L.depth_offset_mm for L in scene.layers]
        return list(np.linspace(min(d), max(d), 5))
    return [float(o["depth_offset_mm"]) for o in scene.objects]


def noisy(cam, scene, raw_clean, snr_db, seed):
    """The scene rendered again with shot and read noise (2 e-) whose full well gives
    ``snr_db`` (measured, within 0.2 dB) over the clean raw image; the same seed keeps the
    same rays, and the noise falls on the light before the sensor clips it (a pixel
    saturates as a real one does).
    Returns (raw, measured SNR dB, full well)."""
    if snr_db is None:
        return raw_clean, np.inf, None
    s = raw_clean.astype(np.float64)
    read = 2.0
    # noise power sum(s) / fw + N read^2 / fw^2 = sum(s^2) / 10^(snr/10): a quadratic in 1 / fw
    a, b, c = s.size * read ** 2, s.sum(), -np.sum(s ** 2) / 10 ** (snr_db / 10)
    fw = 1.0 / ((-b + np.sqrt(b * b - 4 * a * c)) / (2 * a))
    for _ in range(4):   # saturated pixels are noise-free: shrink the full well until the SNR is measured
        fx = dataclasses.replace(scene.effects, full_well_e=float(fw), read_noise_e=read)
        raw = simulate.render(cam, dataclasses.replace(scene, effects=fx), RAYS_DATA, seed)
        snr = 10 * np.log10(np.sum(s ** 2) / np.sum((raw - s) ** 2))
        if abs(snr - snr_db) < 0.2:
            break
        fw /= 10 ** ((snr - snr_db) / 10)
    return raw, float(snr), float(fw)


def cached_render(cam, scene, rays, seed, path: Path, snr_db):
    """The scene traced at ``rays`` per pixel (views noise-free and at ``snr_db``), its own error
    ``||r_1 - r_2|| / (sqrt 2 ||r_1||)`` from a second seed and the measured SNR, kept in ``path``
    (.npz, written to a temporary file and renamed) and read back from it when there.
    Returns (clean views, noisy views, own error, SNR dB)."""
    global RAYS_DATA
    if not path.exists():
        RAYS_DATA = rays
        raw = simulate.render(cam, scene, rays, seed)
        other = simulate.render(cam, scene, rays, seed + 7)
        own = own_error(raw, other)
        loud, snr, _ = noisy(cam, scene, raw, snr_db, seed)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".partial.npz")
        np.savez_compressed(tmp, clean=raw, noisy=loud, own=own, snr=snr)
        tmp.rename(path)
    f = np.load(path)
    n = cam.pixels_per_lenslet
    return raw_to_views(f["clean"], n), raw_to_views(f["noisy"], n), float(f["own"]), float(f["snr"])


def light_field(kind, cam, seed, snr_db):
    scene = build_scene(kind, cam, seed)
    raw, snr, fw = noisy(cam, scene, simulate.render(cam, scene, RAYS_DATA, seed), snr_db, seed)
    depths = planes_of(kind, scene)
    op = EmissionOperator(cam, depths, rays_per_pixel=RAYS_OP)
    objects = None if kind == "volume" else scene.objects
    return scene, raw_to_views(raw, cam.pixels_per_lenslet), depths, op, scene_truth(scene, op), objects, snr


def rel_errors(x, truth):
    x = x.reshape(truth.shape)
    return np.linalg.norm((x - truth).reshape(len(x), -1), axis=1) / np.linalg.norm(truth.reshape(len(x), -1), axis=1)


def iteration_curves(cam, kinds, noise_levels):
    """Error per plane at CHECKPOINTS of every candidate, from one run each, on VAL_SEEDS."""
    rows = []
    for kind in kinds:
        for snr_db in noise_levels:
            for seed in VAL_SEEDS:
                scene, views, depths, op, truth, objects, snr = light_field(kind, cam, seed, snr_db)
                for solver, cands in CANDIDATES.items():
                    for kw in cands:
                        t0 = time.perf_counter()
                        marks = {}

                        def cb(k, x):
                            if k in CHECKPOINTS:
                                marks[k] = (time.perf_counter() - t0, rel_errors(x, truth))
                        reconstruct(views, op, solver, MAX_ITERS, callback=cb, **kw)
                        for k, (t, e) in marks.items():
                            rows += [dict(scene=kind, snr_db=snr_db if snr_db else np.inf, snr_measured_db=snr,
                                          seed=seed, solver=solver, knobs=json.dumps(kw), iters=k, time_s=t,
                                          plane=p, depth_mm=depths[p], rel_err=e[p]) for p in range(len(depths))]
                print(f"  validation {kind} snr={snr_db} seed={seed} done", flush=True)
    return pd.DataFrame(rows)


def choose(curves: pd.DataFrame, slack: float = 1.1) -> tuple[dict, str]:
    """Per solver, the knobs and the fewest iterations whose score is within ``slack`` of
    the solver's best, and the solver whose choice scores best: *the* chosen solver.
    Score: the worst over the validation renders (noise-free and noisy) of each render's
    worst plane error."""
    worst = curves.groupby(["solver", "knobs", "iters", "scene", "snr_db", "seed"]).rel_err.max().reset_index()
    score = worst.groupby(["solver", "knobs", "iters"]).rel_err.max().reset_index()
    ok = score[score.rel_err <= slack * score.groupby("solver").rel_err.transform("min")]
    best = ok.sort_values(["iters", "rel_err"]).groupby("solver").head(1)
    per_solver = {r.solver: dict(iters=int(r.iters), **json.loads(r.knobs)) for r in best.itertuples()}
    return per_solver, str(best.sort_values("rel_err").solver.iloc[0])


def score_tests(cam, kinds, noise_levels, chosen, best, n_tests, figdir):
    rows = []
    n = cam.pixels_per_lenslet
    mask = aperture_mask(n, "circular")
    for kind in kinds:
        for snr_db in noise_levels:
            for seed in TEST_SEEDS[:n_tests]:
                scene, views, depths, op, truth, objects, snr = light_field(kind, cam, seed, snr_db)
                labels = dict(scene=kind, snr_db=snr_db if snr_db else np.inf, snr_measured_db=snr, seed=seed)
                # the floor: the diagnostics on the true emission itself
                rows.append(score_planes(truth, truth, cam, depths, objects, time_s=0.0, route="truth",
                                         measure=measure_settings("truth"), **labels))
                t0 = time.perf_counter()
                fs = focal_stack(views, [cam.slope_for_depth(d) for d in depths], mask)
                rows.append(score_planes(fs, truth, cam, depths, objects, time_s=time.perf_counter() - t0,
                                         route="refocus-shift-sum", **labels))
                adj = reconstruct(views, op, "adjoint")
                rows.append(score_planes(adj.planes, truth, cam, depths, objects, time_s=adj.time_s,
                                         route="refocus-adjoint", **labels))
                for solver, kw in chosen.items():
                    kw = dict(kw)
                    rec = reconstruct(views, op, solver, kw.pop("iters"), **kw)
                    rows.append(score_planes(rec.planes, truth, cam, depths, objects, time_s=rec.time_s,
                                             route=f"reconstruct-{solver}", iters=rec.settings["iters"],
                                             measure=measure_settings(f"reconstruct-{solver}"), **labels))
                    if solver == best and seed == TEST_SEEDS[0]:
                        tag = f"{kind}_{'clean' if snr_db is None else f'{snr_db:.0f}dB'}"
                        plot_reconstruction(figdir / f"reconstruct_{tag}.png", rec, adj.planes, truth,
                                            title=f"{kind} scene, {tag}: {solver} {rec.settings['iters']} it., "
                                                  f"{rec.time_s:.1f} s | refocused | truth")
                print(f"  test {kind} snr={snr_db} seed={seed} done", flush=True)
    return pd.concat(rows, ignore_index=True)


def tail(cam, solver, knobs, seeds):
    """Height errors (:func:`lf_flame.measure.scoring.score_stacks`, flags included) of every
    plane of fresh varied flame scenes, one per seed: shift-and-sum beside ``solver``."""
    rows = []
    depths = list(scenes.PAPER_DEPTHS_MM)
    op = EmissionOperator(cam, depths, rays_per_pixel=RAYS_OP)
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    kw = dict(knobs)
    iters = kw.pop("iters", None)
    for seed in tqdm(seeds, desc="tail", unit="scene"):
        scene = scenes.flame_scene(cam, np.random.default_rng(seed), regime="varied")
        views = raw_to_views(simulate.render(cam, scene, 4, seed), cam.pixels_per_lenslet)
        fs = focal_stack(views, [cam.slope_for_depth(d) for d in depths], mask)
        rec = reconstruct(views, op, solver, iters, **kw)
        for route, st in (("refocus-shift-sum", fs), (f"reconstruct-{solver}", rec.planes)):
            rows.append(score_stacks(np.clip(st, 0, None)[None], cam, [scene.objects], samples=[seed],
                                     measure=measure_settings(route), route=route))
    return pd.concat(rows, ignore_index=True)


def edge_scores(cam, solver, knobs, noise_levels, n_truth=80):
    """Height errors of flames on planes of emission under every :data:`EDGE_CANDIDATES`
    setting: the true emission on the grid of ``n_truth`` validation scenes per kind
    (seeds ``EDGE_SEED0 + i``), and ``solver``'s reconstructions of the ``VAL_SEEDS``
    renders at every noise level. Validation only: no scored render enters."""
    rows = []

    def measure(planes, objects, **labels):
        for j, kw in enumerate(EDGE_CANDIDATES):
            rows.append(score_stacks(np.clip(planes, 0, None)[None], cam, [objects], measure=kw, candidate=j,
                                     segment_fraction=kw["segment_fraction"], edge_fit_range=str(kw["edge_fit_range"]),
                                     **labels))
    kw = dict(knobs)
    iters = kw.pop("iters", None)
    for kind in ("paper", "varied", "overlap"):
        for i in range(n_truth):
            scene = build_scene(kind, cam, EDGE_SEED0 + i)
            op = EmissionOperator(cam, planes_of(kind, scene), rays_per_pixel=RAYS_OP)
            measure(scene_truth(scene, op), scene.objects, route="truth", scene=kind, seed=EDGE_SEED0 + i,
                    snr_db=np.inf)
        for snr_db in noise_levels:
            for seed in VAL_SEEDS:
                scene, views, depths, op, truth, objects, snr = light_field(kind, cam, seed, snr_db)
                measure(reconstruct(views, op, solver, iters, **kw).planes, objects, route=f"reconstruct-{solver}",
                        scene=kind, seed=seed, snr_db=snr_db if snr_db else np.inf)
        print(f"  edges {kind} done", flush=True)
    return pd.concat(rows, ignore_index=True)


def choose_edges(df: pd.DataFrame) -> tuple[int, pd.DataFrame]:
    """The candidate with the lowest worst height error over its trusted planes (truth and
    reconstructions together), and the table of every candidate per route."""
    d = df.assign(flags=df["flags"].fillna(""), failure=df["failure"].fillna(""))
    table = error_table(d, ("candidate", "segment_fraction", "edge_fit_range", "route"))
    ok = d[(d["flags"] == "") & (d["failure"] == "")]
    worst = ok.groupby("candidate").height_err_mm.max()
    return int(worst.idxmin()), table


def fwhm(z, p) -> float:
    """Full width at half maximum (units of ``z``) of the profile ``p`` sampled at ``z``
    (increasing), by linear interpolation of the half-maximum crossings on either side of
    the peak; a side that never falls below half is cut at the sampled range."""
    p = np.asarray(p, float)
    k = int(np.argmax(p))
    half = p[k] / 2
    i, j = k, k
    while i > 0 and p[i - 1] > half:
        i -= 1
    while j < len(p) - 1 and p[j + 1] > half:
        j += 1
    lo = z[0] if i == 0 else np.interp(half, [p[i - 1], p[i]], [z[i - 1], z[i]])
    hi = z[-1] if j == len(p) - 1 else np.interp(half, [p[j + 1], p[j]], [z[j + 1], z[j]])
    return float(hi - lo)


#: axial resolution: point sources at these depths (mm), planes every AXIAL_STEP_MM within
#: AXIAL_HALF_RANGE_MM of each, on a 41 x 41 lenslet crop of the paper's camera (same optics)
AXIAL_DEPTHS_MM = (-10.0, 0.0, 10.0, 20.0)
AXIAL_STEP_MM = 0.25
AXIAL_HALF_RANGE_MM = 8.0


def axial_resolution(solver, knobs):
    """The axial response of a point source: a Gaussian spot (1 lenslet footprint sigma,
    radiance 0.8) alone at each of :data:`AXIAL_DEPTHS_MM`, rendered noise-free, then
    reconstructed by ``solver`` on planes every :data:`AXIAL_STEP_MM` through it, beside the
    shift-and-sum focal stack on the same planes. Response per plane: the brightest value
    within one lenslet of the point. Returns (profiles, summary): the summary gives each
    route's FWHM along depth and the depth step that moves the point by one lenslet
    between the outermost views of the aperture (the views' parallax)."""
    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.measure.diagnostics import lenslet_size_mm
    from lf_flame.tomo.operator import FLAME_EFFECTS
    cam = PlenopticCamera(n_rows=41, n_cols=41)      # the paper's optics, a crop of its lenslet grid
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    n_views = int(mask.sum(axis=1).max())            # views across the aperture's diameter
    c = cam.n_rows // 2
    kw = dict(knobs)
    iters = kw.pop("iters", None)
    yy, xx = np.mgrid[-4:5, -4:5]
    spot = (0.8 * np.exp(-(yy ** 2 + xx ** 2) / 2.0)).astype(np.float32)   # 3 texels per lenslet footprint
    profiles, summary = [], []
    for z0 in AXIAL_DEPTHS_MM:
        s = lenslet_size_mm(cam, z0)
        scene = scenes.Scene("point", (scenes.Layer(spot, None, z0, (0.0, 0.0), (3 * s, 3 * s)),), FLAME_EFFECTS)
        views = raw_to_views(simulate.render(cam, scene, RAYS_DATA, 1), cam.pixels_per_lenslet)
        planes = z0 + np.arange(-AXIAL_HALF_RANGE_MM, AXIAL_HALF_RANGE_MM + 1e-9, AXIAL_STEP_MM)
        rec = reconstruct(views, EmissionOperator(cam, planes, rays_per_pixel=RAYS_OP), solver, iters, **kw)
        fs = focal_stack(views, [cam.slope_for_depth(d) for d in planes], mask)
        row = dict(depth_mm=z0, lenslet_mm=s, solve_s=rec.time_s)
        for route, st in ((f"reconstruct-{solver}", rec.planes), ("refocus-shift-sum", fs)):
            resp = st[:, c - 1:c + 2, c - 1:c + 2].max(axis=(1, 2))
            profiles += [dict(point_depth_mm=z0, route=route, plane_mm=float(d), response=float(v))
                         for d, v in zip(planes, resp)]
            row[f"fwhm_mm {route}"] = fwhm(planes, resp)
            row[f"peak_at_mm {route}"] = float(planes[int(np.argmax(resp))])
        s0, ds = cam.slope_for_depth(z0), 1.0 / (n_views - 1)
        row["parallax_step_mm"] = abs(cam.depth_for_slope(s0 + ds) - cam.depth_for_slope(s0 - ds)) / 2
        summary.append(row)
        print(f"  axial {z0:+g} mm: {row}", flush=True)
    return pd.DataFrame(profiles), pd.DataFrame(summary)


def tail_table(df: pd.DataFrame, by=("route",)) -> pd.DataFrame:
    cols = ["n", "n_failed", "n_flagged", "height_err_mm", "share_over_1mm", "height_err_mm_p90", "height_err_mm_max",
            "share_over_1mm_trusted", "height_err_mm_p90_trusted", "height_err_mm_max_trusted"]
    return error_table(df.assign(flags=df["flags"].fillna(""), failure=df["failure"].fillna("")), by)[list(by) + cols]


def time_pair(cam, repeats=7, chosen=None, solve_repeats=3):
    """One operator pair (A, A^T) beside one 4-plane focal_stack, same light field, same run,
    from the recorded map and traced (``ray_table=False``), and the recording itself (one
    first ``A``); with ``chosen`` ({solver: knobs}), one whole 4-plane reconstruction by each
    solver too, and by the default solver on the traced operator."""
    depths = list(scenes.PAPER_DEPTHS_MM)
    op = EmissionOperator(cam, depths, rays_per_pixel=RAYS_OP)
    scene = scenes.flame_scene(cam, np.random.default_rng(VAL_SEEDS[0]), regime="varied")
    views = raw_to_views(simulate.render(cam, scene, RAYS_DATA, 0), cam.pixels_per_lenslet)
    x = np.random.default_rng(0).random(op.shape[1])
    y = views.astype(np.float64).ravel()
    slopes = [cam.slope_for_depth(d) for d in depths]
    mask = aperture_mask(cam.pixels_per_lenslet, "circular")
    traced = EmissionOperator(cam, depths, rays_per_pixel=RAYS_OP, ray_table=False)
    out = {}

    def put(name, f, n):
        out[name] = dict(zip(("median_ms", "p10_ms", "p90_ms"), map(float, _times(f, n))))
    put("record the operator's rays (once)",
        lambda: EmissionOperator(cam, depths, rays_per_pixel=RAYS_OP).matvec(x), 3)
    for name, f in (("A", lambda: op.matvec(x)), ("A^T", lambda: op.rmatvec(y)),
                    ("A traced", lambda: traced.matvec(x)), ("A^T traced", lambda: traced.rmatvec(y)),
                    ("focal_stack", lambda: focal_stack(views, slopes, mask))):
        put(name, f, repeats)
    for solver, knobs in (chosen or {}).items():
        kw = dict(knobs)
        it = kw.pop("iters")
        put(f"reconstruct {solver} {it} it.", lambda: reconstruct(views, op, solver, it, **kw), solve_repeats)
        if solver == DEFAULT_SOLVER:
            put(f"reconstruct {solver} {it} it. traced", lambda: reconstruct(views, traced, solver, it, **kw),
                solve_repeats)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", default="results")
    p.add_argument("--tests", type=int, default=3, help="scored renders per scene and noise level")
    p.add_argument("--tail", type=int, default=200, help="fresh varied scenes of the height-error tail")
    p.add_argument("--snr-db", type=float, default=14.0)
    p.add_argument("--kinds", default="paper,varied,overlap,volume")
    p.add_argument("--stage", choices=["all", "main", "score", "tail", "report", "timing", "edges", "axial"],
                   default="all",
                   help="tail: only the height tail (--tail-solver and its knobs, scenes --tail-first ... + --tail); "
                        "main: all but the tail (the report reads an existing reconstruct_tail.csv); score: main "
                        "with the validation curves read from reconstruct_iters.csv in --out, not rerun; report: "
                        "measure nothing, rewrite reconstruct.md from the CSVs and reconstruct.json in --out; timing: "
                        "time A, A^T, focal_stack and each chosen solver (from reconstruct_iters.csv) on a quiet "
                        "machine -> reconstruct_timing.json, read by the report")
    p.add_argument("--tail-first", type=int, default=0, help="first tail scene (seed TAIL_SEED0 + it): shards")
    p.add_argument("--tail-solver", default="rl", choices=[s for s in SOLVERS if s != "adjoint"])
    p.add_argument("--tail-knobs", default="{}", help='JSON, e.g. {"iters": 40, "tv": 0.3}')
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    cam = PAPER_CAMERA
    t0 = time.perf_counter()
    tail_seeds = range(TAIL_SEED0 + a.tail_first, TAIL_SEED0 + a.tail_first + a.tail)
    if a.stage == "tail":
        tl = tail(cam, a.tail_solver, json.loads(a.tail_knobs), tail_seeds)
        atomic_write_text(out / "reconstruct_tail.csv", tl.to_csv(index=False, float_format="%.5g"))
        print(tail_table(tl).to_string(index=False), f"\n{(time.perf_counter() - t0) / 60:.1f} min")
        return
    tail_csv = out / "reconstruct_tail.csv"
    if a.stage == "timing":
        timing = time_pair(cam, chosen=choose(pd.read_csv(out / "reconstruct_iters.csv"))[0])
        atomic_write_text(out / "reconstruct_timing.json", json.dumps(dict(timing_ms=timing, provenance=provenance()),
                                                                      indent=2, default=str))
        print(pd.DataFrame(timing).T.to_string())
        return
    if a.stage == "edges":
        chosen, best = choose(pd.read_csv(out / "reconstruct_iters.csv"))
        df = edge_scores(cam, best, chosen[best], (None, a.snr_db))
        keep = ["candidate", "segment_fraction", "edge_fit_range", "route", "scene", "seed", "snr_db", "depth_mm",
                "height_mm_true", "height_mm", "height_err_mm", "base_err_mm", "tip_err_mm", "flags", "failure"]
        atomic_write_text(out / "reconstruct_edges.csv", df[keep].to_csv(index=False, float_format="%.5g"))
        j, table = choose_edges(df)
        atomic_write_text(out / "reconstruct_edges.json", json.dumps(dict(
            choice=EDGE_CANDIDATES[j], candidates=EDGE_CANDIDATES, solver=best, knobs=chosen[best], val_seeds=VAL_SEEDS,
            edge_seed0=EDGE_SEED0, table=table.to_dict("records"), provenance=provenance(),
            wall_time_s=time.perf_counter() - t0), indent=2, default=float))
        print(table.to_string(index=False), "\nchoice:", EDGE_CANDIDATES[j])
        if EDGE_CANDIDATES[j] != {k: v for k, v in EMISSION_MEASURE.items()}:
            print(f"lf_flame.measure.diagnostics.EMISSION_MEASURE is {EMISSION_MEASURE}: set it to the choice")
        return
    if a.stage == "axial":
        chosen, best = choose(pd.read_csv(out / "reconstruct_iters.csv"))
        prof, summ = axial_resolution(best, chosen[best])
        atomic_write_text(out / "reconstruct_axial.csv", prof.to_csv(index=False, float_format="%.5g"))
        atomic_write_text(out / "reconstruct_axial.json", json.dumps(dict(
            summary=summ.to_dict("records"), solver=best, knobs=chosen[best], step_mm=AXIAL_STEP_MM,
            provenance=provenance(), wall_time_s=time.perf_counter() - t0), indent=2, default=float))
        plot_axial(out / "reconstruct_axial.png", prof)
        print(summ.to_string(index=False))
        return
    if a.stage == "report":
        j = json.loads((out / "reconstruct.json").read_text())
        tl = pd.read_csv(tail_csv, keep_default_na=False, na_values=[""]) if tail_csv.exists() else pd.DataFrame()
        curves = pd.read_csv(out / "reconstruct_iters.csv")
        chosen, best = choose(curves)    # the same choice, from the same curves
        write_report(out, pd.read_csv(out / "reconstruct.csv"), curves, tl, chosen, best, j["timing_ms"], a,
                     j["wall_time_s"], j["provenance"])
        return
    kinds = a.kinds.split(",")
    noise = (None, a.snr_db)
    timing = time_pair(cam)
    print("timing", timing, flush=True)
    if a.stage == "score":
        curves = pd.read_csv(out / "reconstruct_iters.csv")
    else:
        curves = iteration_curves(cam, [k for k in kinds if k in ("varied", "overlap")], noise)
        atomic_write_text(out / "reconstruct_iters.csv", curves.to_csv(index=False, float_format="%.5g"))
    chosen, best = choose(curves)
    print("chosen on validation renders:", chosen, "best:", best, flush=True)
    scores = score_tests(cam, kinds, noise, chosen, best, a.tests, out)
    atomic_write_text(out / "reconstruct.csv", scores.to_csv(index=False, float_format="%.5g"))
    if a.stage == "all":
        tl = tail(cam, best, chosen[best], tail_seeds)
        atomic_write_text(out / "reconstruct_tail.csv", tl.to_csv(index=False, float_format="%.5g"))
    tl = pd.read_csv(tail_csv, keep_default_na=False, na_values=[""]) if tail_csv.exists() else pd.DataFrame()
    write_report(out, scores, curves, tl, chosen, best, timing, a, time.perf_counter() - t0, provenance())


def _versus(worst: pd.DataFrame, route: str) -> pd.DataFrame:
    """Per scene and noise: ``route``'s worst plane (error, height error, time) beside
    shift-and-sum's on the same renders, and the ratio of their worst-plane errors."""
    key = ["scene", "noise"]
    r = worst[worst.route == route].set_index(key)
    b = worst[worst.route == "refocus-shift-sum"].set_index(key)
    t = worst[worst.route == "truth"].set_index(key).reindex(r.index)
    return pd.DataFrame({"worst_plane_rel_err": r.worst_plane_rel_err,
                         "shift_sum_worst_plane_rel_err": b.worst_plane_rel_err,
                         "ratio": r.worst_plane_rel_err / b.worst_plane_rel_err,
                         "worst_height_err_mm": r.worst_height_err_mm,
                         "shift_sum_worst_height_err_mm": b.worst_height_err_mm,
                         "truth_worst_height_err_mm": t.worst_height_err_mm,
                         "time_s_median": r.time_s_median, "time_s_worst": r.time_s_worst}).reset_index()


def plot_axial(path, prof: pd.DataFrame) -> None:
    """Each point's response along depth, per route, normalised to its peak."""
    import matplotlib.pyplot as plt
    pts = sorted(prof.point_depth_mm.unique())
    fig, ax = plt.subplots(1, len(pts), figsize=(3.2 * len(pts), 2.8), squeeze=False)
    for a_, z0 in zip(ax[0], pts):
        for route, g in prof[prof.point_depth_mm == z0].groupby("route"):
            a_.plot(g.plane_mm - z0, g.response / g.response.max(), label=route)
        a_.axhline(0.5, color="0.6", lw=0.8)
        a_.set_title(f"point at {z0:+g} mm", fontsize=9)
        a_.set_xlabel("plane − point depth (mm)", fontsize=8)
    ax[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(out, scores, curves, tl, chosen, best, timing, a, wall, prov):
    s = scores.assign(noise=np.where(np.isinf(scores.snr_db), "noise-free", f"{a.snr_db:g} dB"))
    per_plane = s.groupby(["scene", "noise", "route", "depth_mm"], sort=False).agg(
        rel_err=("rel_err", "mean"), rel_err_worst=("rel_err", "max"), ssim=("ssim", "mean"),
        psnr_db=("psnr_db", "mean"), height_err_mm=("height_err_mm", "mean"),
        height_err_worst=("height_err_mm", "max"), time_s=("time_s", "median")).reset_index()
    worst = s.groupby(["scene", "noise", "route"], sort=False).agg(
        worst_plane_rel_err=("rel_err", "max"), mean_rel_err=("rel_err", "mean"),
        worst_height_err_mm=("height_err_mm", "max"), time_s_median=("time_s", "median"),
        time_s_worst=("time_s", "max")).reset_index()
    lines = ["# Each plane's emission, reconstructed from one light field (`make reconstruct`)", "",
             f"Command: `python experiments/reconstruct.py --out {a.out} --tests {a.tests} --tail {a.tail} "
             f"--snr-db {a.snr_db:g}`; wall time {wall / 60:.1f} min. Solver settings chosen on validation renders "
             f"(seeds {VAL_SEEDS}; `reconstruct_iters.csv`): `{json.dumps(chosen)}`; **the chosen solver: "
             f"`{best}`** (the lowest worst-plane error over the validation renders). Scored on renders "
             f"{TEST_SEEDS[:a.tests]} ({RAYS_DATA} rays/pixel); operator {RAYS_OP} rays/pixel; relative error "
             "‖x̂ − x‖/‖x‖ per plane against the scene's emission on the grid (one sample per lenslet).", "",
             f"## The chosen solver (`{best}`) against refocusing (shift-and-sum), same renders", "",
             _versus(worst, f"reconstruct-{best}").to_markdown(index=False, floatfmt=".3f"), "",
             "## Worst plane per route (over planes and renders)", "",
             worst.to_markdown(index=False, floatfmt=".3f"), "",
             "## Per plane (mean over renders; worst beside it)", "",
             per_plane.to_markdown(index=False, floatfmt=".3f"), "",
             "## One operator pair beside one 4-plane focal stack (same light field, same run)", "",
             pd.DataFrame(timing).T.to_markdown(floatfmt=".1f"), ""]
    edges = out / "reconstruct_edges.json"
    if edges.exists():
        j = json.loads(edges.read_text())
        cols = ["segment_fraction", "edge_fit_range", "route", "n", "n_flagged", "height_err_mm", "height_bias_mm",
                "height_err_mm_p90_trusted", "height_err_mm_max_trusted"]
        lines += ["## How flames are measured on planes of emission (`--stage edges`, validation only)", "",
                  f"Chosen: `{json.dumps(j['choice'])}` (`lf_flame.measure.diagnostics.EMISSION_MEASURE`): the lowest worst "
                  "trusted height error over the true emission of 80 validation scenes per kind (seeds "
                  f"{j['edge_seed0']}+i, paper, varied, overlap) and `{j['solver']}`'s reconstructions of the "
                  "validation renders (noise-free and noisy). Refocused planes keep the defaults (first row).", "",
                  pd.DataFrame(j["table"])[cols].to_markdown(index=False, floatfmt=".3f"), ""]
    axial = out / "reconstruct_axial.json"
    if axial.exists():
        j = json.loads(axial.read_text())
        lines += [f"## Axial resolution: a point source (`--stage axial`, noise-free, `{j['solver']}` "
                  f"{json.dumps(j['knobs'])})", "",
                  f"A spot one lenslet footprint wide alone at each depth, planes every {j['step_mm']} mm through it "
                  "(41 x 41 lenslets of the paper's camera). FWHM along depth of the brightest value within one "
                  "lenslet of the point, reconstructed and refocused; *parallax step*: the depth change that moves "
                  "the point by one lenslet between the outermost views of the aperture. Figure: "
                  "`reconstruct_axial.png`.", "",
                  pd.DataFrame(j["summary"]).to_markdown(index=False, floatfmt=".3f"), ""]
    quiet = out / "reconstruct_timing.json"
    if quiet.exists():
        j = json.loads(quiet.read_text())
        lines += [f"## Times on a quiet machine (`--stage timing`, {j['provenance']['date']}, "
                  f"{j['provenance']['cpu_count']} cores): one paper light field, 4 planes", "",
                  "Each solver at its chosen iterations: the whole solve (operator applied, step found, "
                  "iterations); median and 10th-90th percentile of 3 solves after a warm-up.", "",
                  pd.DataFrame(j["timing_ms"]).T.to_markdown(floatfmt=".1f"), ""]
    if len(tl):
        lines += [f"## Flame height tail: {tl['sample'].nunique()} fresh varied scenes (seeds {TAIL_SEED0}+i, "
                  "4 rays/pixel, analytic slopes; `--stage tail`)", "",
                  "Absolute height error (mm); *trusted*: planes without flags (`FlameMeasurement.flags`).", "", tail_table(tl).to_markdown(index=False, floatfmt=".3f"), "",
                  tail_table(tl, ("route", "depth_mm")).to_markdown(index=False, floatfmt=".3f"), ""]
    atomic_write_text(out / "reconstruct.md", "\n".join(lines))
    atomic_write_text(out / "reconstruct.json", json.dumps(dict(
        provenance=prov, chosen=chosen, chosen_solver=best, timing_ms=timing, wall_time_s=wall, val_seeds=VAL_SEEDS,
        test_seeds=TEST_SEEDS[:a.tests], tail_seed0=TAIL_SEED0, tail=a.tail, snr_db=a.snr_db,
        rays_per_pixel_data=RAYS_DATA, rays_per_pixel_operator=RAYS_OP), indent=2, default=str))
    print((out / "reconstruct.md").read_text())


if __name__ == "__main__":
    main()
