"""Two-colour pyrometry with a colour (Bayer) light-field camera.

Writes ``<out>/temperature.csv`` (one row per route, noise level and plane, and one per
blackbody check), ``<out>/temperature.md`` (the bars and the table), ``<out>/temperature.json``
(settings, own errors, measured SNR per channel, provenance, wall time) and
``<out>/temperature_calibration.json`` (the calibration, written atomically).

- **Camera**: the paper's (``PAPER_CAMERA``) with an RGGB CFA, phase (0, 0) (pixel (0, 0) is
  red), the Nikon 5100 sensitivities that colour-science ships, channel gains
  :data:`GAINS` (unknown to the pyrometer).
- **Calibration**: a blackbody furnace filling the field (``furnace_scene``) rendered at
  :data:`FIT_K`; the R/G gain ratio fitted (``fit_calibration``); checked on
  :data:`CHECK_K` (not fitted), noise-free and at 14 dB. The band-integrated lookup is
  compared with the monochromatic Wien formula over 1,500-2,500 K.
- **Flames**: the paper's four flames at the paper's planes, each with its own temperature
  field (``colour_flame_scene``: sheath peaks ``FLAME_PEAK_K``), the nominal scene and
  ``--scenes - 1`` drawn in the ``paper`` regime; rendered by the ray tracer at ``--rays``
  rays per pixel (own error from a second seed), noise-free and at 14 dB (shot + 2 e- read
  noise on the mosaic; SNR measured over each channel's pixels).
- **Routes** (each channel's emission, then R/G -> T by the calibration's lookup; pixels
  below 10 % of the plane's peak R+G masked and counted):
  ``admm-cfa-matched`` (the default of ``lf-flame temperature``): each channel by admm on its
  own pixels on a 2 x 2 grid per lenslet, re-imaged and solved again on the other channel's
  pixels (both channels through both sampling patterns), binned to the lenslets, with the
  admm knobs ``MATCHED_KNOBS`` of the light field's noise regime and the ratio filtered by
  ``MATCHED_RATIO_FILTER`` for that noise (:func:`lf_flame.temperature.channels.matched_channels`,
  :func:`lf_flame.temperature.ratio.filter_ratio`: averaged along the brightness contours when noisy, then
  a guided filter);
  ``admm-cfa``: the exact operator's admm on each channel's own pixels (the CFA complement
  as the missing-data mask); ``admm-cfa-smooth``: the same, both channels smoothed by a
  Gaussian of :data:`SMOOTH_SIGMA` lenslets before the ratio; ``refocus-cfa``: each
  channel's pixels refocused by shift-and-sum at the planes' slopes (mean over the views
  that hold that channel: the focal-stack ratio baseline); ``admm-full`` (noise-free, a
  reference, not a colour camera): admm on each channel's full, unmosaicked light field,
  what three sensors or a filter wheel would give, on the lenslet grid and (``2x2``) on the
  matched route's grid: the operator's own limit, what the CFA costs beside it.
- **Scores** per plane over pixels whose *true* R+G emission is >= 10 % of the plane's peak:
  |T - T_true| median, p90, worst over the pixels the route reports, and the truth pixels it
  masks. The truth temperature of a grid cell is the lookup of its true R/G emission ratio
  (the area-weighted truth of :func:`lf_flame.tomo.truth.resample_layer`).

- **Behind** (``--stage behind``): two flames in the same columns, one behind the other, at
  different temperatures (``colour_behind_scene``, sheath peaks ``BEHIND_PEAK_K``), depth
  separations :data:`BEHIND_SEPARATIONS_MM` alternating over ``--behind-scenes`` seeds; the
  same routes, scored per plane over all its bright pixels and over those where the other
  flame is bright on the same lenslet (where refocusing mixes them); written to
  ``<out>/temperature_behind.{csv,md,json}``.

Usage: ``python experiments/temperature.py --out results [--quick] [--stage all|flames|behind]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text, provenance
from lf_flame.measure.metrics import own_error
from lf_flame.temperature import pyrometry as P
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.optics.colour import library_sensor, mosaic
from lf_flame.refocus.shift_and_sum import raw_to_views
from lf_flame.simulate import tracer
from lf_flame.simulate.colour import render_colour
from lf_flame.simulate.scenes_temperature import (BEHIND_PEAK_K, FLAME_PEAK_K, colour_behind_scene, colour_flame_scene,
                                                  furnace_scene)
from lf_flame.temperature.channels import (CFA_FILLS as FILLS, CFA_LAM as LAM, CFA_TV as TV, MATCHED_KNOBS,
                                           MATCHED_QUIET_NOISE, MATCHED_RATIO_FILTER, MATCHED_SUBSAMPLES,
                                           MATCHED_WIDE_NOISE, admm_channel, channel_emission, colour_truth,
                                           route_operator)
from lf_flame.temperature.mosaic import channel_views
from lf_flame.temperature.ratio import SMOOTH_SIGMA, smooth_planes
from lf_flame.tomo.truth import bin_planes

GAINS = (1.0, 1.25, 0.8)
FIT_K = (1400.0, 1700.0, 2000.0, 2300.0, 2600.0)
CHECK_K = (1550.0, 1950.0, 2450.0)
SNR_DB = 14.0
READ_E = 2.0
SEED0 = 937000
#: furnace exposure: brightest channel at this fraction of saturation, so that 14 dB noise (about 20 %
#: per pixel) seldom reaches the clipping level, which would bias the brighter channel low
FURNACE_PEAK = 0.5
#: two flames one behind another: seeds and depth separations (mm), alternating
BEHIND_SEED0 = 937200
BEHIND_SEPARATIONS_MM = (10.0, 20.0)
BARS = dict(p90_clean=30.0, worst_clean=80.0, p90_noisy=60.0, blackbody=5.0)
#: the matched route's settings, as the reports record them
MATCHED = dict(subsamples=MATCHED_SUBSAMPLES, knobs=MATCHED_KNOBS, quiet_noise=MATCHED_QUIET_NOISE,
               ratio_filter=MATCHED_RATIO_FILTER, wide_noise=MATCHED_WIDE_NOISE)


def full_well_for(clean: np.ndarray, snr_db: float, read: float = READ_E) -> float:
    """Full well (e-) giving ``snr_db`` over the image with shot and read noise (as make reconstruct)."""
    s = clean.astype(np.float64)
    a, b, c = s.size * read ** 2, s.sum(), -np.sum(s ** 2) / 10 ** (snr_db / 10)
    return float(1.0 / ((-b + np.sqrt(b * b - 4 * a * c)) / (2 * a)))


def add_noise(clean, effects, seed, target_db=SNR_DB):
    """Shot and read noise on a noise-free mosaic at ``target_db`` (measured within 0.2 dB: the full
    well is corrected up to 4 times, as make reconstruct does). Returns (noisy, full well)."""
    fw = full_well_for(clean, target_db)
    for _ in range(4):
        fx = dataclasses.replace(effects, full_well_e=fw, read_noise_e=READ_E)
        noisy = tracer.apply_sensor(clean.copy(), fx, seed)
        snr = snr_db(clean, noisy)
        if abs(snr - target_db) < 0.2:
            break
        fw /= 10 ** ((snr - target_db) / 10)
    return noisy, fw


def snr_db(clean, noisy) -> float:
    """SNR (dB) of ``noisy`` against the noise-free ``clean``, over the whole image."""
    c = clean.astype(np.float64)
    return float(10 * np.log10(np.sum(c ** 2) / np.sum((noisy - c) ** 2)))


def setup(out):
    """The paper's camera, the colour sensor (with :data:`GAINS`) and the pyrometer's model of it, and the
    calibration the flames stage wrote to ``out``: (cam, sensor, model, cal)."""
    cam, sensor, model = PAPER_CAMERA, library_sensor(gains=GAINS), library_sensor()
    return cam, sensor, model, P.load_calibration(Path(out) / "temperature_calibration.json", model)


def scene_case(cam, cs, sensor, rays, seed, cal, model):
    """A colour scene rendered (:func:`render_scene`), each plane's true temperature on the lenslet grid
    (:func:`true_temperature`) and the views' channel map: (depths, r, Tt, vt, chan)."""
    depths = [float(o["depth_offset_mm"]) for o in cs.scene.objects]
    r = render_scene(cam, cs, sensor, rays, seed)
    Tt, vt = true_temperature(cs, route_operator(cam, depths, "admm-cfa"), cal, model)
    return depths, r, Tt, vt, channel_views(r["clean"].shape, sensor, cam.pixels_per_lenslet)


def flame_scenes(seeds, rays, cam, sensor, model, cal):
    """The paper's four flames drawn with each seed of ``seeds`` (the validation scripts' scenes) and
    :func:`scene_case`'d, with the matched route's operator: yields (seed, cs, r, Tt, vt, chan, op)."""
    for seed in seeds:
        cs = colour_flame_scene(cam, sensor, np.random.default_rng(seed))
        depths, r, Tt, vt, chan = scene_case(cam, cs, sensor, rays, seed, cal, model)
        yield seed, cs, r, Tt, vt, chan, route_operator(cam, depths, "admm-cfa-matched")


def ratio_filter_label(f: dict) -> str:
    """A ratio filter's name in the validation scripts' tables (``MATCHED_RATIO_FILTER``'s form): e.g.
    ``"contour 8 + guided r1 eps0.1"``, ``"guided r1 eps0.001"``; ``"none"`` for an empty dict."""
    if not f:
        return "none"
    contour = f"contour {f['contour']:g} + " if f.get("contour") else ""
    return f"{contour}guided r{f['radius']} eps{f['eps']:g}"


def true_temperature(cs, op, cal, model):
    """Each plane's true temperature (K) and truth mask of a colour scene on ``op``'s grid:
    :func:`colour_truth`'s R and G through the calibration's lookup. Returns (Tt, vt)."""
    truth = colour_truth(cs.channel_radiance, cs.scene.layers, op)
    Tt, vt, _ = P.temperature_planes(truth[0], truth[1], cal, model)
    return Tt, vt


def snr_per_channel(clean, noisy, chan):
    return {c: float(10 * np.log10(np.sum(clean[chan == i].astype(float) ** 2)
                                   / np.sum((noisy[chan == i].astype(float) - clean[chan == i]) ** 2)))
            for i, c in enumerate("RGB")}


def calibrate(cam, sensor, model, rays, seed, out):
    rows, ratios = [], []
    for T in FIT_K:
        sc, ch = furnace_scene(cam, sensor, T, FURNACE_PEAK)
        ratios.append(P.blackbody_ratio(render_colour(cam, sc, ch, sensor, rays, seed), model, cam.pixels_per_lenslet))
    cal = P.fit_calibration(model, FIT_K, ratios)
    P.write_calibration(out / "temperature_calibration.json", cal)
    cal = P.load_calibration(out / "temperature_calibration.json", model)
    for T in CHECK_K:
        sc, ch = furnace_scene(cam, sensor, T, FURNACE_PEAK)
        clean = render_colour(cam, sc, ch, sensor, rays, seed + 1)
        noisy, _ = add_noise(clean, sc.effects, seed + 1)
        for noise, raw in (("clean", clean), (f"{SNR_DB:g}dB", noisy)):
            t = float(P.ratio_to_temperature(P.blackbody_ratio(raw, model, cam.pixels_per_lenslet), cal, model, alpha=0.0))
            rows.append(dict(kind="blackbody", route="calibration", noise=noise, true_k=T, measured_k=t,
                             error_k=t - T, worst_k=abs(t - T)))
    return cal, rows


def score(route, noise, scene_id, a, b, Tt, vt, cal, model, **extra):
    Tr, valid, _ = P.temperature_planes(a, b, cal, model)
    rows = []
    for k in range(len(Tt)):
        sel = vt[k] & valid[k]
        err = np.abs(Tr[k] - Tt[k])[sel]
        rows.append(dict(kind="flame", route=route, noise=noise, scene=scene_id, plane=k, n_truth=int(vt[k].sum()),
                         n_reported=int(sel.sum()), n_masked=int((vt[k] & ~valid[k]).sum()),
                         n_outside_truth=int((valid[k] & ~vt[k]).sum()),
                         median_k=float(np.median(err)) if err.size else np.nan,
                         p90_k=float(np.percentile(err, 90)) if err.size else np.nan,
                         worst_k=float(err.max()) if err.size else np.nan, **extra))
    return rows


def operators(cam, depths):
    """The routes' operators: the matched route's grid and the lenslet grid of the others."""
    return {route: route_operator(cam, depths, route) for route in ("admm-cfa-matched", "admm-cfa")}


def render_scene(cam, cs, sensor, rays, seed):
    """Each channel rendered twice (own error), mosaicked, clipped; and at 14 dB. Returns a dict."""
    t0 = time.perf_counter()
    chans, other = [], []
    for c in range(3):
        layers = tuple(dataclasses.replace(L, radiance=cs.channel_radiance[k][c])
                       for k, L in enumerate(cs.scene.layers))
        sc = dataclasses.replace(cs.scene, layers=layers)
        chans.append(tracer.render(cam, sc, rays, seed, sensor=False))
        other.append(tracer.render(cam, sc, rays, seed + 7, sensor=False))
    chans, other = np.stack(chans), np.stack(other)
    own = own_error(chans, other)
    clean = tracer.apply_sensor(mosaic(chans, sensor), cs.scene.effects, seed)   # clipping only
    noisy, fw = add_noise(clean, cs.scene.effects, seed)
    snr = snr_per_channel(clean, noisy, sensor.channel_map(clean.shape))
    return dict(chans=chans, own=own, clean=clean, noisy=noisy, fw=fw, snr=snr, snr_all=snr_db(clean, noisy),
                render_s=time.perf_counter() - t0)


def route_rows(cam, sensor, ops, depths, r, scorer, log, tag):
    """Every route on the clean and the 14 dB render; ``scorer(route, noise, a, b, **extra)`` -> rows.
    ``ops``: the routes' operators (:func:`operators`)."""
    rows, op = [], ops["admm-cfa"]
    chan_v = channel_views(r["clean"].shape, sensor, cam.pixels_per_lenslet)
    slopes = [cam.slope_for_depth(d) for d in depths]
    for noise, raw in (("clean", r["clean"]), (f"{SNR_DB:g}dB", r["noisy"])):
        views = raw_to_views(raw, cam.pixels_per_lenslet)
        lab = dict(snr_db=r["snr_all"] if noise != "clean" else np.inf, own_error=r["own"])
        t0 = time.perf_counter()
        chosen = {}
        m = channel_emission("admm-cfa-matched", views, chan_v, (0, 1), op=ops["admm-cfa-matched"], info=chosen)
        rows += scorer("admm-cfa-matched", noise, m[0], m[1], time_s=time.perf_counter() - t0,
                       sigma=chosen["sigma"], ratio_filter=str(chosen["ratio_filter"]), measured_noise=chosen["noise"],
                       fills=chosen["knobs"]["fills"],
                       lam=chosen["knobs"]["lam"], **lab)
        t0 = time.perf_counter()
        rec = channel_emission("admm-cfa", views, chan_v, (0, 1), op=op)
        rows += scorer("admm-cfa", noise, rec[0], rec[1], time_s=time.perf_counter() - t0, **lab)
        rows += scorer("admm-cfa-smooth", noise, smooth_planes(rec[0]), smooth_planes(rec[1]), **lab)
        t0 = time.perf_counter()
        fs = channel_emission("refocus-cfa", views, chan_v, (0, 1), slopes=slopes)
        rows += scorer("refocus-cfa", noise, fs[0], fs[1], time_s=time.perf_counter() - t0, **lab)
        if noise == "clean":
            full = [raw_to_views(r["chans"][c], cam.pixels_per_lenslet) for c in (0, 1)]
            for name, o in (("admm-full (no CFA, reference)", op),
                            ("admm-full 2x2 (no CFA, reference)", ops["admm-cfa-matched"])):
                rec = [bin_planes(admm_channel(v, o, v < 1), o.subsamples) for v in full]
                rows += scorer(name, noise, rec[0], rec[1], **lab)
        log(f"  {tag} {noise} done")
    return rows


def flames(cam, sensor, model, cal, n_scenes, rays, log):
    rows, info = [], []
    ops = {}
    for i in range(n_scenes):
        seed = SEED0 + i
        cs = colour_flame_scene(cam, sensor, None if i == 0 else np.random.default_rng(seed))
        depths = [float(o["depth_offset_mm"]) for o in cs.scene.objects]
        key = tuple(depths)
        if key not in ops:
            ops[key] = operators(cam, depths)
        op = ops[key]["admm-cfa"]
        r = render_scene(cam, cs, sensor, rays, seed)
        info.append(dict(scene=i, seed=seed, peaks_k=list(FLAME_PEAK_K), depths_mm=depths, own_error=r["own"],
                         full_well_e=r["fw"], snr_db=r["snr_all"], snr_db_per_channel=r["snr"],
                         render_s=r["render_s"], heights_mm=[o["height_mm"] for o in cs.scene.objects]))
        log(f"  scene {i}: own error {r['own']:.4f}, SNR {r['snr_all']:.2f} dB {r['snr']}")
        Tt, vt = true_temperature(cs, op, cal, model)

        def scorer(route, noise, a, b, **extra):
            return score(route, noise, i, a, b, Tt, vt, cal, model, **extra)

        rows += route_rows(cam, sensor, ops[key], depths, r, scorer, log, f"scene {i}")
    return rows, info


def behind(cam, sensor, model, cal, n_scenes, rays, log):
    """Two flames in the same columns at different temperatures: scored per plane over all its bright
    pixels and over those where the other flame is bright on the same lenslet (refocusing mixes them)."""
    rows, info = [], []
    for i in range(n_scenes):
        seed = BEHIND_SEED0 + i
        sep = BEHIND_SEPARATIONS_MM[i % len(BEHIND_SEPARATIONS_MM)]
        cs = colour_behind_scene(cam, sensor, np.random.default_rng(seed), sep)
        depths = [float(o["depth_offset_mm"]) for o in cs.scene.objects]
        ops = operators(cam, depths)
        r = render_scene(cam, cs, sensor, rays, seed)
        Tt, vt = true_temperature(cs, ops["admm-cfa"], cal, model)
        mixed = vt & vt[::-1]
        info.append(dict(scene=i, seed=seed, separation_mm=sep, peaks_k=list(BEHIND_PEAK_K), depths_mm=depths,
                         heights_mm=[o["height_mm"] for o in cs.scene.objects], own_error=r["own"],
                         full_well_e=r["fw"], snr_db=r["snr_all"], snr_db_per_channel=r["snr"],
                         render_s=r["render_s"], n_mixed=[int(m.sum()) for m in mixed]))
        log(f"  behind {i} ({sep:g} mm, depths {[round(d, 2) for d in depths]}): own error {r['own']:.4f}, SNR "
            f"{r['snr_all']:.2f} dB, mixed pixels {[int(m.sum()) for m in mixed]}")

        def scorer(route, noise, a, b, **extra):
            out = []
            for region, v in (("mixed", mixed), ("all", vt)):
                out += [dict(x, region=region, separation_mm=sep, depth_mm=depths[x["plane"]])
                        for x in score(route, noise, i, a, b, Tt, v, cal, model, **extra)]
            return out

        rows += route_rows(cam, sensor, ops, depths, r, scorer, log, f"behind {i}")
    return rows, info


def write_behind(out, df, info, cal_note, args, wall, prov):
    df.to_csv(out / "temperature_behind.csv", index=False)
    cols = ["route", "noise", "scene", "plane", "region", "n_truth", "n_masked", "median_k", "p90_k", "worst_k"]
    g = df.groupby(["route", "noise", "region"]).agg(p90_worst_plane=("p90_k", "max"), worst=("worst_k", "max"),
                                                     median_median=("median_k", "median"),
                                                     masked=("n_masked", "sum"), truth=("n_truth", "sum")).reset_index()
    lines = ["# Two-colour pyrometry: two flames one behind another", "",
             f"Command: `python experiments/temperature.py --stage behind --out {args.out}"
             f"{' --quick' if args.quick else ''}` (also `make temperature`); wall time {wall:.0f} s; commit "
             f"{prov.get('git_commit')}. {cal_note}", "",
             f"Scenes: `colour_behind_scene` (the geometry of `scenes_depth.behind_scene`: two flames in the same "
             f"columns, far one taller), sheath peaks far/near {BEHIND_PEAK_K} K, separations "
             f"{[x['separation_mm'] for x in info]} mm, seeds {[x['seed'] for x in info]}, depths "
             f"{[[round(d, 2) for d in x['depths_mm']] for x in info]} mm (far, near), rays/pixel {args.rays}, own "
             f"error {[round(x['own_error'], 4) for x in info]}; 14 dB: measured SNR "
             f"{[round(x['snr_db'], 2) for x in info]} dB, per channel "
             f"{[{k: round(v, 2) for k, v in x['snr_db_per_channel'].items()} for x in info]}.", "",
             "Per plane (0 far, 1 near) over its pixels with >= 10 % of its true peak R+G emission (`all`), and "
             "over those where the other flame is also >= 10 % of its peak on the same lenslet (`mixed`: where "
             "refocusing mixes the two): |T - T_true| (K) over the pixels the route reports; `n_masked`: truth "
             "pixels left without a temperature. Routes as in temperature.md.", "",
             df[cols].to_markdown(index=False, floatfmt=".1f"), "", "## Bar: each plane within 50 K p90 where "
             "refocusing mixes them", "", g.to_markdown(index=False, floatfmt=".1f"), ""]
    for (route, noise), r in g[g.region == "mixed"].groupby(["route", "noise"]):
        v = float(r.p90_worst_plane.iloc[0])
        lines.append(f"- `{route}` {noise}: worst plane's p90 over the mixed pixels {v:.0f} K (bar 50) -> "
                     f"**{'met' if v <= 50 else 'NOT met'}**")
    lines.append("")
    atomic_write_text(out / "temperature_behind.md", "\n".join(lines))
    atomic_write_text(out / "temperature_behind.json", json.dumps(dict(
        provenance=prov, wall_time_s=wall, rays_per_pixel=args.rays, scenes=info, gains=GAINS, snr_db=SNR_DB,
        read_noise_e=READ_E, admm=dict(fills=FILLS, lam=LAM, tv=TV), smooth_sigma_lenslets=SMOOTH_SIGMA,
        matched=MATCHED, calibration=cal_note), indent=2, default=str))


def wien_difference(cal, model):
    t = np.arange(1500.0, 2501.0, 1.0)
    out = {}
    for name, alpha in (("soot", 1.39), ("blackbody", 0.0)):
        r = cal.gain_ratio * P.model_ratio(model, t, cal.channels, alpha)
        d = P.wien_temperature(r, cal, model, alpha) - t
        out[name] = dict(max_abs_k=float(np.abs(d).max()), at_1500_k=float(d[0]), at_2000_k=float(d[500]),
                         at_2500_k=float(d[-1]))
    return out


def write_report(out, df, info, cal, wien, args, wall, prov):
    df.to_csv(out / "temperature.csv", index=False)
    bb = df[df.kind == "blackbody"]
    fl = df[df.kind == "flame"]
    lines = ["# Two-colour pyrometry with a colour light-field camera", "",
             f"Command: `python experiments/temperature.py --out {args.out}"
             f"{' --stage ' + args.stage if args.stage != 'all' else ''}{' --quick' if args.quick else ''}` "
             f"(`make temperature`); wall time {wall:.0f} s; commit {prov.get('git_commit', prov.get('commit'))}.",
             "Camera: the paper's, RGGB CFA phase (0, 0) (pixel (0, 0) red), Nikon 5100 (NPL) sensitivities "
             f"(colour-science), channel gains {GAINS} (unknown to the pyrometer); R/G ratio; soot emissivity "
             "∝ λ^-1.39 (Hottel & Broughton 1932).", "",
             "## Calibration (blackbody furnace)", "",
             f"Fitted on {FIT_K} K (rays/pixel {args.rays}; furnace exposure: brightest channel at {FURNACE_PEAK} of saturation): gain ratio {cal.gain_ratio:.5f} (true "
             f"{GAINS[0] / GAINS[1]:.5f}); fit residuals {[round(x, 3) for x in cal.fit_residuals_k]} K.", "",
             "Temperatures not used in the fit (bar: within 5 K):", "",
             bb[["noise", "true_k", "measured_k", "error_k"]].to_markdown(index=False, floatfmt=".2f"), "",
             f"Worst: {bb.worst_k.max():.2f} K -> **{'met' if bb.worst_k.max() <= BARS['blackbody'] else 'NOT met'}**.",
             "", "Band-integrated lookup against the monochromatic Wien formula (sensitivity centroids), "
             "1,500-2,500 K (T_Wien - T):", "",
             pd.DataFrame(wien).T.to_markdown(floatfmt=".1f"), "",
             "## The paper's four flames at the paper's planes", "",
             f"Sheath peaks {FLAME_PEAK_K} K (planes 0-3 = depths +20, +10, 0, -10 mm); scenes: "
             f"{len(info)} (nominal first); rays/pixel {args.rays}; own error of the renders "
             f"{[round(x['own_error'], 4) for x in info]}; 14 dB: measured SNR "
             f"{[round(x['snr_db'], 2) for x in info]} dB overall, per channel "
             f"{[{k: round(v, 2) for k, v in x['snr_db_per_channel'].items()} for x in info]}.", "",
             "Per plane over the pixels with >= 10 % of the plane's true peak R+G emission: |T - T_true| (K) over "
             "those the route reports; `n_masked`: truth pixels it leaves without a temperature (below 10 % "
             "of its own peak, or ratio out of the table).", ""]
    cols = ["route", "noise", "scene", "plane", "n_truth", "n_masked", "median_k", "p90_k", "worst_k"]
    lines += [fl[cols].to_markdown(index=False, floatfmt=".1f"), "", "## Bars", ""]
    g = fl.groupby(["route", "noise"]).agg(p90_worst_plane=("p90_k", "max"), worst=("worst_k", "max"),
                                          median_median=("median_k", "median"),
                                          masked=("n_masked", "sum"), truth=("n_truth", "sum")).reset_index()
    lines += [g.to_markdown(index=False, floatfmt=".1f"), ""]
    for route in g.route.unique():
        r = g[g.route == route].set_index("noise")
        msg = []
        if "clean" in r.index:
            msg.append(f"noise-free p90 {r.loc['clean', 'p90_worst_plane']:.0f} K (bar 30), worst "
                       f"{r.loc['clean', 'worst']:.0f} K (bar 80)")
        nz = f"{SNR_DB:g}dB"
        if nz in r.index:
            msg.append(f"14 dB p90 {r.loc[nz, 'p90_worst_plane']:.0f} K (bar 60)")
        ok = (("clean" not in r.index or (r.loc["clean", "p90_worst_plane"] <= 30 and r.loc["clean", "worst"] <= 80))
              and (nz not in r.index or r.loc[nz, "p90_worst_plane"] <= 60))
        lines.append(f"- `{route}`: {'; '.join(msg)} -> **{'met' if ok else 'NOT met'}** (worst plane of all scenes)")
    lines += ["", "Two flames one behind another: `temperature_behind.md` (`--stage behind`). Not measured here: per "
              "voxel (see `temperature_volume.md`).", ""]
    atomic_write_text(out / "temperature.md", "\n".join(lines))
    atomic_write_text(out / "temperature.json", json.dumps(dict(
        provenance=prov, wall_time_s=wall, rays_per_pixel=args.rays, scenes=info, gains=GAINS, fit_k=FIT_K,
        check_k=CHECK_K, snr_db=SNR_DB, read_noise_e=READ_E, admm=dict(fills=FILLS, lam=LAM, tv=TV),
        smooth_sigma_lenslets=SMOOTH_SIGMA,
        matched=MATCHED, calibration=dataclasses.asdict(cal), wien=wien), indent=2, default=str))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--quick", action="store_true", help="one scene at 16 rays/pixel (minutes)")
    ap.add_argument("--rays", type=int, default=None, help="rays per pixel (default 400; --quick 16)")
    ap.add_argument("--scenes", type=int, default=None, help="flame scenes (default 2; --quick 1)")
    ap.add_argument("--stage", choices=["all", "flames", "behind"], default="all",
                    help="flames: calibration and the paper's four flames (temperature.*); behind: two flames one "
                         "behind another (temperature_behind.*; the calibration in --out if there, else fitted)")
    ap.add_argument("--behind-scenes", type=int, default=None, help="behind scenes (default 4; --quick 1)")
    args = ap.parse_args(argv)
    n_behind = args.behind_scenes or (1 if args.quick else 4)
    args.rays = args.rays or (16 if args.quick else 400)
    n_scenes = args.scenes or (1 if args.quick else 2)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    cam = PAPER_CAMERA
    sensor = library_sensor(gains=GAINS)
    model = library_sensor()

    def log(msg):
        print(msg, flush=True)

    calfile = args.out / "temperature_calibration.json"
    if args.stage == "behind" and calfile.is_file():
        cal = P.load_calibration(calfile, model)
        cal_note = f"Calibration: {calfile.name} (written by the flames stage), gain ratio {cal.gain_ratio:.5f}."
    else:
        cal, bb_rows = calibrate(cam, sensor, model, args.rays, SEED0, args.out)
        log(f"calibration: gain ratio {cal.gain_ratio:.5f}; checks {[round(r['error_k'], 3) for r in bb_rows]} K")
        cal_note = f"Calibration: fitted in this run, gain ratio {cal.gain_ratio:.5f}."
    if args.stage in ("all", "flames"):
        wien = wien_difference(cal, model)
        rows, info = flames(cam, sensor, model, cal, n_scenes, args.rays, log)
        df = pd.DataFrame(bb_rows + rows)
        write_report(args.out, df, info, cal, wien, args, time.perf_counter() - t0, provenance())
        print((args.out / "temperature.md").read_text())
    if args.stage in ("all", "behind"):
        t1 = time.perf_counter()
        rows, info = behind(cam, sensor, model, cal, n_behind, args.rays, log)
        write_behind(args.out, pd.DataFrame(rows), info, cal_note, args, time.perf_counter() - t1, provenance())
        print((args.out / "temperature_behind.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
