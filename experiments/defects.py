"""A sensor's defective pixels: what they do to the depths found and the planes, and what the repair leaves.

Three stages, one run:

- **scenes**: ``--scenes`` random-depth scenes of the paper's camera (``camera_depth_scene``, seeds from ``SEED``,
  ``--rays`` per pixel), with a share of their pixels defective (``FRACTIONS``: half hot, at 0.3-1 of the clipping
  level or their own light if brighter, half dead, at 0), each read two ways: **as is** (``raw_to_views``) and
  **repaired** (:func:`lf_flame.real.lightfield.from_raw`, the light field every command reads: the defects found
  by :func:`lf_flame.real.defects.defective_pixels`, repaired and left out of the fit). Per scene and way:
  :func:`lf_flame.tomo.found_planes.find_planes` (the route of ``lf-flame reconstruct``) scored by
  :func:`lf_flame.tomo.scoring.score_flames`: found depths that are no flame's (more than ``SPURIOUS_MM`` from
  every flame), flames missed, the emission error per flame; and the defects: how many, how many flagged, how
  many of those that stand out of the light (changed by more than 0.2 of the image's 99.9th percentile), and
  pixels flagged that are not defects.
- **renders**: the pixels :func:`~lf_flame.real.defects.defective_pixels` takes in renders without defects:
  ``experiments/fourier_solver.py``'s renders (``data/fourier_solver``, 400 rays per pixel, noise-free and at
  14 dB) and the scenes above at ``--rays``.
- **time**: :func:`~lf_flame.real.defects.defective_pixels` on the paper camera's 2700 x 1350 raw image, median
  and worst of ``REPEATS`` calls after a warm-up.

Writes ``<out>/defects.{csv,md,json}`` (scenes' rows; the renders' counts and the time in the JSON and the
Markdown). Usage: ``python experiments/defects.py --out results [--scenes 6] [--rays 16]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
SEED = 3_800_000
#: Shares of the sensor's pixels that are defective (1e-4: a sensor's factory defects; 1e-3: an aged one).
FRACTIONS = (0.0, 1e-4, 1e-3)
#: A found depth farther than this from every flame is spurious (mm).
SPURIOUS_MM = 1.0
REPEATS = 5


def with_defects(raw, fraction, rng):
    """``raw`` with ``fraction`` of its pixels defective (half hot, half dead): (image, where they changed it)."""
    bad = raw.copy()
    k = int(round(fraction * raw.size))
    idx = rng.choice(raw.size, k, replace=False)
    hot, dead = idx[: k // 2], idx[k // 2:]
    bad.flat[hot] = np.maximum(bad.flat[hot], rng.uniform(0.3, 1.0, len(hot)))
    bad.flat[dead] = 0.0
    return bad, bad != raw


def scene_rows(n_scenes: int, rays: int) -> list:
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.real.lightfield import from_raw
    from lf_flame.refocus.shift_and_sum import raw_to_views, views_to_raw
    from lf_flame.simulate import tracer
    from lf_flame.simulate.scenes_depth import camera_depth_scene
    from lf_flame.tomo.found_planes import find_planes
    from lf_flame.tomo.scoring import score_flames
    sys.path.insert(0, str(ROOT / "experiments"))
    from depth import found_flames
    rows = []
    for i in range(n_scenes):
        seed = SEED + i
        scene = camera_depth_scene(cam, np.random.default_rng(seed))
        raw = tracer.render(cam, scene, rays, seed)
        peak = float(np.percentile(raw, 99.9))
        true = np.array([o["depth_offset_mm"] for o in scene.objects])
        for fraction in FRACTIONS:
            bad, where = with_defects(raw, fraction, np.random.default_rng([seed, 1]))
            big = where & (np.abs(bad - raw) > 0.2 * peak)
            lf = from_raw(bad, cam)                   # its defects, as sensor pixels
            flagged = np.zeros(raw.shape, bool) if lf.defects is None else views_to_raw(lf.defects)
            for way, views, saturation in (("as is", raw_to_views(bad, cam.pixels_per_lenslet), 1.0),
                                           ("repaired", lf.views, lf.fit_mask())):
                t0 = time.perf_counter()
                found, _, rec = find_planes(views, cam, saturation=saturation)
                wall = time.perf_counter() - t0
                d = np.asarray(found.depths_mm)
                spurious = int(sum(np.min(np.abs(true - x)) > SPURIOUS_MM for x in d))
                flames = score_flames(rec.planes, found.planes_mm, scene, cam, found=found_flames(found))
                rows.append(dict(seed=seed, fraction=fraction, way=way, flames=len(true), found_depths=len(d),
                                 spurious_depths=spurious, missed=int(flames.depth_mm.isna().sum()),
                                 rel_err_median=float(flames.rel_err.median()),
                                 rel_err_worst=float(flames.rel_err.max()), planes=len(found.planes_mm),
                                 defects=int(where.sum()), defects_standing_out=int(big.sum()),
                                 flagged=int(flagged.sum()), flagged_standing_out=int((flagged & big).sum()),
                                 flagged_not_defects=int((flagged & ~where).sum()), wall_s=wall))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    return rows


def _flagged_pixels(raw, cam):
    from lf_flame.real.defects import defective_pixels, lenslet_offsets
    return defective_pixels(raw, lenslet_offsets(cam.pixels_per_lenslet * np.eye(2)))[0]


def render_counts(rays: int, n_scenes: int) -> list:
    """Pixels taken for defects in renders without any: (render, noise, pixels, flagged)."""
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.simulate import tracer
    from lf_flame.simulate.scenes_depth import camera_depth_scene
    out = []
    for f in sorted((ROOT / "data" / "fourier_solver").glob("*.npz")):
        z = np.load(f)
        for key, noise in (("clean", "noise-free"), ("noisy", "14 dB")):
            out.append(dict(render=f.stem, noise=noise, pixels=int(z[key].size),
                            flagged=int(_flagged_pixels(z[key], cam).sum())))
    for i in range(n_scenes):
        raw = tracer.render(cam, camera_depth_scene(cam, np.random.default_rng(SEED + i)), rays, SEED + i)
        out.append(dict(render=f"depth_{SEED + i}_{rays}", noise="noise-free", pixels=int(raw.size),
                        flagged=int(_flagged_pixels(raw, cam).sum())))
    return out


def timing() -> dict:
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.real.defects import defective_pixels, lenslet_offsets
    from lf_flame.simulate import tracer
    from lf_flame.simulate.scenes_depth import camera_depth_scene
    raw = tracer.render(cam, camera_depth_scene(cam, np.random.default_rng(SEED)), 4, SEED)
    off = lenslet_offsets(cam.pixels_per_lenslet * np.eye(2))
    defective_pixels(raw, off)
    t = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        defective_pixels(raw, off)
        t.append(time.perf_counter() - t0)
    return dict(shape=list(raw.shape), median_s=float(np.median(t)), worst_s=float(np.max(t)), repeats=REPEATS)


def main(argv=None) -> int:
    from lf_flame.config import atomic_write_text, provenance
    from lf_flame.real.defects import DEFECT_MARGIN, DEFECT_SPREAD
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--rays", type=int, default=16)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    df = pd.DataFrame(scene_rows(a.scenes, a.rays))
    counts = pd.DataFrame(render_counts(a.rays, a.scenes))
    tm = timing()
    wall = time.perf_counter() - t0
    a.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(a.out / "defects.csv", df.to_csv(index=False))
    summary = df.groupby(["fraction", "way"]).agg(
        scenes=("seed", "size"), flames=("flames", "sum"), spurious_depths=("spurious_depths", "sum"),
        scenes_with_spurious=("spurious_depths", lambda s: int((s > 0).sum())), missed=("missed", "sum"),
        rel_err_median=("rel_err_median", "median"), rel_err_worst=("rel_err_worst", "max"),
        defects=("defects", "sum"), standing_out=("defects_standing_out", "sum"),
        flagged_standing_out=("flagged_standing_out", "sum"), flagged_not_defects=("flagged_not_defects", "sum"),
        wall_s_median=("wall_s", "median")).reset_index()
    cmd = f"python experiments/defects.py --out {a.out} --scenes {a.scenes} --rays {a.rays}"
    md = ["# A sensor's defective pixels: found depths and planes, as they are and repaired\n",
          f"`{cmd}` ({wall / 60:.1f} min on 2 cores). {a.scenes} random-depth scenes of the paper's camera "
          f"(seeds {SEED}-{SEED + a.scenes - 1}, {a.rays} rays per pixel), a share of their pixels defective (half "
          "hot at 0.3-1 of the clipping level, half dead at 0), each solved by the route of `lf-flame reconstruct` "
          "(depths found, admm): **as is**, and **repaired** as every command now reads an image (each pixel "
          "against its 16 neighbours in the light field, `DEFECT_MARGIN` "
          f"{DEFECT_MARGIN}, `DEFECT_SPREAD` {DEFECT_SPREAD}; repaired pixels left out of the fit). A found depth "
          f"more than {SPURIOUS_MM:g} mm from every flame is spurious; emission error per flame (`score_flames`). "
          "`standing_out`: defects that change their pixel by more than 0.2 of the image's 99.9th percentile; "
          "`flagged_standing_out`: those found.\n",
          summary.to_markdown(index=False, floatfmt=".3g"), "\n",
          "## Pixels taken for defects in renders without any\n",
          "`experiments/fourier_solver.py`'s renders (400 rays per pixel) and the scenes above:\n",
          counts.to_markdown(index=False), "\n",
          f"## Time\n\n`defective_pixels` on a {tm['shape'][0]} x {tm['shape'][1]} raw image: median "
          f"{1e3 * tm['median_s']:.0f} ms, worst {1e3 * tm['worst_s']:.0f} ms of {tm['repeats']} calls.\n",
          f"Provenance: `{json.dumps(provenance())}`\n"]
    atomic_write_text(a.out / "defects.md", "\n".join(md))
    atomic_write_text(a.out / "defects.json", json.dumps(dict(
        command=cmd, seeds=[SEED, SEED + a.scenes - 1], rays=a.rays, fractions=FRACTIONS, margin=DEFECT_MARGIN,
        spread=DEFECT_SPREAD, summary=summary.to_dict("records"), renders=counts.to_dict("records"), time=tm,
        wall_s=wall, provenance=provenance()), indent=1, default=str))
    print(f"wrote {a.out / 'defects.md'} in {wall / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
