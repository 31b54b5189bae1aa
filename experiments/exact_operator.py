"""The exact operator beside the recorded Monte-Carlo operator, on the paper's camera and planes.

Writes ``<out>/exact_operator.csv`` (both tables, long form), ``<out>/exact_operator.md``
and ``<out>/exact_operator.json`` (settings, canvas, wall time, provenance):

- **cost**: setup time (``__init__``; for the Monte-Carlo operator also the ray record its
  first application makes), memory held (the exact operator's kernels' spectra and
  weights; the Monte-Carlo operator's compressed ray record), and one ``A`` and one
  ``A^T`` (median and 90th percentile of ``--repeats`` calls after a warm-up call), for
  :class:`lf_flame.tomo.exact.ExactOperator` in float64 and float32 and
  :class:`lf_flame.tomo.operator.EmissionOperator` at 4 rays per pixel (recorded);
- **accuracy**: on one paper-regime flame scene (its truth on the operator's grid,
  :func:`lf_flame.tomo.truth.scene_truth`), per plane and for all planes together, the
  relative L2 difference of each operator's light field from a traced operator at
  ``--rays`` rays per pixel (seed 1), beside that traced operator's own seed-to-seed noise
  (``||T_1 x - T_2 x|| / sqrt 2``, relative): an operator that *is* the map the traced one
  estimates differs from it by exactly that noise.

Timings are taken on a shared 2-core machine: noisy; compare rows of one run only.

Usage: ``python experiments/exact_operator.py --out results [--rays 1024] [--repeats 10]``.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from lf_flame.config import atomic_write_text, provenance
from lf_flame.optics.camera import PAPER_CAMERA
from lf_flame.simulate import scenes
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.operator import EmissionOperator
from lf_flame.tomo.truth import scene_truth

DEPTHS = (20.0, 10.0, 0.0, -10.0)
SCENE_SEED = 7


def _times(f, repeats):
    f()                                           # warm-up (threads, caches)
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        t.append(time.perf_counter() - t0)
    return float(np.median(t)), float(np.percentile(t, 90))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results"))
    ap.add_argument("--rays", type=int, default=1024, help="rays per pixel of the traced reference")
    ap.add_argument("--repeats", type=int, default=10)
    args = ap.parse_args(argv)
    cam = PAPER_CAMERA
    t_start = time.perf_counter()
    rows = []

    ops = {}
    for name, make in (("exact float64", lambda: ExactOperator(cam, DEPTHS)),
                       ("exact float32", lambda: ExactOperator(cam, DEPTHS, precision="float32"))):
        setups = []
        for _ in range(3):
            t0 = time.perf_counter()
            op = make()
            setups.append(time.perf_counter() - t0)
        ops[name] = op
        rows.append(dict(operator=name, setup_s=float(np.median(setups)), record_s=0.0, memory_mb=op.nbytes / 1e6))
    t0 = time.perf_counter()
    mc = EmissionOperator(cam, DEPTHS, rays_per_pixel=4)
    init_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = mc._ray_table()
    record_s = time.perf_counter() - t0
    ops["monte-carlo 4 rays (recorded)"] = mc
    rows.append(dict(operator="monte-carlo 4 rays (recorded)", setup_s=init_s, record_s=record_s,
                     memory_mb=sum(a.nbytes for a in table if isinstance(a, np.ndarray)) / 1e6))

    rng = np.random.default_rng(0)
    x = rng.random(mc.shape[1])
    y = rng.random(mc.shape[0])
    for row in rows:
        op = ops[row["operator"]]
        row["A_median_ms"], row["A_p90_ms"] = (1e3 * v for v in _times(lambda: op.matvec(x), args.repeats))
        row["AT_median_ms"], row["AT_p90_ms"] = (1e3 * v for v in _times(lambda: op.rmatvec(y), args.repeats))

    # accuracy on a flame scene, per plane, against a traced operator at many rays
    scene = scenes.flame_scene(cam, np.random.default_rng(SCENE_SEED), regime="paper")
    truth = scene_truth(scene, mc)
    refs = [EmissionOperator(cam, DEPTHS, rays_per_pixel=args.rays, seed=s, ray_table=False) for s in (1, 2)]
    acc = []
    for k in list(range(len(DEPTHS))) + [None]:
        xk = truth if k is None else np.where(np.arange(len(DEPTHS))[:, None, None] == k, truth, 0.0)
        t1, t2 = (r.matvec(xk.ravel()) for r in refs)
        norm = np.linalg.norm(t1)
        entry = dict(plane="all" if k is None else f"{DEPTHS[k]:+g} mm",
                     traced_noise=float(np.linalg.norm(t1 - t2) / np.sqrt(2) / norm))
        for name, op in ops.items():
            entry[name] = float(np.linalg.norm(op.matvec(xk.ravel()) - t1) / norm)
        acc.append(entry)
    cost = pd.DataFrame(rows)
    accuracy = pd.DataFrame(acc)
    meta = dict(camera="paper", depths_mm=DEPTHS, rays_reference=args.rays, repeats=args.repeats,
                scene=f"flame_scene(paper, seed {SCENE_SEED})", wall_time_s=time.perf_counter() - t_start,
                canvas_shape=ops["exact float64"].canvas_shape, provenance=provenance())
    args.out.mkdir(parents=True, exist_ok=True)
    long = accuracy.melt(id_vars=["plane"], var_name="operator", value_name="relative_difference")
    csv = pd.concat([cost.assign(table="cost"), long.assign(table="accuracy")])
    atomic_write_text(args.out / "exact_operator.csv", csv.to_csv(index=False, float_format="%.5g"))
    atomic_write_text(args.out / "exact_operator.json", json.dumps(meta, indent=2, default=str))
    md = ["# The exact operator beside the recorded Monte-Carlo operator (paper camera, 4 planes)", "",
          f"Measured by `python experiments/exact_operator.py --rays {args.rays} --repeats {args.repeats}` on a shared "
          "2-core machine (noisy: compare rows of this run only). Provenance: `exact_operator.json`.", "",
          "## Cost", "", cost.to_markdown(index=False, floatfmt=".4g"), "",
          f"## Accuracy: relative L2 difference from a {args.rays}-ray traced operator (seed 1), flame scene",
          "", "`traced_noise` is that operator's own seed-to-seed noise; an exact map differs from it by that much.",
          "", accuracy.to_markdown(index=False, floatfmt=".4g"), ""]
    atomic_write_text(args.out / "exact_operator.md", "\n".join(md))
    print("\n".join(md))


if __name__ == "__main__":
    main()
