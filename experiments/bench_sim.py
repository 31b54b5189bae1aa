"""Simulator benchmark (``make bench-sim``): throughput, cost of each effect, error against rays.

Writes ``<out>/bench_sim.csv``, ``<out>/bench_sim.md`` and ``<out>/bench_sim.json``
(provenance). All figures are measured in this one run on this machine:

- throughput: Mray/s end to end (sample generation + tracing + binning + sensor
  model) of :func:`lf_flame.simulate.tracer.render` against the plain NumPy version of the same
  chain (:func:`lf_flame.simulate.tracer.render_reference`);
- effects: ms per raw image for each effect set, each switched on alone;
- sampling: RMSE of the raw image against a high-sample reference for each ray count
  (the data behind the default rays per pixel);
- forward vs backward: the same single flame layer traced object -> sensor
  (:func:`lf_flame.simulate._kernels.render_forward`) and sensor -> object, error against time.

Usage: ``python experiments/bench_sim.py --out results [--quick]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numba
import numpy as np
import pandas as pd

from lf_flame.simulate import _kernels as _simulate_kernels
from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.config import atomic_write_text, provenance


def _time(fn, repeats):
    fn()  # warm-up (and JIT compile)
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * float(np.median(ts)), 1e3 * float(np.min(ts))


def _rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a, np.float64) - b) ** 2)))


def _with(scene, **fx):
    return dataclasses.replace(scene, effects=dataclasses.replace(scene.effects, **fx))


#: the benchmark's sections, in the order they run (column ``section`` of the table)
SECTIONS = ("throughput", "effects", "sampling", "forward vs backward")


def run(quick: bool, sections=SECTIONS) -> pd.DataFrame:
    """The benchmark's rows (one per section, scene, method and setting), measured here.

    ``quick``: the 41 x 41 lenslet camera and fewer repeats and ray counts; ``sections``: the
    ones of :data:`SECTIONS` to measure (``make tradeoff`` uses only 'effects' and 'sampling').

    Raises
    ------
    ValueError
        ``sections`` names a section that is not in :data:`SECTIONS`.
    """
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        raise ValueError(f"sections must be among {SECTIONS}. Received: {sorted(unknown)}")
    cam = PlenopticCamera(n_rows=41, n_cols=41) if quick else PAPER_CAMERA
    repeats = 2 if quick else 7
    ref_rpp = 64 if quick else 256
    rpps = (1, 4, 16) if quick else (1, 2, 4, 8, 16, 32, 64)
    n_px = cam.sensor_shape[0] * cam.sensor_shape[1]
    rng = np.random.default_rng(2025)
    shapes, flame = scenes.shapes_scene(cam, rng), scenes.flame_scene(cam, rng)
    point = scenes.point_scene(cam, 10.0)
    rows = []

    def add(section, scene, method, setting, rpp, n_rays, ms, rmse=np.nan):
        rows.append(dict(section=section, scene=scene, method=method, setting=setting, rays_per_pixel=rpp,
                         n_rays=n_rays, ms_median=ms[0], ms_min=ms[1], mray_s=n_rays / ms[0] / 1e3, rmse=rmse))

    if "throughput" in sections:
        # throughput, Numba kernel against the NumPy version of the same chain
        for name, sc in (("shapes", shapes), ("flame", flame), ("point", point)):
            for rpp in (1, 4, 16):
                add("throughput", name, "numba", "scene's effects", rpp, n_px * rpp,
                    _time(lambda: simulate.render(cam, sc, rpp, 0), repeats))
            add("throughput", name, "numpy", "scene's effects", 4, n_px * 4,
                _time(lambda: simulate.render_reference(cam, sc, 4, 0), 1))

    if "effects" in sections:
        # each effect on its own, against none (additive layers, no aperture, no cos^4)
        bare = _with(shapes, aperture=False, cos4=False, occlusion=False)
        sets = {"none": {}, "aperture": dict(aperture=True), "cos4": dict(cos4=True), "occlusion": dict(occlusion=True),
                "crosstalk": dict(crosstalk=True), "shot+read noise": dict(full_well_e=10000.0, read_noise_e=5.0),
                "12-bit": dict(bit_depth=12), "paper shapes (aperture, cos4, occlusion)":
                dict(aperture=True, cos4=True, occlusion=True)}
        for label, fx in sets.items():
            add("effects", "shapes", "numba", label, 4, n_px * 4,
                _time(lambda: simulate.render(cam, _with(bare, **fx), 4, 0), repeats))

    if "sampling" in sections:
        # image error against rays per pixel (noise-free, the scenes' own optical effects)
        for name, sc in (("shapes", shapes), ("flame", flame)):
            ref = simulate.render(cam, sc, ref_rpp, 99)
            for rpp in rpps:
                raw = simulate.render(cam, sc, rpp, 0)
                add("sampling", name, "numba", f"reference {ref_rpp} rays/pixel", rpp, n_px * rpp,
                    _time(lambda: simulate.render(cam, sc, rpp, 0), repeats), _rmse(raw, ref))

    if "forward vs backward" not in sections:
        return pd.DataFrame(rows)
    # forward (object -> sensor, scatter) against backward (sensor -> object) tracing
    layer = flame.layers[1]
    one = dataclasses.replace(flame, layers=(layer,), effects=scenes.Effects(aperture=True, cos4=False,
                                                                             occlusion=False))
    ref = simulate.render(cam, one, ref_rpp, 99).astype(np.float64)
    z = cam.object_distance_mm(layer.depth_offset_mm)
    top, left = layer.centre_mm[0] + layer.size_mm[0] / 2, layer.centre_mm[1] - layer.size_mm[1] / 2

    def forward(n):
        return _simulate_kernels.render_forward(z, cam.main_focal_mm, cam.mla_distance_mm, cam.sensor_distance_mm,
                                                cam.mla_pitch_mm, cam.mla_focal_mm,
                                                cam.pixel_pitch_mm, cam.n_rows, cam.n_cols, cam.pixels_per_lenslet,
                                                cam.aperture_diameter_mm / 2, layer.radiance, top, left,
                                                layer.size_mm[0], layer.size_mm[1], n, 0, numba.get_num_threads())
    for mult in (1, 4, 16):
        n = n_px * mult
        add("forward vs backward", "flame layer", "forward", "rays = pixels x", mult, n,
            _time(lambda: forward(n), max(1, repeats // 2)), _rmse(np.clip(forward(n), 0, 1), ref))
    for rpp in (1, 4, 16):
        add("forward vs backward", "flame layer", "backward", "rays per pixel", rpp, n_px * rpp,
            _time(lambda: simulate.render(cam, one, rpp, 0), repeats), _rmse(simulate.render(cam, one, rpp, 0), ref))
    return pd.DataFrame(rows)


def summary(df: pd.DataFrame, cam_label: str) -> str:
    fmt = dict(floatfmt=".4g", index=False)
    out = [f"# Simulator benchmark ({cam_label})", "",
           "Generated by `make bench-sim` (`experiments/bench_sim.py`); medians of repeated runs after warm-up.", ""]
    thr = df[df.section == "throughput"]
    numpy_rate = thr[thr.method == "numpy"].set_index("scene").mray_s
    t = thr[thr.method == "numba"].copy()
    t["x_numpy"] = t.mray_s / t.scene.map(numpy_rate)
    out += ["## Throughput, end to end (Mray/s)", "",
            t[["scene", "rays_per_pixel", "ms_median", "mray_s", "x_numpy"]].to_markdown(**fmt), "",
            "NumPy version of the same chain, 4 rays/pixel: " +
            ", ".join(f"{k} {v:.3g} Mray/s" for k, v in numpy_rate.items()), ""]
    e = df[df.section == "effects"]
    out += ["## Cost of each effect (shapes scene, 4 rays/pixel)", "",
            e[["setting", "ms_median", "ms_min"]].to_markdown(**fmt), ""]
    s = df[df.section == "sampling"]
    out += ["## Image error against rays per pixel", "",
            s[["scene", "rays_per_pixel", "ms_median", "rmse", "setting"]].to_markdown(**fmt), ""]
    f = df[df.section == "forward vs backward"]
    out += ["## Forward against backward tracing (one flame layer)", "",
            f[["method", "setting", "rays_per_pixel", "n_rays", "ms_median", "mray_s", "rmse"]].to_markdown(**fmt),
            ""]
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--quick", action="store_true", help="41 x 41 lenslets, fewer repeats (for tests)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    t0 = time.perf_counter()
    df = run(args.quick)
    label = "41 x 41 lenslets (quick)" if args.quick else "paper camera, 180 x 90 lenslets, 2700 x 1350 pixels"
    atomic_write_text(out / "bench_sim.csv", df.to_csv(index=False))
    atomic_write_text(out / "bench_sim.md", summary(df, label))
    prov = provenance() | dict(camera=label, threads=numba.get_num_threads(), wall_time_s=time.perf_counter() - t0,
                               command="python " + " ".join(sys.argv))
    atomic_write_text(out / "bench_sim.json", json.dumps(prov, indent=2))
    print(summary(df, label))


if __name__ == "__main__":
    main()
