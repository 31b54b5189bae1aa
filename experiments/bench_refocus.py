"""Refocusing benchmark (``make bench-refocus``): ms per plane and per 4-plane focal stack.

Writes ``<out>/bench_refocus.csv``, ``<out>/bench_refocus.md``, ``<out>/slopes_depths.csv``
(the slope search at the paper's depths and others, both scoring methods) and
``<out>/bench_refocus.json`` (provenance). The light field is the paper camera's
(15 x 15 views of 180 x 90 lenslets, float32), rendered from the nominal shapes scene.
Every row is measured in this one run: median, 10th and 90th percentile of ``repeats``
calls after a warm-up call.

- ``lf-read``: one parallel read of the light field (a Numba sum), the memory floor;
- ``inner-loop floor``: the focal-stack kernel's inner loop (two views' bilinear samples
  added to a sum) run on data that stay in L1 cache, as many times as the 4-plane stack
  needs it: the time its arithmetic takes with no memory traffic, the compute floor;
- ``shift-sum bilinear`` / ``shift-sum nearest``: :func:`lf_flame.refocus.shift_and_sum.focal_stack`
  (views already checked, ``check_finite=False``; the check that ``check_finite=True``
  adds is its own row);
- ``fourier``: :class:`lf_flame.refocus.shift_and_sum.FourierSlice`, the 4-D FFT (``precompute``) and
  then the slices;
- ``plenopticam``: PlenoptiCam 0.9.3's ``LfpShiftAndSum.refo_from_vp`` (integer shifts
  only, 3 colour channels) where it imports from ``--plenopticam PATH`` (a folder made
  with ``pip install --no-deps --target``; see the Makefile). The package never imports it.

Agreement rows give the RMSE between methods on this light field (all pixels, and the
interior: farther from the border than the largest shift, where no view runs out).

Usage: ``python experiments/bench_refocus.py --out results [--quick] [--plenopticam DIR]``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import types
from pathlib import Path

import numba
import numpy as np
import pandas as pd
from numba import njit, prange

from lf_flame.refocus import _kernels as _refocus_kernels
from lf_flame.simulate import scenes
from lf_flame.simulate import tracer as simulate
from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.config import atomic_write_text, provenance
from lf_flame.refocus.shift_and_sum import FourierSlice, _check_finite, aperture_mask, focal_stack, raw_to_views

PAPER_SLOPES = [2.281, 1.175, 0.0, -1.249]  # analytic slopes of the paper's four planes
INTEGER_SLOPES = [-2.0, -1.0, 0.0, 1.0]  # what PlenoptiCam can do: a = 2, 1, 0, -1


@njit(parallel=True, fastmath=True)  # no cache: the tests load this file under another module name
def _read_all(a):
    """Sum of a flat float32 array, in parallel: one read of it."""
    s = 0.0
    for i in prange(a.size):
        s += a[i]
    return s


@njit(parallel=True, fastmath={'contract'})  # no cache: see _read_all
def _inner_loop_floor(n_threads, n_pass, n, n_cols):
    """Run the row pass's inner loop of :func:`lf_flame.refocus._kernels.shift_sum_stack` (its
    two-view form, ``t += (g1 a1 + f1 c1) + (g2 a2 + f2 c2)`` with ``c`` one row of
    ``n_cols`` below ``a``) ``n_pass`` times over ``n`` samples in each of ``n_threads``
    threads, on per-thread arrays small enough to stay in L1 cache. Returns a checksum."""
    out = np.zeros(n_threads, np.float32)
    g1, f1, g2, f2 = np.float32(0.7), np.float32(0.3), np.float32(0.4), np.float32(0.6)
    for i in prange(n_threads):
        src = np.ones((2, n + n_cols + 8), np.float32)  # allocated here: aligned as the kernel's, no false sharing
        t = np.zeros(n, np.float32)
        a1 = src[0, 3:3 + n]  # sources not 32-byte aligned, as the kernel's mostly are not
        c1 = src[0, 3 + n_cols:3 + n_cols + n]
        a2 = src[1, 5:5 + n]
        c2 = src[1, 5 + n_cols:5 + n_cols + n]
        for _ in range(n_pass):
            for p in range(n):
                t[p] += (g1 * a1[p] + f1 * c1[p]) + (g2 * a2[p] + f2 * c2[p])
        out[i] = t.sum()  # every sum is used: no store can be dropped
    return out


def _times(fn, repeats):
    fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return 1e3 * np.percentile(ts, [50, 10, 90])


def _load_plenopticam(path):
    """PlenoptiCam's LfpShiftAndSum and its config, or None. Its optional dependencies
    that the refocusing path never calls are stubbed (see NOTES: ``scipy.misc.face``)."""
    if not path or not Path(path).is_dir():
        return None
    sys.path.insert(0, str(path))
    try:
        import scipy.misc
        if not hasattr(scipy.misc, "face"):
            scipy.misc.face = lambda *a, **k: np.zeros((8, 8, 3))
        stub = types.ModuleType("colour_demosaicing")
        for name in ("demosaicing_CFA_Bayer_bilinear", "demosaicing_CFA_Bayer_Malvar2004",
                     "demosaicing_CFA_Bayer_Menon2007"):
            setattr(stub, name, None)
        sys.modules.setdefault("colour_demosaicing", stub)
        from plenopticam.cfg import PlenopticamConfig
        from plenopticam.lfp_refocuser import LfpShiftAndSum
        from plenopticam.misc import PlenopticamStatus
    except Exception as e:  # noqa: BLE001 - an optional baseline; say why and go on
        print(f"PlenoptiCam not used: {type(e).__name__}: {e}")
        return None
    return LfpShiftAndSum, PlenopticamConfig, PlenopticamStatus


def _plenopticam_stack(mod, views, a_range):
    """PlenoptiCam's shift-and-sum of ``views`` (N, N, R, C) for a in range(*a_range):
    returns a callable (timed) and the mean-normalised stack (for the agreement row)."""
    cls, cfg_cls, sta_cls = mod
    n = views.shape[0]
    cfg = cfg_cls()
    cfg.params[cfg.ptc_leng] = n
    cfg.params[cfg.ran_refo] = list(a_range)
    cfg.params[cfg.opt_refi] = False
    cfg.params[cfg.opt_prnt] = False
    arr = np.ascontiguousarray(views[..., None])  # its first view axis pads rows: our u

    def run():
        obj = cls(vp_img_arr=arr.copy(), cfg=cfg, sta=sta_cls())  # it divides its array in place
        obj.refo_from_vp()
        return np.asarray(obj._refo_stack)[..., 0] / n  # its output is sum / N, not the mean

    return run


def run(quick: bool, plenopticam_dir) -> pd.DataFrame:
    cam = PlenopticCamera(n_rows=45, n_cols=40) if quick else PAPER_CAMERA
    repeats = 5 if quick else 50
    sc = scenes.shapes_scene(cam, np.random.default_rng(0), vary=False)
    views = raw_to_views(simulate.render(cam, sc, 4, seed=0), cam.pixels_per_lenslet)
    n, _, R, C = views.shape
    mask = aperture_mask(n, "square")
    rows = []

    def add(method, what, planes, t, note=""):
        rows.append(dict(method=method, what=what, planes=planes, ms_median=t[0], ms_p10=t[1], ms_p90=t[2],
                         ms_per_plane=t[0] / planes if planes else float("nan"), note=note))

    flat = views.reshape(-1)
    add("lf-read", "one read of the light field", 0, _times(lambda: _read_all(flat), repeats),
        f"{views.nbytes / 1e6:.1f} MB")
    threads, block = numba.get_num_threads(), _refocus_kernels._SUB_ROWS * C  # the kernel's blocks of rows
    per_pass = threads * 2 * block  # view samples of one pass: 2 views per thread
    n_pass = -(-len(PAPER_SLOPES) * views.size // per_pass)  # each view sample once per plane
    add("inner-loop floor", "4-plane stack's row-pass arithmetic, data in L1", 4,
        _times(lambda: _inner_loop_floor(threads, n_pass, block, C), repeats), f"{n_pass * per_pass} view samples")
    add("shift-sum", "check_finite (NaN/inf scan)", 0, _times(lambda: _check_finite("views", views), repeats))
    for interp in ("bilinear", "nearest"):
        add(f"shift-sum {interp}", "4-plane stack", 4,
            _times(lambda: focal_stack(views, PAPER_SLOPES, mask, interpolation=interp, check_finite=False), repeats))
        single = [_times(lambda s=s: focal_stack(views, [s], mask, interpolation=interp, check_finite=False),
                         repeats) for s in PAPER_SLOPES]
        add(f"shift-sum {interp}", "1 plane (mean over the 4 slopes)", 1, np.mean(single, axis=0))
    add("shift-sum bilinear", "4-plane stack, integer slopes", 4,
        _times(lambda: focal_stack(views, INTEGER_SLOPES, mask, check_finite=False), repeats))
    max_slope = 2.5
    add("fourier", "precompute (4-D FFT)", 0, _times(lambda: FourierSlice(views, max_slope, mask), max(3, repeats // 10)))
    fs = FourierSlice(views, max_slope, mask)
    add("fourier", "4-plane stack", 4, _times(lambda: fs.stack(PAPER_SLOPES), repeats))
    add("fourier", "1 plane (mean over the 4 slopes)", 1,
        np.mean([_times(lambda s=s: fs.stack([s]), repeats) for s in PAPER_SLOPES], axis=0))

    mod = _load_plenopticam(plenopticam_dir)
    pc_stack = None
    if mod is not None:
        pc = _plenopticam_stack(mod, views, (-1, 3))  # a = -1, 0, 1, 2: slopes 1, 0, -1, -2
        t = _times(pc, max(3, repeats // 5))
        add("plenopticam", "4-plane stack, integer slopes", 4, t, "PlenoptiCam 0.9.3, 3 channels")
        pc_stack = pc()[::-1]  # -> slopes -2, -1, 0, 1, the order of INTEGER_SLOPES

    # agreement between methods on this light field
    def agree(name, a, b):
        d = np.asarray(a, np.float64) - b
        m = int(np.ceil(max(map(abs, PAPER_SLOPES + INTEGER_SLOPES)) * (n - 1) / 2)) + 1  # the largest shift
        inner = d[:, m:-m, m:-m]
        rows.append(dict(method="agreement", what=name, planes=len(a),
                         rmse_all=float(np.sqrt(np.mean(d ** 2))), rmse_interior=float(np.sqrt(np.mean(inner ** 2))),
                         max_abs_interior=float(np.abs(inner).max())))

    agree("fourier vs shift-sum bilinear, paper slopes", fs.stack(PAPER_SLOPES), focal_stack(views, PAPER_SLOPES, mask))
    agree("fourier vs shift-sum bilinear, integer slopes", fs.stack(INTEGER_SLOPES),
          focal_stack(views, INTEGER_SLOPES, mask))
    agree("shift-sum nearest vs bilinear, paper slopes",
          focal_stack(views, PAPER_SLOPES, mask, interpolation="nearest"), focal_stack(views, PAPER_SLOPES, mask))
    if pc_stack is not None:
        agree("plenopticam vs shift-sum, integer slopes", pc_stack, focal_stack(views, INTEGER_SLOPES, mask))
    return pd.DataFrame(rows)


PAPER_FOUND = {"rectangle": 2.10, "triangle": 1.15, "circle": 0.0, "square": -1.25}  # paper Sec. III-A
DEPTH_SETS = [(20.0, 10.0, 0.0, -10.0), (-15.0, -5.0, 5.0, 25.0), (-12.0, -2.0, 8.0, 18.0), (25.0, 15.0, -5.0, -15.0)]


def slope_search_table(quick: bool) -> pd.DataFrame:
    """Sharpest slope of each shape found by both scoring methods, at the paper's depths and
    others in -15..+25 mm, beside the analytic slope (and the paper's, at its depths)."""
    from lf_flame.refocus.slope_search import find_sharpest_slope
    cam = PAPER_CAMERA
    rows = []
    for depths in DEPTH_SETS[:2] if quick else DEPTH_SETS:
        sc = scenes.shapes_scene(cam, np.random.default_rng(0), vary=False, depths_mm=depths)
        views = raw_to_views(simulate.render(cam, sc, 4, seed=0), cam.pixels_per_lenslet)
        for o in sc.objects:
            row = dict(object=o["name"], depth_mm=o["depth_offset_mm"],
                       slope_analytic=round(cam.slope_for_depth(o["depth_offset_mm"]), 4))
            for method in ("fourier", "shift-sum"):
                t = time.perf_counter()
                res = find_sharpest_slope(views, o["roi"], method=method, mask=aperture_mask(15, "circular"))
                row[f"found_{method}"] = round(res.slope, 4)
                row[f"error_{method}"] = round(res.slope - row["slope_analytic"], 4)
                row[f"s_{method}"] = round(time.perf_counter() - t, 3)
            paper_depth = depths == DEPTH_SETS[0]
            row["slope_paper"] = PAPER_FOUND[o["name"]] if paper_depth else float("nan")
            rows.append(row)
    return pd.DataFrame(rows)


def summary(df: pd.DataFrame, label: str) -> str:
    t = df[df.method != "agreement"][["method", "what", "planes", "ms_median", "ms_p10", "ms_p90", "ms_per_plane",
                                      "note"]]
    a = df[df.method == "agreement"][["what", "rmse_all", "rmse_interior", "max_abs_interior"]]
    lines = [f"# Refocusing benchmark ({label})", "",
             "ms per call: median, 10th and 90th percentile (`make bench-refocus`).", "",
             t.to_markdown(index=False, floatfmt=".3f"), "",
             "## Agreement between methods (RMSE, images in [0, 1])", "",
             a.to_markdown(index=False, floatfmt=".2e"), ""]
    stack = df[(df.what == "4-plane stack")].set_index("method").ms_median
    pc = df[df.method == "plenopticam"].ms_median
    if len(pc):
        lines.append(f"PlenoptiCam / shift-sum bilinear, 4-plane stack: "
                     f"{float(pc.iloc[0]) / float(stack['shift-sum bilinear']):.0f}x.")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="results")
    ap.add_argument("--quick", action="store_true", help="45 x 40 lenslets, 5 repeats (for tests)")
    ap.add_argument("--plenopticam", help="folder with PlenoptiCam installed (pip install --no-deps --target)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    t0 = time.perf_counter()
    df = run(args.quick, args.plenopticam)
    label = "45 x 40 lenslets (quick)" if args.quick else "15 x 15 x 180 x 90 float32"
    atomic_write_text(out / "bench_refocus.csv", df.to_csv(index=False))
    slopes = slope_search_table(args.quick)
    atomic_write_text(out / "slopes_depths.csv", slopes.to_csv(index=False))
    atomic_write_text(out / "bench_refocus.md", summary(df, label) + "\n## Slope search (`slopes_depths.csv`)\n\n"
                      + slopes.to_markdown(index=False) + "\n")
    prov = provenance() | dict(light_field=label, threads=numba.get_num_threads(),
                               wall_time_s=time.perf_counter() - t0, command="python " + " ".join(sys.argv))
    atomic_write_text(out / "bench_refocus.json", json.dumps(prov, indent=2))
    print(summary(df, label))
    print(slopes.to_string(index=False))


if __name__ == "__main__":
    main()
