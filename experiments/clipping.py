"""A sensor's clipping level in an image file: found in the image, against the file type's level taken before.

A sensor clips at one level, and image files do not say which: a 12-bit sensor's counts in a 16-bit TIFF or PNG
(clipping at 4095, or at 65520 shifted to the top bits), or a sensor whose full well is reached below its converter's
top. The commands read such files scaled by their type's range, and took 1.0 (the type's top) for the clipping level,
so that clipped pixels were fitted as light. Now the level is found where the image's pixels pile up at its largest
value (:func:`lf_flame.real.clipping.auto_saturation`).

Two stages, one run:

- **scenes**: ``--scenes`` random-depth scenes of the paper's camera (``camera_depth_scene``, seeds from ``SEED``,
  ``--rays`` per pixel, rendered without the sensor), exposed so that each of ``CLIPPED_SHARES`` of the pixels
  clip, written as a 12-bit sensor's counts in a 16-bit TIFF and read back as the commands read an image file
  (:func:`lf_flame.cli._io._load_raw`). Each is solved by the route of ``lf-flame reconstruct`` (depths found,
  admm; :func:`lf_flame.tomo.found_planes.find_planes`) two ways: **type's level** (1.0, what was taken before:
  the clipped pixels fitted as light) and **found** (:func:`lf_flame.real.lightfield.from_raw`'s level, what
  every reader takes now: the clipped pixels left out), scored by :func:`lf_flame.tomo.scoring.score_flames` (the
  planes divided by the exposure, back to the scene's radiance), beside the same scene exposed below clipping.
  The level is also found in the same counts stored as each of ``ENCODINGS``.
- **no clipping**: the same scenes exposed below clipping (as floats and as 12-bit counts), and napari-lf's real
  captures where ``make real-data`` fetched them: the level found, and the pixels at or above it (none: nothing
  is taken for clipped in an image that does not clip).

Writes ``<out>/clipping.{csv,md,json,png}``. Usage: ``python experiments/clipping.py --out results [--scenes 6]
[--rays 16]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
SEED = 3_810_000
#: Shares of the pixels that clip in the scored images (the flames' brightest cores, and more of them, over-exposed).
CLIPPED_SHARES = (0.0005, 0.005)
#: Exposure of the scenes that do not clip: their brightest pixel at this fraction of the clipping level.
UNDER = 0.9
#: How a sensor's counts are stored (16-bit files): its clipping count and the shift to the file's top bits.
ENCODINGS = {"12-bit counts": (4095, 0), "12-bit counts in the top bits": (4095, 4),
             "full well at 3600 of 4095 counts": (3600, 0)}
#: napari-lf's captures (``make real-data``), where present.
REAL = ROOT / ".bench" / "napari-lf" / "napari_lf" / "examples"
#: A found depth farther than this from every flame is spurious (mm).
SPURIOUS_MM = 1.0


def counts_file(radiance, gain, top, shift, path) -> float:
    """``radiance`` times ``gain``, clipped at 1, as a sensor's counts (1 -> ``top``) shifted by ``shift`` bits in a
    16-bit TIFF at ``path``: the true clipping level in the units the commands read it in (scaled by 65535)."""
    import tifffile
    counts = np.round(np.clip(radiance * gain, 0, 1) * top).astype(np.uint16) << shift
    tifffile.imwrite(path, counts)
    return float(top << shift) / 65535


def scene_rows(n_scenes: int, rays: int, tmp: Path) -> tuple:
    from lf_flame.cli._io import _load_raw
    from lf_flame.optics.camera import PAPER_CAMERA as cam
    from lf_flame.real.clipping import clipped_share
    from lf_flame.real.lightfield import from_raw
    from lf_flame.simulate import tracer
    from lf_flame.simulate.scenes_depth import camera_depth_scene
    from lf_flame.tomo.found_planes import find_planes
    from lf_flame.tomo.scoring import score_flames
    sys.path.insert(0, str(ROOT / "experiments"))
    from depth import found_flames
    rows, levels, unclipped = [], [], []
    for i in range(n_scenes):
        seed = SEED + i
        scene = camera_depth_scene(cam, np.random.default_rng(seed))
        radiance = tracer.render(cam, scene, rays, seed, sensor=False)
        true = np.array([o["depth_offset_mm"] for o in scene.objects])
        exposures = [(0.0, UNDER / float(radiance.max()))] + [
            (share, 1.0 / float(np.quantile(radiance, 1 - share))) for share in CLIPPED_SHARES]
        for share, gain in exposures:
            path = tmp / f"{seed}.tif"
            level = counts_file(radiance, gain, 4095, 0, path)
            raw = _load_raw(path)[0]
            ways = [("no clipping", from_raw(raw, cam))] if share == 0 else [
                ("type's level", from_raw(raw, cam, saturation=1.0)), ("found", from_raw(raw, cam))]
            for way, lf in ways:
                t0 = time.perf_counter()
                found, _, rec = find_planes(lf.views, cam, saturation=lf.fit_mask())
                wall = time.perf_counter() - t0
                d = np.asarray(found.depths_mm)
                flames = score_flames(rec.planes / (gain * level), found.planes_mm, scene, cam,
                                      found=found_flames(found))
                clipped = raw >= level
                rows.append(dict(seed=seed, clipped_share=share, way=way, level=lf.saturation,
                                 clipped_pixels=int(clipped.sum()),
                                 clipped_of_lit=clipped_share(raw, level),
                                 left_out=int(np.count_nonzero(lf.views >= lf.saturation)),
                                 flames=len(true), found_depths=len(d),
                                 spurious_depths=int(sum(np.min(np.abs(true - x)) > SPURIOUS_MM for x in d)),
                                 missed=int(flames.depth_mm.isna().sum()),
                                 rel_err_median=float(flames.rel_err.median()),
                                 rel_err_worst=float(flames.rel_err.max()), wall_s=wall))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
            if share == 0:
                for image, kind in ((radiance * gain, "float"), (raw, "12-bit counts")):
                    lf = from_raw(image, cam)
                    unclipped.append(dict(image=f"depth_{seed}_{rays}", kind=kind, peak=float(image.max()),
                                          level_found=lf.saturation,
                                          at_or_above=int(np.count_nonzero(image >= lf.saturation))))
                continue
            for encoding, (top, shift) in ENCODINGS.items():         # the level found in each file's counts
                true_level = counts_file(radiance, gain, top, shift, path)
                found_level = from_raw(_load_raw(path)[0], cam).saturation
                levels.append(dict(seed=seed, clipped_share=share, encoding=encoding, true_level=true_level,
                                   found=found_level, type_level=1.0))
    return rows, levels, unclipped


def real_rows() -> list:
    """The level found in napari-lf's captures (light field, radiometry and dark frames), where present."""
    from lf_flame.real.clipping import auto_saturation
    from lf_flame.real.images import load_image
    out = []
    for f in sorted(REAL.glob("*/*.tif")):
        img = load_image(f)
        level = auto_saturation(img)
        out.append(dict(image=f"{f.parent.name}/{f.name}", kind="real capture (counts)", peak=float(img.max()),
                        level_found=level, at_or_above=int(np.count_nonzero(img >= level))))
    return out


def figure(df, path) -> None:
    """Each scene's emission error (median and worst flame) against its clipped share of the lit pixels, the clipped
    pixels fitted as light and left out, the scenes below clipping at 0; the warning's threshold dashed."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from lf_flame.real.clipping import CLIPPED_WARN
    from lf_flame.measure.figures import save_figure
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 3.6), sharex=True)
    ways = (("no clipping", "below clipping", "k", "s"), ("type's level", "clipped pixels fitted as light", "C1", "^"),
            ("found", "clipped pixels left out (the level found)", "C0", "o"))
    for ax, col, title in ((axes[0], "rel_err_median", "median flame of each scene"),
                           (axes[1], "rel_err_worst", "worst flame of each scene")):
        for way, label, colour, marker in ways:
            g = df[df.way == way]
            ax.scatter(100 * g.clipped_of_lit, 100 * g[col], c=colour, marker=marker, s=22, label=label)
        ax.axvline(100 * CLIPPED_WARN, color="0.4", lw=0.8, ls="--", label="reconstruct warns beyond")
        ax.set_xlabel("clipped pixels (% of the lit ones)")
        ax.set_ylabel("emission error (%)")
        ax.set_title(title)
    axes[0].legend(fontsize=7.5)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def main(argv=None) -> int:
    from lf_flame.config import atomic_write_text, provenance
    from lf_flame.real.clipping import LIT_SHARE, PILE_MIN_PIXELS, PILE_RATIO
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scenes", type=int, default=6)
    ap.add_argument("--rays", type=int, default=16)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        rows, levels, unclipped = scene_rows(a.scenes, a.rays, Path(tmp))
    df, lv, free = pd.DataFrame(rows), pd.DataFrame(levels), pd.DataFrame(unclipped + real_rows())
    wall = time.perf_counter() - t0
    a.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(a.out / "clipping.csv", df.to_csv(index=False))
    figure(df, a.out / "clipping.png")
    summary = df.groupby(["clipped_share", "way"], sort=False).agg(
        scenes=("seed", "size"), clipped_of_lit_median=("clipped_of_lit", "median"),
        clipped_pixels=("clipped_pixels", "sum"), left_out=("left_out", "sum"), flames=("flames", "sum"),
        spurious_depths=("spurious_depths", "sum"), missed=("missed", "sum"),
        rel_err_median=("rel_err_median", "median"), rel_err_worst=("rel_err_worst", "max"),
        wall_s_median=("wall_s", "median")).reset_index()
    lv["found_is_true"] = np.isclose(lv.found, lv.true_level, rtol=0, atol=1e-6)
    lv_summary = lv.groupby(["encoding"], sort=False).agg(
        images=("seed", "size"), true_level=("true_level", "first"), found_is_true=("found_is_true", "sum"),
        type_level=("type_level", "first")).reset_index()
    cmd = f"python experiments/clipping.py --out {a.out} --scenes {a.scenes} --rays {a.rays}"
    md = ["# A sensor's clipping level in an image file, and what clipping costs\n",
          f"`{cmd}` ({wall / 60:.1f} min on 2 cores). {a.scenes} random-depth scenes of the paper's camera (seeds "
          f"{SEED}-{SEED + a.scenes - 1}, {a.rays} rays per pixel, noise-free), exposed so that "
          f"{' and '.join(f'{100 * x:g} %' for x in CLIPPED_SHARES)} of the pixels clip (and below clipping: the "
          f"brightest pixel at {UNDER:g} of the level), written as a 12-bit sensor's counts in a 16-bit TIFF and "
          "read as the commands read an image file (scaled by 65535). Each solved by the route of `lf-flame "
          "reconstruct` (depths found, admm) with the **type's level** (1.0, what the readers took: the clipped "
          "pixels fitted as light) and with the level **found** where the pixels pile up (at least "
          f"{PILE_MIN_PIXELS} pixels at the image's largest value, {PILE_RATIO} times as many as at the next value "
          "below; the clipped pixels left out of the fit). `clipped_of_lit`: the clipped pixels' share of those lit "
          f"above {LIT_SHARE:g} of the level (median over the scenes); `left_out`: pixels left out as clipped; a found "
          f"depth more than {SPURIOUS_MM:g} mm from every flame is spurious; emission error per flame "
          "(`score_flames`, the planes divided by the exposure).\n",
          summary.to_markdown(index=False, floatfmt=".3g"), "\n",
          "![each scene's emission error against its clipped share](clipping.png)\n",
          "## The level found, per way of storing the counts\n",
          "The clipped images above, their counts stored each way (the level in the units the commands read, "
          "scaled by 65535):\n",
          lv_summary.to_markdown(index=False, floatfmt=".6g"), "\n",
          "## Images that do not clip\n",
          f"The same scenes exposed to {UNDER:g} of the clipping level (as floats, and as 12-bit counts scaled by "
          "65535), and napari-lf's real captures as counts where `make real-data` fetched them: the level found and "
          "the pixels at or above it.\n",
          free.to_markdown(index=False, floatfmt=".6g"), "\n",
          f"Provenance: `{json.dumps(provenance())}`\n"]
    atomic_write_text(a.out / "clipping.md", "\n".join(md))
    atomic_write_text(a.out / "clipping.json", json.dumps(dict(
        command=cmd, seeds=[SEED, SEED + a.scenes - 1], rays=a.rays, clipped_shares=CLIPPED_SHARES, lit=LIT_SHARE,
        under=UNDER, encodings=ENCODINGS, pile_min_pixels=PILE_MIN_PIXELS, pile_ratio=PILE_RATIO,
        summary=summary.to_dict("records"), levels=lv_summary.to_dict("records"), unclipped=free.to_dict("records"),
        wall_s=wall,
        provenance=provenance()), indent=1, default=str))
    print(f"wrote {a.out / 'clipping.md'} in {wall / 60:.1f} min")
    return 0


if __name__ == "__main__":
    sys.exit(main())
