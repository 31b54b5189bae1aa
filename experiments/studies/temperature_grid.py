"""A diagnosis: what limits two-colour pyrometry on the paper's planes, the planes' grid or the CFA?

On validation scenes only (the paper's four flames drawn with :data:`SEEDS`, distinct from the
scored 937000-937001), at ``--rays`` rays per pixel, noise-free and at 14 dB, each channel's
emission by admm (as ``admm-cfa``, :func:`lf_flame.temperature.channels.admm_channel`) on:

- the lenslet grid (``ExactOperator``, as ``results/temperature.md``) and the 2 x 2 grid per
  lenslet (``subsamples=2``, binned back to the lenslets before the ratio), through the CFA
  (each channel's own samples), unsmoothed and smoothed by a Gaussian of 0.7 lenslets
  (``admm-cfa-smooth``);
- the same through the CFA by the matched route (each channel re-imaged and solved again
  on the other channel's samples, :func:`lf_flame.temperature.channels.matched_channels`);
- the same without the CFA (each channel rendered on every pixel: the operator's own limit),
  noise-free and at 14 dB (each channel's full image with the shot and read noise of the
  mosaic's 14 dB full well: the same noise per pixel as through the CFA), the latter also with
  the monochrome admm knobs for 14 dB on the 2 x 2 grid (``ADMM_KNOBS[2, "noisy"]``).

Beside each plane: its slope (lenslets per view step) and the share of the red channel's
samples whose object position on that plane falls on an even lenslet row (0.5: the red
samples cover both row parities; near 0 or 1: the plane's odd or even rows are barely seen
in red). With an odd number of pixels per lenslet the CFA's phase alternates between lenslets,
and a view ``u`` steps the object position by the slope: at a slope near an odd integer
the red samples all land on one parity.

Writes ``<out>/temperature_grid.{csv,md}``.

Usage: ``python experiments/studies/temperature_grid.py --out results [--rays 400]``.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import dataclasses

import numpy as np
import pandas as pd

sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]  # experiments/, studies/
import temperature as E  # noqa: E402

from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.temperature import pyrometry as P  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.optics.colour import library_sensor  # noqa: E402
from lf_flame.refocus.shift_and_sum import raw_to_views  # noqa: E402
from lf_flame.simulate.scenes_temperature import colour_flame_scene  # noqa: E402
from lf_flame.simulate import tracer  # noqa: E402
from lf_flame.temperature.channels import CFA_LAM, admm_channel, matched_channels  # noqa: E402
from lf_flame.temperature.mosaic import channel_views  # noqa: E402
from lf_flame.temperature.ratio import smooth_planes  # noqa: E402
from lf_flame.tomo.defaults import ADMM_KNOBS  # noqa: E402
from lf_flame.tomo.exact import ExactOperator  # noqa: E402
from lf_flame.tomo.truth import bin_planes  # noqa: E402

SEEDS = (937500, 937501)
SIGMA = 0.7


def even_share(chan, slope, channel=0):
    """Share of ``channel``'s samples (views (N, N, R, C)) whose object row on a plane of ``slope``
    (lenslets per view step, about the central view) rounds to an even lenslet row."""
    n = chan.shape[0]
    u, _, r, _ = np.nonzero(chan == channel)
    return float(np.mean(np.round(r + slope * (u - (n - 1) / 2)) % 2 == 0))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--rays", type=int, default=400)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    cam, sensor, model = PAPER_CAMERA, library_sensor(gains=E.GAINS), library_sensor()
    cal = P.load_calibration(args.out / "temperature_calibration.json", model)
    n = cam.pixels_per_lenslet
    rows, own = [], {}
    for seed in SEEDS:
        cs = colour_flame_scene(cam, sensor, np.random.default_rng(seed))
        depths = [float(o["depth_offset_mm"]) for o in cs.scene.objects]
        ops = {1: ExactOperator(cam, depths, precision="float32"),
               2: ExactOperator(cam, depths, precision="float32", subsamples=2)}
        r = E.render_scene(cam, cs, sensor, args.rays, seed)
        own[seed] = r["own"]
        Tt, vt = E.true_temperature(cs, ops[1], cal, model)
        chan = channel_views(r["clean"].shape, sensor, n)
        slopes = [cam.slope_for_depth(d) for d in depths]
        plane = dict(slope=slopes, red_even_share=[even_share(chan, s) for s in slopes])
        full = [raw_to_views(tracer.apply_sensor(r["chans"][c].copy(), cs.scene.effects, seed), n) for c in (0, 1)]
        fx = dataclasses.replace(cs.scene.effects, full_well_e=r["fw"], read_noise_e=E.READ_E)
        full_noisy = [raw_to_views(tracer.apply_sensor(r["chans"][c].copy(), fx, seed + 11 + c), n) for c in (0, 1)]
        mono = {k: v for k, v in ADMM_KNOBS[2, "noisy"].items() if k in ("fills", "lam", "tv", "l1")}
        mosaic_views = {k: raw_to_views(r[k], n) for k in ("clean", "noisy")}
        cases = [("cfa", solve, noise, mosaic_views[k], {}) for solve in ("own samples", "matched")
                 for noise, k in (("clean", "clean"), ("14dB", "noisy"))]
        cases += [("no CFA", "own samples", "clean", full, {}), ("no CFA", "own samples", "14dB", full_noisy, {}),
                  ("no CFA", "own samples, 14 dB knobs", "14dB", full_noisy, mono)]
        for sub, op in ops.items():
            for data, route, noise, views, knobs in cases:
                t1 = time.perf_counter()
                knobs = knobs or dict(lam=CFA_LAM)
                if data == "no CFA":
                    rec = [admm_channel(v, op, v < 1, **knobs) for v in views]
                elif route == "matched":
                    rec = matched_channels(views, op, [(chan == c) & (views < 1) for c in (0, 1)], **knobs)
                else:
                    rec = [admm_channel(views, op, (chan == c) & (views < 1), **knobs) for c in (0, 1)]
                rec = [bin_planes(x, sub) for x in rec]
                dt = time.perf_counter() - t1
                for sigma in (0.0, SIGMA):
                    a, b = (smooth_planes(x, sigma) if sigma else x for x in rec)
                    for x in E.score(f"{data}, {route}, grid {sub}x{sub}", noise, seed, a, b, Tt, vt, cal, model,
                                     time_s=dt):
                        rows.append(dict(x, data=data, solve=route, subsamples=sub, sigma=sigma,
                                         **{k: v[x["plane"]] for k, v in plane.items()}))
            print(f"seed {seed} grid {sub} done", flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(args.out / "temperature_grid.csv", index=False)
    per_plane = df.assign(sigma=df.sigma.map(lambda v: f"{v:g} lenslet" if v else "none")).pivot_table(
        index=["data", "solve", "subsamples", "sigma", "noise"], columns="plane", values="p90_k",
        aggfunc="max").reset_index()
    per_plane.columns = [c if isinstance(c, str) else f"plane {c}" for c in per_plane.columns]
    planes = df.groupby("plane")[["slope", "red_even_share"]].first().reset_index()
    prov = provenance()
    atomic_write_text(args.out / "temperature_grid.md", "\n".join([
        "# Two-colour pyrometry on validation scenes: the planes' grid or the CFA?", "",
        f"Command: `python experiments/studies/temperature_grid.py --out {args.out} --rays {args.rays}`; wall time "
        f"{time.perf_counter() - t0:.0f} s; commit {prov.get('git_commit')}; seeds {SEEDS} (validation, not the scored "
        f"ones); own error of the renders {[round(v, 4) for v in own.values()]}; admm as `admm-cfa` "
        f"(lam {CFA_LAM}), except `14 dB knobs`: {mono}; the 2 x 2 grid binned to the lenslets before the ratio; "
        "no CFA at 14 dB: each channel's full image with the noise of the mosaic's full well.", "",
        "p90 |T error| (K) per plane, the worse of the two scenes, over the pixels >= 10 % of each plane's true peak "
        f"(as temperature.md); sigma: the Gaussian (lenslets) both channels are smoothed by (0: none, {SIGMA}: "
        "`admm-cfa-smooth`):", "",
        per_plane.to_markdown(index=False, floatfmt=".0f"), "",
        "Planes (0-3: +20, +10, 0, -10 mm from focus): slope (lenslets per view step) and the share of the red "
        "samples on even object rows (0.5: both parities seen; at a slope of exactly 1 it is 0):", "",
        planes.to_markdown(index=False, floatfmt=".3f"), ""]))
    print((args.out / "temperature_grid.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
