"""A diagnosis: the depths found in a colour capture of two flames one behind another.

Scenes: ``colour_behind_scene`` (two flames in the same columns, the far one taller, sheath peaks
2,050 K far and 1,800 K near) on the paper's camera behind an RGGB mosaic (Nikon 5100 sensitivities,
channel gains unknown to the pyrometer), separations 5, 10 and 20 mm in turn, seeds from :data:`SEED0`
(never scored elsewhere), rendered at ``--rays`` rays per pixel, noise-free. Each capture's depths as
found by:

- ``temperature``: ``lf-flame temperature RAW --route admm-cfa`` (its planes are found before its route runs:
  the fastest route gives the default route's planes);
- ``reconstruct``: ``lf-flame reconstruct RAW`` (the red and green samples levelled into one light
  field, depths found, the solve's residual searched and the depths of flames one behind another
  refined: the found planes' route);
- ``green, monochrome``: a yardstick, the found planes' route
  (:func:`lf_flame.tomo.found_planes.find_planes`) on the green channel rendered on every pixel: what a
  monochrome camera of the same flames finds.

Scored per scene: the flames with a found depth within 1 mm (``found``), the found depths with no flame
within 1 mm (``false``), and each found plane's share of the solved emission (reconstruct).

Writes ``<out>/colour_behind_depths.{csv,md}``.

Usage: ``python experiments/studies/colour_behind_depths.py --out results [--scenes 9] [--rays 64]``.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np
import pandas as pd

sys.path[:0] = [str(Path(__file__).resolve().parents[1])]  # experiments/
from lf_flame.cli import main as cli  # noqa: E402
from lf_flame.config import atomic_write_text, provenance  # noqa: E402
from lf_flame.measure.metrics import own_error  # noqa: E402
from lf_flame.optics.camera import PAPER_CAMERA  # noqa: E402
from lf_flame.optics.colour import library_sensor  # noqa: E402
from lf_flame.refocus.shift_and_sum import raw_to_views  # noqa: E402
from lf_flame.simulate import tracer  # noqa: E402
from lf_flame.simulate.colour import render_colour  # noqa: E402
from lf_flame.simulate.scenes_temperature import colour_behind_scene  # noqa: E402
from lf_flame.tomo.found_planes import find_planes  # noqa: E402
from temperature import GAINS  # noqa: E402

SEED0 = 937950
SEPARATIONS_MM = (10.0, 20.0, 5.0)
#: A flame is found where a found depth lies within this of it (mm).
MATCH_MM = 1.0
CALIBRATION = Path(__file__).resolve().parents[2] / "results" / "temperature_calibration.json"


def score(truth, found) -> dict:
    """Flames with a found depth within :data:`MATCH_MM`, and found depths with no flame so near."""
    t, f = np.asarray(truth, float), np.asarray(found, float)
    near = np.abs(t[:, None] - f[None, :]) <= MATCH_MM if f.size else np.zeros((t.size, 0), bool)
    return dict(found=int(near.any(axis=1).sum()), false=int((~near.any(axis=0)).sum()),
                depths_mm=json.dumps(np.round(f, 2).tolist()))


def run_cli(argv) -> None:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        if cli([str(a) for a in argv]) != 0:
            raise SystemExit(f"lf-flame {' '.join(map(str, argv))} failed")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scenes", type=int, default=9)
    ap.add_argument("--rays", type=int, default=64)
    args = ap.parse_args(argv)
    t_start = time.perf_counter()
    cam, sensor = PAPER_CAMERA, library_sensor(gains=GAINS)
    rows, own = [], None
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.scenes):
            seed, sep = SEED0 + i, SEPARATIONS_MM[i % len(SEPARATIONS_MM)]
            cs = colour_behind_scene(cam, sensor, np.random.default_rng(seed), sep)
            truth = sorted(float(o["depth_offset_mm"]) for o in cs.scene.objects)
            raw = render_colour(cam, cs.scene, cs.channel_radiance, sensor, args.rays, seed)
            if own is None:          # the renders' own error: the first scene rendered again with other rays
                own = own_error(raw, render_colour(cam, cs.scene, cs.channel_radiance, sensor, args.rays, seed + 7))
            path = Path(tmp) / f"b{seed}.npz"
            np.savez(path, raw=raw, camera=json.dumps(cam.to_dict()),
                     sensor=json.dumps(dict(name=sensor.name, pattern=sensor.pattern, phase=list(sensor.phase))))
            base = dict(seed=seed, separation_mm=sep, truth_mm=json.dumps(np.round(truth, 2).tolist()))
            for route, argv in (("temperature", ["temperature", path, "--calibration", CALIBRATION, "--route",
                                                 "admm-cfa"]),
                                ("reconstruct", ["reconstruct", path])):
                out = Path(tmp) / f"{route}.h5"
                t0 = time.perf_counter()
                run_cli(argv + ["--no-figure", "--out", out])
                with h5py.File(out) as f:
                    depths = f["depths_mm"][:]
                    planes = f["planes"][:] if route == "reconstruct" else None
                shares = None if planes is None else planes.reshape(len(planes), -1).sum(axis=1)
                rows.append(dict(base, route=route, **score(truth, depths), wall_s=time.perf_counter() - t0,
                                 emission_share=None if shares is None else
                                 json.dumps(np.round(shares / shares.sum(), 3).tolist())))
            layers = tuple(dataclasses.replace(L, radiance=cs.channel_radiance[k][1])
                           for k, L in enumerate(cs.scene.layers))
            green = tracer.render(cam, dataclasses.replace(cs.scene, layers=layers), args.rays, seed)
            t0 = time.perf_counter()
            found, _, _ = find_planes(raw_to_views(green, cam.pixels_per_lenslet), cam)
            rows.append(dict(base, route="green, monochrome", **score(truth, found.planes_mm),
                             wall_s=time.perf_counter() - t0, emission_share=None))
            print(f"  {i + 1}/{args.scenes} seed {seed}: " + "; ".join(
                f"{r['route']} {r['depths_mm']}" for r in rows[-3:]) + f" (truth {base['truth_mm']})", flush=True)
    df = pd.DataFrame(rows)
    summary = df.groupby("route", sort=False).agg(scenes=("seed", "size"), flames_found=("found", "sum"),
                                                  false_depths=("false", "sum"), wall_s_median=("wall_s", "median"))
    summary.insert(1, "flames", 2 * summary.scenes)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "colour_behind_depths.csv", df.to_csv(index=False))
    prov = provenance()
    atomic_write_text(args.out / "colour_behind_depths.md", "\n".join([
        "# Depths found in a colour capture of two flames one behind another", "",
        f"`python experiments/studies/colour_behind_depths.py --out {args.out} --scenes {args.scenes} --rays "
        f"{args.rays}` ({time.perf_counter() - t_start:.0f} s). `colour_behind_scene` on the paper's camera behind "
        f"an RGGB mosaic, separations {list(SEPARATIONS_MM)} mm in turn, seeds {SEED0}-{SEED0 + args.scenes - 1}, "
        f"{args.rays} rays per pixel (own error {100 * own:.1f} %: the first scene rendered again with other rays), "
        f"noise-free. A flame is found where a found depth lies within {MATCH_MM:g} mm "
        "of it; a false depth has no flame so near. Routes: the module docstring.", "",
        summary.reset_index().to_markdown(index=False, floatfmt=".2f"), "",
        "Per scene (`emission_share`: each found plane's share of reconstruct's solved emission):", "",
        df.to_markdown(index=False, floatfmt=".2f"), "",
        f"Provenance: `{json.dumps(prov)}`", ""]))
    print(summary.to_string())
    return 0


if __name__ == "__main__":
    sys.exit(main())
