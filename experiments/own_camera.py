"""A camera of another geometry, from its camera file to its planes.

The camera of ``examples/own_camera.toml`` (150 µm lenslets of 3 mm focal length behind a
100 mm f/10 lens focused at 200 mm, 14.4 µm pixels: lenslet images 10.57 px apart, rotated
0.4°, offset) and three variants of its grid: its white image rendered and calibrated
(:func:`lf_flame.real.calibration.calibrate`), three flames on three planes rendered
(:func:`side_flames`), decoded (:func:`lf_flame.real.decoding.decode`), and reconstructed
by FISTA (100 iterations) on the exact operator of the decoded views' camera
(:func:`lf_flame.real.own_camera.views_camera`, :func:`lf_flame.tomo.decoded.decoded_problem`);
each plane's relative L2 error against the truth in the decoded frame
(:func:`lf_flame.tomo.decoded.decoded_truth`). Beside them:

- the render's own Monte-Carlo noise in the decoded views (two seeds, difference / sqrt 2);
- the floor without decoding: the decoded views' camera itself rendered (a perfect grid),
  its views against its exact operator's light field of the truth, and their reconstruction;
- the paper's slender flames (:func:`lf_flame.simulate.scenes.flame_scene`, scaled to this
  field), 2-3 lenslets wide on this grid;
- FISTA's error against its iterations, and pd-tv, LSQR and Richardson-Lucy at their
  default iterations;
- a capture clipped by the sensor (the raw image x 1.5 and x 2, clipped at 1): clipped samples
  left out of the fit (decode's mask) or fitted as they are.

Writes ``<out>/own_camera.csv`` and ``<out>/own_camera.md`` (with the command and provenance).
Usage: ``python experiments/own_camera.py --out results`` (40-80 s on 2 cores).
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

#: (depth mm, centre x / field width, height / field height, peak radiance) of each flame.
FLAMES = ((20.0, -0.3, 0.8, 1.0), (0.0, 0.0, 0.55, 0.7), (-10.0, 0.3, 0.7, 0.9))
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml"
#: Grid variants: (name, rotation deg, offset px); the first is the example file's.
VARIANTS = (("example", 0.4, (2.3, -3.1)), ("centred", 0.4, (0.0, 0.0)), ("2 deg", 2.0, (0.0, 0.0)),
            ("-1.3 deg, offset", -1.3, (-4.0, 1.7)))
ITERS = 100


def side_flames(camera, flames=FLAMES, texels_per_lenslet: float = 3.0):
    """Flames side by side, one per plane, with :func:`lf_flame.simulate.scenes.flame_luminosity`:
    base at 8 % of the field height from the bottom, half-width 12 % of the height at the base
    (the paper's: 7 %), so about eight lenslets wide on a 48-lenslet-tall grid."""
    from lf_flame.simulate.scenes import FLAME_EFFECTS, flame_luminosity
    from lf_flame.simulate.layers import Layer, Scene
    layers = []
    for dz, fx, fh, level in flames:
        h, w = (v * 1.2 for v in camera.field_of_view_mm(dz))
        rows = int(math.ceil(camera.n_rows * 1.2 * texels_per_lenslet))
        cols = int(math.ceil(camera.n_cols * 1.2 * texels_per_lenslet))
        y = ((0.5 - (np.arange(rows) + 0.5) / rows) * h)[:, None]
        x = (((np.arange(cols) + 0.5) / cols - 0.5) * w)[None, :]
        H = fh * h / 1.2
        eta = (y + 0.42 * h / 1.2) / H
        half = 0.12 * H * np.sqrt(np.clip(1 - eta, 0, 1)) + 1e-9
        lum = (level * flame_luminosity(eta, (x - fx * w / 1.2) / half)).astype(np.float32)
        layers.append(Layer(lum, None, float(dz), (0.0, 0.0), (h, w)))
    return Scene("side_flames", tuple(layers), FLAME_EFFECTS)


def _camera(rotation, offset):
    import tomllib

    from lf_flame.optics.camera_file import camera_from_datasheet
    sheet = tomllib.loads(EXAMPLE.read_text())
    sheet["microlens_array"].update(rotation_deg=rotation, offset_px=list(offset))
    return camera_from_datasheet(sheet)


def _errors(planes, truth):
    P = len(truth)
    return np.linalg.norm((planes - truth).reshape(P, -1), axis=1) / np.linalg.norm(truth.reshape(P, -1), axis=1)


def main(argv=None) -> int:
    import pandas as pd

    from lf_flame.config import atomic_write_text, provenance
    from lf_flame.real import calibration, decoding
    from lf_flame.real.own_camera import decoded_frame, views_camera
    from lf_flame.refocus.shift_and_sum import raw_to_views
    from lf_flame.simulate import scenes, tracer
    from lf_flame.tomo.decoded import decoded_problem, decoded_truth
    from lf_flame.tomo.exact import ExactOperator
    from lf_flame.tomo.solvers import reconstruct
    from lf_flame.tomo.truth import scene_truth
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    t_all = time.perf_counter()
    rows = []

    def solve(case, variant, rays, cam, cal, white, raw, scene, clipped=None, gain=1.0):
        views = decoding.decode(raw, cal, white)
        vcam = views_camera(cam, cal, views.shape)
        fr = decoded_frame(cal, *views.shape[2:])
        op = ExactOperator(vcam, [L.depth_offset_mm for L in scene.layers])
        data, leave = decoded_problem(views, op, clipped)
        rec = reconstruct(data, op, "fista", ITERS, saturation=leave)
        err = _errors(rec.planes, gain * decoded_truth(scene, op, fr.rotation_deg, fr.centre_lenslets))
        rows.append(dict(case=case, variant=variant, rays=rays, pitch_px=cal.pitch_px, rotation_deg=cal.rotation_deg,
                         grid=f"{views.shape[2]}x{views.shape[3]}", n_left_out=int(leave.sum()),
                         **{f"err_{d:+g}mm": e for d, e in zip(op.depths_mm, err)}, worst=err.max(),
                         solve_s=rec.time_s))
        print(rows[-1], flush=True)
        return views, op, vcam

    for name, rot, off in VARIANTS:
        cam = _camera(rot, off)
        white = tracer.render(cam, scenes.white_scene(cam), 16)
        cal = calibration.calibrate(white)
        scene = side_flames(cam)
        for rays in ((64, 256, 1024) if name == "example" else (256,)):
            raw = tracer.render(cam, scene, rays, 1)
            views, op, vcam = solve("side flames", name, rays, cam, cal, white, raw, scene)
            if name == "example":
                y2, _ = decoded_problem(decoding.decode(tracer.render(cam, scene, rays, 2), cal, white), op)
                y1, leave = decoded_problem(views, op)
                rows[-1]["decoded_mc_noise"] = float(np.linalg.norm((y1 - y2)[~leave]) /
                                                     np.linalg.norm(y1[~leave]) / math.sqrt(2))
            if name == "example" and rays == 256:
                # FISTA's error against its iterations, and the other solvers at their defaults
                y, leave = decoded_problem(views, op)
                fr = decoded_frame(cal, *views.shape[2:])
                truth = decoded_truth(scene, op, fr.rotation_deg, fr.centre_lenslets)
                curve = {}
                reconstruct(y, op, "fista", 300, saturation=leave, callback=lambda k, x: curve.__setitem__(
                    k, _errors(x.reshape(op.dims), truth)) if k in (30, 50, 75, 100, 300) else None)
                for k, err in curve.items():
                    rows.append(dict(case=f"fista {k} iterations", variant=name, rays=rays, worst=err.max(),
                                     **{f"err_{d:+g}mm": e for d, e in zip(op.depths_mm, err)}))
                for solver in ("pd-tv", "lsqr", "rl"):
                    rec = reconstruct(y, op, solver, None, saturation=leave)
                    err = _errors(rec.planes, truth)
                    rows.append(dict(case=f"{solver} {rec.settings['iters']} iterations (its default)", variant=name,
                                     rays=rays, worst=err.max(), solve_s=rec.time_s,
                                     **{f"err_{d:+g}mm": e for d, e in zip(op.depths_mm, err)}))
                for gain in (1.5, 2.0):
                    bright = np.minimum(gain * raw, 1.0)
                    mask = decoding.clipped_samples(bright, cal, 1.0)
                    solve("clipped, mask", name, rays, cam, cal, white, bright, scene, mask, gain)
                    rows[-1]["clipped_fraction"] = float(mask.mean())
                    solve("clipped, fitted as is", name, rays, cam, cal, white, bright, scene, None, gain)
                    rows[-1]["clipped_fraction"] = float(mask.mean())
                # the floor without decoding: the decoded views' camera rendered itself
                sc = side_flames(vcam)
                truth = scene_truth(sc, op)
                direct = raw_to_views(tracer.render(vcam, sc, rays, 3), vcam.pixels_per_lenslet)
                _, leave = decoded_problem(np.zeros(op.dimsd), op)
                model = op.matvec(truth.ravel()).reshape(op.dimsd)
                err = _errors(reconstruct(direct, op, "fista", ITERS, saturation=leave).planes, truth)
                rows.append(dict(case="no decoding: the views' camera rendered", variant=name, rays=rays,
                                 **{f"err_{d:+g}mm": e for d, e in zip(op.depths_mm, err)}, worst=err.max(),
                                 render_vs_operator=float(np.linalg.norm((direct - model)[~leave]) /
                                                          np.linalg.norm(model[~leave]))))
                print(rows[-1], flush=True)
                # the paper's slender flames, scaled to this field
                h0 = cam.field_of_view_mm(0.0)[0]
                thin = scenes.flame_scene(cam, np.random.default_rng(0), template_scale=0.64 * h0 / 23.7,
                                          regime="paper", depths_mm=(20.0, 10.0, 0.0, -10.0))
                solve("paper's slender flames", name, rays, cam, cal, white, tracer.render(cam, thin, rays, 1), thin)
    table = pd.DataFrame(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "own_camera.csv", table.to_csv(index=False, float_format="%.4f"))
    prov = provenance()
    md = ["# A camera of another geometry: decoded views on the exact operator", "",
          f"`python experiments/own_camera.py --out {args.out}`, {time.perf_counter() - t_all:.0f} s; camera "
          f"`examples/own_camera.toml` and grid variants; FISTA {ITERS} iterations; relative L2 error per plane "
          "against the truth in the decoded frame.", "",
          table.to_markdown(index=False, floatfmt=".4f"), "",
          f"Provenance: {prov}"]
    atomic_write_text(args.out / "own_camera.md", "\n".join(md) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
