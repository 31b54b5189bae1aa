"""Real light fields through depth finding and the default reconstruction (``make real-found``).

napari-lf 0.1.7's three microscopy captures (``make real-data`` reads the same files) go through what a
user runs on their own capture: ``lf-flame calibrate`` on the radiometry (white) frame with its dark frame,
then ``lf-flame reconstruct LIGHT_FIELD --camera CAM.toml --calibration CAL.json``: decoded on the fly, the
depths found over the camera's imaging range, admm on the decoded views' operator. The camera files
(``data_gen/napari_lf/*.toml``) take each objective with its tube lens as one thin lens of the objective's
magnification (the immersion's index is not modelled: depths are the model's, in air). There is no truth:
what is reported is what the route finds (depths, the planes they merge into, the emission's share at the
field's edge, the share of the light field the planes leave unexplained, and that share again with
``--iters 20``) and its time, with the route's figure (the reconstructed and the refocused planes).

Writes ``<out>/found.{csv,md,json}`` and ``<out>/<capture>_found.png``. Usage: ``python
experiments/real_found.py --data .bench/napari-lf/napari_lf/examples --out results/real``.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
#: Per capture: its light-field, radiometry and dark frames (napari-lf's names).
CAPTURES = {"GUVExperim1": ("Lightfield_GUVExperim1.tif", "Radiometry_GUVExperim1.tif", "DarkFrame_GUVExperim1.tif"),
            "seaurchin": ("light_field.tif", "radiometry_frame.tif", "dark_frame.tif"),
            "antleg": ("light_field.png", "radiometry_frame.png", "dark_frame.tif")}


#: admm's fills of the second reconstruction of each capture (``--iters``).
MORE_FILLS = 20


def run(*argv) -> tuple[int, str]:
    """One ``lf-flame`` command in-process: its exit code and its output (stdout and stderr)."""
    from lf_flame.cli import main
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        rc = main([str(a) for a in argv])
    return rc, out.getvalue()


def main(argv=None) -> int:
    import h5py
    import numpy as np

    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.tomo.depth import MERGE_PARALLAX, depth_tolerance_scale
    from lf_flame.config import atomic_write_text, provenance
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, required=True, help="napari_lf/examples")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rows, merge_um, t_all = [], {}, time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, (lf_file, white, dark) in CAPTURES.items():
            d, cam = a.data / name, ROOT / "data_gen" / "napari_lf" / f"{name}.toml"
            rc, text = run("calibrate", d / white, "--dark", d / dark, "--out", tmp / f"{name}.json")
            if rc:
                raise RuntimeError(f"calibrate {name}: {text.strip()[-300:]}")
            t0 = time.perf_counter()
            rc, text = run("reconstruct", d / lf_file, "--camera", cam, "--calibration", tmp / f"{name}.json",
                           "--out", tmp / f"{name}.h5")
            wall = time.perf_counter() - t0
            if rc:
                raise RuntimeError(f"reconstruct {name}: {text.strip()[-300:]}")
            with h5py.File(tmp / f"{name}.h5") as f:
                found = json.loads(f.attrs["found_depths"])
                misfit = json.loads(f.attrs["misfit"])
                edge = json.loads(f.attrs["edge_share"])
                planes_mm = [float(v) for v in f["depths_mm"][...]]
                shape = f["planes"].shape
                views_cam = PlenopticCamera.from_dict(json.loads(f.attrs["camera"]))   # the decoded views'
            shutil.copy(tmp / f"{name}.png", a.out / f"{name}_found.png")
            # the same with more fills than the default's cap and stopping (chosen on the paper camera's 4 planes)
            rc, text_more = run("reconstruct", d / lf_file, "--camera", cam, "--calibration", tmp / f"{name}.json",
                                "--iters", MORE_FILLS, "--out", tmp / f"{name}_more.h5")
            if rc:
                raise RuntimeError(f"reconstruct --iters {MORE_FILLS} {name}: {text_more.strip()[-300:]}")
            with h5py.File(tmp / f"{name}_more.h5") as f:
                misfit_more = json.loads(f.attrs["misfit"])["misfit"]
            n = views_cam.pixels_per_lenslet      # the depth of MERGE_PARALLAX lenslets of parallax at the focal plane
            merge_um[name] = 1e3 * abs(views_cam.depth_for_slope(MERGE_PARALLAX / (n - 1))
                                       - views_cam.depth_for_slope(0.0))
            rows.append(dict(capture=name, tolerance_scale=depth_tolerance_scale(views_cam,
                                                                                 views_cam.pixels_per_lenslet),
                             plane_samples=" x ".join(map(str, shape[1:])), found_depths_um=", ".join(
                f"{1e3 * r['depth_mm']:+.1f} +- {1e3 * r['uncertainty_mm']:.1f}" for r in found),
                planes_um=", ".join(f"{1e3 * v:+.1f}" for v in planes_mm), edge_share_max=float(np.max(edge)),
                misfit=float(misfit["misfit"]), **{f"misfit_{MORE_FILLS}_fills": float(misfit_more)},
                relative_residual=float(misfit["relative_residual"]),
                noise_share=float(misfit["noise_share"]), reconstruct_wall_s=wall,
                warnings=" | ".join(line[len("warning: "):].removeprefix(f"{d / lf_file}: ").split(":")[0]
                                    for line in text.splitlines() if line.startswith("warning"))))
            print(f"{name}: found {rows[-1]['found_depths_um']} um -> planes {rows[-1]['planes_um']} um; misfit "
                  f"{rows[-1]['misfit']:.3f}, edge {rows[-1]['edge_share_max']:.3f}; {wall:.1f} s", flush=True)
    df = pd.DataFrame(rows)
    wall = time.perf_counter() - t_all
    atomic_write_text(a.out / "found.csv", df.to_csv(index=False, float_format="%.4g"))
    md = ["# Real captures: depths found and each plane's emission", "",
          f"`python experiments/real_found.py --data {a.data} --out {a.out}` ({wall:.0f} s on 2 cores). napari-lf's "
          "microscopy captures through `lf-flame calibrate` (radiometry frame, dark frame) and `lf-flame reconstruct "
          "LIGHT_FIELD --camera data_gen/napari_lf/CAPTURE.toml --calibration CAL.json` (decoded on the fly, depths "
          "found, admm). Depths in micrometres from the focal plane in the camera file's thin-lens model (in air; "
          "the immersion's index is not modelled). No truth: `misfit` is the share of the light field the planes "
          "leave unexplained beyond the noise, `edge_share_max` the largest share of a plane's emission within 2 "
          "lenslets of the field's edge. Found depths share one plane within "
          f"`lf_flame.tomo.depth.MERGE_PARALLAX` ({MERGE_PARALLAX:g}) lenslets of parallax across the aperture: on "
          "these microscopes, whose parallax changes far faster with depth than the paper camera's, micrometres (at "
          "the focal plane: " + ", ".join(f"{k} {v:.2g} um" for k, v in merge_um.items()) + "). "
          f"`misfit_{MORE_FILLS}_fills`: the same command with `--iters {MORE_FILLS}` (admm's fills; the default "
          "caps them and stops when the planes settle, knobs chosen on the paper camera's four planes).", "",
          df.drop(columns="warnings").to_markdown(index=False, floatfmt=".3g"), "",
          "Warnings the command printed:", "", *[f"- {r.capture}: {r.warnings}" for r in df.itertuples()], ""]
    atomic_write_text(a.out / "found.md", "\n".join(md))
    atomic_write_text(a.out / "found.json", json.dumps(dict(rows=rows, wall_s=wall, provenance=provenance()),
                                                       indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
