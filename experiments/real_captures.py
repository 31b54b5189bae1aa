"""Real light fields (``make real-data``): calibrate, decode and refocus napari-lf's three captures.

napari-lf 0.1.7 (BSD-3) ships three real light-field microscopy captures (plenoptic 1.0:
microlens array at the image plane, sensor at its focus), each a light-field frame, a
radiometry (white) frame and a dark frame, with the optics in a README or metadata file.
The Makefile installs the package with ``pip --no-deps --target`` into its own folder;
this script reads its ``napari_lf/examples`` files only (lf_flame never imports napari_lf).

For each capture, measured in this run:

- :func:`lf_flame.real.calibration.calibrate` on the white frame minus the dark frame: pitch,
  rotation, offset, fit residual (px) and wall time;
- an independent pitch: the peak of the periodogram of the white image's mean row and
  column profiles (SciPy, Hann window, zero-padded to 2^20 points), and the pitch the
  stated optics imply (lenslet pitch / pixel size, parsed from the capture's files);
- :func:`lf_flame.real.decoding.decode` of the light-field frame (dark-subtracted,
  white-normalised) into N × N views, N the pitch rounded down;
- the slope search (:func:`lf_flame.refocus.slope_search.find_sharpest_slope`, Fourier slice,
  Tenengrad, circular aperture, slopes -2 to 2) on the brightest structure of the
  centre view, and its sharpness curve: the peak over the curve's ends, the full width
  at half maximum (slope units), and whether the peak lies inside the searched range;
- a figure: the white image with fitted (lattice) and measured centres, the centre
  view, the sharpness curve and a focal stack of 6 planes (shift-and-sum).
- optionally (``--plenopticam DIR``), PlenoptiCam 0.9.3's calibration (``LfpCalibrator``,
  'area' centroids and 'grid-fit') on the same white image: its centres matched to ours
  (nearest within half a pitch), the mean offset and spread, and both run times.

Then both calibrations on the simulator's white images with known centres
(:data:`SYNTHETIC`). Writes ``<out>/<capture>.png``, ``<out>/summary.csv``,
``<out>/synthetic_centres.csv``, ``<out>/summary.md`` and ``<out>/summary.json``
(with provenance).

Usage: ``python experiments/real_captures.py --data .bench/napari-lf/napari_lf/examples --out results/real
[--plenopticam .bench/plenopticam] [--figures-only]`` (``--figures-only``: the figures alone,
the summaries left as they are).
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import ndimage, signal

from lf_flame.real import calibration as calibrate
from lf_flame.real.images import load_image
from lf_flame.real import decoding as decode
from lf_flame.config import atomic_write_text, provenance
from lf_flame.refocus.shift_and_sum import aperture_mask, refocus_views

#: file names of each capture in napari_lf/examples (light field, white, dark, optics files)
from lf_flame.refocus.slope_search import find_sharpest_slope  # noqa: E402
CAPTURES = {
    "antleg": ("antleg/light_field.png", "antleg/radiometry_frame.png", "antleg/dark_frame.tif", ["antleg/README"]),
    "seaurchin": ("seaurchin/light_field.tif", "seaurchin/radiometry_frame.tif", "seaurchin/dark_frame.tif",
                  ["seaurchin/metadata.txt"]),
    "GUVExperim1": ("GUVExperim1/Lightfield_GUVExperim1.tif", "GUVExperim1/Radiometry_GUVExperim1.tif",
                    "GUVExperim1/DarkFrame_GUVExperim1.tif", ["GUVExperim1/metadata.txt", "GUVExperim1/README"]),
}


def stated_optics(data: Path, files) -> tuple[float, float, str]:
    """Lenslet pitch (µm) and effective pixel size (µm) stated by a capture's files.

    metadata.txt: JSON ``calibrate.ulens_pitch`` and ``calibrate.pixel_size``; README:
    the lines ``pitch <µm> um`` and ``pixel-size <µm> um`` of its summary.
    """
    for name in files:
        text = (data / name).read_text(errors="replace")
        if name.endswith("metadata.txt"):
            c = json.loads(text)["calibrate"]
            return float(c["ulens_pitch"]), float(c["pixel_size"]), name
        p = re.search(r"^pitch\s+([\d.]+)\s*um", text, re.M)
        s = re.search(r"^pixel-size\s+([\d.]+)\s*um", text, re.M)
        if p and s:
            return float(p.group(1)), float(s.group(1)), name
    raise ValueError(f"no stated lenslet pitch and pixel size in {files}")


def periodogram_pitch(img: np.ndarray, lo: float = 5.0, hi: float = 100.0) -> tuple[float, float]:
    """Period (px) of the strongest peak, among periods ``lo`` to ``hi``, of the periodogram
    of the mean row profile and of the mean column profile: (along columns, along rows)."""
    out = []
    for axis in (0, 1):
        prof = img.mean(axis=axis)
        f, p = signal.periodogram(prof, window="hann", nfft=1 << 20, detrend="linear")
        band = (f > 1 / hi) & (f < 1 / lo)
        out.append(1 / f[band][np.argmax(p[band])])
    return out[0], out[1]


def brightest_roi(view: np.ndarray, size: int) -> tuple[int, int, int, int]:
    """ROI (row0, row1, col0, col1), ``size`` lenslets square and wholly inside the view,
    about the brightest structure of the centre view: the maximum of the view smoothed over
    a quarter of the ROI, among the centres that keep the ROI inside."""
    R, C = view.shape
    size = min(size, R, C)
    sm = ndimage.gaussian_filter(view, size / 4)
    h = size // 2
    inner = sm[h:R - (size - h) + 1, h:C - (size - h) + 1]
    r, c = np.unravel_index(np.argmax(inner), inner.shape)
    return int(r), int(r) + size, int(c), int(c) + size


def peak_width(slopes: np.ndarray, scores: np.ndarray) -> float:
    """Full width (slope units) of the sharpness curve at half its maximum, about the maximum."""
    k = int(np.argmax(scores))
    half = 0.5 * scores[k]
    lo = k
    while lo > 0 and scores[lo - 1] >= half:
        lo -= 1
    hi = k
    while hi < len(scores) - 1 and scores[hi + 1] >= half:
        hi += 1
    return float(slopes[hi] - slopes[lo])


def _load_plenopticam(path):
    """PlenoptiCam 0.9.3's ``LfpCalibrator`` and its config classes, or None.

    Loaded as ``experiments/bench_refocus.py`` loads PlenoptiCam (same folder, same stubs
    for its optional dependencies that calibration never calls)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_refocus
    if bench_refocus._load_plenopticam(path) is None:
        return None
    try:
        from plenopticam.cfg import PlenopticamConfig
        from plenopticam.lfp_calibrator import LfpCalibrator
        from plenopticam.misc import PlenopticamStatus
    except Exception as e:  # noqa: BLE001 - an optional baseline; say why and go on
        print(f"PlenoptiCam calibration not used: {type(e).__name__}: {e}")
        return None
    return LfpCalibrator, PlenopticamConfig, PlenopticamStatus


def plenopticam_centres(mod, white: np.ndarray, method: str = "grid-fit"):
    """PlenoptiCam's lenslet centres (K, 2) (row, column) in our pixel coordinates, and seconds.

    ``LfpCalibrator`` (pitch estimate, LoG peaks, ``method`` refinement: 'area' centroids
    or 'grid-fit' lines through them, sorting) on the white image scaled to [0, 1]; its
    centres are array indices (pixel centres at integers), hence + 0.5. An empty array
    where it finds no grid (its status flags an error)."""
    import tempfile
    cls, cfg_cls, sta_cls = mod
    cfg = cfg_cls()
    cfg.params[cfg.opt_prnt] = False
    cfg.params[cfg.cal_meth] = method
    img = np.clip(white / np.percentile(white, 99.5), 0, 1)
    with tempfile.TemporaryDirectory() as tmp:
        cfg.params[cfg.cal_meta] = str(Path(tmp) / "calibration.json")   # it saves its result there
        sta = sta_cls()
        t = time.perf_counter()
        cls(img, cfg, sta).main()
        dt = time.perf_counter() - t
    mic = np.asarray(cfg.calibs.get(cfg.mic_list, []), np.float64)
    if sta.error or mic.ndim != 2 or len(mic) == 0:
        return np.zeros((0, 2)), dt
    return mic[:, :2] + 0.5, dt


def match(a: np.ndarray, b: np.ndarray, radius: float):
    """Each point of ``a`` (K, 2) to its nearest in ``b`` within ``radius``: (mask, a - b[nearest])."""
    if len(a) == 0:
        return np.zeros(0, bool), np.zeros((0, 2))
    d = a[:, None, :] - b[None, :, :]
    dist = np.hypot(d[..., 0], d[..., 1])
    k = dist.argmin(axis=1)
    ok = dist[np.arange(len(a)), k] < radius
    return ok, (a - b[k])[ok]


#: synthetic white images with known centres for both calibrations: (rotation °, offset px)
SYNTHETIC = [(0.0, (0.0, 0.0)), (0.4, (3.2, -5.7)), (-1.3, (-2.5, 4.1)), (1.9, (0.6, 0.3))]


def synthetic_rows(pcam) -> list[dict]:
    """Both calibrations on the simulator's white images (28 x 28 lenslets, pitch 15.43 px,
    f-number matched, cos⁴): centre errors against the camera's true lenslet image centres."""
    from lf_flame.simulate import scenes
    from lf_flame.simulate import tracer as simulate
    from lf_flame.optics.camera import PlenopticCamera
    rows = []
    for rot, off in SYNTHETIC:
        cam = PlenopticCamera(n_rows=28, n_cols=28, pixels_per_lenslet=15, grid_pitch_px=15.43,
                              grid_rotation_deg=rot, grid_offset_px=off)
        white = simulate.render(cam, scenes.white_scene(cam), 16).astype(np.float64)
        truth = cam.lenslet_image_centres_px().reshape(-1, 2)
        t = time.perf_counter()
        cal = calibrate.calibrate(white)
        t_ours = time.perf_counter() - t
        _, e = match(cal.centres_px().reshape(-1, 2), truth, 0.5 * cal.pitch_px)
        _, em = match(cal.lenslets[:, 2:], truth, 0.5 * cal.pitch_px)
        row = dict(rotation_deg=rot, offset_px=f"{off[0]:+.1f}, {off[1]:+.1f}", lenslets=cam.n_rows * cam.n_cols,
                   ours_pitch_err_pct=round(100 * (cal.pitch_px / 15.43 - 1), 4),
                   ours_rotation_err_deg=round(cal.rotation_deg - rot, 4),
                   ours_lattice_err_max_px=round(float(np.hypot(*e.T).max()), 3),
                   ours_measured_err_rms_px=round(float(np.sqrt(np.mean(np.sum(em ** 2, 1)))), 3),
                   ours_s=round(t_ours, 2))
        if pcam is not None:
            for meth in ("area", "grid-fit"):
                pc, dt = plenopticam_centres(pcam, white, meth)
                ok, e = match(pc, truth, 0.5 * 15.43)
                found = len(pc) > 0
                row.update({f"pcam_{meth}_centres": len(pc),
                            f"pcam_{meth}_err_rms_px": round(float(np.sqrt(np.mean(np.sum(e ** 2, 1)))), 3)
                            if found and ok.any() else float("nan"),
                            f"pcam_{meth}_s": round(dt, 2)})
        rows.append(row)
        print(json.dumps(row))
    return rows


def figure(path, name, white, cal, views, roi, search, slopes, stack):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # two rows laid out apart (subfigures): the top row's three panels, the focal stack's
    # planes below, each row as tall as its images need
    width, top_h = 16.0, 4.6
    stack_h = width / len(slopes) * stack.shape[1] / stack.shape[2] + 0.45
    fig = plt.figure(figsize=(width, top_h + stack_h + 0.4), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[top_h, stack_h])
    ax_white, ax_view, ax_curve = top.subplots(1, 3)
    ax = ax_white
    cen = cal.centres_px()
    mid = cen[cal.n_rows // 2, cal.n_cols // 2]
    half = 5 * cal.pitch_px
    r0, r1 = int(max(0, mid[0] - half)), int(min(white.shape[0], mid[0] + half))
    c0, c1 = int(max(0, mid[1] - half)), int(min(white.shape[1], mid[1] + half))
    ax.imshow(white[r0:r1, c0:c1], cmap="gray", extent=(c0, c1, r1, r0))
    sel = ((cen[..., 0] > r0) & (cen[..., 0] < r1) & (cen[..., 1] > c0) & (cen[..., 1] < c1))
    ax.plot(cen[sel][:, 1], cen[sel][:, 0], "r+", ms=9, label="fitted lattice")
    m = cal.lenslets[:, 2:]
    sm = (m[:, 0] > r0) & (m[:, 0] < r1) & (m[:, 1] > c0) & (m[:, 1] < c1)
    ax.plot(m[sm, 1], m[sm, 0], "cx", ms=6, label="measured")
    ax.set_title(f"white image, 10 x 10 lenslets about the centre\npitch {cal.pitch_px:.3f} px, "
                 f"rotation {cal.rotation_deg:+.3f}°, residual {cal.residual_rms_px:.2f} px rms", fontsize=9)
    ax.set(xlabel="sensor column (px)", ylabel="sensor row (px)")
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1), borderaxespad=0)   # beside, not on, the lenslets
    n = views.shape[0]
    ax = ax_view
    cv = views[n // 2, n // 2]
    ax.imshow(cv, cmap="gray", vmin=0, vmax=np.percentile(cv, 99.5))
    ax.add_patch(plt.Rectangle((roi[2] - 0.5, roi[0] - 0.5), roi[3] - roi[2], roi[1] - roi[0], fill=False,
                               ec="y", lw=1))
    ax.set_title(f"centre view of {n} x {n}, {views.shape[2]} x {views.shape[3]} lenslets\n"
                 "(box: ROI of the slope search)", fontsize=9)
    ax.set(xlabel="lenslet column", ylabel="lenslet row")
    ax = ax_curve
    ax.plot(search.slopes, search.scores / search.scores.max(), ".-", ms=3)
    ax.axvline(search.slope, color="r", lw=0.8)
    ax.set_xlabel("slope (lenslets per view)")
    ax.set_ylabel("Tenengrad / max")
    ax.set_title(f"sharpness of the ROI (Fourier slice, Tenengrad)\npeak at slope {search.slope:+.3f}",
                 fontsize=9)
    vmax = np.percentile(stack, 99.5)
    for s, im, ax in zip(slopes, stack, bottom.subplots(1, len(slopes))):
        ax.imshow(im, cmap="gray", vmin=0, vmax=vmax)
        ax.set_title(f"shift-and-sum, slope {s:+.2f}", fontsize=9)
        ax.axis("off")
    fig.suptitle(f"{name}: napari-lf 0.1.7 example capture, calibrated and decoded by lf_flame", fontsize=11)
    fig.savefig(path, dpi=90)
    plt.close(fig)


def run(data: Path, out: Path, plenopticam_dir=None, figures_only: bool = False) -> pd.DataFrame | None:
    """Every capture's figure and, unless ``figures_only``, the summaries (``figures_only``:
    the figures alone, no PlenoptiCam, no synthetic images, no tables written; None)."""
    out.mkdir(parents=True, exist_ok=True)
    pcam = None if figures_only else _load_plenopticam(plenopticam_dir)
    rows = []
    for name, (lf_file, white_file, dark_file, optics_files) in CAPTURES.items():
        raw = load_image(data / lf_file)
        white = load_image(data / white_file)
        dark = load_image(data / dark_file)
        t = time.perf_counter()
        cal = calibrate.calibrate(white, dark, camera_id=name)
        t_cal = time.perf_counter() - t
        p_cols, p_rows = periodogram_pitch(white - dark)
        p_per = 0.5 * (p_cols + p_rows)
        pitch_um, pixel_um, src = stated_optics(data, optics_files)
        p_stated = pitch_um / pixel_um
        t = time.perf_counter()
        views = decode.decode(raw, cal, white, dark, camera_id=name)
        t_dec = time.perf_counter() - t
        n = views.shape[0]
        mask = aperture_mask(n, "circular")
        roi = brightest_roi(views[n // 2, n // 2], max(8, min(views.shape[2:]) // 3))
        t = time.perf_counter()
        search = find_sharpest_slope(views, roi, lo=-2.0, hi=2.0, mask=mask)
        t_search = time.perf_counter() - t
        sc = search.scores
        ends = float(sc.max() / max(sc[0], sc[-1]))           # peak over the curve's ends
        width = peak_width(search.slopes, sc)
        inside = bool(-2.0 + 0.1 < search.slope < 2.0 - 0.1)
        slopes = np.round(search.slope + np.linspace(-1.0, 1.0, 6), 3)
        stack = refocus_views(views, slopes, mask, method="shift-sum")
        figure(out / f"{name}.png", name, (white - dark) / np.percentile(white - dark, 99.5), cal, views, roi,
               search, slopes, stack)
        print(f"-> {out / f'{name}.png'}")
        if figures_only:
            continue
        row = dict(capture=name, sensor=f"{white.shape[0]}x{white.shape[1]}", layout=cal.layout,
                   pitch_px=round(cal.pitch_px, 4), periodogram_px=round(p_per, 4),
                   periodogram_cols_rows_px=f"{p_cols:.3f} / {p_rows:.3f}",
                   vs_periodogram_pct=round(100 * (cal.pitch_px / p_per - 1), 3),
                   stated_px=round(p_stated, 4), stated_from=f"{pitch_um:g} um / {pixel_um:g} um ({src})",
                   vs_stated_pct=round(100 * (cal.pitch_px / p_stated - 1), 3),
                   rotation_deg=round(cal.rotation_deg, 4), offset_px=f"{cal.offset_px[0]:+.2f}, {cal.offset_px[1]:+.2f}",
                   residual_rms_px=round(cal.residual_rms_px, 3), residual_max_px=round(cal.residual_max_px, 3),
                   lenslets_fitted=len(cal.lenslets), spots_found=cal.n_found,
                   views=f"{n}x{n}x{views.shape[2]}x{views.shape[3]}", calibrate_s=round(t_cal, 2),
                   decode_s=round(t_dec, 2), roi=" ".join(map(str, roi)), best_slope=round(search.slope, 3),
                   peak_over_ends=round(ends, 1), peak_fwhm_slope=round(width, 3), peak_inside_range=inside,
                   search_s=round(t_search, 2))
        if pcam is not None:
            for meth in ("area", "grid-fit"):
                pc, t_pc = plenopticam_centres(pcam, white - dark, meth)
                ref = cal.lenslets[:, 2:] if meth == "area" else cal.centres_px().reshape(-1, 2)
                ok, e = match(pc, ref, 0.5 * cal.pitch_px)
                row.update({f"pcam_{meth}_centres": len(pc), f"pcam_{meth}_matched": int(ok.sum()),
                            f"pcam_{meth}_mean_offset_px": f"{e[:, 0].mean():+.3f}, {e[:, 1].mean():+.3f}"
                            if ok.any() else "", f"pcam_{meth}_std_px": f"{e[:, 0].std():.3f}, {e[:, 1].std():.3f}"
                            if ok.any() else "", f"pcam_{meth}_s": round(t_pc, 2)})
        rows.append(row)
        print(json.dumps(row))
    if figures_only:
        return None
    df = pd.DataFrame(rows)
    df.to_csv(out / "summary.csv", index=False)
    syn = pd.DataFrame(synthetic_rows(pcam))
    syn.to_csv(out / "synthetic_centres.csv", index=False)
    pc_note = ("PlenoptiCam 0.9.3 (`LfpCalibrator`, methods 'area' and 'grid-fit') ran on the same white images "
               "(minus dark); its centres are matched to ours (measured for 'area', fitted lattice for 'grid-fit') "
               "within half a pitch: mean offset and spread (rows, columns; px)." if pcam is not None else
               "PlenoptiCam was not available in this run (no comparison).")
    atomic_write_text(out / "summary.md", "# Real captures: lenslet-grid calibration and decoding\n\n"
                      "Written by `experiments/real_captures.py` (`make real-data`); every number measured "
                      "in that run. Pitches in pixels; `vs_*_pct`: our pitch relative to the periodogram's "
                      "and to the stated optics'. " + pc_note + "\n\n" + df.to_markdown(index=False) +
                      "\n\n## Synthetic white images with known centres\n\nThe simulator's white images "
                      "(28 x 28 lenslets, pitch 15.43 px): errors against the true lenslet image centres; "
                      "PlenoptiCam's centre count is 0 where it reported an error (no grid).\n\n"
                      + syn.to_markdown(index=False) + "\n")
    atomic_write_text(out / "summary.json", json.dumps({"rows": rows, "synthetic": syn.to_dict("records"),
                                                        "provenance": provenance()}, indent=1, default=str))
    return df


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", required=True, help="napari_lf/examples folder")
    ap.add_argument("--out", required=True)
    ap.add_argument("--plenopticam", help="folder with PlenoptiCam installed (pip install --no-deps --target)")
    ap.add_argument("--figures-only", action="store_true",
                    help="redraw <out>/<capture>.png only: no PlenoptiCam, no synthetic images, summaries untouched")
    a = ap.parse_args(argv)
    data = Path(a.data)
    if not data.is_dir():
        raise SystemExit(f"error: no napari-lf example folder at {data} (make real-data installs it)")
    df = run(data, Path(a.out), a.plenopticam, a.figures_only)
    if df is not None:
        print(df.to_string(index=False))


if __name__ == "__main__":
    main()
